//! Log output: the original's line format on standard output
//! (`YYYY-MM-DD HH:MM:SS  <message>`, local time, two spaces), warnings and errors on
//! standard error. Lines are buffered and flushed once per event-loop turn.

use std::fmt::Display;
use std::io::{self, BufWriter, Stdout, Write};
use std::time::{SystemTime, UNIX_EPOCH};

use super::sys;
use crate::routing::Event;

/// Writes log lines for one level (0 = none … 3 = every packet decision).
pub struct Logger {
    level: u8,
    out: BufWriter<Stdout>,
    /// The prefix for the second it was made for (formatting local time is not free).
    prefix: (i64, String),
}

/// `YYYY-MM-DD HH:MM:SS  ` for a UNIX time, in local time (UTC if it cannot be had).
pub fn prefix_for(unix_seconds: i64) -> String {
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
    pub fn new(level: u8) -> Self {
        Logger {
            level,
            out: BufWriter::with_capacity(64 * 1024, io::stdout()),
            prefix: (i64::MIN, String::new()),
        }
    }

    /// The configured level.
    pub fn level(&self) -> u8 {
        self.level
    }

    fn refresh_prefix(&mut self) {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        if self.prefix.0 != now {
            self.prefix = (now, prefix_for(now));
        }
    }

    /// Prints `message` if `level` is enabled.
    pub fn line(&mut self, level: u8, message: &dyn Display) {
        if level == 0 || level > self.level {
            return;
        }
        self.refresh_prefix();
        let _ = writeln!(self.out, "{}{message}", self.prefix.1);
    }

    /// Prints a routing event at its level.
    pub fn event(&mut self, event: &Event) {
        self.line(event.level(), event);
    }

    /// Sends buffered lines to standard output.
    pub fn flush(&mut self) {
        let _ = self.out.flush();
    }
}

/// A warning on standard error (not subject to the log level).
pub fn warn(message: &dyn Display) {
    eprintln!("warning: {message}");
}

/// An error on standard error (not subject to the log level).
pub fn error(message: &dyn Display) {
    eprintln!("error: {message}");
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
}
