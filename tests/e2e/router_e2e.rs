//! End-to-end tests of the live router: the real `mavtables` binary,
//! real UDP sockets on 127.0.0.1, real pseudo-terminals for serial links, and pymavlink
//! (`tests/py/peer.py`) as the independent peer. The scenarios are those of the
//! original's integration suite plus device loss, garbage input, bitrate
//! accuracy and shutdown.
//!
//! Synchronisation is on events, never on sleeps: the router's UDP ports being bound,
//! its `new component S.C on LINK` log lines, the peers' "setup"/"ready"/"done" lines.

use crate::common;

use std::io::{Read, Write};
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use common::router::{
    Peer, Received, Router, Scratch, free_udp_port, hexes, names, shared_messages, strip_ports,
};
use mavtables::dialect;
use mavtables::wire::Parser;
use mavtables::wire::encode::{Header, encode_v1, encode_v2};
use serialport::TTYPort;

const SECOND: Duration = Duration::from_secs(1);

// ----------------------------------------------------------------------------------------
// Helpers

/// Peer arguments for the router's UDP socket on `port`.
fn udp(port: u16) -> Vec<String> {
    vec!["--udp".into(), format!("127.0.0.1:{port}")]
}

/// Peer arguments for a pty the peer makes, reached by the router at `device`.
fn pty(device: &str) -> Vec<String> {
    vec!["--serial".into(), device.into()]
}

fn peer_args(cmd: &str, link: &[String], address: &str, extra: &[String]) -> Vec<String> {
    let (s, c) = address.split_once('.').expect("S.C");
    let mut args = vec![cmd.to_string()];
    args.extend_from_slice(link);
    args.extend(["--sys".into(), s.into(), "--comp".into(), c.into()]);
    args.extend_from_slice(extra);
    args
}

/// A pymavlink listener at `address` that expects `count` messages.
fn listener(link: &[String], address: &str, count: usize, extra: &[&str]) -> Peer {
    let mut more: Vec<String> = vec![
        "--count".into(),
        count.to_string(),
        "--timeout".into(),
        "30".into(),
    ];
    more.extend(extra.iter().map(|s| s.to_string()));
    Peer::start(&peer_args("listen", link, address, &more))
}

/// A pymavlink sender at `address` of `items` (`NAME` or `NAME@S.C`).
fn sender<S: AsRef<str>>(link: &[String], address: &str, flags: &[&str], items: &[S]) -> Peer {
    let mut more: Vec<String> = flags.iter().map(|s| s.to_string()).collect();
    more.extend(items.iter().map(|s| s.as_ref().to_string()));
    Peer::start(&peer_args("send", link, address, &more))
}

/// Lets a listener send its HEARTBEAT and waits until the router has learned it.
fn learn(router: &mut Router, peer: &mut Peer, address: &str, link: &str) {
    peer.go_ready();
    router.wait_for(&format!("new component {address} on {link}"));
}

/// Equality of two frame lists with a readable failure: lengths and the first difference.
fn assert_frames(what: &str, got: &[String], want: &[String]) {
    if got == want {
        return;
    }
    let first = got
        .iter()
        .zip(want)
        .position(|(a, b)| a != b)
        .unwrap_or(got.len().min(want.len()));
    panic!(
        "{what}: got {} frames, want {}; first difference at #{first}:\n got  {:?}\n want {:?}",
        got.len(),
        want.len(),
        got.get(first),
        want.get(first)
    );
}

/// The frames of `received` that came from `source` (`S.C`).
fn from_source(received: &[Received], source: &str) -> Vec<String> {
    received
        .iter()
        .filter(|r| r.source == source)
        .map(|r| r.hex.clone())
        .collect()
}

const REJECT_HEARTBEAT_ACCEPT: &str = "chain default {\n    reject if HEARTBEAT;\n    accept;\n}\n";

/// [`REJECT_HEARTBEAT_ACCEPT`] that also forwards SETUP_SIGNING, which a rule must name
/// to be forwarded (it carries a signing key in the clear): for the tests that send every
/// message type.
const EVERY_MESSAGE_BUT_HEARTBEAT: &str =
    "chain default {\n    reject if HEARTBEAT;\n    accept if SETUP_SIGNING;\n    accept;\n}\n";

fn udp_block(port: u16, extra: &str) -> String {
    format!("udp {{ port {port}; address 127.0.0.1; {extra}}}\n")
}

fn serial_block(device: &str, extra: &str) -> String {
    format!("serial {{ device {device}; baudrate 57600; {extra}}}\n")
}

/// A MAVLink frame built with the crate's encoder: message `name` from `sys.comp`, its
/// payload filled from `fill` (no target fields are used by these tests).
fn frame(name: &str, v2: bool, seq: u8, sys: u8, comp: u8, fill: u8) -> Vec<u8> {
    let info = dialect::by_name(name).expect("message name");
    let payload: Vec<u8> = (0..info.max_len)
        .map(|i| fill.wrapping_mul(31).wrapping_add(i).max(1))
        .collect();
    let header = Header {
        seq,
        system: sys,
        component: comp,
    };
    let mut out = Vec::new();
    if v2 {
        encode_v2(header, info.id, &payload, None, &mut out).expect("encode");
    } else {
        encode_v1(header, info.id, &payload, &mut out).expect("encode");
    }
    out
}

fn heartbeat(sys: u8, comp: u8) -> Vec<u8> {
    frame("HEARTBEAT", true, 0, sys, comp, 3)
}

/// A plain UDP peer of our own (for the tests that need byte-level control).
struct UdpPeer {
    sock: UdpSocket,
    router: String,
}

impl UdpPeer {
    fn new(port: u16) -> UdpPeer {
        let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
        sock.set_read_timeout(Some(Duration::from_millis(50)))
            .expect("timeout");
        UdpPeer {
            sock,
            router: format!("127.0.0.1:{port}"),
        }
    }

    fn port(&self) -> u16 {
        self.sock.local_addr().expect("addr").port()
    }

    fn send(&self, bytes: &[u8]) {
        self.sock.send_to(bytes, &self.router).expect("send");
    }

    /// Datagrams until `n` have arrived or `timeout` passed.
    fn recv(&self, n: usize, timeout: Duration) -> Vec<Vec<u8>> {
        let deadline = Instant::now() + timeout;
        let mut out = Vec::new();
        let mut buf = [0u8; 65536];
        while out.len() < n && Instant::now() < deadline {
            if let Ok((len, _)) = self.sock.recv_from(&mut buf) {
                out.push(buf[..len].to_vec());
            }
        }
        out
    }
}

/// Frames read from a pty master until `done` says so or `timeout` passed.
fn read_frames(
    master: &mut TTYPort,
    timeout: Duration,
    done: impl Fn(&[Vec<u8>]) -> bool,
) -> Vec<Vec<u8>> {
    let deadline = Instant::now() + timeout;
    let mut parser = Parser::new();
    let mut frames = Vec::new();
    let mut buf = [0u8; 4096];
    while !done(&frames) && Instant::now() < deadline {
        match master.read(&mut buf) {
            Ok(0) => break,
            Ok(k) => parser.feed(&buf[..k], |f| frames.push(f.as_bytes().to_vec())),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("pty read: {e}"),
        }
    }
    frames
}

