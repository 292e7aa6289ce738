//! Recording, end to end: the real router with a `record` block, pymavlink peers on
//! 127.0.0.1, and the recordings read back by pymavlink (`tests/py/tlog_read.py`, what
//! ground stations use) and by `mavtables inspect`.
//!
//! The disk tests mount a 1 MiB tmpfs, which needs root: they are `#[ignore]`d for a
//! plain `cargo test`, `scripts/test` runs them, and without the right to mount they fail
//! saying so. Others run the router under a file-size limit (`prlimit`).

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use common::disk::{Tmpfs, date_back, new_year};
use common::router::{BIN, Guard, Peer, Router, Scratch, Stopped, free_udp_port, hexes};
use common::run_py;

/// A mix of message types of several lengths (a target on COMMAND_LONG).
const MIX: &[&str] = &[
    "HEARTBEAT",
    "ATTITUDE",
    "SYS_STATUS",
    "GPS_RAW_INT",
    "COMMAND_LONG@9.1",
    "VFR_HUD",
    "SCALED_PRESSURE",
];

fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// `n` items cycling through [`MIX`].
fn items(n: usize) -> Vec<String> {
    MIX.iter().cycle().take(n).map(|s| s.to_string()).collect()
}

/// `n` items cycling through [`MIX`] without the targeted one: broadcasts, which the
/// router delivers to a listener whatever its address.
fn broadcasts(n: usize) -> Vec<String> {
    MIX.iter()
        .filter(|s| !s.contains('@'))
        .cycle()
        .take(n)
        .map(|s| s.to_string())
        .collect()
}

/// Starts a sender of `items` as `sys.comp` towards the router's `port`, lets it send and
/// returns the frames it sent (hex) once it is done.
fn send(port: u16, sys: u8, items: &[String]) -> Vec<String> {
    let mut args = vec![
        "send".to_string(),
        "--udp".to_string(),
        format!("127.0.0.1:{port}"),
        "--sys".to_string(),
        sys.to_string(),
        "--comp".to_string(),
        "1".to_string(),
    ];
    args.extend(items.iter().cloned());
    let mut peer = Peer::start(&args);
    peer.go();
    peer.sent(Duration::from_secs(20))
}

/// A listener on the router's `port` as `sys.1` that ends after `count` messages.
fn listener(port: u16, sys: u8, count: usize) -> Peer {
    let mut peer = Peer::start(&[
        "listen",
        "--udp",
        &format!("127.0.0.1:{port}"),
        "--sys",
        &sys.to_string(),
        "--comp",
        "1",
        "--count",
        &count.to_string(),
        "--timeout",
        "30",
    ]);
    peer.go_ready();
    peer
}

/// The `.tlog` files in `dir`, oldest first (by their first record's time, then name).
fn recordings(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "tlog"))
                .collect()
        })
        .unwrap_or_default();
    files.sort_by_key(|p| {
        let bytes = fs::read(p).unwrap_or_default();
        let first = bytes.get(..8).map_or(u64::MAX, |b| {
            u64::from_be_bytes(b.try_into().unwrap_or([0xff; 8]))
        });
        (first, p.clone())
    });
    files
}

/// One record as pymavlink read it.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Rec {
    file: usize,
    stamp_us: u64,
    hex: String,
}

/// Every record of `files` in order, as pymavlink reads them; fails on data it cannot
/// decode.
fn read_with_pymavlink(files: &[PathBuf]) -> Vec<Rec> {
    let args: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = run_py("tlog_read.py", &args, "");
    out.lines()
        .map(|line| {
            assert!(!line.starts_with("BAD_DATA"), "pymavlink: {line}");
            let parts: Vec<&str> = line.split(' ').collect();
            let [file, stamp, hex] = parts.as_slice() else {
                panic!("bad line {line:?}");
            };
            Rec {
                file: file.parse().expect("index"),
                stamp_us: stamp.parse().expect("stamp"),
                hex: hex.to_string(),
            }
        })
        .collect()
}

/// The numbers of the recorder's line of the counters report: written, bytes, dropped
/// (queue full, disk errors, no space), files opened, removed.
#[derive(Debug, Default, PartialEq, Eq)]
struct Counts {
    written: u64,
    bytes: u64,
    queue_full: u64,
    disk: u64,
    no_space: u64,
    files: u64,
    removed: u64,
}

