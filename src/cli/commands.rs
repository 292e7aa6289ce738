//! The command lines of the `inspect` and `replay` subcommands (read by the shared
//! [`super::arg_reader`] reader, so they follow the same rules as the main command) and
//! the texts they print.

use std::io::{IsTerminal, Read, Write};

use super::Outcome;
use super::arg_reader::{Arg, ArgReader, OptionSpec};
use crate::address::Subnet;
use crate::commands::inspect::{self, Failure, Options};
use crate::commands::replay::{self, ProgressBar, ReplayError, Speed, Target};
use crate::config::suggest::did_you_mean;
use crate::dialect::{Dialect, Loader};
use crate::files::{FileError, RegularFile};
use std::path::Path;

const INSPECT_USAGE: &str = "\
usage: mavtables inspect [OPTIONS] FILE...
  Reads raw MAVLink streams, .tlog, .pcap and .pcapng files (told from the content)
  and prints one line per frame and a summary. FILE '-' is standard input, listed as
  it arrives (tcpdump -U -w - udp port 14550 | mavtables inspect -).
  --json            one JSON object per frame, every field decoded (summary on stderr)
  --check           only a verdict: exit 0 if the file is a valid sequence of frames
  --only NAME[,..]  with --check: the message types allowed
  --no-crc          with --check: check structure only, not checksums
  --msg NAME[,..]   show only these message types
  --from SUBNET     show only frames from this MAVLink subnet (e.g. 1.0/8)
  --to SUBNET       show only frames targeted into this MAVLink subnet
  --dialect FILE    also know the messages of this MAVLink XML file (repeatable)
";

/// The options of `inspect`, as read by the shared reader.
const INSPECT_OPTIONS: &[OptionSpec] = &[
    OptionSpec::flag("help"),
    OptionSpec::flag("json"),
    OptionSpec::flag("check"),
    OptionSpec::value("only"),
    OptionSpec::flag("no-crc"),
    OptionSpec::value("msg"),
    OptionSpec::value("from"),
    OptionSpec::value("to"),
    OptionSpec::value("dialect"),
];

const REPLAY_USAGE: &str = "\
usage: mavtables replay FILE --to udp:HOST:PORT|serial:DEVICE:BAUD [--speed X|max]
                        [--dialect FILE]...
  Sends a capture's valid frames at their recorded timing (divided by X; default 1),
  or as fast as possible with --speed max. Raw streams have no timing: they are sent
  as fast as the link takes them. FILE '-' is standard input, sent as it arrives;
  any other FILE must be a regular file.
  --dialect FILE    also know the messages of this MAVLink XML file (repeatable);
                    frames of messages no dialect knows are not sent
";

/// The options of `replay`, as read by the shared reader.
const REPLAY_OPTIONS: &[OptionSpec] = &[
    OptionSpec::flag("help"),
    OptionSpec::value("to"),
    OptionSpec::value("speed"),
    OptionSpec::value("dialect"),
];

