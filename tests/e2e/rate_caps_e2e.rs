//! `accept with rate 2/s if ATTITUDE to 254.0/8;` in the real router over real UDP
//! sockets: three vehicles send ATTITUDE at 50 Hz (and GPS_RAW_INT at 5 Hz) for 5 s; the
//! satellite ground station (254.190) gets each vehicle's ATTITUDE every 500 ms and every
//! GPS_RAW_INT, and `/stats` counts the rest as `rate_limited` on the rule.
//!
//! Tolerance, from counting: a cap passes the first frame at once and then one per
//! interval on a fixed schedule, so the passes of one vehicle are evenly spaced and
//! `(n − 1) / (last − first)` is the rate, off only by the jitter of the first and last
//! arrival (a few ms over 4.5 s: well within 2.00 ± 0.05). The exact long-run figure (a
//! minute, to the frame) is `tests/rate_caps.rs`, on a simulated clock.

use crate::common;

use std::collections::BTreeMap;
use std::net::UdpSocket;
use std::thread;
use std::time::{Duration, Instant};

use common::eventually;
use common::net::{frame, heartbeat};
use common::router::{Scratch, free_udp_port};
use common::stats_router;
use mavtables::wire::Parser;

const VEHICLES: u8 = 3;
const SECONDS: u64 = 5;

fn rule_counts(port: u16) -> (u64, u64) {
    let s = stats_router::stats(port);
    let rule = &s["chains"][0]["rules"][0];
    (
        rule["decided"].as_u64().unwrap_or(0),
        rule["rate_limited"].as_u64().unwrap_or(0),
    )
}

#[test]
fn three_vehicles_at_50_hz_reach_the_satellite_link_at_2_per_second_each() {
    let scratch = Scratch::new("rate-caps");
    let (vport, sport) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {vport}; address 127.0.0.1; }}\n\
         udp {{ port {sport}; address 127.0.0.1; }}\n\
         chain default {{\n    accept with rate 2/s if ATTITUDE to 254.0/8;\n    accept;\n}}\n"
    );
    let (_router, http) = stats_router::start(&scratch, &config);
    let sat = UdpSocket::bind("127.0.0.1:0").expect("bind");
    sat.send_to(&heartbeat(254), ("127.0.0.1", sport))
        .expect("send");
    eventually("the router knows 254.1", Duration::from_secs(10), || {
        let s = stats_router::stats(http);
        s["links"].as_array().is_some_and(|l| {
            l.iter().any(|l| {
                l["addresses"]
                    .as_array()
                    .is_some_and(|a| a.contains(&"254.1".into()))
            })
        })
    });
    // The vehicles' sender: absolute deadlines every 20 ms, so the load is 50 Hz each.
    let sender = thread::spawn(move || {
        let socks: Vec<UdpSocket> = (0..VEHICLES)
            .map(|_| UdpSocket::bind("127.0.0.1:0").expect("bind"))
            .collect();
        let start = Instant::now();
        for tick in 0..SECONDS * 50 {
            let due = start + Duration::from_millis(tick * 20);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                thread::sleep(wait);
            }
            for (v, s) in socks.iter().enumerate() {
                let sys = v as u8 + 1;
                let _ = s.send_to(&frame(30, sys, tick as u8, 7, 28), ("127.0.0.1", vport));
                if tick % 10 == 0 {
                    let _ = s.send_to(&frame(24, sys, tick as u8, 7, 30), ("127.0.0.1", vport));
                }
            }
        }
    });
    // The satellite station reads until 1.5 s after the sender is done.
    let mut passes: BTreeMap<u8, Vec<Instant>> = BTreeMap::new();
    let mut gps: BTreeMap<u8, usize> = BTreeMap::new();
    let mut parser = Parser::new();
    let mut buf = [0u8; 4096];
    sat.set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let mut done_at: Option<Instant> = None;
    while done_at.is_none_or(|d| d.elapsed() < Duration::from_millis(1500)) {
        if done_at.is_none() && sender.is_finished() {
            done_at = Some(Instant::now());
        }
        if let Ok(n) = sat.recv(&mut buf) {
            let now = Instant::now();
            parser.feed(&buf[..n], |f| {
                let sys = f.source().system;
                match f.message_id() {
                    30 => passes.entry(sys).or_default().push(now),
                    24 => *gps.entry(sys).or_default() += 1,
                    _ => {}
                }
            });
        }
    }
    sender.join().expect("sender");
    let mut passed = 0;
    for sys in 1..=VEHICLES {
        let times = passes.get(&sys).cloned().unwrap_or_default();
        let n = times.len();
        // 250 frames 20 ms apart span 4.98 s: schedule slots 0, 0.5, ..., 4.5 s.
        assert!((9..=11).contains(&n), "vehicle {sys}: {n} passes");
        let span = times[n - 1].duration_since(times[0]).as_secs_f64();
        let rate = (n - 1) as f64 / span;
        assert!(
            (rate - 2.0).abs() <= 0.05,
            "vehicle {sys}: {rate:.3}/s over {n} passes in {span:.3} s"
        );
        for w in times.windows(2) {
            let gap = w[1].duration_since(w[0]).as_millis();
            assert!((400..=600).contains(&gap), "vehicle {sys}: gap {gap} ms");
        }
        assert_eq!(
            gps.get(&sys),
            Some(&25),
            "vehicle {sys}: GPS_RAW_INT uncapped"
        );
        passed += n as u64;
    }
    // The rule decided every ATTITUDE for the satellite link; all but the passes were
    // dropped by its rate (the snapshot is at most a second old: wait for it).
    let want = (
        u64::from(VEHICLES) * SECONDS * 50,
        u64::from(VEHICLES) * SECONDS * 50 - passed,
    );
    eventually(
        "/stats counts every ATTITUDE",
        Duration::from_secs(5),
        || rule_counts(http) == want,
    );
}
