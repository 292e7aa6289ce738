//! The `path` of a `record` block: a directory and a file-name pattern with the
//! directives `%Y %m %d %H %M %S` (the calendar time a file is opened at) and `%%`.
//!
//! A file is never overwritten: when the name is taken, `-1`, `-2`, … is added before
//! the extension (`2024-05-01_10-00-00-1.tlog`). Which names the pattern makes is told
//! by [`FilePattern::matches`]: the pattern with digits for the directives, with or
//! without such a suffix. A matching name alone never makes a file a recording: only
//! the files the router created (its [`manifest`](super::manifest)) are ever removed.

use std::fmt::Write;
use std::ops::Range;

/// A calendar time (local or UTC: the caller chooses) to name a file after.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LocalTime {
    /// Year (four digits are written).
    pub year: i32,
    /// Month, 1–12.
    pub month: u32,
    /// Day of the month, 1–31.
    pub day: u32,
    /// Hour, 0–23.
    pub hour: u32,
    /// Minute, 0–59.
    pub minute: u32,
    /// Second, 0–60.
    pub second: u32,
}

/// A mistake in a path pattern: where (a byte range of the pattern) and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PatternError {
    /// The offending bytes of the pattern.
    pub at: Range<usize>,
    /// What is wrong.
    pub message: String,
    /// How to write it instead.
    pub note: &'static str,
}

/// One piece of a file-name pattern.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Piece {
    /// Text written as is.
    Text(String),
    /// A calendar field, written with `width` digits.
    Field { field: Field, width: usize },
    /// Where `-N` goes when the name is taken.
    Suffix,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Field {
    Year,
    Month,
    Day,
    Hour,
    Minute,
    Second,
}

/// A parsed `path`: the directory of the recordings and the pattern of their names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FilePattern {
    dir: String,
    /// The file name part as written (with its directives).
    name_pattern: String,
    pieces: Vec<Piece>,
}

/// The largest suffix tried when a file name is taken (`-1` … `-9999`).
pub(crate) const MAX_SUFFIX: u32 = 9999;

/// The longest file name (in bytes) the file systems mavtables runs on allow (Linux's
/// `NAME_MAX`).
pub(crate) const NAME_MAX: usize = 255;

const NOTE: &str = "the file name may use %Y %m %d %H %M %S (the time the file is opened) and %% (a '%'), e.g. /var/log/mavtables/%Y-%m-%d_%H-%M-%S.tlog";

impl FilePattern {
    /// Parses `path`; directives are allowed in the file name only (all recordings of a
    /// router live in one directory, where rotation finds them).
    pub fn parse(path: &str) -> Result<FilePattern, PatternError> {
        let (dir, name, name_at) = match path.rfind('/') {
            Some(i) => (&path[..i.max(1)], &path[i + 1..], i + 1),
            None => (".", path, 0),
        };
        if let Some(i) = path[..name_at].find('%') {
            return Err(PatternError {
                at: i..i + 1,
                message: "'%' directives are allowed in the file name only, not in the directory"
                    .to_string(),
                note: NOTE,
            });
        }
        if name.is_empty() {
            return Err(PatternError {
                at: path.len().saturating_sub(1)..path.len(),
                message: "expected a file name after the directory".to_string(),
                note: NOTE,
            });
        }
        let mut pieces: Vec<Piece> = Vec::new();
        let mut text = String::new();
        let mut chars = name.char_indices();
        while let Some((i, c)) = chars.next() {
            if c != '%' {
                text.push(c);
                continue;
            }
            let at = name_at + i;
            let (field, width) = match chars.next() {
                Some((_, '%')) => {
                    text.push('%');
                    continue;
                }
                Some((_, 'Y')) => (Field::Year, 4),
                Some((_, 'm')) => (Field::Month, 2),
                Some((_, 'd')) => (Field::Day, 2),
                Some((_, 'H')) => (Field::Hour, 2),
                Some((_, 'M')) => (Field::Minute, 2),
                Some((_, 'S')) => (Field::Second, 2),
                Some((_, other)) => {
                    return Err(PatternError {
                        at: at..at + 1 + other.len_utf8(),
                        message: format!("unknown directive '%{other}'"),
                        note: NOTE,
                    });
                }
                None => {
                    return Err(PatternError {
                        at: at..at + 1,
                        message: "a '%' at the end of the file name".to_string(),
                        note: NOTE,
                    });
                }
            };
            if !text.is_empty() {
                pieces.push(Piece::Text(std::mem::take(&mut text)));
            }
            pieces.push(Piece::Field { field, width });
        }
        // The suffix goes before the extension: the last '.' of the text after the last
        // directive (not the first character of a name without directives: a hidden file).
        match text.rfind('.') {
            Some(dot) if dot > 0 || !pieces.is_empty() => {
                let ext = text.split_off(dot);
                if !text.is_empty() {
                    pieces.push(Piece::Text(text));
                }
                pieces.push(Piece::Suffix);
                pieces.push(Piece::Text(ext));
            }
            _ => {
                if !text.is_empty() {
                    pieces.push(Piece::Text(text));
                }
                pieces.push(Piece::Suffix);
            }
        }
        Ok(FilePattern {
            dir: dir.to_string(),
            name_pattern: name.to_string(),
            pieces,
        })
    }

