//! One interface as the core sees it — a datagram server (a UDP socket and the remotes
//! behind it), a datagram client, a stream (a serial port, a TCP client or an accepted
//! TCP connection: one link each) or a stream server — with its parser, its quiet-line
//! rule, its `max_bitrate` pacer and its counters.

use std::net::SocketAddr;

use super::admission::Refused;
use super::link::{GroupId, LinkId};
use super::pacer::{DEFAULT_BURST, Pacer};
use super::reconnect::{Connection, FIRST_BACKOFF, MAX_BACKOFF, MAX_RECONNECT_WAIT};
use super::remotes::Remotes;
use super::stale::StaleTail;
use crate::config::PeerLimits;
use crate::signing::Edge;
use crate::time::Timestamp;
use crate::wire::{Parser, ParserStats};

/// Identifies an interface of an [`Engine`](super::Engine) for as long as it exists (the
/// number of a closed connection may be used again).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct InterfaceId(pub usize);

/// How late the loop may wake up for a datagram the pacer held back without the
/// interface losing rate. With a bucket of only one datagram every late wake-up is rate
/// lost for good, and a busy machine wakes the loop milliseconds late. The bucket holds
/// this much time at the configured rate beyond the largest datagram, but never more
/// than one more largest datagram: a burst is at most one datagram plus at most one
/// datagram's worth of catching up.
pub(crate) const PACING_SLACK_MICROS: u64 = 5_000;

/// The pacer of an interface limited to `rate` bit/s (0 = unlimited), with
/// [`PACING_SLACK_MICROS`] of slack.
pub(crate) fn pacer_for(rate: u64) -> Pacer {
    let slack =
        (rate.saturating_mul(PACING_SLACK_MICROS) / 8 / 1_000_000).min(u64::from(DEFAULT_BURST));
    let burst = u64::from(DEFAULT_BURST).saturating_add(slack);
    Pacer::with_burst(rate, u32::try_from(burst).unwrap_or(u32::MAX))
}

/// What kind of transport an interface is.
#[derive(Debug)]
pub enum Kind {
    /// A datagram server: datagrams from and to any number of peers, each its own link.
    Datagram {
        /// Peer ↔ link, and the round-robin turn.
        remotes: Remotes,
        /// The peer of the last datagram: a frame may continue in the same peer's next
        /// datagram, never in another's.
        last_sender: Option<SocketAddr>,
        /// Which peers may become links.
        limits: PeerLimits,
    },
    /// A datagram client: one link, sent to one configured peer (or a broadcast
    /// address) from the start; whatever its socket receives is that link's.
    DatagramClient {
        /// Its link (lives as long as the interface).
        link: LinkId,
        /// Where its datagrams go, once known (a host name is resolved when it opens).
        target: Option<SocketAddr>,
        /// The peer of the last datagram (replies to a broadcast come from each station).
        last_sender: Option<SocketAddr>,
        /// Bound, or when to try again.
        connection: Connection,
    },
    /// A byte stream that is one link: a serial port, a TCP client, or a connection a
    /// TCP server accepted.
    Stream {
        /// Its link.
        link: LinkId,
        /// Open, or when to try again.
        connection: Connection,
        /// The server that accepted it (it is removed when it closes), if any.
        accepted_by: Option<InterfaceId>,
        /// How the stream comes back after a loss.
        reopen: Reopen,
    },
    /// A stream server: accepts connections, each its own [`Kind::Stream`] interface.
    Listener {
        /// Which remotes may connect.
        limits: PeerLimits,
        /// Connections open now.
        connections: usize,
        /// The `max_bitrate` of each connection it accepts (0: no limit).
        max_bitrate: u64,
        /// How its connections' links are named: `SCHEME:a.b.c.d:port` (`tcp`, `ws`).
        scheme: &'static str,
    },
}

impl Reopen {
    /// A serial device: tried 100 ms after a loss, then with a backoff up to 2 s;
    /// what was queued is kept.
    pub const DEVICE: Reopen = Reopen {
        first_wait: FIRST_BACKOFF,
        max_wait: MAX_BACKOFF,
        forget_after: None,
        down_since: None,
        flapping: false,
    };

    /// A TCP client: tried again at once, then with a backoff up to 1 s; what was
    /// queued while it was down longer than `forget_after` is dropped.
    pub(crate) const fn client(forget_after: std::time::Duration) -> Reopen {
        Reopen {
            first_wait: std::time::Duration::ZERO,
            max_wait: MAX_RECONNECT_WAIT,
            forget_after: Some(forget_after),
            down_since: None,
            flapping: false,
        }
    }

    /// An accepted connection: never reopened (it is removed when it closes).
    pub const ACCEPTED: Reopen = Reopen {
        first_wait: std::time::Duration::ZERO,
        max_wait: std::time::Duration::ZERO,
        forget_after: None,
        down_since: None,
        flapping: false,
    };
}