// ----------------------------------------------------------------------------------------
// 1. Every shared message type, v1 and v2, UDP→UDP, UDP→serial, serial→UDP, serial→serial

/// One sender (on UDP or on serial), two listeners (12.26 on UDP, 29.39 on serial): each
/// listener receives every message the sender sent, byte for byte, in order.
/// The shared message types without HEARTBEAT (the configs reject it, so that the
/// listeners' own heartbeats do not reach each other): `(v1, v2)`.
fn message_lists() -> (Vec<&'static str>, Vec<&'static str>) {
    let (mut v1, mut v2) = shared_messages();
    v1.retain(|n| *n != "HEARTBEAT");
    v2.retain(|n| *n != "HEARTBEAT");
    (v1, v2)
}

fn every_message(sender_on_serial: bool, v1: bool) {
    let (v1_names, v2_names) = message_lists();
    let list = if v1 { v1_names } else { v2_names };
    assert!(
        list.len() > 100,
        "only {} shared message types?",
        list.len()
    );
    let s = Scratch::new("every");
    let port = free_udp_port();
    let listen_dev = s.path("listener");
    let send_dev = s.path("sender");
    let mut config = udp_block(port, "") + &serial_block(&listen_dev, "");
    if sender_on_serial {
        config += &serial_block(&send_dev, "");
    }
    config += EVERY_MESSAGE_BUT_HEARTBEAT;

    // Serial peers first: their ptys exist before the router opens the devices.
    let mut serial_listener = listener(&pty(&listen_dev), "29.39", list.len(), &[]);
    let flags: &[&str] = if v1 { &["--v1"] } else { &[] };
    let mut serial_sender =
        sender_on_serial.then(|| sender(&pty(&send_dev), "192.168", flags, &list));
    let mut router = Router::start(&s, &config, 1);
    let mut udp_listener = listener(&udp(port), "12.26", list.len(), &[]);
    learn(&mut router, &mut udp_listener, "12.26", "127.0.0.1:");
    learn(&mut router, &mut serial_listener, "29.39", &listen_dev);

    let mut the_sender = match serial_sender.take() {
        Some(p) => p,
        None => sender(&udp(port), "192.168", flags, &list),
    };
    the_sender.go();
    let sent = the_sender.sent(Duration::from_secs(30));
    assert_eq!(sent.len(), list.len());
    for (what, peer) in [("udp", &mut udp_listener), ("serial", &mut serial_listener)] {
        let got = peer.received(Duration::from_secs(40));
        let want_names: Vec<String> = list.iter().map(|n| n.to_string()).collect();
        assert_frames(
            &format!("{what} listener: types"),
            &names(&got),
            &want_names,
        );
        assert_frames(&format!("{what} listener"), &hexes(&got), &sent);
    }
    router.stop();
}

#[test]
fn every_message_v2_from_udp_to_udp_and_serial() {
    every_message(false, false);
}

#[test]
fn every_message_v1_from_udp_to_udp_and_serial() {
    every_message(false, true);
}

#[test]
fn every_message_v2_from_serial_to_udp_and_serial() {
    every_message(true, false);
}

#[test]
fn every_message_v1_from_serial_to_udp_and_serial() {
    every_message(true, true);
}

// ----------------------------------------------------------------------------------------
// 2. Several senders at once

/// Two UDP senders (192.168 in v2, 172.128 in v1) and a serial sender (127.1, v2) send
/// every shared message at the same time; each listener (12.26 on UDP, 10.20 on serial)
/// receives every message of each sender exactly once, each sender's in its order.
#[test]
fn multiple_senders_at_once() {
    let (v1_names, v2_names) = message_lists();
    let s = Scratch::new("multi");
    let port = free_udp_port();
    let listen_dev = s.path("listener");
    let send_dev = s.path("sender");
    let config = udp_block(port, "")
        + &serial_block(&listen_dev, "")
        + &serial_block(&send_dev, "")
        + EVERY_MESSAGE_BUT_HEARTBEAT;
    let total = 2 * v2_names.len() + v1_names.len();
    let mut serial_listener = listener(&pty(&listen_dev), "10.20", total, &[]);
    let mut serial_sender = sender(&pty(&send_dev), "127.1", &[], &v2_names);
    let mut router = Router::start(&s, &config, 1);
    let mut udp_listener = listener(&udp(port), "12.26", total, &[]);
    learn(&mut router, &mut udp_listener, "12.26", "127.0.0.1:");
    learn(&mut router, &mut serial_listener, "10.20", &listen_dev);
    let mut a = sender(&udp(port), "192.168", &[], &v2_names);
    let mut b = sender(&udp(port), "172.128", &["--v1"], &v1_names);
    for p in [&mut a, &mut b, &mut serial_sender] {
        p.go();
    }
    let sent: Vec<(&str, Vec<String>)> = vec![
        ("192.168", a.sent(Duration::from_secs(30))),
        ("172.128", b.sent(Duration::from_secs(30))),
        ("127.1", serial_sender.sent(Duration::from_secs(30))),
    ];
    for (what, peer) in [("udp", &mut udp_listener), ("serial", &mut serial_listener)] {
        let got = peer.received(Duration::from_secs(40));
        assert_eq!(got.len(), total, "{what} listener: total received");
        for (source, frames) in &sent {
            assert_frames(
                &format!("{what} listener, from {source}"),
                &from_source(&got, source),
                frames,
            );
        }
    }
    router.stop();
}

// ----------------------------------------------------------------------------------------
// 3 and 4. Routing with the log at levels 1, 2 and 3

const ROUTING: &str = include_str!("../data/config/routing_chains.conf");

/// What the sender (10.10) sends after its HEARTBEAT.
const ROUTING_SCRIPT: [&str; 10] = [
    "ATTITUDE",
    "PARAM_REQUEST_READ@192.168",
    "PARAM_REQUEST_READ@127.1",
    "PING@192.168",
    "PING@127.1",
    "GPS_RAW_INT",
    "SET_HOME_POSITION@172.0",
    "MISSION_REQUEST_LIST@172.128",
    "MISSION_REQUEST_LIST@172.168",
    "MISSION_REQUEST_LIST@192.168",
];

