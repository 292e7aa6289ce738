//! Routing decisions for one broadcast packet offered to 10 links of 5 addresses each,
//! with a 1-rule configuration and a 300-rule one (chains with calls and gotos), with and
//! without the filter's verdict memo.
//!
//! Run: `cargo bench --bench routing`. Variants are interleaved round by round so that
//! machine noise hits them alike; the report gives medians and the ratios of medians.

#![forbid(unsafe_code)]

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::encode;
use mavtables::routing::{Output, Timestamp};
use mavtables::wire::Frame;

const ROUNDS: usize = 41;
const BATCH: usize = 2000;
const LINKS: usize = 10;
const ADDRESSES: usize = 5;

const ONE_RULE: &str = "chain default { accept; }";

/// 300 rules in 32 chains. Without the memo, the packet (ATTITUDE from 200.1, filtered for
/// each of the links' addresses) walks 63 rules of `default` and 21 calls that fall
/// through (126 more rules) before a goto whose chain accepts it on its 30th, last rule:
/// about 220 rule checks per address.
fn three_hundred_rules() -> String {
    let mut s = String::from("chain default {\n");
    let mut rules = 0;
    // 30 calls and a goto interleaved with 60 non-matching rules in `default`.
    for i in 0..30 {
        s += &format!("    reject if PING from {}.0/8;\n", 100 + i);
        s += &format!("    accept if GPS_RAW_INT to {}.1;\n", i);
        s += &format!("    call c{i} if from 200.0/8;\n");
        rules += 3;
        if i == 20 {
            s += "    goto last if ATTITUDE;\n";
            rules += 1;
        }
    }
    s += "}\n";
    // 30 chains of 6 rules that do not decide for ATTITUDE (calls fall through).
    for i in 0..30 {
        s += &format!("chain c{i} {{\n");
        for j in 0..6 {
            s += &format!("    reject if SYS_STATUS to {}.{};\n", i, j);
            rules += 1;
        }
        s += "}\n";
    }
    s += "chain last {\n";
    while rules < 299 {
        s += &format!(
            "    reject if GLOBAL_POSITION_INT from {}.1;\n",
            rules % 250
        );
        rules += 1;
    }
    s += "    accept with priority 2 if ATTITUDE from 200.0/8;\n}\n";
    rules += 1;
    assert_eq!(rules, 300);
    s
}

type Setup = common::LearnedRouter;

fn setup(conf: &str, cache_slots: usize) -> Setup {
    Setup::new(conf, cache_slots, LINKS, ADDRESSES)
}

fn drain(s: &mut Setup) {
    s.drain();
}

/// Routes the packet BATCH times; returns the time and how many links queued it.
fn run(s: &mut Setup, frame: &Frame<'_>, out: &mut Output) -> (Duration, usize) {
    let now = Timestamp::from_secs(1);
    let mut queued = 0;
    let start = Instant::now();
    for _ in 0..BATCH {
        s.router.receive(s.source, black_box(frame), now, out);
        queued += out.queued.len();
        out.clear();
    }
    let t = start.elapsed();
    drain(s);
    (t, queued / BATCH)
}

fn main() {
    let rounds = common::rounds(ROUNDS);
    let big = three_hundred_rules();
    let bytes = encode(30, 200, 1); // ATTITUDE, no target: a broadcast
    let frame = Frame::parse_exact(&bytes).expect("frame");
    let mut variants = [
        (
            "1 rule,    memo   ",
            setup(ONE_RULE, mavtables::filter::cache::DEFAULT_SLOTS),
        ),
        (
            "300 rules, memo   ",
            setup(&big, mavtables::filter::cache::DEFAULT_SLOTS),
        ),
        ("1 rule,    no memo", setup(ONE_RULE, 0)),
        ("300 rules, no memo", setup(&big, 0)),
    ];
    let mut out = Output::default();
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    for _ in 0..rounds {
        for (i, (name, s)) in variants.iter_mut().enumerate() {
            let (t, queued) = run(s, &frame, &mut out);
            assert_eq!(queued, LINKS, "{name}: every link accepts");
            times[i].push(t);
        }
    }
    let per: Vec<f64> = times
        .iter_mut()
        .map(|t| common::median(t).as_secs_f64() * 1e9 / BATCH as f64)
        .collect();
    println!(
        "routing benchmark: broadcast ATTITUDE to {LINKS} links x {ADDRESSES} addresses ({} filter checks), {rounds} interleaved rounds of {BATCH}, medians",
        LINKS * ADDRESSES
    );
    for ((name, _), ns) in variants.iter().zip(&per) {
        println!("  {name}  {ns:>8.0} ns/decision");
    }
    println!(
        "  ratio 300 rules / 1 rule, memo:    {:.2}x",
        per[1] / per[0]
    );
    println!(
        "  ratio 300 rules / 1 rule, no memo: {:.2}x",
        per[3] / per[2]
    );
    let (_, s) = &variants[1];
    let stats = s.router.filter_stats();
    println!(
        "  memo (300 rules): {} hits, {} misses",
        stats.hits, stats.misses
    );
}
