//! What the light-load benchmarks share (`idle_links`, `versus_router`): routers to
//! start (mavtables, mavlink-router), a generator of targeted COMMAND_LONG frames that
//! carry their send time, a sink that records latency, the router's CPU time
//! (`/proc/<pid>/task/*/schedstat`, to the nanosecond) and its system calls (`perf stat`
//! on the `syscalls:sys_enter_*` tracepoints, attached for a window of its own).
//!
//! The path is the one a vehicle's command takes: generator (system 1) → the router's
//! UDP server → a UDP client endpoint of the router → the sink (system 101, known to
//! the router by its HEARTBEAT). COMMAND_LONG is targeted, so a router sends it to the
//! sink only.
#![allow(dead_code)]

use std::cell::Cell;
use std::io;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, encode_v2};

/// System id of the generator.
pub const GEN_SYSTEM: u8 = 1;
/// System id of the sink (the command's target).
pub const SINK_SYSTEM: u8 = 101;
const MSG_HEARTBEAT: u32 = 0;
const MSG_COMMAND_LONG: u32 = 76;

/// Rounds and durations: the full plan under `cargo bench` (which passes `--bench`),
/// none otherwise (`cargo test --all-targets` then runs only a smoke test).
pub fn benchmarking() -> bool {
    std::env::args().any(|a| a == "--bench")
}

/// A COMMAND_LONG from the generator to the sink carrying `seq` and `sent_ns` in its
/// first two parameters' bytes (every frame has the same length: `confirmation` is set).
pub fn probe(seq: u32, sent_ns: u64) -> Vec<u8> {
    let mut payload = [0u8; 33];
    payload[..8].copy_from_slice(&sent_ns.to_le_bytes());
    payload[8..12].copy_from_slice(&seq.to_le_bytes());
    payload[28..30].copy_from_slice(&511u16.to_le_bytes()); // MAV_CMD_SET_MESSAGE_INTERVAL
    payload[30] = SINK_SYSTEM;
    payload[31] = 1;
    payload[32] = 1;
    let header = Header {
        seq: seq as u8,
        system: GEN_SYSTEM,
        component: 1,
    };
    let mut out = Vec::new();
    encode_v2(header, MSG_COMMAND_LONG, &payload, None, &mut out).expect("COMMAND_LONG encodes");
    out
}

/// `(seq, sent_ns)` of a probe; None for any other datagram.
fn read_probe(datagram: &[u8]) -> Option<(u32, u64)> {
    let frame = Frame::parse_exact(datagram).ok()?;
    if frame.system() != GEN_SYSTEM || frame.message_id() != MSG_COMMAND_LONG {
        return None;
    }
    let p = frame.payload_padded();
    let sent = u64::from_le_bytes(p[..8].try_into().ok()?);
    let seq = u32::from_le_bytes(p[8..12].try_into().ok()?);
    Some((seq, sent))
}

/// A HEARTBEAT from `system`, component `component` (a ground station's).
pub fn heartbeat(system: u8, component: u8) -> Vec<u8> {
    let payload = [0, 0, 0, 0, 6, 8, 0, 0, 3];
    let header = Header {
        seq: 0,
        system,
        component,
    };
    let mut out = Vec::new();
    encode_v2(header, MSG_HEARTBEAT, &payload, None, &mut out).expect("HEARTBEAT encodes");
    out
}

