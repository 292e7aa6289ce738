//! MAVLink 2 signing through the router with independent peers: pymavlink (its own
//! `mav.signing`, plus an explicit hashlib check of every signature in
//! `tests/py/signing_peer.py`) and MAVProxy (`signing setup PASSPHRASE`).
//!
//! - signed peers on both sides: their frames cross the router byte for byte, signatures
//!   unbroken, both ways;
//! - an unsigned peer behind an interface without a key reaches a vehicle that requires
//!   signing: the router signs for it, with the keyed interface's index as link id;
//! - every frame the router signed verifies in pymavlink, and with hashlib;
//! - MAVProxy as a signing ground station over UDP and over TCP, with a signing vehicle
//!   behind another keyed interface (the same key given once as a passphrase, once as
//!   hex): heartbeats, every parameter, a command;
//! - MAVProxy as the signing vehicle side, refusing unsigned frames: what an unsigned
//!   pymavlink ground station sends reaches it signed by the router and is accepted,
//!   while a MAVLink 1 frame (which the router passes unsigned) is refused by it.
//!
//! A scratch tag or file name must not contain "udp": `Router::start` finds the UDP ports
//! by that word.

use crate::common;
use crate::signing;

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use common::mavproxy::wait_tcp_listening;
use common::net::free_tcp_port;
use common::router::{Router, Scratch, free_udp_port};
use common::{run_py, unhex};
use mavtables::wire::Frame;
use mavtables::wire::signing::verify;
use signing::{
    Key, MINUTE, Py, SigPeer, count_of, exit_report, hex, hex_key_file, key_file, key_from,
    mavproxy, now_ts, parse_stats, passphrase_key, py_script, report_now, signing_counts,
};

const T: Duration = Duration::from_secs(10);

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

fn frame(hex_text: &str) -> Vec<u8> {
    unhex(hex_text)
}

/// The header fields and payload of a frame, without its signature (what a re-signing
/// must keep).
fn content(bytes: &[u8]) -> (u8, u8, u8, u32, Vec<u8>) {
    let f = Frame::parse_exact(bytes).unwrap_or_else(|e| panic!("{}: {e}", hex(bytes)));
    (
        f.seq(),
        f.system(),
        f.component(),
        f.message_id(),
        f.payload().to_vec(),
    )
}

fn assert_near_now(ts: i64, what: &str) {
    let now = now_ts() as i64;
    assert!(
        (ts - now).abs() < MINUTE as i64,
        "{what}: timestamp {ts} is not within 60 s of the signing clock {now}"
    );
}

