//! A reload that removes or reopens an interface, in the core on a simulated clock: the
//! interface leaves routing at once (no new packet goes there, nothing it receives is
//! routed) but sends what was queued for it first, and is closed once that is sent or a
//! second after the reload, whichever comes first, what is left dropped and said.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Duration;

use crate::routing;

use mavtables::config;
use mavtables::routing::{
    CLOSE_FLUSH, Engine, InterfaceId, Notice, Request, RouterOptions, Timestamp,
};

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

const BOTH: &str = "udp { port 14550; }\nudp { port 14560; }\ndefault_action accept;\n";
const FIRST: &str = "udp { port 14550; }\ndefault_action accept;\n";

fn load(conf: &str) -> config::Config {
    config::load(conf).expect("config loads").config
}

/// A core running `conf` (its interfaces without keys) and the two interfaces it has.
fn start_two(conf: &str) -> (Engine, InterfaceId, InterfaceId) {
    let config = load(conf);
    let mut e = Engine::new(&config, RouterOptions::default());
    let done = e.configure(&config, &[None, None], Timestamp::ZERO);
    let [first, second] = opened(&done.requests)[..] else {
        panic!("two interfaces: {:?}", done.requests);
    };
    (e, first, second)
}

/// The interfaces `requests` opens, in order.
fn opened(requests: &[Request]) -> Vec<InterfaceId> {
    requests
        .iter()
        .filter_map(|r| match r {
            Request::Open(id, _) => Some(*id),
            _ => None,
        })
        .collect()
}

/// `from` says a heartbeat on interface `iface`, from peer port `port` (the core learns
/// it there).
fn hello(e: &mut Engine, iface: InterfaceId, port: u16, from: &str, now: Timestamp) {
    e.handle_datagram(
        iface,
        peer(port),
        &routing::frame("HEARTBEAT", from, None),
        now,
    );
}

/// The bytes interface `iface` sends at `now`.
fn sent(e: &mut Engine, iface: InterfaceId, now: Timestamp) -> Vec<Vec<u8>> {
    let mut queue = VecDeque::new();
    e.poll_transmit(iface, now, 1024, &mut queue);
    let frames = queue.iter().map(|t| t.packet.to_vec()).collect();
    e.on_sent_batch(queue);
    frames
}

fn notices(e: &mut Engine) -> Vec<Notice> {
    std::iter::from_fn(|| e.poll_event()).collect()
}

/// A core running [`BOTH`]: a vehicle (1.1) behind the first interface, a ground
/// station (255.190) behind the second, and five frames of the vehicle queued for the
/// ground station, not sent yet. Returns the core, both interfaces and the frames.
fn five_queued() -> (Engine, InterfaceId, InterfaceId, Vec<Vec<u8>>) {
    let (mut e, vehicle, gcs) = start_two(BOTH);
    let now = Timestamp::from_secs(1);
    hello(&mut e, gcs, 2, "255.190", now);
    hello(&mut e, vehicle, 1, "1.1", now);
    sent(&mut e, vehicle, now);
    sent(&mut e, gcs, now);
    let frames: Vec<Vec<u8>> = (0..5)
        .map(|n| routing::frame_seq("ATTITUDE", "1.1", None, n))
        .collect();
    for f in &frames {
        e.handle_datagram(vehicle, peer(1), f, now);
    }
    notices(&mut e);
    (e, vehicle, gcs, frames)
}

