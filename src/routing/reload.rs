//! What a reload changes: the pure comparison of the running configuration with a new
//! one, decided before anything is touched. [`Engine::configure`](super::Engine::configure)
//! applies it; the event loop only opens and closes what it is told to.
//!
//! Interface blocks are matched by what they stand for on this machine ([`Identity`]:
//! the kind and the bound address and port, the device, or the remote), never by their
//! place in the file. A matched block is
//! - **kept** when nothing that matters changed (a key file renamed but holding the same
//!   key is no change);
//! - **changed in place** when only `max_bitrate`, the signing key or `allow_unsigned`,
//!   or the server limits (`allow`, `max_peers`) changed: socket, links, queues, learned
//!   addresses, connections and counters stay;
//! - **reopened** when a setting of the socket or device itself changed (a serial port's
//!   `baudrate`, `flow_control` or `preload`, a client's local address or port).
//!
//! Rules are matched by their text within their chain ([`plan_rules`]), so the counters
//! of a rule that reads the same go on counting after the reload.

use std::collections::HashMap;
use std::net::SocketAddr;

use crate::config::{Config, Interface, PeerLimits};
use crate::signing::SigningKey;
use crate::stats::rule_text::rule_text;

/// What an interface block stands for on this machine: two blocks with the same identity
/// (and the same rank among blocks of that identity) are the same interface.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) enum Identity {
    /// A UDP server bound at this address and port.
    UdpServer(SocketAddr),
    /// A UDP client of this remote (as written).
    UdpClient(String),
    /// A TCP server listening at this address and port.
    TcpServer(SocketAddr),
    /// A TCP client of this remote (as written).
    TcpClient(String),
    /// A WebSocket server listening at this address and port.
    WebSocketServer(SocketAddr),
    /// A serial port at this path (as written).
    Serial(String),
    /// A Zenoh session publishing under this prefix, in this mode, with these
    /// endpoints.
    Zenoh(String),
}

impl Identity {
    /// The identity of `iface`.
    pub(crate) fn of(iface: &Interface) -> Identity {
        match iface {
            Interface::Udp(u) => match &u.connect {
                None => Identity::UdpServer(SocketAddr::new(u.local_address(), u.port)),
                Some(remote) => Identity::UdpClient(remote.to_string()),
            },
            Interface::Tcp(t) => match &t.connect {
                None => Identity::TcpServer(SocketAddr::new(t.local_address(), t.port)),
                Some(remote) => Identity::TcpClient(remote.to_string()),
            },
            Interface::WebSocket(w) => {
                Identity::WebSocketServer(SocketAddr::new(w.local_address(), w.port))
            }
            Interface::Serial(s) => Identity::Serial(s.device.clone()),
            Interface::Zenoh(z) => Identity::Zenoh(format!(
                "{:?} {} {:?} {:?}",
                z.mode, z.prefix, z.connect, z.listen
            )),
        }
    }
}

/// A setting that changes without closing the socket or device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum InPlace {
    /// `max_bitrate`: the pacer takes the new rate.
    MaxBitrate,
    /// The signing key or `allow_unsigned`.
    Signing,
    /// A server's `allow` or `max_peers` (for remotes that arrive from now on).
    Peers,
}

impl InPlace {
    /// The setting's name as the configuration writes it.
    pub(crate) fn name(self) -> &'static str {
        match self {
            InPlace::MaxBitrate => "max_bitrate",
            InPlace::Signing => "signing",
            InPlace::Peers => "allow/max_peers",
        }
    }
}

/// What happens to an interface present in both configurations.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Fate {
    /// Nothing changed: untouched.
    Kept,
    /// These settings change in place.
    Changed(Vec<InPlace>),
    /// Closed and opened again (its socket or device settings changed).
    Reopened,
}

/// An interface of the old configuration matched to one of the new.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Matched {
    /// Its index in the old configuration's interfaces.
    pub old: usize,
    /// Its index in the new configuration's interfaces.
    pub new: usize,
    /// What happens to it.
    pub fate: Fate,
}

/// What a reload does to the interfaces.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct InterfacePlan {
    /// Interfaces in both configurations, in the new configuration's order.
    pub matched: Vec<Matched>,
    /// Old indices of the interfaces the new configuration no longer has.
    pub removed: Vec<usize>,
    /// New indices of the interfaces the old configuration did not have.
    pub added: Vec<usize>,
}

/// One interface block and the key its `signing_key` file held.
pub(crate) type Keyed<'a> = (&'a Interface, Option<&'a SigningKey>);