/// 1. Signing pymavlink peers on both sides of the router: a ground station on a keyed
///    UDP interface, a vehicle that requires signing on a keyed TCP interface. HEARTBEATs
///    both ways and a COMMAND_LONG / COMMAND_ACK exchange arrive byte for byte as sent,
///    with the sender's own link id (the router verified them and did not re-sign), and
///    neither peer refuses anything.
#[test]
fn signed_pymavlink_peers_both_ways_byte_for_byte() {
    let s = Scratch::new("sig-peers");
    let key = key_from(0x21);
    let kf = hex_key_file(&s, "shared.key", &key);
    let (port, tport) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {port}; address 127.0.0.1; signing_key {kf}; }}\n\
         tcp {{ port {tport}; address 127.0.0.1; signing_key {kf}; }}\n\
         default_action accept;\n"
    );
    let mut router = Router::start(&s, &config, 1);
    wait_tcp_listening(tport, T);
    let k = hex(&key);
    let mut vehicle = SigPeer::start(&args(&[
        "--tcp",
        &format!("127.0.0.1:{tport}"),
        "--sys",
        "1",
        "--comp",
        "1",
        "--key",
        &k,
        "--sign",
        "--link-id",
        "9",
        "--require-signed",
        "--vehicle",
    ]));
    let mut gcs = SigPeer::start(&args(&[
        "--udp",
        &format!("127.0.0.1:{port}"),
        "--sys",
        "255",
        "--comp",
        "190",
        "--key",
        &k,
        "--sign",
        "--link-id",
        "7",
        "--require-signed",
    ]));

    // The ground station speaks first (the router learns where it is).
    let sent = gcs.send("heartbeat");
    let got = vehicle.recv("HEARTBEAT", "255.190", T);
    assert_eq!(got.hex, sent, "the GCS's HEARTBEAT, byte for byte");
    assert!(got.signed && got.check == "ok" && got.link == 7, "{got:?}");

    let sent = vehicle.send("heartbeat 2");
    let got = gcs.recv("HEARTBEAT", "1.1", T);
    assert_eq!(got.hex, sent, "the vehicle's HEARTBEAT, byte for byte");
    assert!(got.signed && got.check == "ok" && got.link == 9, "{got:?}");

    let sent = gcs.send("command 1.1 400");
    let got = vehicle.recv("COMMAND_LONG", "255.190", T);
    assert_eq!(got.hex, sent, "the COMMAND_LONG, byte for byte");
    assert!(got.signed && got.check == "ok" && got.link == 7, "{got:?}");
    vehicle.py.wait_for("acked 400 to 255.190", T);
    let ack_sent = vehicle
        .py
        .out
        .seen
        .iter()
        .rev()
        .find_map(|l| l.strip_prefix("sent "))
        .expect("the ack as sent")
        .to_string();
    let got = gcs.recv("COMMAND_ACK", "1.1", T);
    assert_eq!(got.hex, ack_sent, "the COMMAND_ACK, byte for byte");
    assert!(got.signed && got.check == "ok" && got.link == 9, "{got:?}");

    let report = report_now(&mut router);
    let counts = signing_counts(&report);
    assert!(
        count_of(&counts, "verified") >= 4,
        "the router verified the 4 frames at least: {report:#?}"
    );
    assert_eq!(
        count_of(&counts, "signed"),
        0,
        "the router signed nothing (all was signed): {report:#?}"
    );
    for (who, peer) in [("vehicle", &mut vehicle), ("gcs", &mut gcs)] {
        let [sig, good, bad, unsigned, reject] = peer.stats();
        assert!(good >= 2 && sig == good, "{who}: {sig} signed, {good} good");
        assert_eq!((bad, unsigned, reject), (0, 0, 0), "{who} refused frames");
    }
    let all = [vehicle.stop(), gcs.stop()].concat();
    assert!(
        !all.iter().any(|l| l.starts_with("rejected")),
        "a peer refused a frame: {all:#?}"
    );
    router.stop();
}

