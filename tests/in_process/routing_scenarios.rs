//! The original's integration scenarios (routing, priority, preload, component
//! broadcast fallback) rebuilt on the routing core, plus expiry over time.

use crate::routing;

use mavtables::routing::{Pace, Pacer, RouterOptions, Timestamp};
use routing::{Net, frame};
use std::time::Duration;

// Listeners: 127.1 and 192.168 on UDP, 172.128 on the serial port; sender 10.10 on UDP.
const ROUTING: &str = concat!(
    "serial { device ./ttyS0; baudrate 57600; }\n",
    "udp { port 14500; max_bitrate 262144; }\n",
    include_str!("../data/config/routing_chains.conf"),
);

const SENDER: &str = "127.0.0.1:5000";
const L127: &str = "127.0.0.1:5001";
const L192: &str = "127.0.0.1:5002";
const SERIAL: &str = "./ttyS0";

fn routing_net() -> Net {
    let mut net = Net::new(ROUTING);
    net.heartbeat(L127, "127.1");
    net.heartbeat(L192, "192.168");
    net.heartbeat(SERIAL, "172.128");
    net.heartbeat(SENDER, "10.10");
    net
}

#[test]
fn routing_scenario_deliveries() {
    let mut net = routing_net();
    let script: &[(&str, Option<&str>)] = &[
        ("ATTITUDE", None),
        ("PARAM_REQUEST_READ", Some("192.168")),
        ("PARAM_REQUEST_READ", Some("127.1")),
        ("PING", Some("192.168")),
        ("PING", Some("127.1")),
        ("GPS_RAW_INT", None),
        ("SET_HOME_POSITION", Some("172.0")),
        ("MISSION_REQUEST_LIST", Some("172.128")),
        ("MISSION_REQUEST_LIST", Some("172.168")),
        ("MISSION_REQUEST_LIST", Some("192.168")),
    ];
    for (name, to) in script {
        net.send(SENDER, name, "10.10", *to);
    }
    assert_eq!(
        net.drain(L127),
        [
            // HEARTBEATs are rejected everywhere; ATTITUDE is accepted by the last rules.
            "ATTITUDE (#30) from 10.10 (v2.0)",
        ]
    );
    assert_eq!(
        net.drain(L192),
        [
            // ATTITUDE: the call to addr_192_168 does not decide and falls through.
            "ATTITUDE (#30) from 10.10 (v2.0)",
            "PARAM_REQUEST_READ (#20) from 10.10 to 192.168 (v2.0)",
        ]
    );
    assert_eq!(
        net.drain(SERIAL),
        [
            // Priority 3 puts it first; the fallback to 172.168 is filtered as 172.168
            // and rejected; ATTITUDE goes to addr_172_128, which falls to default reject.
            "SET_HOME_POSITION (#243) from 10.10 to 172.0 (v2.0)",
            "MISSION_REQUEST_LIST (#43) from 10.10 to 172.128 (v2.0)",
        ]
    );
}