/// The level-3 log of the routing run, written from the original's log formats and
/// routing rules: links in creation order (the serial port, then 127.1,
/// 192.168 and 10.10 on UDP), UDP link names without their port.
fn routing_log(dev: &str, v: &str) -> Vec<String> {
    let u = "127.0.0.1";
    let hb = |from: &str, ver: &str| format!("HEARTBEAT (#0) from {from} (v{ver}.0)");
    let p = |what: &str| format!("{what} (v{v}.0)");
    let mut log = vec![
        format!("new component 127.1 on {u}"),
        format!("received {} source {u}", hb("127.1", "2")),
        format!("rejected {} source {u} dest {dev}", hb("127.1", "2")),
        format!("new component 192.168 on {u}"),
        format!("received {} source {u}", hb("192.168", "2")),
        format!("rejected {} source {u} dest {dev}", hb("192.168", "2")),
        format!("rejected {} source {u} dest {u}", hb("192.168", "2")),
        format!("new component 172.128 on {dev}"),
        format!("received {} source {dev}", hb("172.128", "2")),
        format!("rejected {} source {dev} dest {u}", hb("172.128", "2")),
        format!("rejected {} source {dev} dest {u}", hb("172.128", "2")),
        format!("new component 10.10 on {u}"),
        format!("received {} source {u}", hb("10.10", v)),
        format!("rejected {} source {u} dest {dev}", hb("10.10", v)),
        format!("rejected {} source {u} dest {u}", hb("10.10", v)),
        format!("rejected {} source {u} dest {u}", hb("10.10", v)),
    ];
    // (packet, [(verdict, dest)]) in link order; silent drops have no line.
    let serial = dev;
    let steps: [(&str, &[(&str, &str)]); 10] = [
        (
            "ATTITUDE (#30) from 10.10",
            &[("rejected", serial), ("accepted", u), ("accepted", u)],
        ),
        (
            "PARAM_REQUEST_READ (#20) from 10.10 to 192.168",
            &[("accepted", u)],
        ),
        (
            "PARAM_REQUEST_READ (#20) from 10.10 to 127.1",
            &[("rejected", u)],
        ),
        ("PING (#4) from 10.10 to 192.168", &[("rejected", u)]),
        ("PING (#4) from 10.10 to 127.1", &[("rejected", u)]),
        (
            "GPS_RAW_INT (#24) from 10.10",
            &[("rejected", serial), ("rejected", u), ("rejected", u)],
        ),
        (
            "SET_HOME_POSITION (#243) from 10.10 to 172.0",
            &[("accepted", serial)],
        ),
        (
            "MISSION_REQUEST_LIST (#43) from 10.10 to 172.128",
            &[("accepted", serial)],
        ),
        (
            "MISSION_REQUEST_LIST (#43) from 10.10 to 172.168",
            &[("rejected", serial)],
        ),
        (
            "MISSION_REQUEST_LIST (#43) from 10.10 to 192.168",
            &[("rejected", u)],
        ),
    ];
    for (packet, verdicts) in steps {
        log.push(format!("received {} source {u}", p(packet)));
        for (verdict, dest) in verdicts {
            log.push(format!("{verdict} {} source {u} dest {dest}", p(packet)));
        }
    }
    log
}

/// The lowest log level at which a line is printed.
fn line_level(line: &str) -> u8 {
    if line.starts_with("new component") {
        1
    } else if line.starts_with("received") {
        2
    } else {
        3
    }
}

fn local_now() -> String {
    let out = std::process::Command::new("date")
        .arg("+%Y-%m-%d %H:%M:%S")
        .output()
        .expect("date");
    String::from_utf8(out.stdout)
        .expect("utf-8")
        .trim()
        .to_string()
}

/// Every log line starts with `YYYY-MM-DD HH:MM:SS  ` (local time, two spaces) taken
/// between `before` and `after`.
fn check_timestamps(lines: &[String], before: &str, after: &str) {
    for line in lines {
        let b = line.as_bytes();
        let shape = b.len() > 21
            && b[..19].iter().enumerate().all(|(i, c)| match i {
                4 | 7 => *c == b'-',
                10 => *c == b' ',
                13 | 16 => *c == b':',
                _ => c.is_ascii_digit(),
            })
            && &b[19..21] == b"  "
            && b[21] != b' ';
        assert!(shape, "timestamp prefix of {line:?}");
        let stamp = &line[..19];
        assert!(
            before <= stamp && stamp <= after,
            "{stamp} not between {before} and {after}"
        );
    }
}

fn routing_run(loglevel: u8, v1: bool) {
    let s = Scratch::new("routing");
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    let config = serial_block(&dev, "") + &udp_block(port, "max_bitrate 262144; ") + ROUTING;
    let mut serial_listener = listener(&pty(&dev), "172.128", 2, &["--linger", "0.5"]);
    let before = local_now();
    let mut router = Router::start(&s, &config, loglevel);
    let mut l127 = listener(&udp(port), "127.1", 1, &["--linger", "0.5"]);
    let mut l192 = listener(&udp(port), "192.168", 2, &["--linger", "0.5"]);
    learn(&mut router, &mut l127, "127.1", "127.0.0.1:");
    learn(&mut router, &mut l192, "192.168", "127.0.0.1:");
    learn(&mut router, &mut serial_listener, "172.128", &dev);
    let flags: &[&str] = if v1 {
        &["--heartbeat", "--v1"]
    } else {
        &["--heartbeat"]
    };
    let mut tx = sender(&udp(port), "10.10", flags, &ROUTING_SCRIPT);
    tx.go();
    let sent = tx.sent(Duration::from_secs(10));
    // sent[0] is the HEARTBEAT; sent[1 + i] is ROUTING_SCRIPT[i].
    let pick = |idx: &[usize]| -> Vec<String> { idx.iter().map(|i| sent[1 + i].clone()).collect() };
    let wait = Duration::from_secs(15);
    assert_frames("127.1", &hexes(&l127.received(wait)), &pick(&[0]));
    assert_frames("192.168", &hexes(&l192.received(wait)), &pick(&[0, 1]));
    // SET_HOME_POSITION (priority 3), then MISSION_REQUEST_LIST to 172.128.
    assert_frames(
        "172.128",
        &hexes(&serial_listener.received(wait)),
        &pick(&[6, 7]),
    );
    let stopped = router.stop();
    let after = local_now();
    check_timestamps(&stopped.stdout, &before, &after);
    let got: Vec<String> = stopped
        .stdout
        .iter()
        .map(|l| strip_ports(&l[21..]))
        .collect();
    let want: Vec<String> = routing_log(&dev, if v1 { "1" } else { "2" })
        .into_iter()
        .filter(|l| line_level(l) <= loglevel)
        .collect();
    if got != want {
        let first = got.iter().zip(&want).position(|(a, b)| a != b);
        panic!(
            "log at level {loglevel} differs (first at line {first:?}):\n--- got\n{}\n--- want\n{}",
            got.join("\n"),
            want.join("\n")
        );
    }
}

#[test]
fn routing_v2_with_log_level_1() {
    routing_run(1, false);
}

#[test]
fn routing_v2_with_log_level_2() {
    routing_run(2, false);
}

#[test]
fn routing_v2_with_log_level_3() {
    routing_run(3, false);
}

#[test]
fn routing_v1_with_log_level_3() {
    routing_run(3, true);
}

// ----------------------------------------------------------------------------------------
// 3. Priority, preload, component-broadcast fallback

