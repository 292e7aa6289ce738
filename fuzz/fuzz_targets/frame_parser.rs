//! Arbitrary bytes, fed in arbitrary chunks, never panic the frame parser, and every
//! byte is accounted for (in a frame, skipped as junk, or held back).
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::wire::{Frame, Parser};

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, rest)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk).max(1);
    let mut parser = Parser::new();
    let mut in_frames = 0u64;
    for c in rest.chunks(chunk) {
        parser.feed(c, |f| {
            in_frames += f.as_bytes().len() as u64;
            let _ = (f.target(), f.signature(), f.to_string());
        });
    }
    let held = parser.pending_len() as u64;
    assert_eq!(in_frames + parser.stats().junk_bytes + held, parser.position());
    parser.finish_frames(|f| in_frames += f.as_bytes().len() as u64);
    assert_eq!(parser.pending_len(), 0);
    assert_eq!(in_frames + parser.stats().junk_bytes, parser.position());
    let _ = Frame::parse_exact(rest);
});
