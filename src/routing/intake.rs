//! Frames from a parser into the router: the signing check of an interface with a key
//! (a refused frame never reaches the router, and a datagram remote whose frames are all
//! refused never becomes a link), the recording tap (admitted frames only), the sender's link (a datagram remote gets one on its
//! first valid frame), counters, and unknown message ids reported once per id.

use crate::flight_log::FlightLogger;
use std::collections::{HashSet, VecDeque};
use std::net::SocketAddr;

use super::link::{GroupId, LinkId};
use super::notice::Notice;
use super::remotes::Remotes;
use super::router::{Output, Router};
use crate::recording::Tap;
use crate::signing::clock::UNITS_PER_SEC;
use crate::signing::{Admission, Edge, Refusal, Signing};
use crate::time::Timestamp;
use crate::wire::{Frame, ParseEvents, Rejection};

/// How many distinct unknown ids are reported; beyond that they are only counted, so a
/// flood of random ids can neither fill the log nor grow memory.
pub(crate) const MAX_REPORTED_IDS: usize = 1024;

/// What the first unknown-id report adds: how to let such frames through.
pub const UNKNOWN_ID_HINT: &str = "frames of message ids no dialect defines are dropped; \
to forward them add 'dialect FILE.xml;' (MAVLink XML defining them) or \
'unknown_messages accept;' to the configuration";

/// Message ids already reported as unknown (once per id, not per frame).
#[derive(Debug, Default)]
pub(crate) struct UnknownIds(HashSet<u32>);

impl UnknownIds {
    /// Reports `id` the first time it is seen (the first report says how to let such
    /// frames through).
    pub(crate) fn report(&mut self, id: u32, notices: &mut VecDeque<Notice>) {
        if self.0.len() >= MAX_REPORTED_IDS || !self.0.insert(id) {
            return;
        }
        notices.push_back(Notice::UnknownId(id));
        if self.0.len() == 1 {
            notices.push_back(Notice::Warning(UNKNOWN_ID_HINT.to_string()));
        }
        if self.0.len() == MAX_REPORTED_IDS {
            notices.push_back(Notice::Warning(format!(
                "{MAX_REPORTED_IDS} unknown message ids reported; further ones are only counted"
            )));
        }
    }
}

/// Where the bytes being parsed come from.
pub(crate) enum Sender<'a> {
    /// A stream with its one link.
    Stream(LinkId),
    /// A peer of a datagram interface, with its link once it has one.
    Remote {
        /// The interface's remotes (where a new link is recorded).
        remotes: &'a mut Remotes,
        /// The peer.
        address: SocketAddr,
        /// Its link, if it has sent a valid frame before.
        link: Option<LinkId>,
    },
}

/// Parser events of one input, routed through the router.
pub(crate) struct Intake<'a> {
    /// The router.
    pub router: &'a mut Router,
    /// The router's output of the current call.
    pub out: &'a mut Output,
    /// Notices for the operator.
    pub notices: &'a mut VecDeque<Notice>,
    /// Unknown-id reporting.
    pub unknown: &'a mut UnknownIds,
    /// The time of arrival.
    pub now: Timestamp,
    /// Where the bytes came from.
    pub sender: Sender<'a>,
    /// The interface's signing settings and counters, if it has a key.
    pub edge: Option<&'a mut Edge>,
    /// The router's keys, streams and clock.
    pub signing: &'a mut Signing,
    /// How messages name the interface.
    pub described: &'a str,
    /// Where admitted frames are kept for recording, when the router records.
    pub tap: Option<&'a mut Tap>,
    /// The interface's group, which a new link joins.
    pub group: Option<GroupId>,
    /// The flight log, when configured: it takes the stream's frames addressed to the
    /// router and notes the autopilot's heartbeats.
    pub flight_log: Option<&'a mut FlightLogger>,
}

impl Intake<'_> {
    /// The sender's link, created for a datagram peer on its first valid frame.
    fn link(&mut self) -> LinkId {
        match &mut self.sender {
            Sender::Stream(id) => *id,
            Sender::Remote {
                remotes,
                address,
                link,
            } => *link.get_or_insert_with(|| {
                let name = address.to_string();
                let id = self.router.add_udp_link(&name, self.now);
                self.router.set_group(id, self.group);
                remotes.insert(*address, id);
                self.notices.push_back(Notice::LinkAdded { id, name });
                id
            }),
        }
    }

    /// Counts a refused frame (on the interface, and on the sender's link if it has one)
    /// and says the first of each reason.
    fn refuse(&mut self, frame: &Frame<'_>, why: Refusal) {
        let Some(edge) = self.edge.as_deref_mut() else {
            return;
        };
        edge.counters.refused(why);
        let first = edge.first_time(why);
        if let Some(c) = self
            .existing_link()
            .and_then(|id| self.router.counters_mut(id))
        {
            c.signing.refused(why);
        }
        if first {
            let text = refusal_text(self.described, frame, why, self.signing.clock(self.now));
            self.notices.push_back(Notice::Warning(text));
        }
    }

    /// The sender's link, if it has one yet.
    pub(super) fn existing_link(&self) -> Option<LinkId> {
        match &self.sender {
            Sender::Stream(id) => Some(*id),
            Sender::Remote { link, .. } => *link,
        }
    }
}