impl Kind {
    /// A stream that is `link`, in state `connection`, accepted by `accepted_by` (if
    /// any), coming back after a loss as `reopen` says.
    pub(crate) fn stream(
        link: LinkId,
        connection: Connection,
        accepted_by: Option<InterfaceId>,
        reopen: Reopen,
    ) -> Self {
        Kind::Stream {
            link,
            connection,
            accepted_by,
            reopen,
        }
    }
}

/// How a stream comes back after it was lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reopen {
    /// Wait before the first attempt after a loss (a serial device needs a moment to
    /// reappear; a TCP client tries again at once).
    pub first_wait: std::time::Duration,
    /// Longest wait between attempts.
    pub max_wait: std::time::Duration,
    /// If the stream stayed down longer than this, what was queued for it meanwhile is
    /// dropped when it comes back, so stale telemetry is not replayed (None: kept).
    pub forget_after: Option<std::time::Duration>,
    /// When it was lost (while it is down).
    pub down_since: Option<Timestamp>,
    /// Its last connection was lost right after it opened (see
    /// [`crate::routing::reconnect::STABLE`]): losses are not said again until one stays.
    pub flapping: bool,
}

/// The core's state of one interface as it runs (what the file says about it is
/// [`crate::config::Interface`]).
#[derive(Debug)]
pub struct LiveInterface {
    /// How the counters report names it (`udp 0.0.0.0:14500`, or the device path).
    pub label: String,
    /// How messages name it (`udp 0.0.0.0:14500`, `serial device /dev/ttyUSB0`).
    pub described: String,
    /// The frame parser of its input.
    pub parser: Parser,
    /// What parsers of connections it accepted saw, added up when they closed.
    pub closed_parsers: ParserStats,
    /// When held-back bytes stop waiting.
    pub tail: StaleTail,
    /// Its `max_bitrate`.
    pub pacer: Pacer,
    /// When the pacer next lets a held-back packet go, if it is holding one.
    pub pace_deadline: Option<Timestamp>,
    /// Receive, send and open errors (for a stream: the times it was lost or could
    /// not be opened).
    pub io_errors: u64,
    /// Remotes refused by a server's limits.
    pub refused: Refused,
    /// Datagram or stream, server or client.
    pub kind: Kind,
    /// Its signing key, policy and counters, if it has a key.
    pub signing: Option<Edge>,
    /// Its `group` (redundant paths to one vehicle), if it has one; its links take it.
    pub group: Option<GroupId>,
    /// When it is closed at the latest, once a reload removed it: until then what it
    /// reads is dropped, and it sends what was queued for it (see `Engine::configure`).
    pub retiring: Option<Timestamp>,
}

impl LiveInterface {
    /// A new interface of `kind`.
    pub fn new(label: String, described: String, tail: StaleTail, rate: u64, kind: Kind) -> Self {
        LiveInterface {
            label,
            described,
            parser: Parser::new(),
            closed_parsers: ParserStats::default(),
            tail,
            pacer: pacer_for(rate),
            pace_deadline: None,
            io_errors: 0,
            refused: Refused::default(),
            kind,
            signing: None,
            group: None,
            retiring: None,
        }
    }

    /// A datagram network interface (no line rate: held-back bytes wait the plain quiet
    /// gap) named `label` in messages and counters alike.
    pub(crate) fn network(label: String, rate: u64, kind: Kind) -> Self {
        LiveInterface::new(label.clone(), label, StaleTail::new(None), rate, kind)
    }

    /// A TCP interface (a client, a server or one of its connections) named `label`:
    /// its held-back bytes wait for the rest of their frame as long as the connection
    /// lasts.
    pub(crate) fn reliable_stream(label: String, rate: u64, kind: Kind) -> Self {
        LiveInterface::new(label.clone(), label, StaleTail::reliable(), rate, kind)
    }

    /// The connection state of an interface that opens (streams, datagram clients).
    pub(crate) fn connection(&self) -> Option<&Connection> {
        match &self.kind {
            Kind::Stream { connection, .. } | Kind::DatagramClient { connection, .. } => {
                Some(connection)
            }
            Kind::Datagram { .. } | Kind::Listener { .. } => None,
        }
    }

    /// The connection state, mutable.
    pub(crate) fn connection_mut(&mut self) -> Option<&mut Connection> {
        match &mut self.kind {
            Kind::Stream { connection, .. } | Kind::DatagramClient { connection, .. } => {
                Some(connection)
            }
            Kind::Datagram { .. } | Kind::Listener { .. } => None,
        }
    }

    /// The one link of a client or stream interface.
    pub(crate) fn own_link(&self) -> Option<LinkId> {
        match self.kind {
            Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => Some(link),
            Kind::Datagram { .. } | Kind::Listener { .. } => None,
        }
    }

    /// True while bytes can flow (servers always; others once open).
    pub(crate) fn is_open(&self) -> bool {
        self.connection().is_none_or(Connection::is_open)
    }
}
