//! Plain sockets of our own against the router: frames made with the crate's encoder,
//! frames read back with its parser, TCP connects that wait for the server, the router's
//! counters report parsed, and what `/proc` says about the router process. Every wait is
//! bounded and ends on an event.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use mavtables::wire::Parser;
use mavtables::wire::encode::{Header, encode_v2};

use super::router::Router;

pub const SECOND: Duration = Duration::from_secs(1);
pub const ACCEPT_ALL: &str = "default_action accept;\n";

/// A MAVLink 2 frame of message `id` from `sys.1` whose payload is `fill` repeated.
pub fn frame(id: u32, sys: u8, seq: u8, fill: u8, len: usize) -> Vec<u8> {
    with_payload(id, sys, seq, &vec![fill.max(1); len])
}

/// A MAVLink 2 frame of message `id` from `sys.1` with `payload` (trailing zeros are
/// cut, as MAVLink 2 does).
pub fn with_payload(id: u32, sys: u8, seq: u8, payload: &[u8]) -> Vec<u8> {
    let header = Header {
        seq,
        system: sys,
        component: 1,
    };
    let mut out = Vec::new();
    encode_v2(header, id, payload, None, &mut out).expect("encode");
    out
}

pub fn heartbeat(sys: u8) -> Vec<u8> {
    frame(0, sys, 0, 3, 9)
}

/// ATTITUDE number `n` from system `sys` (28 payload bytes, all `n + 1`).
pub fn attitude(sys: u8, n: u8) -> Vec<u8> {
    frame(30, sys, n, n.wrapping_add(1), 28)
}

/// ATTITUDE from `sys` that carries the counter `n` (its first four payload bytes, the
/// rest non-zero so every frame is 40 bytes long).
pub fn numbered(sys: u8, n: u32) -> Vec<u8> {
    let mut payload = [0x55u8; 28];
    payload[..4].copy_from_slice(&n.to_le_bytes());
    with_payload(30, sys, n as u8, &payload)
}

/// ENCAPSULATED_DATA (a 255-byte payload: 267-byte frames) from `sys` that carries the
/// counter `n` in its first four payload bytes.
pub fn numbered_large(sys: u8, n: u32) -> Vec<u8> {
    let mut payload = [0x55u8; 255];
    payload[..4].copy_from_slice(&n.to_le_bytes());
    with_payload(131, sys, n as u8, &payload)
}

/// The counter of a frame made by [`numbered`] or [`numbered_large`].
pub fn number_of(frame: &[u8]) -> u32 {
    let frame = mavtables::wire::Frame::parse_exact(frame).expect("a frame");
    u32::from_le_bytes(frame.payload()[..4].try_into().expect("a counter"))
}

/// Frames read from `read` until `want` frames arrived or `timeout` passed.
pub fn collect(
    mut read: impl FnMut(&mut [u8]) -> Option<usize>,
    want: usize,
    timeout: Duration,
) -> Vec<Vec<u8>> {
    let deadline = Instant::now() + timeout;
    let mut parser = Parser::new();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while got.len() < want && Instant::now() < deadline {
        if let Some(n) = read(&mut buf) {
            parser.feed(&buf[..n], |f| got.push(f.as_bytes().to_vec()));
        }
    }
    got
}

pub fn udp_frames(sock: &UdpSocket, want: usize, timeout: Duration) -> Vec<Vec<u8>> {
    sock.set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    collect(|b| sock.recv(b).ok(), want, timeout)
}

pub fn tcp_frames(stream: &mut TcpStream, want: usize, timeout: Duration) -> Vec<Vec<u8>> {
    stream
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    collect(|b| stream.read(b).ok().filter(|n| *n > 0), want, timeout)
}

