//! The event loop: builds the core and one driver per interface from the configuration,
//! then waits → reads → core → sends → arms the one timer, until SIGINT or SIGTERM; then
//! flushes what is queued (for at most a second) and prints the counters. SIGHUP reads
//! the configuration file again and applies it between two turns ([`apply`]); under
//! systemd the loop tells it so, and feeds its watchdog ([`super::notify`]).
//!
//! One thread, one `epoll` (through `mio`): descriptors are non-blocking and
//! edge-triggered; every driver lives in one slab whose keys are the poll tokens; a
//! `timerfd` wakes the loop for the core's next deadline with microsecond precision.
//! Nothing busy-waits: an idle router sleeps in `epoll_wait`.

use std::collections::VecDeque;
use std::io;
use std::os::fd::{AsRawFd, RawFd};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token, Waker};
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGUSR1, SIGXFSZ};
use signal_hook_mio::v1_0::Signals;
use slab::Slab;

mod apply;

use super::driver::{Driver, Progress};
use super::flight_log::FlightLogWriter;
use super::log::{self, Logger};
use super::notify::Notifier;
use super::recorder::{self, Recorder};
use super::state_file::StateFile;
use super::stats_server::StatsServer;
use super::sys::{self, TimerFd};
use crate::config::Config;
use crate::dialect::DIALECT_NAME;
use crate::recording::{RecordFilter, RecorderStats};
use crate::routing::{CLOSE_FLUSH, Engine, InterfaceId, Notice, Request, RouterOptions, Timestamp};
use crate::signing::SigningKey;
use crate::signing::clock::units_from_unix;

/// Token of the signal pipe (driver tokens are slab keys, far below).
const SIGNALS: Token = Token(usize::MAX - 1);
/// Token of the timer.
const TIMER: Token = Token(usize::MAX - 2);
/// Token of the waker that look-ups of host names ring when they have an answer, and
/// drivers fed by threads (Zenoh) when they have input.
const WAKER: Token = Token(usize::MAX - 3);
/// How long the log output may take to drain at exit.
const LOG_DRAIN: Duration = Duration::from_secs(1);
/// How often a lingering socket is asked whether its peer acknowledged everything
/// (no event says so).
const LINGER_POLL: Duration = Duration::from_millis(10);
/// At most this many sockets linger at once after an error ([`Driver::parting`]);
/// beyond, one is closed at once: a flood of bad requests cannot hold descriptors.
const MAX_PARTING: usize = 64;
/// How long the recorder may take to write its last records and close its file at exit.
const RECORDER_FINISH: Duration = Duration::from_secs(2);

/// A driver and what the loop knows about it.
struct Slot {
    driver: Box<dyn Driver>,
    /// The descriptor registered with the poller, if any.
    registered: Option<RawFd>,
    /// Whether writability is watched (only while the driver is blocked: an idle socket
    /// is always writable, and watching it would wake the loop after every send).
    watching_writes: bool,
    /// Its input may not be drained yet (its turn ended early, or it just opened): it
    /// is in [`Runtime::readable`].
    ready: bool,
    /// It is in [`Runtime::to_flush`].
    flush_queued: bool,
    /// Its open waits for a look-up of its remote (the waker rings): it is in
    /// [`Runtime::opening`].
    opening: bool,
    /// A reload removed its interface: it is flushed until the core closes it
    /// ([`Request::Retire`]); what it reads the core drops. It is in
    /// [`Runtime::retiring`].
    retiring: bool,
    /// Its interface is gone (or the router stops, or its connection ended for an error)
    /// and its sending side is being shut: it only sends what was still to go, and is
    /// read and dropped, until closing loses nothing ([`Driver::linger`]); it is in
    /// [`Runtime::lingering`], and no longer the slot of any interface number.
    lingering: bool,
}

