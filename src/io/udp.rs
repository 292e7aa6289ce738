//! The driver of one `udp { }` interface: a non-blocking IPv4 or IPv6 socket, watched
//! level-triggered; one `recvmsg` per wake-up while traffic is light, batched receive
//! (`recvmmsg`) in bursts, and batched send (`sendmmsg`, with UDP segmentation offload
//! for runs to one peer). A packet routed from a datagram read on its own that finds
//! its queue empty is sent at once with `sendto`, before the rest of the loop's turn
//! (`Driver::send_now`). A server binds at start; a client binds and resolves its
//! target when the core asks it to open. Which peer is which link, and what to send
//! when, is the core's.

use std::collections::VecDeque;
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::os::fd::{AsRawFd, RawFd};

use socket2::{Domain, Protocol, SockRef, Socket, Type};

use std::sync::Arc;
use std::time::Duration;

use mio::Waker;

use super::driver::{Driver, Progress};
use super::log;
use super::resolve::Lookup;
use super::sys::{self, MAX_BATCH, RecvBatch, SendBatch};
use crate::config::UdpInterface;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// Socket buffer sizes asked for, so bursts are not dropped by the kernel.
const SOCKET_BUFFER: usize = 4 * 1024 * 1024;
/// Longest datagram read whole; longer ones are dropped and counted as junk (a MAVLink
/// frame is at most 280 bytes; several frames may share a datagram).
const DATAGRAM_MAX: usize = 8192;
/// Receive batches taken per wake-up before the loop gets a turn to send.
const BATCHES_PER_TURN: usize = 8;
/// Datagrams arriving closer together than this (above ~20k a second) are read in
/// batches; slower traffic one datagram per wake-up.
const BURST_GAP: Duration = Duration::from_micros(50);

/// Where a datagram without a peer would go: nowhere (its send fails and is counted).
/// Every datagram of a UDP interface has a peer.
const NOWHERE: SocketAddr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0));

/// Binds a non-blocking socket with large buffers at `local`.
fn bind(local: SocketAddr) -> io::Result<UdpSocket> {
    let socket = Socket::new(Domain::for_address(local), Type::DGRAM, Some(Protocol::UDP))?;
    if local.is_ipv6() && local.ip().is_unspecified() {
        // `address ::;` takes IPv4 peers too, as `::ffff:a.b.c.d`.
        let _ = socket.set_only_v6(false);
    }
    // Beyond the system's limit when privileged, else up to it.
    if sys::force_buffer_size(&socket, true, SOCKET_BUFFER).is_err() {
        let _ = socket.set_recv_buffer_size(SOCKET_BUFFER);
    }
    if sys::force_buffer_size(&socket, false, SOCKET_BUFFER).is_err() {
        let _ = socket.set_send_buffer_size(SOCKET_BUFFER);
    }
    socket.set_nonblocking(true)?;
    socket.bind(&local.into())?;
    Ok(socket.into())
}

/// Counts the `bytes` read of datagrams longer than [`DATAGRAM_MAX`] on interface `id`
/// (`label`) as junk (the kernel dropped their rest); said once per interface (`said`).
#[cold]
fn cut_datagram(engine: &mut Engine, id: InterfaceId, label: &str, said: &mut bool, bytes: usize) {
    engine.stream_junk(id, bytes);
    if !*said {
        *said = true;
        log::warn(&format_args!(
            "{label}: a datagram longer than {DATAGRAM_MAX} bytes was dropped (counted as junk \
             bytes; further ones are only counted)"
        ));
    }
}

/// The address to send to from a socket of the given family: an IPv4 peer of an IPv6
/// socket is written `::ffff:a.b.c.d`.
fn on_wire(to: SocketAddr, v6_socket: bool) -> SocketAddr {
    match to {
        SocketAddr::V4(a) if v6_socket => {
            SocketAddr::new(IpAddr::V6(a.ip().to_ipv6_mapped()), a.port())
        }
        other => other,
    }
}

/// True for receive errors that say nothing about the socket: a signal, or an ICMP
/// "port unreachable" for an earlier datagram.
fn is_transient(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::Interrupted | io::ErrorKind::ConnectionRefused
    )
}

