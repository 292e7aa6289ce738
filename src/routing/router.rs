//! The router: every link, the shared filter, and what happens to each received frame.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;
use std::time::Duration;

use super::counters::LinkCounters;
use super::dispatch::{Decision, decide};
use super::event::{Event, LinkRef, PacketSummary};
use super::link::{Link, LinkId, LinkKind};
use super::pool::DEFAULT_EXPIRY;
use super::queue::{DEFAULT_CAPACITY, DEFAULT_TOTAL_CAPACITY, Packet, PacketQueue, PushOutcome};
use super::rate_limit::RateLimiter;
use super::sources::{Sequences, SourceTable};
use crate::address::Address;
use crate::config::Config;
use crate::dialect::SETUP_SIGNING_ID;
use crate::filter::{CacheStats, Filter, FilterCounts, cache};
use crate::time::Timestamp;
use crate::wire::Frame;

mod direct;
mod redundancy;
pub(crate) use direct::Direct;
use redundancy::Redundancy;

/// Packets kept for reuse once sent (see [`Router::recycle`]): at most this many, a few
/// KiB at most, so that a packet of a length seen recently costs no allocation.
const SPARE_PACKETS: usize = 16;

/// Tunables of a [`Router`]; `Default` gives the original's behaviour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RouterOptions {
    /// How long a learned address lasts without traffic (120 s).
    pub expiry: Duration,
    /// Bytes each link's queue may hold (`DEFAULT_CAPACITY`).
    pub queue_capacity: usize,
    /// Bytes all queues together may hold (`DEFAULT_TOTAL_CAPACITY`). A
    /// packet that would pass it first pushes out the oldest packets of the lowest
    /// priority queued anywhere (from the link holding the most, among equals) until an
    /// eighth of it is free, or is dropped itself if everything queued ranks above it.
    /// So many links (say, a flood of spoofed UDP senders) cannot together hold more.
    pub total_queue_capacity: usize,
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
            total_queue_capacity: DEFAULT_TOTAL_CAPACITY,
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
    /// A packet held out of its empty queue to be sent at once, when the caller allowed
    /// it ([`Output::cut_through`]; see `router/direct.rs`).
    pub(crate) direct: Option<Direct>,
    /// Set by the caller: this call may hold one packet out of its queue in
    /// [`Output::direct`]. Not cleared by [`Output::clear`].
    pub(crate) cut_through: bool,
}

