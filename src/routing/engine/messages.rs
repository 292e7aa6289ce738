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
    use super::SystemSet;

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
