//! Attacks on the router's MAVLink 2 signing, from plain sockets on 127.0.0.1: forged
//! signatures, replays (also across a restart, and a crash, of the router on the same
//! `signing_state`), valid signatures on modified frames, timestamps out of the window,
//! unsigned frames, other keys, and a flood of forgeries. Each test asserts that nothing
//! forged reaches any destination and that no valid frame is lost: the receiver collects
//! every frame up to a last valid one sent after the attack (one sender socket, one
//! router link, one receiver: the order holds), and what it got must be exactly the valid
//! frames, byte for byte.
//!
//! Frames are made with the crate's encoder (`encode_v2` with `Signing`), with
//! timestamps of the router's signing clock: UTC in 10 µs units since 2015-01-01.
//!
//! A scratch tag or file name must not contain "udp": `Router::start` finds the UDP ports
//! by that word.

#![forbid(unsafe_code)]

mod common;
#[path = "common/signing.rs"]
mod signing;

use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};
use std::thread;
use std::time::{Duration, Instant};

use common::net::status_bytes;
use common::router::{BIN, Router, Scratch, free_udp_port};
use mavtables::wire::signing::verify;
use mavtables::wire::{Frame, Parser};
use signing::{
    Key, MINUTE, Stream, attitude_payload, count_of, exit_report, hex, hex_key_file, key_from,
    now_ts, signed, signing_counts, unsigned, v1,
};

const T: Duration = Duration::from_secs(10);

/// A small deterministic generator of "random" bytes (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn bytes(&mut self, out: &mut [u8]) {
        for b in out {
            *b = self.next() as u8;
        }
    }
}

/// The router with a keyed sender interface (index 0, `udp` server `a`) and a receiver
/// interface without a key (index 1, `udp` server `b`), a sender socket and a receiver
/// socket the router has learned.
struct Rig {
    /// Whose turn it is: the flood test runs alone (see [`ALONE`]).
    _turn: Turn,
    router: Router,
    key: Key,
    tx: UdpSocket,
    rx: UdpSocket,
    a: String,
    b: String,
    rx_parser: Parser,
}

/// The flood test takes this for writing, every other test for reading, so the flood
/// runs with no other router of this file beside it: on 2 CPUs the other tests' routers
/// and peers are load enough to starve the flooded router for the few tens of
/// milliseconds its socket buffer covers at 100,000 frames a second.
static ALONE: RwLock<()> = RwLock::new(());

