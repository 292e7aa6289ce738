//! The signing state file: read once at start, then written by a thread of its own
//! (write to a temporary file, flush it to the disk, rename it over the old one), so the
//! file is always whole and the event loop never waits for a slow disk. Only the latest
//! state waits to be written; an older one not yet written is replaced. At exit the last
//! state is written by the same thread, and the exit waits for it a bounded time.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use super::log;
use super::writer_thread::{Shared, WriterThread};
use crate::config::read_signing_state;
use crate::files::replace_file;
use crate::signing::state::SavedState;

/// How long the exit waits for the last state to be written: a disk that does not
/// answer (a stuck network mount) cannot hold the router's exit.
const FINISH: Duration = Duration::from_secs(5);

/// How often the writer looks at the queue without being woken (it is woken for each
/// state handed to it).
const LOOK_EVERY: Duration = Duration::from_secs(60);

/// How every signing state file mavtables writes begins, whatever its version: what an
/// interrupted save left may be removed only if it begins so (see [`replace_file`]).
const MARK: &[u8] = b"mavtables signing state ";

/// Held while a state is written: a writer a reload left behind on a stuck disk, coming
/// unstuck, cannot write beside the writer that followed it (on the same file, the same
/// temporary name), and the newer writer's saves, waiting for it, land last.
static SAVING: Mutex<()> = Mutex::new(());

/// What waits to be written: the latest state's text.
type Queued = Option<String>;

/// A signing state file and its writer thread.
pub(super) struct StateFile {
    path: PathBuf,
    writer: WriterThread<Queued, ()>,
}

impl StateFile {
    /// The state saved at `path` by an earlier run (`None` if there is none, or if its
    /// lines after the header cannot be understood: said in the log), and a writer for
    /// it. Anything at `path` but a state file mavtables wrote is an error (see
    /// [`read_signing_state`]), since the writer would rename a file over it; the error
    /// reads as a predicate of the file.
    pub(super) fn open(path: PathBuf) -> Result<(StateFile, Option<SavedState>), String> {
        let saved = match read_signing_state(&path)? {
            Some(bytes) => match SavedState::parse(&String::from_utf8_lossy(&bytes)) {
                Ok(state) => Some(state),
                Err(e) => {
                    log::warn(&format_args!(
                        "signing state {}: {e}; starting without it (frames from before may be replayable for up to a minute)",
                        path.display()
                    ));
                    None
                }
            },
            None => None,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            let _ = fs::create_dir_all(dir);
        }
        let writer = {
            let path = path.clone();
            WriterThread::spawn("signing-state", "signing state", move |shared| {
                write_loop(&path, &shared);
            })
        };
        if !writer.running() {
            log::warn(&format_args!(
                "signing state {}: it is saved only at exit",
                path.display()
            ));
        }
        Ok((StateFile { path, writer }, saved))
    }

    /// Hands `state` to the writer (replacing one it has not written yet).
    pub(super) fn save(&self, state: &SavedState) {
        self.writer.shared().queue().queued = Some(state.to_text());
        self.writer.shared().wake();
    }

    /// Writes `last` (the state at exit, or before a reload opens another file) and
    /// stops the writer, waiting for it at most [`FINISH`]. Without a writer thread it is
    /// written here.
    pub(super) fn finish(mut self, last: Option<&SavedState>) {
        let text = last.map(SavedState::to_text);
        if self.writer.running() {
            {
                // Both at once: the writer takes the last state as the last.
                let mut q = self.writer.shared().queue();
                q.queued = text;
                q.stop = true;
            }
            self.writer.finish(FINISH, "state");
        } else if let Some(text) = text {
            write_last(&self.path, &text);
        }
    }
}

/// The writer thread: writes whatever is pending until told to stop, and then what was
/// handed to it last. A failure is said once until a write succeeds again; a failure of
/// the last write is always said.
fn write_loop(path: &Path, shared: &Shared<Queued, ()>) {
    let mut failing = false;
    loop {
        let (text, stop) = {
            let mut q = shared.wait_due(LOOK_EVERY, Option::is_some);
            (q.queued.take(), q.stop)
        };
        if stop {
            if let Some(text) = text {
                write_last(path, &text);
            }
            return;
        }
        let Some(text) = text else { continue };
        match write_atomically(path, &text) {
            Ok(()) => failing = false,
            Err(e) if !failing => {
                failing = true;
                log::warn(&format_args!(
                    "cannot save signing state {}: {e} (retried while it changes)",
                    path.display()
                ));
            }
            Err(_) => {}
        }
    }
}

