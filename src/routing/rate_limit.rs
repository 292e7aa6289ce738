//! Holding accepted packets to their rule's `with rate` (see [`crate::filter::Cap`]).
//!
//! State is kept per *stream*: (destination link, source address, message id). Each
//! stream has the earliest time its next packet may pass. The first packet passes at
//! once; each packet that passes moves that time on by one interval from where it was
//! (not from when the packet came), so a packet arriving a little late does not delay
//! the ones after it and the long-run rate is exactly the rule's. After a whole interval
//! of silence the schedule starts afresh (no burst is saved up). A packet that comes
//! before its time is dropped, not queued: the newest state wins.
//!
//! The table is bounded ([`RATE_TABLE_ENTRIES`]): when it is full, streams whose schedule
//! has lapsed (which behave exactly as absent ones) are forgotten; if that frees less
//! than an eighth, arbitrary streams are forgotten too and counted in
//! [`RateLimiter::evicted`]. The streams of a removed link are dropped with it.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::time::Duration;

use super::link::LinkId;
use super::sources::IntHasher;
use super::time::Timestamp;
use crate::address::Address;

/// Most streams whose schedule is kept.
pub const RATE_TABLE_ENTRIES: usize = 16384;

#[derive(Debug, Clone, Copy)]
struct Slot {
    /// When the next packet may pass.
    next: Timestamp,
    /// From when the stream behaves as new (`next` plus the interval).
    lapsed: Timestamp,
}

/// The schedules of rate-capped streams; see the module documentation.
#[derive(Debug, Clone)]
pub struct RateLimiter {
    slots: HashMap<(u64, u64), Slot, BuildHasherDefault<IntHasher>>,
    capacity: usize,
    evicted: u64,
}

impl Default for RateLimiter {
    fn default() -> Self {
        RateLimiter::with_capacity(RATE_TABLE_ENTRIES)
    }
}

impl RateLimiter {
    /// A limiter that keeps at most `capacity` streams (at least 8).
    pub fn with_capacity(capacity: usize) -> Self {
        RateLimiter {
            slots: HashMap::default(),
            capacity: capacity.max(8),
            evicted: 0,
        }
    }

    /// Whether a packet of `message_id` from `source` may go to `link` at `now` under a
    /// cap of one packet per `interval`; if so, it is counted against the stream.
    #[inline]
    pub fn allow(
        &mut self,
        link: LinkId,
        source: Address,
        message_id: u32,
        interval: Duration,
        now: Timestamp,
    ) -> bool {
        let key = (
            link.0,
            u64::from(message_id) << 16 | u64::from(source.to_u16()),
        );
        if let Some(slot) = self.slots.get_mut(&key) {
            if now < slot.next {
                return false;
            }
            let next = if now < slot.lapsed {
                slot.next + interval
            } else {
                now + interval
            };
            *slot = Slot {
                next,
                lapsed: next + interval,
            };
            return true;
        }
        if self.slots.len() >= self.capacity {
            self.make_room(now);
        }
        let next = now + interval;
        self.slots.insert(
            key,
            Slot {
                next,
                lapsed: next + interval,
            },
        );
        true
    }

    /// Forgets lapsed streams, then (if that freed less than an eighth) any streams,
    /// until an eighth of the table is free.
    fn make_room(&mut self, now: Timestamp) {
        self.slots.retain(|_, s| now < s.lapsed);
        let goal = self.capacity - self.capacity / 8;
        if self.slots.len() > goal {
            let excess = self.slots.len() - goal;
            let victims: Vec<_> = self.slots.keys().take(excess).copied().collect();
            for k in victims {
                self.slots.remove(&k);
            }
            self.evicted += excess as u64;
        }
    }

    /// Forgets the streams of `link` (a removed link).
    pub fn forget_link(&mut self, link: LinkId) {
        if !self.slots.is_empty() {
            self.slots.retain(|k, _| k.0 != link.0);
        }
    }

    /// Forgets every stream (a reload that changed the rules).
    pub fn clear(&mut self) {
        self.slots.clear();
    }

    /// Streams kept now.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether no stream is kept.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Live streams forgotten because the table was full.
    pub fn evicted(&self) -> u64 {
        self.evicted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Timestamp = Timestamp::from_millis;

    fn passes(l: &mut RateLimiter, at: &[u64], interval: u64) -> Vec<u64> {
        let i = Duration::from_millis(interval);
        at.iter()
            .copied()
            .filter(|&t| l.allow(LinkId(1), Address::new(1, 1), 30, i, MS(t)))
            .collect()
    }

    #[test]
    fn first_at_once_then_on_schedule_without_drift() {
        let mut l = RateLimiter::default();
        // 50 Hz input from 7 ms, cap 2/s: one every 500 ms on the schedule 7, 507, ...
        let input: Vec<u64> = (0..150).map(|k| 7 + 20 * k).collect();
        assert_eq!(
            passes(&mut l, &input, 500),
            vec![7, 507, 1007, 1507, 2007, 2507]
        );
        // Late arrivals (every 300 ms) keep the long-run rate: no drift.
        let mut l = RateLimiter::default();
        let input: Vec<u64> = (0..20).map(|k| 300 * k).collect();
        assert_eq!(
            passes(&mut l, &input, 500),
            vec![
                0, 600, 1200, 1500, 2100, 2700, 3000, 3600, 4200, 4500, 5100, 5700
            ]
        );
    }

    #[test]
    fn silence_saves_no_burst() {
        let mut l = RateLimiter::default();
        assert_eq!(
            passes(&mut l, &[0, 5000, 5001, 5499, 5500], 500),
            vec![0, 5000, 5500]
        );
    }

    #[test]
    fn streams_are_apart_and_links_forgotten() {
        let mut l = RateLimiter::default();
        let i = Duration::from_secs(1);
        assert!(l.allow(LinkId(1), Address::new(1, 1), 30, i, MS(0)));
        assert!(l.allow(LinkId(2), Address::new(1, 1), 30, i, MS(0)));
        assert!(l.allow(LinkId(1), Address::new(2, 1), 30, i, MS(0)));
        assert!(l.allow(LinkId(1), Address::new(1, 1), 31, i, MS(0)));
        assert!(!l.allow(LinkId(1), Address::new(1, 1), 30, i, MS(10)));
        l.forget_link(LinkId(1));
        assert_eq!(l.len(), 1);
        assert!(l.allow(LinkId(1), Address::new(1, 1), 30, i, MS(20)));
    }

    #[test]
    fn the_table_is_bounded() {
        let mut l = RateLimiter::with_capacity(64);
        let i = Duration::from_secs(10);
        for s in 0..1000u16 {
            assert!(l.allow(LinkId(1), Address::from_u16(s), 30, i, MS(0)));
            assert!(l.len() <= 64);
        }
        assert!(l.evicted() > 0);
        // Lapsed streams go first, uncounted.
        let mut l = RateLimiter::with_capacity(64);
        for s in 0..64u16 {
            l.allow(LinkId(1), Address::from_u16(s), 30, i, MS(0));
        }
        l.allow(LinkId(1), Address::from_u16(999), 30, i, MS(30_000));
        assert_eq!((l.len(), l.evicted()), (1, 0));
    }
}