/// A test's hold on [`ALONE`].
enum Turn {
    Shared(#[allow(dead_code)] RwLockReadGuard<'static, ()>),
    Alone(#[allow(dead_code)] RwLockWriteGuard<'static, ()>),
}

impl Turn {
    /// A turn beside the other tests (not beside the flood).
    fn shared() -> Turn {
        Turn::Shared(ALONE.read().unwrap_or_else(PoisonError::into_inner))
    }

    /// A turn with no other test running.
    fn alone() -> Turn {
        Turn::Alone(ALONE.write().unwrap_or_else(PoisonError::into_inner))
    }
}

fn interface_a(port: u16, key_path: &str, extra: &str) -> String {
    format!("udp {{ port {port}; address 127.0.0.1; signing_key {key_path};{extra} }}\n")
}

impl Rig {
    /// `a_extra` goes inside the keyed block (e.g. ` allow_unsigned yes;`); `tail` after
    /// the blocks (e.g. a `signing_state` or a chain).
    fn start(s: &Scratch, a_extra: &str, tail: &str) -> Rig {
        Rig::start_binary(Turn::shared(), BIN, s, a_extra, tail)
    }

    /// [`Rig::start`] with the router binary at `bin`.
    fn start_binary(turn: Turn, bin: &str, s: &Scratch, a_extra: &str, tail: &str) -> Rig {
        let key = key_from(0x5c);
        let kf = hex_key_file(s, "sender.key", &key);
        let (pa, pb) = (free_udp_port(), free_udp_port());
        let config = format!(
            "{}udp {{ port {pb}; address 127.0.0.1; }}\n{tail}default_action accept;\n",
            interface_a(pa, &kf, a_extra)
        );
        let router = Router::start_binary(bin, s, &config, 1);
        let mut rig = Rig {
            _turn: turn,
            router,
            key,
            tx: UdpSocket::bind("127.0.0.1:0").expect("bind"),
            rx: UdpSocket::bind("127.0.0.1:0").expect("bind"),
            a: format!("127.0.0.1:{pa}"),
            b: format!("127.0.0.1:{pb}"),
            rx_parser: Parser::new(),
        };
        rig.rx
            .set_read_timeout(Some(Duration::from_millis(50)))
            .expect("timeout");
        rig.register_receiver();
        rig
    }

    /// The receiver's HEARTBEAT (unsigned, 200.1) teaches the router where it is.
    fn register_receiver(&mut self) {
        self.rx
            .send_to(
                &unsigned(200, 1, 0, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]),
                &self.b,
            )
            .expect("send");
        self.router.wait_for("new component 200.1 on 127.0.0.1:");
    }

    fn send(&self, frame: &[u8]) {
        self.tx.send_to(frame, &self.a).expect("send");
    }

    /// Every frame the receiver gets up to and including `last`.
    fn until(&mut self, last: &[u8]) -> Vec<Vec<u8>> {
        receive_until(&self.rx, &mut self.rx_parser, last, T)
    }

    /// Sends `valid` (interleaved by the caller with whatever else was sent before) and
    /// checks the receiver gets exactly `want` up to its last frame.
    fn expect_exactly(&mut self, want: &[Vec<u8>]) {
        let last = want.last().expect("a last frame");
        let got = self.until(last);
        assert_same(&got, want);
    }

    fn counts(self) -> Vec<(u64, String)> {
        let stopped = self.router.stop();
        signing_counts(&exit_report(&stopped.stderr))
    }
}

/// Frames from `sock` until one equal to `last` (panics, with what came, after
/// `timeout`).
fn receive_until(
    sock: &UdpSocket,
    parser: &mut Parser,
    last: &[u8],
    timeout: Duration,
) -> Vec<Vec<u8>> {
    let deadline = Instant::now() + timeout;
    let mut got: Vec<Vec<u8>> = Vec::new();
    let mut buf = [0u8; 65536];
    loop {
        if got.last().is_some_and(|f| f == last) {
            return got;
        }
        assert!(
            Instant::now() < deadline,
            "the frame {} never came; got {} frames, the first 10: {:#?}",
            hex(last),
            got.len(),
            got.iter().take(10).map(|f| hex(f)).collect::<Vec<_>>()
        );
        if let Ok(n) = sock.recv(&mut buf) {
            let mut frames = Vec::new();
            parser.feed(&buf[..n], |f| frames.push(f.as_bytes().to_vec()));
            for f in frames {
                let done = f == last;
                got.push(f);
                if done {
                    break;
                }
            }
        }
    }
}

fn assert_same(got: &[Vec<u8>], want: &[Vec<u8>]) {
    if got == want {
        return;
    }
    let show = |v: &[&Vec<u8>]| {
        v.iter()
            .take(10)
            .map(|f| hex(f))
            .collect::<Vec<_>>()
            .join("\n  ")
    };
    let extra: Vec<&Vec<u8>> = got.iter().filter(|f| !want.contains(f)).collect();
    let missing: Vec<&Vec<u8>> = want.iter().filter(|f| !got.contains(f)).collect();
    panic!(
        "the receiver must get exactly the valid frames, byte for byte, in order: got {} \
         frames for {} valid; {} not valid (first 10):\n  {}\n{} valid ones missing \
         (first 10):\n  {}",
        got.len(),
        want.len(),
        extra.len(),
        show(&extra),
        missing.len(),
        show(&missing)
    );
}

/// `frame` with its signature value (last 6 bytes) replaced by random bytes.
fn random_signature(frame: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut f = frame.to_vec();
    let n = f.len();
    rng.bytes(&mut f[n - 6..]);
    f
}

/// `frame` with payload byte `at` flipped and the checksum recomputed, so that it parses
/// (the signature no longer matches).
fn modified_payload(frame: &[u8], at: usize) -> Vec<u8> {
    let mut f = frame.to_vec();
    f[10 + at] ^= 0x01;
    rechecksum(&mut f);
    f
}

/// Recomputes the CRC of a MAVLink 2 frame after its header or payload changed.
fn rechecksum(f: &mut [u8]) {
    let len = f[1] as usize;
    let id = u32::from_le_bytes([f[7], f[8], f[9], 0]);
    let info = mavtables::dialect::by_id(id).expect("known id");
    let crc = mavtables::wire::crc::frame_checksum(&f[1..10 + len], info.crc_extra);
    f[10 + len..12 + len].copy_from_slice(&crc.to_le_bytes());
    Frame::parse_exact(f).expect("still a well-formed frame");
}

/// Random signatures, on frames of the valid stream itself (with timestamps ahead of
/// it, which must not move it on) and of streams never seen (random link ids, systems
/// and timestamps, which must not make streams), interleaved with valid frames: only the
/// valid ones arrive.
#[test]
fn random_signatures_never_pass() {
    let s = Scratch::new("sig-random");
    let mut rig = Rig::start(&s, "", "");
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut stream = Stream::new(rig.key, 0, 10);
    let mut valid = Vec::new();
    let mut forged = 0u64;
    for _ in 0..50 {
        let v = stream.next();
        rig.send(&v);
        valid.push(v);
        for j in 0..20u64 {
            // Ahead of the stream: a valid frame to come, its signature random.
            let ahead = signed(
                &rig.key,
                0,
                stream.next_ts + 1000 + j,
                10,
                1,
                0,
                30,
                &attitude_payload(9999),
            );
            rig.send(&random_signature(&ahead, &mut rng));
            // A new stream.
            let link = rng.next() as u8;
            let sys = rng.next() as u8;
            let ts = now_ts() - MINUTE / 2 + rng.next() % MINUTE;
            let new = signed(&rig.key, link, ts, sys, 1, 0, 30, &attitude_payload(7777));
            rig.send(&random_signature(&new, &mut rng));
            forged += 2;
        }
    }
    let last = stream.next();
    rig.send(&last);
    valid.push(last);
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(
        count_of(&counts, "bad") >= forged,
        "{forged} forged frames, counted: {counts:?}"
    );
}

/// A valid frame sent again, byte for byte, is refused; so is an older one of the same
/// stream, and one with the last accepted timestamp again (a valid signature on another
/// payload); the stream then goes on.
#[test]
fn replayed_frames_are_refused() {
    let s = Scratch::new("sig-replay");
    let mut rig = Rig::start(&s, "", "");
    let mut stream = Stream::new(rig.key, 0, 10);
    let first: Vec<Vec<u8>> = (0..3).map(|_| stream.next()).collect();
    for f in &first {
        rig.send(f);
    }
    rig.expect_exactly(&first);

    for f in [&first[2], &first[1], &first[0], &first[2]] {
        rig.send(f);
    }
    let same_ts = signed(
        &rig.key,
        0,
        stream.next_ts - 1,
        10,
        1,
        3,
        30,
        &attitude_payload(4242),
    );
    rig.send(&same_ts);
    let next = stream.next();
    rig.send(&next);
    rig.expect_exactly(std::slice::from_ref(&next));
    let counts = rig.counts();
    assert!(count_of(&counts, "replay") >= 5, "{counts:?}");
}

/// Frames captured before a restart (SIGTERM) are still refused by the next router on
/// the same `signing_state`; the stream goes on after it.
#[test]
fn replay_after_restart_is_refused() {
    let s = Scratch::new("sig-restart");
    let state = s.path("signing.state");
    let tail = format!("signing_state {state};\n");
    let mut rig = Rig::start(&s, "", &tail);
    let mut stream = Stream::new(rig.key, 0, 10);
    let before: Vec<Vec<u8>> = (0..5).map(|_| stream.next()).collect();
    for f in &before {
        rig.send(f);
    }
    rig.expect_exactly(&before);
    let Rig {
        _turn: turn,
        router,
        key,
        tx,
        rx,
        a,
        b,
        ..
    } = rig;
    let stopped = router.stop();
    assert!(stopped.status.success());
    let saved = std::fs::metadata(&state).expect("the signing state was saved at exit");
    assert!(saved.len() > 0, "an empty signing state");

    let config = std::fs::read_to_string(s.dir.join("mavtables.conf")).expect("config");
    let router = Router::start(&s, &config, 1);
    let mut rig = Rig {
        _turn: turn,
        router,
        key,
        tx,
        rx,
        a,
        b,
        rx_parser: Parser::new(),
    };
    rig.register_receiver();
    for f in &before {
        rig.send(f);
    }
    let next = stream.next();
    rig.send(&next);
    rig.expect_exactly(std::slice::from_ref(&next));
    let counts = rig.counts();
    assert!(count_of(&counts, "replay") >= 5, "{counts:?}");
}

/// The state is saved while the router runs (at least every second while it changes),
/// so a frame captured before a crash (SIGKILL, no saving at exit) is refused after it;
/// the stream goes on with a frame 3 s later.
#[test]
fn replay_after_a_crash_is_refused() {
    let s = Scratch::new("sig-crash");
    let state = s.path("signing.state");
    let tail = format!("signing_state {state};\n");
    let mut rig = Rig::start(&s, "", &tail);
    let initial = std::fs::read(&state).ok();
    let mut stream = Stream::new(rig.key, 0, 10);
    let v = stream.next();
    rig.send(&v);
    rig.expect_exactly(std::slice::from_ref(&v));
    // The next save has the stream.
    common::eventually("the signing state saved", Duration::from_secs(5), || {
        std::fs::read(&state)
            .ok()
            .is_some_and(|now| Some(&now) != initial.as_ref())
    });
    let Rig {
        _turn: turn,
        router,
        key,
        tx,
        rx,
        a,
        b,
        ..
    } = rig;
    router.stop_with(libc::SIGKILL);
    let config = std::fs::read_to_string(s.dir.join("mavtables.conf")).expect("config");
    let router = Router::start(&s, &config, 1);
    let mut rig = Rig {
        _turn: turn,
        router,
        key,
        tx,
        rx,
        a,
        b,
        rx_parser: Parser::new(),
    };
    rig.register_receiver();
    rig.send(&v);
    // After a crash the router cannot know what it accepted after its last save, so it
    // raises every saved stream by a margin (two save intervals: 2 s); the sender's clock
    // has moved on by more than that when it next sends.
    stream.next_ts += 3 * 100_000;
    let next = stream.next();
    rig.send(&next);
    rig.expect_exactly(std::slice::from_ref(&next));
}

/// A valid signature on a modified frame: a payload byte flipped, the sequence number or
/// the system id changed (checksum recomputed, so the frame parses), the signature's
/// timestamp or link id changed. Each is refused; the unmodified frame, sent after its
/// forgeries with the same timestamp, is delivered (the forgeries did not use it up).
#[test]
fn valid_signature_on_a_modified_frame_is_refused() {
    let s = Scratch::new("sig-modified");
    let mut rig = Rig::start(&s, "", "");
    let mut stream = Stream::new(rig.key, 0, 10);
    let mut valid = Vec::new();
    for at in [0usize, 5, 27] {
        let v = stream.next();
        let mut forgeries = vec![modified_payload(&v, at)];
        let mut seq = v.clone();
        seq[4] ^= 0x80;
        rechecksum(&mut seq);
        forgeries.push(seq);
        let mut sys = v.clone();
        sys[5] = 11;
        rechecksum(&mut sys);
        forgeries.push(sys);
        let n = v.len();
        let mut ts = v.clone();
        ts[n - 12] ^= 0x02; // the timestamp's low byte (not covered by the checksum)
        forgeries.push(ts);
        let mut link = v.clone();
        link[n - 13] = 1;
        forgeries.push(link);
        for f in &forgeries {
            assert!(Frame::parse_exact(f).is_ok(), "{}", hex(f));
            assert!(!verify(&Frame::parse_exact(f).unwrap(), &rig.key));
            rig.send(f);
        }
        rig.send(&v);
        valid.push(v);
    }
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(count_of(&counts, "bad") >= 15, "{counts:?}");
}

/// Timestamps out of the window: a frame a day ahead of the signing clock, one 2 minutes
/// ahead, and the first frame of a stream 2 minutes behind are refused; normal traffic of
/// those streams right after is delivered, as is a new stream starting 30 s behind (in
/// the window).
#[test]
fn timestamps_out_of_the_window_are_refused_and_traffic_goes_on() {
    let s = Scratch::new("sig-window");
    let mut rig = Rig::start(&s, "", "");
    let key = rig.key;
    let now = now_ts();
    let day = 24 * 60 * MINUTE;
    let future = signed(&key, 0, now + day, 10, 1, 0, 30, &attitude_payload(1));
    let ahead = signed(
        &key,
        0,
        now + 2 * MINUTE,
        10,
        1,
        1,
        30,
        &attitude_payload(2),
    );
    let stale = signed(
        &key,
        0,
        now - 2 * MINUTE,
        12,
        1,
        0,
        30,
        &attitude_payload(3),
    );
    for f in [&future, &ahead, &stale] {
        rig.send(f);
    }
    let mut s10 = Stream::new(key, 0, 10);
    let mut s12 = Stream::new(key, 0, 12);
    let mut s13 = Stream::new(key, 0, 13);
    s13.next_ts = now_ts() - MINUTE / 2;
    let mut valid = Vec::new();
    for _ in 0..5 {
        for st in [&mut s10, &mut s12, &mut s13] {
            let f = st.next();
            rig.send(&f);
            valid.push(f);
        }
    }
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(count_of(&counts, "window") >= 3, "{counts:?}");
}

/// Unsigned frames on a keyed interface are dropped (and counted); signed traffic goes on.
#[test]
fn unsigned_frames_on_a_keyed_interface_are_dropped() {
    let s = Scratch::new("sig-unsigned");
    let mut rig = Rig::start(&s, "", "");
    let mut stream = Stream::new(rig.key, 0, 10);
    let mut valid = Vec::new();
    for n in 0..10u32 {
        rig.send(&unsigned(10, 1, n as u8, 30, &attitude_payload(1000 + n)));
        rig.send(&unsigned(20, 1, n as u8, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]));
        rig.send(&v1(21, 1, n as u8, 30, &attitude_payload(2000 + n)));
        let f = stream.next();
        rig.send(&f);
        valid.push(f);
    }
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(count_of(&counts, "unsigned") >= 20, "{counts:?}");
}

