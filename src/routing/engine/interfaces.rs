//! Adding interfaces and what they carry: UDP and TCP servers and clients, serial ports,
//! accepted connections, signing keys, the recording tap and the signing state.

use super::*;

impl Engine {
    /// Adds a datagram server (a UDP socket) named `label`: any number of peers, each a
    /// link from its first valid frame, within `limits`; sending at most `max_bitrate`
    /// bit/s (0: no limit).
    pub fn add_datagram_interface(
        &mut self,
        label: String,
        max_bitrate: u64,
        limits: PeerLimits,
    ) -> InterfaceId {
        self.push_interface(Interface::network(
            label,
            max_bitrate,
            Kind::Datagram {
                remotes: Remotes::default(),
                last_sender: None,
                limits,
            },
        ))
    }

    /// Adds a datagram client named `label` whose one link is `link_name`: it sends to
    /// its target from the start (once [`Engine::set_target`] names it), and whatever
    /// its socket receives is that link's. Opened like a stream ([`Notice::Open`]).
    pub fn add_datagram_client(
        &mut self,
        label: String,
        link_name: &str,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self.core.router.add_client_link(link_name, now);
        self.push_interface(Interface::network(
            label,
            max_bitrate,
            Kind::DatagramClient {
                link,
                target: None,
                last_sender: None,
                connection: Connection::new(now),
            },
        ))
    }

    /// Sets where datagram client `id` sends (its resolved target).
    pub fn set_target(&mut self, id: InterfaceId, target: SocketAddr) {
        if let Some(Interface {
            kind: Kind::DatagramClient { target: t, .. },
            ..
        }) = self.interfaces.get_mut(id.0)
        {
            *t = Some(target);
            self.mark_ready(id);
        }
    }

    /// Adds a byte-stream interface that is one link named `device` (a serial port at
    /// `baudrate`), reaching `preload` permanently. The core asks for it to be opened
    /// ([`Notice::Open`]) at the first [`Engine::handle_timeout`], and again with a
    /// backoff whenever it is missing or lost.
    pub fn add_stream_interface(
        &mut self,
        device: &str,
        preload: &[Address],
        baudrate: Option<u32>,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self
            .core
            .router
            .add_serial_link(device, preload, now, &mut self.core.out);
        self.take_output();
        self.push_interface(Interface::new(
            device.to_string(),
            format!("serial device {device}"),
            StaleTail::new(baudrate),
            max_bitrate,
            Kind::stream(link, Connection::new(now), None, Reopen::DEVICE),
        ))
    }

    /// Adds a stream client (a TCP client) named `label` whose one link is `link_name`:
    /// opened at once, reconnected at once after a loss and then with a backoff capped
    /// at one second, forever; what was queued while it was down longer than
    /// [`FORGET_AFTER`] is dropped when it comes back, or when it first connects (it is
    /// down from `now` until then).
    pub fn add_stream_client(
        &mut self,
        label: String,
        link_name: &str,
        max_bitrate: u64,
        now: Timestamp,
    ) -> InterfaceId {
        let link = self.core.router.add_client_link(link_name, now);
        self.push_interface(Interface::reliable_stream(
            label,
            max_bitrate,
            Kind::stream(
                link,
                Connection::new(now),
                None,
                Reopen {
                    down_since: Some(now),
                    ..Reopen::client(FORGET_AFTER)
                },
            ),
        ))
    }

    /// Adds a stream server (a TCP listener) named `label`, taking connections within
    /// `limits` ([`Engine::accept`]); each sends at most `max_bitrate` bit/s (0: no
    /// limit).
    pub fn add_listener(
        &mut self,
        label: String,
        limits: PeerLimits,
        max_bitrate: u64,
    ) -> InterfaceId {
        self.add_listener_of("tcp", label, limits, max_bitrate)
    }

    /// A stream server like [`Engine::add_listener`] whose connections' links are named
    /// `SCHEME:a.b.c.d:port` (`ws` for a WebSocket server).
    pub fn add_listener_of(
        &mut self,
        scheme: &'static str,
        label: String,
        limits: PeerLimits,
        max_bitrate: u64,
    ) -> InterfaceId {
        self.push_interface(Interface::reliable_stream(
            label,
            0,
            Kind::Listener {
                limits,
                connections: 0,
                max_bitrate,
                scheme,
            },
        ))
    }

