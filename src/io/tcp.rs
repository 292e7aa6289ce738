//! The drivers of one `tcp { }` interface: a server's listening socket, whose every
//! accepted connection gets a driver of its own, and the connection of a client, made
//! without blocking and made again whenever the core asks. Every connection has
//! `TCP_NODELAY` (a frame leaves at once, not when Nagle's algorithm lets it), and
//! keepalive and `TCP_USER_TIMEOUT` (a peer that vanished without a word, whether the
//! connection was idle or being sent to, is noticed within about a minute).

use std::io::{self, Read};
use std::net::{IpAddr, Shutdown, SocketAddr, TcpListener, TcpStream};
use std::os::fd::{AsRawFd, RawFd};
use std::time::Duration;

use socket2::{Domain, Protocol, Socket, TcpKeepalive, Type};

use std::sync::Arc;

use mio::Waker;

use super::driver::{Driver, NOTHING_DUE, Progress};
use super::resolve::Lookup;
use super::stream::StreamIo;
use super::sys;
use crate::config::{Remote, TcpInterface};
use crate::routing::{Engine, InterfaceId, Timestamp};

/// Connections taken per wake-up before the loop gets a turn to route.
const ACCEPTS_PER_TURN: usize = 64;
/// How long a listener waits before it accepts again after the system refused it a
/// connection for want of descriptors or memory.
const ACCEPT_RETRY: Duration = Duration::from_secs(1);
/// Idle time before the first keepalive probe, and between probes.
const KEEPALIVE: Duration = Duration::from_secs(10);
/// Longest a connection waits for its peer to acknowledge what was sent (or a client
/// for its server to answer the connection) before it is given up: keepalive probes
/// only an idle connection, and without this a peer that vanished while frames were
/// being sent to it (a radio out of range, a dropped cellular link) would be noticed
/// only after the system's retransmissions, about 15 minutes, and an unanswered
/// connection attempt after about two.
const USER_TIMEOUT: Duration = Duration::from_secs(50);
/// Longest a client's attempt (its look-up and connection) may take before it is given
/// up and made again with the backoff: a server behind a network that drops packets
/// (a link that went down) would otherwise hold the attempt for [`USER_TIMEOUT`], and
/// the client would reconnect that late after the network came back.
const CONNECT_LIMIT: Duration = Duration::from_secs(5);

/// Whether `accept` failed for the connection it was taking, not for the listener:
/// Linux passes such errors of the network on to the caller, who is to try again.
fn peer_gone(e: &io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(
            libc::ENETDOWN
                | libc::EPROTO
                | libc::ENOPROTOOPT
                | libc::EHOSTDOWN
                | libc::ENONET
                | libc::EHOSTUNREACH
                | libc::EOPNOTSUPP
                | libc::ENETUNREACH
        )
    )
}

/// Sets the options every connection has.
fn tune(stream: &TcpStream) -> io::Result<()> {
    stream.set_nonblocking(true)?;
    stream.set_nodelay(true)?;
    let keepalive = TcpKeepalive::new()
        .with_time(KEEPALIVE)
        .with_interval(KEEPALIVE)
        .with_retries(4);
    let socket = socket2::SockRef::from(stream);
    socket.set_tcp_keepalive(&keepalive)?;
    socket.set_tcp_user_timeout(Some(USER_TIMEOUT))
}

/// The label of `config` in messages and counters: `tcp ADDRESS:PORT` for a server,
/// `tcp connect HOST:PORT` for a client.
pub fn label(config: &TcpInterface) -> String {
    config.label()
}

/// Makes the driver of a connection the core accepted as interface `id`.
pub(super) type Accepted = Box<dyn Fn(InterfaceId, TcpStream, Timestamp) -> Box<dyn Driver>>;

