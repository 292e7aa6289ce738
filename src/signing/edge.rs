//! Signing as the routing core runs it: each keyed interface's settings and counters
//! ([`Edge`]), and what the whole router shares ([`Signing`]): the keys, the stream
//! table, the clock, and whether the saved state is behind.

use super::clock::SigningClock;
use super::counters::SigningCounters;
use super::key::SigningKey;
use super::sign::{sign, wants_signature};
use super::state::{SavedState, SavedStream, UNCLEAN_MARGIN};
use super::streams::{StreamId, StreamTable};
use super::verify::{Admission, Check, Refusal};
use crate::time::Timestamp;
use crate::wire::header::V2;
use crate::wire::signing::SigningTime;
use crate::wire::{Frame, Packet};

/// The signing settings of one interface with a key, and what it counted.
#[derive(Debug, Clone)]
pub struct Edge {
    /// Slot of its key in [`Signing`]'s key list.
    pub key_slot: usize,
    /// Whether unsigned frames are taken in.
    pub allow_unsigned: bool,
    /// The link id of the signatures the router adds here.
    pub link_id: u8,
    /// What was checked, refused and signed here.
    pub counters: SigningCounters,
    /// Refusal reasons already said in the log (each once per interface).
    pub said: Vec<Refusal>,
}

impl Edge {
    /// A fresh edge with the same settings and nothing counted (for a connection a keyed
    /// server accepts).
    pub(crate) fn fresh_copy(&self) -> Edge {
        Edge {
            counters: SigningCounters::default(),
            said: Vec::new(),
            ..self.clone()
        }
    }

    /// True the first time `why` is seen here.
    pub(crate) fn first_time(&mut self, why: Refusal) -> bool {
        if self.said.contains(&why) {
            return false;
        }
        self.said.push(why);
        true
    }
}

/// Keys, stream table and clock shared by every interface of the router.
#[derive(Debug, Default)]
pub struct Signing {
    /// Every key configured since the start, by slot. A key a reload takes out stays, so
    /// that its streams stay too and a reload that puts it back finds them; the list is
    /// as long as the distinct keys of the process's life, 32 bytes each.
    keys: Vec<SigningKey>,
    streams: StreamTable,
    /// The streams of the signatures the router made itself, apart from `streams`: a
    /// frame sent back to it is a replay, but what strangers make it sign (an unsigned
    /// flood through an open interface) must not push real streams out of the table.
    issued: StreamTable,
    clock: SigningClock,
    changed: bool,
}

impl Signing {
    /// The slot of `key`, added if new (interfaces with the same key share its streams,
    /// so a frame taken in on one cannot be replayed on another).
    pub(crate) fn add_key(&mut self, key: SigningKey) -> usize {
        if let Some(i) = self.keys.iter().position(|k| *k == key) {
            return i;
        }
        self.keys.push(key);
        self.keys.len() - 1
    }

    /// True when some interface has a key.
    pub(crate) fn has_keys(&self) -> bool {
        !self.keys.is_empty()
    }

    /// Notes the wall clock: at `now` it read `units` of signature time.
    pub(crate) fn set_wall_clock(&mut self, now: Timestamp, units: SigningTime) {
        self.clock.set_wall(now, units);
    }

    /// The signing clock at `now` (10 µs units since 2015).
    pub(crate) fn clock(&self, now: Timestamp) -> SigningTime {
        self.clock.now(now)
    }

    /// Checks `frame`, arrived at `now` on an interface with `edge`.
    pub fn admit(&mut self, edge: &Edge, frame: &Frame<'_>, now: Timestamp) -> Admission {
        let Some(check) = check_of(&self.keys, edge, self.clock.now(now)) else {
            return Admission::Refused(Refusal::BadSignature);
        };
        let admission = check.admit(frame, &mut self.streams, &self.issued);
        if admission == Admission::Signed {
            self.changed = true;
        }
        admission
    }

    /// Whether `frame`, arrived on an interface with `edge`, passes as far as its
    /// signature goes (its stream not looked at): `Ok(true)` signed with the key,
    /// `Ok(false)` unsigned where unsigned frames are taken.
    pub fn authenticate(&self, edge: &Edge, frame: &Frame<'_>) -> Result<bool, Refusal> {
        // The clock is not looked at without a stream.
        match check_of(&self.keys, edge, 0) {
            Some(check) => check.authenticate(frame),
            None => Err(Refusal::BadSignature),
        }
    }

