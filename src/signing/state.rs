//! The saved signing state: the router's signing clock when it was saved and every
//! stream's last timestamp,
//! as a small text file the I/O layer writes atomically, so that a frame captured before
//! a restart cannot be replayed after it.
//!
//! ```text
//! mavtables signing state 1
//! clean 1
//! clock 371234567890
//! stream 9f86d081884c7d65 0 255 190 371234567000
//! ```
//! Keys are named by their fingerprint (see [`SigningKey::fingerprint`]), never by their
//! bytes. `clean 0` marks a file written while running: after a crash, frames accepted
//! after it was written may be replayable, so each stream's floor is raised by
//! [`UNCLEAN_MARGIN`] when it is read, and so are the clock and what a stream first
//! heard after the save must begin above (the `clock` line plus the margin).

use std::fmt::Write;

use super::clock::UNITS_PER_SEC;
#[cfg(doc)]
use super::key::SigningKey;
use super::streams::MAX_STREAMS;

/// The first line of a state file.
pub const HEADER: &str = "mavtables signing state 1";

/// Whether `bytes` begin as a state file mavtables wrote: with [`HEADER`] as their
/// first line. Only such a file may be replaced by a new one.
pub fn is_state_file(bytes: &[u8]) -> bool {
    bytes
        .strip_prefix(HEADER.as_bytes())
        .is_some_and(|rest| rest.is_empty() || rest.starts_with(b"\n") || rest.starts_with(b"\r\n"))
}

/// The longest line a state file can have: a stream with the widest numbers,
/// `stream 0123456789abcdef 255 255 255 18446744073709551615` and its line ending.
const MAX_LINE: usize = "stream ".len() + 16 + 3 * " 255".len() + 1 + 20 + 1;

/// The largest state file read (1 MiB). One written by mavtables has the header, the
/// `clean` and `clock` lines and at most [`MAX_STREAMS`] stream lines: under 240 KiB.
/// Anything larger was not written by mavtables and is refused, not read.
pub const STATE_FILE_LIMIT: u64 = 1 << 20;

// The limit leaves a margin of four times the largest file mavtables writes.
const _: () = assert!(4 * (MAX_STREAMS + 3) * MAX_LINE <= STATE_FILE_LIMIT as usize);

/// How often the state is saved while it changes (seconds).
pub const SAVE_INTERVAL_SECS: u64 = 1;

/// How much a stream's last timestamp is raised when the file was not written at a clean
/// exit: the save interval plus as much again (10 µs units).
pub const UNCLEAN_MARGIN: u64 = 2 * SAVE_INTERVAL_SECS * UNITS_PER_SEC;

/// One saved stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SavedStream {
    /// Fingerprint of the stream's key.
    pub key: [u8; 8],
    /// Link id.
    pub link_id: u8,
    /// Source system.
    pub system: u8,
    /// Source component.
    pub component: u8,
    /// Last accepted timestamp.
    pub timestamp: u64,
}

/// The whole saved state.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SavedState {
    /// Written at a clean exit (nothing was accepted after it).
    pub clean: bool,
    /// The router's signing clock when the state was taken (never below a timestamp
    /// it issued): the next run's clock floor.
    pub clock: u64,
    /// Every stream.
    pub streams: Vec<SavedStream>,
}

impl SavedState {
    /// The file's text.
    pub fn to_text(&self) -> String {
        let mut s = String::with_capacity(64 + self.streams.len() * 48);
        let _ = writeln!(s, "{HEADER}");
        let _ = writeln!(s, "clean {}", u8::from(self.clean));
        let _ = writeln!(s, "clock {}", self.clock);
        for st in &self.streams {
            s.push_str("stream ");
            for b in st.key {
                let _ = write!(s, "{b:02x}");
            }
            let _ = writeln!(
                s,
                " {} {} {} {}",
                st.link_id, st.system, st.component, st.timestamp
            );
        }
        s
    }

    /// Reads a file's text; an error says which line is wrong.
    pub fn parse(text: &str) -> Result<SavedState, String> {
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, HEADER)) => {}
            _ => return Err("not a mavtables signing state file".to_string()),
        }
        let mut state = SavedState::default();
        for (n, line) in lines {
            let bad = || format!("line {}: cannot read {line:?}", n + 1);
            let mut words = line.split_ascii_whitespace();
            match words.next() {
                None => {}
                Some("clean") => state.clean = words.next() == Some("1"),
                Some("clock") => {
                    state.clock = words.next().and_then(|w| w.parse().ok()).ok_or_else(bad)?;
                }
                Some("stream") => {
                    let key = words.next().and_then(parse_fingerprint).ok_or_else(bad)?;
                    let mut num = || words.next().and_then(|w| w.parse::<u64>().ok());
                    let (Some(link_id), Some(system), Some(component), Some(timestamp)) =
                        (num(), num(), num(), num())
                    else {
                        return Err(bad());
                    };
                    let byte = |v: u64| u8::try_from(v).map_err(|_| bad());
                    state.streams.push(SavedStream {
                        key,
                        link_id: byte(link_id)?,
                        system: byte(system)?,
                        component: byte(component)?,
                        timestamp,
                    });
                }
                Some(_) => return Err(bad()),
            }
        }
        Ok(state)
    }
}

fn parse_fingerprint(hex: &str) -> Option<[u8; 8]> {
    if hex.len() != 16 || !hex.is_ascii() {
        return None;
    }
    let mut out = [0u8; 8];
    for (i, b) in out.iter_mut().enumerate() {
        *b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_round_trips() {
        let state = SavedState {
            clean: true,
            clock: 371_234_567_890,
            streams: vec![SavedStream {
                key: [0x9f, 0x86, 0xd0, 0x81, 0x88, 0x4c, 0x7d, 0x65],
                link_id: 0,
                system: 255,
                component: 190,
                timestamp: 371_234_567_000,
            }],
        };
        let text = state.to_text();
        assert!(text.contains("stream 9f86d081884c7d65 0 255 190 371234567000\n"));
        assert_eq!(SavedState::parse(&text), Ok(state));
    }

    #[test]
    fn the_largest_state_is_well_within_the_limit() {
        let widest = SavedStream {
            key: [0xff; 8],
            link_id: 255,
            system: 255,
            component: 255,
            timestamp: u64::MAX,
        };
        let state = SavedState {
            clean: false,
            clock: u64::MAX,
            streams: vec![widest; MAX_STREAMS],
        };
        let text = state.to_text();
        assert!(text.lines().all(|l| l.len() < MAX_LINE), "a line is longer");
        assert!(
            4 * text.len() as u64 <= STATE_FILE_LIMIT,
            "{} bytes",
            text.len()
        );
    }

    #[test]
    fn damage_is_an_error_not_a_panic() {
        assert!(SavedState::parse("").is_err());
        assert!(SavedState::parse("hello").is_err());
        let bad = format!("{HEADER}\nstream zz 0 1 1 5\n");
        assert_eq!(
            SavedState::parse(&bad),
            Err("line 2: cannot read \"stream zz 0 1 1 5\"".to_string())
        );
        assert!(
            SavedState::parse(&format!("{HEADER}\nstream 0011223344556677 300 1 1 5\n")).is_err()
        );
        assert!(SavedState::parse(&format!("{HEADER}\nstream 00112233445566é 0 1 1 5\n")).is_err());
        assert!(SavedState::parse(&format!("{HEADER}\nclock\n")).is_err());
    }
}
