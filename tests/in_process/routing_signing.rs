//! MAVLink 2 signing in the routing core, on a simulated clock: what a keyed interface
//! takes in (signature, stream order, clock window, unsigned policy), what it signs on
//! the way out, and the saved state that keeps replays out after a restart. Peers and
//! sockets are in `tests/signing_*.rs`.

use crate::routing;

use std::collections::VecDeque;
use std::net::SocketAddr;

use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, Notice, RouterOptions, Timestamp, Transmit};
use mavtables::signing::SigningKey;
use mavtables::signing::clock::UNITS_PER_SEC;
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, SignWith, encode_v2};
use mavtables::wire::signing::verify;
use routing::{frame, frame_v1};

const KEY: [u8; 32] = [0x42; 32];
const OTHER_KEY: [u8; 32] = [0x43; 32];
/// The wall clock of the simulated router: some day in 2026, in signature units.
const WALL: u64 = 11 * 365 * 24 * 3600 * UNITS_PER_SEC;

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// `frame(name, from, to)` signed with `key`, `link_id` and `timestamp`.
fn signed_with(key: &[u8; 32], name: &str, from: &str, timestamp: u64) -> Vec<u8> {
    let plain = frame(name, from, None);
    let f = Frame::parse_exact(&plain).expect("valid");
    let header = Header {
        seq: f.seq(),
        system: f.source().system,
        component: f.source().component,
    };
    let mut out = Vec::new();
    let signing = SignWith {
        key,
        link_id: 1,
        timestamp,
    };
    encode_v2(header, f.message_id(), f.payload(), Some(signing), &mut out).expect("encode");
    out
}

fn signed(name: &str, from: &str, timestamp: u64) -> Vec<u8> {
    signed_with(&KEY, name, from, timestamp)
}

/// An engine with a keyed datagram interface (`allow_unsigned` as given) whose peer 1 is
/// a listener (system 200, learned from a signed heartbeat), and an unkeyed one whose
/// peer 2 is another listener (system 201).
struct Rig {
    e: Engine,
    keyed: InterfaceId,
    open: InterfaceId,
    clock: u64,
}

impl Rig {
    fn new(conf: &str, allow_unsigned: bool) -> Rig {
        let config = config::load(conf).expect("config").config;
        let mut e = Engine::new(&config, RouterOptions::default());
        let keyed = e.add_datagram_interface("udp keyed".into(), 0, Default::default());
        let open = e.add_datagram_interface("udp open".into(), 0, Default::default());
        e.set_signing(keyed, SigningKey::from_bytes(KEY), allow_unsigned, 7);
        e.set_wall_clock(Timestamp::ZERO, WALL);
        let mut rig = Rig {
            e,
            keyed,
            open,
            clock: WALL,
        };
        let hb = signed("HEARTBEAT", "200.1", rig.next());
        rig.e.handle_datagram(keyed, peer(1), &hb, Timestamp::ZERO);
        let hb = frame("HEARTBEAT", "201.1", None);
        rig.e.handle_datagram(open, peer(2), &hb, Timestamp::ZERO);
        rig.sent(keyed);
        rig.sent(open);
        rig.notices();
        rig
    }

    /// The next timestamp of the simulated ground station.
    fn next(&mut self) -> u64 {
        self.clock += 1;
        self.clock
    }

    /// Everything interface `iface` sends now.
    fn sent(&mut self, iface: InterfaceId) -> Vec<Transmit> {
        let mut q = VecDeque::new();
        self.e.poll_transmit(iface, Timestamp::ZERO, 1024, &mut q);
        q.iter().for_each(|t| self.e.on_sent(t));
        q.into()
    }

    fn notices(&mut self) -> Vec<String> {
        std::iter::from_fn(|| self.e.poll_event())
            .filter_map(|n| match n {
                Notice::Warning(w) => Some(w),
                _ => None,
            })
            .collect()
    }

    /// Sends `bytes` from peer 3 of the keyed interface; returns how many frames reached
    /// the unkeyed interface's listener.
    fn through(&mut self, bytes: &[u8]) -> usize {
        self.e
            .handle_datagram(self.keyed, peer(3), bytes, Timestamp::ZERO);
        self.sent(self.open).len()
    }
}

