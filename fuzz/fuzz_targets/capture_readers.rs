//! Arbitrary bytes never panic the `.tlog` and `.pcap` readers.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::capture::{pcap, tlog};

fuzz_target!(|data: &[u8]| {
    for record in tlog::records(data) {
        if record.is_err() {
            break;
        }
    }
    if let Ok(reader) = pcap::Reader::new(data) {
        for dg in reader {
            if dg.is_err() {
                break;
            }
        }
    }
});
