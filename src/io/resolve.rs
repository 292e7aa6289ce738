//! Where a client connects: an address as configured, or a host name looked up when the
//! client opens (at start, and again on every reconnect), so that a name that does not
//! resolve yet stops nothing: the core tries again with its backoff.
//!
//! The system resolver answers when it likes (seconds, when a DNS server does not
//! answer), so a name is looked up on a thread of its own, which wakes the loop with
//! its answer; the loop never waits for it.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs};
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
    /// thread that wakes the loop through `waker` when it has the answer.
    pub(super) fn start(remote: &Remote, waker: &Arc<Waker>) -> Self {
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
                let _ = tx.send(resolve(&name, port));
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

/// The first address `name` resolves to, with `port`.
fn resolve(name: &str, port: u16) -> io::Result<SocketAddr> {
    (name, port).to_socket_addrs()?.next().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::NotFound,
            format!("{name} resolves to no address"),
        )
    })
}
