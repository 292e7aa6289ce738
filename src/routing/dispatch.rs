//! The per-link decision, as the original makes it: which destination addresses a
//! packet is filtered for on one link, and what comes of it.

use super::pool::AddressPool;
use crate::address::Address;
use crate::filter::{Cap, Filter, Verdict};
use crate::time::Timestamp;

/// The outcome of offering a packet to one link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Dropped without a log line: the link already reaches the sender (loop prevention),
    /// or the packet targets a system the link does not know.
    Silent,
    /// The filter accepted it for at least one candidate address: the highest priority,
    /// and the `with rate` cap that holds it back ([`Cap::NONE`] when any accepting rule
    /// has no rate; else the most generous of their caps).
    Accept(i32, Cap),
    /// The filter rejected it for every candidate address, or a broadcast met an empty pool.
    Reject,
}

/// Decides what happens to a packet with `message_id` from `source`, whose payload targets
/// `target`, on a link whose addresses are `pool`. A link that `reaches_unknown` (a
/// client, whose peer may never speak first) takes broadcasts while its pool is empty,
/// filtered for the broadcast address `0.0`. `signed` tells the filter whether the packet
/// arrived with an accepted signature; `len` (the frame's bytes) is what the filter's
/// per-rule counters add.
#[inline]
// The packet's facts as plain values, as the per-link hot loop has them at hand.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decide(
    filter: &mut Filter,
    pool: &AddressPool,
    reaches_unknown: bool,
    now: Timestamp,
    message_id: u32,
    source: Address,
    target: Option<Address>,
    signed: bool,
    len: usize,
) -> Decision {
    if pool.contains(source, now) {
        return Decision::Silent;
    }
    match target {
        // Broadcast: every address of the pool; an empty pool gives "rejected".
        None
        | Some(Address {
            system: 0,
            component: 0,
        }) => {
            let mut candidates = pool.addresses(now).peekable();
            if reaches_unknown && candidates.peek().is_none() {
                return best(
                    filter,
                    std::iter::once(Address::new(0, 0)),
                    message_id,
                    source,
                    signed,
                    len,
                );
            }
            best(filter, candidates, message_id, source, signed, len)
        }
        // System broadcast S.0: every address of system S; none known is silent.
        Some(Address {
            system,
            component: 0,
        }) => {
            let mut of_system = pool
                .addresses(now)
                .filter(|a| a.system == system)
                .peekable();
            if of_system.peek().is_none() {
                return Decision::Silent;
            }
            best(filter, of_system, message_id, source, signed, len)
        }
        // Targeted S.C: filtered once for S.C itself if present, or (component-broadcast
        // fallback) if any component of S is present; otherwise silent.
        Some(dest) => {
            let reachable = pool.addresses(now).any(|a| a.system == dest.system);
            if !reachable {
                return Decision::Silent;
            }
            match filter.check_capped(message_id, source, dest, signed, len) {
                (Verdict::Accept(p), cap) => Decision::Accept(p, cap),
                (Verdict::Reject, _) => Decision::Reject,
            }
        }
    }
}

/// Accepted if any candidate accepts, with the highest accepting priority; capped only
/// when every accepting rule has a rate (by the one of the shortest interval).
#[inline]
fn best(
    filter: &mut Filter,
    candidates: impl Iterator<Item = Address>,
    message_id: u32,
    source: Address,
    signed: bool,
    len: usize,
) -> Decision {
    let mut best: Option<(i32, Cap)> = None;
    for dest in candidates {
        if let (Verdict::Accept(p), cap) =
            filter.check_capped(message_id, source, dest, signed, len)
        {
            best = Some(match best {
                None => (p, cap),
                Some((b, c)) => (b.max(p), c.looser(cap)),
            });
        }
    }
    best.map_or(Decision::Reject, |(p, c)| Decision::Accept(p, c))
}
