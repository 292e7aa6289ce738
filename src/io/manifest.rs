//! The file of the recorder's [`Manifest`], the list of the recordings it created: read
//! at start (and by `--check`), written whole when the list changes — a temporary file
//! beside it, synced, renamed over it — so that it is always the old list or the new one.
//!
//! Only a regular file of bounded size that the router's user owns, and nobody else may
//! write, is read as the list; anything else at its name is left alone (never read,
//! never replaced), and the list is then kept for this run only.

use std::fs::{self, File, Metadata, OpenOptions};
use std::io::{self, Read};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use super::made_files::Freeing;
use super::{log, sys};
use crate::files::replace_file;
use crate::recording::manifest::{self, Created, FileId, Found, MAX_BYTES, Verdict};
use crate::recording::rotation::Existing;
use crate::recording::{FilePattern, Manifest};

/// What is at the list's name.
#[derive(Debug)]
pub(crate) enum Stored {
    /// Nothing: no recording was made with this pattern here (or only by a mavtables
    /// that kept no list).
    Absent,
    /// The list, as read.
    List(Manifest),
    /// Something mavtables did not write, or that cannot be read; why.
    Refused(String),
}

/// The path of the list of `pattern`.
pub(crate) fn list_path(pattern: &FilePattern) -> PathBuf {
    Path::new(pattern.dir()).join(Manifest::file_name(pattern))
}

/// Reads the list of `pattern` from its file.
pub(crate) fn read(pattern: &FilePattern) -> Stored {
    match read_at(&list_path(pattern)) {
        Ok(Some(list)) => Stored::List(list),
        Ok(None) => Stored::Absent,
        Err(why) => Stored::Refused(why),
    }
}

/// The list at `path`, `None` if there is no file; a device, a FIFO or a link there is
/// never opened.
fn read_at(path: &Path) -> Result<Option<Manifest>, String> {
    match fs::symlink_metadata(path) {
        Ok(meta) => believe(&meta)?,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e.to_string()),
    }
    let file = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| e.to_string())?;
    // What was opened, not what was looked at before: it may have been replaced.
    believe(&file.metadata().map_err(|e| e.to_string())?)?;
    let mut bytes = Vec::new();
    file.take(MAX_BYTES as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() > MAX_BYTES {
        return Err(format!("it is longer than {MAX_BYTES} bytes"));
    }
    let text = String::from_utf8(bytes).map_err(|_| "it is not text".to_string())?;
    if !Manifest::is_list(&text) {
        return Err(
            "it is not a list mavtables wrote (its first line is not mavtables' own)".to_string(),
        );
    }
    Ok(Some(Manifest::parse(&text)))
}

/// Whether a file with `meta` may be read as a list.
fn believe(meta: &Metadata) -> Result<(), String> {
    if !meta.is_file() {
        return Err("it is not a regular file".to_string());
    }
    manifest::trust(meta.uid(), meta.mode(), sys::effective_uid())
}

/// What is at `path` (a link is not followed), with its metadata when there is
/// something.
fn look(path: &Path) -> (Found, Option<Metadata>) {
    match fs::symlink_metadata(path) {
        Ok(meta) => (
            Found::Entry {
                id: id_of(&meta),
                regular: meta.is_file(),
                owner: meta.uid(),
            },
            Some(meta),
        ),
        Err(e) if e.kind() == io::ErrorKind::NotFound => (Found::Gone, None),
        Err(_) => (Found::Unknown, None),
    }
}

/// The identity of the file with `meta` (its birth time where the file system has it).
fn id_of(meta: &Metadata) -> FileId {
    FileId {
        dev: meta.dev(),
        ino: meta.ino(),
        born: meta
            .created()
            .ok()
            .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
            .map(|d| d.as_nanos()),
    }
}

/// Whether `name` in the directory of `pattern` is a recording the router created, by
/// its list (`Err`: why the list could not be read).
pub(crate) fn created(pattern: &FilePattern, name: &str) -> Result<bool, String> {
    let list = match read(pattern) {
        Stored::List(list) => list,
        Stored::Absent => return Ok(false),
        Stored::Refused(why) => return Err(why),
    };
    let Some(entry) = list.get(name) else {
        return Ok(false);
    };
    let (found, _) = look(&Path::new(pattern.dir()).join(name));
    Ok(manifest::judge(entry, pattern, found, sys::effective_uid()) == Verdict::Ours)
}

/// A writer's list of the files it created (the recorder's recordings, the flight log's
/// logs), and its file.
pub(crate) struct MadeList {
    /// Whose list it is, as messages begin (`recording`, `flight log`).
    what: &'static str,
    /// What its files are called in messages (`recordings`, `logs`).
    files: &'static str,
    pattern: FilePattern,
    dir: PathBuf,
    list: Manifest,
    /// The user the router runs as.
    us: u32,
    /// Whether the list may be written to its file (not when something mavtables did
    /// not write is there).
    may_save: bool,
    /// Whether the last save failed (said once until one works).
    failing: bool,
    /// Whether leaving the oldest entries out of the file was said.
    trimmed: bool,
    /// Space the files last removed for `min_free_bytes` should free, while the disk
    /// does not show it yet.
    pub(super) freeing: Freeing,
}

