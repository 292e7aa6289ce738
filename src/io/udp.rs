//! One `udp { }` interface: a non-blocking IPv4 socket, the remotes that have sent it a
//! valid frame (each a link named `a.b.c.d:port`), batched receive and send, and the
//! interface's `max_bitrate` pacer.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::net::{SocketAddr, SocketAddrV4};

use mio::net::UdpSocket;
use socket2::{Domain, Protocol, Socket, Type};

use super::counters::{LinkCounters, LinkReport};
use super::frames::{Source, ToRouter, UnknownIds};
use super::log;
use super::sys::{self, MAX_BATCH, RecvBatch, SendBatch};
use crate::config::UdpInterface;
use crate::routing::pacer::DEFAULT_BURST;
use crate::routing::{LinkId, Output, Pace, Pacer, Packet, Router, Timestamp};
use crate::wire::{Parser, ParserStats};

/// Socket buffer sizes asked for, so bursts are not dropped by the kernel.
const SOCKET_BUFFER: usize = 4 * 1024 * 1024;
/// Datagrams longer than this are cut (a MAVLink frame is at most 280 bytes; several
/// frames may share a datagram).
const DATAGRAM_MAX: usize = 8192;
/// How long bytes held back for an incomplete frame wait for the sender's next datagram.
const STALE_GAP: std::time::Duration = std::time::Duration::from_millis(100);
/// Receive batches taken per wake-up before the loop gets a turn to send.
const BATCHES_PER_TURN: usize = 8;
/// Most packets one link sends in a row before the next link's turn, when the
/// interface has no `max_bitrate` (see [`UdpDriver::flush`]).
const SEND_TURN: usize = 16;
/// How late the loop may wake up for a datagram the pacer held back without the
/// interface losing rate. With a bucket of only one datagram every late wake-up is rate
/// lost for good, and a busy machine wakes the loop milliseconds late: the end-to-end
/// test measured 1.7% below `max_bitrate` at 256 kbit/s with two CPU hogs on two cores.
/// The bucket holds this much time at the configured rate beyond the largest datagram
/// (40 bytes at 64 kbit/s), but never more than one more largest datagram: so a burst
/// is at most one datagram plus at most one datagram's worth of catching up.
const PACING_SLACK_MICROS: u64 = 5_000;

/// The pacer of an interface limited to `rate` bit/s (0 = unlimited).
fn pacer_for(rate: u64) -> Pacer {
    let slack =
        (rate.saturating_mul(PACING_SLACK_MICROS) / 8 / 1_000_000).min(u64::from(DEFAULT_BURST));
    let burst = u64::from(DEFAULT_BURST).saturating_add(slack);
    Pacer::with_burst(rate, u32::try_from(burst).unwrap_or(u32::MAX))
}

/// A remote that has sent a valid frame.
struct Remote {
    address: SocketAddrV4,
    name: String,
    counters: LinkCounters,
}

/// A bound UDP interface and its remotes.
pub struct UdpDriver {
    /// `udp a.b.c.d:port` for messages.
    pub label: String,
    socket: UdpSocket,
    parser: Parser,
    last_sender: Option<SocketAddrV4>,
    by_address: HashMap<SocketAddrV4, LinkId>,
    remotes: HashMap<LinkId, Remote>,
    /// Links in creation order, for round-robin sending.
    order: Vec<LinkId>,
    next_turn: usize,
    pacer: Pacer,
    in_flight: VecDeque<(SocketAddrV4, Packet)>,
    batch: RecvBatch,
    send_scratch: SendBatch,
    /// When the pacer next allows a datagram, if it is holding one back.
    pub pace_deadline: Option<Timestamp>,
    /// Receive or send errors other than "would block".
    pub io_errors: u64,
    /// When the last datagram arrived.
    last_rx: Timestamp,
    /// The socket refused datagrams: wait for it to become writable. (Writability is
    /// only watched while this is set: an idle UDP socket is always writable, and
    /// watching it would wake the loop after every datagram sent.)
    pub blocked: bool,
    /// Runs of equal datagrams to one remote are sent as one UDP GSO message (see
    /// [`sys::send_batch`]): on when the kernel offers it, off for good once a send
    /// with GSO is refused.
    gso: bool,
}

