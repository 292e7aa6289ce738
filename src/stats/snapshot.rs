//! The snapshot: every counter of the router at one instant, with the rates of the last
//! second and of the last minutes, in plain values that the renderers turn into JSON or
//! Prometheus text.

use crate::recording::RecorderStats;

/// Every counter of the router at one instant.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StatsSnapshot {
    /// Seconds since the router started.
    pub uptime_s: f64,
    /// Every link, in creation order.
    pub links: Vec<LinkStats>,
    /// Every configured interface, in configuration order (a TCP server's connections
    /// are added into its entry).
    pub interfaces: Vec<InterfaceStats>,
    /// Every chain, in configuration order, with its rules' counts.
    pub chains: Vec<ChainStats>,
    /// Evaluations no rule decided.
    pub default_action: DefaultActionStats,
    /// Frames per (source address, message type), by source then message.
    pub sources: Vec<SourceStats>,
    /// Sequence gaps per source address, by address.
    pub sequence_gaps: Vec<SequenceStats>,
    /// (Source, message) pairs that lost their place in the bounded table.
    pub sources_evicted: u64,
    /// Rate-capped streams forgotten because their bounded table was full.
    pub rate_streams_evicted: u64,
    /// Frames of sources beyond the sequence table's bound.
    pub sequence_untracked: u64,
    /// Bytes all queues hold together.
    pub queued_bytes: u64,
    /// Lookups answered by the filter's verdict memo.
    pub filter_cache_hits: u64,
    /// Lookups that walked the rules.
    pub filter_cache_misses: u64,
    /// What the recorder did, when the router records (the I/O layer fills it in: the
    /// recorder is a thread of its own).
    pub recording: Option<RecorderStats>,
    /// The flight log's counters, when the router writes flight logs.
    pub flight_log: Option<crate::flight_log::FlightLogStats>,
}

/// Frames dropped, by reason. A link's receive-side reasons (`no_route`, `bad_crc`,
/// `unknown_id` and the signing refusals) count frames that came from it; its send-side
/// reasons (`filter_rejected`, `queue_full`, `send_error`) frames that were for it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Drops {
    /// Frames for this link that the filter rejected (for every candidate address).
    pub filter_rejected: u64,
    /// Frames from this link that no link took or rejected (nobody reaches their target).
    pub no_route: u64,
    /// Frames for this link dropped because its queue (or all queues) were full.
    pub queue_full: u64,
    /// Frames for this link whose sending failed.
    pub send_error: u64,
    /// Frames from this link with a bad checksum.
    pub bad_crc: u64,
    /// Frames from this link with a message id outside the dialect.
    pub unknown_id: u64,
    /// Signed frames from this link whose signature did not check.
    pub bad_signature: u64,
    /// Signed frames from this link with a timestamp not after their stream's last.
    pub replayed: u64,
    /// A new stream's first frame from this link, too far from the router's clock.
    pub out_of_window: u64,
    /// Unsigned frames from this link where signing is required.
    pub unsigned: u64,
    /// `SETUP_SIGNING` frames from this link forwarded nowhere (only a rule naming it
    /// forwards it: it carries a signing key in the clear).
    pub setup_signing: u64,
    /// Frames from this link dropped as copies of one taken in within the `dedup`
    /// window (redundant paths deliver each frame once per path).
    pub duplicate: u64,
}

