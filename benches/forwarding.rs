//! UDP and TCP forwarding benchmark: a load generator and sinks of our own,
//! on 127.0.0.1 only.
//!
//! Run: `cargo bench --bench forwarding` (about 2–3 minutes), or
//! `cargo bench --bench forwarding -- --quick` (or `MAVTABLES_BENCH_QUICK=1`) for a short
//! run. `cargo test --all-targets` runs this file with no `--bench` argument: then it only
//! does a ~3 s smoke test of direct and relay mode and never starts the router.
//!
//! The generator sends MAVLink 2 SYSTEM_TIME frames (24 bytes) from system
//! [`GEN_SYSTEM`]: `time_unix_usec` carries the send time in ns since a shared
//! [`Instant`], `time_boot_ms` the sequence number with [`SEQ_MARK`] set (so the last
//! payload byte is never zero and every frame has the same length). Frames go out in
//! bursts paced per millisecond (single frames up to 10k frames/s), each burst in
//! `sendmmsg(2)` batches of up to 64 datagrams.
//!
//! Sinks (one thread and one socket each) parse with [`Parser`], detect loss and
//! reordering by sequence number and record latency = receive time − send time. For
//! throughput they read in batches every 0.5 ms; for latency they block on every frame.
//!
//! Figures, per mode and number of receivers: the highest rate of a ladder (25k … 1M
//! frames/s, 2 s steps, a lossy step is retried once) with zero loss; CPU time per frame
//! sent, of the forwarder and of this process (`/proc/<pid>/stat`), at 50k frames/s;
//! latency p50/p99/p99.9 at 10k frames/s (medians of 3 rounds); the router's peak RSS
//! (`VmHWM`) before and after 2 s at 10× its zero-loss rate.
//!
//! Modes: *direct* sends each frame straight to every sink (the machine's ceiling);
//! *relay* sends to the least forwarder there can be, a process of this benchmark that
//! blocks in `recvmmsg` and sends every datagram on unparsed (the floor under any router,
//! measured in the same run); *router* sends to `mavtables --config <temp file>`, which
//! must forward to the sinks. `--cpu` also measures a process that only receives, the
//! floor of CPU per received frame. The forwarders' CPU time is read to the nanosecond
//! from `/proc/<pid>/task/*/schedstat`.
//! Each sink announces itself with a HEARTBEAT (systems 101, 102, 103) to the router,
//! once before the run and then every second; SYSTEM_TIME has no target, so the router
//! forwards it to every link but the generator's.
//!
//! TCP (`--tcp`, `--tcp-fanout`, and at the end of the full run): the router then also
//! has a TCP server (`tcp { port P; address 127.0.0.1; }`), where every connection is a
//! link of its own. The generator may be a client of it ([`Legs`]): it writes each burst
//! with one `write` (`TCP_NODELAY`, paced as over UDP); a step fails if it falls behind
//! its rate by more than 5% (the router not reading fast enough shows up so), and "loss"
//! is frames missing at a sink by sequence number. Sinks may be clients of it too (they
//! write their HEARTBEAT into the connection and parse the stream across reads). `--tcp`
//! compares UDP→UDP, TCP→TCP and TCP→UDP, one receiver, a router each: ladder, then
//! interleaved latency rounds at 10k frames/s and TCP p50 ÷ UDP p50 round by round
//! (`--tcp --latency`: the latency rounds alone).
//! `--tcp-fanout`: 100 TCP clients receive a broadcast stream of 1k frames/s from a TCP
//! and (another router) a UDP generator; one thread reads them all every 2 ms
//! ([`Reading::Sweep`]); the figure is the router's CPU per frame delivered.

#![forbid(unsafe_code)]

use std::io::{self, ErrorKind, Read, Write};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, TcpListener, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use mavtables::wire::encode::{Header, encode_v2};
use mavtables::wire::{Frame, Parser};

mod light;

/// MAVLink system id of the generator.
const GEN_SYSTEM: u8 = 1;
/// System id of sink `i` is `SINK_SYSTEM + i`.
const SINK_SYSTEM: u8 = 101;
/// SYSTEM_TIME: `time_unix_usec` (u64) then `time_boot_ms` (u32), 12 payload bytes.
const MSG_SYSTEM_TIME: u32 = 2;
const MSG_HEARTBEAT: u32 = 0;
/// Set in every sequence number on the wire: marks our frames and keeps them 24 bytes.
const SEQ_MARK: u32 = 1 << 31;
/// Largest datagram a sink reads.
const DGRAM_MAX: usize = 2048;
/// Rates tried when searching for the highest rate with zero loss, frames/s.
const LADDER: [f64; 10] = [
    25e3, 50e3, 100e3, 150e3, 200e3, 300e3, 400e3, 500e3, 700e3, 1e6,
];
/// Bursts are sent every millisecond, except at rates up to [`SINGLE_FRAME_RATE`]:
/// there every frame goes out alone, every `1/rate` (at most every 1 ms), so that the
/// latency runs measure a frame's own latency and not that of the frames queued ahead of
/// it in its burst. (A tick costs the generator a wake-up, about 9 µs of CPU on this VM,
/// hence no finer ticks at high rates.)
const TICK: Duration = Duration::from_millis(1);
const SINGLE_FRAME_RATE: f64 = 10e3;
/// Rate of the latency runs: 10k frames/s, a busy telemetry link.
const LATENCY_RATE: f64 = 10e3;
/// Fixed rate at which CPU time per frame is measured.
const CPU_RATE: f64 = 50e3;

/// Thin wrappers over the system calls that `std` does not offer (batched send/receive,
/// socket buffer size, signals, clock ticks), made through `nix`'s safe API and, for
/// batched sends, the router crate's hidden `io::harness`, as the `forbid` attribute at
/// the top of this file requires.
mod sys {
    use std::cell::RefCell;
    use std::io::{self, IoSliceMut};
    use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
    use std::os::fd::AsRawFd;

    use mavtables::io::harness::DatagramSender;

    pub use nix::sys::signal::Signal;
    use nix::sys::signal::kill;
    use nix::sys::socket::sockopt::{RcvBuf, RcvBufForce};
    use nix::sys::socket::{MsgFlags, MultiHeaders, SockaddrIn, recvmmsg, setsockopt};
    use nix::unistd::{Pid, SysconfVar, sysconf};

    /// Most datagrams handed to the kernel in one call: the router's own batch (64).
    pub const BATCH: usize = mavtables::io::harness::MAX_BATCH;

    thread_local! {
        /// The `mmsghdr`s of this thread's batched receives, allocated once.
        static RECV_HEADERS: RefCell<MultiHeaders<SockaddrIn>> =
            RefCell::new(MultiHeaders::preallocate(BATCH, None));
        /// The same for its batched sends.
        static SENDER: RefCell<DatagramSender> = RefCell::new(DatagramSender::new());
    }

    /// Sends up to [`BATCH`] `(datagram, destination)` pairs with one `sendmmsg(2)`
    /// (the router crate's own, which counts what was sent without reading headers the
    /// kernel did not write); returns how many were sent (always a prefix of `msgs`).
    pub fn send_batch(sock: &UdpSocket, msgs: &[(&[u8], SocketAddrV4)]) -> io::Result<usize> {
        let batch = msgs.iter().map(|&(data, to)| (data, SocketAddr::V4(to)));
        SENDER.with_borrow_mut(|sender| sender.send(sock, batch))
    }

