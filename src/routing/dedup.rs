//! `dedup DURATION;`: frames byte-identical to one taken in within the window, from any
//! link, are dropped on the way in (before the filter and the queues). Redundant radios
//! deliver each frame of a vehicle once per radio; this keeps the first copy.
//!
//! Memory is bounded: a ring of the hashes taken in within the window (oldest first)
//! and a map from hash to its latest time, both at most [`MAX_ENTRIES`]. When more
//! frames than that arrive within one window the oldest hashes are forgotten early (a
//! late copy of such a frame then passes: a duplicate, never a lost frame). A frame is
//! known by a 64-bit keyed hash of all its bytes (sequence number, checksum and
//! signature included); with the key random per router, two different frames share a
//! hash with a chance of about `MAX_ENTRIES / 2^64` per frame.

use std::collections::hash_map::RandomState;
use std::collections::{HashMap, VecDeque};
use std::hash::{BuildHasher, BuildHasherDefault, Hasher};
use std::time::Duration;

use crate::time::Timestamp;

/// Most hashes remembered at once (a few MiB at the most): 65,536 frames, over
/// 100 seconds of a busy vehicle's 600 frames per second.
pub const MAX_ENTRIES: usize = 65_536;

/// The deduplication window and the hashes seen within it.
#[derive(Debug)]
pub struct Dedup {
    window: Option<Duration>,
    keys: RandomState,
    /// Hashes in order of arrival, with their time.
    ring: VecDeque<(Timestamp, u64)>,
    /// Each hash in the ring, with the time of its latest entry.
    latest: HashMap<u64, Timestamp, BuildHasherDefault<Prehashed>>,
}

/// The map's hasher: its keys are keyed hashes already, uniform in every bit, so they
/// are used as they are (hashing them again would double the cost of a look-up).
#[derive(Debug, Default)]
struct Prehashed(u64);

impl Hasher for Prehashed {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = self.0.rotate_left(8) ^ u64::from(b);
        }
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = n;
    }
}

impl Default for Dedup {
    fn default() -> Self {
        Dedup {
            window: None,
            keys: RandomState::new(),
            ring: VecDeque::new(),
            latest: HashMap::default(),
        }
    }
}

impl Dedup {
    /// Sets the window (`None`: off, and everything remembered is forgotten). A reload
    /// keeps what was seen when the window stays on.
    pub fn set_window(&mut self, window: Option<Duration>) {
        self.window = window;
        if window.is_none() {
            self.ring = VecDeque::new();
            self.latest = HashMap::default();
        }
    }

    /// The hash of `bytes` if deduplication is on, else `None`.
    #[inline]
    pub fn hash(&self, bytes: &[u8]) -> Option<u64> {
        self.window.map(|_| self.keys.hash_one(bytes))
    }

    /// True if a frame of hash `hash` was taken in within the window before `now`.
    pub fn is_duplicate(&mut self, hash: u64, now: Timestamp) -> bool {
        let Some(window) = self.window else {
            return false;
        };
        self.expire(now, window);
        self.latest.get(&hash).is_some_and(|&t| now <= t + window)
    }

    /// Notes that a frame of hash `hash` was taken in at `now`.
    pub fn note(&mut self, hash: u64, now: Timestamp) {
        if self.window.is_none() {
            return;
        }
        if self.ring.len() >= MAX_ENTRIES {
            self.pop_oldest();
        }
        self.ring.push_back((now, hash));
        self.latest.insert(hash, now);
    }

    /// Hashes remembered now.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// True when nothing is remembered.
    #[cfg(test)]
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }

    /// Forgets the hashes older than the window.
    fn expire(&mut self, now: Timestamp, window: Duration) {
        while let Some(&(t, _)) = self.ring.front() {
            if now <= t + window {
                break;
            }
            self.pop_oldest();
        }
    }

    fn pop_oldest(&mut self) {
        if let Some((t, hash)) = self.ring.pop_front()
            && self.latest.get(&hash) == Some(&t)
        {
            self.latest.remove(&hash);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_within_the_window_are_duplicates() {
        let mut d = Dedup::default();
        d.set_window(Some(Duration::from_millis(500)));
        let h = d.hash(b"frame").expect("on");
        let t0 = Timestamp::from_millis(1000);
        assert!(!d.is_duplicate(h, t0));
        d.note(h, t0);
        assert!(d.is_duplicate(h, Timestamp::from_millis(1500)));
        assert!(!d.is_duplicate(h, Timestamp::from_millis(1501)));
        assert!(d.is_empty());
    }

    #[test]
    fn memory_is_bounded() {
        let mut d = Dedup::default();
        d.set_window(Some(Duration::from_secs(10)));
        let now = Timestamp::from_secs(1);
        for i in 0..(MAX_ENTRIES as u64 * 2) {
            let h = d.hash(&i.to_le_bytes()).expect("on");
            if !d.is_duplicate(h, now) {
                d.note(h, now);
            }
        }
        assert_eq!(d.len(), MAX_ENTRIES);
        assert!(d.latest.len() <= MAX_ENTRIES);
    }

    #[test]
    fn off_remembers_nothing() {
        let mut d = Dedup::default();
        assert_eq!(d.hash(b"x"), None);
        d.note(1, Timestamp::ZERO);
        assert!(!d.is_duplicate(1, Timestamp::ZERO));
        assert!(d.is_empty());
    }
}
