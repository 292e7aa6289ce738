//! Per-rule hit counting that survives the verdict memo.
//!
//! A rule walk's *trace* — which rules' conditions matched, and which accept or reject
//! rule decided (if any) — depends only on the memo's key, like the verdict. So the memo
//! keeps a small trace number with each verdict, and an evaluation answered from the memo
//! adds one packet (and its bytes) to its trace's count: O(1) whatever the number of
//! rules. Per-rule totals are summed from the traces only when someone asks
//! ([`Traces::rule_counts`]).
//!
//! Traces are interned up to [`MAX_TRACES`]; beyond that a walk's rules are counted
//! directly and its verdict is not memoized, so the counts stay exact and memory bounded.

use std::collections::HashMap;

/// Most distinct traces kept; real configurations produce a handful.
pub(crate) const MAX_TRACES: usize = 4096;

/// The counts of one rule: evaluations its condition matched, and how many of them it
/// decided.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RuleCounts {
    /// (packet, destination) evaluations in which the rule's condition matched.
    pub packets: u64,
    /// The frame bytes of those evaluations.
    pub bytes: u64,
    /// How many of them this rule decided (accept and reject rules only; a `call` or
    /// `goto` rule leaves the decision to the rule inside that finally decides).
    pub decided: u64,
    /// Frames this rule accepted for a link but its `with rate` held back (dropped).
    pub rate_limited: u64,
}

/// Per-rule counts and the default action's, as [`Traces::rule_counts`] sums them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FilterCounts {
    /// By flat rule number (chains in order, their rules in order).
    pub rules: Vec<RuleCounts>,
    /// Evaluations no rule decided (the default action did).
    pub default_packets: u64,
    /// Their bytes.
    pub default_bytes: u64,
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct Trace {
    matched: Box<[u32]>,
    decider: Option<u32>,
}

/// The interned traces and their counts.
#[derive(Debug, Clone, Default)]
pub struct Traces {
    ids: HashMap<Trace, u32>,
    list: Vec<Trace>,
    packets: Vec<u64>,
    bytes: Vec<u64>,
    /// Counts of walks whose trace could not be interned (the table was full).
    direct: FilterCounts,
}

impl Traces {
    /// The number of the trace (`matched`, `decider`), interned now if new; `None` when
    /// the table is full.
    pub(crate) fn intern(&mut self, matched: &[u32], decider: Option<u32>) -> Option<u32> {
        let key = Trace {
            matched: matched.into(),
            decider,
        };
        if let Some(&id) = self.ids.get(&key) {
            return Some(id);
        }
        if self.list.len() >= MAX_TRACES {
            return None;
        }
        let id = self.list.len() as u32;
        self.ids.insert(key.clone(), id);
        self.list.push(key);
        self.packets.push(0);
        self.bytes.push(0);
        Some(id)
    }

    /// Counts one evaluation of `len` bytes with trace `id`.
    #[inline]
    pub(crate) fn hit(&mut self, id: u32, len: usize) {
        if let (Some(p), Some(b)) = (
            self.packets.get_mut(id as usize),
            self.bytes.get_mut(id as usize),
        ) {
            *p += 1;
            *b += len as u64;
        }
    }

    /// The accept or reject rule that decided trace `id` (`None`: the default action, or
    /// no such trace).
    #[inline]
    pub fn decider(&self, id: u32) -> Option<u32> {
        self.list.get(id as usize).and_then(|t| t.decider)
    }

    /// Counts one frame that rule `rule` accepted but its rate held back.
    pub fn rate_limited(&mut self, rule: u32) {
        let rules = &mut self.direct.rules;
        let r = rule as usize;
        if r >= rules.len() {
            rules.resize(r + 1, RuleCounts::default());
        }
        rules[r].rate_limited += 1;
    }

    /// Counts one evaluation of `len` bytes whose trace was not interned.
    pub(crate) fn hit_direct(&mut self, matched: &[u32], decider: Option<u32>, len: usize) {
        let d = &mut self.direct;
        add(d, matched, decider, 1, len as u64);
    }

    /// Counts `base` as if this table had counted it (the counts a reload carries over
    /// from the filter it replaces).
    pub(crate) fn carry(&mut self, base: &FilterCounts) {
        let d = &mut self.direct;
        if d.rules.len() < base.rules.len() {
            d.rules.resize(base.rules.len(), RuleCounts::default());
        }
        for (r, b) in d.rules.iter_mut().zip(&base.rules) {
            r.packets += b.packets;
            r.bytes += b.bytes;
            r.decided += b.decided;
            r.rate_limited += b.rate_limited;
        }
        d.default_packets += base.default_packets;
        d.default_bytes += base.default_bytes;
    }

    /// Per-rule totals for `rule_count` rules.
    pub fn rule_counts(&self, rule_count: usize) -> FilterCounts {
        let mut c = FilterCounts {
            rules: vec![RuleCounts::default(); rule_count],
            ..FilterCounts::default()
        };
        for (i, t) in self.list.iter().enumerate() {
            let (p, b) = (self.packets[i], self.bytes[i]);
            if p > 0 {
                add(&mut c, &t.matched, t.decider, p, b);
            }
        }
        for (r, d) in c.rules.iter_mut().zip(&self.direct.rules) {
            r.packets += d.packets;
            r.bytes += d.bytes;
            r.decided += d.decided;
            r.rate_limited += d.rate_limited;
        }
        c.default_packets += self.direct.default_packets;
        c.default_bytes += self.direct.default_bytes;
        c
    }
}

/// Adds `packets` evaluations of `bytes` with one trace to `c` (growing it as needed).
fn add(c: &mut FilterCounts, matched: &[u32], decider: Option<u32>, packets: u64, bytes: u64) {
    for &r in matched {
        let r = r as usize;
        if r >= c.rules.len() {
            c.rules.resize(r + 1, RuleCounts::default());
        }
        c.rules[r].packets += packets;
        c.rules[r].bytes += bytes;
    }
    match decider {
        Some(d) => {
            let d = d as usize;
            if d >= c.rules.len() {
                c.rules.resize(d + 1, RuleCounts::default());
            }
            c.rules[d].decided += packets;
        }
        None => {
            c.default_packets += packets;
            c.default_bytes += bytes;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interned_and_direct_counts_add_up() {
        let mut t = Traces::default();
        let a = t.intern(&[0, 2], Some(2)).unwrap_or(u32::MAX);
        assert_eq!(t.intern(&[0, 2], Some(2)), Some(a));
        let b = t.intern(&[1], None).unwrap_or(u32::MAX);
        assert_ne!(a, b);
        t.hit(a, 10);
        t.hit(a, 20);
        t.hit(b, 5);
        t.hit_direct(&[2], Some(2), 7);
        let c = t.rule_counts(3);
        assert_eq!(
            c.rules,
            vec![
                RuleCounts {
                    packets: 2,
                    bytes: 30,
                    decided: 0,
                    rate_limited: 0
                },
                RuleCounts {
                    packets: 1,
                    bytes: 5,
                    decided: 0,
                    rate_limited: 0
                },
                RuleCounts {
                    packets: 3,
                    bytes: 37,
                    decided: 3,
                    rate_limited: 0
                },
            ]
        );
        assert_eq!((c.default_packets, c.default_bytes), (1, 5));
    }

    #[test]
    fn the_table_is_bounded() {
        let mut t = Traces::default();
        for i in 0..MAX_TRACES as u32 {
            assert!(t.intern(&[i], None).is_some());
        }
        assert_eq!(t.intern(&[u32::MAX], None), None);
        assert!(t.intern(&[0], None).is_some());
    }
}
