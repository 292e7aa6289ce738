//! The flight log in the core, on a simulated clock: an ArduPilot on one peer streams
//! its dataflash log to the router (the `flight_log` block). The router asks for it at
//! arming and stops it at disarming (one log per arming), acknowledges each block,
//! asks again for a missing one and writes the blocks in order; the stream's frames do
//! not reach the ground station, whose own log download passes through. A reboot of the
//! autopilot (its heartbeats stop, its blocks start again from 0) ends the log.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Duration;

use crate::routing;

use mavtables::config;
use mavtables::flight_log::{LogWrite, Protocol};
use mavtables::routing::{Engine, InterfaceId, Request, RouterOptions, Timestamp};
use mavtables::wire::Frame;
use mavtables::wire::encode::{Header, encode_v2};

const AUTOPILOT: u16 = 1;
const GCS: u16 = 3;
const START: u32 = 2_147_483_646;
const STOP: u32 = 2_147_483_645;

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

fn encode(from: &str, id: u32, payload: &[u8]) -> Vec<u8> {
    let a = routing::addr(from);
    let mut out = Vec::new();
    let header = Header {
        seq: 0,
        system: a.system,
        component: a.component,
    };
    encode_v2(header, id, payload, None, &mut out).expect("encodes");
    out
}

/// A HEARTBEAT of an ArduPilot (autopilot 3, or `autopilot`), armed or not.
fn heartbeat(autopilot: u8, armed: bool) -> Vec<u8> {
    let base_mode = if armed { 128 | 1 } else { 1 };
    encode("1.1", 0, &[0, 0, 0, 0, 2, autopilot, base_mode, 4, 3])
}

/// Block `seqno` of the log: 200 bytes, each its seqno's low byte.
fn block_data(seqno: u32) -> [u8; 200] {
    [(seqno % 251) as u8 + 1; 200]
}

/// REMOTE_LOG_DATA_BLOCK `seqno` from the autopilot to `to`.
fn block(seqno: u32, to: &str) -> Vec<u8> {
    let t = routing::addr(to);
    let mut p = seqno.to_le_bytes().to_vec();
    p.extend_from_slice(&[t.system, t.component]);
    p.extend_from_slice(&block_data(seqno));
    encode("1.1", 184, &p)
}

struct Vehicle {
    e: Engine,
    udp: InterfaceId,
    now: Timestamp,
}

const CONF: &str = "udp { port 14550; }\n\
    flight_log { system 1; mode while_armed; }\n\
    default_action accept;\n";

impl Vehicle {
    fn new(conf: &str) -> Self {
        let config = config::load(conf).expect("config loads").config;
        let mut e = Engine::new(&config, RouterOptions::default());
        let keys = vec![None; config.interfaces.len()];
        let done = e.configure(&config, &keys, Timestamp::ZERO);
        let udp = done
            .requests
            .iter()
            .find_map(|r| match r {
                Request::Open(id, _) => Some(*id),
                _ => None,
            })
            .expect("one interface");
        let mut v = Vehicle {
            e,
            udp,
            now: Timestamp::from_secs(1),
        };
        // The ground station is known before the vehicle.
        v.from(GCS, &encode("255.190", 0, &[0, 0, 0, 0, 6, 8, 0, 4, 3]));
        v
    }

    fn from(&mut self, port: u16, bytes: &[u8]) {
        self.e
            .handle_datagram(self.udp, peer(port), bytes, self.now);
    }

    /// Moves the clock on by `d`, running what is due.
    fn wait(&mut self, d: Duration) {
        let end = self.now + d;
        loop {
            let due = self.e.poll_timeout();
            if due > end {
                break;
            }
            self.now = due.max(self.now);
            self.e.handle_timeout(self.now);
        }
        self.now = end;
    }

    /// What each peer got since last asked: (port, frame bytes).
    fn sent(&mut self) -> Vec<(u16, Vec<u8>)> {
        let mut queue = VecDeque::new();
        self.e
            .poll_transmit(self.udp, self.now, 1 << 16, &mut queue);
        queue
            .into_iter()
            .map(|t| {
                self.e.on_sent(&t);
                (t.to.map_or(0, |a| a.port()), t.packet.to_vec())
            })
            .collect()
    }