/// Binds the socket of `config` (non-blocking, large buffers).
fn bind(config: &UdpInterface) -> io::Result<UdpSocket> {
    let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    // Beyond the system's limit when privileged, else up to it.
    if sys::force_buffer_size(&socket, true, SOCKET_BUFFER).is_err() {
        let _ = socket.set_recv_buffer_size(SOCKET_BUFFER);
    }
    if sys::force_buffer_size(&socket, false, SOCKET_BUFFER).is_err() {
        let _ = socket.set_send_buffer_size(SOCKET_BUFFER);
    }
    // Linux reports twice the size asked for (the rest is its bookkeeping).
    if let Ok(got) = socket.recv_buffer_size()
        && got < SOCKET_BUFFER
    {
        log::warn(&format_args!(
            "udp {}:{}: the receive buffer is {} KiB, not the {} KiB asked for, so bursts \
             may be dropped by the kernel; raise the limit with \
             `sysctl -w net.core.rmem_max={SOCKET_BUFFER}`",
            config.address,
            config.port,
            got / 2 / 1024,
            SOCKET_BUFFER / 1024
        ));
    }
    socket.set_nonblocking(true)?;
    let address = SocketAddr::V4(SocketAddrV4::new(config.address, config.port));
    socket.bind(&address.into())?;
    Ok(UdpSocket::from_std(socket.into()))
}

/// The link of the current sender, created on its first valid frame.
struct Sender<'a> {
    address: SocketAddrV4,
    by_address: &'a mut HashMap<SocketAddrV4, LinkId>,
    remotes: &'a mut HashMap<LinkId, Remote>,
    order: &'a mut Vec<LinkId>,
}

impl Source for Sender<'_> {
    fn link(&mut self, router: &mut Router, now: Timestamp) -> (LinkId, &mut LinkCounters) {
        let address = self.address;
        let order = &mut *self.order;
        let id = *self.by_address.entry(address).or_insert_with(|| {
            let id = router.add_udp_link(&address.to_string(), now);
            order.push(id);
            id
        });
        let remote = self.remotes.entry(id).or_insert_with(|| Remote {
            address,
            name: address.to_string(),
            counters: LinkCounters::default(),
        });
        (id, &mut remote.counters)
    }

    fn counters(&mut self) -> Option<&mut LinkCounters> {
        let id = self.by_address.get(&self.address)?;
        self.remotes.get_mut(id).map(|r| &mut r.counters)
    }
}

impl UdpDriver {
    /// Binds the interface's socket.
    pub fn open(config: &UdpInterface) -> io::Result<Self> {
        let socket = bind(config)?;
        let gso = sys::gso_supported(&socket);
        let rate = config.max_bitrate.unwrap_or(0);
        Ok(UdpDriver {
            label: format!("udp {}:{}", config.address, config.port),
            socket,
            parser: Parser::new(),
            last_sender: None,
            by_address: HashMap::new(),
            remotes: HashMap::new(),
            order: Vec::new(),
            next_turn: 0,
            pacer: pacer_for(rate),
            in_flight: VecDeque::new(),
            batch: RecvBatch::new(DATAGRAM_MAX),
            send_scratch: SendBatch::new(),
            pace_deadline: None,
            io_errors: 0,
            blocked: false,
            last_rx: Timestamp::ZERO,
            gso,
        })
    }

