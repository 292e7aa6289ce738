//! The router: every link, the shared filter, and what happens to each received frame.

use std::sync::Arc;
use std::time::Duration;

use super::dispatch::{Decision, decide};
use super::event::{Event, LinkRef, PacketSummary};
use super::link::{Link, LinkId, LinkKind};
use super::pool::DEFAULT_EXPIRY;
use super::queue::{DEFAULT_CAPACITY, Packet, PushOutcome};
use super::time::Timestamp;
use crate::address::Address;
use crate::config::Config;
use crate::filter::{CacheStats, Filter, cache};
use crate::wire::Frame;

/// Tunables of a [`Router`]; `Default` gives the original's behaviour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RouterOptions {
    /// How long a learned address lasts without traffic (120 s).
    pub expiry: Duration,
    /// Bytes each link's queue may hold ([`DEFAULT_CAPACITY`]).
    pub queue_capacity: usize,
    /// Events above this level (0–3) are not produced at all (3: every event).
    pub event_level: u8,
    /// Entries of the filter's verdict memo ([`cache::DEFAULT_SLOTS`]; 0 = no memo).
    pub cache_slots: usize,
}

impl Default for RouterOptions {
    fn default() -> Self {
        RouterOptions {
            expiry: DEFAULT_EXPIRY,
            queue_capacity: DEFAULT_CAPACITY,
            event_level: 3,
            cache_slots: cache::DEFAULT_SLOTS,
        }
    }
}

/// What one call into the router produced. Reuse one across calls; the router appends.
#[derive(Debug, Default)]
pub struct Output {
    /// Log events, in the order the original prints them.
    pub events: Vec<Event>,
    /// Links that got a packet queued (each at most once per call), in offer order.
    pub queued: Vec<LinkId>,
    /// Packets dropped because a destination queue was full (including evictions).
    pub queue_drops: u64,
}

impl Output {
    /// Empties the output for the next call.
    pub fn clear(&mut self) {
        self.events.clear();
        self.queued.clear();
        self.queue_drops = 0;
    }
}

/// The sans-IO routing core.
#[derive(Debug)]
pub struct Router {
    filter: Filter,
    links: Vec<Link>,
    next_id: u64,
    options: RouterOptions,
}

impl Router {
    /// A router with no links, filtering with `config`'s chains.
    pub fn new(config: &Config) -> Self {
        Router::with_options(config, RouterOptions::default())
    }

    /// A router with no links and the given tunables.
    pub fn with_options(config: &Config, options: RouterOptions) -> Self {
        Router {
            filter: Filter::with_cache_slots(config, options.cache_slots),
            links: Vec::new(),
            next_id: 0,
            options,
        }
    }

    /// The tunables in use.
    pub fn options(&self) -> &RouterOptions {
        &self.options
    }

    /// Changes which events are produced (0 = none, 3 = all).
    pub fn set_event_level(&mut self, level: u8) {
        self.options.event_level = level;
    }

    fn add_link(&mut self, name: &str, kind: LinkKind, now: Timestamp) -> usize {
        let id = LinkId(self.next_id);
        self.next_id += 1;
        self.links.push(Link::new(
            id,
            name,
            kind,
            self.options.expiry,
            self.options.queue_capacity,
            now,
        ));
        self.links.len() - 1
    }

    /// Adds a serial link named `name` (the device as written) that reaches `preload`
    /// permanently; a "new component" event for each preloaded address.
    pub fn add_serial_link(
        &mut self,
        name: &str,
        preload: &[Address],
        now: Timestamp,
        out: &mut Output,
    ) -> LinkId {
        let i = self.add_link(name, LinkKind::Serial, now);
        let want = self.options.event_level >= 1;
        let link = &mut self.links[i];
        for &address in preload {
            if link.pool.preload(address) && want {
                out.events.push(Event::NewComponent {
                    address,
                    link: link_ref(link),
                });
            }
        }
        link.id()
    }

