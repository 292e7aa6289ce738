//! The small harness shared by the benchmarks: interleaved rounds and medians.
#![allow(dead_code)]

use std::time::Duration;

/// Rounds to run: `full` under `cargo bench` (which passes `--bench`), one otherwise
/// (`cargo test --all-targets` runs each benchmark once as a smoke test).
pub fn rounds(full: usize) -> usize {
    if std::env::args().any(|a| a == "--bench") {
        full
    } else {
        1
    }
}

/// The median of `v` (sorts it).
pub fn median(v: &mut [Duration]) -> Duration {
    v.sort_unstable();
    v[v.len() / 2]
}
