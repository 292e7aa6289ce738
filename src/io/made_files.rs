//! The file steps both writers (the recorder, the flight log) take on the files they
//! create: a new file created afresh under a name of the pattern, files of the
//! [`MadeList`] removed (and only those), and the plan of which to remove to keep
//! `min_free_bytes` free. Listing, saving and what is said stay with each writer.

use std::fs::{self, File, OpenOptions};
use std::io;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicU64;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use super::manifest::MadeList;
use super::writer_thread::add;
use super::{log, sys};
use crate::recording::manifest::Verdict;
use crate::recording::pattern::MAX_SUFFIX;
use crate::recording::rotation::{self, SpacePlan};
use crate::recording::{FilePattern, LocalTime};

/// Why no new file was created.
pub(super) enum CreateError {
    /// Creating `path` failed (other than because it exists).
    Failed { path: PathBuf, error: io::Error },
    /// Every name of the pattern for this time, up to suffix `MAX_SUFFIX`, is taken.
    AllTaken,
}

/// The suffixes one writer gave under one name of its pattern (one second's name, or a
/// fixed name): a file made later under the same name takes a higher suffix than every
/// one before it, even when an older one was removed meanwhile and its name is free
/// again, so that suffixes follow the order the files were made in (rotation orders
/// files of one time by suffix, and some file systems keep times to 2 s only). Past
/// [`MAX_SUFFIX`] the search starts from the bare name again.
#[derive(Debug, Default)]
pub(super) struct Suffixes {
    /// The bare name (suffix 0) of the last file made, and the suffix to try next.
    last: Option<(String, u32)>,
}

/// Creates `dir` if needed and in it a new file named by `pattern` after the local time
/// now (with a suffix if the name is taken, or was given before: see [`Suffixes`]);
/// never opens a file that exists. Returns the file, open for appending, and its name.
pub(super) fn create_new(
    dir: &Path,
    pattern: &FilePattern,
    suffixes: &mut Suffixes,
) -> Result<(File, String), CreateError> {
    create_at(dir, pattern, &local_now(), suffixes)
}

/// [`create_new`] at the local time `time`.
fn create_at(
    dir: &Path,
    pattern: &FilePattern,
    time: &LocalTime,
    suffixes: &mut Suffixes,
) -> Result<(File, String), CreateError> {
    let _ = fs::create_dir_all(dir);
    let bare = pattern.name(time, 0);
    let first = match &suffixes.last {
        Some((name, next)) if *name == bare && *next <= MAX_SUFFIX => *next,
        _ => 0,
    };
    for n in (first..=MAX_SUFFIX).chain(0..first) {
        let name = pattern.name(time, n);
        // Appending: after a failed write is cut back, the next one goes at the end
        // again (not where the failed one stopped, which would leave a hole).
        match OpenOptions::new()
            .append(true)
            .create_new(true)
            .mode(0o640)
            .open(dir.join(&name))
        {
            Ok(file) => {
                suffixes.last = Some((bare, n.saturating_add(1)));
                return Ok((file, name));
            }
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(error) => {
                return Err(CreateError::Failed {
                    path: dir.join(&name),
                    error,
                });
            }
        }
    }
    Err(CreateError::AllTaken)
}