/// A UDP listener behind `max_bitrate 65536`: 50 ENCAPSULATED_DATA (+1), 100 ATTITUDE
/// (−1) and 100 GLOBAL_POSITION_INT (0) from a UDP sender and 50 ENCAPSULATED_DATA from
/// a serial sender arrive as every ENCAPSULATED_DATA, then every GLOBAL_POSITION_INT,
/// then every ATTITUDE.
#[test]
fn priority_under_64_kbits() {
    let s = Scratch::new("priority");
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    let config = udp_block(port, "max_bitrate 65536; ")
        + &serial_block(&dev, "")
        + "chain default {
    reject if HEARTBEAT;
    accept with priority 1 if ENCAPSULATED_DATA;
    accept with priority -1 if ATTITUDE;
    accept;
}
";
    let mut udp_items = vec!["ENCAPSULATED_DATA"; 50];
    udp_items.extend(["ATTITUDE"; 100]);
    udp_items.extend(["GLOBAL_POSITION_INT"; 100]);
    let mut serial_tx = sender(&pty(&dev), "172.128", &[], &["ENCAPSULATED_DATA"; 50]);
    let mut router = Router::start(&s, &config, 1);
    let mut rx = listener(&udp(port), "12.26", 300, &[]);
    learn(&mut router, &mut rx, "12.26", "127.0.0.1:");
    let mut udp_tx = sender(&udp(port), "192.168", &[], &udp_items);
    serial_tx.go();
    udp_tx.go();
    let from_udp = udp_tx.sent(Duration::from_secs(10));
    let from_serial = serial_tx.sent(Duration::from_secs(10));
    let got = rx.received(Duration::from_secs(20));
    let want: Vec<&str> = std::iter::repeat_n("ENCAPSULATED_DATA", 100)
        .chain(std::iter::repeat_n("GLOBAL_POSITION_INT", 100))
        .chain(std::iter::repeat_n("ATTITUDE", 100))
        .collect();
    assert_eq!(names(&got), want);
    // Equal priorities keep each sender's order.
    assert_frames("from 192.168", &from_source(&got, "192.168"), &{
        let mut f = from_udp[..50].to_vec();
        f.extend_from_slice(&from_udp[150..]);
        f.extend_from_slice(&from_udp[50..150]);
        f
    });
    assert_frames("from 172.128", &from_source(&got, "172.128"), &from_serial);
    router.stop();
}

/// The original's large-packet scenario: 5,000 ENCAPSULATED_DATA (267-byte frames) from a
/// UDP sender and 5,000 from a serial sender, all for a listener behind a UDP interface
/// limited to 262,144 bit/s. They arrive in a second or two and leave over about 81 s,
/// so the listener's queue holds up to about 2.6 MB; the default queue bounds hold it
/// and every frame arrives, in each sender's order (the original, unbounded, delivered
/// them all). Slow by nature: the link's rate sets the time.
#[test]
fn large_packets_into_256_kbits_lose_nothing() {
    let s = Scratch::new("large");
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    // Only the listener (127.1) is a destination: the shared 256 kbit/s carries 10,000.
    let config = udp_block(port, "max_bitrate 262144; ")
        + &serial_block(&dev, "")
        + "chain default {\n    accept if ENCAPSULATED_DATA to 127.1;\n}\n";
    let items = vec!["ENCAPSULATED_DATA"; 5000];
    let mut serial_tx = sender(&pty(&dev), "172.128", &[], &items);
    let mut router = Router::start(&s, &config, 1);
    let mut rx = Peer::start(&peer_args(
        "listen",
        &udp(port),
        "127.1",
        &[
            "--count".into(),
            "10000".into(),
            "--timeout".into(),
            "150".into(),
        ],
    ));
    learn(&mut router, &mut rx, "127.1", "127.0.0.1:");
    let mut udp_tx = sender(&udp(port), "192.168", &[], &items);
    serial_tx.go();
    udp_tx.go();
    let from_udp = udp_tx.sent(Duration::from_secs(30));
    let from_serial = serial_tx.sent(Duration::from_secs(30));
    let got = rx.received(Duration::from_secs(160));
    let counters = router.stop().stderr.join("\n");
    // The router's counters say where a missing frame was lost (never taken in, dropped
    // on the way, or sent and lost after).
    assert_eq!(got.len(), 10_000, "frames received; router:\n{counters}");
    assert_frames("from 192.168", &from_source(&got, "192.168"), &from_udp);
    assert_frames("from 172.128", &from_source(&got, "172.128"), &from_serial);
    assert!(counters.contains("out 10000 frames"), "{counters}");
    for line in counters.lines().filter(|l| l.contains("(queue full)")) {
        assert!(line.contains("dropped 0 (queue full)"), "{line}");
    }
}

/// A silent serial listener (10.10, never sends) behind `preload 192.168; preload 127.1;`
/// gets broadcasts and packets for the preloaded systems (also a system broadcast and an
/// unknown component of a preloaded system); packets for the unknown system 172 are not
/// delivered.
#[test]
fn preload_reaches_a_silent_serial_listener() {
    let s = Scratch::new("preload");
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    let config = udp_block(port, "")
        + &serial_block(&dev, "preload 192.168; preload 127.1; ")
        + REJECT_HEARTBEAT_ACCEPT;
    let mut rx = listener(
        &pty(&dev),
        "10.10",
        6,
        &["--no-heartbeat", "--linger", "0.5"],
    );
    let mut router = Router::start(&s, &config, 1);
    router.wait_for(&format!("new component 192.168 on {dev}"));
    router.wait_for(&format!("new component 127.1 on {dev}"));
    rx.go_ready();
    let items = [
        "ATTITUDE",
        "PING@192.168",
        "PING@127.1",
        "PING@172.128",
        "PING@127.5",
        "SET_MODE@172.0",
        "PING@192.0",
        "PARAM_REQUEST_LIST@172.1",
        "SYS_STATUS",
    ];
    let mut tx = sender(&udp(port), "255.190", &[], &items);
    tx.go();
    let sent = tx.sent(Duration::from_secs(10));
    let want: Vec<String> = [0, 1, 2, 4, 6, 8]
        .iter()
        .map(|&i| sent[i].clone())
        .collect();
    assert_frames(
        "silent listener",
        &hexes(&rx.received(Duration::from_secs(15))),
        &want,
    );
    let stopped = router.stop();
    assert!(
        !stopped
            .stdout
            .iter()
            .any(|l| l.contains("new component 10.10")),
        "the silent listener sent something"
    );
}

/// `MISSION_REQUEST_LIST` to 1.0 … 1.255 reaches a serial link that only knows 1.1
/// exactly for 1.128 … 1.255 under `accept if to 1.255/9`: the fallback filters with the
/// packet's own destination.
#[test]
fn component_broadcast_fallback() {
    let s = Scratch::new("fallback");
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    let config = udp_block(port, "")
        + &serial_block(&dev, "")
        + "chain default {\n    reject if HEARTBEAT;\n    accept if to 1.255/9;\n}\n";
    let mut rx = listener(&pty(&dev), "1.1", 128, &["--linger", "0.5"]);
    let mut router = Router::start(&s, &config, 1);
    learn(&mut router, &mut rx, "1.1", &dev);
    let items: Vec<String> = (0..=255)
        .map(|c| format!("MISSION_REQUEST_LIST@1.{c}"))
        .collect();
    let mut tx = sender(&udp(port), "192.168", &[], &items);
    tx.go();
    let sent = tx.sent(Duration::from_secs(10));
    assert_frames(
        "serial listener 1.1",
        &hexes(&rx.received(Duration::from_secs(15))),
        &sent[128..],
    );
    router.stop();
}

/// A router with one UDP interface and one serial port (a pty reached as `ttyS0` in the
/// scratch folder) that drops heartbeats and accepts the rest, and a UDP peer it has
/// already learned as 12.26.
struct UdpAndSerial {
    port: u16,
    dev: String,
    master: TTYPort,
    slave: TTYPort,
    router: Router,
    rx: UdpPeer,
}