    /// The REMOTE_LOG_BLOCK_STATUS (seqno, status) the autopilot got, checking they
    /// come from the router's address to it; panics on a frame the GCS got of them.
    fn statuses(&mut self) -> Vec<(u32, u8)> {
        let mut out = Vec::new();
        for (port, bytes) in self.sent() {
            let f = Frame::parse_exact(&bytes).expect("valid frame");
            if f.message_id() != 185 {
                continue;
            }
            assert_eq!(port, AUTOPILOT, "a status went to the ground station");
            assert_eq!(f.source(), routing::addr("245.190"));
            assert_eq!(f.target(), Some(routing::addr("1.1")));
            let p = f.payload_padded();
            out.push((u32::from_le_bytes([p[0], p[1], p[2], p[3]]), p[6]));
        }
        out
    }

    fn writes(&mut self) -> Vec<LogWrite> {
        let mut out = Vec::new();
        self.e.poll_flight_log(&mut |w| out.push(w));
        out
    }
}

/// The bytes of `writes`, and the number of blocks they hold.
fn data(writes: &[LogWrite]) -> (Vec<u8>, u64) {
    let mut bytes = Vec::new();
    let mut n = 0;
    for w in writes {
        if let LogWrite::Data { bytes: b, blocks } = w {
            bytes.extend_from_slice(b);
            n += blocks;
        }
    }
    (bytes, n)
}

fn expected(seqnos: impl IntoIterator<Item = u32>) -> Vec<u8> {
    seqnos.into_iter().flat_map(block_data).collect()
}

#[test]
fn arming_starts_the_log_each_block_is_acked_and_disarming_stops_it() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, false));
    assert_eq!(v.statuses(), [], "nothing asked while disarmed");
    v.from(AUTOPILOT, &heartbeat(3, true));
    assert_eq!(v.statuses(), [(START, 1)]);
    assert_eq!(v.writes(), [LogWrite::Begin(Protocol::Dataflash)]);
    for s in 0..3 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    assert_eq!(v.statuses(), [(0, 1), (1, 1), (2, 1)]);
    let writes = v.writes();
    assert_eq!(data(&writes), (expected(0..3), 3));
    v.from(AUTOPILOT, &heartbeat(3, false));
    assert_eq!(v.statuses(), [(STOP, 1)]);
    // A block that was on its way is still taken into this log; the file is closed
    // once the blocks on their way had time to come.
    v.from(AUTOPILOT, &block(3, "245.190"));
    assert_eq!(v.statuses(), [(3, 1)]);
    assert_eq!(data(&v.writes()), (expected(3..4), 1));
    v.wait(Duration::from_millis(1900));
    assert_eq!(v.writes(), []);
    v.wait(Duration::from_millis(200));
    assert_eq!(v.writes(), [LogWrite::End]);
    let (c, streaming) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.blocks, c.logs, c.late, streaming), (4, 1, 0, None));
}

#[test]
fn arming_again_while_the_last_log_drains_begins_the_next_file_at_once() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.from(AUTOPILOT, &block(0, "245.190"));
    v.from(AUTOPILOT, &heartbeat(3, false));
    v.writes();
    v.statuses();
    v.wait(Duration::from_millis(500));
    v.from(AUTOPILOT, &heartbeat(3, true));
    assert_eq!(v.statuses(), [(START, 1)]);
    assert_eq!(
        v.writes(),
        [LogWrite::End, LogWrite::Begin(Protocol::Dataflash)]
    );
}

#[test]
fn the_stream_does_not_reach_the_ground_station() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in 0..5 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    let to_gcs: Vec<u32> = v
        .sent()
        .iter()
        .filter(|(port, _)| *port == GCS)
        .map(|(_, b)| Frame::parse_exact(b).expect("valid").message_id())
        .collect();
    assert_eq!(to_gcs, [0], "only the heartbeat reaches the ground station");
}

#[test]
fn a_missing_block_is_nacked_and_written_in_order_once_resent() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.statuses();
    v.writes();
    for s in [0, 1, 3, 4] {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    assert_eq!(v.statuses(), [(0, 1), (1, 1), (3, 1), (2, 0), (4, 1)]);
    assert_eq!(data(&v.writes()), (expected(0..2), 2));
    // Not resent yet: asked again after a while.
    v.wait(Duration::from_millis(250));
    assert_eq!(v.statuses(), [(2, 0)]);
    v.from(AUTOPILOT, &block(2, "245.190"));
    assert_eq!(v.statuses(), [(2, 1)]);
    assert_eq!(data(&v.writes()), (expected(2..5), 3));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.resent, c.lost, c.nacks), (1, 0, 2));
}

