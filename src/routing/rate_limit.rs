//! Holding accepted packets to their rule's `with rate` (see [`crate::filter::Cap`]).
//!
//! State is kept per *stream*: (destination link, source address, message id). Each
//! stream has the earliest time its next packet may pass. The first packet passes at
//! once; each packet that passes moves that time on by one interval from where it was
//! (not from when the packet came), so a packet arriving a little late does not delay
//! the ones after it and the long-run rate is exactly the rule's. After a whole interval
//! (the one of the cap the packet now meets) of silence the schedule starts afresh (no
//! burst is saved up). A packet that comes before its time is dropped, not queued: the
//! newest state wins.
//!
//! The table is bounded ([`RATE_TABLE_ENTRIES`] streams in sets of 4, each set one
//! 64-byte cache line). A stream is known by a 64-bit fingerprint of its (link, source,
//! message id) and lives in one of three sets: first the set of (link / 4, source,
//! message id), so that the streams of one packet on four neighbouring links share a
//! line and a broadcast to 10 links reads about 3 lines, not 10; when that set is taken
//! by other groups, one of two sets of its own, chosen by the fingerprint. (A group
//! fills a whole set, so with the first choice alone two groups meeting in one set
//! evicted each other even in a nearly empty table. With the other two, fewer live
//! streams are evicted than when each stream had one set of its own: of 2,000 streams
//! on 10 links about 5 instead of 8, of 6,000 about 280 instead of 600.)
//!
//! A new stream takes an empty slot of its three sets, else one whose schedule has
//! lapsed (which behaves exactly as an absent one), or else the place of the one of the
//! twelve that is due soonest, counted in [`RateLimiter::evicted`] (that stream's next
//! packet passes as a first one). A removed link's streams are not swept: link ids are
//! never reused, so they are never met again, and their places are taken as their
//! schedules lapse.
//!
//! Two streams share a schedule only if their fingerprints are equal and they meet in a
//! set, a chance below one in 2^63 for any two streams.

use super::link::LinkId;
use crate::address::Address;

/// Most streams whose schedule is kept.
pub const RATE_TABLE_ENTRIES: usize = 8192;
/// Ways of each set of the table.
const WAYS: usize = 4;

/// One stream's schedule (16 bytes).
#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    /// 0 = empty; else the stream's [`fingerprint`] (never 0).
    tag: u64,
    /// When the next packet may pass, in nanoseconds since the start of time (584
    /// years fit).
    next: u64,
}

/// The [`WAYS`] slots of one set: one cache line.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
struct Set([Slot; WAYS]);

/// The odd constant of Fibonacci hashing (2^64 / the golden ratio).
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The stream's message id and source, in 48 bits.
#[inline]
fn stream_bits(source: Address, message_id: u32) -> u64 {
    u64::from(message_id) << 16 | u64::from(source.to_u16())
}

/// MurmurHash3's 64-bit finalizer: a bijection that mixes every bit into every other.
#[inline]
fn mix(mut x: u64) -> u64 {
    x ^= x >> 33;
    x = x.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    x ^= x >> 33;
    x = x.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    x ^ (x >> 33)
}

/// The fingerprint of stream (`link`, `bits`): never 0.
#[inline]
fn fingerprint(link: LinkId, bits: u64) -> u64 {
    mix(link.0.wrapping_mul(GOLDEN) ^ bits) | 1
}

