//! Streams and clients opening, failing and closing, and receive errors.

use super::*;

impl Engine {
    /// Notes that receiving on interface `id` failed (other than "would block").
    pub fn on_receive_failed(&mut self, id: InterfaceId, error: &io::Error) {
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.io_errors += 1;
            self.core.notices.push_back(Notice::Error(format!(
                "{}: receive failed: {error}",
                interface.described
            )));
        }
    }

    /// Notes that stream `id` failed (`why` says how: a failed send, a refused
    /// handshake): said and counted as one I/O error. Its loss follows, through
    /// [`Engine::stream_lost`].
    pub fn on_stream_failed(&mut self, id: InterfaceId, why: &dyn Display) {
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.io_errors += 1;
            self.core
                .notices
                .push_back(Notice::Error(format!("{}: {why}", interface.described)));
        }
    }

    /// Interface `id` (a stream or a datagram client) was opened at `now`. What was
    /// queued for a client that stayed down too long is dropped now (stale telemetry is
    /// not replayed).
    pub fn stream_opened(&mut self, id: InterfaceId, now: Timestamp) {
        self.settle_direct();
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        let link = interface.own_link();
        let frames = interface.parser.stats().frames;
        let Some(connection) = interface.connection_mut() else {
            return;
        };
        connection.opened(now, frames);
        interface.parser.clear();
        if let Kind::Stream { reopen, .. } = &mut interface.kind
            && let Some(since) = reopen.down_since.take()
            && reopen.forget_after.is_some_and(|limit| now > since + limit)
            && let Some(link) = link
        {
            self.core.router.clear_queue(link);
        }
        let flapping = matches!(&interface.kind, Kind::Stream { reopen, .. } if reopen.flapping);
        if interface.io_errors > 0 && !flapping {
            self.core
                .notices
                .push_back(Notice::Warning(format!("{} is back", interface.described)));
        }
        // What was queued while it was closed can go now.
        self.mark_ready(id);
        self.refresh_deadline(id);
    }

    /// Opening interface `id` failed at `now`: it is tried again after a backoff (said
    /// once per outage, not once per attempt).
    pub fn stream_open_failed(&mut self, id: InterfaceId, now: Timestamp, error: &dyn Display) {
        self.settle_direct();
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        let cap = match &interface.kind {
            Kind::Stream { reopen, .. } => reopen.max_wait,
            _ => MAX_BACKOFF,
        };
        if let Some(connection) = interface.connection_mut()
            && connection.failed(now, cap)
        {
            interface.io_errors += 1;
            self.core.notices.push_back(Notice::Warning(format!(
                "cannot open {}: {error}; retrying until it appears",
                interface.described
            )));
        }
        self.refresh_deadline(id);
    }

    /// Stream `id` was lost at `now` (unplugged, closed by the peer, a read or write
    /// error): held-back bytes are dropped; a configured stream is opened again after
    /// its first wait, an accepted connection is removed with its link.
    pub fn stream_lost(&mut self, id: InterfaceId, now: Timestamp, why: &dyn Display) {
        self.settle_direct();
        let Some(interface) = self.interfaces.get_mut(id.0) else {
            return;
        };
        if interface.retiring.is_some() {
            // A reload removed it: it is not opened again.
            self.close_retiring(id);
            return;
        }
        interface.parser.clear();
        match &mut interface.kind {
            Kind::Stream {
                accepted_by: Some(server),
                link,
                ..
            } => {
                let (server, link) = (*server, *link);
                self.close_connection(id, server, link);
            }
            Kind::Stream {
                connection, reopen, ..
            } => {
                let frames = interface.parser.stats().frames;
                let soon = connection.lost(now, reopen.first_wait, reopen.max_wait, frames);
                reopen.down_since = Some(now);
                interface.io_errors += 1;
                // Lost again right after it opened: said once, then quiet (and not said
                // back either) until a connection stays.
                let said = match (soon, reopen.flapping) {
                    (false, _) => Some(format!("{} lost: {why}", interface.described)),
                    (true, false) => Some(format!(
                        "{} lost again right after it opened: {why}; tried again with a growing wait, quietly until a connection stays",
                        interface.described
                    )),
                    (true, true) => None,
                };
                reopen.flapping = soon;
                if let Some(said) = said {
                    self.core.notices.push_back(Notice::Warning(said));
                }
            }
            Kind::DatagramClient { connection, .. } => {
                let frames = interface.parser.stats().frames;
                connection.lost(now, FIRST_BACKOFF, MAX_BACKOFF, frames);
                interface.io_errors += 1;
                self.core.notices.push_back(Notice::Warning(format!(
                    "{} lost: {why}",
                    interface.described
                )));
            }
            Kind::Datagram { .. } | Kind::Listener { .. } => {}
        }
        self.refresh_deadline(id);
    }

    /// Stream `id` was lost at `now` for an error (`why`: a failed read or write), not
    /// a plain end of stream: as [`Engine::stream_lost`], and the error of an accepted
    /// connection is counted too, on its server (a configured stream counts every loss).
    pub fn stream_broken(&mut self, id: InterfaceId, now: Timestamp, why: &dyn Display) {
        if let Some(interface) = self.interfaces.get_mut(id.0)
            && matches!(
                interface.kind,
                Kind::Stream {
                    accepted_by: Some(_),
                    ..
                }
            )
        {
            interface.io_errors += 1;
        }
        self.stream_lost(id, now, why);
    }

    /// Removes accepted connection `id` of `server` and its link.
    pub(super) fn close_connection(&mut self, id: InterfaceId, server: InterfaceId, link: LinkId) {
        let Some(closed) = self.interfaces.try_remove(id.0) else {
            return;
        };
        self.core.router.remove_link(link);
        self.owner.remove(&link);
        if let Some(server) = self.interfaces.get_mut(server.0) {
            server.closed_parsers += *closed.parser.stats();
            server.io_errors += closed.io_errors;
            if let (Some(total), Some(edge)) = (server.signing.as_mut(), &closed.signing) {
                total.counters += edge.counters;
            }
            if let Kind::Listener { connections, .. } = &mut server.kind {
                *connections = connections.saturating_sub(1);
            }
        }
        self.core.notices.push_back(Notice::LinkRemoved {
            id: link,
            name: closed.label,
        });
        self.core.notices.push_back(Notice::Closed(id));
    }
}