/// 2 and 4. The router signs for an unsigned peer: an unsigned pymavlink "companion" on
///    an interface without a key sends a HEARTBEAT and a COMMAND_LONG; a pymavlink vehicle
///    on a keyed TCP interface (the config's third block: index 2) that refuses anything
///    not signed with its key accepts both, signed with link id 2 and a timestamp of the
///    signing clock; its answer, signed by itself, reaches the companion unchanged.
#[test]
fn router_signs_for_an_unsigned_companion() {
    let s = Scratch::new("sig-companion");
    let key = key_from(0x42);
    let kf = hex_key_file(&s, "vehicle.key", &key);
    let (port, spare, tport) = (free_udp_port(), free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {port}; address 127.0.0.1; }}\n\
         udp {{ port {spare}; address 127.0.0.1; }}\n\
         tcp {{ port {tport}; address 127.0.0.1; signing_key {kf}; }}\n\
         default_action accept;\n"
    );
    let mut router = Router::start(&s, &config, 1);
    wait_tcp_listening(tport, T);
    let mut vehicle = SigPeer::start(&args(&[
        "--tcp",
        &format!("127.0.0.1:{tport}"),
        "--sys",
        "1",
        "--comp",
        "1",
        "--key",
        &hex(&key),
        "--sign",
        "--link-id",
        "5",
        "--require-signed",
        "--vehicle",
    ]));
    let mut companion = SigPeer::start(&args(&[
        "--udp",
        &format!("127.0.0.1:{port}"),
        "--sys",
        "100",
        "--comp",
        "191",
    ]));

    let mut checked = Vec::new();
    let sent = companion.send("heartbeat 18");
    let got = vehicle.recv("HEARTBEAT", "100.191", T);
    checked.push((sent, got));
    let sent = vehicle.send("heartbeat 2");
    let got = companion.recv("HEARTBEAT", "1.1", T);
    assert_eq!(
        got.hex, sent,
        "the vehicle's own signed frame passes unchanged"
    );
    assert_eq!((got.link, got.check.as_str()), (5, "none"), "{got:?}");
    let sent = companion.send("command 1.1 400");
    let got = vehicle.recv("COMMAND_LONG", "100.191", T);
    checked.push((sent, got));
    vehicle.py.wait_for("acked 400 to 100.191", T);
    let ack = companion.recv("COMMAND_ACK", "1.1", T);
    assert!(
        ack.link == 5,
        "the vehicle's ACK, signed by the vehicle: {ack:?}"
    );

    let mut last_ts = 0;
    for (sent, got) in &checked {
        assert!(got.signed, "pymavlink did not take it as signed: {got:?}");
        assert_eq!(got.check, "ok", "the hashlib check: {got:?}");
        assert_eq!(
            got.link, 2,
            "link id = the keyed interface's index: {got:?}"
        );
        assert_near_now(got.ts, &got.name);
        assert!(got.ts > last_ts, "timestamps go up: {checked:?}");
        last_ts = got.ts;
        let bytes = frame(&got.hex);
        assert_eq!(content(&bytes), content(&frame(sent)), "{}", got.name);
        let parsed = Frame::parse_exact(&bytes).expect("frame");
        assert!(
            verify(&parsed, &key),
            "our own check of the router's signature"
        );
        let mut other = key;
        other[0] ^= 1;
        assert!(!verify(&parsed, &other), "the check can fail");
    }
    let [sig, good, bad, unsigned, reject] = vehicle.stats();
    assert_eq!((sig, good), (2, 2), "the vehicle's accepted signed frames");
    assert_eq!((bad, unsigned, reject), (0, 0, 0));
    // While the vehicle's TCP connection, whose link line has them, is still open.
    let counts = signing_counts(&report_now(&mut router));
    assert!(
        count_of(&counts, "signed") >= 2 && count_of(&counts, "verified") >= 2,
        "the router counted the frames it signed and verified: {counts:?}"
    );
    vehicle.stop();
    companion.stop();
    router.stop();
}