    /// The directory the recordings are written in (`.` for a bare file name).
    pub(crate) fn dir(&self) -> &str {
        &self.dir
    }

    /// The file name part as written, with its directives (`%Y-%m-%d_%H-%M-%S.tlog`).
    pub(crate) fn name_pattern(&self) -> &str {
        &self.name_pattern
    }

    /// The one name the pattern makes before any suffix, when it has no directives
    /// (`important.conf`); `None` when its names change with the time.
    pub(crate) fn fixed_name(&self) -> Option<String> {
        let timed = self.pieces.iter().any(|p| matches!(p, Piece::Field { .. }));
        (!timed).then(|| self.name(&LocalTime::default(), 0))
    }

    /// The length in bytes of the longest name the pattern makes, with the suffix
    /// `-MAX_SUFFIX`.
    pub(crate) fn longest_name(&self) -> usize {
        self.pieces
            .iter()
            .map(|piece| match piece {
                Piece::Text(t) => t.len(),
                Piece::Field { width, .. } => *width,
                Piece::Suffix => 1 + MAX_SUFFIX.to_string().len(),
            })
            .sum()
    }

    /// The file name for a file opened at `time`, with suffix `-n` (none for 0).
    pub fn name(&self, time: &LocalTime, n: u32) -> String {
        let mut out = String::new();
        for piece in &self.pieces {
            match piece {
                Piece::Text(t) => out.push_str(t),
                Piece::Suffix if n > 0 => {
                    let _ = write!(out, "-{n}");
                }
                Piece::Suffix => {}
                Piece::Field { field, width } => {
                    let value = match field {
                        Field::Year => i64::from(time.year),
                        Field::Month => i64::from(time.month),
                        Field::Day => i64::from(time.day),
                        Field::Hour => i64::from(time.hour),
                        Field::Minute => i64::from(time.minute),
                        Field::Second => i64::from(time.second),
                    };
                    let _ = write!(out, "{value:0width$}");
                }
            }
        }
        out
    }

    /// Whether `name` (a file name, no directory) is one this pattern makes: digits where
    /// the directives are, with or without a `-N` suffix.
    pub fn matches(&self, name: &str) -> bool {
        self.suffix_of(name).is_some()
    }

    /// The suffix number of `name` (0 without one), if the pattern makes it: files opened
    /// within one second differ only in it, and a higher one is newer.
    pub(crate) fn suffix_of(&self, name: &str) -> Option<u32> {
        suffix_from(&self.pieces, name.as_bytes())
    }
}