#[test]
fn a_block_that_never_comes_is_given_up_and_the_file_goes_on() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in [0, 2, 3] {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    // Heartbeats keep the autopilot known meanwhile.
    for _ in 0..4 {
        v.wait(Duration::from_secs(1));
        v.from(AUTOPILOT, &heartbeat(3, true));
    }
    let nacks = v
        .statuses()
        .iter()
        .filter(|(s, st)| (*s, *st) == (1, 0))
        .count();
    assert_eq!(nacks, 10, "asked for a bounded number of times");
    assert_eq!(data(&v.writes()).0, expected([0, 2, 3]));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!(c.lost, 1);
}

#[test]
fn one_log_per_arming() {
    let mut v = Vehicle::new(CONF);
    let mut logs = 0;
    for _ in 0..3 {
        v.from(AUTOPILOT, &heartbeat(3, true));
        // Heartbeats while armed do not start another.
        v.from(AUTOPILOT, &heartbeat(3, true));
        for s in 0..2 {
            v.from(AUTOPILOT, &block(s, "245.190"));
        }
        v.from(AUTOPILOT, &heartbeat(3, false));
        v.from(AUTOPILOT, &heartbeat(3, false));
        v.wait(Duration::from_millis(2100));
        let writes = v.writes();
        assert_eq!(writes.first(), Some(&LogWrite::Begin(Protocol::Dataflash)));
        assert_eq!(writes.last(), Some(&LogWrite::End));
        assert_eq!(data(&writes).1, 2);
        logs += writes
            .iter()
            .filter(|w| matches!(w, LogWrite::Begin(_)))
            .count();
    }
    assert_eq!(logs, 3);
    // Blocks after disarming start nothing: they are answered with a stop.
    v.from(AUTOPILOT, &block(2, "245.190"));
    assert_eq!(v.statuses().last(), Some(&(STOP, 1)));
    assert_eq!(v.writes(), []);
}

#[test]
fn another_component_saying_it_is_an_autopilot_does_not_flap_the_log() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    let other = encode("1.2", 0, &[0, 0, 0, 0, 2, 3, 1, 4, 3]);
    for _ in 0..3 {
        v.from(AUTOPILOT, &other);
        v.from(AUTOPILOT, &heartbeat(3, true));
    }
    assert_eq!(v.statuses(), [(START, 1)], "one start, no stop");
    assert_eq!(v.writes(), [LogWrite::Begin(Protocol::Dataflash)]);
}

#[test]
fn the_start_is_asked_again_until_blocks_come() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    assert_eq!(v.statuses(), [(START, 1)]);
    v.wait(Duration::from_millis(1100));
    assert_eq!(v.statuses(), [(START, 1)]);
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.from(AUTOPILOT, &block(0, "245.190"));
    v.wait(Duration::from_millis(500));
    v.from(AUTOPILOT, &block(1, "245.190"));
    v.wait(Duration::from_millis(500));
    assert_eq!(v.statuses(), [(0, 1), (1, 1)], "no start while blocks come");
}

#[test]
fn an_autopilot_reboot_ends_the_log_and_its_next_log_is_a_new_file() {
    let mut v = Vehicle::new(
        "udp { port 14550; }\nflight_log { system 1; mode always; }\ndefault_action accept;\n",
    );
    v.from(AUTOPILOT, &heartbeat(3, false));
    for s in 0..3 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    // Silent for longer than AUTOPILOT_LOST: the log ends.
    v.wait(Duration::from_secs(6));
    let writes = v.writes();
    assert_eq!(writes.last(), Some(&LogWrite::End));
    assert_eq!(data(&writes).1, 3);
    // Back: a new log, numbered from 0 again.
    v.statuses();
    v.from(AUTOPILOT, &heartbeat(3, false));
    assert_eq!(v.statuses(), [(START, 1)]);
    v.from(AUTOPILOT, &block(0, "245.190"));
    let writes = v.writes();
    assert_eq!(writes[0], LogWrite::Begin(Protocol::Dataflash));
    assert_eq!(data(&writes).0, expected([0]));
}

