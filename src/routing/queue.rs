//! A link's outgoing packets: bounded, highest priority first, FIFO among equals.

use std::collections::VecDeque;

pub use crate::wire::Packet;

/// Bytes one link's queue holds by default: 4 MiB.
///
/// Enough for 10,000 frames of 267 bytes (about 2.7 MB) arriving far faster than a
/// 256 kbit/s link drains them — two senders of 5,000 ENCAPSULATED_DATA each, a load the
/// original's unbounded queues delivered whole — so that configurations that worked with
/// the original keep working. [`DEFAULT_TOTAL_CAPACITY`] bounds all links together.
pub(crate) const DEFAULT_CAPACITY: usize = 4 * 1024 * 1024;

/// Bytes all queues together hold by default: 16 MiB, so that no number of links (a
/// flood of spoofed UDP senders included) takes the router's memory beyond a few tens of
/// MiB, while four links can each hold a full [`DEFAULT_CAPACITY`] at once. (Queues
/// charge every packet to every queue holding it, though they share its bytes, so the
/// memory they really use is at most this.)
pub(crate) const DEFAULT_TOTAL_CAPACITY: usize = 16 * 1024 * 1024;

/// Bytes charged per packet on top of its length (shared-buffer header and queue slot),
/// so that a flood of tiny packets is bounded too.
pub(crate) const PACKET_OVERHEAD: usize = 32;

/// Empty buckets a queue keeps for reuse before it lets the extra ones go.
const MAX_EMPTY_BUCKETS: usize = 8;

/// What [`PacketQueue::push`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PushOutcome {
    /// Queued; `evicted` older, lower-or-equal-priority packets were dropped to make room.
    Queued {
        /// Packets dropped to make room.
        evicted: usize,
    },
    /// Not queued: the packets ahead of it (higher priority) fill the queue, or the packet
    /// alone exceeds the capacity.
    Dropped,
}

/// The packets of one priority, oldest first, with their total cost.
#[derive(Debug, Clone, Default)]
struct Bucket {
    packets: VecDeque<Packet>,
    bytes: usize,
}

/// Bounded priority queue of packets.
///
/// Order: higher priority first; equal priorities in arrival order. Bound: the sum of
/// packet lengths plus `PACKET_OVERHEAD` each never exceeds the capacity. When a new
/// packet does not fit, the lowest-priority, oldest packets are dropped until it does;
/// if it still could not fit after dropping everything of its own priority or lower, the
/// new packet itself is dropped instead (a new packet never displaces a higher-priority
/// one). Every drop is counted.
///
/// A bucket stays (empty, its ring kept) after its last packet leaves, so a link that
/// sends every packet as it arrives allocates nothing per packet; priorities come from
/// the configuration, so there are few of them, and empty buckets beyond
/// [`MAX_EMPTY_BUCKETS`] are let go (a reload may bring new ones).
#[derive(Debug, Clone)]
pub struct PacketQueue {
    /// One bucket per priority seen, in ascending priority.
    buckets: Vec<(i32, Bucket)>,
    bytes: usize,
    len: usize,
    capacity: usize,
    dropped: u64,
    /// Most bytes ever held at once.
    high_water: usize,
}

impl PacketQueue {
    /// An empty queue holding at most `capacity` bytes (see `PACKET_OVERHEAD`).
    pub fn new(capacity: usize) -> Self {
        PacketQueue {
            buckets: Vec::new(),
            bytes: 0,
            len: 0,
            capacity,
            dropped: 0,
            high_water: 0,
        }
    }

    /// Whether a packet of `cost` bytes and `priority` would be queued (making room
    /// within this queue by dropping what ranks below it), not dropped.
    pub(crate) fn would_take(&self, cost: usize, priority: i32) -> bool {
        if self.bytes.saturating_add(cost) <= self.capacity {
            return true;
        }
        let ahead: usize = self
            .buckets
            .iter()
            .filter(|(p, _)| *p > priority)
            .map(|(_, b)| b.bytes)
            .sum();
        ahead.saturating_add(cost) <= self.capacity
    }

    /// Queues `packet` with `priority`, dropping lower-priority or older packets if full.
    pub fn push(&mut self, packet: Packet, priority: i32) -> PushOutcome {
        let cost = Self::cost_of(&packet);
        let mut evicted = 0;
        if self.bytes.saturating_add(cost) > self.capacity {
            if !self.would_take(cost, priority) {
                self.dropped += 1;
                return PushOutcome::Dropped;
            }
            while self.bytes.saturating_add(cost) > self.capacity {
                if self.take(true).is_none() {
                    break; // unreachable: `ahead + cost` fits
                }
                self.dropped += 1;
                evicted += 1;
            }
        }
        self.bytes += cost;
        self.len += 1;
        let bucket = self.bucket(priority);
        bucket.bytes += cost;
        bucket.packets.push_back(packet);
        self.high_water = self.high_water.max(self.bytes);
        PushOutcome::Queued { evicted }
    }

