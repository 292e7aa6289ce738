//! mavtables against mavlink-router at the rates vehicles send (issue 19): router CPU
//! per frame, system calls per frame and latency p50/p99, with a no-router baseline, in
//! one run.
//!
//! Run by hand: `MAVLINK_ROUTER=/path/to/mavlink-routerd cargo bench --bench
//! versus_router` (without `MAVLINK_ROUTER` it says it was skipped; nothing of
//! mavlink-router is part of this repository). `MAVTABLES_BEFORE=<path>` adds another
//! mavtables build. Each router gets a UDP server and a UDP client endpoint to its own
//! sink: `mavlink-routerd -c <file: [General] TcpServerPort = 0> -t 0 -e 127.0.0.1:SINK
//! 127.0.0.1:PORT`, and for mavtables the same as a configuration, every frame
//! accepted. Targeted COMMAND_LONG frames, one datagram each, carry their send time (see
//! `light/mod.rs`). At 1k and 10k frames/s, 5 rounds (3 s and 1 s) per router, the
//! order alternating round by round; medians. System calls: `perf stat -e
//! raw_syscalls:sys_enter,… -p PID` over a separate 3 s window per router and rate,
//! divided by the frames sent in it (the router's idle wake-ups in the window count).
//! Under each table, every mavtables build against mavlink-router paired by round: the
//! median ratio of CPU per frame, of p50 and of p99, with a 95% interval of that median
//! (at least 6 rounds give one; 9 or more give a useful one at 1k frames/s); and with
//! `MAVTABLES_BEFORE`, this build against each build compared, paired the same way.
//! `MAVTABLES_BENCH_RATE=10000` runs one rate only; `MAVTABLES_BENCH_TRACE=1` prints
//! each trial (its p50 and p99, how many frames took over 150 µs, CPU per frame and the
//! router's moves to another CPU) on standard error, to tell a router's tail from the
//! machine's stalls.

#![forbid(unsafe_code)]

mod light;

use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::Duration;

use light::{Router, Sink, Trial};

const ROUNDS: usize = 5;
const RATES: [(f64, Duration); 2] = [
    (1e3, Duration::from_secs(3)),
    (10e3, Duration::from_secs(1)),
];

/// A contestant: a router (None: the generator sends straight to the sink).
struct Contestant {
    name: String,
    router: Option<Router>,
    sink: Sink,
    sender: UdpSocket,
    /// Trials per rate (index into [`RATES`]).
    trials: [Vec<Trial>; 2],
    /// System calls and frames sent in the counted window, per rate.
    syscalls: [Option<(light::Syscalls, u64)>; 2],
}

impl Contestant {
    fn new(name: &str, start: impl FnOnce(u16) -> Result<Router, String>) -> Result<Self, String> {
        let sink = Sink::new().map_err(|e| e.to_string())?;
        let router = start(sink.port())?;
        Contestant::with(name, Some(router), sink)
    }

    fn with(name: &str, router: Option<Router>, sink: Sink) -> Result<Self, String> {
        let sender = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
        light::handshake(&sender, router.as_ref().map(|r| r.udp), &sink)?;
        Ok(Contestant {
            name: name.to_string(),
            router,
            sink,
            sender,
            trials: [Vec::new(), Vec::new()],
            syscalls: [None, None],
        })
    }

    fn to(&self) -> Option<SocketAddr> {
        self.router.as_ref().map(|r| r.udp)
    }

    fn pid(&self) -> Option<u32> {
        self.router.as_ref().map(Router::pid)
    }
}

