//! `accept with rate N/UNIT` in the routing core, on a simulated clock: a minute of
//! 50 Hz ATTITUDE from three vehicles through a 2/s cap towards a satellite ground
//! station, exact to the frame; memo or not; the most generous of several accepting
//! rules; caps inside called chains; reload and counts.

use crate::routing;

use std::collections::BTreeMap;
use std::time::Duration;

use mavtables::address::Address;
use mavtables::routing::{RouterOptions, Timestamp};
use mavtables::wire::Frame;
use routing::{Net, frame};

const ATTITUDE: u32 = 30;

/// ATTITUDE to the satellite station (254.x) at most 2 a second; everything else as is.
const SATCOM: &str = "chain default {
    accept with rate 2/s if ATTITUDE to 254.0/8;
    accept;
}";

/// Pops everything queued on `link`: (source, message id) per frame.
fn pop_all(net: &mut Net, link: &str) -> Vec<(Address, u32)> {
    let id = net.links[link];
    std::iter::from_fn(|| net.router.pop(id))
        .map(|p| {
            let f = Frame::parse_exact(&p).expect("a frame");
            (f.source(), f.message_id())
        })
        .collect()
}

fn net_with(conf: &str, options: RouterOptions) -> Net {
    let mut net = Net::with_options(conf, options);
    net.heartbeat("sat", "254.190");
    net.heartbeat("lan", "255.190");
    for v in 1..=3 {
        net.heartbeat(&format!("v{v}"), &format!("{v}.1"));
    }
    for l in ["sat", "lan", "v1", "v2", "v3"] {
        pop_all(&mut net, l);
    }
    net
}

/// One simulated minute: each vehicle sends ATTITUDE at 50 Hz (phases 0, 7 and 13 ms)
/// and GPS_RAW_INT at 5 Hz. Returns, per vehicle system, the times (ms) at which its
/// ATTITUDE reached the satellite link, and the frames the LAN station got.
fn one_minute(net: &mut Net) -> (BTreeMap<u8, Vec<u64>>, usize) {
    let phases = [0u64, 7, 13];
    let attitude: Vec<Vec<u8>> = (1..=3)
        .map(|v| frame("ATTITUDE", &format!("{v}.1"), None))
        .collect();
    let gps: Vec<Vec<u8>> = (1..=3)
        .map(|v| frame("GPS_RAW_INT", &format!("{v}.1"), None))
        .collect();
    let mut at_sat: BTreeMap<u8, Vec<u64>> = BTreeMap::new();
    let mut gps_at_sat = 0;
    let mut lan = 0;
    let start = net.now;
    for ms in 0..60_000u64 {
        net.now = start + Duration::from_millis(ms);
        for (v, phase) in phases.iter().enumerate() {
            if ms % 20 == *phase {
                net.recv(&format!("v{}", v + 1), &attitude[v]);
            }
            if ms % 200 == *phase {
                net.recv(&format!("v{}", v + 1), &gps[v]);
            }
        }
        for (src, id) in pop_all(net, "sat") {
            if id == ATTITUDE {
                at_sat.entry(src.system).or_default().push(ms);
            } else {
                gps_at_sat += 1;
            }
        }
        lan += pop_all(net, "lan").len();
    }
    assert_eq!(gps_at_sat, 3 * 300, "uncapped messages pass as they are");
    (at_sat, lan)
}

#[test]
fn a_minute_at_50_hz_gives_exactly_2_per_second_per_vehicle() {
    for slots in [mavtables::filter::cache::DEFAULT_SLOTS, 0] {
        let options = RouterOptions {
            cache_slots: slots,
            ..RouterOptions::default()
        };
        let mut net = net_with(SATCOM, options);
        let (at_sat, lan) = one_minute(&mut net);
        assert_eq!(lan, 3 * (3000 + 300), "the LAN station gets everything");
        assert_eq!(at_sat.len(), 3);
        for (system, times) in &at_sat {
            // 2.00 per second over 60 s, to the frame; the first at once.
            assert_eq!(times.len(), 120, "vehicle {system} (memo slots {slots})");
            assert!(times[0] <= 13, "the first passes at once");
            // Evenly spaced: one every 500 ms on the dot (the input is on a 20 ms grid).
            for w in times.windows(2) {
                assert_eq!(w[1] - w[0], 500, "vehicle {system}: {w:?}");
            }
        }
        let counts = net.router.filter_counts();
        assert_eq!(counts.rules[0].decided, 3 * 3000);
        assert_eq!(counts.rules[0].rate_limited, 3 * (3000 - 120));
        assert_eq!(counts.rules[1].rate_limited, 0);
    }
}

#[test]
fn an_uncapped_accepting_rule_for_another_address_on_the_link_wins() {
    // The satellite link also reaches 10.1 (a relay), which takes ATTITUDE uncapped.
    let mut net = net_with(SATCOM, RouterOptions::default());
    net.heartbeat("sat", "10.1");
    pop_all(&mut net, "lan");
    for ms in 0..1000 {
        net.now = Timestamp::from_millis(10_000 + ms * 20);
        net.send("v1", "ATTITUDE", "1.1", None);
    }
    assert_eq!(pop_all(&mut net, "sat").len(), 1000);
    assert_eq!(net.router.filter_counts().rules[0].rate_limited, 0);
}

