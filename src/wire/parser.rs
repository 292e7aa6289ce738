//! The streaming frame parser: bytes in (arbitrary chunks from a serial port, or whole
//! datagrams), checked frames out.
//!
//! Every candidate frame is checked (known id, known incompatibility flags, payload
//! length within the message's limits, checksum with CRC_EXTRA). When a candidate is
//! rejected the parser resumes scanning at the byte after the candidate's start byte,
//! so a corrupt frame never hides a good frame behind it. Frames lying wholly inside
//! the chunk being fed are handed out without copying; only a frame that straddles two
//! chunks is assembled in a small internal buffer (at most one frame long).
//!
//! A MAVLink 2 frame longer than its message's known length is handed out when its
//! checksum holds (a newer autopilot's extension fields; see [`super::check`]) and counted
//! in [`ParserStats::longer_than_known`]; [`Checks::STRICT`] rejects it instead. The cost
//! of this: a corrupt length byte on a known id is no longer rejected at the header, so
//! the parser may hold up to one longest frame (280 bytes) before the checksum rejects
//! the candidate and it rescans the bytes behind its start. On a serial line or UDP
//! sender that goes quiet meanwhile, [`Parser::finish`] (called by the routing core for a
//! stale tail) releases them; on TCP they wait for the rest of their frame.

use std::fmt;
use std::ops::AddAssign;

use super::check::{Candidate, Checks, Rejection, check_candidate};
use super::frame::Frame;
use super::header::{MAX_FRAME_LEN, Version};
use crate::dialect::Dialect;

/// Running totals of what a parser has seen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ParserStats {
    /// Valid frames handed out.
    pub frames: u64,
    /// Of `frames`, v2 frames longer than their message's known length (accepted for
    /// their good checksum: extension fields this dialect does not know).
    pub longer_than_known: u64,
    /// Candidates rejected for a checksum mismatch.
    pub bad_crc: u64,
    /// Candidates rejected for a message id outside the dialect.
    pub unknown_id: u64,
    /// Candidates rejected for unknown incompatibility flags.
    pub bad_flags: u64,
    /// Candidates rejected for a payload length the message does not allow (including,
    /// under [`Checks::STRICT`], v2 frames longer than the message's known length).
    pub bad_length: u64,
    /// Candidates cut short by the end of the stream ([`Parser::finish`]).
    pub truncated: u64,
    /// Bytes skipped while looking for a frame start (including the start bytes of
    /// rejected candidates).
    pub junk_bytes: u64,
}

impl ParserStats {
    /// Counts a valid frame.
    #[inline]
    fn count_frame(&mut self, frame: &Frame<'_>) {
        self.frames += 1;
        if frame.is_longer_than_known() {
            self.longer_than_known += 1;
        }
    }

    fn count(&mut self, why: Rejection) {
        match why {
            Rejection::BadCrc => self.bad_crc += 1,
            Rejection::UnknownId(_) => self.unknown_id += 1,
            Rejection::BadFlags(_) => self.bad_flags += 1,
            Rejection::BadLength { .. } | Rejection::LongerThanKnown { .. } => self.bad_length += 1,
            Rejection::Truncated { .. } => self.truncated += 1,
        }
    }

    /// Total candidates rejected, whatever the reason.
    pub fn rejected(&self) -> u64 {
        self.bad_crc + self.unknown_id + self.bad_flags + self.bad_length + self.truncated
    }
}

/// The counters on one line, the way the router's counters and `inspect`'s summary print
/// them: `N frames, N bad checksum, N unknown id, N bad flags, N bad length, N truncated,
/// N longer than known, N junk bytes`.
impl fmt::Display for ParserStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} frames, {} bad checksum, {} unknown id, {} bad flags, {} bad length, \
             {} truncated, {} longer than known, {} junk bytes",
            self.frames,
            self.bad_crc,
            self.unknown_id,
            self.bad_flags,
            self.bad_length,
            self.truncated,
            self.longer_than_known,
            self.junk_bytes
        )
    }
}

