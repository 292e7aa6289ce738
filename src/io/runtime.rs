//! The event loop: builds the drivers from the configuration, runs until SIGINT or
//! SIGTERM, then flushes what is queued (for at most a second) and prints the counters.

use std::io;
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};
use signal_hook::consts::{SIGINT, SIGTERM, SIGUSR1};
use signal_hook_mio::v1_0::Signals;

use super::frames::UnknownIds;
use super::log::{self, Logger};
use super::serial::SerialDriver;
use super::sys::TimerFd;
use super::udp::UdpDriver;
use crate::config::{Config, Interface};
use crate::routing::{Output, Router, RouterOptions, Timestamp};

const SIGNALS: Token = Token(0);
const PACING_TIMER: Token = Token(1);
/// UDP interface `i` is `Token(UDP_BASE + i)`.
const UDP_BASE: usize = 16;
/// Serial interface `i` is `Token(SERIAL_BASE + i)`.
const SERIAL_BASE: usize = 1 << 20;
/// How often learned addresses are expired and idle UDP links removed.
const TICK: Duration = Duration::from_secs(1);
/// How long queued packets may still be sent after SIGINT/SIGTERM.
const SHUTDOWN_FLUSH: Duration = Duration::from_secs(1);
/// How long the log writers may still write after the loop ends.
const LOG_DRAIN: Duration = Duration::from_secs(1);
/// Per-link queue bound: 1 MiB is a minute of backlog for a 128 kbit/s radio.
pub const QUEUE_CAPACITY: usize = 1024 * 1024;
/// Bound of all queues together, so that no number of links (a flood of spoofed UDP
/// senders included) takes the router beyond a few MiB.
pub const TOTAL_QUEUE_CAPACITY: usize = 4 * 1024 * 1024;

/// Everything the loop owns.
struct Runtime {
    poll: Poll,
    router: Router,
    udp: Vec<UdpDriver>,
    serial: Vec<SerialDriver>,
    timer: TimerFd,
    /// The deadline the pacing timer is armed for (re-armed only when it changes).
    pacing_armed: Option<Timestamp>,
    signals: Signals,
    logger: Logger,
    out: Output,
    unknown: UnknownIds,
    start: Instant,
    /// UDP interfaces whose socket may hold more datagrams (their turn ended early).
    udp_ready: Vec<bool>,
    /// Serial ports likewise.
    serial_ready: Vec<bool>,
    /// Whether writability is currently watched, per UDP interface and serial port.
    udp_watching_writes: Vec<bool>,
    serial_watching_writes: Vec<bool>,
}

impl Runtime {
    fn now(&self) -> Timestamp {
        Timestamp::new(self.start.elapsed())
    }

    /// Prints the core's events and notes queue levels.
    fn drain_output(&mut self) {
        for event in &self.out.events {
            self.logger.event(event);
        }
        for id in &self.out.queued {
            let bytes = self.router.link(*id).map_or(0, |l| l.queue().bytes());
            for u in &mut self.udp {
                if u.owns(*id) {
                    u.note_queue(*id, bytes);
                }
            }
            for s in &mut self.serial {
                if s.link() == *id {
                    s.note_queue(bytes);
                }
            }
        }
        self.out.clear();
    }

    fn receive_udp(&mut self, i: usize, now: Timestamp) {
        let more = self.udp[i].receive(&mut self.router, now, &mut self.out, &mut self.unknown);
        self.udp_ready[i] = more;
        self.drain_output();
    }

    fn receive_serial(&mut self, i: usize, now: Timestamp) {
        match self.serial[i].receive(&mut self.router, now, &mut self.out, &mut self.unknown) {
            Ok(more) => self.serial_ready[i] = more,
            Err(file) => {
                self.serial_ready[i] = false;
                if let Some(f) = file {
                    let _ = self
                        .poll
                        .registry()
                        .deregister(&mut SourceFd(&f.as_raw_fd()));
                }
            }
        }
        self.drain_output();
    }

    /// Sends what every link can send now; arms the pacing timer for the earliest
    /// datagram a pacer holds back.
    fn flush_all(&mut self, now: Timestamp) {
        let mut next: Option<Timestamp> = None;
        for u in &mut self.udp {
            u.flush(&mut self.router, now);
            if let Some(t) = u.pace_deadline {
                next = Some(next.map_or(t, |n| n.min(t)));
            }
        }
        for s in &mut self.serial {
            if let Err(Some(f)) = s.flush(&mut self.router, now) {
                let _ = self
                    .poll
                    .registry()
                    .deregister(&mut SourceFd(&f.as_raw_fd()));
            }
        }
        self.watch_writes();
        if next != self.pacing_armed {
            self.pacing_armed = next;
            let delay = next.map(|t| t.saturating_since(self.now()));
            if let Err(e) = self.timer.set(delay) {
                log::error(&format_args!("pacing timer: {e}"));
            }
        }
    }

