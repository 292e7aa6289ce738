//! The skeleton of a file writer on a thread of its own (the recorder's, the flight
//! log's, the signing state's), so that the event loop never waits for a disk.
//!
//! The loop appends to a queue under one short lock and wakes the writer when it wants
//! the queue taken early; the writer takes the whole queue when it is due, or at the
//! latest after a fixed time. At exit [`WriterThread::finish`] lets the writer write what
//! is queued and close its file, waiting a bounded time for it. Counters both sides add
//! to are atomics, and the path of the file being written sits behind a lock.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use super::log;

/// What waits for the writer: the writer's own kind of queue, and whether the loop is
/// stopping.
#[derive(Default)]
pub(super) struct Pending<Q> {
    /// What the loop queued since the writer last took it.
    pub(super) queued: Q,
    /// Set by the loop at exit: the writer writes what is queued and closes its file.
    pub(super) stop: bool,
}

/// What the loop and the writer share: the queue, the writer's wake-up, whether it has
/// finished, its counters (`C`) and the file it is writing.
#[derive(Default)]
pub(super) struct Shared<Q, C> {
    queue: Mutex<Pending<Q>>,
    wake: Condvar,
    /// Set by the writer when it has closed its last file.
    done: Mutex<bool>,
    done_cv: Condvar,
    counters: C,
    /// The file being written (or the last one).
    current: Mutex<Option<String>>,
}

impl<Q, C> Shared<Q, C> {
    /// The queue, locked (a writer that panicked holding it leaves it usable).
    pub(super) fn queue(&self) -> MutexGuard<'_, Pending<Q>> {
        self.queue.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Wakes the writer to take the queue now.
    pub(super) fn wake(&self) {
        self.wake.notify_one();
    }

    /// The counters both sides add to.
    pub(super) fn counters(&self) -> &C {
        &self.counters
    }

    /// The path of the file being written (or of the last one).
    pub(super) fn current(&self) -> Option<String> {
        self.current
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Says that the writer now writes `path`.
    pub(super) fn set_current(&self, path: String) {
        *self.current.lock().unwrap_or_else(PoisonError::into_inner) = Some(path);
    }

    /// For the writer: waits until the queue is `due`, the loop stops, or `every` has
    /// passed, and returns it locked (to be taken).
    pub(super) fn wait_due(
        &self,
        every: Duration,
        due: impl Fn(&Q) -> bool,
    ) -> MutexGuard<'_, Pending<Q>> {
        self.wake
            .wait_timeout_while(self.queue(), every, |q| !q.stop && !due(&q.queued))
            .unwrap_or_else(PoisonError::into_inner)
            .0
    }

    /// Says that the writer has closed its last file.
    fn signal_done(&self) {
        let mut done = self.done.lock().unwrap_or_else(PoisonError::into_inner);
        *done = true;
        self.done_cv.notify_all();
    }

    /// Waits at most `timeout` for the writer to finish; whether it did.
    fn wait_done(&self, timeout: Duration) -> bool {
        let done = self.done.lock().unwrap_or_else(PoisonError::into_inner);
        *self
            .done_cv
            .wait_timeout_while(done, timeout, |done| !*done)
            .unwrap_or_else(PoisonError::into_inner)
            .0
    }
}

/// The loop's handle on a writer thread.
pub(super) struct WriterThread<Q, C> {
    shared: Arc<Shared<Q, C>>,
    thread: Option<JoinHandle<()>>,
    /// What its messages begin with (`recording`, `flight log`).
    what: &'static str,
}

impl<Q, C> WriterThread<Q, C>
where
    Q: Default + Send + 'static,
    C: Default + Send + Sync + 'static,
{
    /// Starts the thread `name`, which runs `writer` and then says it is done; if it
    /// cannot start, that is said (beginning with `what`) and only the queue is left.
    pub(super) fn spawn(
        name: &str,
        what: &'static str,
        writer: impl FnOnce(Arc<Shared<Q, C>>) + Send + 'static,
    ) -> WriterThread<Q, C> {
        let shared = Arc::new(Shared::default());
        let writer_shared = shared.clone();
        let thread = thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                writer(writer_shared.clone());
                writer_shared.signal_done();
            })
            .map_err(|e| log::error(&format_args!("{what}: cannot start the writer: {e}")))
            .ok();
        WriterThread {
            shared,
            thread,
            what,
        }
    }
}

impl<Q, C> WriterThread<Q, C> {
    /// Whether there is a writer thread to hand work to: it started, and `finish` has
    /// not been called.
    pub(super) fn running(&self) -> bool {
        self.thread.is_some()
    }

    /// What the loop shares with the writer.
    pub(super) fn shared(&self) -> &Shared<Q, C> {
        &self.shared
    }

    /// Lets the writer write what is queued and close its file, waiting at most
    /// `timeout` for it (a stuck disk cannot hold the exit); if it does not finish, says
    /// that the last `items` (`records`, `blocks`, `state`) may be lost.
    pub(super) fn finish(&mut self, timeout: Duration, items: &str) {
        {
            let mut q = self.shared.queue();
            q.stop = true;
            self.shared.wake();
        }
        let Some(thread) = self.thread.take() else {
            return;
        };
        if !self.shared.wait_done(timeout) {
            log::warn(&format_args!(
                "{}: the writer did not finish within {timeout:?}; the last {items} may be lost",
                self.what
            ));
            return;
        }
        let _ = thread.join();
    }
}

/// Whether the loop is dropping items because the writer is behind: said once when it
/// begins, and when it is over with how many were dropped meanwhile.
#[derive(Debug, Default)]
pub(super) struct Behind {
    /// Items dropped since it began, while it lasts.
    dropped: Option<u64>,
}

impl Behind {
    /// After a turn of queueing for the writer of `what` (`recording`, `flight log`):
    /// `dropped` items (`items`: `records`, `blocks`) did not fit, and some were
    /// `queued`.
    pub(super) fn turn(&mut self, what: &str, items: &str, dropped: u64, queued: bool) {
        match (&mut self.dropped, dropped) {
            (None, 0) => {}
            (None, _) => {
                log::warn(&format_args!(
                    "{what}: the writer is behind (a slow disk?); {items} are dropped and counted until it catches up"
                ));
                self.dropped = Some(dropped);
            }
            (Some(n), 0) if queued => {
                log::warn(&format_args!(
                    "{what}: the writer caught up; {n} {items} were dropped"
                ));
                self.dropped = None;
            }
            (Some(n), _) => *n += dropped,
        }
    }
}

/// Adds `n` to `counter`.
pub(super) fn add(counter: &AtomicU64, n: u64) {
    counter.fetch_add(n, Ordering::Relaxed);
}

/// What `counter` holds now.
pub(super) fn read(counter: &AtomicU64) -> u64 {
    counter.load(Ordering::Relaxed)
}