/// Writes the state at exit, saying so if it fails.
fn write_last(path: &Path, text: &str) {
    if let Err(e) = write_atomically(path, text) {
        log::warn(&format_args!(
            "cannot save signing state {}: {e}",
            path.display()
        ));
    }
}

/// Writes `text` to `path` so that the file is either the old one or the new one, even
/// if the machine loses power, through a temporary file of mavtables' own name beside
/// it ([`temp_path`]). When `path` is a symbolic link (a state kept on another disk of a
/// read-only system, say), the file it leads to is replaced and the link stays: the
/// state is read through the link, so it must be saved there too.
fn write_atomically(path: &Path, text: &str) -> io::Result<()> {
    let _saving = SAVING.lock().unwrap_or_else(PoisonError::into_inner);
    let target = link_target(path);
    replace_file(&target, &temp_path(&target), text.as_bytes(), 0o600, MARK)
}

/// The file a save to `path` replaces: `path`, or the file its links lead to (which need
/// not exist yet).
fn link_target(path: &Path) -> PathBuf {
    let mut target = path.to_path_buf();
    // A bounded number of links, as the system follows.
    for _ in 0..40 {
        match fs::read_link(&target) {
            Ok(next) => target = target.parent().map_or(next.clone(), |dir| dir.join(next)),
            Err(_) => break,
        }
    }
    target
}