/// A UDP port of 127.0.0.1 that was free a moment ago.
pub fn free_port() -> io::Result<u16> {
    Ok(UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// A TCP port of 127.0.0.1 that was free a moment ago.
pub fn free_tcp_port() -> io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Raises the limit of open descriptors to `n` (the hard limit, if lower); routers
/// started afterwards inherit it.
pub fn raise_fd_limit(n: u64) -> io::Result<u64> {
    use nix::sys::resource::{Resource, getrlimit, setrlimit};
    let (_, hard) = getrlimit(Resource::RLIMIT_NOFILE)?;
    let soft = n.min(hard);
    setrlimit(Resource::RLIMIT_NOFILE, soft, hard)?;
    Ok(soft)
}

/// A router process under test, killed when dropped.
pub struct Router {
    /// How tables name it.
    pub name: String,
    child: Child,
    /// Where the generator sends.
    pub udp: SocketAddr,
    /// Its TCP server, if it has one.
    pub tcp: Option<SocketAddr>,
    dir: PathBuf,
}

impl Router {
    /// The mavtables binary `exe` with a UDP server, a UDP client of `sink` and, with
    /// `tcp`, a TCP server; every frame accepted.
    pub fn mavtables(name: &str, exe: &Path, sink: u16, tcp: bool) -> Result<Router, String> {
        let port = free_port().map_err(|e| e.to_string())?;
        let tcp_port = if tcp {
            Some(free_tcp_port().map_err(|e| e.to_string())?)
        } else {
            None
        };
        let dir = scratch_dir(name, port)?;
        let tcp_block = tcp_port.map_or(String::new(), |p| {
            format!("tcp {{\n    port {p};\n    address 127.0.0.1;\n    max_peers 2000;\n}}\n")
        });
        let text = format!(
            "udp {{\n    port {port};\n    address 127.0.0.1;\n}}\n\
             udp {{\n    connect 127.0.0.1:{sink};\n}}\n{tcp_block}\
             default_action accept;\nchain default {{\n    accept;\n}}\n"
        );
        let config = dir.join("router.conf");
        std::fs::write(&config, text).map_err(|e| format!("{}: {e}", config.display()))?;
        let mut command = Command::new(exe);
        command.arg("--config").arg(&config);
        Router::spawn(name, command, dir, port, tcp_port)
    }

    /// mavlink-router (`mavlink-routerd` at `exe`): a UDP server and a UDP client
    /// endpoint of `sink`, its TCP server off; its configuration file says only that
    /// (an empty one makes it exit, and without one it reads
    /// `/etc/mavlink-router/main.conf`).
    pub fn mavlink_router(name: &str, exe: &Path, sink: u16) -> Result<Router, String> {
        let port = free_port().map_err(|e| e.to_string())?;
        let dir = scratch_dir(name, port)?;
        let conf = dir.join("main.conf");
        std::fs::write(&conf, "[General]\nTcpServerPort = 0\n").map_err(|e| e.to_string())?;
        let mut command = Command::new(exe);
        command
            .arg("-c")
            .arg(&conf)
            .arg("-t")
            .arg("0")
            .arg("-e")
            .arg(format!("127.0.0.1:{sink}"))
            .arg(format!("127.0.0.1:{port}"));
        Router::spawn(name, command, dir, port, None)
    }

    /// Starts `command` (a router listening on UDP `port`, and on TCP `tcp` if any)
    /// with its output logged in `dir`.
    pub fn spawn(
        name: &str,
        command: Command,
        dir: PathBuf,
        port: u16,
        tcp: Option<u16>,
    ) -> Result<Router, String> {
        let child = spawn_logged(command, &dir.join("router.log"), name)?;
        let local = |p| SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, p));
        Ok(Router {
            name: name.to_string(),
            child,
            udp: local(port),
            tcp: tcp.map(local),
            dir,
        })
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `Err` with its last line of output once it has exited.
    pub fn check_running(&mut self) -> Result<(), String> {
        match self.child.try_wait() {
            Ok(None) => Ok(()),
            _ => {
                let log = std::fs::read_to_string(self.dir.join("router.log")).unwrap_or_default();
                let last = log.lines().last().unwrap_or("(no output)").to_string();
                Err(format!("{} exited: {last}", self.name))
            }
        }
    }

    /// CPU time it has used so far (all its threads).
    pub fn cpu(&self) -> Option<Duration> {
        schedstat_cpu(self.pid())
    }
}

impl Drop for Router {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Starts `command` with its standard output and error going to the file `log`.
pub fn spawn_logged(mut command: Command, log: &Path, name: &str) -> Result<Child, String> {
    let log = std::fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
    command
        .stdin(Stdio::null())
        .stdout(log.try_clone().map_err(|e| e.to_string())?)
        .stderr(log)
        .spawn()
        .map_err(|e| format!("cannot start {name}: {e}"))
}

fn scratch_dir(name: &str, port: u16) -> Result<PathBuf, String> {
    let tag: String = name.chars().filter(char::is_ascii_alphanumeric).collect();
    let dir = std::env::temp_dir().join(format!(
        "mavtables-light-{}-{tag}-{port}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    Ok(dir)
}

/// CPU time process `pid` has used, to the nanosecond: the scheduler's run time of
/// each of its threads (`/proc/<pid>/task/*/schedstat`).
pub fn schedstat_cpu(pid: u32) -> Option<Duration> {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).ok()?;
    let mut ns = 0u64;
    for task in tasks {
        let stat = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(Duration::from_nanos(ns))
}

/// The sink: one UDP socket, known to the router by a HEARTBEAT of system 101.
pub struct Sink {
    socket: UdpSocket,
    /// Where the router's frames to the sink come from: each trial starts with a
    /// HEARTBEAT there, as a real peer sends one every second, so that the sink's
    /// address does not expire in the router (120 s) however long the benchmark runs.
    router_side: Cell<Option<SocketAddr>>,
}

impl Sink {
    /// A sink on a free port of 127.0.0.1.
    pub fn new() -> io::Result<Sink> {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        Ok(Sink {
            socket,
            router_side: Cell::new(None),
        })
    }

    /// Its port.
    pub fn port(&self) -> u16 {
        self.socket.local_addr().map_or(0, |a| a.port())
    }
}

/// Makes the sink known to the router at `to` (or, with `None`, the generator sends
/// straight to the sink): the generator sends HEARTBEATs until one arrives (a router
/// sends it to its client endpoint, the sink's port), the sink answers to where it came
/// from, and then probes must arrive; at most 5 s.
pub fn handshake(sender: &UdpSocket, to: Option<SocketAddr>, sink: &Sink) -> Result<(), String> {
    let Some(to) = to else {
        return Ok(());
    };
    let start = Instant::now();
    let _ = sink
        .socket
        .set_read_timeout(Some(Duration::from_millis(50)));
    let mut buf = [0u8; 2048];
    let mut answered = false;
    while start.elapsed() < Duration::from_secs(5) {
        let hello = if answered {
            probe(0, 0)
        } else {
            heartbeat(GEN_SYSTEM, 1)
        };
        sender.send_to(&hello, to).map_err(|e| e.to_string())?;
        while let Ok((n, from)) = sink.socket.recv_from(&mut buf) {
            if answered && read_probe(&buf[..n]).is_some() {
                // Drain what is still on its way.
                thread::sleep(Duration::from_millis(50));
                while sink.socket.recv_from(&mut buf).is_ok() {}
                return Ok(());
            }
            let _ = sink.socket.send_to(&heartbeat(SINK_SYSTEM, 1), from);
            sink.router_side.set(Some(from));
            answered = true;
        }
    }
    Err(format!("no probe reached the sink through {to} within 5 s"))
}

/// What one trial measured.
#[derive(Debug, Default, Clone)]
pub struct Trial {
    /// Probes sent.
    pub sent: u64,
    /// Probes the sink received.
    pub received: u64,
    /// Latency of each received probe, ns.
    pub latencies: Vec<u64>,
    /// The router's CPU time over the trial.
    pub cpu: Option<Duration>,
}

impl Trial {
    /// The router's CPU time per probe sent, µs.
    pub fn cpu_per_frame_us(&self) -> Option<f64> {
        let cpu = self.cpu?;
        (self.sent > 0).then(|| cpu.as_secs_f64() * 1e6 / self.sent as f64)
    }

    /// Latency quantile `q` (0–1), µs.
    pub fn latency_us(&self, q: f64) -> f64 {
        let mut v = self.latencies.clone();
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_unstable();
        let i = ((v.len() - 1) as f64 * q).round() as usize;
        v[i] as f64 / 1e3
    }
}

/// Waits (at most 1 s) until process `pid` has used no more than 20 µs of CPU in 5 ms:
/// it has finished what it was given and sleeps.
fn wait_until_idle(pid: u32) {
    let give_up = Instant::now() + Duration::from_secs(1);
    let mut last = schedstat_cpu(pid);
    while Instant::now() < give_up {
        thread::sleep(Duration::from_millis(5));
        let now = schedstat_cpu(pid);
        match (last, now) {
            (Some(a), Some(b)) if b.saturating_sub(a) <= Duration::from_micros(20) => return,
            (_, None) => return,
            _ => last = now,
        }
    }
}

/// Sends probes to `to` (the sink itself with `None`) at `rate` per second for
/// `duration`, one datagram each, while the sink times their arrival; `router` (if
/// any) is the process whose CPU time is taken.
pub fn trial(
    sender: &UdpSocket,
    to: Option<SocketAddr>,
    sink: &Sink,
    rate: f64,
    duration: Duration,
    router: Option<u32>,
) -> Trial {
    if let Some(router_side) = sink.router_side.get() {
        let _ = sink.socket.send_to(&heartbeat(SINK_SYSTEM, 1), router_side);
        // The HEARTBEAT is a broadcast: the router sends it on to every link it has
        // (1,000 idle TCP clients in `idle_links`). That fan-out is not what this trial
        // times, so the trial starts once the router has done it.
        if let Some(pid) = router {
            wait_until_idle(pid);
        }
    }
    let base = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let dest = to.unwrap_or(SocketAddr::from(([127, 0, 0, 1], sink.port())));
    let reader = {
        let socket = sink.socket.try_clone().expect("sink socket clones");
        let stop = stop.clone();
        thread::spawn(move || {
            let _ = socket.set_read_timeout(Some(Duration::from_millis(20)));
            let mut buf = [0u8; 2048];
            let mut latencies = Vec::new();
            loop {
                match socket.recv(&mut buf) {
                    Ok(n) => {
                        let now = base.elapsed().as_nanos() as u64;
                        if let Some((_, sent)) = read_probe(&buf[..n]) {
                            latencies.push(now.saturating_sub(sent));
                        }
                    }
                    Err(_) if stop.load(Ordering::Relaxed) => return latencies,
                    Err(_) => {}
                }
            }
        })
    };
    let cpu_before = router.and_then(schedstat_cpu);
    let total = (rate * duration.as_secs_f64()).round() as u64;
    let interval = Duration::from_secs_f64(1.0 / rate);
    let mut sent = 0;
    let started = Instant::now();
    while sent < total {
        let due = started + interval * sent as u32;
        let now = Instant::now();
        if now < due {
            thread::sleep(due - now);
        }
        let frame = probe(sent as u32, base.elapsed().as_nanos() as u64);
        if sender.send_to(&frame, dest).is_ok() {
            sent += 1;
        }
    }
    // What is in flight arrives; then the reader stops at its next timeout.
    thread::sleep(Duration::from_millis(30));
    let cpu = router
        .and_then(schedstat_cpu)
        .zip(cpu_before)
        .map(|(after, before)| after.saturating_sub(before));
    stop.store(true, Ordering::Relaxed);
    let latencies = reader.join().unwrap_or_default();
    Trial {
        sent,
        received: latencies.len() as u64,
        latencies,
        cpu,
    }
}

/// System calls a router made in a window of time.
#[derive(Debug, Clone, Copy, Default)]
pub struct Syscalls {
    /// All of them.
    pub total: u64,
    /// `epoll_wait` (each a wake-up, or a poll that found something at once).
    pub epoll_wait: u64,
    /// `timerfd_settime` (re-arming a timer).
    pub timer_settime: u64,
    /// Context switches (each wake-up is one, and so is each time it is preempted).
    pub context_switches: u64,
    /// Moves to another CPU.
    pub migrations: u64,
}

/// System calls process `pid` made while `window` ran, counted by `perf stat` on the
/// `raw_syscalls:sys_enter` and `syscalls:sys_enter_*` tracepoints (attached before
/// the window starts); None when perf cannot count them here. The count includes the
/// router's idle wake-ups during the window.
pub fn syscalls_during(pid: u32, window: impl FnOnce()) -> Option<Syscalls> {
    let out = std::env::temp_dir().join(format!("mavtables-perf-{}-{pid}", std::process::id()));
    let events = "raw_syscalls:sys_enter,syscalls:sys_enter_epoll_wait,\
                  syscalls:sys_enter_timerfd_settime,context-switches,cpu-migrations";
    let mut perf = Command::new("perf")
        .args(["stat", "-x", ",", "-e", events, "-o"])
        .arg(&out)
        .arg("-p")
        .arg(pid.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .ok()?;
    // perf attaches to the tracepoints before it counts.
    thread::sleep(Duration::from_millis(500));
    window();
    // Our own child, not waited for yet: the pid is still perf's.
    let _ = nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(perf.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    );
    let _ = perf.wait();
    let text = std::fs::read_to_string(&out).ok()?;
    let _ = std::fs::remove_file(&out);
    let count = |event: &str| {
        text.lines().find_map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            (fields.get(2) == Some(&event))
                .then(|| fields.first()?.parse::<u64>().ok())
                .flatten()
        })
    };
    Some(Syscalls {
        total: count("raw_syscalls:sys_enter")?,
        epoll_wait: count("syscalls:sys_enter_epoll_wait").unwrap_or(0),
        timer_settime: count("syscalls:sys_enter_timerfd_settime").unwrap_or(0),
        context_switches: count("context-switches").unwrap_or(0),
        migrations: count("cpu-migrations").unwrap_or(0),
    })
}

/// The median of `v` (NaN when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| !x.is_nan());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The median of `v` and a distribution-free interval around it that holds the true
/// median with at least 95% probability (order statistics: the `k`-th smallest and
/// `k`-th largest value, for the largest `k` with P(Binomial(n, ½) < k) ≤ 2.5%). With
/// fewer than 6 values no such interval exists and the bounds are the extremes.
pub fn median_interval(mut v: Vec<f64>) -> Option<(f64, f64, f64)> {
    v.retain(|x| !x.is_nan());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    // P(Binomial(n, ½) <= j), built up term by term.
    let mut below = 0.0;
    let mut term = 0.5f64.powi(n as i32);
    let mut k = 1;
    for j in 0..n {
        below += term;
        if below > 0.025 {
            break;
        }
        k = j + 1;
        term *= (n - j) as f64 / (j + 1) as f64;
    }
    // `k` stays at or below the middle: P(Binomial(n, ½) <= n/2) is at least ½.
    Some((v[n / 2], v[k - 1], v[n - k]))
}

/// Opens `n` TCP connections to `server`, each sending one HEARTBEAT of its own
/// address (systems from 2 on, 100 components each), and keeps them open.
pub fn idle_clients(server: SocketAddr, n: usize) -> io::Result<Vec<TcpStream>> {
    use std::io::Write;
    let mut clients = Vec::with_capacity(n);
    for i in 0..n {
        let mut c = TcpStream::connect(server)?;
        let system = 2 + (i / 100) as u8;
        c.write_all(&heartbeat(system, 1 + (i % 100) as u8))?;
        clients.push(c);
    }
    Ok(clients)
}
