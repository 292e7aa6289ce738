//! The core takes a configuration: at start (from none) and at every reload, in one
//! call between two wake-ups. What to keep, change, close and open is decided here
//! ([`super::super::reload`] compares); the event loop gets the sockets to close and the
//! interfaces to open ([`Request`]) and moves nothing else.

use std::fmt;

use super::{Engine, Notice};
use crate::config::{Config, Interface, PeerLimits};
use crate::filter::FilterCounts;
use crate::routing::interface::{InterfaceId, Kind, LiveInterface, pacer_for};
use crate::routing::reload::{self, Fate, InPlace, Keyed, RulePlan};
use crate::routing::snapshot::RuleBook;
use crate::routing::{LinkId, RouterOptions, Timestamp};
use crate::signing::{Edge, SigningKey};

/// The core's interface for one block of the configuration in force, and its key.
#[derive(Debug, Clone)]
pub(super) struct Configured {
    id: InterfaceId,
    key: Option<SigningKey>,
}

impl Configured {
    /// The core's interface of the block.
    pub(super) fn id(&self) -> InterfaceId {
        self.id
    }
}

/// What the event loop must do after [`Engine::configure`], in the order given (every
/// close and retire comes before every open: a port or device may move from an old block
/// to a new one, and an interface number may be used again). A retiring driver still
/// holds its port: if an open finds it taken, close the retiring one that holds it
/// ([`Engine::close_retiring`]) and try again.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// Close the driver of this interface (the core has forgotten it).
    Close(InterfaceId),
    /// Go on flushing the driver of this interface, which left routing: it sends what
    /// was queued for it (its links take no new packets, and what it reads is dropped),
    /// for at most [`CLOSE_FLUSH`].
    /// Close it when the core says so ([`Notice::Closed`]): once
    /// [`Engine::close_if_drained`], asked whenever its driver has nothing in flight,
    /// finds nothing left, or when the time is up.
    ///
    /// [`CLOSE_FLUSH`]: super::CLOSE_FLUSH
    Retire(InterfaceId),
    /// Make a driver for this new interface from its block. Servers bind at once;
    /// clients and serial ports are opened when the core asks ([`Notice::Open`]). If it
    /// cannot be made, tell the core with [`Engine::unconfigure`].
    Open(InterfaceId, Interface),
}

/// What [`Engine::configure`] did, and what is left to the event loop.
#[derive(Debug, Clone, Default)]
pub struct Reconfigured {
    /// Sockets to close and interfaces to open, in this order.
    pub requests: Vec<Request>,
    /// One line per interface that was added, removed, changed in place or reopened.
    pub details: Vec<String>,
    /// Rules of the new configuration.
    pub rules: usize,
    /// Rules the old configuration did not have (by text, in the same chain).
    pub rules_changed: usize,
    /// Rules of the old configuration the new one does not have.
    pub rules_removed: usize,
    /// The default action changed.
    pub default_changed: bool,
    /// Interfaces added, removed, and changed (in place or reopened).
    pub added: usize,
    /// Interfaces removed.
    pub removed: usize,
    /// Interfaces changed in place or reopened.
    pub changed: usize,
    /// Interfaces to be opened whose driver could not be made (see
    /// [`Reconfigured::open_failed`]).
    pub not_opened: usize,
    /// Other settings that changed, by name: `queue`, `dedup`, `group`, `heartbeat`,
    /// `stats`, `record`, `flight_log`, `signing_state`.
    pub settings_changed: Vec<&'static str>,
    /// The interfaces to be opened: each with its label, its detail line (index into
    /// `details`) and whether it is new (else reopened).
    opening: Vec<Opening>,
    /// Frames that were queued for links of closed interfaces (dropped and counted here,
    /// not sent).
    pub dropped: u64,
    /// The messages known (`dialect`) or the `unknown_messages` policy changed: every
    /// parser uses the new ones from its next frame on.
    pub dialect_changed: bool,
    /// The `record` block changed: the recording is to be restarted (or stopped).
    pub record_changed: bool,
    /// The `stats` block changed: the endpoint is to be restarted (or stopped).
    pub stats_changed: bool,
    /// Where the signing state is kept changed (or whether there is any).
    pub signing_state_changed: bool,
    /// Fingerprints of keys no interface had before: the saved signing state may know
    /// their streams.
    pub new_keys: Vec<[u8; 8]>,
}

