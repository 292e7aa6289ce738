//! The `flight_log { }` block: which vehicle's autopilot streams its flight log to the
//! router, how the router names itself in that stream, when it asks for the log, and
//! where and how many of the files are kept. Each value is checked and located; every
//! error is collected. File names are checked with the `record` block's rules.

use super::Span;
use super::ast::{Ast, FlightLogSetting};
use super::diagnostic::Diagnostic;
use super::values::{mavlink_id, ranged, ranged_bytes};
use crate::address::Address;
use crate::recording::FilePattern;

/// When the router asks for the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightLogMode {
    /// From the autopilot's first heartbeat until shutdown (one file per boot of the
    /// autopilot).
    Always,
    /// From arming to disarming: one file per arming.
    WhileArmed,
}

/// Which log protocol the router speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightLogProtocol {
    /// Chosen by the autopilot's heartbeat: ArduPilot streams dataflash, PX4 ulog.
    Auto,
    /// ArduPilot's dataflash (`REMOTE_LOG_DATA_BLOCK`), written as `.bin`.
    Dataflash,
    /// PX4's ulog (`LOGGING_DATA`), written as `.ulg`.
    Ulog,
}

/// The `flight_log` block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FlightLog {
    /// The vehicle (system id) whose autopilot's log is streamed (default 1).
    pub system: u8,
    /// The router's address in the stream: the autopilot sends the blocks to it and
    /// the router's requests and acknowledgements come from it (default 245.190).
    pub source: Address,
    /// The file-name pattern without extension (`%Y %m %d %H %M %S %%`, local time);
    /// `.bin` or `.ulg` is added by protocol. `None`: `%Y-%m-%d_%H-%M-%S` in
    /// `$LOGS_DIRECTORY` or `/var/log/mavtables`.
    pub path: Option<String>,
    /// When the log is asked for (default `while_armed`).
    pub mode: FlightLogMode,
    /// Which protocol (default `auto`).
    pub protocol: FlightLogProtocol,
    /// At most this many logs of one extension are kept (the oldest the router created
    /// are removed); 0: no limit.
    pub max_files: u32,
    /// Blocks are dropped (and counted) rather than leave less than this free.
    pub min_free_bytes: u64,
}

impl FlightLog {
    /// `source` unless written.
    pub const DEFAULT_SOURCE: Address = Address::new(245, 190);
    /// The file name when `path` is not written.
    pub const DEFAULT_NAME: &str = "%Y-%m-%d_%H-%M-%S";
    /// `max_files` unless written.
    pub const DEFAULT_MAX_FILES: u32 = 50;
    /// `min_free_bytes` unless written: 100 MB.
    pub const DEFAULT_MIN_FREE_BYTES: u64 = 100_000_000;

    /// A block with every default.
    pub fn with_defaults() -> Self {
        FlightLog {
            system: 1,
            source: Self::DEFAULT_SOURCE,
            path: None,
            mode: FlightLogMode::WhileArmed,
            protocol: FlightLogProtocol::Auto,
            max_files: Self::DEFAULT_MAX_FILES,
            min_free_bytes: Self::DEFAULT_MIN_FREE_BYTES,
        }
    }

    /// The path pattern of the logs with extension `ext` (`bin`, `ulg`): `path`, or
    /// the default name in `$LOGS_DIRECTORY` (its first directory), else in
    /// `/var/log/mavtables`. `env` looks up an environment variable.
    pub fn path_pattern(&self, ext: &str, env: impl Fn(&str) -> Option<String>) -> String {
        let base = match &self.path {
            Some(path) => path.clone(),
            None => {
                let dir = env("LOGS_DIRECTORY")
                    .and_then(|dirs| dirs.split(':').next().map(str::to_string))
                    .filter(|dir| !dir.is_empty())
                    .unwrap_or_else(|| super::Recording::DEFAULT_DIRECTORY.to_string());
                format!("{}/{}", dir.trim_end_matches('/'), Self::DEFAULT_NAME)
            }
        };
        format!("{base}.{ext}")
    }
}

