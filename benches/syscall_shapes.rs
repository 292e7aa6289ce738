//! What a forwarder's system calls and its user-space work cost at the rates vehicles
//! send (issue 19), against mavtables and, with `MAVLINK_ROUTER=/path/to/mavlink-routerd`,
//! mavlink-router.
//!
//! Run by hand: `cargo bench --bench syscall_shapes`. The bare forwarders are this
//! binary started again with `--forwarder SHAPE PORT SINK`: a mio loop that sends every
//! datagram of its UDP socket on to the sink, with no parsing and no routing, in one
//! of these shapes:
//! - `mmsg`: `recvmmsg` of up to 64 (headers allocated once), `sendmmsg` of what came;
//! - `single`: `recvfrom` until `EAGAIN`, a `sendto` for each datagram;
//! - `single+1.5us-before` / `single+1.5us-after`: `single` with 1.5 µs of user-space
//!   work (a spin on the clock) before or after each send.
//!
//! Each contestant gets its own sink and generator (`light/mod.rs`: targeted
//! COMMAND_LONG, one datagram each, send time in the payload) at 10k frames/s for 3 s,
//! 5 rounds, the order reversed every other round; medians of router CPU per frame
//! (`/proc/PID/task/*/schedstat`), of the context switches it was dealt per frame
//! (voluntary: it waited; involuntary: it was preempted, from `/proc/PID/task/*/status`)
//! and of latency p50/p99.

#![forbid(unsafe_code)]

mod light;

use std::net::{SocketAddr, UdpSocket};
use std::os::fd::AsRawFd;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use light::{Router, Sink};

const ROUNDS: usize = 5;
const RATE: f64 = 10e3;
const SECONDS: u64 = 3;
const SHAPES: [&str; 4] = [
    "mmsg",
    "single",
    "single+1.5us-before",
    "single+1.5us-after",
];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--forwarder") {
        if let Err(e) = forwarder(&args[2..]) {
            eprintln!("forwarder: {e}");
            std::process::exit(1);
        }
        return;
    }
    if !light::benchmarking() {
        return;
    }
    if let Err(e) = compare() {
        eprintln!("syscall_shapes: {e}");
        std::process::exit(1);
    }
}

/// A contestant: a router process with its own sink and generator.
struct Contestant {
    name: String,
    router: Router,
    sink: Sink,
    sender: UdpSocket,
    cpu: Vec<f64>,
    voluntary: Vec<f64>,
    involuntary: Vec<f64>,
    p50: Vec<f64>,
    p99: Vec<f64>,
    lost: u64,
}

impl Contestant {
    fn new(name: &str, start: impl FnOnce(u16) -> Result<Router, String>) -> Result<Self, String> {
        let sink = Sink::new().map_err(|e| e.to_string())?;
        let router = start(sink.port())?;
        let sender = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
        light::handshake(&sender, Some(router.udp), &sink)?;
        Ok(Contestant {
            name: name.to_string(),
            router,
            sink,
            sender,
            cpu: Vec::new(),
            voluntary: Vec::new(),
            involuntary: Vec::new(),
            p50: Vec::new(),
            p99: Vec::new(),
            lost: 0,
        })
    }

    fn round(&mut self) -> Result<(), String> {
        self.router.check_running()?;
        let pid = self.router.pid();
        let before = switches(pid);
        let t = light::trial(
            &self.sender,
            Some(self.router.udp),
            &self.sink,
            RATE,
            Duration::from_secs(SECONDS),
            Some(pid),
        );
        let after = switches(pid);
        let frames = t.sent.max(1) as f64;
        if let Some(cpu) = t.cpu_per_frame_us() {
            self.cpu.push(cpu);
        }
        if let (Some(b), Some(a)) = (before, after) {
            self.voluntary.push(a.0.saturating_sub(b.0) as f64 / frames);
            self.involuntary
                .push(a.1.saturating_sub(b.1) as f64 / frames);
        }
        self.p50.push(t.latency_us(0.5));
        self.p99.push(t.latency_us(0.99));
        self.lost += t.sent.saturating_sub(t.received);
        Ok(())
    }
}

