//! The routing core as the event loop drives it, in the shape of `quinn-proto`: bytes and
//! time in, what to send and when to wake up out. It never reads a clock, touches a
//! socket or blocks; the drivers in `src/io/` only move bytes between the operating
//! system and these calls.
//!
//! ```text
//! config:    engine.configure(config, keys, now) → close/open requests    (at start, and
//!            at every reload: only what changed is closed or opened; see [`Reconfigured`])
//! start:     ifc = engine.add_datagram_interface(label, max_bitrate)       (a UDP socket)
//!            ifc = engine.add_stream_interface(device, …, now)             (a serial port)
//! input:     engine.handle_datagram(ifc, peer, bytes, now)    every datagram received
//!            engine.handle_stream(ifc, bytes, now)            every chunk read
//! direct:    engine.handle_datagram_direct(…) for a datagram read on its own; then at
//!            once, if engine.direct_interface() names one, its driver sends
//!            engine.take_direct(ifc) if it has nothing in flight, else
//!            engine.queue_direct()                            (see `engine/direct.rs`)
//! ready:     while let Some(ifc) = engine.poll_ready() { flush ifc }   (only those: an
//!            interface never named has nothing to send; see [`Engine::poll_ready`])
//! output:    engine.poll_transmit(ifc, now, room, &mut queue)   then send what it gave;
//!            engine.on_sent_batch(sent) per batch taken, on_send_failed(ifc, &t, &e) if not
//! time:      arm one timer for engine.poll_timeout() (re-arming only when it moves
//!            earlier is enough: handle_timeout(now) called early does nothing)
//! notices:   while let Some(n) = engine.poll_event() { log it, or open a stream it names }
//! streams:   engine.stream_opened / stream_open_failed / stream_lost(ifc, now, …)
//! ```
//!
//! What lives here: the per-interface parsers, which peer address is which link (links of
//! datagram peers are created by their first valid frame and removed after the expiry
//! time), the round robin between the peers of an interface, the `max_bitrate` pacer, the
//! quiet-line rule for held-back bytes, the backoff for reopening lost devices, and every
//! counter. The routing decisions themselves are the [`Router`]'s.

mod configure;
mod direct;
mod flight_log;
mod input;
mod interfaces;
mod messages;
mod paths;
mod ready;
mod report;
mod streams;
mod timers;
mod transmit;

use std::collections::VecDeque;
use std::fmt::Display;
use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use slab::Slab;

use super::admission;
use super::counters::InterfaceReport;
use super::intake::{Intake, Sender, UnknownIds};
use super::interface::{InterfaceId, Kind, LiveInterface as Interface, Reopen};
use super::link::{GroupId, LinkId};
use super::notice::Notice;
use super::own_heartbeat::OwnHeartbeat;
use super::pacer::Pace;
use super::queue::Packet;
use super::reconnect::{Connection, FIRST_BACKOFF, MAX_BACKOFF};
use super::remotes::Remotes;
use super::router::{Output, Router, RouterOptions};
use super::snapshot::{self, RuleBook};
use super::stale::StaleTail;
use super::time::Timestamp;
use crate::address::Address;
use crate::config::{Config, PeerLimits};
use crate::flight_log::FlightLogger;
use crate::recording::{RecordFilter, Tap};
use crate::signing::sign;
use crate::signing::state::SavedState;
use crate::signing::{Edge, Signing, SigningKey};
use crate::stats::{History, StatsSnapshot};

pub use configure::{Reconfigured, Request};
pub use messages::SystemSet;

/// How often learned addresses are expired and idle datagram links removed.
pub const TICK: Duration = Duration::from_secs(1);

/// How long an interface may still send what was queued for it once it is to close: at
/// shutdown (SIGINT, SIGTERM), and when a reload removes or reopens it; also how long a
/// connection ended for an error may linger to tell its peer why.
pub const CLOSE_FLUSH: Duration = Duration::from_secs(1);