#[test]
fn of_two_capped_rules_for_addresses_on_one_link_the_more_generous_holds_and_counts() {
    // The satellite link also reaches 10.1, which takes ATTITUDE at 4/s: a broadcast
    // goes to the link at 4/s, whichever address the filter tries first.
    let conf = "chain default {
        accept with rate 1/s if ATTITUDE to 254.190;
        accept with rate 4/s if ATTITUDE to 10.1;
        accept;
    }";
    let mut net = net_with(conf, RouterOptions::default());
    net.heartbeat("sat", "10.1");
    pop_all(&mut net, "lan");
    for k in 0..500 {
        net.now = Timestamp::from_millis(10_000 + k * 20);
        net.send("v1", "ATTITUDE", "1.1", None);
    }
    assert_eq!(pop_all(&mut net, "sat").len(), 40, "4/s over 10 s");
    assert_eq!(pop_all(&mut net, "lan").len(), 500);
    let counts = net.router.filter_counts();
    assert_eq!(counts.rules[0].rate_limited, 0);
    assert_eq!(counts.rules[1].rate_limited, 460);
}

#[test]
fn caps_hold_inside_called_chains_and_with_priorities_in_either_order() {
    let conf = "chain default {
        call sat if to 254.0/8;
        accept with rate 1/s with priority 2 if HEARTBEAT;
        accept;
    }
    chain sat {
        accept with priority 3 with rate 10/min if ATTITUDE;
    }";
    let mut net = net_with(conf, RouterOptions::default());
    for k in 0..600u64 {
        net.now = Timestamp::from_millis(5_000 + k * 100);
        net.send("v1", "ATTITUDE", "1.1", None);
        net.send("v1", "HEARTBEAT", "1.1", None);
    }
    let sat = pop_all(&mut net, "sat");
    let attitude = sat.iter().filter(|(_, id)| *id == ATTITUDE).count();
    let heartbeat = sat.iter().filter(|(_, id)| *id == 0).count();
    assert_eq!(attitude, 10, "10/min over 60 s");
    assert_eq!(heartbeat, 60, "1/s over 60 s");
    // The LAN station is capped for HEARTBEAT only (as are the other vehicles).
    let lan = pop_all(&mut net, "lan");
    assert_eq!(lan.iter().filter(|(_, id)| *id == ATTITUDE).count(), 600);
    assert_eq!(lan.iter().filter(|(_, id)| *id == 0).count(), 60);
    let counts = net.router.filter_counts();
    assert_eq!(counts.rules[3].rate_limited, 590);
    assert_eq!(counts.rules[1].rate_limited, 4 * 540);
}

#[test]
fn streams_are_per_destination_link_source_and_message() {
    let conf = "chain default { accept with rate 1/s; }";
    let mut net = net_with(conf, RouterOptions::default());
    net.now = Timestamp::from_secs(10);
    for name in ["ATTITUDE", "GPS_RAW_INT"] {
        for v in ["1.1", "1.2"] {
            net.send("v1", name, v, None);
            net.send("v1", name, v, None);
        }
    }
    // Each (source, message) passes once, to every other link; the repeat is dropped.
    for link in ["sat", "lan", "v2", "v3"] {
        assert_eq!(pop_all(&mut net, link).len(), 4, "{link}");
    }
    net.now = Timestamp::from_millis(11_000);
    net.send("v1", "ATTITUDE", "1.1", None);
    assert_eq!(
        pop_all(&mut net, "sat").len(),
        1,
        "a second later it passes again"
    );
}

#[test]
fn a_reload_keeps_the_schedules_unless_the_rates_changed() {
    let mut net = net_with(SATCOM, RouterOptions::default());
    net.now = Timestamp::from_secs(10);
    net.send("v1", "ATTITUDE", "1.1", None);
    net.send("v1", "ATTITUDE", "1.1", None);
    assert_eq!(pop_all(&mut net, "sat").len(), 1);
    let reload = |net: &mut Net, conf: &str| {
        let config = mavtables::config::load(conf).expect("loads").config;
        let counts = net.router.filter_counts();
        net.router.replace_filter(&config, &counts);
    };
    // Another rule, the same rate: the stream still waits out its half second.
    let more = SATCOM.replace("    accept;", "    reject if PING;\n    accept;");
    reload(&mut net, &more);
    net.send("v1", "ATTITUDE", "1.1", None);
    assert_eq!(pop_all(&mut net, "sat").len(), 0);
    assert_eq!(net.router.filter_counts().rules[0].rate_limited, 2);
    // A new rate: every stream starts afresh.
    reload(&mut net, &more.replace("2/s", "4/s"));
    net.send("v1", "ATTITUDE", "1.1", None);
    assert_eq!(pop_all(&mut net, "sat").len(), 1);
    // (The counts were handed over as they were: none was added.)
    assert_eq!(net.router.filter_counts().rules[0].rate_limited, 2);
}