fn counts(stopped: &Stopped) -> Counts {
    let line = stopped
        .stderr
        .iter()
        .rev()
        .find(|l| l.trim_start().starts_with("recording "))
        .unwrap_or_else(|| panic!("no recording line in:\n{}", stopped.stderr.join("\n")));
    let tail = line.split_once(": ").map_or("", |(_, t)| t);
    let n: Vec<u64> = tail
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().expect("number"))
        .collect();
    let [written, bytes, queue_full, disk, no_space, files, removed] = n.as_slice() else {
        panic!("unexpected recording line {line:?}");
    };
    Counts {
        written: *written,
        bytes: *bytes,
        queue_full: *queue_full,
        disk: *disk,
        no_space: *no_space,
        files: *files,
        removed: *removed,
    }
}

/// How many stderr lines contain `pattern`.
fn said(stopped: &Stopped, pattern: &str) -> usize {
    stopped
        .stderr
        .iter()
        .filter(|l| l.contains(pattern))
        .count()
}

/// A router on UDP `port` that accepts everything and records to `dir` with the
/// statements `extra` (each ending in `;`).
fn record_config(port: u16, dir: &Path, extra: &str) -> String {
    format!(
        "udp {{ port {port}; }}\nrecord {{ path {}/%Y-%m-%d_%H-%M-%S.tlog; {extra} }}\ndefault_action accept;\n",
        dir.display()
    )
}

/// The bytes of a frame given in hex.
fn unhex(hex: &str) -> Vec<u8> {
    (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex"))
        .collect()
}

/// Bytes a recording of `frames` takes (an 8-byte timestamp each).
fn recorded_len(frames: &[String]) -> u64 {
    frames.iter().map(|h| 8 + h.len() as u64 / 2).sum()
}

#[test]
fn every_frame_received_is_recorded_in_order_with_its_arrival_time() {
    let scratch = Scratch::new("record-all");
    let port = free_udp_port();
    let dir = scratch.dir.join("rec");
    let config = record_config(port, &dir, "min_free_bytes 0;");
    let router = Router::start(&scratch, &config, 0);
    let t0 = now_us();
    // Two peers, one after the other, then the first system again from a new socket:
    // the order of arrival is known.
    let mut sent = send(port, 1, &items(40));
    sent.extend(send(port, 2, &items(33)));
    sent.extend(send(port, 1, &items(5)));
    let stopped = router.stop();
    let t1 = now_us();
    let files = recordings(&dir);
    assert_eq!(files.len(), 1, "{files:?}");
    let recs = read_with_pymavlink(&files);
    let got: Vec<String> = recs.iter().map(|r| r.hex.clone()).collect();
    assert_eq!(got, sent, "the recording is every frame sent, in order");
    for pair in recs.windows(2) {
        assert!(pair[0].stamp_us <= pair[1].stamp_us, "{pair:?}");
    }
    // pymavlink's float seconds may be a microsecond off.
    assert!(
        recs[0].stamp_us + 1 >= t0,
        "{} before {t0}",
        recs[0].stamp_us
    );
    assert!(recs[recs.len() - 1].stamp_us <= t1 + 1);
    // Byte for byte: the file is exactly timestamp + frame per record.
    let data = fs::read(&files[0]).expect("read");
    let mut at = 0;
    for (rec, hex) in recs.iter().zip(&sent) {
        let stamp = u64::from_be_bytes(data[at..at + 8].try_into().expect("8"));
        assert!(stamp.abs_diff(rec.stamp_us) <= 1);
        let frame = unhex(hex);
        assert_eq!(&data[at + 8..at + 8 + frame.len()], &frame[..]);
        at += 8 + frame.len();
    }
    assert_eq!(at, data.len());
    assert_eq!(
        counts(&stopped),
        Counts {
            written: sent.len() as u64,
            bytes: data.len() as u64,
            files: 1,
            ..Counts::default()
        }
    );
    // mavtables inspect reads it too.
    let out = Command::new(BIN)
        .arg("inspect")
        .arg("--check")
        .arg(&files[0])
        .output()
        .expect("inspect");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains(&format!("valid ({} frames)", sent.len())),
        "{text}"
    );
}

