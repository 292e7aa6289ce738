//! The check of a frame arriving on an interface with a key: its signature, then its
//! timestamp against the stream's last one and the router's clock, then the interface's
//! policy for unsigned frames.

use super::clock::UNITS_PER_SEC;
use super::key::SigningKey;
use super::streams::{StreamId, StreamTable};
use crate::wire::Frame;
use crate::wire::signing::verify;

/// How far a timestamp may be from the router's signing clock: a stream's first frame
/// no older than this, and no frame ahead of it by more (one minute, as MAVLink's
/// signing rules use for new streams).
pub const WINDOW: u64 = 60 * UNITS_PER_SEC;

/// Why a frame was refused at an interface with a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Refusal {
    /// Signed, but the signature is not the key's for these bytes.
    BadSignature,
    /// The timestamp is not after the last one accepted on its stream (or, on a stream
    /// the router does not know, not after its key's floor: see
    /// [`StreamTable::floor`]).
    Replayed,
    /// The timestamp is more than [`WINDOW`] ahead of the router's clock, or more than
    /// [`WINDOW`] behind it (on a stream that is new or silent for longer).
    OutOfWindow,
    /// Not signed, and the interface does not take unsigned frames.
    Unsigned,
}

/// What the check made of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// Signed with the interface's key, timestamp in order: route it as signed.
    Signed,
    /// Not signed, and the interface takes unsigned frames: route it as unsigned.
    Unsigned,
    /// Dropped.
    Refused(Refusal),
}

/// The key and policy of one interface, and the state its check needs.
pub struct Check<'a> {
    /// The interface's key.
    pub key: &'a SigningKey,
    /// The key's slot in the router's key list (streams are per key).
    pub key_slot: usize,
    /// Whether unsigned frames are taken.
    pub allow_unsigned: bool,
    /// The router's signing clock now (10 µs units since 2015).
    pub clock: u64,
}

impl Check<'_> {
    /// Whether `frame` passes as far as its signature goes, its stream not looked at:
    /// `Ok(true)` if it is signed with the key, `Ok(false)` if it is unsigned and the
    /// interface takes unsigned frames.
    pub fn authenticate(&self, frame: &Frame<'_>) -> Result<bool, Refusal> {
        match frame.signature() {
            None if self.allow_unsigned => Ok(false),
            None => Err(Refusal::Unsigned),
            Some(_) if verify(frame, self.key.as_bytes()) => Ok(true),
            Some(_) => Err(Refusal::BadSignature),
        }
    }

    /// Checks `frame`; a frame that passes signed has its timestamp recorded in
    /// `streams`. Nothing is recorded for a refused frame, so a forgery cannot move a
    /// stream's timestamp. `issued` holds the streams of the router's own signatures: a frame of one of them
    /// that is not after the last the router made is a replay of it.
    pub fn admit(
        &self,
        frame: &Frame<'_>,
        streams: &mut StreamTable,
        issued: &StreamTable,
    ) -> Admission {
        match self.authenticate(frame) {
            Err(why) => return Admission::Refused(why),
            Ok(false) => return Admission::Unsigned,
            Ok(true) => {}
        }
        let Some(signature) = frame.signature() else {
            return Admission::Unsigned;
        };
        let timestamp = signature.timestamp();
        if timestamp > self.clock.saturating_add(WINDOW) {
            return Admission::Refused(Refusal::OutOfWindow);
        }
        let source = frame.source();
        let stream = StreamId {
            key: self.key_slot,
            link_id: signature.link_id(),
            system: source.system,
            component: source.component,
        };
        if issued.last(&stream).is_some_and(|last| timestamp <= last) {
            return Admission::Refused(Refusal::Replayed);
        }
        // A frame more than the window behind the clock is refused on a stream that is
        // new, and on one silent for longer than the window (one restored from an old
        // state file): either could otherwise take frames of any age. On a stream
        // heard within the window such a frame is a replay anyway.
        match streams.last(&stream) {
            Some(last) if timestamp <= last => return Admission::Refused(Refusal::Replayed),
            _ if timestamp.saturating_add(WINDOW) < self.clock => {
                return Admission::Refused(Refusal::OutOfWindow);
            }
            None if timestamp <= streams.floor(self.key_slot) => {
                return Admission::Refused(Refusal::Replayed);
            }
            _ => {}
        }
        streams.record(stream, timestamp);
        Admission::Signed
    }
}