/// The settings of a `flight_log` block; `None` after reporting its errors. A statement
/// written twice counts the second time.
pub(crate) fn check(
    ast: &Ast<'_>,
    settings: &[FlightLogSetting],
    errors: &mut Vec<Diagnostic>,
) -> Option<FlightLog> {
    let mut log = FlightLog::with_defaults();
    let mut ok = true;
    let mut fail = |d: Diagnostic| {
        errors.push(d);
        ok = false;
    };
    for s in settings {
        match *s {
            FlightLogSetting::System(v) => match mavlink_id(ast.text(v), "system id") {
                Ok(n) => log.system = n,
                Err(m) => fail(Diagnostic::new(v, m)),
            },
            FlightLogSetting::Source(v) => match source(ast.text(v)) {
                Ok(a) => log.source = a,
                Err(m) => fail(
                    Diagnostic::new(v, m)
                        .with_note("write the router's system and component ids, e.g. 245.190"),
                ),
            },
            FlightLogSetting::Path(v) => match path(ast.text(v), v) {
                Ok(()) => log.path = Some(ast.text(v).to_string()),
                Err(d) => fail(d),
            },
            FlightLogSetting::Mode(v) => match ast.text(v) {
                "always" => log.mode = FlightLogMode::Always,
                "while_armed" => log.mode = FlightLogMode::WhileArmed,
                other => fail(Diagnostic::new(
                    v,
                    format!("expected 'always' or 'while_armed', found '{other}'"),
                )),
            },
            FlightLogSetting::Protocol(v) => match ast.text(v) {
                "auto" => log.protocol = FlightLogProtocol::Auto,
                "dataflash" => log.protocol = FlightLogProtocol::Dataflash,
                "ulog" => log.protocol = FlightLogProtocol::Ulog,
                other => fail(Diagnostic::new(
                    v,
                    format!("expected 'auto', 'dataflash' or 'ulog', found '{other}'"),
                )),
            },
            FlightLogSetting::MaxFiles(v) => {
                match ranged(ast.text(v), 0, u32::MAX.into(), "max_files") {
                    Ok(n) => log.max_files = u32::try_from(n).unwrap_or(u32::MAX),
                    Err(m) => fail(Diagnostic::new(v, m)),
                }
            }
            FlightLogSetting::MinFreeBytes(v) => {
                match ranged_bytes(ast.text(v), 0, u64::MAX, "min_free_bytes") {
                    Ok(n) => log.min_free_bytes = n,
                    Err(m) => fail(Diagnostic::new(v, m)),
                }
            }
        }
    }
    ok.then_some(log)
}

/// `S.C` as an address of a system and a component, neither 0.
fn source(text: &str) -> Result<Address, String> {
    let bad = || format!("expected an address like 245.190, found '{text}'");
    let (s, c) = text.split_once('.').ok_or_else(bad)?;
    let id = |t: &str| {
        t.parse::<u8>()
            .ok()
            .filter(|n| *n != 0 && t.bytes().all(|b| b.is_ascii_digit()))
    };
    match (id(s), id(c)) {
        (Some(s), Some(c)) => Ok(Address::new(s, c)),
        _ => Err(bad()),
    }
}

/// Whether `text` (at `span`) is a valid pattern once an extension is added, with the
/// `record` block's rules on `%` fields and name lengths.
fn path(text: &str, span: Span) -> Result<(), Diagnostic> {
    // Both extensions are three letters: one check covers `.bin` and `.ulg`.
    let with_ext = format!("{text}.bin");
    match FilePattern::parse(&with_ext) {
        Ok(pattern) => match super::recording::too_long(&pattern) {
            None => Ok(()),
            Some((message, note)) => Err(Diagnostic::new(span, message).with_note(note)),
        },
        Err(e) => {
            let end = (span.start + e.at.end).min(span.end);
            let start = (span.start + e.at.start).min(end);
            Err(Diagnostic::new(Span::new(start, end), e.message).with_note(e.note))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_source_is_two_ids_neither_zero() {
        assert_eq!(source("245.190"), Ok(Address::new(245, 190)));
        assert!(source("0.190").is_err());
        assert!(source("245").is_err());
        assert!(source("245.256").is_err());
        assert!(source("+1.2").is_err());
    }

    #[test]
    fn the_extension_follows_the_protocol() {
        let mut log = FlightLog::with_defaults();
        assert_eq!(
            log.path_pattern("bin", |_| None),
            "/var/log/mavtables/%Y-%m-%d_%H-%M-%S.bin"
        );
        log.path = Some("/tmp/x/%H".into());
        assert_eq!(log.path_pattern("ulg", |_| None), "/tmp/x/%H.ulg");
    }
}
