//! Direct sends (`Engine::handle_datagram_direct`) against the queue they skip: two
//! cores get the same datagrams, one through the usual path (queue, ready list,
//! `poll_transmit`), the other allowed to hold a packet out of its empty queue and have
//! it sent at once, its drivers now and then too busy to take it. Every link must get
//! the same packets in the same order, to the same peer, and every counter, queue
//! figure and statistic must be the same at every step.

use crate::routing;

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;

use mavtables::config::{self, PeerLimits};
use mavtables::dialect;
use mavtables::routing::{Engine, InterfaceId, LinkId, RouterOptions, Timestamp, Transmit};
use mavtables::wire::crc::frame_checksum;
use proptest::prelude::*;
use routing::frame;

/// Accepts most, at several priorities; rejects one message type for one system.
const CONFIG: &str = "chain default {\n    reject if PARAM_REQUEST_READ to 7.1;\n    \
    accept with priority 2 if ATTITUDE;\n    accept with priority -1 if to 9.1;\n    accept;\n}\n";

/// Messages of different lengths, and whether they have a target (the others are
/// broadcasts).
const KINDS: [(&str, bool); 5] = [
    ("HEARTBEAT", false),
    ("ATTITUDE", false),
    ("COMMAND_LONG", true),
    ("PARAM_REQUEST_READ", true),
    ("ENCAPSULATED_DATA", false),
];

/// Peers of the server interface; after them, the client's and the paced client's
/// remotes.
const SERVER_PEERS: u16 = 4;

/// One step of a run.
#[derive(Debug, Clone)]
enum Step {
    /// Peer `from` (a server peer, or after them a client's remote) sends a datagram of
    /// one or two frames: (kind, source system, target system or broadcast).
    Datagram {
        from: u16,
        frames: Vec<(usize, u8, Option<u8>)>,
    },
    /// Interface number `n` (of the three) is busy: its driver has something in flight
    /// until the next flush, so it can take nothing at once.
    Busy(usize),
    /// Every interface with output sends it (those not busy).
    Flush,
    /// Time passes (milliseconds), and the core's timers run.
    Wait(u64),
}

fn step() -> impl Strategy<Value = Step> {
    let frame = (0..KINDS.len(), 1u8..10, prop::option::of(1u8..10));
    prop_oneof![
        8 => (0..SERVER_PEERS + 2, prop::collection::vec(frame, 1..3))
            .prop_map(|(from, frames)| Step::Datagram { from, frames }),
        1 => (0usize..3).prop_map(Step::Busy),
        2 => Just(Step::Flush),
        1 => (0u64..150_000).prop_map(Step::Wait),
    ]
}

/// MAVLink 2 frame `f` of message `name` with sequence number `seq` (checksum anew).
fn with_seq(mut f: Vec<u8>, seq: u8, name: &str) -> Vec<u8> {
    let extra = dialect::by_name(name).expect("known message").crc_extra;
    f[4] = seq;
    let end = f.len() - 2;
    let crc = frame_checksum(&f[1..end], extra);
    f[end..].copy_from_slice(&crc.to_le_bytes());
    f
}

