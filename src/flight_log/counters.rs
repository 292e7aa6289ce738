//! The flight log's counters: the stream's (kept by the core) and the files' (kept by
//! the writer), joined in [`FlightLogStats`] for `/stats`, `/metrics` and the report.

use std::fmt;

/// What the core counted of the stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FlightLogCounters {
    /// Logs begun (each is one file once it has bytes).
    pub logs: u64,
    /// Blocks (ulog chunks) put in order for the file.
    pub blocks: u64,
    /// Bytes put in order for the file.
    pub bytes: u64,
    /// Missing blocks asked for again (NACKs sent).
    pub nacks: u64,
    /// Blocks that came after they were asked for again.
    pub resent: u64,
    /// Blocks given up (never came), or ulog chunks lost.
    pub lost: u64,
    /// Blocks received twice.
    pub duplicates: u64,
    /// Blocks that came while no log was asked for, or that belong to the log before
    /// (still on their way when the autopilot began a new one).
    pub late: u64,
    /// Blocks dropped because the writer fell behind.
    pub dropped: u64,
}

/// The flight log's counters and state, for the statistics.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FlightLogStats {
    /// The stream's counters.
    pub stream: FlightLogCounters,
    /// Blocks written to files.
    pub blocks_written: u64,
    /// Bytes written to files.
    pub bytes_written: u64,
    /// Files created.
    pub files: u64,
    /// Old logs removed (beyond `max_files`, or for `min_free_bytes`).
    pub removed: u64,
    /// Blocks not written: the disk failed or had no room.
    pub blocks_dropped_disk: u64,
    /// The protocol of the log being received (`bin`, `ulg`), if one is.
    pub streaming: Option<&'static str>,
    /// The file being written (or the last one).
    pub current_path: Option<String>,
}

impl fmt::Display for FlightLogStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.stream;
        write!(
            f,
            "flight log: {} files, {} blocks ({} bytes) written, {} resent, {} lost, {} dropped",
            self.files,
            self.blocks_written,
            self.bytes_written,
            s.resent,
            s.lost,
            s.dropped + self.blocks_dropped_disk
        )?;
        if let Some(path) = &self.current_path {
            write!(f, ", last file {path}")?;
        }
        Ok(())
    }
}
