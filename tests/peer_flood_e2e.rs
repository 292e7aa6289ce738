//! A flood of spoofed UDP sources cannot take the router's memory or its real peers'
//! traffic: 300,000 HEARTBEATs, each from another address of 127.0.0.0/8, arrive while
//! two real peers exchange 100 ATTITUDE/s. A server interface takes at most `max_peers`
//! remotes (128 by default); the rest are refused, counted and said once.
//!
//! Forged source addresses need a raw socket (`CAP_NET_RAW`, so root): the test is
//! `#[ignore]`d for a plain `cargo test`, `scripts/test` runs it, and without the
//! capability it fails saying so.

#![forbid(unsafe_code)]

mod common;

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use common::net::{heartbeat, number_of, numbered};
use common::router::{Router, Scratch, free_udp_port};
use mavtables::wire::Parser;
use socket2::{Domain, Protocol, Socket, Type};

const SPOOFED: u32 = 300_000;

/// An IPv4 + UDP datagram from `from` to `to` carrying `payload` (checksums left to the
/// kernel: IP's is filled in, UDP's 0 means none).
fn forged(from: SocketAddrV4, to: SocketAddrV4, payload: &[u8]) -> Vec<u8> {
    let total = 20 + 8 + payload.len();
    let mut p = Vec::with_capacity(total);
    p.extend_from_slice(&[0x45, 0]);
    p.extend_from_slice(&(total as u16).to_be_bytes());
    p.extend_from_slice(&[0, 0, 0x40, 0, 64, 17, 0, 0]);
    p.extend_from_slice(&from.ip().octets());
    p.extend_from_slice(&to.ip().octets());
    p.extend_from_slice(&from.port().to_be_bytes());
    p.extend_from_slice(&to.port().to_be_bytes());
    p.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
    p.extend_from_slice(&[0, 0]);
    p.extend_from_slice(payload);
    p
}

fn status_kib(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

#[test]
#[ignore = "needs root (CAP_NET_RAW) to forge source addresses; scripts/test runs it"]
fn spoofed_sources_neither_grow_memory_nor_cost_real_peers_a_frame() {
    let raw = Socket::new(
        Domain::IPV4,
        Type::RAW,
        Some(Protocol::from(libc::IPPROTO_RAW)),
    )
    .unwrap_or_else(|e| {
        panic!("no raw socket ({e}): forged source addresses need CAP_NET_RAW: run the tests as root (sudo scripts/test)")
    });
    raw.set_header_included_v4(true).expect("IP_HDRINCL");
    let s = Scratch::new("flood");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address 127.0.0.1; }}\ndefault_action accept;\n");
    let mut router = Router::start(&s, &config, 1);
    let pid = router.pid();
    let to = SocketAddrV4::new(Ipv4Addr::LOCALHOST, port);
    let (a, b) = (
        UdpSocket::bind("127.0.0.1:0").expect("bind"),
        UdpSocket::bind("127.0.0.1:0").expect("bind"),
    );
    b.send_to(&heartbeat(20), to).expect("send");
    router.wait_for("new component 20.1 on 127.0.0.1:");
    a.send_to(&heartbeat(10), to).expect("send");
    router.wait_for("new component 10.1 on 127.0.0.1:");
    let idle = status_kib(pid, "VmRSS:");

    // B reads all along (a real ground station does), in a thread of its own.
    let flooding = Arc::new(AtomicBool::new(true));
    let receiver = {
        let flooding = flooding.clone();
        thread::spawn(move || {
            b.set_read_timeout(Some(Duration::from_millis(100)))
                .expect("timeout");
            let mut parser = Parser::new();
            let mut got = Vec::new();
            let mut buf = [0u8; 2048];
            let mut quiet_since = Instant::now();
            // Until the flood is over and B has heard nothing for 2 s.
            while flooding.load(Ordering::Relaxed) || quiet_since.elapsed() < Duration::from_secs(2)
            {
                if let Ok(n) = b.recv(&mut buf) {
                    quiet_since = Instant::now();
                    parser.feed(&buf[..n], |f| {
                        if f.message_id() == 30 {
                            got.push(number_of(f.as_bytes()));
                        }
                    });
                }
            }
            got
        })
    };
    // The flood, paced at about 50,000 datagrams a second (6 s).
    let flood = {
        thread::spawn(move || {
            let hb = heartbeat(99);
            let dest: SocketAddr = to.into();
            for i in 0..SPOOFED {
                let ip = Ipv4Addr::new(127, 1 + (i >> 16) as u8, (i >> 8) as u8, i as u8);
                let from = SocketAddrV4::new(ip, 40_000 + (i % 1000) as u16);
                let _ = raw.send_to(&forged(from, to, &hb), &dest.into());
                if i % 1000 == 999 {
                    thread::sleep(Duration::from_millis(20));
                }
            }
        })
    };
    // Meanwhile A sends 100 ATTITUDE a second to B, through the router, until the flood
    // is over.
    let mut sent = 0u32;
    let start = Instant::now();
    while !flood.is_finished() || sent < 100 {
        a.send_to(&numbered(10, sent), to).expect("send");
        sent += 1;
        let next = start + Duration::from_millis(10) * sent;
        thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    flood.join().expect("flood");
    flooding.store(false, Ordering::Relaxed);
    let got = receiver.join().expect("receiver");
    let peak = status_kib(pid, "VmHWM:");
    let err = router.stop().stderr.join("\n");
    assert_eq!(
        got,
        (0..sent).collect::<Vec<_>>(),
        "B lost frames of A, in order; counters: {}",
        err.lines()
            .filter(|l| !l.starts_with("  127.1."))
            .collect::<Vec<_>>()
            .join("\n")
    );
    assert!(
        peak < idle + 4 * 1024,
        "peak RSS {peak} KiB against {idle} KiB idle"
    );
    // 126 spoofed remotes joined the 2 real ones; every other was refused and counted.
    let refused: u64 = err
        .split(" refused (max_peers)")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        refused >= u64::from(SPOOFED) - 126 - 1000,
        "refused {refused}: {err}"
    );
    assert_eq!(
        err.matches("new remotes are refused").count(),
        1,
        "said once: {err}"
    );
}