/// Everything the loop owns.
struct Runtime {
    poll: Poll,
    engine: Engine,
    slots: Slab<Slot>,
    /// The slot key of each interface, by interface id.
    slot_of: Vec<usize>,
    /// Slots whose input may not be drained yet, each once (see [`Slot::ready`]).
    readable: VecDeque<usize>,
    /// Slots to flush this turn, each once: interfaces the core names
    /// ([`Engine::poll_ready`]) and descriptors that became writable or failed.
    to_flush: Vec<usize>,
    /// Slots waiting for a look-up of their remote: flushed when the waker rings.
    opening: Vec<usize>,
    /// Slots whose input comes from threads that ring the waker ([`Driver::woken`]):
    /// read when it rings.
    woken: Vec<usize>,
    /// Slots of interfaces a reload removed that still send their queue (see
    /// [`Slot::retiring`]).
    retiring: Vec<usize>,
    /// Slots that linger before they close, each with the time it closes at the latest
    /// (see [`Slot::lingering`]).
    lingering: Vec<(usize, Timestamp)>,
    /// When the lingering slots are asked next whether they may close.
    next_linger_poll: Timestamp,
    timer: TimerFd,
    /// The deadline the timer is armed for (re-armed only when it changes).
    timer_armed: Option<Timestamp>,
    signals: Signals,
    logger: Logger,
    start: Instant,
    /// Where the signing state is saved (only when some interface has a key).
    state_file: Option<StateFile>,
    /// The recorder, when the configuration has a `record` block.
    recorder: Option<Recorder>,
    /// The flight log writer, when the configuration has a `flight_log` block.
    flight_log: Option<FlightLogWriter>,
    /// The statistics endpoint, if configured.
    stats: Option<StatsServer>,
    /// Rung by look-ups of host names; drivers of clients added by a reload get it too.
    waker: Arc<Waker>,
    /// The configuration file SIGHUP reads again (None: command-line endpoints).
    source: Option<String>,
    /// systemd's notification socket, when it started the router.
    notifier: Option<Notifier>,
    /// When the watchdog is fed next (when systemd asked for one).
    next_watchdog: Option<Timestamp>,
    /// Slots whose driver had a deadline when it joined (see [`Driver::deadline`]):
    /// looked at once a second until it has none.
    expiring: Vec<usize>,
    /// When [`Runtime::expiring`] is looked at next (the core's once-a-second tick
    /// wakes the loop by then).
    next_expiry: Timestamp,
    /// Shutting down: nothing is read any more, so no descriptor is watched
    /// level-triggered (see [`Driver::level_triggered`]).
    stopping: bool,
}

impl Runtime {
    fn now(&self) -> Timestamp {
        Timestamp::new(self.start.elapsed())
    }

    /// Tells the core the wall clock, for signature timestamps (when it signs).
    fn tell_wall_clock(&mut self, now: Timestamp) {
        // Whenever some interface has a key, whether or not its state can be saved.
        if self.engine.has_signing_keys() {
            self.engine.set_wall_clock(now, wall_clock());
        }
    }

    /// Publishes a statistics snapshot to the endpoint (the core says when: once a
    /// second, with its tick).
    fn publish_stats(&mut self, now: Timestamp) {
        let Some(server) = &self.stats else {
            return;
        };
        let mut snapshot = self.engine.stats(now);
        snapshot.recording = self.recorder_stats();
        snapshot.flight_log = self.flight_log.as_ref().map(|w| w.stats(&self.engine));
        server.publish(snapshot);
    }

    /// Writes the signing state a last time, marked as written at a clean exit.
    fn save_signing_state_at_exit(&mut self) {
        if let Some(file) = self.state_file.take() {
            let last = self.engine.signing_state(true, self.now());
            file.finish(last.as_ref());
        }
    }

    /// Hands the frames the core kept for recording to the recorder, stamped with the
    /// wall clock.
    #[inline]
    fn record(&mut self) {
        if self.recorder.is_some() {
            self.hand_to_recorder();
        }
    }

    #[inline(never)]
    fn hand_to_recorder(&mut self) {
        let now = self.now();
        if let Some(recorder) = &mut self.recorder {
            recorder.take_from(&mut self.engine, now, wall_micros());
        }
    }

    /// Hands the flight log's ordered bytes to its writer.
    #[inline]
    fn write_flight_log(&mut self) {
        if self.flight_log.is_some() {
            self.hand_to_flight_log();
        }
    }

    #[inline(never)]
    fn hand_to_flight_log(&mut self) {
        if let Some(writer) = &mut self.flight_log {
            writer.take_from(&mut self.engine);
        }
    }

    /// Closes the flight log (at exit): the stop request was sent with the last frames.
    fn finish_flight_log(&mut self) {
        self.write_flight_log();
        if let Some(writer) = &mut self.flight_log {
            writer.finish(RECORDER_FINISH);
        }
    }

    /// The recorder's counters, when the router records.
    fn recorder_stats(&self) -> Option<RecorderStats> {
        let recorder = self.recorder.as_ref()?;
        Some(recorder.stats(self.engine.recording_dropped()))
    }

    /// The counters report: the core's, and the recorder's line.
    fn report(&self) -> String {
        let mut text = self.engine.report();
        if let Some(stats) = self.recorder_stats() {
            text.push_str(&format!("  {stats}\n"));
        }
        if let Some(writer) = &self.flight_log {
            text.push_str(&format!("  {}\n", writer.stats(&self.engine)));
        }
        text
    }

    /// Records the last frames and closes the recording (at exit).
    fn finish_recording(&mut self) {
        self.record();
        if let Some(recorder) = &mut self.recorder {
            recorder.finish(RECORDER_FINISH);
        }
    }

