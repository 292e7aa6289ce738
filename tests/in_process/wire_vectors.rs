//! The parser against real data: the shared test vectors (verdicts from
//! `tests/data/MANIFEST.md`) and a real 33,261-frame flight as `.tlog`, raw stream and `.pcap`.

use crate::common;

use common::{Verdict, manifest, read_data};
use mavtables::capture::{pcap, tlog};
use mavtables::wire::{Checks, Frame, Parser};

const FLIGHT_FRAMES: usize = 33_261;

/// Strict verdict: the whole file is a sequence of zero or more valid frames (checksums
/// checked, none longer than its message's known length), optionally all of one message id.
fn strict_verdict(bytes: &[u8], only_id: Option<u32>) -> bool {
    let mut parser = Parser::with_checks(Checks::STRICT);
    let mut ids_ok = true;
    parser.feed(bytes, |f| {
        ids_ok &= only_id.is_none_or(|id| f.message_id() == id)
    });
    let s = parser.stats();
    ids_ok && s.rejected() == 0 && s.junk_bytes == 0 && parser.pending_len() == 0
}

fn check_section(section: &str, dir: &str, only_id: Option<u32>, expected_rows: usize) {
    let rows = manifest(section, Verdict::StrictCrc);
    assert_eq!(rows.len(), expected_rows, "manifest rows for {section}");
    let mut wrong = Vec::new();
    for (name, expected) in &rows {
        let bytes = read_data(&format!("{dir}/{name}"));
        if strict_verdict(&bytes, only_id) != *expected {
            wrong.push(name.clone());
        }
    }
    assert!(
        wrong.is_empty(),
        "verdicts differing from the manifest: {wrong:?}"
    );
}

#[test]
fn seed_scaled_pressure_vectors_match_the_strict_verdicts() {
    check_section("seed_scaled_pressure", "seed_scaled_pressure", Some(29), 63);
}

#[test]
fn mavlink_full_vectors_match_the_strict_verdicts() {
    check_section("mavlink_full", "mavlink_full", None, 106);
}

#[test]
fn every_tlog_record_is_one_valid_frame() {
    let data = read_data("flight/rural.tlog");
    let mut n = 0;
    let mut last_ts = 0;
    for rec in tlog::records(&data) {
        let rec = rec.expect("well-formed tlog record");
        let frame = Frame::parse_exact(rec.frame)
            .unwrap_or_else(|e| panic!("record at {}: {e}", rec.offset));
        assert_eq!(frame.as_bytes().len(), rec.frame.len());
        assert!(rec.timestamp_us >= last_ts, "timestamps go forward");
        last_ts = rec.timestamp_us;
        n += 1;
    }
    assert_eq!(n, FLIGHT_FRAMES);
}

#[test]
fn tlog_fed_as_one_stream_yields_every_frame_and_skips_only_timestamps() {
    let data = read_data("flight/rural.tlog");
    let mut parser = Parser::new();
    let mut frames = 0;
    parser.feed(&data, |_| frames += 1);
    // Timestamp bytes are junk to a raw-stream parser; none of them may swallow a frame.
    assert_eq!(frames, FLIGHT_FRAMES);
    assert_eq!(parser.stats().frames as usize, FLIGHT_FRAMES);
}

#[test]
fn raw_flight_stream_parses_completely() {
    let data = read_data("mavlink_full/pass.53");
    let mut parser = Parser::new();
    let mut ids = std::collections::BTreeSet::new();
    parser.feed(&data, |f| {
        ids.insert(f.message_id());
    });
    let s = parser.stats();
    assert_eq!(s.frames as usize, FLIGHT_FRAMES);
    assert_eq!(
        (s.rejected(), s.junk_bytes, parser.pending_len()),
        (0, 0, 0)
    );
    assert_eq!(ids.len(), 48, "distinct message ids in the flight");
}

#[test]
fn pcap_flight_carries_the_same_frames_as_the_tlog() {
    let tlog_data = read_data("flight/rural.tlog");
    let tlog_frames: Vec<&[u8]> = tlog::records(&tlog_data)
        .map(|r| r.expect("record").frame)
        .collect();
    let data = read_data("flight/rural.pcap");
    let reader = pcap::Reader::new(&data).expect("pcap header");
    let mut n = 0;
    for dg in reader {
        let dg = dg.expect("pcap record");
        assert_eq!((dg.source.1, dg.destination.1), (14550, 14580));
        let mut parser = Parser::new();
        let mut got = Vec::new();
        parser.feed(dg.payload, |f| got.push(f.as_bytes().to_vec()));
        assert_eq!(got.len(), 1, "one frame per datagram");
        assert_eq!(parser.stats().rejected(), 0);
        assert_eq!(got[0], tlog_frames[n], "datagram {n}");
        n += 1;
    }
    assert_eq!(n, FLIGHT_FRAMES);
}

#[test]
fn flight_frames_decode_sensible_headers() {
    // The first SCALED_PRESSURE of the flight (seed vector pass.30).
    let bytes = read_data("seed_scaled_pressure/pass.30");
    let f = Frame::parse_exact(&bytes).expect("valid frame");
    assert_eq!(f.name(), "SCALED_PRESSURE");
    assert_eq!(f.payload_len(), 14);
    assert_eq!(f.target(), None);
    assert_eq!(
        f.to_string(),
        format!("SCALED_PRESSURE (#29) from {} (v2.0)", f.source())
    );
}
