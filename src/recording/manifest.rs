//! The list of the recordings a router created (its *manifest*), sans-IO. Rotation
//! removes only the files on it, so a file the router did not write is never removed,
//! whatever its name.
//!
//! The list is kept beside the recordings in a hidden file named after the pattern
//! ([`Manifest::file_name`]: `.%Y-%m-%d_%H-%M-%S.tlog.mavtables`), so that two patterns
//! in one directory keep two lists. Each line names one recording and the file it was
//! when it was created — device, inode and, where the file system keeps it, birth time
//! (an inode number freed by a removal is soon given to a new file) — so that a file
//! later put at the name of a removed recording is not taken for it:
//!
//! ```text
//! # mavtables: the recordings it created from the pattern %Y-%m-%d_%H-%M-%S.tlog ...
//! 2049 1310734 1714557600123456789 2024-05-01_10-00-00.tlog
//! ```
//!
//! The file is trusted only if the user the router runs as owns it and nobody else may
//! write it ([`trust`]); a listed file is a recording only if it still is the file
//! created, owned by that user, under a name the pattern makes ([`judge`]).

use super::FilePattern;

/// The longest list read (a longer file is not one mavtables wrote) or written (the
/// oldest entries are left out): some 20 000 recordings.
pub(crate) const MAX_BYTES: usize = 1 << 20;

/// What the list file's name adds to the pattern.
const EXTENSION: &str = ".mavtables";
/// What the temporary file's name adds to the list's.
const TEMP: &str = ".tmp";
/// How a list file begins: a list whose first line does not is not one mavtables wrote.
const HEADER_START: &str = "# mavtables: ";

/// A file's identity on the machine: the device it is on, its inode there and when it
/// was born.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FileId {
    /// The device number.
    pub dev: u64,
    /// The inode number.
    pub ino: u64,
    /// Its birth time in nanoseconds since the UNIX epoch, where the file system keeps
    /// it (written `-` when it does not).
    pub born: Option<u128>,
}

/// A recording the router created.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Created {
    /// Its file name (in the pattern's directory).
    pub name: String,
    /// The file it was when created.
    pub id: FileId,
}

/// What is at a listed name now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Found {
    /// Nothing.
    Gone,
    /// Something that cannot be looked at now (no permission, an I/O error).
    Unknown,
    /// A directory entry (a symbolic link is not followed).
    Entry {
        /// Its identity.
        id: FileId,
        /// Whether it is a regular file.
        regular: bool,
        /// The user owning it.
        owner: u32,
    },
}

/// What a listed name is now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// The recording the router created: rotation may remove it.
    Ours,
    /// Not, or no longer, the file created: the entry goes.
    Forget,
    /// Cannot be told now: the entry stays and the file is left alone.
    Unsure,
}

/// What `entry` is, given what is `found` at its name, for a router running as user
/// `us`.
pub(crate) fn judge(entry: &Created, pattern: &FilePattern, found: Found, us: u32) -> Verdict {
    if !pattern.matches(&entry.name) {
        return Verdict::Forget;
    }
    match found {
        Found::Gone => Verdict::Forget,
        Found::Unknown => Verdict::Unsure,
        Found::Entry { id, regular, owner } if regular && id == entry.id && owner == us => {
            Verdict::Ours
        }
        Found::Entry { .. } => Verdict::Forget,
    }
}

/// Whether a list file owned by `owner` with permission bits `mode` may be believed by
/// a router running as user `us`: only if `us` owns it and nobody else may write it
/// (anyone else could list a file of `us` for removal). `Err` says why not.
pub(crate) fn trust(owner: u32, mode: u32, us: u32) -> Result<(), String> {
    if owner != us {
        return Err(format!(
            "it belongs to user {owner}, not to the user mavtables runs as ({us})"
        ));
    }
    if mode & 0o022 != 0 {
        return Err(format!("others may write it (mode {:o})", mode & 0o7777));
    }
    Ok(())
}

/// The recordings a router created for one pattern, oldest first.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Manifest {
    entries: Vec<Created>,
}

impl Manifest {
    /// How every list mavtables writes begins.
    pub(crate) const MARK: &'static [u8] = HEADER_START.as_bytes();