/// With `allow_unsigned yes;` unsigned frames (MAVLink 2 and 1) are delivered as they are,
/// but a signature that fails is still refused.
#[test]
fn unsigned_frames_pass_with_allow_unsigned() {
    let s = Scratch::new("sig-allow");
    let mut rig = Rig::start(&s, " allow_unsigned yes;", "");
    let mut rng = Rng(42);
    let mut stream = Stream::new(rig.key, 0, 10);
    let mut valid = Vec::new();
    for n in 0..10u32 {
        let u = unsigned(20, 1, n as u8, 30, &attitude_payload(1000 + n));
        let old = v1(21, 1, n as u8, 30, &attitude_payload(2000 + n));
        let f = stream.next();
        let bad = random_signature(&stream.next(), &mut rng);
        for frame in [&u, &old, &bad, &f] {
            rig.send(frame);
        }
        valid.extend([u, old, f]);
    }
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(count_of(&counts, "bad") >= 10, "{counts:?}");
}

/// Frames correctly signed with another key (on the same stream, ahead of it) are
/// refused; the stream signed with the interface's key goes on.
#[test]
fn signed_with_another_key_is_refused() {
    let s = Scratch::new("sig-otherkey");
    let mut rig = Rig::start(&s, "", "");
    let mut other = rig.key;
    other[31] ^= 0x01;
    let mut stream = Stream::new(rig.key, 0, 10);
    let mut wrong = Stream::new(other, 0, 10);
    wrong.next_ts += 100_000;
    let mut stranger = Stream::new(key_from(0x77), 3, 30);
    let mut valid = Vec::new();
    for _ in 0..20 {
        rig.send(&wrong.next());
        rig.send(&stranger.next());
        let f = stream.next();
        rig.send(&f);
        valid.push(f);
    }
    rig.expect_exactly(&valid);
    let counts = rig.counts();
    assert!(count_of(&counts, "bad") >= 40, "{counts:?}");
}

