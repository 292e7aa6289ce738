//! A bounded memo of filter verdicts keyed by (message id, source, destination, signed),
//! each with the number of its rule walk's trace (see `super::trace`) so that answers
//! from the memo still count the rules that matched, and the rank of the deciding
//! rule's `with rate` (see [`super::Cap`]) so that they give the cap without a second
//! look-up.
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

/// Set in a slot's `word` when the verdict is reject.
const REJECT: u32 = 1 << 31;
/// The low bits of a slot's `word` that hold the trace number.
const TRACE_BITS: u32 = 12;
const TRACE_MASK: u32 = (1 << TRACE_BITS) - 1;
/// The largest cap rank a slot holds (the bits between the trace number and [`REJECT`]).
pub(crate) const MAX_RANK: u32 = (REJECT >> TRACE_BITS) - 1;
// Every interned trace's number fits its bits.
const _: () = assert!(super::trace::MAX_TRACES <= 1 << TRACE_BITS);

#[derive(Debug, Clone, Copy)]
struct Slot {
    key: u64,
    /// The accept priority (0 for a reject).
    priority: i32,
    /// [`REJECT`] for a reject, the cap rank (bits 12 to 30) and the trace number (bits
    /// 0 to 11).
    word: u32,
}

impl Slot {
    fn verdict(self) -> Verdict {
        if self.word & REJECT != 0 {
            Verdict::Reject
        } else {
            Verdict::Accept(self.priority)
        }
    }
}

/// A remembered verdict with its trace number and cap rank (0 for none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Memo {
    pub(crate) verdict: Verdict,
    pub(crate) trace: u32,
    pub(crate) rank: u32,
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
            word: REJECT,
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
            .map(|m| m.verdict)
    }

    /// The remembered verdict with its trace number and cap rank, if any.
    #[inline]
    pub(crate) fn get_traced(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
    ) -> Option<Memo> {
        let key = Self::key(message_id, source, dest, signed);
        let i = self.index(key);
        match self.slots.get(i) {
            Some(s) if s.key == key => {
                self.stats.hits += 1;
                Some(Memo {
                    verdict: s.verdict(),
                    trace: s.word & TRACE_MASK,
                    rank: (s.word & !REJECT) >> TRACE_BITS,
                })
            }
            _ => {
                self.stats.misses += 1;
                None
            }
        }
    }

    /// Remembers `verdict` (with trace number 0 and no cap), replacing the slot's
    /// previous entry.
    #[inline]
    pub fn insert(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        verdict: Verdict,
    ) {
        let memo = Memo {
            verdict,
            trace: 0,
            rank: 0,
        };
        self.insert_traced(message_id, source, dest, signed, memo);
    }

    /// Remembers `memo`, replacing the slot's previous entry. Its trace number must be
    /// below [`super::trace::MAX_TRACES`] and its rank at most [`MAX_RANK`] (0 for a
    /// reject); a memo beyond them is not remembered.
    #[inline]
    pub(crate) fn insert_traced(
        &mut self,
        message_id: u32,
        source: Address,
        dest: Address,
        signed: bool,
        memo: Memo,
    ) {
        if memo.trace > TRACE_MASK || memo.rank > MAX_RANK {
            return;
        }
        let key = Self::key(message_id, source, dest, signed);
        let i = self.index(key);
        let (priority, word) = match memo.verdict {
            Verdict::Accept(p) => (p, memo.rank << TRACE_BITS | memo.trace),
            Verdict::Reject => (0, REJECT | memo.trace),
        };
        if let Some(s) = self.slots.get_mut(i) {
            *s = Slot {
                key,
                priority,
                word,
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
    fn trace_and_rank_come_back_as_given() {
        let mut c = VerdictCache::new(16);
        let memo = |verdict, trace, rank| Memo {
            verdict,
            trace,
            rank,
        };
        let top = memo(Verdict::Accept(-3), TRACE_MASK, MAX_RANK);
        c.insert_traced(4, a(1, 1), a(2, 2), false, top);
        assert_eq!(c.get_traced(4, a(1, 1), a(2, 2), false), Some(top));
        let reject = memo(Verdict::Reject, 5, 0);
        c.insert_traced(4, a(1, 1), a(2, 2), false, reject);
        assert_eq!(c.get_traced(4, a(1, 1), a(2, 2), false), Some(reject));
        // Beyond the bits: not remembered (the caller walks again).
        c.insert_traced(
            5,
            a(1, 1),
            a(2, 2),
            false,
            memo(Verdict::Accept(0), 0, MAX_RANK + 1),
        );
        assert_eq!(c.get_traced(5, a(1, 1), a(2, 2), false), None);
    }

    #[test]
    fn zeroed_slots_do_not_match_id_zero_from_zero_to_zero() {
        let mut c = VerdictCache::new(8);
        assert_eq!(c.get(0, a(0, 0), a(0, 0), false), None);
    }
}
