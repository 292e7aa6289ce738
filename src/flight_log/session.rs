//! The flight log of one vehicle as the router asks for and receives it: which
//! autopilot it is and whether it is armed (its heartbeat), when to start and stop the
//! stream, the frames to send it, and what goes to the file. Sans-IO: frames and time
//! in; frames for the vehicle's links, file writes and the next deadline out.

use std::collections::VecDeque;
use std::time::Duration;

use super::counters::FlightLogCounters;
use super::dataflash::{Acts, Dataflash, Verdict};
use super::messages::{self as m, Beat};
use super::ulog::{Ulog, UlogActs};
use crate::address::Address;
use crate::config::{FlightLog, FlightLogMode, FlightLogProtocol};
use crate::time::Timestamp;
use crate::wire::Frame;

/// Without a heartbeat for this long the autopilot is taken as gone (its link dropped,
/// it rebooted): the log is closed.
pub const AUTOPILOT_LOST: Duration = Duration::from_secs(5);
/// While no block comes, the start request is sent again this often (the first may be
/// lost, or the autopilot booted since).
pub const START_AGAIN: Duration = Duration::from_secs(1);
/// Blocks still coming after a stop are answered with another stop at most this often.
pub const STOP_AGAIN: Duration = Duration::from_secs(1);
/// After the stop request at disarm, blocks already on their way are still taken into
/// the log for this long; then its file is closed.
pub const DRAIN: Duration = Duration::from_secs(2);
/// A block of the log before, still on its way when the autopilot began a new one, lies
/// at most this many blocks (ulog chunks) from where that log had got to; and a block
/// more than this many ahead of a new log in its first `DRAIN` is not one of its own
/// (that many would have had to be lost in a row).
pub const EARLIER_SPAN: u32 = 256;
/// Most bytes waiting for the writer (taken every loop turn): beyond, blocks are
/// dropped and counted.
pub const WRITES_BOUND: usize = 8 << 20;

/// A log protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// ArduPilot's dataflash blocks, a `.bin` file.
    Dataflash,
    /// PX4's ulog, a `.ulg` file.
    Ulog,
}

impl Protocol {
    /// The file extension of its logs.
    pub fn extension(self) -> &'static str {
        match self {
            Protocol::Dataflash => "bin",
            Protocol::Ulog => "ulg",
        }
    }
}

/// What the writer is told, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogWrite {
    /// A new log begins: its file is created with its first bytes (a log that gets none
    /// leaves no file).
    Begin(Protocol),
    /// Bytes of the log, in order, holding `blocks` blocks.
    Data {
        /// The bytes.
        bytes: Vec<u8>,
        /// How many blocks (chunks) they came in.
        blocks: u64,
    },
    /// The log ends: its file is synced and closed.
    End,
}

/// The stream of one log.
#[derive(Debug)]
enum Stream {
    Dataflash(Dataflash),
    Ulog(Ulog),
}

/// A log being asked for or received.
#[derive(Debug)]
struct Active {
    protocol: Protocol,
    stream: Stream,
    /// When the start request goes again if no block came meanwhile.
    start_again: Timestamp,
    /// The start request went again after blocks had come: a block 0 now is a new log
    /// (the autopilot rebooted and answered it), not block 0 sent again.
    restarted: bool,
    /// Stopped at disarm: the blocks on their way are taken until then, and the log ends.
    ending: Option<Timestamp>,
    /// Where the log before got to, when this one replaced it (the autopilot began a
    /// new log), while that log's blocks may still come.
    earlier: Option<Earlier>,
}

/// The log a new one replaced, while its blocks may still be on their way (reordered,
/// or late over a second radio): for `DRAIN` after the new log began.
#[derive(Debug, Clone, Copy)]
struct Earlier {
    /// Its highest seqno (dataflash) or the last chunk it took (ulog).
    end: u32,
    until: Timestamp,
}

impl Earlier {
    /// The log before, which got to `end`, replaced at `now`.
    fn ended(end: u32, now: Timestamp) -> Self {
        Earlier {
            end,
            until: now + DRAIN,
        }
    }

    /// True when a block `distance` away from the earlier log's end, which would open a
    /// gap of `gap` blocks in the new log, is taken for the earlier log's: it lies near
    /// where that log got to and far beyond where the new one is. Such a block is not
    /// written. The new log's own blocks never come that far ahead, so this cannot
    /// feed on itself: a gap in the new log short of `EARLIER_SPAN` is the new log's.
    /// A block of a short earlier log, within that span of the new one, is not told
    /// apart.
    fn claims(&self, now: Timestamp, distance: u32, gap: u32) -> bool {
        now < self.until && distance <= EARLIER_SPAN && gap > EARLIER_SPAN
    }
}

