//! Routing decisions with 100 `accept with rate` rules against the same 100 rules
//! without rates: the cost of holding accepted packets to their caps.
//!
//! Setup as `benches/routing.rs`: a broadcast packet from an 11th link offered to 10 UDP
//! links of 5 learned addresses each (50 filter verdicts, 10 queue pushes per
//! decision). The 100 rules accept one message type each (no target fields); the
//! packets cycle through 25 of them (every 4th rule, so the verdict memo holds all
//! 1,250 keys: see [`MEMO_SLOTS`], as it does in a real network's steady state). The clock moves 1 ms per
//! decision and the caps are 10,000/s, so every packet passes its cap (the limiter looks
//! up and moves on a schedule for each of the 10 links: 250 streams) and both variants
//! queue the same packets.
//!
//! Run: `cargo bench --bench rate_caps`. Variants are interleaved round by round; the
//! report gives medians, the ratio of medians and the median of each round's ratio (two
//! batches measured back to back meet nearly the same load from other processes, so
//! that one is swayed less by load that drifts during the run).
//!
//! `RATE_CAPS_ONLY=without` (or `with`) runs one variant alone, for a cache profiler:
//! `RATE_CAPS_ONLY=with valgrind --tool=cachegrind target/release/deps/rate_caps-* --bench`.

#![forbid(unsafe_code)]

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use mavtables::routing::{Output, Timestamp};
use mavtables::wire::Frame;

const ROUNDS: usize = 41;
const BATCH: usize = 2000;
const LINKS: usize = 10;
const ADDRESSES: usize = 5;
const RULES: usize = 100;
/// A memo large enough that its 1,250 keys do not evict each other (the default 4,096
/// direct-mapped slots lose about a fifth of them to collisions, and the rule walks
/// that causes would swamp what is measured here).
const MEMO_SLOTS: usize = 1 << 16;

/// 100 messages without target fields (broadcasts), by id.
fn messages() -> Vec<u32> {
    mavtables::dialect::messages()
        .iter()
        .filter(|m| m.target_system_offset.is_none() && m.id != 0)
        .map(|m| m.id)
        .take(RULES)
        .collect()
}

fn config(ids: &[u32], rate: &str) -> String {
    let mut s = String::from("chain default {\n");
    for id in ids {
        let name = mavtables::dialect::by_id(*id).map_or("", |m| m.name);
        s += &format!("    accept {rate}if {name} from 200.0/8;\n");
    }
    s + "}\n"
}

struct Setup {
    learned: common::LearnedRouter,
    now: Timestamp,
}

fn setup(conf: &str) -> Setup {
    Setup {
        learned: common::LearnedRouter::new(conf, MEMO_SLOTS, LINKS, ADDRESSES),
        now: Timestamp::from_secs(1),
    }
}

/// A v2 frame of message `id` (full length) from `system.1`.
fn encode(id: u32, system: u8) -> Vec<u8> {
    common::encode(id, system, 1)
}

/// Routes BATCH packets (cycling through `frames`, 1 ms apart); returns the time and
/// how many link queues took a packet.
fn run(s: &mut Setup, frames: &[Frame<'_>], out: &mut Output) -> (Duration, usize) {
    let mut queued = 0;
    let start = Instant::now();
    for i in 0..BATCH {
        s.now = s.now + Duration::from_millis(1);
        let frame = &frames[i % frames.len()];
        let l = &mut s.learned;
        l.router.receive(l.source, black_box(frame), s.now, out);
        queued += out.queued.len();
        out.clear();
    }
    let t = start.elapsed();
    s.learned.drain();
    (t, queued)
}

fn main() {
    let rounds = common::rounds(ROUNDS);
    let ids = messages();
    assert_eq!(ids.len(), RULES, "enough broadcast messages");
    let bytes: Vec<Vec<u8>> = ids.iter().step_by(4).map(|&id| encode(id, 200)).collect();
    let frames: Vec<Frame<'_>> = bytes
        .iter()
        .map(|b| Frame::parse_exact(b).expect("frame"))
        .collect();
    let mut variants = [
        ("100 rules, no rates     ", setup(&config(&ids, ""))),
        (
            "100 rules, with rate 10000/s",
            setup(&config(&ids, "with rate 10000/s ")),
        ),
    ];
    let mut out = Output::default();
    let only = std::env::var("RATE_CAPS_ONLY").ok();
    if let Some(only) = only {
        let i = usize::from(only == "with");
        let mut t: Vec<Duration> = (0..rounds)
            .map(|_| run(&mut variants[i].1, &frames, &mut out).0)
            .collect();
        let ns = common::median(&mut t).as_secs_f64() * 1e9 / BATCH as f64;
        println!("  {} alone  {ns:>8.0} ns/decision", variants[i].0);
        return;
    }
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    for _ in 0..rounds {
        for (i, (name, s)) in variants.iter_mut().enumerate() {
            let (t, queued) = run(s, &frames, &mut out);
            assert_eq!(
                queued,
                LINKS * BATCH,
                "{name}: every link takes every packet"
            );
            times[i].push(t);
        }
    }
    let mut ratios: Vec<f64> = times[1]
        .iter()
        .zip(&times[0])
        .map(|(c, u)| c.as_secs_f64() / u.as_secs_f64())
        .collect();
    ratios.sort_unstable_by(f64::total_cmp);
    let per: Vec<f64> = times
        .iter_mut()
        .map(|t| common::median(t).as_secs_f64() * 1e9 / BATCH as f64)
        .collect();
    println!(
        "rate caps benchmark: {RULES} message types broadcast to {LINKS} links x {ADDRESSES} addresses, {rounds} interleaved rounds of {BATCH}, medians"
    );
    for ((name, _), ns) in variants.iter().zip(&per) {
        println!("  {name}  {ns:>8.0} ns/decision");
    }
    println!("  ratio with rates / without: {:.2}x", per[1] / per[0]);
    println!(
        "  median of the rounds' ratios: {:.2}x",
        ratios[ratios.len() / 2]
    );
    let counts = variants[1].1.learned.router.filter_counts();
    let limited: u64 = counts.rules.iter().map(|r| r.rate_limited).sum();
    assert_eq!(limited, 0, "every packet passes its cap");
    for (name, s) in &variants {
        let c = s.learned.router.filter_stats();
        println!(
            "  memo ({}): {} hits, {} misses",
            name.trim(),
            c.hits,
            c.misses
        );
    }
}