#[test]
fn routing_scenario_level_3_log() {
    let mut net = routing_net();
    assert_eq!(
        net.take_log(),
        [
            "new component 127.1 on 127.0.0.1:5001",
            "received HEARTBEAT (#0) from 127.1 (v2.0) source 127.0.0.1:5001",
            "rejected HEARTBEAT (#0) from 127.1 (v2.0) source 127.0.0.1:5001 dest ./ttyS0",
            "new component 192.168 on 127.0.0.1:5002",
            "received HEARTBEAT (#0) from 192.168 (v2.0) source 127.0.0.1:5002",
            "rejected HEARTBEAT (#0) from 192.168 (v2.0) source 127.0.0.1:5002 dest ./ttyS0",
            "rejected HEARTBEAT (#0) from 192.168 (v2.0) source 127.0.0.1:5002 dest 127.0.0.1:5001",
            "new component 172.128 on ./ttyS0",
            "received HEARTBEAT (#0) from 172.128 (v2.0) source ./ttyS0",
            "rejected HEARTBEAT (#0) from 172.128 (v2.0) source ./ttyS0 dest 127.0.0.1:5001",
            "rejected HEARTBEAT (#0) from 172.128 (v2.0) source ./ttyS0 dest 127.0.0.1:5002",
            "new component 10.10 on 127.0.0.1:5000",
            "received HEARTBEAT (#0) from 10.10 (v2.0) source 127.0.0.1:5000",
            "rejected HEARTBEAT (#0) from 10.10 (v2.0) source 127.0.0.1:5000 dest ./ttyS0",
            "rejected HEARTBEAT (#0) from 10.10 (v2.0) source 127.0.0.1:5000 dest 127.0.0.1:5001",
            "rejected HEARTBEAT (#0) from 10.10 (v2.0) source 127.0.0.1:5000 dest 127.0.0.1:5002",
        ]
    );
    net.send(SENDER, "SET_HOME_POSITION", "10.10", Some("172.0"));
    net.send(SENDER, "MISSION_REQUEST_LIST", "10.10", Some("172.168"));
    net.send(SENDER, "PING", "10.10", Some("192.168"));
    assert_eq!(
        net.take_log(),
        [
            "received SET_HOME_POSITION (#243) from 10.10 to 172.0 (v2.0) source 127.0.0.1:5000",
            "accepted SET_HOME_POSITION (#243) from 10.10 to 172.0 (v2.0) source 127.0.0.1:5000 dest ./ttyS0",
            "received MISSION_REQUEST_LIST (#43) from 10.10 to 172.168 (v2.0) source 127.0.0.1:5000",
            "rejected MISSION_REQUEST_LIST (#43) from 10.10 to 172.168 (v2.0) source 127.0.0.1:5000 dest ./ttyS0",
            "received PING (#4) from 10.10 to 192.168 (v2.0) source 127.0.0.1:5000",
            "rejected PING (#4) from 10.10 to 192.168 (v2.0) source 127.0.0.1:5000 dest 127.0.0.1:5002",
        ]
    );
}

const PRIORITY: &str = "
serial { device ./ttyS0; }
udp { port 14500; max_bitrate 65536; }
chain default {
    reject if HEARTBEAT;
    accept with priority 1 if ENCAPSULATED_DATA;
    accept with priority -1 if ATTITUDE;
    accept;
}
";

/// Priority scenario: a UDP listener behind a 64 kbit/s limit is sent 50
/// ENCAPSULATED_DATA (+1), 100 ATTITUDE (-1) and 100 GLOBAL_POSITION_INT (0) from a UDP
/// sender and 50 ENCAPSULATED_DATA from the serial port, 0.3 ms apart; it receives every
/// ENCAPSULATED_DATA, then every GLOBAL_POSITION_INT, then every ATTITUDE.
#[test]
fn priority_scenario_through_the_pacer() {
    let mut net = Net::new(PRIORITY);
    net.heartbeat("127.0.0.1:6000", "12.26"); // the listener
    net.heartbeat("127.0.0.1:6001", "192.168"); // the UDP sender
    net.heartbeat(SERIAL, "172.128"); // the serial sender
    let listener = net.links["127.0.0.1:6000"];
    let _ = net.router.pop(listener); // nothing: heartbeats are rejected
    let mut arrivals: Vec<(&str, &str, &str)> = Vec::new();
    for _ in 0..50 {
        arrivals.push(("127.0.0.1:6001", "ENCAPSULATED_DATA", "192.168"));
        arrivals.push((SERIAL, "ENCAPSULATED_DATA", "172.128"));
    }
    for i in 0..200 {
        let name = if i % 2 == 0 {
            "ATTITUDE"
        } else {
            "GLOBAL_POSITION_INT"
        };
        arrivals.push(("127.0.0.1:6001", name, "192.168"));
    }
    let mut pacer = Pacer::new(65_536);
    let mut received: Vec<String> = Vec::new();
    let step = Duration::from_micros(300);
    let mut now = Timestamp::from_secs(1);
    let mut next = arrivals.iter();
    let mut pending = true;
    while pending || net.router.peek(listener).is_some() {
        net.now = now;
        if let Some(&(link, name, from)) = next.next() {
            net.send(link, name, from, None);
        } else {
            pending = false;
        }
        // The I/O layer's writable handler: send while the pacer allows.
        while let Some(len) = net.router.peek(listener).map(|p| p.len()) {
            match pacer.check(now, len) {
                Pace::Now => {
                    let p = net.router.pop(listener).expect("peeked");
                    pacer.sent(now, len);
                    received.push(
                        mavtables::wire::Frame::parse_exact(&p)
                            .expect("frame")
                            .name()
                            .to_string(),
                    );
                }
                Pace::At(_) => break,
            }
        }
        now = now + step;
    }
    let expect: Vec<&str> = std::iter::repeat_n("ENCAPSULATED_DATA", 100)
        .chain(std::iter::repeat_n("GLOBAL_POSITION_INT", 100))
        .chain(std::iter::repeat_n("ATTITUDE", 100))
        .collect();
    assert_eq!(received, expect);
    // 100 × 267 + 200 × 40 bytes at 65 536 bit/s take about 4.2 s.
    let elapsed = now.saturating_since(Timestamp::from_secs(1)).as_secs_f64();
    assert!((4.0..4.5).contains(&elapsed), "took {elapsed} s");
}

