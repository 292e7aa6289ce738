//! MAVLink frame layout and [`Frame`], a checked zero-copy view of one frame.

use std::fmt;

use crate::address::Address;
use crate::dialect::{self, MessageInfo};

use super::crc::frame_checksum;

/// First byte of a MAVLink 1 frame.
pub const MAGIC_V1: u8 = 0xFE;
/// First byte of a MAVLink 2 frame.
pub const MAGIC_V2: u8 = 0xFD;
/// Header length of a MAVLink 1 frame, magic byte included.
pub const HEADER_LEN_V1: usize = 6;
/// Header length of a MAVLink 2 frame, magic byte included.
pub const HEADER_LEN_V2: usize = 10;
/// Length of the checksum that follows the payload.
pub const CHECKSUM_LEN: usize = 2;
/// Length of a MAVLink 2 signature block (link id, timestamp, signature).
pub const SIGNATURE_LEN: usize = 13;
/// The only incompatibility flag MAVLink 2 defines: the frame carries a signature.
pub const INCOMPAT_SIGNED: u8 = 0x01;
/// Longest possible frame: signed v2 with a 255-byte payload.
pub const MAX_FRAME_LEN: usize = HEADER_LEN_V2 + 255 + CHECKSUM_LEN + SIGNATURE_LEN;

/// MAVLink protocol version of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Version {
    /// MAVLink 1 (magic 0xFE, 8-bit message ids).
    V1,
    /// MAVLink 2 (magic 0xFD, 24-bit ids, truncated payloads, optional signature).
    V2,
}

impl Version {
    /// Magic (start) byte of this version.
    pub const fn magic(self) -> u8 {
        match self {
            Version::V1 => MAGIC_V1,
            Version::V2 => MAGIC_V2,
        }
    }

    /// Header length (magic byte included) of this version.
    pub const fn header_len(self) -> usize {
        match self {
            Version::V1 => HEADER_LEN_V1,
            Version::V2 => HEADER_LEN_V2,
        }
    }
}

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
/// no waiting for bytes that belong to the next one.
#[inline]
pub(crate) fn check_candidate(s: &[u8]) -> Candidate {
    let v2 = s[0] == MAGIC_V2;
    let header_len = if v2 { HEADER_LEN_V2 } else { HEADER_LEN_V1 };
    if s.len() < header_len {
        return Candidate::NeedMore(header_len);
    }
    let len = s[1];
    let (id, signed) = if v2 {
        let flags = s[2];
        if flags & !INCOMPAT_SIGNED != 0 {
            return Candidate::Reject(Rejection::BadFlags(flags));
        }
        (
            u32::from_le_bytes([s[7], s[8], s[9], 0]),
            flags & INCOMPAT_SIGNED != 0,
        )
    } else {
        (u32::from(s[5]), false)
    };
    let Some(info) = dialect::by_id(id) else {
        return Candidate::Reject(Rejection::UnknownId(id));
    };
    // v1 carries the whole base payload (extensions allowed); v2 may drop trailing zero
    // bytes but never the first one.
    let min = if v2 { 1 } else { info.min_len };
    if len < min || len > info.max_len {
        return Candidate::Reject(Rejection::BadLength { id, len });
    }
    let body = header_len + len as usize;
    let total = body + CHECKSUM_LEN + if signed { SIGNATURE_LEN } else { 0 };
    if s.len() < total {
        return Candidate::NeedMore(total);
    }
    let wire = u16::from_le_bytes([s[body], s[body + 1]]);
    if frame_checksum(&s[1..body], info.crc_extra) != wire {
        return Candidate::Reject(Rejection::BadCrc);
    }
    Candidate::Frame(total, info)
}

/// Why [`Frame::parse_exact`] refused a byte string.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExactError {
    /// The first byte is not a MAVLink magic byte.
    BadMagic(u8),
    /// The frame is invalid (or cut short: [`Rejection::Truncated`]).
    Rejected(Rejection),
    /// Bytes follow the end of the frame.
    TrailingBytes(usize),
}

impl fmt::Display for ExactError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExactError::BadMagic(b) => write!(f, "bad start byte 0x{b:02x}"),
            ExactError::Rejected(r) => write!(f, "{r}"),
            ExactError::TrailingBytes(n) => write!(f, "{n} bytes after the end of the frame"),
        }
    }
}