/// 4. Twenty unsigned frames of ten message types, from a plain socket on an interface
///    without a key, reach a pymavlink listener on a keyed UDP interface (index 1) signed
///    by the router: pymavlink accepts each as signed, hashlib confirms each signature,
///    the link id is 1, timestamps strictly increase and lie within 60 s of the signing
///    clock, and header and payload are those sent. The existing `signing.py verify`
///    (another pymavlink parser, key 0..31) agrees.
#[test]
fn frames_the_router_signed_verify_in_pymavlink() {
    let s = Scratch::new("sig-verify");
    let key: Key = std::array::from_fn(|i| i as u8); // signing.py's KEY
    let kf = hex_key_file(&s, "listener.key", &key);
    let (p0, p1) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {p0}; address 127.0.0.1; }}\n\
         udp {{ port {p1}; address 127.0.0.1; signing_key {kf}; }}\n\
         default_action accept;\n"
    );
    let router = Router::start(&s, &config, 1);
    let mut listener = SigPeer::start(&args(&[
        "--udp",
        &format!("127.0.0.1:{p1}"),
        "--sys",
        "250",
        "--comp",
        "1",
        "--key",
        &hex(&key),
        "--sign",
        "--link-id",
        "3",
        "--require-signed",
    ]));
    let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let to = format!("127.0.0.1:{p0}");
    // The listener's signed HEARTBEAT teaches the router where it is; ours (which it
    // receives, signed) shows the router knows both.
    listener.send("heartbeat");
    let hb = signing::unsigned(60, 1, 0, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]);
    common::eventually("the listener hearing us", T, || {
        sock.send_to(&hb, &to).expect("send");
        listener
            .py
            .out
            .within("recv HEARTBEAT from 60.1", Duration::from_millis(300))
            .is_some()
    });

    let ids = [0u32, 1, 22, 24, 30, 33, 74, 76, 147, 253];
    let mut sent = Vec::new();
    for n in 0..20u8 {
        let id = ids[n as usize % ids.len()];
        let info = mavtables::dialect::by_id(id).expect("known id");
        let mut payload: Vec<u8> = (0..info.min_len)
            .map(|i| 0x41 + (i.wrapping_add(n) % 26))
            .collect();
        if id == 76 {
            payload[30..32].copy_from_slice(&[0, 0]); // COMMAND_LONG to everyone
        }
        let f = signing::unsigned(61, 2, n, id, &payload);
        sock.send_to(&f, &to).expect("send");
        sent.push(f);
    }
    let deadline = Instant::now() + T;
    let got = loop {
        let got: Vec<_> = listener
            .all_received()
            .into_iter()
            .filter(|r| r.source == "61.2")
            .collect();
        if got.len() >= sent.len() || Instant::now() > deadline {
            break got;
        }
        listener.py.out.within("recv ", Duration::from_millis(200));
    };
    assert_eq!(got.len(), sent.len(), "all 20 arrived: {got:#?}");
    let mut last = 0;
    for (r, f) in got.iter().zip(&sent) {
        assert!(r.signed && r.check == "ok", "{r:?}");
        assert_eq!(r.link, 1, "{r:?}");
        assert!(r.ts > last, "timestamps strictly increase: {r:?}");
        last = r.ts;
        assert_near_now(r.ts, &r.name);
        assert_eq!(content(&frame(&r.hex)), content(f), "{}", r.name);
    }
    let lines: String = got.iter().map(|r| format!("{}\n", r.hex)).collect();
    let verdicts = run_py("signing.py", &["verify"], &lines);
    assert_eq!(
        verdicts.split_whitespace().collect::<Vec<_>>(),
        vec!["ok"; 20],
        "signing.py verify"
    );
    let [_, good, bad, _, reject] = listener.stats();
    assert!(good >= 21, "{good} good");
    assert_eq!((bad, reject), (0, 0));
    listener.stop();
    router.stop();
}

const PASSPHRASE: &str = "mavtables-signing-test-passphrase";

/// The line containing `pattern` that `p` printed already, or else the next one.
fn seen_or_wait(p: &mut Py, pattern: &str, timeout: Duration) -> String {
    match p.out.seen.iter().find(|l| l.contains(pattern)) {
        Some(line) => line.clone(),
        None => p.wait_for(pattern, timeout),
    }
}

/// Starts the signing vehicle (`tests/py/signing_vehicle.py`) on `link` (`--tcp` etc.).
fn signing_vehicle(link: &[&str], key: &Key) -> Py {
    let mut a = args(link);
    a.extend(args(&["--key", &hex(key), "--link-id", "4"]));
    let mut v = py_script("signing_vehicle.py", &a);
    v.wait_for("ready", Duration::from_secs(20));
    v
}

