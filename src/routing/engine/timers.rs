//! Time: the next deadline and what runs when it comes (the expiry tick — with the
//! once-a-second statistics snapshot and signing-state save it schedules — stale
//! held-back bytes, pacing, reopening).

use super::*;
use crate::signing::state::SAVE_INTERVAL_SECS;

// The signing state is saved with the tick: the crash margin of a saved state assumes
// saves at most SAVE_INTERVAL_SECS apart.
const _: () = assert!(TICK.as_secs() == SAVE_INTERVAL_SECS && TICK.subsec_nanos() == 0);

impl Engine {
    /// The next instant something is due: the expiry tick, held-back bytes turning
    /// stale, a packet the pacer holds back, opening an interface again, or the router's
    /// own heartbeat. Its cost
    /// does not grow with the number of interfaces (the deadlines are kept in order).
    pub fn poll_timeout(&self) -> Timestamp {
        let due = self
            .deadlines
            .first()
            .map_or(self.next_tick, |t| t.min(self.next_tick));
        let due = self.heartbeat.as_ref().map_or(due, |h| due.min(h.due()));
        self.core
            .flight_log
            .as_ref()
            .and_then(FlightLogger::poll_timeout)
            .map_or(due, |t| due.min(t))
    }

    /// Runs what is due at `now` (see [`Engine::poll_timeout`]). Calling it early, or
    /// more than once, is harmless: only what is due runs, and only the interfaces
    /// whose deadline passed are visited.
    pub fn handle_timeout(&mut self, now: Timestamp) {
        self.settle_direct();
        let mut due = std::mem::take(&mut self.due);
        self.deadlines.take_due(now, &mut due);
        for &id in &due {
            self.handle_interface_timeout(id, now);
            self.refresh_deadline(id);
        }
        due.clear();
        self.due = due;
        self.send_heartbeat(now);
        if let Some(log) = self.core.flight_log.as_mut()
            && log.poll_timeout().is_some_and(|t| t <= now)
        {
            log.handle_timeout(now);
        }
        if now >= self.next_tick {
            for id in self.core.router.tick(now) {
                self.forget(id);
            }
            self.next_tick = now + TICK;
            // What the event loop does once a second, scheduled here with the tick.
            if self.config.stats.is_some() {
                self.core.notices.push_back(Notice::PublishStats);
            }
            if let Some(state) = self.core.signing.take_state(false, now) {
                self.core
                    .notices
                    .push_back(Notice::SaveSigningState(Box::new(state)));
            }
        }
        self.take_output();
    }

    /// Runs what is due at `now` on interface `id`: lets the pacer's held-back packet
    /// go, asks for a reopen, gives up on held-back bytes, or closes an interface a
    /// reload removed whose queue was not sent in time.
    pub(super) fn handle_interface_timeout(&mut self, id: InterfaceId, now: Timestamp) {
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        if interface.retiring.is_some_and(|t| t <= now) {
            self.close_retiring(id);
            return;
        }
        if interface.pace_deadline.is_some_and(|t| t <= now) {
            // The pacer decides afresh when the loop polls for transmits.
            interface.pace_deadline = None;
            self.ready.mark(id);
        }
        let open = interface.is_open();
        if let Some(connection) = interface.connection_mut()
            && connection.ask_if_due(now)
        {
            self.core.notices.push_back(Notice::Open(id));
        }
        let Interface {
            parser,
            tail,
            kind,
            signing: edge,
            described,
            group,
            ..
        } = interface;
        let stale = open
            && tail
                .deadline(parser.pending_len())
                .is_some_and(|t| t <= now);
        if !stale {
            return;
        }
        let sender = match kind {
            Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => {
                Some(Sender::Stream(*link))
            }
            Kind::Datagram {
                remotes,
                last_sender,
                ..
            } => last_sender.map(|address| Sender::Remote {
                link: remotes.link_of(address),
                remotes,
                address,
            }),
            Kind::Listener { .. } => None,
        };
        let Some(sender) = sender else {
            return;
        };
        // The candidate is rejected and the bytes behind its start scanned again, so
        // valid frames held up behind noise are routed now.
        let mut intake = self
            .core
            .intake(now, sender, edge.as_mut(), *group, described);
        parser.finish(&mut intake);
        let link = intake.existing_link();
        self.adopt_link(link, id);
    }

    /// Forgets the peer of a link the router removed.
    pub(super) fn forget(&mut self, id: LinkId) {
        for (_, interface) in &mut self.interfaces {
            if let Kind::Datagram { remotes, .. } = &mut interface.kind
                && let Some(address) = remotes.remove(id)
            {
                self.owner.remove(&id);
                self.core.notices.push_back(Notice::LinkRemoved {
                    id,
                    name: address.to_string(),
                });
                return;
            }
        }
    }
}