impl fmt::Display for Reconfigured {
    /// `12 rules (3 changed), +1 interface, -0, 1 changed`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = |n: usize| if n == 1 { "" } else { "s" };
        write!(
            f,
            "{} rule{} ({} changed",
            self.rules,
            s(self.rules),
            self.rules_changed
        )?;
        if self.rules_removed > 0 {
            write!(f, ", {} removed", self.rules_removed)?;
        }
        write!(
            f,
            "), +{} interface{}, -{}, {} changed",
            self.added,
            s(self.added),
            self.removed,
            self.changed
        )?;
        if self.not_opened > 0 {
            write!(f, ", {} not opened", self.not_opened)?;
        }
        if self.default_changed {
            write!(f, ", default_action changed")?;
        }
        if self.dialect_changed {
            write!(f, ", dialect changed")?;
        }
        for name in &self.settings_changed {
            write!(f, ", {name} changed")?;
        }
        if self.dropped > 0 {
            write!(f, ", {} queued frames dropped", self.dropped)?;
        }
        Ok(())
    }
}

/// An interface [`Engine::configure`] asks the loop to open, as [`Reconfigured`] keeps it.
#[derive(Debug, Clone)]
struct Opening {
    id: InterfaceId,
    label: String,
    line: usize,
    added: bool,
}

impl Reconfigured {
    /// Notes that the driver of interface `id`, which [`Request::Open`] asked for, could
    /// not be made (`why`): it is no longer counted as added or changed, and its detail
    /// line says so.
    pub fn open_failed(&mut self, id: InterfaceId, why: &str) {
        let Some(opening) = self.opening.iter().find(|o| o.id == id) else {
            return;
        };
        if opening.added {
            self.added = self.added.saturating_sub(1);
        } else {
            self.changed = self.changed.saturating_sub(1);
        }
        self.not_opened += 1;
        if let Some(detail) = self.details.get_mut(opening.line) {
            *detail = format!("{} not opened: {why}", opening.label);
        }
    }
}