fn udp_and_serial(s: &Scratch) -> UdpAndSerial {
    let port = free_udp_port();
    let dev = s.path("ttyS0");
    let config = udp_block(port, "") + &serial_block(&dev, "") + REJECT_HEARTBEAT_ACCEPT;
    let (master, slave) = common::pty_at(&dev);
    let mut router = Router::start(s, &config, 1);
    let rx = UdpPeer::new(port);
    rx.send(&heartbeat(12, 26));
    router.wait_for("new component 12.26 on 127.0.0.1:");
    UdpAndSerial {
        port,
        dev,
        master,
        slave,
        router,
        rx,
    }
}

// ----------------------------------------------------------------------------------------
// 5. A serial device that vanishes and comes back while UDP traffic flows

#[test]
fn serial_device_vanishes_and_comes_back() {
    let s = Scratch::new("vanish");
    let UdpAndSerial {
        port,
        dev,
        mut master,
        slave,
        mut router,
        rx,
    } = udp_and_serial(&s);
    master.write_all(&heartbeat(1, 1)).expect("pty write");
    router.wait_for(&format!("new component 1.1 on {dev}"));
    let tx = UdpPeer::new(port);
    let mut seq = 0u8;
    let mut send = |n: usize, gap: Duration| {
        for _ in 0..n {
            tx.send(&frame("ATTITUDE", true, seq, 192, 168, seq));
            seq = seq.wrapping_add(1);
            thread::sleep(gap);
        }
    };
    let seqs = |frames: &[Vec<u8>]| -> Vec<u8> { frames.iter().map(|f| f[4]).collect() };

    // Before: both listeners get everything.
    send(20, Duration::from_millis(2));
    assert_eq!(seqs(&rx.recv(20, 5 * SECOND)), (0..20).collect::<Vec<u8>>());
    assert_eq!(
        seqs(&read_frames(&mut master, 5 * SECOND, |f| f.len() >= 20)),
        (0..20).collect::<Vec<u8>>()
    );

    // The device goes: its other end closes and the path disappears.
    // The path first: once the pty is closed its number is free for another test's pty,
    // which the router, retrying this path, must never open.
    std::fs::remove_file(&dev).expect("remove link");
    drop(master);
    drop(slave);
    router
        .err
        .wait_for(&format!("serial device {dev} lost"), 5 * SECOND);
    send(50, Duration::from_millis(10));
    assert_eq!(
        seqs(&rx.recv(50, 5 * SECOND)),
        (20..70).collect::<Vec<u8>>(),
        "UDP delivery during the outage"
    );

    // It comes back under the same path (a new pty).
    let (mut master, _slave) = common::pty_at(&dev);
    router
        .err
        .wait_for(&format!("serial device {dev} is back"), 5 * SECOND);
    send(20, Duration::from_millis(2));
    assert_eq!(
        seqs(&rx.recv(20, 5 * SECOND)),
        (70..90).collect::<Vec<u8>>()
    );
    // What was queued for the port while it was away may come first; then all of 70..90.
    let mut got = seqs(&read_frames(&mut master, 5 * SECOND, |f| {
        f.last().is_some_and(|l| l[4] == 89)
    }));
    assert!(got.windows(2).all(|w| w[0] < w[1]), "order: {got:?}");
    let tail = got.split_off(got.len().saturating_sub(20));
    assert_eq!(tail, (70..90).collect::<Vec<u8>>(), "after the return");
    // And the port is a source again.
    let back = frame("SYS_STATUS", true, 7, 1, 1, 9);
    master.write_all(&back).expect("pty write");
    assert_eq!(rx.recv(1, 5 * SECOND), vec![back]);
    router.stop();
}

// ----------------------------------------------------------------------------------------
// 6. Malformed datagrams and garbage bytes among valid frames

/// A small deterministic generator (xorshift).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// `n` junk bytes without a MAVLink start byte.
    fn junk(&mut self, n: usize) -> Vec<u8> {
        (0..n)
            .map(|_| match self.next() as u8 {
                0xFD | 0xFE => 0x55,
                b => b,
            })
            .collect()
    }
}

/// Frames of one sender, with the valid ones noted in order.
struct Frames {
    rng: Rng,
    seq: u8,
    sys: u8,
    comp: u8,
    valid: Vec<Vec<u8>>,
}

impl Frames {
    /// A frame of a random kind; noted as valid if `keep`.
    fn make(&mut self, keep: bool, v2: bool) -> Vec<u8> {
        const KINDS: [&str; 6] = [
            "ATTITUDE",
            "GLOBAL_POSITION_INT",
            "SYS_STATUS",
            "VFR_HUD",
            "ENCAPSULATED_DATA",
            "STATUSTEXT",
        ];
        let kind = KINDS[(self.rng.next() % KINDS.len() as u64) as usize];
        let fill = self.rng.next() as u8;
        let f = frame(kind, v2, self.seq, self.sys, self.comp, fill);
        self.seq = self.seq.wrapping_add(1);
        if keep {
            self.valid.push(f.clone());
        }
        f
    }
}

/// Chunks of a dirty stream from `sys.comp` (for UDP, each chunk is one datagram) and the
/// valid frames in it, in order.
fn dirty_stream(sys: u8, comp: u8, seed: u64) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let mut g = Frames {
        rng: Rng(seed),
        seq: 0,
        sys,
        comp,
        valid: Vec::new(),
    };
    let mut chunks: Vec<Vec<u8>> = Vec::new();
    for round in 0..60 {
        match round % 10 {
            0 => {
                let junk = g.rng.junk(17);
                chunks.extend([junk, g.make(true, true)]);
            }
            1 => {
                let (head, a, tail) = (g.rng.junk(5), g.make(true, true), g.rng.junk(9));
                chunks.push([head, a, tail].concat());
            }
            2 => {
                let mut bad = g.make(false, true);
                let last = bad.len() - 1;
                bad[last] ^= 0x5A; // checksum broken
                chunks.extend([bad, g.make(true, true)]);
            }
            3 => {
                let cut = g.make(false, true);
                chunks.extend([cut[..5].to_vec(), g.make(true, true)]); // truncated, then a frame
            }
            4 => {
                // Well-formed but of an id outside the dialect, glued to a valid frame.
                let mut unknown = vec![
                    0xFD, 4, 0, 0, g.seq, sys, comp, 0xEF, 0xBE, 0xAD, 1, 2, 3, 4,
                ];
                let crc = mavtables::wire::crc::frame_checksum(&unknown[1..], 0);
                unknown.extend(crc.to_le_bytes());
                chunks.push([unknown, g.make(true, true)].concat());
            }
            5 => {
                let mut flagged = g.make(false, true);
                flagged[2] = 0x02; // an unknown incompatibility flag, checksum redone
                let id = u32::from_le_bytes([flagged[7], flagged[8], flagged[9], 0]);
                let extra = dialect::by_id(id).expect("id").crc_extra;
                let end = flagged.len() - 2;
                let crc = mavtables::wire::crc::frame_checksum(&flagged[1..end], extra);
                flagged[end..].copy_from_slice(&crc.to_le_bytes());
                let (a, b) = (g.make(true, true), g.make(true, false));
                chunks.extend([flagged, [a, b].concat()]);
            }
            6 => chunks.push([vec![0xFD, 0xFE, 0xFD], g.make(true, true)].concat()),
            7 => {
                // An empty datagram, then a frame split over two datagrams (reassembled:
                // same sender).
                let a = g.make(true, true);
                chunks.extend([Vec::new(), a[..7].to_vec(), a[7..].to_vec()]);
            }
            8 => {
                // A start byte claiming a long frame, then junk and valid frames.
                let junk = g.rng.junk(20);
                let (a, b) = (g.make(true, true), g.make(true, true));
                chunks.extend([[vec![0xFD, 0xFF], junk, a].concat(), b]);
            }
            _ => {
                let (a, b, junk) = (g.make(true, false), g.make(true, true), g.rng.junk(3));
                chunks.push([a, b, junk].concat());
            }
        }
    }
    // Enough plain bytes to complete any candidate still waiting for its length.
    chunks.push(vec![0; 300]);
    (chunks, g.valid)
}