fn main() {
    if !light::benchmarking() {
        return;
    }
    let Some(routerd) = std::env::var_os("MAVLINK_ROUTER").map(PathBuf::from) else {
        println!("versus_router: skipped (set MAVLINK_ROUTER to a mavlink-routerd binary)");
        return;
    };
    let exe = std::env::var_os("MAVTABLES_BENCH_ROUTER").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_mavtables")),
        PathBuf::from,
    );
    let rounds = std::env::var("MAVTABLES_BENCH_ROUNDS")
        .ok()
        .and_then(|n| n.parse().ok())
        .filter(|&n| n > 0)
        .unwrap_or(ROUNDS);
    let mut all = Vec::new();
    let direct = Sink::new()
        .map_err(|e| e.to_string())
        .and_then(|sink| Contestant::with("no router", None, sink));
    all.push(direct);
    // Builds to compare, separated like PATH; each named by its file name when there
    // are several.
    let befores: Vec<PathBuf> = std::env::var_os("MAVTABLES_BEFORE")
        .map(|v| std::env::split_paths(&v).collect())
        .unwrap_or_default();
    for before in &befores {
        let name = match befores.len() {
            1 => "mavtables before".to_string(),
            _ => format!(
                "mavtables {}",
                before.file_name().unwrap_or_default().display()
            ),
        };
        all.push(Contestant::new(&name, |sink| {
            Router::mavtables("before", before, sink, false)
        }));
    }
    all.push(Contestant::new("mavtables", |sink| {
        Router::mavtables("mavtables", &exe, sink, false)
    }));
    all.push(Contestant::new("mavlink-router", |sink| {
        Router::mavlink_router("mavlink-router", &routerd, sink)
    }));
    let mut contestants = Vec::new();
    for c in all {
        match c {
            Ok(c) => contestants.push(c),
            Err(e) => {
                println!("versus_router: {e}");
                return;
            }
        }
    }
    let trace = std::env::var_os("MAVTABLES_BENCH_TRACE").is_some_and(|v| v != "0");
    println!(
        "versus mavlink-router: {rounds} rounds per rate and router, alternating; {} CPUs",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    let only: Option<f64> = std::env::var("MAVTABLES_BENCH_RATE")
        .ok()
        .and_then(|r| r.parse().ok());
    for (r, &(rate, duration)) in RATES.iter().enumerate() {
        if only.is_some_and(|o| o != rate) {
            continue;
        }
        for round in 0..rounds {
            let n = contestants.len();
            for k in 0..n {
                let i = if round % 2 == 0 { k } else { n - 1 - k };
                let c = &mut contestants[i];
                let moved = c.pid().and_then(migrations);
                let t = light::trial(&c.sender, c.to(), &c.sink, rate, duration, c.pid());
                if trace {
                    let moved = c.pid().and_then(migrations).zip(moved).map(|(b, a)| b - a);
                    let slow = t.latencies.iter().filter(|&&ns| ns > 150_000).count();
                    eprintln!(
                        "trial {rate} {round} {}: p50 {:.1} p99 {:.1} µs, {slow} over 150 µs, cpu/frame {:.2} µs, migrations {}",
                        c.name,
                        t.latency_us(0.5),
                        t.latency_us(0.99),
                        t.cpu_per_frame_us().unwrap_or(f64::NAN),
                        moved.map_or("–".to_string(), |m| m.to_string())
                    );
                }
                c.trials[r].push(t);
            }
        }
        for c in &mut contestants {
            let Some(pid) = c.pid() else {
                continue;
            };
            let mut sent = 0;
            let (sender, to, sink) = (&c.sender, c.to(), &c.sink);
            let calls = light::syscalls_during(pid, || {
                sent = light::trial(sender, to, sink, rate, Duration::from_secs(3), None).sent;
            });
            c.syscalls[r] = calls.map(|n| (n, sent.max(1)));
        }
    }
    for (r, &(rate, _)) in RATES.iter().enumerate() {
        if contestants.iter().all(|c| c.trials[r].is_empty()) {
            continue;
        }
        println!(
            "\n{} frames/s:\n\n| router | CPU/frame (median [min–max]) | syscalls/frame (epoll_wait/frame, timerfd_settime/s) | context switches/frame (migrations/s) | latency p50 / p99 (medians) | received |",
            rate as u64
        );
        println!("|---|---:|---:|---:|---|---:|");
        for c in &contestants {
            let trials = &c.trials[r];
            let cpu: Vec<f64> = trials.iter().filter_map(Trial::cpu_per_frame_us).collect();
            let lo = cpu.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = cpu.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let cpu_text = if cpu.is_empty() {
                "–".to_string()
            } else {
                format!("{:.2} µs [{lo:.2}–{hi:.2}]", light::median(cpu))
            };
            let p50 = light::median(trials.iter().map(|t| t.latency_us(0.5)).collect());
            let p99 = light::median(trials.iter().map(|t| t.latency_us(0.99)).collect());
            let sent: u64 = trials.iter().map(|t| t.sent).sum();
            let received: u64 = trials.iter().map(|t| t.received).sum();
            println!(
                "| {} | {cpu_text} | {} | {} | {p50:.1} / {p99:.1} µs | {received}/{sent} |",
                c.name,
                c.syscalls[r].map_or("–".to_string(), |(s, sent)| {
                    let per_s = rate / sent as f64;
                    format!(
                        "{:.2} ({:.2}, {:.1})",
                        s.total as f64 / sent as f64,
                        s.epoll_wait as f64 / sent as f64,
                        s.timer_settime as f64 * per_s
                    )
                }),
                c.syscalls[r].map_or("–".to_string(), |(s, sent)| {
                    format!(
                        "{:.2} ({:.1})",
                        s.context_switches as f64 / sent as f64,
                        s.migrations as f64 * rate / sent as f64
                    )
                }),
            );
        }
        paired_verdict(&contestants, r);
    }
}

