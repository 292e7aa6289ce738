//! `mavtables inspect`: list, decode, summarise or check the frames of a capture.
//!
//! Reads the capture from any [`Read`] as it comes (a file of any size in constant
//! memory, or standard input while it is written) and writes to any [`Write`], so
//! every mode is testable without touching the file system. Output is flushed whenever
//! more input has to be waited for: a live capture is listed frame by frame as it
//! arrives, and a file is listed at full speed.
//!
//! Listing and decoding read a capture as the router does: a MAVLink 2 frame longer than
//! its message's known length (a newer dialect's extension fields) is a frame, marked
//! `longer than known` and counted in the summary, and decoding ignores its extra bytes.
//! `--check` is strict: such a frame is a problem ("payload length N is longer than
//! message #id's known M bytes"), as the file is not valid for this dialect.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{self, Read, Write};

use serde::ser::{Serialize, SerializeMap, Serializer};

use crate::address::{Address, Subnet};
use crate::capture::{Capture, Format, Unit, Units};
use crate::dialect::{Dialect, decode};
use crate::wire::{Checks, Frame, ParseEvents, Parser, ParserStats, Rejection};

use crate::utc;

/// What `inspect` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// One JSON object per frame with every field decoded (summary on the error stream).
    pub json: bool,
    /// Verdict only: is the file a valid sequence of zero or more frames?
    pub check: bool,
    /// With `check`: message ids allowed (others are a problem).
    pub only: Option<Vec<u32>>,
    /// Check structure only, not checksums.
    pub no_crc: bool,
    /// Show only these message ids.
    pub msgs: Option<Vec<u32>>,
    /// Show only frames whose source is in this subnet.
    pub from: Option<Subnet>,
    /// Show only frames whose target is in this subnet (frames without one never match).
    pub to: Option<Subnet>,
    /// The messages known: the built-in table plus `--dialect` files.
    pub dialect: Dialect,
}

/// The first thing wrong with a capture, for `--check`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// Byte offset in the file.
    pub offset: u64,
    /// What is wrong.
    pub reason: String,
}

/// What one file contained.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// The capture's format.
    pub format: Format,
    /// Its length in bytes.
    pub bytes: u64,
    /// Valid frames.
    pub frames: u64,
    /// Frames that passed the `--msg/--from/--to` selection.
    pub selected: u64,
    /// Parser totals over the whole file.
    pub stats: ParserStats,
    /// Selected frames per message id.
    pub per_message: BTreeMap<u32, u64>,
    /// Selected frames per source address.
    pub per_source: BTreeMap<Address, u64>,
    /// The first problem found, if any (`None` means the file is a valid sequence).
    pub problem: Option<Problem>,
    /// What stopped the reading of the capture before its end (a damaged record), if
    /// anything: the rest of the file was not read.
    pub read_error: Option<Problem>,
    /// Packets of a pcap or pcapng capture passed over: not IPv4/UDP, or of a link type
    /// this reader does not know.
    pub passed_over: u64,
}

/// Why inspecting a capture stopped short.
#[derive(Debug)]
pub enum Failure {
    /// Reading the capture failed.
    Input(io::Error),
    /// Writing the output failed.
    Output(io::Error),
}

/// Receives parser events for the units of a capture.
struct Sink<'a> {
    opts: &'a Options,
    out: &'a mut dyn Write,
    report: Report,
    /// File offset of the parser's stream offset 0: the unit's first byte, or 0 for a
    /// raw capture (one stream read in pieces).
    base: u64,
    timestamp_us: Option<u64>,
    /// The text line being written.
    line: String,
    /// The JSON line being written.
    json: Vec<u8>,
    io_error: Option<io::Error>,
    /// Where the junk that is the problem ends, while it is the last event: a raw
    /// capture read in pieces reports a run of junk across two pieces in two parts,
    /// which make one problem.
    junk_problem: Option<(u64, usize)>,
}

