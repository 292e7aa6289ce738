//! Who has work, on a simulated clock: the core names exactly the interfaces with
//! output to hand out ([`Engine::poll_ready`]), so that the event loop flushes only
//! those, and idle interfaces — a thousand accepted TCP connections that send nothing —
//! are never named, not by a frame for someone else, nor by a timeout.

use crate::routing;

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Duration;

use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, RouterOptions, Timestamp, Transmit};
use routing::frame;

const ACCEPT_ALL: &str = "chain default {\n    accept;\n}\n";

fn engine() -> Engine {
    let config = config::load(ACCEPT_ALL).expect("config loads").config;
    Engine::new(&config, RouterOptions::default())
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// Everything [`Engine::poll_ready`] names now, in order.
fn ready(e: &mut Engine) -> Vec<InterfaceId> {
    std::iter::from_fn(|| e.poll_ready()).collect()
}

/// Sends what `id` hands out now, like a driver that is never refused.
fn flush(e: &mut Engine, id: InterfaceId, now: Timestamp) -> Vec<Transmit> {
    let mut queue = VecDeque::new();
    let mut sent = Vec::new();
    loop {
        e.poll_transmit(id, now, 8, &mut queue);
        if queue.is_empty() {
            return sent;
        }
        sent.extend(queue.iter().cloned());
        e.on_sent_batch(queue.drain(..));
    }
}

fn limits() -> mavtables::config::PeerLimits {
    mavtables::config::PeerLimits {
        max_peers: 2000,
        allow: Vec::new(),
    }
}

#[test]
fn only_interfaces_with_output_are_named_and_idle_connections_never() {
    let mut e = engine();
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let server = e.add_listener("tcp test".into(), limits(), 0);
    let now = Timestamp::ZERO;
    let connections: Vec<InterfaceId> = (0..1000u16)
        .map(|n| e.accept(server, peer(20_000 + n), now).expect("accepted"))
        .collect();
    // Connection n is system 1 + n / 100, component 1 + n % 100 (each one address).
    for (n, &c) in connections.iter().enumerate() {
        let hb = frame(
            "HEARTBEAT",
            &format!("{}.{}", 1 + n / 100, 1 + n % 100),
            None,
        );
        e.handle_stream(c, &hb, now);
    }
    // Their heartbeats go to each other: every connection has output once.
    let named = ready(&mut e);
    assert_eq!(named.len(), 1000);
    for &c in &connections {
        flush(&mut e, c, now);
    }
    assert_eq!(ready(&mut e), [], "flushed: nothing left to name");

    // A vehicle on the UDP side sends a command to one component of one connection.
    let vehicle = peer(14550);
    let now = Timestamp::from_secs(1);
    let hb = frame("HEARTBEAT", "200.1", None);
    e.handle_datagram(udp, vehicle, &hb, now);
    assert_eq!(
        ready(&mut e).len(),
        1000,
        "a broadcast names every connection"
    );
    for &c in &connections {
        flush(&mut e, c, now);
    }
    for _ in 0..3 {
        let command = frame("COMMAND_LONG", "200.1", Some("5.43"));
        e.handle_datagram(udp, vehicle, &command, now);
    }
    // System 5 is behind connections 400–499 (the router sends a command to every link
    // of its system): those are named, once each for three packets, and no other.
    let named = ready(&mut e);
    assert_eq!(named, connections[400..500], "named once each, in order");
    for (n, &c) in connections.iter().enumerate() {
        let sent = flush(&mut e, c, now).len();
        let want = if (400..500).contains(&n) { 3 } else { 0 };
        assert_eq!(
            sent, want,
            "connection {n}: exactly the named ones have output"
        );
    }
    assert_eq!(ready(&mut e), []);
    let target = connections[442];
    // Its answer goes to the vehicle's link on the UDP interface, and only there.
    let ack = frame("COMMAND_ACK", "5.43", Some("200.1"));
    e.handle_stream(target, &ack, now);
    assert_eq!(ready(&mut e), [udp]);
    let sent = flush(&mut e, udp, now);
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].to, Some(vehicle));

    // Time passes: the one-second ticks name nobody, and no connection has a deadline
    // (the next one is the tick).
    for s in 1..5 {
        let now = Timestamp::from_secs(s);
        assert_eq!(e.poll_timeout(), now, "only the tick is due");
        e.handle_timeout(now);
        assert_eq!(ready(&mut e), [], "a timeout names no idle interface");
    }
    // A timeout handled early, or twice, does nothing.
    let early = Timestamp::from_secs(4) + Duration::from_millis(10);
    e.handle_timeout(early);
    e.handle_timeout(early);
    assert_eq!(ready(&mut e), []);
    assert_eq!(e.poll_timeout(), Timestamp::from_secs(5));
}

#[test]
fn a_paced_interface_is_named_again_when_its_pacer_lets_the_next_packet_go() {
    let mut e = engine();
    // 24 kbit/s: once the burst is spent, a COMMAND_LONG every few milliseconds.
    let udp = e.add_datagram_interface("udp paced".into(), 24_000, Default::default());
    let other = e.add_datagram_interface("udp other".into(), 0, Default::default());
    let now = Timestamp::ZERO;
    e.handle_datagram(udp, peer(1), &frame("HEARTBEAT", "101.1", None), now);
    assert_eq!(ready(&mut e), [], "nobody to send to yet");
    for _ in 0..20 {
        let command = frame("COMMAND_LONG", "1.1", Some("101.1"));
        e.handle_datagram(other, peer(2), &command, now);
    }
    assert_eq!(ready(&mut e), [udp]);
    let first = flush(&mut e, udp, now).len();
    assert!(
        (1..20).contains(&first),
        "the pacer holds some back: {first}"
    );
    assert_eq!(
        ready(&mut e),
        [],
        "held back: not named until the pacer allows"
    );
    let due = e.poll_timeout();
    assert!(
        due > now && due < Timestamp::from_secs(1),
        "pace deadline {due:?}"
    );
    let mut sent = first;
    let mut now = now;
    while sent < 20 {
        let due = e.poll_timeout();
        assert!(due < Timestamp::from_secs(1), "a pace deadline each time");
        // Early: nothing is named.
        e.handle_timeout(now);
        assert_eq!(ready(&mut e), []);
        now = due;
        e.handle_timeout(now);
        assert_eq!(ready(&mut e), [udp], "named when the pacer lets one go");
        let n = flush(&mut e, udp, now).len();
        assert!(n >= 1);
        sent += n;
    }
    assert_eq!(
        e.poll_timeout(),
        Timestamp::from_secs(1),
        "only the tick left"
    );
    assert_eq!(ready(&mut e), []);
}

#[test]
fn a_client_is_named_when_it_opens_with_packets_waiting() {
    let mut e = engine();
    let udp = e.add_datagram_interface("udp test".into(), 0, Default::default());
    let now = Timestamp::ZERO;
    let client = e.add_stream_client("tcp connect x:1".into(), "x:1", 0, now);
    // Opening is due at once.
    assert_eq!(e.poll_timeout(), now);
    e.handle_timeout(now);
    e.handle_datagram(udp, peer(1), &frame("HEARTBEAT", "1.1", None), now);
    assert_eq!(ready(&mut e), [client], "queued while it is not open yet");
    assert!(
        flush(&mut e, client, now).is_empty(),
        "closed: nothing goes"
    );
    assert_eq!(ready(&mut e), []);
    let later = Timestamp::from_millis(500);
    e.stream_opened(client, later);
    assert_eq!(ready(&mut e), [client], "opened: named for what waits");
    assert_eq!(flush(&mut e, client, later).len(), 1);
}