impl Output {
    /// Empties the output for the next call.
    pub fn clear(&mut self) {
        debug_assert!(
            self.direct.is_none(),
            "a held packet is taken or queued first"
        );
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
    /// The id of each of `links`, in the same order: searched instead of the links
    /// themselves, so that finding a link touches a few cache lines, not one per step.
    ids: Vec<LinkId>,
    next_id: u64,
    options: RouterOptions,
    /// Bytes held by all queues (each packet counted once per queue holding it).
    queued_bytes: usize,
    /// Frames per (source, message type).
    sources: SourceTable,
    /// Sequence gaps per source.
    sequences: Sequences,
    /// The schedules of streams capped by a `with rate` rule.
    limiter: RateLimiter,
    /// By system id, the links that learned (or were preloaded with) an address of that
    /// system, in creation order: the only links a packet targeted at the system can be
    /// offered without being dropped silently, so that such a packet costs the same
    /// however many other links there are. Links stay listed while their address
    /// expires (the decision checks liveness) and leave with the link.
    by_system: Vec<Vec<LinkId>>,
    /// Counts the changes to which link holds which systems: an address learned (new,
    /// or back after it expired) or a link gone. See [`Router::systems_generation`].
    systems_generation: u64,
    /// `dedup`, groups and the router's own address (see `redundancy`).
    redundancy: Redundancy,
    /// Sent packets no one else holds, kept to carry the next frames of their lengths.
    spare: Vec<Packet>,
    /// Links of interfaces a reload removed, sending what was queued for them before
    /// they close ([`Router::retire_link`]): offered no packet, known to no system.
    retired: Vec<Link>,
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
            ids: Vec::new(),
            next_id: 0,
            options,
            queued_bytes: 0,
            sources: SourceTable::default(),
            sequences: Sequences::default(),
            limiter: RateLimiter::default(),
            redundancy: Redundancy::default(),
            by_system: vec![Vec::new(); 256],
            systems_generation: 0,
            spare: Vec::new(),
            retired: Vec::new(),
        }
    }

    /// A number that changes whenever a link learns an address (new, or back after it
    /// expired) or a link goes: what the systems reached through each link may have
    /// changed. Addresses that merely expire do not change it.
    pub fn systems_generation(&self) -> u64 {
        self.systems_generation
    }

    /// Lists link `id` under `system` (see `by_system`).
    fn index_system(&mut self, system: u8, id: LinkId) {
        self.systems_generation += 1;
        let list = &mut self.by_system[usize::from(system)];
        if let Err(at) = list.binary_search(&id) {
            list.insert(at, id);
        }
    }

    /// Takes the links of `removed` out of every system's list.
    fn unindex(&mut self, removed: &[LinkId]) {
        if removed.is_empty() {
            return;
        }
        self.systems_generation += 1;
        let mut removed = removed.to_vec();
        removed.sort_unstable();
        for list in &mut self.by_system {
            list.retain(|id| removed.binary_search(id).is_err());
        }
    }

    /// The tunables in use.
    pub fn options(&self) -> &RouterOptions {
        &self.options
    }

    /// Replaces the filter with `config`'s chains and default action (a reload): the
    /// verdict memo starts empty, and the per-rule counts start from `counts` (by the
    /// new filter's flat rule numbers: what the same rules counted before). The `with
    /// rate` schedules carry over if the new filter caps at the same rates; otherwise
    /// every stream starts afresh.
    pub fn replace_filter(&mut self, config: &Config, counts: &FilterCounts) {
        let mut filter = Filter::with_cache_slots(config, self.options.cache_slots);
        filter.carry_counts(counts);
        if !filter.same_rates(&self.filter) {
            self.limiter.clear();
        }
        self.filter = filter;
    }

    /// Sets the queue bounds (a reload's `queue` block): every link's queue, and the
    /// total, take the new sizes at once; a queue above its new bound keeps what it holds
    /// and makes room at its next packet.
    pub(crate) fn set_queue_bounds(&mut self, link_bytes: usize, total_bytes: usize) {
        self.options.queue_capacity = link_bytes;
        self.options.total_queue_capacity = total_bytes;
        for link in &mut self.links {
            link.queue.set_capacity(link_bytes);
        }
    }

    /// Changes which events are produced (0 = none, 3 = all).
    pub fn set_event_level(&mut self, level: u8) {
        self.options.event_level = level;
    }

    fn add_link(&mut self, name: &str, kind: LinkKind, now: Timestamp) -> usize {
        let id = LinkId(self.next_id);
        self.next_id += 1;
        self.ids.push(id);
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
        let id = link.id();
        for &address in preload {
            if link.pool.preload(address) && want {
                out.events.push(Event::NewComponent {
                    address,
                    link: link_ref(link),
                });
            }
        }
        for &address in preload {
            self.index_system(address.system, id);
        }
        id
    }

    /// Adds a UDP link for a remote that just sent its first valid frame; `name` is
    /// `a.b.c.d:port`. Call [`Router::receive`] with that frame next.
    pub fn add_udp_link(&mut self, name: &str, now: Timestamp) -> LinkId {
        let i = self.add_link(name, LinkKind::Udp, now);
        self.links[i].id()
    }

    /// Adds the link of a UDP or TCP client named `name` (see [`LinkKind::Client`]).
    pub(crate) fn add_client_link(&mut self, name: &str, now: Timestamp) -> LinkId {
        let i = self.add_link(name, LinkKind::Client, now);
        self.links[i].id()
    }

    /// Adds a link for a connection a server accepted (`tcp:a.b.c.d:port`); it lives until
    /// [`Router::remove_link`].
    pub(crate) fn add_connection_link(&mut self, name: &str, now: Timestamp) -> LinkId {
        let i = self.add_link(name, LinkKind::Connection, now);
        self.links[i].id()
    }

    /// Removes link `id` and what its queue holds (a closed connection). Returns false if
    /// there is no such link.
    pub(crate) fn remove_link(&mut self, id: LinkId) -> bool {
        let Some(i) = self.index(id) else {
            let Some(r) = self.retired.iter().position(|l| l.id() == id) else {
                return false;
            };
            let link = self.retired.swap_remove(r);
            self.queued_bytes -= link.queue.bytes();
            return true;
        };
        let link = self.links.remove(i);
        self.ids.remove(i);
        self.queued_bytes -= link.queue.bytes();
        // Its rate schedules are not swept: they lapse (see `rate_limit`).
        self.unindex(&[id]);
        true
    }

    /// Takes link `id` out of routing while what is queued for it is still sent (its
    /// interface was removed by a reload): no packet is offered to it any more and the
    /// addresses it learned are forgotten, but [`Router::peek`], [`Router::pop`] and its
    /// counters work until [`Router::remove_link`]. Returns false if there is no such
    /// link in routing.
    pub(crate) fn retire_link(&mut self, id: LinkId) -> bool {
        let Some(i) = self.index(id) else {
            return false;
        };
        let link = self.links.remove(i);
        self.ids.remove(i);
        self.unindex(&[id]);
        self.retired.push(link);
        true
    }

    /// Drops everything queued for link `id` (counted as dropped), e.g. telemetry that
    /// went stale while its connection was down. Returns how many packets were dropped.
    pub(crate) fn clear_queue(&mut self, id: LinkId) -> u64 {
        let Some(link) = self.link_mut(id) else {
            return 0;
        };
        let queue = &mut link.queue;
        let (mut n, mut freed) = (0, 0);
        while queue.bytes() > 0 {
            freed += queue.drop_lowest();
            n += 1;
        }
        self.queued_bytes -= freed;
        n
    }

    fn index(&self, id: LinkId) -> Option<usize> {
        // Ids grow with creation order and links are kept in that order.
        self.ids.binary_search(&id).ok()
    }

    /// The link `id`, if it exists (retired links too).
    #[inline]
    pub fn link(&self, id: LinkId) -> Option<&Link> {
        match self.index(id) {
            Some(i) => Some(&self.links[i]),
            None => self.retired(id),
        }
    }

    /// The link `id`, mutable, if it exists (retired links too).
    #[inline]
    fn link_mut(&mut self, id: LinkId) -> Option<&mut Link> {
        match self.index(id) {
            Some(i) => Some(&mut self.links[i]),
            None => self.retired_mut(id),
        }
    }

    /// Retired link `id` (rare: out of the frame's path).
    #[cold]
    #[inline(never)]
    fn retired(&self, id: LinkId) -> Option<&Link> {
        self.retired.iter().find(|l| l.id() == id)
    }

    /// Retired link `id`, mutable.
    #[cold]
    #[inline(never)]
    fn retired_mut(&mut self, id: LinkId) -> Option<&mut Link> {
        self.retired.iter_mut().find(|l| l.id() == id)
    }

    /// Every link in creation order.
    pub fn links(&self) -> impl Iterator<Item = &Link> {
        self.links.iter()
    }

    /// Routes `frame`, received on link `source` at `now`, as an unsigned frame (see
    /// [`Router::receive_as`]).
    pub fn receive(&mut self, source: LinkId, frame: &Frame<'_>, now: Timestamp, out: &mut Output) {
        self.receive_as(source, frame, false, now, out);
    }

    /// Routes `frame`, received on link `source` at `now` and `signed` (its signature
    /// verified by the router) or not: learns its source address, then offers it to
    /// every link in creation order and queues it where accepted. A frame from an
    /// unknown link is ignored.
    pub fn receive_as(
        &mut self,
        source: LinkId,
        frame: &Frame<'_>,
        signed: bool,
        now: Timestamp,
        out: &mut Output,
    ) {
        let Some(si) = self.index(source) else {
            return;
        };
        let level = self.options.event_level;
        let src = frame.source();
        let message_id = frame.message_id();
        // What the filter matches: the id, or the one id of all unknown ones.
        let filter_id = frame.info().id;
        let target = frame.target();

        let len = frame.as_bytes().len();
        // The clock for rate caps, read once for every link.
        let now_nanos = u64::try_from(now.as_nanos()).unwrap_or(u64::MAX);
        self.sources.count(src, message_id);
        self.sequences.count(src, frame.seq());
        self.links[si].counters.received(len);
        self.learn_source(si, src, now, out);
        let own = self.is_own(src);
        let src_ref = (level >= 2).then(|| link_ref(&self.links[si]));
        if let Some(s) = &src_ref {
            out.events.push(Event::Received {
                packet: PacketSummary::of(frame),
                source: s.clone(),
            });
        }

        let mut packet: Option<Packet> = None;
        let mut routed = false;
        let mut forwarded = false;
        // A packet for a system (S.C or S.0, not the broadcast 0.0) is offered only to
        // the links that know an address of S: every other link would drop it silently.
        let system = target
            .filter(|t| *t != Address::new(0, 0))
            .map(|t| usize::from(t.system));
        let offered = system.map_or(self.links.len(), |s| self.by_system[s].len());
        for k in 0..offered {
            let i = match system {
                None => k,
                Some(s) => match self.index(self.by_system[s][k]) {
                    Some(i) => i,
                    None => continue,
                },
            };
            if self.keeps_back(si, i, own) {
                continue;
            }
            let link = &self.links[i];
            let decision = decide(
                &mut self.filter,
                &link.pool,
                link.reaches_the_unknown(),
                now,
                filter_id,
                src,
                target,
                signed,
                len,
            );
            match decision {
                Decision::Silent => {}
                Decision::Accept(priority, cap) => {
                    routed = true;
                    if cap.is_capped()
                        && !self.limiter.allow(
                            link.id(),
                            src,
                            message_id,
                            self.filter.interval_nanos(cap),
                            now_nanos,
                        )
                    {
                        self.filter.count_rate_limited(cap);
                        continue;
                    }
                    forwarded = true;
                    let bytes = packet
                        .get_or_insert_with(|| packet_from(&mut self.spare, frame.as_bytes()))
                        .clone();
                    self.push(i, bytes, priority, out);
                    let link = &self.links[i];
                    if let Some(s) = src_ref.as_ref().filter(|_| level >= 3) {
                        out.events.push(Event::Accepted {
                            packet: PacketSummary::of(frame),
                            source: s.clone(),
                            dest: link_ref(link),
                            priority,
                        });
                    }
                }
                Decision::Reject => {
                    routed = true;
                    self.links[i].counters.filter_rejected += 1;
                    let link = &self.links[i];
                    if let Some(s) = src_ref.as_ref().filter(|_| level >= 3) {
                        out.events.push(Event::Rejected {
                            packet: PacketSummary::of(frame),
                            source: s.clone(),
                            dest: link_ref(link),
                        });
                    }
                }
            }
        }
        if !routed {
            self.links[si].counters.no_route += 1;
        }
        if filter_id == SETUP_SIGNING_ID && !forwarded {
            self.links[si].counters.setup_signing += 1;
        }
    }

    /// Takes back a packet that was sent: when nothing else holds it, it carries a later
    /// frame of the same length instead of a new allocation (at most [`SPARE_PACKETS`]
    /// are kept; the rest are freed).
    pub(crate) fn recycle(&mut self, packet: Packet) {
        if self.spare.len() < SPARE_PACKETS && Arc::strong_count(&packet) == 1 {
            self.spare.push(packet);
        }
    }

    /// Queues `packet` on link `i`, within the link's and the shared capacity, or holds
    /// it out of the link's empty queue to be sent at once (see `direct.rs`).
    fn push(&mut self, i: usize, packet: Packet, priority: i32, out: &mut Output) {
        let packet = if out.direct.is_some() {
            self.queue_held_if_observed(i, PacketQueue::cost_of(&packet), out);
            packet
        } else if out.cut_through {
            match self.hold(i, packet, priority, out) {
                Ok(()) => return,
                Err(packet) => packet,
            }
        } else {
            packet
        };
        self.enqueue(i, packet, priority, out);
    }

    /// Queues `packet` on link `i`, within the link's and the shared capacity. Other
    /// links' packets are dropped for shared room only for a packet the link's own
    /// queue takes.
    fn enqueue(&mut self, i: usize, packet: Packet, priority: i32, out: &mut Output) {
        let cost = PacketQueue::cost_of(&packet);
        if self.queued_bytes.saturating_add(cost) > self.options.total_queue_capacity
            && (!self.links[i].queue.would_take(cost, priority)
                || !self.make_room(cost, priority, out))
        {
            self.links[i].queue.count_drop();
            out.queue_drops += 1;
            return;
        }
        let link = &mut self.links[i];
        let before = link.queue.bytes();
        let outcome = link.queue.push(packet, priority);
        self.queued_bytes = self.queued_bytes - before + link.queue.bytes();
        match outcome {
            PushOutcome::Queued { evicted } => {
                out.queue_drops += evicted as u64;
                out.queued.push(link.id());
            }
            PushOutcome::Dropped => out.queue_drops += 1,
        }
    }

    /// Frees shared capacity for a packet of `cost` bytes and `priority`: drops what
    /// retired links still hold first, then the oldest packets of the lowest priority
    /// queued anywhere, each from the link holding the most among those with such a
    /// packet, never one that ranks above the new one.
    /// Frees an eighth of the capacity beyond what is needed, so that under a sustained
    /// flood the scan over all links runs once per many packets, not for each. Returns
    /// false if the new packet still does not fit.
    fn make_room(&mut self, cost: usize, priority: i32, out: &mut Output) -> bool {
        let cap = self.options.total_queue_capacity;
        let goal = cap.saturating_sub(cap / 8).max(cost);
        // What retired links still send ranks below any live link's packet.
        for link in &mut self.retired {
            while self.queued_bytes.saturating_add(cost) > goal && link.queue.bytes() > 0 {
                self.queued_bytes -= link.queue.drop_lowest();
                out.queue_drops += 1;
            }
        }
        let key = |k: usize, q: &PacketQueue| {
            q.lowest_priority()
                .map(|p| Reverse((p, Reverse(q.bytes()), k)))
        };
        let mut victims: BinaryHeap<_> = self
            .links
            .iter()
            .enumerate()
            .filter_map(|(k, l)| key(k, &l.queue))
            .collect();
        while self.queued_bytes.saturating_add(cost) > goal {
            let Some(Reverse((p, _, k))) = victims.pop() else {
                break;
            };
            if p > priority {
                break;
            }
            let queue = &mut self.links[k].queue;
            self.queued_bytes -= queue.drop_lowest();
            out.queue_drops += 1;
            victims.extend(key(k, queue));
        }
        self.queued_bytes.saturating_add(cost) <= cap
    }

    /// The counters of link `id`, to note what its transport did.
    pub(crate) fn counters_mut(&mut self, id: LinkId) -> Option<&mut LinkCounters> {
        Some(&mut self.link_mut(id)?.counters)
    }

    /// Bytes held by all queues together (see [`RouterOptions::total_queue_capacity`]).
    pub fn queued_bytes(&self) -> usize {
        self.queued_bytes
    }

    /// The next packet link `id` should send, without removing it.
    pub fn peek(&self, id: LinkId) -> Option<&Packet> {
        self.link(id).and_then(|l| l.queue.peek())
    }

    /// Removes and returns the next packet link `id` should send.
    pub fn pop(&mut self, id: LinkId) -> Option<Packet> {
        let packet = self.link_mut(id)?.queue.pop()?;
        self.queued_bytes -= PacketQueue::cost_of(&packet);
        Some(packet)
    }

    /// Periodic housekeeping at `now`: forgets expired addresses and removes UDP links
    /// whose pool has been empty for the expiry time. Returns the removed links' ids (the
    /// I/O layer forgets their `ip:port`). Call it about once a second.
    pub fn tick(&mut self, now: Timestamp) -> Vec<LinkId> {
        let mut removed = Vec::new();
        let mut freed = 0;
        self.links.retain_mut(|l| {
            if l.is_stale(now) {
                removed.push(l.id());
                freed += l.queue.bytes();
                false
            } else {
                l.pool.prune(now);
                true
            }
        });
        self.queued_bytes -= freed;
        if !removed.is_empty() {
            self.ids = self.links.iter().map(Link::id).collect();
        }
        self.unindex(&removed);
        removed
    }

    /// Live rate-capped streams forgotten because their table was full (the table
    /// holds a bounded number of streams).
    pub fn rate_streams_evicted(&self) -> u64 {
        self.limiter.evicted()
    }

    /// Hits and misses of the filter's verdict memo.
    pub fn filter_stats(&self) -> CacheStats {
        self.filter.cache_stats()
    }

    /// Per-rule hit counts of the filter (see [`Filter::counts`]).
    pub fn filter_counts(&self) -> FilterCounts {
        self.filter.counts()
    }

    /// Frames per (source, message type) (bounded; see `SourceTable`).
    pub(crate) fn sources_mut(&mut self) -> &mut SourceTable {
        &mut self.sources
    }

    /// Sequence gaps per source (bounded; see `Sequences`).
    pub(crate) fn sequences(&self) -> &Sequences {
        &self.sequences
    }
}