#[test]
fn only_frames_meeting_a_condition_are_recorded() {
    let scratch = Scratch::new("record-only");
    let port = free_udp_port();
    let dir = scratch.dir.join("rec");
    let config = format!(
        "udp {{ port {port}; }}\nrecord {{\n    path {}/only_%H%M%S.tlog;\n    min_free_bytes 0;\n    only if ATTITUDE;\n    only if from 2.0/8;\n    only if to 9.1;\n}}\ndefault_action accept;\n",
        dir.display()
    );
    let router = Router::start(&scratch, &config, 0);
    let items = items(21);
    let from1 = send(port, 1, &items);
    let from2 = send(port, 2, &items);
    let stopped = router.stop();
    // System 1: its ATTITUDE and its COMMAND_LONG to 9.1; system 2: everything.
    let mut want: Vec<String> = items
        .iter()
        .zip(&from1)
        .filter(|(name, _)| *name == "ATTITUDE" || name.ends_with("@9.1"))
        .map(|(_, hex)| hex.clone())
        .collect();
    assert_eq!(want.len(), 6);
    want.extend(from2.iter().cloned());
    let recs = read_with_pymavlink(&recordings(&dir));
    let got: Vec<String> = recs.into_iter().map(|r| r.hex).collect();
    assert_eq!(got, want);
    assert_eq!(counts(&stopped).written, want.len() as u64);
}

#[test]
fn files_rotate_by_size_and_only_the_newest_are_kept() {
    let scratch = Scratch::new("record-rotate");
    let port = free_udp_port();
    let dir = scratch.dir.join("rec");
    // An unrelated file in the directory is never removed.
    fs::create_dir_all(&dir).expect("dir");
    fs::write(dir.join("notes.txt"), "mine").expect("notes");
    let config = format!(
        "udp {{ port {port}; }}\nrecord {{ path {}/%Y%m%d-%H%M%S.tlog; max_file_bytes 1024; max_files 3; min_free_bytes 0; }}\ndefault_action accept;\n",
        dir.display()
    );
    let router = Router::start(&scratch, &config, 0);
    let sent = send(port, 1, &items(300));
    let stopped = router.stop();
    let total = recorded_len(&sent);
    let files = recordings(&dir);
    assert_eq!(files.len(), 3, "{files:?}");
    assert!(dir.join("notes.txt").exists());
    for f in &files {
        let len = fs::metadata(f).expect("meta").len();
        assert!(len <= 1024, "{} holds {len} bytes", f.display());
    }
    let recs = read_with_pymavlink(&files);
    // Each file is valid on its own, and together they are the latest frames sent.
    for (i, f) in files.iter().enumerate() {
        let alone = read_with_pymavlink(std::slice::from_ref(f));
        let in_all: Vec<&String> = recs
            .iter()
            .filter(|r| r.file == i)
            .map(|r| &r.hex)
            .collect();
        assert_eq!(alone.iter().map(|r| &r.hex).collect::<Vec<_>>(), in_all);
        assert!(!alone.is_empty());
    }
    let got: Vec<String> = recs.iter().map(|r| r.hex.clone()).collect();
    assert_eq!(&sent[sent.len() - got.len()..], &got[..]);
    // The older files were full: the frame before the kept ones did not fit in the
    // oldest kept file.
    let oldest = fs::metadata(&files[0]).expect("meta").len();
    let before = &sent[sent.len() - got.len() - 1];
    assert!(oldest + 8 + before.len() as u64 / 2 > 1024);
    let c = counts(&stopped);
    assert_eq!(c.written, sent.len() as u64);
    assert_eq!(c.bytes, total);
    assert!(c.files > 3, "{c:?}");
    assert_eq!(c.removed, c.files - 3);
}

#[test]
fn records_reach_the_file_within_a_second() {
    let scratch = Scratch::new("record-flush");
    let port = free_udp_port();
    let dir = scratch.dir.join("rec");
    let config = record_config(port, &dir, "min_free_bytes 0;");
    let router = Router::start(&scratch, &config, 0);
    let sent = send(port, 1, &items(12));
    let done = Instant::now();
    let want = recorded_len(&sent);
    // A reader sees every record while the router runs (the wait is bounded).
    let mut seen = 0;
    while done.elapsed() < Duration::from_millis(1500) {
        seen = recordings(&dir)
            .iter()
            .map(|f| fs::metadata(f).map_or(0, |m| m.len()))
            .sum();
        if seen == want {
            break;
        }
        thread::sleep(Duration::from_millis(10));
    }
    let took = done.elapsed();
    assert_eq!(seen, want, "after {took:?}");
    assert!(took < Duration::from_secs(1), "took {took:?}");
    let got: Vec<String> = read_with_pymavlink(&recordings(&dir))
        .into_iter()
        .map(|r| r.hex)
        .collect();
    assert_eq!(got, sent);
    router.stop();
}

/// Fills the file system of `dir` with a file until only about `left` bytes are free.
fn fill(dir: &Path, left: u64) {
    use std::io::Write;
    let path = dir.join("filler.bin");
    let mut f = fs::File::create(&path).expect("filler");
    let chunk = vec![0u8; 4096];
    let mut len = 0u64;
    while f.write_all(&chunk).is_ok() {
        len += chunk.len() as u64;
    }
    f.set_len(len.saturating_sub(left)).expect("shrink filler");
    f.sync_all().expect("sync");
}

