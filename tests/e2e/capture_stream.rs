//! `inspect` reads captures as a stream: the same output as the in-memory reader it
//! replaced, byte for byte, on every file in `tests/data` and on generated edge cases
//! (records across read boundaries, a record longer than the read window, cut files),
//! whether the capture is a file, standard input, or arrives in reads of any size.
//!
//! The expected outputs are digests of what the binary printed before streaming
//! (commit 9b8c354), in `tests/golden/inspect.tsv`. To record them again from another
//! build: `MAVTABLES_GOLDEN_BIN=/path/to/old/mavtables cargo test --test capture_stream`.

use crate::common;

use std::fmt::Write as _;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::router::Scratch;
use common::{data, read_data};
use mavtables::commands::inspect::{self, Options};
use mavtables::commands::replay;
use sha2::{Digest, Sha256};

const BIN: &str = env!("CARGO_BIN_EXE_mavtables");

fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/inspect.tsv")
}

/// A pcap file header (little-endian, µs, link type `DLT_NULL` like `rural.pcap`).
fn pcap_header() -> Vec<u8> {
    read_data("flight/rural.pcap")[..24].to_vec()
}

/// The records of `rural.pcap` (header and data), in order.
fn pcap_records() -> Vec<Vec<u8>> {
    let data = read_data("flight/rural.pcap");
    let mut at = 24;
    let mut out = Vec::new();
    while at < data.len() {
        let incl = u32::from_le_bytes(data[at + 8..at + 12].try_into().expect("4 bytes")) as usize;
        out.push(data[at..at + 16 + incl].to_vec());
        at += 16 + incl;
    }
    out
}

fn pcapng_block(kind: u32, body: &[u8]) -> Vec<u8> {
    let total = (12 + body.len().div_ceil(4) * 4) as u32;
    let mut b = kind.to_le_bytes().to_vec();
    b.extend(total.to_le_bytes());
    b.extend(body);
    b.resize(total as usize - 4, 0);
    b.extend(total.to_le_bytes());
    b
}

/// The first 3,000 packets of `rural.pcap` as pcapng: a section, one interface
/// (`DLT_NULL`, µs) with a timestamp-resolution option, an unknown block, then one
/// Enhanced Packet Block per packet.
fn rural_pcapng() -> Vec<u8> {
    let mut shb = 0x1A2B_3C4Du32.to_le_bytes().to_vec();
    shb.extend([1, 0, 0, 0]);
    shb.extend(u64::MAX.to_le_bytes());
    let mut out = pcapng_block(0x0A0D_0D0A, &shb);
    let mut idb = 0u16.to_le_bytes().to_vec();
    idb.extend([0, 0, 0, 0, 0, 0]);
    idb.extend([9, 0, 1, 0, 6, 0, 0, 0]); // if_tsresol = 10^-6
    idb.extend([0, 0, 0, 0]);
    out.extend(pcapng_block(1, &idb));
    out.extend(pcapng_block(0xBAD, b"not a packet"));
    for rec in pcap_records().iter().take(3000) {
        let secs = u64::from(u32::from_le_bytes(rec[0..4].try_into().expect("4")));
        let us = u64::from(u32::from_le_bytes(rec[4..8].try_into().expect("4")));
        let ts = secs * 1_000_000 + us;
        let packet = &rec[16..];
        let mut epb = 0u32.to_le_bytes().to_vec();
        epb.extend(((ts >> 32) as u32).to_le_bytes());
        epb.extend((ts as u32).to_le_bytes());
        epb.extend((packet.len() as u32).to_le_bytes());
        epb.extend((packet.len() as u32).to_le_bytes());
        epb.extend(packet);
        out.extend(pcapng_block(6, &epb));
    }
    out
}

/// A pcap whose second record is longer than the reader's window (300 KiB: the
/// flight's second packet followed by padding) between two ordinary records.
fn pcap_with_a_huge_record() -> Vec<u8> {
    let recs = pcap_records();
    let mut out = pcap_header();
    out.extend(&recs[0]);
    let mut huge = recs[1].clone();
    let incl = 300 * 1024;
    huge.resize(16 + incl, 0xEE);
    huge[8..12].copy_from_slice(&(incl as u32).to_le_bytes());
    out.extend(&huge);
    out.extend(&recs[2]);
    out
}