const PRELOAD: &str = "
serial {
    device ./ttyS0;
    preload 192.168;
    preload 127.1;
}
chain default {
    reject if HEARTBEAT;
    accept;
}
";

#[test]
fn preload_scenario() {
    let mut net = Net::new(PRELOAD);
    assert_eq!(
        net.take_log(),
        [
            "new component 192.168 on ./ttyS0",
            "new component 127.1 on ./ttyS0"
        ]
    );
    net.heartbeat("127.0.0.1:5000", "10.10");
    for t in [0, 121, 3600] {
        net.at(t);
        net.send("127.0.0.1:5000", "ATTITUDE", "10.10", None);
        net.send("127.0.0.1:5000", "PING", "10.10", Some("192.168"));
        net.send("127.0.0.1:5000", "PING", "10.10", Some("127.1"));
        net.send("127.0.0.1:5000", "PING", "10.10", Some("127.5")); // fallback
        net.send("127.0.0.1:5000", "PING", "10.10", Some("172.128")); // unknown: silent
        net.send("127.0.0.1:5000", "SET_MODE", "10.10", Some("172.0")); // unknown: silent
        net.tick();
        assert_eq!(
            net.drain(SERIAL),
            [
                "ATTITUDE (#30) from 10.10 (v2.0)",
                "PING (#4) from 10.10 to 192.168 (v2.0)",
                "PING (#4) from 10.10 to 127.1 (v2.0)",
                "PING (#4) from 10.10 to 127.5 (v2.0)",
            ],
            "at {t} s: preloads are permanent"
        );
    }
}

#[test]
fn component_broadcast_fallback_scenario() {
    let conf = "
serial { device ./ttyS0; }
chain default {
    reject if HEARTBEAT;
    accept if to 1.255/9;
}
";
    let mut net = Net::new(conf);
    net.heartbeat(SERIAL, "1.1");
    net.heartbeat("127.0.0.1:5000", "192.168");
    for c in 0..=255u8 {
        let to = format!("1.{c}");
        net.send(
            "127.0.0.1:5000",
            "MISSION_REQUEST_LIST",
            "192.168",
            Some(&to),
        );
    }
    let expect: Vec<String> = (128..=255)
        .map(|c| format!("MISSION_REQUEST_LIST (#43) from 192.168 to 1.{c} (v2.0)"))
        .collect();
    assert_eq!(net.drain(SERIAL), expect);
}

#[test]
fn learned_addresses_expire_after_120_s() {
    let mut net = Net::new("serial { device ./ttyS0; }\ndefault_action accept;");
    net.heartbeat(SERIAL, "1.1");
    net.heartbeat("u:1", "2.1");
    net.drain("u:1");
    net.drain(SERIAL);
    net.at(120);
    net.send("u:1", "PING", "2.2", Some("1.1"));
    assert_eq!(net.drain(SERIAL).len(), 1, "present at exactly 120 s");
    net.take_log();
    net.now = Timestamp::from_secs(120) + Duration::from_millis(1);
    net.send("u:1", "PING", "2.2", Some("1.1"));
    assert!(net.drain(SERIAL).is_empty(), "gone after 120 s");
    assert_eq!(net.take_log().len(), 1, "silent: system 1 is unknown now");
    // A broadcast now meets an empty pool: rejected.
    net.send("u:1", "ATTITUDE", "2.2", None);
    assert!(net.take_log()[1].starts_with("rejected ATTITUDE"));
    // Heard again: a new component again.
    net.heartbeat(SERIAL, "1.1");
    assert_eq!(net.take_log()[0], "new component 1.1 on ./ttyS0");
}

