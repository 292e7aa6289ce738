//! Signatures the router adds: an unsigned MAVLink 2 frame leaving through an interface
//! with a key gets the signed flag, a new checksum (the flag is covered by it) and a
//! signature block with the interface's link id and the router's timestamp. Frames
//! already signed and MAVLink 1 frames (which have no room for a signature) are not
//! touched.

use super::key::SigningKey;
use crate::wire::Packet;
use crate::wire::signing::SigningTime;
pub use crate::wire::signing::{signed_len, wants_signature};

/// `frame` signed with `key`, `link_id` and `timestamp`, or `None` if it is not to be
/// signed (see [`wants_signature`]). The bytes are edited by
/// [`crate::wire::signing::add_signature`], which needs no dialect: messages of a
/// loaded dialect file and unknown ids taken in are signed too.
pub fn sign(frame: &[u8], key: &SigningKey, link_id: u8, timestamp: SigningTime) -> Option<Packet> {
    crate::wire::signing::add_signature(frame, key.as_bytes(), link_id, timestamp)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Frame;
    use crate::wire::encode::{Header, SignWith, encode_v1, encode_v2};
    use crate::wire::header::MAGIC_V2;
    use crate::wire::signing::verify;

    const KEY: [u8; 32] = [7; 32];

    fn header() -> Header {
        Header {
            seq: 9,
            system: 1,
            component: 1,
        }
    }

    #[test]
    fn a_signed_copy_equals_what_the_encoder_signs() {
        let key = SigningKey::from_bytes(KEY);
        let payload = [1, 2, 3, 4, 5, 6, 7, 8, 9];
        let mut plain = Vec::new();
        encode_v2(header(), 0, &payload, None, &mut plain).expect("heartbeat");
        let mut expected = Vec::new();
        let signing = SignWith {
            key: &KEY,
            link_id: 3,
            timestamp: 123_456_789,
        };
        encode_v2(header(), 0, &payload, Some(signing), &mut expected).expect("heartbeat");
        let signed = sign(&plain, &key, 3, 123_456_789).expect("v2 unsigned");
        assert_eq!(&signed[..], &expected[..]);
        assert_eq!(signed_len(&plain), signed.len());
        let frame = Frame::parse_exact(&signed).expect("valid");
        assert!(verify(&frame, &KEY));
        assert_eq!(frame.signature().map(|s| s.link_id()), Some(3));
    }

    #[test]
    fn the_checksum_is_right_for_every_payload_length() {
        let key = SigningKey::from_bytes(KEY);
        for len in 1..=255usize {
            // ENCAPSULATED_DATA (id 131) takes up to 255 bytes; non-zero last byte keeps
            // the length.
            let payload: Vec<u8> = (0..len).map(|i| ((i * 7) % 255 + 1) as u8).collect();
            let mut plain = Vec::new();
            encode_v2(header(), 131, &payload, None, &mut plain).expect("encode");
            let signed = sign(&plain, &key, 0, 99).expect("signed");
            let frame = Frame::parse_exact(&signed).expect("a valid checksum");
            assert_eq!(frame.payload().len(), len);
            assert!(verify(&frame, &KEY));
        }
    }

    #[test]
    fn signed_and_v1_frames_are_left_alone() {
        let key = SigningKey::from_bytes(KEY);
        let mut v1 = Vec::new();
        encode_v1(header(), 0, &[0; 9], &mut v1).expect("heartbeat");
        assert!(sign(&v1, &key, 0, 1).is_none());
        assert_eq!(signed_len(&v1), v1.len());
        let mut signed = Vec::new();
        let signing = SignWith {
            key: &KEY,
            link_id: 0,
            timestamp: 1,
        };
        encode_v2(header(), 0, &[1; 9], Some(signing), &mut signed).expect("heartbeat");
        assert!(sign(&signed, &key, 0, 2).is_none());
        assert!(sign(&[MAGIC_V2, 0, 0], &key, 0, 2).is_none(), "too short");
    }
}