/// Adds another parser's totals (e.g. one parser per datagram or per tlog record).
impl AddAssign for ParserStats {
    fn add_assign(&mut self, other: ParserStats) {
        let ParserStats {
            frames,
            longer_than_known,
            bad_crc,
            unknown_id,
            bad_flags,
            bad_length,
            truncated,
            junk_bytes,
        } = other;
        self.frames += frames;
        self.longer_than_known += longer_than_known;
        self.bad_crc += bad_crc;
        self.unknown_id += unknown_id;
        self.bad_flags += bad_flags;
        self.bad_length += bad_length;
        self.truncated += truncated;
        self.junk_bytes += junk_bytes;
    }
}

/// What the parser reports while it works. Only [`ParseEvents::frame`] is required.
pub trait ParseEvents {
    /// A valid frame was found.
    fn frame(&mut self, frame: Frame<'_>);
    /// A candidate starting at stream offset `offset` was rejected.
    fn rejected(&mut self, _offset: u64, _why: Rejection) {}
    /// `len` bytes starting at stream offset `offset` were skipped as junk.
    fn junk(&mut self, _offset: u64, _len: usize) {}
}

/// Adapts a closure that only wants frames.
struct OnFrame<F>(F);

impl<F: FnMut(Frame<'_>)> ParseEvents for OnFrame<F> {
    #[inline]
    fn frame(&mut self, frame: Frame<'_>) {
        (self.0)(frame)
    }
}

#[inline]
fn is_magic(b: u8) -> bool {
    Version::from_magic(b).is_some()
}

/// A streaming MAVLink v1/v2 parser. One per byte stream (serial port, UDP sender, file).
#[derive(Debug)]
pub struct Parser {
    /// A frame candidate that started in an earlier chunk (starts with a magic byte).
    pending: Vec<u8>,
    /// Stream offset of `pending[0]`.
    pending_offset: u64,
    /// Stream offset of the next byte to be fed.
    position: u64,
    stats: ParserStats,
    /// What is checked beyond structure.
    checks: Checks,
    /// The messages known.
    dialect: Dialect,
}

impl Default for Parser {
    fn default() -> Self {
        Self::new()
    }
}

impl Parser {
    /// A parser at the start of a stream, with the checks a router makes
    /// ([`Checks::ROUTING`]).
    pub fn new() -> Self {
        Parser::with_checks(Checks::ROUTING)
    }

    /// A parser at the start of a stream, making `checks`.
    pub fn with_checks(checks: Checks) -> Self {
        Parser {
            pending: Vec::with_capacity(MAX_FRAME_LEN),
            pending_offset: 0,
            position: 0,
            stats: ParserStats::default(),
            checks,
            dialect: Dialect::builtin(),
        }
    }

    /// This parser, knowing the messages of `dialect` (the built-in table by default).
    pub fn with_dialect(mut self, dialect: Dialect) -> Self {
        self.dialect = dialect;
        self
    }

    /// Knows the messages of `dialect` from the next candidate on.
    pub fn set_dialect(&mut self, dialect: Dialect) {
        self.dialect = dialect;
    }

    /// Makes `checks` from the next candidate on.
    pub fn set_checks(&mut self, checks: Checks) {
        self.checks = checks;
    }

    /// What this parser checks.
    pub fn checks(&self) -> Checks {
        self.checks
    }

    /// A parser that checks frame structure (magic, flags, known id, length limits) but
    /// not checksums. For inspecting captures; never for routing.
    pub fn without_crc_check() -> Self {
        Parser::with_checks(Checks {
            crc: false,
            known_length: true,
            accept_unknown: false,
        })
    }

    /// Totals so far.
    pub fn stats(&self) -> &ParserStats {
        &self.stats
    }

    /// Number of bytes fed so far.
    pub fn position(&self) -> u64 {
        self.position
    }

    /// Bytes of an incomplete frame candidate held back, waiting for the rest.
    pub fn pending_len(&self) -> usize {
        self.pending.len()
    }

    /// Stream offset where the held-back candidate starts, if there is one.
    pub fn pending_offset(&self) -> Option<u64> {
        (!self.pending.is_empty()).then_some(self.pending_offset)
    }