    /// Adds a UDP link for a remote that just sent its first valid frame; `name` is
    /// `a.b.c.d:port`. Call [`Router::receive`] with that frame next.
    pub fn add_udp_link(&mut self, name: &str, now: Timestamp) -> LinkId {
        let i = self.add_link(name, LinkKind::Udp, now);
        self.links[i].id()
    }

    fn index(&self, id: LinkId) -> Option<usize> {
        // Ids grow with creation order and links are kept in that order.
        self.links.binary_search_by_key(&id, |l| l.id()).ok()
    }

    /// The link `id`, if it exists.
    pub fn link(&self, id: LinkId) -> Option<&Link> {
        self.index(id).map(|i| &self.links[i])
    }

    /// Every link in creation order.
    pub fn links(&self) -> impl Iterator<Item = &Link> {
        self.links.iter()
    }

    /// Routes `frame`, received on link `source` at `now`: learns its source address,
    /// then offers it to every link in creation order and queues it where accepted. A
    /// frame from an unknown link is ignored.
    pub fn receive(&mut self, source: LinkId, frame: &Frame<'_>, now: Timestamp, out: &mut Output) {
        let Some(si) = self.index(source) else {
            return;
        };
        let level = self.options.event_level;
        let src = frame.source();
        let message_id = frame.message_id();
        let target = frame.target();
        let summary = PacketSummary::of(frame);

        let src_link = &mut self.links[si];
        if src_link.learn(src, now) && level >= 1 {
            out.events.push(Event::NewComponent {
                address: src,
                link: link_ref(src_link),
            });
        }
        let src_ref = (level >= 2).then(|| link_ref(&self.links[si]));
        if let Some(s) = &src_ref {
            out.events.push(Event::Received {
                packet: summary,
                source: s.clone(),
            });
        }

        let mut packet: Option<Packet> = None;
        for link in &mut self.links {
            let decision = decide(&mut self.filter, &link.pool, now, message_id, src, target);
            match decision {
                Decision::Silent => {}
                Decision::Accept(priority) => {
                    let bytes = packet
                        .get_or_insert_with(|| Arc::from(frame.as_bytes()))
                        .clone();
                    match link.queue.push(bytes, priority) {
                        PushOutcome::Queued { evicted } => {
                            out.queue_drops += evicted as u64;
                            out.queued.push(link.id());
                        }
                        PushOutcome::Dropped => out.queue_drops += 1,
                    }
                    if let Some(s) = src_ref.as_ref().filter(|_| level >= 3) {
                        out.events.push(Event::Accepted {
                            packet: summary,
                            source: s.clone(),
                            dest: link_ref(link),
                            priority,
                        });
                    }
                }
                Decision::Reject => {
                    if let Some(s) = src_ref.as_ref().filter(|_| level >= 3) {
                        out.events.push(Event::Rejected {
                            packet: summary,
                            source: s.clone(),
                            dest: link_ref(link),
                        });
                    }
                }
            }
        }
    }

    /// The next packet link `id` should send, without removing it.
    pub fn peek(&self, id: LinkId) -> Option<&Packet> {
        self.link(id).and_then(|l| l.queue.peek())
    }

    /// Removes and returns the next packet link `id` should send.
    pub fn pop(&mut self, id: LinkId) -> Option<Packet> {
        let i = self.index(id)?;
        self.links[i].queue.pop()
    }

    /// Periodic housekeeping at `now`: forgets expired addresses and removes UDP links
    /// whose pool has been empty for the expiry time. Returns the removed links' ids (the
    /// I/O layer forgets their `ip:port`). Call it about once a second.
    pub fn tick(&mut self, now: Timestamp) -> Vec<LinkId> {
        let mut removed = Vec::new();
        self.links.retain_mut(|l| {
            if l.is_stale(now) {
                removed.push(l.id());
                false
            } else {
                l.pool.prune(now);
                true
            }
        });
        removed
    }

    /// Hits and misses of the filter's verdict memo.
    pub fn filter_stats(&self) -> CacheStats {
        self.filter.cache_stats()
    }
}

fn link_ref(link: &Link) -> LinkRef {
    LinkRef {
        id: link.id(),
        name: link.shared_name(),
    }
}
