//! The flight log writer: the logs the core puts in order ([`Engine::poll_flight_log`])
//! written by a thread of their own, so that the event loop never waits for a disk.
//!
//! One file per log: created with the log's first bytes (a log that gets none leaves
//! no file; a file left empty by a failed write is removed), named after the time then
//! with the `path` pattern and the protocol's extension (`.bin`, `.ulg`), and closed
//! (synced) at the log's end. Each file is created afresh (never opened if it exists)
//! and put on the list of logs the router created (the recorder's [`MadeList`]); the
//! oldest of that list only are removed beyond `max_files` and while the disk has less
//! than `min_free_bytes` free (the recorder's `rotation` rules). Bytes that do not fit
//! — the queue is full, the disk fails or has no room — are dropped and counted, never
//! packets; each kind of trouble is said once.
//!
//! [`Engine::poll_flight_log`]: crate::routing::Engine::poll_flight_log

use std::collections::HashMap;
use std::fs::{self, File};
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::time::Duration;

use super::log;
use super::made_files::{self, CreateError};
use super::manifest::MadeList;
use super::writer_thread::{self, Behind, WriterThread, add, read};
use crate::config::FlightLog;
use crate::flight_log::{FlightLogStats, LogWrite, Protocol};
use crate::recording::FilePattern;
use crate::recording::rotation;
use crate::routing::Engine;

/// What may wait for the writer: seconds of the fastest log stream.
const QUEUE_BOUND: usize = 16 << 20;
/// The writer takes the queue at least this often.
const WRITE_EVERY: Duration = Duration::from_millis(200);

/// Writes waiting for the writer, and the bytes of data they hold.
#[derive(Default)]
struct Queue {
    items: Vec<LogWrite>,
    bytes: usize,
}

/// The counters both sides add to.
#[derive(Default)]
struct Counters {
    blocks: AtomicU64,
    bytes: AtomicU64,
    files: AtomicU64,
    removed: AtomicU64,
    /// Blocks the writer could not write (the disk failed or had no room).
    dropped: AtomicU64,
    /// Blocks the loop could not queue for the writer (it was behind).
    behind: AtomicU64,
}

/// What the loop and the writer share.
type Shared = writer_thread::Shared<Queue, Counters>;

/// The loop's handle on the writer.
pub(super) struct FlightLogWriter {
    writer: WriterThread<Queue, Counters>,
    config: FlightLog,
    /// Whether blocks are being dropped because the writer is behind (said once).
    behind: Behind,
}

impl FlightLogWriter {
    /// Starts the writer for `config`.
    pub(super) fn start(config: &FlightLog) -> FlightLogWriter {
        let cfg = config.clone();
        let writer = WriterThread::spawn("flight-log", "flight log", move |shared| {
            Writer {
                config: cfg,
                shared,
                lists: HashMap::new(),
                unusable: Vec::new(),
                begun: None,
                file: None,
                trouble: false,
            }
            .run();
        });
        FlightLogWriter {
            writer,
            config: config.clone(),
            behind: Behind::default(),
        }
    }

    /// The configuration it writes for.
    pub(super) fn config(&self) -> &FlightLog {
        &self.config
    }

    /// Queues what the core has for the file.
    pub(super) fn take_from(&mut self, engine: &mut Engine) {
        let shared = self.writer.shared();
        let mut pending = shared.queue();
        let q = &mut pending.queued;
        let mut dropped = 0;
        let mut any = false;
        engine.poll_flight_log(&mut |w| {
            if let LogWrite::Data { bytes, blocks } = &w {
                if q.bytes + bytes.len() > QUEUE_BOUND {
                    dropped += blocks;
                    return;
                }
                q.bytes += bytes.len();
            }
            q.items.push(w);
            any = true;
        });
        if any && q.items.iter().any(|w| !matches!(w, LogWrite::Data { .. })) {
            shared.wake();
        }
        drop(pending);
        add(&shared.counters().behind, dropped);
        self.behind.turn("flight log", "blocks", dropped, any);
    }

