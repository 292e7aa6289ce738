//! Hands parsed frames to the routing core, creating links on demand, and reports
//! unknown message ids once per id.

use std::collections::HashSet;

use crate::dialect::DIALECT_NAME;
use crate::routing::{LinkId, Output, Router, Timestamp};
use crate::wire::{Frame, ParseEvents, Rejection};

use super::counters::LinkCounters;

/// How many distinct unknown ids are reported; beyond that they are only counted, so
/// a flood of random ids can neither fill the log nor grow memory.
const MAX_REPORTED: usize = 1024;

/// Message ids already reported as unknown (decisions row 2: once per id, not per frame).
#[derive(Debug, Default)]
pub struct UnknownIds(HashSet<u32>);

impl UnknownIds {
    /// Reports `id` on standard error the first time it is seen.
    pub fn report(&mut self, id: u32) {
        if self.0.len() >= MAX_REPORTED || !self.0.insert(id) {
            return;
        }
        eprintln!("Packet ID (#{id}) is not part of the '{DIALECT_NAME}' MAVLink dialect.");
        if self.0.len() == MAX_REPORTED {
            eprintln!(
                "warning: {MAX_REPORTED} unknown message ids reported; further ones are only counted"
            );
        }
    }
}

/// Where frames of a stream come from: gives the sender's link (a UDP interface creates
/// links lazily, on the first valid frame of a remote) and its counters.
pub trait Source {
    /// The link of the stream's current sender, created if need be.
    fn link(&mut self, router: &mut Router, now: Timestamp) -> (LinkId, &mut LinkCounters);
    /// The counters of the current sender's link if it exists (a UDP remote gets a link
    /// only once it has sent a valid frame).
    fn counters(&mut self) -> Option<&mut LinkCounters>;
}

/// Parser events of one stream, routed through the core.
pub struct ToRouter<'a, L> {
    /// The routing core.
    pub router: &'a mut Router,
    /// Collects the core's output.
    pub out: &'a mut Output,
    /// The time of arrival.
    pub now: Timestamp,
    /// Unknown-id reporting.
    pub unknown: &'a mut UnknownIds,
    /// The link the bytes came from.
    pub link: L,
}

impl<L: Source> ParseEvents for ToRouter<'_, L> {
    fn frame(&mut self, frame: Frame<'_>) {
        let (id, counters) = self.link.link(self.router, self.now);
        counters.received(frame.as_bytes().len());
        self.router.receive(id, &frame, self.now, self.out);
    }

    fn rejected(&mut self, _offset: u64, why: Rejection) {
        match why {
            Rejection::UnknownId(id) => self.unknown.report(id),
            Rejection::BadCrc => {
                if let Some(c) = self.link.counters() {
                    c.bad_crc += 1;
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reporting_is_bounded() {
        let mut u = UnknownIds::default();
        for id in 0..(MAX_REPORTED as u32 * 4) {
            u.report(id);
            u.report(id);
        }
        assert_eq!(u.0.len(), MAX_REPORTED);
    }
}