impl MadeList {
    /// The list of `pattern` as earlier runs left it; what is wrong with it is said,
    /// beginning with `what`, calling the files `files`.
    pub(crate) fn open(pattern: &FilePattern, what: &'static str, files: &'static str) -> MadeList {
        let path = list_path(pattern);
        let (list, may_save) = match read(pattern) {
            Stored::List(list) => (list, true),
            Stored::Absent => (Manifest::default(), true),
            Stored::Refused(why) => {
                log::warn(&format_args!(
                    "{what}: {} is not a list of {files} mavtables wrote ({why}); it is left alone, no file of an earlier run is removed, and those of this run are listed for this run only",
                    path.display()
                ));
                (Manifest::default(), false)
            }
        };
        let mut made = MadeList {
            what,
            files,
            pattern: pattern.clone(),
            dir: PathBuf::from(pattern.dir()),
            list,
            us: sys::effective_uid(),
            may_save,
            failing: false,
            trimmed: false,
            freeing: Freeing::default(),
        };
        made.say_strangers();
        made
    }

    /// Says how many files have a name of the pattern without being recordings this
    /// router created (made by hand, or by a mavtables that kept no list): they stay.
    fn say_strangers(&mut self) {
        let ours: Vec<String> = self.recordings().into_iter().map(|r| r.name).collect();
        let Ok(entries) = fs::read_dir(&self.dir) else {
            return;
        };
        let strangers = entries
            .flatten()
            .filter_map(|e| e.file_name().into_string().ok())
            .filter(|name| self.pattern.matches(name) && !ours.contains(name))
            .count();
        if strangers > 0 {
            log::warn(&format_args!(
                "{}: {strangers} files in {} have names of the pattern but are not on the list of {} mavtables made ({}); they are never removed",
                self.what,
                self.dir.display(),
                self.files,
                Manifest::file_name(&self.pattern)
            ));
        }
    }

    /// Lists `name`, just created and open as `file` (a file that cannot be told from
    /// others is not listed, and never removed).
    pub(crate) fn add(&mut self, name: &str, file: &File) {
        match file.metadata() {
            Ok(meta) => self.list.add(Created {
                name: name.to_string(),
                id: id_of(&meta),
            }),
            Err(e) => log::warn(&format_args!(
                "{}: cannot tell which file {} is ({e}); it is never removed",
                self.what,
                self.dir.join(name).display()
            )),
        }
    }

    /// The listed recordings that are still the files created, under names of the
    /// pattern, owned by the router's user; entries whose file is gone or replaced
    /// leave the list.
    pub(crate) fn recordings(&mut self) -> Vec<Existing> {
        let mut ours = Vec::new();
        let mut stale = Vec::new();
        for entry in self.list.entries() {
            let (found, meta) = look(&self.dir.join(&entry.name));
            match (manifest::judge(entry, &self.pattern, found, self.us), meta) {
                (Verdict::Ours, Some(meta)) => ours.push(existing(&self.pattern, entry, &meta)),
                (Verdict::Forget, _) => stale.push(entry.name.clone()),
                _ => {}
            }
        }
        for name in &stale {
            self.list.forget(name);
        }
        ours
    }

    /// What the file at `name` is now, by its list entry: looked at again just before it
    /// is removed, so that a file put in its place since it was listed (by hand, or by a
    /// second writer on the same directory) is never the one removed.
    pub(crate) fn verdict(&self, name: &str) -> Verdict {
        match self.list.get(name) {
            Some(entry) => {
                let (found, _) = look(&self.dir.join(name));
                manifest::judge(entry, &self.pattern, found, self.us)
            }
            None => Verdict::Unsure,
        }
    }

    /// Takes `name` off the list (removed).
    pub(crate) fn forget(&mut self, name: &str) {
        self.list.forget(name);
    }

    /// Writes the list to its file; trouble is said once until it works again.
    pub(crate) fn save(&mut self) {
        if !self.may_save {
            return;
        }
        let (text, left_out) = self.list.to_text(&self.pattern);
        let path = list_path(&self.pattern);
        let temp = self.dir.join(Manifest::temp_name(&self.pattern));
        match replace_file(&path, &temp, text.as_bytes(), 0o640, Manifest::MARK) {
            Ok(()) => self.failing = false,
            Err(e) => {
                if !self.failing {
                    self.failing = true;
                    log::warn(&format_args!(
                        "{}: cannot save the list of {} {}: {e}; {} not on it are never removed",
                        self.what,
                        self.files,
                        path.display(),
                        self.files
                    ));
                }
            }
        }
        if left_out > 0 && !self.trimmed {
            self.trimmed = true;
            log::warn(&format_args!(
                "{}: the list of {} {} is full; its {left_out} oldest are left out of it and will not be removed by later runs",
                self.what,
                self.files,
                path.display()
            ));
        }
    }
}