    /// Watches writability exactly where a socket or port refused data.
    fn watch_writes(&mut self) {
        for (i, u) in self.udp.iter_mut().enumerate() {
            if u.blocked != self.udp_watching_writes[i] {
                let interest = if u.blocked {
                    Interest::READABLE | Interest::WRITABLE
                } else {
                    Interest::READABLE
                };
                let token = Token(UDP_BASE + i);
                match self
                    .poll
                    .registry()
                    .reregister(u.socket_mut(), token, interest)
                {
                    Ok(()) => self.udp_watching_writes[i] = u.blocked,
                    Err(e) => {
                        log::error(&format_args!("{}: cannot watch the socket: {e}", u.label))
                    }
                }
            }
        }
        for (i, s) in self.serial.iter().enumerate() {
            let Some(f) = s.file() else { continue };
            if s.blocked != self.serial_watching_writes[i] {
                let interest = if s.blocked {
                    Interest::READABLE | Interest::WRITABLE
                } else {
                    Interest::READABLE
                };
                let fd = f.as_raw_fd();
                let token = Token(SERIAL_BASE + i);
                match self
                    .poll
                    .registry()
                    .reregister(&mut SourceFd(&fd), token, interest)
                {
                    Ok(()) => self.serial_watching_writes[i] = s.blocked,
                    Err(e) => {
                        log::error(&format_args!("{}: cannot watch the port: {e}", s.device()))
                    }
                }
            }
        }
    }

    /// Opens serial ports whose retry time has come.
    fn reopen_serial(&mut self, now: Timestamp) {
        for (i, s) in self.serial.iter_mut().enumerate() {
            if s.reopen_if_due(now)
                && let Some(f) = s.file()
            {
                let fd = f.as_raw_fd();
                let registered = self.poll.registry().register(
                    &mut SourceFd(&fd),
                    Token(SERIAL_BASE + i),
                    Interest::READABLE,
                );
                self.serial_watching_writes[i] = false;
                if let Err(e) = registered {
                    log::error(&format_args!("{}: cannot watch the port: {e}", s.device()));
                }
                // Bytes may already be waiting; an edge may have been missed.
                self.serial_ready[i] = true;
            }
        }
    }

    fn idle(&self) -> bool {
        self.udp.iter().all(|u| u.idle(&self.router))
            && self.serial.iter().all(|s| s.idle(&self.router))
    }

    fn print_counters(&self) {
        let mut text = String::from("mavtables counters:\n");
        for s in &self.serial {
            text.push_str(&format!("  {}\n", s.report(&self.router)));
        }
        for u in &self.udp {
            for r in u.reports(&self.router) {
                text.push_str(&format!("  {r}\n"));
            }
        }
        let mut stats = Vec::new();
        for s in &self.serial {
            stats.push((s.device().to_string(), *s.parser_stats(), s.failures));
        }
        for u in &self.udp {
            stats.push((u.label.clone(), *u.parser_stats(), u.io_errors));
        }
        for (name, p, errors) in stats {
            text.push_str(&format!(
                "  {name}: {} frames, {} bad checksum, {} unknown id, {} bad flags, {} bad length, {} junk bytes, {} I/O errors\n",
                p.frames, p.bad_crc, p.unknown_id, p.bad_flags, p.bad_length, p.junk_bytes, errors
            ));
        }
        log::stderr_text(&text);
    }

    /// The next time something is due: the tick, a serial reopening, or the end of the
    /// shutdown flush.
    fn poll_timeout(
        &self,
        now: Timestamp,
        next_tick: Timestamp,
        stop_by: Option<Timestamp>,
    ) -> Duration {
        if self.udp_ready.iter().chain(&self.serial_ready).any(|r| *r) {
            return Duration::ZERO;
        }
        let mut due = next_tick;
        let udp_due = self.udp.iter().filter_map(UdpDriver::stale_at);
        let serial_due = self
            .serial
            .iter()
            .flat_map(|s| s.retry_at().into_iter().chain(s.stale_at()));
        for t in serial_due.chain(udp_due).chain(stop_by) {
            due = due.min(t);
        }
        due.saturating_since(now)
    }