/// The autopilot as its heartbeats describe it.
#[derive(Debug, Clone, Copy)]
struct Autopilot {
    component: u8,
    beat: Beat,
    last: Timestamp,
}

/// The flight log of the configured vehicle.
#[derive(Debug)]
pub struct FlightLogger {
    config: FlightLog,
    /// The sequence number of the router's next frame in the stream.
    seq: u8,
    autopilot: Option<Autopilot>,
    active: Option<Active>,
    /// When blocks coming after a stop may be answered with another stop.
    stop_again: Option<Timestamp>,
    /// Frames for the vehicle's links.
    outbox: Vec<Vec<u8>>,
    writes: VecDeque<LogWrite>,
    /// Bytes in `writes`.
    writes_bytes: usize,
    counters: FlightLogCounters,
    /// Where the last log that ended got to (its protocol and last block or chunk):
    /// its blocks may still come in the first moments of the next log.
    last_end: Option<(Protocol, u32)>,
}

impl FlightLogger {
    /// A logger for `config`, idle until the autopilot's heartbeat is heard.
    pub fn new(config: &FlightLog) -> Self {
        FlightLogger {
            config: config.clone(),
            seq: 0,
            autopilot: None,
            active: None,
            stop_again: None,
            outbox: Vec::new(),
            writes: VecDeque::new(),
            writes_bytes: 0,
            counters: FlightLogCounters::default(),
            last_end: None,
        }
    }

    /// Its configuration.
    pub fn config(&self) -> &FlightLog {
        &self.config
    }

    /// The vehicle whose log it asks for.
    pub fn system(&self) -> u8 {
        self.config.system
    }

    /// The protocol of the log being received, if one is.
    pub fn streaming(&self) -> Option<Protocol> {
        self.active.as_ref().map(|a| a.protocol)
    }

    /// The counters so far.
    pub fn counters(&self) -> FlightLogCounters {
        self.counters
    }

    /// Looks at `frame`, received at `now`: an autopilot heartbeat of the vehicle is
    /// noted (and routed as usual: false); the stream's frames addressed to the router
    /// are taken (true: not routed).
    pub fn take(&mut self, frame: &Frame<'_>, now: Timestamp) -> bool {
        let id = frame.message_id();
        if !matches!(
            id,
            m::HEARTBEAT
                | m::REMOTE_LOG_DATA_BLOCK
                | m::LOGGING_DATA
                | m::LOGGING_DATA_ACKED
                | m::COMMAND_ACK
        ) || frame.source().system != self.config.system
        {
            return false;
        }
        if id == m::HEARTBEAT {
            if let Some(beat) = m::heartbeat(frame) {
                self.heard(frame.source().component, beat, now);
            }
            return false;
        }
        if frame.target() != Some(self.config.source) {
            return false;
        }
        match id {
            m::REMOTE_LOG_DATA_BLOCK => self.dataflash_block(frame, now),
            m::LOGGING_DATA | m::LOGGING_DATA_ACKED => self.ulog_chunk(frame, now),
            _ => {
                // COMMAND_ACK: only the answers to the router's own log commands.
                let command = m::acked_command(frame);
                return command == m::CMD_LOGGING_START || command == m::CMD_LOGGING_STOP;
            }
        }
        true
    }

    /// An autopilot heartbeat from component `component`. While the autopilot heard
    /// first is alive, another component's heartbeat (one more flight controller of
    /// the vehicle, a peripheral saying it is an autopilot) is not taken: its armed
    /// state would start and stop logs in turn.
    fn heard(&mut self, component: u8, beat: Beat, now: Timestamp) {
        if self
            .autopilot
            .is_some_and(|a| a.component != component && now < a.last + AUTOPILOT_LOST)
        {
            return;
        }
        self.autopilot = Some(Autopilot {
            component,
            beat,
            last: now,
        });
        self.decide(now);
    }

    /// The protocol the autopilot speaks (as configured, or by its kind).
    fn protocol(&self) -> Option<Protocol> {
        match self.config.protocol {
            FlightLogProtocol::Dataflash => Some(Protocol::Dataflash),
            FlightLogProtocol::Ulog => Some(Protocol::Ulog),
            FlightLogProtocol::Auto => match self.autopilot?.beat.autopilot {
                m::AUTOPILOT_ARDUPILOT => Some(Protocol::Dataflash),
                m::AUTOPILOT_PX4 => Some(Protocol::Ulog),
                _ => None,
            },
        }
    }

