//! Signatures the router adds: an unsigned MAVLink 2 frame leaving through an interface
//! with a key gets the signed flag, a new checksum (the flag is covered by it) and a
//! signature block with the interface's link id and the router's timestamp. Frames
//! already signed and MAVLink 1 frames (which have no room for a signature) are not
//! touched.

use super::key::SigningKey;
use crate::dialect;
use crate::routing::Packet;
use crate::wire::header::{
    CHECKSUM_LEN, HEADER_LEN_V2, INCOMPAT_SIGNED, MAGIC_V2, MAX_FRAME_LEN, SIGNATURE_LEN,
};
use crate::wire::signing::compute_signature;

/// Offset of the incompatibility flags in a MAVLink 2 header.
const INCOMPAT_AT: usize = 2;
/// Offset of the 24-bit message id in a MAVLink 2 header.
const MESSAGE_ID_AT: usize = 7;

/// One bit step of CRC-16/MCRF4XX (reflected polynomial 0x8408) for a whole byte, with
/// no initial value: the linear part of the checksum.
const fn crc_byte(mut reg: u16, byte: u8) -> u16 {
    reg ^= byte as u16;
    let mut bit = 0;
    while bit < 8 {
        reg = if reg & 1 != 0 {
            (reg >> 1) ^ 0x8408
        } else {
            reg >> 1
        };
        bit += 1;
    }
    reg
}

/// `FLAG_CRC_DELTA[k]`: how the checksum changes when the signed flag is set and `k`
/// bytes follow the flags byte up to the checksum (the rest of the header, the payload
/// and the CRC_EXTRA byte): the flag bit alone, followed by `k` zero bytes.
const FLAG_CRC_DELTA: [u16; MAX_FRAME_LEN] = {
    let mut table = [0u16; MAX_FRAME_LEN];
    let mut reg = crc_byte(0, INCOMPAT_SIGNED);
    let mut k = 0;
    while k < MAX_FRAME_LEN {
        table[k] = reg;
        reg = crc_byte(reg, 0);
        k += 1;
    }
    table
};

/// True if `frame` (a whole frame, as queued) would be signed on its way out: MAVLink 2
/// and not signed yet.
#[inline]
pub fn wants_signature(frame: &[u8]) -> bool {
    frame.len() >= HEADER_LEN_V2 + CHECKSUM_LEN
        && frame[0] == MAGIC_V2
        && frame[INCOMPAT_AT] & INCOMPAT_SIGNED == 0
}

/// Bytes `frame` takes on the wire out of an interface with a key.
#[inline]
pub fn signed_len(frame: &[u8]) -> usize {
    if wants_signature(frame) {
        frame.len() + SIGNATURE_LEN
    } else {
        frame.len()
    }
}

/// `frame` signed with `key`, `link_id` and `timestamp`, or `None` if it is not to be
/// signed (see [`wants_signature`]) or its message id is not in the dialect (its
/// checksum cannot be made again). Built on the stack and copied once into the packet.
pub fn sign(frame: &[u8], key: &SigningKey, link_id: u8, timestamp: u64) -> Option<Packet> {
    if !wants_signature(frame) || frame.len() + SIGNATURE_LEN > MAX_FRAME_LEN {
        return None;
    }
    let id = u32::from_le_bytes([
        frame[MESSAGE_ID_AT],
        frame[MESSAGE_ID_AT + 1],
        frame[MESSAGE_ID_AT + 2],
        0,
    ]);
    // Only ids of the dialect reach a queue; their checksums are valid.
    dialect::by_id(id)?;
    let body = frame.len() - CHECKSUM_LEN;
    let mut out = [0u8; MAX_FRAME_LEN];
    out[..body].copy_from_slice(&frame[..body]);
    out[INCOMPAT_AT] |= INCOMPAT_SIGNED;
    // The checksum is linear: setting the flag changes it by the flag bit's own
    // contribution, which depends only on how many bytes follow it.
    let old = u16::from_le_bytes([frame[body], frame[body + 1]]);
    let crc = old ^ FLAG_CRC_DELTA[body - INCOMPAT_AT];
    out[body..body + CHECKSUM_LEN].copy_from_slice(&crc.to_le_bytes());
    let at = body + CHECKSUM_LEN;
    out[at] = link_id;
    out[at + 1..at + 7].copy_from_slice(&timestamp.to_le_bytes()[..6]);
    let value = compute_signature(key.as_bytes(), &out[..at + 7]);
    out[at + 7..at + SIGNATURE_LEN].copy_from_slice(&value);
    Some(Packet::from(&out[..at + SIGNATURE_LEN]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Frame;
    use crate::wire::encode::{Header, Signing, encode_v1, encode_v2};
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
        let signing = Signing {
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
        let signing = Signing {
            key: &KEY,
            link_id: 0,
            timestamp: 1,
        };
        encode_v2(header(), 0, &[1; 9], Some(signing), &mut signed).expect("heartbeat");
        assert!(sign(&signed, &key, 0, 2).is_none());
        assert!(sign(&[MAGIC_V2, 0, 0], &key, 0, 2).is_none(), "too short");
    }
}
