//! Per-link and per-interface traffic counters, and the one text that reports them (on
//! SIGUSR1 and at exit).

use std::fmt;

use super::admission::Refused;
use crate::signing::SigningCounters;
use crate::wire::ParserStats;

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
    /// Frames from the link dropped for a bad checksum.
    pub bad_crc: u64,
    /// Frames from the link dropped for a message id outside the dialect.
    pub unknown_id: u64,
    /// Frames from the link of an id no dialect defines, taken in under
    /// `unknown_messages accept;` (their checksum unchecked).
    pub unknown_accepted: u64,
    /// `SETUP_SIGNING` frames from the link forwarded nowhere: it carries a signing key
    /// in the clear, so only a rule naming it forwards it.
    pub setup_signing: u64,
    /// (Frame, this link) offers the filter rejected for every candidate address: the
    /// frames that would have gone to this link but for a rule or the default action.
    pub filter_rejected: u64,
    /// Valid frames from the link that no link took or rejected: no other link reaches
    /// their destination (a target nobody has heard of, or only the sender itself).
    pub no_route: u64,
    /// Frames from the link dropped as copies of one taken in within the `dedup`
    /// window (from any link).
    pub duplicate: u64,
    /// Signatures checked, refused and added (links of interfaces with a key).
    pub signing: SigningCounters,
}

impl LinkCounters {
    /// Notes a received frame of `len` bytes.
    #[inline]
    pub(crate) fn received(&mut self, len: usize) {
        self.frames_in += 1;
        self.bytes_in += len as u64;
    }

    /// Notes a sent frame of `len` bytes.
    #[inline]
    pub fn sent(&mut self, len: usize) {
        self.frames_out += 1;
        self.bytes_out += len as u64;
    }

    /// Counts `frames` frames of `bytes` bytes in all as sent.
    pub fn sent_many(&mut self, frames: u64, bytes: usize) {
        self.frames_out += frames;
        self.bytes_out += bytes as u64;
    }
}

/// One link's line of the counters report.
pub struct LinkReport<'a> {
    /// The link's name (as in log lines).
    pub name: &'a str,
    /// Its counters.
    pub counters: LinkCounters,
    /// Packets dropped because its queue was full.
    pub queue_drops: u64,
    /// The most bytes its queue held at once.
    pub queue_high_water: usize,
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
            self.queue_high_water,
            c.bad_crc
        )?;
        if c.unknown_accepted > 0 {
            write!(f, ", {} unknown ids accepted", c.unknown_accepted)?;
        }
        if c.duplicate > 0 {
            write!(f, ", {} duplicates dropped", c.duplicate)?;
        }
        if c.setup_signing > 0 {
            write!(f, ", {} SETUP_SIGNING not forwarded", c.setup_signing)?;
        }
        if !c.signing.is_zero() {
            write!(f, ", {}", c.signing)?;
        }
        Ok(())
    }
}

/// One interface's line of the counters report: what its parser saw and its I/O errors.
pub struct InterfaceReport<'a> {
    /// The interface's label (`udp 0.0.0.0:14500`, `/dev/ttyUSB0`).
    pub label: &'a str,
    /// Its parser's totals.
    pub parser: &'a ParserStats,
    /// Receive, send and open errors other than "would block".
    pub io_errors: u64,
    /// Remotes a server refused.
    pub refused: Refused,
    /// What signing did, if the interface has a key.
    pub signing: Option<SigningCounters>,
}

impl fmt::Display for InterfaceReport<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {}, {} I/O errors",
            self.label, self.parser, self.io_errors
        )?;
        let r = self.refused;
        if r != Refused::default() {
            write!(
                f,
                ", {} refused (not allowed), {} refused (max_peers)",
                r.not_allowed_in_all(),
                r.full
            )?;
        }
        if let Some(s) = self.signing {
            write!(f, ", {s}")?;
        }
        Ok(())
    }
}