    /// Starts or stops the log as the autopilot's state now asks.
    fn decide(&mut self, now: Timestamp) {
        let want = self
            .autopilot
            .is_some_and(|a| self.config.mode == FlightLogMode::Always || a.beat.armed);
        let protocol = if want { self.protocol() } else { None };
        match (&self.active, protocol) {
            (None, Some(p)) => self.start(p, now),
            (Some(a), Some(p)) if a.protocol != p || a.ending.is_some() => {
                // Another protocol, or armed again while the last log drains.
                self.stop(now);
                self.start(p, now);
            }
            (Some(a), None) if a.ending.is_none() && self.autopilot.is_some() => {
                self.begin_ending(now);
            }
            (Some(_), None) if self.autopilot.is_none() => {
                self.stop(now);
                // The autopilot went quiet, its stop request most likely lost: when it is
                // back, blocks near where this log got to are this log going on (an
                // ArduPilot keeps sending until its own timeout), not strays.
                self.last_end = None;
            }
            _ => {}
        }
    }

    /// The autopilot's address (its heartbeat's component), for the router's frames.
    fn target(&self) -> Address {
        let component = self.autopilot.map_or(1, |a| a.component);
        Address::new(self.config.system, component)
    }

    fn next_seq(&mut self) -> u8 {
        let seq = self.seq;
        self.seq = seq.wrapping_add(1);
        seq
    }

    /// Asks for the stream (again).
    fn send_start(&mut self, protocol: Protocol) {
        let (from, to, seq) = (self.config.source, self.target(), self.next_seq());
        self.outbox.push(match protocol {
            Protocol::Dataflash => {
                m::block_status(from, seq, to, m::DATA_BLOCK_START, m::BLOCK_ACK)
            }
            Protocol::Ulog => m::command(from, seq, to, m::CMD_LOGGING_START),
        });
    }

    fn send_stop(&mut self, protocol: Protocol) {
        let (from, to, seq) = (self.config.source, self.target(), self.next_seq());
        self.outbox.push(match protocol {
            Protocol::Dataflash => m::block_status(from, seq, to, m::DATA_BLOCK_STOP, m::BLOCK_ACK),
            Protocol::Ulog => m::command(from, seq, to, m::CMD_LOGGING_STOP),
        });
    }

    /// Begins a log in `protocol`: asks for the stream, tells the writer. Blocks of the
    /// log before (one that ended at a disarm, a reload or a change of protocol, while
    /// the autopilot was heard) may still be on their way: for `DRAIN` they are told
    /// from the new log's as when the autopilot begins a new log by itself.
    fn start(&mut self, protocol: Protocol, now: Timestamp) {
        self.send_start(protocol);
        self.begin(protocol);
        let earlier = (self.last_end.take())
            .filter(|(p, _)| *p == protocol)
            .map(|(_, end)| Earlier::ended(end, now));
        self.active = Some(Active {
            protocol,
            stream: fresh(protocol),
            start_again: now + START_AGAIN,
            restarted: false,
            ending: None,
            earlier,
        });
        self.stop_again = None;
    }

    /// Tells the writer a new log begins.
    fn begin(&mut self, protocol: Protocol) {
        self.counters.logs += 1;
        self.push_write(LogWrite::Begin(protocol));
    }

    /// Asks the autopilot to stop (it disarmed); the log ends `DRAIN` later, with the
    /// blocks that were on their way.
    fn begin_ending(&mut self, now: Timestamp) {
        if let Some(active) = self.active.as_mut() {
            active.ending = Some(now + DRAIN);
            let protocol = active.protocol;
            self.send_stop(protocol);
            self.stop_again = Some(now + STOP_AGAIN);
        }
    }

    /// Ends the log now: asks the autopilot to stop (unless it was asked already),
    /// tells the writer.
    fn stop(&mut self, now: Timestamp) {
        if let Some(mut active) = self.active.take() {
            self.last_end = match &active.stream {
                Stream::Dataflash(d) => d.highest(),
                Stream::Ulog(u) => u.expected().map(|e| u32::from(e.wrapping_sub(1))),
            }
            .map(|end| (active.protocol, end));
            if let Stream::Dataflash(d) = &mut active.stream {
                // The gaps will not be filled now; what came after them ends the file.
                let mut ending = Acts::default();
                d.finish(&mut ending);
                // It sends no status, so no autopilot component is needed.
                self.finish_acts(ending, 0);
            }
            if active.ending.is_none() {
                self.send_stop(active.protocol);
                self.stop_again = Some(now + STOP_AGAIN);
            }
            self.push_write(LogWrite::End);
        }
    }

