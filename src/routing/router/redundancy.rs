//! What the router does for redundant paths and for itself: the `dedup` window (frames
//! are checked against it on the way in, before the filter and the queues), `group`s of
//! links that are one path to a vehicle, and the router's own address (its heartbeat's
//! source, never learned as living on a link).

use super::{Output, Router, link_ref};
use crate::address::Address;
use crate::routing::dedup::Dedup;
use crate::routing::event::Event;
use crate::routing::link::{GroupId, LinkId};
use crate::routing::queue::Packet;
use crate::time::Timestamp;
use crate::wire::Frame;

/// The router's state for redundant paths and its own frames.
#[derive(Debug, Default)]
pub(crate) struct Redundancy {
    /// The `dedup` window and the frames seen within it.
    pub(crate) dedup: Dedup,
    /// The router's own address (its `heartbeat`'s source), if it sends frames.
    pub(crate) own: Option<Address>,
}

impl Router {
    /// The `dedup` window and what it remembers.
    pub(crate) fn dedup_mut(&mut self) -> &mut Dedup {
        &mut self.redundancy.dedup
    }

    /// The `dedup` window and what it remembers.
    pub(crate) fn dedup(&self) -> &Dedup {
        &self.redundancy.dedup
    }

    /// Sets the router's own address: frames from it are not learned on any link.
    pub(crate) fn set_own_address(&mut self, own: Option<Address>) {
        self.redundancy.own = own;
    }

    /// Puts link `id` in `group` (or in none).
    pub(crate) fn set_group(&mut self, id: LinkId, group: Option<GroupId>) {
        if let Some(i) = self.index(id) {
            self.links[i].group = group;
        }
    }

    /// True if `src` is the router's own address.
    #[inline]
    pub(super) fn is_own(&self, src: Address) -> bool {
        self.redundancy.own == Some(src)
    }

    /// Learns `src` on link `si` (a "new component" event when it is new there) and,
    /// when the link is in a group, on every member of the group: a vehicle heard on one
    /// of its paths is reachable through each. The router's own address is not learned.
    pub(super) fn learn_source(
        &mut self,
        si: usize,
        src: Address,
        now: Timestamp,
        out: &mut Output,
    ) {
        if self.is_own(src) {
            return;
        }
        let link = &mut self.links[si];
        let (id, group) = (link.id(), link.group);
        if link.learn(src, now) {
            if self.options.event_level >= 1 {
                out.events.push(Event::NewComponent {
                    address: src,
                    link: link_ref(link),
                });
            }
            self.index_system(src.system, id);
        }
        let Some(group) = group else {
            return;
        };
        for i in 0..self.links.len() {
            let member = &mut self.links[i];
            if i != si && member.group == Some(group) && member.learn_for_group(src, now) {
                let id = member.id();
                self.index_system(src.system, id);
            }
        }
    }

    /// True if a frame from link `si` is not offered to link `i`: a member of the same
    /// group (one path to the vehicle; it has the frame already), or the sender itself
    /// for the router's own frames (never learned, so not kept back by learning).
    #[inline]
    pub(super) fn keeps_back(&self, si: usize, i: usize, own: bool) -> bool {
        (own && i == si)
            || (self.links[si].group.is_some() && self.links[i].group == self.links[si].group)
    }

    /// Takes in a copy of a frame already taken in within the `dedup` window, received
    /// on link `id` at `now`: counted as received and as a duplicate, its source learned
    /// there (the copy proves the path), routed nowhere.
    pub(crate) fn take_duplicate(
        &mut self,
        id: LinkId,
        frame: &Frame<'_>,
        now: Timestamp,
        out: &mut Output,
    ) {
        let Some(i) = self.index(id) else {
            return;
        };
        let counters = &mut self.links[i].counters;
        counters.received(frame.as_bytes().len());
        counters.duplicate += 1;
        self.learn_source(i, frame.source(), now, out);
    }

    /// Takes in a frame addressed to the router itself (its flight log stream),
    /// received on link `id` at `now`: counted as received, its source learned there,
    /// routed nowhere.
    pub(crate) fn take_for_router(
        &mut self,
        id: LinkId,
        frame: &Frame<'_>,
        now: Timestamp,
        out: &mut Output,
    ) {
        let Some(i) = self.index(id) else {
            return;
        };
        let counters = &mut self.links[i].counters;
        counters.received(frame.as_bytes().len());
        self.learn_source(i, frame.source(), now, out);
    }

    /// Queues the router's own `packet` for system `system` on the links that know an
    /// address of it, at priority 0 (its flight log requests and acknowledgements).
    pub(crate) fn queue_own_to(&mut self, system: u8, packet: &Packet, out: &mut Output) {
        for k in 0..self.by_system[usize::from(system)].len() {
            let id = self.by_system[usize::from(system)][k];
            if let Some(i) = self.index(id) {
                self.push(i, packet.clone(), 0, out);
            }
        }
    }

    /// Queues the router's own `packet` (its heartbeat) on every link, at priority 0,
    /// within the queue bounds as any packet.
    pub(crate) fn queue_own(&mut self, packet: &Packet, out: &mut Output) {
        for i in 0..self.links.len() {
            self.push(i, packet.clone(), 0, out);
        }
    }
}