/// How long a TCP client may be down before what was queued for it meanwhile is dropped
/// rather than sent when it reconnects: telemetry seconds old misleads a ground station,
/// and a command nobody saw being sent should not fire minutes later.
pub const FORGET_AFTER: Duration = Duration::from_secs(2);

/// Most packets one link of an unpaced datagram interface hands out in a row before the
/// next link's turn: a run of datagrams to one peer that the driver can send as one
/// segmentation-offload message, short enough that no peer waits long for its turn.
pub const SEND_TURN: usize = 16;

/// One packet to send: to which link, and for a datagram interface to which peer.
#[derive(Debug, Clone)]
pub struct Transmit {
    /// The link it goes to.
    pub link: LinkId,
    /// The peer of a datagram interface (`None` on a stream).
    pub to: Option<SocketAddr>,
    /// The frame's bytes, exactly as received.
    pub packet: Packet,
}

/// The sans-IO routing core: interfaces, links, the router, timers and counters.
#[derive(Debug)]
pub struct Engine {
    /// What every received frame goes through.
    core: Core,
    interfaces: Slab<Interface>,
    next_tick: Timestamp,
    rules: RuleBook,
    history: History,
    /// The configuration in force: its interfaces are those [`Engine::configure`] added.
    config: Config,
    /// The core's interface and the signing key of each of `config.interfaces`.
    configured: Vec<configure::Configured>,
    /// Interfaces with output to hand out ([`Engine::poll_ready`]).
    ready: ready::ReadySet,
    /// The next deadline of each interface that has one.
    deadlines: ready::Deadlines,
    /// The interface each link belongs to.
    owner: ready::ByLink<InterfaceId>,
    /// Scratch for [`Engine::handle_timeout`].
    due: Vec<InterfaceId>,
    /// The router's own heartbeat, when configured.
    heartbeat: Option<OwnHeartbeat>,
    /// File writes of a flight logger replaced by a reload, not yet taken.
    flight_log_leftover: Vec<crate::flight_log::LogWrite>,
    /// A packet held out of its queue for a direct send by the driver of this interface
    /// (see `engine/direct.rs`).
    direct: Option<(InterfaceId, crate::routing::router::Direct)>,
}

/// The parts of the engine every received frame goes through, apart from the
/// interfaces (which hold the parsers feeding it): borrowed as one while a parser of
/// `interfaces` runs.
#[derive(Debug)]
struct Core {
    router: Router,
    /// The router's output of the current call.
    out: Output,
    notices: VecDeque<Notice>,
    unknown: UnknownIds,
    signing: Signing,
    /// Frames kept for recording, when the router records.
    tap: Option<Tap>,
    /// The autopilot's flight log, when configured.
    flight_log: Option<FlightLogger>,
}

impl Core {
    /// The parser events of one input at `now` from `sender`, on an interface with
    /// signing settings `edge` in `group`, described as `described` in messages: the
    /// one place an [`Intake`] is built.
    fn intake<'a>(
        &'a mut self,
        now: Timestamp,
        sender: Sender<'a>,
        edge: Option<&'a mut Edge>,
        group: Option<GroupId>,
        described: &'a str,
    ) -> Intake<'a> {
        Intake {
            router: &mut self.router,
            out: &mut self.out,
            notices: &mut self.notices,
            unknown: &mut self.unknown,
            now,
            sender,
            edge,
            signing: &mut self.signing,
            described,
            tap: self.tap.as_mut(),
            group,
            flight_log: self.flight_log.as_mut(),
        }
    }
}

/// The next deadline of interface `i`: its held-back bytes turning stale (while open),
/// the packet its pacer holds back, its next reopen attempt, or the time it closes after
/// a reload removed it.
fn next_deadline(i: &Interface) -> Option<Timestamp> {
    let stale = i
        .is_open()
        .then(|| i.tail.deadline(i.parser.pending_len()))
        .flatten();
    let retry = i.connection().and_then(Connection::retry_at);
    [stale, i.pace_deadline, retry, i.retiring]
        .into_iter()
        .flatten()
        .min()
}