    /// Watches `key`'s descriptor with the interest it needs now.
    fn watch(&mut self, key: usize) {
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        let fd = slot.driver.fd();
        let registry = self.poll.registry();
        let interest = if slot.watching_writes {
            Interest::READABLE | Interest::WRITABLE
        } else {
            Interest::READABLE
        };
        let mut result = match (slot.registered, fd) {
            (Some(old), Some(fd)) if old == fd => {
                registry.reregister(&mut SourceFd(&fd), Token(key), interest)
            }
            (_, Some(fd)) => registry.register(&mut SourceFd(&fd), Token(key), interest),
            (_, None) => Ok(()),
        };
        // Not while stopping: nothing is read then, and input left waiting would make
        // every wait return at once.
        if let (Ok(()), Some(fd)) = (&result, fd)
            && slot.driver.level_triggered()
            && !self.stopping
        {
            result =
                sys::watch_level_triggered(self.poll.as_raw_fd(), fd, key, slot.watching_writes);
        }
        slot.registered = fd;
        if let Err(e) = result {
            log::error(&format_args!("cannot watch a descriptor: {e}"));
        }
    }

    /// Stops watching `key` and closes its device (it was lost).
    fn close(&mut self, key: usize) {
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        if let Some(fd) = slot.registered.take() {
            let _ = self.poll.registry().deregister(&mut SourceFd(&fd));
        }
        slot.driver.close();
        slot.ready = false;
        slot.watching_writes = false;
    }

    /// Slot `key`'s driver reported its device lost: it is closed now, or, if it still
    /// has something to tell its peer ([`Driver::parting`]) and fewer than
    /// [`MAX_PARTING`] sockets linger, once that is out (for [`CLOSE_FLUSH`] at most).
    #[cold]
    #[inline(never)]
    fn lost(&mut self, key: usize) {
        if self.lingering.len() < MAX_PARTING
            && self.slots.get(key).is_some_and(|s| s.driver.parting())
        {
            let until = self.now() + CLOSE_FLUSH;
            if self.begin_linger(key, until) {
                return;
            }
        }
        self.close(key);
    }

    /// Reads `key` this turn (again).
    fn mark_readable(&mut self, key: usize) {
        if let Some(slot) = self.slots.get_mut(key)
            && !slot.ready
        {
            slot.ready = true;
            self.readable.push_back(key);
        }
    }

    /// Flushes `key` this turn.
    fn mark_flush(&mut self, key: usize) {
        if let Some(slot) = self.slots.get_mut(key)
            && !slot.flush_queued
        {
            slot.flush_queued = true;
            self.to_flush.push(key);
        }
    }

    /// Reads every slot that may have input, each once: a slot whose turn ended with
    /// input left is read again next turn (it is queued behind the others).
    fn receive_readable(&mut self, now: Timestamp) {
        for _ in 0..self.readable.len() {
            let Some(key) = self.readable.pop_front() else {
                break;
            };
            match self.slots.get_mut(key) {
                Some(slot) if slot.ready => slot.ready = false,
                _ => continue,
            }
            self.receive(key, now);
        }
    }

    fn receive(&mut self, key: usize, now: Timestamp) {
        // A lingering slot is read by `end_lingering`.
        let Some(slot) = self.slots.get_mut(key).filter(|s| !s.lingering) else {
            return;
        };
        let progress = slot.driver.receive(&mut self.engine, now);
        if let Some(id) = self.engine.direct_interface() {
            self.send_direct(id, now);
        }
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        let mut accepted = Vec::new();
        while let Some(driver) = slot.driver.take_accepted() {
            accepted.push(driver);
        }
        match progress {
            Progress::More => self.mark_readable(key),
            Progress::Lost => self.lost(key),
            Progress::Done | Progress::Blocked => {}
        }
        // A connection that closed is taken out of the loop now, before another one
        // can be accepted under its (reused) interface number.
        self.handle_notices(now);
        for driver in accepted {
            // Bytes may have arrived with the connection: read at once.
            self.add(driver, true);
        }
    }

    /// Puts `driver` in the loop and watches its descriptor.
    fn add(&mut self, driver: Box<dyn Driver>, ready: bool) {
        let interface = driver.interface();
        let woken = driver.woken();
        let key = self.slots.insert(Slot {
            driver,
            registered: None,
            watching_writes: false,
            ready: false,
            flush_queued: false,
            opening: false,
            retiring: false,
            lingering: false,
        });
        if self.slot_of.len() <= interface.0 {
            self.slot_of.resize(interface.0 + 1, usize::MAX);
        }
        self.slot_of[interface.0] = key;
        if self.slots[key].driver.deadline().is_some() {
            self.expiring.push(key);
        }
        if woken {
            self.woken.push(key);
        }
        self.watch(key);
        if ready {
            self.mark_readable(key);
        }
    }

    /// Takes the driver of a closed connection out of the loop.
    fn remove(&mut self, interface: InterfaceId) {
        let Some(key) = self
            .slot_of
            .get_mut(interface.0)
            .map(|k| std::mem::replace(k, usize::MAX))
        else {
            return;
        };
        // A reload's removed interface ends cleanly, whether its queue went out or its
        // time ran out.
        if self.slots.get(key).is_some_and(|s| s.retiring) {
            let until = self.now() + CLOSE_FLUSH;
            if self.begin_linger(key, until) {
                return;
            }
        }
        self.drop_slot(key);
    }

    /// Closes slot `key` and takes it out of the loop.
    fn drop_slot(&mut self, key: usize) {
        self.close(key);
        self.slots.try_remove(key);
        self.woken.retain(|&k| k != key);
    }

