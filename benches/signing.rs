//! What MAVLink 2 signing costs the router per frame: one ATTITUDE frame (and one of the
//! largest frames) forwarded through the routing core from one datagram interface to
//! another — unsigned (no keys), verified on the way in (a keyed ingress, signed frames
//! with fresh timestamps), and signed on the way out (a keyed egress) — plus the bare
//! SHA-256 signature of each frame size. Everything but the signature is the same work,
//! so the differences of the medians are the cost of verifying and of signing.
//!
//! Run: `cargo bench --bench signing`. Variants are interleaved round by round so that
//! machine noise hits them alike; the report gives medians of per-frame times.

#![forbid(unsafe_code)]

mod common;

use std::collections::VecDeque;
use std::hint::black_box;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, RouterOptions, Timestamp};
use mavtables::signing::SigningKey;
use mavtables::signing::clock::UNITS_PER_SEC;
use mavtables::wire::encode::{Header, SignWith, encode_v2};
use mavtables::wire::signing::compute_signature;

const ROUNDS: usize = 31;
const BATCH: usize = 2000;
const KEY: [u8; 32] = [0x42; 32];
const WALL: u64 = 11 * 365 * 24 * 3600 * UNITS_PER_SEC;

/// Which way a variant uses a key.
#[derive(Clone, Copy, PartialEq)]
enum Mode {
    Unsigned,
    Verify,
    Sign,
}

struct Setup {
    engine: Engine,
    ingress: InterfaceId,
    egress: InterfaceId,
    /// The frames of each round (signed ones with timestamps that keep increasing).
    rounds: Vec<Vec<Vec<u8>>>,
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// A frame of message `id` from 1.1 whose payload is `len` bytes of 0x55, signed with
/// `timestamp` if given.
fn frame(id: u32, len: usize, seq: u8, timestamp: Option<u64>) -> Vec<u8> {
    let payload = vec![0x55u8; len];
    let header = Header {
        seq,
        system: 1,
        component: 1,
    };
    let signing = timestamp.map(|timestamp| SignWith {
        key: &KEY,
        link_id: 0,
        timestamp,
    });
    let mut out = Vec::new();
    encode_v2(header, id, &payload, signing, &mut out).expect("encode");
    out
}

fn setup(mode: Mode, id: u32, len: usize, rounds: usize) -> Setup {
    let config = config::load("default_action accept;")
        .expect("config")
        .config;
    let options = RouterOptions {
        event_level: 0,
        ..RouterOptions::default()
    };
    let mut engine = Engine::new(&config, options);
    let ingress = engine.add_datagram_interface("udp in".into(), 0, Default::default());
    let egress = engine.add_datagram_interface("udp out".into(), 0, Default::default());
    engine.set_wall_clock(Timestamp::ZERO, WALL);
    match mode {
        Mode::Unsigned => {}
        Mode::Verify => engine.set_signing(ingress, SigningKey::from_bytes(KEY), false, 0),
        Mode::Sign => engine.set_signing(egress, SigningKey::from_bytes(KEY), true, 1),
    }
    // The listener behind the egress (learned from its heartbeat).
    let mut hb = Vec::new();
    let header = Header {
        seq: 0,
        system: 201,
        component: 1,
    };
    encode_v2(header, 0, &[1; 9], None, &mut hb).expect("heartbeat");
    engine.handle_datagram(egress, peer(2), &hb, Timestamp::ZERO);
    let mut ts = WALL;
    let frames = (0..rounds + 1)
        .map(|_| {
            (0..BATCH)
                .map(|i| {
                    let t = (mode == Mode::Verify).then(|| {
                        ts += 1;
                        ts
                    });
                    frame(id, len, i as u8, t)
                })
                .collect()
        })
        .collect();
    let mut s = Setup {
        engine,
        ingress,
        egress,
        rounds: frames,
    };
    let mut q = VecDeque::new();
    s.engine
        .poll_transmit(s.egress, Timestamp::ZERO, 64, &mut q);
    s
}

/// Forwards round `r`'s frames one by one; returns the time per frame.
fn run(s: &mut Setup, r: usize, q: &mut VecDeque<mavtables::routing::Transmit>) -> Duration {
    let now = Timestamp::ZERO;
    let mut sent = 0;
    let start = Instant::now();
    for f in &s.rounds[r] {
        s.engine
            .handle_datagram(s.ingress, peer(1), black_box(f), now);
        s.engine.poll_transmit(s.egress, now, 64, q);
        for t in q.drain(..) {
            s.engine.on_sent(black_box(&t));
            sent += 1;
        }
    }
    let t = start.elapsed();
    assert_eq!(
        sent,
        BATCH,
        "every frame is forwarded: {}",
        s.engine.report()
    );
    t / BATCH as u32
}

fn main() {
    let rounds = common::rounds(ROUNDS);
    println!(
        "signing benchmark: frames forwarded through the routing core, {rounds} interleaved rounds of {BATCH}, medians per frame"
    );
    // ATTITUDE (28-byte payload; 53 bytes signed) and ENCAPSULATED_DATA (255; 280 signed).
    for (name, id, len) in [
        ("ATTITUDE", 30u32, 28usize),
        ("ENCAPSULATED_DATA", 131, 253),
    ] {
        let mut variants = [
            ("unsigned          ", setup(Mode::Unsigned, id, len, rounds)),
            (
                "verified on the way in",
                setup(Mode::Verify, id, len, rounds),
            ),
            ("signed on the way out", setup(Mode::Sign, id, len, rounds)),
        ];
        let mut times = vec![Vec::with_capacity(rounds); variants.len() + 1];
        let mut q = VecDeque::new();
        let signed = frame(id, len, 0, Some(WALL));
        let covered = &signed[..signed.len() - 6];
        for r in 0..rounds {
            for (i, (_, s)) in variants.iter_mut().enumerate() {
                times[i].push(run(s, r, &mut q));
            }
            let start = Instant::now();
            for _ in 0..BATCH {
                black_box(compute_signature(black_box(&KEY), black_box(covered)));
            }
            times[3].push(start.elapsed() / BATCH as u32);
        }
        let ns: Vec<f64> = times
            .iter_mut()
            .map(|t| common::median(t).as_secs_f64() * 1e9)
            .collect();
        println!("  {name} ({} bytes signed):", signed.len());
        for (i, (label, _)) in variants.iter().enumerate() {
            let extra = if i == 0 {
                String::new()
            } else {
                format!("   (+{:.0} ns)", ns[i] - ns[0])
            };
            println!("    {label:<24} {:>6.0} ns/frame{extra}", ns[i]);
        }
        println!("    {:<24} {:>6.0} ns", "SHA-256 signature alone", ns[3]);
    }
    println!("  SHA-256 instructions on this CPU: {}", sha_instructions());
}

/// Whether the CPU has SHA-256 instructions (which the `sha2` crate detects and uses).
fn sha_instructions() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("sha") {
            return "yes (SHA-NI)";
        }
    }
    #[cfg(target_arch = "aarch64")]
    {
        if std::arch::is_aarch64_feature_detected!("sha2") {
            return "yes (ARMv8 SHA2)";
        }
    }
    "no"
}