impl Sink<'_> {
    fn problem(&mut self, offset: u64, reason: impl FnOnce() -> String) {
        self.junk_problem = None;
        if self.report.problem.is_none() {
            self.report.problem = Some(Problem {
                offset: self.base + offset,
                reason: reason(),
            });
        }
    }

    fn junk_reason(len: usize) -> String {
        format!("{len} byte(s) that are not part of any frame")
    }

    fn selected(&self, f: &Frame<'_>) -> bool {
        let o = self.opts;
        o.msgs
            .as_ref()
            .is_none_or(|ids| ids.contains(&f.message_id()))
            && o.from.is_none_or(|s| s.contains(f.source()))
            && o.to
                .is_none_or(|s| f.target().is_some_and(|t| s.contains(t)))
    }

    fn write_text(&mut self, f: &Frame<'_>) {
        let line = &mut self.line;
        line.clear();
        match self.timestamp_us {
            Some(ts) => line.push_str(&utc::format_micros(ts)),
            None => {
                let _ = write!(line, "@{:<10}", self.base + f.offset());
            }
        }
        let v = f.version().number();
        let target = f
            .target()
            .map_or_else(|| "-".to_string(), |t| t.to_string());
        let _ = write!(
            line,
            "  v{v}  seq {:>3}  {:>7} -> {:<7}  {} (#{})  len {}{}{}",
            f.seq(),
            f.source().to_string(),
            target,
            f.name(),
            f.message_id(),
            f.payload_len(),
            if f.is_longer_than_known() {
                "  longer than known"
            } else {
                ""
            },
            if f.is_signed() { "  signed" } else { "" }
        );
        line.push('\n');
    }

    fn write_json(&mut self, f: &Frame<'_>) {
        self.json.clear();
        let frame = JsonFrame {
            f,
            offset: self.base + f.offset(),
            time_us: self.timestamp_us,
        };
        // Into memory, of numbers and strings: this cannot fail.
        let _ = serde_json::to_writer(&mut self.json, &frame);
        self.json.push(b'\n');
    }
}

/// One frame as `inspect --json` writes it: where and when it was, its header, and every
/// field of its message.
struct JsonFrame<'a, 'f> {
    f: &'a Frame<'f>,
    offset: u64,
    time_us: Option<u64>,
}

impl Serialize for JsonFrame<'_, '_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let f = self.f;
        let mut m = s.serialize_map(Some(13))?;
        m.serialize_entry("offset", &self.offset)?;
        m.serialize_entry("time_us", &self.time_us)?;
        m.serialize_entry("version", &f.version().number())?;
        m.serialize_entry("seq", &f.seq())?;
        m.serialize_entry("sys", &f.system())?;
        m.serialize_entry("comp", &f.component())?;
        m.serialize_entry("msg_id", &f.message_id())?;
        m.serialize_entry("name", f.name())?;
        m.serialize_entry("len", &f.payload_len())?;
        m.serialize_entry("signed", &f.is_signed())?;
        m.serialize_entry("target", &f.target().map(|t| t.to_string()))?;
        let fields = decode::Fields {
            info: f.info(),
            payload: f.payload(),
        };
        m.serialize_entry("fields", &fields)?;
        m.end()
    }
}

impl ParseEvents for Sink<'_> {
    fn frame(&mut self, f: Frame<'_>) {
        self.junk_problem = None;
        self.report.frames += 1;
        if let Some(only) = &self.opts.only
            && !only.contains(&f.message_id())
        {
            let text = f.to_string();
            self.problem(f.offset(), || {
                format!("{text} is not one of the allowed messages")
            });
        }
        // MAVLink 2 defines no compatibility flags: a strict check treats any as a fault
        // (a router ignores them, as the protocol allows).
        if self.opts.check && f.compat_flags() != 0 {
            let flags = f.compat_flags();
            self.problem(f.offset(), || {
                format!("unknown compatibility flags 0x{flags:02x}")
            });
        }
        if self.opts.check || !self.selected(&f) {
            return;
        }
        self.report.selected += 1;
        *self.report.per_message.entry(f.message_id()).or_default() += 1;
        *self.report.per_source.entry(f.source()).or_default() += 1;
        if self.io_error.is_some() {
            return;
        }
        let written = if self.opts.json {
            self.write_json(&f);
            &self.json[..]
        } else {
            self.write_text(&f);
            self.line.as_bytes()
        };
        if let Err(e) = self.out.write_all(written) {
            self.io_error = Some(e);
        }
    }

    fn rejected(&mut self, offset: u64, why: Rejection) {
        self.problem(offset, || why.to_string());
    }

    fn junk(&mut self, offset: u64, len: usize) {
        let at = self.base + offset;
        if let Some((start, before)) = self.junk_problem
            && start + before as u64 == at
            && let Some(p) = &mut self.report.problem
        {
            p.reason = Self::junk_reason(before + len);
            self.junk_problem = Some((start, before + len));
            return;
        }
        let first = self.report.problem.is_none();
        self.problem(offset, || Self::junk_reason(len));
        if first {
            self.junk_problem = Some((at, len));
        }
    }
}

