//! Moving bytes of a byte stream (a serial port, a TCP connection) between a
//! non-blocking reader/writer and the core: bounded reads per turn, and writes that keep
//! a partly written frame to finish first, so a frame is never cut and never dropped
//! halfway while the stream lives.
//!
//! A failed write does not end the stream at once: what the peer sent before it went
//! away may still wait to be read (a peer that sends its last frame and closes makes the
//! next write fail, often before the loop has read that frame). The loss is reported by
//! the next [`StreamIo::receive`] once it has read everything, or by the next
//! [`StreamIo::flush`] if no read came in between.

use std::collections::VecDeque;
use std::io::{self, Read, Write};

use super::driver::Progress;
use crate::routing::{Engine, InterfaceId, Timestamp, Transmit};

/// Bytes read per system call.
const READ_CHUNK: usize = 4096;
/// Reads per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;

/// The bytes in flight of one stream.
pub struct StreamIo {
    buffer: Vec<u8>,
    /// A packet partly written: the rest goes first when the stream takes bytes again.
    partial: Option<(Transmit, usize)>,
    /// Scratch for [`Engine::poll_transmit`].
    next: VecDeque<Transmit>,
    /// A write failed: the stream is lost once what is left to read has been read.
    failed: Option<io::Error>,
}

impl Default for StreamIo {
    fn default() -> Self {
        StreamIo {
            buffer: vec![0; READ_CHUNK],
            partial: None,
            next: VecDeque::with_capacity(1),
            failed: None,
        }
    }
}

impl StreamIo {
    /// Forgets what was in flight (the stream is gone).
    pub fn clear(&mut self) {
        self.partial = None;
        self.failed = None;
    }

    /// True if no frame is partly written.
    pub fn idle(&self) -> bool {
        self.partial.is_none()
    }

    /// Reads what `stream` has (a bounded amount) into the core's interface `id`. End of
    /// stream and errors are reported to the core as a loss, and so is a failed write
    /// once nothing is left to read.
    pub fn receive(
        &mut self,
        stream: &mut impl Read,
        engine: &mut Engine,
        id: InterfaceId,
        now: Timestamp,
    ) -> Progress {
        for _ in 0..READS_PER_TURN {
            match stream.read(&mut self.buffer) {
                Ok(0) => {
                    match self.failed.take() {
                        Some(e) => engine.stream_lost(id, now, &e),
                        None => engine.stream_lost(id, now, &"end of stream"),
                    }
                    return Progress::Lost;
                }
                Ok(n) => engine.handle_stream(id, &self.buffer[..n], now),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    return match self.failed.take() {
                        Some(e) => {
                            engine.stream_lost(id, now, &e);
                            Progress::Lost
                        }
                        None => Progress::Done,
                    };
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    let why = self.failed.take().unwrap_or(e);
                    engine.stream_lost(id, now, &why);
                    return Progress::Lost;
                }
            }
        }
        Progress::More
    }

    /// Writes what the core has for interface `id`, highest priority first, as far as
    /// `stream` takes it. A write error drops the frame being written and stops the
    /// writing; it gives `Blocked`, so that the loop watches the descriptor, whose error
    /// wakes it to read what is left ([`StreamIo::receive`] then reports the loss). If
    /// the loop flushes again without a read in between, the loss is reported here.
    pub fn flush(
        &mut self,
        stream: &mut impl Write,
        engine: &mut Engine,
        id: InterfaceId,
        now: Timestamp,
    ) -> Progress {
        if let Some(e) = self.failed.take() {
            engine.stream_lost(id, now, &e);
            return Progress::Lost;
        }
        loop {
            let (t, done) = match self.partial.take() {
                Some(p) => p,
                None => {
                    engine.poll_transmit(id, now, 1, &mut self.next);
                    match self.next.pop_front() {
                        Some(t) => (t, 0),
                        None => return Progress::Done,
                    }
                }
            };
            match stream.write(&t.packet[done..]) {
                Ok(n) if done + n == t.packet.len() => engine.on_sent(&t),
                Ok(0) => {
                    self.partial = Some((t, done));
                    return Progress::Blocked;
                }
                Ok(n) => self.partial = Some((t, done + n)),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.partial = Some((t, done));
                    return Progress::Blocked;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => self.partial = Some((t, done)),
                Err(e) => {
                    engine.on_send_failed(id, &t, &e);
                    self.failed = Some(e);
                    return Progress::Blocked;
                }
            }
        }
    }
}
