//! Message interfaces (Zenoh): one whole frame per message, and which systems the
//! router reaches through its other links, for the interface to subscribe to.

use super::*;

/// A set of MAVLink system ids (0–255).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SystemSet([u64; 4]);

impl SystemSet {
    /// Adds `system`.
    pub fn insert(&mut self, system: u8) {
        self.0[usize::from(system >> 6)] |= 1 << (system & 63);
    }

    /// True if `system` is in the set.
    pub fn contains(&self, system: u8) -> bool {
        self.0[usize::from(system >> 6)] & (1 << (system & 63)) != 0
    }

    /// The systems in the set, lowest first.
    pub fn iter(&self) -> impl Iterator<Item = u8> + '_ {
        (0..=255u8).filter(|&s| self.contains(s))
    }
}

impl Engine {
    /// Routes the frames of one message received on stream interface `id` (a Zenoh
    /// sample): a frame never continues in the next message, so bytes left over are
    /// dropped, and one bad message cannot spoil the next.
    pub fn handle_message(&mut self, id: InterfaceId, bytes: &[u8], now: Timestamp) {
        self.handle_stream(id, bytes, now);
        if let Some(interface) = self.interfaces.get_mut(id.0)
            && interface.parser.pending_len() > 0
        {
            interface.parser.clear();
            self.refresh_deadline(id);
        }
    }

    /// The systems with an address present at `now` on some link other than interface
    /// `id`'s own: those the router reaches elsewhere, whose frames a message interface
    /// subscribes to (system 0, "every system", is never one of them).
    pub fn systems_elsewhere(&self, id: InterfaceId, now: Timestamp) -> SystemSet {
        let own = self.stream_link(id);
        let mut set = SystemSet::default();
        for link in self.core.router.links() {
            if Some(link.id()) == own {
                continue;
            }
            for address in link.pool().addresses(now) {
                if address.system != 0 {
                    set.insert(address.system);
                }
            }
        }
        set
    }
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;
    use std::net::SocketAddr;
    use std::time::Duration;

    use super::SystemSet;
    use crate::config::{PeerLimits, load};
    use crate::routing::{Engine, RouterOptions, Timestamp};
    use crate::wire::encode::{Header, encode_v2};

    fn heartbeat(system: u8) -> Vec<u8> {
        let header = Header {
            seq: 0,
            system,
            component: 1,
        };
        let mut out = Vec::new();
        encode_v2(header, 0, &[1, 2, 3, 4, 5, 6, 7, 8, 9], None, &mut out).expect("encode");
        out
    }

    /// A message interface (Zenoh's shape: one stream link, one frame per message) next
    /// to a UDP server: its subscriptions follow the systems the UDP side reaches, until
    /// their addresses expire; what came from it never goes back to it; a bad message
    /// spoils nothing after it.
    #[test]
    fn a_message_interface_follows_the_systems_elsewhere() {
        let config = load("default_action accept;").expect("config").config;
        let mut e = Engine::new(&config, RouterOptions::default());
        let t0 = Timestamp::ZERO;
        let zenoh = e.add_stream_client("zenoh t".into(), "zenoh t", 0, t0);
        e.stream_opened(zenoh, t0);
        let udp = e.add_datagram_interface("udp".into(), 0, PeerLimits::default());
        let peer = SocketAddr::from(([127, 0, 0, 1], 5000));
        assert_eq!(e.systems_elsewhere(zenoh, t0), SystemSet::default());

        let before = e.router().systems_generation();
        e.handle_datagram(udp, peer, &heartbeat(3), t0);
        e.handle_message(zenoh, &heartbeat(9)[..7], t0); // cut short: dropped
        e.handle_message(zenoh, &heartbeat(9), t0);
        let systems: Vec<u8> = e.systems_elsewhere(zenoh, t0).iter().collect();
        assert_eq!(systems, [3], "system 9 is behind Zenoh itself");
        // Learning moved the generation an edge watches.
        let learned = e.router().systems_generation();
        assert_ne!(learned, before);

        // Vehicle 3's heartbeat went out to Zenoh; system 9's went to the UDP peer only.
        let mut out = VecDeque::new();
        e.poll_transmit(zenoh, t0, 16, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(&out[0].packet[..], &heartbeat(3)[..]);
        out.clear();
        e.poll_transmit(udp, t0, 16, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(&out[0].packet[..], &heartbeat(9)[..]);
        // A known address again does not move it.
        e.handle_datagram(udp, peer, &heartbeat(3), t0);
        assert_eq!(e.router().systems_generation(), learned);

        // Addresses expire like any other link's: after 120 s of silence, nothing is
        // reached elsewhere, and system 9 is forgotten on the Zenoh link too.
        let later = t0 + Duration::from_secs(121);
        e.handle_timeout(later);
        assert_eq!(e.systems_elsewhere(zenoh, later), SystemSet::default());
        let link = e.stream_link(zenoh).expect("its link");
        let pool = e.router().link(link).expect("link").pool();
        assert!(pool.is_empty(later));
    }

    #[test]
    fn a_system_set_holds_every_id() {
        let mut s = SystemSet::default();
        for id in [0, 1, 63, 64, 200, 255] {
            s.insert(id);
        }
        assert_eq!(s.iter().collect::<Vec<_>>(), [0, 1, 63, 64, 200, 255]);
        assert!(!s.contains(2));
    }
}
