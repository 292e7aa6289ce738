//! `.tlog` files as written by ground stations (MAVProxy, Mission Planner, QGC): each
//! record is an 8-byte big-endian timestamp (microseconds since the UNIX epoch)
//! followed by one raw MAVLink frame.

use super::Unit;
use super::records::{self, RecordFormat};
use crate::wire::header::HEADER_LEN_V2;
use crate::wire::{HeaderError, HeaderRepr};

/// Length of the big-endian timestamp before each frame.
pub const TIMESTAMP_LEN: usize = 8;

/// One record of a tlog: when it was logged and the frame's bytes (not yet checked).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record<'a> {
    /// Byte offset of the record (its timestamp) in the file.
    pub offset: u64,
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
        offset: u64,
        /// The byte found.
        byte: u8,
    },
    /// The file ends inside a record.
    Truncated {
        /// Offset of the incomplete record.
        offset: u64,
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

/// The tlog format: records sized by their frame's header (it has no state).
#[derive(Debug, Clone, Copy, Default)]
pub struct Tlog;

impl RecordFormat for Tlog {
    type Item<'a> = Record<'a>;
    type Error = TlogError;
    const HEAD: usize = TIMESTAMP_LEN + HEADER_LEN_V2;

    fn record_len(&self, head: &[u8], at: u64) -> Result<u64, TlogError> {
        let Some(body) = head.get(TIMESTAMP_LEN..) else {
            return Err(TlogError::Truncated { offset: at });
        };
        // The frame is sized from its header; checking it is the parser's job.
        let header = HeaderRepr::parse(body).map_err(|e| match e {
            HeaderError::BadMagic(byte) => TlogError::BadMagic {
                offset: at + TIMESTAMP_LEN as u64,
                byte,
            },
            HeaderError::Truncated { .. } => TlogError::Truncated { offset: at },
        })?;
        Ok((TIMESTAMP_LEN + header.frame_len()) as u64)
    }

    fn truncated(&self, at: u64) -> TlogError {
        TlogError::Truncated { offset: at }
    }

    fn item<'a>(
        &mut self,
        record: &'a [u8],
        at: u64,
        _len: u64,
    ) -> Result<Option<Record<'a>>, TlogError> {
        let (ts, frame) = record.split_at(TIMESTAMP_LEN.min(record.len()));
        let ts: [u8; TIMESTAMP_LEN] = ts
            .try_into()
            .map_err(|_| TlogError::Truncated { offset: at })?;
        Ok(Some(Record {
            offset: at,
            timestamp_us: u64::from_be_bytes(ts),
            frame,
        }))
    }

    fn unit<'a>(rec: Self::Item<'a>) -> Unit<'a> {
        Unit {
            timestamp_us: Some(rec.timestamp_us),
            offset: rec.offset + TIMESTAMP_LEN as u64,
            bytes: rec.frame,
            source: None,
        }
    }
}

/// Iterator over the records of a tlog held in memory. After an error it stops.
pub type Records<'a> = records::Records<'a, Tlog>;

/// Iterates over the records of `data`.
pub fn records(data: &[u8]) -> Records<'_> {
    Records::starting_at(data, 0, Tlog)
}