/// A UDP interface: a server bound at start, or a client of one remote.
pub struct UdpDriver {
    interface: InterfaceId,
    label: String,
    config: UdpInterface,
    socket: Option<UdpSocket>,
    v6: bool,
    batch: RecvBatch,
    send_scratch: SendBatch,
    /// Handed out by the core, not yet taken by the kernel.
    in_flight: VecDeque<Transmit>,
    /// Runs of equal datagrams to one peer are sent as one UDP GSO message (see
    /// [`sys::send_batch`]): on when the kernel offers it, off for good once a send
    /// with GSO is refused.
    gso: bool,
    /// Reading in batches (`recvmmsg`) because datagrams come in bursts; otherwise one
    /// per wake-up (`recvmsg`), the socket being watched level-triggered.
    batching: bool,
    /// When the last datagram was read one by one.
    last_single: Option<Timestamp>,
    /// Wakes the loop when a client's look-up has its answer.
    waker: Arc<Waker>,
    /// A client's look-up of its remote, while under way.
    lookup: Option<Lookup>,
    /// A receive buffer smaller than asked for has been said.
    small_buffer_said: bool,
    /// A datagram too long to read whole has been said.
    cut_said: bool,
}

impl UdpDriver {
    /// The label of `config` in messages and counters: `udp ADDRESS:PORT` for a
    /// server, `udp connect HOST:PORT` for a client.
    pub fn label(config: &UdpInterface) -> String {
        config.label()
    }

    /// Binds a server's socket at once (a port in use stops the start, naming the
    /// block); a client's is bound when the core asks it to open.
    pub fn new(
        config: &UdpInterface,
        interface: InterfaceId,
        waker: Arc<Waker>,
    ) -> io::Result<Self> {
        let label = Self::label(config);
        let mut driver = UdpDriver {
            interface,
            label,
            config: config.clone(),
            socket: None,
            v6: false,
            batch: RecvBatch::new(DATAGRAM_MAX),
            send_scratch: SendBatch::new(),
            in_flight: VecDeque::new(),
            gso: false,
            batching: false,
            last_single: None,
            waker,
            lookup: None,
            small_buffer_said: false,
            cut_said: false,
        };
        if config.connect.is_none() {
            let local = SocketAddr::new(config.local_address(), config.port);
            let socket = bind(local)
                .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", driver.label)))?;
            driver.adopt(socket);
        }
        Ok(driver)
    }

    /// Takes `socket` as the interface's; a receive buffer smaller than asked for is
    /// said once per interface (a client binds again at every open).
    fn adopt(&mut self, socket: UdpSocket) {
        // Linux reports twice the size asked for (the rest is its bookkeeping).
        let got = SockRef::from(&socket).recv_buffer_size();
        if let Ok(got) = got
            && got < SOCKET_BUFFER
            && !self.small_buffer_said
        {
            self.small_buffer_said = true;
            log::warn(&format_args!(
                "{}: the receive buffer is {} KiB, not the {} KiB asked for, so bursts \
                 may be dropped by the kernel; raise the limit with \
                 `sysctl -w net.core.rmem_max={SOCKET_BUFFER}`",
                self.label,
                got / 2 / 1024,
                SOCKET_BUFFER / 1024
            ));
        }
        self.gso = sys::gso_supported(&socket);
        self.v6 = socket.local_addr().is_ok_and(|a| a.is_ipv6());
        self.socket = Some(socket);
    }

    /// Binds a client's socket for sending to `target` and tells the core where its
    /// datagrams go.
    fn bind_for(&mut self, target: SocketAddr, engine: &mut Engine) -> io::Result<()> {
        let local_ip = self.config.address.unwrap_or(match target {
            SocketAddr::V4(_) => IpAddr::from([0u8; 4]),
            SocketAddr::V6(_) => IpAddr::from([0u16; 8]),
        });
        let socket = bind(SocketAddr::new(local_ip, self.config.port))?;
        if target.is_ipv4() {
            // A broadcast address needs it; any other target does not mind it.
            socket.set_broadcast(true)?;
        }
        self.adopt(socket);
        engine.set_target(self.interface, target);
        Ok(())
    }

    /// A client whose look-up is under way: binds once it has the answer (then `Ok`),
    /// or reports a failure to the core (then `Err`, the driver is lost).
    fn finish_lookup(&mut self, engine: &mut Engine, now: Timestamp) -> Result<(), ()> {
        let Some(lookup) = self.lookup.take() else {
            return Ok(());
        };
        let target = match lookup.poll() {
            Err(pending) => {
                self.lookup = Some(pending);
                return Ok(());
            }
            Ok(answer) => answer,
        };
        match target.and_then(|t| self.bind_for(t, engine)) {
            Ok(()) => {
                engine.stream_opened(self.interface, now);
                Ok(())
            }
            Err(e) => {
                engine.stream_open_failed(self.interface, now, &e);
                Err(())
            }
        }
    }