    /// The list file's name for `pattern` (in the pattern's directory): a dot, the
    /// pattern's file name as written, `.mavtables`.
    pub(crate) fn file_name(pattern: &FilePattern) -> String {
        format!(".{}{EXTENSION}", pattern.name_pattern())
    }

    /// The name the list is written under before it is renamed to
    /// [`Manifest::file_name`].
    pub(crate) fn temp_name(pattern: &FilePattern) -> String {
        format!("{}{TEMP}", Manifest::file_name(pattern))
    }

    /// The length in bytes of the longest name the list takes (the temporary one).
    pub(crate) fn longest_name(pattern: &FilePattern) -> usize {
        1 + pattern.name_pattern().len() + EXTENSION.len() + TEMP.len()
    }

    /// Whether `text` begins as a list mavtables wrote (its first line).
    pub fn is_list(text: &str) -> bool {
        text.starts_with(HEADER_START)
    }

    /// The list a file holds; comments, blank lines and lines that do not read as
    /// `DEVICE INODE BIRTH NAME` are skipped.
    pub fn parse(text: &str) -> Manifest {
        let mut list = Manifest::default();
        for line in text.lines() {
            if let Some(entry) = entry(line) {
                list.add(entry);
            }
        }
        list
    }

    /// The text of the list file for `pattern`: a comment saying what it is, then one
    /// line per recording. When that would be longer than `MAX_BYTES` the oldest are
    /// left out; how many is the second value.
    pub fn to_text(&self, pattern: &FilePattern) -> (String, usize) {
        let header = format!(
            "{HEADER_START}the recordings it created from the pattern {}, the only files it may remove (device inode birth name)\n",
            pattern.name_pattern()
        );
        let lines: Vec<String> = self
            .entries
            .iter()
            .filter(|e| !e.name.contains(['\n', '\r']))
            .map(|e| {
                let born = e.id.born.map_or_else(|| "-".to_string(), |b| b.to_string());
                format!("{} {} {born} {}\n", e.id.dev, e.id.ino, e.name)
            })
            .collect();
        let mut len = header.len();
        let kept = lines
            .iter()
            .rev()
            .take_while(|line| {
                len += line.len();
                len <= MAX_BYTES
            })
            .count();
        let left_out = self.entries.len() - kept;
        let mut text = header;
        for line in &lines[lines.len() - kept..] {
            text.push_str(line);
        }
        (text, left_out)
    }

    /// Adds a recording just created (one of the same name is replaced).
    pub(crate) fn add(&mut self, created: Created) {
        self.forget(&created.name);
        self.entries.push(created);
    }

    /// Takes `name` off the list.
    pub(crate) fn forget(&mut self, name: &str) {
        self.entries.retain(|e| e.name != name);
    }

    /// The entry for `name`, if it is listed.
    pub(crate) fn get(&self, name: &str) -> Option<&Created> {
        self.entries.iter().find(|e| e.name == name)
    }

    /// Every entry, oldest first.
    pub(crate) fn entries(&self) -> &[Created] {
        &self.entries
    }
}