/// A checked, zero-copy view of one MAVLink frame: the exact bytes as received (what a
/// router forwards) plus accessors for its header, payload, target and signature.
#[derive(Clone, Copy)]
pub struct Frame<'a> {
    bytes: &'a [u8],
    info: &'static MessageInfo,
    offset: u64,
}

impl<'a> Frame<'a> {
    /// Builds a view over bytes already checked by [`check_candidate`].
    #[inline]
    pub(crate) fn new_unchecked(bytes: &'a [u8], info: &'static MessageInfo, offset: u64) -> Self {
        Frame {
            bytes,
            info,
            offset,
        }
    }

    /// Checks that `bytes` is exactly one valid frame (checksum included) and views it.
    pub fn parse_exact(bytes: &'a [u8]) -> Result<Self, ExactError> {
        match bytes.first() {
            None => {
                return Err(ExactError::Rejected(Rejection::Truncated {
                    needed: HEADER_LEN_V1,
                    have: 0,
                }));
            }
            Some(&b) if b != MAGIC_V1 && b != MAGIC_V2 => return Err(ExactError::BadMagic(b)),
            Some(_) => {}
        }
        match check_candidate(bytes) {
            Candidate::NeedMore(needed) => Err(ExactError::Rejected(Rejection::Truncated {
                needed,
                have: bytes.len(),
            })),
            Candidate::Reject(r) => Err(ExactError::Rejected(r)),
            Candidate::Frame(len, info) if len == bytes.len() => {
                Ok(Frame::new_unchecked(bytes, info, 0))
            }
            Candidate::Frame(len, _) => Err(ExactError::TrailingBytes(bytes.len() - len)),
        }
    }

    /// The frame's bytes exactly as received, signature included.
    #[inline]
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Byte offset of the frame's first byte in the stream the parser was fed.
    #[inline]
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Dialect facts about the frame's message.
    #[inline]
    pub fn info(&self) -> &'static MessageInfo {
        self.info
    }

    /// Message name, e.g. `HEARTBEAT`.
    #[inline]
    pub fn name(&self) -> &'static str {
        self.info.name
    }

    /// Protocol version.
    #[inline]
    pub fn version(&self) -> Version {
        if self.bytes[0] == MAGIC_V2 {
            Version::V2
        } else {
            Version::V1
        }
    }

    #[inline]
    fn header_len(&self) -> usize {
        self.version().header_len()
    }

    /// Payload length as sent (v2 payloads may be truncated).
    #[inline]
    pub fn payload_len(&self) -> usize {
        self.bytes[1] as usize
    }

    /// Incompatibility flags (always 0 for v1).
    #[inline]
    pub fn incompat_flags(&self) -> u8 {
        match self.version() {
            Version::V1 => 0,
            Version::V2 => self.bytes[2],
        }
    }

    /// Compatibility flags (always 0 for v1).
    #[inline]
    pub fn compat_flags(&self) -> u8 {
        match self.version() {
            Version::V1 => 0,
            Version::V2 => self.bytes[3],
        }
    }

    /// Packet sequence number.
    #[inline]
    pub fn seq(&self) -> u8 {
        if self.is_v2() {
            self.bytes[4]
        } else {
            self.bytes[2]
        }
    }

    #[inline]
    fn is_v2(&self) -> bool {
        self.bytes[0] == MAGIC_V2
    }

    /// Sender's system id.
    #[inline]
    pub fn system(&self) -> u8 {
        if self.is_v2() {
            self.bytes[5]
        } else {
            self.bytes[3]
        }
    }

    /// Sender's component id.
    #[inline]
    pub fn component(&self) -> u8 {
        if self.is_v2() {
            self.bytes[6]
        } else {
            self.bytes[4]
        }
    }

    /// Sender's address (`system.component`).
    #[inline]
    pub fn source(&self) -> Address {
        Address::new(self.system(), self.component())
    }

    /// Message id.
    #[inline]
    pub fn message_id(&self) -> u32 {
        self.info.id
    }

    /// The payload as sent (possibly truncated in v2: missing bytes read as zero).
    #[inline]
    pub fn payload(&self) -> &'a [u8] {
        let start = self.header_len();
        &self.bytes[start..start + self.payload_len()]
    }

    /// The payload extended with zeros to the message's full length, for decoding.
    pub fn payload_padded(&self) -> [u8; 255] {
        let mut out = [0u8; 255];
        let p = self.payload();
        out[..p.len()].copy_from_slice(p);
        out
    }

    /// The checksum as it appears on the wire.
    #[inline]
    pub fn checksum(&self) -> u16 {
        let at = self.header_len() + self.payload_len();
        u16::from_le_bytes([self.bytes[at], self.bytes[at + 1]])
    }

    /// True if this is a signed MAVLink 2 frame.
    #[inline]
    pub fn is_signed(&self) -> bool {
        self.incompat_flags() & INCOMPAT_SIGNED != 0
    }

    /// The signature block of a signed frame.
    #[inline]
    pub fn signature(&self) -> Option<Signature<'a>> {
        if !self.is_signed() {
            return None;
        }
        let start = self.bytes.len() - SIGNATURE_LEN;
        Some(Signature {
            block: &self.bytes[start..],
        })
    }

    /// Destination address carried in the payload, if the message has a target system
    /// field. Bytes cut off by v2 truncation read as zero; a message with a target
    /// system but no target component gets component 0. `0.0` is a value, not `None`.
    #[inline]
    pub fn target(&self) -> Option<Address> {
        let sys_ofs = self.info.target_system_offset?;
        let payload = self.payload();
        let byte = |ofs: u8| payload.get(ofs as usize).copied().unwrap_or(0);
        let component = self.info.target_component_offset.map_or(0, byte);
        Some(Address::new(byte(sys_ofs), component))
    }
}