#[test]
fn udp_links_go_after_their_pool_has_been_empty_for_the_expiry_time() {
    let mut net = Net::new("serial { device ./ttyS0; }\ndefault_action accept;");
    net.at(10);
    net.heartbeat("u:1", "2.1");
    net.at(100);
    net.heartbeat("u:1", "2.2"); // last learned at 100 s: pool empty after 220 s
    net.at(340);
    assert!(net.tick().is_empty(), "still there at exactly 340 s");
    net.now = Timestamp::from_secs(340) + Duration::from_nanos(1);
    assert_eq!(net.tick(), ["u:1"]);
    assert_eq!(
        net.router.links().count(),
        1,
        "serial links are never removed"
    );
    net.at(100_000);
    assert!(net.tick().is_empty());
    // The remote comes back: a new link, logged as new.
    net.heartbeat("u:1", "2.1");
    assert_eq!(
        net.take_log()[0..2],
        [
            "new component 2.1 on u:1".to_string(),
            "received HEARTBEAT (#0) from 2.1 (v2.0) source u:1".to_string()
        ]
    );
}

#[test]
fn queue_overflow_is_counted_and_bounded() {
    let options = RouterOptions {
        queue_capacity: 10 * 300,
        ..RouterOptions::default()
    };
    let mut net = Net::with_options(
        "serial { device ./ttyS0; }\ndefault_action accept;",
        options,
    );
    net.heartbeat(SERIAL, "1.1");
    let f = frame("ENCAPSULATED_DATA", "2.1", None);
    for _ in 0..1000 {
        net.recv("u:1", &f);
    }
    // 267-byte frames plus 32 bytes of bookkeeping each: ten fit in 3000 bytes.
    let q = net.router.link(net.links[SERIAL]).expect("link").queue();
    assert!(q.bytes() <= 3000);
    assert_eq!(q.len(), 10);
    assert_eq!(q.dropped(), 990);
    assert_eq!(net.drops, 990);
}

/// Sum of every link's queue, as the queues themselves count it.
fn queued_everywhere(net: &Net) -> (usize, Vec<usize>) {
    let lens = net
        .router
        .links()
        .map(|l| l.queue().len())
        .collect::<Vec<_>>();
    let bytes = net.router.links().map(|l| l.queue().bytes()).sum();
    (bytes, lens)
}

#[test]
fn shared_queue_capacity_bounds_many_links_and_spreads_the_loss() {
    // 299 bytes a packet in the queues' reckoning (267-byte frame + 32); 10 per link,
    // 20 in all.
    let options = RouterOptions {
        queue_capacity: 10 * 299,
        total_queue_capacity: 20 * 299,
        ..RouterOptions::default()
    };
    let mut net = Net::with_options("chain default { reject if HEARTBEAT; accept; }\n", options);
    // 50 remotes (say, a flood of spoofed source ports), none sending anything back.
    for k in 0..50 {
        net.heartbeat(&format!("u:{k}"), &format!("3.{}", k + 1));
    }
    let f = frame("ENCAPSULATED_DATA", "2.1", None);
    for _ in 0..1000 {
        net.recv("sender", &f);
    }
    let (bytes, lens) = queued_everywhere(&net);
    assert_eq!(bytes, net.router.queued_bytes());
    // Full, but for the eighth freed at once when it overflows.
    let queued: usize = lens.iter().sum();
    assert!(bytes <= 20 * 299, "{bytes} bytes queued");
    assert!(queued >= 17, "{lens:?}");
    // The link holding the most always gives way, so the loss is spread: without the
    // shared bound every link would hold its own 10.
    assert!(lens.iter().all(|&n| n <= 2), "{lens:?}");
    // Every packet offered is either queued or counted as a drop.
    assert_eq!(net.drops, 50 * 1000 - queued as u64);
    let counted: u64 = net.router.links().map(|l| l.queue().dropped()).sum();
    assert_eq!(counted, net.drops);
    // Sending frees the shared capacity again.
    net.drain("u:0");
    assert_eq!(queued_everywhere(&net).0, net.router.queued_bytes());
}