    /// The writer's counters, joined with the core's.
    pub(super) fn stats(&self, engine: &Engine) -> FlightLogStats {
        let shared = self.writer.shared();
        let c = shared.counters();
        let (mut stream, streaming) = engine.flight_log_counters().unwrap_or_default();
        // The writer fell behind, whether the core or the loop found it so.
        stream.dropped += read(&c.behind);
        FlightLogStats {
            stream,
            blocks_written: read(&c.blocks),
            bytes_written: read(&c.bytes),
            files: read(&c.files),
            removed: read(&c.removed),
            blocks_dropped_disk: read(&c.dropped),
            streaming,
            current_path: shared.current(),
        }
    }

    /// Lets the writer write what is queued and close its file, waiting at most
    /// `timeout` (a stuck disk cannot hold the exit).
    pub(super) fn finish(&mut self, timeout: Duration) {
        self.writer.finish(timeout, "blocks");
    }
}

/// The list of logs of one extension: its pattern and the files it made.
struct List {
    pattern: FilePattern,
    dir: PathBuf,
    made: MadeList,
    /// The suffixes given under the last file's name.
    suffixes: made_files::Suffixes,
}

/// The file being written.
struct Open {
    file: File,
    ext: &'static str,
    name: String,
    size: u64,
}

struct Writer {
    config: FlightLog,
    shared: Arc<Shared>,
    /// By extension.
    lists: HashMap<&'static str, List>,
    /// Extensions whose path pattern is not valid (said once): nothing is written.
    unusable: Vec<&'static str>,
    /// The log begun, whose file is created with its first bytes.
    begun: Option<Protocol>,
    file: Option<Open>,
    /// Whether blocks are being dropped (said once until writing works again).
    trouble: bool,
}

impl Writer {
    fn run(mut self) {
        let mut batch = Vec::new();
        loop {
            let stop = self.wait(&mut batch);
            for w in batch.drain(..) {
                self.apply(w);
            }
            if stop {
                break;
            }
        }
        self.close();
    }

    /// Waits until writes are due and swaps them into `batch` (emptied); true when the
    /// loop is stopping.
    fn wait(&self, batch: &mut Vec<LogWrite>) -> bool {
        let mut q = self
            .shared
            .wait_due(WRITE_EVERY, |q| q.bytes >= QUEUE_BOUND / 4);
        std::mem::swap(&mut q.queued.items, batch);
        q.queued.bytes = 0;
        q.stop
    }

    fn apply(&mut self, w: LogWrite) {
        match w {
            LogWrite::Begin(p) => {
                self.close();
                self.begun = Some(p);
            }
            LogWrite::Data { bytes, blocks } => self.write(&bytes, blocks),
            LogWrite::End => {
                self.close();
                self.begun = None;
            }
        }
    }

    fn write(&mut self, bytes: &[u8], blocks: u64) {
        let counters = self.shared.counters();
        if self.file.is_none() {
            let Some(p) = self.begun else {
                add(&counters.dropped, blocks);
                return;
            };
            if !self.make_room(p.extension(), bytes.len() as u64) {
                self.dropped(
                    blocks,
                    &"less than min_free_bytes free on the disk even without the older logs",
                );
                return;
            }
            self.open_new(p);
        } else if let Some(ext) = self.file.as_ref().map(|f| f.ext)
            && !self.make_room(ext, bytes.len() as u64)
        {
            self.dropped(
                blocks,
                &"less than min_free_bytes free on the disk even without the older logs",
            );
            return;
        }
        let Some(open) = self.file.as_mut() else {
            add(&self.shared.counters().dropped, blocks);
            return;
        };
        match open.file.write_all(bytes) {
            Ok(()) => {
                open.size += bytes.len() as u64;
                let counters = self.shared.counters();
                add(&counters.blocks, blocks);
                add(&counters.bytes, bytes.len() as u64);
                if self.trouble {
                    self.trouble = false;
                    log::warn(&"flight log: writing again");
                }
            }
            Err(e) => {
                // Cut back to whole blocks: a block cut short would garble the rest.
                // The file is kept otherwise: a new one in the middle of a log would
                // lack the log's beginning (its header and definitions), which readers
                // need.
                if let Err(cut) = open.file.set_len(open.size) {
                    // The torn block stays: nothing more of this log may follow it.
                    log::warn(&format_args!(
                        "flight log: cannot write {} ({e}), nor cut it back to its last whole block ({cut}); the rest of this log is dropped",
                        open.name
                    ));
                    add(&self.shared.counters().dropped, blocks);
                    self.close();
                    self.begun = None;
                    return;
                }
                let what = format!("cannot write {}: {e}", open.name);
                self.dropped(blocks, &what);
            }
        }
    }

