//! The routing core as the event loop drives it, on a simulated clock: pacing accuracy,
//! round-robin fairness between the peers of an interface, held-back bytes released when
//! the line goes quiet, link expiry, and the backoff for reopening a lost device. No
//! sockets, no sleeps: time is a value the test moves.

use crate::routing;

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::time::Duration;

use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, Notice, RouterOptions, Timestamp, Transmit};
use routing::frame;

fn engine(conf: &str) -> Engine {
    let config = config::load(conf).expect("config loads").config;
    Engine::new(&config, RouterOptions::default())
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

fn notices(e: &mut Engine) -> Vec<Notice> {
    std::iter::from_fn(|| e.poll_event()).collect()
}

fn warnings(e: &mut Engine) -> Vec<String> {
    notices(e)
        .into_iter()
        .filter_map(|n| match n {
            Notice::Warning(w) => Some(w),
            _ => None,
        })
        .collect()
}

/// Drives `iface` like the event loop: sends whatever the core hands out (calling
/// `sent` for each), sleeps until the core's next deadline, until `end`.
fn run_until(
    e: &mut Engine,
    iface: InterfaceId,
    start: Timestamp,
    end: Timestamp,
    mut sent: impl FnMut(Timestamp, &Transmit),
) {
    let mut now = start;
    let mut queue = VecDeque::new();
    loop {
        e.poll_transmit(iface, now, 64, &mut queue);
        for t in queue.drain(..) {
            e.on_sent(&t);
            sent(now, &t);
        }
        let next = e.poll_timeout();
        if next > end {
            return;
        }
        now = next.max(now);
        e.handle_timeout(now);
    }
}

const ACCEPT: &str = "chain default {\n    reject if HEARTBEAT;\n    accept;\n}\n";

/// An interface with listeners at ports 1..=`listeners` (systems 101…) and a sender at
/// port 100 (system 10) that has sent `backlog` ENCAPSULATED_DATA broadcasts at time 0.
fn backlog(max_bitrate: u64, listeners: u16, backlog: usize) -> (Engine, InterfaceId) {
    let mut e = engine(ACCEPT);
    let iface = e.add_datagram_interface("udp test".into(), max_bitrate, Default::default());
    for l in 1..=listeners {
        let hb = frame("HEARTBEAT", &format!("{}.1", 100 + l), None);
        e.handle_datagram(iface, peer(l), &hb, Timestamp::ZERO);
    }
    let data = frame("ENCAPSULATED_DATA", "10.1", None);
    for _ in 0..backlog {
        e.handle_datagram(iface, peer(100), &data, Timestamp::ZERO);
    }
    (e, iface)
}

#[test]
fn pacing_holds_max_bitrate_within_one_percent() {
    for rate in [65_536u64, 262_144, 1_000_000] {
        // 1,000 frames of 267 bytes for one listener: 2.1 Mbit.
        let (mut e, iface) = backlog(rate, 1, 1000);
        let mut sends: Vec<(Timestamp, usize)> = Vec::new();
        let end = Timestamp::from_secs(100);
        run_until(&mut e, iface, Timestamp::ZERO, end, |now, t| {
            sends.push((now, t.packet.len()))
        });
        assert_eq!(sends.len(), 1000, "rate {rate}");
        // Everything after the first frame went at the configured rate.
        let bits: usize = sends[1..].iter().map(|(_, len)| len * 8).sum();
        let span = sends[sends.len() - 1].0.saturating_since(sends[0].0);
        let measured = bits as f64 / span.as_secs_f64();
        let error = (measured - rate as f64).abs() / rate as f64;
        assert!(error < 0.01, "rate {rate}: measured {measured:.0} bit/s");
        // No burst beyond one largest frame plus the slack.
        let burst = sends.iter().filter(|(t, _)| *t == sends[0].0).count();
        assert!(burst <= 2, "rate {rate}: {burst} frames at once");
    }
}

#[test]
fn paced_peers_take_turns_one_packet_each() {
    // Three listeners, each owed the same 300 frames, behind 64 kbit/s.
    let (mut e, iface) = backlog(65_536, 3, 300);
    let mut order = Vec::new();
    run_until(
        &mut e,
        iface,
        Timestamp::ZERO,
        Timestamp::from_secs(3600),
        |_, t| order.push(t.to.expect("a peer").port()),
    );
    assert_eq!(order.len(), 900);
    // Strict rotation: whichever peer starts, every window of three has all three.
    for w in order.chunks(3) {
        let mut w = w.to_vec();
        w.sort_unstable();
        assert_eq!(w, [1, 2, 3], "{order:?}");
    }
}

#[test]
fn unpaced_peers_take_turns_in_runs() {
    let (mut e, iface) = backlog(0, 3, 100);
    let mut queue = VecDeque::new();
    e.poll_transmit(iface, Timestamp::ZERO, 64, &mut queue);
    let ports: Vec<u16> = queue.iter().map(|t| t.to.expect("a peer").port()).collect();
    // Runs of 16 per peer, in turn, within one batch of 64.
    let mut runs: Vec<(u16, usize)> = Vec::new();
    for p in ports {
        match runs.last_mut() {
            Some((q, n)) if *q == p => *n += 1,
            _ => runs.push((p, 1)),
        }
    }
    assert_eq!(runs, [(1, 16), (2, 16), (3, 16), (1, 16)]);
    // Over the whole backlog each peer gets exactly its 100.
    let mut per_peer = BTreeMap::new();
    for t in &queue {
        *per_peer.entry(t.to.expect("peer").port()).or_insert(0) += 1;
    }
    queue.clear();
    loop {
        e.poll_transmit(iface, Timestamp::ZERO, 64, &mut queue);
        if queue.is_empty() {
            break;
        }
        for t in queue.drain(..) {
            *per_peer.entry(t.to.expect("peer").port()).or_insert(0) += 1;
        }
    }
    assert_eq!(per_peer.into_values().collect::<Vec<_>>(), [100, 100, 100]);
}

/// Noise that looks like the start of a long frame, then a valid frame, in one datagram.
fn noise_then(frame: &[u8]) -> Vec<u8> {
    // 0xFE 0xFE … 0x6E: a v1 candidate for message 110 (254 payload bytes).
    let mut bytes = vec![0xfe, 0xfe, 0xfd, 0xfd, 0xfd, 0x6e];
    bytes.extend_from_slice(frame);
    bytes
}

fn learned(e: &mut Engine) -> Vec<String> {
    notices(e)
        .into_iter()
        .filter_map(|n| match n {
            Notice::Log(ev) => Some(ev.to_string()),
            _ => None,
        })
        .collect()
}

#[test]
fn held_back_bytes_are_released_when_a_datagram_peer_goes_quiet() {
    let mut e = engine(ACCEPT);
    let iface = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let t0 = Timestamp::from_secs(5);
    e.handle_timeout(t0);
    let hb = frame("HEARTBEAT", "7.1", None);
    e.handle_datagram(iface, peer(1), &noise_then(&hb), t0);
    assert!(learned(&mut e).is_empty(), "held back behind the candidate");
    let due = t0 + Duration::from_millis(100);
    assert_eq!(e.poll_timeout(), due);
    e.handle_timeout(t0 + Duration::from_micros(99_999));
    assert!(learned(&mut e).is_empty(), "not before the line is quiet");
    e.handle_timeout(due);
    assert_eq!(
        learned(&mut e)[..],
        [
            "new component 7.1 on 127.0.0.1:1",
            "received HEARTBEAT (#0) from 7.1 (v2.0) source 127.0.0.1:1"
        ]
    );
    assert_eq!(
        e.poll_timeout(),
        Timestamp::from_secs(6),
        "only the tick is left"
    );
}

#[test]
fn held_back_bytes_on_a_serial_line_wait_one_frame_time_more() {
    let mut e = engine(ACCEPT);
    let iface = e.add_stream_interface("/dev/ttyX", &[], Some(9600), 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    assert_eq!(notices(&mut e), [Notice::Open(iface)]);
    e.stream_opened(iface, Timestamp::ZERO);
    let t0 = Timestamp::from_millis(500);
    e.handle_stream(iface, &noise_then(&frame("HEARTBEAT", "7.1", None)), t0);
    // 100 ms plus a largest frame (280 bytes) at 9600 baud: 291.666 ms.
    let due = t0 + Duration::from_micros(391_666);
    assert_eq!(e.poll_timeout(), due);
    e.handle_timeout(due);
    assert_eq!(learned(&mut e)[0], "new component 7.1 on /dev/ttyX");
}

/// TCP loses nothing, so bytes held back for a frame wait as long as the connection
/// lasts: a frame whose second half comes 3 s after its first (a retransmission, a
/// cellular stall) arrives whole, on a TCP client and on an accepted connection alike.
#[test]
fn held_back_bytes_on_tcp_wait_for_the_rest_of_their_frame() {
    let mut e = engine(ACCEPT);
    let server = e.add_listener("tcp 127.0.0.1:5760".into(), limits(8, &[]), 0);
    let accepted = e
        .accept(server, peer(40000), Timestamp::ZERO)
        .expect("accepted");
    let client = e.add_stream_client("tcp 127.0.0.1:5761".into(), "tcp:x", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    e.stream_opened(client, Timestamp::ZERO);
    notices(&mut e);
    for (ifc, sys) in [(accepted, "7.1"), (client, "8.1")] {
        let hb = frame("HEARTBEAT", sys, None);
        let t0 = Timestamp::from_secs(1);
        e.handle_timeout(t0);
        let before = e.poll_timeout();
        e.handle_stream(ifc, &hb[..5], t0);
        assert_eq!(
            e.poll_timeout(),
            before,
            "no deadline for held-back TCP bytes"
        );
        e.handle_timeout(t0 + Duration::from_secs(3));
        assert!(
            learned(&mut e).is_empty(),
            "nothing judged while the rest is due"
        );
        e.handle_stream(ifc, &hb[5..], t0 + Duration::from_secs(3));
        let got = learned(&mut e);
        assert!(
            got.first()
                .is_some_and(|l| l.starts_with(&format!("new component {sys} on tcp"))),
            "{got:?}"
        );
    }
}

#[test]
fn a_silent_datagram_peer_is_removed_after_twice_the_expiry() {
    let mut e = engine(ACCEPT);
    let iface = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let hb = frame("HEARTBEAT", "7.1", None);
    e.handle_datagram(iface, peer(1), &hb, Timestamp::ZERO);
    let added = notices(&mut e);
    assert!(
        matches!(&added[..], [Notice::LinkAdded { name, .. }, ..] if name == "127.0.0.1:1"),
        "{added:?}"
    );
    // Ticks once a second: present up to 240 s after it was last heard, gone after.
    let mut removed_at = None;
    for s in 1..=245 {
        e.handle_timeout(Timestamp::from_secs(s));
        if notices(&mut e)
            .iter()
            .any(|n| matches!(n, Notice::LinkRemoved { name, .. } if name == "127.0.0.1:1"))
        {
            removed_at = Some(s);
            break;
        }
    }
    assert_eq!(removed_at, Some(241));
    assert_eq!(e.router().links().count(), 0);
    // The same peer speaking again is a new link.
    e.handle_datagram(iface, peer(1), &hb, Timestamp::from_secs(300));
    assert!(
        notices(&mut e)
            .iter()
            .any(|n| matches!(n, Notice::LinkAdded { .. }))
    );
}

#[test]
fn a_missing_device_is_retried_with_doubling_backoff_and_said_once() {
    let mut e = engine(ACCEPT);
    let iface = e.add_stream_interface("/dev/ttyX", &[], Some(57600), 0, Timestamp::ZERO);
    let mut attempts = Vec::new();
    let mut now = Timestamp::ZERO;
    let mut said = Vec::new();
    while now < Timestamp::from_secs(10) {
        e.handle_timeout(now);
        for n in notices(&mut e) {
            if n == Notice::Open(iface) {
                attempts.push(now.since_start().as_millis());
                e.stream_open_failed(iface, now, &"No such file or directory");
                said.extend(warnings(&mut e));
            }
        }
        now = e.poll_timeout();
    }
    // At once, then 100, 200, 400, 800, 1600 ms later, then every 2 s.
    assert_eq!(attempts, [0, 100, 300, 700, 1500, 3100, 5100, 7100, 9100]);
    assert_eq!(
        said,
        [
            "cannot open serial device /dev/ttyX: No such file or directory; retrying until it appears"
        ]
    );
    // Next attempt 2 s after the last one.
    let now = Timestamp::from_millis(11_100);
    e.handle_timeout(now);
    assert!(notices(&mut e).contains(&Notice::Open(iface)));
    e.stream_opened(iface, now);
    assert_eq!(warnings(&mut e), ["serial device /dev/ttyX is back"]);
    // Lost after it had stayed open: tried again after the first backoff.
    let lost = now + Duration::from_secs(3);
    e.stream_lost(iface, lost, &"end of file");
    assert_eq!(
        warnings(&mut e),
        ["serial device /dev/ttyX lost: end of file"]
    );
    e.handle_timeout(lost + Duration::from_millis(99));
    assert!(!notices(&mut e).contains(&Notice::Open(iface)));
    e.handle_timeout(lost + Duration::from_millis(100));
    assert!(notices(&mut e).contains(&Notice::Open(iface)));
}

#[test]
fn the_counters_report_every_link_and_interface() {
    let (mut e, iface) = backlog(0, 1, 3);
    run_until(
        &mut e,
        iface,
        Timestamp::ZERO,
        Timestamp::from_secs(1),
        |_, _| {},
    );
    let report = e.report();
    assert!(report.starts_with("mavtables counters:\n"), "{report}");
    assert!(
        report.contains("  127.0.0.1:1: in 1 frames (21 bytes), out 3 frames (801 bytes), dropped 0 (queue full) + 0 (send errors), queue high-water 897 bytes, 0 bad checksum"),
        "{report}"
    );
    assert!(
        report.contains("  udp test: 4 frames, 0 bad checksum"),
        "{report}"
    );
}

fn limits(max_peers: usize, allow: &[&str]) -> mavtables::config::PeerLimits {
    mavtables::config::PeerLimits {
        max_peers,
        allow: allow
            .iter()
            .map(|r| {
                let (ip, bits) = r.split_once('/').expect("a/n");
                mavtables::config::IpRange {
                    address: ip.parse().expect("ip"),
                    prefix: bits.parse().expect("bits"),
                }
            })
            .collect(),
    }
}

#[test]
fn accepted_connections_are_links_until_they_close_within_the_servers_limits() {
    let mut e = engine(ACCEPT);
    let server = e.add_listener("tcp test".into(), limits(2, &["127.0.0.0/8"]), 0);
    let now = Timestamp::ZERO;
    let a = e.accept(server, peer(1), now).expect("first");
    let b = e.accept(server, peer(2), now).expect("second");
    assert!(e.accept(server, peer(3), now).is_none(), "max_peers 2");
    let outside = SocketAddr::from(([10, 0, 0, 1], 9));
    assert!(e.accept(server, outside, now).is_none(), "not allowed");
    let said = notices(&mut e);
    let names: Vec<&str> = said
        .iter()
        .filter_map(|n| match n {
            Notice::LinkAdded { name, .. } => Some(name.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(names, ["tcp:127.0.0.1:1", "tcp:127.0.0.1:2"]);
    assert_eq!(
        said.iter()
            .filter(|n| matches!(n, Notice::Warning(_)))
            .count(),
        2,
        "each refusal reason said once: {said:?}"
    );
    // A frame of A cut in two reaches B (heartbeats only teach addresses here).
    e.handle_stream(a, &frame("HEARTBEAT", "7.1", None), now);
    e.handle_stream(b, &frame("HEARTBEAT", "8.1", None), now);
    let att = frame("ATTITUDE", "7.1", None);
    e.handle_stream(a, &att[..5], now);
    e.handle_stream(a, &att[5..], now);
    let mut queue = VecDeque::new();
    e.poll_transmit(b, now, 10, &mut queue);
    let at_b: Vec<Vec<u8>> = queue.drain(..).map(|t| t.packet.to_vec()).collect();
    assert_eq!(at_b, [att]);
    // A closes: its interface and link go; a new connection fits again.
    notices(&mut e);
    e.stream_lost(a, now, &"end of stream");
    let gone = notices(&mut e);
    assert!(gone.contains(&Notice::Closed(a)), "{gone:?}");
    assert!(
        gone.iter()
            .any(|n| matches!(n, Notice::LinkRemoved { name, .. } if name == "tcp:127.0.0.1:1"))
    );
    assert_eq!(e.router().links().count(), 1);
    assert!(e.accept(server, peer(4), now).is_some());
    // The closed connection's frames are still counted, on the server's line.
    assert!(
        e.report().contains("  tcp test: 2 frames,"),
        "{}",
        e.report()
    );
}

#[test]
fn a_tcp_client_reconnects_at_once_and_forgets_what_went_stale() {
    let mut e = engine(ACCEPT);
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let client = e.add_stream_client("tcp connect x".into(), "tcp:x", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    assert!(notices(&mut e).contains(&Notice::Open(client)));
    e.stream_opened(client, Timestamp::ZERO);
    let send = |e: &mut Engine, at: Timestamp| {
        e.handle_datagram(udp, peer(1), &frame("ATTITUDE", "7.1", None), at);
    };
    let queued = |e: &mut Engine, at: Timestamp| {
        let mut q = VecDeque::new();
        e.poll_transmit(client, at, 100, &mut q);
        q.len()
    };
    // Before it learned any address, the client's link takes broadcasts.
    send(&mut e, Timestamp::ZERO);
    assert_eq!(queued(&mut e, Timestamp::ZERO), 1);
    // Lost: tried again at once; what arrives meanwhile waits, and a short outage keeps it.
    let t = Timestamp::from_secs(5);
    e.stream_lost(client, t, &"reset");
    e.handle_timeout(t);
    assert!(notices(&mut e).contains(&Notice::Open(client)));
    send(&mut e, t);
    e.stream_opened(client, t + Duration::from_secs(1));
    assert_eq!(queued(&mut e, t + Duration::from_secs(1)), 1);
    // A long outage: what was queued is stale and dropped when it comes back.
    let t = Timestamp::from_secs(10);
    e.stream_lost(client, t, &"reset");
    send(&mut e, t);
    e.stream_opened(client, t + Duration::from_secs(3));
    assert_eq!(queued(&mut e, t + Duration::from_secs(3)), 0);
}

#[test]
fn a_udp_client_holds_its_packets_until_it_knows_where_to_send() {
    let mut e = engine(ACCEPT);
    let server = e.add_datagram_interface("udp server".into(), 0, Default::default());
    let client = e.add_datagram_client("udp connect gcs".into(), "gcs:14550", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    e.stream_opened(client, Timestamp::ZERO);
    e.handle_datagram(
        server,
        peer(1),
        &frame("ATTITUDE", "1.1", None),
        Timestamp::ZERO,
    );
    let mut q = VecDeque::new();
    e.poll_transmit(client, Timestamp::ZERO, 10, &mut q);
    assert!(q.is_empty(), "no target yet");
    let gcs = SocketAddr::from(([192, 168, 1, 255], 14550));
    e.set_target(client, gcs);
    e.poll_transmit(client, Timestamp::ZERO, 10, &mut q);
    assert_eq!(q.len(), 1);
    assert_eq!(q[0].to, Some(gcs));
    // Whatever comes back, from any station, is that one link's.
    e.handle_datagram(
        client,
        SocketAddr::from(([192, 168, 1, 7], 14550)),
        &frame("HEARTBEAT", "255.190", None),
        Timestamp::ZERO,
    );
    e.handle_datagram(
        client,
        SocketAddr::from(([192, 168, 1, 8], 14550)),
        &frame("HEARTBEAT", "255.191", None),
        Timestamp::ZERO,
    );
    let link = e.stream_link(client).expect("a link");
    let pool = e.router().link(link).expect("link").pool().clone();
    assert_eq!(pool.addresses(Timestamp::ZERO).count(), 2);
}

#[test]
fn a_tcp_client_tries_at_once_then_at_most_every_second() {
    let mut e = engine(ACCEPT);
    let client = e.add_stream_client("tcp connect x".into(), "tcp:x", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    notices(&mut e);
    e.stream_opened(client, Timestamp::ZERO);
    let lost = Timestamp::from_secs(10);
    e.stream_lost(client, lost, &"reset");
    let mut attempts = Vec::new();
    let mut now = lost;
    while now < lost + Duration::from_secs(5) {
        e.handle_timeout(now);
        if notices(&mut e).contains(&Notice::Open(client)) {
            attempts.push(now.saturating_since(lost).as_millis());
            e.stream_open_failed(client, now, &"connection refused");
        }
        now = e.poll_timeout();
    }
    assert_eq!(attempts, [0, 200, 600, 1400, 2400, 3400, 4400]);
}

/// A datagram from port 0 cannot be answered (sending to port 0 fails): its sender is
/// refused, counted as not allowed, and said once, never made a link.
#[test]
fn a_remote_sending_from_port_0_never_becomes_a_link() {
    let mut e = engine(ACCEPT);
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let nowhere = SocketAddr::from(([127, 0, 0, 1], 0));
    for _ in 0..3 {
        e.handle_datagram(
            udp,
            nowhere,
            &frame("HEARTBEAT", "7.1", None),
            Timestamp::ZERO,
        );
    }
    assert_eq!(e.router().links().count(), 0);
    let said = warnings(&mut e);
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(said[0].contains("sent from port 0"), "{said:?}");
    assert!(
        e.report().contains("3 refused (not allowed)"),
        "{}",
        e.report()
    );
}

/// A TCP client that has not connected yet is down from the start: what was queued for
/// it longer than the limit is stale when it first connects, as after a loss.
#[test]
fn a_tcp_client_that_was_never_up_forgets_what_went_stale() {
    let mut e = engine(ACCEPT);
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let client = e.add_stream_client("tcp connect x".into(), "tcp:x", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    e.stream_open_failed(client, Timestamp::ZERO, &"connection refused");
    let queued = |e: &mut Engine, at: Timestamp| {
        let mut q = VecDeque::new();
        e.poll_transmit(client, at, 100, &mut q);
        q.len()
    };
    e.handle_datagram(
        udp,
        peer(1),
        &frame("ATTITUDE", "7.1", None),
        Timestamp::from_secs(1),
    );
    let later = Timestamp::from_secs(60);
    e.stream_opened(client, later);
    assert_eq!(
        queued(&mut e, later),
        0,
        "59 s old telemetry sent on first connect"
    );
    // One that connects soon after the start keeps what was queued meanwhile.
    let mut e = engine(ACCEPT);
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let client = e.add_stream_client("tcp connect x".into(), "tcp:x", 0, Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    e.handle_datagram(
        udp,
        peer(1),
        &frame("ATTITUDE", "7.1", None),
        Timestamp::ZERO,
    );
    let soon = Timestamp::from_millis(100);
    e.stream_opened(client, soon);
    let mut q = VecDeque::new();
    e.poll_transmit(client, soon, 100, &mut q);
    assert_eq!(q.len(), 1);
}
