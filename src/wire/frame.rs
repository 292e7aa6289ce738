//! [`Frame`], a checked zero-copy view of one frame; its header is read through the
//! per-version layouts of [`super::header`].

use std::fmt;

use crate::address::Address;
use crate::dialect::{Dialect, MessageInfo, UNKNOWN_ID};

use super::check::{Candidate, Checks, Rejection, check_candidate};
use super::header::{
    HEADER_LEN_V1, HeaderRepr, INCOMPAT_SIGNED, Layout, MAGIC_V2, SIGNATURE_LEN, Version,
};

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
    /// Builds a view over bytes already checked by `check_candidate`.
    #[inline]
    pub(crate) fn new_unchecked(bytes: &'a [u8], info: &'static MessageInfo, offset: u64) -> Self {
        Frame {
            bytes,
            info,
            offset,
        }
    }

    /// Checks that `bytes` is exactly one valid frame (checksum included) and views it.
    /// As for a router, a v2 frame longer than its message's known length is valid.
    pub fn parse_exact(bytes: &'a [u8]) -> Result<Self, ExactError> {
        Frame::parse_exact_in(bytes, &Dialect::builtin())
    }

    /// [`Frame::parse_exact`] knowing the messages of `dialect`.
    pub fn parse_exact_in(bytes: &'a [u8], dialect: &Dialect) -> Result<Self, ExactError> {
        match bytes.first() {
            None => {
                return Err(ExactError::Rejected(Rejection::Truncated {
                    needed: HEADER_LEN_V1,
                    have: 0,
                }));
            }
            Some(&b) if Version::from_magic(b).is_none() => return Err(ExactError::BadMagic(b)),
            Some(_) => {}
        }
        match check_candidate(bytes, Checks::ROUTING, dialect) {
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

    /// Dialect facts about the frame's message ([`crate::dialect::UNKNOWN_MESSAGE`] for
    /// an id no dialect defines, accepted under `unknown_messages accept;`). Its `id` is
    /// what the filter matches: the message id, or [`UNKNOWN_ID`] for such a frame.
    #[inline]
    pub fn info(&self) -> &'static MessageInfo {
        self.info
    }

    /// Message name, e.g. `HEARTBEAT` (`UNKNOWN` for an id no dialect defines).
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

    /// Where this frame's header fields sit.
    #[inline]
    fn layout(&self) -> &'static Layout {
        self.version().layout()
    }

    /// The header's fields, owned.
    #[inline]
    pub fn header(&self) -> HeaderRepr {
        HeaderRepr::read(self.version(), self.bytes)
    }

    /// Payload length as sent (v2 payloads may be truncated).
    #[inline]
    pub fn payload_len(&self) -> usize {
        self.layout().read_payload_len(self.bytes) as usize
    }

    /// Incompatibility flags (always 0 for v1).
    #[inline]
    pub(crate) fn incompat_flags(&self) -> u8 {
        self.layout().read_incompat_flags(self.bytes)
    }

    /// Compatibility flags (always 0 for v1).
    #[inline]
    pub(crate) fn compat_flags(&self) -> u8 {
        self.layout().read_compat_flags(self.bytes)
    }

    /// Packet sequence number.
    #[inline]
    pub fn seq(&self) -> u8 {
        self.layout().read_seq(self.bytes)
    }

    /// Sender's system id.
    #[inline]
    pub fn system(&self) -> u8 {
        self.layout().read_system(self.bytes)
    }

    /// Sender's component id.
    #[inline]
    pub fn component(&self) -> u8 {
        self.layout().read_component(self.bytes)
    }

    /// Sender's address (`system.component`).
    #[inline]
    pub fn source(&self) -> Address {
        Address::new(self.system(), self.component())
    }

    /// True for a v2 frame whose payload is longer than its message's known length
    /// (extension fields this dialect does not know; decoding ignores the extra bytes).
    #[inline]
    pub fn is_longer_than_known(&self) -> bool {
        self.payload_len() > self.info.max_len as usize
    }

    /// Message id (as on the wire, also for an id no dialect defines).
    #[inline]
    pub fn message_id(&self) -> u32 {
        let id = self.info.id;
        if id != UNKNOWN_ID {
            return id;
        }
        self.layout().read_message_id(self.bytes)
    }

    /// True for a frame of an id no dialect defines (accepted under
    /// `unknown_messages accept;`, its checksum unchecked).
    #[inline]
    pub fn is_unknown(&self) -> bool {
        self.info.id == UNKNOWN_ID
    }

    /// The payload as sent (possibly truncated in v2: missing bytes read as zero; or
    /// longer than known: see [`Frame::is_longer_than_known`]).
    #[inline]
    pub fn payload(&self) -> &'a [u8] {
        let start = self.layout().header_len;
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
        let at = self.layout().header_len + self.payload_len();
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

impl From<&Frame<'_>> for HeaderRepr {
    #[inline]
    fn from(frame: &Frame<'_>) -> Self {
        frame.header()
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
    pub(crate) fn value(&self) -> &'a [u8] {
        &self.block[7..13]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::crc::frame_checksum;
    use crate::wire::encode::{Header, encode_v1, encode_v2};
    use crate::wire::header::MAGIC_V1;

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
        too_long[1] = 10; // HEARTBEAT is 9 bytes: a longer frame needs one more byte
        assert_eq!(
            Frame::parse_exact(&too_long).err(),
            Some(ExactError::Rejected(Rejection::Truncated {
                needed: 22,
                have: 21
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

    #[test]
    fn longer_than_known_v2_frames_parse_and_read_like_known_ones() {
        // PING (14 bytes known) with 4 more: target fields and the header read as usual.
        let mut payload = vec![0u8; 18];
        payload[12] = 127;
        payload[13] = 1;
        payload[14..].copy_from_slice(&[9, 9, 9, 9]);
        let mut bytes = Vec::new();
        let header = Header {
            seq: 7,
            system: 3,
            component: 4,
        };
        crate::wire::encode::encode_v2_exact(header, 4, &payload, &mut bytes).expect("encodable");
        let f = Frame::parse_exact(&bytes).expect("valid: the checksum holds");
        assert!(f.is_longer_than_known());
        assert_eq!(f.payload_len(), 18);
        assert_eq!(f.payload(), &payload[..]);
        assert_eq!(f.as_bytes(), &bytes[..]);
        assert_eq!(f.target(), Some(Address::new(127, 1)));
        assert_eq!(f.to_string(), "PING (#4) from 3.4 to 127.1 (v2.0)");
        let h = f.header();
        assert_eq!((h.seq, h.payload_len, h.message_id), (7, 18, 4));
        assert_eq!(h.frame_len(), bytes.len());
    }
}
