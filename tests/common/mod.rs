//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod browser;
pub mod disk;
pub mod fleet;
pub mod http_fixture;
pub mod mavproxy;
pub mod needs;
pub mod net;
pub mod process;
pub mod router;
pub mod stats_router;

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What a poll of [`eventually`] says: done (with a value), or not yet (and maybe why).
pub trait Polled {
    /// The value [`eventually`] returns once done.
    type Output;
    /// `Ok` when done; `Err` with what to say if the time runs out now.
    fn done(self) -> Result<Self::Output, Option<String>>;
}

impl Polled for bool {
    type Output = ();
    fn done(self) -> Result<(), Option<String>> {
        if self { Ok(()) } else { Err(None) }
    }
}

impl<T> Polled for Option<T> {
    type Output = T;
    fn done(self) -> Result<T, Option<String>> {
        self.ok_or(None)
    }
}

impl<T> Polled for Result<T, String> {
    type Output = T;
    fn done(self) -> Result<T, Option<String>> {
        self.map_err(Some)
    }
}

/// Polls `poll` every 5 ms until it is done (`true`, `Some`, `Ok`) and returns its
/// value; panics saying `what` did not happen within `timeout` (with the last `Err`'s
/// text). The tests' one deadline loop.
pub fn eventually<P: Polled>(
    what: impl Display,
    timeout: Duration,
    mut poll: impl FnMut() -> P,
) -> P::Output {
    let deadline = Instant::now() + timeout;
    loop {
        let why = match poll().done() {
            Ok(value) => return value,
            Err(why) => why,
        };
        if Instant::now() >= deadline {
            match why {
                Some(why) => panic!("{what}: not within {timeout:?}; {why}"),
                None => panic!("{what}: not within {timeout:?}"),
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Path of a fixture under `tests/data/`.
pub fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel)
}

/// Reads a fixture under `tests/data/`.
pub fn read_data(rel: &str) -> Vec<u8> {
    let p = data(rel);
    std::fs::read(&p).unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()))
}

/// The Python interpreter that has pymavlink: `$MAVTABLES_PYTHON`, else the repo's
/// `.venv` (which `scripts/test` creates). Panics with instructions if neither works,
/// so a missing peer fails loudly instead of skipping tests.
pub fn python() -> PathBuf {
    let candidates: Vec<PathBuf> = std::env::var_os("MAVTABLES_PYTHON")
        .map(PathBuf::from)
        .into_iter()
        .chain([Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python")])
        .collect();
    for c in &candidates {
        let ok = Command::new(c)
            .args(["-c", "import pymavlink"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        if ok {
            return c.clone();
        }
    }
    panic!(
        "no Python with pymavlink found (tried {candidates:?}); run scripts/test, which installs it into .venv"
    );
}

/// Runs a helper script from `tests/py/` with `input` on stdin; returns stdout.
pub fn run_py(script: &str, args: &[&str], input: &str) -> String {
    use std::io::Write;
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/py")
        .join(script);
    let mut child = Command::new(python())
        .arg(&path)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn python");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("write stdin");
    let out = child.wait_with_output().expect("python output");
    assert!(
        out.status.success(),
        "{script} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 output")
}

/// Lower-case hex of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Bytes of a hex string.
pub fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

/// Which verdict column of `tests/data/MANIFEST.md` to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The verdict the file name encodes (`pass.N` / `fail.N`): the grammar's, no CRC.
    Named,
    /// The strict framer's verdict: checksums with CRC_EXTRA checked.
    StrictCrc,
}

/// (file name, verdict) for every vector of one manifest section (`seed_scaled_pressure`
/// or `mavlink_full`).
pub fn manifest(section: &str, column: Verdict) -> Vec<(String, bool)> {
    let manifest = String::from_utf8(read_data("MANIFEST.md")).expect("utf-8");
    let mut rows = Vec::new();
    let mut inside = false;
    for line in manifest.lines() {
        if line.starts_with("## ") {
            inside = line.contains(section);
        } else if inside && (line.starts_with("| pass.") || line.starts_with("| fail.")) {
            let cols: Vec<&str> = line.split('|').map(str::trim).collect();
            let verdict = match column {
                Verdict::StrictCrc => cols[cols.len() - 2],
                Verdict::Named => cols[cols.len() - 4],
            };
            assert!(verdict == "pass" || verdict == "fail", "odd row: {line}");
            rows.push((cols[1].to_string(), verdict == "pass"));
        }
    }
    rows
}

/// A pseudo-terminal pair whose slave is reached through the symlink `device`, a serial
/// port for the router. Neither end is inherited by any child (a router or peer of
/// another test in this process holding the master open would keep the device from
/// ever going away).
pub fn pty_at(device: &str) -> (serialport::TTYPort, serialport::TTYPort) {
    use serialport::SerialPort;
    // `pair` opens both ends without FD_CLOEXEC; `try_clone_native` duplicates a
    // descriptor with F_DUPFD_CLOEXEC: the duplicates are kept, the originals closed.
    let (m, s) = serialport::TTYPort::pair().expect("pty pair");
    let master = m.try_clone_native().expect("FD_CLOEXEC master");
    let slave = s.try_clone_native().expect("FD_CLOEXEC slave");
    drop((m, s));
    let _ = std::fs::remove_file(device);
    std::os::unix::fs::symlink(slave.name().expect("pty name"), device).expect("symlink");
    (master, slave)
}
