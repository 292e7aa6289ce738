//! Which remotes a server interface takes as links: at most `max_peers` at once, and only
//! from the allowed address ranges. A remote refused is dropped and counted per reason,
//! and said once per interface and reason, never per datagram: a flood of spoofed
//! sources can neither grow memory nor fill the log, and never displaces a link that
//! already carries traffic.

use std::net::{IpAddr, SocketAddr};

use crate::config::PeerLimits;

/// Why a remote was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Its address is outside every `allow` range.
    NotAllowed,
    /// The interface already has `max_peers` links.
    Full,
    /// It sent from port 0, which cannot be answered (counted as not allowed).
    PortZero,
}

/// Remotes refused so far, per reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Refused {
    /// Datagrams or connections from addresses outside the allowed ranges.
    pub not_allowed: u64,
    /// Datagrams or connections from new remotes while the interface was full.
    pub full: u64,
    /// Datagrams from port 0 (no reply can reach it; reported within `not_allowed`).
    pub port_zero: u64,
}

impl Refused {
    /// Remotes refused as not allowed, as reported: outside the ranges, or from port 0.
    pub fn not_allowed_in_all(&self) -> u64 {
        self.not_allowed + self.port_zero
    }

    /// Counts a refusal; true the first time for its reason (the one worth saying).
    pub(crate) fn count(&mut self, why: Refusal) -> bool {
        let n = match why {
            Refusal::NotAllowed => &mut self.not_allowed,
            Refusal::Full => &mut self.full,
            Refusal::PortZero => &mut self.port_zero,
        };
        *n += 1;
        *n == 1
    }
}

/// Whether a new remote at `peer` may become a link when `current` links exist.
pub(crate) fn admit(limits: &PeerLimits, current: usize, peer: SocketAddr) -> Result<(), Refusal> {
    if peer.port() == 0 {
        return Err(Refusal::PortZero);
    }
    let ip = match peer.ip() {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(IpAddr::V6(v6), IpAddr::V4),
        v4 => v4,
    };
    if !limits.allow.is_empty() && !limits.allow.iter().any(|r| r.contains(ip)) {
        return Err(Refusal::NotAllowed);
    }
    if current >= limits.max_peers {
        return Err(Refusal::Full);
    }
    Ok(())
}

/// The line that says, once, that remotes are being refused.
pub(crate) fn refusal_text(
    described: &str,
    why: Refusal,
    peer: IpAddr,
    limits: &PeerLimits,
) -> String {
    match why {
        Refusal::NotAllowed => format!(
            "{described}: {peer} is outside the allowed address ranges; such remotes are \
             refused (further ones are only counted)"
        ),
        Refusal::Full => format!(
            "{described}: {} remotes already (max_peers); new remotes are refused until one \
             goes (further ones are only counted)",
            limits.max_peers
        ),
        Refusal::PortZero => format!(
            "{described}: {peer} sent from port 0, which no reply can reach; such remotes \
             are refused (counted as not allowed; further ones are only counted)"
        ),
    }
}