    /// Receives up to [`BATCH`] datagrams with one `recvmmsg(2)`, waiting (up to the
    /// socket's read timeout) for the first only (`MSG_WAITFORONE`); fills `lens` and
    /// `froms` (the senders) and returns the count.
    pub fn recv_batch(
        sock: &UdpSocket,
        bufs: &mut [[u8; super::DGRAM_MAX]; BATCH],
        lens: &mut [usize; BATCH],
        froms: &mut [SocketAddrV4; BATCH],
    ) -> io::Result<usize> {
        RECV_HEADERS.with_borrow_mut(|recv| {
            let mut iovs = bufs.each_mut().map(|buf| [IoSliceMut::new(buf)]);
            let got = recvmmsg(
                sock.as_raw_fd(),
                recv,
                &mut iovs,
                MsgFlags::MSG_WAITFORONE,
                None,
            )?;
            let mut n = 0;
            for ((len, from), msg) in lens.iter_mut().zip(froms.iter_mut()).zip(got) {
                *len = msg.bytes;
                *from = msg.address.map_or(
                    SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0),
                    SocketAddrV4::from,
                );
                n += 1;
            }
            Ok(n)
        })
    }

    /// Asks for a receive buffer of `bytes` (the kernel doubles it for its bookkeeping):
    /// beyond `net.core.rmem_max` if we may (root, `SO_RCVBUFFORCE`), else capped at it
    /// (`SO_RCVBUF`).
    pub fn set_recv_buffer(sock: &UdpSocket, bytes: usize) -> io::Result<()> {
        setsockopt(sock, RcvBufForce, &bytes)
            .or_else(|_| setsockopt(sock, RcvBuf, &bytes))
            .map_err(io::Error::from)
    }

    /// Sends `signal` to process `pid` (SIGSTOP / SIGCONT for the backlog runs).
    pub fn signal(pid: u32, signal: Signal) -> io::Result<()> {
        Ok(kill(Pid::from_raw(pid as i32), signal)?)
    }

    /// Clock ticks per second, the unit of `utime`/`stime` in `/proc/<pid>/stat`.
    pub fn clock_ticks() -> u64 {
        match sysconf(SysconfVar::CLK_TCK) {
            Ok(Some(t)) if t > 0 => t as u64,
            _ => 100,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Frames

/// Appends the benchmark frame `seq` stamped with `sent_ns` to `out`.
fn encode_probe(seq: u32, sent_ns: u64, out: &mut Vec<u8>) {
    let mut payload = [0u8; 12];
    payload[..8].copy_from_slice(&sent_ns.to_le_bytes());
    payload[8..].copy_from_slice(&(seq | SEQ_MARK).to_le_bytes());
    let header = Header {
        seq: seq as u8,
        system: GEN_SYSTEM,
        component: 1,
    };
    encode_v2(header, MSG_SYSTEM_TIME, &payload, None, out).expect("SYSTEM_TIME encodes");
}

/// `(seq, sent_ns)` of a benchmark frame; `None` for any other frame.
fn decode_probe(frame: &Frame<'_>) -> Option<(u32, u64)> {
    if frame.system() != GEN_SYSTEM || frame.message_id() != MSG_SYSTEM_TIME {
        return None;
    }
    let p = frame.payload_padded();
    let seq = u32::from_le_bytes(p[8..12].try_into().unwrap());
    (seq & SEQ_MARK != 0).then(|| {
        let sent = u64::from_le_bytes(p[..8].try_into().unwrap());
        (seq & !SEQ_MARK, sent)
    })
}

/// A ground-station HEARTBEAT from `system`, with which a sink makes itself known.
fn heartbeat(system: u8) -> Vec<u8> {
    // custom_mode 0, type GCS (6), autopilot INVALID (8), base_mode 0, state 0, version 3.
    let payload = [0, 0, 0, 0, 6, 8, 0, 0, 3];
    let header = Header {
        seq: 0,
        system,
        component: 190,
    };
    let mut out = Vec::new();
    encode_v2(header, MSG_HEARTBEAT, &payload, None, &mut out).expect("HEARTBEAT encodes");
    out
}

/// Nanoseconds since the shared base instant.
fn ns_since(base: Instant) -> u64 {
    base.elapsed().as_nanos() as u64
}

// ---------------------------------------------------------------------------------------
// Generator

/// How the generator hands datagrams to the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SendMode {
    /// `sendmmsg(2)`, up to [`sys::BATCH`] datagrams per call.
    Batched,
    /// One `send_to` per datagram.
    OneByOne,
}

/// What one generator run did.
#[derive(Debug, Default, Clone, Copy)]
struct GenReport {
    /// Frames sent (each to every destination).
    sent: u64,
    /// Datagrams the kernel refused.
    errors: u64,
    /// From first to last send.
    elapsed: Duration,
    /// Time spent in `write` on a TCP stream: near `elapsed` when the router does not
    /// read fast enough (the socket's send buffer is full and writes wait).
    in_write: Duration,
}

/// Sends frames numbered from `seq_start` to every address of `dests`, or written to
/// `stream` if there is one, at `rate` frames/s (or as fast as possible with `None`) for
/// `duration`, in bursts paced per tick (see [`TICK`]); a generator that falls behind
/// stops after 1.5 × `duration`.
#[allow(clippy::too_many_arguments)]
fn generate(
    sock: &UdpSocket,
    dests: &[SocketAddrV4],
    stream: Option<&TcpStream>,
    rate: Option<f64>,
    duration: Duration,
    seq_start: u32,
    mode: SendMode,
    base: Instant,
) -> GenReport {
    let total = rate.map(|r| (r * duration.as_secs_f64()).round() as u64);
    let per_call = (sys::BATCH / dests.len()).max(1) as u64;
    let deadline = duration.mul_f64(1.5);
    let mut report = GenReport::default();
    let mut buf = Vec::with_capacity(sys::BATCH * 24);
    let start = Instant::now();
    let mut ticks = 0u64;
    loop {
        let elapsed = start.elapsed();
        let due = match (rate, total) {
            (Some(r), Some(t)) if report.sent < t && elapsed < deadline => {
                ((r * elapsed.as_secs_f64()).ceil() as u64).clamp(report.sent, t)
            }
            (None, _) if elapsed < duration => report.sent + per_call,
            _ => break,
        };
        while report.sent < due {
            let n = (due - report.sent).min(per_call);
            buf.clear();
            let now = ns_since(base);
            for i in 0..n {
                encode_probe(seq_start + (report.sent + i) as u32, now, &mut buf);
            }
            if let Some(stream) = stream {
                // One write per burst, as one `sendmmsg` per burst over UDP.
                let t = Instant::now();
                report.errors += write_stream(stream, &buf, start + deadline);
                report.in_write += t.elapsed();
                report.sent += n;
                continue;
            }
            let frame_len = buf.len() / n as usize;
            let msgs: Vec<(&[u8], SocketAddrV4)> = buf
                .chunks(frame_len)
                .flat_map(|frame| dests.iter().map(move |&d| (frame, d)))
                .collect();
            report.errors += send_all(sock, &msgs, mode);
            report.sent += n;
        }
        if let Some(r) = rate {
            // Sleep to the next tick boundary; the next burst catches up on whatever the
            // sleep overshot, so the rate stays exact.
            let tick = if r <= SINGLE_FRAME_RATE {
                (1.0 / r).min(TICK.as_secs_f64())
            } else {
                TICK.as_secs_f64()
            };
            ticks = ticks.max((elapsed.as_secs_f64() / tick) as u64) + 1;
            let next = Duration::from_secs_f64(ticks as f64 * tick);
            if let Some(wait) = next.checked_sub(start.elapsed()) {
                thread::sleep(wait);
            }
        }
    }
    report.elapsed = start.elapsed();
    report
}

/// Writes all of `bytes` to `stream` (which has a write timeout), waiting while the
/// router does not read until `give_up`; returns 1 if it gave up or the write failed.
/// (The frame cut short then reaches the sink as garbage, which its parser skips.)
fn write_stream(mut stream: &TcpStream, mut bytes: &[u8], give_up: Instant) -> u64 {
    while !bytes.is_empty() {
        match stream.write(bytes) {
            Ok(0) => return 1,
            Ok(n) => bytes = &bytes[n..],
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e)
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut)
                    && Instant::now() < give_up => {}
            Err(_) => return 1,
        }
    }
    0
}

/// Sends every message, returns how many the kernel refused (counted, then skipped).
fn send_all(sock: &UdpSocket, msgs: &[(&[u8], SocketAddrV4)], mode: SendMode) -> u64 {
    let mut errors = 0;
    match mode {
        SendMode::Batched => {
            let mut rest = msgs;
            while !rest.is_empty() {
                match sys::send_batch(sock, rest) {
                    Ok(n) => rest = &rest[n..],
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    // The send does not block: wait for room as a blocking send would.
                    Err(e) if e.kind() == ErrorKind::WouldBlock => std::thread::yield_now(),
                    Err(_) => {
                        errors += 1;
                        rest = &rest[1..];
                    }
                }
            }
        }
        SendMode::OneByOne => {
            for (data, to) in msgs {
                if sock.send_to(data, to).is_err() {
                    errors += 1;
                }
            }
        }
    }
    errors
}

// ---------------------------------------------------------------------------------------
// Sink

/// What one sink saw during one trial.
#[derive(Debug, Default)]
struct SinkReport {
    /// Distinct benchmark frames of this trial received.
    distinct: u64,
    /// Benchmark frames received more than once.
    duplicates: u64,
    /// Frames that arrived after a frame with a higher sequence number.
    reordered: u64,
    /// Benchmark frames left over from an earlier trial.
    stale: u64,
    /// Valid frames that are not ours (e.g. other sinks' heartbeats via the router).
    other: u64,
    /// Candidates the parser rejected (bad CRC, unknown id, ...).
    rejected: u64,
    /// Receive errors other than timeouts.
    errors: u64,
    /// Receive time − send time of every frame, ns (saturated at u32::MAX).
    latencies: Vec<u32>,
}

/// A sink's socket: a UDP socket the router sends datagrams to, or a connection to the
/// router's TCP server (a byte stream: frames may straddle reads).
enum Sock {
    Udp(UdpSocket),
    Tcp(TcpStream),
}

impl Sock {
    /// Reads one datagram, or what the stream has; waits up to the read timeout unless
    /// the socket is non-blocking. The end of a stream is an error.
    fn recv(&self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Sock::Udp(s) => s.recv(buf),
            Sock::Tcp(s) => match Read::read(&mut &*s, buf)? {
                0 => Err(ErrorKind::UnexpectedEof.into()),
                n => Ok(n),
            },
        }
    }

    /// Sends `frame` to the router: over the connection, or as a datagram to its UDP
    /// port `udp`.
    fn announce(&self, frame: &[u8], udp: SocketAddrV4) -> io::Result<()> {
        match self {
            Sock::Udp(s) => s.send_to(frame, udp).map(drop),
            Sock::Tcp(s) => Write::write_all(&mut &*s, frame),
        }
    }

    fn set_nonblocking(&self, on: bool) -> io::Result<()> {
        match self {
            Sock::Udp(s) => s.set_nonblocking(on),
            Sock::Tcp(s) => s.set_nonblocking(on),
        }
    }

    fn is_stream(&self) -> bool {
        matches!(self, Sock::Tcp(_))
    }
}

