//! Where a client connects: an address as configured, or a host name looked up when the
//! client opens (at start, and a TCP client again at every reconnect; a UDP client opens
//! once), so that a name that does not resolve yet stops nothing: the core tries again
//! with its backoff. With a local `address`, the answer is an address of its family.
//!
//! The system resolver answers when it likes (seconds, when a DNS server does not
//! answer), so a name is looked up on a thread of its own, which wakes the loop with
//! its answer; the loop never waits for it.

use std::io;
use std::net::{IpAddr, SocketAddr, ToSocketAddrs};
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, TryRecvError};

use mio::Waker;

use crate::config::{Host, Remote};

/// A look-up under way, or its answer.
pub(super) enum Lookup {
    /// The address is known.
    Done(io::Result<SocketAddr>),
    /// A thread is asking the resolver.
    Pending(Receiver<io::Result<SocketAddr>>),
}

impl Lookup {
    /// Starts looking `remote` up: an address answers at once; a name is asked on a
    /// thread that wakes the loop through `waker` when it has the answer. With `local`
    /// (the address the client sends from), the answer is one of its family.
    pub(super) fn start(remote: &Remote, local: Option<IpAddr>, waker: &Arc<Waker>) -> Self {
        let name = match &remote.host {
            Host::Ip(ip) => return Lookup::Done(Ok(SocketAddr::new(*ip, remote.port))),
            Host::Name(name) => name.clone(),
        };
        let port = remote.port;
        let (tx, rx) = mpsc::channel();
        let waker = waker.clone();
        let spawned = std::thread::Builder::new()
            .name("resolve".into())
            .spawn(move || {
                let _ = tx.send(resolve(&name, port, local));
                let _ = waker.wake();
            });
        match spawned {
            Ok(_) => Lookup::Pending(rx),
            Err(e) => Lookup::Done(Err(e)),
        }
    }

    /// The answer if there is one, or the look-up still under way.
    pub(super) fn poll(self) -> Result<io::Result<SocketAddr>, Lookup> {
        match self {
            Lookup::Done(answer) => Ok(answer),
            Lookup::Pending(rx) => match rx.try_recv() {
                Ok(answer) => Ok(answer),
                Err(TryRecvError::Empty) => Err(Lookup::Pending(rx)),
                Err(TryRecvError::Disconnected) => Ok(Err(io::Error::other(
                    "the resolver thread ended without an answer",
                ))),
            },
        }
    }
}

/// The first address `name` resolves to, with `port` (of `local`'s family if given).
fn resolve(name: &str, port: u16, local: Option<IpAddr>) -> io::Result<SocketAddr> {
    let found: Vec<SocketAddr> = (name, port).to_socket_addrs()?.collect();
    pick(&found, local).ok_or_else(|| {
        let family = match local {
            Some(IpAddr::V4(_)) => " IPv4",
            Some(IpAddr::V6(_)) => " IPv6",
            None => "",
        };
        let why = match (found.is_empty(), local) {
            (false, Some(local)) => format!(
                "{name} resolves to no{family} address (the block's `address` {local} is{family})"
            ),
            _ => format!("{name} resolves to no address"),
        };
        io::Error::new(io::ErrorKind::NotFound, why)
    })
}

/// The first of `found` that a socket bound to `local` can send to: of its family, or
/// any if there is no `local` or it is `::` (an IPv6 socket on every address also
/// reaches IPv4 peers, as `::ffff:a.b.c.d`).
fn pick(found: &[SocketAddr], local: Option<IpAddr>) -> Option<SocketAddr> {
    let any = local.is_none_or(|l| l.is_ipv6() && l.is_unspecified());
    found
        .iter()
        .find(|a| any || local.is_some_and(|l| l.is_ipv4() == a.is_ipv4()))
        .copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_resolves_to_an_address_of_the_local_addresss_family() {
        let v6: SocketAddr = "[::1]:14550".parse().expect("address");
        let v4: SocketAddr = "127.0.0.1:14550".parse().expect("address");
        let local4 = Some(IpAddr::from([127, 0, 0, 1]));
        let local6 = Some(IpAddr::from([0u16, 0, 0, 0, 0, 0, 0, 1]));
        assert_eq!(pick(&[v6, v4], local4), Some(v4));
        assert_eq!(pick(&[v6, v4], local6), Some(v6));
        assert_eq!(pick(&[v6, v4], None), Some(v6));
        assert_eq!(pick(&[v6], local4), None);
        // `::` takes either (a dual-stack socket).
        assert_eq!(pick(&[v4], Some(IpAddr::from([0u16; 8]))), Some(v4));
        let err = resolve(
            "localhost",
            1,
            Some(IpAddr::from([0u16, 0, 0, 0, 0, 0, 0, 1])),
        );
        // Whatever the machine's hosts file says, never an IPv4 answer for a socket on
        // an IPv6 address.
        assert!(!err.is_ok_and(|a| a.is_ipv4()));
    }
}
