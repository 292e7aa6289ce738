//! The MAVLink frame header in one place: where each field sits in a v1 and a v2
//! header ([`Layout`], one table per version), and an owned form of a header
//! ([`HeaderRepr`]) that is read from bytes with [`HeaderRepr::parse`] and written with
//! [`HeaderRepr::emit`]. Every other module reads and writes header bytes through these,
//! so no header offset is written anywhere else.
//!
//! A frame is the header, the payload, a 2-byte checksum and, for a signed v2 frame, a
//! 13-byte signature block.

/// First byte of a MAVLink 1 frame.
pub(crate) const MAGIC_V1: u8 = 0xFE;
/// First byte of a MAVLink 2 frame.
pub(crate) const MAGIC_V2: u8 = 0xFD;
/// Header length of a MAVLink 1 frame, magic byte included.
pub(crate) const HEADER_LEN_V1: usize = V1.header_len;
/// Header length of a MAVLink 2 frame, magic byte included.
pub(crate) const HEADER_LEN_V2: usize = V2.header_len;
/// Length of the checksum that follows the payload.
pub(crate) const CHECKSUM_LEN: usize = 2;
/// The checksum covers the frame from this offset (the byte after the magic byte) to
/// the end of the payload.
pub(crate) const CHECKSUM_START: usize = 1;
/// Length of a MAVLink 2 signature block (link id, timestamp, signature).
pub(crate) const SIGNATURE_LEN: usize = 13;
/// The only incompatibility flag MAVLink 2 defines: the frame carries a signature.
pub(crate) const INCOMPAT_SIGNED: u8 = 0x01;
/// Longest possible frame: signed v2 with a 255-byte payload.
pub(crate) const MAX_FRAME_LEN: usize = HEADER_LEN_V2 + 255 + CHECKSUM_LEN + SIGNATURE_LEN;

/// Where the header fields of one MAVLink version sit, as byte offsets from the
/// frame's first (magic) byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// The magic (start) byte at offset 0.
    pub magic: u8,
    /// Header length, magic byte included: the payload starts here.
    pub header_len: usize,
    /// Offset of the payload length byte.
    pub payload_len: usize,
    /// Offset of the incompatibility flags byte (v2 only).
    pub incompat_flags: Option<usize>,
    /// Offset of the compatibility flags byte (v2 only).
    pub compat_flags: Option<usize>,
    /// Offset of the sequence number.
    pub seq: usize,
    /// Offset of the sender's system id.
    pub system: usize,
    /// Offset of the sender's component id.
    pub component: usize,
    /// Offset of the first (least significant) byte of the message id.
    pub message_id: usize,
    /// Number of message id bytes (little-endian).
    pub message_id_len: usize,
}

/// The MAVLink 1 header: magic, len, seq, sysid, compid, msgid (8 bits).
pub(crate) const V1: Layout = Layout {
    magic: MAGIC_V1,
    header_len: 6,
    payload_len: 1,
    incompat_flags: None,
    compat_flags: None,
    seq: 2,
    system: 3,
    component: 4,
    message_id: 5,
    message_id_len: 1,
};

/// The MAVLink 2 header: magic, len, incompat flags, compat flags, seq, sysid, compid,
/// msgid (24 bits).
pub(crate) const V2: Layout = Layout {
    magic: MAGIC_V2,
    header_len: 10,
    payload_len: 1,
    incompat_flags: Some(2),
    compat_flags: Some(3),
    seq: 4,
    system: 5,
    component: 6,
    message_id: 7,
    message_id_len: 3,
};

// The readers below index `h` directly: callers hand them at least `header_len` bytes
// (a checked frame, or bytes whose length they tested first).
impl Layout {
    /// Payload length byte.
    #[inline(always)]
    pub(crate) fn read_payload_len(&self, h: &[u8]) -> u8 {
        h[self.payload_len]
    }

    /// Incompatibility flags (0 where the version has none).
    #[inline(always)]
    pub(crate) fn read_incompat_flags(&self, h: &[u8]) -> u8 {
        self.incompat_flags.map_or(0, |at| h[at])
    }

    /// Compatibility flags (0 where the version has none).
    #[inline(always)]
    pub(crate) fn read_compat_flags(&self, h: &[u8]) -> u8 {
        self.compat_flags.map_or(0, |at| h[at])
    }

    /// Sequence number.
    #[inline(always)]
    pub(crate) fn read_seq(&self, h: &[u8]) -> u8 {
        h[self.seq]
    }