/// The suffix number if `name` matches `pieces` (0 when it has none).
fn suffix_from(pieces: &[Piece], name: &[u8]) -> Option<u32> {
    let Some((first, rest)) = pieces.split_first() else {
        return name.is_empty().then_some(0);
    };
    match first {
        Piece::Text(t) => suffix_from(rest, name.strip_prefix(t.as_bytes())?),
        Piece::Field { width, .. } => {
            let digits = name.get(..*width)?;
            if !digits.iter().all(u8::is_ascii_digit) {
                return None;
            }
            suffix_from(rest, &name[*width..])
        }
        Piece::Suffix => {
            if let Some(n) = suffix_from(rest, name) {
                return Some(n);
            }
            let after = name.strip_prefix(b"-")?;
            let len = after.iter().take_while(|b| b.is_ascii_digit()).count();
            let n = std::str::from_utf8(&after[..len]).ok()?.parse().ok()?;
            suffix_from(rest, &after[len..])?;
            Some(n)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: LocalTime = LocalTime {
        year: 2024,
        month: 5,
        day: 1,
        hour: 9,
        minute: 7,
        second: 3,
    };

    #[test]
    fn names_follow_the_pattern_and_take_the_suffix_before_the_extension() {
        let p = FilePattern::parse("/var/log/mavtables/%Y-%m-%d_%H-%M-%S.tlog").expect("ok");
        assert_eq!(p.dir(), "/var/log/mavtables");
        assert_eq!(p.name(&T, 0), "2024-05-01_09-07-03.tlog");
        assert_eq!(p.name(&T, 2), "2024-05-01_09-07-03-2.tlog");
        let p = FilePattern::parse("flight_%H%%").expect("ok");
        assert_eq!(p.dir(), ".");
        assert_eq!(p.name(&T, 0), "flight_09%");
        assert_eq!(p.name(&T, 1), "flight_09%-1");
        let p = FilePattern::parse("/x.y/%Y.tar.tlog").expect("ok");
        assert_eq!(p.name(&T, 1), "2024.tar-1.tlog");
        let p = FilePattern::parse("/%Y.tlog").expect("ok");
        assert_eq!(p.dir(), "/");
        let p = FilePattern::parse("d/.%Y").expect("ok");
        assert_eq!(p.name(&T, 1), ".2024-1");
        let p = FilePattern::parse("d/%Y.tlog").expect("ok");
        assert_eq!(p.name(&T, 1), "2024-1.tlog");
        let p = FilePattern::parse(".tlog").expect("ok");
        assert_eq!(p.name(&T, 1), ".tlog-1");
    }

    #[test]
    fn matching_accepts_made_names_only() {
        let p = FilePattern::parse("/r/%Y-%m-%d_%H-%M-%S.tlog").expect("ok");
        for n in [0, 1, 12] {
            assert_eq!(p.suffix_of(&p.name(&T, n)), Some(n));
        }
        for other in [
            "2024-05-01_09-07-03.tlog.tmp",
            "2024-05-01_09-07-3.tlog",
            "2024-05-01_09-07-03-.tlog",
            "2024-05-01_09-07-03-x.tlog",
            "notes.txt",
            "2024-05-01_09-07-03",
        ] {
            assert!(!p.matches(other), "{other}");
        }
    }

    #[test]
    fn mistakes_are_located() {
        let e = FilePattern::parse("/var/%Y/x.tlog").expect_err("dir");
        assert_eq!(e.at, 5..6);
        let e = FilePattern::parse("/var/x_%q.tlog").expect_err("unknown");
        assert_eq!(e.at, 7..9);
        assert_eq!(e.message, "unknown directive '%q'");
        let e = FilePattern::parse("/var/x_%").expect_err("end");
        assert_eq!(e.at, 7..8);
        let e = FilePattern::parse("/var/").expect_err("no name");
        assert_eq!(e.at, 4..5);
    }

    #[test]
    fn a_pattern_knows_its_fixed_name_and_longest_name() {
        let p = FilePattern::parse("/r/%Y-%m-%d_%H-%M-%S.tlog").expect("ok");
        assert_eq!(p.name_pattern(), "%Y-%m-%d_%H-%M-%S.tlog");
        assert_eq!(p.fixed_name(), None);
        assert_eq!(p.longest_name(), p.name(&T, MAX_SUFFIX).len());
        let p = FilePattern::parse("/etc/important.conf").expect("ok");
        assert_eq!(p.fixed_name().as_deref(), Some("important.conf"));
        assert_eq!(p.longest_name(), "important-9999.conf".len());
        let p = FilePattern::parse("100%%").expect("ok");
        assert_eq!(p.name_pattern(), "100%%");
        assert_eq!(p.fixed_name().as_deref(), Some("100%"));
        assert_eq!(p.longest_name(), "100%-9999".len());
    }
}