#[test]
fn an_autopilot_that_rebooted_while_heard_starts_a_new_file_at_the_start_asked_again() {
    // Its heartbeats went on (another link, or a quick reboot): the blocks stopped, the
    // start went again, and the log it answers with is numbered from 0.
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in 0..20 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    v.writes();
    v.statuses();
    v.wait(Duration::from_millis(1100));
    v.from(AUTOPILOT, &heartbeat(3, true));
    assert_eq!(v.statuses(), [(START, 1)]);
    v.from(AUTOPILOT, &block(0, "245.190"));
    v.from(AUTOPILOT, &block(1, "245.190"));
    let writes = v.writes();
    assert_eq!(
        writes[..2],
        [LogWrite::End, LogWrite::Begin(Protocol::Dataflash)]
    );
    assert_eq!(data(&writes).0, expected(0..2));
    // Without a start asked again, block 0 once more is a resend whose ACK was lost.
    v.from(AUTOPILOT, &block(0, "245.190"));
    assert_eq!(v.statuses().last(), Some(&(0, 1)));
    assert_eq!(v.writes(), []);
}

/// LOGGING_DATA `sequence` to the router: one whole ulog message after the header
/// (chunk 0 carries the 16-byte header first).
fn ulog_chunk(sequence: u16) -> Vec<u8> {
    let mut data = Vec::new();
    if sequence == 0 {
        data.extend_from_slice(b"ULog\x01\x12\x35\x01");
        data.extend_from_slice(&[0; 8]);
    }
    data.extend_from_slice(&[4, 0, b'D', 0, 0, sequence as u8, 9]);
    let mut p = sequence.to_le_bytes().to_vec();
    p.extend_from_slice(&[
        245,
        190,
        data.len() as u8,
        if sequence == 0 { 16 } else { 0 },
    ]);
    p.extend_from_slice(&data);
    encode("1.1", 266, &p)
}

#[test]
fn a_px4_log_is_asked_for_with_a_command_and_a_restarted_one_is_a_new_file() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(12, true));
    let commands: Vec<(u16, u16)> = v
        .sent()
        .iter()
        .filter_map(|(port, b)| {
            let f = Frame::parse_exact(b).expect("valid");
            let p = f.payload_padded();
            (f.message_id() == 76).then(|| (*port, u16::from_le_bytes([p[28], p[29]])))
        })
        .collect();
    assert_eq!(commands, [(AUTOPILOT, 2510)]);
    assert_eq!(v.writes(), [LogWrite::Begin(Protocol::Ulog)]);
    for s in 0..5 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    assert_eq!(data(&v.writes()), (ulog_bytes(0..5), 5));
    // Stalled, asked again, answered from chunk 0: a new file.
    v.wait(Duration::from_millis(1100));
    v.from(AUTOPILOT, &heartbeat(12, true));
    v.sent();
    v.from(AUTOPILOT, &ulog_chunk(0));
    let writes = v.writes();
    assert_eq!(
        writes[..2],
        [LogWrite::End, LogWrite::Begin(Protocol::Ulog)]
    );
    assert_eq!(data(&writes).0, ulog_bytes(0..1));
}

/// What the file gets of chunks `seqs` (see [`ulog_chunk`]).
fn ulog_bytes(seqs: std::ops::Range<u16>) -> Vec<u8> {
    let mut out = Vec::new();
    for s in seqs {
        let f = ulog_chunk(s);
        let frame = Frame::parse_exact(&f).expect("valid");
        let p = frame.payload_padded();
        out.extend_from_slice(&p[6..6 + usize::from(p[4])]);
    }
    out
}

/// A vehicle whose autopilot has streamed blocks 0 to 1099 of a log (written out).
fn after_a_long_log() -> Vehicle {
    let mut v = Vehicle::new(
        "udp { port 14550; }\nflight_log { system 1; mode always; }\ndefault_action accept;\n",
    );
    v.from(AUTOPILOT, &heartbeat(3, false));
    for s in 0..1100 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    v.writes();
    v
}

#[test]
fn a_sequence_that_starts_again_mid_stream_is_a_new_file() {
    let mut v = after_a_long_log();
    v.from(AUTOPILOT, &block(0, "245.190"));
    let writes = v.writes();
    assert_eq!(writes[0], LogWrite::End);
    assert_eq!(writes[1], LogWrite::Begin(Protocol::Dataflash));
    assert_eq!(data(&writes).0, expected([0]));
}