/// A server's listening socket (of a `tcp` block, or of a `websocket` block: what
/// `accepted` makes of each connection tells them apart).
pub struct TcpListenerDriver {
    interface: InterfaceId,
    listener: TcpListener,
    accepted: Vec<Box<dyn Driver>>,
    make: Accepted,
    /// Out of descriptors or memory: when to accept again. The listener is watched
    /// edge-triggered, so the connections already waiting would wake nobody (and once
    /// its backlog is full, no new one comes to): the loop's deadline call does.
    retry_at: Option<Timestamp>,
}

impl TcpListenerDriver {
    /// Listens for `config` (a port in use stops the start, naming the block).
    pub fn bind(config: &TcpInterface, interface: InterfaceId) -> io::Result<Self> {
        let local = SocketAddr::new(config.local_address(), config.port);
        let make: Accepted = Box::new(|id, stream, _| {
            Box::new(TcpStreamDriver {
                interface: id,
                stream: Some(stream),
                client: None,
                connecting: false,
                connect_by: None,
                io: StreamIo::default(),
            })
        });
        Self::listen(local, &label(config), interface, make)
    }

    /// Listens on `local` (errors name `label`); `make` gives each connection the core
    /// accepts its driver.
    pub(super) fn listen(
        local: SocketAddr,
        label: &str,
        interface: InterfaceId,
        make: Accepted,
    ) -> io::Result<Self> {
        let named = |e: io::Error| io::Error::new(e.kind(), format!("{label}: {e}"));
        let socket = Socket::new(
            Domain::for_address(local),
            Type::STREAM,
            Some(Protocol::TCP),
        )
        .map_err(named)?;
        if local.is_ipv6() && local.ip().is_unspecified() {
            let _ = socket.set_only_v6(false);
        }
        socket.set_reuse_address(true).map_err(named)?;
        socket.set_nonblocking(true).map_err(named)?;
        socket.bind(&local.into()).map_err(named)?;
        socket.listen(128).map_err(named)?;
        Ok(TcpListenerDriver {
            interface,
            listener: socket.into(),
            accepted: Vec::new(),
            make,
            retry_at: None,
        })
    }
}

impl Driver for TcpListenerDriver {
    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        Some(self.listener.as_raw_fd())
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        for _ in 0..ACCEPTS_PER_TURN {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    self.retry_at = None;
                    // A peer mapped into IPv6 is named, and judged, by its IPv4 address.
                    let peer = match peer {
                        SocketAddr::V6(a) => a
                            .ip()
                            .to_ipv4_mapped()
                            .map_or(peer, |v4| SocketAddr::new(v4.into(), a.port())),
                        v4 => v4,
                    };
                    if tune(&stream).is_err() {
                        continue; // already gone
                    }
                    // Refused by the limits: dropping the stream closes it.
                    if let Some(id) = engine.accept(self.interface, peer, now) {
                        self.accepted.push((self.make)(id, stream, now));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.retry_at = None;
                    return Progress::Done;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // The peer gave up before we took it, or its connection failed on the
                // way (errors of the network Linux passes on through `accept`).
                Err(e) if e.kind() == io::ErrorKind::ConnectionAborted || peer_gone(&e) => {}
                Err(e) => {
                    // Out of descriptors or memory: said once until it works again,
                    // and tried again after a while (see `retry_at`).
                    if self.retry_at.is_none() {
                        engine.on_receive_failed(self.interface, &e);
                    }
                    self.retry_at = Some(now + ACCEPT_RETRY);
                    return Progress::Done;
                }
            }
        }
        Progress::More
    }

    fn take_accepted(&mut self) -> Option<Box<dyn Driver>> {
        self.accepted.pop()
    }

    fn deadline(&self) -> Option<Timestamp> {
        Some(self.retry_at.unwrap_or(NOTHING_DUE))
    }

    fn expire(&mut self, _engine: &mut Engine, _now: Timestamp) -> Progress {
        // Accepts again from the next turn; a new refusal sets the next try.
        Progress::More
    }

    fn flush(&mut self, _engine: &mut Engine, _now: Timestamp) -> Progress {
        Progress::Done
    }

    fn idle(&self) -> bool {
        true
    }
}

