//! Reading MAVLink captures: raw byte streams, ground-station `.tlog` files, and
//! `.pcap` / `.pcapng` packet captures (MAVLink in UDP). The format is told from the
//! content, not the file name.
//!
//! Each format answers two questions about its records ([`records::RecordFormat`]): how
//! long is the one at hand, and what does it carry. [`Capture`] reads a capture from any
//! [`std::io::Read`] with those answers through a bounded buffer, so files of any size
//! take constant memory and standard input is read as it arrives; [`tlog::records`],
//! [`pcap::Reader`] and [`pcapng::Reader`] walk a capture already in memory with the
//! same answers.

pub(crate) mod linktype;
pub mod pcap;
pub mod pcapng;
pub mod records;
mod stream;
pub mod tlog;
mod window;

pub use stream::{Capture, End, Units};

use std::fmt;

use crate::wire::Version;

/// The kinds of capture understood.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// MAVLink bytes as they came off a serial port (no framing of its own); also what
    /// an empty input is.
    #[default]
    Raw,
    /// Ground-station telemetry log: 8-byte big-endian µs timestamp before each frame.
    Tlog,
    /// Classic libpcap.
    Pcap,
    /// pcapng.
    PcapNg,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Raw => "raw MAVLink",
            Format::Tlog => "tlog",
            Format::Pcap => "pcap",
            Format::PcapNg => "pcapng",
        })
    }
}

/// Microseconds since the UNIX epoch of 2000-01-01 and 2100-01-01: the plausible range
/// of a tlog's first timestamp.
const TLOG_EPOCH_RANGE: std::ops::Range<u64> = 946_684_800_000_000..4_102_444_800_000_000;

/// Tells the format of a capture from its first bytes (it looks at nine at most).
pub(crate) fn detect(data: &[u8]) -> Format {
    if pcap::is_pcap(data) {
        return Format::Pcap;
    }
    if pcapng::is_pcapng(data) {
        return Format::PcapNg;
    }
    let ts = tlog::TIMESTAMP_LEN;
    let tlog_like = data.len() > ts
        && Version::from_magic(data[ts]).is_some()
        && data[..ts]
            .try_into()
            .map(u64::from_be_bytes)
            .is_ok_and(|ts| TLOG_EPOCH_RANGE.contains(&ts));
    if tlog_like { Format::Tlog } else { Format::Raw }
}

/// A stretch of MAVLink bytes from a capture, as it was received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unit<'a> {
    /// When it was captured (µs since the UNIX epoch), if the format records it.
    pub timestamp_us: Option<u64>,
    /// Offset of `bytes` in the file.
    pub offset: u64,
    /// The bytes: the next piece of the stream (raw: the pieces make one stream, read
    /// as they came), one tlog record's frame, or one UDP payload.
    pub bytes: &'a [u8],
    /// For packet captures, the UDP source (IPv4 address and port).
    pub source: Option<([u8; 4], u16)>,
}

/// Why a capture could not be read to its end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureError {
    /// A tlog problem.
    Tlog(tlog::TlogError),
    /// A pcap or pcapng problem.
    Pcap(pcap::PcapError),
}

impl CaptureError {
    /// Byte offset of the problem, where known.
    pub fn offset(&self) -> u64 {
        match self {
            CaptureError::Tlog(tlog::TlogError::BadMagic { offset, .. }) => *offset,
            CaptureError::Tlog(tlog::TlogError::Truncated { offset }) => *offset,
            CaptureError::Pcap(
                pcap::PcapError::Truncated(at)
                | pcap::PcapError::BadLength(at)
                | pcap::PcapError::BadByteOrder(at)
                | pcap::PcapError::TooManyInterfaces(at),
            ) => *at,
            CaptureError::Pcap(_) => 0,
        }
    }
}

impl From<tlog::TlogError> for CaptureError {
    fn from(e: tlog::TlogError) -> Self {
        CaptureError::Tlog(e)
    }
}

impl From<pcap::PcapError> for CaptureError {
    fn from(e: pcap::PcapError) -> Self {
        CaptureError::Pcap(e)
    }
}

impl fmt::Display for CaptureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaptureError::Tlog(e) => write!(f, "{e}"),
            CaptureError::Pcap(e) => write!(f, "{e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::header::MAGIC_V2;

    #[test]
    fn formats_are_told_from_content() {
        assert_eq!(detect(&[0xd4, 0xc3, 0xb2, 0xa1, 0, 0]), Format::Pcap);
        assert_eq!(detect(&[0x0a, 0x0d, 0x0d, 0x0a]), Format::PcapNg);
        let mut tlog = 1_723_734_165_000_000u64.to_be_bytes().to_vec();
        tlog.push(MAGIC_V2);
        assert_eq!(detect(&tlog), Format::Tlog);
        assert_eq!(detect(&[MAGIC_V2, 9, 0]), Format::Raw);
        assert_eq!(detect(&[]), Format::Raw);
        // A raw stream whose 9th byte happens to be a magic byte is still raw.
        assert_eq!(
            detect(&[MAGIC_V2, 0, 0, 0, 0, 0, 0, 0, MAGIC_V2]),
            Format::Raw
        );
    }
}
