//! Replay protection: the last accepted signature timestamp of every signing stream — a
//! (key, link id, source system, source component) — within a bounded table.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// How many streams are remembered. Only holders of a key can start a stream (the
/// signature is checked first), so the bound is against a misbehaving peer, not against
/// forgers. Beyond it the least recently used streams are forgotten.
pub const MAX_STREAMS: usize = 4096;

/// One signing stream: which key (its slot in the router's key list) and the frame's
/// link id, source system and source component.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StreamId {
    /// Slot of the key in the router's key list.
    pub key: usize,
    /// Link id of the signature.
    pub link_id: u8,
    /// Source system of the frame.
    pub system: u8,
    /// Source component of the frame.
    pub component: u8,
}

impl StreamId {
    /// The id as one number (the table's key).
    fn packed(&self) -> u64 {
        (self.key as u64) << 24
            | u64::from(self.link_id) << 16
            | u64::from(self.system) << 8
            | u64::from(self.component)
    }

    fn unpacked(v: u64) -> StreamId {
        StreamId {
            key: (v >> 24) as usize,
            link_id: (v >> 16) as u8,
            system: (v >> 8) as u8,
            component: v as u8,
        }
    }
}

/// A multiplicative hash of the packed id: streams are only made by holders of a key
/// (their signature is checked first), so a keyed hash against chosen collisions would
/// cost every frame for nothing.
#[derive(Default)]
struct PackedHasher(u64);

impl Hasher for PackedHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0 ^ v)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29);
    }
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    last: u64,
    used: u64,
}

/// The last accepted timestamp of each stream.
#[derive(Debug, Clone)]
pub struct StreamTable {
    entries: HashMap<u64, Entry, BuildHasherDefault<PackedHasher>>,
    capacity: usize,
    uses: u64,
    /// By key slot: what a stream the table does not know must begin above. It is
    /// raised to the last timestamp of every stream the table forgot (so that a full
    /// table cannot reopen a forgotten stream's last minute to replays), and after a
    /// restart that did not follow a clean exit (see [`StreamTable::raise_floor`]).
    floors: Vec<u64>,
}

impl Default for StreamTable {
    fn default() -> Self {
        StreamTable::with_capacity(MAX_STREAMS)
    }
}

impl StreamTable {
    /// A table remembering at most `capacity` streams (at least one).
    pub fn with_capacity(capacity: usize) -> Self {
        StreamTable {
            entries: HashMap::default(),
            capacity: capacity.max(1),
            uses: 0,
            floors: Vec::new(),
        }
    }

    /// What a new stream of key slot `key` must begin above (0: anything).
    pub fn floor(&self, key: usize) -> u64 {
        self.floors.get(key).copied().unwrap_or(0)
    }

    /// Raises what a new stream of key slot `key` must begin above to `timestamp`.
    pub(crate) fn raise_floor(&mut self, key: usize, timestamp: u64) {
        if self.floors.len() <= key {
            self.floors.resize(key + 1, 0);
        }
        self.floors[key] = self.floors[key].max(timestamp);
    }

    /// The last accepted timestamp of `id`, if the stream is known.
    pub fn last(&self, id: &StreamId) -> Option<u64> {
        self.entries.get(&id.packed()).map(|e| e.last)
    }

    /// Records `timestamp` as the last of `id` (never lowering it), forgetting the least
    /// recently used streams first if the table is full.
    pub(crate) fn record(&mut self, id: StreamId, timestamp: u64) {
        self.uses += 1;
        let used = self.uses;
        let key = id.packed();
        if let Some(e) = self.entries.get_mut(&key) {
            e.last = e.last.max(timestamp);
            e.used = used;
            return;
        }
        if self.entries.len() >= self.capacity {
            self.forget_least_used();
        }
        self.entries.insert(
            key,
            Entry {
                last: timestamp,
                used,
            },
        );
    }

    /// Forgets an eighth of the table (at least one stream), least recently used first,
    /// so the scan runs once per many new streams.
    fn forget_least_used(&mut self) {
        let mut uses: Vec<u64> = self.entries.values().map(|e| e.used).collect();
        let n = (self.capacity / 8).max(1).min(uses.len());
        if n == 0 {
            return;
        }
        let (_, cut, _) = uses.select_nth_unstable(n - 1);
        let cut = *cut;
        let mut forgotten = Vec::new();
        self.entries.retain(|packed, e| {
            let keep = e.used > cut;
            if !keep {
                forgotten.push((StreamId::unpacked(*packed).key, e.last));
            }
            keep
        });
        for (key, last) in forgotten {
            self.raise_floor(key, last);
        }
    }

    /// Streams remembered.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when no stream is remembered.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Every stream and its last timestamp, in a fixed order (for saving).
    pub(crate) fn snapshot(&self) -> Vec<(StreamId, u64)> {
        let mut all: Vec<_> = self
            .entries
            .iter()
            .map(|(k, e)| (StreamId::unpacked(*k), e.last))
            .collect();
        all.sort_unstable();
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(system: u8) -> StreamId {
        StreamId {
            key: 0,
            link_id: 0,
            system,
            component: 1,
        }
    }

    #[test]
    fn the_last_timestamp_never_goes_down() {
        let mut t = StreamTable::default();
        t.record(id(1), 10);
        t.record(id(1), 5);
        assert_eq!(t.last(&id(1)), Some(10));
        assert_eq!(t.last(&id(2)), None);
    }

    #[test]
    fn a_forgotten_stream_leaves_its_last_timestamp_as_its_keys_floor() {
        let mut t = StreamTable::with_capacity(2);
        let other_key = StreamId { key: 1, ..id(9) };
        t.record(id(1), 500);
        t.record(other_key, 900);
        assert_eq!((t.floor(0), t.floor(1)), (0, 0));
        t.record(id(2), 600); // stream 1 (key 0) is forgotten
        assert_eq!(t.last(&id(1)), None);
        assert_eq!((t.floor(0), t.floor(1)), (500, 0));
        t.raise_floor(3, 7);
        assert_eq!((t.floor(2), t.floor(3)), (0, 7));
    }

    #[test]
    fn the_table_is_bounded_and_keeps_the_recently_used() {
        let mut t = StreamTable::with_capacity(16);
        t.record(id(0), 1);
        for s in 1..=200u8 {
            t.record(id(s), 1);
            t.record(id(0), u64::from(s) + 1); // stream 0 stays in use
            assert!(t.len() <= 16);
        }
        assert_eq!(t.last(&id(0)), Some(201));
        assert_eq!(t.last(&id(200)), Some(1));
        assert_eq!(t.last(&id(1)), None);
    }
}