/// MAVProxy, signing with PASSPHRASE and refusing unsigned frames, downloads every
/// parameter of the signing vehicle and arms it; the vehicle refused nothing, so every
/// frame of MAVProxy's that reached it was signed (the unsigned ones MAVProxy sent before
/// `signing setup`, and the SETUP_SIGNING itself, were dropped by the router).
fn signed_ground_station_session(mut router: Router, mut gcs: Py, mut vehicle: Py) {
    let start = Instant::now();
    let limit = Duration::from_secs(60);
    let left = || limit.saturating_sub(start.elapsed());
    gcs.send_line("set allow_unsigned 0");
    gcs.send_line(&format!("signing setup {PASSPHRASE}"));
    gcs.wait_for("Setup signing key", left());
    // The vehicle's HEARTBEATs, signed by the vehicle, may have reached MAVProxy before
    // its `signing setup` (it takes anything until then), and the download started.
    seen_or_wait(&mut gcs, "Detected vehicle 1:1", left());
    let received = seen_or_wait(&mut gcs, "Received ", left());
    assert!(
        received.contains("Received 300 parameters"),
        "MAVProxy's parameter download: {received}"
    );
    vehicle.wait_for("param list sent 300", left());
    gcs.send_line("arm throttle");
    vehicle.wait_for("command 400 from 255.", left());
    gcs.wait_for("ARMED", left());
    eprintln!("signed session took {:?}", start.elapsed());
    let counts = signing_counts(&report_now(&mut router));
    assert!(count_of(&counts, "verified") > 300, "{counts:?}");
    let gcs_lines = gcs.finish(Duration::from_secs(10));
    let vehicle_lines = vehicle.finish(Duration::from_secs(10));
    let stats = vehicle_lines
        .iter()
        .find(|l| l.starts_with("signing "))
        .unwrap_or_else(|| panic!("no stats from the vehicle: {vehicle_lines:#?}"));
    let [sig, good, bad, unsigned, reject] = parse_stats(stats);
    assert!(good > 300 / 50 && sig == good, "vehicle: {stats}");
    assert_eq!(
        (bad, unsigned, reject),
        (0, 0, 0),
        "the vehicle refused frames that the router let through: {stats}"
    );
    assert!(
        !gcs_lines.iter().any(|l| l.contains("Invalid signature")),
        "MAVProxy refused frames: {gcs_lines:#?}"
    );
    router.stop();
}

/// 3. MAVProxy (`signing setup PASSPHRASE`) a UDP client of a router UDP server whose key
///    file holds the passphrase; the signing vehicle a TCP client of a router TCP server
///    whose key file holds the same key as 64 hex digits.
#[test]
fn mavproxy_signing_over_udp_vehicle_signing_over_tcp() {
    let s = Scratch::new("sig-mavproxy-u");
    let key = passphrase_key(PASSPHRASE);
    let gcs_kf = key_file(&s, "gcs.key", PASSPHRASE);
    let veh_kf = hex_key_file(&s, "vehicle.key", &key);
    let (port, tport) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {port}; address 127.0.0.1; signing_key {gcs_kf}; }}\n\
         tcp {{ port {tport}; address 127.0.0.1; signing_key {veh_kf}; }}\n\
         default_action accept;\n"
    );
    let router = Router::start(&s, &config, 1);
    wait_tcp_listening(tport, T);
    let vehicle = signing_vehicle(&["--tcp", &format!("127.0.0.1:{tport}")], &key);
    let gcs = mavproxy(&s, &format!("udpout:127.0.0.1:{port}"), &["--show-errors"]);
    signed_ground_station_session(router, gcs, vehicle);
}

/// 3. The same over TCP: MAVProxy a TCP client of a keyed router TCP server, the signing
///    vehicle a UDP client of a keyed router UDP server.
#[test]
fn mavproxy_signing_over_tcp_vehicle_signing_over_udp() {
    let s = Scratch::new("sig-mavproxy-t");
    let key = passphrase_key(PASSPHRASE);
    let gcs_kf = key_file(&s, "gcs.key", PASSPHRASE);
    let veh_kf = hex_key_file(&s, "vehicle.key", &key);
    let (port, tport) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "tcp {{ port {tport}; address 127.0.0.1; signing_key {gcs_kf}; }}\n\
         udp {{ port {port}; address 127.0.0.1; signing_key {veh_kf}; }}\n\
         default_action accept;\n"
    );
    let router = Router::start(&s, &config, 1);
    wait_tcp_listening(tport, T);
    let vehicle = signing_vehicle(&["--udp", &format!("127.0.0.1:{port}")], &key);
    let gcs = mavproxy(&s, &format!("tcp:127.0.0.1:{tport}"), &["--show-errors"]);
    signed_ground_station_session(router, gcs, vehicle);
}