impl Engine {
    /// Runs `config` from now on, with `keys` (the key of each of its interfaces, in
    /// order), keeping all that did not change:
    /// - the filter (chains, priorities, default action) is replaced at once when it
    ///   changed, with an empty verdict memo; the counts of rules that read the same go
    ///   on;
    /// - interfaces are matched by identity (`reload::plan_interfaces`): an unchanged
    ///   one keeps its links, queues, learned addresses, connections, signing streams and
    ///   counters; `max_bitrate`, the signing settings and the server limits change in
    ///   place; a removed or reopened one leaves routing with its links at once, and is
    ///   closed once what was queued for it was sent, within [`CLOSE_FLUSH`]
    ///   ([`Request::Retire`]; a stream that is down, and a server socket, close at once,
    ///   and what could not be sent is dropped and counted);
    ///
    /// [`CLOSE_FLUSH`]: super::CLOSE_FLUSH
    /// - new queue bounds apply to every queue at once.
    ///
    /// At start, call it once after [`Engine::new`] with the same configuration.
    pub fn configure(
        &mut self,
        config: &Config,
        keys: &[Option<SigningKey>],
        now: Timestamp,
    ) -> Reconfigured {
        self.settle_direct();
        let key_of = |i: usize| keys.get(i).and_then(Option::as_ref);
        let parsing_changed = self.set_parsing(config);
        let rules = reload::plan_rules(&self.config, config);
        let plan = {
            let old: Vec<Keyed<'_>> = self
                .config
                .interfaces
                .iter()
                .zip(&self.configured)
                .map(|(i, c)| (i, c.key.as_ref()))
                .collect();
            let new: Vec<Keyed<'_>> = (config.interfaces.iter().enumerate())
                .map(|(n, i)| (i, key_of(n)))
                .collect();
            reload::plan_interfaces(&old, &new)
        };
        let record_changed = self.config.record != config.record;
        let stats_changed = self.config.stats != config.stats;
        let signing_state_changed =
            self.config.signing_state_path(|_| None) != config.signing_state_path(|_| None);
        let mut done = Reconfigured {
            dialect_changed: parsing_changed,
            rules: rules.total,
            rules_changed: rules.changed,
            rules_removed: rules.removed,
            default_changed: !rules.default_carried,
            record_changed,
            stats_changed,
            signing_state_changed,
            settings_changed: [
                ("queue", self.config.queue != config.queue),
                ("dedup", self.config.dedup != config.dedup),
                ("group", self.config.groups != config.groups),
                ("heartbeat", self.config.heartbeat != config.heartbeat),
                ("stats", stats_changed),
                ("record", record_changed),
                ("flight_log", self.config.flight_log != config.flight_log),
                ("signing_state", signing_state_changed),
            ]
            .into_iter()
            .filter_map(|(name, changed)| changed.then_some(name))
            .collect(),
            ..Reconfigured::default()
        };
        // A changed dialect may give a message name another id: the filter is rebuilt.
        if !rules.unchanged || parsing_changed {
            let counts = carried_counts(&self.core.router.filter_counts(), &rules);
            self.core.router.replace_filter(config, &counts);
            self.rules = RuleBook::new(config);
        }
        if self.config.queue != config.queue {
            let d = RouterOptions::default();
            self.core.router.set_queue_bounds(
                config.queue.link_bytes.unwrap_or(d.queue_capacity),
                config.queue.total_bytes.unwrap_or(d.total_queue_capacity),
            );
        }
        let mut ids: Vec<Option<InterfaceId>> = vec![None; config.interfaces.len()];
        for &o in &plan.removed {
            let id = self.configured[o].id;
            let label = self.describe(id);
            let (dropped, sending) = self.retire_interface(id, now, &mut done.requests);
            done.details
                .push(format!("{label} removed{}", closing_text(dropped, sending)));
            done.dropped += dropped;
            done.removed += 1;
        }
        let mut to_open = plan.added.clone();
        // Reopened interfaces by their block's number, with their detail line.
        let mut reopened: Vec<(usize, usize, String)> = Vec::new();
        for m in &plan.matched {
            let id = self.configured[m.old].id;
            match &m.fate {
                Fate::Kept => ids[m.new] = Some(id),
                Fate::Changed(what) => {
                    let iface = &config.interfaces[m.new];
                    self.change_in_place(id, iface, key_of(m.new), m.new, what);
                    let names: Vec<&str> = what.iter().map(|w| w.name()).collect();
                    let label = self.describe(id);
                    done.details
                        .push(format!("{label} changed in place: {}", names.join(", ")));
                    done.changed += 1;
                    ids[m.new] = Some(id);
                }
                Fate::Reopened => {
                    let label = self.describe(id);
                    // A serial port is reopened on the same device, whose new settings
                    // would garble what the old handle still wrote: it closes at once.
                    let (dropped, sending) = match config.interfaces[m.new] {
                        Interface::Serial(_) => (self.forget_interface(id, &mut done.requests), 0),
                        _ => self.retire_interface(id, now, &mut done.requests),
                    };
                    reopened.push((m.new, done.details.len(), label.clone()));
                    done.details.push(format!(
                        "{label} reopened: a setting of its socket or device changed{}",
                        closing_text(dropped, sending)
                    ));
                    done.dropped += dropped;
                    done.changed += 1;
                    to_open.push(m.new);
                }
            }
        }
        // Serial links first, then the others, each in file order (the order links
        // are offered packets at start).
        to_open.sort_by_key(|&n| (!matches!(config.interfaces[n], Interface::Serial(_)), n));
        for n in to_open {
            let iface = &config.interfaces[n];
            let id = self.add_configured(iface, key_of(n), n, now);
            if plan.added.contains(&n) {
                let label = self.describe(id);
                done.opening.push(Opening {
                    id,
                    line: done.details.len(),
                    label: label.clone(),
                    added: true,
                });
                done.details.push(format!("{label} added"));
                done.added += 1;
            } else if let Some((_, line, label)) = reopened.iter().find(|(of, ..)| *of == n) {
                done.opening.push(Opening {
                    id,
                    line: *line,
                    label: label.clone(),
                    added: false,
                });
            }
            done.requests.push(Request::Open(id, iface.clone()));
            ids[n] = Some(id);
        }
        let had = |k: &SigningKey| self.configured.iter().any(|c| c.key.as_ref() == Some(k));
        let mut new_keys: Vec<[u8; 8]> = (keys.iter().flatten())
            .filter(|k| !had(k))
            .map(SigningKey::fingerprint)
            .collect();
        new_keys.dedup();
        done.new_keys = new_keys;
        self.configured = (ids.into_iter().enumerate())
            .filter_map(|(n, id)| {
                Some(Configured {
                    id: id?,
                    key: key_of(n).cloned(),
                })
            })
            .collect();
        self.apply_paths(config, now);
        self.config = config.clone();
        // A reload is rare: every deadline is filed afresh, and every interface gets a
        // turn to send (a changed pacer may let a held-back packet go).
        let ids: Vec<InterfaceId> = self
            .interfaces
            .iter()
            .map(|(k, _)| InterfaceId(k))
            .collect();
        for id in ids {
            self.refresh_deadline(id);
            self.mark_ready(id);
        }
        self.take_output();
        done
    }