    /// Sender's system id.
    #[inline(always)]
    pub(crate) fn read_system(&self, h: &[u8]) -> u8 {
        h[self.system]
    }

    /// Sender's component id.
    #[inline(always)]
    pub(crate) fn read_component(&self, h: &[u8]) -> u8 {
        h[self.component]
    }

    /// Message id.
    #[inline(always)]
    pub(crate) fn read_message_id(&self, h: &[u8]) -> u32 {
        let mut id = 0u32;
        for i in 0..self.message_id_len {
            id |= u32::from(h[self.message_id + i]) << (8 * i);
        }
        id
    }

    /// Length of a whole frame with this payload length and these incompatibility flags.
    #[inline(always)]
    pub const fn frame_len(&self, payload_len: u8, incompat_flags: u8) -> usize {
        let signature = if incompat_flags & INCOMPAT_SIGNED != 0 {
            SIGNATURE_LEN
        } else {
            0
        };
        self.header_len + payload_len as usize + CHECKSUM_LEN + signature
    }
}

/// MAVLink protocol version of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Version {
    /// MAVLink 1 (magic 0xFE, 8-bit message ids).
    V1,
    /// MAVLink 2 (magic 0xFD, 24-bit ids, truncated payloads, optional signature).
    V2,
}

impl Version {
    /// The version a frame starting with `byte` has, if `byte` is a magic byte.
    #[inline]
    pub(crate) const fn from_magic(byte: u8) -> Option<Version> {
        match byte {
            MAGIC_V1 => Some(Version::V1),
            MAGIC_V2 => Some(Version::V2),
            _ => None,
        }
    }

    /// Where this version's header fields sit.
    #[inline]
    pub(crate) const fn layout(self) -> &'static Layout {
        match self {
            Version::V1 => &V1,
            Version::V2 => &V2,
        }
    }

    /// Magic (start) byte of this version.
    pub const fn magic(self) -> u8 {
        self.layout().magic
    }

    /// Header length (magic byte included) of this version.
    pub(crate) const fn header_len(self) -> usize {
        self.layout().header_len
    }

    /// The major version number: 1 or 2 (as in the log text's `(v2.0)`).
    pub(crate) const fn number(self) -> u8 {
        match self {
            Version::V1 => 1,
            Version::V2 => 2,
        }
    }
}

/// Why [`HeaderRepr::parse`] could not read a header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeaderError {
    /// The first byte is not a MAVLink magic byte.
    BadMagic(u8),
    /// Fewer bytes than the header needs.
    Truncated {
        /// Bytes the header needs.
        needed: usize,
        /// Bytes there were.
        have: usize,
    },
}

impl std::fmt::Display for HeaderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HeaderError::BadMagic(b) => write!(f, "bad start byte 0x{b:02x}"),
            HeaderError::Truncated { needed, have } => {
                write!(f, "truncated header: needs {needed} bytes, {have} present")
            }
        }
    }
}

/// The fields of a frame header, owned: what [`HeaderRepr::parse`] reads from bytes and
/// [`HeaderRepr::emit`] writes back. Only the structure is read; whether the id is known,
/// the flags understood and the checksum right is the frame checker's business.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct HeaderRepr {
    /// Protocol version (which layout the header has).
    pub version: Version,
    /// Payload length as sent.
    pub payload_len: u8,
    /// Incompatibility flags (always 0 in v1).
    pub incompat_flags: u8,
    /// Compatibility flags (always 0 in v1).
    pub compat_flags: u8,
    /// Sequence number.
    pub seq: u8,
    /// Sender's system id.
    pub system: u8,
    /// Sender's component id.
    pub component: u8,
    /// Message id (at most 255 in v1, 24 bits in v2).
    pub message_id: u32,
}

impl HeaderRepr {
    /// Reads the header at the start of `bytes` (more bytes may follow).
    pub fn parse(bytes: &[u8]) -> Result<Self, HeaderError> {
        let Some(&first) = bytes.first() else {
            return Err(HeaderError::Truncated {
                needed: HEADER_LEN_V1,
                have: 0,
            });
        };
        let version = Version::from_magic(first).ok_or(HeaderError::BadMagic(first))?;
        let l = version.layout();
        if bytes.len() < l.header_len {
            return Err(HeaderError::Truncated {
                needed: l.header_len,
                have: bytes.len(),
            });
        }
        Ok(Self::read(version, bytes))
    }

