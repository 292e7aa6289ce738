//! The flight log state machine fed arbitrary streams: autopilot heartbeats (ArduPilot,
//! PX4 or another kind, armed or not), dataflash blocks with any seqno, ulog chunks
//! with any sequence, length and first-message offset, and time passing. Nothing
//! panics, the file is told Begin and End in turn (never two logs open), what waits
//! for the writer stays bounded, and after `handle_timeout(now)` the next deadline lies
//! in the future.
#![no_main]

use std::time::Duration;

use libfuzzer_sys::fuzz_target;
use mavtables::config::{FlightLog, FlightLogMode};
use mavtables::flight_log::{FlightLogger, LogWrite};
use mavtables::time::Timestamp;
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, encode_v2};

fn frame(id: u32, component: u8, payload: &[u8]) -> Vec<u8> {
    let header = Header {
        seq: 0,
        system: 1,
        component,
    };
    let mut out = Vec::new();
    let _ = encode_v2(header, id, payload, None, &mut out);
    out
}

fuzz_target!(|data: &[u8]| {
    let mut config = FlightLog::with_defaults();
    if data.first().is_some_and(|b| b & 1 == 1) {
        config.mode = FlightLogMode::Always;
    }
    let mut log = FlightLogger::new(&config);
    let mut now = Timestamp::ZERO;
    let mut open = false;
    let mut rest = data;
    let mut take = |n: usize| -> &[u8] {
        let n = n.min(rest.len());
        let (head, tail) = rest.split_at(n);
        rest = tail;
        head
    };
    while let Some(&op) = take(1).first() {
        let arg = take(1).first().copied().unwrap_or(0);
        let bytes = match op % 5 {
            0 => {
                let autopilot = [3, 12, 8, 0][usize::from(arg) % 4];
                let base = if arg & 4 != 0 { 128 } else { 0 };
                Some(frame(0, 1, &[0, 0, 0, 0, 2, autopilot, base, 4, 3]))
            }
            1 => {
                // Mostly near the last ones, sometimes anywhere.
                let seqno = if arg & 0x80 == 0 {
                    u32::from(arg & 0x3f)
                } else {
                    let b = take(4);
                    let mut s = [0u8; 4];
                    s[..b.len()].copy_from_slice(b);
                    u32::from_le_bytes(s)
                };
                let mut p = seqno.to_le_bytes().to_vec();
                p.extend_from_slice(&[245, 190]);
                p.extend_from_slice(take(200));
                Some(frame(184, 1, &p))
            }
            2 => {
                let id = if arg & 1 == 0 { 266 } else { 267 };
                let head = take(4);
                let mut p = [0u8; 6];
                p[..head.len()].copy_from_slice(head);
                p[2] = 245;
                p[3] = 190;
                let mut p = p.to_vec();
                p.extend_from_slice(take(usize::from(arg)));
                Some(frame(id, 1, &p))
            }
            3 => {
                now = now + Duration::from_millis(u64::from(arg) * u64::from(op));
                if log.poll_timeout().is_some_and(|t| t <= now) {
                    log.handle_timeout(now);
                    assert!(log.poll_timeout().is_none_or(|t| t > now), "would spin");
                }
                None
            }
            _ => {
                log.shutdown(now);
                None
            }
        };
        if let Some(bytes) = bytes
            && let Ok(f) = Frame::parse_exact(&bytes)
        {
            let _ = log.take(&f, now);
        }
        log.drain_frames(&mut |f| assert!(Frame::parse_exact(&f).is_ok()));
        let mut held = 0;
        log.drain_writes(&mut |w| match w {
            LogWrite::Begin(_) => {
                assert!(!open, "a log begun while one is open");
                open = true;
            }
            LogWrite::End => {
                assert!(open, "an end without a log");
                open = false;
            }
            LogWrite::Data { bytes, .. } => {
                assert!(open, "data without a log");
                held += bytes.len();
            }
        });
        assert!(held <= 8 << 20);
    }
});
