//! Parser throughput on a real flight (33,261 frames, 989,451 bytes), against the
//! `mavlink` crate's raw-frame reader on the same bytes in the same run.
//!
//! Run: `cargo bench --bench parser`. Variants are interleaved round by round so that
//! machine noise hits them alike; the report gives medians and the ratios of medians.

#![forbid(unsafe_code)]

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use mavlink::MavlinkReader;
use mavlink::dialects::ardupilotmega::MavMessage;
use mavtables::wire::Parser;

const ROUNDS: usize = 41;

fn flight() -> Vec<u8> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/mavlink_full/pass.53"
    );
    std::fs::read(path).expect("tests/data/mavlink_full/pass.53 (raw flight stream)")
}

/// Frames of the flight as separate slices (what a UDP link receives).
fn datagrams(stream: &[u8]) -> Vec<&[u8]> {
    let mut offsets = Vec::new();
    Parser::new().feed(stream, |f| {
        offsets.push((f.offset() as usize, f.as_bytes().len()))
    });
    offsets.iter().map(|&(o, l)| &stream[o..o + l]).collect()
}

fn ours_stream(stream: &[u8]) -> usize {
    let mut parser = Parser::new();
    let mut n = 0;
    parser.feed(black_box(stream), |f| {
        black_box(f.message_id());
        n += 1
    });
    n
}

fn ours_datagrams(dgs: &[&[u8]]) -> usize {
    let mut parser = Parser::new();
    let mut n = 0;
    for d in dgs {
        parser.feed(black_box(d), |f| {
            black_box(f.message_id());
            n += 1
        });
    }
    n
}

fn theirs_stream(stream: &[u8]) -> usize {
    let mut reader = MavlinkReader::new(black_box(stream));
    let mut n = 0;
    while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
        black_box(raw.message_id());
        n += 1;
    }
    n
}

fn theirs_datagrams(dgs: &[&[u8]]) -> usize {
    let mut n = 0;
    for d in dgs {
        let mut reader = MavlinkReader::new(black_box(*d));
        while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
            black_box(raw.message_id());
            n += 1;
        }
    }
    n
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --all-targets` runs benches as tests
    // with no argument: then one quick round checks that they work.
    let rounds = common::rounds(ROUNDS);
    let stream = flight();
    let dgs = datagrams(&stream);
    let frames = dgs.len();
    assert_eq!(frames, 33_261);
    type Variant<'a> = (&'a str, Box<dyn Fn() -> usize + 'a>);
    let variants: Vec<Variant> = vec![
        ("mavtables  stream   ", Box::new(|| ours_stream(&stream))),
        ("mavlink    stream   ", Box::new(|| theirs_stream(&stream))),
        ("mavtables  datagrams", Box::new(|| ours_datagrams(&dgs))),
        ("mavlink    datagrams", Box::new(|| theirs_datagrams(&dgs))),
    ];
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    for _ in 0..rounds {
        for (i, (name, run)) in variants.iter().enumerate() {
            let start = Instant::now();
            let n = run();
            times[i].push(start.elapsed());
            assert_eq!(n, frames, "{name} found {n} frames");
        }
    }
    let medians: Vec<Duration> = times.iter_mut().map(|t| common::median(t)).collect();
    println!(
        "parser benchmark: {} bytes, {frames} frames, {rounds} interleaved rounds, medians",
        stream.len()
    );
    for ((name, _), m) in variants.iter().zip(&medians) {
        let secs = m.as_secs_f64();
        println!(
            "  {name}  {:>8.1} µs  {:>8.1} MB/s  {:>7.2} M frames/s  {:>6.1} ns/frame",
            secs * 1e6,
            stream.len() as f64 / secs / 1e6,
            frames as f64 / secs / 1e6,
            secs * 1e9 / frames as f64
        );
    }
    let ratio = |a: usize, b: usize| medians[b].as_secs_f64() / medians[a].as_secs_f64();
    println!(
        "  ratio stream    (mavtables frames/s ÷ mavlink frames/s): {:.1}x",
        ratio(0, 1)
    );
    println!(
        "  ratio datagrams (mavtables frames/s ÷ mavlink frames/s): {:.1}x",
        ratio(2, 3)
    );
}