fn addr(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// What one link was sent: each packet with the peer it went to.
type Sent = Vec<(Option<SocketAddr>, Vec<u8>)>;

/// A core, its three interfaces, and what each link was sent.
struct Side {
    engine: Engine,
    /// Server, client, paced client.
    interfaces: [InterfaceId; 3],
    /// Interfaces whose driver has something in flight (until the next flush).
    busy: [bool; 3],
    /// Interfaces named while busy: sent from as soon as they are not (as the loop
    /// does when a blocked socket becomes writable).
    skipped: [bool; 3],
    sent: BTreeMap<LinkId, Sent>,
    /// The last sequence number of each source system.
    seq: [u8; 16],
}

impl Side {
    fn new(options: RouterOptions) -> Side {
        let loaded = config::load(CONFIG).expect("config loads");
        let mut engine = Engine::new(&loaded.config, options);
        let limits = PeerLimits {
            max_peers: 100,
            allow: Vec::new(),
        };
        let server = engine.add_datagram_interface("udp server".into(), 0, limits);
        let now = Timestamp::ZERO;
        let client = engine.add_datagram_client("udp client".into(), "client", 0, now);
        // Paced: never sent directly.
        let paced = engine.add_datagram_client("udp paced".into(), "paced", 100_000, now);
        for (id, port) in [(client, 20_001), (paced, 20_002)] {
            engine.stream_opened(id, now);
            engine.set_target(id, addr(port));
        }
        let mut side = Side {
            engine,
            interfaces: [server, client, paced],
            busy: [false; 3],
            skipped: [false; 3],
            sent: BTreeMap::new(),
            seq: [0; 16],
        };
        side.flush(now);
        side
    }

    fn record(&mut self, t: &Transmit) {
        self.sent
            .entry(t.link)
            .or_default()
            .push((t.to, t.packet.to_vec()));
    }

    /// Every interface the core names sends what it hands out, unless its driver is
    /// busy (then what it has waits in its queue).
    fn flush(&mut self, now: Timestamp) {
        let mut named: Vec<InterfaceId> = std::iter::from_fn(|| self.engine.poll_ready()).collect();
        for n in 0..3 {
            if self.skipped[n] && !self.busy[n] {
                self.skipped[n] = false;
                named.push(self.interfaces[n]);
            }
        }
        for id in named {
            let n = self.interfaces.iter().position(|&i| i == id);
            if let Some(n) = n.filter(|&n| self.busy[n]) {
                self.skipped[n] = true;
                continue;
            }
            let mut queue = VecDeque::new();
            loop {
                self.engine.poll_transmit(id, now, 8, &mut queue);
                if queue.is_empty() {
                    break;
                }
                for t in &queue {
                    self.record(t);
                }
                self.engine.on_sent_batch(queue.drain(..));
            }
        }
    }

    fn input(&mut self, from: SocketAddr, on: usize, bytes: &[u8], now: Timestamp, direct: bool) {
        let id = self.interfaces[on];
        if !direct {
            self.engine.handle_datagram(id, from, bytes, now);
            return;
        }
        self.engine.handle_datagram_direct(id, from, bytes, now);
        let Some(to) = self.engine.direct_interface() else {
            return;
        };
        let n = self.interfaces.iter().position(|&i| i == to).expect("ours");
        if self.busy[n] {
            self.engine.queue_direct();
        } else {
            let t = self.engine.take_direct(to).expect("held for it");
            self.record(&t);
            self.engine.on_sent_batch(std::iter::once(t));
        }
    }

    fn apply(&mut self, s: &Step, now: Timestamp, direct: bool) {
        match s {
            Step::Datagram { from, frames } => {
                let bytes: Vec<u8> = frames
                    .iter()
                    .flat_map(|&(kind, system, to)| {
                        let (name, targeted) = KINDS[kind];
                        let to = to.filter(|_| targeted).map(|t| format!("{t}.1"));
                        let f = frame(name, &format!("{system}.1"), to.as_deref());
                        // Sequence numbers with gaps and repeats, per sender.
                        let seq = &mut self.seq[usize::from(system)];
                        *seq = seq.wrapping_add(1 + system % 3);
                        with_seq(f, *seq, name)
                    })
                    .collect();
                let (on, peer) = match *from {
                    p if p < SERVER_PEERS => (0, addr(14_550 + p)),
                    p => (
                        usize::from(p - SERVER_PEERS) + 1,
                        addr(20_001 + p - SERVER_PEERS),
                    ),
                };
                self.input(peer, on, &bytes, now, direct);
                // As the loop does after every input.
                self.flush(now);
            }
            Step::Busy(n) => self.busy[*n] = true,
            Step::Flush => {
                self.busy = [false; 3];
                self.flush(now);
            }
            Step::Wait(_) => {
                self.engine.handle_timeout(now);
                self.flush(now);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn direct_sends_change_nothing_but_the_path(
        steps in prop::collection::vec(step(), 1..200),
        per_link in 1usize..20,
        shared in 2usize..40,
    ) {
        let options = routing::queue_options(per_link * 100, shared * 100);
        let mut usual = Side::new(options);
        let mut direct = Side::new(options);
        let mut now = Timestamp::ZERO;
        for (k, s) in steps.iter().enumerate() {
            if let Step::Wait(ms) = s {
                now = now + std::time::Duration::from_millis(*ms);
            }
            usual.apply(s, now, false);
            direct.apply(s, now, true);
            prop_assert_eq!(&usual.sent, &direct.sent, "step {}: {:?}", k, s);
            prop_assert_eq!(
                usual.engine.router().queued_bytes(),
                direct.engine.router().queued_bytes(),
                "step {}", k
            );
            prop_assert_eq!(usual.engine.report(), direct.engine.report(), "step {}", k);
            for (a, b) in usual.engine.router().links().zip(direct.engine.router().links()) {
                prop_assert_eq!(a.queue().len(), b.queue().len());
                prop_assert_eq!(a.queue().bytes(), b.queue().bytes());
            }
            // Every counter, the per-source tables and sequence gaps included.
            prop_assert_eq!(usual.engine.stats(now), direct.engine.stats(now), "step {}", k);
        }
    }
}
