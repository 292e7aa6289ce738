//! Arbitrary traffic on four links, arbitrary sending and arbitrary passing of time never
//! panic the routing core, and its queue bookkeeping stays exact: the shared byte count
//! equals what the queues hold and never passes the shared capacity.
//!
//! Input: a sequence of operations. An operation byte `op` picks link `(op >> 2) & 3`;
//! `op & 3` is 0–2 for "the link receives the next `n` bytes" (`n` the following byte,
//! fed to that link's own parser, every frame routed), and 3 for housekeeping: pop up to
//! `op >> 4` packets from the link, then let the following byte's worth of seconds pass
//! and run the core's tick (which may remove silent UDP links; they come back on their
//! next frame).
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavtables::address::Address;
use mavtables::config;
use mavtables::routing::{LinkId, Output, Router, RouterOptions, Timestamp};
use mavtables::wire::Parser;

const CONFIG: &str = "
default_action accept;
chain default {
    reject if HEARTBEAT from 9.9;
    call prio if to 1.0/8;
    goto slow if PING;
    accept with priority -3 if ENCAPSULATED_DATA;
}
chain prio {
    accept with priority 7 if COMMAND_LONG;
    accept with priority 2 if from 255.190;
}
chain slow {
    reject if from 3.3 to 4.4;
    accept with priority 1;
}
";

fuzz_target!(|data: &[u8]| {
    let loaded = config::load(CONFIG).expect("the fuzz target's configuration is valid");
    let options = RouterOptions {
        queue_capacity: 2_000,
        total_queue_capacity: 5_000,
        event_level: 3,
        ..RouterOptions::default()
    };
    let mut router = Router::with_options(&loaded.config, options);
    let mut out = Output::default();
    let mut now = Timestamp::ZERO;
    let serial = router.add_serial_link("serial", &[Address::new(1, 1)], now, &mut out);
    let names = ["udp:1", "udp:2", "udp:3"];
    let mut links: [Option<LinkId>; 4] = [None, None, None, Some(serial)];
    // Without the checksum check, so that random bytes make frames often enough to
    // exercise the core (which never looks at checksums).
    let mut parsers: [Parser; 4] = std::array::from_fn(|_| Parser::without_crc_check());
    let mut rest = data;
    while let Some((&op, tail)) = rest.split_first() {
        rest = tail;
        let k = usize::from((op >> 2) & 3);
        if op & 3 != 3 {
            let n = rest.first().map_or(0, |&n| usize::from(n)).min(rest.len().saturating_sub(1));
            let chunk = rest.get(1..1 + n).unwrap_or(&[]);
            rest = rest.get(1 + n..).unwrap_or(&[]);
            let id = *links[k].get_or_insert_with(|| router.add_udp_link(names[k], now));
            parsers[k].feed(chunk, |frame| router.receive(id, &frame, now, &mut out));
        } else {
            if let Some(id) = links[k] {
                for _ in 0..(op >> 4) {
                    if router.pop(id).is_none() {
                        break;
                    }
                }
            }
            let secs = rest.first().copied().unwrap_or(0);
            rest = rest.get(1..).unwrap_or(&[]);
            now = Timestamp::from_secs(now.since_start().as_secs() + u64::from(secs));
            for removed in router.tick(now) {
                for l in &mut links {
                    if *l == Some(removed) {
                        *l = None;
                    }
                }
            }
        }
        for event in &out.events {
            let _ = event.to_string();
        }
        out.clear();
        let held: usize = router.links().map(|l| l.queue().bytes()).sum();
        assert_eq!(held, router.queued_bytes());
        assert!(held <= 5_000);
    }
});
