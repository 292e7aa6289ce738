//! Flight logs kept within bounds, end to end: the real router with a `flight_log`
//! block and the scripted ArduPilot (`tests/py/ardupilot_log_peer.py`) arming several
//! times, one log (one file) per arming. Beyond `max_files`, and while the disk would
//! have less than `min_free_bytes` free (a 1 MiB tmpfs: needs root), the oldest logs
//! the router made are removed — never a file of the user's, even one with a name of
//! the pattern that is older than all of them — and every log kept is whole.

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::disk::{Tmpfs, date_back, new_year};
use common::router::{Scratch, free_udp_port};
use common::{run_py, stats_router};

/// The `.bin` files in `dir`.
fn bins(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "bin"));
    files.sort();
    files
}

/// A dataflash log of `records` ATT records made at `path`, zero-padded to whole
/// 200-byte blocks as it is streamed (and written).
fn make_log(path: &str, records: usize) -> Vec<u8> {
    run_py(
        "dataflash_log.py",
        &["make", path, "--records", &records.to_string()],
        "",
    );
    let mut log = fs::read(path).expect("the made log");
    log.resize(log.len().div_ceil(200) * 200, 0);
    log
}

/// A file of the user's at `path`, a name the pattern makes, dated back to 1999: older
/// than any log. Returns its bytes.
fn plant(path: &Path) -> Vec<u8> {
    let bytes: Vec<u8> = (0..20_000u32).map(|i| (i * 7 % 251) as u8).collect();
    fs::write(path, &bytes).expect("plant");
    date_back(path, new_year(1999));
    bytes
}

/// A router writing flight logs of system 1 to `dir` with `limits`, its `/stats` on
/// the second value.
fn start(scratch: &Scratch, port: u16, dir: &Path, limits: &str) -> (common::router::Router, u16) {
    let config = format!(
        "udp {{ port {port}; address 127.0.0.1; }}\n\
         flight_log {{ system 1; path {}/flight-%Y%m%d-%H%M%S; mode while_armed; {limits} }}\n\
         default_action accept;\n",
        dir.display()
    );
    stats_router::start(scratch, &config)
}

/// One arming of the scripted ArduPilot streaming `log` (the `n`th log of the run):
/// waits until the router has closed its file and returns the file it made (the one
/// `dir` did not hold before).
fn fly(port: u16, http: u16, log: &str, n: u64, dir: &Path) -> PathBuf {
    let before = bins(dir);
    let out = run_py(
        "ardupilot_log_peer.py",
        &["--udp", &format!("127.0.0.1:{port}"), "--log", log],
        "",
    );
    assert!(out.contains("stop yes"), "{out}");
    // The file is closed 2 s after the disarm.
    common::eventually("the log closed", Duration::from_secs(10), || {
        let s = stats_router::stats(http);
        let f = &s["flight_log"];
        f["files"].as_u64() == Some(n) && f["streaming"].is_null()
    });
    let made: Vec<PathBuf> = bins(dir)
        .into_iter()
        .filter(|p| !before.contains(p))
        .collect();
    let [made] = made.as_slice() else {
        panic!("expected one new log in {}: {made:?}", dir.display());
    };
    made.clone()
}

/// The names on the router's list of the logs it made (`.PATTERN.bin.mavtables`).
fn made_list(dir: &Path) -> String {
    fs::read_to_string(dir.join(".flight-%Y%m%d-%H%M%S.bin.mavtables")).unwrap_or_default()
}

fn name(p: &Path) -> String {
    p.file_name()
        .expect("a file name")
        .to_string_lossy()
        .to_string()
}

/// Bytes free for an unprivileged user on the file system of `dir`.
fn free_bytes(dir: &Path) -> u64 {
    let out = Command::new("stat")
        .args(["-f", "-c", "%a %S"])
        .arg(dir)
        .output()
        .expect("stat -f");
    let text = String::from_utf8_lossy(&out.stdout);
    let mut n = text
        .split_whitespace()
        .map(|w| w.parse::<u64>().expect("a number"));
    n.next().expect("blocks") * n.next().expect("block size")
}