/// Matches the interfaces of `old` to those of `new` (each with its key) by
/// [`Identity`] and decides the [`Fate`] of each.
pub(crate) fn plan_interfaces(old: &[Keyed<'_>], new: &[Keyed<'_>]) -> InterfacePlan {
    // Identity → old indices with it, in file order (taken from the front).
    let mut by_identity: HashMap<Identity, Vec<usize>> = HashMap::new();
    for (i, (iface, _)) in old.iter().enumerate() {
        by_identity.entry(Identity::of(iface)).or_default().push(i);
    }
    let mut plan = InterfacePlan::default();
    let mut taken = vec![false; old.len()];
    for (n, &(iface, key)) in new.iter().enumerate() {
        let candidates = by_identity.get_mut(&Identity::of(iface));
        match candidates.and_then(|c| (!c.is_empty()).then(|| c.remove(0))) {
            Some(o) => {
                taken[o] = true;
                let fate = fate(old[o], (iface, key));
                plan.matched.push(Matched {
                    old: o,
                    new: n,
                    fate,
                });
            }
            None => plan.added.push(n),
        }
    }
    plan.removed = (0..old.len()).filter(|&i| !taken[i]).collect();
    plan
}

/// The settings that can change in place: `max_bitrate`, the signing settings (the path
/// of the key file aside: its key is compared) and the server limits.
fn in_place(iface: &Interface) -> (Option<u64>, Option<bool>, Option<&PeerLimits>) {
    let allow_unsigned = iface.signing().map(|s| s.allow_unsigned);
    match iface {
        Interface::Udp(u) => (u.max_bitrate, allow_unsigned, Some(&u.peers)),
        Interface::Tcp(t) => (t.max_bitrate, allow_unsigned, Some(&t.peers)),
        Interface::WebSocket(w) => (w.max_bitrate, allow_unsigned, Some(&w.peers)),
        Interface::Serial(s) => (s.max_bitrate, allow_unsigned, None),
        Interface::Zenoh(_) => (None, allow_unsigned, None),
    }
}

/// `iface` without the settings that change in place.
fn fixed_part(iface: &Interface) -> Interface {
    let mut f = iface.clone();
    match &mut f {
        Interface::Udp(u) => {
            (u.max_bitrate, u.signing, u.peers) = (None, None, PeerLimits::default());
        }
        Interface::Tcp(t) => {
            (t.max_bitrate, t.signing, t.peers) = (None, None, PeerLimits::default());
        }
        Interface::WebSocket(w) => {
            (w.max_bitrate, w.signing, w.peers) = (None, None, PeerLimits::default());
        }
        Interface::Serial(s) => (s.max_bitrate, s.signing) = (None, None),
        Interface::Zenoh(z) => z.signing = None,
    }
    f
}

fn fate(old: Keyed<'_>, new: Keyed<'_>) -> Fate {
    if fixed_part(old.0) != fixed_part(new.0) {
        return Fate::Reopened;
    }
    let (a, b) = (in_place(old.0), in_place(new.0));
    let mut changed = Vec::new();
    if a.0 != b.0 {
        changed.push(InPlace::MaxBitrate);
    }
    if a.1 != b.1 || old.1 != new.1 {
        changed.push(InPlace::Signing);
    }
    if a.2 != b.2 {
        changed.push(InPlace::Peers);
    }
    if changed.is_empty() {
        Fate::Kept
    } else {
        Fate::Changed(changed)
    }
}

/// What a reload does to the filter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct RulePlan {
    /// The chains, default chain and default action are the same: the filter and its
    /// memo stay as they are.
    pub unchanged: bool,
    /// Rules of the new configuration.
    pub total: usize,
    /// Rules of the new configuration that the old one did not have (by text, in the
    /// same chain).
    pub changed: usize,
    /// Rules of the old configuration the new one does not have.
    pub removed: usize,
    /// For each rule of the new configuration (by flat number: chains in order, their
    /// rules in order), the flat number of the same rule in the old one, whose counts
    /// it continues.
    pub carried: Vec<Option<usize>>,
    /// The default action is the same, so its counts continue.
    pub default_carried: bool,
}

/// Compares the filters of `old` and `new`: a rule is the same rule when its chain has
/// the same name and it reads the same (the `n`th such rule of a chain matches the
/// `n`th).
pub(crate) fn plan_rules(old: &Config, new: &Config) -> RulePlan {
    let unchanged = old.chains == new.chains
        && old.default_chain == new.default_chain
        && old.default_action == new.default_action;
    let mut old_rules: HashMap<(String, String), Vec<usize>> = HashMap::new();
    for (flat, key) in flat_rules(old).into_iter().enumerate() {
        old_rules.entry(key).or_default().push(flat);
    }
    let carried: Vec<Option<usize>> = flat_rules(new)
        .into_iter()
        .map(|key| {
            let same = old_rules.get_mut(&key)?;
            (!same.is_empty()).then(|| same.remove(0))
        })
        .collect();
    RulePlan {
        unchanged,
        total: carried.len(),
        changed: carried.iter().filter(|c| c.is_none()).count(),
        removed: old_rules.values().map(Vec::len).sum(),
        carried,
        default_carried: old.default_action == new.default_action,
    }
}

