//! A bounded hand-over of text to a writer thread, so that whoever logs never waits for
//! the reader of the stream. Only whole lines are kept; what does not fit is dropped and
//! counted, and a notice saying how many lines were lost is written where they would
//! have been, as soon as the next line fits.

use std::io::Write;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread;
use std::time::Instant;

/// Makes the line (ending in a newline) that stands in for `n` dropped lines.
pub(super) type Notice = fn(n: u64) -> String;

/// Room kept free for the notice once lines have been dropped (longer than any notice).
const NOTICE_ROOM: usize = 128;

/// One output stream, written by a thread of its own.
pub(super) struct Sink {
    shared: Arc<Shared>,
}

struct Shared {
    state: Mutex<State>,
    /// Signalled when there is text for the writer, or the sink is closed.
    has_text: Condvar,
    /// Signalled when the writer has written everything it was given.
    written: Condvar,
}

/// What the caller and the writer share.
struct State {
    /// Text waiting for the writer: whole lines, at most `capacity` bytes (plus one
    /// notice when draining).
    pending: Vec<u8>,
    capacity: usize,
    /// Lines dropped since the last notice.
    dropped: u64,
    notice: Notice,
    /// The writer is writing a batch it took from `pending`.
    busy: bool,
    /// The writer waits for text (so it is worth waking).
    waiting: bool,
    /// No writer thread could be started: everything is dropped.
    writerless: bool,
    /// The sink was dropped: the writer ends once `pending` is written.
    closed: bool,
}

/// Lines in `text`, a last line without its newline included.
fn count_lines(text: &[u8]) -> u64 {
    let newlines = text.iter().filter(|&&b| b == b'\n').count() as u64;
    let unterminated = text.last().is_some_and(|&b| b != b'\n');
    newlines + u64::from(unterminated)
}

impl State {
    /// Nothing pending yet, room for `capacity` bytes.
    fn new(capacity: usize, notice: Notice) -> Self {
        State {
            pending: Vec::new(),
            capacity,
            dropped: 0,
            notice,
            busy: false,
            waiting: false,
            writerless: false,
            closed: false,
        }
    }

    /// Keeps the lines of `text` that fit (a prefix of them, the notice for earlier drops
    /// in front); returns how many lines were dropped.
    fn accept(&mut self, text: &[u8]) -> u64 {
        let mut room = self.capacity.saturating_sub(self.pending.len());
        if self.dropped > 0 {
            room = room.saturating_sub(NOTICE_ROOM);
        }
        let keep = if self.writerless {
            0
        } else if text.len() <= room {
            text.len()
        } else {
            text[..room]
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1)
        };
        if keep > 0 {
            self.note_drops();
            self.pending.extend_from_slice(&text[..keep]);
        }
        let lost = count_lines(&text[keep..]);
        self.dropped += lost;
        lost
    }

    /// Appends the notice for the lines dropped so far, if any.
    fn note_drops(&mut self) {
        if self.dropped > 0 && !self.writerless {
            let notice = (self.notice)(self.dropped);
            self.pending.extend_from_slice(notice.as_bytes());
            self.dropped = 0;
        }
    }

    fn all_written(&self) -> bool {
        self.pending.is_empty() && !self.busy
    }
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn wake_writer(&self, state: &State) {
        if state.waiting && !state.pending.is_empty() {
            self.has_text.notify_one();
        }
    }
}

impl Sink {
    /// A sink that keeps at most `capacity` bytes waiting for `out`, written by a thread
    /// called `name`. (The batch being written is apart from these: a stuck reader costs
    /// at most twice `capacity`.) If no thread can be started, everything is dropped.
    pub(super) fn start<W: Write + Send + 'static>(
        name: &str,
        capacity: usize,
        out: W,
        notice: Notice,
    ) -> Sink {
        let shared = Arc::new(Shared {
            state: Mutex::new(State::new(capacity, notice)),
            has_text: Condvar::new(),
            written: Condvar::new(),
        });
        let for_writer = Arc::clone(&shared);
        let spawned = thread::Builder::new()
            .name(name.to_string())
            .spawn(move || write_until_closed(&for_writer, out));
        if spawned.is_err() {
            shared.lock().writerless = true;
        }
        Sink { shared }
    }

    /// Hands `text` (lines ending in newlines) to the writer without waiting for it;
    /// returns how many lines did not fit and were dropped.
    pub(super) fn push(&self, text: &[u8]) -> u64 {
        if text.is_empty() {
            return 0;
        }
        let mut state = self.shared.lock();
        let lost = state.accept(text);
        self.shared.wake_writer(&state);
        lost
    }

    /// Queues the notice for lines dropped so far now, not only once the next line fits.
    pub(super) fn note_drops(&self) {
        let mut state = self.shared.lock();
        state.note_drops();
        self.shared.wake_writer(&state);
    }

    /// Waits until everything handed over has been written, or `deadline`; returns
    /// whether it was all written.
    pub(super) fn wait_written(&self, deadline: Instant) -> bool {
        let mut state = self.shared.lock();
        while !state.all_written() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            state = self
                .shared
                .written
                .wait_timeout(state, left)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
        true
    }
}

impl Drop for Sink {
    /// Lets the writer finish what it holds (with the notice for any drops) and end.
    fn drop(&mut self) {
        let mut state = self.shared.lock();
        state.note_drops();
        state.closed = true;
        self.shared.has_text.notify_one();
    }
}

