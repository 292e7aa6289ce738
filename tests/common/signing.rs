//! Helpers of the signing tests (`tests/e2e/signing_peers.rs`, `tests/signing_attacks.rs`):
//! keys and key files, the router's signing clock, signed frames made with the crate's
//! encoder, the pymavlink signing peer (`tests/py/signing_peer.py`) and signing vehicle
//! (`tests/py/signing_vehicle.py`), MAVProxy with extra options, and the signing part of
//! the counters report.
//!
//! Included with `#[path = "common/signing.rs"] mod signing;` next to `mod common;`.
#![allow(dead_code)]

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use mavtables::wire::encode::{Header, SignWith, encode_v1, encode_v2};
use sha2::{Digest, Sha256};

use crate::common::mavproxy::mavproxy_command;
use crate::common::process::Proc;
use crate::common::python;
use crate::common::router::Scratch;

pub type Key = [u8; 32];

/// 2015-01-01 00:00:00 UTC in Unix seconds.
pub const EPOCH_2015: u64 = 1_420_070_400;

/// The signing clock now: UTC in 10 µs units since 2015-01-01.
pub fn now_ts() -> u64 {
    let since = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock after 1970")
        - Duration::from_secs(EPOCH_2015);
    (since.as_micros() / 10) as u64
}

/// One minute of the signing clock.
pub const MINUTE: u64 = 60 * 100_000;

/// The key MAVProxy's `signing setup PASSPHRASE` derives: SHA-256 of the passphrase.
pub fn passphrase_key(passphrase: &str) -> Key {
    Sha256::digest(passphrase.as_bytes()).into()
}

/// A key made of `seed`, `seed + 1`, … (wrapping).
pub fn key_from(seed: u8) -> Key {
    std::array::from_fn(|i| seed.wrapping_add(i as u8))
}

pub fn hex(bytes: &[u8]) -> String {
    crate::common::hex(bytes)
}

/// Writes a key file (`contents` and a newline) with mode 0600; returns its path.
pub fn key_file(scratch: &Scratch, name: &str, contents: &str) -> String {
    let path = scratch.path(name);
    std::fs::write(&path, format!("{contents}\n")).expect("write key file");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).expect("chmod 600");
    path
}

/// A key file holding `key` as 64 hex digits.
pub fn hex_key_file(scratch: &Scratch, name: &str, key: &Key) -> String {
    key_file(scratch, name, &hex(key))
}

/// A MAVLink 2 frame of message `id` from `sys.comp`, signed with `key`, `link_id` and
/// `timestamp`.
#[allow(clippy::too_many_arguments)]
pub fn signed(
    key: &Key,
    link_id: u8,
    timestamp: u64,
    sys: u8,
    comp: u8,
    seq: u8,
    id: u32,
    payload: &[u8],
) -> Vec<u8> {
    let mut out = Vec::new();
    encode_v2(
        Header {
            seq,
            system: sys,
            component: comp,
        },
        id,
        payload,
        Some(SignWith {
            key,
            link_id,
            timestamp,
        }),
        &mut out,
    )
    .expect("encode");
    out
}

/// An unsigned MAVLink 2 frame.
pub fn unsigned(sys: u8, comp: u8, seq: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    encode_v2(
        Header {
            seq,
            system: sys,
            component: comp,
        },
        id,
        payload,
        None,
        &mut out,
    )
    .expect("encode");
    out
}

/// A MAVLink 1 frame.
pub fn v1(sys: u8, comp: u8, seq: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    encode_v1(
        Header {
            seq,
            system: sys,
            component: comp,
        },
        id,
        payload,
        &mut out,
    )
    .expect("encode");
    out
}

/// ATTITUDE (id 30, 28 bytes) carrying the counter `n` in its first four payload bytes
/// (the rest non-zero, so every frame has the full payload).
pub fn attitude_payload(n: u32) -> Vec<u8> {
    let mut p = vec![0x5a; 28];
    p[..4].copy_from_slice(&n.to_le_bytes());
    p
}

