//! `.tlog` files as written by ground stations (MAVProxy, Mission Planner, QGC): each
//! record is an 8-byte big-endian timestamp (microseconds since the UNIX epoch)
//! followed by one raw MAVLink frame.

use crate::wire::frame::{
    HEADER_LEN_V1, HEADER_LEN_V2, INCOMPAT_SIGNED, MAGIC_V1, MAGIC_V2, SIGNATURE_LEN,
};

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

/// Length of a frame from its header bytes, or `None` if `bytes` is too short to tell.
fn frame_len(bytes: &[u8]) -> Option<usize> {
    match *bytes.first()? {
        MAGIC_V1 => Some(HEADER_LEN_V1 + *bytes.get(1)? as usize + 2),
        MAGIC_V2 => {
            let signed = *bytes.get(2)? & INCOMPAT_SIGNED != 0;
            Some(
                HEADER_LEN_V2
                    + *bytes.get(1)? as usize
                    + 2
                    + if signed { SIGNATURE_LEN } else { 0 },
            )
        }
        _ => None,
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
            let ts: [u8; 8] = rest
                .get(..8)
                .and_then(|b| b.try_into().ok())
                .ok_or(TlogError::Truncated { offset })?;
            let body = &rest[8..];
            match body.first() {
                None => return Err(TlogError::Truncated { offset }),
                Some(&b) if b != MAGIC_V1 && b != MAGIC_V2 => {
                    return Err(TlogError::BadMagic {
                        offset: offset + 8,
                        byte: b,
                    });
                }
                Some(_) => {}
            }
            let len = frame_len(body).ok_or(TlogError::Truncated { offset })?;
            let frame = body.get(..len).ok_or(TlogError::Truncated { offset })?;
            Ok(Record {
                offset,
                timestamp_us: u64::from_be_bytes(ts),
                frame,
            })
        })();
        match &result {
            Ok(r) => self.pos += 8 + r.frame.len(),
            Err(_) => self.failed = true,
        }
        Some(result)
    }
}
