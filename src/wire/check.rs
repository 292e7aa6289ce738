//! Judging a frame candidate: the bytes at a magic byte either start a valid frame, start
//! something that is not one ([`Rejection`]), or need more bytes before a verdict.

use std::fmt;

use crate::dialect::{self, MessageInfo};

use super::crc::frame_checksum;
use super::header::{self, CHECKSUM_START, INCOMPAT_SIGNED, Layout, MAGIC_V2};

/// Why a frame candidate was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// The checksum (with CRC_EXTRA) does not match.
    BadCrc,
    /// The message id is not part of the dialect.
    UnknownId(u32),
    /// A v2 frame sets incompatibility flags this implementation does not understand.
    BadFlags(u8),
    /// The payload length is outside what the message allows.
    BadLength {
        /// Message id of the frame.
        id: u32,
        /// Payload length the frame claims.
        len: u8,
    },
    /// The stream ended before the frame did.
    Truncated {
        /// Bytes the frame needs.
        needed: usize,
        /// Bytes there were.
        have: usize,
    },
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Rejection::BadCrc => write!(f, "bad checksum"),
            Rejection::UnknownId(id) => {
                write!(
                    f,
                    "message id #{id} is not part of the '{}' dialect",
                    dialect::DIALECT_NAME
                )
            }
            Rejection::BadFlags(flags) => write!(f, "unknown incompatibility flags 0x{flags:02x}"),
            Rejection::BadLength { id, len } => {
                write!(f, "payload length {len} is not valid for message #{id}")
            }
            Rejection::Truncated { needed, have } => {
                write!(f, "truncated frame: needs {needed} bytes, {have} present")
            }
        }
    }
}

/// Outcome of looking at bytes that start with a magic byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Candidate {
    /// At least this many bytes in total are needed before a verdict.
    NeedMore(usize),
    /// The bytes do not start a valid frame.
    Reject(Rejection),
    /// A valid frame of this many bytes starts here.
    Frame(usize, &'static MessageInfo),
}

/// Judges the frame candidate at the start of `s` (which must start with a magic byte).
/// Header problems are reported as soon as the header is complete, so a bad frame costs
/// no waiting for bytes that belong to the next one. With `check_crc` false only the
/// structure is checked (for tools that inspect captures with damaged checksums).
#[inline]
pub(crate) fn check_candidate(s: &[u8], check_crc: bool) -> Candidate {
    // One copy of the checks per version, each with its layout known at compile time.
    if s[0] == MAGIC_V2 {
        check_with(&header::V2, s, check_crc)
    } else {
        check_with(&header::V1, s, check_crc)
    }
}

#[inline(always)]
fn check_with(l: &'static Layout, s: &[u8], check_crc: bool) -> Candidate {
    if s.len() < l.header_len {
        return Candidate::NeedMore(l.header_len);
    }
    let v2 = l.magic == MAGIC_V2;
    let len = l.read_payload_len(s);
    let flags = l.read_incompat_flags(s);
    if flags & !INCOMPAT_SIGNED != 0 {
        return Candidate::Reject(Rejection::BadFlags(flags));
    }
    let id = l.read_message_id(s);
    let Some(info) = dialect::by_id(id) else {
        return Candidate::Reject(Rejection::UnknownId(id));
    };
    // v1 carries the whole base payload (extensions allowed); v2 may drop trailing zero
    // bytes but never the first one.
    let min = if v2 { 1 } else { info.min_len };
    if len < min || len > info.max_len {
        return Candidate::Reject(Rejection::BadLength { id, len });
    }
    let body = l.header_len + len as usize;
    let total = l.frame_len(len, flags);
    if s.len() < total {
        return Candidate::NeedMore(total);
    }
    let wire = u16::from_le_bytes([s[body], s[body + 1]]);
    if check_crc && frame_checksum(&s[CHECKSUM_START..body], info.crc_extra) != wire {
        return Candidate::Reject(Rejection::BadCrc);
    }
    Candidate::Frame(total, info)
}