#[test]
fn a_ground_station_log_download_and_blocks_for_others_pass_through() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.sent();
    // LOG_REQUEST_LIST from the GCS to the vehicle, LOG_ENTRY back.
    v.from(
        GCS,
        &routing::frame("LOG_REQUEST_LIST", "255.190", Some("1.1")),
    );
    v.from(AUTOPILOT, &routing::frame("LOG_ENTRY", "1.1", None));
    // A data block addressed to the ground station is its own business.
    v.from(AUTOPILOT, &block(0, "255.190"));
    let mut got: Vec<(u16, u32)> = v
        .sent()
        .iter()
        .map(|(p, b)| (*p, Frame::parse_exact(b).expect("valid").message_id()))
        .collect();
    got.sort_unstable();
    assert_eq!(got, [(AUTOPILOT, 117), (GCS, 118), (GCS, 184)]);
    assert_eq!(data(&v.writes()).1, 0);
}

#[test]
fn a_reload_keeps_an_unchanged_log_and_ends_a_changed_one() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.from(AUTOPILOT, &block(0, "245.190"));
    v.statuses();
    v.writes();
    let reload = |v: &mut Vehicle, conf: &str| {
        let config = config::load(conf).expect("config loads").config;
        let keys = vec![None; config.interfaces.len()];
        v.e.configure(&config, &keys, v.now);
    };
    reload(&mut v, CONF);
    v.from(AUTOPILOT, &block(1, "245.190"));
    assert_eq!(v.statuses(), [(1, 1)], "the same log goes on");
    assert_eq!(data(&v.writes()).1, 1);
    reload(
        &mut v,
        "udp { port 14550; }\nflight_log { system 1; max_files 3; }\ndefault_action accept;\n",
    );
    assert_eq!(v.statuses(), [(STOP, 1)]);
    assert_eq!(v.writes(), [LogWrite::End]);
    v.from(AUTOPILOT, &heartbeat(3, true));
    assert_eq!(v.statuses(), [(START, 1)]);
    assert_eq!(v.writes(), [LogWrite::Begin(Protocol::Dataflash)]);
    reload(&mut v, "udp { port 14550; }\ndefault_action accept;\n");
    assert_eq!(v.statuses(), [(STOP, 1)]);
    assert_eq!(v.writes(), [LogWrite::End]);
    assert!(v.e.flight_log_counters().is_none());
}

mod props {
    //! The state machine under arbitrary streams (as the `flight_log` fuzz target):
    //! Begin and End in turn, ordered data only inside a log, frames that parse, and
    //! never a deadline that would make the loop spin.

    use std::time::Duration;

    use mavtables::config::{FlightLog, FlightLogMode};
    use mavtables::flight_log::{FlightLogger, LogWrite};
    use mavtables::routing::Timestamp;
    use mavtables::wire::Frame;
    use proptest::prelude::*;

    use super::encode;

