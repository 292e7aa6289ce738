//! Classic libpcap files (`.pcap`): the UDP payloads they carry (link types as in
//! `super::linktype`). Non-UDP packets are passed over and counted.

use super::records::{self, RecordFormat};
use super::{Unit, linktype};

/// Length of the file header.
pub const GLOBAL_HEADER_LEN: usize = 24;
const RECORD_HEADER_LEN: usize = 16;

/// One UDP datagram found in a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Datagram<'a> {
    /// Capture time, microseconds since the UNIX epoch.
    pub timestamp_us: u64,
    /// Source IPv4 address and port.
    pub source: ([u8; 4], u16),
    /// Destination IPv4 address and port.
    pub destination: ([u8; 4], u16),
    /// The UDP payload.
    pub payload: &'a [u8],
    /// Byte offset of the payload in the file.
    pub offset: u64,
}

impl<'a> Datagram<'a> {
    /// The datagram as a unit of MAVLink bytes.
    pub(crate) fn unit(self) -> Unit<'a> {
        Unit {
            timestamp_us: Some(self.timestamp_us),
            offset: self.offset,
            bytes: self.payload,
            source: Some(self.source),
        }
    }
}

/// Why a pcap file could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcapError {
    /// The file does not start with a pcap magic number.
    NotPcap,
    /// The link-layer type is not one this reader knows.
    UnsupportedLinkType(u32),
    /// The file ends inside the record at this offset.
    Truncated(u64),
    /// The pcapng block at this offset has a length no block can have.
    BadLength(u64),
    /// The pcapng section header at this offset has no byte-order magic.
    BadByteOrder(u64),
    /// The pcapng section describes more than [`super::pcapng::MAX_INTERFACES`]
    /// interfaces (the one at this offset is one too many).
    TooManyInterfaces(u64),
}

impl std::fmt::Display for PcapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PcapError::NotPcap => write!(f, "not a pcap file"),
            PcapError::UnsupportedLinkType(t) => write!(f, "unsupported pcap link type {t}"),
            PcapError::Truncated(_) => write!(f, "file ends inside a packet record"),
            PcapError::BadLength(_) => {
                write!(f, "a block's length is not a multiple of 4 of at least 12")
            }
            PcapError::BadByteOrder(_) => {
                write!(
                    f,
                    "a section header without the byte-order magic 0x1A2B3C4D"
                )
            }
            PcapError::TooManyInterfaces(_) => write!(
                f,
                "more than {} interfaces in one section",
                super::pcapng::MAX_INTERFACES
            ),
        }
    }
}

/// True if `data` starts like a classic pcap file.
pub(crate) fn is_pcap(data: &[u8]) -> bool {
    matches!(
        data.get(..4),
        Some(
            [0xd4, 0xc3, 0xb2, 0xa1]
                | [0xa1, 0xb2, 0xc3, 0xd4]
                | [0x4d, 0x3c, 0xb2, 0xa1]
                | [0xa1, 0xb2, 0x3c, 0x4d]
        )
    )
}

/// The pcap format as its file header describes it.
#[derive(Debug, Clone)]
pub struct Pcap {
    big_endian: bool,
    nanos: bool,
    link_type: u32,
    /// Packets that were not IPv4/UDP (or were cut short by the snap length).
    pub skipped: u64,
}

impl Pcap {
    /// Reads the file header (the first [`GLOBAL_HEADER_LEN`] bytes of `data`).
    pub(crate) fn from_header(data: &[u8]) -> Result<Self, PcapError> {
        if data.len() < GLOBAL_HEADER_LEN || !is_pcap(data) {
            return Err(PcapError::NotPcap);
        }
        let (big_endian, nanos) = match data[..4] {
            [0xd4, 0xc3, 0xb2, 0xa1] => (false, false),
            [0x4d, 0x3c, 0xb2, 0xa1] => (false, true),
            [0xa1, 0xb2, 0xc3, 0xd4] => (true, false),
            _ => (true, true),
        };
        let mut p = Pcap {
            big_endian,
            nanos,
            link_type: 0,
            skipped: 0,
        };
        p.link_type = p.u32_at(data, 20) & 0x0fff_ffff;
        if linktype::supported(p.link_type) {
            Ok(p)
        } else {
            Err(PcapError::UnsupportedLinkType(p.link_type))
        }
    }

    /// The `u32` at `at` in `data`, which holds at least `at + 4` bytes.
    fn u32_at(&self, data: &[u8], at: usize) -> u32 {
        let b = [data[at], data[at + 1], data[at + 2], data[at + 3]];
        if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }
}

impl RecordFormat for Pcap {
    type Item<'a> = Datagram<'a>;
    type Error = PcapError;
    const HEAD: usize = RECORD_HEADER_LEN;

    fn record_len(&self, head: &[u8], at: u64) -> Result<u64, PcapError> {
        if head.len() < RECORD_HEADER_LEN {
            return Err(PcapError::Truncated(at));
        }
        Ok(RECORD_HEADER_LEN as u64 + u64::from(self.u32_at(head, 8)))
    }

    fn truncated(&self, at: u64) -> PcapError {
        PcapError::Truncated(at)
    }

    fn item<'a>(
        &mut self,
        record: &'a [u8],
        at: u64,
        _len: u64,
    ) -> Result<Option<Datagram<'a>>, PcapError> {
        let secs = u64::from(self.u32_at(record, 0));
        let frac = u64::from(self.u32_at(record, 4));
        let frame = &record[RECORD_HEADER_LEN..];
        let timestamp_us = secs * 1_000_000 + if self.nanos { frac / 1000 } else { frac };
        match linktype::udp_payload(self.link_type, frame) {
            Some(udp) => Ok(Some(Datagram {
                timestamp_us,
                source: udp.source,
                destination: udp.destination,
                payload: udp.payload,
                offset: at + (RECORD_HEADER_LEN + udp.offset) as u64,
            })),
            None => {
                self.skipped += 1;
                Ok(None)
            }
        }
    }

    fn unit<'a>(dg: Self::Item<'a>) -> Unit<'a> {
        dg.unit()
    }

    fn passed_over(&self) -> u64 {
        self.skipped
    }
}

/// Reader over a classic pcap file held in memory.
pub type Reader<'a> = records::Records<'a, Pcap>;

impl<'a> Reader<'a> {
    /// Checks the file header and prepares to read records.
    pub fn new(data: &'a [u8]) -> Result<Self, PcapError> {
        let format = Pcap::from_header(data)?;
        Ok(records::Records::starting_at(
            data,
            GLOBAL_HEADER_LEN,
            format,
        ))
    }
}