/// Feeds the units of a capture to the parser: one parser for a raw capture's pieces,
/// a fresh one for each tlog record or datagram (each is a stream of its own).
struct Run<'a> {
    sink: Sink<'a>,
    checks: Checks,
    dialect: Dialect,
    stream: Option<Parser>,
}

impl Units for Run<'_> {
    fn unit(&mut self, unit: Unit<'_>) -> bool {
        let sink = &mut self.sink;
        sink.timestamp_us = unit.timestamp_us;
        match &mut self.stream {
            Some(parser) => parser.feed_events(unit.bytes, sink),
            None => {
                sink.base = unit.offset;
                let mut parser = Parser::with_checks(self.checks).with_dialect(self.dialect);
                parser.feed_events(unit.bytes, sink);
                parser.finish(sink);
                sink.report.stats += *parser.stats();
            }
        }
        sink.io_error.is_none()
    }

    fn waiting(&mut self) {
        if self.sink.io_error.is_none()
            && let Err(e) = self.sink.out.flush()
        {
            self.sink.io_error = Some(e);
        }
    }
}

/// What the parser checks for these options: strict for `--check`, as a router otherwise.
fn checks(opts: &Options) -> Checks {
    Checks {
        crc: !opts.no_crc,
        known_length: opts.check,
        accept_unknown: false,
    }
}

/// Inspects the capture read from `input`, writing per-frame output to `out` (nothing
/// in `check` mode). Returns what was found.
pub fn inspect(input: impl Read, opts: &Options, out: &mut dyn Write) -> Result<Report, Failure> {
    let capture = Capture::new(input).map_err(Failure::Input)?;
    let format = capture.format();
    let checks = checks(opts);
    let mut run = Run {
        sink: Sink {
            opts,
            out,
            report: Report {
                format,
                ..Report::default()
            },
            base: 0,
            timestamp_us: None,
            line: String::with_capacity(512),
            json: Vec::with_capacity(1024),
            io_error: None,
            junk_problem: None,
        },
        checks,
        dialect: opts.dialect,
        stream: (format == Format::Raw)
            .then(|| Parser::with_checks(checks).with_dialect(opts.dialect)),
    };
    let end = capture.read(&mut run).map_err(Failure::Input)?;
    let mut sink = run.sink;
    if let Some(mut parser) = run.stream
        && sink.io_error.is_none()
    {
        parser.finish(&mut sink);
        sink.report.stats += *parser.stats();
    }
    if let Some(e) = sink.io_error {
        return Err(Failure::Output(e));
    }
    let mut report = sink.report;
    report.bytes = end.bytes;
    report.passed_over = end.passed_over;
    if let Some(e) = end.error {
        let stop = Problem {
            offset: e.offset(),
            reason: e.to_string(),
        };
        if report
            .problem
            .as_ref()
            .is_none_or(|p| p.offset > stop.offset)
        {
            report.problem = Some(stop.clone());
        }
        report.read_error = Some(stop);
    }
    Ok(report)
}

/// Writes the end-of-file summary of `report` for the capture called `name`.
pub fn write_summary(name: &str, report: &Report, out: &mut dyn Write) -> io::Result<()> {
    write_summary_in(name, report, &Dialect::builtin(), out)
}