const ACCEPT_ALL: &str = "default_action accept;";

#[test]
fn verified_frames_pass_and_forged_ones_never_do() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let t = r.next();
    let good = signed("ATTITUDE", "1.1", t);
    assert_eq!(r.through(&good), 1, "a valid signed frame is routed");
    assert_eq!(r.through(&good), 0, "the same bytes again are a replay");

    let mut flipped = signed("ATTITUDE", "1.1", r.next());
    let last = flipped.len() - 1;
    flipped[last] ^= 1;
    assert_eq!(r.through(&flipped), 0, "a wrong signature is refused");

    let other = signed_with(&OTHER_KEY, "ATTITUDE", "1.1", r.next());
    assert_eq!(r.through(&other), 0, "another key's signature is refused");

    let unsigned = frame("ATTITUDE", "1.1", None);
    assert_eq!(
        r.through(&unsigned),
        0,
        "unsigned frames are refused by default"
    );

    let older = signed("ATTITUDE", "1.1", t - 1);
    assert_eq!(
        r.through(&older),
        0,
        "an older timestamp on a known stream is a replay"
    );

    let future = signed("ATTITUDE", "2.1", WALL + 61 * UNITS_PER_SEC);
    assert_eq!(r.through(&future), 0, "more than a minute ahead is refused");
    let stale = signed("ATTITUDE", "3.1", WALL - 61 * UNITS_PER_SEC);
    assert_eq!(
        r.through(&stale),
        0,
        "a new stream over a minute old is refused"
    );
    // The refused far-future frame did not poison stream 2.1: normal traffic flows.
    let normal = signed("ATTITUDE", "2.1", r.next());
    assert_eq!(r.through(&normal), 1);
    // Streams are per source: 4.1 may start anywhere within the window.
    let behind = signed("ATTITUDE", "4.1", WALL - 59 * UNITS_PER_SEC);
    assert_eq!(r.through(&behind), 1);

    let warnings = r.notices().join("\n");
    for said in [
        "bad signature",
        "replayed frame",
        "61 s ahead of this router's clock",
        "unsigned frame",
    ] {
        assert!(warnings.contains(said), "{said:?} not said in:\n{warnings}");
    }
    assert_eq!(warnings.matches("bad signature").count(), 1, "said once");
    let report = r.e.report();
    let keyed = report
        .lines()
        .find(|l| l.contains("udp keyed"))
        .expect("line");
    assert!(
        keyed.ends_with(
            "signing: 4 verified, 2 bad signature, 2 replayed, 2 out of window, 1 unsigned dropped, 1 signed"
        ),
        "{keyed}"
    );
    assert!(
        !report.contains("0x42") && !report.contains("4242"),
        "no key in output"
    );
}

#[test]
fn allow_unsigned_takes_unsigned_frames_but_never_bad_signatures() {
    let mut r = Rig::new(ACCEPT_ALL, true);
    assert_eq!(r.through(&frame("ATTITUDE", "1.1", None)), 1);
    assert_eq!(r.through(&frame_v1("ATTITUDE", "1.1", None)), 1);
    let mut bad = signed("ATTITUDE", "1.1", r.next());
    let last = bad.len() - 1;
    bad[last] ^= 0x80;
    assert_eq!(r.through(&bad), 0);
}

#[test]
fn a_remote_whose_frames_are_all_refused_never_becomes_a_link() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    for port in 10..20 {
        let forged = signed_with(&OTHER_KEY, "HEARTBEAT", "9.1", 1);
        r.e.handle_datagram(r.keyed, peer(port), &forged, Timestamp::ZERO);
    }
    let links = r.e.router().links().count();
    assert_eq!(links, 2, "only the two listeners are links");
}