/// 3. MAVProxy on the vehicle side of a keyed interface, with `signing setup PASSPHRASE`
///    and `allow_unsigned 0`; an unsigned pymavlink ground station on an interface without
///    a key. MAVProxy's signed HEARTBEATs reach the ground station (and none of its
///    unsigned ones from before the setup); the ground station's unsigned HEARTBEAT and
///    STATUSTEXT reach MAVProxy signed by the router and are accepted ("Detected vehicle
///    200:1", the text shown), while its MAVLink 1 STATUSTEXT, which the router passes
///    unsigned, is refused by MAVProxy ("Invalid signature": the check is live).
#[test]
fn mavproxy_accepts_what_the_router_signed() {
    let s = Scratch::new("sig-mavproxy-v");
    let kf = key_file(&s, "mavproxy.key", PASSPHRASE);
    let (p0, p1) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {p0}; address 127.0.0.1; }}\n\
         udp {{ port {p1}; address 127.0.0.1; signing_key {kf}; }}\n\
         default_action accept;\n"
    );
    let router = Router::start(&s, &config, 1);
    let mut gcs = SigPeer::start(&args(&[
        "--udp",
        &format!("127.0.0.1:{p0}"),
        "--sys",
        "200",
        "--comp",
        "1",
    ]));
    let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let start = Instant::now();
    gcs.send("heartbeat 2");
    let mut mp = mavproxy(&s, &format!("udpout:127.0.0.1:{p1}"), &["--show-errors"]);
    mp.send_line("set allow_unsigned 0");
    mp.send_line(&format!("signing setup {PASSPHRASE}"));
    mp.wait_for("Setup signing key", T);
    let hb = gcs.recv("HEARTBEAT", "255.", Duration::from_secs(20));
    assert!(hb.link >= 0, "MAVProxy's HEARTBEAT is signed: {hb:?}");

    // MAVLink 1 passes the keyed egress unsigned: MAVProxy must refuse it.
    let text = b"v1 frame, unsigned";
    let mut payload = vec![6u8];
    payload.extend_from_slice(text);
    sock.send_to(
        &signing::v1(200, 1, 0, 253, &payload),
        format!("127.0.0.1:{p0}"),
    )
    .expect("send");
    mp.wait_for("Invalid signature", T);
    // MAVLink 2, signed by the router: accepted.
    gcs.send("heartbeat 2");
    mp.wait_for("Detected vehicle 200:1", T);
    gcs.send("text signed by the router");
    mp.wait_for("signed by the router", T);
    eprintln!("session took {:?}", start.elapsed());
    let mp_lines = mp.finish(Duration::from_secs(10));
    assert!(
        !mp_lines.iter().any(|l| l.contains("v1 frame, unsigned")),
        "MAVProxy showed the unsigned text: {mp_lines:#?}"
    );
    let from_mavproxy: Vec<_> = gcs
        .all_received()
        .into_iter()
        .filter(|r| r.source.starts_with("255."))
        .collect();
    assert!(!from_mavproxy.is_empty());
    assert!(
        from_mavproxy.iter().all(|r| r.link >= 0),
        "an unsigned frame of MAVProxy's got through the keyed interface: {from_mavproxy:#?}"
    );
    gcs.stop();
    let stopped = router.stop();
    let counts = signing_counts(&exit_report(&stopped.stderr));
    assert!(count_of(&counts, "signed") >= 2, "{counts:?}");
}