/// The raw flight with 100 junk bytes where the first read of a file ends (the window
/// is 320 KiB), so the junk comes in two reads.
fn raw_with_junk_across_reads() -> Vec<u8> {
    let raw = read_data("mavlink_full/pass.53");
    // A frame boundary just before the read boundary at 327,680.
    let mut parser = mavtables::wire::Parser::new();
    let mut cut = 0;
    parser.feed(&raw, |f| {
        let end = f.offset() as usize + f.as_bytes().len();
        if end <= 327_650 {
            cut = end;
        }
    });
    let mut out = raw[..cut].to_vec();
    out.resize(327_650, 0x55);
    out.extend([0x55; 100]);
    out.extend(&raw[cut..cut + 50_000]);
    out
}

/// Generated captures: name and bytes.
fn generated() -> Vec<(&'static str, Vec<u8>)> {
    let tlog = read_data("flight/rural.tlog");
    let pcap = read_data("flight/rural.pcap");
    let ng = rural_pcapng();
    let mut tcp = pcap[..24 + 16 + 73].to_vec();
    tcp[24 + 16 + 4 + 9] = 6;
    vec![
        ("empty", Vec::new()),
        ("garbage", b"this is not mavlink at all".to_vec()),
        ("tlog-cut-1000", tlog[..1000].to_vec()),
        ("tlog-cut-mid-record", tlog[..100_003].to_vec()),
        ("tlog-first-9", tlog[..9].to_vec()),
        ("pcap-cut-mid-record", pcap[..100_003].to_vec()),
        ("pcap-cut-mid-header", pcap[..24 + 8].to_vec()),
        ("pcap-header-only-short", pcap[..20].to_vec()),
        ("pcap-tcp", tcp),
        ("pcap-huge-record", pcap_with_a_huge_record()),
        ("pcapng", ng.clone()),
        ("pcapng-cut", ng[..ng.len() - 7].to_vec()),
        ("raw-junk-across-reads", raw_with_junk_across_reads()),
    ]
}

/// One run of `inspect`: its name, the capture files, the extra arguments, and whether
/// it is also run with the capture on standard input (one file only).
struct Case {
    name: String,
    files: Vec<PathBuf>,
    args: Vec<&'static str>,
    stdin: bool,
}

/// Every case. The test vectors run one directory at a time (`inspect` takes many
/// files), the flight and the generated captures one by one, from the file and from
/// standard input. The generated captures are written into `scratch`.
fn cases(scratch: &Scratch) -> Vec<Case> {
    let modes = || [vec![], vec!["--json"], vec!["--check"]];
    let mut out = Vec::new();
    for dir in ["mavlink_full", "seed_scaled_pressure"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(data(dir))
            .expect("data dir")
            .map(|e| e.expect("entry").path())
            .collect();
        files.sort();
        for args in modes() {
            out.push(Case {
                name: dir.to_string(),
                files: files.clone(),
                args,
                stdin: false,
            });
        }
    }
    let mut single: Vec<(String, PathBuf)> = ["flight/rural.tlog", "flight/rural.pcap"]
        .iter()
        .map(|f| (f.to_string(), data(f)))
        .collect();
    for (name, bytes) in generated() {
        let path = scratch.dir.join(name);
        std::fs::write(&path, bytes).expect("write generated capture");
        single.push((format!("generated/{name}"), path));
    }
    for (name, path) in single {
        // From standard input too: every mode for the small captures, the verdict for
        // the flight (the in-process test reads it in pieces of every size).
        let small = std::fs::metadata(&path).expect("capture").len() < 1_000_000;
        for args in modes() {
            let stdin = small || args == ["--check"];
            out.push(Case {
                name: name.clone(),
                files: vec![path.clone()],
                args,
                stdin,
            });
        }
    }
    out.push(Case {
        name: "flight/rural.tlog".into(),
        files: vec![data("flight/rural.tlog")],
        args: vec![
            "--msg",
            "COMMAND_LONG,PING",
            "--from",
            "255.0/8",
            "--to",
            "1.1",
        ],
        stdin: true,
    });
    out.push(Case {
        name: "seed_scaled_pressure".into(),
        files: vec![data("seed_scaled_pressure")],
        args: vec!["--check", "--only", "SCALED_PRESSURE", "--no-crc"],
        stdin: false,
    });
    if let Some(last) = out.last_mut() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(data("seed_scaled_pressure"))
            .expect("data dir")
            .map(|e| e.expect("entry").path())
            .collect();
        files.sort();
        last.files = files;
    }
    out
}