/// Forged frames a millisecond: 100 (100,000 a second), against the optimised router
/// users run (`scripts/test` builds it and names it in `MAVTABLES_RELEASE_ROUTER`). An
/// unoptimised build checks only about 95,000 signatures a second on 2 CPUs, so this
/// test needs the release build and is `#[ignore]`d for a plain `cargo test`.
const FORGED_PER_MS: u64 = 100;

/// About 100,000 forged frames a second for 3 s — random signatures on random streams,
/// replays, other keys, unsigned — from one socket, while another sends 1,000 valid
/// signed frames a second: every valid frame arrives, in order, and nothing else; the
/// router's memory stays within a few MiB of what it was before.
#[test]
#[ignore = "needs the release router at full rate; scripts/test builds and runs it"]
fn flood_of_forgeries_costs_no_valid_frame_and_no_memory() {
    let s = Scratch::new("sig-flood");
    let bin = common::needs::release_router();
    let per_ms = FORGED_PER_MS;
    let mut rig = Rig::start_binary(Turn::alone(), &bin, &s, "", "");
    let pid = rig.router.pid();
    let key = rig.key;
    let mut stream = Stream::new(key, 0, 10);
    let warm: Vec<Vec<u8>> = (0..100).map(|_| stream.next()).collect();
    for f in &warm {
        rig.send(f);
    }
    rig.expect_exactly(&warm);
    let idle = status_bytes(pid, "VmRSS");

    let flooding = Arc::new(AtomicBool::new(true));
    let a = rig.a.clone();
    let replay = warm[50].clone();
    let flood = {
        let flooding = flooding.clone();
        // Made beforehand, so that sending them is all the flood thread does.
        let mut rng = Rng(7);
        let mut other = key;
        other[0] ^= 0xff;
        let forgeries: Vec<Vec<u8>> = (0..40_000u64)
            .map(|i| {
                let r = rng.next();
                let (link, sys, comp) = (r as u8, (r >> 8) as u8, (r >> 16) as u8);
                let ts = now_ts() - MINUTE / 2 + (r >> 24) % MINUTE;
                match i % 4 {
                    0 => random_signature(
                        &signed(&key, link, ts, sys, comp, 0, 30, &attitude_payload(1)),
                        &mut rng,
                    ),
                    1 => replay.clone(),
                    2 => signed(&other, link, ts, sys, comp, 0, 30, &attitude_payload(2)),
                    _ => unsigned(sys, comp, 0, 30, &attitude_payload(3)),
                }
            })
            .collect();
        thread::spawn(move || {
            let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
            let start = Instant::now();
            let mut sent = 0u64;
            while start.elapsed() < Duration::from_secs(3) {
                for _ in 0..per_ms {
                    let f = &forgeries[(sent % forgeries.len() as u64) as usize];
                    let _ = sock.send_to(f, &a);
                    sent += 1;
                }
                let next = start + Duration::from_millis(sent / per_ms);
                thread::sleep(next.saturating_duration_since(Instant::now()));
            }
            flooding.store(false, Ordering::Relaxed);
            sent
        })
    };
    // The receiver reads all along, in a thread of its own, into a large buffer.
    let rx = rig.rx.try_clone().expect("clone");
    socket2::SockRef::from(&rx)
        .set_recv_buffer_size(8 << 20)
        .expect("SO_RCVBUF");
    let end = signed(&key, 0, 0, 10, 1, 0, 30, &attitude_payload(u32::MAX));
    let end_counter = end[10..14].to_vec();
    let receiver = thread::spawn(move || {
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut parser = Parser::new();
        let mut got: Vec<Vec<u8>> = Vec::new();
        let mut buf = [0u8; 65536];
        while Instant::now() < deadline {
            if got
                .last()
                .is_some_and(|f| f.len() > 14 && f[10..14] == end_counter[..])
            {
                break;
            }
            if let Ok(n) = rx.recv(&mut buf) {
                parser.feed(&buf[..n], |f| got.push(f.as_bytes().to_vec()));
            }
        }
        got
    });
    let mut valid = Vec::new();
    let start = Instant::now();
    while flooding.load(Ordering::Relaxed) {
        let f = stream.next();
        rig.send(&f);
        valid.push(f);
        let next = start + Duration::from_millis(valid.len() as u64);
        thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    let forged = flood.join().expect("flood");
    let last = signed(
        &key,
        0,
        stream.next_ts,
        10,
        1,
        0,
        30,
        &attitude_payload(u32::MAX),
    );
    rig.send(&last);
    valid.push(last);
    let got = receiver.join().expect("receiver");
    let rss = status_bytes(pid, "VmRSS");
    eprintln!(
        "{forged} forged frames in 3 s, {} valid; RSS {} KiB before, {} KiB after",
        valid.len(),
        idle / 1024,
        rss / 1024
    );
    assert!(
        forged >= per_ms * 2_500,
        "the flood sent only {forged} in 3 s"
    );
    let stopped = rig.router.stop();
    let report = exit_report(&stopped.stderr);
    if got != valid {
        eprintln!("the router's counters:\n{}", report.join("\n"));
    }
    assert_same(&got, &valid);
    assert!(
        rss < idle + 4 * 1024 * 1024,
        "RSS {rss} after the flood against {idle} before"
    );
    let counts = signing_counts(&report);
    let refused = count_of(&counts, "bad")
        + count_of(&counts, "replay")
        + count_of(&counts, "window")
        + count_of(&counts, "unsigned");
    assert!(refused >= forged / 2, "{forged} forged, counted {counts:?}");
}

/// The router with a sender interface without a key (index 0) and a keyed receiver
/// interface (index 1), whose receiver registers with a signed HEARTBEAT.
fn keyed_egress(s: &Scratch, more: &str) -> (Router, Key, UdpSocket, UdpSocket, String) {
    let key = key_from(0x33);
    let kf = hex_key_file(s, "receiver.key", &key);
    let (pa, pb) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {pa}; address 127.0.0.1; }}\n\
         udp {{ port {pb}; address 127.0.0.1; signing_key {kf}; }}\n\
         {more}default_action accept;\n"
    );
    let mut router = Router::start(s, &config, 1);
    let tx = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
    rx.set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let hb = signed(
        &key,
        0,
        now_ts(),
        201,
        1,
        0,
        0,
        &[0, 0, 0, 0, 6, 8, 0, 0, 3],
    );
    rx.send_to(&hb, format!("127.0.0.1:{pb}")).expect("send");
    router.wait_for("new component 201.1 on 127.0.0.1:");
    (router, key, tx, rx, format!("127.0.0.1:{pa}"))
}