    fn run(&mut self) -> io::Result<()> {
        let mut events = Events::with_capacity(256);
        let mut next_tick = Timestamp::new(TICK);
        let mut stop_by: Option<Timestamp> = None;
        let now = self.now();
        self.reopen_serial(now);
        loop {
            let now = self.now();
            let timeout = self.poll_timeout(now, next_tick, stop_by);
            if let Err(e) = self.poll.poll(&mut events, Some(timeout)) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            let now = self.now();
            for event in events.iter() {
                match event.token() {
                    SIGNALS => {
                        for signal in self.signals.pending() {
                            if signal == SIGUSR1 {
                                self.print_counters();
                            } else if stop_by.is_none() {
                                stop_by = Some(Timestamp::new(now.since_start() + SHUTDOWN_FLUSH));
                            }
                        }
                    }
                    PACING_TIMER => {
                        self.timer.acknowledge();
                        // Fired: whatever the pacers need next is armed afresh.
                        self.pacing_armed = None;
                    }
                    Token(t) if (UDP_BASE..SERIAL_BASE).contains(&t) => {
                        if event.is_readable() && stop_by.is_none() {
                            self.receive_udp(t - UDP_BASE, now);
                        }
                    }
                    Token(t) => {
                        let i = t - SERIAL_BASE;
                        if i < self.serial.len()
                            && (event.is_readable() || event.is_error() || event.is_read_closed())
                            && stop_by.is_none()
                        {
                            self.receive_serial(i, now);
                        }
                    }
                }
            }
            // Interfaces whose turn ended before their input was drained.
            if stop_by.is_none() {
                for i in 0..self.udp.len() {
                    if self.udp_ready[i] {
                        self.receive_udp(i, now);
                    }
                }
                for i in 0..self.serial.len() {
                    if self.serial_ready[i] {
                        self.receive_serial(i, now);
                    }
                }
            }
            // Bytes held back on a line that has gone quiet are judged now.
            for u in &mut self.udp {
                u.finish_stale(&mut self.router, now, &mut self.out, &mut self.unknown);
            }
            for s in &mut self.serial {
                s.finish_stale(&mut self.router, now, &mut self.out, &mut self.unknown);
            }
            self.drain_output();
            self.flush_all(now);
            if now >= next_tick {
                let removed = self.router.tick(now);
                if !removed.is_empty() {
                    for u in &mut self.udp {
                        u.forget(&removed);
                    }
                }
                next_tick = Timestamp::new(now.since_start() + TICK);
            }
            self.reopen_serial(now);
            self.logger.flush();
            if let Some(deadline) = stop_by {
                self.udp_ready.iter_mut().for_each(|r| *r = false);
                self.serial_ready.iter_mut().for_each(|r| *r = false);
                if self.idle() || now >= deadline {
                    return Ok(());
                }
            }
        }
    }
}

/// Runs the router for `config` with log level `loglevel` until SIGINT or SIGTERM.
/// Returns the process exit status: 0 after a clean shutdown, 1 if it could not start
/// (a UDP port that cannot be bound; serial devices are retried instead).
pub fn run(config: &Config, loglevel: u8) -> u8 {
    let status = run_until_stopped(config, loglevel);
    // The log writers get a bounded time to write what is buffered.
    log::drain(LOG_DRAIN);
    status
}

fn run_until_stopped(config: &Config, loglevel: u8) -> u8 {
    match start(config, loglevel) {
        Ok(mut rt) => {
            let result = rt.run();
            rt.logger.flush();
            rt.print_counters();
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
    }
}

fn start(config: &Config, loglevel: u8) -> io::Result<Runtime> {
    let poll = Poll::new()?;
    let options = RouterOptions {
        event_level: loglevel,
        queue_capacity: QUEUE_CAPACITY,
        total_queue_capacity: TOTAL_QUEUE_CAPACITY,
        ..RouterOptions::default()
    };
    let mut router = Router::with_options(config, options);
    let mut logger = Logger::new(loglevel);
    let mut out = Output::default();
    let start = Instant::now();
    // Serial links first, in file order (the original's link order), with preloads.
    let mut serial = Vec::new();
    for iface in &config.interfaces {
        if let Interface::Serial(s) = iface {
            let link = router.add_serial_link(&s.device, &s.preload, Timestamp::ZERO, &mut out);
            serial.push(SerialDriver::new(s, link));
        }
    }
    for event in &out.events {
        logger.event(event);
    }
    out.clear();
    let mut udp = Vec::new();
    for iface in &config.interfaces {
        if let Interface::Udp(u) = iface {
            let mut driver = UdpDriver::open(u).map_err(|e| {
                io::Error::new(e.kind(), format!("udp {}:{}: {e}", u.address, u.port))
            })?;
            poll.registry().register(
                driver.socket_mut(),
                Token(UDP_BASE + udp.len()),
                Interest::READABLE,
            )?;
            udp.push(driver);
        }
    }
    let timer = TimerFd::new()?;
    poll.registry().register(
        &mut SourceFd(&timer.as_raw_fd()),
        PACING_TIMER,
        Interest::READABLE,
    )?;
    let mut signals = Signals::new([SIGINT, SIGTERM, SIGUSR1])?;
    poll.registry()
        .register(&mut signals, SIGNALS, Interest::READABLE)?;
    if config.interfaces.is_empty() {
        log::warn(&"no interfaces are configured: waiting for SIGINT or SIGTERM");
    }
    let udp_ready = vec![false; udp.len()];
    let serial_ready = vec![false; serial.len()];
    let udp_watching_writes = vec![false; udp.len()];
    let serial_watching_writes = vec![false; serial.len()];
    Ok(Runtime {
        poll,
        router,
        udp,
        serial,
        timer,
        signals,
        logger,
        out,
        unknown: UnknownIds::default(),
        start,
        udp_ready,
        serial_ready,
        udp_watching_writes,
        serial_watching_writes,
        pacing_armed: None,
    })
}