/// A packet holding `bytes`: a spare of the same length when one is free, else a new one.
fn packet_from(spare: &mut Vec<Packet>, bytes: &[u8]) -> Packet {
    if let Some(i) = spare.iter().position(|p| p.len() == bytes.len()) {
        let mut packet = spare.swap_remove(i);
        if let Some(buffer) = Arc::get_mut(&mut packet) {
            buffer.copy_from_slice(bytes);
            return packet;
        }
    }
    Arc::from(bytes)
}

fn link_ref(link: &Link) -> LinkRef {
    LinkRef {
        id: link.id(),
        name: link.shared_name(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spare_of_the_same_length_carries_the_next_frame() {
        let mut spare: Vec<Packet> = vec![Arc::from(&[9u8; 3][..]), Arc::from(&[7u8; 5][..])];
        let reused = spare[1].as_ptr();
        let packet = packet_from(&mut spare, &[1, 2, 3, 4, 5]);
        assert_eq!(&packet[..], &[1, 2, 3, 4, 5]);
        assert_eq!(packet.as_ptr(), reused, "the spare's buffer, not a new one");
        assert_eq!(spare.len(), 1);
        // No spare of this length: a new packet, the spare left alone.
        let other = packet_from(&mut spare, &[6; 4]);
        assert_eq!(&other[..], &[6; 4]);
        assert_eq!(&spare[0][..], &[9; 3]);
    }

    #[test]
    fn a_packet_still_held_elsewhere_is_never_reused() {
        let loaded = crate::config::load("chain default { accept; }\n").expect("config");
        let mut router = Router::new(&loaded.config);
        let queued: Packet = Arc::from(&[7u8; 5][..]);
        let held = queued.clone();
        router.recycle(queued);
        assert!(router.spare.is_empty(), "another queue still holds it");
        let mut spare = vec![held.clone()];
        let packet = packet_from(&mut spare, &[1, 2, 3, 4, 5]);
        assert_eq!(&held[..], &[7; 5], "the held packet is unchanged");
        assert_eq!(&packet[..], &[1, 2, 3, 4, 5]);
        for _ in 0..SPARE_PACKETS * 2 {
            router.recycle(Arc::from(&[0u8; 8][..]));
        }
        assert_eq!(router.spare.len(), SPARE_PACKETS, "the spares are bounded");
    }
}