    /// Shuts the sending side of slot `key`'s driver and lets it linger (until `until`
    /// at the latest) before it closes, if it is a stream (see [`Driver::shut_write`]);
    /// false if it is not. Its interface number is no longer its: what is read is
    /// dropped without the core.
    fn begin_linger(&mut self, key: usize, until: Timestamp) -> bool {
        let Some(slot) = self.slots.get_mut(key).filter(|s| !s.lingering) else {
            return false;
        };
        if !slot.driver.shut_write() {
            return false;
        }
        slot.lingering = true;
        let id = slot.driver.interface();
        if self.slot_of.get(id.0) == Some(&key) {
            self.slot_of[id.0] = usize::MAX;
        }
        self.woken.retain(|&k| k != key);
        self.lingering.push((key, until));
        true
    }

    /// Closes the lingering slots for which closing loses nothing any more, or whose time
    /// is up.
    fn end_lingering(&mut self, now: Timestamp) {
        if self.lingering.is_empty() || now < self.next_linger_poll {
            return;
        }
        self.next_linger_poll = now + LINGER_POLL;
        let mut lingering = std::mem::take(&mut self.lingering);
        lingering.retain(|&(key, until)| {
            let Some(slot) = self.slots.get_mut(key).filter(|s| s.lingering) else {
                return false;
            };
            if now < until && !slot.driver.linger() {
                return true;
            }
            self.drop_slot(key);
            false
        });
        self.lingering.append(&mut lingering);
    }

    /// Flushes the driver of `interface`, which a reload removed, until the core closes
    /// it ([`Request::Retire`]). It is still read: the core drops what it gets, and a
    /// socket closed with unread input would be reset, losing what it had just sent.
    fn retire(&mut self, interface: InterfaceId) {
        let Some(&key) = self.slot_of.get(interface.0) else {
            return;
        };
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        slot.retiring = true;
        self.retiring.push(key);
        self.mark_flush(key);
    }

    /// Has the core close the retiring interfaces whose driver has nothing in flight
    /// (nor the core anything queued for them); those closed leave the list.
    fn close_drained(&mut self) {
        if self.retiring.is_empty() {
            return;
        }
        let mut keys = std::mem::take(&mut self.retiring);
        keys.retain(|&key| {
            let Some(slot) = self.slots.get(key).filter(|s| s.retiring && !s.lingering) else {
                return false;
            };
            let id = slot.driver.interface();
            if slot.driver.idle() {
                self.engine.close_if_drained(id);
            }
            self.engine.is_retiring(id)
        });
        self.retiring.append(&mut keys);
    }

    /// True if `error` says a port is taken, and it is `port`, held by a retiring UDP
    /// socket, which is closed now (what it had queued dropped): try again.
    fn freed_port(&mut self, error: &io::Error, port: Option<u16>, now: Timestamp) -> bool {
        error.kind() == io::ErrorKind::AddrInUse
            && port.is_some_and(|port| self.close_retiring_on(port, now))
    }

    /// Closes the retiring interfaces whose UDP socket holds local `port` now, what
    /// they had queued dropped (a new socket needs the port). True if there was one.
    fn close_retiring_on(&mut self, port: u16, now: Timestamp) -> bool {
        let holders: Vec<InterfaceId> = (self.retiring.iter())
            .filter_map(|&key| self.slots.get(key))
            .filter(|s| s.retiring && s.driver.udp_port() == Some(port))
            .map(|s| s.driver.interface())
            .collect();
        for &id in &holders {
            self.engine.close_retiring(id);
        }
        // Their slots leave the loop before any interface number is used again.
        self.handle_notices(now);
        !holders.is_empty()
    }

    /// Sends what the drivers with something to send can send now — the interfaces the
    /// core names, the descriptors that became writable or failed, and after the waker
    /// rang the drivers waiting for a look-up — and watches writability exactly where
    /// the operating system refused data. Idle drivers are not visited.
    fn flush_ready(&mut self, now: Timestamp) {
        // Flushing can name more (a client that bound its socket and opened): a few
        // rounds; what is named after them is flushed next turn (the poll does not
        // wait then).
        for _ in 0..4 {
            while let Some(id) = self.engine.poll_ready() {
                if let Some(&key) = self.slot_of.get(id.0) {
                    self.mark_flush(key);
                }
            }
            if self.to_flush.is_empty() {
                return;
            }
            let mut keys = std::mem::take(&mut self.to_flush);
            for &key in &keys {
                if let Some(slot) = self.slots.get_mut(key) {
                    slot.flush_queued = false;
                    self.flush(key, now);
                }
            }
            keys.clear();
            if self.to_flush.is_empty() {
                self.to_flush = keys;
            }
        }
    }

