//! Property tests of the frame parser: round trips through the encoder, chunking
//! independence, garbage resistance, byte accounting, and v2 frames longer than their
//! message's known length (forwarded when the checksum holds).

use mavtables::dialect;
use mavtables::wire::encode::{Header, SignWith, encode_v1, encode_v2, encode_v2_exact};
use mavtables::wire::{Checks, Frame, Parser, Rejection, Version};
use proptest::prelude::*;

/// A message to encode: dialect index, version, header, payload, signing.
#[derive(Debug, Clone)]
struct Msg {
    index: usize,
    v1: bool,
    header: Header,
    payload: Vec<u8>,
    sign: Option<(u8, u64)>,
}

fn msg() -> impl Strategy<Value = Msg> {
    let n = dialect::messages().len();
    (
        0..n,
        any::<bool>(),
        any::<(u8, u8, u8)>(),
        prop::collection::vec(any::<u8>(), 0..=255),
        any::<Option<(u8, u64)>>(),
    )
        .prop_map(|(index, v1, (seq, system, component), payload, sign)| {
            let info = &dialect::messages()[index];
            let v1 = v1 && info.id < 256;
            let mut payload = payload;
            payload.truncate(info.max_len as usize);
            Msg {
                index,
                v1,
                header: Header {
                    seq,
                    system,
                    component,
                },
                payload,
                sign: if v1 {
                    None
                } else {
                    sign.map(|(l, t)| (l, t & 0xffff_ffff_ffff))
                },
            }
        })
}

const KEY: [u8; 32] = [7; 32];

fn encode(m: &Msg, out: &mut Vec<u8>) {
    let id = dialect::messages()[m.index].id;
    if m.v1 {
        encode_v1(m.header, id, &m.payload, out).expect("encode v1");
    } else {
        let signing = m.sign.map(|(link_id, timestamp)| SignWith {
            key: &KEY,
            link_id,
            timestamp,
        });
        encode_v2(m.header, id, &m.payload, signing, out).expect("encode v2");
    }
}

/// Everything observable about a frame, owned.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Seen {
    bytes: Vec<u8>,
    id: u32,
}

/// Feeds `chunks` as one stream, then ends the stream.
fn parse_all(chunks: &[&[u8]]) -> (Vec<Seen>, Parser) {
    let mut parser = Parser::new();
    let mut seen = Vec::new();
    let mut keep = |f: Frame<'_>| {
        seen.push(Seen {
            bytes: f.as_bytes().to_vec(),
            id: f.message_id(),
        })
    };
    for c in chunks {
        parser.feed(c, &mut keep);
    }
    parser.finish_frames(&mut keep);
    (seen, parser)
}

