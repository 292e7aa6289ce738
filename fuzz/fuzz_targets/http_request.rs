//! Arbitrary bytes as the request head of the statistics endpoint: never a panic, and
//! always one bounded answer with a status line.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::io::stats_server::respond;
use mavtables::stats::StatsSnapshot;

fuzz_target!(|data: &[u8]| {
    let answer = respond(data, &StatsSnapshot::default());
    assert!(answer.starts_with(b"HTTP/1.1 "));
    // The largest answer to an empty snapshot is the status page and its head.
    assert!(answer.len() < mavtables::stats::STATUS_PAGE.len() + 1024);
});