    /// `frame` signed for sending at `now` out of an interface with `edge`, or `None` if
    /// it goes as it is (already signed, MAVLink 1). The signature's stream is recorded
    /// as if the frame had come in: a copy sent back to the router, on any interface
    /// with the key, is a replay.
    pub fn sign(&mut self, edge: &Edge, frame: &[u8], now: Timestamp) -> Option<Packet> {
        if !wants_signature(frame) {
            return None;
        }
        let key = self.keys.get(edge.key_slot)?;
        let timestamp = self.clock.issue(now);
        self.changed = true;
        let signed = sign(frame, key, edge.link_id, timestamp)?;
        let stream = StreamId {
            key: edge.key_slot,
            link_id: edge.link_id,
            system: V2.read_system(frame),
            component: V2.read_component(frame),
        };
        self.issued.record(stream, timestamp);
        Some(signed)
    }

    /// Takes over a saved state: the clock floor, and the streams of keys still in use
    /// (raised by [`UNCLEAN_MARGIN`] if the file was not written at a clean exit).
    /// A stream the table already knows keeps what it knows: the file was written from
    /// it (a key a reload took out and put back), so the table's timestamp is the
    /// newer, and exact. Returns how many streams were taken.
    ///
    /// `at_start`: the state of an earlier run, restored before any frame. If that run
    /// did not end cleanly, what it did after its last save is not in the file: the
    /// clock, and what a stream the table does not know must begin above, are raised
    /// to the time of that save plus the margin, so that neither the router's own
    /// signatures nor a stream first heard after the save can be replayed.
    pub(crate) fn restore(&mut self, state: &SavedState, at_start: bool) -> usize {
        let margin = if state.clean { 0 } else { UNCLEAN_MARGIN };
        if at_start {
            let after = state.clock.saturating_add(margin);
            self.clock.raise_floor(after);
            if !state.clean {
                for slot in 0..self.keys.len() {
                    self.streams.raise_floor(slot, after);
                }
            }
        }
        let prints: Vec<[u8; 8]> = self.keys.iter().map(SigningKey::fingerprint).collect();
        let mut n = 0;
        for s in &state.streams {
            let Some(key) = prints.iter().position(|p| *p == s.key) else {
                continue;
            };
            let id = StreamId {
                key,
                link_id: s.link_id,
                system: s.system,
                component: s.component,
            };
            if self.streams.last(&id).is_some() {
                continue;
            }
            self.streams.record(id, s.timestamp.saturating_add(margin));
            n += 1;
        }
        n
    }

    /// The state to save at `now`, if it changed since the last call (or always when
    /// `clean`: the router is stopping and nothing is accepted after it). Its clock is
    /// the signing clock now (never below a timestamp the router issued).
    pub(crate) fn take_state(&mut self, clean: bool, now: Timestamp) -> Option<SavedState> {
        if !self.has_keys() || !(self.changed || clean) {
            return None;
        }
        self.changed = false;
        let prints: Vec<[u8; 8]> = self.keys.iter().map(SigningKey::fingerprint).collect();
        let streams = self
            .streams
            .snapshot()
            .into_iter()
            .filter_map(|(id, timestamp)| {
                Some(SavedStream {
                    key: *prints.get(id.key)?,
                    link_id: id.link_id,
                    system: id.system,
                    component: id.component,
                    timestamp,
                })
            })
            .collect();
        Some(SavedState {
            clean,
            clock: self.clock.now(now).max(self.clock.floor()),
            streams,
        })
    }
}

/// The check of `edge` (its key among `keys`) with the signing clock at `clock`; `None`
/// if its key slot is empty.
fn check_of<'a>(keys: &'a [SigningKey], edge: &Edge, clock: SigningTime) -> Option<Check<'a>> {
    Some(Check {
        key: keys.get(edge.key_slot)?,
        key_slot: edge.key_slot,
        allow_unsigned: edge.allow_unsigned,
        clock,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_put_back_keeps_the_exact_timestamps_the_table_knows() {
        let mut signing = Signing::default();
        let key = SigningKey::from_bytes([5; 32]);
        let slot = signing.add_key(key.clone());
        let known = StreamId {
            key: slot,
            link_id: 1,
            system: 7,
            component: 1,
        };
        let evicted = StreamId { system: 8, ..known };
        signing.streams.record(known, 1_000);
        // Saved while running (unclean): taken back, only the stream the table forgot
        // is raised by the margin.
        let saved = |id: StreamId, timestamp| SavedStream {
            key: key.fingerprint(),
            link_id: id.link_id,
            system: id.system,
            component: id.component,
            timestamp,
        };
        let state = SavedState {
            clean: false,
            clock: 0,
            streams: vec![saved(known, 900), saved(evicted, 900)],
        };
        assert_eq!(signing.restore(&state, false), 1);
        assert_eq!(signing.streams.last(&known), Some(1_000));
        assert_eq!(signing.streams.last(&evicted), Some(900 + UNCLEAN_MARGIN));
    }
}