/// What a client knows of where it connects.
struct Client {
    remote: Remote,
    /// The local address to connect from, if the block names one.
    local: Option<IpAddr>,
    /// Wakes the loop when a look-up has its answer.
    waker: Arc<Waker>,
    /// The look-up of `remote`, while under way.
    lookup: Option<Lookup>,
}

/// One TCP connection: accepted by a server, or a client's.
pub struct TcpStreamDriver {
    interface: InterfaceId,
    stream: Option<TcpStream>,
    /// A client's remote (None for an accepted connection).
    client: Option<Client>,
    /// A client's connection is being made (its remote looked up, or connected to).
    connecting: bool,
    /// When a client's attempt under way is given up ([`CONNECT_LIMIT`]).
    connect_by: Option<Timestamp>,
    io: StreamIo,
}

impl TcpStreamDriver {
    /// A client of `remote`, connected when the core asks.
    pub fn client(config: &TcpInterface, interface: InterfaceId, waker: Arc<Waker>) -> Self {
        TcpStreamDriver {
            interface,
            stream: None,
            client: config.connect.as_ref().map(|remote| Client {
                remote: remote.clone(),
                local: config.address,
                waker,
                lookup: None,
            }),
            connecting: false,
            connect_by: None,
            io: StreamIo::default(),
        }
    }

    /// Starts connecting to `to` (from `local`, if given) without waiting: the stream,
    /// and whether it is connected already.
    fn connect(to: SocketAddr, local: Option<IpAddr>) -> io::Result<(TcpStream, bool)> {
        let socket = Socket::new(Domain::for_address(to), Type::STREAM, Some(Protocol::TCP))?;
        socket.set_nonblocking(true)?;
        // Before the attempt, so that it bounds the attempt too.
        socket.set_tcp_user_timeout(Some(USER_TIMEOUT))?;
        if let Some(ip) = local {
            socket.bind(&SocketAddr::new(ip, 0).into())?;
        }
        let done = match socket.connect(&to.into()) {
            Ok(()) => true,
            Err(e) if e.raw_os_error() == Some(libc::EINPROGRESS) => false,
            Err(e) => return Err(e),
        };
        let stream: TcpStream = socket.into();
        tune(&stream)?;
        Ok((stream, done))
    }

    /// A connection being made: Some(true) once made, Some(false) while under way,
    /// None if it failed (reported to the core).
    fn check_connected(&mut self, engine: &mut Engine, now: Timestamp) -> Option<bool> {
        if let Some(client) = &mut self.client
            && let Some(lookup) = client.lookup.take()
        {
            match lookup.poll() {
                Err(pending) => {
                    client.lookup = Some(pending);
                    return Some(false);
                }
                Ok(answer) => match answer.and_then(|to| Self::connect(to, client.local)) {
                    Ok((stream, done)) => {
                        self.stream = Some(stream);
                        if !done {
                            return Some(false);
                        }
                    }
                    Err(e) => {
                        engine.stream_open_failed(self.interface, now, &e);
                        return None;
                    }
                },
            }
        }
        let stream = self.stream.as_ref()?;
        if let Ok(Some(e)) | Err(e) = stream.take_error() {
            engine.stream_open_failed(self.interface, now, &e);
            return None;
        }
        match stream.peer_addr() {
            Ok(_) => {
                self.connecting = false;
                engine.stream_opened(self.interface, now);
                Some(true)
            }
            Err(e) if e.kind() == io::ErrorKind::NotConnected => Some(false),
            Err(e) => {
                engine.stream_open_failed(self.interface, now, &e);
                None
            }
        }
    }
}

