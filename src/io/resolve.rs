//! Where a client connects: an address as configured, or a host name looked up when the
//! client opens (at start, and again on every reconnect), so that a name that does not
//! resolve yet stops nothing: the core tries again with its backoff.
//!
//! A look-up asks the system resolver and waits for its answer; names in `/etc/hosts`
//! (`localhost`) answer at once. A name that needs a DNS server that does not answer
//! holds the loop for the resolver's timeout, once per attempt.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs};

use crate::config::{Host, Remote};

/// The socket address of `remote` (the first one a host name resolves to).
pub fn resolve(remote: &Remote) -> io::Result<SocketAddr> {
    match &remote.host {
        Host::Ip(ip) => Ok(SocketAddr::new(*ip, remote.port)),
        Host::Name(name) => (name.as_str(), remote.port)
            .to_socket_addrs()?
            .next()
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::NotFound,
                    format!("{name} resolves to no address"),
                )
            }),
    }
}