    /// Stops the log at shutdown (the stop request goes with the last frames).
    pub fn shutdown(&mut self, now: Timestamp) {
        self.stop(now);
        self.autopilot = None;
    }

    /// A block that came while no log is asked for: counted, and the autopilot told
    /// again to stop (at most once every `STOP_AGAIN`).
    fn late(&mut self, protocol: Protocol, now: Timestamp) {
        self.counters.late += 1;
        if self.stop_again.is_none_or(|t| now >= t) {
            self.send_stop(protocol);
            self.stop_again = Some(now + STOP_AGAIN);
        }
    }

    fn dataflash_block(&mut self, frame: &Frame<'_>, now: Timestamp) {
        let (seqno, data) = m::dataflash_block(frame);
        let component = frame.source().component;
        let Some(active) = self
            .active
            .as_mut()
            .filter(|a| a.protocol == Protocol::Dataflash)
        else {
            return self.late(Protocol::Dataflash, now);
        };
        let Stream::Dataflash(d) = &mut active.stream else {
            return;
        };
        if let Some(earlier) = active.earlier {
            // Before its first block, the new log is at 0.
            let gap = match d.highest() {
                Some(highest) => seqno.saturating_sub(highest.saturating_add(1)),
                None => seqno,
            };
            if earlier.claims(now, seqno.abs_diff(earlier.end), gap) {
                self.counters.late += 1;
                return;
            }
        }
        active.start_again = now + START_AGAIN;
        let restarted = std::mem::take(&mut active.restarted);
        let mut acts = Acts::default();
        let new_log = (restarted && seqno == 0 && d.next() > 1)
            || d.block(seqno, &data, now, &mut acts) == Verdict::NewLog;
        if new_log {
            // The autopilot started a new log (it rebooted): what the old one held
            // behind its gaps ends its file, and a new file begins.
            let end = d.highest().unwrap_or(0);
            let mut ending = Acts::default();
            d.finish(&mut ending);
            *d = Dataflash::new();
            d.block(seqno, &data, now, &mut acts);
            active.earlier = Some(Earlier::ended(end, now));
            self.finish_acts(ending, component);
            self.push_write(LogWrite::End);
            self.begin(Protocol::Dataflash);
        }
        self.finish_acts(acts, component);
    }

    /// Sends the statuses and writes the bytes of `acts`, to the autopilot `component`.
    fn finish_acts(&mut self, acts: Acts, component: u8) {
        let to = Address::new(self.config.system, component);
        for (seqno, ack) in acts.statuses {
            let seq = self.next_seq();
            let status = if ack { m::BLOCK_ACK } else { m::BLOCK_NACK };
            self.outbox
                .push(m::block_status(self.config.source, seq, to, seqno, status));
            if !ack {
                self.counters.nacks += 1;
            }
        }
        let c = &mut self.counters;
        c.resent += acts.resent;
        c.lost += acts.lost;
        c.duplicates += acts.duplicates;
        self.write_data(acts.bytes, u64::from(acts.blocks));
    }

    fn ulog_chunk(&mut self, frame: &Frame<'_>, now: Timestamp) {
        let chunk = m::ulog_chunk(frame);
        if frame.message_id() == m::LOGGING_DATA_ACKED {
            // Acknowledged whatever becomes of it, or the autopilot waits and resends.
            let (from, seq) = (self.config.source, self.next_seq());
            let to = frame.source();
            self.outbox
                .push(m::logging_ack(from, seq, to, chunk.sequence));
        }
        let Some(active) = self
            .active
            .as_mut()
            .filter(|a| a.protocol == Protocol::Ulog)
        else {
            return self.late(Protocol::Ulog, now);
        };
        let Stream::Ulog(u) = &mut active.stream else {
            return;
        };
        if let Some(earlier) = active.earlier {
            // Before its first chunk, the new log is at 0.
            let expected = u.expected().unwrap_or(0);
            let end = earlier.end as u16;
            let distance = chunk
                .sequence
                .wrapping_sub(end)
                .min(end.wrapping_sub(chunk.sequence));
            // Behind the new log's next (a chunk sent again) opens no gap.
            let gap = chunk.sequence.wrapping_sub(expected);
            let gap = if gap >= 0x8000 { 0 } else { gap };
            if earlier.claims(now, u32::from(distance), u32::from(gap)) {
                self.counters.late += 1;
                return;
            }
        }
        active.start_again = now + START_AGAIN;
        let restarted = std::mem::take(&mut active.restarted);
        let mut acts = UlogActs::default();
        if restarted && chunk.sequence == 0 && u.started() {
            // The autopilot answered the start asked again with a new log.
            let end = u.expected().unwrap_or(0).wrapping_sub(1);
            *u = Ulog::new();
            u.chunk(&chunk, &mut acts);
            active.earlier = Some(Earlier::ended(u32::from(end), now));
            self.push_write(LogWrite::End);
            self.begin(Protocol::Ulog);
        } else {
            u.chunk(&chunk, &mut acts);
        }
        self.counters.lost += acts.lost;
        self.counters.duplicates += acts.duplicates;
        self.counters.late += acts.before_start;
        self.write_data(acts.bytes, u64::from(acts.chunks));
    }