    #[derive(Debug, Clone)]
    enum Op {
        Beat(u8, bool),
        Block(u32),
        Chunk(bool, u16, u8, u8),
        Wait(u16),
        Shutdown,
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            (prop::sample::select(vec![3u8, 12, 8]), any::<bool>())
                .prop_map(|(a, b)| Op::Beat(a, b)),
            prop_oneof![0u32..80, any::<u32>()].prop_map(Op::Block),
            (any::<bool>(), 0u16..40, any::<u8>(), any::<u8>())
                .prop_map(|(a, s, l, f)| Op::Chunk(a, s, l, f)),
            (0u16..3000).prop_map(Op::Wait),
            Just(Op::Shutdown),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn begin_and_end_alternate_and_time_moves_on(
            always in any::<bool>(),
            ops in prop::collection::vec(op(), 1..300),
        ) {
            let mut config = FlightLog::with_defaults();
            if always {
                config.mode = FlightLogMode::Always;
            }
            let mut log = FlightLogger::new(&config);
            let mut now = Timestamp::ZERO;
            let mut open = false;
            for op in ops {
                let bytes = match op {
                    Op::Beat(autopilot, armed) => {
                        let base = if armed { 129 } else { 1 };
                        Some(encode("1.1", 0, &[0, 0, 0, 0, 2, autopilot, base, 4, 3]))
                    }
                    Op::Block(seqno) => {
                        let mut p = seqno.to_le_bytes().to_vec();
                        p.extend_from_slice(&[245, 190]);
                        p.extend_from_slice(&[seqno as u8 | 1; 200]);
                        Some(encode("1.1", 184, &p))
                    }
                    Op::Chunk(acked, seq, len, first) => {
                        let mut p = seq.to_le_bytes().to_vec();
                        p.extend_from_slice(&[245, 190, len, first]);
                        p.extend_from_slice(&[7; 249]);
                        Some(encode("1.1", if acked { 267 } else { 266 }, &p))
                    }
                    Op::Wait(ms) => {
                        now = now + Duration::from_millis(u64::from(ms));
                        if log.poll_timeout().is_some_and(|t| t <= now) {
                            log.handle_timeout(now);
                            prop_assert!(log.poll_timeout().is_none_or(|t| t > now));
                        }
                        None
                    }
                    Op::Shutdown => {
                        log.shutdown(now);
                        None
                    }
                };
                if let Some(b) = bytes {
                    let f = Frame::parse_exact(&b).expect("valid frame");
                    log.take(&f, now);
                }
                let mut ok = true;
                log.drain_frames(&mut |f| ok &= Frame::parse_exact(&f).is_ok());
                prop_assert!(ok);
                let mut order = Ok(());
                log.drain_writes(&mut |w| {
                    let fine = match w {
                        LogWrite::Begin(_) => !std::mem::replace(&mut open, true),
                        LogWrite::End => std::mem::replace(&mut open, false),
                        LogWrite::Data { .. } => open,
                    };
                    if !fine && order.is_ok() {
                        order = Err(format!("{w:?} out of turn"));
                    }
                });
                prop_assert!(order.is_ok(), "{:?}", order);
            }
        }
    }
}

/// At shutdown (or a reload that ends the log), blocks received and acknowledged behind
/// a gap go to the file in order, the gap given up: the autopilot will not send them
/// again, so dropping them would lose them for good.
#[test]
fn blocks_held_behind_a_gap_end_the_file_when_the_log_stops() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in (0..3).chain(4..10) {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    assert_eq!(data(&v.writes()).0, expected(0..3), "4–9 wait behind 3");
    v.e.stop_flight_log(v.now);
    let writes = v.writes();
    assert_eq!(writes.last(), Some(&LogWrite::End));
    assert_eq!(data(&writes).0, expected(4..10));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.blocks, c.lost), (9, 1));
}

#[test]
fn a_block_of_the_log_before_still_on_its_way_stays_out_of_the_new_file() {
    let mut v = after_a_long_log();
    v.statuses();
    // The autopilot rebooted: its new log's block 0, then one of the old log's last
    // blocks, reordered behind it, then the new log goes on.
    v.from(AUTOPILOT, &block(0, "245.190"));
    v.from(AUTOPILOT, &block(1100, "245.190"));
    v.from(AUTOPILOT, &block(1, "245.190"));
    v.from(AUTOPILOT, &block(2, "245.190"));
    let writes = v.writes();
    let begins = writes
        .iter()
        .filter(|w| matches!(w, LogWrite::Begin(_)))
        .count();
    assert_eq!(
        (writes[0].clone(), begins),
        (LogWrite::End, 1),
        "{writes:?}"
    );
    assert_eq!(data(&writes).0, expected(0..3), "only the new log's blocks");
    assert_eq!(
        v.statuses(),
        [(0, 1), (1, 1), (2, 1)],
        "the old block is not acked"
    );
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.late, c.lost, c.logs), (1, 0, 2));
    // Two seconds on, a block that far ahead is the new log's own gap again.
    v.wait(Duration::from_millis(2100));
    v.from(AUTOPILOT, &heartbeat(3, false));
    v.from(AUTOPILOT, &block(1101, "245.190"));
    assert!(v.statuses().contains(&(1101, 1)));
}

