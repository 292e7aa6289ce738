//! Arbitrary bytes as the request head of the statistics endpoint: never a panic, and
//! always one bounded answer with a status line.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::io::stats_server::respond;
use mavtables::stats::StatsSnapshot;

fuzz_target!(|data: &[u8]| {
    // The first byte says whether the endpoint listens on loopback (the Host check).
    let (loopback, head) = match data.split_first() {
        Some((first, rest)) => (first & 1 == 1, rest),
        None => (false, data),
    };
    let answer = respond(head, &StatsSnapshot::default(), loopback);
    assert!(answer.starts_with(b"HTTP/1.1 "));
    // The largest answer to an empty snapshot is the status page and its head.
    assert!(answer.len() < mavtables::stats::STATUS_PAGE.len() + 1024);
});