#[test]
fn a_removed_interface_sends_its_queue_then_closes() {
    let (mut e, vehicle, gcs, frames) = five_queued();
    let now = Timestamp::from_secs(2);
    let done = e.configure(&load(FIRST), &[None], now);
    assert_eq!(done.requests, [Request::Retire(gcs)]);
    assert_eq!(done.removed, 1);
    assert_eq!(done.dropped, 0);
    assert!(
        done.details[0].ends_with("removed (closed once its 5 queued frames are sent)"),
        "{:?}",
        done.details
    );
    assert!(e.is_retiring(gcs));
    assert!(e.poll_timeout() <= now + CLOSE_FLUSH);
    let shown: Vec<String> = (e.stats(now).interfaces.into_iter())
        .map(|i| i.label)
        .collect();
    assert_eq!(
        shown,
        ["udp 0.0.0.0:14550"],
        "the statistics show what runs"
    );

    // Out of routing: a new frame of the vehicle is not queued for it, and what it
    // receives is not routed.
    e.handle_datagram(
        vehicle,
        peer(1),
        &routing::frame_seq("ATTITUDE", "1.1", None, 9),
        now,
    );
    e.handle_datagram(gcs, peer(2), &routing::frame("PING", "255.190", None), now);
    assert!(
        sent(&mut e, vehicle, now).is_empty(),
        "routed from a removed one"
    );

    // Still open until its queue is out: exactly the five frames, then it closes.
    e.close_if_drained(gcs);
    assert!(e.is_retiring(gcs), "closed with frames still queued");
    assert_eq!(sent(&mut e, gcs, now), frames);
    e.close_if_drained(gcs);
    assert!(!e.is_retiring(gcs));
    assert!(e.interface(gcs).is_none());
    let said = notices(&mut e);
    assert!(said.contains(&Notice::Closed(gcs)), "{said:?}");
    assert!(
        !said.iter().any(|n| matches!(n, Notice::Warning(_))),
        "{said:?}"
    );
    // The ground station's link is gone from the router.
    assert!(e.router().links().all(|l| l.name() != "127.0.0.1:2"));
}

#[test]
fn what_is_not_sent_within_a_second_is_dropped_and_said() {
    let (mut e, _, gcs, _) = five_queued();
    let now = Timestamp::from_secs(2);
    e.configure(&load(FIRST), &[None], now);
    notices(&mut e);
    // Its driver cannot send (say, a full socket): the time runs out.
    e.handle_timeout(now + (CLOSE_FLUSH - Duration::from_millis(1)));
    assert!(e.is_retiring(gcs), "closed before its time");
    let due = e.poll_timeout();
    assert_eq!(due, now + CLOSE_FLUSH);
    e.handle_timeout(due);
    assert!(!e.is_retiring(gcs));
    let said = notices(&mut e);
    assert!(said.contains(&Notice::Closed(gcs)), "{said:?}");
    assert!(
        said.contains(&Notice::Warning(
            "udp 0.0.0.0:14560 closed: 5 queued frames dropped".into()
        )),
        "{said:?}"
    );
    assert_eq!(
        e.router().queued_bytes(),
        0,
        "the dropped frames' bytes are freed"
    );
}

#[test]
fn a_reopened_interface_retires_the_old_socket_and_opens_a_new_one() {
    let (mut e, _, gcs, frames) = five_queued();
    let now = Timestamp::from_secs(2);
    // Another setting of the socket (the address written out): reopened.
    let reopened = "udp { port 14550; }\nudp { port 14560; address 0.0.0.0; }\n\
                    default_action accept;\n";
    let done = e.configure(&load(reopened), &[None, None], now);
    let [Request::Retire(old), Request::Open(new, _)] = done.requests[..] else {
        panic!("{:?}", done.requests);
    };
    assert_eq!(old, gcs);
    assert_ne!(new, gcs, "the new interface has a number of its own");
    assert_eq!(done.changed, 1);
    // The loop's driver cannot bind while the old socket holds the port: it closes the
    // old one at once, what it had queued dropped.
    e.close_retiring(gcs);
    assert!(e.interface(gcs).is_none());
    let said = notices(&mut e);
    assert!(said.contains(&Notice::Closed(gcs)), "{said:?}");
    assert!(
        said.iter().any(|n| matches!(n, Notice::Warning(w)
            if w.ends_with(&format!("closed: {} queued frames dropped", frames.len())))),
        "{said:?}"
    );
    assert!(e.interface(new).is_some());
}

#[test]
fn a_stream_that_is_down_closes_at_once() {
    let (mut e, _, client) =
        start_two("udp { port 14550; }\ntcp { connect 127.0.0.1:1; }\ndefault_action accept;\n");
    let done = e.configure(&load(FIRST), &[None], Timestamp::from_secs(1));
    assert_eq!(done.requests, [Request::Close(client)]);
    assert!(e.interface(client).is_none());
}

