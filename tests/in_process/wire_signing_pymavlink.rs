//! MAVLink 2 signing checked against pymavlink, an independent implementation:
//! frames it signs verify with our code, frames we sign verify with it, and our encoder
//! reproduces its signed frames byte for byte.

use crate::common;

use common::{hex, run_py, unhex};
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, SignWith, encode_v2};
use mavtables::wire::signing::{SecretKey, verify};

fn key() -> SecretKey {
    let mut k = [0u8; 32];
    for (i, b) in k.iter_mut().enumerate() {
        *b = i as u8;
    }
    k
}

fn pymavlink_frames() -> Vec<Vec<u8>> {
    let out = run_py("signing.py", &["make"], "");
    let frames: Vec<Vec<u8>> = out.split_whitespace().map(unhex).collect();
    assert_eq!(frames.len(), 7, "pymavlink should have produced 7 frames");
    frames
}

#[test]
fn frames_signed_by_pymavlink_verify() {
    for bytes in pymavlink_frames() {
        let frame = Frame::parse_exact(&bytes).unwrap_or_else(|e| panic!("{}: {e}", hex(&bytes)));
        assert!(frame.is_signed());
        let sig = frame.signature().expect("signature block");
        assert_eq!(sig.link_id(), 3);
        assert!(sig.timestamp() >= 0x123456789A);
        assert_eq!(frame.source().to_string(), "42.7");
        assert!(
            verify(&frame, &key()),
            "valid signature rejected: {}",
            hex(&bytes)
        );
    }
}

#[test]
fn wrong_key_or_tampered_signature_fails() {
    let mut other = key();
    other[31] ^= 0x80;
    for bytes in pymavlink_frames() {
        let frame = Frame::parse_exact(&bytes).expect("valid frame");
        assert!(
            !verify(&frame, &other),
            "signature accepted with the wrong key"
        );
        // Flip a bit of the timestamp: the signature no longer matches, but the frame
        // is still well formed (the CRC does not cover the signature block).
        let mut t = bytes.clone();
        let at = t.len() - 8;
        t[at] ^= 1;
        let frame = Frame::parse_exact(&t).expect("still a well-formed frame");
        assert!(!verify(&frame, &key()), "tampered timestamp accepted");
    }
}

#[test]
fn unsigned_frames_do_not_verify() {
    let mut out = Vec::new();
    let header = Header {
        seq: 1,
        system: 1,
        component: 1,
    };
    encode_v2(header, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3], None, &mut out).expect("encode");
    let frame = Frame::parse_exact(&out).expect("parse");
    assert!(!verify(&frame, &key()));
}

#[test]
fn our_encoder_reproduces_pymavlink_signed_frames() {
    for bytes in pymavlink_frames() {
        let frame = Frame::parse_exact(&bytes).expect("valid frame");
        let sig = frame.signature().expect("signed");
        let header = Header {
            seq: frame.seq(),
            system: frame.system(),
            component: frame.component(),
        };
        let k = key();
        let signing = SignWith {
            key: &k,
            link_id: sig.link_id(),
            timestamp: sig.timestamp(),
        };
        let mut ours = Vec::new();
        encode_v2(
            header,
            frame.message_id(),
            frame.payload(),
            Some(signing),
            &mut ours,
        )
        .expect("encode");
        assert_eq!(hex(&ours), hex(&bytes), "{}", frame.name());
    }
}

#[test]
fn pymavlink_verifies_frames_we_sign() {
    let k = key();
    let mut lines = String::new();
    let payloads: [(u32, Vec<u8>); 3] = [
        (0, vec![0, 0, 0, 0, 6, 8, 0, 0, 3]),
        (4, vec![0x40, 0xe2, 1, 0, 0, 0, 0, 0, 7, 0, 1, 1, 0, 0]),
        (11, vec![0, 0, 0, 0, 1, 1]),
    ];
    for (n, (id, payload)) in payloads.iter().enumerate() {
        let mut out = Vec::new();
        let header = Header {
            seq: n as u8,
            system: 9,
            component: 1,
        };
        let signing = SignWith {
            key: &k,
            link_id: 3,
            timestamp: 0x2000_0000_0000 + n as u64,
        };
        encode_v2(header, *id, payload, Some(signing), &mut out).expect("encode");
        lines.push_str(&hex(&out));
        lines.push('\n');
    }
    // And one with a corrupted signature value, which pymavlink must refuse.
    let mut bad = Vec::new();
    let signing = SignWith {
        key: &k,
        link_id: 3,
        timestamp: 0x2000_0000_0100,
    };
    encode_v2(
        Header {
            seq: 9,
            system: 9,
            component: 1,
        },
        0,
        &payloads[0].1,
        Some(signing),
        &mut bad,
    )
    .expect("encode");
    let last = bad.len() - 1;
    bad[last] ^= 0xff;
    lines.push_str(&hex(&bad));
    let verdicts: Vec<String> = run_py("signing.py", &["verify"], &lines)
        .split_whitespace()
        .map(String::from)
        .collect();
    assert_eq!(verdicts, ["ok", "ok", "ok", "bad"]);
}
