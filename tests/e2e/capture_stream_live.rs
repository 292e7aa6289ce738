//! `inspect -` and `replay -` on live input: each frame is shown (or sent) as soon as
//! its bytes arrive on standard input, before the input ends; and `inspect` reads a
//! capture of any size in constant memory.

use crate::common;

use std::io::{BufRead, BufReader, Write};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

use common::read_data;
use common::router::Scratch;
use mavtables::capture::tlog;

const BIN: &str = env!("CARGO_BIN_EXE_mavtables");
const WAIT: Duration = Duration::from_secs(10);

/// `inspect ARGS` with piped standard input, and its output lines as they come.
fn spawn_inspect(args: &[&str]) -> (Child, ChildStdin, Receiver<String>) {
    let mut child = Command::new(BIN)
        .arg("inspect")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn inspect");
    let stdin = child.stdin.take().expect("stdin");
    let stdout = child.stdout.take().expect("stdout");
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (child, stdin, rx)
}

/// The next output line, waiting at most [`WAIT`].
fn next_line(rx: &Receiver<String>, what: &str) -> String {
    rx.recv_timeout(WAIT)
        .unwrap_or_else(|e| panic!("no line for {what} within {WAIT:?}: {e}"))
}

/// The lines `inspect` prints for a whole capture file (the reference).
fn listing(rel: &str) -> Vec<String> {
    let out = Command::new(BIN)
        .args(["inspect", &common::data(rel).display().to_string()])
        .output()
        .expect("run inspect");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(str::to_string)
        .collect()
}

/// Writes `pieces` one at a time, each time reading the line it must produce before
/// writing the next (the input stays open), then closes the input and returns the rest.
fn feed_live(args: &[&str], pieces: &[Vec<u8>], expected: &[String]) -> Vec<String> {
    let (mut child, mut stdin, rx) = spawn_inspect(args);
    for (i, piece) in pieces.iter().enumerate() {
        stdin.write_all(piece).expect("write to inspect");
        stdin.flush().expect("flush");
        assert_eq!(
            next_line(&rx, &format!("piece {i}")),
            expected[i],
            "piece {i}"
        );
    }
    drop(stdin);
    let status = child.wait().expect("inspect exits");
    assert!(status.success());
    rx.iter().collect()
}

#[test]
fn a_pcap_on_standard_input_is_listed_packet_by_packet_as_it_arrives() {
    let pcap = read_data("flight/rural.pcap");
    let mut pieces = vec![];
    let mut at = 24;
    for i in 0..3 {
        let incl = u32::from_le_bytes(pcap[at + 8..at + 12].try_into().expect("4")) as usize;
        let mut piece = if i == 0 { pcap[..24].to_vec() } else { vec![] };
        piece.extend(&pcap[at..at + 16 + incl]);
        pieces.push(piece);
        at += 16 + incl;
    }
    let expected = listing("flight/rural.pcap");
    let rest = feed_live(&["-"], &pieces, &expected);
    assert!(
        rest[0].starts_with(&format!("-: pcap ({at} bytes): 3 frames, 3 shown")),
        "{rest:?}"
    );
}

#[test]
fn a_tlog_and_a_raw_stream_on_standard_input_are_listed_frame_by_frame() {
    let tlog_data = read_data("flight/rural.tlog");
    let records: Vec<tlog::Record<'_>> = tlog::records(&tlog_data)
        .take(3)
        .map(|r| r.expect("record"))
        .collect();
    let pieces: Vec<Vec<u8>> = records
        .iter()
        .map(|r| {
            let at = r.offset as usize;
            tlog_data[at..at + 8 + r.frame.len()].to_vec()
        })
        .collect();
    let expected = listing("flight/rural.tlog");
    let rest = feed_live(&["-"], &pieces, &expected);
    assert!(rest[0].starts_with("-: tlog ("), "{rest:?}");

    // The same frames as a raw stream; JSON, one object per frame.
    let frames: Vec<Vec<u8>> = records.iter().map(|r| r.frame.to_vec()).collect();
    let raw: Vec<u8> = frames.concat();
    let scratch = Scratch::new("live");
    let path = scratch.dir.join("flight.raw");
    std::fs::write(&path, &raw).expect("write raw");
    let out = Command::new(BIN)
        .args(["inspect", "--json", &path.display().to_string()])
        .output()
        .expect("inspect");
    let expected: Vec<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(str::to_string)
        .collect();
    assert_eq!(expected.len(), 3);
    feed_live(&["--json", "-"], &frames, &expected);
}

/// A tlog of `copies` back-to-back copies of the flight (timestamps moved on by the
/// flight's span each time, so it reads as one long flight), in `scratch`.
fn long_tlog(scratch: &Scratch, copies: usize) -> PathBuf {
    let data = read_data("flight/rural.tlog");
    let recs: Vec<tlog::Record<'_>> = tlog::records(&data).map(|r| r.expect("record")).collect();
    let span = recs[recs.len() - 1].timestamp_us - recs[0].timestamp_us + 1000;
    let path = scratch.dir.join(format!("long-{copies}.tlog"));
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path).expect("create"));
    let mut copy = data.clone();
    for i in 0..copies as u64 {
        for r in &recs {
            let at = r.offset as usize;
            copy[at..at + 8].copy_from_slice(&(r.timestamp_us + i * span).to_be_bytes());
        }
        out.write_all(&copy).expect("write");
    }
    out.flush().expect("flush");
    path
}

