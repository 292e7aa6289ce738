//! The routing core as the event loop drives it, fed arbitrary input: datagrams from
//! three peers and bytes on a serial stream (raw, or well-formed frames built from the
//! input so that routing really happens), sending with any room and any outcome, time
//! passing, and the stream opening, failing and getting lost. Datagrams may go the
//! direct way the loop takes with light traffic (`handle_datagram_direct`), the held
//! packet then sent, failed, queued after all or left for the next call to settle.
//! Nothing panics, the queue bookkeeping stays exact, and after `handle_timeout(now)`
//! the next deadline lies in the future (the loop can never spin).
#![no_main]

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Duration;

use libfuzzer_sys::fuzz_target;
use mavtables::address::Address;
use mavtables::config;
use mavtables::routing::{Engine, InterfaceId, Notice, RouterOptions, Timestamp};
use mavtables::wire::encode::{Header, encode_v1, encode_v2};

const CONFIG: &str = "
default_action accept;
chain default {
    reject if HEARTBEAT from 9.9;
    accept with priority 7 if COMMAND_LONG;
    accept with priority -3 if ENCAPSULATED_DATA;
}
";

/// Messages the frame operation picks from (with and without targets, short and long).
const IDS: [u32; 6] = [0, 30, 76, 4, 131, 11];

/// Routes a datagram as the loop does: directly when `direct`, then does with the packet
/// the core holds what `how` says (send it, fail it, queue it, or leave it held).
fn datagram(
    e: &mut Engine,
    id: InterfaceId,
    peer: SocketAddr,
    bytes: &[u8],
    now: Timestamp,
    direct: bool,
    how: u8,
) {
    if !direct {
        e.handle_datagram(id, peer, bytes, now);
        return;
    }
    e.handle_datagram_direct(id, peer, bytes, now);
    let Some(to) = e.direct_interface() else {
        return;
    };
    if to != id {
        assert!(
            e.take_direct(id).is_none(),
            "a held packet is taken only by its interface"
        );
    }
    match how % 4 {
        0 => {
            if let Some(t) = e.take_direct(to) {
                e.on_sent_batch(std::iter::once(t));
            }
        }
        1 => {
            if let Some(t) = e.take_direct(to) {
                e.on_send_failed(to, &t, &std::io::Error::other("refused"));
            }
        }
        2 => e.queue_direct(),
        _ => {}
    }
}

