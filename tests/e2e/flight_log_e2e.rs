//! Flight logs, end to end: the real router with a `flight_log` block and a scripted
//! ArduPilot on 127.0.0.1 (`tests/py/ardupilot_log_peer.py`, pymavlink) that streams a
//! real dataflash log with ArduPilot's protocol — REMOTE_LOG_BLOCK_STATUS start and
//! stop, REMOTE_LOG_DATA_BLOCK, each block ACKed — leaving out the first sending of some
//! blocks, which the router must NACK to get them resent. The written `.bin` is compared
//! byte for byte with the source (zero-padded to whole blocks, as ArduPilot sends it)
//! and read by pymavlink's DFReader. The log is made at test time
//! (`tests/py/dataflash_log.py`).

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Duration;

use std::net::UdpSocket;
use std::process::Command;

use common::net::{heartbeat, udp_frames};
use common::router::{BIN, Router, Scratch, free_udp_port};
use common::{run_py, stats_router};

/// Makes a dataflash log of `records` ATT records (and FMT, PARM) at `path`.
fn make_log(path: &str, records: usize) -> Vec<u8> {
    run_py(
        "dataflash_log.py",
        &["make", path, "--records", &records.to_string()],
        "",
    );
    fs::read(path).expect("the made log")
}

/// What DFReader reads in `path`: "NAME COUNT" lines and "total N".
fn dfreader(path: &Path) -> String {
    run_py(
        "dataflash_log.py",
        &["read", &path.display().to_string()],
        "",
    )
}

/// The `.bin` files in `dir`, oldest name first.
fn bins(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "bin"));
    files.sort();
    files
}

fn config(port: u16, logs: &str) -> String {
    format!(
        "udp {{ port {port}; }}\n\
         flight_log {{ system 1; path {logs}/flight-%Y%m%d-%H%M%S; mode while_armed; min_free_bytes 0; }}\n\
         default_action accept;\n"
    )
}

/// The source as streamed: zero-padded to whole 200-byte blocks.
fn padded(mut log: Vec<u8>) -> Vec<u8> {
    log.resize(log.len().div_ceil(200) * 200, 0);
    log
}

#[test]
fn a_dataflash_log_streamed_with_gaps_is_written_whole_and_in_order() {
    let scratch = Scratch::new("flight-log");
    let source = make_log(&scratch.path("source.bin"), 3000);
    let logs = scratch.path("logs");
    let port = free_udp_port();
    let router = Router::start(&scratch, &config(port, &logs), 1);
    let out = run_py(
        "ardupilot_log_peer.py",
        &[
            "--udp",
            &format!("127.0.0.1:{port}"),
            "--log",
            &scratch.path("source.bin"),
            "--skip",
            "3,10,11,200",
        ],
        "",
    );
    let stopped = router.stop();
    let line = out.lines().next().expect("a flight line");
    let blocks = source.len().div_ceil(200);
    assert!(
        line.starts_with(&format!("flight 1 blocks {blocks} acks ")),
        "{out}"
    );
    assert!(
        line.contains("nacked 3,10,11,200 "),
        "each skipped block NACKed: {out}"
    );
    assert!(
        line.ends_with("stop yes"),
        "the router stopped the stream at disarm: {out}"
    );
    let files = bins(Path::new(&logs));
    assert_eq!(files.len(), 1, "one file per arming: {files:?}");
    let written = fs::read(&files[0]).expect("the written log");
    assert_eq!(written.len(), padded(source.clone()).len());
    assert!(
        written == padded(source),
        "the written log differs from the source"
    );
    let read = dfreader(&files[0]);
    assert!(read.contains("ATT 3000\n"), "{read}");
    assert!(read.contains("PARM 20\n"), "{read}");
    let report = stopped.stderr.join("\n");
    assert!(
        report.contains(&format!("flight log: 1 files, {blocks} blocks")),
        "{report}"
    );
    // The file is on the router's list of logs it created (the only ones it removes).
    let list = fs::read_to_string(Path::new(&logs).join(".flight-%Y%m%d-%H%M%S.bin.mavtables"))
        .expect("the list of created logs");
    let name = files[0]
        .file_name()
        .expect("name")
        .to_string_lossy()
        .to_string();
    assert!(list.contains(&name), "{list}");
}