    /// Takes `config`'s dialect and `unknown_messages` policy for every parser (those of
    /// interfaces made from now on too: see `push_interface`). True if they changed.
    fn set_parsing(&mut self, config: &Config) -> bool {
        if self.config.dialect == config.dialect
            && self.config.unknown_messages == config.unknown_messages
        {
            return false;
        }
        self.config.dialect = config.dialect;
        self.config.unknown_messages = config.unknown_messages;
        for (_, interface) in self.interfaces.iter_mut() {
            interface.parser.set_dialect(config.dialect);
            interface.parser.set_checks(config.checks());
        }
        true
    }

    /// Forgets interface `id`, which [`Request::Open`] named but the event loop could
    /// not open (a port taken by another program): the configuration runs without it,
    /// and the next reload tries it again.
    pub fn unconfigure(&mut self, id: InterfaceId) {
        self.settle_direct();
        let Some(n) = self.configured.iter().position(|c| c.id == id) else {
            return;
        };
        self.forget_interface(id, &mut Vec::new());
        self.configured.remove(n);
        if n < self.config.interfaces.len() {
            self.config.interfaces.remove(n);
        }
    }

    /// Notes that the statistics endpoint of the configuration in force could not be
    /// started: none is published to, and the next reload that names one starts it.
    pub fn stats_not_started(&mut self) {
        self.config.stats = None;
    }

    /// Notes that the recording of the configuration in force could not be started:
    /// the next reload that names one starts it.
    pub fn record_not_started(&mut self) {
        self.config.record = None;
    }

    /// The configuration in force (its interfaces are those the core runs).
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// How messages name interface `id`.
    fn describe(&self, id: InterfaceId) -> String {
        self.interfaces
            .get(id.0)
            .map_or_else(|| format!("interface {}", id.0), |i| i.described.clone())
    }