fuzz_target!(|data: &[u8]| {
    let loaded = config::load(CONFIG).expect("the fuzz target's configuration is valid");
    let options = RouterOptions {
        queue_capacity: 3_000,
        total_queue_capacity: 8_000,
        event_level: 3,
        ..RouterOptions::default()
    };
    let mut e = Engine::new(&loaded.config, options);
    let mut now = Timestamp::ZERO;
    let serial = e.add_stream_interface("serial", &[Address::new(1, 1)], Some(57_600), 0, now);
    let udp = e.add_datagram_interface("udp".into(), 64_000, Default::default());
    // Without max_bitrate: its packets may go out directly.
    let udp_free = e.add_datagram_interface("udp free".into(), 0, Default::default());
    let limits = mavtables::config::PeerLimits {
        max_peers: 3,
        allow: Vec::new(),
    };
    let listener = e.add_listener("tcp".into(), limits, 32_000);
    let client = e.add_datagram_client("udp client".into(), "gcs", 0, now);
    let mut accepted: Vec<mavtables::routing::InterfaceId> = Vec::new();
    let peers: [SocketAddr; 3] = [1, 2, 3].map(|p| SocketAddr::from(([127, 0, 0, 1], p)));
    let mut queue = VecDeque::new();
    let mut rest = data;
    let mut take = |n: usize| -> &[u8] {
        let n = n.min(rest.len());
        let (head, tail) = rest.split_at(n);
        rest = tail;
        head
    };
    while let Some(&op) = take(1).first() {
        let arg = take(1).first().copied().unwrap_or(0);
        match op % 10 {
            0 => {
                let chunk = take(usize::from(arg)).to_vec();
                let how = take(1).first().copied().unwrap_or(0);
                let peer = peers[usize::from(op >> 3) % 3];
                let iface = if op & 0x40 != 0 { udp_free } else { udp };
                datagram(&mut e, iface, peer, &chunk, now, op & 0x20 != 0, how);
            }
            1 | 2 => {
                let id = IDS[usize::from(arg) % IDS.len()];
                let header = Header {
                    seq: arg,
                    system: op >> 4,
                    component: arg >> 4,
                };
                let payload = take(usize::from(arg % 48));
                let mut frame = Vec::new();
                let built = if arg & 0x80 != 0 {
                    encode_v1(header, id, payload, &mut frame)
                } else {
                    encode_v2(header, id, payload, None, &mut frame)
                };
                if built.is_ok() {
                    if op % 10 == 1 {
                        let how = take(1).first().copied().unwrap_or(0);
                        let peer = peers[usize::from(op >> 3) % 3];
                        let iface = if op & 0x40 != 0 { udp_free } else { udp };
                        datagram(&mut e, iface, peer, &frame, now, op & 0x20 != 0, how);
                    } else {
                        e.handle_stream(serial, &frame, now);
                    }
                }
            }
            3 => {
                let chunk = take(usize::from(arg));
                e.handle_stream(serial, chunk, now);
            }
            4 => {
                let iface = match (op & 8 == 0, op & 0x40 == 0) {
                    (true, true) => udp,
                    (true, false) => udp_free,
                    _ => serial,
                };
                e.poll_transmit(iface, now, usize::from(arg % 70), &mut queue);
                for (i, t) in queue.drain(..).enumerate() {
                    if (usize::from(op >> 4) >> (i % 4)) & 1 == 1 {
                        let error = std::io::Error::other("refused");
                        e.on_send_failed(iface, &t, &error);
                    } else {
                        e.on_sent(&t);
                    }
                }
            }
            5 => {
                now = now + Duration::from_micros(u64::from(arg) * u64::from(op));
                if now >= e.poll_timeout() {
                    e.handle_timeout(now);
                    assert!(e.poll_timeout() > now, "the loop would spin");
                }
            }
            6 => e.stream_lost(serial, now, &"unplugged"),
            7 => {
                let peer = peers[usize::from(arg) % 3];
                if let Some(id) = e.accept(listener, peer, now) {
                    accepted.push(id);
                }
            }
            8 => {
                let chunk = take(usize::from(arg));
                match accepted.get(usize::from(op >> 4) % accepted.len().max(1)) {
                    Some(&id) if op & 8 == 0 => e.handle_stream(id, chunk, now),
                    Some(&id) => {
                        e.poll_transmit(id, now, usize::from(arg % 5), &mut queue);
                        queue.drain(..).for_each(|t| e.on_sent(&t));
                    }
                    None => {}
                }
            }
            _ => {
                if arg & 1 == 0 {
                    e.set_target(client, peers[usize::from(arg >> 1) % 3]);
                    let chunk = take(usize::from(arg)).to_vec();
                    datagram(
                        &mut e,
                        client,
                        peers[0],
                        &chunk,
                        now,
                        op & 0x20 != 0,
                        arg >> 2,
                    );
                    e.poll_transmit(client, now, 8, &mut queue);
                    queue.drain(..).for_each(|t| e.on_sent(&t));
                } else if let Some(id) = accepted.pop() {
                    e.stream_lost(id, now, &"closed");
                }
            }
        }
        while let Some(notice) = e.poll_event() {
            match notice {
                Notice::Closed(iface) => accepted.retain(|a| *a != iface),
                Notice::Open(iface) if arg & 1 == 0 => e.stream_opened(iface, now),
                Notice::Open(iface) => e.stream_open_failed(iface, now, &"missing"),
                Notice::Log(event) => {
                    let _ = event.to_string();
                }
                _ => {}
            }
        }
        // A packet held for a direct send counts in the shared total but is in no
        // queue: the sum is checked when none is held.
        let router = e.router();
        let held: usize = router.links().map(|l| l.queue().bytes()).sum();
        if e.direct_interface().is_none() {
            assert_eq!(held, router.queued_bytes());
        }
        assert!(router.queued_bytes() <= 8_000);
    }
    let _ = e.report();
});
