//! The small harness shared by the benchmarks: interleaved rounds and medians.
#![allow(dead_code)]

use std::time::Duration;

/// Rounds to run: `full` under `cargo bench` (which passes `--bench`), one otherwise
/// (`cargo test --all-targets` runs each benchmark once as a smoke test).
pub fn rounds(full: usize) -> usize {
    if std::env::args().any(|a| a == "--bench") {
        full
    } else {
        1
    }
}

/// The median of `v` (sorts it).
pub fn median(v: &mut [Duration]) -> Duration {
    v.sort_unstable();
    v[v.len() / 2]
}

/// A router whose `links` UDP links have learned `addresses` systems each (systems 1,
/// 2, …, all component 1, by a HEARTBEAT), and one more link, `source`, for the packets
/// the benchmark routes: what the routing benchmarks offer each packet to.
pub struct LearnedRouter {
    /// The router, with empty queues.
    pub router: mavtables::routing::Router,
    /// The link the benchmark's packets come from.
    pub source: mavtables::routing::LinkId,
    /// The links that learned addresses.
    pub links: Vec<mavtables::routing::LinkId>,
}

impl LearnedRouter {
    /// The router of configuration `conf` with a verdict memo of `cache_slots` slots.
    pub fn new(conf: &str, cache_slots: usize, links: usize, addresses: usize) -> Self {
        use mavtables::routing::{Output, Router, RouterOptions, Timestamp};
        let config = mavtables::config::load(conf).expect("bench config").config;
        let options = RouterOptions {
            event_level: 0,
            cache_slots,
            ..RouterOptions::default()
        };
        let mut router = Router::with_options(&config, options);
        let mut out = Output::default();
        let now = Timestamp::ZERO;
        let mut ids = Vec::new();
        for l in 0..links {
            let id = router.add_udp_link(&format!("10.0.0.{l}:14550"), now);
            for a in 0..addresses {
                let system = u8::try_from(l * addresses + a + 1).expect("at most 255 systems");
                let f = encode(0, system, 1);
                let frame = mavtables::wire::Frame::parse_exact(&f).expect("frame");
                router.receive(id, &frame, now, &mut out);
            }
            ids.push(id);
        }
        let source = router.add_udp_link("10.0.1.1:14550", now);
        let mut r = LearnedRouter {
            router,
            source,
            links: ids,
        };
        r.drain();
        r
    }

    /// Empties every link's queue.
    pub fn drain(&mut self) {
        for &l in &self.links {
            while self.router.pop(l).is_some() {}
        }
    }
}

/// A v2 frame of message `id` (full length, payload bytes 0x55) from `system.component`.
pub fn encode(id: u32, system: u8, component: u8) -> Vec<u8> {
    use mavtables::wire::encode::{Header, encode_v2};
    let info = mavtables::dialect::by_id(id).expect("message");
    let payload = vec![0x55u8; info.max_len as usize];
    let mut out = Vec::new();
    let header = Header {
        seq: 0,
        system,
        component,
    };
    encode_v2(header, id, &payload, None, &mut out).expect("encode");
    out
}
