//! Running the real router and its peers for the end-to-end tests: a scratch directory,
//! the `mavtables` binary with a config in the config language, pymavlink peers
//! (`tests/py/peer.py`), and line readers that wait for events with a time limit.
//!
//! Every child process is killed when its guard is dropped, so a failing assertion never
//! leaves a router or a peer behind.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::thread;
use std::time::{Duration, Instant};

use super::python;

/// The router under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_mavtables");

/// A directory of its own for one test (configs, pty symlinks); removed on drop.
pub struct Scratch {
    pub dir: PathBuf,
}

impl Scratch {
    pub fn new(tag: &str) -> Scratch {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "mavtables-e2e-{}-{}-{tag}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).expect("scratch dir");
        Scratch { dir }
    }

    /// A path inside the directory, as a string (for configs and peer arguments).
    pub fn path(&self, name: &str) -> String {
        self.dir.join(name).display().to_string()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Lines of a child's output stream, read by a thread, waited for with a time limit.
pub struct Lines {
    rx: Receiver<String>,
    /// Every line taken from the stream so far.
    pub seen: Vec<String>,
    closed: bool,
    what: String,
}

impl Lines {
    pub fn new(stream: impl Read + Send + 'static, what: &str) -> Lines {
        let (tx, rx) = mpsc::channel();
        thread::spawn(move || {
            for line in BufReader::new(stream).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Lines {
            rx,
            seen: Vec::new(),
            closed: false,
            what: what.to_string(),
        }
    }

    fn next(&mut self, deadline: Instant) -> Option<String> {
        if self.closed {
            return None;
        }
        let left = deadline.saturating_duration_since(Instant::now());
        match self.rx.recv_timeout(left) {
            Ok(line) => {
                self.seen.push(line.clone());
                Some(line)
            }
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => {
                self.closed = true;
                None
            }
        }
    }

    /// The next line containing `pattern` (lines before it are kept in `seen`), or None if
    /// none comes within `timeout`.
    pub fn within(&mut self, pattern: &str, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        while let Some(line) = self.next(deadline) {
            if line.contains(pattern) {
                return Some(line);
            }
        }
        None
    }

    /// The next line containing `pattern` (lines before it are kept in `seen`); panics,
    /// showing what was seen, if none comes within `timeout`.
    pub fn wait_for(&mut self, pattern: &str, timeout: Duration) -> String {
        self.within(pattern, timeout).unwrap_or_else(|| {
            panic!(
                "{}: no line containing {pattern:?} within {timeout:?} (stream {}); seen:\n{}",
                self.what,
                if self.closed { "closed" } else { "open" },
                self.seen.join("\n")
            )
        })
    }

    /// Every line until the stream closes (or `timeout` passes).
    pub fn rest(&mut self, timeout: Duration) -> Vec<String> {
        let deadline = Instant::now() + timeout;
        let mut out = Vec::new();
        while let Some(line) = self.next(deadline) {
            out.push(line);
        }
        out
    }

    /// Lines that are already there, without waiting.
    pub fn drain(&mut self) -> Vec<String> {
        let mut out = Vec::new();
        while let Ok(line) = self.rx.try_recv() {
            self.seen.push(line.clone());
            out.push(line);
        }
        out
    }
}

/// A child process that is killed when dropped.
pub struct Guard(pub Option<Child>);

impl Guard {
    /// The child (panics if it was already waited for).
    pub fn child(&mut self) -> &mut Child {
        self.0.as_mut().expect("child")
    }

    /// Waits up to `timeout` for the child to exit.
    pub fn wait(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let deadline = Instant::now() + timeout;
        loop {
            self.0.as_ref()?;
            if let Ok(Some(status)) = self.child().try_wait() {
                self.0 = None;
                return Some(status);
            }
            if Instant::now() >= deadline {
                return None;
            }
            thread::sleep(Duration::from_millis(5));
        }
    }

    fn pid(&mut self) -> i32 {
        self.child().id() as i32
    }
}

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// How the router ended.
pub struct Stopped {
    pub status: ExitStatus,
    /// From the signal to the exit.
    pub took: Duration,
    /// Every line of standard output.
    pub stdout: Vec<String>,
    /// Every line of standard error.
    pub stderr: Vec<String>,
}

/// The running router.
pub struct Router {
    guard: Guard,
    /// Standard output (log lines).
    pub out: Lines,
    /// Standard error (warnings, counters).
    pub err: Lines,
    /// The config file.
    pub config: PathBuf,
}

/// The optimised router that `scripts/test` builds (`cargo build --release`) and names in
/// `MAVTABLES_RELEASE_ROUTER`, for tests of what users run at full rate; `None` when the
/// tests run without it (plain `cargo test`).
pub fn release_binary() -> Option<String> {
    std::env::var("MAVTABLES_RELEASE_ROUTER")
        .ok()
        .filter(|p| std::path::Path::new(p).is_file())
}

impl Router {
    /// Writes `config` to the scratch directory and starts `mavtables --config FILE
    /// --loglevel LEVEL`. Returns once every `udp` port the config names is bound.
    pub fn start(scratch: &Scratch, config: &str, loglevel: u8) -> Router {
        Router::start_binary(BIN, scratch, config, loglevel)
    }

    /// [`Router::start`] with the binary at `bin` (e.g. [`release_binary`]).
    pub fn start_binary(bin: &str, scratch: &Scratch, config: &str, loglevel: u8) -> Router {
        let path = scratch.dir.join("mavtables.conf");
        std::fs::write(&path, config).expect("write config");
        let mut child = Command::new(bin)
            .arg("--config")
            .arg(&path)
            .arg("--loglevel")
            .arg(loglevel.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn mavtables");
        let out = Lines::new(child.stdout.take().expect("stdout"), "router stdout");
        let err = Lines::new(child.stderr.take().expect("stderr"), "router stderr");
        let mut router = Router {
            guard: Guard(Some(child)),
            out,
            err,
            config: path,
        };
        for port in udp_ports(config) {
            router.wait_bound(port);
        }
        router
    }

    fn wait_bound(&mut self, port: u16) {
        super::eventually(
            format!("port {port} bound"),
            Duration::from_secs(10),
            || {
                if let Ok(Some(status)) = self.guard.child().try_wait() {
                    panic!(
                        "mavtables exited ({status}) before binding port {port}: {}",
                        self.err.rest(Duration::from_secs(1)).join("\n")
                    );
                }
                udp_port_bound(port)
            },
        );
    }

    /// The next log line containing `pattern`.
    pub fn wait_for(&mut self, pattern: &str) -> String {
        self.out.wait_for(pattern, Duration::from_secs(10))
    }

    /// The process id.
    pub fn pid(&mut self) -> u32 {
        self.guard.child().id()
    }

    /// Sends `signal` (e.g. `libc::SIGTERM`).
    pub fn signal(&mut self, signal: i32) {
        let pid = self.guard.pid();
        let sig = nix::sys::signal::Signal::try_from(signal).expect("a signal number");
        let rc = nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), sig);
        assert_eq!(rc, Ok(()), "kill({pid}, {signal})");
    }

    /// Sends `signal` and waits (at most 5 s) for the exit; collects all output.
    pub fn stop_with(mut self, signal: i32) -> Stopped {
        let start = Instant::now();
        self.signal(signal);
        let status = self
            .guard
            .wait(Duration::from_secs(5))
            .expect("mavtables did not exit within 5 s of the signal");
        let took = start.elapsed();
        let mut stdout = std::mem::take(&mut self.out.seen);
        stdout.extend(self.out.rest(Duration::from_secs(2)));
        let mut stderr = std::mem::take(&mut self.err.seen);
        stderr.extend(self.err.rest(Duration::from_secs(2)));
        Stopped {
            status,
            took,
            stdout,
            stderr,
        }
    }

    /// SIGTERM, and the exit must be clean.
    pub fn stop(self) -> Stopped {
        let stopped = self.stop_with(libc::SIGTERM);
        assert!(
            stopped.status.success(),
            "mavtables exited with {}: {}",
            stopped.status,
            stopped.stderr.join("\n")
        );
        stopped
    }
}

/// The `port N;` values of a config's `udp` blocks (simple configs of these tests only).
fn udp_ports(config: &str) -> Vec<u16> {
    let mut ports = Vec::new();
    for part in config.split("udp").skip(1) {
        let block = part.split('}').next().unwrap_or("");
        if let Some(p) = block.split("port").nth(1) {
            let digits: String = p
                .trim_start()
                .chars()
                .take_while(char::is_ascii_digit)
                .collect();
            if let Ok(n) = digits.parse() {
                ports.push(n);
            }
        }
    }
    ports
}

/// True if some UDP socket, IPv4 or IPv6, is bound to `port` (from /proc/net/udp{,6}).
pub fn udp_port_bound(port: u16) -> bool {
    let wanted = format!(":{port:04X}");
    ["/proc/net/udp", "/proc/net/udp6"].iter().any(|file| {
        let table = std::fs::read_to_string(file).unwrap_or_default();
        table.lines().skip(1).any(|l| {
            l.split_whitespace()
                .nth(1)
                .is_some_and(|local| local.ends_with(&wanted))
        })
    })
}

/// A UDP port that is free right now on 127.0.0.1.
pub fn free_udp_port() -> u16 {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    s.local_addr().expect("addr").port()
}

/// `127.0.0.1:PORT` → `127.0.0.1` in every link name of a log line (the original's tests
/// strip the port with sed: it changes from run to run).
pub fn strip_ports(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut rest = line;
    while let Some(i) = rest.find("127.0.0.1:") {
        let after = &rest[i + "127.0.0.1:".len()..];
        let digits = after.bytes().take_while(u8::is_ascii_digit).count();
        out.push_str(&rest[..i + "127.0.0.1".len()]);
        if digits == 0 {
            out.push(':');
        }
        rest = &after[digits..];
    }
    out.push_str(rest);
    out
}

/// A pymavlink peer (`tests/py/peer.py`).
pub struct Peer {
    guard: Guard,
    stdin: Option<ChildStdin>,
    /// The symlink a `--serial` peer points at its pty (removed before the peer ends).
    serial_link: Option<PathBuf>,
    /// Its standard output.
    pub out: Lines,
}

impl Peer {
    /// Starts `peer.py ARGS` and waits for its "setup" line (its link exists).
    pub fn start<S: AsRef<str>>(args: &[S]) -> Peer {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/py/peer.py");
        let mut child = Command::new(python())
            .arg(script)
            .args(args.iter().map(AsRef::as_ref))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn peer.py");
        let what = format!(
            "peer {}",
            args.iter()
                .take(6)
                .map(AsRef::as_ref)
                .collect::<Vec<_>>()
                .join(" ")
        );
        let out = Lines::new(child.stdout.take().expect("stdout"), &what);
        let stdin = child.stdin.take();
        let serial_link = args
            .iter()
            .map(AsRef::as_ref)
            .skip_while(|a| *a != "--serial")
            .nth(1)
            .map(PathBuf::from);
        let mut peer = Peer {
            guard: Guard(Some(child)),
            stdin,
            serial_link,
            out,
        };
        peer.out.wait_for("setup", Duration::from_secs(20));
        peer
    }

    /// Lets it act (listen: send its HEARTBEAT; send: send its messages).
    pub fn go(&mut self) {
        let stdin = self.stdin.as_mut().expect("stdin");
        stdin.write_all(b"go\n").expect("write go");
        stdin.flush().expect("flush");
    }

    /// A listener: lets it go and waits until its HEARTBEAT is out.
    pub fn go_ready(&mut self) {
        self.go();
        self.out.wait_for("ready", Duration::from_secs(10));
    }

    /// A sender: waits for "done"; returns the frames it sent (hex), in order.
    pub fn sent(&mut self, timeout: Duration) -> Vec<String> {
        self.out.wait_for("done", timeout);
        self.out
            .seen
            .iter()
            .filter_map(|l| l.strip_prefix("sent ").map(str::to_string))
            .collect()
    }

    /// A listener: waits for its end; returns what it received, one `NAME from S.C HEX`
    /// per message.
    pub fn received(&mut self, timeout: Duration) -> Vec<Received> {
        self.out.wait_for("end", timeout);
        let _ = self.guard.wait(Duration::from_secs(5));
        self.out
            .seen
            .iter()
            .filter(|l| l.contains(" from ") || l.starts_with("BAD_DATA"))
            .map(|l| {
                let parts: Vec<&str> = l.split(' ').collect();
                match parts.as_slice() {
                    [name, "from", source, hex] => Received {
                        name: name.to_string(),
                        source: source.to_string(),
                        hex: hex.to_string(),
                    },
                    _ => Received {
                        name: l.clone(),
                        source: String::new(),
                        hex: String::new(),
                    },
                }
            })
            .collect()
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        // The path goes before the pty: a router still retrying it must not open the
        // next pty the kernel gives the same number (another test's).
        if let Some(link) = &self.serial_link {
            let _ = std::fs::remove_file(link);
        }
        // Closing stdin lets a sender exit (a serial sender keeps its pty open till then).
        self.stdin = None;
        let _ = self.guard.wait(Duration::from_millis(500));
    }
}

/// One message a listener received.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    pub name: String,
    /// `S.C`
    pub source: String,
    /// The whole frame as received, in hex.
    pub hex: String,
}

/// Hex frames of `received`, in order.
pub fn hexes(received: &[Received]) -> Vec<String> {
    received.iter().map(|r| r.hex.clone()).collect()
}

/// Names of `received`, in order.
pub fn names(received: &[Received]) -> Vec<String> {
    received.iter().map(|r| r.name.clone()).collect()
}

/// The message types pymavlink and our dialect both have, with the same name, CRC_EXTRA
/// and payload size: `(v1 names, v2 names)`, by id. v1 is limited to ids below 256 and
/// compares the base payload, v2 the payload with extensions.
pub fn shared_messages() -> (Vec<&'static str>, Vec<&'static str>) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/py/peer.py");
    let out = Command::new(python())
        .arg(script)
        .arg("dialect")
        .stdin(Stdio::null())
        .output()
        .expect("peer.py dialect");
    assert!(out.status.success(), "peer.py dialect failed");
    let text = String::from_utf8(out.stdout).expect("utf-8");
    let mut v1 = BTreeMap::new();
    let mut v2 = BTreeMap::new();
    for line in text.lines() {
        let f: Vec<&str> = line.split(' ').collect();
        let [version, id, name, crc, size] = f.as_slice() else {
            panic!("bad dialect line {line:?}");
        };
        let id: u32 = id.parse().expect("id");
        let Some(ours) = mavtables::dialect::by_id(id) else {
            continue;
        };
        if ours.name != *name || u32::from(ours.crc_extra) != crc.parse::<u32>().expect("crc") {
            continue;
        }
        let size: usize = size.parse().expect("size");
        if *version == "v1" && id < 256 && size == usize::from(ours.min_len) {
            v1.insert(id, ours.name);
        } else if *version == "v2" && size == usize::from(ours.max_len) {
            v2.insert(id, ours.name);
        }
    }
    (v1.into_values().collect(), v2.into_values().collect())
}