#[test]
fn frames_leaving_a_keyed_interface_are_signed_unless_signed_or_v1() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    // From the unkeyed side to the keyed listener (system 200).
    let plain = frame("ATTITUDE", "201.1", None);
    let v1 = frame_v1("ATTITUDE", "201.1", None);
    let theirs = signed("ATTITUDE", "201.1", 5);
    for bytes in [&plain, &plain, &v1, &theirs] {
        r.e.handle_datagram(r.open, peer(2), bytes, Timestamp::ZERO);
    }
    let out = r.sent(r.keyed);
    assert_eq!(out.len(), 4);
    let mut last_ts = 0;
    for t in &out[..2] {
        let f = Frame::parse_exact(&t.packet).expect("a valid frame");
        assert!(verify(&f, &KEY), "signed with the interface's key");
        let sig = f.signature().expect("signed");
        assert_eq!(sig.link_id(), 7);
        assert!(sig.timestamp() > last_ts, "timestamps strictly increase");
        assert!(sig.timestamp() >= WALL, "from the router's clock");
        last_ts = sig.timestamp();
        assert_eq!(
            f.payload(),
            Frame::parse_exact(&plain).expect("valid").payload()
        );
    }
    assert_eq!(&out[2].packet[..], &v1[..], "MAVLink 1 passes as it is");
    assert_eq!(
        &out[3].packet[..],
        &theirs[..],
        "a sender's signature is kept"
    );
    // The listener's heartbeat in the rig, and the two MAVLink 2 frames.
    let report = r.e.report();
    assert!(report.contains(", 3 signed"), "{report}");
}

#[test]
fn accepted_connections_take_the_servers_key() {
    let config = config::load(ACCEPT_ALL).expect("config").config;
    let mut e = Engine::new(&config, RouterOptions::default());
    let server = e.add_listener("tcp keyed".into(), Default::default(), 0);
    e.set_signing(server, SigningKey::from_bytes(KEY), false, 0);
    e.set_wall_clock(Timestamp::ZERO, WALL);
    let conn = e
        .accept(server, peer(9), Timestamp::ZERO)
        .expect("accepted");
    e.handle_stream(conn, &frame("HEARTBEAT", "1.1", None), Timestamp::ZERO);
    e.handle_stream(conn, &signed("HEARTBEAT", "1.1", WALL), Timestamp::ZERO);
    let report = e.report();
    let line = report
        .lines()
        .find(|l| l.contains("tcp:127.0.0.1:9"))
        .expect("line");
    assert!(
        line.contains("1 verified") && line.contains("1 unsigned dropped"),
        "{report}"
    );
}

#[test]
fn saved_state_keeps_replays_out_after_a_restart() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let captured = signed("ATTITUDE", "1.1", r.next());
    assert_eq!(r.through(&captured), 1);
    let clean = r.e.signing_state(true, Timestamp::ZERO).expect("state");
    assert!(clean.clean);
    assert!(
        r.e.signing_state(false, Timestamp::ZERO).is_none(),
        "nothing changed since"
    );

    // A new router, as after a restart, on the saved state.
    let text = clean.to_text();
    assert!(
        !text.contains("4242"),
        "the file names keys by fingerprint only"
    );
    let saved = mavtables::signing::state::SavedState::parse(&text).expect("parses");
    let mut again = Rig::new(ACCEPT_ALL, false);
    again.e.restore_signing_state(&saved);
    assert_eq!(again.through(&captured), 0, "replayed after the restart");
    let next = signed("ATTITUDE", "1.1", captured_ts(&captured) + 1);
    assert_eq!(again.through(&next), 1, "the stream goes on");

    // After a crash (the file written while running), the streams' floors are raised:
    // frames accepted after that write cannot be replayed either.
    let mut crashed = r.e.signing_state(true, Timestamp::ZERO).expect("state");
    crashed.clean = false;
    let mut third = Rig::new(ACCEPT_ALL, false);
    third.e.restore_signing_state(&crashed);
    let soon_after = signed("ATTITUDE", "1.1", captured_ts(&captured) + UNITS_PER_SEC);
    assert_eq!(third.through(&soon_after), 0);
}

fn captured_ts(bytes: &[u8]) -> u64 {
    let f = Frame::parse_exact(bytes).expect("valid");
    f.signature().expect("signed").timestamp()
}

