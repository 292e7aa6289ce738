//! Cut-through: a packet accepted for a link whose queue is empty may skip the queue and
//! be sent at once, before the rest of the turn's work (see `Engine::handle_datagram_direct`).
//! At the rates vehicles send, nearly every packet finds its queue empty, and the queue,
//! the ready list and the transmit hand-out are work done before the send that changes
//! nothing.
//!
//! The held packet counts exactly as if it had been queued and then popped: the link's
//! high-water mark sees it, and it is part of the shared total ([`Router::queued_bytes`])
//! until it is taken. The moment anything could tell the difference, it goes into its
//! queue after all, where it would have been: when another packet comes for the same
//! link, when the shared capacity runs out (it could then have been evicted), or when
//! the caller does not send it.

use super::{Output, Router};
use crate::routing::link::LinkId;
use crate::routing::queue::{Packet, PacketQueue};

/// A packet held out of its link's empty queue, to be sent at once.
#[derive(Debug)]
pub(crate) struct Direct {
    /// The link it goes to.
    pub(crate) link: LinkId,
    /// Its bytes.
    pub(crate) packet: Packet,
    /// The priority it would have been queued with.
    pub(crate) priority: i32,
}

impl Router {
    /// Holds `packet` for link `i` out of the link's queue if the queue is empty and the
    /// packet fits both it and the shared capacity without evicting anything; gives it
    /// back otherwise (queue it then).
    pub(super) fn hold(
        &mut self,
        i: usize,
        packet: Packet,
        priority: i32,
        out: &mut Output,
    ) -> Result<(), Packet> {
        let cost = PacketQueue::cost_of(&packet);
        if self.queued_bytes.saturating_add(cost) > self.options.total_queue_capacity
            || !self.links[i].queue.pass(cost)
        {
            return Err(packet);
        }
        self.queued_bytes += cost;
        out.direct = Some(Direct {
            link: self.links[i].id(),
            packet,
            priority,
        });
        Ok(())
    }

    /// Before a packet of `cost` bytes is queued on link `i`: queues the held packet
    /// first if the two would otherwise tell apart from a queue that held it all along
    /// (the same link, or the shared capacity running out). It is queued as it would
    /// have been when it was held: its queue was empty then and has been left alone
    /// since, so it fits as it did.
    pub(super) fn queue_held_if_observed(&mut self, i: usize, cost: usize, out: &mut Output) {
        let link = self.links[i].id();
        let crowded = self.queued_bytes.saturating_add(cost) > self.options.total_queue_capacity;
        if let Some(held) = out.direct.take_if(|d| crowded || d.link == link) {
            self.queue_direct(held, out);
        }
    }

    /// Queues `held`, a packet held out of its queue, after all.
    pub(crate) fn queue_direct(&mut self, held: Direct, out: &mut Output) {
        self.queued_bytes -= PacketQueue::cost_of(&held.packet);
        if let Some(i) = self.index(held.link) {
            self.enqueue(i, held.packet, held.priority, out);
        }
        // A link removed meanwhile drops it, as it drops what its queue held.
    }

    /// Notes that `held` was taken to be sent: it leaves the shared total, as a packet
    /// taken from a queue does.
    pub(crate) fn release_direct(&mut self, held: &Direct) {
        self.queued_bytes -= PacketQueue::cost_of(&held.packet);
    }
}