    /// Flushes the drivers waiting for a look-up (the waker rang); those that got their
    /// descriptor stop waiting.
    fn flush_opening(&mut self) {
        let opening = std::mem::take(&mut self.opening);
        for key in opening {
            match self.slots.get_mut(key) {
                Some(slot) if slot.opening && slot.driver.fd().is_none() => {
                    if slot.driver.woken() {
                        // Read at every ring: its `receive` hears how the opening went.
                        slot.opening = false;
                    } else {
                        self.opening.push(key);
                    }
                    self.mark_flush(key);
                }
                Some(slot) => slot.opening = false,
                None => {}
            }
        }
    }

    /// Sends what driver `key` can send now.
    fn flush(&mut self, key: usize, now: Timestamp) {
        // A lingering slot sends nothing: its interface number may be another's now.
        let Some(slot) = self.slots.get_mut(key).filter(|s| !s.lingering) else {
            return;
        };
        let progress = slot.driver.flush(&mut self.engine, now);
        self.after_send(key, progress);
    }

    /// Has the driver of interface `id` send the packet the core holds for a direct send
    /// at once (before anything else of the turn), or the core queue it if the driver
    /// cannot.
    fn send_direct(&mut self, id: InterfaceId, now: Timestamp) {
        let key = self.slot_of.get(id.0).copied().unwrap_or(usize::MAX);
        let progress = self
            .slots
            .get_mut(key)
            .and_then(|slot| slot.driver.send_now(&mut self.engine, now));
        match progress {
            Some(progress) => self.after_send(key, progress),
            None => self.engine.queue_direct(),
        }
    }

    /// Acts on how a send of `key`'s driver went: a lost device is closed, and
    /// writability is watched exactly while the operating system refuses data.
    fn after_send(&mut self, key: usize, progress: Progress) {
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        if progress == Progress::Lost {
            self.lost(key);
            return;
        }
        let blocked = progress == Progress::Blocked;
        // A client that has just resolved its remote has a descriptor to watch.
        let fd_changed = slot.driver.fd() != slot.registered;
        if fd_changed || (blocked != slot.watching_writes && slot.registered.is_some()) {
            slot.watching_writes = blocked;
            self.watch(key);
        }
    }

    /// Acts on the core's notices: log lines, warnings, and streams to open. Most turns
    /// have none: that check is all a frame's turn runs of it (the rest stays out of the
    /// frame's path and its instruction cache lines).
    #[inline]
    fn handle_notices(&mut self, now: Timestamp) {
        if self.engine.has_notices() {
            self.act_on_notices(now);
        }
    }

    #[inline(never)]
    fn act_on_notices(&mut self, now: Timestamp) {
        while let Some(notice) = self.engine.poll_event() {
            match notice {
                Notice::Log(event) => self.logger.event(&event),
                Notice::Warning(text) => log::warn(&text),
                Notice::Error(text) => log::error(&text),
                Notice::UnknownId(id) => log::stderr_text(&format!(
                    "Packet ID (#{id}) is not part of the '{DIALECT_NAME}' MAVLink dialect.\n"
                )),
                Notice::LinkAdded { .. } | Notice::LinkRemoved { .. } => {}
                // Nothing is opened while stopping (it would only be closed again).
                Notice::Open(interface) if !self.stopping => self.open(interface, now),
                Notice::Open(_) => {}
                Notice::Closed(interface) => self.remove(interface),
                Notice::PublishStats => self.publish_stats(now),
                Notice::SaveSigningState(state) => {
                    if let Some(file) = &self.state_file {
                        file.save(&state);
                    }
                }
            }
        }
    }

    fn open(&mut self, interface: InterfaceId, now: Timestamp) {
        let Some(&key) = self.slot_of.get(interface.0) else {
            return;
        };
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        let mut opened = slot.driver.open(&mut self.engine, now);
        // A UDP client's fixed port still held by the socket a reload retired.
        let port = slot.driver.udp_port();
        if let Err(e) = &opened
            && self.freed_port(e, port, now)
        {
            let Some(slot) = self.slots.get_mut(key) else {
                return;
            };
            opened = slot.driver.open(&mut self.engine, now);
        }
        let Some(slot) = self.slots.get_mut(key) else {
            return;
        };
        match opened {
            Ok(true) => {
                self.engine.stream_opened(interface, now);
                slot.watching_writes = false;
                self.watch(key);
                // Bytes may already be waiting; an edge may have been missed.
                self.mark_readable(key);
            }
            Ok(false) => {
                // Connecting: writable (or an error) says how it went; without a
                // descriptor yet, the waker says the look-up has its answer.
                slot.watching_writes = true;
                if slot.driver.fd().is_none() && !slot.opening {
                    slot.opening = true;
                    self.opening.push(key);
                }
                self.watch(key);
            }
            Err(e) => self.engine.stream_open_failed(interface, now, &e),
        }
    }

