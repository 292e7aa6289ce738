//! Judging a frame candidate: the bytes at a magic byte either start a valid frame, start
//! something that is not one ([`Rejection`]), or need more bytes before a verdict.
//!
//! A MAVLink 2 frame longer than its message's known length is valid when its checksum
//! holds: a newer autopilot sends extension fields this dialect does not know yet, and
//! receivers must ignore the extra bytes, so a router forwards such a frame unchanged.
//! [`Checks::STRICT`] (for `inspect --check`) rejects it instead, and so does a check
//! without checksums, which has nothing to vouch for the longer length. A MAVLink 1 frame
//! never carries extensions: a length above the message's is always rejected.
//!
//! Messages are looked up in a [`Dialect`] (the built-in table plus loaded dialects). A
//! frame whose id none of them defines is rejected, unless [`Checks::accept_unknown`]
//! (`unknown_messages accept;`): then it is framed by its length byte alone, as any id
//! may have any length, and its checksum cannot be checked (no CRC_EXTRA is known).

use std::fmt;

use crate::dialect::{self, Dialect, MessageInfo, UNKNOWN_MESSAGE};

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
    /// A v2 frame longer than its message's known length, under [`Checks::STRICT`] or
    /// without checksum checks (otherwise such a frame is valid).
    LongerThanKnown {
        /// Message id of the frame.
        id: u32,
        /// Payload length the frame claims.
        len: u8,
        /// The message's known (longest) payload length.
        known: u8,
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
            Rejection::LongerThanKnown { id, len, known } => write!(
                f,
                "payload length {len} is longer than message #{id}'s known {known} bytes"
            ),
            Rejection::Truncated { needed, have } => {
                write!(f, "truncated frame: needs {needed} bytes, {have} present")
            }
        }
    }
}

/// What is checked beyond a frame's structure (magic, known id, known incompatibility
/// flags, payload length within the message's limits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checks {
    /// Check checksums. Off only for inspecting captures with damaged checksums; then a
    /// v2 frame longer than its message's known length is rejected, as nothing vouches
    /// for its length.
    pub crc: bool,
    /// Reject a v2 frame longer than its message's known length
    /// ([`Rejection::LongerThanKnown`]) instead of accepting it.
    pub known_length: bool,
    /// Frame a message id no dialect defines by its length byte and hand it out
    /// (described by [`UNKNOWN_MESSAGE`], its checksum unchecked) instead of rejecting it
    /// ([`Rejection::UnknownId`]).
    pub accept_unknown: bool,
}

impl Checks {
    /// What a router checks: checksums; v2 frames longer than known are valid.
    pub const ROUTING: Checks = Checks {
        crc: true,
        known_length: false,
        accept_unknown: false,
    };
    /// What `inspect --check` checks: checksums, and no frame longer than known.
    pub const STRICT: Checks = Checks {
        crc: true,
        known_length: true,
        accept_unknown: false,
    };
}

impl Default for Checks {
    fn default() -> Self {
        Checks::ROUTING
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
/// no waiting for bytes that belong to the next one. The exception is a v2 frame longer
/// than its message's known length when that is allowed: only the checksum, at the end,
/// can tell such a frame from a corrupt length byte.
#[inline]
pub(crate) fn check_candidate(s: &[u8], checks: Checks, dialect: &Dialect) -> Candidate {
    // One copy of the checks per version, each with its layout known at compile time.
    if s[0] == MAGIC_V2 {
        check_with(&header::V2, s, checks, dialect)
    } else {
        check_with(&header::V1, s, checks, dialect)
    }
}

#[inline(always)]
fn check_with(l: &'static Layout, s: &[u8], checks: Checks, dialect: &Dialect) -> Candidate {
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
    let Some(info) = dialect.by_id(id) else {
        if checks.accept_unknown {
            return unknown_id(l, s, id, len, flags);
        }
        return Candidate::Reject(Rejection::UnknownId(id));
    };
    // v1 carries the whole base payload (extensions allowed); v2 may drop trailing zero
    // bytes but never the first one, and may carry extensions this dialect lacks.
    let min = if v2 { 1 } else { info.min_len };
    if len < min || (len > info.max_len && !v2) {
        return Candidate::Reject(Rejection::BadLength { id, len });
    }
    if len > info.max_len && (checks.known_length || !checks.crc) {
        return Candidate::Reject(Rejection::LongerThanKnown {
            id,
            len,
            known: info.max_len,
        });
    }
    let body = l.header_len + len as usize;
    let total = l.frame_len(len, flags);
    if s.len() < total {
        return Candidate::NeedMore(total);
    }
    let wire = u16::from_le_bytes([s[body], s[body + 1]]);
    if checks.crc && frame_checksum(&s[CHECKSUM_START..body], info.crc_extra) != wire {
        return Candidate::Reject(Rejection::BadCrc);
    }
    Candidate::Frame(total, info)
}

/// A frame of an id no dialect defines, accepted as such: framed by its length byte (a
/// v2 payload is never empty), its checksum unchecked.
#[cold]
fn unknown_id(l: &'static Layout, s: &[u8], id: u32, len: u8, flags: u8) -> Candidate {
    if l.magic == MAGIC_V2 && len == 0 {
        return Candidate::Reject(Rejection::BadLength { id, len });
    }
    let total = l.frame_len(len, flags);
    if s.len() < total {
        return Candidate::NeedMore(total);
    }
    Candidate::Frame(total, &UNKNOWN_MESSAGE)
}