#[test]
fn shared_queue_capacity_keeps_higher_priorities() {
    // FILE_TRANSFER_PROTOCOL frames: 266 bytes + 32 in the queues' reckoning.
    let cost = 266 + 32;
    let options = RouterOptions {
        queue_capacity: 100 * cost,
        total_queue_capacity: 4 * cost,
        ..RouterOptions::default()
    };
    let mut net = Net::with_options(
        "chain default {\n    reject if HEARTBEAT;\n    accept with priority 5 if to 9.9;\n    accept;\n}\n",
        options,
    );
    net.heartbeat("slow", "9.9");
    net.heartbeat("other", "8.8");
    // Priority 0 packets for 8.8 fill the shared capacity...
    for _ in 0..4 {
        net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.1", Some("8.8"));
    }
    assert_eq!(net.router.queued_bytes(), 4 * cost);
    // ...priority 5 packets for 9.9 push them out, although it is another link...
    for _ in 0..4 {
        net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.1", Some("9.9"));
    }
    assert_eq!(net.router.queued_bytes(), 4 * cost);
    assert_eq!(net.drops, 4);
    // ...and a priority 0 packet finds no room above them: it is the one dropped.
    net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.1", Some("8.8"));
    assert_eq!(net.drops, 5);
    let slow = net.drain("slow");
    assert_eq!(slow.len(), 4, "{slow:?}");
    assert!(slow.iter().all(|p| p.contains("to 9.9")), "{slow:?}");
    assert_eq!(net.drain("other"), Vec::<String>::new());
    assert_eq!(net.router.queued_bytes(), 0);
}

/// When the shared capacity is full, other links' packets are dropped for room only for
/// a packet the link's own queue takes: one its full queue refuses anyway (full of
/// higher priorities) costs no other link anything.
#[test]
fn a_packet_its_own_full_queue_refuses_evicts_nothing_elsewhere() {
    // FILE_TRANSFER_PROTOCOL frames: 266 bytes + 32 in the queues' reckoning.
    let cost = 266 + 32;
    let options = RouterOptions {
        queue_capacity: 2 * cost,
        total_queue_capacity: 4 * cost,
        ..RouterOptions::default()
    };
    let mut net = Net::with_options(
        "chain default {\n    reject if HEARTBEAT;\n    accept with priority 5 if from 2.1 to 9.9;\n    accept;\n}\n",
        options,
    );
    net.heartbeat("a", "9.9");
    net.heartbeat("b", "8.8");
    for _ in 0..2 {
        net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.1", Some("9.9")); // a, priority 5
        net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.1", Some("8.8")); // b, priority 0
    }
    assert_eq!(net.router.queued_bytes(), 4 * cost);
    // For a, at priority 0: a's queue is full of priority 5, so it is dropped...
    net.send("sender", "FILE_TRANSFER_PROTOCOL", "2.2", Some("9.9"));
    assert_eq!(net.drops, 1);
    // ...and b keeps what it had.
    assert_eq!(net.drain("b").len(), 2);
    assert_eq!(net.drain("a").len(), 2);
}

/// A peer forging source addresses cannot make one link hold thousands of them: a
/// link keeps at most `MAX_ADDRESSES`, so what one broadcast costs in filter checks
/// for that link stays bounded.
#[test]
fn forged_sources_do_not_multiply_the_cost_of_each_broadcast() {
    let mut net = Net::new("chain default { reject if HEARTBEAT; accept; }");
    net.heartbeat("v:1", "1.1");
    for i in 0..20_000u32 {
        net.heartbeat("x:9", &format!("{}.{}", 2 + i / 256, i % 256));
    }
    let before = net.router.filter_stats();
    net.send("v:1", "ATTITUDE", "1.1", None);
    let after = net.router.filter_stats();
    let checks = after.hits + after.misses - before.hits - before.misses;
    let bound = mavtables::routing::MAX_ADDRESSES as u64 + 8;
    assert!(checks <= bound, "one broadcast cost {checks} filter checks");
}