    /// Reads a header from bytes known to hold one of `version`'s layout.
    #[inline]
    pub(crate) fn read(version: Version, h: &[u8]) -> Self {
        let l = version.layout();
        HeaderRepr {
            version,
            payload_len: l.read_payload_len(h),
            incompat_flags: l.read_incompat_flags(h),
            compat_flags: l.read_compat_flags(h),
            seq: l.read_seq(h),
            system: l.read_system(h),
            component: l.read_component(h),
            message_id: l.read_message_id(h),
        }
    }

    /// Number of bytes [`HeaderRepr::emit`] writes: the header length.
    pub const fn buffer_len(&self) -> usize {
        self.version.header_len()
    }

    /// True if the flags say a signature block ends the frame.
    pub const fn is_signed(&self) -> bool {
        self.incompat_flags & INCOMPAT_SIGNED != 0
    }

    /// Length of the whole frame this header announces: header, payload, checksum and
    /// signature block.
    pub const fn frame_len(&self) -> usize {
        self.version
            .layout()
            .frame_len(self.payload_len, self.incompat_flags)
    }

    /// Writes the header into the first [`HeaderRepr::buffer_len`] bytes of `buf`. A v1
    /// header has no flags and one message id byte: those fields must be 0 and below
    /// 256 (the encoder checks this before).
    ///
    /// # Panics
    /// If `buf` is shorter than [`HeaderRepr::buffer_len`].
    pub fn emit(&self, buf: &mut [u8]) {
        let l = self.version.layout();
        let h = &mut buf[..l.header_len];
        h[0] = l.magic;
        h[l.payload_len] = self.payload_len;
        if let Some(at) = l.incompat_flags {
            h[at] = self.incompat_flags;
        }
        if let Some(at) = l.compat_flags {
            h[at] = self.compat_flags;
        }
        h[l.seq] = self.seq;
        h[l.system] = self.system;
        h[l.component] = self.component;
        let id = self.message_id.to_le_bytes();
        h[l.message_id..l.message_id + l.message_id_len].copy_from_slice(&id[..l.message_id_len]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(version: Version) -> HeaderRepr {
        HeaderRepr {
            version,
            payload_len: 14,
            incompat_flags: if version == Version::V2 { 1 } else { 0 },
            compat_flags: 0,
            seq: 0xfe,
            system: 192,
            component: 168,
            message_id: if version == Version::V2 {
                0x01_02_03
            } else {
                4
            },
        }
    }

    #[test]
    fn emit_then_parse_round_trips() {
        for v in [Version::V1, Version::V2] {
            let h = sample(v);
            let mut buf = [0u8; HEADER_LEN_V2];
            h.emit(&mut buf);
            assert_eq!(HeaderRepr::parse(&buf[..h.buffer_len()]), Ok(h));
        }
    }

    #[test]
    fn emitted_bytes_follow_the_published_layouts() {
        let mut buf = [0u8; HEADER_LEN_V2];
        sample(Version::V2).emit(&mut buf);
        assert_eq!(buf, [0xfd, 14, 1, 0, 0xfe, 192, 168, 3, 2, 1]);
        let mut buf = [0u8; HEADER_LEN_V1];
        sample(Version::V1).emit(&mut buf);
        assert_eq!(buf, [0xfe, 14, 0xfe, 192, 168, 4]);
    }

    #[test]
    fn frame_length_counts_checksum_and_signature() {
        let signed = sample(Version::V2);
        assert_eq!(signed.frame_len(), 10 + 14 + 2 + 13);
        assert_eq!(sample(Version::V1).frame_len(), 6 + 14 + 2);
        assert_eq!(
            V2.frame_len(255, INCOMPAT_SIGNED),
            MAX_FRAME_LEN,
            "the longest frame"
        );
    }

    #[test]
    fn parse_refuses_short_or_foreign_bytes() {
        assert_eq!(
            HeaderRepr::parse(&[]),
            Err(HeaderError::Truncated { needed: 6, have: 0 })
        );
        assert_eq!(
            HeaderRepr::parse(&[MAGIC_V2, 9, 0, 0, 0]),
            Err(HeaderError::Truncated {
                needed: 10,
                have: 5
            })
        );
        assert_eq!(
            HeaderRepr::parse(&[0x55; 12]),
            Err(HeaderError::BadMagic(0x55))
        );
    }
}