impl fmt::Debug for Frame<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Frame")
            .field("version", &self.version())
            .field("seq", &self.seq())
            .field("source", &self.source())
            .field("message", &self.name())
            .field("len", &self.payload_len())
            .field("signed", &self.is_signed())
            .finish()
    }
}

/// The log text of a packet: `NAME (#id) from S.C[ to S.C] (vN.0)`, as the original
/// prints it (` to 0.0` included).
impl fmt::Display for Frame<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (#{}) from {}",
            self.name(),
            self.message_id(),
            self.source()
        )?;
        if let Some(to) = self.target() {
            write!(f, " to {to}")?;
        }
        let v = match self.version() {
            Version::V1 => 1,
            Version::V2 => 2,
        };
        write!(f, " (v{v}.0)")
    }
}

/// The 13-byte signature block at the end of a signed MAVLink 2 frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Signature<'a> {
    block: &'a [u8],
}

impl<'a> Signature<'a> {
    /// Link id chosen by the signer.
    pub fn link_id(&self) -> u8 {
        self.block[0]
    }

    /// Timestamp in units of 10 µs since 2015-01-01 00:00:00 UTC (48 bits).
    pub fn timestamp(&self) -> u64 {
        let mut b = [0u8; 8];
        b[..6].copy_from_slice(&self.block[1..7]);
        u64::from_le_bytes(b)
    }

    /// The 6-byte signature value (first 6 bytes of the SHA-256 digest).
    pub fn value(&self) -> &'a [u8] {
        &self.block[7..13]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::encode::{Header, encode_v1, encode_v2};

    fn v2(id: u32, payload: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let header = Header {
            seq: 0xfe,
            system: 192,
            component: 168,
        };
        encode_v2(header, id, payload, None, &mut out).expect("encodable");
        out
    }

    #[test]
    fn v2_header_accessors() {
        let bytes = v2(4, &[1, 0, 0, 0, 0, 0, 0, 0, 9, 0, 0, 0, 127, 1]);
        let f = Frame::parse_exact(&bytes).expect("valid");
        assert_eq!(f.version(), Version::V2);
        assert_eq!((f.seq(), f.system(), f.component()), (0xfe, 192, 168));
        assert_eq!((f.message_id(), f.name()), (4, "PING"));
        assert_eq!(f.target(), Some(Address::new(127, 1)));
        assert_eq!(f.to_string(), "PING (#4) from 192.168 to 127.1 (v2.0)");
        assert_eq!(f.payload_len(), 14);
        assert!(!f.is_signed() && f.signature().is_none());
    }

