//! The signing state file: read once at start, then written by a thread of its own
//! (write to a temporary file, flush it to the disk, rename it over the old one), so the
//! file is always whole and the event loop never waits for a slow disk. Only the latest
//! state waits to be written; an older one not yet written is replaced.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::{self, JoinHandle};

use super::log;
use crate::config::read_signing_state;
use crate::files::replace_file;
use crate::signing::state::SavedState;

/// What the loop and the writer share: the text to write next, and whether to stop.
#[derive(Default)]
struct Pending {
    text: Option<String>,
    stop: bool,
}

/// A signing state file and its writer thread.
pub(super) struct StateFile {
    path: PathBuf,
    shared: Arc<(Mutex<Pending>, Condvar)>,
    writer: Option<JoinHandle<()>>,
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
        let shared = Arc::new((Mutex::new(Pending::default()), Condvar::new()));
        let writer = {
            let shared = shared.clone();
            let path = path.clone();
            thread::Builder::new()
                .name("signing-state".into())
                .spawn(move || write_loop(&path, &shared))
                .map_err(|e| {
                    log::error(&format_args!(
                        "signing state: cannot start its writer: {e}; it is saved only at exit"
                    ));
                })
                .ok()
        };
        Ok((
            StateFile {
                path,
                shared,
                writer,
            },
            saved,
        ))
    }

    /// Hands `state` to the writer (replacing one it has not written yet).
    pub(super) fn save(&self, state: &SavedState) {
        let (lock, cv) = &*self.shared;
        let mut p = lock.lock().unwrap_or_else(PoisonError::into_inner);
        p.text = Some(state.to_text());
        cv.notify_one();
    }

    /// Stops the writer and writes `last` (the state at exit) before returning.
    pub(super) fn finish(mut self, last: Option<&SavedState>) {
        {
            let (lock, cv) = &*self.shared;
            let mut p = lock.lock().unwrap_or_else(PoisonError::into_inner);
            p.stop = true;
            p.text = None;
            cv.notify_one();
        }
        if let Some(w) = self.writer.take() {
            let _ = w.join();
        }
        if let Some(state) = last
            && let Err(e) = write_atomically(&self.path, &state.to_text())
        {
            log::warn(&format_args!(
                "cannot save signing state {}: {e}",
                self.path.display()
            ));
        }
    }
}

/// The writer thread: writes whatever is pending until told to stop. A failure is said
/// once until a write succeeds again.
fn write_loop(path: &Path, shared: &(Mutex<Pending>, Condvar)) {
    let (lock, cv) = shared;
    let mut failing = false;
    loop {
        let text = {
            let mut p = lock.lock().unwrap_or_else(PoisonError::into_inner);
            while p.text.is_none() && !p.stop {
                p = cv.wait(p).unwrap_or_else(PoisonError::into_inner);
            }
            if p.stop {
                return;
            }
            p.text.take()
        };
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

/// Writes `text` to `path` so that the file is either the old one or the new one, even
/// if the machine loses power, through a temporary file of mavtables' own name beside
/// it ([`temp_path`]). When `path` is a symbolic link (a state kept on another disk of a
/// read-only system, say), the file it leads to is replaced and the link stays: the
/// state is read through the link, so it must be saved there too.
fn write_atomically(path: &Path, text: &str) -> io::Result<()> {
    let target = link_target(path);
    replace_file(&target, &temp_path(&target), text.as_bytes(), 0o600)
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
    fn the_state_is_written_through_a_name_of_mavtables_own_and_links_are_not_followed() {
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
        write_atomically(&path, &state.to_text()).expect("write");
        assert_eq!(
            SavedState::parse(&fs::read_to_string(&path).expect("read")),
            Ok(state)
        );
        assert!(fs::symlink_metadata(&path).expect("meta").is_file());
        assert_eq!(
            fs::read_to_string(dir.join("notes.tmp")).expect("read"),
            "mine"
        );
        assert_eq!(
            fs::read_to_string(dir.join("victim")).expect("read"),
            "victim data"
        );
        assert!(!temp.exists() && fs::symlink_metadata(&temp).is_err());
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
