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
//! The table is bounded ([`RATE_TABLE_ENTRIES`] streams in sets of 4): a new stream takes
//! the place of one whose schedule has lapsed (which behaves exactly as an absent one),
//! or else of the one of its set that lapses soonest, counted in
//! [`RateLimiter::evicted`] (that stream's next packet passes as a first one). The streams
//! of a removed link are dropped with it.

use std::time::Duration;

use super::link::LinkId;
use super::time::Timestamp;
use crate::address::Address;

/// Most streams whose schedule is kept.
pub const RATE_TABLE_ENTRIES: usize = 8192;
/// Ways of each set of the table.
const WAYS: usize = 4;

/// One stream's schedule. Times are nanoseconds since the start (as
/// [`Timestamp::as_nanos`]; 584 years fit).
#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    /// 0 = empty; else the stream's [`key`].
    key: u64,
    /// The destination link (the key holds only its low bits).
    link: u64,
    /// When the next packet may pass.
    next: u64,
    /// From when the stream behaves as new (`next` plus the interval).
    lapsed: u64,
}

/// A stream's key: never 0; the link id's low 23 bits, the message id (24 bits, all the
/// dialect's) and the source address. Slots also keep the whole link id.
#[inline]
fn key(link: LinkId, source: Address, message_id: u32) -> u64 {
    1 << 63
        | (link.0 & 0x7F_FFFF) << 40
        | u64::from(message_id & 0xFF_FFFF) << 16
        | u64::from(source.to_u16())
}

/// The schedules of rate-capped streams; see the module documentation.
///
/// Set-associative: a stream hashes to one set of [`WAYS`] slots; a new stream takes an
/// empty or lapsed slot of its set, or else the one that lapses soonest (counted as
/// evicted). A lookup is one multiply and up to four compares in one cache line pair.
#[derive(Debug, Clone)]
pub struct RateLimiter {
    slots: Box<[Slot]>,
    /// `64 - log2(sets)`, for Fibonacci hashing.
    shift: u32,
    len: usize,
    evicted: u64,
}

impl Default for RateLimiter {
    fn default() -> Self {
        RateLimiter::with_capacity(RATE_TABLE_ENTRIES)
    }
}

impl RateLimiter {
    /// A limiter that keeps at most `capacity` streams (rounded up to a power of two, at
    /// least [`WAYS`]).
    pub fn with_capacity(capacity: usize) -> Self {
        let sets = capacity.div_ceil(WAYS).max(1).next_power_of_two();
        RateLimiter {
            slots: vec![Slot::default(); sets * WAYS].into_boxed_slice(),
            shift: 64 - sets.trailing_zeros(),
            len: 0,
            evicted: 0,
        }
    }

    #[inline]
    fn set(&mut self, key: u64) -> &mut [Slot] {
        let h = key.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let set = h.checked_shr(self.shift).unwrap_or(0) as usize;
        let start = set * WAYS;
        &mut self.slots[start..start + WAYS]
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
        let key = key(link, source, message_id);
        let now = u64::try_from(now.as_nanos()).unwrap_or(u64::MAX);
        let interval = u64::try_from(interval.as_nanos()).unwrap_or(u64::MAX);
        let set = self.set(key);
        if let Some(slot) = set.iter_mut().find(|s| s.key == key && s.link == link.0) {
            if now < slot.next {
                return false;
            }
            slot.next = if now < slot.lapsed {
                slot.next.saturating_add(interval)
            } else {
                now.saturating_add(interval)
            };
            slot.lapsed = slot.next.saturating_add(interval);
            return true;
        }
        // A new stream: an empty or lapsed slot, else the one that lapses soonest.
        let mut victim = 0;
        for (i, s) in set.iter().enumerate() {
            if s.key == 0 || s.lapsed <= now {
                victim = i;
                break;
            }
            if s.lapsed < set[victim].lapsed {
                victim = i;
            }
        }
        let old = set[victim];
        let next = now.saturating_add(interval);
        set[victim] = Slot {
            key,
            link: link.0,
            next,
            lapsed: next.saturating_add(interval),
        };
        if old.key == 0 {
            self.len += 1;
        } else if old.lapsed > now {
            self.evicted += 1;
        }
        true
    }

    /// Forgets the streams of `link` (a removed link).
    pub fn forget_link(&mut self, link: LinkId) {
        if self.len == 0 {
            return;
        }
        for s in self.slots.iter_mut() {
            if s.key != 0 && s.link == link.0 {
                *s = Slot::default();
                self.len -= 1;
            }
        }
    }

    /// Forgets every stream (a reload that changed the rules).
    pub fn clear(&mut self) {
        if self.len > 0 {
            self.slots.fill(Slot::default());
            self.len = 0;
        }
    }

    /// Slots holding a stream now (lapsed ones included until reused).
    #[cfg(test)]
    fn len(&self) -> usize {
        self.len
    }

    /// Live streams forgotten because their set was full.
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
        assert_eq!(l.len() as u64 + l.evicted(), 1000);
        // Lapsed streams give their place up uncounted.
        let before = l.evicted();
        for s in 0..1000u16 {
            l.allow(LinkId(1), Address::from_u16(s), 31, i, MS(30_000));
        }
        assert_eq!(l.evicted() - before, 1000 - 64);
        // Ids that share the key's low bits stay apart.
        let mut l = RateLimiter::default();
        let (a, b) = (LinkId(1), LinkId(1 + (1 << 23)));
        assert!(l.allow(a, Address::new(1, 1), 30, i, MS(0)));
        assert!(l.allow(b, Address::new(1, 1), 30, i, MS(0)));
        assert!(!l.allow(a, Address::new(1, 1), 30, i, MS(1)));
        assert!(!l.allow(b, Address::new(1, 1), 30, i, MS(1)));
    }
}
