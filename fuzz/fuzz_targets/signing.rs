//! Arbitrary bytes through the signing check of a keyed interface never panic it, and
//! it never takes in a frame whose signature is wrong or whose timestamp breaks the
//! stream and clock rules. Frames the router signs are valid, verify with the key and
//! keep their payload. The saved state's text reader takes any text without panicking,
//! and what it reads is written back to the same state.
#![no_main]

use std::collections::HashMap;

use libfuzzer_sys::fuzz_target;
use mavtables::signing::sign::sign;
use mavtables::signing::state::SavedState;
use mavtables::signing::streams::{StreamId, StreamTable};
use mavtables::signing::verify::{Admission, Check, WINDOW};
use mavtables::signing::SigningKey;
use mavtables::wire::signing::verify;
use mavtables::wire::{Frame, Parser};

const KEY: [u8; 32] = [0x5a; 32];

/// Checks `frame` and the rules behind an admission.
fn admit(
    check: &Check<'_>,
    frame: &Frame<'_>,
    streams: &mut StreamTable,
    last: &mut HashMap<(u8, u8, u8), u64>,
) {
    let admission = check.admit(frame, streams, &StreamTable::default());
    let Some(sig) = frame.signature() else {
        assert_ne!(admission, Admission::Signed);
        return;
    };
    if admission != Admission::Signed {
        return;
    }
    assert!(verify(frame, &KEY), "taken in with a wrong signature");
    let ts = sig.timestamp();
    assert!(ts <= check.clock + WINDOW, "taken in from too far ahead");
    let src = frame.source();
    let key = (sig.link_id(), src.system, src.component);
    match last.get(&key) {
        Some(&prev) => assert!(ts > prev, "taken in out of order"),
        None => assert!(ts + WINDOW >= check.clock, "a new stream taken in too old"),
    }
    last.insert(key, ts);
    // Streams the bounded table forgot are forgotten by the model too.
    last.retain(|&(link_id, system, component), _| {
        let id = StreamId {
            key: 0,
            link_id,
            system,
            component,
        };
        streams.last(&id).is_some()
    });
}

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(state) = SavedState::parse(text)
    {
        assert_eq!(SavedState::parse(&state.to_text()), Ok(state));
    }
    let Some((&head, rest)) = data.split_first() else {
        return;
    };
    let key = SigningKey::from_bytes(KEY);
    let check = Check {
        key: &key,
        key_slot: 0,
        allow_unsigned: head & 1 == 1,
        clock: u64::from(head) << 24,
    };
    // A small table, so that forgetting streams is exercised too (a forgotten stream
    // starts again: the model forgets it as well when the table does).
    let mut streams = StreamTable::with_capacity(usize::from(head >> 4) + 1);
    let mut last = HashMap::new();
    let mut parser = Parser::new();
    let mut frames: Vec<Vec<u8>> = Vec::new();
    parser.feed(rest, |f| frames.push(f.as_bytes().to_vec()));
    for bytes in &frames {
        let Ok(frame) = Frame::parse_exact(bytes) else {
            continue;
        };
        admit(&check, &frame, &mut streams, &mut last);
        // The same frame signed by the router, with a timestamp taken from its bytes.
        let ts = bytes.iter().fold(0u64, |a, &b| a.rotate_left(5) ^ u64::from(b)) & 0xffff_ffff;
        if let Some(signed) = sign(bytes, &key, bytes[bytes.len() / 2], ts) {
            let f = Frame::parse_exact(&signed).expect("the router's signed frame is valid");
            assert!(verify(&f, &KEY));
            assert_eq!(f.payload(), frame.payload());
            assert_eq!(f.signature().map(|s| s.timestamp()), Some(ts));
            admit(&check, &f, &mut streams, &mut last);
        }
    }
});