/// Routes `n` frames from system 1 to a listener (system 7) with the router running
/// `config`; asserts every frame was delivered; returns what was sent (the listener's
/// HEARTBEAT first) and how the router stopped.
fn route_through(scratch: &Scratch, config: &str, port: u16, n: usize) -> (Vec<String>, Stopped) {
    route_through_binary(BIN, scratch, config, port, n)
}

fn route_through_binary(
    bin: &str,
    scratch: &Scratch,
    config: &str,
    port: u16,
    n: usize,
) -> (Vec<String>, Stopped) {
    let router = Router::start_binary(bin, scratch, config, 0);
    let mut sink = listener(port, 7, n);
    let sent = send(port, 1, &broadcasts(n));
    let received = sink.received(Duration::from_secs(30));
    assert_eq!(
        hexes(&received),
        sent,
        "every packet is routed whatever the disk does"
    );
    let stopped = router.stop();
    (sent, stopped)
}

#[test]
#[ignore = "needs root to mount a small tmpfs; scripts/test runs it"]
fn a_full_disk_drops_records_never_packets() {
    let scratch = Scratch::new("record-full");
    let mnt = scratch.dir.join("disk");
    let _disk = Tmpfs::mount(&mnt);
    // Four pages left: one may go to the list of recordings the recorder keeps beside
    // them (written when it is, before or after the first records), the rest hold about
    // 250 of the 401 records.
    fill(&mnt, 16384);
    let port = free_udp_port();
    let config = record_config(port, &mnt, "min_free_bytes 0;");
    let (sent, stopped) = route_through(&scratch, &config, port, 400);
    let c = counts(&stopped);
    // The listener's HEARTBEAT and the 400 frames: each written or dropped.
    assert_eq!(c.written + c.disk, sent.len() as u64 + 1, "{c:?}");
    assert!(c.disk > 0 && c.written > 0, "{c:?}");
    assert_eq!(c.queue_full + c.no_space, 0);
    assert!(said(&stopped, "recording: cannot write") >= 1);
    // What was written is whole: every record decodes, in the order of arrival (the
    // listener's HEARTBEAT first).
    let files = recordings(&mnt);
    assert_eq!(files.len(), 1);
    let got: Vec<String> = read_with_pymavlink(&files)
        .into_iter()
        .map(|r| r.hex)
        .collect();
    assert_eq!(got.len() as u64, c.written);
    assert_in_order(&got[1..], &sent);
    assert_eq!(fs::metadata(&files[0]).expect("meta").len(), c.bytes);
}

/// Runs the router on `config` once, without traffic, and returns the recording it
/// made (the `.tlog` in `dir` that `before` does not hold).
fn one_run(scratch: &Scratch, config: &str, dir: &Path, before: &[PathBuf]) -> PathBuf {
    Router::start(scratch, config, 0).stop();
    let made: Vec<PathBuf> = recordings(dir)
        .into_iter()
        .filter(|p| !before.contains(p))
        .collect();
    let [made] = made.as_slice() else {
        panic!("expected one new recording in {}: {made:?}", dir.display());
    };
    made.clone()
}

/// A file of the user's at `path` (a name the pattern makes), dated back to 1999: older
/// than any recording. Returns its bytes.
fn plant(path: &Path) -> Vec<u8> {
    let bytes: Vec<u8> = (0..20_000u32).map(|i| (i * 7 % 251) as u8).collect();
    fs::write(path, &bytes).expect("plant");
    date_back(path, new_year(1999));
    bytes
}

/// What became of the files on the disk before the router ran.
struct Before {
    /// Whether the recording of an earlier run is still there.
    old_kept: bool,
    /// Whether the user's file with a name of the pattern is there, byte for byte.
    planted_intact: bool,
}

