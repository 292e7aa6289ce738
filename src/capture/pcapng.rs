//! pcapng files (Wireshark's default format): the UDP payloads of their Enhanced and
//! Simple Packet Blocks (link types as in `super::linktype`). Other blocks, other
//! protocols and interfaces of unknown link types are passed over and counted.

use super::pcap::{Datagram, PcapError};
use super::records::{self, RecordFormat};
use super::{Unit, linktype};

const SHB: u32 = 0x0A0D_0D0A;
const IDB: u32 = 1;
const SPB: u32 = 3;
const EPB: u32 = 6;
const BYTE_ORDER_MAGIC: u32 = 0x1A2B_3C4D;
const OPT_IF_TSRESOL: u16 = 9;
/// Bytes of the first Section Header Block that tell a pcapng file and its byte order.
pub const FILE_HEADER_LEN: usize = 12;
/// Most interfaces one section may describe: real captures have a few, and the list
/// is kept in memory while the section is read.
pub const MAX_INTERFACES: usize = 4096;

/// True if `data` starts like a pcapng file.
pub(crate) fn is_pcapng(data: &[u8]) -> bool {
    data.get(..4) == Some(&SHB.to_le_bytes())
}

/// One interface described by an Interface Description Block.
#[derive(Debug, Clone, Copy)]
struct Interface {
    link_type: u32,
    snap_len: u32,
    /// Timestamp units per second.
    units_per_sec: u64,
}

/// The pcapng format: the current section's byte order and interfaces.
#[derive(Debug, Clone)]
pub struct PcapNg {
    big_endian: bool,
    interfaces: Vec<Interface>,
    /// Packets that were not IPv4/UDP, or on interfaces of unsupported link types.
    pub skipped: u64,
}

/// Reads numbers of one byte order from a block.
#[derive(Clone, Copy)]
struct Block<'a> {
    bytes: &'a [u8],
    big_endian: bool,
}

impl<'a> Block<'a> {
    fn u16_at(self, at: usize) -> Option<u16> {
        let b = [*self.bytes.get(at)?, *self.bytes.get(at + 1)?];
        Some(if self.big_endian {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        })
    }

    fn u32_at(self, at: usize) -> Option<u32> {
        let b: [u8; 4] = self.bytes.get(at..at + 4)?.try_into().ok()?;
        Some(if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }
}

impl PcapNg {
    /// Checks the start of the first Section Header Block (the first
    /// [`FILE_HEADER_LEN`] bytes of `data`); reading starts with that block.
    pub(crate) fn from_header(data: &[u8]) -> Result<Self, PcapError> {
        if data.len() < FILE_HEADER_LEN || !is_pcapng(data) {
            return Err(PcapError::NotPcap);
        }
        let big_endian = match u32::from_le_bytes([data[8], data[9], data[10], data[11]]) {
            BYTE_ORDER_MAGIC => false,
            m if m.swap_bytes() == BYTE_ORDER_MAGIC => true,
            _ => return Err(PcapError::NotPcap),
        };
        Ok(PcapNg {
            big_endian,
            interfaces: Vec::new(),
            skipped: 0,
        })
    }

    fn block<'a>(&self, bytes: &'a [u8]) -> Block<'a> {
        Block {
            bytes,
            big_endian: self.big_endian,
        }
    }

    /// Reads an IDB body starting at `body` and ending before `end`.
    fn interface(b: Block<'_>, body: usize, end: usize) -> Option<Interface> {
        let link_type = u32::from(b.u16_at(body)?);
        let snap_len = b.u32_at(body + 4)?;
        let mut units_per_sec = 1_000_000;
        let mut at = body + 8;
        while at + 4 <= end {
            let code = b.u16_at(at)?;
            let len = b.u16_at(at + 2)? as usize;
            if code == 0 {
                break;
            }
            if code == OPT_IF_TSRESOL && len >= 1 {
                let v = *b.bytes.get(at + 4)?;
                let exp = u32::from(v & 0x7f);
                units_per_sec = if v & 0x80 == 0 {
                    10u64.checked_pow(exp)?
                } else {
                    1u64.checked_shl(exp)?
                };
            }
            at += 4 + len.div_ceil(4) * 4;
        }
        Some(Interface {
            link_type,
            snap_len,
            units_per_sec,
        })
    }

    /// The datagram in a packet block, if any: (interface, timestamp, captured bytes,
    /// their start in the block). `end` is where the block's body ends; the captured
    /// bytes are cut to what `b` holds (a block longer than [`records::MAX_RECORD`]).
    fn packet<'a>(
        &self,
        b: Block<'a>,
        kind: u32,
        body: usize,
        end: usize,
    ) -> Option<(Interface, u64, &'a [u8], usize)> {
        let (iface, ts, start, len) = if kind == EPB {
            let iface = *self.interfaces.get(b.u32_at(body)? as usize)?;
            let ts = (u64::from(b.u32_at(body + 4)?) << 32) | u64::from(b.u32_at(body + 8)?);
            (iface, ts, body + 20, b.u32_at(body + 12)? as usize)
        } else {
            let iface = *self.interfaces.first()?;
            let orig = b.u32_at(body)? as usize;
            let cap = if iface.snap_len == 0 {
                orig
            } else {
                orig.min(iface.snap_len as usize)
            };
            (iface, 0, body + 4, cap)
        };
        if start.checked_add(len)? > end {
            return None;
        }
        let held = b.bytes.get(start..(start + len).min(b.bytes.len()))?;
        Some((iface, ts, held, start))
    }
}