    /// A connection from `peer` arrived at server `listener`: returns its new stream
    /// interface (one link, named `tcp:a.b.c.d:port` or `ws:…`, paced at the server's
    /// `max_bitrate`), or None if the server's limits refuse it (counted; said once per
    /// reason). Close a refused connection at once.
    pub fn accept(
        &mut self,
        listener: InterfaceId,
        peer: SocketAddr,
        now: Timestamp,
    ) -> Option<InterfaceId> {
        self.settle_direct();
        let server = self.interfaces.get_mut(listener.0)?;
        let Kind::Listener {
            limits,
            connections,
            max_bitrate,
            scheme,
        } = &mut server.kind
        else {
            return None;
        };
        if let Err(why) = admission::admit(limits, *connections, peer) {
            if server.refused.count(why) {
                let text = admission::refusal_text(&server.described, why, peer.ip(), limits);
                self.core.notices.push_back(Notice::Warning(text));
            }
            return None;
        }
        *connections += 1;
        let max_bitrate = *max_bitrate;
        let edge = server.signing.as_ref().map(Edge::fresh_copy);
        let group = server.group;
        let name = format!("{scheme}:{peer}");
        let link = self.core.router.add_connection_link(&name, now);
        self.core.router.set_group(link, group);
        self.core.notices.push_back(Notice::LinkAdded {
            id: link,
            name: name.clone(),
        });
        let mut connection = Interface::reliable_stream(
            name,
            max_bitrate,
            Kind::stream(
                link,
                Connection::open(now),
                Some(listener),
                Reopen::ACCEPTED,
            ),
        );
        connection.signing = edge;
        connection.group = group;
        Some(self.push_interface(connection))
    }

    /// Gives interface `id` a signing key: signed frames arriving there are checked
    /// with it (and unsigned ones dropped unless `allow_unsigned`), and unsigned
    /// MAVLink 2 frames leaving there are signed with it and `link_id`. A server's
    /// connections take its key.
    pub fn set_signing(
        &mut self,
        id: InterfaceId,
        key: SigningKey,
        allow_unsigned: bool,
        link_id: u8,
    ) {
        let key_slot = self.core.signing.add_key(key);
        if let Some(interface) = self.interfaces.get_mut(id.0) {
            interface.signing = Some(Edge {
                key_slot,
                allow_unsigned,
                link_id,
                counters: Default::default(),
                said: Vec::new(),
            });
        }
    }

    /// Starts recording: from now on every frame taken in (after the signing check of
    /// its interface) that `filter` passes is kept, with its time of arrival, until
    /// [`Engine::poll_recorded`] takes it. Take them every loop turn: what does not fit
    /// in a bounded buffer is dropped and counted ([`Engine::recording_dropped`]).
    pub fn set_recording(&mut self, filter: RecordFilter) {
        self.core.tap = Some(Tap::new(filter));
    }

    /// Stops recording (a reload removed or changed the `record` block): frames kept
    /// and not yet taken are dropped.
    pub fn stop_recording(&mut self) {
        self.core.tap = None;
    }

    /// Hands each frame kept for recording to `take` with its time of arrival, oldest
    /// first (arrival order), and forgets them.
    #[inline]
    pub fn poll_recorded(&mut self, take: &mut impl FnMut(Timestamp, &[u8])) {
        if let Some(tap) = self.core.tap.as_mut().filter(|t| !t.is_empty()) {
            tap.drain(take);
        }
    }

    /// Frames not kept for recording because the buffer was full.
    pub fn recording_dropped(&self) -> u64 {
        self.core.tap.as_ref().map_or(0, Tap::dropped)
    }

    /// Notes the wall clock for signing: at `now` it read `units` (MAVLink signature
    /// time, 10 µs units since 2015-01-01 UTC). Call it at start and about once a second.
    pub fn set_wall_clock(&mut self, now: Timestamp, units: u64) {
        self.core.signing.set_wall_clock(now, units);
    }

    /// True when some interface has a signing key (so there is signing state to keep).
    pub fn has_signing_keys(&self) -> bool {
        self.core.signing.has_keys()
    }

    /// Takes over signing state saved by an earlier run, before any frame (after every
    /// [`Engine::set_signing`]); returns how many streams it knew.
    pub fn restore_signing_state(&mut self, state: &SavedState) -> usize {
        self.core.signing.restore(state, true)
    }

    /// Takes the streams of `state`, saved by this run, that the table does not know
    /// (those of keys a reload added); returns how many.
    pub fn restore_signing_streams(&mut self, state: &SavedState) -> usize {
        self.core.signing.restore(state, false)
    }

    /// The signing state to save at `now`, if it changed since the last call (always
    /// when `clean`: the router is stopping).
    pub fn signing_state(&mut self, clean: bool, now: Timestamp) -> Option<SavedState> {
        self.core.signing.take_state(clean, now)
    }
}
