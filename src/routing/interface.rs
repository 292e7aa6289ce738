//! One configured interface as the core sees it: a datagram interface (a UDP socket and
//! the remotes behind it) or a stream (a serial port, one link), with its parser, its
//! quiet-line rule, its `max_bitrate` pacer and its error count.

use super::link::LinkId;
use super::pacer::{DEFAULT_BURST, Pacer};
use super::reconnect::Connection;
use super::remotes::Remotes;
use super::stale::StaleTail;
use super::time::Timestamp;
use crate::wire::Parser;

/// Identifies an interface of an [`Engine`](super::Engine): its index in creation order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct InterfaceId(pub usize);

/// How late the loop may wake up for a datagram the pacer held back without the
/// interface losing rate. With a bucket of only one datagram every late wake-up is rate
/// lost for good, and a busy machine wakes the loop milliseconds late. The bucket holds
/// this much time at the configured rate beyond the largest datagram, but never more
/// than one more largest datagram: a burst is at most one datagram plus at most one
/// datagram's worth of catching up.
pub const PACING_SLACK_MICROS: u64 = 5_000;

/// The pacer of an interface limited to `rate` bit/s (0 = unlimited), with
/// [`PACING_SLACK_MICROS`] of slack.
pub fn pacer_for(rate: u64) -> Pacer {
    let slack =
        (rate.saturating_mul(PACING_SLACK_MICROS) / 8 / 1_000_000).min(u64::from(DEFAULT_BURST));
    let burst = u64::from(DEFAULT_BURST).saturating_add(slack);
    Pacer::with_burst(rate, u32::try_from(burst).unwrap_or(u32::MAX))
}

/// What kind of transport an interface is.
#[derive(Debug)]
pub enum Kind {
    /// Datagrams from and to any number of peers, each its own link.
    Datagram {
        /// Peer ↔ link, and the round-robin turn.
        remotes: Remotes,
        /// The peer of the last datagram: a frame may continue in the same peer's next
        /// datagram, never in another's.
        last_sender: Option<std::net::SocketAddr>,
    },
    /// A byte stream that is one link.
    Stream {
        /// Its link (lives as long as the interface).
        link: LinkId,
        /// Open, or when to try again.
        connection: Connection,
    },
}

/// The core's state of one interface.
#[derive(Debug)]
pub struct Interface {
    /// How the counters report names it (`udp 0.0.0.0:14500`, or the device path).
    pub label: String,
    /// How messages name it (`udp 0.0.0.0:14500`, `serial device /dev/ttyUSB0`).
    pub described: String,
    /// The frame parser of its input.
    pub parser: Parser,
    /// When held-back bytes stop waiting.
    pub tail: StaleTail,
    /// Its `max_bitrate`.
    pub pacer: Pacer,
    /// When the pacer next lets a held-back packet go, if it is holding one.
    pub pace_deadline: Option<Timestamp>,
    /// Receive, send and open errors (for a stream: the times it was lost or could
    /// not be opened).
    pub io_errors: u64,
    /// Datagram or stream.
    pub kind: Kind,
}