#[test]
fn each_arming_is_one_file_counted_in_stats_and_metrics() {
    let scratch = Scratch::new("flight-log-two");
    let source = make_log(&scratch.path("source.bin"), 400);
    let logs = scratch.path("logs");
    let port = free_udp_port();
    let (router, http) = stats_router::start(&scratch, &config(port, &logs));
    let out = run_py(
        "ardupilot_log_peer.py",
        &[
            "--udp",
            &format!("127.0.0.1:{port}"),
            "--log",
            &scratch.path("source.bin"),
            "--flights",
            "2",
        ],
        "",
    );
    assert_eq!(
        out.lines().filter(|l| l.ends_with("stop yes")).count(),
        2,
        "{out}"
    );
    // Both closed before the router stops: each file whole already.
    common::eventually("two logs written", Duration::from_secs(5), || {
        let files = bins(Path::new(&logs));
        files.len() == 2
            && files
                .iter()
                .all(|f| fs::read(f).is_ok_and(|b| b == padded(source.clone())))
    });
    let blocks = source.len().div_ceil(200) as u64;
    let s = common::eventually("the counters published", Duration::from_secs(5), || {
        let s = stats_router::stats(http);
        // The last log ends 2 s after the disarm (blocks on their way are taken).
        let f = &s["flight_log"];
        (f["blocks_written"].as_u64() == Some(2 * blocks) && f["streaming"].is_null()).then_some(s)
    });
    let f = &s["flight_log"];
    assert_eq!(f["files"].as_u64(), Some(2), "{f:#}");
    assert_eq!(f["logs"].as_u64(), Some(2), "{f:#}");
    assert_eq!(f["lost"].as_u64(), Some(0), "{f:#}");
    assert!(f["streaming"].is_null(), "disarmed: {f:#}");
    let metrics = metrics(http);
    let parsed = run_py("prom_parse.py", &[], &metrics);
    for (name, want) in [
        ("mavtables_flight_log_files_total", 2),
        ("mavtables_flight_log_blocks_written_total", 2 * blocks),
        ("mavtables_flight_log_blocks_lost_total", 0),
    ] {
        let line = parsed
            .lines()
            .find(|l| l.contains(&format!("\"name\": \"{name}\"")))
            .unwrap_or_else(|| panic!("no {name}: {parsed}"));
        assert!(line.contains(&format!("\"value\": {want}.0")), "{line}");
    }
    let stopped = router.stop();
    assert_eq!(bins(Path::new(&logs)).len(), 2);
    let report = stopped.stderr.join("\n");
    assert!(report.contains("flight log: 2 files"), "{report}");
}

/// The router's `/metrics` text.
fn metrics(port: u16) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    write!(s, "GET /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n").expect("request");
    let mut answer = String::new();
    s.read_to_string(&mut answer).expect("answer");
    answer
        .split_once("\r\n\r\n")
        .map(|(_, body)| body.to_string())
        .expect("a body")
}

#[test]
fn a_link_that_drops_mid_flight_closes_the_file_and_the_next_arming_gets_a_new_one() {
    let scratch = Scratch::new("flight-log-drop");
    let source = padded(make_log(&scratch.path("source.bin"), 1000));
    let logs = scratch.path("logs");
    let port = free_udp_port();
    let (router, http) = stats_router::start(&scratch, &config(port, &logs));
    let udp = format!("127.0.0.1:{port}");
    let log = scratch.path("source.bin");
    let args = ["--udp", &udp, "--log", &log, "--vanish-after", "60"];
    let out = run_py("ardupilot_log_peer.py", &args, "");
    assert!(out.contains("vanished"), "{out}");
    // Silent for 5 s: the log ends (its file closed) without a disarm.
    common::eventually("the log closed", Duration::from_secs(10), || {
        let s = stats_router::stats(http);
        s["flight_log"]["logs"].as_u64() == Some(1) && s["flight_log"]["streaming"].is_null()
    });
    // The vehicle is back and arms: a new file, the whole log.
    let out = run_py("ardupilot_log_peer.py", &args[..4], "");
    assert!(out.contains("stop yes"), "{out}");
    let stopped = router.stop();
    let files = bins(Path::new(&logs));
    assert_eq!(files.len(), 2, "{files:?}");
    let first = fs::read(&files[0]).expect("the first log");
    let second = fs::read(&files[1]).expect("the second log");
    // The first holds the blocks that came before the drop (the peer sends up to 32
    // ahead of its ACKs), whole and in order.
    assert!(
        first.len() >= 40 * 200 && first.len() < source.len(),
        "{}",
        first.len()
    );
    assert!(first[..] == source[..first.len()]);
    assert!(second == source);
    let c = exit_counters(&stopped.stderr);
    assert_eq!(c[0], 2, "{c:?}");
}