/// [`write_summary`], naming messages from `dialect`.
pub fn write_summary_in(
    name: &str,
    report: &Report,
    dialect: &Dialect,
    out: &mut dyn Write,
) -> io::Result<()> {
    let s = &report.stats;
    writeln!(
        out,
        "{name}: {} ({} bytes): {} frames, {} shown",
        report.format, report.bytes, report.frames, report.selected
    )?;
    writeln!(out, "  parser: {s}")?;
    if report.passed_over > 0 {
        writeln!(
            out,
            "  passed over: {} packets (not IPv4/UDP, or of a link type not read)",
            report.passed_over
        )?;
    }
    if !report.per_message.is_empty() {
        writeln!(out, "  messages:")?;
        for (id, n) in &report.per_message {
            let name = dialect.by_id(*id).map_or("?", |m| m.name);
            writeln!(out, "    {n:>8}  {name} (#{id})")?;
        }
        writeln!(out, "  sources:")?;
        for (addr, n) in &report.per_source {
            writeln!(out, "    {n:>8}  {addr}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::encode::{Header, encode_v1, encode_v2, encode_v2_exact};

    fn sample() -> Vec<u8> {
        let mut s = Vec::new();
        let h = |system| Header {
            seq: 1,
            system,
            component: 1,
        };
        encode_v2(h(1), 0, &[0, 0, 0, 0, 2, 3, 0, 4, 3], None, &mut s).expect("heartbeat");
        // PING to 127.1.
        encode_v1(
            h(2),
            4,
            &[0, 0, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 127, 1],
            &mut s,
        )
        .expect("ping");
        s
    }

    #[test]
    fn text_lines_and_summary() {
        let mut out = Vec::new();
        let r = inspect(sample().as_slice(), &Options::default(), &mut out).expect("in memory");
        let text = String::from_utf8(out).expect("utf-8");
        assert_eq!(
            text,
            "@0           v2  seq   1      1.1 -> -        HEARTBEAT (#0)  len 9\n\
             @21          v1  seq   1      2.1 -> 127.1    PING (#4)  len 14\n"
        );
        assert_eq!((r.frames, r.selected, &r.problem), (2, 2, &None));
        let mut summary = Vec::new();
        write_summary("s", &r, &mut summary).expect("in memory");
        let summary = String::from_utf8(summary).expect("utf-8");
        assert!(
            summary.starts_with("s: raw MAVLink (43 bytes): 2 frames, 2 shown\n"),
            "{summary}"
        );
        assert!(summary.contains("       1  PING (#4)\n"));
    }

    /// A HEARTBEAT, then a PING to 127.1 with 4 bytes beyond its known 14.
    fn with_a_longer_frame() -> Vec<u8> {
        let mut s = Vec::new();
        let h = Header {
            seq: 1,
            system: 1,
            component: 1,
        };
        encode_v2(h, 0, &[0, 0, 0, 0, 2, 3, 0, 4, 3], None, &mut s).expect("heartbeat");
        let mut ping = [0u8; 18];
        ping[8] = 5;
        ping[12] = 127;
        ping[13] = 1;
        ping[14..].copy_from_slice(&[0xaa; 4]);
        encode_v2_exact(h, 4, &ping, &mut s).expect("ping");
        s
    }

    #[test]
    fn longer_than_known_frames_are_listed_and_counted_but_fail_the_check() {
        let data = with_a_longer_frame();
        let mut out = Vec::new();
        let r = inspect(data.as_slice(), &Options::default(), &mut out).expect("in memory");
        let text = String::from_utf8(out).expect("utf-8");
        assert_eq!(
            text.lines().nth(1),
            Some(
                "@21          v2  seq   1      1.1 -> 127.1    PING (#4)  len 18  longer than known"
            )
        );
        assert_eq!(
            (r.frames, r.stats.longer_than_known, &r.problem),
            (2, 1, &None)
        );
        let mut summary = Vec::new();
        write_summary("s", &r, &mut summary).expect("in memory");
        let summary = String::from_utf8(summary).expect("utf-8");
        assert!(
            summary.contains(
                "\n  parser: 2 frames, 0 bad checksum, 0 unknown id, 0 bad flags, 0 bad length, \
                 0 truncated, 1 longer than known, 0 junk bytes\n"
            ),
            "{summary}"
        );
        // JSON decodes the known fields and ignores the rest.
        let json = Options {
            json: true,
            ..Options::default()
        };
        let mut out = Vec::new();
        inspect(data.as_slice(), &json, &mut out).expect("in memory");
        let text = String::from_utf8(out).expect("utf-8");
        assert!(
            text.lines().nth(1).is_some_and(|l| l.ends_with(
                "\"fields\":{\"time_usec\":0,\"seq\":5,\"target_system\":127,\"target_component\":1}}"
            )),
            "{text}"
        );
        // --check is strict.
        let check = Options {
            check: true,
            ..Options::default()
        };
        let r = inspect(data.as_slice(), &check, &mut Vec::new()).expect("in memory");
        assert_eq!(
            r.problem,
            Some(Problem {
                offset: 21,
                reason: "payload length 18 is longer than message #4's known 14 bytes".into()
            })
        );
        assert_eq!((r.frames, r.stats.bad_length), (1, 1));
    }

    #[test]
    fn filters_select_frames() {
        let opts = Options {
            to: Some("127.0/8".parse().expect("subnet")),
            ..Options::default()
        };
        let mut out = Vec::new();
        let r = inspect(sample().as_slice(), &opts, &mut out).expect("in memory");
        assert_eq!((r.frames, r.selected), (2, 1));
        let opts = Options {
            msgs: Some(vec![0]),
            from: Some("1.1".parse().expect("subnet")),
            ..Options::default()
        };
        assert_eq!(
            inspect(sample().as_slice(), &opts, &mut Vec::new())
                .expect("in memory")
                .selected,
            1
        );
    }

    #[test]
    fn json_has_every_field() {
        let opts = Options {
            json: true,
            ..Options::default()
        };
        let mut out = Vec::new();
        inspect(sample().as_slice(), &opts, &mut out).expect("in memory");
        let text = String::from_utf8(out).expect("utf-8");
        let first = text.lines().next().expect("a line");
        assert_eq!(
            first,
            "{\"offset\":0,\"time_us\":null,\"version\":2,\"seq\":1,\"sys\":1,\"comp\":1,\"msg_id\":0,\
             \"name\":\"HEARTBEAT\",\"len\":9,\"signed\":false,\"target\":null,\"fields\":{\"custom_mode\":0,\
             \"type\":2,\"autopilot\":3,\"base_mode\":0,\"system_status\":4,\"mavlink_version\":3}}"
        );
    }

    #[test]
    fn check_reports_the_first_problem_with_its_offset() {
        let mut data = sample();
        data[25] ^= 0xff; // inside the PING payload: bad checksum
        let opts = Options {
            check: true,
            ..Options::default()
        };
        let r = inspect(data.as_slice(), &opts, &mut Vec::new()).expect("in memory");
        assert_eq!(
            r.problem,
            Some(Problem {
                offset: 21,
                reason: "bad checksum".into()
            })
        );
        let only = Options {
            check: true,
            only: Some(vec![0]),
            ..Options::default()
        };
        let r = inspect(sample().as_slice(), &only, &mut Vec::new()).expect("in memory");
        assert_eq!(r.problem.map(|p| p.offset), Some(21));
        let r = inspect(&sample()[..30], &opts, &mut Vec::new()).expect("in memory");
        assert_eq!(
            r.problem.map(|p| (p.offset, p.reason)),
            Some((21, "truncated frame: needs 22 bytes, 9 present".into()))
        );
    }

    #[test]
    fn empty_and_garbage_inputs() {
        let opts = Options {
            check: true,
            ..Options::default()
        };
        assert_eq!(
            inspect(&[][..], &opts, &mut Vec::new())
                .expect("in memory")
                .problem,
            None
        );
        let r = inspect(&b"garbage"[..], &opts, &mut Vec::new()).expect("in memory");
        assert_eq!(r.problem.map(|p| p.offset), Some(0));
    }
}
