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
//! output:    engine.poll_transmit(ifc, now, room, &mut queue)   then send what it gave;
//!            engine.on_sent(&t) for each sent, engine.on_send_failed(ifc, &t, &e) if not
//! time:      arm one timer for engine.poll_timeout(); when it fires: handle_timeout(now)
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
mod paths;

use std::collections::VecDeque;
use std::fmt::Display;
use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use slab::Slab;

use super::admission;
use super::counters::InterfaceReport;
use super::event::Event;
use super::intake::{Intake, Sender, UnknownIds};
use super::interface::{InterfaceId, Kind, LiveInterface as Interface, Reopen};
use super::link::LinkId;
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
use crate::recording::{RecordFilter, Tap};
use crate::signing::sign;
use crate::signing::state::SavedState;
use crate::signing::{Edge, Signing, SigningKey};
use crate::stats::{History, StatsSnapshot};

pub use configure::{Reconfigured, Request};

/// How often learned addresses are expired and idle datagram links removed.
pub const TICK: Duration = Duration::from_secs(1);

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

/// Something the core tells the event loop: lines for the operator, links that came and
/// went, and streams to open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Notice {
    /// A routing log line, printed at its level (1–3).
    Log(Event),
    /// A datagram peer sent its first valid frame and is now a link.
    LinkAdded {
        /// The new link.
        id: LinkId,
        /// Its name (`a.b.c.d:port`).
        name: String,
    },
    /// A datagram link was removed: its addresses expired.
    LinkRemoved {
        /// The link.
        id: LinkId,
        /// Its name.
        name: String,
    },
    /// A warning for standard error.
    Warning(String),
    /// An error for standard error.
    Error(String),
    /// A message id outside the dialect was seen for the first time.
    UnknownId(u32),
    /// The interface (a stream, or a datagram client) should be opened now; answer with
    /// [`Engine::stream_opened`] or [`Engine::stream_open_failed`].
    Open(InterfaceId),
    /// The accepted connection was removed (it closed): drop its driver.
    Closed(InterfaceId),
}

/// The sans-IO routing core: interfaces, links, the router, timers and counters.
#[derive(Debug)]
pub struct Engine {
    router: Router,
    interfaces: Slab<Interface>,
    out: Output,
    notices: VecDeque<Notice>,
    unknown: UnknownIds,
    next_tick: Timestamp,
    signing: Signing,
    /// Frames kept for recording, when the router records.
    tap: Option<Tap>,
    rules: RuleBook,
    history: History,
    /// The configuration in force: its interfaces are those [`Engine::configure`] added.
    config: Config,
    /// The core's interface and the signing key of each of `config.interfaces`.
    configured: Vec<configure::Configured>,
    /// The router's own heartbeat, when configured.
    heartbeat: Option<OwnHeartbeat>,
}

impl Engine {
    /// A core with no interfaces, filtering with `config`'s chains.
    pub fn new(config: &Config, options: RouterOptions) -> Self {
        Engine {
            router: Router::with_options(config, options),
            interfaces: Slab::new(),
            out: Output::default(),
            notices: VecDeque::new(),
            unknown: UnknownIds::default(),
            next_tick: Timestamp::ZERO + TICK,
            signing: Signing::default(),
            tap: None,
            rules: RuleBook::new(config),
            history: History::default(),
            config: Config {
                interfaces: Vec::new(),
                ..config.clone()
            },
            configured: Vec::new(),
            heartbeat: None,
        }
    }

    /// The router (links, queues, filter statistics).
    pub fn router(&self) -> &Router {
        &self.router
    }

    /// Interface `id`, if it exists.
    pub fn interface(&self, id: InterfaceId) -> Option<&Interface> {
        self.interfaces.get(id.0)
    }

    /// Adds a datagram server (a UDP socket) named `label`: any number of peers, each a
    /// link from its first valid frame, within `limits`; sending at most `max_bitrate`
    /// bit/s (0: no limit).
    pub fn add_datagram_interface(
        &mut self,
        label: String,
        max_bitrate: u64,
        limits: PeerLimits,
    ) -> InterfaceId {
        self.push_interface(Interface::network(
            label,
            max_bitrate,
            Kind::Datagram {
                remotes: Remotes::default(),
                last_sender: None,
                limits,
            },
        ))
    }