    /// Gives the drivers whose deadline has passed their [`Driver::expire`] (once a
    /// second); those left without a deadline stop being looked at.
    fn expire(&mut self, now: Timestamp) {
        if self.expiring.is_empty() || now < self.next_expiry {
            return;
        }
        self.next_expiry = now + Duration::from_secs(1);
        let mut keys = std::mem::take(&mut self.expiring);
        keys.retain(|&key| {
            let Some(slot) = self.slots.get_mut(key) else {
                return false;
            };
            match slot.driver.deadline() {
                Some(due) if now >= due => match slot.driver.expire(&mut self.engine, now) {
                    Progress::Lost => {
                        self.lost(key);
                        // A client gave up an attempt: it is made again, and watched again.
                        self.slots
                            .get(key)
                            .is_some_and(|s| s.driver.deadline().is_some())
                    }
                    // It wants to be read again (a listener that was refused a
                    // connection tries once more).
                    Progress::More => {
                        self.mark_readable(key);
                        true
                    }
                    _ => true,
                },
                Some(_) => true,
                None => false,
            }
        });
        self.expiring.extend(keys);
    }

    /// Feeds systemd's watchdog when it is due (at half its interval): from the loop's
    /// own turn, so a loop that is stuck is restarted.
    fn feed_watchdog(&mut self, now: Timestamp) {
        let Some(due) = self.next_watchdog else {
            return;
        };
        if now >= due {
            self.feed_watchdog_now(now);
        }
    }

    /// Feeds systemd's watchdog now (when it asked for one): before and between the
    /// bounded waits of a reload (for the writers of files it replaces), which together
    /// may take longer than half the watchdog's interval.
    pub(super) fn feed_watchdog_now(&mut self, now: Timestamp) {
        let (Some(notifier), Some(_)) = (&self.notifier, self.next_watchdog) else {
            return;
        };
        notifier.watchdog();
        let interval = notifier
            .watchdog_interval()
            .unwrap_or(Duration::from_secs(1));
        self.next_watchdog = Some(now + interval);
    }

    /// Arms the timer for the core's next deadline (or the watchdog's, if earlier) —
    /// only when it is earlier than the time the timer is armed for: a timer that fires
    /// before the deadline wakes a turn that finds nothing due and re-arms (handling
    /// timeouts early is harmless), which costs less than a `timerfd_settime` every
    /// time a deadline moves later (held-back bytes, with every datagram).
    fn arm_timer(&mut self, now: Timestamp) {
        let mut due = self.engine.poll_timeout();
        if let Some(watchdog) = self.next_watchdog {
            due = due.min(watchdog);
        }
        if !self.lingering.is_empty() {
            due = due.min(self.next_linger_poll.max(now));
        }
        if self.timer_armed.is_none_or(|armed| due < armed) {
            self.timer_armed = Some(due);
            if let Err(e) = self.timer.set(Some(due.saturating_since(now))) {
                log::error(&format_args!("timer: {e}"));
            }
        }
    }

    /// Watches every level-triggered descriptor edge-triggered again: at shutdown
    /// nothing is read, and input left waiting would make every wait return at once.
    fn stop_reading(&mut self) {
        self.stopping = true;
        let keys: Vec<usize> = self
            .slots
            .iter()
            .filter(|(_, s)| s.driver.level_triggered() && s.registered.is_some())
            .map(|(key, _)| key)
            .collect();
        for key in keys {
            self.watch(key);
        }
    }

    fn idle(&self) -> bool {
        self.lingering.is_empty()
            && self
                .slots
                .iter()
                .all(|(_, s)| s.driver.idle() && self.engine.is_idle(s.driver.interface()))
    }

    /// At shutdown, lets each stream that has sent all that was queued for it linger
    /// (until `until`) rather than be closed at exit, when a peer that still sends would
    /// have it reset (see [`Driver::shut_write`]).
    fn linger_sent(&mut self, until: Timestamp) {
        let sent: Vec<usize> = (self.slots.iter())
            .filter(|(_, s)| {
                !s.lingering
                    && s.registered.is_some()
                    && s.driver.idle()
                    && self.engine.is_idle(s.driver.interface())
            })
            .map(|(key, _)| key)
            .collect();
        for key in sent {
            self.begin_linger(key, until);
        }
    }

