//! The cost of the flight log in the core: a dataflash block the router takes for its
//! log (`Engine::handle_datagram`: parse, the flight log's take, the ACK built and
//! queued to the vehicle, the block put in order and handed to the writer's queue)
//! against routing the same-sized block to a ground station (parse, filter, one queue
//! push), and against an ATTITUDE routed to it (the telemetry beside the log).
//!
//! One UDP interface with the vehicle (system 1, an armed ArduPilot) and a ground
//! station. Variants: blocks addressed to the router (`flight_log` on), the same blocks
//! addressed to the ground station (routed), ATTITUDE routed. Queues and the writer's
//! queue are drained between batches, outside the timing.
//!
//! Run: `cargo bench --bench flight_log`. Variants are interleaved round by round; the
//! report gives medians per frame received, the ratios, and the blocks per second one
//! core could take (ArduPilot streams its log at up to a few hundred blocks a second).

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

fn encode(system: u8, component: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    let header = Header {
        seq: 0,
        system,
        component,
    };
    let mut out = Vec::new();
    encode_v2(header, id, payload, None, &mut out).expect("encode");
    out
}

/// REMOTE_LOG_DATA_BLOCK `seqno` to `to`.
fn block(seqno: u32, to: (u8, u8)) -> Vec<u8> {
    let mut p = seqno.to_le_bytes().to_vec();
    p.extend_from_slice(&[to.0, to.1]);
    p.extend_from_slice(&[(seqno % 200) as u8 + 1; 200]);
    encode(1, 1, 184, &p)
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([10, 0, 0, 1], port))
}

struct Setup {
    engine: Engine,
    udp: InterfaceId,
    now: Timestamp,
    /// The frames it is fed, in turn.
    frames: Vec<Vec<u8>>,
    next: usize,
}

fn setup(frames: Vec<Vec<u8>>) -> Setup {
    let conf = "udp { port 1; }\nflight_log { system 1; }\ndefault_action accept;\n";
    let config = mavtables::config::load(conf).expect("bench config").config;
    let options = RouterOptions {
        event_level: 0,
        ..RouterOptions::default()
    };
    let mut engine = Engine::new(&config, options);
    let done = engine.configure(&config, &[None], Timestamp::ZERO);
    let udp = done
        .requests
        .iter()
        .find_map(|r| match r {
            Request::Open(id, _) => Some(*id),
            _ => None,
        })
        .expect("one interface");
    let gcs = encode(255, 190, 0, &[0, 0, 0, 0, 6, 8, 0, 4, 3]);
    engine.handle_datagram(udp, peer(2), &gcs, Timestamp::ZERO);
    let armed = encode(1, 1, 0, &[0, 0, 0, 0, 2, 3, 129, 4, 3]);
    engine.handle_datagram(udp, peer(1), &armed, Timestamp::ZERO);
    let mut s = Setup {
        engine,
        udp,
        now: Timestamp::from_secs(1),
        frames,
        next: 0,
    };
    drain(&mut s);
    s
}

/// Empties the queues and the writer's queue; how many transmits there were.
fn drain(s: &mut Setup) -> usize {
    let mut queue = VecDeque::new();
    let mut n = 0;
    loop {
        s.engine.poll_transmit(s.udp, s.now, 4096, &mut queue);
        if queue.is_empty() {
            break;
        }
        n += queue.len();
        queue.clear();
    }
    s.engine.poll_flight_log(&mut |w| {
        black_box(w);
    });
    n
}

fn run(s: &mut Setup) -> (Duration, usize) {
    let start = Instant::now();
    for _ in 0..BATCH {
        // 100 µs a frame; no timer runs (`handle_timeout` is not called), as within a
        // burst between two of the loop's wake-ups.
        s.now = s.now + Duration::from_micros(100);
        let f = &s.frames[s.next % s.frames.len()];
        s.next += 1;
        s.engine
            .handle_datagram(s.udp, peer(1), black_box(f), s.now);
    }
    let t = start.elapsed();
    (t, drain(s))
}

fn main() {
    let rounds = common::rounds(ROUNDS);
    // Blocks numbered on and on: each variant's own sequence, none ever missing.
    let n = (rounds + 1) * BATCH;
    let to_router: Vec<Vec<u8>> = (0..n as u32).map(|s| block(s, (245, 190))).collect();
    let to_gcs: Vec<Vec<u8>> = (0..4096).map(|s| block(s, (255, 190))).collect();
    let attitude = vec![encode(1, 1, 30, &[0x55; 28])];
    let mut variants = [
        ("block for the flight log", setup(to_router)),
        ("block routed to the GCS ", setup(to_gcs)),
        ("ATTITUDE routed         ", setup(attitude)),
    ];
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    let mut sent = vec![0usize; variants.len()];
    for _ in 0..rounds {
        for (i, (_, s)) in variants.iter_mut().enumerate() {
            let (t, n) = run(s);
            times[i].push(t);
            sent[i] = n;
        }
    }
    let (c, _) = variants[0]
        .1
        .engine
        .flight_log_counters()
        .expect("configured");
    assert_eq!(c.lost + c.nacks, 0, "no block missing");
    let per: Vec<f64> = times
        .iter_mut()
        .map(|t| common::median(t).as_secs_f64() * 1e9 / BATCH as f64)
        .collect();
    println!(
        "flight log benchmark: frames into the core from an armed ArduPilot, {rounds} interleaved rounds of {BATCH}, medians"
    );
    for (((name, _), ns), n) in variants.iter().zip(&per).zip(&sent) {
        println!("  {name}  {ns:>8.0} ns/frame  ({n} transmits per batch)");
    }
    println!(
        "  flight log block / routed block {:.2}x; / routed ATTITUDE {:.2}x; {:.0} blocks/s ({:.0} MB/s of log) per core",
        per[0] / per[1],
        per[0] / per[2],
        1e9 / per[0],
        1e9 / per[0] * 200.0 / 1e6
    );
}
