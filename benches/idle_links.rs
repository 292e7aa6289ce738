//! CPU per forwarded frame with and without 1,000 idle TCP clients (issue 19: "the CPU
//! per forwarded frame must not grow with idle links").
//!
//! Run: `cargo bench --bench idle_links`. Two routers of the same build run side by side,
//! each with a UDP server, a UDP client to a sink and a TCP server; one has no TCP
//! clients, the other 1,000 that each sent one HEARTBEAT and then nothing. Targeted
//! COMMAND_LONG frames go UDP → UDP at 10k frames/s (see `light/mod.rs`); rounds of
//! one second alternate between the routers (and which goes first), 7 rounds each; the
//! figures are medians of the router's CPU per frame, their ratio, latency, and system
//! calls per frame (`perf stat`, a separate two-second window). `MAVTABLES_BEFORE=<path>`
//! adds another build (say the one before a change), interleaved in the same rounds.
//!
//! Without `--bench` (`cargo test --all-targets`) it only checks, in about a second,
//! that a router with 20 idle clients forwards.

#![forbid(unsafe_code)]

mod light;

use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::Duration;

use light::{Router, Sink, Trial};

const CLIENTS: usize = 1000;
const RATE: f64 = 10e3;
const ROUNDS: usize = 7;
const ROUND: Duration = Duration::from_secs(1);

/// A router, its sink, the generator's socket and the idle clients it has.
struct Setup {
    build: String,
    clients: usize,
    router: Router,
    sink: Sink,
    sender: UdpSocket,
    _idle: Vec<std::net::TcpStream>,
    trials: Vec<Trial>,
}

impl Setup {
    fn start(build: &str, exe: &Path, clients: usize) -> Result<Setup, String> {
        let sink = Sink::new().map_err(|e| e.to_string())?;
        let name = format!("{build}-{clients}");
        let mut router = Router::mavtables(&name, exe, sink.port(), true)?;
        let sender = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
        light::handshake(&sender, Some(router.udp), &sink)?;
        let server = router.tcp.ok_or("no TCP server")?;
        let idle = light::idle_clients(server, clients).map_err(|e| format!("clients: {e}"))?;
        // The router takes them in and routes their heartbeats to each other.
        std::thread::sleep(Duration::from_millis(500));
        router.check_running()?;
        Ok(Setup {
            build: build.to_string(),
            clients,
            router,
            sink,
            sender,
            _idle: idle,
            trials: Vec::new(),
        })
    }

    fn round(&mut self, rate: f64, duration: Duration) {
        let t = light::trial(
            &self.sender,
            Some(self.router.udp),
            &self.sink,
            rate,
            duration,
            Some(self.router.pid()),
        );
        self.trials.push(t);
    }

    fn cpu_us(&self) -> f64 {
        light::median(
            self.trials
                .iter()
                .filter_map(Trial::cpu_per_frame_us)
                .collect(),
        )
    }

    fn latency_us(&self, q: f64) -> f64 {
        light::median(self.trials.iter().map(|t| t.latency_us(q)).collect())
    }
}

fn smoke(exe: &Path) {
    let mut s = Setup::start("smoke", exe, 20).expect("router with idle clients starts");
    s.round(1e3, Duration::from_millis(300));
    let t = &s.trials[0];
    println!(
        "idle_links smoke: sent {}, received {}, router CPU/frame {:?} µs",
        t.sent,
        t.received,
        t.cpu_per_frame_us()
    );
    assert!(
        t.received * 10 >= t.sent * 9,
        "{} of {}",
        t.received,
        t.sent
    );
    assert!(t.cpu.is_some(), "no CPU time for the router");
}

fn main() {
    let exe = std::env::var_os("MAVTABLES_BENCH_ROUTER").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_mavtables")),
        PathBuf::from,
    );
    if !light::benchmarking() {
        smoke(&exe);
        return;
    }
    match light::raise_fd_limit(8192) {
        Ok(n) if n >= 2 * CLIENTS as u64 + 100 => {}
        Ok(n) => println!("open files limited to {n}: fewer clients may connect"),
        Err(e) => println!("cannot raise the open files limit: {e}"),
    }
    let mut builds = Vec::new();
    if let Some(before) = std::env::var_os("MAVTABLES_BEFORE") {
        builds.push(("before", PathBuf::from(before)));
    }
    builds.push(("this build", exe));
    let mut setups = Vec::new();
    for (build, exe) in &builds {
        for clients in [0, CLIENTS] {
            match Setup::start(build, exe, clients) {
                Ok(s) => setups.push(s),
                Err(e) => {
                    println!("{build} with {clients} idle clients: {e}");
                    return;
                }
            }
        }
    }
    println!(
        "idle links: {} rounds of {} s at {RATE} frames/s per router, alternating",
        ROUNDS,
        ROUND.as_secs_f64()
    );
    for round in 0..ROUNDS {
        let n = setups.len();
        for k in 0..n {
            // Odd rounds run the routers in reverse order.
            let i = if round % 2 == 0 { k } else { n - 1 - k };
            setups[i].round(RATE, ROUND);
        }
    }
    let mut syscalls = Vec::new();
    for s in &setups {
        let (sender, sink, to) = (&s.sender, &s.sink, s.router.udp);
        let window = Duration::from_secs(2);
        let mut sent = 0;
        let calls = light::syscalls_during(s.router.pid(), || {
            sent = light::trial(sender, Some(to), sink, RATE, window, None).sent;
        });
        syscalls.push(calls.map(|c| c.total as f64 / sent.max(1) as f64));
    }
    println!(
        "\n| build | idle TCP clients | router CPU/frame (median) | ÷ no clients | latency p50 / p99 | syscalls/frame | received |"
    );
    println!("|---|---:|---:|---:|---|---:|---:|");
    for (i, s) in setups.iter().enumerate() {
        let base = setups
            .iter()
            .find(|b| b.build == s.build && b.clients == 0)
            .map_or(f64::NAN, Setup::cpu_us);
        let sent: u64 = s.trials.iter().map(|t| t.sent).sum();
        let received: u64 = s.trials.iter().map(|t| t.received).sum();
        println!(
            "| {} | {} | {:.2} µs | {:.2} | {:.1} / {:.1} µs | {} | {received}/{sent} |",
            s.build,
            s.clients,
            s.cpu_us(),
            s.cpu_us() / base,
            s.latency_us(0.5),
            s.latency_us(0.99),
            syscalls[i].map_or("n/a".to_string(), |c| format!("{c:.2}")),
        );
    }
    let per_round: Vec<String> = setups
        .iter()
        .map(|s| {
            let v: Vec<String> = s
                .trials
                .iter()
                .filter_map(Trial::cpu_per_frame_us)
                .map(|c| format!("{c:.2}"))
                .collect();
            format!("{} {}: {}", s.build, s.clients, v.join(" "))
        })
        .collect();
    println!("\nCPU/frame per round, µs:\n{}", per_round.join("\n"));
}
