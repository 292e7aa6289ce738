//! What each sender sends: frames per (source address, message type), and the MAVLink
//! sequence gaps per source address — the loss a radio link causes upstream of the router.
//!
//! Both tables are bounded, so a flood of forged source addresses costs no memory:
//! - (source, message) pairs live in [`SourceTable`]: 4096 entries in 1024 sets of 4; a
//!   new pair takes the place of the least recently seen pair of its set (counted in
//!   [`SourceTable::evicted`]). A real network's few dozen pairs never collide out.
//! - Sequence state lives in [`Sequences`] for up to [`MAX_SEQUENCE_SOURCES`] source
//!   addresses; frames of further sources are counted in [`Sequences::untracked`] only.
//!
//! The gap rule: every sender numbers its frames with a one-byte counter `seq` that goes
//! up by one per frame and wraps from 255 to 0. For a source whose last frame had `seq`
//! `s`, the next is expected with `s + 1`; a frame arriving with `seq` `n` instead means
//! `(n − expected) mod 256` frames were lost, when that is below 128 (a forward jump).
//! and `n + 1` is expected next. A larger difference is a step back (a duplicate, or a
//! frame overtaken by another): it counts nothing and the expectation stays, so a
//! repeated frame is not taken for a loss. A sender
//! that reaches the router over two links, or two senders sharing one address, look
//! like loss and duplicates to this rule.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use crate::address::Address;

/// Entries of the (source, message) table.
pub(crate) const SOURCE_TABLE_ENTRIES: usize = 4096;
/// Ways of each set of the (source, message) table.
const WAYS: usize = 4;
/// Most source addresses whose sequence numbers are followed.
pub(crate) const MAX_SEQUENCE_SOURCES: usize = 4096;

/// One (source, message) pair's counts.
#[derive(Debug, Clone, Copy, Default)]
struct Entry {
    /// 0 = empty; else `1 << 40 | message_id << 16 | source`.
    key: u64,
    frames: u64,
    /// When it was last seen (the table's frame count then).
    last_seen: u64,
    /// `frames` at the last [`SourceTable::sample`].
    sampled: u64,
    /// Frames per second between the last two samples.
    rate: f64,
}

/// One (source, message) pair as [`SourceTable::sample`] reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceCount {
    /// The sender's address.
    pub source: Address,
    /// The message id.
    pub message_id: u32,
    /// Frames received since the pair entered the table.
    pub frames: u64,
    /// Frames per second between the last two samples.
    pub rate_fps: f64,
}

/// Frames per (source address, message id); see the module documentation for the bound.
#[derive(Debug, Clone)]
pub struct SourceTable {
    entries: Box<[Entry]>,
    /// Frames counted so far (the clock of least-recent eviction).
    seen: u64,
    evicted: u64,
}

impl Default for SourceTable {
    fn default() -> Self {
        SourceTable {
            entries: vec![Entry::default(); SOURCE_TABLE_ENTRIES].into_boxed_slice(),
            seen: 0,
            evicted: 0,
        }
    }
}

impl SourceTable {
    /// Counts one frame with `message_id` from `source`.
    #[inline]
    pub(crate) fn count(&mut self, source: Address, message_id: u32) {
        self.seen += 1;
        let key = 1 << 40 | u64::from(message_id & 0xFF_FFFF) << 16 | u64::from(source.to_u16());
        let sets = SOURCE_TABLE_ENTRIES / WAYS;
        let set = (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 54) as usize % sets;
        let Some(ways) = self.entries.get_mut(set * WAYS..set * WAYS + WAYS) else {
            return;
        };
        if let Some(e) = ways.iter_mut().find(|e| e.key == key) {
            e.frames += 1;
            e.last_seen = self.seen;
            return;
        }
        // A new pair takes an empty way, or else the least recently seen one.
        let age = |e: &Entry| if e.key == 0 { 0 } else { e.last_seen };
        let mut v = 0;
        for i in 1..ways.len() {
            if age(&ways[i]) < age(&ways[v]) {
                v = i;
            }
        }
        if ways[v].key != 0 {
            self.evicted += 1;
        }
        ways[v] = Entry {
            key,
            frames: 1,
            last_seen: self.seen,
            sampled: 0,
            rate: 0.0,
        };
    }

    /// Pairs that lost their place to a new pair of their set.
    pub(crate) fn evicted(&self) -> u64 {
        self.evicted
    }