#[test]
fn a_gap_in_a_new_log_near_where_the_log_before_ended_is_the_new_logs_own() {
    // The log before got to block 99; the new one loses 40 to 70. Block 71 lies nearer
    // to 99 than to 40, and is still the new log's: acknowledged, the gap asked for.
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in 0..100 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    v.wait(Duration::from_millis(1100));
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.writes();
    v.statuses();
    for s in (0..40).chain(71..81) {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    let statuses = v.statuses();
    assert!(
        statuses.contains(&(71, 1)) && statuses.contains(&(40, 0)),
        "{statuses:?}"
    );
    for s in 40..71 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    let writes = v.writes();
    assert_eq!(
        writes[..2],
        [LogWrite::End, LogWrite::Begin(Protocol::Dataflash)]
    );
    assert_eq!(data(&writes).0, expected(0..81));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!(c.late, 0);
}

#[test]
fn a_gap_in_a_new_px4_log_near_where_the_log_before_ended_is_the_new_logs_own() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(12, true));
    for s in 0..100 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    v.wait(Duration::from_millis(1100));
    v.from(AUTOPILOT, &heartbeat(12, true));
    v.writes();
    for s in (0..40).chain(71..81) {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    let mut want = ulog_bytes(0..40);
    want.extend_from_slice(&ulog_bytes(71..81));
    assert_eq!(data(&v.writes()).0, want);
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.late, c.lost), (0, 31));
}

#[test]
fn a_chunk_of_the_px4_log_before_stays_out_of_the_new_file() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(12, true));
    for s in 0..300 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    v.wait(Duration::from_millis(1100));
    v.from(AUTOPILOT, &heartbeat(12, true));
    v.writes();
    // Answered from chunk 0 (a new log); a chunk of the old one comes late.
    v.from(AUTOPILOT, &ulog_chunk(0));
    v.from(AUTOPILOT, &ulog_chunk(300));
    for s in 1..4 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    let writes = v.writes();
    assert_eq!(
        writes[..2],
        [LogWrite::End, LogWrite::Begin(Protocol::Ulog)]
    );
    assert_eq!(data(&writes).0, ulog_bytes(0..4), "the new log whole");
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.late, c.lost, c.duplicates), (1, 0, 0));
}

/// Armed again while the last PX4 log drains: a chunk of that log, still on its way,
/// neither starts the new file nor shifts it (a new log begins with its file header).
#[test]
fn a_late_px4_chunk_does_not_start_the_next_log() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(12, true));
    for s in 0..100 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    v.from(AUTOPILOT, &heartbeat(12, false));
    v.wait(Duration::from_millis(300));
    v.from(AUTOPILOT, &heartbeat(12, true));
    v.writes();
    v.from(AUTOPILOT, &ulog_chunk(100));
    for s in 0..4 {
        v.from(AUTOPILOT, &ulog_chunk(s));
    }
    assert_eq!(data(&v.writes()), (ulog_bytes(0..4), 4));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!((c.late, c.duplicates), (1, 0));
}

/// The link came back after the autopilot went quiet for longer than the router waits
/// (its log ended) but not for as long as ArduPilot waits: it goes on with the blocks of
/// its log, which are written as a log joined under way, not dropped as strays.
#[test]
fn an_ardupilot_log_going_on_after_a_lost_link_is_written() {
    let mut v = after_a_long_log();
    v.wait(Duration::from_secs(6));
    v.from(AUTOPILOT, &heartbeat(3, false));
    v.writes();
    for s in 1100..1110 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    assert_eq!(data(&v.writes()).0, expected(1100..1110));
    let (c, _) = v.e.flight_log_counters().expect("configured");
    assert_eq!(c.late, 0);
}

/// Armed again while the last ArduPilot log drains: a block of that log still on its
/// way does not open a file of its own as a log joined under way; the new log is one
/// file from its block 0.
#[test]
fn a_late_dataflash_block_after_arming_again_does_not_open_a_file_of_its_own() {
    let mut v = Vehicle::new(CONF);
    v.from(AUTOPILOT, &heartbeat(3, true));
    for s in 0..1100 {
        v.from(AUTOPILOT, &block(s, "245.190"));
    }
    v.from(AUTOPILOT, &heartbeat(3, false));
    v.wait(Duration::from_millis(300));
    v.from(AUTOPILOT, &heartbeat(3, true));
    v.writes();
    v.from(AUTOPILOT, &block(1100, "245.190"));
    v.from(AUTOPILOT, &block(0, "245.190"));
    let writes = v.writes();
    let begins = writes
        .iter()
        .filter(|w| matches!(w, LogWrite::Begin(_)))
        .count();
    assert_eq!(begins, 0, "{writes:?}");
    assert!(!writes.contains(&LogWrite::End), "{writes:?}");
    assert_eq!(data(&writes).0, expected([0]));
}