/// The recording `entry`, whose file has `meta`, as rotation sees it.
fn existing(pattern: &FilePattern, entry: &Created, meta: &Metadata) -> Existing {
    let modified = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    Existing {
        name: entry.name.clone(),
        modified,
        suffix: pattern.suffix_of(&entry.name).unwrap_or(0),
        bytes: meta.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A directory of its own, removed on drop.
    struct Dir(PathBuf);

    impl Dir {
        fn new(tag: &str) -> Dir {
            let dir = std::env::temp_dir()
                .join(format!("mavtables-manifest-{}-{tag}", std::process::id()));
            let _ = fs::remove_dir_all(&dir);
            fs::create_dir_all(&dir).expect("dir");
            Dir(dir)
        }

        fn pattern(&self) -> FilePattern {
            FilePattern::parse(&format!("{}/%Y_%H%M%S.tlog", self.0.display())).expect("pattern")
        }
    }

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn a_saved_list_reads_back_and_knows_only_the_files_created() {
        let dir = Dir::new("saved");
        let p = dir.pattern();
        assert!(matches!(read(&p), Stored::Absent));
        let mut made = MadeList::open(&p, "recording", "recordings");
        let name = "2024_100000.tlog";
        let file = File::create(dir.0.join(name)).expect("create");
        made.add(name, &file);
        made.save();
        assert!(matches!(read(&p), Stored::List(l) if l.entries().len() == 1));
        assert_eq!(created(&p, name), Ok(true));
        // Another file put at its name is not it.
        drop(file);
        fs::write(dir.0.join("other"), "mine").expect("other");
        fs::rename(dir.0.join("other"), dir.0.join(name)).expect("replace");
        assert_eq!(created(&p, name), Ok(false));
        let mut again = MadeList::open(&p, "recording", "recordings");
        assert!(again.recordings().is_empty());
        assert_eq!(created(&p, "2024_100001.tlog"), Ok(false));
    }

    #[test]
    fn what_mavtables_did_not_write_is_not_read_nor_replaced() {
        let dir = Dir::new("refused");
        let p = dir.pattern();
        let path = list_path(&p);
        fs::create_dir(&path).expect("a directory at the list's name");
        assert!(matches!(read(&p), Stored::Refused(_)));
        fs::remove_dir(&path).expect("rmdir");
        fs::write(&path, vec![b'#'; MAX_BYTES + 1]).expect("long");
        assert!(matches!(read(&p), Stored::Refused(why) if why.contains("longer")));
        let mut made = MadeList::open(&p, "recording", "recordings");
        made.save();
        assert_eq!(
            fs::metadata(&path).expect("meta").len(),
            MAX_BYTES as u64 + 1
        );
        fs::remove_file(&path).expect("rm");
        std::os::unix::fs::symlink("/dev/zero", &path).expect("link");
        assert!(matches!(read(&p), Stored::Refused(_)));
        // A text file of the user's at the list's name: not taken for a list, not
        // rewritten.
        fs::remove_file(&path).expect("rm");
        fs::write(&path, "1 2 3 notes.tlog\n").expect("text");
        assert!(matches!(read(&p), Stored::Refused(why) if why.contains("not a list")));
        MadeList::open(&p, "recording", "recordings").save();
        assert_eq!(
            fs::read_to_string(&path).expect("read"),
            "1 2 3 notes.tlog\n"
        );
    }

    #[test]
    fn only_what_an_interrupted_save_of_a_list_left_is_removed_before_the_next() {
        let dir = Dir::new("leftover");
        let p = dir.pattern();
        let path = list_path(&p);
        let temp = Path::new(p.dir()).join(Manifest::temp_name(&p));
        let mut made = MadeList::open(&p, "recording", "recordings");
        // A file of the user's at the temporary name: left, and the list not saved.
        fs::write(&temp, "# my notes\n").expect("write");
        made.save();
        assert!(!path.exists());
        assert_eq!(fs::read_to_string(&temp).expect("read"), "# my notes\n");
        // What a save cut short leaves: a beginning of the list, or zeros.
        let leftovers: [&[u8]; 3] = [b"# mavtables: the rec", &[0; 300], b""];
        for leftover in leftovers {
            let _ = fs::remove_file(&path);
            fs::write(&temp, leftover).expect("write");
            made.save();
            assert!(matches!(read(&p), Stored::List(_)), "{leftover:?}");
            assert!(fs::symlink_metadata(&temp).is_err(), "{leftover:?}");
        }
    }
}