    /// Every pair, with its rate over the `interval_s` seconds since the last sample
    /// (when `interval_s` is positive; else the rates of the last sample stay).
    pub(crate) fn sample(&mut self, interval_s: f64) -> Vec<SourceCount> {
        let mut out = Vec::new();
        for e in self.entries.iter_mut().filter(|e| e.key != 0) {
            if interval_s > 0.0 {
                e.rate = (e.frames - e.sampled) as f64 / interval_s;
                e.sampled = e.frames;
            }
            out.push(SourceCount {
                source: Address::from_u16(e.key as u16),
                message_id: ((e.key >> 16) & 0xFF_FFFF) as u32,
                frames: e.frames,
                rate_fps: e.rate,
            });
        }
        out.sort_by_key(|c| (c.source, c.message_id));
        out
    }
}

/// The sequence state of one source address.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SequenceCount {
    /// Frames received from it.
    pub received: u64,
    /// Frames its sequence numbers say were lost on the way (see the module's rule).
    pub lost: u64,
    /// The `seq` expected next.
    expected: u8,
}

/// A hasher for small integer keys: one multiply (the keys are not chosen to collide
/// by anyone who could gain from it; the table is bounded anyway).
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct IntHasher(u64);

impl Hasher for IntHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_u16(&mut self, v: u16) {
        self.0 = u64::from(v).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0 ^ v).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// Sequence gaps per source address; see the module documentation for the rule.
#[derive(Debug, Clone, Default)]
pub struct Sequences {
    by_source: HashMap<u16, SequenceCount, BuildHasherDefault<IntHasher>>,
    untracked: u64,
}

impl Sequences {
    /// Notes a frame from `source` with sequence number `seq`.
    #[inline]
    pub(crate) fn count(&mut self, source: Address, seq: u8) {
        let len = self.by_source.len();
        let s = match self.by_source.get_mut(&source.to_u16()) {
            Some(s) => s,
            None if len >= MAX_SEQUENCE_SOURCES => {
                self.untracked += 1;
                return;
            }
            None => {
                self.by_source.insert(
                    source.to_u16(),
                    SequenceCount {
                        received: 1,
                        lost: 0,
                        expected: seq.wrapping_add(1),
                    },
                );
                return;
            }
        };
        let jump = seq.wrapping_sub(s.expected);
        if jump < 128 {
            s.lost += u64::from(jump);
            s.expected = seq.wrapping_add(1);
        }
        s.received += 1;
    }

    /// Frames of sources beyond the table's bound (not followed).
    pub(crate) fn untracked(&self) -> u64 {
        self.untracked
    }

    /// Every followed source with its counts, by address.
    pub(crate) fn all(&self) -> Vec<(Address, SequenceCount)> {
        let mut v: Vec<_> = self
            .by_source
            .iter()
            .map(|(&a, &c)| (Address::from_u16(a), c))
            .collect();
        v.sort_by_key(|(a, _)| *a);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_count_forward_jumps_only() {
        let mut s = Sequences::default();
        let a = Address::new(1, 1);
        for seq in [250u8, 251, 254, 255, 0, 3, 3, 2, 4] {
            s.count(a, seq);
        }
        let all = s.all();
        assert_eq!(all.len(), 1);
        // 251→254 loses 2, 0→3 loses 2; the repeated 3 and the 2 are steps back, and
        // 4 is the one expected after them.
        assert_eq!((all[0].1.received, all[0].1.lost), (9, 4));
    }

    #[test]
    fn sequence_sources_are_bounded() {
        let mut s = Sequences::default();
        for a in 0..=u16::MAX {
            s.count(Address::from_u16(a), 0);
        }
        assert_eq!(s.all().len(), MAX_SEQUENCE_SOURCES);
        assert_eq!(s.untracked(), 65536 - MAX_SEQUENCE_SOURCES as u64);
    }

    #[test]
    fn source_table_counts_and_evicts_the_least_recent() {
        let mut t = SourceTable::default();
        for _ in 0..3 {
            t.count(Address::new(1, 1), 30);
        }
        t.count(Address::new(2, 1), 0);
        let s = t.sample(1.0);
        assert_eq!(s.len(), 2);
        assert_eq!(
            (s[0].source, s[0].message_id, s[0].frames),
            (Address::new(1, 1), 30, 3)
        );
        assert_eq!(s[0].rate_fps, 3.0);
        // Far more pairs than entries: bounded, and the latest pair is always there.
        for m in 0..20_000 {
            t.count(Address::new(9, 9), m);
        }
        let s = t.sample(1.0);
        assert!(s.len() <= SOURCE_TABLE_ENTRIES);
        assert!(s.iter().any(|c| c.message_id == 19_999));
        assert!(t.evicted() > 0);
    }
}