impl RecordFormat for PcapNg {
    type Item<'a> = Datagram<'a>;
    type Error = PcapError;
    /// A block's type and length, and a Section Header Block's byte-order magic (a
    /// block is at least 12 bytes long).
    const HEAD: usize = 12;

    fn record_len(&self, head: &[u8], at: u64) -> Result<u64, PcapError> {
        let mut b = self.block(head);
        if head.get(..4) == Some(&SHB.to_le_bytes()) {
            // A new section says its own byte order, its length included.
            match head
                .get(8..12)
                .map(|m| u32::from_le_bytes([m[0], m[1], m[2], m[3]]))
            {
                Some(BYTE_ORDER_MAGIC) => b.big_endian = false,
                Some(m) if m.swap_bytes() == BYTE_ORDER_MAGIC => b.big_endian = true,
                Some(_) => return Err(PcapError::BadByteOrder(at)),
                None => return Err(PcapError::Truncated(at)),
            }
        }
        let (Some(_), Some(total)) = (b.u32_at(0), b.u32_at(4)) else {
            return Err(PcapError::Truncated(at));
        };
        if total < 12 || !total.is_multiple_of(4) {
            return Err(PcapError::BadLength(at));
        }
        Ok(u64::from(total))
    }

    fn truncated(&self, at: u64) -> PcapError {
        PcapError::Truncated(at)
    }

    fn item<'a>(
        &mut self,
        block: &'a [u8],
        at: u64,
        len: u64,
    ) -> Result<Option<Datagram<'a>>, PcapError> {
        let b = self.block(block);
        let kind = b.u32_at(0).ok_or(PcapError::Truncated(at))?;
        // `len` fits in a u32: it was read from one.
        let total = len as usize;
        let (body, end) = (8, total - 4);
        match kind {
            SHB => {
                // A new section may switch byte order; its interfaces start afresh.
                if let Some(m) = block.get(body..body + 4) {
                    let m = u32::from_le_bytes([m[0], m[1], m[2], m[3]]);
                    self.big_endian = m != BYTE_ORDER_MAGIC;
                }
                self.interfaces.clear();
            }
            IDB => match Self::interface(b, body, end.min(block.len())) {
                Some(_) if self.interfaces.len() >= MAX_INTERFACES => {
                    return Err(PcapError::TooManyInterfaces(at));
                }
                Some(i) => self.interfaces.push(i),
                None => return Err(PcapError::Truncated(at)),
            },
            EPB | SPB => {
                let found =
                    self.packet(b, kind, body, end)
                        .and_then(|(iface, ts, frame, start)| {
                            let udp = linktype::udp_payload(iface.link_type, frame)?;
                            let timestamp_us = u64::try_from(
                                u128::from(ts) * 1_000_000 / u128::from(iface.units_per_sec.max(1)),
                            )
                            .unwrap_or(u64::MAX);
                            Some(Datagram {
                                timestamp_us,
                                source: udp.source,
                                destination: udp.destination,
                                payload: udp.payload,
                                offset: at + (start + udp.offset) as u64,
                            })
                        });
                match found {
                    Some(d) => return Ok(Some(d)),
                    None => self.skipped += 1,
                }
            }
            _ => {}
        }
        Ok(None)
    }

    fn unit<'a>(dg: Self::Item<'a>) -> Unit<'a> {
        dg.unit()
    }

    fn passed_over(&self) -> u64 {
        self.skipped
    }
}

/// Reader over a pcapng file held in memory.
pub type Reader<'a> = records::Records<'a, PcapNg>;