    /// Adds a datagram client named `label` whose one link is `link_name`: it sends to
    /// its target from the start (once [`Engine::set_target`] names it), and whatever
    /// its socket receives is that link's. Opened like a stream ([`Notice::Open`]).
    pub fn add_datagram_client(
        &mut self,
        label: String,
        link_name: &str,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self.router.add_client_link(link_name, now);
        self.push_interface(Interface::network(
            label,
            max_bitrate,
            Kind::DatagramClient {
                link,
                target: None,
                last_sender: None,
                connection: Connection::new(now),
            },
        ))
    }

    /// Sets where datagram client `id` sends (its resolved target).
    pub fn set_target(&mut self, id: InterfaceId, target: SocketAddr) {
        if let Some(Interface {
            kind: Kind::DatagramClient { target: t, .. },
            ..
        }) = self.interfaces.get_mut(id.0)
        {
            *t = Some(target);
        }
    }

    /// Adds a byte-stream interface that is one link named `device` (a serial port at
    /// `baudrate`), reaching `preload` permanently. The core asks for it to be opened
    /// ([`Notice::Open`]) at the first [`Engine::handle_timeout`], and again with a
    /// backoff whenever it is missing or lost.
    pub fn add_stream_interface(
        &mut self,
        device: &str,
        preload: &[Address],
        baudrate: Option<u32>,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self
            .router
            .add_serial_link(device, preload, now, &mut self.out);
        self.take_output();
        self.push_interface(Interface::new(
            device.to_string(),
            format!("serial device {device}"),
            StaleTail::new(baudrate),
            max_bitrate,
            Kind::stream(link, Connection::new(now), None, Reopen::DEVICE),
        ))
    }

    /// Adds a stream client (a TCP client) named `label` whose one link is `link_name`:
    /// opened at once, reconnected at once after a loss and then with a backoff capped
    /// at one second, forever; what was queued while it was down longer than
    /// [`FORGET_AFTER`] is dropped when it comes back.
    pub fn add_stream_client(
        &mut self,
        label: String,
        link_name: &str,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self.router.add_client_link(link_name, now);
        self.push_interface(Interface::reliable_stream(
            label,
            max_bitrate,
            Kind::stream(
                link,
                Connection::new(now),
                None,
                Reopen::client(FORGET_AFTER),
            ),
        ))
    }

    /// Adds a stream server (a TCP listener) named `label`, taking connections within
    /// `limits` ([`Engine::accept`]); each sends at most `max_bitrate` bit/s (0: no
    /// limit).
    pub fn add_listener(
        &mut self,
        label: String,
        limits: PeerLimits,
        max_bitrate: u64,
    ) -> InterfaceId {
        self.push_interface(Interface::reliable_stream(
            label,
            0,
            Kind::Listener {
                limits,
                connections: 0,
                max_bitrate,
            },
        ))
    }

    /// A connection from `peer` arrived at server `listener`: returns its new stream
    /// interface (one link, named `tcp:a.b.c.d:port`, paced at the server's
    /// `max_bitrate`), or None if the server's limits refuse it (counted; said once per
    /// reason). Close a refused connection at once.
    pub fn accept(
        &mut self,
        listener: InterfaceId,
        peer: SocketAddr,
        now: Timestamp,
    ) -> Option<InterfaceId> {
        let server = self.interfaces.get_mut(listener.0)?;
        let Kind::Listener {
            limits,
            connections,
            max_bitrate,
        } = &mut server.kind
        else {
            return None;
        };
        if let Err(why) = admission::admit(limits, *connections, peer.ip()) {
            if server.refused.count(why) {
                let text = admission::refusal_text(&server.described, why, peer.ip(), limits);
                self.notices.push_back(Notice::Warning(text));
            }
            return None;
        }
        *connections += 1;
        let max_bitrate = *max_bitrate;
        let edge = server.signing.as_ref().map(Edge::fresh_copy);
        let group = server.group;
        let name = format!("tcp:{peer}");
        let link = self.router.add_connection_link(&name, now);
        self.router.set_group(link, group);
        self.notices.push_back(Notice::LinkAdded {
            id: link,
            name: name.clone(),
        });
        let mut connection = Interface::reliable_stream(
            name,
            max_bitrate,
            Kind::stream(link, Connection::Open, Some(listener), Reopen::ACCEPTED),
        );
        connection.signing = edge;
        connection.group = group;
        Some(self.push_interface(connection))
    }