#[test]
fn the_routers_signatures_never_go_back_across_a_restart() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    r.e.handle_datagram(
        r.open,
        peer(2),
        &frame("ATTITUDE", "201.1", None),
        Timestamp::ZERO,
    );
    let first = r.sent(r.keyed);
    let ts = captured_ts(&first[0].packet);
    let state = r.e.signing_state(true, Timestamp::ZERO).expect("state");
    // The next run's wall clock is an hour behind (a board without a real-time clock).
    let config = config::load(ACCEPT_ALL).expect("config").config;
    let mut e = Engine::new(&config, RouterOptions::default());
    let keyed = e.add_datagram_interface("udp keyed".into(), 0, Default::default());
    let open = e.add_datagram_interface("udp open".into(), 0, Default::default());
    e.set_signing(keyed, SigningKey::from_bytes(KEY), true, 7);
    e.set_wall_clock(Timestamp::ZERO, WALL - 3600 * UNITS_PER_SEC);
    e.restore_signing_state(&state);
    e.handle_datagram(
        keyed,
        peer(1),
        &frame("HEARTBEAT", "200.1", None),
        Timestamp::ZERO,
    );
    e.handle_datagram(
        open,
        peer(2),
        &frame("ATTITUDE", "201.1", None),
        Timestamp::ZERO,
    );
    let mut q = VecDeque::new();
    e.poll_transmit(keyed, Timestamp::ZERO, 8, &mut q);
    assert_eq!(q.len(), 1);
    assert!(captured_ts(&q[0].packet) > ts);
}

#[test]
fn rules_match_frames_the_router_verified() {
    let conf = "chain default {\n    reject if unsigned ATTITUDE;\n    accept;\n}\ndefault_action accept;\n";
    let mut r = Rig::new(conf, true);
    assert_eq!(
        r.through(&frame("ATTITUDE", "1.1", None)),
        0,
        "unsigned: rejected"
    );
    assert_eq!(
        r.through(&frame("SYS_STATUS", "1.1", None)),
        1,
        "other types pass"
    );
    let t = r.next();
    assert_eq!(
        r.through(&signed("ATTITUDE", "1.1", t)),
        1,
        "verified: accepted"
    );
    // A signature the router has no key for (an interface without one) is unsigned.
    let theirs = signed("ATTITUDE", "201.1", 5);
    r.sent(r.keyed); // what the frames above sent to the keyed listener
    r.e.handle_datagram(r.open, peer(2), &theirs, Timestamp::ZERO);
    assert!(r.sent(r.keyed).is_empty(), "signed, but not verified here");
}

#[test]
fn only_frames_that_pass_the_check_are_recorded() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    r.e.set_recording(mavtables::recording::RecordFilter::new(Vec::new()));
    let good = signed("ATTITUDE", "1.1", r.next());
    let mut forged = signed("ATTITUDE", "1.1", r.next());
    let last = forged.len() - 1;
    forged[last] ^= 1;
    let unsigned = frame("ATTITUDE", "1.1", None);
    for bytes in [&forged, &good, &good, &unsigned] {
        r.through(bytes);
    }
    let mut recorded = Vec::new();
    r.e.poll_recorded(&mut |_, bytes| recorded.push(bytes.to_vec()));
    assert_eq!(
        recorded,
        [good],
        "the forgery, the replay and the unsigned frame are not flight data"
    );
}