#[test]
fn garbage_and_malformed_frames_lose_no_valid_frame() {
    let s = Scratch::new("garbage");
    let UdpAndSerial {
        port,
        dev,
        mut master,
        slave: _slave,
        router,
        rx,
    } = udp_and_serial(&s);

    let (udp_chunks, udp_valid) = dirty_stream(192, 168, 0x9E37_79B9_7F4A_7C15);
    let (serial_chunks, serial_valid) = dirty_stream(172, 128, 0xD1B5_4A32_D192_ED03);
    let tx = UdpPeer::new(port);
    for c in &udp_chunks {
        tx.send(c);
        thread::sleep(Duration::from_micros(200));
    }
    // The serial stream in pieces that do not follow the chunk boundaries.
    let serial_bytes = serial_chunks.concat();
    for piece in serial_bytes.chunks(37) {
        master.write_all(piece).expect("pty write");
    }
    let total = udp_valid.len() + serial_valid.len();
    let got = rx.recv(total + 1, 5 * SECOND);
    let from = |sys: u8| -> Vec<String> {
        got.iter()
            .filter(|f| f[if f[0] == 0xFD { 5 } else { 3 }] == sys)
            .map(|f| common::hex(f))
            .collect()
    };
    let want = |v: &[Vec<u8>]| -> Vec<String> { v.iter().map(|f| common::hex(f)).collect() };
    assert_frames("UDP garbage sender", &from(192), &want(&udp_valid));
    assert_frames("serial garbage sender", &from(172), &want(&serial_valid));
    assert_eq!(got.len(), total, "nothing else came through");
    let stopped = router.stop();
    // The id sent on purpose is reported, once, however often it came; candidates made
    // of junk may add their own ids, each once too.
    let unknown: Vec<&String> = stopped
        .stderr
        .iter()
        .filter(|l| l.contains("is not part of the 'ardupilotmega' MAVLink dialect"))
        .collect();
    let ours = "Packet ID (#11386607) is not part of the 'ardupilotmega' MAVLink dialect.";
    assert_eq!(
        unknown.iter().filter(|l| **l == ours).count(),
        1,
        "{unknown:?}"
    );
    let distinct: std::collections::HashSet<&&String> = unknown.iter().collect();
    assert_eq!(
        distinct.len(),
        unknown.len(),
        "reported once per id: {unknown:?}"
    );
    // Each sender's counters name the frames it lost to a bad checksum: at least the six
    // broken on purpose (junk may add candidates of its own).
    let bad_crc = |link: &str| -> u64 {
        stopped
            .stderr
            .iter()
            .find(|l| l.trim_start().starts_with(&format!("{link}: in ")))
            .and_then(|l| l.strip_suffix(" bad checksum"))
            .and_then(|l| l.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no counters for {link}: {:?}", stopped.stderr))
    };
    assert!(bad_crc(&format!("127.0.0.1:{}", tx.port())) >= 6);
    assert!(bad_crc(&dev) >= 6);
    assert_eq!(bad_crc(&format!("127.0.0.1:{}", rx.port())), 0);
}

// ----------------------------------------------------------------------------------------
// 7. max_bitrate accuracy

/// Flooding a UDP listener behind `max_bitrate 262144` at about twice the rate, the frame
/// bytes it receives over 10 s of steady state come at the configured rate within 1%.
#[test]
fn max_bitrate_within_one_percent_over_10_s() {
    const RATE: f64 = 262_144.0;
    let s = Scratch::new("bitrate");
    let port = free_udp_port();
    let config = udp_block(port, "max_bitrate 262144; ") + REJECT_HEARTBEAT_ACCEPT;
    let mut router = Router::start(&s, &config, 1);
    let rx = UdpPeer::new(port);
    rx.send(&heartbeat(12, 26));
    router.wait_for("new component 12.26 on 127.0.0.1:");
    let stop = Arc::new(AtomicBool::new(false));
    let flood = {
        let stop = Arc::clone(&stop);
        let tx = UdpPeer::new(port);
        thread::spawn(move || {
            // Mixed sizes (267 and 40 bytes) on a schedule: 3 s worth of the limit within
            // the first half second, then twice the limit. A sender that was not scheduled
            // for a while catches up at once, so the router's queue never runs dry.
            let start = Instant::now();
            let (mut seq, mut sent) = (0u8, 0f64);
            while !stop.load(Ordering::Relaxed) {
                let t = start.elapsed().as_secs_f64();
                let due = RATE / 8.0 * (3.0 * (t / 0.5).min(1.0) + 2.0 * t);
                while sent < due {
                    let name = if seq % 3 == 1 {
                        "ATTITUDE"
                    } else {
                        "ENCAPSULATED_DATA"
                    };
                    let f = frame(name, true, seq, 192, 168, seq);
                    tx.send(&f);
                    sent += f.len() as f64;
                    seq = seq.wrapping_add(1);
                }
                thread::sleep(Duration::from_millis(5));
            }
        })
    };
    let _stop_flood = StopOnDrop(Arc::clone(&stop));
    // Arrival times and sizes, for 1 s of warm-up plus 10 s of measurement after the
    // first frame (however late a loaded machine lets it come; at most 30 s in all).
    let mut arrivals: Vec<(Instant, usize)> = Vec::new();
    let mut buf = [0u8; 2048];
    let deadline = Instant::now() + Duration::from_secs(30);
    let enough = Duration::from_millis(11_200);
    while Instant::now() < deadline
        && arrivals
            .first()
            .is_none_or(|(first, _)| first.elapsed() < enough)
    {
        if let Ok((len, _)) = rx.sock.recv_from(&mut buf) {
            arrivals.push((Instant::now(), len));
        }
    }
    stop.store(true, Ordering::Relaxed);
    flood.join().expect("flood thread");
    let start = arrivals[0].0 + SECOND;
    let first = arrivals
        .iter()
        .position(|(t, _)| *t >= start)
        .expect("steady state");
    let t0 = arrivals[first].0;
    let last = arrivals
        .iter()
        .position(|(t, _)| t.duration_since(t0) >= Duration::from_secs(10))
        .expect("10 s of traffic");
    let bytes: usize = arrivals[first + 1..=last].iter().map(|(_, n)| n).sum();
    let secs = arrivals[last].0.duration_since(t0).as_secs_f64();
    let rate = bytes as f64 * 8.0 / secs;
    let error = (rate - RATE) / RATE;
    eprintln!(
        "measured {rate:.0} bit/s over {secs:.3} s ({:+.3}%)",
        error * 100.0
    );
    let stopped = router.stop();
    let longest_gap = arrivals[first..=last]
        .windows(2)
        .map(|w| w[1].0.duration_since(w[0].0))
        .max()
        .unwrap_or_default();
    // A pacer cannot send while the machine does not run it: time the router was plainly
    // starved of (a gap over three times the median one, beyond that) is allowed for, so
    // a loaded machine does not fail the test; on a quiet one this adds nothing.
    let mut gaps: Vec<Duration> = arrivals[first..=last]
        .windows(2)
        .map(|w| w[1].0.duration_since(w[0].0))
        .collect();
    gaps.sort();
    let typical = gaps[gaps.len() / 2];
    let starved: f64 = gaps
        .iter()
        .filter(|g| **g > typical * 3)
        .map(|g| (*g - typical * 3).as_secs_f64())
        .sum();
    // Starving only makes the rate lower: too fast is never excused.
    let allowed = 0.01 + starved / secs;
    assert!(
        error < 0.01 && -error < allowed,
        "{rate:.0} bit/s over {secs:.3} s: {:+.2}% off {RATE} (allowed {:.2}%: {starved:.3} s \
         starved); longest gap between arrivals {longest_gap:?}; router:\n{}",
        error * 100.0,
        allowed * 100.0,
        stopped.stderr.join("\n")
    );
}

struct StopOnDrop(Arc<AtomicBool>);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

// ----------------------------------------------------------------------------------------
// 8. Clean shutdown

/// CPU time (user + system, in clock ticks) the process has used so far.
fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("stat");
    let after_name = &stat[stat.rfind(')').expect("comm") + 2..];
    let f: Vec<&str> = after_name.split(' ').collect();
    // Fields 14 and 15 of stat(5), counted from the state (field 3) here.
    f[11].parse::<u64>().expect("utime") + f[12].parse::<u64>().expect("stime")
}