#[test]
fn a_removed_servers_connections_send_their_queue_and_stay_apart_from_a_new_server() {
    let (mut e, vehicle, server) =
        start_two("udp { port 14550; }\ntcp { port 5760; }\ndefault_action accept;\n");
    let now = Timestamp::from_secs(1);
    let conn = e.accept(server, peer(9), now).expect("accepted");
    let frame = routing::frame("ATTITUDE", "1.1", None);
    e.handle_datagram(vehicle, peer(1), &frame, now);
    notices(&mut e);

    let moved = "udp { port 14550; }\ntcp { port 5761; }\ndefault_action accept;\n";
    let done = e.configure(&load(moved), &[None, None], now);
    let [
        Request::Close(closed),
        Request::Retire(retiring),
        Request::Open(new_server, _),
    ] = done.requests[..]
    else {
        panic!("{:?}", done.requests);
    };
    assert_eq!((closed, retiring), (server, conn));
    // The new server has the old one's number: the retiring connection is not one of
    // its connections.
    assert_eq!(new_server, server);
    let done = e.configure(
        &load("udp { port 14550; }\ndefault_action accept;\n"),
        &[None],
        now,
    );
    assert_eq!(done.requests, [Request::Close(new_server)]);
    assert!(e.is_retiring(conn));
    assert!(e.interface(new_server).is_none());
    assert_eq!(sent(&mut e, conn, now), [frame]);
    e.close_if_drained(conn);
    assert!(notices(&mut e).contains(&Notice::Closed(conn)));
}

#[test]
fn a_reopened_serial_port_closes_at_once() {
    let serial = |baud: u32| {
        format!(
            "udp {{ port 14550; }}\nserial {{ device /dev/ttyFAKE0; baudrate {baud}; }}\n\
             default_action accept;\n"
        )
    };
    // Serial links are offered packets first: the port is the first interface.
    let (mut e, port, vehicle) = start_two(&serial(57600));
    let now = Timestamp::from_secs(1);
    e.stream_opened(port, now);
    e.handle_stream(port, &routing::frame("HEARTBEAT", "255.190", None), now);
    e.handle_datagram(
        vehicle,
        peer(1),
        &routing::frame("ATTITUDE", "1.1", None),
        now,
    );
    let done = e.configure(&load(&serial(115200)), &[None, None], now);
    let [Request::Close(closed), Request::Open(..)] = done.requests[..] else {
        panic!("{:?}", done.requests);
    };
    assert_eq!(closed, port);
    assert_eq!(done.dropped, 1, "its queued frame");
}

#[test]
fn what_retiring_links_hold_is_the_first_to_go_when_all_queues_are_full() {
    let three = "udp { port 14550; }\nudp { port 14560; }\nudp { port 14570; }\n\
                 default_action accept;\n";
    let frame = |n: u8| routing::frame_seq("ATTITUDE", "1.1", None, n);
    let now = Timestamp::from_secs(1);
    // Three interfaces, a ground station behind each of the last two.
    let start = |options: RouterOptions| {
        let config = load(three);
        let mut e = Engine::new(&config, options);
        let done = e.configure(&config, &[None, None, None], Timestamp::ZERO);
        let [vehicle, gone, kept] = opened(&done.requests)[..] else {
            panic!("three interfaces: {:?}", done.requests);
        };
        hello(&mut e, gone, 2, "255.190", now);
        hello(&mut e, kept, 3, "255.191", now);
        hello(&mut e, vehicle, 1, "1.1", now);
        for i in [vehicle, gone, kept] {
            sent(&mut e, i, now);
        }
        // Eight frames for each ground station.
        for n in 0..8 {
            e.handle_datagram(vehicle, peer(1), &frame(n), now);
        }
        (e, vehicle, gone, kept)
    };
    // What a queued frame costs, then room for twenty in all queues together.
    let cost = start(RouterOptions::default()).0.router().queued_bytes() / 16;
    let (mut e, vehicle, gone, kept) = start(RouterOptions {
        total_queue_capacity: 20 * cost,
        ..RouterOptions::default()
    });
    let fewer = "udp { port 14550; }\nudp { port 14570; }\ndefault_action accept;\n";
    e.configure(&load(fewer), &[None, None], now);
    assert!(e.is_retiring(gone));
    // Eight more for the one kept: 24 frames do not fit in 20.
    for n in 8..16 {
        e.handle_datagram(vehicle, peer(1), &frame(n), now);
    }
    let got = sent(&mut e, kept, now);
    assert_eq!(
        got,
        (0..16).map(frame).collect::<Vec<_>>(),
        "the kept one lost nothing"
    );
    assert!(
        sent(&mut e, gone, now).len() < 8,
        "the retiring one kept all"
    );
}