    /// Adds the interface of block `iface`, the `index`th of its configuration, with
    /// its `key`.
    fn add_configured(
        &mut self,
        iface: &Interface,
        key: Option<&SigningKey>,
        index: usize,
        now: Timestamp,
    ) -> InterfaceId {
        let id = match iface {
            Interface::Serial(s) => {
                let rate = s.max_bitrate.unwrap_or(0);
                self.add_stream_interface(&s.device, &s.preload, Some(s.baudrate), rate, now)
            }
            Interface::Udp(u) => {
                let rate = u.max_bitrate.unwrap_or(0);
                match &u.connect {
                    None => self.add_datagram_interface(u.label(), rate, u.peers.clone()),
                    Some(remote) => {
                        self.add_datagram_client(u.label(), &remote.to_string(), rate, now)
                    }
                }
            }
            Interface::Tcp(t) => {
                let rate = t.max_bitrate.unwrap_or(0);
                match &t.connect {
                    None => self.add_listener(t.label(), t.peers.clone(), rate),
                    Some(remote) => {
                        self.add_stream_client(t.label(), &format!("tcp:{remote}"), rate, now)
                    }
                }
            }
            Interface::WebSocket(w) => {
                let rate = w.max_bitrate.unwrap_or(0);
                self.add_listener_of("ws", w.label(), w.peers.clone(), rate)
            }
            // One link for the whole Zenoh network: Zenoh routes between its sessions
            // itself, so what came from it never goes back to it.
            Interface::Zenoh(z) => self.add_stream_client(z.label(), &z.label(), 0, now),
        };
        if let (Some(key), Some(s)) = (key, iface.signing()) {
            let link_id = u8::try_from(index % 256).unwrap_or(0);
            self.set_signing(id, key.clone(), s.allow_unsigned, link_id);
        }
        id
    }

    /// Applies the settings `what` of block `iface` (the `index`th, with `key`) to
    /// interface `id` and, for a server, to the connections it accepted.
    fn change_in_place(
        &mut self,
        id: InterfaceId,
        iface: &Interface,
        key: Option<&SigningKey>,
        index: usize,
        what: &[InPlace],
    ) {
        let (rate, limits) = match iface {
            Interface::Udp(u) => (u.max_bitrate, Some(&u.peers)),
            Interface::Tcp(t) => (t.max_bitrate, Some(&t.peers)),
            Interface::WebSocket(w) => (w.max_bitrate, Some(&w.peers)),
            Interface::Serial(s) => (s.max_bitrate, None),
            Interface::Zenoh(_) => (None, None),
        };
        let signing = iface.signing().zip(key).map(|(s, key)| {
            let slot = self.core.signing.add_key(key.clone());
            (slot, s.allow_unsigned)
        });
        let family = self.family(id);
        for &w in what {
            for &member in &family {
                let Some(interface) = self.interfaces.get_mut(member.0) else {
                    continue;
                };
                match w {
                    InPlace::MaxBitrate => {
                        let rate = rate.unwrap_or(0);
                        match &mut interface.kind {
                            Kind::Listener { max_bitrate, .. } => *max_bitrate = rate,
                            _ => {
                                interface.pacer = pacer_for(rate);
                                interface.pace_deadline = None;
                            }
                        }
                    }
                    InPlace::Signing => {
                        interface.signing = signing.map(|(key_slot, allow_unsigned)| {
                            let old = interface.signing.take();
                            Edge {
                                key_slot,
                                allow_unsigned,
                                link_id: old
                                    .as_ref()
                                    .map_or(u8::try_from(index % 256).unwrap_or(0), |e| e.link_id),
                                counters: old.map(|e| e.counters).unwrap_or_default(),
                                said: Vec::new(),
                            }
                        });
                    }
                    InPlace::Peers => {
                        if let (
                            Kind::Datagram { limits: l, .. } | Kind::Listener { limits: l, .. },
                            Some(new),
                        ) = (&mut interface.kind, limits)
                        {
                            *l = PeerLimits::clone(new);
                        }
                    }
                }
            }
        }
    }

