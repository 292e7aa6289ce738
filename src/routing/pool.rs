//! The MAVLink addresses reachable through one link, learned from traffic or preloaded.

use std::time::Duration;

use crate::address::Address;
use crate::time::Timestamp;

/// How long a learned address stays without being heard from (the original's 120 s).
pub(crate) const DEFAULT_EXPIRY: Duration = Duration::from_secs(120);
/// Most addresses one link keeps: far beyond a fleet behind one link, and a bound on
/// what a peer forging source addresses makes every broadcast cost (each address of a
/// link is a filter check). Beyond it the address heard least recently gives way.
pub const MAX_ADDRESSES: usize = 1024;

#[derive(Debug, Clone, Copy)]
struct Entry {
    address: Address,
    /// `None` for preloaded addresses, which never expire.
    last_seen: Option<Timestamp>,
}

/// Addresses of one link with their last-seen times.
///
/// A learned address is present while `now - last_seen <= expiry` (so at exactly 120 s it
/// is still there and gone after). Every query takes `now` and ignores expired entries;
/// [`AddressPool::prune`] frees them. A plain vector: pools hold a handful of addresses and
/// are scanned for every packet, where a linear scan beats hashing.
#[derive(Debug, Clone)]
pub struct AddressPool {
    entries: Vec<Entry>,
    expiry: Duration,
}

impl AddressPool {
    /// An empty pool whose learned addresses expire after `expiry`.
    pub fn new(expiry: Duration) -> Self {
        AddressPool {
            entries: Vec::new(),
            expiry,
        }
    }

    #[inline]
    fn live(&self, e: &Entry, now: Timestamp) -> bool {
        e.last_seen.is_none_or(|seen| now <= seen + self.expiry)
    }

    /// Records that `address` sent something at `now`. True if it was not present (never
    /// seen, or expired): the "new component" case.
    pub(crate) fn learn(&mut self, address: Address, now: Timestamp) -> bool {
        match self.entries.iter().position(|e| e.address == address) {
            Some(i) => {
                let was_live = self.live(&self.entries[i], now);
                let e = &mut self.entries[i];
                if e.last_seen.is_some() {
                    e.last_seen = Some(now);
                }
                !was_live
            }
            None => {
                if self.entries.len() >= MAX_ADDRESSES {
                    self.make_room(now);
                }
                self.entries.push(Entry {
                    address,
                    last_seen: Some(now),
                });
                true
            }
        }
    }

    /// Frees a place in a full pool: the expired addresses go, or else the one heard
    /// least recently (preloaded ones stay).
    #[cold]
    fn make_room(&mut self, now: Timestamp) {
        self.prune(now);
        if self.entries.len() < MAX_ADDRESSES {
            return;
        }
        let oldest = (self.entries.iter().enumerate())
            .filter_map(|(i, e)| Some((e.last_seen?, i)))
            .min();
        if let Some((_, i)) = oldest {
            self.entries.remove(i);
        }
    }

    /// Adds `address` permanently. True if it was not present.
    pub(crate) fn preload(&mut self, address: Address) -> bool {
        match self.entries.iter_mut().find(|e| e.address == address) {
            Some(e) => {
                e.last_seen = None;
                false
            }
            None => {
                self.entries.push(Entry {
                    address,
                    last_seen: None,
                });
                true
            }
        }
    }

    /// True if `address` is present at `now`.
    #[inline]
    pub(crate) fn contains(&self, address: Address, now: Timestamp) -> bool {
        self.entries
            .iter()
            .any(|e| e.address == address && self.live(e, now))
    }

    /// Addresses present at `now`, oldest first.
    #[inline]
    pub fn addresses(&self, now: Timestamp) -> impl Iterator<Item = Address> + '_ {
        self.entries
            .iter()
            .filter(move |e| self.live(e, now))
            .map(|e| e.address)
    }

    /// True if no address is present at `now`.
    pub fn is_empty(&self, now: Timestamp) -> bool {
        self.addresses(now).next().is_none()
    }

    /// Forgets the addresses expired at `now`.
    pub fn prune(&mut self, now: Timestamp) {
        let expiry = self.expiry;
        self.entries
            .retain(|e| e.last_seen.is_none_or(|s| now <= s + expiry));
    }

    /// How long learned addresses last.
    pub(crate) fn expiry(&self) -> Duration {
        self.expiry
    }
}

impl Default for AddressPool {
    fn default() -> Self {
        AddressPool::new(DEFAULT_EXPIRY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_pool_gives_up_the_address_heard_least_recently() {
        let mut p = AddressPool::default();
        p.preload(A);
        let t = |s| Timestamp::from_secs(s);
        for n in 0..MAX_ADDRESSES as u16 - 1 {
            let a = Address::new(2 + (n / 200) as u8, 1 + (n % 200) as u8);
            p.learn(a, t(1 + u64::from(n % 3)));
        }
        let first = Address::new(2, 1); // heard at 1 s, with a third of the others
        p.learn(first, t(5));
        assert_eq!(p.addresses(t(5)).count(), MAX_ADDRESSES);
        let new = Address::new(200, 1);
        assert!(p.learn(new, t(6)));
        assert_eq!(p.addresses(t(6)).count(), MAX_ADDRESSES);
        assert!(p.contains(A, t(6)), "preloaded");
        assert!(p.contains(first, t(6)) && p.contains(new, t(6)));
        assert!(!p.contains(Address::new(2, 4), t(6)), "heard at 1 s: gone");
    }

    const A: Address = Address::new(1, 1);
    const B: Address = Address::new(2, 1);

    fn t(secs: u64) -> Timestamp {
        Timestamp::from_secs(secs)
    }

    #[test]
    fn present_at_exactly_120_s_gone_after() {
        let mut p = AddressPool::default();
        assert!(p.learn(A, t(0)));
        assert!(p.contains(A, t(120)));
        assert!(!p.contains(A, t(120) + Duration::from_nanos(1)));
        assert!(!p.contains(A, t(121)));
    }

    #[test]
    fn learning_refreshes_and_reports_new_only_when_absent() {
        let mut p = AddressPool::default();
        assert!(p.learn(A, t(0)));
        assert!(!p.learn(A, t(100)));
        assert!(p.contains(A, t(220)));
        assert!(!p.contains(A, t(221)));
        // Expired, then heard again: new component again.
        assert!(p.learn(A, t(221)));
    }

    #[test]
    fn preloads_are_permanent_and_stay_so_when_heard() {
        let mut p = AddressPool::default();
        assert!(p.preload(A));
        assert!(!p.learn(A, t(5)));
        p.prune(t(1_000_000));
        assert!(p.contains(A, t(1_000_000)));
        assert!(!p.preload(A));
    }

    #[test]
    fn prune_and_listing_skip_expired() {
        let mut p = AddressPool::new(Duration::from_secs(10));
        p.learn(A, t(0));
        p.learn(B, t(5));
        assert_eq!(p.addresses(t(10)).collect::<Vec<_>>(), vec![A, B]);
        assert_eq!(p.addresses(t(11)).collect::<Vec<_>>(), vec![B]);
        p.prune(t(11));
        assert_eq!(p.entries.len(), 1);
        assert!(!p.is_empty(t(15)));
        assert!(p.is_empty(t(16)));
    }
}