/// Peak resident memory (kB) of `inspect --check FILE -`, read once the file's verdict
/// is out and while the process waits on the standard input the test holds open.
fn peak_rss_kb(file: &Path, copies: usize) -> u64 {
    let (mut child, stdin, rx) = spawn_inspect(&["--check", &file.display().to_string(), "-"]);
    let line = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the verdict on the long file");
    assert_eq!(
        line,
        format!("{}: valid ({} frames)", file.display(), copies * 33_261)
    );
    let status = std::fs::read_to_string(format!("/proc/{}/status", child.id())).expect("status");
    let peak = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmHWM in /proc/PID/status");
    drop(stdin);
    assert_eq!(next_line(&rx, "the empty input"), "-: valid (0 frames)");
    assert!(child.wait().expect("exit").success());
    peak
}

#[test]
fn memory_stays_flat_whatever_the_file_size() {
    // 30 and 120 copies of the flight: 38 MB and 151 MB.
    let (small, large) = (30, 120);
    // Removed with the scratch directory, however the test ends.
    let scratch = Scratch::new("long-tlog");
    let (small_file, large_file) = (long_tlog(&scratch, small), long_tlog(&scratch, large));
    let small_kb = peak_rss_kb(&small_file, small);
    let large_kb = peak_rss_kb(&large_file, large);
    let size = std::fs::metadata(&large_file).expect("size").len();
    eprintln!("peak RSS: {small_kb} kB for 38 MB, {large_kb} kB for {size} bytes");
    assert!(large_kb < 20_000, "{large_kb} kB for a {size}-byte file");
    assert!(
        large_kb < small_kb + 2_000,
        "memory grows with the file: {small_kb} kB, then {large_kb} kB"
    );
}

#[test]
fn replay_from_standard_input_sends_each_frame_as_it_arrives() {
    let data = read_data("flight/rural.tlog");
    let records: Vec<tlog::Record<'_>> = tlog::records(&data)
        .take(50)
        .map(|r| r.expect("record"))
        .collect();
    let sink = UdpSocket::bind("127.0.0.1:0").expect("bind");
    sink.set_read_timeout(Some(WAIT)).expect("timeout");
    let to = format!("udp:{}", sink.local_addr().expect("addr"));
    let mut child = Command::new(BIN)
        .args(["replay", "-", "--to", &to, "--speed", "max"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn replay");
    let mut stdin = child.stdin.take().expect("stdin");
    let mut buf = [0u8; 2048];
    // The first two records one at a time: each is sent before the next is written.
    for r in &records[..2] {
        let at = r.offset as usize;
        stdin
            .write_all(&data[at..at + 8 + r.frame.len()])
            .expect("write");
        stdin.flush().expect("flush");
        let n = sink.recv(&mut buf).expect("the frame, while stdin is open");
        assert_eq!(&buf[..n], r.frame);
    }
    let last = &records[records.len() - 1];
    let end = last.offset as usize + 8 + last.frame.len();
    stdin
        .write_all(&data[records[2].offset as usize..end])
        .expect("write");
    drop(stdin);
    for r in &records[2..] {
        let n = sink.recv(&mut buf).expect("a datagram");
        assert_eq!(&buf[..n], r.frame);
    }
    let out = child.wait_with_output().expect("replay exits");
    assert!(out.status.success());
    let bytes: usize = records.iter().map(|r| r.frame.len()).sum();
    assert!(
        String::from_utf8_lossy(&out.stdout)
            .starts_with(&format!("sent 50 frames ({bytes} bytes) to {to} in ")),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

#[test]
fn replay_from_standard_input_reports_a_broken_end_after_sending_what_came_before() {
    let data = read_data("flight/rural.tlog");
    let records: Vec<tlog::Record<'_>> = tlog::records(&data)
        .take(5)
        .map(|r| r.expect("record"))
        .collect();
    let sink = UdpSocket::bind("127.0.0.1:0").expect("bind");
    sink.set_read_timeout(Some(WAIT)).expect("timeout");
    let to = format!("udp:{}", sink.local_addr().expect("addr"));
    let mut child = Command::new(BIN)
        .args(["replay", "-", "--to", &to, "--speed", "max"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn replay");
    let mut stdin = child.stdin.take().expect("stdin");
    let cut = records[4].offset as usize + 12;
    stdin.write_all(&data[..cut]).expect("write");
    drop(stdin);
    let mut buf = [0u8; 2048];
    for r in &records[..4] {
        let n = sink.recv(&mut buf).expect("a datagram");
        assert_eq!(&buf[..n], r.frame);
    }
    let out = child.wait_with_output().expect("replay exits");
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("sent 4 frames ("));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!("error: -: file ends inside a record\n")
    );
}