/// The entry a line of the list file holds, if it is one.
fn entry(line: &str) -> Option<Created> {
    let (dev, rest) = line.split_once(' ')?;
    let (ino, rest) = rest.split_once(' ')?;
    let (born, name) = rest.split_once(' ')?;
    if name.is_empty() || name.contains('/') || name == "." || name == ".." {
        return None;
    }
    Some(Created {
        name: name.to_string(),
        id: FileId {
            dev: dev.parse().ok()?,
            ino: ino.parse().ok()?,
            born: match born {
                "-" => None,
                n => Some(n.parse().ok()?),
            },
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern() -> FilePattern {
        FilePattern::parse("/r/%Y-%m-%d_%H-%M-%S.tlog").expect("pattern")
    }

    fn created(name: &str, ino: u64) -> Created {
        Created {
            name: name.to_string(),
            id: FileId {
                dev: 7,
                ino,
                born: Some(u128::from(ino) * 1000),
            },
        }
    }

    const NAME: &str = "2024-05-01_10-00-00.tlog";

    #[test]
    fn the_list_is_named_after_the_pattern_and_reads_back() {
        let p = pattern();
        assert_eq!(Manifest::file_name(&p), ".%Y-%m-%d_%H-%M-%S.tlog.mavtables");
        assert_eq!(Manifest::longest_name(&p), Manifest::temp_name(&p).len());
        let mut list = Manifest::default();
        list.add(created(NAME, 11));
        list.add(created("2024-05-01_10-00-00-1.tlog", 12));
        list.add(created("with space.tlog", 13));
        let (text, left_out) = list.to_text(&p);
        assert_eq!(left_out, 0);
        assert!(text.starts_with("# mavtables: "), "{text}");
        assert!(
            text.contains("\n7 11 11000 2024-05-01_10-00-00.tlog\n"),
            "{text}"
        );
        assert_eq!(Manifest::parse(&text), list);
        // A file system without birth times.
        let unborn = Created {
            id: FileId {
                born: None,
                ..created(NAME, 1).id
            },
            ..created(NAME, 1)
        };
        list.add(unborn.clone());
        let (text, _) = list.to_text(&p);
        assert!(
            text.contains("\n7 1 - 2024-05-01_10-00-00.tlog\n"),
            "{text}"
        );
        assert_eq!(Manifest::parse(&text), list);
        // Adding a name again replaces it, newest last.
        list.add(created(NAME, 14));
        assert_eq!(list.entries().last(), Some(&created(NAME, 14)));
        assert_eq!(list.entries().len(), 3);
        list.forget(NAME);
        assert_eq!(list.get(NAME), None);
    }

    #[test]
    fn damaged_lines_are_skipped() {
        let text = "# comment\n\n7 x - a.tlog\n7 1 -\n-1 2 - b.tlog\n7 3 - ../c.tlog\n7 4 - \n7 5 - ..\n7 8 x d.tlog\n7 9 ok.tlog\n7 6 6000 ok.tlog\n";
        assert_eq!(Manifest::parse(text).entries(), [created("ok.tlog", 6)]);
    }

    #[test]
    fn a_long_list_leaves_out_the_oldest() {
        let p = pattern();
        let mut list = Manifest::default();
        let n = MAX_BYTES / 30 + 100;
        for i in 0..n {
            list.add(created(&format!("2024-05-01_10-00-00-{i}.tlog"), i as u64));
        }
        let (text, left_out) = list.to_text(&p);
        assert!(text.len() <= MAX_BYTES);
        assert!(left_out > 0);
        let back = Manifest::parse(&text);
        assert_eq!(back.entries().len(), n - left_out);
        assert_eq!(back.entries().last(), list.entries().last());
    }

    #[test]
    fn only_the_file_created_under_a_name_of_the_pattern_is_ours() {
        let p = pattern();
        let entry = created(NAME, 11);
        let same = entry.id;
        let at = |id: FileId, regular: bool, owner: u32| Found::Entry { id, regular, owner };
        assert_eq!(judge(&entry, &p, at(same, true, 0), 0), Verdict::Ours);
        // Another file put at the name, a link or a directory there, another owner.
        let other = FileId { ino: 12, ..same };
        assert_eq!(judge(&entry, &p, at(other, true, 0), 0), Verdict::Forget);
        let moved = FileId { dev: 8, ..same };
        assert_eq!(judge(&entry, &p, at(moved, true, 0), 0), Verdict::Forget);
        // The inode number given again to a new file.
        let reborn = FileId {
            born: Some(99),
            ..same
        };
        assert_eq!(judge(&entry, &p, at(reborn, true, 0), 0), Verdict::Forget);
        assert_eq!(judge(&entry, &p, at(same, false, 0), 0), Verdict::Forget);
        assert_eq!(judge(&entry, &p, at(same, true, 1000), 0), Verdict::Forget);
        assert_eq!(judge(&entry, &p, Found::Gone, 0), Verdict::Forget);
        assert_eq!(judge(&entry, &p, Found::Unknown, 0), Verdict::Unsure);
        // A name the pattern does not make is never a recording.
        let stray = created("notes.txt", 11);
        assert_eq!(judge(&stray, &p, at(same, true, 0), 0), Verdict::Forget);
    }

    #[test]
    fn only_a_list_of_the_user_that_nobody_else_may_write_is_believed() {
        assert_eq!(trust(0, 0o100_640, 0), Ok(()));
        assert_eq!(trust(1000, 0o600, 1000), Ok(()));
        assert!(trust(1000, 0o600, 0).is_err());
        assert!(trust(0, 0o660, 0).is_err());
        assert!(trust(0, 0o646, 0).is_err());
    }
}
