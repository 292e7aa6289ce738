//! Loading MAVLink XML dialect files at run time, with their `<include>`s, on top of the
//! built-in `ardupilotmega` table.
//!
//! Each file is read through `crate::files::read_regular` (a regular file of at most
//! [`DIALECT_FILE_LIMIT`] bytes; [`MAX_FILES`] files in all), parsed by [`super::xml`]
//! and laid out by [`super::layout`]. A message that the built-in table (or an earlier
//! file) already has with the same name and CRC_EXTRA is the same message and adds
//! nothing (so a dialect may include `common.xml`, even a newer one with more extension
//! fields: the built-in definition stays, and frames longer than it are accepted by
//! their checksum as ever). Any other clash is an error naming both places: an id
//! defined twice differently, a name used for two ids, the reserved name `UNKNOWN`.
//!
//! [`Loader::finish`] gives a [`Dialect`]. Its tables are leaked to be `'static` (frames
//! hand out `&'static MessageInfo`), once per distinct content: loading the same
//! messages again (a reload) gives the same tables back.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

use super::layout::{LaidOut, lay_out};
use super::table::{Dialect, UNKNOWN_NAME};
use super::{DIALECT_NAME, Field, MessageInfo, by_id, by_name, xml};
use crate::files::read_regular;

/// The largest dialect file read (4 MiB; the official `common.xml` is about 600 KiB).
pub const DIALECT_FILE_LIMIT: u64 = 4 << 20;

/// The most files (dialect files and their includes, each counted once) one
/// configuration loads.
pub const MAX_FILES: usize = 64;

/// Why a dialect could not be loaded: the file (and line) where, and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoadError {
    /// The file the problem is in.
    pub file: PathBuf,
    /// Its line, when the problem has one.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for LoadError {}

/// Where a loaded message was defined.
#[derive(Debug, Clone)]
struct Origin {
    file: PathBuf,
    line: usize,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

/// Collects the messages of one or more dialect files.
#[derive(Debug, Default)]
pub struct Loader {
    /// Loaded messages the built-in table lacks, by id.
    messages: BTreeMap<u32, (LaidOut, Origin)>,
    /// Their names.
    names: HashMap<String, u32>,
    /// Files already read (canonical paths): an include reached twice is read once.
    visited: HashSet<PathBuf>,
}

impl Loader {
    /// A loader with nothing loaded.
    pub fn new() -> Self {
        Loader::default()
    }

    /// Loads the file at `path` and, first, everything it includes (relative to its own
    /// directory).
    pub fn add(&mut self, path: &Path) -> Result<(), LoadError> {
        self.add_file(path, None)
    }

    /// Loads `path`, included from `from` (file and line) if it is an include.
    fn add_file(&mut self, path: &Path, from: Option<(&Path, usize)>) -> Result<(), LoadError> {
        let fail = |message: String| match from {
            Some((file, line)) => LoadError {
                file: file.to_path_buf(),
                line: Some(line),
                message,
            },
            None => LoadError {
                file: path.to_path_buf(),
                line: None,
                message,
            },
        };
        let canonical = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        if self.visited.contains(&canonical) {
            return Ok(());
        }
        if self.visited.len() >= MAX_FILES {
            return Err(fail(format!(
                "more than {MAX_FILES} dialect files and includes"
            )));
        }
        self.visited.insert(canonical);
        // The included file is named in the message; a top-level one is the error's file.
        let what = match from {
            Some(_) => format!("included file {} ", path.display()),
            None => String::new(),
        };
        let bytes =
            read_regular(path, DIALECT_FILE_LIMIT).map_err(|e| fail(format!("{what}{e}")))?;
        let text =
            String::from_utf8(bytes).map_err(|_| fail(format!("{what}is not UTF-8 text")))?;
        let at = |line: usize, message: String| LoadError {
            file: path.to_path_buf(),
            line: Some(line),
            message,
        };
        let parsed = xml::parse(&text).map_err(|e| at(e.line, e.message))?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for include in &parsed.includes {
            self.add_file(&dir.join(&include.path), Some((path, include.line)))?;
        }
        for m in &parsed.messages {
            let laid = lay_out(m).map_err(|why| at(m.line, why))?;
            let origin = Origin {
                file: path.to_path_buf(),
                line: m.line,
            };
            self.insert(laid, origin).map_err(|why| at(m.line, why))?;
        }
        Ok(())
    }