    /// Counts `n` bytes that the transport dropped before they reached the parser (the
    /// text messages of a WebSocket, which carries MAVLink in binary ones) as junk.
    pub fn count_dropped(&mut self, n: usize) {
        self.stats.junk_bytes += n as u64;
    }

    /// Forgets any partial frame (e.g. when a datagram arrives from another sender).
    /// The held-back bytes are counted as junk.
    pub fn clear(&mut self) {
        self.stats.junk_bytes += self.pending.len() as u64;
        self.pending.clear();
    }

    /// Feeds bytes and calls `on_frame` for every valid frame they complete.
    #[inline]
    pub fn feed(&mut self, data: &[u8], on_frame: impl FnMut(Frame<'_>)) {
        self.feed_events(data, &mut OnFrame(on_frame));
    }

    /// Feeds bytes and reports frames, rejected candidates and junk to `events`.
    pub fn feed_events<E: ParseEvents>(&mut self, data: &[u8], events: &mut E) {
        let data = self.finish_pending(data, false, events);
        self.scan(data, events);
    }

    /// Declares the end of the stream (end of file, or a link gone quiet): a held-back
    /// candidate that is still incomplete is rejected as truncated, and the bytes behind
    /// its start are scanned again, so a valid frame hiding there is not lost.
    pub fn finish<E: ParseEvents>(&mut self, events: &mut E) {
        self.finish_pending(&[], true, events);
    }

    /// [`Parser::finish`] for callers that only want frames.
    pub fn finish_frames(&mut self, on_frame: impl FnMut(Frame<'_>)) {
        self.finish(&mut OnFrame(on_frame));
    }

    /// Completes (or rejects) a candidate carried over from earlier chunks, taking
    /// bytes from `data` only as needed. Returns the bytes of `data` not yet looked at.
    fn finish_pending<'d, E: ParseEvents>(
        &mut self,
        mut data: &'d [u8],
        at_end: bool,
        events: &mut E,
    ) -> &'d [u8] {
        while !self.pending.is_empty() {
            // After a rejection the held-back bytes may start with junk: skip to a magic byte.
            if !is_magic(self.pending[0]) {
                let skip = self
                    .pending
                    .iter()
                    .position(|&b| is_magic(b))
                    .unwrap_or(self.pending.len());
                self.skip_pending(skip, events);
                continue;
            }
            match check_candidate(&self.pending, self.checks, &self.dialect) {
                Candidate::NeedMore(total) => {
                    let take = (total - self.pending.len()).min(data.len());
                    self.pending.extend_from_slice(&data[..take]);
                    data = &data[take..];
                    self.position += take as u64;
                    if self.pending.len() < total {
                        if !at_end {
                            return data;
                        }
                        // No more bytes will come: the candidate is cut short.
                        let why = Rejection::Truncated {
                            needed: total,
                            have: self.pending.len(),
                        };
                        self.stats.count(why);
                        events.rejected(self.pending_offset, why);
                        self.skip_pending(1, events);
                    }
                }
                Candidate::Frame(len, info) => {
                    let frame =
                        Frame::new_unchecked(&self.pending[..len], info, self.pending_offset);
                    self.stats.count_frame(&frame);
                    events.frame(frame);
                    self.pending.drain(..len);
                    self.pending_offset += len as u64;
                }
                Candidate::Reject(why) => {
                    self.stats.count(why);
                    events.rejected(self.pending_offset, why);
                    // Resynchronise at the byte after the rejected start byte.
                    self.skip_pending(1, events);
                }
            }
        }
        data
    }

    /// Drops the first `n` held-back bytes as junk.
    fn skip_pending<E: ParseEvents>(&mut self, n: usize, events: &mut E) {
        self.stats.junk_bytes += n as u64;
        events.junk(self.pending_offset, n);
        self.pending.drain(..n);
        self.pending_offset += n as u64;
    }