impl Driver for TcpStreamDriver {
    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        self.stream.as_ref().map(AsRawFd::as_raw_fd)
    }

    fn open(&mut self, _engine: &mut Engine, now: Timestamp) -> io::Result<bool> {
        let Some(client) = &mut self.client else {
            return Ok(true);
        };
        self.connect_by = Some(now + CONNECT_LIMIT);
        match Lookup::start(&client.remote, client.local, &client.waker).poll() {
            Ok(to) => {
                let (stream, done) = Self::connect(to?, client.local)?;
                self.stream = Some(stream);
                self.connecting = !done;
                Ok(done)
            }
            Err(pending) => {
                // Connected once the name resolves (see `flush`).
                client.lookup = Some(pending);
                self.connecting = true;
                Ok(false)
            }
        }
    }

    fn close(&mut self) {
        self.stream = None;
        self.connecting = false;
        if let Some(client) = &mut self.client {
            client.lookup = None;
        }
        self.io.clear();
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if self.connecting {
            return Progress::Done; // flush finds out how the connection went
        }
        match &mut self.stream {
            Some(stream) => self.io.receive(stream, engine, self.interface, now),
            None => Progress::Done,
        }
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if self.connecting {
            match self.check_connected(engine, now) {
                Some(true) => {}
                Some(false) => return Progress::Blocked, // writable means connected
                None => return Progress::Lost,
            }
        }
        match &mut self.stream {
            Some(stream) => self.io.flush(stream, engine, self.interface, now),
            None => Progress::Done,
        }
    }

    fn idle(&self) -> bool {
        self.io.idle() || self.stream.is_none()
    }

    fn deadline(&self) -> Option<Timestamp> {
        self.client.as_ref()?;
        Some(match self.connect_by {
            Some(by) if self.connecting => by,
            _ => NOTHING_DUE,
        })
    }

    fn expire(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if !self.connecting {
            return Progress::Done;
        }
        self.connecting = false;
        engine.stream_open_failed(
            self.interface,
            now,
            &format!("no answer within {} s", CONNECT_LIMIT.as_secs()),
        );
        Progress::Lost
    }

    fn shut_write(&mut self) -> bool {
        let Some(stream) = self.stream.as_ref().filter(|_| !self.connecting) else {
            return false;
        };
        stream.shutdown(Shutdown::Write).is_ok()
    }

    fn linger(&mut self) -> bool {
        self.stream.as_ref().is_none_or(linger_on)
    }
}

/// Reads and drops what `stream` has (a bounded amount); true once closing it loses
/// nothing: everything sent was acknowledged, or the peer ended, or it failed.
pub(super) fn linger_on(stream: &TcpStream) -> bool {
    drain(stream) != Input::Open || all_acknowledged(stream)
}

/// True if the peer's system has acknowledged everything sent on `stream` (or that
/// cannot be known).
pub(super) fn all_acknowledged(stream: &TcpStream) -> bool {
    !matches!(sys::unacknowledged_bytes(stream), Ok(n) if n > 0)
}

/// What reading and dropping the input of a stream that lingers found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Input {
    /// The peer may still send.
    Open,
    /// The peer ended its sending side (it may still read).
    Ended,
    /// The connection failed.
    Failed,
}

/// Reads and drops what `stream` has (a bounded amount).
pub(super) fn drain(mut stream: &TcpStream) -> Input {
    let mut scratch = [0u8; 16 * 1024];
    for _ in 0..64 {
        match stream.read(&mut scratch) {
            Ok(0) => return Input::Ended,
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => return Input::Failed,
        }
    }
    Input::Open
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_connection_gives_up_a_silent_peer_within_about_a_minute() {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let to = listener.local_addr().expect("addr");
        let (client, _) = TcpStreamDriver::connect(to, None).expect("connect");
        let (accepted, _) = listener.accept().expect("accept");
        tune(&accepted).expect("tune");
        for stream in [&client, &accepted] {
            let socket = socket2::SockRef::from(stream);
            assert_eq!(socket.tcp_user_timeout().ok(), Some(Some(USER_TIMEOUT)));
            assert!(socket.keepalive().unwrap_or(false));
        }
    }
}