    /// Gives interface `id` a signing key: signed frames arriving there are checked
    /// with it (and unsigned ones dropped unless `allow_unsigned`), and unsigned
    /// MAVLink 2 frames leaving there are signed with it and `link_id`. A server's
    /// connections take its key.
    pub fn set_signing(
        &mut self,
        id: InterfaceId,
        key: SigningKey,
        allow_unsigned: bool,
        link_id: u8,
    ) {
        let key_slot = self.signing.add_key(key);
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.signing = Some(Edge {
                key_slot,
                allow_unsigned,
                link_id,
                counters: Default::default(),
                said: Vec::new(),
            });
        }
    }

    /// Starts recording: from now on every frame taken in (after the signing check of
    /// its interface) that `filter` passes is kept, with its time of arrival, until
    /// [`Engine::poll_recorded`] takes it. Take them every loop turn: what does not fit
    /// in a bounded buffer is dropped and counted ([`Engine::recording_dropped`]).
    pub fn set_recording(&mut self, filter: RecordFilter) {
        self.tap = Some(Tap::new(filter));
    }

    /// Stops recording (a reload removed or changed the `record` block): frames kept
    /// and not yet taken are dropped.
    pub fn stop_recording(&mut self) {
        self.tap = None;
    }

    /// Hands each frame kept for recording to `take` with its time of arrival, oldest
    /// first (arrival order), and forgets them.
    #[inline]
    pub fn poll_recorded(&mut self, take: &mut impl FnMut(Timestamp, &[u8])) {
        if let Some(tap) = self.tap.as_mut().filter(|t| !t.is_empty()) {
            tap.drain(take);
        }
    }

    /// Frames not kept for recording because the buffer was full.
    pub fn recording_dropped(&self) -> u64 {
        self.tap.as_ref().map_or(0, Tap::dropped)
    }

    /// Notes the wall clock for signing: at `now` it read `units` (MAVLink signature
    /// time, 10 µs units since 2015-01-01 UTC). Call it at start and about once a second.
    pub fn set_wall_clock(&mut self, now: Timestamp, units: u64) {
        self.signing.set_wall_clock(now, units);
    }

    /// True when some interface has a signing key (so there is signing state to keep).
    pub fn has_signing_keys(&self) -> bool {
        self.signing.has_keys()
    }

    /// Takes over signing state saved by an earlier run (after every
    /// [`Engine::set_signing`]); returns how many streams it knew.
    pub fn restore_signing_state(&mut self, state: &SavedState) -> usize {
        self.signing.restore(state)
    }

    /// The signing state to save, if it changed since the last call (always when
    /// `clean`: the router is stopping).
    pub fn signing_state(&mut self, clean: bool) -> Option<SavedState> {
        self.signing.take_state(clean)
    }

    fn push_interface(&mut self, mut interface: Interface) -> InterfaceId {
        // The messages and checks of the configuration in force (see `set_parsing`).
        interface.parser.set_dialect(self.config.dialect);
        interface.parser.set_checks(self.config.checks());
        InterfaceId(self.interfaces.insert(interface))
    }

    /// The link of stream or client interface `id`.
    pub fn stream_link(&self, id: InterfaceId) -> Option<LinkId> {
        self.interfaces.get(id.0)?.own_link()
    }

    /// Routes the frames of a datagram from `peer` on interface `id`. A frame may
    /// continue in the same peer's next datagram; a datagram from another peer drops it.
    /// On a server, a peer without a link yet must pass the interface's limits.
    pub fn handle_datagram(
        &mut self,
        id: InterfaceId,
        peer: SocketAddr,
        bytes: &[u8],
        now: Timestamp,
    ) {
        let Some(Interface {
            parser,
            tail,
            kind,
            refused,
            described,
            signing: edge,
            group,
            ..
        }) = self.interfaces.get_mut(id.0)
        else {
            return;
        };
        let sender = match kind {
            Kind::Datagram {
                remotes,
                last_sender,
                limits,
            } => {
                let link = remotes.link_of(peer);
                if link.is_none()
                    && let Err(why) = admission::admit(limits, remotes.len(), peer.ip())
                {
                    if refused.count(why) {
                        let text = admission::refusal_text(described, why, peer.ip(), limits);
                        self.notices.push_back(Notice::Warning(text));
                    }
                    return;
                }
                if *last_sender != Some(peer) {
                    parser.clear();
                    *last_sender = Some(peer);
                }
                Sender::Remote {
                    remotes,
                    address: peer,
                    link,
                }
            }
            Kind::DatagramClient {
                link,
                last_sender,
                connection,
                ..
            } => {
                if !connection.is_open() {
                    return;
                }
                if *last_sender != Some(peer) {
                    parser.clear();
                    *last_sender = Some(peer);
                }
                Sender::Stream(*link)
            }
            Kind::Stream { .. } | Kind::Listener { .. } => return,
        };
        let mut intake = Intake {
            router: &mut self.router,
            out: &mut self.out,
            notices: &mut self.notices,
            unknown: &mut self.unknown,
            now,
            sender,
            edge: edge.as_mut(),
            signing: &mut self.signing,
            described,
            tap: self.tap.as_mut(),
            group: *group,
        };
        parser.feed_events(bytes, &mut intake);
        tail.received(now);
        self.take_output();
    }

    /// Routes the frames completed by `bytes`, read from stream interface `id`.
    pub fn handle_stream(&mut self, id: InterfaceId, bytes: &[u8], now: Timestamp) {
        let Some(Interface {
            parser,
            tail,
            kind,
            signing: edge,
            described,
            group,
            ..
        }) = self.interfaces.get_mut(id.0)
        else {
            return;
        };
        let Kind::Stream {
            link, connection, ..
        } = *kind
        else {
            return;
        };
        if !connection.is_open() {
            return;
        }
        let mut intake = Intake {
            router: &mut self.router,
            out: &mut self.out,
            notices: &mut self.notices,
            unknown: &mut self.unknown,
            now,
            sender: Sender::Stream(link),
            edge: edge.as_mut(),
            signing: &mut self.signing,
            described,
            tap: self.tap.as_mut(),
            group: *group,
        };
        parser.feed_events(bytes, &mut intake);
        tail.received(now);
        self.take_output();
    }

    /// Moves the router's events into the notices and readies its output for reuse.
    fn take_output(&mut self) {
        if !self.out.events.is_empty() {
            self.notices
                .extend(self.out.events.drain(..).map(Notice::Log));
        }
        self.out.clear();
    }

    /// Appends to `queue` up to `room` packets interface `id` may send at `now`: highest
    /// priority first on each link; between the peers of a datagram interface in turns
    /// (runs of up to [`SEND_TURN`] packets without `max_bitrate`, one packet with it);
    /// never faster than `max_bitrate`. When the pacer holds a packet back, the time it
    /// may go is part of [`Engine::poll_timeout`].
    pub fn poll_transmit(
        &mut self,
        id: InterfaceId,
        now: Timestamp,
        room: usize,
        queue: &mut VecDeque<Transmit>,
    ) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        if room == 0 {
            return;
        }
        let Interface {
            pacer,
            pace_deadline,
            kind,
            signing: edge,
            ..
        } = interface;
        *pace_deadline = None;
        let unpaced = pacer.rate() == 0;
        let router = &mut self.router;
        let signing = &mut self.signing;
        let mut left = room;
        // Takes the next packet of `link` if the pacer lets it go now, signed if the
        // interface has a key.
        let mut take = |router: &mut Router, link: LinkId| -> Result<Option<Packet>, Timestamp> {
            let Some(len) = router.peek(link).map(|p| match edge {
                Some(_) => sign::signed_len(p),
                None => p.len(),
            }) else {
                return Ok(None);
            };
            if let Pace::At(t) = pacer.check(now, len) {
                return Err(t);
            }
            pacer.sent(now, len);
            let packet = router.pop(link);
            let Some(edge) = edge.as_mut() else {
                return Ok(packet);
            };
            let signed = packet.as_deref().and_then(|p| signing.sign(edge, p, now));
            let Some(signed) = signed else {
                return Ok(packet);
            };
            edge.counters.signed_out += 1;
            if let Some(c) = router.counters_mut(link) {
                c.signing.signed_out += 1;
            }
            Ok(Some(signed))
        };
        match kind {
            Kind::Datagram { remotes, .. } => {
                let turn_len = if unpaced { SEND_TURN } else { 1 };
                'turns: while left > 0 {
                    let Some(turn) = remotes.next_ready(|l| router.peek(l).is_some()) else {
                        break;
                    };
                    let mut sent = 0;
                    while sent < turn_len && left > 0 {
                        match take(router, turn.link) {
                            Ok(Some(packet)) => {
                                queue.push_back(Transmit {
                                    link: turn.link,
                                    to: Some(turn.address),
                                    packet,
                                });
                                sent += 1;
                                left -= 1;
                            }
                            Ok(None) => break,
                            Err(t) => {
                                *pace_deadline = Some(t);
                                if sent > 0 {
                                    remotes.end_turn(&turn);
                                }
                                break 'turns;
                            }
                        }
                    }
                    remotes.end_turn(&turn);
                }
            }
            Kind::Stream {
                link, connection, ..
            } if connection.is_open() => {
                Self::drain_link(&mut take, router, *link, None, left, queue, pace_deadline);
            }
            Kind::DatagramClient {
                link,
                connection,
                target: Some(to),
                ..
            } if connection.is_open() => {
                let to = Some(*to);
                Self::drain_link(&mut take, router, *link, to, left, queue, pace_deadline);
            }
            Kind::Stream { .. } | Kind::DatagramClient { .. } | Kind::Listener { .. } => {}
        }
    }

    /// Hands out up to `left` packets of `link` (going `to`) as far as `take` lets them.
    fn drain_link(
        take: &mut impl FnMut(&mut Router, LinkId) -> Result<Option<Packet>, Timestamp>,
        router: &mut Router,
        link: LinkId,
        to: Option<SocketAddr>,
        mut left: usize,
        queue: &mut VecDeque<Transmit>,
        pace_deadline: &mut Option<Timestamp>,
    ) {
        while left > 0 {
            match take(router, link) {
                Ok(Some(packet)) => {
                    queue.push_back(Transmit { link, to, packet });
                    left -= 1;
                }
                Ok(None) => break,
                Err(t) => {
                    *pace_deadline = Some(t);
                    break;
                }
            }
        }
    }

    /// Notes that `t` was sent.
    #[inline]
    pub fn on_sent(&mut self, t: &Transmit) {
        if let Some(c) = self.router.counters_mut(t.link) {
            c.sent(t.packet.len());
        }
    }

    /// Notes that `t` could not be sent on interface `id` (it is dropped). A datagram
    /// peer's first failure is reported; later ones are only counted, so a dead route
    /// cannot flood the log.
    pub fn on_send_failed(&mut self, id: InterfaceId, t: &Transmit, error: &io::Error) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        interface.io_errors += 1;
        let Some(c) = self.router.counters_mut(t.link) else {
            return;
        };
        c.send_errors += 1;
        if c.send_errors == 1
            && let Some(to) = t.to
        {
            self.notices.push_back(Notice::Error(format!(
                "{}: sending to {to} failed: {error} (further failures are only counted)",
                interface.described
            )));
        }
    }

    /// Notes that receiving on interface `id` failed (other than "would block").
    pub fn on_receive_failed(&mut self, id: InterfaceId, error: &io::Error) {
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.io_errors += 1;
            self.notices.push_back(Notice::Error(format!(
                "{}: receive failed: {error}",
                interface.described
            )));
        }
    }

    /// Interface `id` (a stream or a datagram client) was opened at `now`. What was
    /// queued for a client that stayed down too long is dropped now (stale telemetry is
    /// not replayed).
    pub fn stream_opened(&mut self, id: InterfaceId, now: Timestamp) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        let link = interface.own_link();
        let Some(connection) = interface.connection_mut() else {
            return;
        };
        *connection = Connection::Open;
        interface.parser.clear();
        if let Kind::Stream { reopen, .. } = &mut interface.kind
            && let Some(since) = reopen.down_since.take()
            && reopen
                .forget_after
                .is_some_and(|limit| now.saturating_since(since) > limit)
            && let Some(link) = link
        {
            self.router.clear_queue(link);
        }
        if interface.io_errors > 0 {
            self.notices
                .push_back(Notice::Warning(format!("{} is back", interface.described)));
        }
    }

    /// Opening interface `id` failed at `now`: it is tried again after a backoff (said
    /// once per outage, not once per attempt).
    pub fn stream_open_failed(&mut self, id: InterfaceId, now: Timestamp, error: &dyn Display) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        let cap = match &interface.kind {
            Kind::Stream { reopen, .. } => reopen.max_wait,
            _ => MAX_BACKOFF,
        };
        if let Some(connection) = interface.connection_mut()
            && connection.failed(now, cap)
        {
            interface.io_errors += 1;
            self.notices.push_back(Notice::Warning(format!(
                "cannot open {}: {error}; retrying until it appears",
                interface.described
            )));
        }
    }

    /// Stream `id` was lost at `now` (unplugged, closed by the peer, a read or write
    /// error): held-back bytes are dropped; a configured stream is opened again after
    /// its first wait, an accepted connection is removed with its link.
    pub fn stream_lost(&mut self, id: InterfaceId, now: Timestamp, why: &dyn Display) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        interface.parser.clear();
        match &mut interface.kind {
            Kind::Stream {
                accepted_by: Some(server),
                link,
                ..
            } => {
                let (server, link) = (*server, *link);
                self.close_connection(id, server, link);
            }
            Kind::Stream {
                connection, reopen, ..
            } => {
                connection.lost(now, reopen.first_wait);
                reopen.down_since = Some(now);
                interface.io_errors += 1;
                self.notices.push_back(Notice::Warning(format!(
                    "{} lost: {why}",
                    interface.described
                )));
            }
            Kind::DatagramClient { connection, .. } => {
                connection.lost(now, FIRST_BACKOFF);
                interface.io_errors += 1;
                self.notices.push_back(Notice::Warning(format!(
                    "{} lost: {why}",
                    interface.described
                )));
            }
            Kind::Datagram { .. } | Kind::Listener { .. } => {}
        }
    }

    /// Removes accepted connection `id` of `server` and its link.
    fn close_connection(&mut self, id: InterfaceId, server: InterfaceId, link: LinkId) {
        let Some(closed) = self.interfaces.try_remove(id.0) else {
            return;
        };
        self.router.remove_link(link);
        if let Some(server) = self.interfaces.get_mut(server.0) {
            server.closed_parsers += *closed.parser.stats();
            server.io_errors += closed.io_errors;
            if let (Some(total), Some(edge)) = (server.signing.as_mut(), &closed.signing) {
                total.counters += edge.counters;
            }
            if let Kind::Listener { connections, .. } = &mut server.kind {
                *connections = connections.saturating_sub(1);
            }
        }
        self.notices.push_back(Notice::LinkRemoved {
            id: link,
            name: closed.label,
        });
        self.notices.push_back(Notice::Closed(id));
    }

    /// The next instant something is due: the expiry tick, held-back bytes turning
    /// stale, a packet the pacer holds back, or opening an interface again.
    pub fn poll_timeout(&self) -> Timestamp {
        let mut due = self.next_tick;
        for (_, i) in &self.interfaces {
            let stale = i
                .is_open()
                .then(|| i.tail.deadline(i.parser.pending_len()))
                .flatten();
            let retry = i.connection().and_then(Connection::retry_at);
            for t in [stale, i.pace_deadline, retry].into_iter().flatten() {
                due = due.min(t);
            }
        }
        if let Some(h) = &self.heartbeat {
            due = due.min(h.due());
        }
        due
    }

    /// Runs what is due at `now` (see [`Engine::poll_timeout`]).
    pub fn handle_timeout(&mut self, now: Timestamp) {
        for (index, interface) in self.interfaces.iter_mut() {
            if interface.pace_deadline.is_some_and(|t| t <= now) {
                // The caller polls for transmits next; the pacer decides afresh then.
                interface.pace_deadline = None;
            }
            let open = interface.is_open();
            if let Some(connection) = interface.connection_mut()
                && connection.ask_if_due(now)
            {
                self.notices.push_back(Notice::Open(InterfaceId(index)));
            }
            let Interface {
                parser,
                tail,
                kind,
                signing: edge,
                described,
                group,
                ..
            } = interface;
            let stale = open
                && tail
                    .deadline(parser.pending_len())
                    .is_some_and(|t| t <= now);
            if !stale {
                continue;
            }
            let sender = match kind {
                Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => {
                    Some(Sender::Stream(*link))
                }
                Kind::Datagram {
                    remotes,
                    last_sender,
                    ..
                } => last_sender.map(|address| Sender::Remote {
                    link: remotes.link_of(address),
                    remotes,
                    address,
                }),
                Kind::Listener { .. } => None,
            };
            if let Some(sender) = sender {
                // The candidate is rejected and the bytes behind its start scanned again,
                // so valid frames held up behind noise are routed now.
                parser.finish(&mut Intake {
                    router: &mut self.router,
                    out: &mut self.out,
                    notices: &mut self.notices,
                    unknown: &mut self.unknown,
                    now,
                    sender,
                    edge: edge.as_mut(),
                    signing: &mut self.signing,
                    described,
                    tap: self.tap.as_mut(),
                    group: *group,
                });
            }
        }
        self.send_heartbeat(now);
        if now >= self.next_tick {
            for id in self.router.tick(now) {
                self.forget(id);
            }
            self.next_tick = now + TICK;
        }
        self.take_output();
    }

    /// Forgets the peer of a link the router removed.
    fn forget(&mut self, id: LinkId) {
        for (_, interface) in &mut self.interfaces {
            if let Kind::Datagram { remotes, .. } = &mut interface.kind
                && let Some(address) = remotes.remove(id)
            {
                self.notices.push_back(Notice::LinkRemoved {
                    id,
                    name: address.to_string(),
                });
                return;
            }
        }
    }

    /// The next notice, oldest first.
    #[inline]
    pub fn poll_event(&mut self) -> Option<Notice> {
        self.notices.pop_front()
    }

    /// True if interface `id` has nothing queued that it could send (a closed stream
    /// can send nothing).
    pub fn is_idle(&self, id: InterfaceId) -> bool {
        let Some(interface) = self.interfaces.get(id.0) else {
            return true;
        };
        match &interface.kind {
            Kind::Datagram { remotes, .. } => {
                remotes.iter().all(|(l, _)| self.router.peek(l).is_none())
            }
            Kind::Stream { .. } | Kind::DatagramClient { .. } => {
                !interface.is_open()
                    || interface
                        .own_link()
                        .is_none_or(|l| self.router.peek(l).is_none())
            }
            Kind::Listener { .. } => true,
        }
    }

    /// Every counter at `now`, with the rates since the previous call (take one about
    /// once a second: each call is a sample of the rate history).
    pub fn stats(&mut self, now: Timestamp) -> StatsSnapshot {
        snapshot::snapshot(
            snapshot::Sources {
                router: &mut self.router,
                interfaces: &self.interfaces,
                rules: &self.rules,
                history: &mut self.history,
            },
            now,
        )
    }

    /// The counters of every link (in creation order) and every interface, one line
    /// each, under a `mavtables counters:` heading.
    pub fn report(&self) -> String {
        let mut text = String::from("mavtables counters:\n");
        for link in self.router.links() {
            text.push_str(&format!("  {}\n", link.report()));
        }
        for (_, i) in &self.interfaces {
            let mut parser = *i.parser.stats();
            parser += i.closed_parsers;
            let line = InterfaceReport {
                label: &i.label,
                parser: &parser,
                io_errors: i.io_errors,
                refused: i.refused,
                signing: i.signing.as_ref().map(|e| e.counters),
            };
            text.push_str(&format!("  {line}\n"));
        }
        text
    }
}