/// (chain name, rule text) of every rule, by flat number.
fn flat_rules(config: &Config) -> Vec<(String, String)> {
    config
        .chains
        .iter()
        .flat_map(|c| {
            c.rules
                .iter()
                .map(|r| (c.name.clone(), rule_text(config, r)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::load;

    fn config(src: &str) -> Config {
        load(src).expect("a valid configuration").config
    }

    fn plan(old: &str, new: &str) -> InterfacePlan {
        let (old, new) = (config(old), config(new));
        let o: Vec<Keyed<'_>> = old.interfaces.iter().map(|i| (i, None)).collect();
        let n: Vec<Keyed<'_>> = new.interfaces.iter().map(|i| (i, None)).collect();
        plan_interfaces(&o, &n)
    }

    const BASE: &str = "udp { port 14550; address 127.0.0.1; }\n\
                        tcp { port 5760; address 127.0.0.1; }\n\
                        serial { device /dev/ttyUSB0; baudrate 57600; }\n";

    #[test]
    fn the_same_file_keeps_everything() {
        let p = plan(BASE, BASE);
        assert!(p.added.is_empty() && p.removed.is_empty());
        assert!(
            p.matched
                .iter()
                .all(|m| m.fate == Fate::Kept && m.old == m.new)
        );
    }

    #[test]
    fn interfaces_match_by_identity_not_position() {
        let moved = "serial { device /dev/ttyUSB0; baudrate 57600; }\n\
                     udp { port 14551; address 127.0.0.1; }\n\
                     tcp { port 5760; address 127.0.0.1; }\n\
                     udp { port 14550; address 127.0.0.1; }\n";
        let p = plan(BASE, moved);
        let pairs: Vec<(usize, usize)> = p.matched.iter().map(|m| (m.old, m.new)).collect();
        assert_eq!(pairs, [(2, 0), (1, 2), (0, 3)]);
        assert!(p.matched.iter().all(|m| m.fate == Fate::Kept));
        assert_eq!(p.added, [1]);
        assert!(p.removed.is_empty());
    }

    #[test]
    fn settings_of_the_socket_reopen_others_change_in_place() {
        let new = "udp { port 14550; address 127.0.0.1; max_bitrate 9600; allow 10.0.0.0/8; }\n\
                   tcp { port 5760; address 127.0.0.1; max_peers 3; }\n\
                   serial { device /dev/ttyUSB0; baudrate 115200; }\n";
        let p = plan(BASE, new);
        let fates: Vec<Fate> = p.matched.iter().map(|m| m.fate.clone()).collect();
        assert_eq!(
            fates,
            [
                Fate::Changed(vec![InPlace::MaxBitrate, InPlace::Peers]),
                Fate::Changed(vec![InPlace::Peers]),
                Fate::Reopened,
            ]
        );
    }

    #[test]
    fn a_new_port_is_another_interface() {
        let new = "udp { port 14560; address 127.0.0.1; }\n\
                   tcp { port 5760; address 127.0.0.1; }\n";
        let p = plan(BASE, new);
        assert_eq!(p.added, [0]);
        assert_eq!(p.removed, [0, 2]);
        assert_eq!(p.matched.len(), 1);
    }

    #[test]
    fn a_changed_key_is_an_in_place_signing_change() {
        let old = config("udp { port 14550; }\n");
        let (a, b) = (
            SigningKey::from_passphrase("a"),
            SigningKey::from_passphrase("b"),
        );
        let i = &old.interfaces[0];
        let p = plan_interfaces(&[(i, Some(&a))], &[(i, Some(&b))]);
        assert_eq!(p.matched[0].fate, Fate::Changed(vec![InPlace::Signing]));
        let p = plan_interfaces(&[(i, Some(&a))], &[(i, Some(&a))]);
        assert_eq!(p.matched[0].fate, Fate::Kept);
    }

    #[test]
    fn rules_are_carried_by_their_text() {
        let old = config(
            "chain default { reject if HEARTBEAT; accept if PING; call c; }\n\
             chain c { accept; }\n",
        );
        let new = config(
            "chain c { accept; }\n\
             chain default { reject if ATTITUDE; accept if PING; call c; }\n",
        );
        let r = plan_rules(&old, &new);
        assert!(!r.unchanged);
        assert_eq!(r.total, 4);
        assert_eq!(r.changed, 1);
        // New flat order: c's accept, then default's three rules.
        assert_eq!(r.carried, [Some(3), None, Some(1), Some(2)]);
        assert!(r.default_carried);
        let same = plan_rules(&old, &old);
        assert!(same.unchanged && same.changed == 0);
    }
}
