//! The signing state file: read once at start, then written by a thread of its own
//! (write to a temporary file, flush it to the disk, rename it over the old one), so the
//! file is always whole and the event loop never waits for a slow disk. Only the latest
//! state waits to be written; an older one not yet written is replaced.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::{self, JoinHandle};

use super::log;
use crate::files::{FileError, read_regular};
use crate::signing::state::{STATE_FILE_LIMIT, SavedState};

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
    /// The state saved at `path` by an earlier run (`None` if there is none or it cannot
    /// be read or understood: said in the log), and a writer for it. Something at `path`
    /// that is not a regular file, or is larger than [`STATE_FILE_LIMIT`], is an error:
    /// it is not read, and the writer would rename a file over it.
    pub(super) fn open(path: PathBuf) -> Result<(StateFile, Option<SavedState>), FileError> {
        let saved = match read_regular(&path, STATE_FILE_LIMIT) {
            Ok(bytes) => match SavedState::parse(&String::from_utf8_lossy(&bytes)) {
                Ok(state) => Some(state),
                Err(e) => {
                    log::warn(&format_args!(
                        "signing state {}: {e}; starting without it (frames from before may be replayable for up to a minute)",
                        path.display()
                    ));
                    None
                }
            },
            Err(FileError::NotFound) => None,
            Err(FileError::Unreadable(why)) => {
                log::warn(&format_args!(
                    "cannot read signing state {}: {why}; starting without it",
                    path.display()
                ));
                None
            }
            Err(e) => return Err(e),
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
/// if the machine loses power: a temporary file beside it, synced, renamed over it.
fn write_atomically(path: &Path, text: &str) -> io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let mut f: File = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(0o600)
        .open(&tmp)?;
    f.write_all(text.as_bytes())?;
    f.sync_all()?;
    drop(f);
    fs::rename(&tmp, path)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && let Ok(d) = File::open(dir)
    {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(saved, Some(state));
        file.finish(None);
        fs::write(&path, "garbage").expect("write");
        let (file, saved) = StateFile::open(path.clone()).expect("open");
        assert_eq!(saved, None);
        file.finish(None);
        // Not a regular file, or too large: refused, not read.
        fs::remove_file(&path).expect("remove");
        std::os::unix::fs::symlink("/dev/zero", &path).expect("symlink");
        assert!(matches!(
            StateFile::open(path.clone()),
            Err(FileError::NotRegular(_))
        ));
        fs::remove_file(&path).expect("remove");
        File::create(&path)
            .and_then(|f| f.set_len(STATE_FILE_LIMIT + 1))
            .expect("sparse file");
        assert!(matches!(
            StateFile::open(path.clone()),
            Err(FileError::TooLarge { .. })
        ));
        let _ = fs::remove_dir_all(&dir);
    }
}