    /// Scans `data` (with nothing pending) and keeps an incomplete tail for later.
    fn scan<E: ParseEvents>(&mut self, data: &[u8], events: &mut E) {
        let base = self.position;
        self.position += data.len() as u64;
        let mut i = 0;
        while i < data.len() {
            if !is_magic(data[i]) {
                let skip = data[i..]
                    .iter()
                    .position(|&b| is_magic(b))
                    .unwrap_or(data.len() - i);
                self.stats.junk_bytes += skip as u64;
                events.junk(base + i as u64, skip);
                i += skip;
                continue;
            }
            let rest = &data[i..];
            match check_candidate(rest, self.checks, &self.dialect) {
                Candidate::Frame(len, info) => {
                    let frame = Frame::new_unchecked(&rest[..len], info, base + i as u64);
                    self.stats.count_frame(&frame);
                    events.frame(frame);
                    i += len;
                }
                Candidate::Reject(why) => {
                    self.stats.count(why);
                    events.rejected(base + i as u64, why);
                    self.stats.junk_bytes += 1;
                    events.junk(base + i as u64, 1);
                    i += 1;
                }
                Candidate::NeedMore(_) => {
                    self.pending.extend_from_slice(rest);
                    self.pending_offset = base + i as u64;
                    return;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::encode::{Header, encode_v1, encode_v2, encode_v2_exact};

    /// A v2 HEARTBEAT with `extra` bytes beyond its known 9 (a newer dialect's fields).
    fn longer_heartbeat(seq: u8, extra: usize) -> Vec<u8> {
        let mut payload = vec![0, 0, 0, 0, 2, 3, 0x51, 4, 3];
        payload.extend((0..extra).map(|i| i as u8 + 1));
        let mut out = Vec::new();
        let header = Header {
            seq,
            system: 1,
            component: 1,
        };
        encode_v2_exact(header, 0, &payload, &mut out).expect("encodable");
        out
    }

    fn heartbeat(seq: u8) -> Vec<u8> {
        let mut out = Vec::new();
        let header = Header {
            seq,
            system: 1,
            component: 1,
        };
        encode_v2(header, 0, &[0, 0, 0, 0, 2, 3, 0x51, 4, 3], None, &mut out).expect("encodable");
        out
    }

    /// Records every event, owned.
    #[derive(Default)]
    struct Log {
        frames: Vec<(u64, u8)>,
        rejected: Vec<(u64, Rejection)>,
        junk: Vec<(u64, usize)>,
    }

    impl ParseEvents for Log {
        fn frame(&mut self, f: Frame<'_>) {
            self.frames.push((f.offset(), f.seq()));
        }
        fn rejected(&mut self, offset: u64, why: Rejection) {
            self.rejected.push((offset, why));
        }
        fn junk(&mut self, offset: u64, len: usize) {
            self.junk.push((offset, len));
        }
    }

    #[test]
    fn junk_between_frames_is_skipped_and_counted() {
        let mut stream = b"hello".to_vec();
        stream.extend(heartbeat(1));
        stream.extend(b"xy");
        stream.extend(heartbeat(2));
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&stream, &mut log);
        assert_eq!(log.frames, [(5, 1), (28, 2)]);
        assert_eq!(log.junk, [(0, 5), (26, 2)]);
        assert_eq!(p.stats().junk_bytes, 7);
        assert_eq!(p.stats().frames, 2);
    }

    #[test]
    fn corrupt_length_does_not_swallow_the_next_frame() {
        // The original trusted the length byte: a corrupt one ate the following frames.
        // A v1 length beyond the message's is rejected at the header.
        let mut bad = Vec::new();
        let h = Header {
            seq: 1,
            system: 1,
            component: 1,
        };
        encode_v1(h, 0, &[0, 0, 0, 0, 2, 3, 0x51, 4, 3], &mut bad).expect("encodable");
        bad[1] = 200;
        let mut stream = bad.clone();
        stream.extend(heartbeat(2));
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&stream, &mut log);
        assert_eq!(log.frames, [(bad.len() as u64, 2)]);
        assert_eq!(
            log.rejected,
            [(0, Rejection::BadLength { id: 0, len: 200 })]
        );
    }

    #[test]
    fn a_corrupt_v2_length_waits_for_the_checksum_then_yields() {
        // A v2 length beyond HEARTBEAT's may be a longer frame from a newer dialect: the
        // parser waits for the checksum, which fails, and then finds the next frame.
        let mut bad = heartbeat(1);
        bad[1] = 20;
        let mut stream = bad.clone();
        stream.extend(heartbeat(2));
        stream.extend(heartbeat(3));
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&stream, &mut log);
        assert_eq!(log.rejected, [(0, Rejection::BadCrc)]);
        assert_eq!(log.frames, [(21, 2), (42, 3)]);
        // Under strict checks the header alone rejects it.
        let mut p = Parser::with_checks(Checks::STRICT);
        let mut log = Log::default();
        p.feed_events(&bad, &mut log);
        assert_eq!(
            log.rejected,
            [(
                0,
                Rejection::LongerThanKnown {
                    id: 0,
                    len: 20,
                    known: 9
                }
            )]
        );
        assert_eq!(p.pending_len(), 0, "no waiting");
    }

    #[test]
    fn bad_crc_frame_is_dropped_and_the_next_one_found_across_chunks() {
        let mut bad = heartbeat(1);
        let last = bad.len() - 1;
        bad[last] ^= 0xff;
        let mut stream = bad;
        stream.extend(heartbeat(2));
        for chunk in 1..stream.len() {
            let mut p = Parser::new();
            let mut log = Log::default();
            for c in stream.chunks(chunk) {
                p.feed_events(c, &mut log);
            }
            assert_eq!(log.frames, [(21, 2)], "chunk size {chunk}");
            assert_eq!(p.stats().bad_crc, 1);
        }
    }

    #[test]
    fn a_longer_bogus_candidate_yields_to_the_frames_inside_it() {
        // 0xFE 0xFE ... 0x6E starts a v1 FILE_TRANSFER_PROTOCOL candidate claiming 262
        // bytes; the valid frame inside it must come out when the stream ends.
        let mut stream = vec![0xfe, 0xfe, 0xfd, 0xfd, 0xfd, 0x6e];
        stream.extend(heartbeat(9));
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&stream, &mut log);
        assert!(log.frames.is_empty(), "the candidate may still complete");
        assert_eq!(p.pending_offset(), Some(0));
        p.finish(&mut log);
        assert_eq!(log.frames, [(6, 9)]);
        assert_eq!(
            log.rejected[0].1,
            Rejection::Truncated {
                needed: 262,
                have: 27
            }
        );
        assert_eq!(p.pending_len(), 0);
    }