fn hex(d: &[u8]) -> String {
    d.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// Runs `bin inspect ARGS FILES` (or `-` with the one file on standard input) and
/// returns "stdout digest, stderr digest, exit code", with the data and scratch
/// folders in file names written as `DATA` and `SCRATCH`.
fn digest(bin: &str, case: &Case, stdin: bool, scratch: &Scratch) -> String {
    let mut cmd = Command::new(bin);
    cmd.arg("inspect").args(&case.args);
    if stdin {
        cmd.arg("-")
            .stdin(std::fs::File::open(&case.files[0]).expect("open capture"));
    } else {
        cmd.args(&case.files).stdin(Stdio::null());
    }
    let out = cmd.output().expect("run inspect");
    let data_dir = data("").display().to_string();
    let scratch_dir = format!("{}/", scratch.dir.display());
    let first = case.files[0].display().to_string();
    let norm = |b: &[u8]| {
        let text = String::from_utf8_lossy(b);
        let mut s = String::new();
        for line in text.split_inclusive('\n') {
            // Standard input is named `-` where a file is named by its path (also in
            // the error line that says where the reading stopped).
            let (head, line) = match line.strip_prefix("error: ") {
                Some(rest) => ("error: ", rest),
                None => ("", line),
            };
            s.push_str(head);
            match line.strip_prefix("-: ") {
                Some(rest) if stdin => {
                    s.push_str(&first);
                    s.push_str(": ");
                    s.push_str(rest);
                }
                _ => s.push_str(line),
            }
        }
        let s = s
            .replace(&data_dir, "DATA/")
            .replace(&scratch_dir, "SCRATCH/");
        hex(&Sha256::digest(s.as_bytes()))
    };
    format!(
        "{}\t{}\t{}",
        norm(&out.stdout),
        norm(&out.stderr),
        out.status.code().unwrap_or(-1)
    )
}

#[test]
fn output_is_byte_identical_to_the_in_memory_reader_for_files_and_standard_input() {
    let scratch = Scratch::new("capture-stream");
    let cases = cases(&scratch);
    if let Ok(old) = std::env::var("MAVTABLES_GOLDEN_BIN") {
        let mut tsv = String::from("# case\targuments\tstdout sha256\tstderr sha256\texit code\n");
        for case in &cases {
            let d = digest(&old, case, false, &scratch);
            let _ = writeln!(tsv, "{}\t{}\t{d}", case.name, case.args.join(" "));
        }
        std::fs::create_dir_all(golden_path().parent().expect("dir")).expect("golden dir");
        std::fs::write(golden_path(), tsv).expect("write golden file");
    }
    let golden = std::fs::read_to_string(golden_path()).expect("tests/golden/inspect.tsv");
    let expected: Vec<&str> = golden.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(expected.len(), cases.len(), "one golden line per case");
    let mut wrong = Vec::new();
    for (case, want) in cases.iter().zip(&expected) {
        let prefix = format!("{}\t{}\t", case.name, case.args.join(" "));
        assert!(
            want.starts_with(&prefix),
            "golden line {want:?} is for another case than {prefix:?}"
        );
        for stdin in [false, true] {
            if stdin && !case.stdin {
                continue;
            }
            let got = format!("{prefix}{}", digest(BIN, case, stdin, &scratch));
            if got != *want {
                wrong.push(format!(
                    "{} {} {:?}",
                    if stdin { "stdin" } else { "file" },
                    case.name,
                    case.args
                ));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "output differs from before streaming: {wrong:#?}"
    );
}

/// A reader that returns at most a few bytes per read, the counts drawn from `seed`.
struct ShortReads<'a> {
    data: &'a [u8],
    state: u64,
    most: usize,
}

impl Read for ShortReads<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.state = self
            .state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let n = ((self.state >> 33) as usize % self.most + 1)
            .min(buf.len())
            .min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fn run_inspect(input: impl Read, opts: &Options) -> (String, String) {
    let mut out = Vec::new();
    let report = inspect::inspect(input, opts, &mut out).expect("in memory");
    let mut summary = Vec::new();
    inspect::write_summary("x", &report, &mut summary).expect("in memory");
    (
        String::from_utf8_lossy(&out).into_owned() + &String::from_utf8_lossy(&summary),
        format!("{:?}", report.problem),
    )
}

/// Frames replay would send: timestamp and bytes.
type Sent = Vec<(Option<u64>, Vec<u8>)>;

fn frames(input: impl Read) -> (Sent, String) {
    let mut got = Vec::new();
    let r = replay::for_each_frame(input, mavtables::dialect::Dialect::builtin(), |f| {
        got.push((f.timestamp_us, f.bytes.to_vec()));
        Ok(())
    });
    (got, format!("{:?}", r.err()))
}

#[test]
fn reads_of_any_size_give_the_same_output_and_frames() {
    let mut captures: Vec<(String, Vec<u8>)> = generated()
        .into_iter()
        .map(|(n, b)| (n.to_string(), b))
        .collect();
    for f in [
        "flight/rural.tlog",
        "flight/rural.pcap",
        "mavlink_full/pass.53",
        "mavlink_full/fail.53",
        "seed_scaled_pressure/fail.31",
    ] {
        captures.push((f.to_string(), read_data(f)));
    }
    let modes = [
        Options::default(),
        Options {
            check: true,
            ..Options::default()
        },
    ];
    let mut compared = 0;
    for (name, bytes) in &captures {
        let whole_frames = frames(bytes.as_slice());
        for opts in &modes {
            let whole = run_inspect(bytes.as_slice(), opts);
            // One-byte reads on the small captures; on the big ones, reads that still
            // split most records and cross the 320 KiB window's end.
            let sizes = if bytes.len() < 400_000 {
                [(1, 1), (2, 7), (3, 300), (4, 70_000)]
            } else {
                [(1, 61), (2, 997), (3, 40_000), (4, 70_000)]
            };
            for (seed, most) in sizes {
                let short = ShortReads {
                    data: bytes,
                    state: seed,
                    most,
                };
                assert!(
                    run_inspect(short, opts) == whole,
                    "{name}: reads of at most {most} bytes change the output"
                );
                compared += 1;
            }
        }
        let short = ShortReads {
            data: bytes,
            state: 9,
            most: 113,
        };
        assert!(
            frames(short) == whole_frames,
            "{name}: short reads change the frames replayed"
        );
    }
    assert_eq!(compared, captures.len() * 8);
}

#[test]
fn a_record_longer_than_the_window_is_passed_over_without_losing_its_neighbours() {
    let capture = pcap_with_a_huge_record();
    let (text, problem) = run_inspect(capture.as_slice(), &Options::default());
    assert_eq!(problem, "None");
    let lines: Vec<&str> = text.lines().filter(|l| l.starts_with("20")).collect();
    assert_eq!(lines.len(), 3, "{text}");
    assert!(
        text.contains(&format!(
            "x: pcap ({} bytes): 3 frames, 3 shown",
            capture.len()
        )),
        "{text}"
    );
    // Cut inside the huge record's padding: reported at that record, as before.
    let cut = &capture[..capture.len() - 100];
    let check = Options {
        check: true,
        ..Options::default()
    };
    let mut out = Vec::new();
    let report = inspect::inspect(cut, &check, &mut out).expect("in memory");
    let second = 24 + pcap_records()[0].len() as u64;
    assert_eq!(
        report.problem.map(|p| (p.offset, p.reason)),
        Some((second, "file ends inside a packet record".to_string()))
    );
}

#[test]
fn standard_input_is_named_dash_and_read_to_its_end() {
    let mut child = Command::new(BIN)
        .args(["inspect", "--check", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn inspect");
    let tlog = read_data("flight/rural.tlog");
    let mut stdin = child.stdin.take().expect("stdin");
    let writer = std::thread::spawn(move || {
        for chunk in tlog.chunks(4096) {
            stdin.write_all(chunk).expect("write to inspect");
        }
    });
    let out = child.wait_with_output().expect("inspect exits");
    writer.join().expect("writer");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        "-: valid (33261 frames)\n"
    );
    assert!(out.status.success());
}