    /// Interface `id` and, for a server, the connections it accepted.
    pub(super) fn family(&self, id: InterfaceId) -> Vec<InterfaceId> {
        let mut family = vec![id];
        family.extend(self.interfaces.iter().filter_map(|(key, i)| match i.kind {
            Kind::Stream {
                accepted_by: Some(server),
                ..
            } if server == id => Some(InterfaceId(key)),
            _ => None,
        }));
        family
    }

    /// Takes interface `id` (with the connections of a server) out of routing, asking
    /// the loop to close each: at once where it cannot send (a server socket, a stream
    /// that is down: what was queued for it is dropped), else once what was queued for
    /// it, in the core and in its driver, was sent, by `now` + [`CLOSE_FLUSH`] at the
    /// latest ([`Request::Retire`]).
    /// Returns how many queued frames were dropped now and how many are being sent.
    ///
    /// [`CLOSE_FLUSH`]: super::CLOSE_FLUSH
    fn retire_interface(
        &mut self,
        id: InterfaceId,
        now: Timestamp,
        requests: &mut Vec<Request>,
    ) -> (u64, usize) {
        let (mut dropped, mut sending) = (0, 0);
        for member in self.family(id) {
            // A server socket sends nothing itself; a stream that is down cannot send.
            let sends = self
                .interfaces
                .get(member.0)
                .is_some_and(|i| i.is_open() && !matches!(i.kind, Kind::Listener { .. }));
            if !sends {
                dropped += self.forget_member(member, requests);
                continue;
            }
            let Some(interface) = self.interfaces.get_mut(member.0) else {
                continue;
            };
            interface.retiring = Some(now + super::CLOSE_FLUSH);
            interface.parser.clear();
            // Its server is closing: the number may soon be another interface's.
            if let Kind::Stream { accepted_by, .. } = &mut interface.kind {
                *accepted_by = None;
            }
            for (link, name) in links_of(interface) {
                sending += self.core.router.link(link).map_or(0, |l| l.queue.len());
                self.core.router.retire_link(link);
                self.core
                    .notices
                    .push_back(Notice::LinkRemoved { id: link, name });
            }
            self.refresh_deadline(member);
            self.mark_ready(member);
            requests.push(Request::Retire(member));
        }
        (dropped, sending)
    }

    /// True while interface `id` sends what was queued for it before it closes
    /// ([`Request::Retire`]).
    pub fn is_retiring(&self, id: InterfaceId) -> bool {
        self.interfaces
            .get(id.0)
            .is_some_and(|i| i.retiring.is_some())
    }

    /// Closes retiring interface `id` ([`Request::Retire`]) if nothing is queued for it
    /// any more: ask whenever its driver has nothing in flight. [`Notice::Closed`]
    /// follows when it closes.
    pub fn close_if_drained(&mut self, id: InterfaceId) {
        if self.is_retiring(id) && self.is_idle(id) {
            self.close_retiring(id);
        }
    }

    /// Closes retiring interface `id` ([`Request::Retire`]) now: its time is up, its
    /// stream was lost, or its port is wanted by an interface a reload opens. What is
    /// still queued for it is dropped, counted and said; [`Notice::Closed`] follows.
    pub fn close_retiring(&mut self, id: InterfaceId) {
        self.settle_direct();
        if !self.is_retiring(id) {
            return;
        }
        let described = self.describe(id);
        let dropped = self.forget_member(id, &mut Vec::new());
        self.core.notices.push_back(Notice::Closed(id));
        if dropped > 0 {
            let frames = if dropped == 1 { "frame" } else { "frames" };
            self.core.notices.push_back(Notice::Warning(format!(
                "{described} closed: {dropped} queued {frames} dropped"
            )));
        }
    }

