//! One `serial { }` interface: the port (raw 8N1, any baud rate, optional RTS/CTS) as a
//! non-blocking file in the event loop, and its reopening with backoff when it is
//! missing or disappears (USB unplug) — the router never exits because of a link.

use std::fs::File;
use std::io::{self, Read, Write};
use std::time::Duration;

use super::counters::{LinkCounters, LinkReport};
use super::frames::{Source, ToRouter, UnknownIds};
use super::log;
use super::sys;
use crate::config::SerialInterface;
use crate::routing::{LinkId, Output, Packet, Router, Timestamp};
use crate::wire::frame::MAX_FRAME_LEN;
use crate::wire::{Parser, ParserStats};

/// First wait before reopening a missing device; doubled up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_millis(100);
/// Longest wait between reopening attempts.
const MAX_BACKOFF: Duration = Duration::from_secs(2);
/// Bytes read per system call.
const READ_CHUNK: usize = 4096;
/// Reads per wake-up before the loop gets a turn to send.
const READS_PER_TURN: usize = 16;
/// Quiet time (beyond a largest frame's transmission time) after which bytes held back
/// for an incomplete frame are judged.
const STALE_GAP: Duration = Duration::from_millis(100);

/// Whether the device is open.
enum State {
    Open(File),
    Closed {
        /// When to try again.
        retry_at: Timestamp,
        /// The wait after the next failure.
        backoff: Duration,
    },
}

/// A serial interface (one link, named by the device path as written).
pub struct SerialDriver {
    config: SerialInterface,
    link: LinkId,
    state: State,
    parser: Parser,
    /// A packet partly written: the rest goes first when the port takes bytes again.
    partial: Option<(Packet, usize)>,
    counters: LinkCounters,
    buffer: Vec<u8>,
    /// Times the device was lost or could not be opened.
    pub failures: u64,
    /// The port refused bytes: wait for it to become writable (only then is
    /// writability watched, so sending does not wake the loop needlessly).
    pub blocked: bool,
    /// When bytes last arrived.
    last_rx: Timestamp,
}

/// The device's link counters as the source of received frames.
struct Port<'a> {
    link: LinkId,
    counters: &'a mut LinkCounters,
}

impl Source for Port<'_> {
    fn link(&mut self, _router: &mut Router, _now: Timestamp) -> (LinkId, &mut LinkCounters) {
        (self.link, self.counters)
    }

    fn counters(&mut self) -> Option<&mut LinkCounters> {
        Some(self.counters)
    }
}

fn open_port(config: &SerialInterface) -> io::Result<File> {
    let flow = if config.flow_control {
        serialport::FlowControl::Hardware
    } else {
        serialport::FlowControl::None
    };
    let port = serialport::new(&config.device, config.baudrate)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(flow)
        .open_native()
        .map_err(io::Error::other)?;
    // Best effort: most USB-serial adapters and UARTs take it, a pty or a USB CDC device
    // may not, and the port works either way.
    let _ = sys::request_low_latency(&port);
    sys::nonblocking_file(port)
}

impl SerialDriver {
    /// A driver for `config` whose link `link` already exists in the core. The port is
    /// opened by [`SerialDriver::reopen_if_due`].
    pub fn new(config: &SerialInterface, link: LinkId) -> Self {
        SerialDriver {
            config: config.clone(),
            link,
            state: State::Closed {
                retry_at: Timestamp::ZERO,
                backoff: FIRST_BACKOFF,
            },
            parser: Parser::new(),
            partial: None,
            counters: LinkCounters::default(),
            buffer: vec![0; READ_CHUNK],
            failures: 0,
            blocked: false,
            last_rx: Timestamp::ZERO,
        }
    }

    /// The device path.
    pub fn device(&self) -> &str {
        &self.config.device
    }

    /// The link of this port.
    pub fn link(&self) -> LinkId {
        self.link
    }

    /// The open port, to register with the poller.
    pub fn file(&self) -> Option<&File> {
        match &self.state {
            State::Open(f) => Some(f),
            State::Closed { .. } => None,
        }
    }

    /// When the next reopening attempt is due, if the port is closed.
    pub fn retry_at(&self) -> Option<Timestamp> {
        match self.state {
            State::Open(_) => None,
            State::Closed { retry_at, .. } => Some(retry_at),
        }
    }

    /// Parser totals of this port.
    pub fn parser_stats(&self) -> &ParserStats {
        self.parser.stats()
    }

    /// Tries to open the port if it is closed and the wait is over. Returns true when it
    /// has just been opened (the caller registers it with the poller).
    pub fn reopen_if_due(&mut self, now: Timestamp) -> bool {
        let State::Closed { retry_at, backoff } = self.state else {
            return false;
        };
        if now < retry_at {
            return false;
        }
        match open_port(&self.config) {
            Ok(file) => {
                if self.failures > 0 {
                    log::warn(&format_args!(
                        "serial device {} is back",
                        self.config.device
                    ));
                }
                self.state = State::Open(file);
                self.parser.clear();
                true
            }
            Err(e) => {
                // Say it once per outage, not once per attempt.
                if backoff == FIRST_BACKOFF {
                    log::warn(&format_args!(
                        "cannot open serial device {}: {e}; retrying until it appears",
                        self.config.device
                    ));
                    self.failures += 1;
                }
                self.state = State::Closed {
                    retry_at: Timestamp::new(now.since_start() + backoff),
                    backoff: (backoff * 2).min(MAX_BACKOFF),
                };
                false
            }
        }
    }