/// Through a keyed egress: MAVLink 1 frames pass unchanged (unsigned); unsigned MAVLink 2
/// frames are signed by the router with the interface's key, link id 1 (its index),
/// strictly increasing timestamps of the signing clock, header and payload unchanged.
#[test]
fn keyed_egress_signs_v2_and_passes_v1_unchanged() {
    let _turn = Turn::shared();
    let s = Scratch::new("sig-egress");
    let (router, key, tx, rx, a) = keyed_egress(&s, "");
    let mut sent = Vec::new();
    for n in 0..10u8 {
        let f = if n % 2 == 0 {
            v1(40, 1, n, 30, &attitude_payload(n.into()))
        } else {
            unsigned(40, 1, n, 30, &attitude_payload(n.into()))
        };
        tx.send_to(&f, &a).expect("send");
        sent.push(f);
    }
    let got = common::net::udp_frames(&rx, 10, T);
    assert_eq!(
        got.len(),
        10,
        "{:#?}",
        got.iter().map(|f| hex(f)).collect::<Vec<_>>()
    );
    let mut last_ts = 0;
    for (g, f) in got.iter().zip(&sent) {
        if f[0] == 0xfe {
            assert_eq!(hex(g), hex(f), "MAVLink 1 passes unchanged");
            continue;
        }
        let frame = Frame::parse_exact(g).expect("frame");
        let sent_frame = Frame::parse_exact(f).expect("frame");
        let sig = frame
            .signature()
            .unwrap_or_else(|| panic!("not signed: {}", hex(g)));
        assert_eq!(sig.link_id(), 1, "link id = the interface's index");
        assert!(verify(&frame, &key), "the router's signature verifies");
        let ts = sig.timestamp();
        assert!(ts > last_ts, "timestamps strictly increase");
        last_ts = ts;
        assert!(
            ts.abs_diff(now_ts()) < MINUTE,
            "timestamp {ts} off the clock"
        );
        assert_eq!(
            (
                frame.seq(),
                frame.system(),
                frame.component(),
                frame.message_id(),
                frame.payload()
            ),
            (
                sent_frame.seq(),
                sent_frame.system(),
                sent_frame.component(),
                sent_frame.message_id(),
                sent_frame.payload()
            )
        );
    }
    router.stop();
}