    /// Queues `bytes` (`blocks` blocks) for the file, within the bound.
    fn write_data(&mut self, bytes: Vec<u8>, blocks: u64) {
        if blocks == 0 && bytes.is_empty() {
            return;
        }
        if self.writes_bytes + bytes.len() > WRITES_BOUND {
            self.counters.dropped += blocks;
            return;
        }
        self.counters.blocks += blocks;
        self.counters.bytes += bytes.len() as u64;
        self.writes_bytes += bytes.len();
        if let Some(LogWrite::Data {
            bytes: last,
            blocks: n,
        }) = self.writes.back_mut()
        {
            last.extend_from_slice(&bytes);
            *n += blocks;
            return;
        }
        self.writes.push_back(LogWrite::Data { bytes, blocks });
    }

    fn push_write(&mut self, write: LogWrite) {
        self.writes.push_back(write);
    }

    /// Runs what is due at `now`: the autopilot given up without heartbeats, the start
    /// request again while no block comes, missing blocks asked for again.
    pub fn handle_timeout(&mut self, now: Timestamp) {
        if self
            .autopilot
            .is_some_and(|a| now >= a.last + AUTOPILOT_LOST)
        {
            self.autopilot = None;
            self.decide(now);
        }
        if self
            .active
            .as_ref()
            .and_then(|a| a.ending)
            .is_some_and(|t| now >= t)
        {
            self.stop(now);
        }
        let Some(active) = self.active.as_mut() else {
            return;
        };
        let mut again = None;
        if active.ending.is_none() && now >= active.start_again {
            active.start_again = now + START_AGAIN;
            again = Some(active.protocol);
            active.restarted = match &active.stream {
                Stream::Dataflash(d) => d.next() > 0,
                Stream::Ulog(u) => u.started(),
            };
        }
        let mut acts = Acts::default();
        if let Stream::Dataflash(d) = &mut active.stream {
            d.handle_timeout(now, &mut acts);
        }
        if let Some(p) = again {
            self.send_start(p);
        }
        let component = self.target().component;
        self.finish_acts(acts, component);
    }

    /// The next instant something is due, if anything is.
    pub fn poll_timeout(&self) -> Option<Timestamp> {
        let lost = self.autopilot.map(|a| a.last + AUTOPILOT_LOST);
        let active = self.active.as_ref().map(|a| {
            let ask = match &a.stream {
                Stream::Dataflash(d) => d.poll_timeout(),
                Stream::Ulog(_) => None,
            };
            let next = a.ending.unwrap_or(a.start_again);
            ask.map_or(next, |t| t.min(next))
        });
        [lost, active].into_iter().flatten().min()
    }

    /// Hands each frame for the vehicle to `send`, oldest first.
    pub fn drain_frames(&mut self, send: &mut impl FnMut(Vec<u8>)) {
        for frame in self.outbox.drain(..) {
            send(frame);
        }
    }

    /// True when frames wait for the vehicle.
    pub fn has_frames(&self) -> bool {
        !self.outbox.is_empty()
    }

    /// Hands each write for the file to `take`, oldest first.
    pub fn drain_writes(&mut self, take: &mut impl FnMut(LogWrite)) {
        self.writes_bytes = 0;
        for w in self.writes.drain(..) {
            take(w);
        }
    }
}

/// A stream of `protocol` at its beginning.
fn fresh(protocol: Protocol) -> Stream {
    match protocol {
        Protocol::Dataflash => Stream::Dataflash(Dataflash::new()),
        Protocol::Ulog => Stream::Ulog(Ulog::new()),
    }
}
