//! The recorder: `.tlog` files written by a thread of its own, so that the event loop
//! never waits for a disk.
//!
//! Every loop turn the loop takes the frames the core kept for recording
//! ([`Engine::poll_recorded`]), stamps them with the wall clock (never going back, even
//! when the clock is stepped back) and appends them to a bounded queue under one short
//! lock. The writer takes the whole queue at least every 200 ms (sooner when a quarter of
//! it is full) and writes it: a new file when the current one would pass
//! `max_file_bytes` (the oldest recordings beyond `max_files` are removed then), old
//! recordings removed while the disk has less than `min_free_bytes` free. Only the
//! files the writer created are ever appended to, cut back or removed: each new file is
//! created afresh (never opened if it exists) and put on the list of recordings
//! ([`MadeList`]), and rotation chooses among the files on that list only. Records that
//! do not fit — the queue is full, the disk fails or has no room left — are dropped and
//! counted, never packets; each kind of trouble is said once, and again when it is over.
//! At exit the last records are written and the file is synced and closed.

use std::fs::File;
use std::io::{self, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::time::Duration;

use super::log;
use super::made_files::{self, CreateError};
use super::manifest::MadeList;
use super::writer_thread::{self, Behind, WriterThread, add, read};
use crate::capture::tlog::TIMESTAMP_LEN;
use crate::config::Recording;
use crate::recording::pattern::MAX_SUFFIX;
use crate::recording::rotation;
use crate::recording::{FilePattern, RecorderStats};
use crate::routing::{Engine, Timestamp};

/// What the queue between the loop and the writer may hold: seconds of the busiest
/// links, so that a disk's short stall loses nothing.
pub(super) const QUEUE_BOUND: usize = 4 << 20;
/// The writer takes the queue early once it holds this much.
const WAKE_AT: usize = QUEUE_BOUND / 4;
/// The writer takes the queue at least this often, so that records reach the file
/// (where readers see them) within this time.
const WRITE_EVERY: Duration = Duration::from_millis(200);

/// Records waiting for the writer: `bytes` holds them back to back (timestamp and
/// frame), `lens` the length of each.
#[derive(Default)]
struct Queue {
    bytes: Vec<u8>,
    lens: Vec<u32>,
}

/// The counters both sides add to.
#[derive(Default)]
struct Counters {
    written: AtomicU64,
    bytes: AtomicU64,
    dropped_queue_full: AtomicU64,
    dropped_disk: AtomicU64,
    dropped_no_space: AtomicU64,
    files: AtomicU64,
    removed: AtomicU64,
}

impl Counters {
    /// Records the writer dropped (the disk failed or had no room).
    fn dropped_by_writer(&self) -> u64 {
        read(&self.dropped_disk) + read(&self.dropped_no_space)
    }
}

/// What the loop and the writer share.
type Shared = writer_thread::Shared<Queue, Counters>;

/// The loop's handle on the recorder.
pub(super) struct Recorder {
    writer: WriterThread<Queue, Counters>,
    /// The last timestamp queued, in microseconds since the epoch.
    last_us: u64,
    /// Whether records are being dropped because the queue is full (said once).
    behind: Behind,
}

impl Recorder {
    /// Starts the writer for `record`, whose path pattern is `pattern`; it opens the
    /// first file at once.
    pub(super) fn start(record: &Recording, pattern: FilePattern) -> Recorder {
        let (max_file_bytes, max_files, min_free_bytes) = (
            record.max_file_bytes,
            record.max_files,
            record.min_free_bytes,
        );
        let writer = WriterThread::spawn("recorder", "recording", move |shared| {
            let writer = Writer {
                dir: PathBuf::from(pattern.dir()),
                // Read here, on the writer's thread: the disk may be slow.
                made: MadeList::open(&pattern, "recording", "recordings"),
                pattern,
                max_file_bytes,
                max_files,
                min_free_bytes,
                shared,
                file: None,
                name: None,
                size: 0,
                trouble: None,
                suffixes: made_files::Suffixes::default(),
            };
            writer.run();
        });
        Recorder {
            writer,
            last_us: 0,
            behind: Behind::default(),
        }
    }

    /// Queues the frames the core kept for recording, stamped with the wall clock:
    /// `now` on the core's clock is `wall_us` (microseconds since the epoch).
    pub(super) fn take_from(&mut self, engine: &mut Engine, now: Timestamp, wall_us: u64) {
        let mut queued = 0u64;
        let mut dropped = 0u64;
        let last = &mut self.last_us;
        {
            let mut pending = self.writer.shared().queue();
            let q = &mut pending.queued;
            let before = q.bytes.len();
            engine.poll_recorded(&mut |at, frame| {
                let age = u64::try_from(now.saturating_since(at).as_micros()).unwrap_or(0);
                let stamp = wall_us.saturating_sub(age).max(*last);
                *last = stamp;
                let len = TIMESTAMP_LEN + frame.len();
                if q.bytes.len() + len > QUEUE_BOUND {
                    dropped += 1;
                    return;
                }
                q.bytes.extend_from_slice(&stamp.to_be_bytes());
                q.bytes.extend_from_slice(frame);
                q.lens.push(u32::try_from(len).unwrap_or(u32::MAX));
                queued += 1;
            });
            if before < WAKE_AT && q.bytes.len() >= WAKE_AT {
                self.writer.shared().wake();
            }
        }
        add(&self.writer.shared().counters().dropped_queue_full, dropped);
        self.behind
            .turn("recording", "records", dropped, queued > 0);
    }

    /// The counters so far (`core_dropped`: frames the core's buffer could not keep,
    /// counted as queue full).
    pub(super) fn stats(&self, core_dropped: u64) -> RecorderStats {
        let shared = self.writer.shared();
        let c = shared.counters();
        RecorderStats {
            written: read(&c.written),
            bytes: read(&c.bytes),
            dropped_queue_full: read(&c.dropped_queue_full) + core_dropped,
            dropped_disk: read(&c.dropped_disk),
            dropped_no_space: read(&c.dropped_no_space),
            files: read(&c.files),
            removed: read(&c.removed),
            current_path: shared.current(),
        }
    }

    /// Lets the writer write what is queued, sync and close its file, waiting at most
    /// `timeout` for it (a stuck disk cannot hold the exit).
    pub(super) fn finish(&mut self, timeout: Duration) {
        self.writer.finish(timeout, "records");
    }
}

/// What keeps records from the disk, said once until it is over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Trouble {
    /// Opening or writing a file failed.
    Disk,
    /// Less than `min_free_bytes` free even without the older recordings.
    NoSpace,
}

