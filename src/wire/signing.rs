//! MAVLink 2 message signing: the 6-byte signature is the start of
//! SHA-256(secret key ‖ frame up to and including the signature timestamp).
//!
//! The cryptographic check and the byte edits of signing a frame live here; which key,
//! what to do with unsigned frames and how to guard against replays is policy for the
//! layers above (`crate::signing`).

use sha2::{Digest, Sha256};

use super::Packet;
use super::crc::SIGNED_FLAG_DELTA;
use super::frame::Frame;
use super::header::{
    CHECKSUM_LEN, HEADER_LEN_V2, INCOMPAT_SIGNED, MAX_FRAME_LEN, SIGNATURE_LEN, V2,
};

/// Offset of the incompatibility flags in a MAVLink 2 header (from the header table).
const INCOMPAT_AT: usize = match V2.incompat_flags {
    Some(at) => at,
    None => panic!("a MAVLink 2 header has incompatibility flags"),
};

/// A signature's time: units of 10 µs since 2015-01-01 00:00 UTC, 48 bits on the wire.
/// Not a [`crate::time::Timestamp`] (the router's monotonic "now"): a signing term, on
/// the wall clock's scale, that only ever goes up per stream.
pub type SigningTime = u64;

/// A 32-byte MAVLink 2 signing key.
pub type SecretKey = [u8; 32];

/// Length of the signature value proper (the tail of the signature block).
pub const SIGNATURE_VALUE_LEN: usize = 6;

/// Signature value of `signed_part`: the frame from its magic byte through the
/// signature's link id and 6-byte timestamp.
pub fn compute_signature(key: &SecretKey, signed_part: &[u8]) -> [u8; SIGNATURE_VALUE_LEN] {
    let mut hasher = Sha256::new();
    hasher.update(key);
    hasher.update(signed_part);
    let digest = hasher.finalize();
    let mut out = [0u8; SIGNATURE_VALUE_LEN];
    out.copy_from_slice(&digest[..SIGNATURE_VALUE_LEN]);
    out
}

/// True if `frame` is signed and its signature is valid for `key`. Unsigned frames
/// return false. The comparison takes the same time wherever the values differ.
pub fn verify(frame: &Frame<'_>, key: &SecretKey) -> bool {
    let Some(sig) = frame.signature() else {
        return false;
    };
    let bytes = frame.as_bytes();
    let signed_part = &bytes[..bytes.len() - SIGNATURE_VALUE_LEN];
    debug_assert!(bytes.len() >= SIGNATURE_LEN);
    let expected = compute_signature(key, signed_part);
    expected
        .iter()
        .zip(sig.value())
        .fold(0u8, |acc, (a, b)| acc | (a ^ b))
        == 0
}

/// True if `frame` (a whole frame, as queued) can take a signature: MAVLink 2 and not
/// signed yet.
#[inline]
pub fn wants_signature(frame: &[u8]) -> bool {
    frame.len() >= HEADER_LEN_V2 + CHECKSUM_LEN
        && frame[0] == V2.magic
        && frame[INCOMPAT_AT] & INCOMPAT_SIGNED == 0
}

/// Bytes `frame` takes once signed (its own length when it is not to be signed, see
/// [`wants_signature`]).
#[inline]
pub fn signed_len(frame: &[u8]) -> usize {
    if wants_signature(frame) {
        frame.len() + SIGNATURE_LEN
    } else {
        frame.len()
    }
}

/// `frame` with the signed flag set, its checksum made again (the flag is covered by it)
/// and a signature block with `link_id`, `timestamp` and the signature by `key`
/// appended; `None` if it does not want a signature (see [`wants_signature`]) or would
/// be too long. The checksum is not checked: a frame with a wrong one stays wrong. Built
/// on the stack and copied once into the packet.
pub fn add_signature(
    frame: &[u8],
    key: &SecretKey,
    link_id: u8,
    timestamp: SigningTime,
) -> Option<Packet> {
    if !wants_signature(frame) || frame.len() + SIGNATURE_LEN > MAX_FRAME_LEN {
        return None;
    }
    let body = frame.len() - CHECKSUM_LEN;
    let mut out = [0u8; MAX_FRAME_LEN];
    out[..body].copy_from_slice(&frame[..body]);
    out[INCOMPAT_AT] |= INCOMPAT_SIGNED;
    // The checksum is linear: setting the flag changes it by the flag bit's own
    // contribution, which depends only on how many bytes follow it.
    let old = u16::from_le_bytes([frame[body], frame[body + 1]]);
    let crc = old ^ SIGNED_FLAG_DELTA[body - INCOMPAT_AT];
    out[body..body + CHECKSUM_LEN].copy_from_slice(&crc.to_le_bytes());
    let at = body + CHECKSUM_LEN;
    out[at] = link_id;
    out[at + 1..at + 7].copy_from_slice(&timestamp.to_le_bytes()[..6]);
    let value = compute_signature(key, &out[..at + 7]);
    out[at + 7..at + SIGNATURE_LEN].copy_from_slice(&value);
    Some(Packet::from(&out[..at + SIGNATURE_LEN]))
}