/// Where the state for `path` is written before it is renamed over it: a hidden name of
/// mavtables' own in the same directory (`.signing.state.mavtables.tmp`), never a name a
/// user would give a file of theirs.
fn temp_path(path: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(".mavtables.tmp");
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signing::state::{HEADER, STATE_FILE_LIMIT};
    use std::fs::File;

    #[test]
    fn the_mark_begins_every_version_of_the_header() {
        assert!(HEADER.as_bytes().starts_with(MARK));
    }

    #[test]
    fn the_last_state_handed_over_is_the_one_saved() {
        let dir = std::env::temp_dir().join(format!("mavtables-state-last-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let path = dir.join("signing.state");
        let state = |clock| SavedState {
            clean: clock % 2 == 0,
            clock,
            streams: Vec::new(),
        };
        for round in 0..20 {
            let (file, _) = StateFile::open(path.clone()).expect("open");
            for clock in 0..round {
                file.save(&state(clock));
            }
            file.finish(Some(&state(1000 + round)));
            assert_eq!(
                SavedState::parse(&fs::read_to_string(&path).expect("read")),
                Ok(state(1000 + round))
            );
        }
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn saved_state_is_read_back_and_damage_is_not_fatal() {
        let dir = std::env::temp_dir().join(format!("mavtables-state-{}", std::process::id()));
        let path = dir.join("sub").join("signing.state");
        let (file, saved) = StateFile::open(path.clone()).expect("open");
        assert_eq!(saved, None);
        let state = SavedState {
            clean: true,
            clock: 42,
            streams: Vec::new(),
        };
        file.save(&state);
        file.finish(Some(&state));
        let (file, saved) = StateFile::open(path.clone()).expect("open");
        assert_eq!(saved, Some(state.clone()));
        file.finish(None);
        // Its own file, damaged after the header: started without, and replaced.
        fs::write(&path, format!("{HEADER}\ngarbage\n")).expect("write");
        let (file, saved) = StateFile::open(path.clone()).expect("open");
        assert_eq!(saved, None);
        file.finish(Some(&state));
        assert_eq!(
            SavedState::parse(&fs::read_to_string(&path).expect("read")),
            Ok(state.clone())
        );
        // Somebody else's file: refused, and left as it was.
        fs::write(&path, "my notes\n").expect("write");
        let refused = StateFile::open(path.clone()).err().expect("refused");
        assert!(
            refused.contains("does not hold a mavtables signing state"),
            "{refused}"
        );
        assert_eq!(fs::read_to_string(&path).expect("read"), "my notes\n");
        // Not a regular file, or too large: refused, not read.
        fs::remove_file(&path).expect("remove");
        std::os::unix::fs::symlink("/dev/zero", &path).expect("symlink");
        let refused = StateFile::open(path.clone()).err().expect("refused");
        assert!(refused.contains("not a regular file"), "{refused}");
        fs::remove_file(&path).expect("remove");
        File::create(&path)
            .and_then(|f| f.set_len(STATE_FILE_LIMIT + 1))
            .expect("sparse file");
        let refused = StateFile::open(path.clone()).err().expect("refused");
        assert!(refused.contains("larger than the limit"), "{refused}");
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_state_is_written_through_a_name_of_mavtables_own_and_only_its_own_leftover_is_removed() {
        let dir = std::env::temp_dir().join(format!("mavtables-state-tmp-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("notes");
        // The user's own `notes.tmp`, and a link at the temporary name to a file of theirs.
        fs::write(dir.join("notes.tmp"), "mine").expect("write");
        fs::write(dir.join("victim"), "victim data").expect("write");
        let temp = temp_path(&path);
        assert_eq!(temp, dir.join(".notes.mavtables.tmp"));
        std::os::unix::fs::symlink(dir.join("victim"), &temp).expect("symlink");
        let state = SavedState {
            clean: true,
            clock: 7,
            streams: Vec::new(),
        };
        let text = state.to_text();
        // A link there is neither followed nor removed: the save fails and says why.
        let refused = write_atomically(&path, &text).expect_err("a link is in the way");
        assert!(refused.to_string().contains("in the way"), "{refused}");
        assert!(fs::symlink_metadata(&temp).expect("meta").is_symlink());
        assert!(!path.exists());
        // Nor is a file that is not mavtables'.
        fs::remove_file(&temp).expect("remove");
        fs::write(&temp, "the user's notes").expect("write");
        write_atomically(&path, &text).expect_err("a file of theirs is in the way");
        assert_eq!(fs::read_to_string(&temp).expect("read"), "the user's notes");
        // What an interrupted save leaves (mavtables' header, or nothing yet) is removed.
        for leftover in [format!("{HEADER}\nhalf a sta"), String::new()] {
            fs::write(&temp, leftover).expect("write");
            write_atomically(&path, &text).expect("write");
            assert_eq!(
                SavedState::parse(&fs::read_to_string(&path).expect("read")),
                Ok(state.clone())
            );
            assert!(fs::symlink_metadata(&temp).is_err());
        }
        assert!(fs::symlink_metadata(&path).expect("meta").is_file());
        assert_eq!(
            fs::read_to_string(dir.join("notes.tmp")).expect("read"),
            "mine"
        );
        assert_eq!(
            fs::read_to_string(dir.join("victim")).expect("read"),
            "victim data"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_state_file_that_is_a_link_is_saved_where_it_leads_and_the_link_stays() {
        let dir = std::env::temp_dir().join(format!("mavtables-state-link-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("persist")).expect("dir");
        fs::create_dir_all(dir.join("etc")).expect("dir");
        let kept = dir.join("persist").join("signing.state");
        let path = dir.join("etc").join("signing.state");
        // A relative link, as `ln -s ../persist/signing.state` makes; its file not there yet.
        std::os::unix::fs::symlink("../persist/signing.state", &path).expect("symlink");
        let state = |clock| SavedState {
            clean: true,
            clock,
            streams: Vec::new(),
        };
        for clock in [7, 8] {
            let (file, _) = StateFile::open(path.clone()).expect("open");
            file.finish(Some(&state(clock)));
            assert!(fs::symlink_metadata(&path).expect("meta").is_symlink());
            assert_eq!(
                SavedState::parse(&fs::read_to_string(&kept).expect("read")),
                Ok(state(clock))
            );
        }
        let (file, saved) = StateFile::open(path.clone()).expect("open");
        assert_eq!(saved, Some(state(8)));
        file.finish(None);
        assert!(
            !dir.join("etc")
                .join(".signing.state.mavtables.tmp")
                .exists()
        );
        let _ = fs::remove_dir_all(&dir);
    }
}