/// One sink's accounting of one trial: loss, duplicates, order and latency by sequence
/// number, whatever the transport.
struct Tally {
    report: SinkReport,
    seen: Vec<u64>,
    highest: Option<u32>,
    parser: Parser,
    seq_start: u32,
}

impl Tally {
    fn new(seq_start: u32) -> Tally {
        Tally {
            report: SinkReport::default(),
            seen: Vec::new(),
            highest: None,
            parser: Parser::new(),
            seq_start,
        }
    }

    /// Counts the frames of `bytes`, received at `now` (ns since the base instant).
    /// `datagram`: `bytes` is one datagram, which holds whole frames, so nothing carries
    /// over; else it is the next piece of a stream.
    fn feed(&mut self, bytes: &[u8], now: u64, datagram: bool) {
        let Tally {
            report: r,
            seen,
            highest,
            parser,
            seq_start,
        } = self;
        parser.feed(bytes, |frame| {
            let Some((seq, sent)) = decode_probe(&frame) else {
                r.other += 1;
                return;
            };
            let Some(i) = seq.checked_sub(*seq_start).map(|i| i as usize) else {
                r.stale += 1;
                return;
            };
            if seen.len() <= i / 64 {
                seen.resize(i / 64 + 1, 0);
            }
            let bit = 1u64 << (i % 64);
            if seen[i / 64] & bit != 0 {
                r.duplicates += 1;
                return;
            }
            seen[i / 64] |= bit;
            r.distinct += 1;
            if highest.is_some_and(|h| seq < h) {
                r.reordered += 1;
            } else {
                *highest = Some(seq);
            }
            r.latencies
                .push(now.saturating_sub(sent).min(u32::MAX as u64) as u32);
        });
        if datagram {
            parser.clear();
        }
    }

    fn finish(mut self) -> SinkReport {
        self.report.rejected = self.parser.stats().rejected();
        self.report
    }
}

/// How a sink behaves in one trial.
struct SinkJob<'a> {
    sock: &'a Sock,
    seq_start: u32,
    base: Instant,
    stop: &'a AtomicBool,
    /// Distinct frames so far, for the drain wait.
    progress: &'a AtomicU64,
    /// Router mode: the router's UDP port (where a UDP sink sends its heartbeat every
    /// second; a TCP sink writes it to its connection), and as whom.
    announce: Option<(SocketAddrV4, u8)>,
    /// How the sink reads.
    reading: Reading,
}

/// How a sink waits for datagrams.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reading {
    /// Blocks in `recvmmsg` (or `read`) and wakes for every datagram (or segment): for
    /// latency.
    Eager,
    /// Once its queue is empty, sleeps [`LAZY_POLL`] before reading again, so it wakes
    /// at most 2,000 times a second whatever the rate and leaves the CPU to the router
    /// (on this VM a wake-up per datagram costs more than the datagram): for throughput.
    Lazy,
    /// One thread for all sinks, which reads every socket without blocking until it is
    /// empty, then sleeps [`SWEEP_POLL`]: for many sinks (the TCP fan-out), whose
    /// threads would otherwise take the CPU from the router. No heartbeats.
    Sweep,
}

/// Sleep of a [`Reading::Lazy`] sink between reads; its 8 MB receive buffer holds
/// about 10 ms at 1M frames/s.
const LAZY_POLL: Duration = Duration::from_micros(500);
/// Sleep of the [`Reading::Sweep`] thread between sweeps.
const SWEEP_POLL: Duration = Duration::from_millis(2);
/// Largest read from a TCP sink's stream.
const STREAM_READ: usize = sys::BATCH * DGRAM_MAX;

/// Receives until `stop` is set (checked at least every read timeout).
fn sink(job: SinkJob<'_>) -> SinkReport {
    let mut tally = Tally::new(job.seq_start);
    let mut bufs = Box::new([[0u8; DGRAM_MAX]; sys::BATCH]);
    let mut lens = [0usize; sys::BATCH];
    let mut froms = [SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0); sys::BATCH];
    let hb = job.announce.map(|(_, sys_id)| heartbeat(sys_id));
    let mut next_hb = Instant::now() + Duration::from_secs(1);
    while !job.stop.load(Ordering::Relaxed) {
        if let (Some((router, _)), Some(hb)) = (job.announce, &hb)
            && Instant::now() >= next_hb
        {
            let _ = job.sock.announce(hb, router);
            next_hb += Duration::from_secs(1);
        }
        // (pieces read, whether the read filled what was offered)
        let got = match job.sock {
            Sock::Udp(s) => {
                sys::recv_batch(s, &mut bufs, &mut lens, &mut froms).map(|n| (n, n == sys::BATCH))
            }
            Sock::Tcp(_) => job.sock.recv(bufs.as_flattened_mut()).map(|n| {
                lens[0] = n;
                (1, n == STREAM_READ)
            }),
        };
        let (n, full) = match got {
            Ok(got) => got,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => (0, false),
            Err(e) if e.kind() == ErrorKind::Interrupted => (0, false),
            Err(_) => {
                tally.report.errors += 1;
                thread::sleep(Duration::from_millis(1));
                (0, false)
            }
        };
        let now = ns_since(job.base);
        if job.sock.is_stream() {
            if n == 1 {
                tally.feed(&bufs.as_flattened()[..lens[0]], now, false);
            }
        } else {
            for (buf, &len) in bufs.iter().zip(&lens[..n]) {
                tally.feed(&buf[..len], now, true);
            }
        }
        job.progress.store(tally.report.distinct, Ordering::Relaxed);
        if job.reading == Reading::Lazy && !full {
            thread::sleep(LAZY_POLL);
        }
    }
    tally.finish()
}

/// [`Reading::Sweep`]: reads every one of `socks` (non-blocking) until it is empty,
/// sleeps [`SWEEP_POLL`], again until `stop` is set.
fn sweep(
    socks: &[Sock],
    seq_start: u32,
    base: Instant,
    stop: &AtomicBool,
    progress: &[AtomicU64],
) -> Vec<SinkReport> {
    let mut tallies: Vec<Tally> = socks.iter().map(|_| Tally::new(seq_start)).collect();
    let mut buf = vec![0u8; STREAM_READ];
    while !stop.load(Ordering::Relaxed) {
        for ((sock, tally), progress) in socks.iter().zip(&mut tallies).zip(progress) {
            loop {
                match sock.recv(&mut buf) {
                    Ok(n) => {
                        let now = ns_since(base);
                        tally.feed(&buf[..n], now, !sock.is_stream());
                        if sock.is_stream() && n < buf.len() {
                            break;
                        }
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(_) => {
                        tally.report.errors += 1;
                        break;
                    }
                }
            }
            progress.store(tally.report.distinct, Ordering::Relaxed);
        }
        thread::sleep(SWEEP_POLL);
    }
    tallies.into_iter().map(Tally::finish).collect()
}

// ---------------------------------------------------------------------------------------
// The router under test

/// A forwarding process under test, killed on drop: `mavtables` with a generated
/// configuration, or the minimal relay ([`relay_serve`]).
struct Forwarder {
    child: Child,
    /// Its UDP port.
    addr: SocketAddrV4,
    /// Its TCP server, if it has one.
    tcp_addr: Option<SocketAddrV4>,
    dir: PathBuf,
}

impl Forwarder {
    /// Starts the mavtables binary `exe` (router mode) or this benchmark's minimal relay
    /// (the other modes) on a free port of 127.0.0.1, output to a log file in a temp dir.
    /// With `tcp` the router also has a TCP server (`tcp { port P; address 127.0.0.1; }`)
    /// on another free port.
    fn start(exe: &Path, mode: Mode, tcp: bool) -> Result<Forwarder, String> {
        let port = free_port().map_err(|e| format!("no free port: {e}"))?;
        let tcp_port = if tcp && mode == Mode::Router {
            let l = TcpListener::bind("127.0.0.1:0").map_err(|e| format!("no free port: {e}"))?;
            Some(l.local_addr().map_err(|e| e.to_string())?.port())
        } else {
            None
        };
        let dir =
            std::env::temp_dir().join(format!("mavtables-bench-{}-{port}", std::process::id()));
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let command = if mode != Mode::Router {
            let me = std::env::current_exe().map_err(|e| format!("own path: {e}"))?;
            let mut c = Command::new(me);
            c.arg(RELAY_ARG).arg(port.to_string());
            if mode == Mode::ReceiveOnly {
                c.arg(RECEIVE_ONLY_ARG);
            }
            c
        } else {
            let config = dir.join("router.conf");
            let tcp_block = tcp_port.map_or(String::new(), |p| {
                format!("tcp {{\n    port {p};\n    address 127.0.0.1;\n}}\n")
            });
            let text = format!(
                "udp {{\n    port {port};\n    address 127.0.0.1;\n}}\n{tcp_block}\
                 default_action accept;\nchain default {{\n    accept;\n}}\n"
            );
            std::fs::write(&config, text).map_err(|e| format!("{}: {e}", config.display()))?;
            let mut c = Command::new(exe);
            c.arg("--config").arg(&config);
            c
        };
        let child = light::spawn_logged(command, &dir.join("router.log"), "the forwarder")?;
        Ok(Forwarder {
            child,
            addr: SocketAddrV4::new(Ipv4Addr::LOCALHOST, port),
            tcp_addr: tcp_port.map(|p| SocketAddrV4::new(Ipv4Addr::LOCALHOST, p)),
            dir,
        })
    }

    /// `None` while running, else why it stopped and the last line it printed.
    fn exited(&mut self) -> Option<String> {
        let status = self.child.try_wait().ok()??;
        let log = std::fs::read_to_string(self.dir.join("router.log")).unwrap_or_default();
        let last = log.lines().last().unwrap_or("(no output)").to_string();
        Some(format!("router exited ({status}): {last}"))
    }

    /// Makes every sink known to the router and waits (at most 5 s) until a frame from
    /// the generator (over `gen_tcp` if given, else a datagram from `gen_sock`) reaches
    /// each of them. A TCP sink announces itself once, a UDP sink every 100 ms.
    fn handshake(
        &mut self,
        gen_sock: &UdpSocket,
        gen_tcp: Option<&TcpStream>,
        sinks: &[Sock],
    ) -> Result<(), String> {
        let start = Instant::now();
        let mut reached = vec![false; sinks.len()];
        let mut parsers: Vec<Parser> = sinks.iter().map(|_| Parser::new()).collect();
        let mut probe = Vec::new();
        encode_probe(0, 0, &mut probe);
        let mut buf = vec![0u8; STREAM_READ];
        for s in sinks {
            s.set_nonblocking(true).map_err(|e| format!("sink: {e}"))?;
        }
        let mut first = true;
        while start.elapsed() < Duration::from_secs(5) {
            if let Some(why) = self.exited() {
                return Err(why);
            }
            for (i, s) in sinks.iter().enumerate() {
                if first || !s.is_stream() {
                    let _ = s.announce(&heartbeat(SINK_SYSTEM + i as u8), self.addr);
                }
            }
            first = false;
            thread::sleep(Duration::from_millis(20));
            match gen_tcp {
                Some(stream) => {
                    write_stream(stream, &probe, Instant::now() + Duration::from_secs(1));
                }
                None => {
                    let _ = gen_sock.send_to(&probe, self.addr);
                }
            }
            thread::sleep(Duration::from_millis(80));
            for ((s, ok), parser) in sinks.iter().zip(&mut reached).zip(&mut parsers) {
                while let Ok(n) = s.recv(&mut buf) {
                    parser.feed(&buf[..n], |f| *ok |= decode_probe(&f).is_some());
                    if !s.is_stream() {
                        parser.clear();
                    }
                }
            }
            if reached.iter().all(|&r| r) {
                for s in sinks {
                    s.set_nonblocking(false).map_err(|e| format!("sink: {e}"))?;
                }
                return Ok(());
            }
        }
        Err(match self.exited() {
            Some(why) => why,
            None => format!(
                "no frame forwarded to {} of {} sinks within 5 s",
                reached.iter().filter(|&&r| !r).count(),
                sinks.len()
            ),
        })
    }

    /// CPU time the forwarder has used so far, to the nanosecond: the scheduler's
    /// run time of each of its threads (`/proc/<pid>/task/*/schedstat`), where
    /// `/proc/<pid>/stat` counts in 10 ms ticks.
    fn cpu(&self) -> Option<Duration> {
        light::schedstat_cpu(self.child.id())
    }

    /// Peak resident set size (`VmHWM`), KiB.
    fn peak_rss_kib(&self) -> Option<u64> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).ok()?;
        let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
        line.split_whitespace().nth(1)?.parse().ok()
    }
}