    /// The socket, to register with the poller.
    pub fn socket_mut(&mut self) -> &mut UdpSocket {
        &mut self.socket
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Parser totals (checksum errors and the like) of this interface.
    pub fn parser_stats(&self) -> &ParserStats {
        self.parser.stats()
    }

    /// Reads datagrams and routes their frames. Returns true if more may be waiting
    /// (the turn ended before the socket was drained).
    pub fn receive(
        &mut self,
        router: &mut Router,
        now: Timestamp,
        out: &mut Output,
        unknown: &mut UnknownIds,
    ) -> bool {
        for _ in 0..BATCHES_PER_TURN {
            match sys::recv_batch(&self.socket, &mut self.batch) {
                // Fewer than a full batch: the socket is drained. With edge-triggered
                // readiness a datagram arriving later raises a new event.
                Ok(n) if n < MAX_BATCH => {
                    self.route_batch(router, now, out, unknown);
                    return false;
                }
                Ok(_) => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return false,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                // An ICMP "port unreachable" for an earlier datagram: not a receive problem.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => continue,
                Err(e) => {
                    self.io_errors += 1;
                    log::error(&format_args!("{}: receive failed: {e}", self.label));
                    return false;
                }
            }
            self.route_batch(router, now, out, unknown);
        }
        true
    }

    /// Routes the frames of the datagrams of the last receive batch.
    fn route_batch(
        &mut self,
        router: &mut Router,
        now: Timestamp,
        out: &mut Output,
        unknown: &mut UnknownIds,
    ) {
        let Self {
            batch,
            parser,
            last_sender,
            by_address,
            remotes,
            order,
            ..
        } = self;
        for (from, bytes) in batch.iter() {
            // Non-IPv4 senders are ignored, as in the original.
            let Some(address) = from else { continue };
            // A frame may continue in the sender's next datagram, but never in
            // another sender's: partial frames of interleaved senders are dropped.
            if *last_sender != Some(address) {
                parser.clear();
                *last_sender = Some(address);
            }
            let mut events = ToRouter {
                router: &mut *router,
                out: &mut *out,
                now,
                unknown: &mut *unknown,
                link: Sender {
                    address,
                    by_address: &mut *by_address,
                    remotes: &mut *remotes,
                    order: &mut *order,
                },
            };
            parser.feed_events(bytes, &mut events);
        }
        self.last_rx = now;
    }

    /// When the bytes held back for an incomplete frame count as stale, if there are
    /// any: a frame split over datagrams continues in the sender's very next datagram,
    /// so after [`STALE_GAP`] without one the candidate is judged (see
    /// [`UdpDriver::finish_stale`]).
    pub fn stale_at(&self) -> Option<Timestamp> {
        (self.parser.pending_len() > 0)
            .then(|| Timestamp::new(self.last_rx.since_start() + STALE_GAP))
    }

    /// Ends a stale candidate: it is rejected and the bytes behind its start scanned
    /// again, so valid frames held up behind noise are routed now.
    pub fn finish_stale(
        &mut self,
        router: &mut Router,
        now: Timestamp,
        out: &mut Output,
        unknown: &mut UnknownIds,
    ) {
        let (Some(t), Some(address)) = (self.stale_at(), self.last_sender) else {
            return;
        };
        if now < t {
            return;
        }
        let mut events = ToRouter {
            router,
            out,
            now,
            unknown,
            link: Sender {
                address,
                by_address: &mut self.by_address,
                remotes: &mut self.remotes,
                order: &mut self.order,
            },
        };
        self.parser.finish(&mut events);
    }

    /// True if this interface owns link `id`.
    pub fn owns(&self, id: LinkId) -> bool {
        self.remotes.contains_key(&id)
    }

    /// Notes queue levels after routing, for the high-water marks.
    pub fn note_queue(&mut self, id: LinkId, bytes: usize) {
        if let Some(r) = self.remotes.get_mut(&id) {
            r.counters.queue_level(bytes);
        }
    }

    /// Forgets links the core removed (their pools stayed empty for the expiry time).
    pub fn forget(&mut self, removed: &[LinkId]) {
        for id in removed {
            if let Some(r) = self.remotes.remove(id) {
                self.by_address.remove(&r.address);
                self.in_flight.retain(|(a, _)| *a != r.address);
            }
        }
        self.order.retain(|id| self.remotes.contains_key(id));
    }

    /// The next link (round robin) with a packet waiting; the turn after it goes to the
    /// link that follows it.
    fn next_ready(&mut self, router: &Router) -> Option<LinkId> {
        let n = self.order.len();
        let i = (0..n)
            .map(|k| (self.next_turn + k) % n)
            .find(|&i| router.peek(self.order[i]).is_some())?;
        self.next_turn = (i + 1) % n;
        Some(self.order[i])
    }

    /// Sends what the links' queues hold, round robin between remotes, as far as the
    /// socket and the pacer allow. Sets [`UdpDriver::pace_deadline`] when the pacer
    /// holds a datagram back.
    pub fn flush(&mut self, router: &mut Router, now: Timestamp) {
        self.pace_deadline = None;
        self.blocked = false;
        // Unpaced, a link's turn is a run of up to `SEND_TURN` packets, so that its
        // datagrams lie next to each other in the batch and go out as one GSO message;
        // paced, a turn is one packet, so the bandwidth is shared fairly.
        let turn = if self.pacer.rate() == 0 { SEND_TURN } else { 1 };
        loop {
            'fill: while self.in_flight.len() < MAX_BATCH {
                let Some(id) = self.next_ready(router) else {
                    break;
                };
                let Some(address) = self.remotes.get(&id).map(|r| r.address) else {
                    break;
                };
                for _ in 0..turn {
                    if self.in_flight.len() >= MAX_BATCH {
                        break;
                    }
                    let Some(len) = router.peek(id).map(|p| p.len()) else {
                        break;
                    };
                    match self.pacer.check(now, len) {
                        Pace::Now => {}
                        Pace::At(t) => {
                            self.pace_deadline = Some(t);
                            break 'fill;
                        }
                    }
                    let Some(packet) = router.pop(id) else { break };
                    self.pacer.sent(now, len);
                    self.in_flight.push_back((address, packet));
                }
            }
            if self.in_flight.is_empty() {
                return;
            }
            let wanted = self.in_flight.len();
            let batch = self.in_flight.iter().map(|(a, p)| (*a, &p[..]));
            match sys::send_batch(&self.socket, &mut self.send_scratch, batch, self.gso) {
                Ok(sent) => {
                    for _ in 0..sent {
                        if let Some((address, packet)) = self.in_flight.pop_front() {
                            self.count_sent(address, packet.len());
                        }
                    }
                    if sent < wanted {
                        self.blocked = true; // the socket buffer is full: wait until writable
                        return;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.blocked = true;
                    return;
                }
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
                Err(e) => {
                    // This datagram cannot be sent (e.g. no route): count it, go on.
                    self.io_errors += 1;
                    if let Some((address, _)) = self.in_flight.pop_front() {
                        let remote = self.remote_mut(address);
                        // Logged once per remote (the counters keep the total), so a dead
                        // route cannot flood the log.
                        let first = remote.as_ref().is_none_or(|r| r.counters.send_errors == 0);
                        if let Some(r) = remote {
                            r.counters.send_errors += 1;
                        }
                        if first {
                            log::error(&format_args!(
                                "{}: sending to {address} failed: {e} (further failures are only counted)",
                                self.label
                            ));
                        }
                    }
                }
            }
        }
    }

    /// The remote at `address`, if it still has a link.
    fn remote_mut(&mut self, address: SocketAddrV4) -> Option<&mut Remote> {
        let id = self.by_address.get(&address)?;
        self.remotes.get_mut(id)
    }

    fn count_sent(&mut self, address: SocketAddrV4, len: usize) {
        if let Some(r) = self.remote_mut(address) {
            r.counters.sent(len);
        }
    }

    /// True if nothing is waiting to be sent on this interface.
    pub fn idle(&self, router: &Router) -> bool {
        self.in_flight.is_empty() && self.order.iter().all(|id| router.peek(*id).is_none())
    }

    /// Reports of every remote, in creation order.
    pub fn reports<'a>(&'a self, router: &'a Router) -> impl Iterator<Item = LinkReport<'a>> + 'a {
        self.order.iter().filter_map(move |id| {
            let r = self.remotes.get(id)?;
            Some(LinkReport {
                name: &r.name,
                counters: r.counters,
                queue_drops: router.link(*id).map_or(0, |l| l.queue().dropped()),
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Interface, load};
    use crate::routing::RouterOptions;
    use crate::wire::encode::{Header, encode_v2};
    use std::net::UdpSocket as StdUdpSocket;
    use std::os::fd::AsRawFd;
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

    /// Receives on `driver` until `want` frames were routed or 5 s passed.
    fn receive_until(driver: &mut UdpDriver, router: &mut Router, out: &mut Output, want: usize) {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut unknown = UnknownIds::default();
        while driver.parser_stats().frames < want as u64 && Instant::now() < deadline {
            driver.receive(router, Timestamp::ZERO, out, &mut unknown);
            std::thread::yield_now();
        }
        out.clear();
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
        let mut router = Router::with_options(&loaded.config, RouterOptions::default());
        let mut driver = UdpDriver::open(iface).expect("bind");
        let to = driver.local_addr().expect("addr");
        let (listener, sender) = (
            StdUdpSocket::bind("127.0.0.1:0").expect("bind"),
            StdUdpSocket::bind("127.0.0.1:0").expect("bind"),
        );
        listener
            .set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        let mut out = Output::default();
        listener.send_to(&frame(0, 12), to).expect("send");
        receive_until(&mut driver, &mut router, &mut out, 1);
        // SO_NO_CHECK: UDP GSO needs checksum offload and refuses these sockets.
        let one: libc::c_int = 1;
        // SAFETY (test): passes a pointer to a live c_int and its size.
        let r = unsafe {
            libc::setsockopt(
                driver.socket_mut().as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_NO_CHECK,
                (&one as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        assert_eq!(r, 0, "SO_NO_CHECK");
        let burst: Vec<Vec<u8>> = (1..=10).map(|i| frame(i, 1)).collect();
        sender.send_to(&burst.concat(), to).expect("send");
        receive_until(&mut driver, &mut router, &mut out, 11);
        driver.flush(&mut router, Timestamp::ZERO);
        let mut got = Vec::new();
        let mut buf = [0u8; 2048];
        while got.len() < burst.len() {
            let n = listener.recv(&mut buf).expect("a datagram within 5 s");
            got.push(buf[..n].to_vec());
        }
        assert_eq!(got, burst);
        assert!(!driver.gso, "GSO is off after the refusal");
        assert!(driver.idle(&router));
    }
}