    fn run(&mut self) -> io::Result<()> {
        let mut events = Events::with_capacity(256);
        let mut stop_by: Option<Timestamp> = None;
        let now = self.now();
        self.feed_watchdog(now);
        self.engine.handle_timeout(now);
        self.handle_notices(now);
        self.publish_stats(now);
        self.arm_timer(now);
        self.logger.flush();
        loop {
            let timeout = if !self.readable.is_empty()
                || !self.to_flush.is_empty()
                || self.engine.has_ready()
            {
                Some(Duration::ZERO)
            } else {
                stop_by.map(|t| t.saturating_since(self.now()))
            };
            if let Err(e) = self.poll.poll(&mut events, timeout) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            let now = self.now();
            let mut reload = false;
            for event in events.iter() {
                match event.token() {
                    SIGNALS => {
                        for signal in self.signals.pending() {
                            if signal == SIGUSR1 {
                                log::stderr_text(&self.report());
                            } else if signal == SIGHUP {
                                reload = true;
                            } else if stop_by.is_none() {
                                stop_by = Some(now + CLOSE_FLUSH);
                                self.stop_reading();
                                // The stop request goes out with the last frames.
                                self.engine.stop_flight_log(now);
                                if let Some(notifier) = &self.notifier {
                                    notifier.stopping();
                                }
                            }
                        }
                    }
                    // A look-up has its answer (the drivers' flush takes it below), or
                    // a driver fed by threads has input.
                    WAKER => {
                        self.flush_opening();
                        for i in 0..self.woken.len() {
                            let key = self.woken[i];
                            self.mark_readable(key);
                        }
                    }
                    TIMER => {
                        self.timer.acknowledge();
                        // Fired: whatever is due next is armed afresh.
                        self.timer_armed = None;
                    }
                    Token(key) => {
                        if event.is_readable() || event.is_error() || event.is_read_closed() {
                            self.mark_readable(key);
                        }
                        // A blocked driver can write again, a connection was made or
                        // failed, or a failed write waits to be reported.
                        if event.is_writable() || event.is_error() || event.is_write_closed() {
                            self.mark_flush(key);
                        }
                    }
                }
            }
            if reload && stop_by.is_none() {
                // Between two turns: nothing is half-routed, and what is read next is
                // judged by the new rules only.
                self.reload(now);
            }
            if stop_by.is_none() {
                self.receive_readable(now);
                // What was just routed goes out before the turn's bookkeeping, which
                // would otherwise add to every frame's latency.
                self.flush_ready(now);
            }
            self.tell_wall_clock(now);
            self.feed_watchdog(now);
            if now >= self.engine.poll_timeout() {
                self.engine.handle_timeout(now);
            }
            self.expire(now);
            self.handle_notices(now);
            self.record();
            self.write_flight_log();
            self.flush_ready(now);
            self.close_drained();
            self.handle_notices(now);
            if let Some(deadline) = stop_by {
                self.linger_sent(deadline);
            }
            self.end_lingering(now);
            self.arm_timer(now);
            self.logger.flush();
            if let Some(deadline) = stop_by {
                for key in self.readable.drain(..) {
                    if let Some(slot) = self.slots.get_mut(key) {
                        slot.ready = false;
                    }
                }
                if self.idle() || now >= deadline {
                    return Ok(());
                }
            }
        }
    }
}

/// Runs the router for `config`, with `keys` (the signing key of each of its interfaces,
/// in order) and log level `loglevel`, until SIGINT or SIGTERM; SIGHUP reads `source`
/// (the configuration file `config` came from; `None` for command-line endpoints) again.
/// Returns the process exit status: 0 after a clean shutdown, 1 if it could not start
/// (a UDP port that cannot be bound; serial devices are retried instead).
pub fn run(config: &Config, keys: &[Option<SigningKey>], loglevel: u8, source: Option<&str>) -> u8 {
    let status = match start(config, keys, loglevel, source) {
        Ok(mut rt) => {
            if let Some(notifier) = &rt.notifier {
                notifier.ready();
            }
            let result = rt.run();
            rt.save_signing_state_at_exit();
            rt.finish_recording();
            rt.finish_flight_log();
            rt.handle_notices(rt.now());
            rt.logger.flush();
            log::stderr_text(&rt.report());
            match result {
                Ok(()) => 0,
                Err(e) => {
                    log::error(&format_args!("event loop: {e}"));
                    1
                }
            }
        }
        Err(e) => {
            log::error(&e);
            1
        }
    };
    log::drain(LOG_DRAIN);
    status
}

/// The routing core's options for `config` at `loglevel`: its defaults, with the queue
/// bounds the configuration sets.
fn options(config: &Config, loglevel: u8) -> RouterOptions {
    let defaults = RouterOptions::default();
    RouterOptions {
        event_level: loglevel,
        queue_capacity: config.queue.link_bytes.unwrap_or(defaults.queue_capacity),
        total_queue_capacity: config
            .queue
            .total_bytes
            .unwrap_or(defaults.total_queue_capacity),
        ..defaults
    }
}

/// The wall clock in microseconds since the UNIX epoch.
fn wall_micros() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// Catches SIGXFSZ (a file-size limit reached), so that a write beyond the limit fails
/// with an error, which the writer of `what` handles, instead of ending the process.
/// Once per process: each writer a reload starts calls it, and a registration is never
/// undone.
fn catch_file_size_signal(what: &str) {
    static CAUGHT: std::sync::Once = std::sync::Once::new();
    CAUGHT.call_once(|| {
        let caught = Arc::new(std::sync::atomic::AtomicBool::new(false));
        if let Err(e) = signal_hook::flag::register(SIGXFSZ, caught) {
            log::warn(&format_args!("{what}: cannot catch SIGXFSZ: {e}"));
        }
    });
}

/// Starts the flight log writer when `config` has a `flight_log` block.
pub(super) fn start_flight_log(config: &Config) -> Option<FlightLogWriter> {
    let log = config.flight_log.as_ref()?;
    catch_file_size_signal("flight log");
    Some(FlightLogWriter::start(log))
}