/// A copy of a frame taken in within the `dedup` window is dropped before the replay
/// check (the same frame over a second radio), but at an interface with a key it must
/// still pass the signature check, and a signed copy from a remote that has no link
/// yet is refused as a replay: a copy makes no one a link.
#[test]
fn a_copy_within_the_dedup_window_makes_no_one_a_link_at_a_keyed_interface() {
    let conf = "dedup 500ms;\n\
        udp { port 14550; signing_key /nonexistent/gcs.key; }\n\
        udp { port 14560; }\n\
        default_action accept;\n";
    let config = config::load(conf).expect("config").config;
    let mut e = Engine::new(&config, RouterOptions::default());
    let keys = [Some(SigningKey::from_bytes(KEY)), None];
    let done = e.configure(&config, &keys, Timestamp::ZERO);
    let ids: Vec<InterfaceId> = (done.requests.iter())
        .filter_map(|r| match r {
            mavtables::routing::Request::Open(id, _) => Some(*id),
            _ => None,
        })
        .collect();
    let [keyed, open] = ids[..] else {
        panic!("two interfaces: {ids:?}")
    };
    e.set_wall_clock(Timestamp::ZERO, WALL);
    let now = Timestamp::ZERO;
    // The ground station has two remotes (two paths to it).
    e.handle_datagram(keyed, peer(1), &signed("HEARTBEAT", "200.1", WALL + 1), now);
    e.handle_datagram(keyed, peer(3), &signed("HEARTBEAT", "200.2", WALL + 2), now);
    // An unsigned frame, taken in on the open interface, then sent again by a stranger
    // to the keyed one.
    let plain = frame("ATTITUDE", "201.1", None);
    e.handle_datagram(open, peer(2), &plain, now);
    let links = e.router().links().count();
    e.handle_datagram(keyed, peer(9), &plain, now);
    // The ground station's signed frame, and a stranger's copy of it.
    let captured = signed("ATTITUDE", "200.1", WALL + 3);
    e.handle_datagram(keyed, peer(1), &captured, now);
    e.handle_datagram(keyed, peer(10), &captured, now);
    assert_eq!(e.router().links().count(), links, "no new link");
    let report = e.report();
    let line = |start: &str| {
        let found = report.lines().find(|l| l.trim_start().starts_with(start));
        found.expect("a line").to_string()
    };
    let keyed_line = line("udp 0.0.0.0:14550");
    assert!(
        keyed_line.contains("1 unsigned dropped") && keyed_line.contains("1 replayed"),
        "{report}"
    );
    // A copy over the ground station's other path is still only a copy.
    e.handle_datagram(keyed, peer(3), &captured, now);
    let report = e.report();
    let other_path = report
        .lines()
        .find(|l| l.trim_start().starts_with("127.0.0.1:3:"))
        .expect("the other path's line");
    assert!(other_path.contains("1 duplicates dropped"), "{report}");
}

/// A frame the router signed, sent back to it, is a replay: the router's own
/// signatures are streams like any other.
#[test]
fn a_frame_the_router_signed_is_refused_when_sent_back() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let plain = frame("ATTITUDE", "201.1", None);
    r.e.handle_datagram(r.open, peer(2), &plain, Timestamp::ZERO);
    let out = r.sent(r.keyed);
    assert_eq!(out.len(), 1);
    assert_ne!(out[0].packet[2] & 1, 0, "signed on the way out");
    r.e.handle_datagram(r.keyed, peer(1), &out[0].packet, Timestamp::ZERO);
    assert_eq!(r.sent(r.open).len(), 0, "the reflected copy is refused");
    assert!(r.e.report().contains("1 replayed"), "{}", r.e.report());
}

/// The `n`th of many distinct sources, `S.C`.
fn nth_source(n: u32) -> String {
    format!("{}.{}", 1 + n / 250, 1 + n % 250)
}

/// When the stream table is full, the streams it forgets leave their last timestamp
/// behind: a forgotten stream's frames cannot be replayed as a new stream's.
#[test]
fn a_stream_pushed_out_of_a_full_table_cannot_be_replayed() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let captured = signed("ATTITUDE", "200.1", r.next());
    assert_eq!(r.through(&captured), 1);
    for n in 0..mavtables::signing::streams::MAX_STREAMS as u32 {
        let from = nth_source(n);
        let ts = r.next();
        r.e.handle_datagram(
            r.keyed,
            peer(4),
            &signed("HEARTBEAT", &from, ts),
            Timestamp::ZERO,
        );
    }
    while !r.sent(r.open).is_empty() {}
    assert_eq!(r.through(&captured), 0, "replayed after being pushed out");
}