#[test]
fn beyond_max_files_the_oldest_logs_are_removed_never_other_files() {
    let scratch = Scratch::new("flight-log-max-files");
    let log = scratch.path("source.bin");
    let source = make_log(&log, 400);
    let dir = scratch.dir.join("logs");
    fs::create_dir_all(&dir).expect("logs dir");
    let planted = dir.join("flight-19991231-235959.bin");
    let bytes = plant(&planted);
    let port = free_udp_port();
    let (router, http) = start(&scratch, port, &dir, "max_files 2; min_free_bytes 0;");
    let mut made = Vec::new();
    for n in 1..=4 {
        made.push(fly(port, http, &log, n, &dir));
        // The newest two are kept; the older ones were removed as the next was created.
        let kept: Vec<&PathBuf> = made.iter().rev().take(2).collect();
        for (i, f) in made.iter().enumerate() {
            assert_eq!(
                f.exists(),
                kept.contains(&f),
                "after arming {n}: the log of arming {}",
                i + 1
            );
        }
        assert_eq!(
            fs::read(&planted).ok().as_ref(),
            Some(&bytes),
            "the user's file is never removed"
        );
    }
    for f in &made[2..] {
        assert!(fs::read(f).expect("a kept log") == source, "{f:?} whole");
    }
    let list = made_list(&dir);
    for (i, f) in made.iter().enumerate() {
        assert_eq!(list.contains(&name(f)), i >= 2, "{list}");
    }
    // The user's file by its name: a bare "1999" also occurs in the list's nanosecond
    // birth times (…59971999), which failed this test now and then.
    assert!(!list.contains(&name(&planted)), "{list}");
    let s = stats_router::stats(http);
    let f = &s["flight_log"];
    assert_eq!(f["files"].as_u64(), Some(4), "{f:#}");
    assert_eq!(f["removed"].as_u64(), Some(2), "{f:#}");
    assert_eq!(f["lost"].as_u64(), Some(0), "{f:#}");
    assert_eq!(f["dropped_disk"].as_u64(), Some(0), "{f:#}");
    router.stop();
    assert_eq!(bins(&dir).len(), 3, "two logs and the user's file");
}

#[test]
#[ignore = "needs root to mount a small tmpfs; scripts/test runs it"]
fn old_flight_logs_make_room_for_min_free_bytes_never_other_files() {
    let scratch = Scratch::new("flight-log-room");
    let log = scratch.path("source.bin");
    // 695 blocks: 139,000 bytes, 34 pages of the tmpfs.
    let source = make_log(&log, 6000);
    let dir = scratch.dir.join("disk");
    let _disk = Tmpfs::mount(&dir);
    let planted = dir.join("flight-19991231-235959.bin");
    let bytes = plant(&planted);
    // 1 MiB less the user's file and the list of logs: room above the floor for two
    // logs; the third needs the first's place, the fourth the second's.
    let min_free = 700_000;
    let port = free_udp_port();
    let (router, http) = start(
        &scratch,
        port,
        &dir,
        &format!("max_files 0; min_free_bytes {min_free};"),
    );
    let mut made = Vec::new();
    for n in 1..=4 {
        made.push(fly(port, http, &log, n, &dir));
        let kept: Vec<&PathBuf> = made.iter().rev().take(2).collect();
        for (i, f) in made.iter().enumerate() {
            assert_eq!(
                f.exists(),
                kept.contains(&f),
                "after arming {n}: the log of arming {}",
                i + 1
            );
        }
        assert!(
            free_bytes(&dir) >= min_free,
            "after arming {n}: {} bytes free",
            free_bytes(&dir)
        );
        assert_eq!(
            fs::read(&planted).ok().as_ref(),
            Some(&bytes),
            "the user's file is never removed, though older than every log"
        );
    }
    for f in &made[2..] {
        assert!(fs::read(f).expect("a kept log") == source, "{f:?} whole");
    }
    let list = made_list(&dir);
    for (i, f) in made.iter().enumerate() {
        assert_eq!(list.contains(&name(f)), i >= 2, "{list}");
    }
    let s = stats_router::stats(http);
    let f = &s["flight_log"];
    assert_eq!(f["files"].as_u64(), Some(4), "{f:#}");
    assert_eq!(f["removed"].as_u64(), Some(2), "{f:#}");
    assert_eq!(
        f["dropped_disk"].as_u64(),
        Some(0),
        "nothing dropped: {f:#}"
    );
    assert_eq!(f["lost"].as_u64(), Some(0), "{f:#}");
    let stopped = router.stop();
    let said = stopped
        .stderr
        .iter()
        .filter(|l| l.contains("less than min_free_bytes"))
        .count();
    assert_eq!(said, 0, "room was always made: {:?}", stopped.stderr);
}