/// Every byte fed is in a frame, skipped as junk, or held back: nothing is lost or
/// counted twice.
fn assert_accounting(parser: &Parser, seen: &[Seen]) {
    let in_frames: u64 = seen.iter().map(|s| s.bytes.len() as u64).sum();
    assert_eq!(
        in_frames + parser.stats().junk_bytes + parser.pending_len() as u64,
        parser.position()
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn encode_then_parse_round_trips(m in msg()) {
        let info = &dialect::messages()[m.index];
        let mut bytes = Vec::new();
        encode(&m, &mut bytes);
        let f = Frame::parse_exact(&bytes).expect("our own frame parses");
        prop_assert_eq!(f.message_id(), info.id);
        prop_assert_eq!(f.version(), if m.v1 { Version::V1 } else { Version::V2 });
        prop_assert_eq!((f.seq(), f.system(), f.component()), (m.header.seq, m.header.system, m.header.component));
        prop_assert_eq!(f.is_signed(), m.sign.is_some());
        let len = if m.v1 { info.min_len } else { info.max_len } as usize;
        let mut want = m.payload.clone();
        want.resize(len, 0);
        prop_assert_eq!(&f.payload_padded()[..len], &want[..]);
        if let Some((link, ts)) = m.sign {
            let sig = f.signature().expect("signature");
            prop_assert_eq!((sig.link_id(), sig.timestamp()), (link, ts));
            prop_assert!(mavtables::wire::signing::verify(&f, &KEY));
        }
        // The target read from a truncated payload equals the one from the full payload.
        if let Some(ofs) = info.target_system_offset {
            prop_assert_eq!(f.target().map(|a| a.system), Some(want.get(ofs as usize).copied().unwrap_or(0)));
        }
    }

    #[test]
    fn splitting_a_stream_anywhere_yields_the_same_frames(
        msgs in prop::collection::vec(msg(), 1..12),
        cuts in prop::collection::vec(any::<prop::sample::Index>(), 0..20),
    ) {
        let mut stream = Vec::new();
        for m in &msgs {
            encode(m, &mut stream);
        }
        let (whole, _) = parse_all(&[&stream]);
        prop_assert_eq!(whole.len(), msgs.len());
        let mut points: Vec<usize> = cuts.iter().map(|c| c.index(stream.len() + 1)).collect();
        points.sort_unstable();
        let mut chunks = Vec::new();
        let mut last = 0;
        for p in points {
            chunks.push(&stream[last..p]);
            last = p;
        }
        chunks.push(&stream[last..]);
        let (split, parser) = parse_all(&chunks);
        prop_assert_eq!(&split, &whole);
        assert_accounting(&parser, &split);
    }

    #[test]
    fn byte_by_byte_equals_whole(msgs in prop::collection::vec(msg(), 1..6)) {
        let mut stream = Vec::new();
        for m in &msgs {
            encode(m, &mut stream);
        }
        let bytes: Vec<&[u8]> = stream.chunks(1).collect();
        prop_assert_eq!(parse_all(&bytes).0, parse_all(&[&stream]).0);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_are_accounted_for(
        chunks in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..300), 0..8),
    ) {
        let refs: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
        let (seen, parser) = parse_all(&refs);
        assert_accounting(&parser, &seen);
    }

    #[test]
    fn magic_heavy_garbage_never_panics(
        chunk in prop::collection::vec(prop_oneof![Just(0xfdu8), Just(0xfe), any::<u8>()], 0..600),
        split in any::<prop::sample::Index>(),
    ) {
        let at = split.index(chunk.len() + 1);
        let (seen, parser) = parse_all(&[&chunk[..at], &chunk[at..]]);
        assert_accounting(&parser, &seen);
    }

    #[test]
    fn garbage_between_frames_loses_no_valid_frame(
        msgs in prop::collection::vec(msg(), 1..10),
        garbage in prop::collection::vec(
            prop::collection::vec(prop_oneof![Just(0xfdu8), Just(0xfe), any::<u8>()], 0..40), 10),
        chunk_len in 1usize..64,
    ) {
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        for (i, m) in msgs.iter().enumerate() {
            stream.extend_from_slice(&garbage[i % garbage.len()]);
            let start = stream.len();
            encode(m, &mut stream);
            expected.push(stream[start..].to_vec());
        }
        stream.extend_from_slice(&garbage[msgs.len() % garbage.len()]);
        let chunks: Vec<&[u8]> = stream.chunks(chunk_len).collect();
        let (seen, parser) = parse_all(&chunks);
        assert_accounting(&parser, &seen);
        // Every valid frame comes out, in order (garbage may, very rarely, form an extra
        // valid frame of its own, so this is a subsequence check).
        let mut it = seen.iter();
        for want in &expected {
            prop_assert!(it.any(|s| &s.bytes == want), "lost a valid frame");
        }
    }

    #[test]
    fn longer_than_known_frames_come_out_exactly_and_are_counted(
        msgs in prop::collection::vec(msg(), 0..6),
        at in any::<prop::sample::Index>(),
        index in 0..dialect::messages().len(),
        extra in prop::collection::vec(any::<u8>(), 1..=200),
        header in any::<(u8, u8, u8)>(),
        chunk_len in 1usize..64,
    ) {
        let info = &dialect::messages()[index];
        let room = 255 - info.max_len as usize;
        prop_assume!(room > 0);
        // The known payload (any bytes), then bytes of fields this dialect does not know.
        let mut payload: Vec<u8> = (0..info.max_len).map(|i| i.wrapping_mul(31)).collect();
        payload.extend(extra.iter().take(room));
        let (seq, system, component) = header;
        let mut long = Vec::new();
        encode_v2_exact(Header { seq, system, component }, info.id, &payload, &mut long)
            .expect("known id, at most 255 bytes");
        // Among ordinary frames, at any position.
        let mut stream = Vec::new();
        let slot = at.index(msgs.len() + 1);
        let mut long_at = 0;
        for (i, m) in msgs.iter().enumerate() {
            if i == slot {
                long_at = stream.len();
                stream.extend_from_slice(&long);
            }
            encode(m, &mut stream);
        }
        if slot == msgs.len() {
            long_at = stream.len();
            stream.extend_from_slice(&long);
        }
        let chunks: Vec<&[u8]> = stream.chunks(chunk_len).collect();
        let (seen, parser) = parse_all(&chunks);
        prop_assert_eq!(seen.len(), msgs.len() + 1);
        prop_assert_eq!(&seen[slot].bytes, &long, "forwarded unchanged");
        prop_assert_eq!(parser.stats().longer_than_known, 1);
        prop_assert_eq!(parser.stats().frames, msgs.len() as u64 + 1);
        assert_accounting(&parser, &seen);
        let f = Frame::parse_exact(&long).expect("a longer frame is one valid frame");
        prop_assert!(f.is_longer_than_known());
        prop_assert_eq!((f.seq(), f.system(), f.component()), (seq, system, component));
        // The target comes from the known part of the payload.
        if let Some(ofs) = info.target_system_offset {
            prop_assert_eq!(f.target().map(|a| a.system), Some(payload[ofs as usize]));
        }
        // Strict checks reject it at its header and still find every other frame.
        let mut strict = Parser::with_checks(Checks::STRICT);
        let mut rejected = Vec::new();
        let mut others = 0;
        struct Events<'a>(&'a mut Vec<(u64, Rejection)>, &'a mut usize);
        impl mavtables::wire::ParseEvents for Events<'_> {
            fn frame(&mut self, _: Frame<'_>) {
                *self.1 += 1;
            }
            fn rejected(&mut self, offset: u64, why: Rejection) {
                self.0.push((offset, why));
            }
        }
        let mut events = Events(&mut rejected, &mut others);
        for c in &chunks {
            strict.feed_events(c, &mut events);
        }
        strict.finish(&mut events);
        prop_assert_eq!(
            rejected.first().copied(),
            Some((
                long_at as u64,
                Rejection::LongerThanKnown { id: info.id, len: payload.len() as u8, known: info.max_len }
            ))
        );
        prop_assert!(others >= msgs.len(), "strict checks lost an ordinary frame");
    }
}