/// Removes the files `names` in `dir` and takes them off `made`, counting each in
/// `removed`; each is looked at again first, and one that is no longer the file created
/// is only taken off the list. One that cannot be removed stays listed and is said
/// (beginning with `what`, giving `why` it was to go). The caller saves the list.
pub(super) fn remove(
    dir: &Path,
    made: &mut MadeList,
    names: &[String],
    why: &str,
    what: &str,
    removed: &AtomicU64,
) {
    for name in names {
        let path = dir.join(name);
        match made.verdict(name) {
            Verdict::Ours => {}
            Verdict::Forget => {
                // Gone, or not the file created any more: that file is not ours to remove.
                made.forget(name);
                continue;
            }
            Verdict::Unsure => {
                log::warn(&format_args!(
                    "{what}: cannot tell whether {} is still the file created, so it stays ({why})",
                    path.display()
                ));
                continue;
            }
        }
        let bytes = fs::symlink_metadata(&path).map_or(0, |m| m.len());
        match fs::remove_file(&path) {
            Ok(()) => {
                add(removed, 1);
                made.freeing.removed(bytes, Instant::now());
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => {
                log::warn(&format_args!(
                    "{what}: cannot remove {} ({why}): {e}",
                    path.display()
                ));
                continue;
            }
        }
        made.forget(name);
    }
}

/// Which of `made`'s files to remove so that `needed` bytes can be written in `dir` with
/// `min_free` bytes left free (never `current`, the open file); nothing when the disk has
/// room or its free space cannot be told.
pub(super) fn room_plan(
    dir: &Path,
    made: &mut MadeList,
    min_free: u64,
    needed: u64,
    current: Option<&str>,
) -> SpacePlan {
    let room = SpacePlan {
        remove: Vec::new(),
        enough: true,
    };
    if min_free == 0 {
        return room;
    }
    let Ok(free) = sys::free_bytes(dir) else {
        return room;
    };
    let now = Instant::now();
    let counted = made.freeing.counted(free, now);
    if counted >= min_free.saturating_add(needed) {
        return room;
    }
    let files = made.recordings();
    // What is removed (by `remove`) is counted as being freed from then on.
    rotation::make_room(&files, counted, needed, min_free, current)
}

/// How long space that removed files should free is counted as free before the disk
/// shows it: a file system may give it back only later (btrfs, ZFS), and a file another
/// program holds open keeps its space until it is closed.
const FREEING_WAIT: Duration = Duration::from_secs(30);

/// The space the files last removed for `min_free_bytes` should free. Until the disk
/// shows it (or for [`FREEING_WAIT`]), it is counted as free: otherwise each write
/// would find the disk still short and remove the next oldest file, and the next,
/// until none was left.
#[derive(Debug, Default)]
pub(crate) struct Freeing {
    /// The disk's free space when they were removed, their bytes, and when.
    pending: Option<(u64, u64, Instant)>,
    /// The free space the disk showed when it was last looked at.
    seen: Option<u64>,
}

impl Freeing {
    /// The free space to plan with when the disk shows `free` at `now`: with the space
    /// being freed while the disk shows no more than before the removal (what was
    /// written since is already less in `free`).
    fn counted(&mut self, free: u64, now: Instant) -> u64 {
        self.seen = Some(free);
        match self.pending {
            Some((before, bytes, since)) if free <= before && now < since + FREEING_WAIT => {
                free.saturating_add(bytes)
            }
            _ => {
                self.pending = None;
                free
            }
        }
    }

    /// A file of `bytes` was removed at `now` (after the disk was looked at).
    fn removed(&mut self, bytes: u64, now: Instant) {
        if let Some(free) = self.seen.filter(|_| bytes > 0) {
            let (free, bytes) = match self.pending {
                // Still waiting for the last ones: theirs is not shown either.
                Some((before, pending, _)) => (before.min(free), pending.saturating_add(bytes)),
                None => (free, bytes),
            };
            self.pending = Some((free, bytes, now));
        }
    }
}

/// The local calendar time now (UTC if the C library cannot tell).
pub(super) fn local_now() -> LocalTime {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_secs()).unwrap_or(i64::MAX));
    let (year, month, day, hour, minute, second) = match sys::local_time(secs) {
        Some((y, mo, d, h, mi, s)) => (i64::from(y), mo, d, h, mi, s),
        None => crate::utc::calendar(secs),
    };
    LocalTime {
        year: i32::try_from(year).unwrap_or(9999),
        month,
        day,
        hour,
        minute,
        second,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn space_being_freed_counts_as_free_until_it_shows_or_the_wait_is_over() {
        let mut f = Freeing::default();
        let t0 = Instant::now();
        let s = Duration::from_secs;
        // Nothing is credited before the disk was looked at.
        f.removed(50, t0);
        assert_eq!(f.counted(100, t0), 100);
        f.removed(50, t0);
        // The disk does not show it yet (and 10 bytes were written since): planned
        // with the 50 to come, so no second file goes.
        assert_eq!(f.counted(90, t0 + s(1)), 140);
        // The space showed up (less what was written): the disk from now on.
        assert_eq!(f.counted(135, t0 + s(2)), 135);
        assert_eq!(f.counted(90, t0 + s(3)), 90);
        // It never shows: after the wait, the disk is believed again.
        f.removed(50, t0);
        f.removed(20, t0 + s(1));
        assert_eq!(f.counted(90, t0 + FREEING_WAIT - s(1)), 160);
        assert_eq!(f.counted(90, t0 + FREEING_WAIT + s(2)), 90);
    }

    /// An empty scratch directory named after `tag`, and a pattern of names in it.
    fn scratch(tag: &str) -> (PathBuf, FilePattern) {
        let dir = std::env::temp_dir().join(format!("mavtables-made-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let pattern =
            FilePattern::parse(&format!("{}/r_%H-%M-%S.tlog", dir.display())).expect("pattern");
        (dir, pattern)
    }

    #[test]
    fn a_later_file_under_one_name_takes_a_higher_suffix_even_where_an_older_name_is_free() {
        let (dir, pattern) = scratch("suffix");
        let time = local_now();
        let mut suffixes = Suffixes::default();
        let make = |suffixes: &mut Suffixes| {
            create_at(&dir, &pattern, &time, suffixes)
                .ok()
                .expect("a new file")
                .1
        };
        let names: Vec<String> = (0..3).map(|_| make(&mut suffixes)).collect();
        let named = |n: u32| pattern.name(&time, n);
        assert_eq!(names, [named(0), named(1), named(2)]);
        // Rotation removed the oldest: its name is free, but the next file is newer.
        fs::remove_file(dir.join(&names[0])).expect("remove");
        assert_eq!(make(&mut suffixes), named(3));
        // Past the last suffix, the lowest free name is taken again.
        suffixes.last = Some((named(0), MAX_SUFFIX + 1));
        assert_eq!(make(&mut suffixes), named(0));
        // Another writer (or a restart) starts from the bare name: the lowest free one.
        assert_eq!(make(&mut Suffixes::default()), named(4));
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_listed_file_replaced_since_is_left_alone_and_only_taken_off_the_list() {
        let (dir, pattern) = scratch("rm");
        let mut made = MadeList::open(&pattern, "recording", "recordings");
        let mut suffixes = Suffixes::default();
        let mut make = || {
            let (file, name) = create_new(&dir, &pattern, &mut suffixes)
                .ok()
                .expect("a new file");
            made.add(&name, &file);
            name
        };
        let (kept, replaced) = (make(), make());
        // The second is replaced by another file under its name (another writer, or by
        // hand) after it was listed.
        let theirs = dir.join("theirs");
        fs::write(&theirs, "not a recording").expect("write");
        fs::rename(&theirs, dir.join(&replaced)).expect("rename");
        let removed = AtomicU64::new(0);
        let names = [kept.clone(), replaced.clone()];
        remove(&dir, &mut made, &names, "test", "recording", &removed);
        assert!(!dir.join(&kept).exists(), "the file created is removed");
        assert_eq!(
            fs::read_to_string(dir.join(&replaced)).ok().as_deref(),
            Some("not a recording"),
            "the file put in its place is not"
        );
        assert_eq!(removed.load(std::sync::atomic::Ordering::Relaxed), 1);
        assert!(made.recordings().is_empty(), "both are off the list");
        let _ = fs::remove_dir_all(&dir);
    }
}