/// Voluntary and involuntary context switches of every thread of `pid` so far.
fn switches(pid: u32) -> Option<(u64, u64)> {
    let mut total = (0, 0);
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).ok()? {
        let status = std::fs::read_to_string(task.ok()?.path().join("status")).ok()?;
        for line in status.lines() {
            let value = |l: &str| l.split_whitespace().nth(1)?.parse::<u64>().ok();
            if line.starts_with("voluntary_ctxt_switches:") {
                total.0 += value(line)?;
            } else if line.starts_with("nonvoluntary_ctxt_switches:") {
                total.1 += value(line)?;
            }
        }
    }
    Some(total)
}

fn compare() -> Result<(), String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let mavtables = Path::new(env!("CARGO_BIN_EXE_mavtables"));
    let mut contestants = vec![Contestant::new("mavtables", |sink| {
        Router::mavtables("mavtables", mavtables, sink, false)
    })?];
    if let Ok(path) = std::env::var("MAVLINK_ROUTER") {
        contestants.push(Contestant::new("mavlink-router", |sink| {
            Router::mavlink_router("mavlink-router", Path::new(&path), sink)
        })?);
    }
    for shape in SHAPES {
        contestants.push(Contestant::new(&format!("bare: {shape}"), |sink| {
            let port = light::free_port().map_err(|e| e.to_string())?;
            let mut command = Command::new(&exe);
            command
                .arg("--forwarder")
                .arg(shape)
                .arg(port.to_string())
                .arg(sink.to_string());
            let dir = std::env::temp_dir().join(format!("mavtables-shapes-{port}"));
            std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
            Router::spawn(shape, command, dir, port, None)
        })?);
    }
    println!(
        "{} rounds of {SECONDS} s at {RATE} frames/s per contestant, order reversed every other round",
        ROUNDS
    );
    for round in 0..ROUNDS {
        let order: Vec<usize> = if round % 2 == 0 {
            (0..contestants.len()).collect()
        } else {
            (0..contestants.len()).rev().collect()
        };
        for i in order {
            contestants[i].round()?;
        }
    }
    println!(
        "| forwarder | CPU/frame | context switches/frame (voluntary + involuntary) | latency p50 / p99 | lost |"
    );
    println!("|---|---:|---:|---|---:|");
    for c in contestants {
        println!(
            "| {} | {:.2} µs | {:.2} + {:.2} | {:.1} / {:.1} µs | {} |",
            c.name,
            light::median(c.cpu),
            light::median(c.voluntary),
            light::median(c.involuntary),
            light::median(c.p50),
            light::median(c.p99),
            c.lost
        );
    }
    Ok(())
}

/// The bare forwarder: `SHAPE PORT SINK`.
fn forwarder(args: &[String]) -> Result<(), String> {
    let [shape, port, sink] = args else {
        return Err("usage: --forwarder SHAPE PORT SINK".into());
    };
    let port: u16 = port.parse().map_err(|_| "PORT")?;
    let sink: u16 = sink.parse().map_err(|_| "SINK")?;
    let (single, spin_before, spin_after) = match shape.as_str() {
        "mmsg" => (false, 0, 0),
        "single" => (true, 0, 0),
        "single+1.5us-before" => (true, 1500, 0),
        "single+1.5us-after" => (true, 0, 1500),
        other => return Err(format!("no shape {other}")),
    };
    let local = SocketAddr::from(([127, 0, 0, 1], port));
    let mut server = mio::net::UdpSocket::bind(local).map_err(|e| e.to_string())?;
    let to = SocketAddr::from(([127, 0, 0, 1], sink));
    let mut client = mio::net::UdpSocket::bind(SocketAddr::from(([127, 0, 0, 1], 0)))
        .map_err(|e| e.to_string())?;
    let mut poll = mio::Poll::new().map_err(|e| e.to_string())?;
    let both = mio::Interest::READABLE | mio::Interest::WRITABLE;
    (poll.registry().register(&mut server, mio::Token(0), both)).map_err(|e| e.to_string())?;
    (poll.registry().register(&mut client, mio::Token(1), both)).map_err(|e| e.to_string())?;
    let mut events = mio::Events::with_capacity(64);
    let mut batch = mmsg::Batch::new(to);
    let mut buf = [0u8; 2048];
    let spin = |ns: u128| {
        let start = Instant::now();
        while start.elapsed().as_nanos() < ns {}
    };
    loop {
        poll.poll(&mut events, None).map_err(|e| e.to_string())?;
        for event in events.iter() {
            if event.token() == mio::Token(1) {
                // The sink's HEARTBEATs: read and dropped.
                while client.recv_from(&mut buf).is_ok() {}
                continue;
            }
            if !event.is_readable() {
                continue;
            }
            if single {
                while let Ok((n, _)) = server.recv_from(&mut buf) {
                    spin(spin_before);
                    let _ = client.send_to(&buf[..n], to);
                    spin(spin_after);
                }
            } else {
                while batch.forward(server.as_raw_fd(), client.as_raw_fd()) == mmsg::MAX {}
            }
        }
    }
}

