//! One link: a serial port, or one remote `ip:port` behind a UDP interface: its name,
//! learned addresses, outgoing queue and counters.

use std::sync::Arc;
use std::time::Duration;

use super::counters::{LinkCounters, LinkReport};
use super::pool::AddressPool;
use super::queue::PacketQueue;
use crate::time::Timestamp;

/// Identifies a link for as long as it exists; never reused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LinkId(pub u64);

/// A `group` of interfaces: redundant paths to one vehicle (numbered by the core).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GroupId(pub u16);

/// How long a link lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkKind {
    /// Configured: a serial port, a UDP or TCP client. Created at start, lives as long
    /// as the router; may have preloaded addresses.
    Serial,
    /// A remote `ip:port` of a UDP server interface: created by its first valid frame,
    /// removed when its address pool has stayed empty for the expiry time.
    Udp,
    /// A connection accepted by a TCP server interface: removed when it closes.
    Connection,
    /// A UDP or TCP client: configured, lives as long as the router. Its peer may never
    /// speak first (a ground station waits for a vehicle), so before it has taught the
    /// link any address, broadcasts are filtered for the broadcast address `0.0` and
    /// sent.
    Client,
}

/// A link's name (for logs), kind, learned addresses and outgoing queue.
#[derive(Debug, Clone)]
pub struct Link {
    id: LinkId,
    name: Arc<str>,
    kind: LinkKind,
    pub(crate) pool: AddressPool,
    pub(crate) queue: PacketQueue,
    pub(crate) counters: LinkCounters,
    /// Creation time, or the last time an address was learned.
    last_learned: Timestamp,
    /// The group of its interface: frames from one member never go to another, and
    /// addresses learned on one are learned on each.
    pub(crate) group: Option<GroupId>,
}

impl Link {
    pub(crate) fn new(
        id: LinkId,
        name: &str,
        kind: LinkKind,
        expiry: Duration,
        queue_capacity: usize,
        now: Timestamp,
    ) -> Self {
        Link {
            id,
            name: name.into(),
            kind,
            pool: AddressPool::new(expiry),
            queue: PacketQueue::new(queue_capacity),
            counters: LinkCounters::default(),
            last_learned: now,
            group: None,
        }
    }

    /// The link's id.
    pub(crate) fn id(&self) -> LinkId {
        self.id
    }

    /// The name used in logs: the device as written, or `a.b.c.d:port`.
    pub fn name(&self) -> &str {
        &self.name
    }

    pub(crate) fn shared_name(&self) -> Arc<str> {
        self.name.clone()
    }

    /// Serial or UDP.
    pub fn kind(&self) -> LinkKind {
        self.kind
    }

    /// True if broadcasts reach this link before it has learned any address (see
    /// [`LinkKind::Client`]; accepted connections likewise).
    pub(crate) fn reaches_the_unknown(&self) -> bool {
        matches!(self.kind, LinkKind::Client | LinkKind::Connection)
    }

    /// The group of its interface, if it has one.
    pub fn group(&self) -> Option<GroupId> {
        self.group
    }

    /// The addresses reachable through this link.
    pub fn pool(&self) -> &AddressPool {
        &self.pool
    }

    /// Packets waiting to be sent on this link.
    pub fn queue(&self) -> &PacketQueue {
        &self.queue
    }

    /// What went through this link.
    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// This link's line of the counters report.
    pub(crate) fn report(&self) -> LinkReport<'_> {
        LinkReport {
            name: &self.name,
            counters: self.counters,
            queue_drops: self.queue.dropped(),
            queue_high_water: self.queue.high_water(),
        }
    }

    pub(crate) fn learn(&mut self, address: crate::address::Address, now: Timestamp) -> bool {
        self.last_learned = self.last_learned.max(now);
        self.pool.learn(address, now)
    }

    /// Learns `address`, heard at `now` on another link of this link's group (the same
    /// path to it), without taking it as a sign that this link lives: a UDP remote that
    /// fell silent still goes (see [`Link::is_stale`]) however much its group hears.
    pub(crate) fn learn_for_group(
        &mut self,
        address: crate::address::Address,
        now: Timestamp,
    ) -> bool {
        self.pool.learn(address, now)
    }

    /// True for a UDP link whose pool has been empty for the expiry time at `now`: its
    /// last address expired at `last_learned + expiry`, so it goes once `now` is more than
    /// twice the expiry after the last learning (present at exactly that time, gone after).
    pub(crate) fn is_stale(&self, now: Timestamp) -> bool {
        self.kind == LinkKind::Udp && now > self.last_learned + self.pool.expiry().saturating_mul(2)
    }
}