impl Drop for Forwarder {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// User + system CPU time of process `pid` from `/proc/<pid>/stat`.
fn cpu_time(pid: u32) -> Option<Duration> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which may contain spaces) start at field 3.
    let rest = &stat[stat.rfind(')')? + 2..];
    let mut f = rest.split_whitespace().skip(11);
    let ticks: u64 = f.next()?.parse::<u64>().ok()? + f.next()?.parse::<u64>().ok()?;
    Some(Duration::from_secs_f64(
        ticks as f64 / sys::clock_ticks() as f64,
    ))
}

/// A UDP port of 127.0.0.1 that was free a moment ago.
fn free_port() -> io::Result<u16> {
    Ok(UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// Argument with which this benchmark runs as the minimal relay (`RELAY_ARG PORT`), or
/// as a process that only receives (`RELAY_ARG PORT RECEIVE_ONLY_ARG`).
const RELAY_ARG: &str = "--relay-serve";
const RECEIVE_ONLY_ARG: &str = "--receive-only";
/// Most peers the minimal relay remembers.
const RELAY_PEERS: usize = 16;

/// The minimal relay: the least work any UDP router must do, as a yardstick for
/// `mavtables` in the same run. Blocks in `recvmmsg` (no `epoll`), learns every sender
/// as a peer and sends each datagram, unparsed, to every other peer with `sendmmsg`,
/// one datagram each (no GSO); with `receive_only` it sends nothing, which is the least
/// CPU any router spends per received frame. Runs until killed.
fn relay_serve(port: u16, receive_only: bool) -> io::Result<()> {
    let sock = UdpSocket::bind(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port))?;
    let _ = sys::set_recv_buffer(&sock, 4 << 20);
    let mut bufs = Box::new([[0u8; DGRAM_MAX]; sys::BATCH]);
    let mut lens = [0usize; sys::BATCH];
    let mut froms = [SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0); sys::BATCH];
    let mut peers: Vec<SocketAddrV4> = Vec::new();
    loop {
        let n = match sys::recv_batch(&sock, &mut bufs, &mut lens, &mut froms) {
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if receive_only {
            continue;
        }
        for from in &froms[..n] {
            if !peers.contains(from) && peers.len() < RELAY_PEERS {
                peers.push(*from);
            }
        }
        let msgs: Vec<(&[u8], SocketAddrV4)> = bufs
            .iter()
            .zip(&lens[..n])
            .zip(&froms[..n])
            .flat_map(|((buf, &len), from)| {
                peers
                    .iter()
                    .filter(move |p| *p != from)
                    .map(move |&p| (&buf[..len], p))
            })
            .collect();
        send_all(&sock, &msgs, SendMode::Batched);
    }
}

// ---------------------------------------------------------------------------------------
// Trials

/// Where the generator sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Straight to the sinks: one hop, the machine's ceiling.
    Direct,
    /// Through the minimal relay ([`relay_serve`]): the least any router adds.
    Relay,
    /// To a process that only receives ([`relay_serve`] without sending), with no
    /// sinks: for the least CPU per received frame.
    ReceiveOnly,
    /// Through `mavtables`.
    Router,
}

/// A transport between the benchmark and the router.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Transport {
    Udp,
    Tcp,
}

/// How the generator and the sinks reach the router (router mode): over its UDP port,
/// or as clients of its TCP server, where every connection is a link of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Legs {
    generator: Transport,
    sinks: Transport,
}

impl Legs {
    const UDP: Legs = Legs {
        generator: Transport::Udp,
        sinks: Transport::Udp,
    };

    fn uses_tcp(self) -> bool {
        self.generator == Transport::Tcp || self.sinks == Transport::Tcp
    }

    /// `TCP→UDP` and the like.
    fn name(self) -> String {
        format!("{:?}→{:?}", self.generator, self.sinks).to_uppercase()
    }
}

/// Connects to the router's TCP server (retrying for up to 5 s while it starts), with
/// `TCP_NODELAY` (else Nagle's algorithm would hold back each frame written while the
/// previous one is unacknowledged) and 20 ms / 100 ms read / write timeouts.
fn connect(router: &mut Forwarder) -> Result<TcpStream, String> {
    let to = router.tcp_addr.ok_or("the router has no TCP server")?;
    let start = Instant::now();
    let stream = loop {
        match TcpStream::connect(to) {
            Ok(s) => break s,
            Err(e) if start.elapsed() > Duration::from_secs(5) => {
                return Err(router.exited().unwrap_or(format!("connect to {to}: {e}")));
            }
            Err(_) => thread::sleep(Duration::from_millis(20)),
        }
    };
    let io = |e: io::Error| format!("TCP socket: {e}");
    stream.set_nodelay(true).map_err(io)?;
    stream
        .set_read_timeout(Some(Duration::from_millis(20)))
        .map_err(io)?;
    stream
        .set_write_timeout(Some(Duration::from_millis(100)))
        .map_err(io)?;
    Ok(stream)
}

/// The sockets (and router) of one mode and number of receivers, reused by its trials.
struct Setup {
    gen_sock: UdpSocket,
    /// The generator's connection, when it writes to the router's TCP server.
    gen_tcp: Option<TcpStream>,
    sinks: Vec<Sock>,
    dests: Vec<SocketAddrV4>,
    router: Option<Forwarder>,
    next_seq: u32,
    base: Instant,
}

/// The outcome of one trial.
#[derive(Debug)]
struct Trial {
    rate: Option<f64>,
    generator: GenReport,
    sinks: Vec<SinkReport>,
    /// CPU time of the router (router mode) during the trial.
    router_cpu: Option<Duration>,
    /// CPU time of this process (generator + sinks) during the trial.
    harness_cpu: Option<Duration>,
}

impl Trial {
    /// Frames that did not reach a sink, summed over sinks.
    fn lost(&self) -> u64 {
        self.sinks
            .iter()
            .map(|s| self.generator.sent.saturating_sub(s.distinct))
            .sum()
    }

    /// Frames per second actually sent.
    fn achieved(&self) -> f64 {
        self.generator.sent as f64 / self.generator.elapsed.as_secs_f64().max(1e-9)
    }

    /// The generator kept up with the target rate (within 5%).
    fn on_rate(&self) -> bool {
        self.rate.is_none_or(|r| self.achieved() >= 0.95 * r)
    }