    /// Closes the port after an error; reopening starts after the first backoff.
    /// Returns the file so the caller can deregister it.
    fn lose(&mut self, now: Timestamp, why: &dyn std::fmt::Display) -> Option<File> {
        log::warn(&format_args!(
            "serial device {} lost: {why}",
            self.config.device
        ));
        self.failures += 1;
        self.parser.clear();
        let old = std::mem::replace(
            &mut self.state,
            State::Closed {
                retry_at: Timestamp::new(now.since_start() + FIRST_BACKOFF),
                backoff: FIRST_BACKOFF * 2,
            },
        );
        match old {
            State::Open(f) => Some(f),
            State::Closed { .. } => None,
        }
    }

    /// Reads what the port has and routes its frames. Returns `Err(file)` when the
    /// device was lost (deregister the file), `Ok(more)` otherwise.
    pub fn receive(
        &mut self,
        router: &mut Router,
        now: Timestamp,
        out: &mut Output,
        unknown: &mut UnknownIds,
    ) -> Result<bool, Option<File>> {
        for _ in 0..READS_PER_TURN {
            let State::Open(file) = &mut self.state else {
                return Ok(false);
            };
            let n = match file.read(&mut self.buffer) {
                Ok(0) => return Err(self.lose(now, &"end of file")),
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(false),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.lose(now, &e)),
            };
            self.last_rx = now;
            let mut events = ToRouter {
                router: &mut *router,
                out: &mut *out,
                now,
                unknown: &mut *unknown,
                link: Port {
                    link: self.link,
                    counters: &mut self.counters,
                },
            };
            self.parser.feed_events(&self.buffer[..n], &mut events);
        }
        Ok(true)
    }

    /// When the parser's held-back bytes count as stale, if it holds any: a sender
    /// writes a frame's bytes back to back, so once the line has been quiet for longer
    /// than a whole largest frame takes at this baud rate (plus 100 ms for USB adapters
    /// that deliver in chunks), an incomplete candidate is not a frame. Noise that looks
    /// like the start of a long frame would otherwise hold up the valid frames behind it
    /// until enough further bytes arrive — seconds on a link that only carries heartbeats.
    pub fn stale_at(&self) -> Option<Timestamp> {
        if self.parser.pending_len() == 0 || self.file().is_none() {
            return None;
        }
        let frame_time = Duration::from_micros(
            MAX_FRAME_LEN as u64 * 10 * 1_000_000 / u64::from(self.config.baudrate.max(1)),
        );
        Some(Timestamp::new(
            self.last_rx.since_start() + STALE_GAP + frame_time,
        ))
    }

    /// Ends a stale candidate ([`SerialDriver::stale_at`]): it is rejected and the bytes
    /// behind its start are scanned again, so the valid frames among them are routed now.
    pub fn finish_stale(
        &mut self,
        router: &mut Router,
        now: Timestamp,
        out: &mut Output,
        unknown: &mut UnknownIds,
    ) {
        if self.stale_at().is_none_or(|t| now < t) {
            return;
        }
        let mut events = ToRouter {
            router,
            out,
            now,
            unknown,
            link: Port {
                link: self.link,
                counters: &mut self.counters,
            },
        };
        self.parser.finish(&mut events);
    }

    /// Writes queued packets, highest priority first, as far as the port takes them.
    /// Returns `Err(file)` when the device was lost.
    pub fn flush(&mut self, router: &mut Router, now: Timestamp) -> Result<(), Option<File>> {
        self.blocked = false;
        loop {
            let State::Open(file) = &mut self.state else {
                return Ok(());
            };
            let (packet, done) = match self.partial.take() {
                Some(p) => p,
                None => match router.pop(self.link) {
                    Some(p) => (p, 0),
                    None => return Ok(()),
                },
            };
            match file.write(&packet[done..]) {
                Ok(n) if done + n == packet.len() => self.counters.sent(packet.len()),
                Ok(n) => {
                    self.partial = Some((packet, done + n));
                    if n == 0 {
                        self.blocked = true;
                        return Ok(());
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.partial = Some((packet, done));
                    self.blocked = true;
                    return Ok(());
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {
                    self.partial = Some((packet, done))
                }
                Err(e) => {
                    // The packet being written is lost with the device.
                    self.counters.send_errors += 1;
                    return Err(self.lose(now, &e));
                }
            }
        }
    }

    /// Notes the queue level, for the high-water mark.
    pub fn note_queue(&mut self, bytes: usize) {
        self.counters.queue_level(bytes);
    }

    /// True if nothing is waiting to be written (or the port is closed: nothing can be).
    pub fn idle(&self, router: &Router) -> bool {
        self.file().is_none() || (self.partial.is_none() && router.peek(self.link).is_none())
    }

    /// This port's counters.
    pub fn report<'a>(&'a self, router: &Router) -> LinkReport<'a> {
        LinkReport {
            name: &self.config.device,
            counters: self.counters,
            queue_drops: router.link(self.link).map_or(0, |l| l.queue().dropped()),
        }
    }
}
