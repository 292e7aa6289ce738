//! Redundant paths and the router's own heartbeat in the core, on a simulated clock:
//! `dedup` drops copies within its window (from any link), a `group` of interfaces is
//! one path to a vehicle (nothing reflected between members, commands out on each), and
//! `heartbeat` goes to every link at exactly its interval. A reload takes new values.

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::time::Duration;

use crate::routing;

use mavtables::address::Address;
use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, Request, RouterOptions, Timestamp};
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, encode_v2};

/// A HEARTBEAT from `from` with sequence `seq` (its bytes differ per `seq`).
fn heartbeat(from: &str, seq: u8) -> Vec<u8> {
    let a = routing::addr(from);
    let mut out = Vec::new();
    let header = Header {
        seq,
        system: a.system,
        component: a.component,
    };
    encode_v2(header, 0, &[0, 0, 0, 0, 1, 3, 0, 4, 3], None, &mut out).expect("encodes");
    out
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// A core running `conf`, and its interfaces by the port of their block.
fn start(conf: &str) -> (Engine, BTreeMap<u16, InterfaceId>) {
    let config = config::load(conf).expect("config loads").config;
    let mut e = Engine::new(&config, RouterOptions::default());
    let keys = vec![None; config.interfaces.len()];
    let done = e.configure(&config, &keys, Timestamp::ZERO);
    (e, ports(&done.requests))
}

fn ports(requests: &[Request]) -> BTreeMap<u16, InterfaceId> {
    requests
        .iter()
        .filter_map(|r| match r {
            Request::Open(id, config::Interface::Udp(u)) => Some((u.port, *id)),
            _ => None,
        })
        .collect()
}

/// Everything interface `iface` sends at `now`, as (peer port, bytes).
fn sent(e: &mut Engine, iface: InterfaceId, now: Timestamp) -> Vec<(u16, Vec<u8>)> {
    let mut queue = VecDeque::new();
    e.poll_transmit(iface, now, 1024, &mut queue);
    queue
        .into_iter()
        .map(|t| {
            e.on_sent(&t);
            (t.to.map_or(0, |a| a.port()), t.packet.to_vec())
        })
        .collect()
}

const RADIOS: &str = "dedup 500ms;\n\
    udp { port 14550; group radios; }\n\
    udp { port 14551; group radios; }\n\
    udp { port 14560; }\n\
    default_action accept;\n";

#[test]
fn two_radios_in_a_group_are_one_path() {
    let (mut e, ports) = start(RADIOS);
    let (a, b, gcs) = (ports[&14550], ports[&14551], ports[&14560]);
    let mut now = Timestamp::from_secs(1);
    e.handle_datagram(gcs, peer(3), &heartbeat("255.190", 0), now);
    for i in [a, b, gcs] {
        sent(&mut e, i, now);
    }
    // The vehicle sends every frame on both radios; the second radio lags sometimes.
    let mut want = Vec::new();
    for seq in 0..50u8 {
        now = now + Duration::from_millis(100);
        let f = heartbeat("1.1", seq);
        e.handle_datagram(a, peer(1), &f, now);
        e.handle_datagram(
            b,
            peer(2),
            &f,
            now + Duration::from_millis(u64::from(seq % 3)),
        );
        want.push(f);
    }
    let got: Vec<Vec<u8>> = sent(&mut e, gcs, now).into_iter().map(|(_, f)| f).collect();
    assert_eq!(got, want, "each frame once, in order");
    // Nothing from the vehicle is reflected to the other radio.
    let back: Vec<_> = sent(&mut e, a, now)
        .into_iter()
        .chain(sent(&mut e, b, now))
        .filter(|(_, f)| Frame::parse_exact(f).expect("frame").source() == routing::addr("1.1"))
        .collect();
    assert!(back.is_empty(), "reflected: {back:?}");
    // Each radio's copies are counted as duplicates on its own link.
    let duplicates: u64 = e.router().links().map(|l| l.counters().duplicate).sum();
    assert_eq!(duplicates, 50);
    // A command for the vehicle goes out on both radios, once each.
    let cmd = routing::frame("COMMAND_LONG", "255.190", Some("1.1"));
    e.handle_datagram(gcs, peer(3), &cmd, now);
    assert_eq!(sent(&mut e, a, now), vec![(1, cmd.clone())]);
    assert_eq!(sent(&mut e, b, now), vec![(2, cmd)]);
}

#[test]
fn a_resend_after_the_window_passes_and_one_within_it_does_not() {
    let (mut e, ports) = start(RADIOS);
    let (a, gcs) = (ports[&14550], ports[&14560]);
    let t0 = Timestamp::from_secs(1);
    e.handle_datagram(gcs, peer(3), &heartbeat("255.190", 0), t0);
    let f = heartbeat("1.1", 7);
    e.handle_datagram(a, peer(1), &f, t0);
    e.handle_datagram(a, peer(1), &f, t0 + Duration::from_millis(500));
    e.handle_datagram(a, peer(1), &f, t0 + Duration::from_millis(501));
    let now = t0 + Duration::from_millis(501);
    assert_eq!(sent(&mut e, gcs, now).len(), 2);
}

#[test]
fn without_dedup_every_copy_passes_and_a_reload_turns_it_on() {
    let plain = RADIOS.replace("dedup 500ms;\n", "");
    let (mut e, ports) = start(&plain);
    let (a, b, gcs) = (ports[&14550], ports[&14551], ports[&14560]);
    let now = Timestamp::from_secs(1);
    e.handle_datagram(gcs, peer(3), &heartbeat("255.190", 0), now);
    let f = heartbeat("1.1", 1);
    e.handle_datagram(a, peer(1), &f, now);
    e.handle_datagram(b, peer(2), &f, now);
    assert_eq!(sent(&mut e, gcs, now).len(), 2);
    let config = config::load(RADIOS).expect("loads").config;
    let done = e.configure(&config, &[None, None, None], now);
    assert!(
        done.requests.is_empty(),
        "nothing reopened: {:?}",
        done.requests
    );
    let f = heartbeat("1.1", 2);
    e.handle_datagram(a, peer(1), &f, now);
    e.handle_datagram(b, peer(2), &f, now);
    assert_eq!(sent(&mut e, gcs, now).len(), 1);
}

const BEAT: &str = "heartbeat { system 1; component 191; interval 1s; }\n\
    udp { port 14550; }\n\
    default_action accept;\n";

#[test]
fn the_heartbeat_goes_to_every_link_at_its_exact_interval() {
    let (mut e, ports) = start(BEAT);
    let u = ports[&14550];
    // Two peers become links by sending (the router's own address is not learned).
    e.handle_datagram(u, peer(1), &heartbeat("10.1", 0), Timestamp::ZERO);
    e.handle_datagram(u, peer(2), &heartbeat("1.191", 0), Timestamp::ZERO);
    let mut times: BTreeMap<u16, Vec<(Timestamp, u8)>> = BTreeMap::new();
    let mut now = Timestamp::ZERO;
    let end = Timestamp::from_secs(10);
    while now <= end {
        e.handle_timeout(now);
        for (port, bytes) in sent(&mut e, u, now) {
            let f = Frame::parse_exact(&bytes).expect("frame");
            // The router's own (type 18); peer 2's frame from the same address is
            // forwarded like any other.
            if f.source() == Address::new(1, 191) && f.payload()[4] == 18 {
                assert_eq!(f.payload(), &[0, 0, 0, 0, 18, 8, 0, 4, 3]);
                times.entry(port).or_default().push((now, f.seq()));
            }
        }
        now = e.poll_timeout();
    }
    let want: Vec<(Timestamp, u8)> = (0..=10)
        .map(|s| (Timestamp::from_secs(s), s as u8))
        .collect();
    assert_eq!(times.get(&1), Some(&want));
    assert_eq!(times.get(&2), Some(&want));
    let own = Address::new(1, 191);
    for link in e.router().links() {
        assert!(
            link.pool().addresses(now).all(|a| a != own),
            "{} learned the router's own address",
            link.name()
        );
    }
}

#[test]
fn a_reload_changes_the_interval_and_one_without_the_block_stops_it() {
    let (mut e, ports) = start(BEAT);
    let u = ports[&14550];
    e.handle_datagram(u, peer(1), &heartbeat("10.1", 0), Timestamp::ZERO);
    e.handle_timeout(Timestamp::ZERO);
    assert_eq!(sent(&mut e, u, Timestamp::ZERO).len(), 1);
    let faster = config::load(&BEAT.replace("interval 1s", "interval 250ms"))
        .expect("loads")
        .config;
    e.configure(&faster, &[None], Timestamp::from_millis(100));
    assert_eq!(e.poll_timeout(), Timestamp::from_millis(250));
    let none = config::load("udp { port 14550; }\ndefault_action accept;")
        .expect("loads")
        .config;
    e.configure(&none, &[None], Timestamp::from_millis(200));
    assert!(e.poll_timeout() > Timestamp::from_millis(250));
}

#[test]
fn a_reload_takes_the_new_groups_for_links_already_there() {
    let (mut e, ports) = start(RADIOS);
    let (a, b) = (ports[&14550], ports[&14551]);
    let now = Timestamp::from_secs(1);
    e.handle_datagram(a, peer(1), &heartbeat("1.1", 1), now);
    e.handle_datagram(b, peer(2), &heartbeat("1.1", 2), now);
    let groups =
        |e: &Engine| -> Vec<bool> { e.router().links().map(|l| l.group().is_some()).collect() };
    assert_eq!(groups(&e), vec![true, true]);
    let ungrouped = config::load(&RADIOS.replace(" group radios;", ""))
        .expect("loads")
        .config;
    let done = e.configure(&ungrouped, &[None, None, None], now);
    assert!(
        done.requests.is_empty(),
        "nothing reopened: {:?}",
        done.requests
    );
    assert_eq!(groups(&e), vec![false, false]);
    e.configure(
        &config::load(RADIOS).expect("loads").config,
        &[None, None, None],
        now,
    );
    assert_eq!(groups(&e), vec![true, true]);
}

/// A UDP remote of a grouped server that fell silent (a radio bridge that restarted on a
/// new port) still expires, however much the group hears meanwhile: it would otherwise
/// hold a place of `max_peers` for good.
#[test]
fn a_grouped_servers_silent_remote_still_expires() {
    let (mut e, ports) = start(
        "udp { port 14550; group radio; max_peers 2; }\n\
         udp { port 14551; group radio; }\n\
         default_action accept;\n",
    );
    let radio = ports[&14550];
    e.handle_datagram(
        radio,
        peer(1),
        &heartbeat("1.1", 0),
        Timestamp::from_secs(1),
    );
    for s in 2..=400u64 {
        let now = Timestamp::from_secs(s);
        e.handle_datagram(radio, peer(2), &heartbeat("1.1", s as u8), now);
        e.handle_timeout(now);
    }
    assert!(
        !e.router().links().any(|l| l.name() == "127.0.0.1:1"),
        "silent 399 s, still a link"
    );
    e.handle_datagram(
        radio,
        peer(3),
        &heartbeat("1.1", 0),
        Timestamp::from_secs(401),
    );
    assert!(
        e.router().links().any(|l| l.name() == "127.0.0.1:3"),
        "refused as over max_peers"
    );
}