    /// The bound address.
    #[cfg(test)]
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket
            .as_ref()
            .ok_or_else(|| io::Error::from(io::ErrorKind::NotConnected))?
            .local_addr()
    }
}

impl Driver for UdpDriver {
    fn level_triggered(&self) -> bool {
        true
    }

    fn interface(&self) -> InterfaceId {
        self.interface
    }

    fn fd(&self) -> Option<RawFd> {
        self.socket.as_ref().map(AsRawFd::as_raw_fd)
    }

    fn open(&mut self, engine: &mut Engine, _now: Timestamp) -> io::Result<bool> {
        let Some(remote) = &self.config.connect else {
            return Ok(true);
        };
        match Lookup::start(remote, self.config.address, &self.waker).poll() {
            Ok(target) => {
                self.bind_for(target?, engine)?;
                Ok(true)
            }
            Err(pending) => {
                // Bound, and the core told, once the name resolves (see `flush`).
                self.lookup = Some(pending);
                Ok(false)
            }
        }
    }

    fn close(&mut self) {
        if self.config.connect.is_some() {
            self.socket = None;
            self.lookup = None;
            self.in_flight.clear();
        }
    }

    fn receive(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        let Some(socket) = &self.socket else {
            return Progress::Done;
        };
        for turn in 0..BATCHES_PER_TURN {
            // Light traffic: one datagram, the level-triggered watch reports the rest;
            // bursts: batches.
            let read = if self.batching {
                sys::recv_batch(socket, &mut self.batch)
            } else {
                sys::recv_one(socket, &mut self.batch)
            };
            let n = match read {
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.batching = false;
                    return Progress::Done;
                }
                Err(e) if is_transient(&e) => continue,
                Err(e) => {
                    engine.on_receive_failed(self.interface, &e);
                    return Progress::Done;
                }
            };
            // One datagram read on its own, and the loop turns right after it: what it
            // routes may be sent at once (`Engine::handle_datagram_direct`).
            let single = !self.batching;
            let cut = self.batch.cut_bytes();
            if cut > 0 {
                cut_datagram(engine, self.interface, &self.label, &mut self.cut_said, cut);
            }
            for (from, bytes) in self.batch.iter() {
                match from {
                    Some(from) if single => {
                        engine.handle_datagram_direct(self.interface, from, bytes, now);
                    }
                    Some(from) => engine.handle_datagram(self.interface, from, bytes, now),
                    None => {}
                }
            }
            if single {
                // Two datagrams close together: a burst begins.
                self.batching = self.last_single.is_some_and(|last| now < last + BURST_GAP);
                self.last_single = Some(now);
                return Progress::Done;
            }
            // Fewer than a full batch: the socket is drained; a datagram arriving later
            // raises a new event. A lone datagram where a burst was: back to one by one.
            if n < MAX_BATCH {
                if turn == 0 && n < 2 {
                    self.batching = false;
                }
                return Progress::Done;
            }
        }
        Progress::More
    }

    fn flush(&mut self, engine: &mut Engine, now: Timestamp) -> Progress {
        if self.finish_lookup(engine, now).is_err() {
            return Progress::Lost;
        }
        let Some(socket) = &self.socket else {
            return Progress::Done;
        };
        loop {
            let waiting = self.in_flight.len();
            let room = MAX_BATCH - waiting;
            engine.poll_transmit(self.interface, now, room, &mut self.in_flight);
            let handed_out = self.in_flight.len() - waiting;
            if self.in_flight.is_empty() {
                return Progress::Done;
            }
            let wanted = self.in_flight.len();
            let v6 = self.v6;
            // A missing peer fails to send and is counted, and shifts no other datagram.
            let batch = self
                .in_flight
                .iter()
                .map(|t| (on_wire(t.to.unwrap_or(NOWHERE), v6), &t.packet[..]));
            match sys::send_batch(socket, &mut self.send_scratch, batch, self.gso) {
                Ok(sent) => {
                    let sent_here = sent.min(wanted);
                    engine.on_sent_batch(self.in_flight.drain(..sent_here));
                    if sent < wanted {
                        return Progress::Blocked; // the socket buffer is full
                    }
                    if handed_out < room {
                        // The core handed out less than there was room for: it has
                        // nothing more now (it names the interface again when it has).
                        return Progress::Done;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Progress::Blocked,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // The kernel or the route refused a GSO run (no checksum offload,
                // IPsec, ...): send every datagram on its own from now on.
                Err(e) if self.gso && e.kind() == io::ErrorKind::Unsupported => {
                    self.gso = false;
                    log::warn(&format_args!(
                        "{}: {e}; sending datagrams one by one",
                        self.label
                    ));
                }
                // A late ICMP error for an earlier datagram surfaced here; nothing was sent.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {}
                // This datagram cannot be sent (e.g. no route): the core counts it.
                Err(e) => {
                    if let Some(t) = self.in_flight.pop_front() {
                        engine.on_send_failed(self.interface, &t, &e);
                    }
                }
            }
        }
    }

    fn send_now(&mut self, engine: &mut Engine, now: Timestamp) -> Option<Progress> {
        if !self.in_flight.is_empty() || self.lookup.is_some() {
            return None;
        }
        let socket = self.socket.as_ref()?;
        let t = engine.take_direct(self.interface)?;
        let to = on_wire(t.to.unwrap_or(NOWHERE), self.v6);
        if socket.send_to(&t.packet, to).is_ok() {
            engine.on_sent_batch(std::iter::once(t));
            return Some(Progress::Done);
        }
        // Full, refused or failed: the usual send takes it from here (it retries, waits
        // for room, or counts the failure).
        self.in_flight.push_back(t);
        Some(self.flush(engine, now))
    }

    fn idle(&self) -> bool {
        self.in_flight.is_empty()
    }

    fn udp_port(&self) -> Option<u16> {
        Some(self.config.port).filter(|&p| p != 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Interface, load};
    use crate::routing::RouterOptions;
    use crate::wire::encode::{Header, encode_v2};
    use std::time::{Duration, Instant};

    fn frame(seq: u8, system: u8) -> Vec<u8> {
        let header = Header {
            seq,
            system,
            component: 1,
        };
        let mut out = Vec::new();
        // ATTITUDE (id 30, 28 bytes), every byte set so nothing is truncated.
        encode_v2(header, 30, &[seq | 1; 28], None, &mut out).expect("encode");
        out
    }

    /// Receives on `driver` until the core counted `want` frames or 5 s passed.
    fn receive_until(driver: &mut UdpDriver, engine: &mut Engine, want: u64) {
        let deadline = Instant::now() + Duration::from_secs(5);
        let id = driver.interface;
        let frames = |e: &Engine| e.interface(id).map_or(0, |i| i.parser.stats().frames);
        while frames(engine) < want && Instant::now() < deadline {
            driver.receive(engine, Timestamp::ZERO);
            std::thread::yield_now();
        }
    }

    /// When the route refuses GSO (here: a socket with UDP checksums turned off, which
    /// the kernel refuses to segment), the interface falls back to one datagram at a
    /// time for good and loses nothing.
    #[test]
    fn refused_gso_falls_back_to_single_datagrams() {
        let loaded = load("udp { port 0; address 127.0.0.1; }\nchain default { accept; }\n")
            .expect("config");
        let Some(Interface::Udp(iface)) = loaded.config.interfaces.first() else {
            panic!("one udp interface");
        };
        let mut engine = Engine::new(&loaded.config, RouterOptions::default());
        let id = engine.add_datagram_interface("udp test".into(), 0, Default::default());
        let poll = mio::Poll::new().expect("poll");
        let waker = Arc::new(Waker::new(poll.registry(), mio::Token(0)).expect("waker"));
        let mut driver = UdpDriver::new(iface, id, waker).expect("bind");
        let to = driver.local_addr().expect("addr");
        let (listener, sender) = (
            UdpSocket::bind("127.0.0.1:0").expect("bind"),
            UdpSocket::bind("127.0.0.1:0").expect("bind"),
        );
        listener
            .set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        listener.send_to(&frame(0, 12), to).expect("send");
        receive_until(&mut driver, &mut engine, 1);
        let socket = driver.socket.as_ref().expect("bound");
        sys::disable_udp_checksums(socket).expect("SO_NO_CHECK");
        let burst: Vec<Vec<u8>> = (1..=10).map(|i| frame(i, 1)).collect();
        sender.send_to(&burst.concat(), to).expect("send");
        receive_until(&mut driver, &mut engine, 11);
        assert_eq!(driver.flush(&mut engine, Timestamp::ZERO), Progress::Done);
        let mut got = Vec::new();
        let mut buf = [0u8; 2048];
        while got.len() < burst.len() {
            let n = listener.recv(&mut buf).expect("a datagram within 5 s");
            got.push(buf[..n].to_vec());
        }
        assert_eq!(got, burst);
        assert!(!driver.gso, "GSO is off after the refusal");
        assert!(driver.idle() && engine.is_idle(id));
    }
}