/// A free TCP port below the kernel's ephemeral range, for a listener that another
/// process binds later (a Zenoh router or peer): a port from [`free_tcp_port`] may be
/// taken meanwhile by any outgoing connection's ephemeral port, one of these never is.
pub fn free_listen_port() -> u16 {
    use std::sync::atomic::{AtomicU16, Ordering};
    // Each test process starts at its own place in 20000..32000 and walks on from there.
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let _ = NEXT.compare_exchange(
        0,
        20_000 + (std::process::id() % 12_000) as u16,
        Ordering::Relaxed,
        Ordering::Relaxed,
    );
    loop {
        let port = NEXT.fetch_add(1, Ordering::Relaxed);
        let port = 20_000 + port.wrapping_sub(20_000) % 12_000;
        if TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
}

pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// Connects to the router's TCP server at `to`, retrying until it listens.
pub fn connect(to: &str) -> TcpStream {
    super::eventually(format!("a connection to {to}"), 10 * SECOND, || {
        TcpStream::connect(to).map_err(|e| format!("{to}: {e}"))
    })
}

/// A connection to `to` with a receive buffer of only 4 KiB: what the router sends it
/// waits in the router's socket until it reads.
pub fn connect_small(to: &str) -> TcpStream {
    let socket =
        socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    socket.set_recv_buffer_size(4096).expect("receive buffer");
    let addr: std::net::SocketAddr = to.parse().expect("an address");
    socket.connect(&addr.into()).expect("connect");
    socket.into()
}

/// A ground station on `stream` that says a heartbeat from `sys` every 5 ms for as long
/// as the connection lasts, and reads only from `delay` on: once the connection ended
/// (or nothing came for 5 s), the frames it read, in order.
pub fn chatty_late_reader(
    mut stream: TcpStream,
    sys: u8,
    delay: Duration,
) -> std::thread::JoinHandle<Vec<Vec<u8>>> {
    let mut beating = stream.try_clone().expect("clone");
    std::thread::spawn(move || {
        let beat = std::thread::spawn(move || {
            while beating.write_all(&heartbeat(sys)).is_ok() {
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        std::thread::sleep(delay);
        stream.set_read_timeout(Some(5 * SECOND)).expect("timeout");
        let (mut parser, mut frames, mut buf) = (Parser::new(), Vec::new(), vec![0u8; 65536]);
        while let Ok(n) = stream.read(&mut buf) {
            if n == 0 {
                break;
            }
            parser.feed(&buf[..n], |f| frames.push(f.as_bytes().to_vec()));
        }
        // The heartbeats fail from now on.
        let _ = stream.shutdown(std::net::Shutdown::Both);
        beat.join().expect("heartbeats");
        frames
    })
}

/// One link's line of the counters report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkLine {
    pub name: String,
    pub frames_in: u64,
    pub bytes_in: u64,
    pub frames_out: u64,
    pub bytes_out: u64,
    pub queue_drops: u64,
    pub send_errors: u64,
    pub high_water: u64,
    pub bad_crc: u64,
}

/// One interface's line of the counters report (the numbers this file needs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InterfaceLine {
    pub label: String,
    pub frames: u64,
    pub truncated: u64,
    pub junk_bytes: u64,
    pub io_errors: u64,
}

/// The counters report: a line per link, a line per interface.
#[derive(Debug, Clone, Default)]
pub struct Counters {
    pub links: Vec<LinkLine>,
    pub interfaces: Vec<InterfaceLine>,
    /// The report as printed.
    pub text: String,
}

fn numbers(text: &str) -> Vec<u64> {
    text.split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().expect("a number"))
        .collect()
}

/// The number just before `what` in `text` (`3 junk bytes` → 3).
fn number_before(text: &str, what: &str) -> u64 {
    let at = text
        .find(what)
        .unwrap_or_else(|| panic!("no {what:?} in {text:?}"));
    let digits: String = text[..at]
        .trim_end()
        .chars()
        .rev()
        .take_while(char::is_ascii_digit)
        .collect::<Vec<char>>()
        .into_iter()
        .rev()
        .collect();
    digits.parse().expect("a number")
}

impl Counters {
    /// Parses the lines of one report (the lines after `mavtables counters:`).
    pub fn parse(lines: &[String]) -> Counters {
        let mut c = Counters::default();
        for line in lines {
            let line = line.trim();
            c.text.push_str(line);
            c.text.push('\n');
            if let Some((name, rest)) = line.split_once(": in ") {
                // The signing part, on links of keyed interfaces, is read by the
                // signing tests.
                let rest = rest.split(", signing: ").next().unwrap_or(rest);
                let n = numbers(rest);
                assert_eq!(n.len(), 8, "odd link line {line:?}");
                c.links.push(LinkLine {
                    name: name.to_string(),
                    frames_in: n[0],
                    bytes_in: n[1],
                    frames_out: n[2],
                    bytes_out: n[3],
                    queue_drops: n[4],
                    send_errors: n[5],
                    high_water: n[6],
                    bad_crc: n[7],
                });
            } else if line.contains(" junk bytes") {
                let (label, rest) = line.split_once(": ").expect("label");
                c.interfaces.push(InterfaceLine {
                    label: label.to_string(),
                    frames: number_before(rest, " frames"),
                    truncated: number_before(rest, " truncated"),
                    junk_bytes: number_before(rest, " junk bytes"),
                    io_errors: number_before(rest, " I/O errors"),
                });
            }
        }
        c
    }

    pub fn link(&self, name: &str) -> Option<&LinkLine> {
        self.links.iter().find(|l| l.name == name)
    }

    pub fn interface(&self, label: &str) -> Option<&InterfaceLine> {
        self.interfaces.iter().find(|i| i.label == label)
    }

    /// The report at the end of `stderr` (the router's last words at exit).
    pub fn at_exit(stderr: &[String]) -> Counters {
        let start = stderr
            .iter()
            .rposition(|l| l.starts_with("mavtables counters:"))
            .expect("a counters report at exit");
        Counters::parse(&stderr[start + 1..])
    }
}

/// The router's counters now: SIGUSR1, then SIGUSR1 again so that the second heading
/// marks where the first report ends.
pub fn counters(router: &mut Router) -> Counters {
    const HEADING: &str = "mavtables counters:";
    router.signal(libc::SIGUSR1);
    router.err.wait_for(HEADING, 10 * SECOND);
    let from = router.err.seen.len();
    router.signal(libc::SIGUSR1);
    router.err.wait_for(HEADING, 10 * SECOND);
    let lines = &router.err.seen[from..router.err.seen.len() - 1];
    let report: Vec<String> = lines
        .iter()
        .filter(|l| l.starts_with("  "))
        .cloned()
        .collect();
    Counters::parse(&report)
}

/// Open descriptors of process `pid`.
pub fn fd_count(pid: u32) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd"))
        .expect("/proc/PID/fd")
        .count()
}

/// A `kB` field of `/proc/PID/status` (`VmRSS`, `VmHWM`), in bytes.
pub fn status_bytes(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let line = status
        .lines()
        .find(|l| l.starts_with(&format!("{field}:")))
        .unwrap_or_else(|| panic!("no {field} in /proc/{pid}/status"));
    numbers(line)[0] * 1024
}
