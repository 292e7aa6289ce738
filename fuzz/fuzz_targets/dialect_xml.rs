//! Any bytes given to the MAVLink XML reader and the layout yield messages or an error
//! with a line, never a panic; whatever lays out fits a MAVLink payload.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::dialect::{layout, xml};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match xml::parse(&text) {
        Ok(file) => {
            for m in &file.messages {
                if let Ok(l) = layout::lay_out(m) {
                    assert!(l.min_len <= l.max_len);
                    assert!(usize::from(l.max_len) <= layout::MAX_PAYLOAD);
                    assert!(l.fields.len() <= layout::MAX_FIELDS);
                    assert_eq!(l.id, m.id);
                }
            }
        }
        Err(e) => assert!(e.line >= 1 && e.line <= text.lines().count().max(1) + 1),
    }
});