/// SIGTERM on an idle router: exit 0 at once, counters on stderr; idle it uses no CPU.
#[test]
fn sigterm_exits_cleanly_and_promptly() {
    let (_s, mut router, a, b) = listener_and_sender("sigterm");
    let pid = router.pid();
    let before = cpu_ticks(pid);
    thread::sleep(SECOND);
    let idle = cpu_ticks(pid) - before;
    assert!(idle <= 2, "an idle second cost {idle} clock ticks of CPU");
    let stopped = router.stop_with(libc::SIGTERM);
    assert!(stopped.status.success(), "exit status {}", stopped.status);
    assert!(
        stopped.took < Duration::from_millis(500),
        "took {:?}",
        stopped.took
    );
    let err = stopped.stderr.join("\n");
    assert!(err.contains("mavtables counters:"), "{err}");
    assert!(
        err.contains(&format!(
            "127.0.0.1:{}: in 1 frames (21 bytes), out 1 frames",
            a.port()
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!("127.0.0.1:{}: in 1 frames", b.port())),
        "{err}"
    );
}

/// SIGINT with a backlog behind a slow `max_bitrate`: the router keeps sending for at
/// most about a second, exits 0 and its counters match what the listener received.
#[test]
fn sigint_flushes_for_at_most_a_second_and_exits_cleanly() {
    let s = Scratch::new("sigint");
    let port = free_udp_port();
    let config = udp_block(port, "max_bitrate 16384; ") + REJECT_HEARTBEAT_ACCEPT;
    let mut router = Router::start(&s, &config, 1);
    let rx = UdpPeer::new(port);
    rx.send(&heartbeat(12, 26));
    router.wait_for("new component 12.26 on 127.0.0.1:");
    let tx = UdpPeer::new(port);
    // 50 × 267 bytes at 2 kB/s: about 6.5 s of backlog.
    for i in 0..50u8 {
        tx.send(&frame("ENCAPSULATED_DATA", true, i, 1, 1, i));
    }
    assert_eq!(rx.recv(1, 5 * SECOND).len(), 1, "sending has started");
    // Every frame read (a stopping router reads no more): only then the signal.
    let sender = format!("127.0.0.1:{}", tx.port());
    common::eventually("all 50 frames read", 10 * SECOND, || {
        let counters = common::net::counters(&mut router);
        counters.link(&sender).is_some_and(|l| l.frames_in == 50)
    });
    let stopped = router.stop_with(libc::SIGINT);
    assert!(stopped.status.success(), "exit status {}", stopped.status);
    assert!(
        stopped.took >= Duration::from_millis(900) && stopped.took < Duration::from_millis(1800),
        "took {:?}",
        stopped.took
    );
    let received = 1 + rx.recv(50, Duration::from_millis(300)).len();
    assert!(received < 50, "the backlog cannot have drained: {received}");
    // The report at exit (the ones asked for above came before it).
    let all = stopped.stderr.join("\n");
    let err = &all[all.rfind("mavtables counters:").unwrap_or(0)..];
    let line = format!(
        "127.0.0.1:{}: in 1 frames (21 bytes), out {received} frames ({} bytes)",
        rx.port(),
        received * 267
    );
    assert!(err.contains(&line), "want {line:?} in:\n{err}");
    assert!(
        err.contains(&format!(
            "127.0.0.1:{}: in 50 frames (13350 bytes)",
            tx.port()
        )),
        "{err}"
    );
}

/// A router on one UDP port with listener `a` (12.26) learned and sender `b` (1.1) whose
/// first ATTITUDE `a` has received.
fn listener_and_sender(tag: &str) -> (Scratch, Router, UdpPeer, UdpPeer) {
    let s = Scratch::new(tag);
    let port = free_udp_port();
    let config = udp_block(port, "") + REJECT_HEARTBEAT_ACCEPT;
    let mut router = Router::start(&s, &config, 1);
    let a = UdpPeer::new(port);
    a.send(&heartbeat(12, 26));
    router.wait_for("new component 12.26 on 127.0.0.1:");
    let b = UdpPeer::new(port);
    b.send(&frame("ATTITUDE", true, 0, 1, 1, 5));
    router.wait_for("new component 1.1 on 127.0.0.1:");
    assert_eq!(a.recv(1, 5 * SECOND).len(), 1);
    (s, router, a, b)
}

/// A MAVLink 2 frame longer than its message's known length (extension fields of a newer
/// dialect) whose checksum holds is forwarded byte for byte and counted as "longer than
/// known"; the same frame with a bad checksum is not.
#[test]
fn a_frame_longer_than_known_is_forwarded_unchanged() {
    let (_s, router, a, b) = listener_and_sender("longer");
    let header = Header {
        seq: 9,
        system: 1,
        component: 1,
    };
    // ATTITUDE is 28 bytes; 8 more of an extension this dialect does not know.
    let mut longer = Vec::new();
    mavtables::wire::encode::encode_v2_exact(header, 30, &[0x33; 36], &mut longer).expect("encode");
    let mut broken = longer.clone();
    let last = broken.len() - 1;
    broken[last] ^= 0xff;
    b.send(&broken);
    b.send(&longer);
    assert_eq!(a.recv(1, 5 * SECOND), [longer]);
    let counters = router.stop().stderr.join("\n");
    assert!(counters.contains(", 1 longer than known,"), "{counters}");
    assert!(counters.contains(" 1 bad checksum,"), "{counters}");
}

/// A burst reaches every receiver as one datagram per frame, in order, whatever the
/// frames' lengths. (The router hands runs of equal-length datagrams for one receiver to
/// the kernel as one UDP GSO message; the receivers here are plain sockets, so this
/// checks that the kernel cuts them back into exactly the datagrams sent.)
#[test]
fn a_burst_arrives_one_frame_per_datagram_in_order() {
    let (_s, mut router, a, b) = listener_and_sender("burst");
    let c = UdpPeer::new(
        b.router
            .rsplit(':')
            .next()
            .and_then(|p| p.parse().ok())
            .expect("port"),
    );
    c.send(&heartbeat(12, 27));
    router.wait_for("new component 12.27 on 127.0.0.1:");
    // Runs of one length, broken by shorter and longer frames, v1 and v2 mixed: 120
    // frames in 12 datagrams of 10, sent back to back so the router reads them together.
    let kinds = [
        ("ATTITUDE", true),
        ("ATTITUDE", true),
        ("ATTITUDE", true),
        ("SYS_STATUS", true),
        ("ATTITUDE", true),
        ("ATTITUDE", false),
        ("GPS_RAW_INT", true),
        ("GPS_RAW_INT", true),
        ("SCALED_PRESSURE", true),
        ("ATTITUDE", true),
    ];
    let frames: Vec<Vec<u8>> = (0..120u8)
        .map(|i| {
            let (name, v2) = kinds[usize::from(i) % kinds.len()];
            frame(name, v2, i, 1, 1, i)
        })
        .collect();
    for chunk in frames.chunks(10) {
        b.send(&chunk.concat());
    }
    assert_eq!(a.recv(frames.len(), 10 * SECOND), frames, "receiver 12.26");
    assert_eq!(c.recv(frames.len(), 10 * SECOND), frames, "receiver 12.27");
    // The counters agree (`a` also got the ATTITUDE of `listener_and_sender`).
    let stderr = router.stop().stderr;
    let line = |port: u16| {
        stderr
            .iter()
            .find(|l| l.contains(&format!("127.0.0.1:{port}: in 1 frames")))
            .cloned()
            .unwrap_or_default()
    };
    assert!(line(a.port()).contains("out 121 frames"), "{stderr:?}");
    assert!(line(c.port()).contains("out 120 frames"), "{stderr:?}");
}

/// The router's peak resident memory, from `/proc`.
fn peak_rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmHWM")
}