/// Runs `inspect`, `replay` or `stats` if `args` (without the program name) starts with one.
pub fn run_subcommand(
    args: &[String],
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Option<Outcome> {
    let (name, rest) = args.split_first()?;
    let result = match name.as_str() {
        "inspect" => run_inspect(rest, out, err),
        "replay" => run_replay(rest, out, err),
        "stats" => super::stats_args::run_stats(rest, out, err),
        _ => return None,
    };
    Some(match result {
        Ok(code) => Outcome::Exit(code),
        Err(message) => {
            let _ = writeln!(err, "error: {message}");
            Outcome::Exit(1)
        }
    })
}

/// Message ids from a comma-separated list of names in `dialect`.
fn message_ids(list: &str, dialect: &Dialect) -> Result<Vec<u32>, String> {
    list.split(',')
        .map(|name| {
            dialect.by_name(name).map(|m| m.id).ok_or_else(|| {
                match did_you_mean(name, dialect.names()) {
                    Some(hint) => format!("unknown message name '{name}'; {hint}"),
                    None => format!("unknown message name '{name}'"),
                }
            })
        })
        .collect()
}

/// Opens a capture: standard input for `-`, else the file, which must be a regular file
/// (a device is not opened, a FIFO not waited on: a stream comes in on standard input).
/// Also says whether it is a regular file (which can be read twice).
fn open_capture(file: &str) -> Result<(Box<dyn Read>, bool), String> {
    if file == "-" {
        return Ok((Box::new(std::io::stdin().lock()), false));
    }
    match RegularFile::open(Path::new(file)) {
        Ok(f) => Ok((Box::new(f.into_file()), true)),
        Err(e @ FileError::NotRegular(_)) => Err(format!(
            "cannot read {file}: it {e} (to read a stream, give - and send it to standard input)"
        )),
        Err(e) => Err(format!("cannot read {file}: it {e}")),
    }
}

fn subnet(text: &str) -> Result<Subnet, String> {
    text.parse()
        .map_err(|e: crate::address::SubnetParseError| e.0)
}

fn run_inspect(args: &[String], out: &mut dyn Write, err: &mut dyn Write) -> Result<u8, String> {
    let mut opts = Options::default();
    let mut files = Vec::new();
    // Names are resolved once every `--dialect` is loaded, wherever they were given.
    let (mut only, mut msgs) = (None, None);
    let mut dialects = Loader::new();
    let mut reader = ArgReader::new(args.iter().cloned(), &[INSPECT_OPTIONS]);
    while let Some(arg) = reader.next_arg()? {
        let (name, value) = match arg {
            Arg::Positional(file) => {
                files.push(file);
                continue;
            }
            Arg::Option { name, value } => (name, value.unwrap_or_default()),
        };
        match name {
            "help" => {
                let _ = out.write_all(INSPECT_USAGE.as_bytes());
                return Ok(0);
            }
            "json" => opts.json = true,
            "check" => opts.check = true,
            "no-crc" => opts.no_crc = true,
            "only" => only = Some(value),
            "msg" => msgs = Some(value),
            "dialect" => dialects
                .add(Path::new(&value))
                .map_err(|e| format!("cannot load the dialect: {e}"))?,
            "from" => opts.from = Some(subnet(&value)?),
            "to" => opts.to = Some(subnet(&value)?),
            _ => {}
        }
    }
    opts.dialect = dialects.finish();
    if let Some(list) = only {
        opts.only = Some(message_ids(&list, &opts.dialect)?);
    }
    if let Some(list) = msgs {
        opts.msgs = Some(message_ids(&list, &opts.dialect)?);
    }
    if files.is_empty() {
        let _ = err.write_all(INSPECT_USAGE.as_bytes());
        return Err("no capture file given".into());
    }
    if (opts.only.is_some() || opts.no_crc) && !opts.check {
        return Err("--only and --no-crc go with --check".into());
    }
    let mut code = 0;
    for file in &files {
        let (input, _) = open_capture(file)?;
        // Buffered for speed; `inspect` flushes whenever it waits for more input.
        let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut *out);
        let report = inspect::inspect(input, &opts, &mut buffered)
            .and_then(|r| buffered.flush().map(|()| r).map_err(Failure::Output));
        drop(buffered);
        let report = match report {
            Ok(r) => r,
            // The reader went away (`| head`): stop quietly, as command-line tools do.
            Err(Failure::Output(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                return Ok(code);
            }
            Err(Failure::Output(e)) => return Err(format!("writing output: {e}")),
            Err(Failure::Input(e)) => return Err(format!("cannot read {file}: {e}")),
        };
        if opts.check {
            match &report.problem {
                None if report.passed_over > 0 => {
                    let _ = writeln!(
                        out,
                        "{file}: valid ({} frames; {} packets passed over: not IPv4/UDP, or of a link type not read)",
                        report.frames, report.passed_over
                    );
                }
                None => {
                    let _ = writeln!(out, "{file}: valid ({} frames)", report.frames);
                }
                Some(p) => {
                    let _ = writeln!(out, "{file}: invalid at byte {}: {}", p.offset, p.reason);
                    code = 1;
                }
            }
        } else {
            let summary: &mut dyn Write = if opts.json { &mut *err } else { &mut *out };
            inspect::write_summary_in(file, &report, &opts.dialect, summary)
                .map_err(|e| format!("writing output: {e}"))?;
            // The rest of the file was not read: the listing is not the whole capture.
            if let Some(p) = &report.read_error {
                let _ = writeln!(
                    err,
                    "error: {file}: reading stopped at byte {}: {}; what follows it was not read",
                    p.offset, p.reason
                );
                code = 1;
            }
        }
    }
    Ok(code)
}

fn run_replay(args: &[String], out: &mut dyn Write, err: &mut dyn Write) -> Result<u8, String> {
    let mut file = None;
    let mut target = None;
    let mut speed = Speed::Factor(1.0);
    let mut dialects = Loader::new();
    let mut reader = ArgReader::new(args.iter().cloned(), &[REPLAY_OPTIONS]);
    while let Some(arg) = reader.next_arg()? {
        match arg {
            Arg::Option { name: "help", .. } => {
                let _ = out.write_all(REPLAY_USAGE.as_bytes());
                return Ok(0);
            }
            Arg::Option { name: "to", value } => {
                target = Some(Target::parse(&value.unwrap_or_default())?);
            }
            Arg::Option {
                name: "speed",
                value,
            } => speed = Speed::parse(&value.unwrap_or_default())?,
            Arg::Option {
                name: "dialect",
                value,
            } => dialects
                .add(Path::new(&value.unwrap_or_default()))
                .map_err(|e| format!("cannot load the dialect: {e}"))?,
            Arg::Option { .. } => {}
            Arg::Positional(f) if file.is_none() => file = Some(f),
            Arg::Positional(extra) => return Err(format!("unexpected argument '{extra}'")),
        }
    }
    let (Some(file), Some(target)) = (file, target) else {
        let _ = err.write_all(REPLAY_USAGE.as_bytes());
        return Err("replay needs a FILE and --to".into());
    };
    let describe = |e: ReplayError| match e {
        ReplayError::Input(e) => format!("cannot read {file}: {e}"),
        ReplayError::Capture(e) => format!("{file}: {e}"),
        ReplayError::Send(e) => format!("{target}: {e}"),
    };
    let dialect = dialects.finish();
    let (input, regular) = open_capture(&file)?;
    let terminal = std::io::stderr().is_terminal();
    let mut bar = ProgressBar::new(std::io::stderr());
    let (summary, error) = if regular {
        // A file is read twice: once to count its frames (the progress bar's total) and
        // to find a broken capture before anything is sent, then to send.
        let mut total = 0u64;
        replay::for_each_frame(input, dialect, |_| {
            total += 1;
            Ok(())
        })
        .map_err(describe)?;
        let (input, _) = open_capture(&file)?;
        replay::replay(input, &target, speed, dialect, &mut |done| {
            if terminal {
                bar.update(done, total);
            }
        })
    } else {
        let sent = replay::replay(input, &target, speed, dialect, &mut |done| {
            if terminal {
                bar.update_count(done);
            }
        });
        if terminal && sent.0.frames > 0 {
            bar.finish_count(sent.0.frames);
        }
        sent
    };
    // What was sent before a broken capture (read as it came) is still reported.
    match error {
        None | Some(ReplayError::Capture(_)) => {}
        Some(e) => return Err(describe(e)),
    }
    let _ = writeln!(
        out,
        "sent {} frames ({} bytes) to {target} in {:.3} s",
        summary.frames,
        summary.bytes,
        summary.elapsed.as_secs_f64()
    );
    match error {
        Some(e) => Err(describe(e)),
        None => Ok(0),
    }
}