    /// Removes interface `id` (with the connections of a server) and its links at once;
    /// asks the loop to close each. Returns how many queued frames were dropped.
    fn forget_interface(&mut self, id: InterfaceId, requests: &mut Vec<Request>) -> u64 {
        self.family(id)
            .into_iter()
            .map(|member| self.forget_member(member, requests))
            .sum()
    }

    /// Removes interface `id` alone and its links; asks the loop to close it. Returns
    /// how many queued frames were dropped.
    fn forget_member(&mut self, id: InterfaceId, requests: &mut Vec<Request>) -> u64 {
        let mut dropped = 0;
        let Some(interface) = self.interfaces.try_remove(id.0) else {
            return 0;
        };
        for (link, name) in links_of(&interface) {
            dropped += self.core.router.clear_queue(link);
            self.core.router.remove_link(link);
            self.owner.remove(&link);
            // A retiring interface's links left routing (and were said gone) before.
            if interface.retiring.is_none() {
                self.core
                    .notices
                    .push_back(Notice::LinkRemoved { id: link, name });
            }
        }
        self.refresh_deadline(id);
        requests.push(Request::Close(id));
        dropped
    }
}

/// The links of `interface`, with their names.
fn links_of(interface: &LiveInterface) -> Vec<(LinkId, String)> {
    match &interface.kind {
        Kind::Datagram { remotes, .. } => remotes.iter().map(|(l, a)| (l, a.to_string())).collect(),
        Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => {
            vec![(*link, interface.label.clone())]
        }
        Kind::Listener { .. } => Vec::new(),
    }
}

/// What a detail line says of the queue of an interface a reload closes: `dropped`
/// frames dropped now, `sending` frames sent before it closes.
fn closing_text(dropped: u64, sending: usize) -> String {
    let sent = match sending {
        0 => String::new(),
        1 => "closed once its 1 queued frame is sent".to_string(),
        n => format!("closed once its {n} queued frames are sent"),
    };
    match (dropped, sent.is_empty()) {
        (0, true) => String::new(),
        (d, true) => format!(" ({d} queued frames dropped)"),
        (0, false) => format!(" ({sent})"),
        (d, false) => format!(" ({d} queued frames dropped; {sent})"),
    }
}

/// The counts the new filter starts from: each rule's old counts where [`RulePlan`]
/// found the same rule, and the default action's if it is the same.
fn carried_counts(old: &FilterCounts, rules: &RulePlan) -> FilterCounts {
    let rule = |o: Option<usize>| {
        o.and_then(|o| old.rules.get(o).copied())
            .unwrap_or_default()
    };
    FilterCounts {
        rules: rules.carried.iter().map(|&o| rule(o)).collect(),
        default_packets: if rules.default_carried {
            old.default_packets
        } else {
            0
        },
        default_bytes: if rules.default_carried {
            old.default_bytes
        } else {
            0
        },
    }
}

#[cfg(test)]
mod tests {
    use std::net::SocketAddr;

    use super::*;
    use crate::config::load;
    use crate::wire::encode::{Header, encode_v2};

    const T0: Timestamp = Timestamp::ZERO;

    fn frame(id: u32, system: u8) -> Vec<u8> {
        let header = Header {
            seq: 0,
            system,
            component: 1,
        };
        let mut out = Vec::new();
        encode_v2(header, id, &[7; 9], None, &mut out).expect("encode");
        out
    }

