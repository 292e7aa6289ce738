//! `.tlog` files as written by ground stations (MAVProxy, Mission Planner, QGC): each
//! record is an 8-byte big-endian timestamp (microseconds since the UNIX epoch)
//! followed by one raw MAVLink frame.

use crate::wire::{HeaderError, HeaderRepr};

/// Length of the big-endian timestamp before each frame.
pub const TIMESTAMP_LEN: usize = 8;

/// One record of a tlog: when it was logged and the frame's bytes (not yet checked).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record<'a> {
    /// Byte offset of the record (its timestamp) in the file.
    pub offset: usize,
    /// Microseconds since 1970-01-01 UTC.
    pub timestamp_us: u64,
    /// The frame's bytes, sized from its header.
    pub frame: &'a [u8],
}

/// Why a tlog could not be read to the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TlogError {
    /// The byte after a timestamp is not a MAVLink start byte.
    BadMagic {
        /// Offset of the offending byte.
        offset: usize,
        /// The byte found.
        byte: u8,
    },
    /// The file ends inside a record.
    Truncated {
        /// Offset of the incomplete record.
        offset: usize,
    },
}

impl std::fmt::Display for TlogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TlogError::BadMagic { byte, .. } => write!(
                f,
                "expected a MAVLink start byte after the timestamp, found 0x{byte:02x}"
            ),
            TlogError::Truncated { .. } => write!(f, "file ends inside a record"),
        }
    }
}

/// Iterator over the records of a tlog held in memory. After an error it stops.
#[derive(Debug, Clone)]
pub struct Records<'a> {
    data: &'a [u8],
    pos: usize,
    failed: bool,
}

/// Iterates over the records of `data`.
pub fn records(data: &[u8]) -> Records<'_> {
    Records {
        data,
        pos: 0,
        failed: false,
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Result<Record<'a>, TlogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed || self.pos >= self.data.len() {
            return None;
        }
        let offset = self.pos;
        let rest = &self.data[offset..];
        let result = (|| {
            let ts: [u8; TIMESTAMP_LEN] = rest
                .get(..TIMESTAMP_LEN)
                .and_then(|b| b.try_into().ok())
                .ok_or(TlogError::Truncated { offset })?;
            let body = &rest[TIMESTAMP_LEN..];
            // The frame is sized from its header; checking it is the parser's job.
            let header = HeaderRepr::parse(body).map_err(|e| match e {
                HeaderError::BadMagic(byte) => TlogError::BadMagic {
                    offset: offset + TIMESTAMP_LEN,
                    byte,
                },
                HeaderError::Truncated { .. } => TlogError::Truncated { offset },
            })?;
            let frame = body
                .get(..header.frame_len())
                .ok_or(TlogError::Truncated { offset })?;
            Ok(Record {
                offset,
                timestamp_us: u64::from_be_bytes(ts),
                frame,
            })
        })();
        match &result {
            Ok(r) => self.pos += TIMESTAMP_LEN + r.frame.len(),
            Err(_) => self.failed = true,
        }
        Some(result)
    }
}