impl Drops {
    /// The reasons with their names, in the JSON's order.
    pub(crate) fn named(&self) -> [(&'static str, u64); 12] {
        [
            ("filter_rejected", self.filter_rejected),
            ("no_route", self.no_route),
            ("queue_full", self.queue_full),
            ("send_error", self.send_error),
            ("bad_crc", self.bad_crc),
            ("unknown_id", self.unknown_id),
            ("bad_signature", self.bad_signature),
            ("replayed", self.replayed),
            ("out_of_window", self.out_of_window),
            ("unsigned", self.unsigned),
            ("setup_signing", self.setup_signing),
            ("duplicate", self.duplicate),
        ]
    }
}

/// One link.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkStats {
    /// The link's number (unique for the router's lifetime).
    pub id: u64,
    /// Its name, as in log lines (`127.0.0.1:41219`, `/dev/ttyUSB0`, `tcp:…`).
    pub name: String,
    /// The label of the interface it belongs to.
    pub interface: String,
    /// Valid frames received from it.
    pub frames_in: u64,
    /// Their bytes.
    pub bytes_in: u64,
    /// Frames sent to it.
    pub frames_out: u64,
    /// Their bytes.
    pub bytes_out: u64,
    /// Frames received per second over the last interval.
    pub rate_in_fps: f64,
    /// Frames sent per second over the last interval.
    pub rate_out_fps: f64,
    /// Bits received per second over the last interval.
    pub rate_in_bps: f64,
    /// Bits sent per second over the last interval.
    pub rate_out_bps: f64,
    /// Frames dropped, by reason.
    pub drops: Drops,
    /// Bytes its queue holds now (frames plus bookkeeping).
    pub queue_bytes: u64,
    /// The most bytes its queue held at once.
    pub queue_high_water: u64,
    /// The MAVLink addresses it reaches now (`1.1`).
    pub addresses: Vec<String>,
    /// Frames received per second, one sample a second, oldest first.
    pub history_in_fps: Vec<f64>,
    /// Frames sent per second, one sample a second, oldest first.
    pub history_out_fps: Vec<f64>,
}

/// What signing did on one interface: the routing core's own counters.
pub type SigningStats = crate::signing::SigningCounters;

/// One configured interface: what its parser saw.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct InterfaceStats {
    /// Its label (`udp 0.0.0.0:14550`, the device path).
    pub label: String,
    /// Valid frames parsed.
    pub frames: u64,
    /// Frames with a bad checksum.
    pub bad_crc: u64,
    /// Frames with a message id outside the dialect.
    pub unknown_id: u64,
    /// Bytes that were not part of any frame.
    pub junk_bytes: u64,
    /// Receive, send and open errors.
    pub io_errors: u64,
    /// Remotes a server refused because `allow` does not cover them.
    pub refused_not_allowed: u64,
    /// Remotes a server refused because it had `max_peers` links.
    pub refused_max_peers: u64,
    /// What signing did, if the interface has a key.
    pub signing: Option<SigningStats>,
}

/// One chain and its rules.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ChainStats {
    /// The chain's name.
    pub name: String,
    /// Its rules in order.
    pub rules: Vec<RuleStats>,
}

/// One rule's counts.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RuleStats {
    /// The rule, normalised to one line (`accept with priority 3 if PING from 1.0/8`).
    pub text: String,
    /// (Packet, destination) evaluations its condition matched.
    pub packets: u64,
    /// The frame bytes of those evaluations.
    pub bytes: u64,
    /// How many of them it decided (accept and reject rules; see `docs/configuration.md`).
    pub decided: u64,
    /// Frames it accepted for a link that its `with rate` dropped.
    pub rate_limited: u64,
}

/// The default action and the evaluations it decided.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DefaultActionStats {
    /// `accept` or `reject`.
    pub action: String,
    /// Evaluations no rule decided.
    pub packets: u64,
    /// Their frame bytes.
    pub bytes: u64,
}

/// Frames of one (source address, message type) pair.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceStats {
    /// The sender's MAVLink address (`1.1`).
    pub source: String,
    /// The message's name (or its number when outside the dialect).
    pub message: String,
    /// Frames received.
    pub frames: u64,
    /// Frames per second over the last interval.
    pub rate_fps: f64,
}

/// Sequence numbers of one source address.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SequenceStats {
    /// The sender's MAVLink address (`1.1`).
    pub source: String,
    /// Frames received from it.
    pub received: u64,
    /// Frames its sequence numbers say were lost before they reached the router.
    pub lost: u64,
}