/// The REMOTE_LOG_BLOCK_STATUS seqnos (and statuses) among `frames`.
fn statuses(frames: &[Vec<u8>]) -> Vec<(u32, u8)> {
    frames
        .iter()
        .filter_map(|b| {
            let f = mavtables::wire::Frame::parse_exact(b).ok()?;
            let p = f.payload_padded();
            (f.message_id() == 185).then(|| (u32::from_le_bytes([p[0], p[1], p[2], p[3]]), p[6]))
        })
        .collect()
}

#[test]
fn shutdown_while_armed_stops_the_stream_and_closes_the_file() {
    let scratch = Scratch::new("flight-log-shutdown");
    let logs = scratch.path("logs");
    let port = free_udp_port();
    let router = Router::start(&scratch, &config(port, &logs), 1);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    vehicle.connect(("127.0.0.1", port)).expect("connect");
    // An armed ArduPilot.
    let armed = common::net::with_payload(0, 1, 0, &[0, 0, 0, 0, 2, 3, 129, 4, 3]);
    vehicle.send(&armed).expect("send");
    let got = udp_frames(&vehicle, 1, Duration::from_secs(5));
    assert_eq!(statuses(&got), [(2_147_483_646, 1)], "the start request");
    for seqno in 0u32..3 {
        let mut p = seqno.to_le_bytes().to_vec();
        p.extend_from_slice(&[245, 190]);
        p.extend_from_slice(&[seqno as u8 + 1; 200]);
        vehicle
            .send(&common::net::with_payload(184, 1, seqno as u8, &p))
            .expect("send");
    }
    let got = udp_frames(&vehicle, 3, Duration::from_secs(5));
    assert_eq!(statuses(&got), [(0, 1), (1, 1), (2, 1)]);
    let stopped = router.stop();
    let got = udp_frames(&vehicle, 1, Duration::from_secs(2));
    assert_eq!(
        statuses(&got),
        [(2_147_483_645, 1)],
        "the stop request at shutdown"
    );
    let files = bins(Path::new(&logs));
    assert_eq!(files.len(), 1);
    let want: Vec<u8> = (1u8..=3).flat_map(|b| [b; 200]).collect();
    assert_eq!(fs::read(&files[0]).expect("the log"), want);
    assert_eq!(exit_counters(&stopped.stderr)[..2], [1, 3]);
}

/// The numbers of the counters line at exit: files, blocks written, bytes, resent,
/// lost, dropped.
fn exit_counters(stderr: &[String]) -> Vec<u64> {
    let line = stderr
        .iter()
        .find(|l| l.contains("flight log: ") && l.contains(" files, "))
        .unwrap_or_else(|| panic!("no flight log counters: {stderr:?}"));
    line.split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .filter_map(|w| w.parse().ok())
        .collect()
}

#[test]
fn a_full_disk_drops_blocks_counted_and_routing_goes_on() {
    let scratch = Scratch::new("flight-log-full");
    let source = make_log(&scratch.path("source.bin"), 3000);
    let logs = scratch.path("logs");
    // The router under RLIMIT_FSIZE: no file may pass 20000 bytes, as on a full disk.
    let wrapper = scratch.dir.join("limited.sh");
    fs::write(
        &wrapper,
        format!("#!/bin/sh\nexec prlimit --fsize=20000 -- {BIN} \"$@\"\n"),
    )
    .expect("wrapper");
    let chmod = Command::new("chmod")
        .arg("755")
        .arg(&wrapper)
        .status()
        .expect("chmod");
    assert!(chmod.success());
    let port = free_udp_port();
    let router = Router::start_binary(
        &wrapper.display().to_string(),
        &scratch,
        &config(port, &logs),
        1,
    );
    // A ground station on the same router.
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind");
    gcs.connect(("127.0.0.1", port)).expect("connect");
    gcs.send(&heartbeat(255)).expect("send");
    let out = run_py(
        "ardupilot_log_peer.py",
        &[
            "--udp",
            &format!("127.0.0.1:{port}"),
            "--log",
            &scratch.path("source.bin"),
        ],
        "",
    );
    assert!(
        out.contains("stop yes"),
        "every block acknowledged all the same: {out}"
    );
    // The vehicle's heartbeats (10 a second while it streamed, a second or so) reached
    // the ground station meanwhile.
    let got = udp_frames(&gcs, 5, Duration::from_secs(5));
    assert!(got.len() >= 5, "routing stopped: {} frames", got.len());
    let stopped = router.stop();
    let c = exit_counters(&stopped.stderr);
    let blocks = source.len().div_ceil(200) as u64;
    let (files, written, dropped) = (c[0], c[1], c[5]);
    assert_eq!(files, 1, "{c:?}");
    assert!(written > 0 && dropped > 0, "{c:?}");
    assert_eq!(
        written + dropped,
        blocks,
        "every block written or counted: {c:?}"
    );
    // What was written is blocks of the log, whole and in order (those that did not
    // fit are left out, as lost blocks are).
    let files = bins(Path::new(&logs));
    let bytes = fs::read(&files[0]).expect("the written log");
    assert!(
        bytes.len() <= 20_000 && bytes.len().is_multiple_of(200),
        "{}",
        bytes.len()
    );
    assert_eq!(bytes.len() as u64, written * 200);
    let source = padded(source);
    let mut rest = source.chunks(200);
    for (i, block) in bytes.chunks(200).enumerate() {
        assert!(
            rest.any(|s| s == block),
            "written block {i} is not the next of the log"
        );
    }
}