    /// The bucket of `priority`, made (or an empty one's place taken) if there is none.
    fn bucket(&mut self, priority: i32) -> &mut Bucket {
        // Usually one or two buckets: a linear search from the top is the quickest.
        let at = match self.buckets.iter().rposition(|(p, _)| *p == priority) {
            Some(i) => i,
            None => {
                self.forget_empty_buckets();
                let i = self.buckets.partition_point(|(p, _)| *p < priority);
                self.buckets.insert(i, (priority, Bucket::default()));
                i
            }
        };
        &mut self.buckets[at].1
    }

    /// Lets empty buckets go once more than [`MAX_EMPTY_BUCKETS`] are kept.
    fn forget_empty_buckets(&mut self) {
        let empty = self
            .buckets
            .iter()
            .filter(|(_, b)| b.packets.is_empty())
            .count();
        if empty >= MAX_EMPTY_BUCKETS {
            self.buckets.retain(|(_, b)| !b.packets.is_empty());
        }
    }

    /// The index of the lowest (`lowest`) or highest priority bucket holding packets.
    fn occupied(&self, lowest: bool) -> Option<usize> {
        if self.len == 0 {
            return None;
        }
        if lowest {
            self.buckets.iter().position(|(_, b)| !b.packets.is_empty())
        } else {
            self.buckets
                .iter()
                .rposition(|(_, b)| !b.packets.is_empty())
        }
    }

    /// The priority of the packet [`PacketQueue::drop_lowest`] would drop.
    pub(crate) fn lowest_priority(&self) -> Option<i32> {
        self.occupied(true).map(|i| self.buckets[i].0)
    }

    /// Drops the oldest packet of the lowest priority (counted as a drop) to make room
    /// elsewhere. Returns the bytes it freed (0 if the queue was empty).
    pub(crate) fn drop_lowest(&mut self) -> usize {
        let before = self.bytes;
        if self.take(true).is_some() {
            self.dropped += 1;
        }
        before - self.bytes
    }

    /// Counts a packet that was dropped before it reached this queue (the shared
    /// capacity was used up by packets of higher priority).
    pub(crate) fn count_drop(&mut self) {
        self.dropped += 1;
    }

    /// What `packet` counts against a capacity: its length plus `PACKET_OVERHEAD`.
    pub(crate) fn cost_of(packet: &[u8]) -> usize {
        packet.len().saturating_add(PACKET_OVERHEAD)
    }

    /// Removes the oldest packet of the lowest (`lowest`) or highest priority.
    fn take(&mut self, lowest: bool) -> Option<Packet> {
        let i = self.occupied(lowest)?;
        let bucket = &mut self.buckets[i].1;
        let p = bucket.packets.pop_front()?;
        let cost = Self::cost_of(&p);
        bucket.bytes -= cost;
        self.bytes -= cost;
        self.len -= 1;
        Some(p)
    }

    /// Lets a packet of `cost` bytes pass this queue while it is empty, without storing
    /// it: what a push and an immediate pop would leave, i.e. the high-water mark sees
    /// it. False, and nothing changed, if the queue holds packets or the packet alone
    /// exceeds the capacity (a push would drop it): queue it then.
    pub(crate) fn pass(&mut self, cost: usize) -> bool {
        if self.len != 0 || cost > self.capacity {
            return false;
        }
        self.high_water = self.high_water.max(cost);
        true
    }

    /// The next packet to send, without removing it.
    pub fn peek(&self) -> Option<&Packet> {
        self.occupied(false)
            .and_then(|i| self.buckets[i].1.packets.front())
    }

    /// Removes and returns the next packet to send.
    pub fn pop(&mut self) -> Option<Packet> {
        self.take(false)
    }

    /// Packets queued.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes charged against the capacity.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// Changes the capacity (a reload's `queue` block): packets beyond a smaller one
    /// stay queued, and the next push makes room as usual.
    pub(crate) fn set_capacity(&mut self, capacity: usize) {
        self.capacity = capacity;
    }

    /// The capacity in bytes.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Packets dropped because the queue was full, since creation.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// The most bytes the queue has held at once, since creation.
    pub(crate) fn high_water(&self) -> usize {
        self.high_water
    }
}