    #[test]
    fn unknown_ids_and_flags_are_counted() {
        let mut unknown = heartbeat(1);
        unknown[7] = 0xff;
        unknown[8] = 0xff; // id 0x00ffff: not in the dialect
        let mut flags = heartbeat(2);
        flags[2] = 0x80;
        let mut stream = unknown;
        stream.extend(flags);
        stream.extend(heartbeat(3));
        let mut p = Parser::new();
        let mut seqs = Vec::new();
        p.feed(&stream, |f| seqs.push(f.seq()));
        assert_eq!(seqs, [3]);
        assert_eq!((p.stats().unknown_id, p.stats().bad_flags), (1, 1));
    }

    #[test]
    fn clear_drops_a_partial_frame() {
        let hb = heartbeat(1);
        let mut p = Parser::new();
        let mut n = 0;
        p.feed(&hb[..10], |_| n += 1);
        assert_eq!(p.pending_len(), 10);
        p.clear();
        p.feed(&hb[10..], |_| n += 1);
        p.feed(&hb, |_| n += 1);
        assert_eq!(n, 1);
        assert_eq!(p.stats().junk_bytes, 10 + (hb.len() - 10) as u64);
    }

    #[test]
    fn v1_and_signed_v2_frames_back_to_back() {
        let key = [1u8; 32];
        let mut stream = Vec::new();
        let header = Header {
            seq: 5,
            system: 10,
            component: 10,
        };
        encode_v1(header, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3], &mut stream).expect("encodable");
        let signing = crate::wire::encode::SignWith {
            key: &key,
            link_id: 1,
            timestamp: 42,
        };
        encode_v2(
            header,
            0,
            &[0, 0, 0, 0, 6, 8, 0, 0, 3],
            Some(signing),
            &mut stream,
        )
        .expect("encodable");
        let mut p = Parser::new();
        let mut seen = Vec::new();
        p.feed(&stream, |f| {
            seen.push((f.version(), f.is_signed(), f.as_bytes().len()))
        });
        use crate::wire::Version;
        assert_eq!(seen, [(Version::V1, false, 17), (Version::V2, true, 34)]);
    }