/// Makes a ulog of `samples` samples at `path`; its bytes and where its definitions end.
fn make_ulog(path: &str, samples: usize) -> (Vec<u8>, String) {
    run_py(
        "ulog_log.py",
        &["make", path, "--samples", &samples.to_string()],
        "",
    );
    let defs = run_py("ulog_log.py", &["split", path], "");
    (
        fs::read(path).expect("the made ulog"),
        defs.trim().to_string(),
    )
}

/// The `.ulg` files in `dir`.
fn ulgs(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "ulg"));
    files.sort();
    files
}

/// Streams `source.ulg` from a scripted PX4 with `extra` arguments through a router
/// with `protocol auto`; the peer's line, the written files and the router's exit.
fn px4_flight(scratch: &Scratch, defs: &str, extra: &[&str]) -> (String, Vec<PathBuf>, Vec<u64>) {
    let logs = scratch.path("logs");
    let port = free_udp_port();
    let router = Router::start(scratch, &config(port, &logs), 1);
    let udp = format!("127.0.0.1:{port}");
    let source = scratch.path("source.ulg");
    let mut args = vec!["--udp", &udp, "--log", &source, "--defs", defs];
    args.extend_from_slice(extra);
    let out = run_py("px4_log_peer.py", &args, "");
    let stopped = router.stop();
    (out, ulgs(Path::new(&logs)), exit_counters(&stopped.stderr))
}

#[test]
fn a_px4_ulog_is_written_whole_with_its_acknowledged_chunks_resent() {
    let scratch = Scratch::new("flight-log-ulog");
    let (source, defs) = make_ulog(&scratch.path("source.ulg"), 2000);
    // The first sending of acknowledged chunk 1 is lost: the peer sends it again.
    let (out, files, c) = px4_flight(&scratch, &defs, &["--skip-acked", "1"]);
    assert!(out.contains(" resent 1 lost 0 stop yes"), "{out}");
    assert_eq!(files.len(), 1, "{files:?}");
    let written = fs::read(&files[0]).expect("the written ulog");
    assert_eq!(written.len(), source.len());
    assert!(
        written == source,
        "the written ulog differs from the source"
    );
    let read = run_py(
        "ulog_log.py",
        &["read", &files[0].display().to_string()],
        "",
    );
    assert!(read.contains("samples 2000\n"), "{read}");
    assert!(read.contains("params 30\n"), "{read}");
    assert_eq!((c[0], c[4]), (1, 0), "one file, nothing lost: {c:?}");
}

#[test]
fn a_lost_ulog_chunk_costs_only_the_messages_it_carried() {
    let scratch = Scratch::new("flight-log-ulog-lost");
    let (_, defs) = make_ulog(&scratch.path("source.ulg"), 2000);
    let (out, files, c) = px4_flight(&scratch, &defs, &["--skip", "10,11,40"]);
    assert!(out.contains(" lost 3 stop yes"), "{out}");
    assert_eq!(files.len(), 1, "{files:?}");
    let read = run_py(
        "ulog_log.py",
        &["read", &files[0].display().to_string()],
        "",
    );
    let samples: usize = read
        .lines()
        .find_map(|l| l.strip_prefix("samples "))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{read}"));
    // Each chunk carries about 249 / 27 samples, and the ones cut at its ends.
    assert!((1960..2000).contains(&samples), "{read}");
    assert!(
        read.contains("increasing True"),
        "whole samples, in order: {read}"
    );
    assert_eq!(c[4], 3, "three chunks lost: {c:?}");
}