/// A 1 MiB disk holding a recording of an earlier run, grown to `old_bytes` and dated
/// 2000, and a user's file with a name the pattern makes, dated 1999; recorded to with
/// `min_free_bytes` while `n` frames are routed: what became of the two, what was sent
/// and how the router stopped.
fn with_old_recording(
    tag: &str,
    old_bytes: usize,
    min_free_bytes: u64,
    n: usize,
) -> (Before, Vec<String>, Stopped) {
    let scratch = Scratch::new(tag);
    let mnt = scratch.dir.join("disk");
    let _disk = Tmpfs::mount(&mnt);
    let port = free_udp_port();
    let old = one_run(
        &scratch,
        &record_config(port, &mnt, "min_free_bytes 0;"),
        &mnt,
        &[],
    );
    {
        use std::io::Write;
        let mut f = fs::OpenOptions::new()
            .append(true)
            .open(&old)
            .expect("grow the old recording");
        f.write_all(&vec![0u8; old_bytes]).expect("grow");
    }
    date_back(&old, new_year(2000));
    let planted = mnt.join("1999-12-31_23-59-59.tlog");
    let bytes = plant(&planted);
    let extra = format!("min_free_bytes {min_free_bytes};");
    let config = record_config(port, &mnt, &extra);
    let (sent, stopped) = route_through(&scratch, &config, port, n);
    let before = Before {
        old_kept: old.exists(),
        planted_intact: fs::read(&planted).ok() == Some(bytes),
    };
    (before, sent, stopped)
}

#[test]
#[ignore = "needs root to mount a small tmpfs; scripts/test runs it"]
fn old_recordings_make_room_for_min_free_bytes_never_other_files() {
    let (before, sent, stopped) = with_old_recording("record-room", 700_000, 500_000, 50);
    assert!(
        !before.old_kept,
        "the old recording was removed to keep 500000 bytes free"
    );
    assert!(
        before.planted_intact,
        "a file the router did not write is never removed, whatever its name and age"
    );
    let c = counts(&stopped);
    assert_eq!(c.removed, 1);
    assert_eq!(c.written, sent.len() as u64 + 1);
    assert_eq!(c.disk + c.no_space + c.queue_full, 0);
    assert_eq!(said(&stopped, "1 files in"), 1, "the planted file is said");
}

#[test]
#[ignore = "needs root to mount a small tmpfs; scripts/test runs it"]
fn without_min_free_bytes_records_are_dropped_and_old_recordings_kept() {
    let (before, sent, stopped) = with_old_recording("record-nospace", 10_000, 2_000_000, 100);
    assert!(
        before.old_kept,
        "removing it would not have made room: it stays"
    );
    assert!(before.planted_intact);
    let c = counts(&stopped);
    assert_eq!(c.no_space, sent.len() as u64 + 1, "{c:?}");
    assert_eq!(c.written + c.removed + c.disk, 0);
    assert_eq!(said(&stopped, "less than min_free_bytes free"), 1);
}

#[test]
fn a_file_size_limit_moves_recording_to_a_new_file() {
    let scratch = Scratch::new("record-fsize");
    let dir = scratch.dir.join("rec");
    // The router under RLIMIT_FSIZE: without SIGXFSZ caught, the first write beyond the
    // limit would end the process.
    let wrapper = scratch.dir.join("limited.sh");
    fs::write(
        &wrapper,
        format!("#!/bin/sh\nexec prlimit --fsize=2000 -- {BIN} \"$@\"\n"),
    )
    .expect("wrapper");
    let chmod = Command::new("chmod")
        .arg("755")
        .arg(&wrapper)
        .status()
        .expect("chmod");
    assert!(chmod.success());
    let port = free_udp_port();
    let config = record_config(port, &dir, "min_free_bytes 0;");
    let wrapper = wrapper.display().to_string();
    let (sent, stopped) = route_through_binary(&wrapper, &scratch, &config, port, 200);
    let c = counts(&stopped);
    // Nothing is lost: the records that met the limit go on in a new file, and files
    // are rotated at the limit from then on.
    assert_eq!(c.written, sent.len() as u64 + 1, "{c:?}");
    assert_eq!(c.disk + c.no_space + c.queue_full, 0, "{c:?}");
    assert!(c.files > 1, "{c:?}");
    assert_eq!(said(&stopped, "cannot grow beyond 2000 bytes"), 1);
    let files = recordings(&dir);
    assert_eq!(files.len() as u64, c.files);
    for f in &files {
        assert!(fs::metadata(f).expect("meta").len() <= 2000);
    }
    // Every file decodes, and together they are every frame in the order of arrival
    // (the listener's HEARTBEAT first).
    let got: Vec<String> = read_with_pymavlink(&files)
        .into_iter()
        .map(|r| r.hex)
        .collect();
    assert_eq!(&got[1..], &sent[..]);
}

/// `got` is `sent` with some frames left out, in the same order.
#[track_caller]
fn assert_in_order(got: &[String], sent: &[String]) {
    let mut rest = sent.iter();
    for hex in got {
        assert!(rest.any(|s| s == hex), "{hex} is not next in what was sent");
    }
}

