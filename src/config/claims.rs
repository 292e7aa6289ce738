//! What each interface holds for itself on this machine (a local port, a serial device),
//! so that two interfaces claiming the same one are refused before anything is opened,
//! whether they come from a configuration file or from command-line endpoints.

use super::model::Interface;
use std::fmt;
use std::net::{IpAddr, SocketAddr};

/// A local resource only one interface can hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Claim {
    /// A UDP port on a local address.
    Udp(SocketAddr),
    /// A TCP listening port on a local address.
    Tcp(SocketAddr),
    /// A TCP listening port on a local address, of a `websocket` block.
    WebSocket(SocketAddr),
    /// A serial device, by its path as written.
    Device(String),
}

impl Claim {
    /// What `iface` claims: its bound socket (none for port 0, any free port, nor for a
    /// TCP client, which binds no chosen port), or its device.
    pub(crate) fn of(iface: &Interface) -> Option<Claim> {
        match iface {
            Interface::Udp(u) if u.port != 0 => {
                Some(Claim::Udp(SocketAddr::new(u.local_address(), u.port)))
            }
            Interface::Tcp(t) if t.connect.is_none() && t.port != 0 => {
                Some(Claim::Tcp(SocketAddr::new(t.local_address(), t.port)))
            }
            Interface::WebSocket(w) if w.port != 0 => {
                Some(Claim::WebSocket(SocketAddr::new(w.local_address(), w.port)))
            }
            Interface::Serial(s) => Some(Claim::Device(s.device.clone())),
            _ => None,
        }
    }

    /// Whether `self` and `other` cannot both be held: the same device, or sockets of one
    /// protocol on one port whose addresses overlap (equal, or one is every address of its
    /// family; `::` also covers IPv4, as a dual-stack socket does). UDP and TCP never clash;
    /// a `websocket` block listens on TCP.
    pub(crate) fn clashes(&self, other: &Claim) -> bool {
        match (self, other) {
            (Claim::Udp(a), Claim::Udp(b))
            | (Claim::Tcp(a) | Claim::WebSocket(a), Claim::Tcp(b) | Claim::WebSocket(b)) => {
                a.port() == b.port() && overlap(a.ip(), b.ip())
            }
            (Claim::Device(a), Claim::Device(b)) => a == b,
            _ => false,
        }
    }

    /// `udp`, `tcp`, `websocket` or `serial`: the kind of block that makes this claim.
    pub(crate) fn kind(&self) -> &'static str {
        match self {
            Claim::Udp(_) => "udp",
            Claim::Tcp(_) => "tcp",
            Claim::WebSocket(_) => "websocket",
            Claim::Device(_) => "serial",
        }
    }
}

/// Whether sockets bound to `a` and `b` (on one port) would be in each other's way.
fn overlap(a: IpAddr, b: IpAddr) -> bool {
    let covers =
        |any: IpAddr, other: IpAddr| any.is_unspecified() && (any.is_ipv6() || other.is_ipv4());
    a == b || covers(a, b) || covers(b, a)
}

impl fmt::Display for Claim {
    /// `0.0.0.0:14550`, `[::]:5760`, or the device path.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Claim::Udp(a) | Claim::Tcp(a) | Claim::WebSocket(a) => write!(f, "{a}"),
            Claim::Device(d) => f.write_str(d),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn udp(s: &str) -> Claim {
        Claim::Udp(s.parse().expect("socket address"))
    }

    fn tcp(s: &str) -> Claim {
        Claim::Tcp(s.parse().expect("socket address"))
    }

    #[test]
    fn overlapping_addresses_on_one_port_clash() {
        assert!(udp("0.0.0.0:1").clashes(&udp("127.0.0.1:1")));
        assert!(udp("127.0.0.1:1").clashes(&udp("0.0.0.0:1")));
        assert!(udp("10.0.0.1:1").clashes(&udp("10.0.0.1:1")));
        assert!(udp("[::]:1").clashes(&udp("10.0.0.1:1")));
        assert!(udp("[::]:1").clashes(&udp("[fd00::1]:1")));
        assert!(!udp("0.0.0.0:1").clashes(&udp("[::1]:1")));
        assert!(!udp("10.0.0.1:1").clashes(&udp("10.0.0.2:1")));
        assert!(!udp("0.0.0.0:1").clashes(&udp("0.0.0.0:2")));
        assert!(tcp("0.0.0.0:5760").clashes(&tcp("0.0.0.0:5760")));
        assert!(!tcp("0.0.0.0:5760").clashes(&udp("0.0.0.0:5760")));
        let ws = Claim::WebSocket("127.0.0.1:5760".parse().expect("socket address"));
        assert!(ws.clashes(&tcp("0.0.0.0:5760")));
        assert!(!ws.clashes(&udp("127.0.0.1:5760")));
        assert!(Claim::Device("/dev/a".into()).clashes(&Claim::Device("/dev/a".into())));
        assert!(!Claim::Device("/dev/a".into()).clashes(&Claim::Device("/dev/b".into())));
        assert_eq!(udp("[::]:14550").to_string(), "[::]:14550");
    }
}