/// How many times process `pid` has moved to another CPU (`se.nr_migrations` in
/// `/proc/PID/sched`), if the kernel says.
fn migrations(pid: u32) -> Option<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/sched")).ok()?;
    let line = text.lines().find(|l| l.starts_with("se.nr_migrations"))?;
    line.split(':').nth(1)?.trim().parse().ok()
}

/// Each mavtables build against mavlink-router, round by round (the two ran back to
/// back in every round, so the machine's drift over the run cancels): the median of
/// the per-round ratios of CPU per frame and of p50 latency, with the 95% interval of
/// that median, and whether the goal (no higher than mavlink-router) is shown
/// met, shown missed, or within the noise of this run. Then, when builds to compare
/// were given, this build against each of them the same way: a change judged against
/// the build before it.
fn paired_verdict(contestants: &[Contestant], r: usize) {
    let Some(theirs) = contestants.iter().find(|c| c.name == "mavlink-router") else {
        return;
    };
    println!("\nmavtables ÷ mavlink-router, paired by round (median [95% interval]):\n");
    let goal = ["below: goal met", "above: goal not met"];
    for c in contestants
        .iter()
        .filter(|c| c.name.starts_with("mavtables"))
    {
        let [cpu, p50, p99] = paired_ratios(c, theirs, r);
        println!(
            "- {}: CPU/frame {}; p50 {}; p99 {}",
            c.name,
            show_ratio(cpu, goal),
            show_ratio(p50, goal),
            show_ratio(p99, goal)
        );
    }
    let Some(ours) = contestants.iter().find(|c| c.name == "mavtables") else {
        return;
    };
    let befores: Vec<&Contestant> = contestants
        .iter()
        .filter(|c| c.name.starts_with("mavtables "))
        .collect();
    if befores.is_empty() {
        return;
    }
    println!("\nmavtables ÷ each build compared, paired by round (median [95% interval]):\n");
    for before in befores {
        let [cpu, p50, p99] = paired_ratios(ours, before, r);
        let change = ["lower", "higher"];
        println!(
            "- ÷ {}: CPU/frame {}; p50 {}; p99 {}",
            before.name,
            show_ratio(cpu, change),
            show_ratio(p50, change),
            show_ratio(p99, change)
        );
    }
}

/// Per round, `a`'s CPU per frame, p50 and p99 latency divided by `b`'s at rate `r`.
fn paired_ratios(a: &Contestant, b: &Contestant, r: usize) -> [Vec<f64>; 3] {
    let pairs = a.trials[r].iter().zip(&b.trials[r]);
    let cpu = pairs
        .clone()
        .filter_map(|(a, b)| Some(a.cpu_per_frame_us()? / b.cpu_per_frame_us()?))
        .collect();
    let latency = |q| {
        pairs
            .clone()
            .map(|(a, b)| a.latency_us(q) / b.latency_us(q))
            .collect()
    };
    [cpu, latency(0.5), latency(0.99)]
}

/// The median of `ratios` with its 95% interval, and what it shows: `says[0]` when the
/// whole interval is below 1, `says[1]` when above, else that it is within the noise.
fn show_ratio(ratios: Vec<f64>, says: [&str; 2]) -> String {
    match light::median_interval(ratios) {
        Some((m, lo, hi)) => {
            let verdict = if hi < 1.0 {
                says[0]
            } else if lo > 1.0 {
                says[1]
            } else {
                "within this run's noise"
            };
            format!("{m:.2} [{lo:.2}–{hi:.2}], {verdict}")
        }
        None => "–".to_string(),
    }
}
