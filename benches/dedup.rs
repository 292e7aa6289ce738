//! The cost of `dedup`: frames taken in through the core (`Engine::handle_datagram`,
//! parse, dedup check, routing to 10 UDP links) with `dedup 500ms;` against the same
//! configuration without it.
//!
//! Two radios: every ATTITUDE (distinct by its counter) arrives on two UDP interfaces
//! of one `group`, 1 ms apart. Variants: no dedup (both copies routed: 20 queue pushes
//! per pair), dedup (the second copy dropped: 10 pushes); and one radio (each frame
//! once) with and without dedup, the pure cost of hashing and remembering. The window
//! holds 500 pairs at steady state. Queues are drained between batches, outside the
//! timing.
//!
//! Run: `cargo bench --bench dedup`. Variants are interleaved round by round; the
//! report gives medians per frame received and the ratios.

#![forbid(unsafe_code)]

mod common;

use std::collections::VecDeque;
use std::hint::black_box;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavtables::routing::{Engine, InterfaceId, Request, RouterOptions, Timestamp};
use mavtables::wire::encode::{Header, encode_v2};

const ROUNDS: usize = 41;
const BATCH: usize = 2000;
const LISTENERS: u16 = 10;

fn numbered(n: u32) -> Vec<u8> {
    let mut payload = [0x55u8; 28];
    payload[..4].copy_from_slice(&n.to_le_bytes());
    let header = Header {
        seq: n as u8,
        system: 1,
        component: 1,
    };
    let mut out = Vec::new();
    encode_v2(header, 30, &payload, None, &mut out).expect("encode");
    out
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([10, 0, 0, 1], port))
}

struct Setup {
    engine: Engine,
    radios: [InterfaceId; 2],
    gcs: InterfaceId,
    now: Timestamp,
    next: u32,
    copies: usize,
}

fn setup(dedup: bool, copies: usize) -> Setup {
    let conf = format!(
        "{}udp {{ port 1; group radios; }}\nudp {{ port 2; group radios; }}\nudp {{ port 3; }}\ndefault_action accept;\n",
        if dedup { "dedup 500ms;\n" } else { "" }
    );
    let config = mavtables::config::load(&conf).expect("bench config").config;
    let options = RouterOptions {
        event_level: 0,
        ..RouterOptions::default()
    };
    let mut engine = Engine::new(&config, options);
    let done = engine.configure(&config, &[None, None, None], Timestamp::ZERO);
    let ids: Vec<InterfaceId> = done
        .requests
        .iter()
        .filter_map(|r| match r {
            Request::Open(id, _) => Some(*id),
            _ => None,
        })
        .collect();
    let gcs = ids[2];
    for l in 0..LISTENERS {
        let mut hb = Vec::new();
        let header = Header {
            seq: 0,
            system: 200 + l as u8,
            component: 1,
        };
        encode_v2(header, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3], None, &mut hb).expect("hb");
        engine.handle_datagram(gcs, peer(100 + l), &hb, Timestamp::ZERO);
    }
    let mut s = Setup {
        engine,
        radios: [ids[0], ids[1]],
        gcs,
        now: Timestamp::from_secs(1),
        next: 0,
        copies,
    };
    drain(&mut s);
    s
}

fn drain(s: &mut Setup) -> usize {
    let mut queue = VecDeque::new();
    let mut n = 0;
    for iface in [s.gcs, s.radios[0], s.radios[1]] {
        loop {
            s.engine.poll_transmit(iface, s.now, 4096, &mut queue);
            if queue.is_empty() {
                break;
            }
            n += queue.len();
            queue.clear();
        }
    }
    n
}

/// Takes in BATCH frames (each on `copies` radios, 1 ms apart); returns the time per
/// frame received and how many transmits it led to.
fn run(s: &mut Setup, frames: &[Vec<u8>]) -> (Duration, usize) {
    let start = Instant::now();
    for _ in 0..BATCH / s.copies {
        s.now = s.now + Duration::from_millis(1);
        let f = &frames[s.next as usize % frames.len()];
        s.next += 1;
        for c in 0..s.copies {
            s.engine
                .handle_datagram(s.radios[c], peer(c as u16 + 1), black_box(f), s.now);
        }
    }
    let t = start.elapsed();
    (t, drain(s))
}

fn main() {
    let rounds = common::rounds(ROUNDS);
    // More distinct frames than fit in the window, so no pair repeats within it.
    let frames: Vec<Vec<u8>> = (0..4096).map(numbered).collect();
    let mut variants = [
        ("two radios, no dedup ", setup(false, 2)),
        ("two radios, dedup    ", setup(true, 2)),
        ("one radio, no dedup  ", setup(false, 1)),
        ("one radio, dedup     ", setup(true, 1)),
    ];
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    let mut sent = vec![0usize; variants.len()];
    for _ in 0..rounds {
        for (i, (_, s)) in variants.iter_mut().enumerate() {
            let (t, n) = run(s, &frames);
            times[i].push(t);
            sent[i] = n;
        }
    }
    let per: Vec<f64> = times
        .iter_mut()
        .map(|t| common::median(t).as_secs_f64() * 1e9 / BATCH as f64)
        .collect();
    println!(
        "dedup benchmark: ATTITUDE into the core to {LISTENERS} UDP links, {rounds} interleaved rounds of {BATCH} frames received, medians"
    );
    for (((name, _), ns), n) in variants.iter().zip(&per).zip(&sent) {
        println!("  {name}  {ns:>8.0} ns/frame received  ({n} transmits per batch)");
    }
    println!(
        "  two radios: dedup / no dedup {:.2}x; one radio: dedup / no dedup {:.2}x",
        per[1] / per[0],
        per[3] / per[2]
    );
}
