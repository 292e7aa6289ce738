//! Classic libpcap files (`.pcap`): the UDP payloads they carry (link types as in
//! [`super::linktype`]). Non-UDP packets are passed over and counted.

use super::linktype;

const GLOBAL_HEADER_LEN: usize = 24;
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
    pub offset: usize,
}

/// Why a pcap file could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcapError {
    /// The file does not start with a pcap magic number.
    NotPcap,
    /// The link-layer type is not one this reader knows.
    UnsupportedLinkType(u32),
    /// The file ends inside the record at this offset.
    Truncated(usize),
}

impl std::fmt::Display for PcapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PcapError::NotPcap => write!(f, "not a pcap file"),
            PcapError::UnsupportedLinkType(t) => write!(f, "unsupported pcap link type {t}"),
            PcapError::Truncated(_) => write!(f, "file ends inside a packet record"),
        }
    }
}

/// True if `data` starts like a classic pcap file.
pub fn is_pcap(data: &[u8]) -> bool {
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

/// Reader over a classic pcap file held in memory.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
    nanos: bool,
    link_type: u32,
    /// Packets that were not IPv4/UDP (or were cut short by the snap length).
    pub skipped: u64,
    failed: bool,
}

impl<'a> Reader<'a> {
    /// Checks the global header and prepares to read records.
    pub fn new(data: &'a [u8]) -> Result<Self, PcapError> {
        if data.len() < GLOBAL_HEADER_LEN || !is_pcap(data) {
            return Err(PcapError::NotPcap);
        }
        let (big_endian, nanos) = match data[..4] {
            [0xd4, 0xc3, 0xb2, 0xa1] => (false, false),
            [0x4d, 0x3c, 0xb2, 0xa1] => (false, true),
            [0xa1, 0xb2, 0xc3, 0xd4] => (true, false),
            _ => (true, true),
        };
        let mut r = Reader {
            data,
            pos: GLOBAL_HEADER_LEN,
            big_endian,
            nanos,
            link_type: 0,
            skipped: 0,
            failed: false,
        };
        r.link_type = r.u32_at(20) & 0x0fff_ffff;
        if linktype::supported(r.link_type) {
            Ok(r)
        } else {
            Err(PcapError::UnsupportedLinkType(r.link_type))
        }
    }

    fn u32_at(&self, at: usize) -> u32 {
        let b = [
            self.data[at],
            self.data[at + 1],
            self.data[at + 2],
            self.data[at + 3],
        ];
        if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }
}

impl<'a> Iterator for Reader<'a> {
    type Item = Result<Datagram<'a>, PcapError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed && self.pos < self.data.len() {
            let at = self.pos;
            if self.data.len() - at < RECORD_HEADER_LEN {
                self.failed = true;
                return Some(Err(PcapError::Truncated(at)));
            }
            let secs = u64::from(self.u32_at(at));
            let frac = u64::from(self.u32_at(at + 4));
            let incl = self.u32_at(at + 8) as usize;
            let start = at + RECORD_HEADER_LEN;
            let Some(frame) = self.data.get(start..start.saturating_add(incl)) else {
                self.failed = true;
                return Some(Err(PcapError::Truncated(at)));
            };
            self.pos = start + incl;
            let timestamp_us = secs * 1_000_000 + if self.nanos { frac / 1000 } else { frac };
            match linktype::udp_payload(self.link_type, frame) {
                Some(udp) => {
                    return Some(Ok(Datagram {
                        timestamp_us,
                        source: udp.source,
                        destination: udp.destination,
                        payload: udp.payload,
                        offset: start + udp.offset,
                    }));
                }
                None => self.skipped += 1,
            }
        }
        None
    }
}
