//! Output: what an interface may send now (pacing, the round robin between peers), and
//! the outcome of sending it.

use super::*;

impl Engine {
    /// Appends to `queue` up to `room` packets interface `id` may send at `now`: highest
    /// priority first on each link; between the peers of a datagram interface in turns
    /// (runs of up to [`SEND_TURN`] packets without `max_bitrate`, one packet with it);
    /// never faster than `max_bitrate`. When the pacer holds a packet back, the time it
    /// may go is part of [`Engine::poll_timeout`], and the interface is named by
    /// [`Engine::poll_ready`] again once it has passed. When it hands out `room`
    /// packets, call it again (after sending them) until it hands out fewer or the
    /// operating system refuses more: the interface is not named again for what is left.
    pub fn poll_transmit(
        &mut self,
        id: InterfaceId,
        now: Timestamp,
        room: usize,
        queue: &mut VecDeque<Transmit>,
    ) {
        self.settle_direct();
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        if room == 0 {
            return;
        }
        let Interface {
            pacer,
            pace_deadline,
            kind,
            signing: edge,
            ..
        } = interface;
        let was_paced = pace_deadline.take().is_some();
        let unpaced = pacer.rate() == 0;
        let router = &mut self.core.router;
        let signing = &mut self.core.signing;
        let mut left = room;
        // Takes the next packet of `link` if the pacer lets it go now, signed if the
        // interface has a key.
        let mut take = |router: &mut Router, link: LinkId| -> Result<Option<Packet>, Timestamp> {
            let Some(len) = router.peek(link).map(|p| match edge {
                Some(_) => sign::signed_len(p),
                None => p.len(),
            }) else {
                return Ok(None);
            };
            if let Pace::At(t) = pacer.check(now, len) {
                return Err(t);
            }
            pacer.sent(now, len);
            let packet = router.pop(link);
            let Some(edge) = edge.as_mut() else {
                return Ok(packet);
            };
            let signed = packet.as_deref().and_then(|p| signing.sign(edge, p, now));
            let Some(signed) = signed else {
                return Ok(packet);
            };
            edge.counters.signed_out += 1;
            if let Some(c) = router.counters_mut(link) {
                c.signing.signed_out += 1;
            }
            Ok(Some(signed))
        };
        match kind {
            Kind::Datagram { remotes, .. } => {
                let turn_len = if unpaced { SEND_TURN } else { 1 };
                'turns: while left > 0 {
                    let Some(turn) = remotes.next_ready(|l| router.peek(l).is_some()) else {
                        break;
                    };
                    let mut sent = 0;
                    while sent < turn_len && left > 0 {
                        match take(router, turn.link) {
                            Ok(Some(packet)) => {
                                queue.push_back(Transmit {
                                    link: turn.link,
                                    to: Some(turn.address),
                                    packet,
                                });
                                sent += 1;
                                left -= 1;
                            }
                            Ok(None) => break,
                            Err(t) => {
                                *pace_deadline = Some(t);
                                if sent > 0 {
                                    remotes.end_turn(&turn);
                                }
                                break 'turns;
                            }
                        }
                    }
                    remotes.end_turn(&turn);
                }
            }
            Kind::Stream {
                link, connection, ..
            } if connection.is_open() => {
                Self::drain_link(&mut take, router, *link, None, left, queue, pace_deadline);
            }
            Kind::DatagramClient {
                link,
                connection,
                target: Some(to),
                ..
            } if connection.is_open() => {
                let to = Some(*to);
                Self::drain_link(&mut take, router, *link, to, left, queue, pace_deadline);
            }
            Kind::Stream { .. } | Kind::DatagramClient { .. } | Kind::Listener { .. } => {}
        }
        if was_paced || pace_deadline.is_some() {
            self.refresh_deadline(id);
        }
    }

    /// Hands out up to `left` packets of `link` (going `to`) as far as `take` lets them.
    pub(super) fn drain_link(
        take: &mut impl FnMut(&mut Router, LinkId) -> Result<Option<Packet>, Timestamp>,
        router: &mut Router,
        link: LinkId,
        to: Option<SocketAddr>,
        mut left: usize,
        queue: &mut VecDeque<Transmit>,
        pace_deadline: &mut Option<Timestamp>,
    ) {
        while left > 0 {
            match take(router, link) {
                Ok(Some(packet)) => {
                    queue.push_back(Transmit { link, to, packet });
                    left -= 1;
                }
                Ok(None) => break,
                Err(t) => {
                    *pace_deadline = Some(t);
                    break;
                }
            }
        }
    }

    /// Notes that `t` was sent.
    #[inline]
    pub fn on_sent(&mut self, t: &Transmit) {
        if let Some(c) = self.core.router.counters_mut(t.link) {
            c.sent(t.packet.len());
        }
    }

    /// Takes back every packet of `sent`, which was sent (one batch the operating system
    /// took): each run of packets to one link is counted with one look-up of that link,
    /// and the packets are kept for reuse where nothing else holds them.
    pub fn on_sent_batch(&mut self, sent: impl IntoIterator<Item = Transmit>) {
        let mut run: Option<(LinkId, u64, usize)> = None;
        for t in sent {
            match &mut run {
                Some((link, frames, bytes)) if *link == t.link => {
                    *frames += 1;
                    *bytes += t.packet.len();
                }
                _ => {
                    if let Some((link, frames, bytes)) = run.take() {
                        self.count_sent(link, frames, bytes);
                    }
                    run = Some((t.link, 1, t.packet.len()));
                }
            }
            self.core.router.recycle(t.packet);
        }
        if let Some((link, frames, bytes)) = run {
            self.count_sent(link, frames, bytes);
        }
    }

    /// Counts `frames` frames of `bytes` bytes in all as sent on `link`.
    pub(super) fn count_sent(&mut self, link: LinkId, frames: u64, bytes: usize) {
        if let Some(c) = self.core.router.counters_mut(link) {
            c.sent_many(frames, bytes);
        }
    }

    /// Notes that `t` went with its stream: written in part or not at all when the
    /// stream failed. It is counted as a send error of its link; the stream's loss
    /// itself is said and counted once, by [`Engine::stream_lost`].
    pub fn on_stream_frame_lost(&mut self, t: &Transmit) {
        if let Some(c) = self.core.router.counters_mut(t.link) {
            c.send_errors += 1;
        }
    }

    /// Notes that `t` could not be sent on interface `id` (it is dropped). A datagram
    /// peer's first failure is reported; later ones are only counted, so a dead route
    /// cannot flood the log.
    pub fn on_send_failed(&mut self, id: InterfaceId, t: &Transmit, error: &io::Error) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        interface.io_errors += 1;
        let Some(c) = self.core.router.counters_mut(t.link) else {
            return;
        };
        c.send_errors += 1;
        if c.send_errors == 1
            && let Some(to) = t.to
        {
            self.core.notices.push_back(Notice::Error(format!(
                "{}: sending to {to} failed: {error} (further failures are only counted)",
                interface.described
            )));
        }
    }
}