/// `recvmmsg` / `sendmmsg` for the `mmsg` shape, through nix's safe wrappers: the headers
/// (`MultiHeaders`), buffers and destinations are allocated once, but each call points the
/// 64 headers at the buffers again (about 0.1 µs a call more than headers set up once).
mod mmsg {
    use std::io::{IoSlice, IoSliceMut};
    use std::net::SocketAddr;
    use std::os::fd::RawFd;

    use nix::sys::socket::{
        ControlMessage, MsgFlags, MultiHeaders, SockaddrIn, recvmmsg, sendmmsg,
    };

    pub const MAX: usize = 64;
    const LEN: usize = 2048;

    pub struct Batch {
        data: Box<[[u8; LEN]; MAX]>,
        lens: [usize; MAX],
        msgs: MultiHeaders<SockaddrIn>,
        out_msgs: MultiHeaders<SockaddrIn>,
        /// The sink, once per send header (none if it is not IPv4: the send fails).
        to: [Option<SockaddrIn>; MAX],
    }

    impl Batch {
        pub fn new(to: SocketAddr) -> Batch {
            let to = match to {
                SocketAddr::V4(a) => Some(SockaddrIn::from(a)),
                SocketAddr::V6(_) => None,
            };
            Batch {
                data: vec![[0u8; LEN]; MAX]
                    .into_boxed_slice()
                    .try_into()
                    .expect("MAX buffers"),
                lens: [0; MAX],
                msgs: MultiHeaders::preallocate(MAX, None),
                out_msgs: MultiHeaders::preallocate(MAX, None),
                to: [to; MAX],
            }
        }

        /// Receives a batch on `from` and sends it on `out`; returns how many came.
        pub fn forward(&mut self, from: RawFd, out: RawFd) -> usize {
            let n = {
                let mut iovs = self.data.each_mut().map(|buf| [IoSliceMut::new(buf)]);
                match recvmmsg(
                    from,
                    &mut self.msgs,
                    &mut iovs,
                    MsgFlags::MSG_DONTWAIT,
                    None,
                ) {
                    Ok(got) => {
                        let mut n = 0;
                        for (len, msg) in self.lens.iter_mut().zip(got) {
                            *len = msg.bytes;
                            n += 1;
                        }
                        n
                    }
                    Err(_) => 0,
                }
            };
            if n == 0 {
                return 0;
            }
            let mut out_iovs = [[IoSlice::new(&[])]; MAX];
            for (iov, (buf, &len)) in out_iovs
                .iter_mut()
                .zip(self.data.iter().zip(&self.lens[..n]))
            {
                *iov = [IoSlice::new(&buf[..len])];
            }
            let no_cmsgs: [ControlMessage<'_>; 0] = [];
            let _ = sendmmsg(
                out,
                &mut self.out_msgs,
                &out_iovs[..n],
                &self.to[..n],
                no_cmsgs,
                MsgFlags::MSG_DONTWAIT,
            );
            n
        }
    }
}