/// The first line of the first error `config::load` finds in `src`, for a file `f`.
fn first_error(src: &str) -> String {
    match mavtables::config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => mavtables::config::render_errors("f", src, &e),
    }
}

#[test]
fn the_record_block_prints_in_ast_like_rules() {
    let scratch = Scratch::new("record-ast");
    let path = scratch.dir.join("good.conf");
    let src = "record {\n    path /tmp/r/%Y%m%d_%H%M%S.tlog;\n    max_file_bytes 2000000;\n    max_files 5;\n    min_free_bytes 0;\n    only if signed ATTITUDE from 1.0/8 to 255.0:255.0;\n    only if from 2.1;\n}\ndefault_action accept;\n";
    fs::write(&path, src).expect("config");
    let out = Command::new(BIN)
        .arg("--ast")
        .arg("--config")
        .arg(&path)
        .output()
        .expect("--ast");
    assert!(out.status.success());
    let want = format!(
        "===== {} =====\n\
:001:  record\n\
:002:  |  path /tmp/r/%Y%m%d_%H%M%S.tlog\n\
:003:  |  max_file_bytes 2000000\n\
:004:  |  max_files 5\n\
:005:  |  min_free_bytes 0\n\
:006:  |  only\n\
:006:  |  |  condition\n\
:006:  |  |  |  signed\n\
:006:  |  |  |  packet_type ATTITUDE\n\
:006:  |  |  |  source 1.0/8\n\
:006:  |  |  |  dest 255.0:255.0\n\
:007:  |  only\n\
:007:  |  |  condition\n\
:007:  |  |  |  source 2.1\n\
:009:  default_action\n\
:009:  |  accept\n",
        path.display()
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout), want);
    // And what it means.
    let config = mavtables::config::load(src).expect("valid").config;
    let r = config.record.expect("record");
    assert_eq!(r.path.as_deref(), Some("/tmp/r/%Y%m%d_%H%M%S.tlog"));
    assert_eq!(
        (r.max_file_bytes, r.max_files, r.min_free_bytes),
        (2_000_000, 5, 0)
    );
    assert_eq!(r.only.len(), 2);
    assert_eq!(r.only[0].signed, Some(true));
    assert_eq!(r.only[0].message_id, Some(30));
    assert!(r.only[0].dest.is_some() && r.only[1].source.is_some());
    // Defaults: an empty block records every frame to the logs directory.
    let r = mavtables::config::load("record { }")
        .expect("valid")
        .config
        .record
        .expect("record");
    assert_eq!(r, mavtables::config::Recording::with_defaults());
    assert_eq!(
        (r.max_file_bytes, r.max_files, r.min_free_bytes),
        (100_000_000, 100, 100_000_000)
    );
    assert_eq!(
        r.path_pattern(|_| None),
        "/var/log/mavtables/%Y-%m-%d_%H-%M-%S.tlog"
    );
    assert_eq!(
        r.path_pattern(|k| (k == "LOGS_DIRECTORY").then(|| "/var/log/mt:/other".to_string())),
        "/var/log/mt/%Y-%m-%d_%H-%M-%S.tlog"
    );
}

