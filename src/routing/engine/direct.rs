//! Direct sends: when a datagram read on its own (light traffic) yields a packet for a
//! link whose queue is empty, the router holds it out of the queue
//! (`router/direct.rs`), and the loop hands it to the destination's driver at once,
//! before the rest of its turn. The queue, the ready list and the transmit hand-out are
//! skipped; what the packet counts, and where and in what order it goes, is what the
//! queue would have made of it.

use super::*;
use crate::routing::router::Direct;

impl Engine {
    /// [`Engine::handle_datagram`], allowing one accepted packet to skip its link's
    /// empty queue, when that link's interface is a datagram interface without
    /// `max_bitrate` or signing key that has nothing else to send. The caller then asks
    /// for it at once: the destination's driver takes it with [`Engine::take_direct`]
    /// if it has nothing else in flight, or [`Engine::queue_direct`] puts it in its
    /// queue after all. Any other call of the core queues it first.
    pub fn handle_datagram_direct(
        &mut self,
        id: InterfaceId,
        peer: SocketAddr,
        bytes: &[u8],
        now: Timestamp,
    ) {
        self.core.out.cut_through = true;
        self.handle_datagram(id, peer, bytes, now);
        self.core.out.cut_through = false;
    }

    /// The interface whose driver may send the held packet now, if there is one.
    #[inline]
    pub fn direct_interface(&self) -> Option<InterfaceId> {
        self.direct.as_ref().map(|(id, _)| *id)
    }

    /// The held packet of interface `id`, to send now (its driver has nothing else in
    /// flight): taken as [`Engine::poll_transmit`] would have handed it out.
    pub fn take_direct(&mut self, id: InterfaceId) -> Option<Transmit> {
        let (_, held) = self.direct.take_if(|(of, _)| *of == id)?;
        let to = self
            .interfaces
            .get_mut(id.0)
            .and_then(|interface| match &mut interface.kind {
                Kind::DatagramClient { target, .. } => *target,
                Kind::Datagram { remotes, .. } => remotes.take_turn(held.link),
                Kind::Stream { .. } | Kind::Listener { .. } => None,
            });
        self.core.router.release_direct(&held);
        Some(Transmit {
            link: held.link,
            to,
            packet: held.packet,
        })
    }

    /// Queues the held packet after all (its driver cannot send it now), and names its
    /// interface in [`Engine::poll_ready`].
    pub fn queue_direct(&mut self) {
        if let Some((_, held)) = self.direct.take() {
            self.core.router.queue_direct(held, &mut self.core.out);
            self.mark_queued();
            self.core.out.clear();
        }
    }

    /// Queues a held packet nobody asked for before the core does anything else, so
    /// that nothing can tell it apart from a queued one.
    #[inline]
    pub(super) fn settle_direct(&mut self) {
        if self.direct.is_some() {
            self.queue_direct();
        }
    }

    /// At the end of an input: keeps the packet the router held for a direct send if
    /// its interface can take one, else queues it.
    pub(super) fn resolve_held(&mut self) {
        let Some(held) = self.core.out.direct.take() else {
            return;
        };
        match self.direct_interface_of(&held) {
            Some(id) => self.direct = Some((id, held)),
            None => self.core.router.queue_direct(held, &mut self.core.out),
        }
    }

    /// The interface that may send `held` at once: a datagram interface whose packets
    /// go out as they are (no `max_bitrate`, no signing key), open, with a peer to send
    /// to, and with nothing else to hand out (so no other link of it would have gone
    /// first).
    fn direct_interface_of(&self, held: &Direct) -> Option<InterfaceId> {
        let &id = self.owner.get(&held.link)?;
        let interface = self.interfaces.get(id.0)?;
        if self.ready.contains(id) || interface.signing.is_some() || interface.pacer.rate() != 0 {
            return None;
        }
        match &interface.kind {
            Kind::DatagramClient {
                link,
                target: Some(_),
                connection,
                ..
            } if *link == held.link && connection.is_open() => Some(id),
            Kind::Datagram { .. } => Some(id),
            Kind::DatagramClient { .. } | Kind::Stream { .. } | Kind::Listener { .. } => None,
        }
    }
}