/// The schedules of rate-capped streams; see the module documentation.
#[derive(Debug, Clone)]
pub struct RateLimiter {
    sets: Box<[Set]>,
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
            sets: vec![Set::default(); sets].into_boxed_slice(),
            shift: 64 - sets.trailing_zeros(),
            len: 0,
            evicted: 0,
        }
    }

    /// The set of `hash`'s top bits.
    #[inline]
    fn index(&self, hash: u64) -> usize {
        let last = self.sets.len() - 1;
        hash.checked_shr(self.shift).unwrap_or(0) as usize & last
    }

    /// A stream's first choice of set: that of its group of four neighbouring links.
    #[inline]
    fn group_set(&self, link: LinkId, bits: u64) -> usize {
        self.index(((link.0 >> 2).rotate_left(48) ^ bits).wrapping_mul(GOLDEN))
    }

    /// A stream's second and third choices of set: two of its own, by (different bits
    /// of) its fingerprint `tag`.
    #[inline]
    fn own_sets(&self, tag: u64) -> [usize; 2] {
        [self.index(tag), self.index(tag.rotate_left(24))]
    }

    /// The way of set `set` that holds stream `tag`, if one does.
    #[inline]
    fn find(&self, set: usize, tag: u64) -> Option<usize> {
        self.sets[set].0.iter().position(|s| s.tag == tag)
    }

    /// Whether a packet of `message_id` from `source` may go to `link` at `now` under a
    /// cap of one packet per `interval`, both in nanoseconds (`interval` above 0); if
    /// so, it is counted against the stream.
    #[inline]
    pub fn allow(
        &mut self,
        link: LinkId,
        source: Address,
        message_id: u32,
        interval: u64,
        now: u64,
    ) -> bool {
        let bits = stream_bits(source, message_id);
        let tag = fingerprint(link, bits);
        let group = self.group_set(link, bits);
        if let Some(way) = self.find(group, tag) {
            return self.pass(group, way, interval, now);
        }
        let own = self.own_sets(tag);
        for set in own {
            if let Some(way) = self.find(set, tag) {
                return self.pass(set, way, interval, now);
            }
        }
        self.insert([group, own[0], own[1]], tag, interval, now);
        true
    }

    /// A packet of the stream in `way` of `set`: whether it may pass now, and if so its
    /// schedule moves on.
    #[inline]
    fn pass(&mut self, set: usize, way: usize, interval: u64, now: u64) -> bool {
        let slot = &mut self.sets[set].0[way];
        if now < slot.next {
            return false;
        }
        let lapses = slot.next.saturating_add(interval);
        slot.next = if now < lapses {
            lapses
        } else {
            now.saturating_add(interval)
        };
        true
    }

    /// Starts stream `tag` at `now` in one of `sets` (in that order of preference): in an
    /// empty slot, else a lapsed one, else in place of the one due soonest (counted as
    /// evicted).
    #[inline(never)]
    fn insert(&mut self, sets: [usize; 3], tag: u64, interval: u64, now: u64) {
        let places = sets
            .into_iter()
            .flat_map(|s| (0..WAYS).map(move |w| (s, w)));
        let slot = |(s, w): (usize, usize)| self.sets[s].0[w];
        let lapsed = |x: Slot| x.next.saturating_add(interval) <= now;
        let (s, w) = places
            .clone()
            .find(|&p| slot(p).tag == 0)
            .or_else(|| places.clone().find(|&p| lapsed(slot(p))))
            .or_else(|| places.min_by_key(|&p| slot(p).next))
            .unwrap_or((sets[0], 0));
        let old = self.sets[s].0[w];
        if old.tag == 0 {
            self.len += 1;
        } else if !lapsed(old) {
            self.evicted += 1;
        }
        self.sets[s].0[w] = Slot {
            tag,
            next: now.saturating_add(interval),
        };
    }

    /// Forgets every stream (a reload that changed the rules).
    pub fn clear(&mut self) {
        if self.len > 0 {
            self.sets.fill(Set::default());
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

    /// Nanoseconds in `ms` milliseconds.
    const fn ms(ms: u64) -> u64 {
        ms * 1_000_000
    }

    fn passes(l: &mut RateLimiter, at: &[u64], interval: u64) -> Vec<u64> {
        at.iter()
            .copied()
            .filter(|&t| l.allow(LinkId(1), Address::new(1, 1), 30, ms(interval), ms(t)))
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
    fn streams_are_apart() {
        let mut l = RateLimiter::default();
        let i = ms(1000);
        // Links 0 to 3 share a set; 4 is in another.
        for link in 0..5 {
            assert!(l.allow(LinkId(link), Address::new(1, 1), 30, i, 0));
        }
        assert!(l.allow(LinkId(1), Address::new(2, 1), 30, i, 0));
        assert!(l.allow(LinkId(1), Address::new(1, 1), 31, i, 0));
        assert!(l.allow(LinkId(1), Address::new(1, 1), 30 + (1 << 24), i, 0));
        for link in 0..5 {
            assert!(!l.allow(LinkId(link), Address::new(1, 1), 30, i, ms(10)));
        }
        assert!(!l.allow(LinkId(1), Address::new(2, 1), 30, i, ms(10)));
        assert!(!l.allow(LinkId(1), Address::new(1, 1), 31, i, ms(10)));
        assert_eq!(l.len(), 8);
        assert_eq!(l.evicted(), 0);
        // Ids far apart stay apart too.
        let (a, b) = (LinkId(1), LinkId(1 + (1 << 23)));
        let mut l = RateLimiter::default();
        assert!(l.allow(a, Address::new(1, 1), 30, i, 0));
        assert!(l.allow(b, Address::new(1, 1), 30, i, 0));
        assert!(!l.allow(a, Address::new(1, 1), 30, i, 1));
        assert!(!l.allow(b, Address::new(1, 1), 30, i, 1));
    }

    #[test]
    fn the_table_is_bounded() {
        let mut l = RateLimiter::with_capacity(64);
        let i = ms(10_000);
        for s in 0..1000u16 {
            assert!(l.allow(LinkId(1), Address::from_u16(s), 30, i, 0));
            assert!(l.len() <= 64);
        }
        assert_eq!(l.len() as u64 + l.evicted(), 1000);
        // Lapsed streams give their place up uncounted.
        let before = l.evicted();
        for s in 0..1000u16 {
            l.allow(LinkId(1), Address::from_u16(s), 31, i, ms(30_000));
        }
        assert_eq!(l.evicted() - before, 1000 - 64);
    }

    #[test]
    fn groups_that_meet_in_a_set_do_not_evict_each_other() {
        // 1,000 streams (100 scattered senders and message ids on 10 links) in a table
        // of 8,192: groups of links meet in some sets, and move on to sets of their own.
        // (With the first choice alone, about 50 would be evicted.)
        let mut l = RateLimiter::default();
        let i = ms(500);
        let mut passed_again = 0;
        for round in 0..2 {
            for k in 1..=100 {
                let h = mix(k);
                let (source, message) = (Address::from_u16(h as u16), (h >> 40) as u32);
                for link in 0..10 {
                    let passed = l.allow(LinkId(link), source, message, i, ms(round));
                    assert!(passed || round == 1);
                    passed_again += u64::from(passed && round == 1);
                }
            }
        }
        assert!(l.evicted() <= 5, "{} evicted", l.evicted());
        assert!(passed_again <= l.evicted());
    }

    #[test]
    fn a_removed_links_streams_lapse_and_give_their_places_up() {
        // A table full of one link's streams; the link goes, and another's streams come
        // once those schedules lapsed: they evict no more than in an empty table.
        let i = ms(500);
        let mut l = RateLimiter::with_capacity(64);
        for s in 0..64u16 {
            l.allow(LinkId(7), Address::from_u16(s), 30, i, 0);
        }
        let mut fresh = RateLimiter::with_capacity(64);
        let before = l.evicted();
        for s in 0..64u16 {
            assert!(l.allow(LinkId(8), Address::from_u16(s), 30, i, ms(1000)));
            assert!(fresh.allow(LinkId(8), Address::from_u16(s), 30, i, ms(1000)));
        }
        assert_eq!(l.evicted() - before, fresh.evicted());
        // Not yet lapsed, they are live streams.
        let mut l = RateLimiter::with_capacity(64);
        for s in 0..64u16 {
            l.allow(LinkId(7), Address::from_u16(s), 30, i, 0);
        }
        let before = l.evicted();
        for s in 0..64u16 {
            l.allow(LinkId(8), Address::from_u16(s), 30, i, ms(999));
        }
        assert!(l.evicted() - before > fresh.evicted());
    }
}