/// The writer thread's state.
struct Writer {
    pattern: FilePattern,
    dir: PathBuf,
    /// The recordings this writer (and earlier runs) created: the only files it may
    /// remove.
    made: MadeList,
    max_file_bytes: u64,
    max_files: u32,
    min_free_bytes: u64,
    shared: Arc<Shared>,
    file: Option<File>,
    /// The open file's name (in `dir`).
    name: Option<String>,
    /// Bytes in the open file.
    size: u64,
    /// What is failing now, and the writer's drop count when it began.
    trouble: Option<(Trouble, u64)>,
    /// The suffixes given under the last file's name.
    suffixes: made_files::Suffixes,
}

impl Writer {
    fn run(mut self) {
        self.open_new();
        let mut batch = Queue::default();
        loop {
            let stop = self.wait(&mut batch);
            self.write(&batch.bytes, &batch.lens);
            batch.bytes.clear();
            batch.lens.clear();
            if stop {
                break;
            }
        }
        self.close();
    }

    /// Waits until records are due to be written and swaps them into `batch` (whose
    /// emptied buffers the loop fills next); true when the loop is stopping.
    fn wait(&self, batch: &mut Queue) -> bool {
        let mut q = self
            .shared
            .wait_due(WRITE_EVERY, |q| q.bytes.len() >= WAKE_AT);
        std::mem::swap(&mut q.queued.bytes, &mut batch.bytes);
        std::mem::swap(&mut q.queued.lens, &mut batch.lens);
        q.stop
    }