    #[test]
    fn v1_header_accessors() {
        let mut bytes = Vec::new();
        let header = Header {
            seq: 7,
            system: 127,
            component: 1,
        };
        encode_v1(header, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3], &mut bytes).expect("encodable");
        let f = Frame::parse_exact(&bytes).expect("valid");
        assert_eq!(f.version(), Version::V1);
        assert_eq!((f.seq(), f.system(), f.component()), (7, 127, 1));
        assert_eq!(f.incompat_flags(), 0);
        assert_eq!(f.to_string(), "HEARTBEAT (#0) from 127.1 (v1.0)");
    }

    #[test]
    fn truncated_v2_targets_read_as_zero() {
        // SET_MODE has a target system but no target component: component is 0.
        let set_mode = v2(11, &[0, 0, 0, 0, 123, 1]);
        let f = Frame::parse_exact(&set_mode).expect("valid");
        assert_eq!(f.target(), Some(Address::new(123, 0)));
        // MISSION_SET_CURRENT with every byte zero is truncated to one byte: target 0.0,
        // which is printed.
        let msc = v2(41, &[0, 0, 0, 0]);
        let f = Frame::parse_exact(&msc).expect("valid");
        assert_eq!(f.payload_len(), 1);
        assert_eq!(f.target(), Some(Address::new(0, 0)));
        assert!(f.to_string().ends_with(" to 0.0 (v2.0)"));
    }

    #[test]
    fn manual_control_target_is_the_target_system() {
        let mut payload = [0u8; 11];
        payload[10] = 1;
        let f_bytes = v2(69, &payload);
        let f = Frame::parse_exact(&f_bytes).expect("valid");
        assert_eq!(f.target(), Some(Address::new(1, 0)));
    }

    #[test]
    fn messages_without_target_system_have_no_target() {
        let bytes = v2(0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]);
        assert_eq!(Frame::parse_exact(&bytes).expect("valid").target(), None);
    }

    #[test]
    fn parse_exact_reports_what_is_wrong() {
        let good = v2(0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]);
        assert_eq!(
            Frame::parse_exact(&good[1..]).err(),
            Some(ExactError::BadMagic(good[1]))
        );
        assert!(matches!(
            Frame::parse_exact(&good[..good.len() - 1]),
            Err(ExactError::Rejected(Rejection::Truncated { .. }))
        ));
        let mut long = good.clone();
        long.push(0);
        assert_eq!(
            Frame::parse_exact(&long).err(),
            Some(ExactError::TrailingBytes(1))
        );
        let mut bad_crc = good.clone();
        bad_crc[12] ^= 1;
        assert_eq!(
            Frame::parse_exact(&bad_crc).err(),
            Some(ExactError::Rejected(Rejection::BadCrc))
        );
        let mut flags = good.clone();
        flags[2] = 0x02;
        assert_eq!(
            Frame::parse_exact(&flags).err(),
            Some(ExactError::Rejected(Rejection::BadFlags(0x02)))
        );
        let mut unknown = good.clone();
        unknown[7] = 255;
        assert_eq!(
            Frame::parse_exact(&unknown).err(),
            Some(ExactError::Rejected(Rejection::UnknownId(255)))
        );
        let mut too_long = good;
        too_long[1] = 10; // HEARTBEAT is at most 9 bytes
        assert_eq!(
            Frame::parse_exact(&too_long).err(),
            Some(ExactError::Rejected(Rejection::BadLength {
                id: 0,
                len: 10
            }))
        );
        assert!(matches!(
            Frame::parse_exact(&[]),
            Err(ExactError::Rejected(Rejection::Truncated { have: 0, .. }))
        ));
    }

    #[test]
    fn v1_frames_must_carry_the_whole_base_payload() {
        // HEARTBEAT v1 with 8 payload bytes instead of 9.
        let mut bytes = vec![MAGIC_V1, 8, 0, 1, 1, 0, 0, 0, 0, 0, 6, 8, 0, 0];
        let crc = frame_checksum(&bytes[1..], 50);
        bytes.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(
            Frame::parse_exact(&bytes).err(),
            Some(ExactError::Rejected(Rejection::BadLength { id: 0, len: 8 }))
        );
    }
}