    fn zero_loss(&self) -> bool {
        self.lost() == 0 && self.generator.errors == 0
    }

    fn loss_percent(&self) -> f64 {
        100.0 * self.lost() as f64 / (self.generator.sent * self.sinks.len() as u64).max(1) as f64
    }

    /// Latency quantiles (ns) over all sinks' frames.
    fn latency(&self, qs: &[f64]) -> Vec<u32> {
        let mut all: Vec<u32> = self
            .sinks
            .iter()
            .flat_map(|s| &s.latencies)
            .copied()
            .collect();
        all.sort_unstable();
        qs.iter().map(|&q| quantile(&all, q)).collect()
    }

    fn sink_errors(&self) -> u64 {
        self.sinks.iter().map(|s| s.errors + s.rejected).sum()
    }
}

/// The `q` quantile (nearest rank) of sorted `v`; 0 for an empty slice.
fn quantile(v: &[u32], q: f64) -> u32 {
    if v.is_empty() {
        return 0;
    }
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

impl Setup {
    /// Binds the generator and `receivers` sinks; in router mode also starts the router
    /// and waits until it forwards to every sink.
    fn new(mode: Mode, receivers: usize, exe: Option<&Path>) -> Result<Setup, String> {
        Setup::open(mode, Legs::UDP, receivers, exe)
    }

    /// As [`Setup::new`], with the generator and the sinks on the router's UDP port or
    /// TCP server as `legs` say (router mode only).
    fn open(mode: Mode, legs: Legs, receivers: usize, exe: Option<&Path>) -> Result<Setup, String> {
        if legs.uses_tcp() && mode != Mode::Router {
            return Err("TCP only in router mode".into());
        }
        let io = |e: io::Error| format!("socket: {e}");
        let gen_sock = UdpSocket::bind("127.0.0.1:0").map_err(io)?;
        gen_sock
            .set_write_timeout(Some(Duration::from_millis(100)))
            .map_err(io)?;
        let mut sinks = Vec::new();
        // TCP sinks connect once the router is up.
        for _ in 0..if legs.sinks == Transport::Udp {
            receivers
        } else {
            0
        } {
            let s = UdpSocket::bind("127.0.0.1:0").map_err(io)?;
            s.set_read_timeout(Some(Duration::from_millis(20)))
                .map_err(io)?;
            // Large enough that the sink is never what drops frames; best effort.
            let _ = sys::set_recv_buffer(&s, 4 << 20);
            sinks.push(Sock::Udp(s));
        }
        let mut router = None;
        let mut gen_tcp = None;
        let dests = match mode {
            Mode::Direct => sinks
                .iter()
                .map(|s| match s {
                    Sock::Udp(s) => match s.local_addr() {
                        Ok(SocketAddr::V4(a)) => Ok(a),
                        other => Err(format!("sink address: {other:?}")),
                    },
                    Sock::Tcp(_) => Err("no TCP sinks in direct mode".into()),
                })
                .collect::<Result<Vec<_>, _>>()?,
            Mode::Relay | Mode::Router | Mode::ReceiveOnly => {
                let exe = exe.ok_or("no router binary")?;
                let mut r = Forwarder::start(exe, mode, legs.uses_tcp())?;
                if legs.sinks == Transport::Tcp {
                    for _ in 0..receivers {
                        sinks.push(Sock::Tcp(connect(&mut r)?));
                    }
                }
                if legs.generator == Transport::Tcp {
                    gen_tcp = Some(connect(&mut r)?);
                }
                if mode == Mode::ReceiveOnly {
                    // Nothing to wait for but the socket.
                    thread::sleep(Duration::from_millis(100));
                } else {
                    r.handshake(&gen_sock, gen_tcp.as_ref(), &sinks)?;
                }
                let addr = r.addr;
                router = Some(r);
                vec![addr]
            }
        };
        Ok(Setup {
            gen_sock,
            gen_tcp,
            sinks,
            dests,
            router,
            next_seq: 1,
            base: Instant::now(),
        })
    }

    /// Runs the generator on this thread and the sinks on their own, then waits for the
    /// sinks to drain (until they have everything, or 150 ms without progress, or 2 s).
    fn trial(
        &mut self,
        rate: Option<f64>,
        duration: Duration,
        send: SendMode,
        reading: Reading,
    ) -> Trial {
        let seq_start = self.next_seq;
        let stop = AtomicBool::new(false);
        let progress: Vec<AtomicU64> = self.sinks.iter().map(|_| AtomicU64::new(0)).collect();
        let announce = self.router.as_ref().map(|r| r.addr);
        let router_before = self.router.as_ref().and_then(Forwarder::cpu);
        let self_before = cpu_time(std::process::id());
        for sink in &self.sinks {
            let _ = sink.set_nonblocking(reading == Reading::Sweep);
        }
        let (generator, sinks) = thread::scope(|s| {
            let sweeper = (reading == Reading::Sweep).then(|| {
                let (socks, stop, progress) = (&self.sinks, &stop, &progress);
                let base = self.base;
                s.spawn(move || sweep(socks, seq_start, base, stop, progress))
            });
            let handles: Vec<_> = self
                .sinks
                .iter()
                .zip(&progress)
                .enumerate()
                .filter(|_| reading != Reading::Sweep)
                .map(|(i, (sock, progress))| {
                    let job = SinkJob {
                        sock,
                        seq_start,
                        base: self.base,
                        stop: &stop,
                        progress,
                        announce: announce.map(|a| (a, SINK_SYSTEM + i as u8)),
                        reading,
                    };
                    s.spawn(move || sink(job))
                })
                .collect();
            let generator = generate(
                &self.gen_sock,
                &self.dests,
                self.gen_tcp.as_ref(),
                rate,
                duration,
                seq_start,
                send,
                self.base,
            );
            let drain_start = Instant::now();
            let mut last = (Instant::now(), 0u64);
            while drain_start.elapsed() < Duration::from_secs(2) {
                let got: u64 = progress.iter().map(|p| p.load(Ordering::Relaxed)).sum();
                if got >= generator.sent * progress.len() as u64
                    || last.0.elapsed() > Duration::from_millis(150)
                {
                    break;
                }
                if got != last.1 {
                    last = (Instant::now(), got);
                }
                thread::sleep(Duration::from_millis(5));
            }
            stop.store(true, Ordering::Relaxed);
            let mut sinks: Vec<SinkReport> = handles
                .into_iter()
                .map(|h| h.join().unwrap_or_default())
                .collect();
            if let Some(h) = sweeper {
                sinks = h.join().unwrap_or_default();
            }
            (generator, sinks)
        });
        self.next_seq = seq_start + generator.sent as u32 + 1;
        let diff = |a: Option<Duration>, b: Option<Duration>| Some(b?.saturating_sub(a?));
        Trial {
            rate,
            generator,
            sinks,
            router_cpu: diff(router_before, self.router.as_ref().and_then(Forwarder::cpu)),
            harness_cpu: diff(self_before, cpu_time(std::process::id())),
        }
    }
}

// ---------------------------------------------------------------------------------------
// The measurement plan

/// Durations of one run.
struct Plan {
    step: Duration,
    latency_rounds: usize,
    latency_step: Duration,
    cpu_step: Duration,
    /// Interleaved rounds of the TCP latency and fan-out runs.
    tcp_rounds: usize,
    /// One round of the TCP fan-out.
    fanout_step: Duration,
}

/// Figures of one mode and number of receivers.
#[derive(Default)]
struct Row {
    /// Why the mode could not be measured.
    unavailable: Option<String>,
    /// Highest rate of the ladder with zero loss.
    zero_loss: Option<f64>,
    /// Why the ladder stopped: loss (rate, loss %), the generator, or the end.
    stop: String,
    /// Forwarder (relay and router modes) and harness CPU per frame sent, µs.
    router_cpu_us: Option<f64>,
    harness_cpu_us: Option<f64>,
    /// Median p50, p99, p99.9 latency, µs.
    latency_us: Option<[f64; 3]>,
    /// Frames lost during the latency rounds.
    latency_loss: u64,
    /// Forwarder's peak RSS after the normal runs, KiB.
    rss_kib: Option<u64>,
    /// What 10× overload did (rate reached, loss, peak RSS).
    overload: Option<String>,
}

fn fmt_rate(r: f64) -> String {
    if r >= 1e6 {
        format!("{:.2}M", r / 1e6)
    } else {
        format!("{:.0}k", r / 1e3)
    }
}

fn per_frame_us(cpu: Option<Duration>, frames: u64) -> Option<f64> {
    Some(cpu?.as_secs_f64() * 1e6 / frames.max(1) as f64)
}

/// Climbs [`LADDER`] until a step loses frames twice or the generator falls behind its
/// rate by more than 5% (for a TCP generator, also because the router does not read
/// fast enough), printing a line per step; sets `row.zero_loss` and `row.stop`. Returns
/// the forwarder's CPU per frame (µs) at each zero-loss step.
fn ladder(setup: &mut Setup, label: &str, plan: &Plan, row: &mut Row) -> Vec<(f64, Option<f64>)> {
    let mut cpu_at = Vec::new();
    // Highest rate with zero loss: a step with loss is tried once more (noisy machine).
    row.stop = "end of ladder".into();
    for &rate in &LADDER {
        let mut t = setup.trial(Some(rate), plan.step, SendMode::Batched, Reading::Lazy);
        if !t.zero_loss() && t.on_rate() {
            t = setup.trial(Some(rate), plan.step, SendMode::Batched, Reading::Lazy);
        }
        let cpu = per_frame_us(t.router_cpu, t.generator.sent).map_or(String::new(), |us| {
            format!(", forwarder CPU/frame {us:.2} µs")
        });
        println!(
            "  {label:<10} {:>6}/s: sent {:>8} at {:>6}/s, lost {:>7} ({:.3}%), send errors {}, sink errors {}{cpu}",
            fmt_rate(rate),
            t.generator.sent,
            fmt_rate(t.achieved()),
            t.lost(),
            t.loss_percent(),
            t.generator.errors,
            t.sink_errors()
        );
        if !t.on_rate() {
            let writes = if setup.gen_tcp.is_some() {
                format!(
                    ", {:.0}% of the time in write",
                    100.0 * t.generator.in_write.as_secs_f64()
                        / t.generator.elapsed.as_secs_f64().max(1e-9)
                )
            } else {
                String::new()
            };
            row.stop = format!(
                "{}/s not reached: generator at most {}/s{writes}",
                fmt_rate(rate),
                fmt_rate(t.achieved())
            );
            break;
        }
        if !t.zero_loss() {
            row.stop = format!("loss at {}/s ({:.2}%)", fmt_rate(rate), t.loss_percent());
            break;
        }
        row.zero_loss = Some(rate);
        cpu_at.push((rate, per_frame_us(t.router_cpu, t.generator.sent)));
    }
    cpu_at
}

/// Measures one mode with `receivers` sinks, printing progress as it goes.
fn measure(mode: Mode, receivers: usize, exe: Option<&Path>, plan: &Plan) -> Row {
    let mut row = Row::default();
    let mut setup = match Setup::new(mode, receivers, exe) {
        Ok(s) => s,
        Err(why) => {
            row.unavailable = Some(why);
            return row;
        }
    };
    let label = format!("{mode:?} x{receivers}").to_lowercase();
    ladder(&mut setup, &label, plan, &mut row);
    if let Some(why) = setup.router.as_mut().and_then(Forwarder::exited) {
        row.stop = format!("{} — then {why}", row.stop);
        return row;
    }
    // CPU per frame at a fixed rate.
    let t = setup.trial(
        Some(CPU_RATE),
        plan.cpu_step,
        SendMode::Batched,
        Reading::Lazy,
    );
    row.router_cpu_us = per_frame_us(t.router_cpu, t.generator.sent);
    row.harness_cpu_us = per_frame_us(t.harness_cpu, t.generator.sent);
    // Latency at 10k frames/s, medians over rounds.
    let mut qs = [vec![], vec![], vec![]];
    for _ in 0..plan.latency_rounds {
        let t = setup.trial(
            Some(LATENCY_RATE),
            plan.latency_step,
            SendMode::Batched,
            Reading::Eager,
        );
        row.latency_loss += t.lost();
        for (v, q) in qs.iter_mut().zip(t.latency(&[0.5, 0.99, 0.999])) {
            v.push(q as f64 / 1e3);
        }
    }
    row.latency_us = Some(qs.map(median));
    // Peak RSS of the router, then under 10x overload.
    if let Some(router) = &setup.router {
        row.rss_kib = router.peak_rss_kib();
        let rate = 10.0 * row.zero_loss.unwrap_or(LADDER[0]);
        let t = setup.trial(Some(rate), plan.step, SendMode::Batched, Reading::Lazy);
        let rss = setup.router.as_ref().and_then(Forwarder::peak_rss_kib);
        row.overload = Some(format!(
            "{}/s sent ({} target): {:.1}% lost, peak RSS {} KiB",
            fmt_rate(t.achieved()),
            fmt_rate(rate),
            t.loss_percent(),
            rss.map_or("?".into(), |k| k.to_string())
        ));
        if let Some(why) = setup.router.as_mut().and_then(Forwarder::exited) {
            row.overload = Some(format!("{} — then {why}", row.overload.unwrap()));
        }
    }
    row
}

/// `--latency`: only the latency rounds at 10k frames/s, direct and router mode
/// interleaved (1 receiver), 5 rounds each: for working on the latency path.
fn latency_only(exe: &Path, plan: &Plan) {
    let mut setups = Vec::new();
    for mode in [Mode::Direct, Mode::Relay, Mode::Router] {
        match Setup::new(mode, 1, Some(exe)) {
            Ok(s) => setups.push((mode, s)),
            Err(why) => println!("  {mode:?}: unavailable: {why}"),
        }
    }
    let mut qs: Vec<[Vec<f64>; 3]> = setups.iter().map(|_| [vec![], vec![], vec![]]).collect();
    for _ in 0..5 {
        for ((mode, setup), q) in setups.iter_mut().zip(&mut qs) {
            let t = setup.trial(
                Some(LATENCY_RATE),
                plan.latency_step,
                SendMode::Batched,
                Reading::Eager,
            );
            let l = t.latency(&[0.5, 0.99, 0.999]);
            let cpu = per_frame_us(t.router_cpu, t.generator.sent).map_or(String::new(), |us| {
                format!(", forwarder CPU/frame {us:.2} µs")
            });
            println!(
                "  {:<7} p50 {:>5} p99 {:>6} p99.9 {:>6} ns, lost {}{cpu}",
                format!("{mode:?}").to_lowercase(),
                l[0],
                l[1],
                l[2],
                t.lost()
            );
            for (v, x) in q.iter_mut().zip(l) {
                v.push(x as f64 / 1e3);
            }
        }
    }
    for ((mode, _), q) in setups.iter().zip(qs) {
        let [a, b, c] = q.map(median);
        println!(
            "{:<7} median of rounds: p50 {a:.0} / p99 {b:.0} / p99.9 {c:.0} µs",
            format!("{mode:?}").to_lowercase()
        );
    }
}

/// The three ways through the router that `--tcp` compares, 1 receiver each.
const TCP_LEGS: [Legs; 3] = [
    Legs::UDP,
    Legs {
        generator: Transport::Tcp,
        sinks: Transport::Tcp,
    },
    Legs {
        generator: Transport::Tcp,
        sinks: Transport::Udp,
    },
];
/// One latency round of one path.
struct LatencyRound {
    /// p50, p99, p99.9, µs.
    q_us: [f64; 3],
    /// The router's CPU per frame, µs.
    cpu_us: Option<f64>,
    lost: u64,
}

/// Most a TCP path's p50 latency may exceed UDP→UDP's (the target).
const TCP_P50_TARGET: f64 = 1.2;

/// `--tcp` (also part of the full run): UDP→UDP, TCP→TCP and TCP→UDP through a router
/// each (UDP port and TCP server, 1 receiver): the ladder of each, one after the other,
/// then `plan.tcp_rounds` interleaved latency rounds at 10k frames/s, and each TCP path's
/// p50 ÷ UDP→UDP's p50 of the same round. Prints a Markdown table. Without `ladders`
/// (`--tcp --latency`) only the latency rounds.
fn tcp_paths(exe: &Path, plan: &Plan, ladders: bool, out: &mut impl Write) -> io::Result<()> {
    let mut setups = Vec::new();
    for legs in TCP_LEGS {
        match Setup::open(Mode::Router, legs, 1, Some(exe)) {
            Ok(s) => setups.push((legs, s, Row::default())),
            Err(why) => println!("  {}: unavailable: {why}", legs.name()),
        }
    }
    let mut cpu_50k = Vec::new();
    for (legs, setup, row) in setups.iter_mut().filter(|_| ladders) {
        let steps = ladder(setup, &legs.name(), plan, row);
        cpu_50k.push(steps.iter().find(|s| s.0 == CPU_RATE).and_then(|s| s.1));
    }
    // Per setup: p50, p99, p99.9 (µs), router CPU/frame (µs) and loss of each round.
    let mut rounds: Vec<Vec<LatencyRound>> = setups.iter().map(|_| vec![]).collect();
    for _ in 0..plan.tcp_rounds {
        for ((legs, setup, _), r) in setups.iter_mut().zip(&mut rounds) {
            let t = setup.trial(
                Some(LATENCY_RATE),
                plan.latency_step,
                SendMode::Batched,
                Reading::Eager,
            );
            let l = t.latency(&[0.5, 0.99, 0.999]);
            let cpu = per_frame_us(t.router_cpu, t.generator.sent);
            println!(
                "  {:<8} @{}: p50 {:>5} p99 {:>6} p99.9 {:>7} ns, lost {}, router CPU/frame {} µs",
                legs.name(),
                fmt_rate(LATENCY_RATE),
                l[0],
                l[1],
                l[2],
                t.lost(),
                cpu.map_or("?".into(), |c| format!("{c:.2}")),
            );
            r.push(LatencyRound {
                q_us: [l[0], l[1], l[2]].map(|x| x as f64 / 1e3),
                cpu_us: cpu,
                lost: t.lost(),
            });
        }
    }
    let udp = setups.iter().position(|(l, ..)| *l == Legs::UDP);
    writeln!(
        out,
        "\n| path | highest zero-loss rate (then) | router CPU/frame @{} | latency p50 / p99 / p99.9 @{} | router CPU/frame @{} | p50 ÷ UDP→UDP p50 |",
        fmt_rate(CPU_RATE),
        fmt_rate(LATENCY_RATE),
        fmt_rate(LATENCY_RATE),
    )?;
    writeln!(out, "|---|---|---:|---|---:|---|")?;
    let mut verdicts = Vec::new();
    for (i, (legs, _, row)) in setups.iter().enumerate() {
        let r = &rounds[i];
        let q = |k: usize| median(r.iter().map(|x| x.q_us[k]).collect());
        let cpu = median(r.iter().filter_map(|x| x.cpu_us).collect());
        let lost: u64 = r.iter().map(|x| x.lost).sum();
        let ratio = match udp {
            Some(u) if u != i => {
                // Round by round: both measured within seconds of each other.
                let per_round: Vec<f64> = r
                    .iter()
                    .zip(&rounds[u])
                    .map(|(t, u)| t.q_us[0] / u.q_us[0])
                    .collect();
                let lo = per_round.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = per_round.iter().copied().fold(0.0, f64::max);
                let m = median(per_round);
                verdicts.push(format!(
                    "{} p50 is {m:.2}× UDP→UDP's ({}within {TCP_P50_TARGET}×)",
                    legs.name(),
                    if m <= TCP_P50_TARGET { "" } else { "not " }
                ));
                format!("{m:.2}× ({lo:.2}–{hi:.2}×)")
            }
            _ => "—".into(),
        };
        writeln!(
            out,
            "| {} | {} | {} | {:.0} / {:.0} / {:.0} µs{} | {} | {ratio} |",
            legs.name(),
            match (ladders, row.zero_loss) {
                (false, _) => "—".into(),
                (true, None) => format!("none ({})", row.stop),
                (true, Some(r)) => format!("{}/s ({})", fmt_rate(r), row.stop),
            },
            cpu_50k
                .get(i)
                .copied()
                .flatten()
                .map_or("—".into(), |c| format!("{c:.2} µs")),
            q(0),
            q(1),
            q(2),
            if lost > 0 {
                format!(" ({lost} lost)")
            } else {
                String::new()
            },
            if cpu.is_nan() {
                "—".into()
            } else {
                format!("{cpu:.2} µs")
            },
        )?;
    }
    writeln!(
        out,
        "\nlatency: medians of {} interleaved rounds of {:.1} s; ratio: median (range) of the rounds' ratios. {}",
        plan.tcp_rounds,
        plan.latency_step.as_secs_f64(),
        verdicts.join("; ")
    )
}

/// Clients of the router's TCP server in the `--tcp-fanout` run.
const FANOUT_CLIENTS: usize = 100;
/// Rate of the broadcast stream every fan-out client receives, frames/s.
const FANOUT_RATE: f64 = 1e3;

/// `--tcp-fanout` (also part of the full run): [`FANOUT_CLIENTS`] clients of the router's
/// TCP server, each announced with a HEARTBEAT, receive a broadcast stream of
/// [`FANOUT_RATE`] frames/s from a TCP generator (a client of the same server) and,
/// with another router, from a UDP generator; `plan.tcp_rounds` interleaved rounds.
/// One thread reads all clients ([`Reading::Sweep`]). Prints a Markdown table of the
/// router's CPU per delivered frame and the loss.
fn tcp_fanout(exe: &Path, plan: &Plan, out: &mut impl Write) -> io::Result<()> {
    let mut setups = Vec::new();
    for generator in [Transport::Tcp, Transport::Udp] {
        let legs = Legs {
            generator,
            sinks: Transport::Tcp,
        };
        match Setup::open(Mode::Router, legs, FANOUT_CLIENTS, Some(exe)) {
            Ok(s) => setups.push((legs, s, vec![], 0u64, 0u64)),
            Err(why) => println!("  fan-out {}: unavailable: {why}", legs.name()),
        }
    }
    for _ in 0..plan.tcp_rounds {
        for (legs, setup, cpu, lost, expected) in &mut setups {
            let t = setup.trial(
                Some(FANOUT_RATE),
                plan.fanout_step,
                SendMode::Batched,
                Reading::Sweep,
            );
            let delivered: u64 = t.sinks.iter().map(|s| s.distinct).sum();
            let us = per_frame_us(t.router_cpu, delivered);
            println!(
                "  fan-out {} x{FANOUT_CLIENTS} @{}/s: sent {}, delivered {delivered}, lost {} ({:.3}%), router CPU/delivered frame {} µs",
                legs.name(),
                fmt_rate(FANOUT_RATE),
                t.generator.sent,
                t.lost(),
                t.loss_percent(),
                us.map_or("?".into(), |c| format!("{c:.2}")),
            );
            cpu.extend(us);
            *lost += t.lost();
            *expected += t.generator.sent * FANOUT_CLIENTS as u64;
        }
    }
    writeln!(
        out,
        "\n| generator → {FANOUT_CLIENTS} TCP clients @{}/s each | router CPU per delivered frame (median; range) | frames lost |",
        fmt_rate(FANOUT_RATE)
    )?;
    writeln!(out, "|---|---:|---:|")?;
    for (legs, _, cpu, lost, expected) in &setups {
        let lo = cpu.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = cpu.iter().copied().fold(0.0, f64::max);
        writeln!(
            out,
            "| {:?} generator | {:.2} µs ({lo:.2}–{hi:.2}) | {lost} of {expected} |",
            legs.generator,
            median(cpu.clone()),
        )?;
    }
    writeln!(
        out,
        "\n{} interleaved rounds of {:.1} s each",
        plan.tcp_rounds,
        plan.fanout_step.as_secs_f64()
    )
}

/// `--cpu`: only the CPU per frame of the minimal relay and of the router at 50k
/// frames/s, 1 and 3 receivers, 7 interleaved rounds of 1 s each, then working off a
/// backlog (routers of other builds: `MAVTABLES_BENCH_ROUTER`).
fn cpu_only(exe: &Path) {
    for receivers in [1, 3] {
        let mut setups = Vec::new();
        let modes: &[Mode] = if receivers == 1 {
            &[Mode::ReceiveOnly, Mode::Relay, Mode::Router]
        } else {
            &[Mode::Relay, Mode::Router]
        };
        for &mode in modes {
            let receivers = if mode == Mode::ReceiveOnly {
                0
            } else {
                receivers
            };
            match Setup::new(mode, receivers, Some(exe)) {
                Ok(s) => setups.push((mode, s, Vec::new())),
                Err(why) => println!("  {mode:?} x{receivers}: unavailable: {why}"),
            }
        }
        for _ in 0..7 {
            for (_, setup, v) in &mut setups {
                let t = setup.trial(
                    Some(CPU_RATE),
                    Duration::from_secs(1),
                    SendMode::Batched,
                    Reading::Lazy,
                );
                if let Some(us) = per_frame_us(t.router_cpu, t.generator.sent) {
                    v.push(us);
                }
            }
        }
        for (mode, setup, v) in &mut setups {
            let name = match mode {
                Mode::ReceiveOnly => "receive-only".to_string(),
                _ => format!("{mode:?} x{receivers}").to_lowercase(),
            };
            let shown: Vec<String> = v.iter().map(|us| format!("{us:.2}")).collect();
            println!(
                "{name}: CPU/frame @{}: median {:.2} µs ({})",
                fmt_rate(CPU_RATE),
                median(std::mem::take(v)),
                shown.join(", ")
            );
            match backlog_cpu(setup, 30, 4000) {
                Ok((frames, us)) => println!(
                    "{name}: CPU/frame working off a backlog (full batches): {us:.2} µs over {frames} frames"
                ),
                Err(why) => println!("{name}: backlog run unavailable: {why}"),
            }
        }
    }
}

/// The router's CPU per frame when it works through a backlog, so that every receive
/// and send is a full batch: `rounds` times, the router is stopped (SIGSTOP), `per_round`
/// frames are queued in its socket, and it is let go (SIGCONT) for 100 ms, after which
/// every sink must have them all. Returns (frames forwarded, µs of router CPU per frame)
/// over all rounds.
fn backlog_cpu(setup: &mut Setup, rounds: usize, per_round: usize) -> Result<(u64, f64), String> {
    let router = setup.router.as_ref().ok_or("no router")?;
    let (pid, to) = (router.child.id(), router.addr);
    let mut buf = Vec::with_capacity(per_round * 24);
    let mut total = Duration::ZERO;
    let mut frames = 0u64;
    let mut dgram = [0u8; DGRAM_MAX];
    for _ in 0..rounds {
        sys::signal(pid, sys::Signal::SIGSTOP).map_err(|e| format!("SIGSTOP: {e}"))?;
        buf.clear();
        for i in 0..per_round {
            encode_probe(setup.next_seq + i as u32, 0, &mut buf);
        }
        setup.next_seq += per_round as u32;
        let msgs: Vec<(&[u8], SocketAddrV4)> =
            buf.chunks(buf.len() / per_round).map(|f| (f, to)).collect();
        send_all(&setup.gen_sock, &msgs, SendMode::Batched);
        let before = router.cpu().ok_or("no CPU time")?;
        sys::signal(pid, sys::Signal::SIGCONT).map_err(|e| format!("SIGCONT: {e}"))?;
        // Read only once the router is done: a sink blocked in `recv` would be woken for
        // every datagram, at the router's expense (about 1 µs each on this VM).
        thread::sleep(Duration::from_millis(100));
        for sink in &setup.sinks {
            let mut got = 0;
            let start = Instant::now();
            while got < per_round && start.elapsed() < Duration::from_secs(5) {
                if sink.recv(&mut dgram).is_ok() {
                    got += 1;
                }
            }
            if got < per_round {
                return Err(format!("a sink got {got} of {per_round} frames"));
            }
        }
        total += router.cpu().ok_or("no CPU time")?.saturating_sub(before);
        frames += per_round as u64;
    }
    Ok((frames, total.as_secs_f64() * 1e6 / frames as f64))
}

/// Unpaced sending for `duration` with each send mode, interleaved over `rounds`:
/// median frames/s sent and delivered (direct mode, 1 receiver).
fn batching_gain(rounds: usize, duration: Duration) -> Result<[(f64, f64); 2], String> {
    let mut setup = Setup::new(Mode::Direct, 1, None)?;
    let mut v = [(vec![], vec![]), (vec![], vec![])];
    for _ in 0..rounds {
        for (i, mode) in [SendMode::Batched, SendMode::OneByOne]
            .into_iter()
            .enumerate()
        {
            let t = setup.trial(None, duration, mode, Reading::Lazy);
            let secs = t.generator.elapsed.as_secs_f64();
            v[i].0.push(t.achieved());
            v[i].1.push(t.sinks[0].distinct as f64 / secs);
        }
    }
    Ok(v.map(|(s, d)| (median(s), median(d))))
}

fn print_row(out: &mut impl Write, mode: Mode, receivers: usize, row: &Row) -> io::Result<()> {
    let name = format!("{mode:?}").to_lowercase();
    if let Some(why) = &row.unavailable {
        return writeln!(
            out,
            "| {name} | {receivers} | {name} mode unavailable: {why} |"
        );
    }
    let us = |v: Option<f64>| v.map_or("—".into(), |v| format!("{v:.2} µs"));
    let lat = row.latency_us.map_or("—".into(), |[a, b, c]| {
        format!("{a:.0} / {b:.0} / {c:.0} µs")
    });
    writeln!(
        out,
        "| {name} | {receivers} | {} ({}) | {} | {} | {lat}{} | {} | {} |",
        row.zero_loss
            .map_or("none".into(), |r| format!("{}/s", fmt_rate(r))),
        row.stop,
        us(row.router_cpu_us),
        us(row.harness_cpu_us),
        if row.latency_loss > 0 {
            format!(" ({} lost)", row.latency_loss)
        } else {
            String::new()
        },
        row.rss_kib.map_or("—".into(), |k| format!("{k} KiB")),
        row.overload.as_deref().unwrap_or("—"),
    )
}

/// `cargo test`: a ~3 s check that the generator, sinks, accounting and relay work.
fn smoke() {
    // A TCP sink's accounting: frames cut anywhere between reads count once each.
    let mut stream = Vec::new();
    for seq in 1..=3 {
        encode_probe(seq, 0, &mut stream);
    }
    let mut tally = Tally::new(1);
    for piece in stream.chunks(7) {
        tally.feed(piece, 1, false);
    }
    let r = tally.finish();
    assert_eq!((r.distinct, r.rejected, r.other), (3, 0, 0), "stream tally");
    let mut setup = Setup::new(Mode::Direct, 1, None).expect("direct setup");
    let t = setup.trial(
        Some(20e3),
        Duration::from_secs(1),
        SendMode::Batched,
        Reading::Lazy,
    );
    let got = t.sinks[0].distinct;
    println!(
        "forwarding smoke: sent {} at {}/s, received {got}, lost {}, reordered {}",
        t.generator.sent,
        fmt_rate(t.achieved()),
        t.lost(),
        t.sinks[0].reordered,
    );
    assert!(
        t.generator.sent >= 19_000,
        "generator sent {}",
        t.generator.sent
    );
    assert!(
        got * 10 >= t.generator.sent * 9,
        "sink got {got} of {}",
        t.generator.sent
    );
    assert_eq!(t.sinks[0].rejected, 0, "sink rejected frames");
    assert_eq!(t.sinks[0].duplicates, 0);
    let t = setup.trial(
        None,
        Duration::from_millis(300),
        SendMode::OneByOne,
        Reading::Eager,
    );
    assert!(
        t.sinks[0].distinct > 0,
        "unpaced one-by-one run delivered nothing"
    );
    // The relay (the floor of the benchmark) forwards: it is this very binary.
    let mut relay = Setup::new(Mode::Relay, 1, Some(Path::new("unused"))).expect("relay setup");
    let t = relay.trial(
        Some(10e3),
        Duration::from_millis(500),
        SendMode::Batched,
        Reading::Lazy,
    );
    let got = t.sinks[0].distinct;
    println!("relay smoke: sent {}, received {got}", t.generator.sent);
    assert!(
        got * 10 >= t.generator.sent * 9,
        "relay delivered {got} of {}",
        t.generator.sent
    );
    assert!(
        relay.router.as_ref().and_then(Forwarder::cpu).is_some(),
        "no CPU time for the relay"
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let [_, flag, port, rest @ ..] = &args[..]
        && flag == RELAY_ARG
    {
        let receive_only = rest.iter().any(|a| a == RECEIVE_ONLY_ARG);
        let result = port
            .parse()
            .map_err(|e| format!("port {port}: {e}"))
            .and_then(|p| relay_serve(p, receive_only).map_err(|e| e.to_string()));
        if let Err(e) = result {
            eprintln!("relay: {e}");
            std::process::exit(1);
        }
        return;
    }
    if !args.iter().any(|a| a == "--bench") {
        smoke();
        return;
    }
    let quick = args.iter().any(|a| a == "--quick")
        || std::env::var_os("MAVTABLES_BENCH_QUICK").is_some_and(|v| v != "0");
    let plan = if quick {
        Plan {
            step: Duration::from_millis(500),
            latency_rounds: 1,
            latency_step: Duration::from_millis(500),
            cpu_step: Duration::from_millis(500),
            tcp_rounds: 1,
            fanout_step: Duration::from_millis(500),
        }
    } else {
        Plan {
            step: Duration::from_secs(2),
            latency_rounds: 3,
            latency_step: Duration::from_secs(1),
            cpu_step: Duration::from_secs(2),
            tcp_rounds: 5,
            fanout_step: Duration::from_secs(2),
        }
    };
    // Cargo sets this for benches; `MAVTABLES_BENCH_ROUTER` points at another build.
    let exe = std::env::var_os("MAVTABLES_BENCH_ROUTER")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_mavtables")));
    let started = Instant::now();
    println!(
        "UDP forwarding benchmark on 127.0.0.1, {} CPUs, {} steps{}",
        thread::available_parallelism().map_or(0, |n| n.get()),
        if quick { "0.5 s" } else { "2 s" },
        if quick { " (--quick)" } else { "" }
    );
    let tcp = args.iter().any(|a| a == "--tcp");
    let fanout = args.iter().any(|a| a == "--tcp-fanout");
    if tcp || fanout {
        let mut out = io::stdout().lock();
        if tcp {
            let ladders = !args.iter().any(|a| a == "--latency");
            let _ = tcp_paths(&exe, &plan, ladders, &mut out);
        }
        if fanout {
            let _ = tcp_fanout(&exe, &plan, &mut out);
        }
        let _ = writeln!(out, "total time {:.0} s", started.elapsed().as_secs_f64());
        return;
    }
    let gain = batching_gain(
        if quick { 1 } else { 3 },
        Duration::from_millis(if quick { 300 } else { 700 }),
    );
    if args.iter().any(|a| a == "--latency") {
        latency_only(&exe, &plan);
        return;
    }
    if args.iter().any(|a| a == "--cpu") {
        cpu_only(&exe);
        return;
    }
    let mut rows = Vec::new();
    for mode in [Mode::Direct, Mode::Relay, Mode::Router] {
        for receivers in [1, 3] {
            let row = measure(mode, receivers, Some(&exe), &plan);
            if let Some(why) = &row.unavailable {
                let mode = format!("{mode:?}").to_lowercase();
                println!("  {mode} x{receivers}: {mode} mode unavailable: {why}");
            }
            rows.push((mode, receivers, row));
        }
    }
    let mut out = io::stdout().lock();
    let _ = writeln!(
        out,
        "\n| mode | receivers | highest zero-loss rate (then) | forwarder CPU/frame @{} | harness CPU/frame | latency p50 / p99 / p99.9 @{} | forwarder peak RSS | 10x overload |",
        fmt_rate(CPU_RATE),
        fmt_rate(LATENCY_RATE)
    );
    let _ = writeln!(out, "|---|---:|---|---:|---:|---|---:|---|");
    for (mode, receivers, row) in &rows {
        let _ = print_row(&mut out, *mode, *receivers, row);
    }
    match gain {
        Ok([(bs, bd), (os, od)]) => {
            let _ = writeln!(
                out,
                "\nunpaced sending, direct x1: sendmmsg {}/s sent, {}/s delivered; \
                 send_to {}/s sent, {}/s delivered; batching gain {:.2}x sent",
                fmt_rate(bs),
                fmt_rate(bd),
                fmt_rate(os),
                fmt_rate(od),
                bs / os
            );
        }
        Err(why) => {
            let _ = writeln!(out, "\nunpaced sending: unavailable: {why}");
        }
    }
    let _ = writeln!(out, "\nTCP forwarding (`--tcp`, `--tcp-fanout`):");
    let _ = tcp_paths(&exe, &plan, true, &mut out);
    let _ = tcp_fanout(&exe, &plan, &mut out);
    let _ = writeln!(out, "total time {:.0} s", started.elapsed().as_secs_f64());
}
