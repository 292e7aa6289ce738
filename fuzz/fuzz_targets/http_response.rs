//! Arbitrary bytes as the answer `mavtables stats` reads from a statistics endpoint:
//! never a panic, a body no longer than the answer, and errors of one line.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::commands::stats::http::{complete_length, parse_response};

fuzz_target!(|data: &[u8]| {
    let _ = complete_length(data);
    match parse_response(data) {
        Ok(body) => assert!(body.len() <= data.len()),
        Err(e) => assert!(!e.contains('\n')),
    }
});