impl Default for PacketQueue {
    fn default() -> Self {
        PacketQueue::new(DEFAULT_CAPACITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pkt(tag: u8, len: usize) -> Packet {
        let mut v = vec![0u8; len];
        if let Some(b) = v.first_mut() {
            *b = tag;
        }
        v.into()
    }

    fn tags(q: &mut PacketQueue) -> Vec<u8> {
        std::iter::from_fn(|| q.pop()).map(|p| p[0]).collect()
    }

    /// Room for exactly `n` packets of `len` bytes.
    fn cap(n: usize, len: usize) -> usize {
        n * (len + PACKET_OVERHEAD)
    }

    #[test]
    fn priority_then_fifo() {
        let mut q = PacketQueue::default();
        for (tag, prio) in [(1, 0), (2, 5), (3, 0), (4, -1), (5, 5), (6, 0)] {
            q.push(pkt(tag, 10), prio);
        }
        assert_eq!(q.peek().map(|p| p[0]), Some(2));
        assert_eq!(tags(&mut q), vec![2, 5, 1, 3, 6, 4]);
        assert!(q.is_empty());
        assert_eq!(q.bytes(), 0);
    }

    #[test]
    fn empty_buckets_are_reused_and_bounded() {
        let mut q = PacketQueue::default();
        for prio in 0..100 {
            q.push(pkt(prio as u8, 10), prio);
            assert_eq!(q.pop().map(|p| p[0]), Some(prio as u8));
            assert!(q.buckets.len() <= MAX_EMPTY_BUCKETS + 1);
        }
        // A priority whose bucket is kept: no new bucket, still in order.
        let kept = q.buckets.len();
        q.push(pkt(1, 10), q.buckets[0].0);
        q.push(pkt(2, 10), 1000);
        q.push(pkt(3, 10), -1000);
        assert_eq!(q.buckets.len(), kept + 2);
        assert_eq!(tags(&mut q), vec![2, 1, 3]);
        assert_eq!(q.lowest_priority(), None);
    }

    #[test]
    fn full_queue_drops_lowest_priority_oldest() {
        let mut q = PacketQueue::new(cap(3, 10));
        q.push(pkt(1, 10), 0);
        q.push(pkt(2, 10), -1);
        q.push(pkt(3, 10), -1);
        assert_eq!(q.push(pkt(4, 10), 0), PushOutcome::Queued { evicted: 1 });
        assert_eq!(q.dropped(), 1);
        assert_eq!(tags(&mut q), vec![1, 4, 3]);
    }

    #[test]
    fn equal_priority_overflow_keeps_the_newest() {
        let mut q = PacketQueue::new(cap(2, 10));
        for tag in 1..=5 {
            q.push(pkt(tag, 10), 0);
        }
        assert_eq!(q.dropped(), 3);
        assert_eq!(tags(&mut q), vec![4, 5]);
    }

    #[test]
    fn new_lower_priority_packet_never_displaces_higher() {
        let mut q = PacketQueue::new(cap(2, 10));
        q.push(pkt(1, 10), 5);
        q.push(pkt(2, 10), 5);
        assert_eq!(q.push(pkt(3, 10), 1), PushOutcome::Dropped);
        assert_eq!(q.dropped(), 1);
        assert_eq!(tags(&mut q), vec![1, 2]);
    }

    #[test]
    fn a_packet_that_cannot_fit_evicts_nothing() {
        let mut q = PacketQueue::new(cap(2, 10));
        q.push(pkt(1, 10), 5);
        q.push(pkt(2, 10), 0);
        // 40 bytes would need the priority-5 packet gone: drop the newcomer, keep both.
        assert_eq!(q.push(pkt(3, 40), 1), PushOutcome::Dropped);
        assert_eq!(q.push(pkt(4, 1000), 9), PushOutcome::Dropped);
        assert_eq!(tags(&mut q), vec![1, 2]);
    }

    #[test]
    fn extreme_priorities() {
        let mut q = PacketQueue::new(cap(2, 10));
        q.push(pkt(1, 10), i32::MAX);
        q.push(pkt(2, 10), i32::MIN);
        q.push(pkt(3, 10), i32::MAX);
        assert_eq!(tags(&mut q), vec![1, 3]);
    }

    #[test]
    fn memory_stays_bounded_under_overload() {
        let capacity = 10_000;
        let mut q = PacketQueue::new(capacity);
        let mut state = 12345u32;
        for i in 0..100_000u32 {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let len = 1 + (state >> 16) as usize % 280;
            let prio = (state >> 8) as i32 % 4;
            q.push(pkt(i as u8, len), prio);
            assert!(q.bytes() <= capacity);
            if i % 7 == 0 {
                q.pop();
            }
        }
        assert!(q.dropped() > 0);
        // One bucket per priority, in ascending order, and no more than that.
        let prios: Vec<i32> = q.buckets.iter().map(|(p, _)| *p).collect();
        assert!(prios.windows(2).all(|w| w[0] < w[1]), "{prios:?}");
        assert!(q.buckets.len() <= 4);
    }
}
