//! The remotes of one datagram interface: which peer address is which link, in the order
//! their first valid frame arrived, and whose turn it is to send.

use std::cell::Cell;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::net::SocketAddr;

use super::link::LinkId;

/// A peer address as a key of the map: compared as the address, hashed (still by the
/// keyed SipHash, since peers choose their addresses) from one or two integers instead
/// of field by field, which takes a third of the instructions for every datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PeerKey(SocketAddr);

impl Hash for PeerKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        // Equal addresses write equal integers; what equality compares beyond them
        // (an IPv6 flow label) only makes equal hashes more common, never wrong.
        match self.0 {
            SocketAddr::V4(a) => {
                state.write_u64(u64::from(a.ip().to_bits()) << 16 | u64::from(a.port()))
            }
            SocketAddr::V6(a) => {
                state.write_u128(a.ip().to_bits());
                state.write_u64(u64::from(a.scope_id()) << 16 | u64::from(a.port()));
            }
        }
    }
}

/// Peer address ↔ link of one datagram interface, and its round-robin turn.
#[derive(Debug, Default)]
pub struct Remotes {
    by_address: HashMap<PeerKey, LinkId>,
    /// Links in creation order with their peer address: the round-robin order.
    order: Vec<(LinkId, SocketAddr)>,
    /// Index into `order` of the link whose turn comes next.
    next_turn: usize,
    /// The address asked for last and its link: datagrams mostly come in runs from one
    /// peer, and the map's keyed hash costs ~160 instructions a datagram. Forgotten
    /// whenever a remote is removed.
    last: Cell<Option<(SocketAddr, LinkId)>>,
}

impl Remotes {
    /// The link of `address`, if it has one.
    #[inline]
    pub(crate) fn link_of(&self, address: SocketAddr) -> Option<LinkId> {
        if let Some((last, link)) = self.last.get()
            && last == address
        {
            return Some(link);
        }
        let link = self.by_address.get(&PeerKey(address)).copied();
        if let Some(link) = link {
            self.last.set(Some((address, link)));
        }
        link
    }

    /// Records that `address` is link `id` (its first valid frame just arrived).
    pub(crate) fn insert(&mut self, address: SocketAddr, id: LinkId) {
        self.by_address.insert(PeerKey(address), id);
        self.order.push((id, address));
    }

    /// Forgets link `id`; returns its address if it was one of these remotes.
    pub(crate) fn remove(&mut self, id: LinkId) -> Option<SocketAddr> {
        let i = self.order.iter().position(|(l, _)| *l == id)?;
        let (_, address) = self.order.remove(i);
        self.by_address.remove(&PeerKey(address));
        self.last.set(None);
        if self.next_turn > i {
            self.next_turn -= 1;
        }
        if self.next_turn >= self.order.len() {
            self.next_turn = 0;
        }
        Some(address)
    }

    /// Every link with its address, in creation order.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (LinkId, SocketAddr)> + '_ {
        self.order.iter().copied()
    }

    /// Number of remotes.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True when no remote has sent a valid frame yet (or all have expired).
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The first link, in round-robin order from the current turn, for which `ready`
    /// holds. One scan at most; the turn stays where it is until [`Remotes::end_turn`].
    #[inline]
    pub(crate) fn next_ready(&self, mut ready: impl FnMut(LinkId) -> bool) -> Option<Turn> {
        let n = self.order.len();
        (0..n).find_map(|k| {
            let index = (self.next_turn + k) % n;
            let (link, address) = self.order[index];
            ready(link).then_some(Turn {
                index,
                link,
                address,
            })
        })
    }

    /// The address of link `link`, whose turn it takes: the turn passes to the link
    /// after it, as after [`Remotes::end_turn`].
    pub(crate) fn take_turn(&mut self, link: LinkId) -> Option<SocketAddr> {
        let index = self.order.iter().position(|(l, _)| *l == link)?;
        self.next_turn = (index + 1) % self.order.len();
        Some(self.order[index].1)
    }

    /// Passes the turn to the link after the one that just had `turn`.
    #[inline]
    pub(crate) fn end_turn(&mut self, turn: &Turn) {
        self.next_turn = (turn.index + 1) % self.order.len().max(1);
    }
}

/// A link whose turn it is to send (see [`Remotes::next_ready`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Turn {
    index: usize,
    /// The link.
    pub link: LinkId,
    /// Its peer address.
    pub address: SocketAddr,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[test]
    fn turns_go_round_and_survive_removal() {
        let mut r = Remotes::default();
        for i in 0..4 {
            r.insert(addr(1000 + i), LinkId(u64::from(i)));
        }
        let mut turns = Vec::new();
        for _ in 0..6 {
            let turn = r.next_ready(|_| true).expect("a link is ready");
            r.end_turn(&turn);
            turns.push(Some(turn.link.0));
        }
        assert_eq!(
            turns,
            [Some(0), Some(1), Some(2), Some(3), Some(0), Some(1)]
        );
        // Link 2's turn is next; removing link 0 (before it) keeps link 2 next.
        assert_eq!(r.remove(LinkId(0)), Some(addr(1000)));
        assert_eq!(r.next_ready(|_| true).map(|t| t.link.0), Some(2));
        // Without `end_turn` the turn stays.
        assert_eq!(r.next_ready(|_| true).map(|t| t.link.0), Some(2));
        assert_eq!(r.link_of(addr(1000)), None);
        assert_eq!(r.link_of(addr(1003)), Some(LinkId(3)));
        // Only link 1 ready: found whatever the turn.
        assert_eq!(r.next_ready(|id| id.0 == 1).map(|t| t.link.0), Some(1));
        assert_eq!(r.next_ready(|_| false), None);
        assert_eq!(r.remove(LinkId(9)), None);
        assert_eq!(r.len(), 3);
    }

    #[test]
    fn the_last_address_asked_for_is_forgotten_with_its_link() {
        let mut r = Remotes::default();
        r.insert(addr(1000), LinkId(0));
        r.insert(addr(1001), LinkId(1));
        assert_eq!(r.link_of(addr(1001)), Some(LinkId(1)));
        assert_eq!(r.link_of(addr(1001)), Some(LinkId(1)));
        assert_eq!(r.link_of(addr(1000)), Some(LinkId(0)));
        r.remove(LinkId(0));
        assert_eq!(r.link_of(addr(1000)), None);
        // The same address back as a new link: the new link, not the one remembered.
        r.insert(addr(1000), LinkId(2));
        assert_eq!(r.link_of(addr(1000)), Some(LinkId(2)));
        assert_eq!(r.link_of(addr(1001)), Some(LinkId(1)));
        r.remove(LinkId(1));
        assert_eq!(r.link_of(addr(1001)), None);
        assert_eq!(r.link_of(addr(1000)), Some(LinkId(2)));
    }
}