    /// Adds one message, or says how it clashes with what is known.
    fn insert(&mut self, m: LaidOut, origin: Origin) -> Result<(), String> {
        if m.name == UNKNOWN_NAME {
            return Err(format!(
                "the message name {UNKNOWN_NAME} is reserved (rules use it for frames of unknown ids)"
            ));
        }
        if let Some(b) = by_id(m.id) {
            if b.name == m.name && b.crc_extra == m.crc_extra {
                return Ok(()); // the built-in message itself
            }
            return Err(format!(
                "message id {} is {} (CRC_EXTRA {}) in the built-in '{DIALECT_NAME}' dialect; here it is {} (CRC_EXTRA {})",
                m.id, b.name, b.crc_extra, m.name, m.crc_extra
            ));
        }
        if let Some(b) = by_name(&m.name) {
            return Err(format!(
                "message name {} is id {} in the built-in '{DIALECT_NAME}' dialect; here it is id {}",
                m.name, b.id, m.id
            ));
        }
        if let Some((old, at)) = self.messages.get(&m.id) {
            if old.name == m.name && old.crc_extra == m.crc_extra {
                return Ok(()); // the same message (the first definition stays)
            }
            return Err(format!(
                "message id {} is already {} (CRC_EXTRA {}, {} to {} bytes) at {at}; here it is {} (CRC_EXTRA {}, {} to {} bytes)",
                m.id,
                old.name,
                old.crc_extra,
                old.min_len,
                old.max_len,
                m.name,
                m.crc_extra,
                m.min_len,
                m.max_len
            ));
        }
        if let Some(&id) = self.names.get(&m.name) {
            let at = self.messages.get(&id).map(|(_, o)| o.to_string());
            return Err(format!(
                "message name {} is already id {id} at {}; here it is id {}",
                m.name,
                at.unwrap_or_default(),
                m.id
            ));
        }
        self.names.insert(m.name.clone(), m.id);
        self.messages.insert(m.id, (m, origin));
        Ok(())
    }

    /// How many messages were loaded beyond the built-in table.
    pub fn len(&self) -> usize {
        self.messages.len()
    }

    /// True when nothing was loaded beyond the built-in table.
    pub fn is_empty(&self) -> bool {
        self.messages.is_empty()
    }

    /// The built-in table plus what was loaded.
    pub fn finish(self) -> Dialect {
        let laid: Vec<LaidOut> = self.messages.into_values().map(|(m, _)| m).collect();
        intern(laid)
    }
}

/// Loads the dialect files `paths` (each with its includes) on top of the built-in
/// table.
pub fn load_files(paths: &[PathBuf]) -> Result<Dialect, LoadError> {
    let mut loader = Loader::new();
    for p in paths {
        loader.add(p)?;
    }
    Ok(loader.finish())
}

/// Every distinct set of loaded messages, with the tables made for it.
static INTERNED: Mutex<Vec<(Vec<LaidOut>, Dialect)>> = Mutex::new(Vec::new());

/// The dialect of `laid` (sorted by id): the tables made for the same messages before,
/// or new ones, leaked.
fn intern(laid: Vec<LaidOut>) -> Dialect {
    if laid.is_empty() {
        return Dialect::builtin();
    }
    let mut interned = INTERNED.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, d)) = interned.iter().find(|(l, _)| *l == laid) {
        return *d;
    }
    let extra: Vec<MessageInfo> = laid.iter().map(leak_message).collect();
    let extra: &'static [MessageInfo] = Box::leak(extra.into_boxed_slice());
    let mut names: Vec<(&'static str, u32)> = (extra.iter().enumerate())
        .map(|(i, m)| (m.name, u32::try_from(i).unwrap_or(u32::MAX)))
        .collect();
    names.sort_unstable();
    let names: &'static [(&'static str, u32)] = Box::leak(names.into_boxed_slice());
    let d = Dialect::with_extra(extra, names);
    interned.push((laid, d));
    d
}

/// `m` as a `'static` table entry.
fn leak_message(m: &LaidOut) -> MessageInfo {
    let fields: Vec<Field> = m
        .fields
        .iter()
        .map(|f| Field {
            name: Box::leak(f.name.clone().into_boxed_str()),
            ty: f.ty,
            array_len: f.array_len,
            offset: f.offset,
            extension: f.extension,
        })
        .collect();
    MessageInfo {
        id: m.id,
        name: Box::leak(m.name.clone().into_boxed_str()),
        crc_extra: m.crc_extra,
        min_len: m.min_len,
        max_len: m.max_len,
        target_system_offset: m.target_system_offset,
        target_component_offset: m.target_component_offset,
        fields: Box::leak(fields.into_boxed_slice()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/dialects")
            .join(name)
    }

    #[test]
    fn the_payload_dialect_loads_on_top_of_the_builtin_table() {
        let d = load_files(&[data("payload.xml")]).expect("loads");
        let names: Vec<&str> = d.loaded().iter().map(|m| m.name).collect();
        eprintln!("{names:?}");
        let m = d.by_name("MY_PAYLOAD_STATUS").expect("loaded");
        assert_eq!(m.id, 60_123);
        assert_eq!(d.by_id(60_123), Some(m));
        assert_eq!(d.by_id(0).map(|m| m.name), Some("HEARTBEAT"));
        // Loading the same files again gives the same tables.
        let again = load_files(&[data("payload.xml")]).expect("loads");
        assert!(std::ptr::eq(again.loaded(), d.loaded()));
    }
}