/// Starts recording when `config` has a `record` block: the core keeps the frames, the
/// recorder writes them. A file-size limit (`RLIMIT_FSIZE`) then makes a write fail
/// rather than end the process: SIGXFSZ is caught.
fn start_recording(config: &Config, engine: &mut Engine) -> Option<Recorder> {
    let record = config.record.as_ref()?;
    catch_file_size_signal("recording");
    let recorder = recorder::start(record)?;
    engine.set_recording(RecordFilter::new(record.only.clone()));
    Some(recorder)
}

/// The wall clock in signature time (10 µs units since 2015-01-01 UTC).
fn wall_clock() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, units_from_unix)
}

/// Starts the statistics endpoint when `config` has a `stats` block.
fn start_stats(config: &Config) -> io::Result<Option<StatsServer>> {
    let Some(endpoint) = &config.stats else {
        return Ok(None);
    };
    let server = StatsServer::start(endpoint).map_err(|e| {
        io::Error::new(
            e.kind(),
            format!(
                "stats: cannot listen on {}: {e}",
                std::net::SocketAddr::new(endpoint.address, endpoint.port)
            ),
        )
    })?;
    log::stderr_text(&format!(
        "statistics on http://{}/ (/metrics, /stats)\n",
        server.address()
    ));
    Ok(Some(server))
}

/// Opens the signing state file (when some interface has a key) and gives the core what
/// it saved, telling it the wall clock as read at `now`; an error when something other
/// than a state file is at its path.
fn open_state_file(
    config: &Config,
    engine: &mut Engine,
    now: Timestamp,
) -> io::Result<Option<StateFile>> {
    if !engine.has_signing_keys() {
        return Ok(None);
    }
    let Some(path) = config.signing_state_path(|k| std::env::var(k).ok()) else {
        return Ok(None);
    };
    let (file, saved) = StateFile::open(path.clone())
        .map_err(|e| io::Error::other(format!("signing state file {} {e}", path.display())))?;
    engine.set_wall_clock(now, wall_clock());
    if let Some(state) = saved {
        engine.restore_signing_state(&state);
    }
    Ok(Some(file))
}

fn start(
    config: &Config,
    keys: &[Option<SigningKey>],
    loglevel: u8,
    source: Option<&str>,
) -> io::Result<Runtime> {
    // First: from here on a signal waits for the loop instead of acting at once (a
    // SIGHUP would otherwise end the process while it opens its interfaces).
    let mut signals = Signals::new([SIGINT, SIGTERM, SIGUSR1, SIGHUP])?;
    let poll = Poll::new()?;
    let mut engine = Engine::new(config, options(config, loglevel));
    let logger = Logger::new(loglevel);
    let start = Instant::now();
    let waker = Arc::new(Waker::new(poll.registry(), WAKER)?);
    // The same path as a reload, from no interfaces: serial links first, in file order
    // (the original's link order), then the others.
    let mut drivers: Vec<Box<dyn Driver>> = Vec::new();
    for request in engine.configure(config, keys, Timestamp::ZERO).requests {
        if let Request::Open(id, iface) = request {
            drivers.push(apply::driver_for(&iface, id, &waker)?);
        }
    }
    let timer = TimerFd::new()?;
    poll.registry()
        .register(&mut SourceFd(&timer.as_raw_fd()), TIMER, Interest::READABLE)?;
    poll.registry()
        .register(&mut signals, SIGNALS, Interest::READABLE)?;
    if config.interfaces.is_empty() {
        log::warn(&"no interfaces are configured: waiting for SIGINT or SIGTERM");
    }
    let state_file = open_state_file(config, &mut engine, Timestamp::ZERO)?;
    let recorder = start_recording(config, &mut engine);
    if config.record.is_some() && recorder.is_none() {
        // Said by the recorder; a reload tries again.
        engine.record_not_started();
    }
    let flight_log = start_flight_log(config);
    let stats = start_stats(config)?;
    let notifier = Notifier::from_env();
    let next_watchdog = notifier
        .as_ref()
        .and_then(Notifier::watchdog_interval)
        .map(|_| Timestamp::ZERO);
    let mut rt = Runtime {
        poll,
        engine,
        slots: Slab::new(),
        slot_of: Vec::new(),
        readable: VecDeque::new(),
        to_flush: Vec::new(),
        retiring: Vec::new(),
        lingering: Vec::new(),
        next_linger_poll: Timestamp::ZERO,
        opening: Vec::new(),
        woken: Vec::new(),
        timer,
        timer_armed: None,
        signals,
        logger,
        start,
        state_file,
        recorder,
        flight_log,
        stats,
        waker,
        source: source.map(str::to_string),
        notifier,
        next_watchdog,
        expiring: Vec::new(),
        next_expiry: Timestamp::ZERO,
        stopping: false,
    };
    for driver in drivers {
        rt.add(driver, false);
    }
    // Preloaded addresses are logged before anything else happens.
    rt.handle_notices(Timestamp::ZERO);
    Ok(rt)
}
