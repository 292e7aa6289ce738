//! Log output: the original's line format on standard output
//! (`YYYY-MM-DD HH:MM:SS  <message>`, local time, two spaces), warnings, errors and
//! other reports on standard error.
//!
//! Nothing here waits for whoever reads those streams: the event loop must not stall
//! behind a paused terminal or a stuck log collector. Each stream has a writer thread of
//! its own (started on first use) fed through a bounded buffer (`log/sink.rs`); lines
//! that do not fit are dropped and counted, and one line says how many once the reader
//! catches up. The logger collects a loop turn's lines and hands them over at
//! [`Logger::flush`]. Before the process exits, [`drain`] gives the writers a bounded
//! time to finish.

mod sink;

use std::fmt::Display;
use std::io::{self, Write};
use std::sync::OnceLock;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use self::sink::Sink;
use super::sys;
use crate::routing::Event;

/// What standard output may hold unread: at level 3 (about 200 bytes per routed frame)
/// over a thousand frames, a second or more of a busy link, so a reader's short pause
/// loses nothing. Memory is taken only as it fills.
const STDOUT_BOUND: usize = 256 * 1024;
/// What standard error may hold unread: room for the counters report of a thousand
/// links, which is handed over in one piece.
const STDERR_BOUND: usize = 256 * 1024;
/// A loop turn's lines are handed over early once they reach this much, so that the
/// logger's own buffer stays small.
const EARLY_HANDOVER: usize = 64 * 1024;

static STDOUT: OnceLock<Sink> = OnceLock::new();
static STDERR: OnceLock<Sink> = OnceLock::new();

fn stdout_sink() -> &'static Sink {
    STDOUT.get_or_init(|| Sink::start("log-stdout", STDOUT_BOUND, io::stdout(), stdout_notice))
}

fn stderr_sink() -> &'static Sink {
    STDERR.get_or_init(|| Sink::start("log-stderr", STDERR_BOUND, io::stderr(), stderr_notice))
}

fn stdout_notice(n: u64) -> String {
    format!(
        "{}{n} log lines dropped: standard output was not read fast enough\n",
        prefix_for(unix_now())
    )
}

fn stderr_notice(n: u64) -> String {
    format!("warning: {n} lines dropped: standard error was not read fast enough\n")
}

fn unix_now() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_secs()).unwrap_or(i64::MAX))
}

/// Writes log lines for one level (0 = none … 3 = every packet decision).
pub(super) struct Logger {
    level: u8,
    /// This loop turn's lines, not yet handed to the standard-output writer.
    lines: Vec<u8>,
    /// The prefix for the second it was made for (formatting local time is not free).
    prefix: (i64, String),
}

/// `YYYY-MM-DD HH:MM:SS  ` for a UNIX time, in local time (UTC if it cannot be had).
pub(super) fn prefix_for(unix_seconds: i64) -> String {
    match sys::local_time(unix_seconds) {
        Some((y, mo, d, h, mi, s)) => format!("{y:04}-{mo:02}-{d:02} {h:02}:{mi:02}:{s:02}  "),
        None => {
            let us = u64::try_from(unix_seconds).unwrap_or(0) * 1_000_000;
            let utc = crate::utc::format_micros(us);
            format!("{}  ", &utc[..19])
        }
    }
}

impl Logger {
    /// A logger printing events of `level` and below.
    pub(super) fn new(level: u8) -> Self {
        Logger {
            level,
            lines: Vec::new(),
            prefix: (i64::MIN, String::new()),
        }
    }

    fn refresh_prefix(&mut self) {
        let now = unix_now();
        if self.prefix.0 != now {
            self.prefix = (now, prefix_for(now));
        }
    }

    /// Prints `message` if `level` is enabled (at the next [`Logger::flush`]).
    pub(super) fn line(&mut self, level: u8, message: &dyn Display) {
        if level == 0 || level > self.level {
            return;
        }
        self.refresh_prefix();
        let _ = writeln!(self.lines, "{}{message}", self.prefix.1);
        if self.lines.len() >= EARLY_HANDOVER {
            self.flush();
        }
    }

    /// Prints a routing event at its level.
    pub(super) fn event(&mut self, event: &Event) {
        self.line(event.level(), event);
    }

    /// Hands the lines so far to the standard-output writer, without waiting for it.
    pub(super) fn flush(&mut self) {
        if !self.lines.is_empty() {
            stdout_sink().push(&self.lines);
            self.lines.clear();
        }
    }
}

impl Drop for Logger {
    /// Hands over the last lines (call [`drain`] before exiting to see them written).
    fn drop(&mut self) {
        self.flush();
    }
}

/// A warning on standard error (not subject to the log level).
pub(super) fn warn(message: &dyn Display) {
    stderr_text(&format!("warning: {message}\n"));
}

/// An error on standard error (not subject to the log level).
pub(super) fn error(message: &dyn Display) {
    stderr_text(&format!("error: {message}\n"));
}

/// Raw text on standard error, such as a multi-line report; lines should end in `\n`.
pub(super) fn stderr_text(text: &str) {
    stderr_sink().push(text.as_bytes());
}

/// Waits at most `timeout` for everything handed over on both streams to be written
/// (with a line for any lines dropped); gives up on a stuck reader. To be called once
/// before the process exits, or what is buffered is lost.
pub(super) fn drain(timeout: Duration) {
    let deadline = Instant::now() + timeout;
    let started = [STDOUT.get(), STDERR.get()];
    for sink in started.iter().flatten() {
        sink.note_drops();
    }
    for sink in started.iter().flatten() {
        sink.wait_written(deadline);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefix_has_the_original_shape() {
        let p = prefix_for(1_723_734_165);
        assert_eq!(p.len(), 21, "{p:?}");
        assert!(p.ends_with("  "));
        assert_eq!(&p[4..5], "-");
        assert_eq!(&p[10..11], " ");
        assert_eq!(&p[13..14], ":");
    }

    #[test]
    fn the_stdout_notice_has_the_log_line_shape() {
        let line = stdout_notice(42);
        assert_eq!(&line[19..21], "  ", "{line:?}");
        assert_eq!(
            &line[21..],
            "42 log lines dropped: standard output was not read fast enough\n"
        );
    }
}
