//! Input: datagrams and stream bytes through an interface's parser into the router.

use super::*;

impl Engine {
    /// Routes the frames of a datagram from `peer` on interface `id`. A frame may
    /// continue in the same peer's next datagram; a datagram from another peer drops it.
    /// On a server, a peer without a link yet must pass the interface's limits.
    pub fn handle_datagram(
        &mut self,
        id: InterfaceId,
        peer: SocketAddr,
        bytes: &[u8],
        now: Timestamp,
    ) {
        self.settle_direct();
        let Some(Interface {
            parser,
            tail,
            kind,
            refused,
            described,
            signing: edge,
            group,
            retiring: None,
            ..
        }) = self.interfaces.get_mut(id.0)
        else {
            // Gone, or retiring: a reload removed it.
            return;
        };
        let sender = match kind {
            Kind::Datagram {
                remotes,
                last_sender,
                limits,
            } => {
                let link = remotes.link_of(peer);
                if link.is_none()
                    && let Err(why) = admission::admit(limits, remotes.len(), peer)
                {
                    if refused.count(why) {
                        let text = admission::refusal_text(described, why, peer.ip(), limits);
                        self.core.notices.push_back(Notice::Warning(text));
                    }
                    return;
                }
                if *last_sender != Some(peer) {
                    parser.clear();
                    *last_sender = Some(peer);
                }
                Sender::Remote {
                    remotes,
                    address: peer,
                    link,
                }
            }
            Kind::DatagramClient {
                link,
                last_sender,
                connection,
                ..
            } => {
                if !connection.is_open() {
                    return;
                }
                if *last_sender != Some(peer) {
                    parser.clear();
                    *last_sender = Some(peer);
                }
                Sender::Stream(*link)
            }
            Kind::Stream { .. } | Kind::Listener { .. } => return,
        };
        let had_link = matches!(
            sender,
            Sender::Stream(_) | Sender::Remote { link: Some(_), .. }
        );
        let mut intake = self
            .core
            .intake(now, sender, edge.as_mut(), *group, described);
        parser.feed_events(bytes, &mut intake);
        let new_link = (!had_link).then(|| intake.existing_link()).flatten();
        tail.received(now);
        let held = parser.pending_len() > 0;
        self.adopt_link(new_link, id);
        if held || self.deadlines.has(id) {
            self.refresh_deadline(id);
        }
        self.take_output();
    }

    /// Routes the frames completed by `bytes`, read from stream interface `id`.
    pub fn handle_stream(&mut self, id: InterfaceId, bytes: &[u8], now: Timestamp) {
        self.settle_direct();
        let Some(Interface {
            parser,
            tail,
            kind,
            signing: edge,
            described,
            group,
            retiring: None,
            ..
        }) = self.interfaces.get_mut(id.0)
        else {
            return;
        };
        let Kind::Stream {
            link, connection, ..
        } = *kind
        else {
            return;
        };
        if !connection.is_open() {
            return;
        }
        let mut intake =
            self.core
                .intake(now, Sender::Stream(link), edge.as_mut(), *group, described);
        parser.feed_events(bytes, &mut intake);
        tail.received(now);
        if parser.pending_len() > 0 || self.deadlines.has(id) {
            self.refresh_deadline(id);
        }
        self.take_output();
    }

    /// Counts `n` bytes that interface `id` received but does not route (a WebSocket's
    /// text message, a datagram too long to read whole) as junk of its parser.
    pub fn stream_junk(&mut self, id: InterfaceId, n: usize) {
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.parser.count_dropped(n);
        }
    }

    /// Moves the router's events into the notices and readies its output for reuse.
    pub(super) fn take_output(&mut self) {
        self.send_flight_log_frames();
        self.mark_queued();
        if self.core.out.direct.is_some() {
            self.resolve_held();
            self.mark_queued();
        }
        if !self.core.out.events.is_empty() {
            self.core
                .notices
                .extend(self.core.out.events.drain(..).map(Notice::Log));
        }
        self.core.out.clear();
    }

    /// Names the interfaces of the links that got a packet queued in
    /// [`Engine::poll_ready`].
    pub(super) fn mark_queued(&mut self) {
        for link in &self.core.out.queued {
            if let Some(&id) = self.owner.get(link) {
                self.ready.mark(id);
            }
        }
    }
}
