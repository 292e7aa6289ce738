//! A log reader that does not keep up must not stall the router: with `--loglevel 3` and
//! standard output a pipe that nobody reads, every frame is still routed; the log lines
//! that did not fit are dropped and counted, and once standard output is read again a
//! line says how many were lost.
//!
//! Synchronisation is on events: the router's port being bound, its `new component`
//! log line (read before the reading stops), the listener receiving each burst.

use crate::common;

use std::collections::HashSet;
use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{ChildStdout, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::thread;
use std::time::{Duration, Instant};

use common::router::{Guard, Lines, Scratch, free_udp_port, udp_port_bound};
use mavtables::wire::encode::{Header, encode_v2};

const BIN: &str = env!("CARGO_BIN_EXE_mavtables");
/// Frames routed while nobody reads the log.
const FRAMES: usize = 3_000;
/// Frames sent before waiting for the listener to have them all (so that no kernel
/// socket buffer overflows).
const BURST: usize = 100;
/// ATTITUDE: a fixed-size message without target fields (broadcast to every other link).
const ATTITUDE: u32 = 30;
const ATTITUDE_LEN: usize = 28;
const HEARTBEAT: u32 = 0;

/// Reads standard output line by line up to the first line containing `pattern`, then
/// stops reading until told to go on; every line read is handed over.
fn read_until_then_pause(stdout: ChildStdout, pattern: &str) -> (Receiver<String>, Sender<()>) {
    let (lines_tx, lines_rx) = mpsc::channel();
    let (go_on_tx, go_on_rx) = mpsc::channel::<()>();
    let pattern = pattern.to_string();
    thread::spawn(move || {
        let mut paused_once = false;
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            let pause = !paused_once && line.contains(&pattern);
            if lines_tx.send(line).is_err() {
                break;
            }
            if pause {
                paused_once = true;
                if go_on_rx.recv().is_err() {
                    break;
                }
            }
        }
    });
    (lines_rx, go_on_tx)
}

/// The next line containing `pattern`, within `timeout`.
fn wait_for_line(lines: &Receiver<String>, pattern: &str, timeout: Duration) -> String {
    let deadline = Instant::now() + timeout;
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) if line.contains(pattern) => return line,
            Ok(line) => seen.push(line),
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => panic!(
                "no stdout line containing {pattern:?} within {timeout:?}; seen:\n{}",
                seen.join("\n")
            ),
        }
    }
}

/// Every remaining line until the stream closes (at most `timeout`).
fn rest(lines: &Receiver<String>, timeout: Duration) -> Vec<String> {
    let deadline = Instant::now() + timeout;
    let mut out = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => out.push(line),
            Err(RecvTimeoutError::Disconnected) => return out,
            Err(RecvTimeoutError::Timeout) => panic!("stdout did not close within {timeout:?}"),
        }
    }
}

fn frame(id: u32, payload: &[u8], seq: u8, system: u8) -> Vec<u8> {
    let header = Header {
        seq,
        system,
        component: 1,
    };
    let mut out = Vec::new();
    encode_v2(header, id, payload, None, &mut out).expect("encode");
    out
}

/// ATTITUDE number `n`: `n + 1` as its `time_boot_ms`, so that every frame differs.
fn attitude(n: usize) -> Vec<u8> {
    let mut payload = [0x11u8; ATTITUDE_LEN];
    let stamp = u32::try_from(n + 1).expect("small n");
    payload[..4].copy_from_slice(&stamp.to_le_bytes());
    frame(ATTITUDE, &payload, n as u8, 1)
}

/// Datagrams that are among `wanted` and not yet in `got`, until `got` holds `until`
/// of them or `deadline` passes.
fn receive(
    socket: &UdpSocket,
    wanted: &HashSet<Vec<u8>>,
    got: &mut HashSet<Vec<u8>>,
    until: usize,
    deadline: Instant,
) {
    let mut buf = [0u8; 512];
    while got.len() < until && Instant::now() < deadline {
        if let Ok(n) = socket.recv(&mut buf)
            && wanted.contains(&buf[..n])
        {
            got.insert(buf[..n].to_vec());
        }
    }
}

/// `YYYY-MM-DD HH:MM:SS  N log lines dropped: …` → N.
fn dropped_count(line: &str) -> Option<u64> {
    const TAIL: &str = " log lines dropped: standard output was not read fast enough";
    let bytes = line.as_bytes();
    let shape_ok = line.len() > 21
        && bytes[4] == b'-'
        && bytes[7] == b'-'
        && bytes[10] == b' '
        && bytes[13] == b':'
        && bytes[16] == b':'
        && &line[19..21] == "  ";
    if !shape_ok {
        return None;
    }
    line[21..].strip_suffix(TAIL)?.parse().ok()
}