/// A flood from hundreds of source ports (spoofed senders, say) onto a slow interface
/// fills every link's queue at once; all queues together stay within the router's
/// shared bound, so memory stays small, and the router keeps routing elsewhere.
#[test]
fn a_flood_from_many_ports_cannot_grow_memory() {
    let s = Scratch::new("port-flood");
    let (slow, fast) = (free_udp_port(), free_udp_port());
    let config =
        udp_block(slow, "max_bitrate 8000; ") + &udp_block(fast, "") + REJECT_HEARTBEAT_ACCEPT;
    let mut router = Router::start(&s, &config, 0);
    // 400 senders, 25 broadcasts of 267 bytes each: every frame is queued for the
    // other 399 links, 4 million queue entries (1.2 GB in the queues' reckoning) if
    // nothing bounded them together.
    // Each sender is its own component, so that every link learns one to route to.
    let senders: Vec<UdpPeer> = (0..400).map(|_| UdpPeer::new(slow)).collect();
    for i in 0..25u8 {
        for (k, p) in senders.iter().enumerate() {
            let (sys, comp) = (1 + (k % 200) as u8, 1 + (k / 200) as u8);
            p.send(&frame("ENCAPSULATED_DATA", true, i, sys, comp, i));
        }
    }
    // Routing goes on: a listener on the other interface gets a frame sent now.
    let listener = UdpPeer::new(fast);
    listener.send(&heartbeat(12, 26));
    let probe = frame("ATTITUDE", true, 0, 5, 9, 9);
    let pid = router.pid();
    common::eventually("the probe arriving", 10 * SECOND, || {
        senders[0].send(&probe);
        listener.recv(1, SECOND / 10).contains(&probe)
    });
    // The queues together hold at most 16 MiB by default (unbounded, they would take
    // 1.2 GB here); the rest is the router itself, a few MiB.
    let peak = peak_rss_kib(pid);
    assert!(peak < 24 * 1024, "peak RSS {peak} KiB");
    let counters = router.stop().stderr.join("\n");
    assert!(counters.contains("dropped"), "{counters}");
}

/// SIGUSR1 prints the counters and the router keeps routing.
#[test]
fn sigusr1_prints_the_counters_and_routing_goes_on() {
    let (_s, mut router, a, b) = listener_and_sender("sigusr1");
    router.signal(libc::SIGUSR1);
    let line = router
        .err
        .wait_for(&format!("127.0.0.1:{}: in 1 frames", b.port()), 5 * SECOND);
    assert!(line.contains("out 0 frames"), "{line}");
    // Still routing after the signal.
    b.send(&frame("ATTITUDE", true, 1, 1, 1, 6));
    assert_eq!(a.recv(1, 5 * SECOND).len(), 1);
    let stopped = router.stop();
    let counters = stopped.stderr.join("\n");
    assert!(
        counters.contains(&format!("127.0.0.1:{}: in 2 frames", b.port())),
        "{counters}"
    );
}

/// Noise that looks like the start of a long frame must not hold up the valid frame
/// behind it when the line then goes quiet — on a serial port or in a UDP sender's last
/// datagram: the held-back bytes are judged once the line has been quiet long enough.
#[test]
fn a_frame_behind_noise_is_not_held_up_on_a_quiet_line() {
    let s = Scratch::new("quiet-noise");
    let UdpAndSerial {
        port,
        dev: _,
        mut master,
        slave: _slave,
        router,
        rx,
    } = udp_and_serial(&s);
    // `FE FE FD FD FD 6E` starts a v1 FILE_TRANSFER_PROTOCOL candidate claiming 262
    // bytes; then one valid frame; then silence.
    let noisy = |valid: &[u8]| -> Vec<u8> {
        let mut bytes = vec![0xFE, 0xFE, 0xFD, 0xFD, 0xFD, 0x6E];
        bytes.extend(valid);
        bytes
    };
    let from_serial = frame("ATTITUDE", true, 0, 1, 1, 5);
    let start = Instant::now();
    master.write_all(&noisy(&from_serial)).expect("pty write");
    let got = rx.recv(1, 5 * SECOND);
    let waited = start.elapsed();
    assert_eq!(got, vec![from_serial]);
    assert!(waited < 2 * SECOND, "the serial frame waited {waited:?}");

    let from_udp = frame("ATTITUDE", true, 0, 2, 1, 6);
    let tx = UdpPeer::new(port);
    let start = Instant::now();
    tx.send(&noisy(&from_udp));
    let got = rx.recv(1, 5 * SECOND);
    let waited = start.elapsed();
    assert_eq!(got, vec![from_udp]);
    assert!(waited < 2 * SECOND, "the UDP frame waited {waited:?}");
    router.stop();
}
