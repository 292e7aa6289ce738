//! Arbitrary bytes, fed in arbitrary chunks, never panic the frame parser, and every
//! byte is accounted for (in a frame, skipped as junk, or held back), under the router's
//! checks and under the strict ones. Every frame handed out (v2 frames longer than their
//! message's known length included) can be read, printed and decoded.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::dialect::decode;
use mavtables::wire::{Checks, Frame, Parser};

/// Feeds `data` in chunks of `chunk` bytes and checks the byte accounting.
fn run(checks: Checks, chunk: usize, data: &[u8]) {
    let mut parser = Parser::with_checks(checks);
    let mut in_frames = 0u64;
    let mut longer = 0u64;
    let mut json = Vec::new();
    for c in data.chunks(chunk) {
        parser.feed(c, |f| {
            in_frames += f.as_bytes().len() as u64;
            longer += u64::from(f.is_longer_than_known());
            assert_eq!(f.header().frame_len(), f.as_bytes().len());
            let _ = (f.target(), f.signature(), f.to_string());
            json.clear();
            let fields = decode::Fields {
                info: f.info(),
                payload: f.payload(),
            };
            serde_json::to_writer(&mut json, &fields).expect("decoded fields always serialize");
        });
    }
    let held = parser.pending_len() as u64;
    assert_eq!(in_frames + parser.stats().junk_bytes + held, parser.position());
    parser.finish_frames(|f| {
        in_frames += f.as_bytes().len() as u64;
        longer += u64::from(f.is_longer_than_known());
    });
    assert_eq!(parser.pending_len(), 0);
    assert_eq!(in_frames + parser.stats().junk_bytes, parser.position());
    assert_eq!(parser.stats().longer_than_known, longer);
    if checks.known_length {
        assert_eq!(longer, 0, "strict checks hand out no longer-than-known frame");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, rest)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk).max(1);
    run(Checks::ROUTING, chunk, rest);
    run(Checks::STRICT, chunk, rest);
    let _ = Frame::parse_exact(rest);
});