/// Already-signed frames pass a keyed egress byte for byte: one verified on a keyed
/// ingress with another key, and one signed with yet another key arriving on an
/// interface without a key (not verified there, but signed: left alone).
#[test]
fn already_signed_frames_pass_a_keyed_egress_byte_for_byte() {
    let _turn = Turn::shared();
    let s = Scratch::new("sig-passthru");
    let other = key_from(0x90);
    let okf = hex_key_file(&s, "other.key", &other);
    let pc = free_udp_port();
    let more = format!("udp {{ port {pc}; address 127.0.0.1; signing_key {okf}; }}\n");
    let (router, key, tx, rx, a) = keyed_egress(&s, &more);
    let mut from_keyed = Stream::new(other, 6, 50);
    let mut from_plain = Stream::new(key_from(0xa0), 2, 51);
    let mut want = Vec::new();
    for _ in 0..5 {
        let f = from_keyed.next();
        tx.send_to(&f, format!("127.0.0.1:{pc}")).expect("send");
        want.push(f);
        // Wait for each, so the two senders' frames come in a known order.
        let got = common::net::udp_frames(&rx, 1, T);
        assert_same(&got, &want[want.len() - 1..]);
        let g = from_plain.next();
        tx.send_to(&g, &a).expect("send");
        want.push(g);
        let got = common::net::udp_frames(&rx, 1, T);
        assert_same(&got, &want[want.len() - 1..]);
    }
    assert!(!verify(&Frame::parse_exact(&want[0]).unwrap(), &key));
    router.stop();
}