impl<'a> Reader<'a> {
    /// Checks the first Section Header Block and prepares to read blocks.
    pub fn new(data: &'a [u8]) -> Result<Self, PcapError> {
        let format = PcapNg::from_header(data)?;
        Ok(records::Records::starting_at(data, 0, format))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block of `kind` around `body`, in the byte order `be` says.
    fn block_in(be: bool, kind: u32, body: &[u8]) -> Vec<u8> {
        let u32b = |v: u32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
        let total = (12 + body.len().div_ceil(4) * 4) as u32;
        let mut b = u32b(kind).to_vec();
        b.extend(u32b(total));
        b.extend(body);
        b.resize(total as usize - 4, 0);
        b.extend(u32b(total));
        b
    }

    fn block(kind: u32, body: &[u8]) -> Vec<u8> {
        block_in(false, kind, body)
    }

    /// A pcapng with one raw-IPv4 interface (µs resolution) and one EPB holding UDP `payload`.
    pub(crate) fn sample(payload: &[u8]) -> Vec<u8> {
        sample_in(false, payload)
    }

    /// [`sample`] in the byte order `be` says.
    fn sample_in(be: bool, payload: &[u8]) -> Vec<u8> {
        let u32b = |v: u32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
        let u16b = |v: u16| if be { v.to_be_bytes() } else { v.to_le_bytes() };
        let mut shb = u32b(BYTE_ORDER_MAGIC).to_vec();
        shb.extend(u16b(1));
        shb.extend(u16b(0));
        shb.extend(u64::MAX.to_le_bytes());
        let mut idb = u16b(linktype::DLT_RAW as u16).to_vec();
        idb.extend([0, 0, 0, 0, 0, 0]);
        let total = 28 + payload.len();
        let mut ip = vec![
            0x45,
            0,
            (total >> 8) as u8,
            total as u8,
            0,
            0,
            0,
            0,
            64,
            17,
            0,
            0,
            127,
            0,
            0,
            1,
            127,
            0,
            0,
            1,
        ];
        let ulen = 8 + payload.len();
        ip.extend([0x38, 0x96, 0x39, 0x14, (ulen >> 8) as u8, ulen as u8, 0, 0]);
        ip.extend(payload);
        let ts: u64 = 1_700_000_000_123_456;
        let mut epb = u32b(0).to_vec();
        epb.extend(u32b((ts >> 32) as u32));
        epb.extend(u32b(ts as u32));
        epb.extend(u32b(ip.len() as u32));
        epb.extend(u32b(ip.len() as u32));
        epb.extend(&ip);
        let mut out = block_in(be, SHB, &shb);
        out.extend(block_in(be, IDB, &idb));
        out.extend(block_in(be, 0xBAD, b"unknown block"));
        out.extend(block_in(be, EPB, &epb));
        out
    }

    #[test]
    fn sections_of_either_byte_order_follow_each_other() {
        for first_be in [false, true] {
            let data = [sample_in(first_be, b"one"), sample_in(!first_be, b"two")].concat();
            let got: Vec<Vec<u8>> = Reader::new(&data)
                .expect("pcapng")
                .map(|d| d.expect("datagram").payload.to_vec())
                .collect();
            assert_eq!(got, [b"one".to_vec(), b"two".to_vec()]);
        }
    }

    #[test]
    fn a_section_describes_a_bounded_number_of_interfaces() {
        let mut data = sample(b"x");
        let idb = block(IDB, &[1, 0, 0, 0, 0, 0, 0, 0]);
        for _ in 0..MAX_INTERFACES {
            data.extend(&idb);
        }
        let got: Vec<_> = Reader::new(&data).expect("pcapng").collect();
        assert!(got[0].is_ok(), "{got:?}");
        assert!(
            matches!(got.last(), Some(Err(PcapError::TooManyInterfaces(_)))),
            "{:?}",
            got.last()
        );
    }

    #[test]
    fn reads_udp_payloads_from_enhanced_packet_blocks() {
        let data = sample(b"hello");
        assert!(is_pcapng(&data));
        let got: Vec<_> = Reader::new(&data).expect("pcapng").collect();
        assert_eq!(got.len(), 1);
        let d = got[0].expect("datagram");
        assert_eq!(d.payload, b"hello");
        assert_eq!(d.timestamp_us, 1_700_000_000_123_456);
        assert_eq!(d.source, ([127, 0, 0, 1], 14486));
        let at = d.offset as usize;
        assert_eq!(&data[at..at + 5], b"hello");
    }

    #[test]
    fn truncated_files_are_reported_not_panicked_on() {
        let data = sample(b"hello");
        for cut in 0..data.len() {
            if let Ok(r) = Reader::new(&data[..cut]) {
                for _ in r {}
            }
        }
        let mut r = Reader::new(&data[..data.len() - 3]).expect("header intact");
        assert!(matches!(r.next(), Some(Err(PcapError::Truncated(_)))));
    }
}