    fn peer(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    fn opened(done: &Reconfigured) -> Vec<InterfaceId> {
        (done.requests.iter())
            .filter_map(|r| match r {
                Request::Open(id, _) => Some(*id),
                Request::Close(_) | Request::Retire(_) => None,
            })
            .collect()
    }

    #[test]
    fn a_reload_keeps_what_did_not_change_and_drops_what_went() {
        let old = load(
            "udp { port 14550; }\nudp { port 14551; }\n\
             chain default { reject if PING; accept; }\n",
        )
        .expect("config")
        .config;
        let mut e = Engine::new(&old, RouterOptions::default());
        let ids = opened(&e.configure(&old, &[], T0));
        let [a, b] = ids[..] else {
            panic!("two interfaces: {ids:?}")
        };
        e.handle_datagram(a, peer(1), &frame(0, 1), T0);
        e.handle_datagram(b, peer(2), &frame(0, 2), T0); // queued for peer 1, on `a`
        e.handle_datagram(a, peer(1), &frame(30, 1), T0); // queued for peer 2, on `b`
        let counts = e.router().filter_counts();

        let new = load(
            "udp { port 14551; max_bitrate 9600; }\n\
             chain default { reject if HEARTBEAT; accept; }\n",
        )
        .expect("config")
        .config;
        let done = e.configure(&new, &[], T0);
        // `a` sends the heartbeat queued for peer 1 before it closes.
        assert_eq!(done.requests, [Request::Retire(a)]);
        assert_eq!((done.added, done.removed, done.changed), (0, 1, 1));
        assert_eq!(done.dropped, 0);
        assert_eq!(
            done.details[0],
            "udp 0.0.0.0:14550 removed (closed once its 1 queued frame is sent)"
        );
        assert_eq!(
            done.to_string(),
            "2 rules (1 changed, 1 removed), +0 interfaces, -1, 1 changed"
        );
        // `b` kept its link, its learned address and its queue; it is paced now.
        let link = e.router().links().next().expect("peer 2's link");
        assert_eq!(link.name(), "127.0.0.1:2");
        assert!(e.router().peek(link.id()).is_some(), "its queue is kept");
        assert_eq!(e.interface(b).map(|i| i.pacer.rate()), Some(9600));
        // `accept` reads the same: its counts go on; the new reject rule starts at 0.
        let carried = e.router().filter_counts();
        assert_eq!(carried.rules[1], counts.rules[1]);
        assert_eq!(carried.rules[0].packets, 0);
        assert!(counts.rules[1].packets > 0);
    }

    #[test]
    fn the_summary_names_each_top_level_block_that_changed() {
        let old = load("udp { port 14550; }\n").expect("config").config;
        let mut e = Engine::new(&old, RouterOptions::default());
        e.configure(&old, &[], T0);
        let new = load(
            "udp { port 14550; }\n\
             stats { port 9100; }\n\
             record { path /tmp/x.tlog; }\n\
             flight_log { system 1; path /tmp/y; }\n",
        )
        .expect("config")
        .config;
        assert_eq!(
            e.configure(&new, &[], T0).to_string(),
            "0 rules (0 changed), +0 interfaces, -0, 0 changed, stats changed, record changed, \
             flight_log changed"
        );
        assert_eq!(
            e.configure(&new, &[], T0).to_string(),
            "0 rules (0 changed), +0 interfaces, -0, 0 changed"
        );
    }

    #[test]
    fn a_server_passes_its_new_rate_to_its_connections() {
        let old = load("tcp { port 5760; }\n").expect("config").config;
        let mut e = Engine::new(&old, RouterOptions::default());
        let ids = opened(&e.configure(&old, &[], T0));
        let conn = e.accept(ids[0], peer(9), T0).expect("accepted");
        let new = load("tcp { port 5760; max_bitrate 4800; }\n")
            .expect("config")
            .config;
        let done = e.configure(&new, &[], T0);
        assert!(done.requests.is_empty(), "{:?}", done.requests);
        assert_eq!(e.interface(conn).map(|i| i.pacer.rate()), Some(4800));
        let later = e.accept(ids[0], peer(10), T0).expect("accepted");
        assert_eq!(e.interface(later).map(|i| i.pacer.rate()), Some(4800));
        // Removing the server closes its connections too.
        let none = load("default_action accept;\n").expect("config").config;
        let done = e.configure(&none, &[], T0);
        assert_eq!(
            done.requests,
            [
                Request::Close(ids[0]),
                Request::Retire(conn),
                Request::Retire(later)
            ]
        );
    }
}