    fn dropped(&mut self, blocks: u64, why: &dyn std::fmt::Display) {
        add(&self.shared.counters().dropped, blocks);
        if !self.trouble {
            self.trouble = true;
            log::warn(&format_args!(
                "flight log: {why}; blocks are dropped and counted until it works again"
            ));
        }
    }

    /// The list of `ext`'s logs, read when first needed.
    fn list(&mut self, ext: &'static str) -> Option<&mut List> {
        if self.unusable.contains(&ext) {
            return None;
        }
        if !self.lists.contains_key(ext) {
            let path = self.config.path_pattern(ext, |k| std::env::var(k).ok());
            let pattern = match FilePattern::parse(&path) {
                Ok(p) => p,
                Err(e) => {
                    log::error(&format_args!("flight log: path {path}: {}", e.message));
                    self.unusable.push(ext);
                    return None;
                }
            };
            let dir = PathBuf::from(pattern.dir());
            let made = MadeList::open(&pattern, "flight log", "logs");
            let suffixes = made_files::Suffixes::default();
            self.lists.insert(
                ext,
                List {
                    pattern,
                    dir,
                    made,
                    suffixes,
                },
            );
        }
        self.lists.get_mut(ext)
    }

    /// Removes old logs while the disk would have less than `min_free_bytes` free after
    /// writing `needed` bytes; false if that is not enough.
    fn make_room(&mut self, ext: &'static str, needed: u64) -> bool {
        let min_free = self.config.min_free_bytes;
        if min_free == 0 {
            return true;
        }
        let current = self.file.as_ref().map(|f| f.name.clone());
        let Some(list) = self.list(ext) else {
            return false;
        };
        let _ = fs::create_dir_all(&list.dir);
        let plan = made_files::room_plan(
            &list.dir,
            &mut list.made,
            min_free,
            needed,
            current.as_deref(),
        );
        if !plan.remove.is_empty() {
            self.remove(ext, &plan.remove, "to keep min_free_bytes free");
        }
        plan.enough
    }

    /// Creates the file of a new log in `p`, then removes the oldest beyond `max_files`.
    fn open_new(&mut self, p: Protocol) {
        let ext = p.extension();
        let max_files = self.config.max_files;
        let Some(list) = self.list(ext) else {
            return;
        };
        let (file, name) =
            match made_files::create_new(&list.dir, &list.pattern, &mut list.suffixes) {
                Ok(opened) => opened,
                Err(e) => {
                    let why = match e {
                        CreateError::Failed { path, error } => {
                            format!("cannot create {}: {error}", path.display())
                        }
                        CreateError::AllTaken => "every name of the pattern is taken".to_string(),
                    };
                    // Said once until writing works again (it is tried with each batch).
                    if !std::mem::replace(&mut self.trouble, true) {
                        log::warn(&format_args!(
                            "flight log: {why}; blocks are dropped and counted until it works again"
                        ));
                    }
                    return;
                }
            };
        list.made.add(&name, &file);
        let path = list.dir.join(&name).display().to_string();
        let files = list.made.recordings();
        let excess = rotation::over_count(&files, max_files, Some(&name));
        list.made.save();
        add(&self.shared.counters().files, 1);
        log::warn(&format_args!("flight log: writing {path}"));
        self.shared.set_current(path);
        self.file = Some(Open {
            file,
            ext,
            name,
            size: 0,
        });
        self.remove(ext, &excess, "beyond max_files");
    }

    /// Removes the logs `names` of `ext` and takes them off its list.
    fn remove(&mut self, ext: &'static str, names: &[String], why: &str) {
        if names.is_empty() {
            return;
        }
        let shared = self.shared.clone();
        let Some(list) = self.list(ext) else {
            return;
        };
        made_files::remove(
            &list.dir,
            &mut list.made,
            names,
            why,
            "flight log",
            &shared.counters().removed,
        );
        list.made.save();
    }

    /// Syncs and closes the open file; one left empty (every write failed) is removed.
    fn close(&mut self) {
        let Some(open) = self.file.take() else {
            return;
        };
        let _ = open.file.sync_data();
        if open.size == 0 {
            self.remove(open.ext, std::slice::from_ref(&open.name), "it is empty");
        }
    }
}