    /// Writes `bytes` (records of `lens` bytes each), in runs that fit the files.
    fn write(&mut self, bytes: &[u8], lens: &[u32]) {
        let (mut at, mut i) = (0usize, 0usize);
        while i < lens.len() {
            let first = u64::from(lens[i]);
            if self.file.is_none() || rotation::must_rotate(self.size, first, self.max_file_bytes) {
                self.open_new();
            }
            if self.file.is_none() {
                let left = (lens.len() - i) as u64;
                add(&self.shared.counters().dropped_disk, left);
                return;
            }
            let (mut run, mut j) = (0u64, i);
            while j < lens.len()
                && !rotation::must_rotate(self.size + run, u64::from(lens[j]), self.max_file_bytes)
            {
                run += u64::from(lens[j]);
                j += 1;
            }
            let end = at + usize::try_from(run).unwrap_or(usize::MAX);
            self.write_run(bytes.get(at..end).unwrap_or_default(), &lens[i..j]);
            at = end;
            i = j;
        }
    }

    /// Writes whole records (`run`, of `lens` bytes each), if the disk has room for them.
    fn write_run(&mut self, run: &[u8], lens: &[u32]) {
        let shared = self.shared.clone();
        let counters = shared.counters();
        let count = lens.len() as u64;
        if !self.make_room(run.len() as u64) {
            // Said before these are counted: they are among those dropped since.
            self.trouble(
                Trouble::NoSpace,
                &"less than min_free_bytes free on the disk even without the older recordings",
            );
            add(&counters.dropped_no_space, count);
            return;
        }
        let Some(file) = self.file.as_mut() else {
            add(&counters.dropped_disk, count);
            return;
        };
        let e = match file.write_all(run) {
            Ok(()) => {
                self.size += run.len() as u64;
                add(&counters.written, count);
                add(&counters.bytes, run.len() as u64);
                self.recovered();
                return;
            }
            Err(e) => e,
        };
        // How far the file got, then cut back: a record cut short would garble the rest
        // of the file for its readers.
        let reached = file.metadata().map_or(0, |m| m.len()).max(self.size);
        let cut = file.set_len(self.size);
        if cut.is_ok() && e.kind() == io::ErrorKind::FileTooLarge && reached < self.max_file_bytes {
            // No file may grow beyond `reached` here (a file-size limit, FAT's 4 GiB):
            // files are rotated at that size from now on, and these records go on in a
            // new one. Each time the limit only shrinks, so this ends.
            let path = self.path_text();
            log::warn(&format_args!(
                "recording: {path} cannot grow beyond {reached} bytes ({e}); new files are started at that size instead of max_file_bytes"
            ));
            self.max_file_bytes = reached;
            self.close();
            self.write(run, lens);
            return;
        }
        let path = self.path_text();
        match &cut {
            Err(cut) => self.trouble(
                Trouble::Disk,
                &format_args!(
                    "cannot write {path} ({e}), nor cut it back to its last whole record ({cut}), so the next records start a new file"
                ),
            ),
            Ok(()) => self.trouble(Trouble::Disk, &format_args!("cannot write {path}: {e}")),
        }
        add(&counters.dropped_disk, count);
        // A full disk may get room again, and this file goes on then. Any other failure
        // (a card that dropped out and came back, an I/O error) may stay with this
        // handle for good, and a torn record left at the end (the cut back failed) must
        // have nothing after it: the next records start a new file.
        let full = matches!(
            e.kind(),
            io::ErrorKind::StorageFull | io::ErrorKind::QuotaExceeded
        );
        if cut.is_err() || !full {
            self.close();
        }
    }

    /// Removes old recordings while the disk would have less than `min_free_bytes` free
    /// after writing `needed` bytes; false if that is not enough.
    fn make_room(&mut self, needed: u64) -> bool {
        let plan = made_files::room_plan(
            &self.dir,
            &mut self.made,
            self.min_free_bytes,
            needed,
            self.name.as_deref(),
        );
        if !plan.remove.is_empty() {
            self.remove(&plan.remove, "to keep min_free_bytes free");
            self.made.save();
        }
        plan.enough
    }

    /// Syncs and closes the open file.
    fn close(&mut self) {
        if let Some(file) = self.file.take() {
            let _ = file.sync_data();
        }
        self.name = None;
        self.size = 0;
    }

