//! MAVLink 2 message signing: the 6-byte signature is the start of
//! SHA-256(secret key ‖ frame up to and including the signature timestamp).
//!
//! Only the cryptographic check lives here; what to do with unsigned frames and how to
//! guard against replays is policy for the layers above.

use sha2::{Digest, Sha256};

use super::frame::Frame;
use super::header::SIGNATURE_LEN;

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