/// A stream of signed ATTITUDE frames from one (link id, system, component): each call
/// gives the next one, numbered and with a timestamp one tick after the last.
pub struct Stream {
    pub key: Key,
    pub link_id: u8,
    pub sys: u8,
    pub comp: u8,
    pub next_ts: u64,
    pub next_n: u32,
}

impl Stream {
    pub fn new(key: Key, link_id: u8, sys: u8) -> Stream {
        Stream {
            key,
            link_id,
            sys,
            comp: 1,
            next_ts: now_ts(),
            next_n: 0,
        }
    }

    /// The next frame (counter, timestamp and sequence number all move on).
    pub fn next(&mut self) -> Vec<u8> {
        let f = signed(
            &self.key,
            self.link_id,
            self.next_ts,
            self.sys,
            self.comp,
            self.next_n as u8,
            30,
            &attitude_payload(self.next_n),
        );
        self.next_ts += 1;
        self.next_n += 1;
        f
    }
}

/// A Python helper in a process group of its own, stdout and stderr merged into one
/// line stream; the group is killed when dropped.
pub type Py = Proc;

/// `tests/py/SCRIPT ARGS…` with the pymavlink interpreter.
pub fn py_script(script: &str, args: &[String]) -> Py {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/py")
        .join(script);
    let mut cmd = Command::new(python());
    cmd.arg(path).args(args).env("PYTHONUNBUFFERED", "1");
    Proc::spawn(cmd, &format!("{script} {}", args.join(" ")))
}

/// One `recv` line of `signing_peer.py`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recv {
    pub name: String,
    /// `S.C`
    pub source: String,
    /// pymavlink's verdict.
    pub signed: bool,
    /// From the signature block; -1 if none.
    pub link: i64,
    pub ts: i64,
    /// The explicit hashlib check: `ok`, `bad` or `none`.
    pub check: String,
    pub hex: String,
}

impl Recv {
    pub fn parse(line: &str) -> Option<Recv> {
        let rest = line.strip_prefix("recv ")?;
        let f: Vec<&str> = rest.split(' ').collect();
        let [name, "from", source, signed, link, ts, check, hex] = f.as_slice() else {
            panic!("odd recv line {line:?}");
        };
        let val = |s: &str, k: &str| -> String {
            s.strip_prefix(k)
                .unwrap_or_else(|| panic!("{k} in {line:?}"))
                .to_string()
        };
        Some(Recv {
            name: name.to_string(),
            source: source.to_string(),
            signed: val(signed, "signed=") == "1",
            link: val(link, "link=").parse().expect("link"),
            ts: val(ts, "ts=").parse().expect("ts"),
            check: val(check, "check="),
            hex: hex.to_string(),
        })
    }
}

/// The pymavlink signing peer (`tests/py/signing_peer.py`).
pub struct SigPeer {
    pub py: Py,
}

impl SigPeer {
    /// Starts it with `args` (see the script) and waits for "ready".
    pub fn start(args: &[String]) -> SigPeer {
        let mut py = py_script("signing_peer.py", args);
        py.wait_for("ready", Duration::from_secs(20));
        SigPeer { py }
    }

    /// Sends a command line; returns the hex of the frame it sent.
    pub fn send(&mut self, command: &str) -> String {
        self.py.send_line(command);
        let line = self.py.wait_for("sent ", Duration::from_secs(10));
        line.strip_prefix("sent ").expect("sent HEX").to_string()
    }

    /// The next received message named `name` from a source starting with `from`.
    pub fn recv(&mut self, name: &str, from: &str, timeout: Duration) -> Recv {
        let pattern = format!("recv {name} from {from}");
        let line = self.py.wait_for(&pattern, timeout);
        Recv::parse(&line[line.find("recv ").expect("recv")..]).expect("recv line")
    }

    /// Every `recv` line so far.
    pub fn all_received(&self) -> Vec<Recv> {
        self.py
            .out
            .seen
            .iter()
            .filter_map(|l| Recv::parse(l))
            .collect()
    }