    /// Closes the open file and opens a new one named after the time now (with a
    /// suffix if the name is taken); then removes the recordings beyond `max_files`.
    fn open_new(&mut self) {
        self.close();
        let (file, name) =
            match made_files::create_new(&self.dir, &self.pattern, &mut self.suffixes) {
                Ok(opened) => opened,
                Err(CreateError::Failed { path, error }) => {
                    self.trouble(
                        Trouble::Disk,
                        &format_args!("cannot create {}: {error}", path.display()),
                    );
                    return;
                }
                Err(CreateError::AllTaken) => {
                    let dir = self.dir.display().to_string();
                    self.trouble(
                        Trouble::Disk,
                        &format_args!("every name up to suffix -{MAX_SUFFIX} is taken in {dir}"),
                    );
                    return;
                }
            };
        self.made.add(&name, &file);
        self.file = Some(file);
        self.name = Some(name);
        add(&self.shared.counters().files, 1);
        self.shared.set_current(self.path_text());
        let files = self.made.recordings();
        let excess = rotation::over_count(&files, self.max_files, self.name.as_deref());
        self.remove(&excess, "beyond max_files");
        self.made.save();
    }

    /// Removes the recordings `names` and takes them off the list (`why` goes in the
    /// message if it fails).
    fn remove(&mut self, names: &[String], why: &str) {
        made_files::remove(
            &self.dir,
            &mut self.made,
            names,
            why,
            "recording",
            &self.shared.counters().removed,
        );
    }

    fn path_text(&self) -> String {
        match &self.name {
            Some(name) => self.dir.join(name).display().to_string(),
            None => self.dir.display().to_string(),
        }
    }

    /// Says `what` if this kind of trouble is new.
    fn trouble(&mut self, kind: Trouble, what: &dyn std::fmt::Display) {
        if self.trouble.is_some_and(|(k, _)| k == kind) {
            return;
        }
        let dropped = self.shared.counters().dropped_by_writer();
        self.trouble = Some((kind, dropped));
        log::warn(&format_args!(
            "recording: {what}; records are dropped and counted until it works again"
        ));
    }

    /// Says that records are written again, after trouble.
    fn recovered(&mut self) {
        if let Some((_, before)) = self.trouble.take() {
            let dropped = self.shared.counters().dropped_by_writer() - before;
            log::warn(&format_args!(
                "recording: writing again to {}; {dropped} records were dropped",
                self.path_text()
            ));
        }
    }
}

/// The recorder for `record`, if its path is a valid pattern (the configuration checks
/// a written one; a default one comes from `$LOGS_DIRECTORY`).
pub(super) fn start(record: &Recording) -> Option<Recorder> {
    let path = record.path_pattern(|k| std::env::var(k).ok());
    match FilePattern::parse(&path) {
        Ok(pattern) => Some(Recorder::start(record, pattern)),
        Err(e) => {
            log::error(&format_args!(
                "recording: path {path}: {}; recording is off",
                e.message
            ));
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_fails_otherwise_than_full_is_left_for_a_new_one() {
        let dir = std::env::temp_dir().join(format!("mavtables-rec-fail-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let pattern =
            FilePattern::parse(&format!("{}/flight.tlog", dir.display())).expect("pattern");
        let mut writer = Writer {
            dir: dir.clone(),
            made: MadeList::open(&pattern, "recording", "recordings"),
            pattern,
            max_file_bytes: 1 << 20,
            max_files: 10,
            min_free_bytes: 0,
            shared: Arc::new(Shared::default()),
            file: None,
            name: None,
            size: 0,
            trouble: None,
            suffixes: made_files::Suffixes::default(),
        };
        let record = [7u8; 20];
        writer.write(&record, &[20]);
        // The handle fails from now on (as one on a card that dropped out would), though
        // the directory is fine.
        let first = dir.join(writer.name.clone().expect("a file"));
        writer.file = Some(File::open(&first).expect("open"));
        writer.write(&record, &[20]);
        writer.write(&record, &[20]);
        let c = writer.shared.counters();
        assert_eq!(
            (read(&c.written), read(&c.dropped_disk), read(&c.files)),
            (2, 1, 2)
        );
        assert_eq!(std::fs::metadata(&first).expect("first").len(), 20);
        writer.close();
        let _ = std::fs::remove_dir_all(&dir);
    }
}
