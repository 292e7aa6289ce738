//! Per-link traffic counters, printed at shutdown and on SIGUSR1.

use std::fmt;

/// What went through one link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Valid frames received from the link.
    pub frames_in: u64,
    /// Bytes of those frames.
    pub bytes_in: u64,
    /// Frames sent to the link.
    pub frames_out: u64,
    /// Bytes of those frames.
    pub bytes_out: u64,
    /// Frames dropped because sending failed.
    pub send_errors: u64,
    /// Largest number of bytes waiting in the link's queue.
    pub queue_high_water: usize,
    /// Frames from the link dropped for a bad checksum.
    pub bad_crc: u64,
}

impl LinkCounters {
    /// Notes a received frame of `len` bytes.
    pub fn received(&mut self, len: usize) {
        self.frames_in += 1;
        self.bytes_in += len as u64;
    }

    /// Notes a sent frame of `len` bytes.
    pub fn sent(&mut self, len: usize) {
        self.frames_out += 1;
        self.bytes_out += len as u64;
    }

    /// Notes the queue's current size.
    pub fn queue_level(&mut self, bytes: usize) {
        self.queue_high_water = self.queue_high_water.max(bytes);
    }
}

/// One link's counters with its name and queue drops, ready to print.
pub struct LinkReport<'a> {
    /// The link's name (as in log lines).
    pub name: &'a str,
    /// Its counters.
    pub counters: LinkCounters,
    /// Packets dropped because its queue was full.
    pub queue_drops: u64,
}

impl fmt::Display for LinkReport<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.counters;
        write!(
            f,
            "{}: in {} frames ({} bytes), out {} frames ({} bytes), dropped {} (queue full) + {} (send errors), queue high-water {} bytes, {} bad checksum",
            self.name,
            c.frames_in,
            c.bytes_in,
            c.frames_out,
            c.bytes_out,
            self.queue_drops,
            c.send_errors,
            c.queue_high_water,
            c.bad_crc
        )
    }
}
