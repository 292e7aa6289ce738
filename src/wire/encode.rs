//! Building frames: the inverse of the parser, for tools (replay, load generation)
//! and tests. Payloads are given in wire order; missing trailing bytes are zeros.

use std::fmt;

use crate::dialect::{self, MessageInfo};

use super::crc::frame_checksum;
use super::header::{CHECKSUM_START, HeaderRepr, INCOMPAT_SIGNED, Version};
use super::signing::{SecretKey, SigningTime, compute_signature};

/// Header fields chosen by the sender.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Header {
    /// Sequence number.
    pub seq: u8,
    /// Sender's system id.
    pub system: u8,
    /// Sender's component id.
    pub component: u8,
}

/// How to sign a MAVLink 2 frame.
#[derive(Debug, Clone, Copy)]
pub struct SignWith<'k> {
    /// Secret key.
    pub key: &'k SecretKey,
    /// Link id to put in the signature block.
    pub link_id: u8,
    /// Timestamp (10 µs units since 2015-01-01), 48 bits.
    pub timestamp: SigningTime,
}

/// Why a frame could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The message id is not part of the dialect.
    UnknownId(u32),
    /// MAVLink 1 cannot carry message ids above 255.
    IdTooLargeForV1(u32),
    /// The payload is longer than the message.
    PayloadTooLong {
        /// Bytes given.
        len: usize,
        /// Most the message takes.
        max: usize,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::UnknownId(id) => write!(f, "unknown message id #{id}"),
            EncodeError::IdTooLargeForV1(id) => {
                write!(f, "message id #{id} does not fit MAVLink 1")
            }
            EncodeError::PayloadTooLong { len, max } => {
                write!(
                    f,
                    "payload of {len} bytes is longer than the message's {max}"
                )
            }
        }
    }
}

impl std::error::Error for EncodeError {}

fn lookup(id: u32, payload: &[u8]) -> Result<&'static MessageInfo, EncodeError> {
    let info = dialect::by_id(id).ok_or(EncodeError::UnknownId(id))?;
    if payload.len() > info.max_len as usize {
        return Err(EncodeError::PayloadTooLong {
            len: payload.len(),
            max: info.max_len as usize,
        });
    }
    Ok(info)
}

/// Appends the header of `repr` to `out`.
fn push_header(out: &mut Vec<u8>, repr: &HeaderRepr) {
    let start = out.len();
    out.resize(start + repr.buffer_len(), 0);
    repr.emit(&mut out[start..]);
}

/// Appends the checksum of the frame that starts at `out[start]` (header and payload).
fn push_checksum(out: &mut Vec<u8>, start: usize, crc_extra: u8) {
    let crc = frame_checksum(&out[start + CHECKSUM_START..], crc_extra);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Appends a MAVLink 1 frame to `out`. The payload is cut or zero-extended to the
/// message's base length (extension fields do not exist in v1).
pub fn encode_v1(
    header: Header,
    id: u32,
    payload: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    let info = lookup(id, payload)?;
    let id8 = u8::try_from(id).map_err(|_| EncodeError::IdTooLargeForV1(id))?;
    let len = info.min_len as usize;
    let start = out.len();
    push_header(
        out,
        &HeaderRepr {
            version: Version::V1,
            payload_len: info.min_len,
            incompat_flags: 0,
            compat_flags: 0,
            seq: header.seq,
            system: header.system,
            component: header.component,
            message_id: u32::from(id8),
        },
    );
    let given = payload.len().min(len);
    out.extend_from_slice(&payload[..given]);
    out.resize(out.len() + (len - given), 0);
    push_checksum(out, start, info.crc_extra);
    Ok(())
}

/// Appends a MAVLink 2 frame to `out`, with trailing zero bytes of the payload
/// truncated (the first byte is always kept) and signed if `signing` is given.
pub fn encode_v2(
    header: Header,
    id: u32,
    payload: &[u8],
    signing: Option<SignWith<'_>>,
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    let info = lookup(id, payload)?;
    let kept = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
    let len = kept.max(1);
    let start = out.len();
    let flags = if signing.is_some() {
        INCOMPAT_SIGNED
    } else {
        0
    };
    push_header(
        out,
        &HeaderRepr {
            version: Version::V2,
            payload_len: len as u8,
            incompat_flags: flags,
            compat_flags: 0,
            seq: header.seq,
            system: header.system,
            component: header.component,
            message_id: id,
        },
    );
    out.extend_from_slice(&payload[..len.min(payload.len())]);
    if payload.is_empty() {
        out.push(0);
    }
    push_checksum(out, start, info.crc_extra);
    if let Some(s) = signing {
        out.push(s.link_id);
        out.extend_from_slice(&s.timestamp.to_le_bytes()[..6]);
        let sig = compute_signature(s.key, &out[start..]);
        out.extend_from_slice(&sig);
    }
    Ok(())
}

/// Appends an unsigned MAVLink 2 frame whose payload is exactly `payload`: no trailing
/// zeros dropped and no length limit but the wire's 255 bytes, so it can be longer than
/// the message's known length (as from a newer dialect's extension fields) or empty
/// (which no receiver accepts). For tests and tools that need such frames.
pub fn encode_v2_exact(
    header: Header,
    id: u32,
    payload: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    let info = dialect::by_id(id).ok_or(EncodeError::UnknownId(id))?;
    let len = u8::try_from(payload.len()).map_err(|_| EncodeError::PayloadTooLong {
        len: payload.len(),
        max: u8::MAX as usize,
    })?;
    let start = out.len();
    push_header(
        out,
        &HeaderRepr {
            version: Version::V2,
            payload_len: len,
            incompat_flags: 0,
            compat_flags: 0,
            seq: header.seq,
            system: header.system,
            component: header.component,
            message_id: id,
        },
    );
    out.extend_from_slice(payload);
    push_checksum(out, start, info.crc_extra);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Frame;

    #[test]
    fn exact_payloads_are_kept_as_given() {
        let h = Header {
            seq: 3,
            system: 1,
            component: 2,
        };
        let mut out = Vec::new();
        encode_v2_exact(h, 0, &[0; 9], &mut out).expect("known id");
        let f = Frame::parse_exact(&out).expect("valid");
        assert_eq!(f.payload(), &[0; 9], "trailing zeros are not dropped");
        assert_eq!(
            encode_v2_exact(h, 0, &[0; 256], &mut out),
            Err(EncodeError::PayloadTooLong { len: 256, max: 255 })
        );
        assert_eq!(
            encode_v2_exact(h, 0x00ff_ffff, &[1], &mut out),
            Err(EncodeError::UnknownId(0x00ff_ffff))
        );
    }
}
