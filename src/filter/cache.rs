//! A bounded memo of filter verdicts keyed by (message id, source, destination, signed),
//! each with the number of its rule walk's trace (see `super::trace`) so that answers
//! from the memo still count the rules that matched.
//!
//! Direct-mapped: each key hashes to one slot, and a new key overwrites whatever was
//! there. Memory is fixed at construction (16 bytes a slot); a lookup is one multiply,
//! one load and one compare, so it costs the same whether the configuration has one rule
//! or hundreds.

use super::Verdict;
use crate::address::Address;

/// Slots in the default cache (64 KiB): far more than the distinct (message, source,
/// destination) triples a real MAVLink network produces, small enough to stay in L2.
pub const DEFAULT_SLOTS: usize = 4096;

/// Marks an occupied slot; message ids use only the low 24 bits of their 32.
const VALID: u64 = 1 << 63;

/// Set in the key of a signed packet's verdict (bit 60: above any 24-bit message id and
/// the id 2^24 that stands for every unknown one, `dialect::UNKNOWN_ID`).
const SIGNED: u64 = 1 << 60;

/// Lookup counters of a [`VerdictCache`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CacheStats {
    /// Lookups answered from the memo.
    pub hits: u64,
    /// Lookups that needed a rule walk.
    pub misses: u64,
}

/// Set in a slot's `trace` word when the verdict is reject (trace numbers stay far below).
const REJECT: u32 = 1 << 31;

#[derive(Debug, Clone, Copy)]
struct Slot {
    key: u64,
    /// The accept priority (0 for a reject).
    priority: i32,
    /// The trace number, with [`REJECT`] set for a reject.
    trace: u32,
}

impl Slot {
    fn verdict(self) -> Verdict {
        if self.trace & REJECT != 0 {
            Verdict::Reject
        } else {
            Verdict::Accept(self.priority)
        }
    }
}

/// Fixed-size, direct-mapped verdict memo.
#[derive(Debug, Clone)]
pub struct VerdictCache {
    slots: Box<[Slot]>,
    shift: u32,
    stats: CacheStats,
}

impl VerdictCache {
    /// A cache of `slots` entries rounded up to a power of two; 0 disables it.
    pub fn new(slots: usize) -> Self {
        let n = if slots == 0 {
            0
        } else {
            slots.next_power_of_two()
        };
        let empty = Slot {
            key: 0,
            priority: 0,
            trace: REJECT,
        };
        VerdictCache {
            slots: vec![empty; n].into_boxed_slice(),
            shift: 64 - n.max(1).trailing_zeros(),
            stats: CacheStats::default(),
        }
    }

    #[inline]
    fn key(message_id: u32, source: Address, dest: Address, signed: bool) -> u64 {
        VALID
            | if signed { SIGNED } else { 0 }
            | (u64::from(message_id) << 32)
            | (u64::from(source.to_u16()) << 16)
            | u64::from(dest.to_u16())
    }

    #[inline]
    fn index(&self, key: u64) -> usize {
        // Fibonacci hashing; with one slot the shift is 64, so use checked_shr.
        key.wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .checked_shr(self.shift)
            .unwrap_or(0) as usize
    }

    /// The remembered verdict, if any.
    #[inline]
    pub fn get(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
    ) -> Option<Verdict> {
        self.get_traced(message_id, source, dest, signed)
            .map(|(v, _)| v)
    }

    /// The remembered verdict and its trace number, if any.
    #[inline]
    pub(crate) fn get_traced(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
    ) -> Option<(Verdict, u32)> {
        let key = Self::key(message_id, source, dest, signed);
        let i = self.index(key);
        match self.slots.get(i) {
            Some(s) if s.key == key => {
                self.stats.hits += 1;
                Some((s.verdict(), s.trace & !REJECT))
            }
            _ => {
                self.stats.misses += 1;
                None
            }
        }
    }

    /// Remembers `verdict` (with trace number 0), replacing the slot's previous entry.
    #[inline]
    pub fn insert(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        verdict: Verdict,
    ) {
        self.insert_traced(message_id, source, dest, signed, verdict, 0);
    }

    /// Remembers `verdict` and its trace number `trace` (below 2^31), replacing the
    /// slot's previous entry.
    #[inline]
    pub(crate) fn insert_traced(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        verdict: Verdict,
        trace: u32,
    ) {
        let key = Self::key(message_id, source, dest, signed);
        let i = self.index(key);
        let (priority, trace) = match verdict {
            Verdict::Accept(p) => (p, trace & !REJECT),
            Verdict::Reject => (0, trace | REJECT),
        };
        if let Some(s) = self.slots.get_mut(i) {
            *s = Slot {
                key,
                priority,
                trace,
            };
        }
    }

    /// Hits and misses so far.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(s: u8, c: u8) -> Address {
        Address::new(s, c)
    }

    #[test]
    fn remembers_and_counts() {
        let mut c = VerdictCache::new(16);
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), None);
        c.insert(4, a(1, 1), a(2, 2), false, Verdict::Accept(7));
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), Some(Verdict::Accept(7)));
        assert_eq!(c.get(4, a(1, 1), a(2, 3), false), None);
        assert_eq!(c.stats(), CacheStats { hits: 1, misses: 2 });
    }

    #[test]
    fn zero_slots_never_remembers() {
        let mut c = VerdictCache::new(0);
        c.insert(4, a(1, 1), a(2, 2), false, Verdict::Accept(7));
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), None);
    }

    #[test]
    fn one_slot_keeps_the_latest() {
        let mut c = VerdictCache::new(1);
        c.insert(4, a(1, 1), a(2, 2), false, Verdict::Accept(1));
        c.insert(5, a(1, 1), a(2, 2), false, Verdict::Reject);
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), None);
        assert_eq!(c.get(5, a(1, 1), a(2, 2), false), Some(Verdict::Reject));
    }

    #[test]
    fn signed_and_unsigned_verdicts_are_kept_apart() {
        let mut c = VerdictCache::new(64);
        c.insert(4, a(1, 1), a(2, 2), true, Verdict::Accept(3));
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), None);
        c.insert(4, a(1, 1), a(2, 2), false, Verdict::Reject);
        assert_eq!(c.get(4, a(1, 1), a(2, 2), true), Some(Verdict::Accept(3)));
        assert_eq!(c.get(4, a(1, 1), a(2, 2), false), Some(Verdict::Reject));
        // The largest message id does not reach the signed bit.
        c.insert(0xFF_FFFF, a(1, 1), a(2, 2), false, Verdict::Reject);
        assert_eq!(c.get(0xFF_FFFF, a(1, 1), a(2, 2), true), None);
    }

    #[test]
    fn zeroed_slots_do_not_match_id_zero_from_zero_to_zero() {
        let mut c = VerdictCache::new(8);
        assert_eq!(c.get(0, a(0, 0), a(0, 0), false), None);
    }
}