#[test]
fn mistakes_in_the_record_block_are_located() {
    let cases: &[(&str, &str)] = &[
        (
            "record {\n    path /var/log/x/%Y_%q.tlog;\n}",
            "f:2:24: unknown directive '%q'",
        ),
        (
            "record { path /var/%Y/x.tlog; }",
            "f:1:20: '%' directives are allowed in the file name only, not in the directory",
        ),
        (
            "record { path /var/log/; }",
            "f:1:23: expected a file name after the directory",
        ),
        (
            "record { max_file_bytes 10; }",
            "f:1:25: max_file_bytes (10) is outside of the allowed range (1024 - 18446744073709551615)",
        ),
        (
            "record { max_files 4294967296; }",
            "f:1:20: max_files (4294967296) is outside of the allowed range (0 - 4294967295)",
        ),
        (
            "record { only ATTITUDE; }",
            "f:1:15: expected 'if' after 'only'",
        ),
        (
            "record { only if; }",
            "f:1:17: condition is empty or invalid",
        ),
        (
            "record { only if NOPE; }",
            "f:1:18: Invalid packet name (\"NOPE\").",
        ),
        (
            "record { only if from 1.300; }",
            "f:1:25: Component ID (300) is outside of the allowed range (0 - 255).",
        ),
        (
            "record { path /tmp/x.tlog }",
            "f:1:27: expected end of statement ';' character",
        ),
        ("record { port 5; }", "f:1:10: unsupported statement"),
        ("udp { max_files 3; }", "f:1:7: unsupported statement"),
        (
            "record { }\nrecord { }",
            "f:2:1: only one 'record' block is allowed",
        ),
    ];
    for (src, want) in cases {
        let got = first_error(src);
        assert_eq!(got.lines().next(), Some(*want), "{src:?}:\n{got}");
    }
    assert!(
        first_error("udp { max_files 3; }")
            .contains("'max_files' belongs in a 'record' or 'flight_log' block")
    );
    assert!(first_error("record { only if Attitude; }").contains("'ATTITUDE'"));
    // Every mistake of a block is reported, not only the first.
    let all = first_error("record {\n    max_file_bytes 1;\n    path /x/%Q;\n    only if NOPE;\n}");
    for want in ["f:2:20:", "f:3:13:", "f:4:13:"] {
        assert!(all.contains(want), "{want} in:\n{all}");
    }
    // The binary says it the same way, with the line and a caret under the mistake.
    let scratch = Scratch::new("record-check");
    let path = scratch.dir.join("bad.conf");
    fs::write(&path, "record {\n    path /var/log/x/%Y_%q.tlog;\n}\n").expect("config");
    let out = Command::new(BIN)
        .arg("--check")
        .arg("--config")
        .arg(&path)
        .output()
        .expect("--check");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines[0],
        format!("{}:2:24: unknown directive '%q'", path.display())
    );
    assert_eq!(lines[1], "    path /var/log/x/%Y_%q.tlog;");
    assert_eq!(lines[2], "                       ^^");
}

#[test]
fn the_documented_record_blocks_are_valid() {
    let doc = fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("## `record`")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("record section");
    let readme =
        fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).expect("README.md");
    let readme = readme
        .split("## Recording flights")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("README section");
    let blocks: Vec<&str> = [section, readme]
        .iter()
        .flat_map(|text| text.split("```").skip(1).step_by(2))
        .map(|b| b.trim_start_matches("sh\n"))
        .filter(|b| b.trim_start().starts_with("record {"))
        .collect();
    assert_eq!(blocks.len(), 3);
    for block in blocks {
        if let Err(e) = mavtables::config::load(block) {
            panic!("{}", mavtables::config::render_errors("doc", block, &e));
        }
    }
}

#[test]
fn max_files_removes_only_recordings_the_router_made() {
    let scratch = Scratch::new("record-planted");
    let port = free_udp_port();
    let dir = scratch.dir.join("rec");
    // Two runs without a limit: two recordings.
    let unlimited = record_config(port, &dir, "max_files 0; min_free_bytes 0;");
    let first = one_run(&scratch, &unlimited, &dir, &[]);
    let second = one_run(&scratch, &unlimited, &dir, std::slice::from_ref(&first));
    // The user removes the first and puts a file of theirs at its name (the freed inode
    // number is likely given to it), and plants another with a name of the pattern;
    // both are older than any recording.
    fs::remove_file(&first).expect("remove the first");
    let at_first = plant(&first);
    let planted = dir.join("1999-12-31_23-59-59.tlog");
    let bytes = plant(&planted);
    // With max_files 1 the new recording stays and the second goes: the files the
    // router did not write neither count nor go.
    let one = record_config(port, &dir, "max_files 1; min_free_bytes 0;");
    let router = Router::start(&scratch, &one, 0);
    let stopped = router.stop();
    assert_eq!(
        fs::read(&planted).ok(),
        Some(bytes),
        "the planted file is intact"
    );
    assert_eq!(
        fs::read(&first).ok(),
        Some(at_first),
        "the file put at a removed recording's name is intact"
    );
    assert!(!second.exists(), "the older recording was rotated away");
    let left = recordings(&dir);
    assert_eq!(left.len(), 3, "{left:?}");
    assert_eq!(counts(&stopped).removed, 1);
    // The list of recordings is beside them, named after the pattern.
    let list = fs::read_to_string(dir.join(".%Y-%m-%d_%H-%M-%S.tlog.mavtables")).expect("list");
    assert_eq!(
        list.lines().filter(|l| !l.starts_with('#')).count(),
        1,
        "{list}"
    );
}

/// Runs `mavtables ARGS`, which must exit within 10 s; its status and standard error.
fn run_to_exit(args: &[&Path]) -> (Option<i32>, String) {
    let child = Command::new(BIN)
        .args(args)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn mavtables");
    let mut guard = Guard(Some(child));
    let mut stderr = guard.child().stderr.take().expect("stderr");
    let status = guard.wait(Duration::from_secs(10));
    let mut err = String::new();
    if status.is_some() {
        use std::io::Read;
        let _ = stderr.read_to_string(&mut err);
    }
    (status.and_then(|s| s.code()), err)
}

