//! Who has work, without walking every interface (quinn's wakers, mini-redis'
//! `expirations`): the interfaces with output to hand out, in the order they got it,
//! and the one next deadline of each interface that has one, ordered by time.
//!
//! A thousand idle TCP connections cost nothing per frame: an interface enters the
//! ready queue only when a packet is queued for one of its links (or its pacer lets a
//! held-back packet go, or it opens), and the deadline set only holds interfaces with a
//! deadline (held-back bytes, a paced packet, a reopen attempt).

use std::collections::{BTreeSet, VecDeque};

use super::InterfaceId;
use crate::routing::time::Timestamp;

/// A map keyed by link id (a counter the router hands out, never chosen by a peer),
/// hashed with one multiplication: it is looked up for every packet queued.
pub(super) type ByLink<V> = std::collections::HashMap<
    crate::routing::link::LinkId,
    V,
    std::hash::BuildHasherDefault<crate::routing::sources::IntHasher>,
>;

/// Interfaces with output waiting, each at most once, oldest first.
#[derive(Debug, Default)]
pub(super) struct ReadySet {
    queue: VecDeque<InterfaceId>,
    /// Whether each interface (by number) is in `queue`.
    queued: Vec<bool>,
}

impl ReadySet {
    /// Adds `id` unless it is waiting already.
    #[inline]
    pub(super) fn mark(&mut self, id: InterfaceId) {
        if self.queued.len() <= id.0 {
            self.queued.resize(id.0 + 1, false);
        }
        if !self.queued[id.0] {
            self.queued[id.0] = true;
            self.queue.push_back(id);
        }
    }

    /// The oldest waiting interface, taken out.
    #[inline]
    pub(super) fn pop(&mut self) -> Option<InterfaceId> {
        let id = self.queue.pop_front()?;
        if let Some(q) = self.queued.get_mut(id.0) {
            *q = false;
        }
        Some(id)
    }

    /// True if interface `id` is waiting.
    #[inline]
    pub(super) fn contains(&self, id: InterfaceId) -> bool {
        self.queued.get(id.0).copied().unwrap_or(false)
    }

    /// True if some interface is waiting.
    #[inline]
    pub(super) fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }
}

/// The next deadline of each interface that has one, ordered by time.
#[derive(Debug, Default)]
pub(super) struct Deadlines {
    set: BTreeSet<(Timestamp, InterfaceId)>,
    /// The entry of each interface (by number) in `set`.
    of: Vec<Option<Timestamp>>,
}

impl Deadlines {
    /// Sets interface `id`'s deadline to `due` (None: it has none).
    #[inline]
    pub(super) fn set(&mut self, id: InterfaceId, due: Option<Timestamp>) {
        let old = self.of.get(id.0).copied().flatten();
        if old == due {
            return;
        }
        if let Some(t) = old {
            self.set.remove(&(t, id));
        }
        if self.of.len() <= id.0 {
            self.of.resize(id.0 + 1, None);
        }
        self.of[id.0] = due;
        if let Some(t) = due {
            self.set.insert((t, id));
        }
    }

    /// True if interface `id` has a deadline.
    #[inline]
    pub(super) fn has(&self, id: InterfaceId) -> bool {
        self.of.get(id.0).is_some_and(Option::is_some)
    }

    /// The earliest deadline.
    #[inline]
    pub(super) fn first(&self) -> Option<Timestamp> {
        self.set.first().map(|&(t, _)| t)
    }

    /// The interfaces whose deadline is at or before `now`, earliest first; their
    /// entries are removed (set them again after handling them).
    pub(super) fn take_due(&mut self, now: Timestamp, into: &mut Vec<InterfaceId>) {
        while let Some(&(t, id)) = self.set.first() {
            if t > now {
                break;
            }
            self.set.pop_first();
            if let Some(slot) = self.of.get_mut(id.0) {
                *slot = None;
            }
            into.push(id);
        }
    }

    /// How many interfaces have a deadline.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.set.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn an_interface_is_queued_once_until_taken() {
        let mut r = ReadySet::default();
        r.mark(InterfaceId(3));
        r.mark(InterfaceId(1));
        r.mark(InterfaceId(3));
        assert_eq!(r.pop(), Some(InterfaceId(3)));
        r.mark(InterfaceId(3));
        assert_eq!(r.pop(), Some(InterfaceId(1)));
        assert_eq!(r.pop(), Some(InterfaceId(3)));
        assert_eq!(r.pop(), None);
        assert!(r.is_empty());
    }

    #[test]
    fn deadlines_move_and_come_out_in_order() {
        let t = |ms| Timestamp::ZERO + Duration::from_millis(ms);
        let mut d = Deadlines::default();
        d.set(InterfaceId(0), Some(t(30)));
        d.set(InterfaceId(1), Some(t(10)));
        d.set(InterfaceId(2), Some(t(20)));
        d.set(InterfaceId(1), Some(t(40)));
        d.set(InterfaceId(2), None);
        assert_eq!(d.first(), Some(t(30)));
        let mut due = Vec::new();
        d.take_due(t(35), &mut due);
        assert_eq!(due, [InterfaceId(0)]);
        assert_eq!(d.len(), 1);
        d.set(InterfaceId(0), Some(t(50)));
        due.clear();
        d.take_due(t(50), &mut due);
        assert_eq!(due, [InterfaceId(1), InterfaceId(0)]);
        assert_eq!(d.first(), None);
    }
}
