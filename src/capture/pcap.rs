//! Classic libpcap files (`.pcap`): the UDP payloads they carry, from Ethernet, Linux
//! cooked (SLL), BSD loopback (DLT_NULL) and raw IPv4 link types. Non-UDP packets are
//! passed over and counted.

/// Link-layer types understood.
const DLT_NULL: u32 = 0;
const DLT_EN10MB: u32 = 1;
const DLT_RAW: u32 = 101;
const DLT_LINUX_SLL: u32 = 113;
const DLT_IPV4: u32 = 228;
const DLT_LINUX_SLL2: u32 = 276;

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
            PcapError::Truncated(at) => write!(f, "offset {at}: file ends inside a packet record"),
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
        match r.link_type {
            DLT_NULL | DLT_EN10MB | DLT_RAW | DLT_LINUX_SLL | DLT_IPV4 | DLT_LINUX_SLL2 => Ok(r),
            other => Err(PcapError::UnsupportedLinkType(other)),
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

    /// The IPv4 packet inside a link-layer frame, if it carries one.
    fn ipv4<'p>(&self, frame: &'p [u8]) -> Option<&'p [u8]> {
        let (ethertype_ok, skip) = match self.link_type {
            DLT_NULL => {
                let fam = frame.get(..4)?;
                let le = u32::from_le_bytes([fam[0], fam[1], fam[2], fam[3]]);
                let be = u32::from_be_bytes([fam[0], fam[1], fam[2], fam[3]]);
                (le == 2 || be == 2, 4)
            }
            DLT_EN10MB => {
                let mut at = 12;
                let mut ethertype = u16::from_be_bytes([*frame.get(at)?, *frame.get(at + 1)?]);
                while ethertype == 0x8100 || ethertype == 0x88a8 {
                    at += 4;
                    ethertype = u16::from_be_bytes([*frame.get(at)?, *frame.get(at + 1)?]);
                }
                (ethertype == 0x0800, at + 2)
            }
            DLT_LINUX_SLL => (
                u16::from_be_bytes([*frame.get(14)?, *frame.get(15)?]) == 0x0800,
                16,
            ),
            DLT_LINUX_SLL2 => (
                u16::from_be_bytes([*frame.first()?, *frame.get(1)?]) == 0x0800,
                20,
            ),
            _ => (true, 0),
        };
        if !ethertype_ok {
            return None;
        }
        frame.get(skip..)
    }
}

/// The UDP datagram inside an IPv4 packet: (source, destination, payload, payload start).
type Udp<'p> = (([u8; 4], u16), ([u8; 4], u16), &'p [u8], usize);

fn udp_in_ipv4(ip: &[u8]) -> Option<Udp<'_>> {
    let first = *ip.first()?;
    if first >> 4 != 4 {
        return None;
    }
    let ihl = (first & 0x0f) as usize * 4;
    let total = u16::from_be_bytes([*ip.get(2)?, *ip.get(3)?]) as usize;
    let fragment = u16::from_be_bytes([*ip.get(6)?, *ip.get(7)?]);
    if *ip.get(9)? != 17 || ihl < 20 || fragment & 0x1fff != 0 || fragment & 0x2000 != 0 {
        return None;
    }
    let src: [u8; 4] = ip.get(12..16)?.try_into().ok()?;
    let dst: [u8; 4] = ip.get(16..20)?.try_into().ok()?;
    let udp = ip.get(ihl..total.min(ip.len()))?;
    let sport = u16::from_be_bytes([*udp.first()?, *udp.get(1)?]);
    let dport = u16::from_be_bytes([*udp.get(2)?, *udp.get(3)?]);
    let ulen = u16::from_be_bytes([*udp.get(4)?, *udp.get(5)?]) as usize;
    if ulen < 8 {
        return None;
    }
    let payload = udp.get(8..ulen)?;
    Some(((src, sport), (dst, dport), payload, ihl + 8))
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
            let found = self.ipv4(frame).and_then(udp_in_ipv4);
            match found {
                Some((source, destination, payload, payload_at)) => {
                    let ip_at = frame.len() - self.ipv4(frame).map_or(0, <[u8]>::len);
                    return Some(Ok(Datagram {
                        timestamp_us,
                        source,
                        destination,
                        payload,
                        offset: start + ip_at + payload_at,
                    }));
                }
                None => self.skipped += 1,
            }
        }
        None
    }
}