    /// pymavlink's signing counters now: (sig, good, bad, unsigned, reject).
    pub fn stats(&mut self) -> [u64; 5] {
        self.py.send_line("stats");
        let line = self.py.wait_for("stats ", Duration::from_secs(10));
        parse_stats(&line)
    }

    /// Stops it; returns every line.
    pub fn stop(mut self) -> Vec<String> {
        let lines = self.py.finish(Duration::from_secs(10));
        assert_eq!(
            lines.last().map(String::as_str),
            Some("end"),
            "the peer did not end cleanly: {lines:#?}"
        );
        lines
    }
}

/// `… sig=N good=N bad=N unsigned=N reject=N` → the five numbers.
pub fn parse_stats(line: &str) -> [u64; 5] {
    let mut out = [0u64; 5];
    for (i, k) in ["sig=", "good=", "bad=", "unsigned=", "reject="]
        .iter()
        .enumerate()
    {
        let at = line
            .find(&format!(" {k}"))
            .unwrap_or_else(|| panic!("no {k} in {line:?}"));
        out[i] = line[at + 1 + k.len()..]
            .chars()
            .take_while(char::is_ascii_digit)
            .collect::<String>()
            .parse()
            .expect("number");
    }
    out
}

/// MAVProxy with `--master=MASTER` and `extra` options, its home and state inside
/// `scratch` (no user keys or scripts); returns once its master link is open.
pub fn mavproxy(scratch: &Scratch, master: &str, extra: &[&str]) -> Py {
    let cmd = mavproxy_command(scratch, master, extra);
    let mut p = Py::spawn(cmd, &format!("mavproxy --master={master}"));
    p.wait_for("Log Directory:", Duration::from_secs(30));
    p
}

/// The signing counters of the report lines that have a `signing:` part, summed over
/// those lines: `(number, words)` pairs such as `(5, "verified")`, `(1, "bad signature")`.
pub fn signing_counts(report: &[String]) -> Vec<(u64, String)> {
    let mut totals: Vec<(u64, String)> = Vec::new();
    for line in report {
        let Some((_, part)) = line.split_once("signing: ") else {
            continue;
        };
        for item in part.split(',') {
            let item = item.trim();
            let Some((n, words)) = item.split_once(' ') else {
                continue;
            };
            let Ok(n) = n.parse::<u64>() else { continue };
            match totals.iter_mut().find(|(_, w)| w == words) {
                Some((t, _)) => *t += n,
                None => totals.push((n, words.to_string())),
            }
        }
    }
    totals
}

/// The summed count of the signing counters one of whose words starts with `what`
/// (`"bad"`, `"replay"`, `"window"`, `"unsigned"`, `"verified"`, `"signed"` — which is
/// not `"unsigned dropped"`); 0 if none.
pub fn count_of(counts: &[(u64, String)], what: &str) -> u64 {
    counts
        .iter()
        .filter(|(_, w)| w.split(' ').any(|word| word.starts_with(what)))
        .map(|(n, _)| n)
        .sum()
}

/// The counters report of the router's exit (the lines after the last heading).
pub fn exit_report(stderr: &[String]) -> Vec<String> {
    let start = stderr
        .iter()
        .rposition(|l| l.starts_with("mavtables counters:"))
        .unwrap_or_else(|| panic!("no counters report at exit: {stderr:#?}"));
    stderr[start + 1..].to_vec()
}

/// The counters report now (SIGUSR1, then SIGUSR1 again so that the second heading marks
/// where the first report ends): its lines, signing parts and all.
pub fn report_now(router: &mut crate::common::router::Router) -> Vec<String> {
    const HEADING: &str = "mavtables counters:";
    router.signal(libc::SIGUSR1);
    router.err.wait_for(HEADING, Duration::from_secs(10));
    let from = router.err.seen.len();
    router.signal(libc::SIGUSR1);
    router.err.wait_for(HEADING, Duration::from_secs(10));
    router.err.seen[from..router.err.seen.len() - 1]
        .iter()
        .filter(|l| l.starts_with("  "))
        .cloned()
        .collect()
}