#[test]
fn a_recording_path_that_is_also_the_flight_logs_is_refused_at_the_path() {
    let scratch = Scratch::new("record-shared");
    let logs = scratch.dir.join("logs");
    let port = free_udp_port();
    let config = format!(
        "udp {{ port {port}; }}\nrecord {{\n    path {logs}/%Y-%m-%d_%H-%M-%S.bin;\n}}\nflight_log {{\n    system 1;\n    path {logs}/%Y-%m-%d_%H-%M-%S;\n}}\ndefault_action accept;\n",
        logs = logs.display()
    );
    let conf = scratch.dir.join("shared.conf");
    fs::write(&conf, &config).expect("config");
    let (code, err) = run_to_exit(&[Path::new("--check"), Path::new("--config"), &conf]);
    assert_eq!(code, Some(1), "{err}");
    let first = err.lines().find(|l| !l.starts_with("warning: "));
    assert_eq!(
        first,
        Some(
            format!(
                "{}:3:10: the recording and the flight log's .bin logs would be written as {}/%Y-%m-%d_%H-%M-%S.bin",
                conf.display(),
                logs.display()
            )
            .as_str()
        ),
        "{err}"
    );
    assert!(err.contains("one list"), "{err}");
    // Starting is refused the same way; nothing is created.
    let (code, start_err) = run_to_exit(&[Path::new("--config"), &conf]);
    assert_eq!(code, Some(1), "{start_err}");
    assert!(!logs.exists());
    // Another extension for the recordings is fine.
    fs::write(&conf, config.replace(".bin;", ".tlog;")).expect("config");
    let (code, err) = run_to_exit(&[Path::new("--check"), Path::new("--config"), &conf]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_fixed_name_that_mavtables_did_not_write_is_refused_and_left_alone() {
    let scratch = Scratch::new("record-fixed");
    let dir = scratch.dir.join("etc");
    fs::create_dir_all(&dir).expect("dir");
    let important = dir.join("important.conf");
    fs::write(&important, "precious settings\n").expect("important");
    date_back(&important, new_year(1999));
    let port = free_udp_port();
    let config = format!(
        "udp {{ port {port}; }}\nrecord {{\n    path {}; max_files 1;\n}}\ndefault_action accept;\n",
        important.display()
    );
    let conf = scratch.dir.join("fixed.conf");
    fs::write(&conf, &config).expect("config");
    let (code, err) = run_to_exit(&[Path::new("--check"), Path::new("--config"), &conf]);
    assert_eq!(code, Some(1), "{err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.starts_with("warning: "))
        .collect();
    assert_eq!(
        lines.first().copied(),
        Some(
            format!(
                "{}:3:10: {} exists and was not written by mavtables",
                conf.display(),
                important.display()
            )
            .as_str()
        ),
        "{err}"
    );
    assert_eq!(
        lines[1],
        format!("    path {}; max_files 1;", important.display())
    );
    assert_eq!(
        lines[2],
        format!(
            "         {}",
            "^".repeat(important.display().to_string().len())
        )
    );
    assert!(err.contains("important_%Y-%m-%d_%H-%M-%S.conf"), "{err}");
    // Starting is refused the same way, before anything is written.
    let (code, start_err) = run_to_exit(&[Path::new("--config"), &conf]);
    assert_eq!(code, Some(1), "{start_err}");
    assert_eq!(start_err, err);
    assert_eq!(
        fs::read_to_string(&important).ok().as_deref(),
        Some("precious settings\n")
    );
    let names: Vec<_> = fs::read_dir(&dir)
        .expect("dir")
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names, ["important.conf"], "nothing else was written there");
    // A fixed name whose file the router made is its recording: accepted, and rotated.
    let flight = dir.join("flight.tlog");
    let config = format!(
        "udp {{ port {port}; }}\nrecord {{ path {}; max_files 1; min_free_bytes 0; }}\ndefault_action accept;\n",
        flight.display()
    );
    Router::start(&scratch, &config, 0).stop();
    assert!(flight.exists());
    fs::write(&conf, &config).expect("config");
    let (code, err) = run_to_exit(&[Path::new("--check"), Path::new("--config"), &conf]);
    assert_eq!(code, Some(0), "{err}");
    Router::start(&scratch, &config, 0).stop();
    assert!(!flight.exists(), "the old recording was rotated away");
    assert!(dir.join("flight-1.tlog").exists());
    assert!(important.exists());
}