/// The writer thread: takes everything pending at once and writes it, blocking in
/// `write` as long as the reader makes it; only this thread ever waits for the reader.
/// A batch that cannot be written (the reader has gone) counts as dropped.
fn write_until_closed<W: Write>(shared: &Shared, mut out: W) {
    let mut batch = Vec::new();
    loop {
        {
            let mut state = shared.lock();
            while state.pending.is_empty() {
                if state.closed {
                    return;
                }
                state.waiting = true;
                state = shared
                    .has_text
                    .wait(state)
                    .unwrap_or_else(PoisonError::into_inner);
                state.waiting = false;
            }
            std::mem::swap(&mut state.pending, &mut batch);
            state.busy = true;
        }
        let lost = match out.write_all(&batch).and_then(|()| out.flush()) {
            Ok(()) => 0,
            Err(_) => count_lines(&batch),
        };
        batch.clear();
        let mut state = shared.lock();
        state.busy = false;
        state.dropped += lost;
        if state.all_written() {
            shared.written.notify_all();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::sync::mpsc;
    use std::time::Duration;

    fn notice(n: u64) -> String {
        format!("-- {n} dropped\n")
    }

    fn state(capacity: usize) -> State {
        State::new(capacity, notice)
    }

    #[test]
    fn only_whole_lines_are_kept_and_the_notice_comes_before_the_next_kept_line() {
        let mut s = state(NOTICE_ROOM + 12);
        let mut first = vec![b'a'; NOTICE_ROOM + 9];
        first.push(b'\n');
        assert_eq!(s.accept(&first), 0);
        // 2 bytes of room left: nothing of these two lines, the second unterminated.
        assert_eq!(s.accept(b"cc\ndd"), 2);
        assert_eq!(s.dropped, 2);
        s.pending.clear();
        // The notice's room is kept: one 5-byte line fits after it, the next does not.
        assert_eq!(s.accept(b"eeee\nffffffff\n"), 1);
        assert_eq!(s.pending, b"-- 2 dropped\neeee\n");
        assert_eq!(s.dropped, 1);
    }

    #[test]
    fn a_line_longer_than_the_bound_is_dropped_and_later_ones_still_fit() {
        let mut s = state(NOTICE_ROOM + 8);
        assert_eq!(s.accept(&[b'x'; 400]), 1);
        assert_eq!(s.accept(b"ok\n"), 0);
        assert_eq!(s.pending, b"-- 1 dropped\nok\n");
    }

    /// Pushes numbered lines, three to a push, into a pipe nobody reads until 50 pushes in
    /// a row lost all their lines. Returns (line, kept) for every line.
    fn fill(sink: &Sink) -> Vec<(String, bool)> {
        let mut lines = Vec::new();
        let mut lost_in_a_row = 0;
        for push in 0..100_000 {
            let text: Vec<String> = (0..3)
                .map(|i| format!("line {:08}\n", 3 * push + i))
                .collect();
            let lost = sink.push(text.concat().as_bytes());
            let kept = 3 - usize::try_from(lost).expect("at most 3");
            for (i, line) in text.into_iter().enumerate() {
                lines.push((line, i < kept));
            }
            lost_in_a_row = if kept == 0 { lost_in_a_row + 1 } else { 0 };
            if lost_in_a_row == 50 {
                return lines;
            }
        }
        panic!("pushes still fit with a reader that never reads");
    }

    /// What the reader must see: kept lines in order, a notice in place of each gap.
    fn expected(lines: &[(String, bool)]) -> String {
        let (mut out, mut gap) = (String::new(), 0);
        for (line, kept) in lines {
            if *kept {
                if gap > 0 {
                    out.push_str(&notice(gap));
                    gap = 0;
                }
                out.push_str(line);
            } else {
                gap += 1;
            }
        }
        if gap > 0 {
            out.push_str(&notice(gap));
        }
        out
    }

    #[test]
    fn a_stuck_reader_costs_counted_lines_and_the_count_comes_before_later_lines() {
        let (mut reader, writer) = std::io::pipe().expect("pipe");
        let sink = Sink::start("test-log-sink", 4096, writer, notice);
        let mut lines = fill(&sink);
        let dropped = lines.iter().filter(|(_, kept)| !kept).count();
        let last_gap = lines.iter().rev().take_while(|(_, kept)| !kept).count();

        let (done_tx, done_rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut text = String::new();
            let read = reader.read_to_string(&mut text).map(|_| text);
            let _ = done_tx.send(read);
        });
        assert!(
            sink.wait_written(Instant::now() + Duration::from_secs(10)),
            "not written once the reader reads"
        );
        for i in 0..5 {
            let line = format!("after {i}\n");
            assert_eq!(sink.push(line.as_bytes()), 0);
            lines.push((line, true));
        }
        drop(sink);
        let text = done_rx
            .recv_timeout(Duration::from_secs(10))
            .expect("writer did not end")
            .expect("read");
        assert_eq!(text, expected(&lines));
        assert!(dropped >= 150, "only {dropped} lines dropped");
        assert!(text.contains(&format!("-- {last_gap} dropped\nafter 0\n")));
    }

    /// A reader that never takes anything until the test ends.
    struct Stuck(mpsc::Receiver<()>);

    impl Write for Stuck {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            let _ = self.0.recv();
            Err(std::io::ErrorKind::BrokenPipe.into())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn waiting_for_a_stuck_reader_ends_at_the_deadline() {
        let (release, stuck) = mpsc::channel();
        let sink = Sink::start("test-log-stuck", 64, Stuck(stuck), notice);
        assert_eq!(sink.push(b"one\n"), 0);
        let start = Instant::now();
        assert!(!sink.wait_written(start + Duration::from_millis(100)));
        let took = start.elapsed();
        assert!(
            took >= Duration::from_millis(100) && took < Duration::from_secs(5),
            "{took:?}"
        );
        drop(release);
    }
}