/// The filter conditions: `signed` means verified by the router. On a keyed interface
/// that allows unsigned frames an unsigned COMMAND_LONG is refused by
/// `reject if unsigned COMMAND_LONG;` and a signed one passes; on an interface without a
/// key a COMMAND_LONG that carries a (valid) signature counts as unsigned; other unsigned
/// messages pass.
#[test]
fn filter_signed_and_unsigned() {
    let _turn = Turn::shared();
    let s = Scratch::new("sig-filter");
    let key = key_from(0x11);
    let kf = hex_key_file(&s, "sender.key", &key);
    let (pa, pb, pc) = (free_udp_port(), free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {pa}; address 127.0.0.1; signing_key {kf}; allow_unsigned yes; }}\n\
         udp {{ port {pb}; address 127.0.0.1; }}\n\
         udp {{ port {pc}; address 127.0.0.1; }}\n\
         chain default {{ reject if unsigned COMMAND_LONG; accept; }}\n\
         default_action accept;\n"
    );
    let mut router = Router::start(&s, &config, 1);
    let rx = UdpSocket::bind("127.0.0.1:0").expect("bind");
    rx.set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    rx.send_to(
        &unsigned(200, 1, 0, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]),
        format!("127.0.0.1:{pc}"),
    )
    .expect("send");
    router.wait_for("new component 200.1 on 127.0.0.1:");
    let keyed = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let plain = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let (to_keyed, to_plain) = (format!("127.0.0.1:{pa}"), format!("127.0.0.1:{pb}"));
    let mut cmd = vec![0u8; 33];
    cmd[28..30].copy_from_slice(&400u16.to_le_bytes());
    let mut ts = now_ts();
    let mut next_ts = || {
        ts += 1;
        ts
    };
    let mut parser = Parser::new();
    let mut expect = |send: &[(&UdpSocket, &String, Vec<u8>)], want: &[Vec<u8>]| {
        for (sock, to, f) in send {
            sock.send_to(f, to).expect("send");
        }
        let got = receive_until(&rx, &mut parser, want.last().expect("last"), T);
        assert_same(&got, want);
    };
    // From the keyed interface.
    let unsigned_cmd = unsigned(10, 1, 0, 76, &cmd);
    let signed_cmd = signed(&key, 0, next_ts(), 10, 1, 1, 76, &cmd);
    let unsigned_hb = unsigned(10, 1, 2, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]);
    expect(
        &[
            (&keyed, &to_keyed, unsigned_cmd),
            (&keyed, &to_keyed, signed_cmd.clone()),
            (&keyed, &to_keyed, unsigned_hb.clone()),
        ],
        &[signed_cmd, unsigned_hb],
    );
    // From the interface without a key: signed, but not verified.
    let signed_cmd = signed(&key, 0, next_ts(), 11, 1, 0, 76, &cmd);
    let unsigned_hb = unsigned(11, 1, 1, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]);
    expect(
        &[
            (&plain, &to_plain, signed_cmd),
            (&plain, &to_plain, unsigned_hb.clone()),
        ],
        &[unsigned_hb],
    );
    router.stop();
}