/// A state file saved long ago (its writes failed since, or it was left behind) does
/// not open its streams to frames of any age: a frame more than the window behind the
/// clock is refused on a stream restored from it, as on a new one.
#[test]
fn a_stale_saved_stream_takes_no_frame_older_than_the_window() {
    let hour = 3600 * UNITS_PER_SEC;
    let mut r = Rig::new(ACCEPT_ALL, false);
    let old = signed("ATTITUDE", "200.5", WALL - hour);
    let state = mavtables::signing::state::SavedState::parse(&format!(
        "mavtables signing state 1\nclean 1\nclock {}\nstream {} 1 200 5 {}\n",
        WALL - hour,
        SigningKey::from_bytes(KEY)
            .fingerprint()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>(),
        WALL - hour
    ))
    .expect("parses");
    r.e.restore_signing_state(&state);
    let captured_since = signed("ATTITUDE", "200.5", WALL - hour / 2);
    assert_eq!(r.through(&old), 0);
    assert_eq!(r.through(&captured_since), 0, "half an hour old");
    let now = signed("ATTITUDE", "200.5", r.next());
    assert_eq!(r.through(&now), 1);
}

/// After a crash, a stream first heard after the last save is not in the file: a new
/// stream must begin after that save plus the margin, or its captured frames could be
/// replayed after the restart. So must the router's own signatures.
#[test]
fn after_a_crash_a_stream_first_heard_after_the_last_save_cannot_be_replayed() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let mut saved = r.e.signing_state(true, Timestamp::ZERO).expect("state");
    saved.clean = false;
    let captured = signed("COMMAND_LONG", "200.2", r.next());
    assert_eq!(r.through(&captured), 1);
    // The router's last signature before the crash.
    let plain = frame("ATTITUDE", "201.1", None);
    r.e.handle_datagram(r.open, peer(2), &plain, Timestamp::ZERO);
    let last_signed = captured_ts(&r.sent(r.keyed)[0].packet);

    let mut again = Rig::new(ACCEPT_ALL, false);
    again.e.restore_signing_state(&saved);
    assert_eq!(again.through(&captured), 0, "replayed after the crash");
    again
        .e
        .handle_datagram(again.open, peer(2), &plain, Timestamp::ZERO);
    let first_signed = captured_ts(&again.sent(again.keyed)[0].packet);
    assert!(first_signed > last_signed, "{first_signed} > {last_signed}");
}

/// Frames of ids the built-in dialect does not know (taken in under `unknown_messages
/// accept;`, or from a loaded dialect file) are signed on the way out like any other.
#[test]
fn a_frame_of_an_unknown_id_is_signed_on_the_way_out() {
    let mut r = Rig::new("unknown_messages accept;\ndefault_action accept;", false);
    // MAVLink 2, 3-byte payload, seq 0, from 201.1, message id 60123.
    let id = 60_123u32.to_le_bytes();
    let unknown = [
        0xFD, 3, 0, 0, 0, 201, 1, id[0], id[1], id[2], 1, 2, 3, 0x12, 0x34,
    ];
    r.e.handle_datagram(r.open, peer(2), &unknown, Timestamp::ZERO);
    let out = r.sent(r.keyed);
    assert_eq!(out.len(), 1, "{}", r.e.report());
    assert_eq!(out[0].packet.len(), unknown.len() + 13);
    assert_ne!(out[0].packet[2] & 1, 0, "signed");
}

/// What strangers make the router sign (an unsigned flood through an open interface,
/// from thousands of sources) does not push real streams out of the table: the ground
/// station's frames still pass, its stream intact.
#[test]
fn an_unsigned_flood_signed_on_the_way_out_leaves_the_streams_alone() {
    let mut r = Rig::new(ACCEPT_ALL, false);
    let first = signed("ATTITUDE", "200.1", r.next());
    assert_eq!(r.through(&first), 1);
    for n in 0..mavtables::signing::streams::MAX_STREAMS as u32 {
        let from = nth_source(n);
        r.e.handle_datagram(
            r.open,
            peer(2),
            &frame("HEARTBEAT", &from, None),
            Timestamp::ZERO,
        );
        if n % 100 == 0 {
            r.sent(r.keyed);
        }
    }
    r.sent(r.keyed);
    assert_eq!(r.through(&first), 0, "still a replay: its stream is known");
    let next = signed("ATTITUDE", "200.1", r.next());
    assert_eq!(r.through(&next), 1, "the ground station's next frame");
}
