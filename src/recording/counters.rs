//! The recorder's counters: what the counters report (SIGUSR1, exit) prints and what a
//! statistics endpoint reads.

use std::fmt;

/// What the recorder has done since the router started.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecorderStats {
    /// Records (frames) written to a file.
    pub written: u64,
    /// Bytes written, timestamps included.
    pub bytes: u64,
    /// Records dropped because the writer was behind (its queue was full).
    pub dropped_queue_full: u64,
    /// Records dropped because a file could not be opened or written (a disk error, a
    /// full disk, a file-size limit).
    pub dropped_disk: u64,
    /// Records dropped because the disk had less than `min_free_bytes` free even with
    /// every older recording removed.
    pub dropped_no_space: u64,
    /// Files opened (one at start, one per rotation).
    pub files: u64,
    /// Old recordings removed (beyond `max_files`, or to keep `min_free_bytes` free).
    pub removed: u64,
    /// The file being written, if one is open.
    pub current_path: Option<String>,
}

impl RecorderStats {
    /// Records dropped for any reason.
    pub fn dropped(&self) -> u64 {
        self.dropped_queue_full + self.dropped_disk + self.dropped_no_space
    }
}

impl fmt::Display for RecorderStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "recording {}: {} records ({} bytes) written, dropped {} (queue full) + {} (disk errors) + {} (no space), {} files opened, {} removed",
            self.current_path.as_deref().unwrap_or("(no file open)"),
            self.written,
            self.bytes,
            self.dropped_queue_full,
            self.dropped_disk,
            self.dropped_no_space,
            self.files,
            self.removed
        )
    }
}