    #[test]
    fn a_longer_than_known_v2_frame_is_handed_out_and_counted() {
        let long = longer_heartbeat(1, 6);
        let mut stream = long.clone();
        stream.extend(heartbeat(2));
        // Whole, and split at every point: the same frames, the exact bytes.
        for chunk in 1..=stream.len() {
            let mut p = Parser::new();
            let mut got = Vec::new();
            for c in stream.chunks(chunk) {
                p.feed(c, |f| {
                    got.push((f.as_bytes().to_vec(), f.is_longer_than_known()))
                });
            }
            assert_eq!(
                got,
                [(long.clone(), true), (heartbeat(2), false)],
                "chunk size {chunk}"
            );
            assert_eq!(
                (p.stats().frames, p.stats().longer_than_known),
                (2, 1),
                "chunk size {chunk}"
            );
            assert_eq!(p.stats().rejected(), 0);
        }
    }

    #[test]
    fn a_longer_than_known_v2_frame_needs_its_checksum() {
        let mut bad = longer_heartbeat(1, 6);
        let last = bad.len() - 1;
        bad[last] ^= 0x01;
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&bad, &mut log);
        assert_eq!(log.rejected, [(0, Rejection::BadCrc)]);
        assert!(log.frames.is_empty());
        assert_eq!((p.stats().bad_crc, p.stats().longer_than_known), (1, 0));
        // Without checksum checks nothing vouches for the length: rejected at the header.
        let good = longer_heartbeat(1, 6);
        let mut p = Parser::without_crc_check();
        let mut log = Log::default();
        p.feed_events(&good, &mut log);
        assert!(log.frames.is_empty());
        assert!(matches!(
            log.rejected[0],
            (
                0,
                Rejection::LongerThanKnown {
                    len: 15,
                    known: 9,
                    ..
                }
            )
        ));
        assert_eq!(p.stats().bad_length, 1);
    }

    #[test]
    fn a_longer_v1_frame_is_still_a_bad_length() {
        // A v1 HEARTBEAT claiming 10 bytes, with a checksum that holds for them.
        let mut bytes = Vec::new();
        let repr = crate::wire::HeaderRepr {
            version: crate::wire::Version::V1,
            payload_len: 10,
            incompat_flags: 0,
            compat_flags: 0,
            seq: 1,
            system: 1,
            component: 1,
            message_id: 0,
        };
        bytes.resize(repr.buffer_len(), 0);
        repr.emit(&mut bytes);
        bytes.extend([0u8; 10]);
        let crc = crate::wire::crc::frame_checksum(&bytes[1..], 50);
        bytes.extend(crc.to_le_bytes());
        let mut p = Parser::new();
        let mut log = Log::default();
        p.feed_events(&bytes, &mut log);
        assert!(log.frames.is_empty());
        assert_eq!(
            log.rejected[0],
            (0, Rejection::BadLength { id: 0, len: 10 })
        );
    }

    #[test]
    fn counters_print_on_one_line_and_add_up() {
        let mut a = ParserStats {
            frames: 10,
            longer_than_known: 1,
            bad_crc: 2,
            unknown_id: 3,
            bad_flags: 4,
            bad_length: 5,
            truncated: 6,
            junk_bytes: 7,
        };
        assert_eq!(
            a.to_string(),
            "10 frames, 2 bad checksum, 3 unknown id, 4 bad flags, 5 bad length, \
             6 truncated, 1 longer than known, 7 junk bytes"
        );
        a += a;
        assert_eq!(
            a.to_string(),
            "20 frames, 4 bad checksum, 6 unknown id, 8 bad flags, 10 bad length, \
             12 truncated, 2 longer than known, 14 junk bytes"
        );
        assert_eq!(a.rejected(), 4 + 6 + 8 + 10 + 12);
    }
}