impl ParseEvents for Intake<'_> {
    #[inline]
    fn frame(&mut self, frame: Frame<'_>) {
        // Copies are dropped before the replay check: the same signed frame over a
        // second radio is a copy, not a replay. Only frames taken in are remembered, so
        // a refused frame cannot hold back a genuine one. At an interface with a key a
        // copy must still pass the signature check, and a signed copy from a remote
        // that has no link yet is a replay: a copy must not make anyone a link.
        let hash = self.router.dedup().hash(frame.as_bytes());
        if let Some(h) = hash
            && self.router.dedup_mut().is_duplicate(h, self.now)
        {
            if let Some(edge) = self.edge.as_deref() {
                let refused = match self.signing.authenticate(edge, &frame) {
                    Err(why) => Some(why),
                    Ok(true) if self.existing_link().is_none() => Some(Refusal::Replayed),
                    Ok(_) => None,
                };
                if let Some(why) = refused {
                    self.refuse(&frame, why);
                    return;
                }
            }
            let id = self.link();
            self.router.take_duplicate(id, &frame, self.now, self.out);
            return;
        }
        let signed = match self.edge.as_deref_mut() {
            None => false,
            Some(edge) => match self.signing.admit(edge, &frame, self.now) {
                Admission::Signed => {
                    edge.counters.verified += 1;
                    true
                }
                Admission::Unsigned => false,
                Admission::Refused(why) => {
                    self.refuse(&frame, why);
                    return;
                }
            },
        };
        if let Some(tap) = self.tap.as_deref_mut() {
            tap.offer(&frame, signed, self.now);
        }
        if let Some(h) = hash {
            self.router.dedup_mut().note(h, self.now);
        }
        let id = self.link();
        if let Some(log) = self.flight_log.as_deref_mut()
            && log.take(&frame, self.now)
        {
            // The stream between the autopilot and the router: not routed.
            self.router.take_for_router(id, &frame, self.now, self.out);
            return;
        }
        if (signed || frame.is_unknown())
            && let Some(c) = self.router.counters_mut(id)
        {
            if signed {
                c.signing.verified += 1;
            }
            if frame.is_unknown() {
                c.unknown_accepted += 1;
            }
        }
        self.router
            .receive_as(id, &frame, signed, self.now, self.out);
    }

    fn rejected(&mut self, _offset: u64, why: Rejection) {
        match why {
            Rejection::UnknownId(id) => {
                self.unknown.report(id, self.notices);
                if let Some(c) = self
                    .existing_link()
                    .and_then(|id| self.router.counters_mut(id))
                {
                    c.unknown_id += 1;
                }
            }
            Rejection::BadCrc => {
                if let Some(c) = self
                    .existing_link()
                    .and_then(|id| self.router.counters_mut(id))
                {
                    c.bad_crc += 1;
                }
            }
            _ => {}
        }
    }
}

/// The warning for the first frame an interface refuses for `why`.
fn refusal_text(described: &str, frame: &Frame<'_>, why: Refusal, clock: u64) -> String {
    let from = frame.source();
    let what = match why {
        Refusal::BadSignature => {
            format!("a frame from {from} with a bad signature (signed with another key?)")
        }
        Refusal::Replayed => format!(
            "a replayed frame from {from} (its signature timestamp is not after the last one of its stream)"
        ),
        Refusal::OutOfWindow => {
            let ts = frame.signature().map_or(0, |s| s.timestamp());
            let (secs, side) = if ts > clock {
                ((ts - clock) / UNITS_PER_SEC, "ahead of")
            } else {
                ((clock - ts) / UNITS_PER_SEC, "behind")
            };
            format!(
                "a signed frame from {from} whose timestamp is {secs} s {side} this router's clock (more than 60 s; is a clock wrong?)"
            )
        }
        Refusal::Unsigned => format!(
            "an unsigned frame from {from} (the interface has a signing_key and no allow_unsigned)"
        ),
    };
    format!("{described}: refused {what}; further ones are only counted")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reporting_is_bounded() {
        let mut u = UnknownIds::default();
        let mut notices = VecDeque::new();
        for id in 0..(MAX_REPORTED_IDS as u32 * 4) {
            u.report(id, &mut notices);
            u.report(id, &mut notices);
        }
        assert_eq!(u.0.len(), MAX_REPORTED_IDS);
        // One notice per id, the hint after the first, and one warning that the rest
        // are only counted.
        assert_eq!(notices.len(), MAX_REPORTED_IDS + 2);
    }
}