#[test]
fn a_stuck_log_reader_does_not_stall_routing() {
    let scratch = Scratch::new("log-backpressure");
    let port = free_udp_port();
    let config_path = scratch.dir.join("mavtables.conf");
    let config = format!(
        "default_action accept;\nudp {{ port {port}; address 127.0.0.1; }}\nchain default {{ accept; }}\n"
    );
    std::fs::write(&config_path, config).expect("write config");
    let mut child = Command::new(BIN)
        .arg("--config")
        .arg(&config_path)
        .args(["--loglevel", "3"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn mavtables");
    let stdout = child.stdout.take().expect("stdout");
    let mut stderr = Lines::new(child.stderr.take().expect("stderr"), "router stderr");
    let mut router = Guard(Some(child));
    let bound_by = Instant::now() + Duration::from_secs(10);
    while !udp_port_bound(port) {
        assert!(Instant::now() < bound_by, "port {port} never bound");
        assert!(
            router.child().try_wait().ok().flatten().is_none(),
            "router exited"
        );
        thread::sleep(Duration::from_millis(5));
    }
    let router_addr = format!("127.0.0.1:{port}");

    // The listener makes itself known; after that line standard output is not read.
    let (lines, go_on) = read_until_then_pause(stdout, "new component 200.1 on");
    let listener = UdpSocket::bind("127.0.0.1:0").expect("bind listener");
    listener
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("read timeout");
    let heartbeat = frame(HEARTBEAT, &[0, 0, 0, 0, 6, 8, 0, 0, 3], 0, 200);
    listener.send_to(&heartbeat, &router_addr).expect("send");
    wait_for_line(&lines, "new component 200.1 on", Duration::from_secs(10));

    // Bursts of frames while the pipe fills and stays full.
    let sender = UdpSocket::bind("127.0.0.1:0").expect("bind sender");
    let sent: Vec<Vec<u8>> = (0..FRAMES).map(attitude).collect();
    let wanted: HashSet<Vec<u8>> = sent.iter().cloned().collect();
    let mut got = HashSet::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    for (i, burst) in sent.chunks(BURST).enumerate() {
        for f in burst {
            sender.send_to(f, &router_addr).expect("send");
        }
        receive(&listener, &wanted, &mut got, (i + 1) * BURST, deadline);
        assert_eq!(
            got.len(),
            (i + 1) * BURST,
            "the listener got {} of {FRAMES} frames within 20 s while standard output was not read",
            got.len()
        );
    }

    // Reading again: routing goes on, and once the backlog is read a line says how many
    // lines were lost (each frame makes new lines, which bring the count with them).
    go_on.send(()).expect("resume reading");
    let mut out: Vec<String> = Vec::new();
    let mut extra = 0;
    let until = Instant::now() + Duration::from_secs(5);
    while !out.iter().any(|l| dropped_count(l).is_some()) {
        assert!(
            Instant::now() < until,
            "no 'log lines dropped' line within 5 s of reading again"
        );
        let f = attitude(FRAMES + extra);
        extra += 1;
        sender.send_to(&f, &router_addr).expect("send");
        let mut got_it = HashSet::new();
        let one: HashSet<Vec<u8>> = [f].into();
        receive(&listener, &one, &mut got_it, 1, until);
        assert_eq!(
            got_it.len(),
            1,
            "a frame was not routed after reading resumed"
        );
        out.extend(lines.try_iter());
    }

    // It stops cleanly and promptly; no line is unaccounted for.
    let pid = nix::unistd::Pid::from_raw(router.child().id() as i32);
    assert_eq!(
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM),
        Ok(()),
        "kill"
    );
    let status = router
        .wait(Duration::from_secs(5))
        .expect("no exit within 5 s of SIGTERM");
    assert!(status.success(), "exit status {status}");

    out.extend(rest(&lines, Duration::from_secs(5)));
    let counts: Vec<u64> = out.iter().filter_map(|l| dropped_count(l)).collect();
    assert!(counts.iter().all(|n| *n > 0), "{counts:?}");
    // Every frame gave a `received` and an `accepted` line: each was kept or counted.
    let kept = out
        .iter()
        .filter(|l| l.contains(" ATTITUDE (#30) "))
        .count() as u64;
    let dropped: u64 = counts.iter().sum();
    let produced = 2 * (FRAMES + extra) as u64;
    assert_eq!(
        kept + dropped,
        produced,
        "{kept} ATTITUDE lines kept and {dropped} dropped, for {produced} made"
    );
    let err = stderr.rest(Duration::from_secs(5)).join("\n");
    let counters = format!(
        "127.0.0.1:{}: in {} frames",
        sender.local_addr().expect("addr").port(),
        FRAMES + extra
    );
    assert!(err.contains(&counters), "stderr lacks {counters:?}:\n{err}");
}