impl Engine {
    /// A core with no interfaces, filtering with `config`'s chains.
    pub fn new(config: &Config, options: RouterOptions) -> Self {
        Engine {
            core: Core {
                router: Router::with_options(config, options),
                out: Output::default(),
                notices: VecDeque::new(),
                unknown: UnknownIds::default(),
                signing: Signing::default(),
                tap: None,
                flight_log: None,
            },
            interfaces: Slab::new(),
            next_tick: Timestamp::ZERO + TICK,
            rules: RuleBook::new(config),
            history: History::default(),
            config: Config {
                interfaces: Vec::new(),
                ..config.clone()
            },
            configured: Vec::new(),
            ready: ready::ReadySet::default(),
            deadlines: ready::Deadlines::default(),
            owner: ready::ByLink::default(),
            due: Vec::new(),
            heartbeat: None,
            flight_log_leftover: Vec::new(),
            direct: None,
        }
    }

    /// The router (links, queues, filter statistics).
    pub fn router(&self) -> &Router {
        &self.core.router
    }

    /// Interface `id`, if it exists.
    pub fn interface(&self, id: InterfaceId) -> Option<&Interface> {
        self.interfaces.get(id.0)
    }

    fn push_interface(&mut self, mut interface: Interface) -> InterfaceId {
        // The messages and checks of the configuration in force (see `set_parsing`).
        interface.parser.set_dialect(self.config.dialect);
        interface.parser.set_checks(self.config.checks());
        let link = interface.own_link();
        let id = InterfaceId(self.interfaces.insert(interface));
        if let Some(link) = link {
            self.owner.insert(link, id);
        }
        self.refresh_deadline(id);
        id
    }

    /// Files interface `id`'s next deadline (after anything that may have moved it:
    /// input, output, a state change); an interface that is gone has none.
    fn refresh_deadline(&mut self, id: InterfaceId) {
        let due = self.interfaces.get(id.0).and_then(next_deadline);
        self.deadlines.set(id, due);
    }

    /// Marks interface `id` as having output to hand out (see [`Engine::poll_ready`]).
    fn mark_ready(&mut self, id: InterfaceId) {
        self.ready.mark(id);
    }

    /// Notes that link `link`, created by the input of interface `id`, belongs to it.
    fn adopt_link(&mut self, link: Option<LinkId>, id: InterfaceId) {
        if let Some(link) = link {
            self.owner.entry(link).or_insert(id);
        }
    }

    /// The next interface with output to hand out, each named once however many
    /// packets it got since it was last named: a packet was queued for one of its links,
    /// its pacer lets a held-back packet go, it opened, or its target became known.
    /// Flush exactly these (and the drivers the operating system says are writable):
    /// an interface never named has nothing to send. Call it after every input,
    /// [`Engine::handle_timeout`] and open or close, until it gives `None`.
    #[inline]
    pub fn poll_ready(&mut self) -> Option<InterfaceId> {
        self.ready.pop()
    }

    /// True if [`Engine::poll_ready`] would name an interface.
    #[inline]
    pub fn has_ready(&self) -> bool {
        !self.ready.is_empty()
    }

    /// The link of stream or client interface `id`.
    pub fn stream_link(&self, id: InterfaceId) -> Option<LinkId> {
        self.interfaces.get(id.0)?.own_link()
    }

    /// True if [`Engine::poll_event`] has something (most turns it has not).
    #[inline]
    pub fn has_notices(&self) -> bool {
        !self.core.notices.is_empty()
    }

    /// The next notice, oldest first.
    #[inline]
    pub fn poll_event(&mut self) -> Option<Notice> {
        self.core.notices.pop_front()
    }
}
