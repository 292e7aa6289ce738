//! The statistics endpoint of the live router: a scripted scenario through the real
//! binary (UDP sockets on 127.0.0.1 as a vehicle and a ground station), then `/stats`
//! JSON and `/metrics` — the latter read by the `prometheus_client` Python package's
//! own parser — must hold exactly what was sent, forwarded, filtered (per rule) and
//! dropped (per reason). A second test holds the endpoint with a silent client and a
//! slow reader while traffic flows: every frame is delivered and `/metrics` still
//! answers another client at once.
//!
//! Synchronisation is on events: frames arriving at a peer, and `/stats` polled
//! (bounded) until its counters show the last frame sent.

use crate::common;

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::thread;
use std::time::{Duration, Instant};

use common::eventually;
use common::net::{SECOND, frame, free_tcp_port, udp_frames};
use common::router::{Router, Scratch, free_udp_port};
use serde_json::Value;

/// `GET path` from the endpoint on `port`: the status code and the body.
fn get(port: u16, path: &str) -> (u16, String) {
    let s = TcpStream::connect(("127.0.0.1", port)).expect("connect to the endpoint");
    request(s, path)
}

/// `GET path` on the connection `s`: the status code and the body.
fn request(mut s: TcpStream, path: &str) -> (u16, String) {
    s.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    write!(s, "GET {path} HTTP/1.1\r\nHost: localhost\r\n\r\n").expect("request");
    let mut answer = Vec::new();
    s.read_to_end(&mut answer).expect("answer");
    let text = String::from_utf8(answer).expect("utf-8 answer");
    let (head, body) = text.split_once("\r\n\r\n").expect("a head and a body");
    let code = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("a status code");
    (code, body.to_string())
}

/// `/stats`, once the endpoint answers (it starts with the router).
fn stats(port: u16) -> Value {
    let s = eventually("the endpoint listening", 10 * SECOND, || {
        TcpStream::connect(("127.0.0.1", port)).ok()
    });
    let (code, body) = request(s, "/stats");
    assert_eq!(code, 200, "{body}");
    serde_json::from_str(&body).expect("/stats is JSON")
}

/// Polls `/stats` (bounded) until `done` holds; returns that snapshot.
fn stats_when(port: u16, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    eventually(what, 10 * SECOND, || {
        let s = stats(port);
        if done(&s) {
            Ok(s)
        } else {
            Err(format!("last /stats: {s:#}"))
        }
    })
}

/// The link named `name` of a `/stats` snapshot, if it has one.
fn find_link<'a>(s: &'a Value, name: &str) -> Option<&'a Value> {
    s["links"]
        .as_array()
        .and_then(|l| l.iter().find(|l| l["name"] == name))
}

/// The link named `name` of a `/stats` snapshot.
fn link<'a>(s: &'a Value, name: &str) -> &'a Value {
    find_link(s, name).unwrap_or_else(|| panic!("no link {name} in {s:#}"))
}

fn n(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("{v} is not a count"))
}

/// A peer socket on 127.0.0.1 and its link name in the router.
fn peer() -> (UdpSocket, String) {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let name = s.local_addr().expect("addr").to_string();
    (s, name)
}

const HEARTBEAT: u32 = 0;
const SYS_STATUS: u32 = 1;
const SYSTEM_TIME: u32 = 2;
const ATTITUDE: u32 = 30;
const VFR_HUD: u32 = 74;
const COMMAND_LONG: u32 = 76;

#[test]
fn counters_after_a_scripted_scenario_are_exact_in_json_and_prometheus() {
    let scratch = Scratch::new("stats");
    let (udp_port, http_port) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}
stats {{ port {http_port}; }}
default_action reject;
chain default {{
    reject if SYSTEM_TIME;
    call gcs if to 255.0/8;
    accept with priority 2 if HEARTBEAT;
    goto tail if from 1.0/8;
}}
chain gcs {{
    accept with priority 5 if ATTITUDE from 1.0/8;
}}
chain tail {{
    reject if SYS_STATUS;
}}
"
    );
    let router = Router::start(&scratch, &config, 0);
    let to = ("127.0.0.1", udp_port);
    let (gcs, gcs_name) = peer();
    let (vehicle, vehicle_name) = peer();

    // The ground station (255.1) speaks first: nobody else is there (no route).
    let gcs_hb = frame(HEARTBEAT, 255, 0, 3, 9);
    gcs.send_to(&gcs_hb, to).expect("send");
    stats_when(http_port, "the ground station's link", |s| {
        s["links"].as_array().is_some_and(|l| l.len() == 1)
    });
    // The vehicle (1.1): its heartbeat reaches the ground station (call gcs falls
    // through, then the HEARTBEAT rule accepts).
    let mut seq = 0u8;
    let vsend = |id: u32, fill: u8, len: usize, seq: &mut u8| -> usize {
        let f = frame(id, 1, *seq, fill, len);
        *seq = seq.wrapping_add(1);
        vehicle.send_to(&f, to).expect("send");
        f.len()
    };
    let hb_len = vsend(HEARTBEAT, 3, 9, &mut seq);
    assert_eq!(udp_frames(&gcs, 1, 5 * SECOND).len(), 1);
    // Three more heartbeats of the ground station reach the vehicle.
    for s in 1..=3 {
        gcs.send_to(&frame(HEARTBEAT, 255, s, 3, 9), to)
            .expect("send");
    }
    assert_eq!(udp_frames(&vehicle, 3, 5 * SECOND).len(), 3);

    // The vehicle's traffic for the ground station.
    let att_len = (0..10)
        .map(|_| vsend(ATTITUDE, 7, 28, &mut seq))
        .sum::<usize>();
    let time_len = (0..4)
        .map(|_| vsend(SYSTEM_TIME, 7, 12, &mut seq))
        .sum::<usize>();
    seq = seq.wrapping_add(3); // three frames "lost on the radio"
    let vfr_len = (0..3)
        .map(|_| vsend(VFR_HUD, 7, 20, &mut seq))
        .sum::<usize>();
    let status_len = (0..2)
        .map(|_| vsend(SYS_STATUS, 7, 31, &mut seq))
        .sum::<usize>();
    // COMMAND_LONG for 7.7 (target_system and target_component are fill bytes): no link
    // reaches system 7.
    vsend(COMMAND_LONG, 7, 33, &mut seq);
    // And one ATTITUDE with a broken checksum.
    let mut bad = frame(ATTITUDE, 1, seq, 7, 28);
    let last = bad.len() - 1;
    bad[last] ^= 0xFF;
    vehicle.send_to(&bad, to).expect("send");
    assert_eq!(udp_frames(&gcs, 10, 5 * SECOND).len(), 10);

    let s = stats_when(http_port, "every frame counted", |s| {
        let (Some(v), Some(g)) = (find_link(s, &vehicle_name), find_link(s, &gcs_name)) else {
            return false;
        };
        n(&v["frames_in"]) == 21 && n(&v["drops"]["bad_crc"]) == 1 && n(&g["frames_out"]) == 11
    });

    // Links: frames and bytes in both directions, addresses, drops by reason.
    let v = link(&s, &vehicle_name);
    let g = link(&s, &gcs_name);
    let vehicle_bytes = hb_len + att_len + time_len + vfr_len + status_len + 45;
    assert_eq!(n(&v["bytes_in"]), vehicle_bytes as u64);
    assert_eq!((n(&v["frames_out"]), n(&v["bytes_out"])), (3, 3 * 21));
    assert_eq!((n(&g["frames_in"]), n(&g["bytes_in"])), (4, 4 * 21));
    assert_eq!(n(&g["bytes_out"]), (hb_len + att_len) as u64);
    assert_eq!(v["addresses"], serde_json::json!(["1.1"]));
    assert_eq!(g["addresses"], serde_json::json!(["255.1"]));
    assert_eq!(v["interface"], format!("udp 127.0.0.1:{udp_port}"));
    let drops = |l: &Value| -> BTreeMap<String, u64> {
        l["drops"]
            .as_object()
            .expect("drops")
            .iter()
            .map(|(k, v)| (k.clone(), n(v)))
            .filter(|(_, v)| *v > 0)
            .collect()
    };
    let expect = |pairs: &[(&str, u64)]| -> BTreeMap<String, u64> {
        pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    };
    // The vehicle: one frame nobody reaches, one bad checksum.
    assert_eq!(drops(v), expect(&[("no_route", 1), ("bad_crc", 1)]));
    // The ground station: its first heartbeat went nowhere; 4 SYSTEM_TIME, 3 VFR_HUD
    // (default action) and 2 SYS_STATUS for it were rejected.
    assert_eq!(drops(g), expect(&[("no_route", 1), ("filter_rejected", 9)]));
    assert_eq!(v["drops"].as_object().map(|d| d.len()), Some(12));

    // Rules: packets (condition matched), bytes, decided.
    let rules: Vec<(String, String, u64, u64, u64)> = s["chains"]
        .as_array()
        .expect("chains")
        .iter()
        .flat_map(|c| {
            let chain = c["name"].as_str().unwrap_or("").to_string();
            c["rules"].as_array().expect("rules").iter().map(move |r| {
                (
                    chain.clone(),
                    r["text"].as_str().unwrap_or("").to_string(),
                    n(&r["packets"]),
                    n(&r["bytes"]),
                    n(&r["decided"]),
                )
            })
        })
        .collect();
    let row =
        |c: &str, t: &str, p: u64, b: usize, d: u64| (c.to_string(), t.to_string(), p, b as u64, d);
    let expected_rules = vec![
        row("default", "reject if SYSTEM_TIME", 4, time_len, 4),
        row(
            "default",
            "call gcs if to 255.0/8",
            16,
            hb_len + att_len + vfr_len + status_len,
            0,
        ),
        row(
            "default",
            "accept with priority 2 if HEARTBEAT",
            4,
            hb_len + 3 * 21,
            4,
        ),
        row(
            "default",
            "goto tail if from 1.0/8",
            5,
            vfr_len + status_len,
            0,
        ),
        row(
            "gcs",
            "accept with priority 5 if ATTITUDE from 1.0/8",
            10,
            att_len,
            10,
        ),
        row("tail", "reject if SYS_STATUS", 2, status_len, 2),
    ];
    assert_eq!(rules, expected_rules);
    assert_eq!(s["default_action"]["action"], "reject");
    assert_eq!(n(&s["default_action"]["packets"]), 3);
    assert_eq!(n(&s["default_action"]["bytes"]), vfr_len as u64);

    // Interfaces, sources, sequence gaps.
    let i = &s["interfaces"][0];
    assert_eq!(i["label"], format!("udp 127.0.0.1:{udp_port}"));
    assert_eq!((n(&i["frames"]), n(&i["bad_crc"])), (25, 1));
    let source = |src: &str, msg: &str| {
        s["sources"]
            .as_array()
            .and_then(|a| a.iter().find(|x| x["source"] == src && x["message"] == msg))
            .map_or(0, |x| n(&x["frames"]))
    };
    assert_eq!(source("1.1", "ATTITUDE"), 10);
    assert_eq!(source("1.1", "COMMAND_LONG"), 1);
    assert_eq!(source("255.1", "HEARTBEAT"), 4);
    assert_eq!(s["sources"].as_array().map(Vec::len), Some(7));
    assert_eq!(
        s["sequence_gaps"],
        serde_json::json!([
            {"source": "1.1", "received": 21, "lost": 3},
            {"source": "255.1", "received": 4, "lost": 0},
        ])
    );

    // The same numbers through prometheus_client's parser.
    let (code, metrics) = get(http_port, "/metrics");
    assert_eq!(code, 200);
    let parsed = common::run_py("prom_parse.py", &[], &metrics);
    let samples: Vec<Value> = parsed
        .lines()
        .map(|l| serde_json::from_str(l).expect("a sample"))
        .collect();
    let metric = |name: &str, labels: &[(&str, &str)]| -> f64 {
        let found: Vec<&Value> = samples
            .iter()
            .filter(|x| x["name"] == name && labels.iter().all(|(k, v)| x["labels"][*k] == *v))
            .collect();
        assert_eq!(found.len(), 1, "{name} {labels:?}: {found:?}");
        found[0]["value"].as_f64().expect("a value")
    };
    assert!(
        samples
            .iter()
            .filter(|x| x["name"].as_str().is_some_and(|n| n.ends_with("_total")))
            .all(|x| x["type"] == "counter")
    );
    assert_eq!(
        metric("mavtables_link_frames_in_total", &[("link", &vehicle_name)]),
        21.0
    );
    assert_eq!(
        metric("mavtables_link_frames_out_total", &[("link", &gcs_name)]),
        11.0
    );
    assert_eq!(
        metric(
            "mavtables_drops_total",
            &[("link", &gcs_name), ("reason", "filter_rejected")]
        ),
        9.0
    );
    assert_eq!(
        metric(
            "mavtables_drops_total",
            &[("link", &vehicle_name), ("reason", "no_route")]
        ),
        1.0
    );
    assert_eq!(
        metric(
            "mavtables_drops_total",
            &[("link", &vehicle_name), ("reason", "bad_crc")]
        ),
        1.0
    );
    for (k, (chain, text, packets, bytes, decided)) in expected_rules.iter().enumerate() {
        let index = expected_rules[..k]
            .iter()
            .filter(|r| r.0 == *chain)
            .count()
            .to_string();
        let labels = [("chain", chain.as_str()), ("rule", index.as_str())];
        assert_eq!(
            metric("mavtables_rule_packets_total", &labels),
            *packets as f64
        );
        assert_eq!(metric("mavtables_rule_bytes_total", &labels), *bytes as f64);
        assert_eq!(
            metric("mavtables_rule_decided_total", &labels),
            *decided as f64
        );
        let with_text = [("chain", chain.as_str()), ("text", text.as_str())];
        assert_eq!(
            metric("mavtables_rule_packets_total", &with_text),
            *packets as f64
        );
    }
    assert_eq!(
        metric(
            "mavtables_default_action_packets_total",
            &[("action", "reject")]
        ),
        3.0
    );
    assert_eq!(
        metric("mavtables_sequence_lost_total", &[("source", "1.1")]),
        3.0
    );
    assert!(metric("mavtables_uptime_seconds", &[]) > 0.0);

    // The status page and the errors.
    let (code, page) = get(http_port, "/");
    assert_eq!(code, 200);
    assert!(page.contains("<html"), "{page}");
    assert_eq!(get(http_port, "/nothing").0, 404);

    router.stop();
}

#[test]
fn silent_and_slow_clients_stall_neither_routing_nor_other_requests() {
    let scratch = Scratch::new("stats-slow");
    let (udp_port, http_port) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}\nstats {{ port {http_port}; }}\ndefault_action accept;\n"
    );
    let router = Router::start(&scratch, &config, 0);
    stats(http_port);
    // A client that connects and sends nothing, and one that asks and then reads its
    // answer a byte every 100 ms.
    let silent = TcpStream::connect(("127.0.0.1", http_port)).expect("connect");
    let mut slow = TcpStream::connect(("127.0.0.1", http_port)).expect("connect");
    slow.write_all(b"GET /stats HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .expect("request");
    // Another client is answered at once, though the silent one holds its place for
    // up to 2 s (a server of one connection at a time would make it wait that long).
    let start = Instant::now();
    let (code, metrics) = get(http_port, "/metrics");
    let took = start.elapsed();
    assert_eq!(code, 200);
    assert!(metrics.contains("mavtables_uptime_seconds"));
    assert!(
        took < Duration::from_millis(1500),
        "/metrics took {took:?} while a silent client was connected"
    );
    let slow_reader = thread::spawn(move || {
        let mut got = Vec::new();
        let mut byte = [0u8; 1];
        for _ in 0..15 {
            if slow.read(&mut byte).is_ok_and(|n| n == 1) {
                got.push(byte[0]);
            }
            thread::sleep(Duration::from_millis(100));
        }
        got
    });

    // Traffic between two peers meanwhile: every frame arrives.
    let (a, _) = peer();
    let (b, _) = peer();
    let to = ("127.0.0.1", udp_port);
    b.send_to(&frame(HEARTBEAT, 255, 0, 3, 9), to)
        .expect("send");
    stats_when(http_port, "the receiver's link", |s| {
        s["links"].as_array().is_some_and(|l| l.len() == 1)
    });
    let mut received = 0;
    for batch in 0..20u32 {
        for k in 0..100u32 {
            let f = frame(ATTITUDE, 1, (batch * 100 + k) as u8, 7, 28);
            a.send_to(&f, to).expect("send");
        }
        let got = udp_frames(&b, 100, 5 * SECOND).len();
        received += got;
        assert_eq!(got, 100, "batch {batch}");
    }
    assert_eq!(received, 2000);

    // And still after the traffic, with the slow reader still reading.
    let (code, metrics) = get(http_port, "/metrics");
    assert_eq!(code, 200);
    assert!(metrics.contains("mavtables_link_frames_in_total"));
    let got = slow_reader.join().expect("slow reader");
    assert!(got.starts_with(b"HTTP/1.1 200"), "{got:?}");
    drop(silent);
    router.stop();
}

/// The `stats` section of docs/configuration.md: its block is valid, and its JSON
/// example has exactly the fields the router writes (top level, link, interface).
#[test]
fn the_documented_block_and_json_are_the_real_ones() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("## `stats`")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("stats section");
    let blocks: Vec<&str> = section.split("```").skip(1).step_by(2).collect();
    let stats = mavtables::config::load(blocks[0])
        .expect("the documented block loads")
        .config
        .stats
        .expect("a stats endpoint");
    assert_eq!(stats.port, 9100);
    let example: Value = serde_json::from_str(blocks[1].trim_start_matches("json\n"))
        .expect("the documented JSON parses");
    let snapshot = mavtables::stats::StatsSnapshot {
        links: vec![Default::default()],
        interfaces: vec![Default::default()],
        chains: vec![mavtables::stats::ChainStats {
            rules: vec![Default::default()],
            ..Default::default()
        }],
        sources: vec![Default::default()],
        sequence_gaps: vec![Default::default()],
        ..Default::default()
    };
    let real = mavtables::stats::json::to_value(&snapshot);
    let keys = |v: &Value| -> Vec<String> {
        let mut k: Vec<String> = v.as_object().expect("an object").keys().cloned().collect();
        k.sort();
        k
    };
    assert_eq!(keys(&example), keys(&real));
    for part in ["links", "interfaces", "sources", "sequence_gaps"] {
        assert_eq!(keys(&example[part][0]), keys(&real[part][0]), "{part}");
    }
    assert_eq!(
        keys(&example["links"][0]["drops"]),
        keys(&real["links"][0]["drops"])
    );
    assert_eq!(
        keys(&example["chains"][0]["rules"][0]),
        keys(&real["chains"][0]["rules"][0])
    );
}

/// A router that records shows its recorder's counters in `/stats` and `/metrics`: every
/// frame it took in written, nothing dropped, the file it writes.
#[test]
fn the_recorder_counters_are_in_json_and_prometheus() {
    let scratch = Scratch::new("stats-rec");
    let (udp_port, http_port) = (free_udp_port(), free_tcp_port());
    let dir = scratch.dir.join("flights");
    let config = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}
stats {{ port {http_port}; }}
record {{ path {}/%Y%m%d-%H%M%S.tlog; min_free_bytes 0; }}
default_action accept;
",
        dir.display()
    );
    let router = Router::start(&scratch, &config, 0);
    let (vehicle, _) = peer();
    let frames: Vec<Vec<u8>> = (0..25u8).map(|i| frame(ATTITUDE, 1, i, 7, 28)).collect();
    for f in &frames {
        vehicle.send_to(f, ("127.0.0.1", udp_port)).expect("send");
    }
    let s = stats_when(http_port, "25 frames recorded", |s| {
        s["recording"]["written"].as_u64() == Some(25)
    });
    let r = &s["recording"];
    let bytes: u64 = frames.iter().map(|f| 8 + f.len() as u64).sum();
    assert_eq!(n(&r["bytes"]), bytes, "{r:#}");
    assert_eq!(n(&r["files"]), 1);
    for reason in ["dropped_queue_full", "dropped_disk", "dropped_no_space"] {
        assert_eq!(n(&r[reason]), 0, "{reason}: {r:#}");
    }
    let path = r["current_path"].as_str().expect("the file being written");
    assert!(path.starts_with(&dir.display().to_string()), "{path}");
    let (code, metrics) = get(http_port, "/metrics");
    assert_eq!(code, 200);
    assert!(
        metrics.contains("\nmavtables_recording_records_total 25\n"),
        "{metrics}"
    );
    assert!(
        metrics.contains(&format!("\nmavtables_recording_bytes_total {bytes}\n")),
        "{metrics}"
    );
    assert!(metrics.contains("mavtables_recording_dropped_total{reason=\"disk\"} 0\n"));
    drop(router);
}

/// A router with a UDP server and a `stats` endpoint, once the endpoint answers: its
/// scratch directory (kept while the router runs), the router and the endpoint's port.
fn endpoint_router(tag: &str) -> (Scratch, Router, u16) {
    let scratch = Scratch::new(tag);
    let (udp_port, http_port) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}\nstats {{ port {http_port}; }}\ndefault_action accept;\n"
    );
    let router = Router::start(&scratch, &config, 0);
    stats(http_port); // listening
    (scratch, router, http_port)
}

/// The `Content-Length` of the response head `head`.
fn content_length(head: &str) -> usize {
    head.lines()
        .find_map(|l| l.strip_prefix("Content-Length: "))
        .and_then(|n| n.parse().ok())
        .expect("Content-Length")
}

/// What the endpoint on `port` answers to the raw request `text`, whole.
fn raw(port: u16, text: &str) -> String {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connect to the endpoint");
    s.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    s.write_all(text.as_bytes()).expect("request");
    let mut answer = Vec::new();
    s.read_to_end(&mut answer).expect("answer");
    String::from_utf8(answer).expect("utf-8 answer")
}

/// HTTP as RFC 9110 and 9112 have it, in raw requests: `HEAD` gets `GET`'s status and
/// headers (its Content-Length too) and no body; the absolute form `GET
/// http://HOST:PORT/stats` is the same request as `GET /stats`; a method the endpoint
/// does not serve gets 405 naming the ones it does.
#[test]
fn head_and_the_absolute_form_are_understood() {
    let (_scratch, router, http_port) = endpoint_router("stats-http");
    for path in ["/stats", "/metrics", "/"] {
        let head = raw(
            http_port,
            &format!("HEAD {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"),
        );
        let (status, rest) = head.split_once("\r\n").expect("a status line");
        assert_eq!(status, "HTTP/1.1 200 OK", "HEAD {path}");
        assert!(rest.ends_with("\r\n\r\n"), "HEAD {path}: no body: {head:?}");
        let length = content_length(rest);
        assert!(length > 0, "HEAD {path}: the length GET's body would have");
    }
    let absolute = raw(
        http_port,
        &format!("GET http://127.0.0.1:{http_port}/stats HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"),
    );
    assert!(absolute.starts_with("HTTP/1.1 200 OK\r\n"), "{absolute}");
    let body = absolute.split_once("\r\n\r\n").expect("a body").1;
    let json: Value = serde_json::from_str(body).expect("/stats is JSON");
    assert!(json["links"].is_array(), "{json}");
    let post = raw(
        http_port,
        "POST /stats HTTP/1.1\r\nContent-Length: 0\r\n\r\n",
    );
    assert!(post.starts_with("HTTP/1.1 405 "), "{post}");
    assert!(post.contains("\r\nAllow: GET, HEAD\r\n"), "{post}");
    drop(router);
}

/// The whole answer reaches a client that sent more than the head (a body, or a second
/// request behind the first), and ends with a FIN: closing with that input unread
/// would make the kernel reset the connection, which cuts off what the client has not
/// read yet. A head whose lines end with a bare LF is understood (RFC 9112 lets a
/// server accept it), and one cut short by the client's end gets 400, not silence.
#[test]
fn answers_are_whole_whatever_the_client_sent_after_the_head() {
    let (_scratch, router, http_port) = endpoint_router("stats-linger");
    let body = "x".repeat(16 * 1024);
    let second = "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".repeat(400);
    for request in [
        format!(
            "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        ),
        format!("GET /stats HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n{second}"),
    ] {
        let mut s = TcpStream::connect(("127.0.0.1", http_port)).expect("connect");
        s.set_read_timeout(Some(5 * SECOND)).expect("timeout");
        s.write_all(request.as_bytes()).expect("request");
        let mut answer = Vec::new();
        s.read_to_end(&mut answer)
            .expect("the answer, ended by a FIN rather than a reset");
        let answer = String::from_utf8(answer).expect("utf-8");
        let (head, got) = answer.split_once("\r\n\r\n").expect("head and body");
        assert!(head.starts_with("HTTP/1.1 200 OK\r\n"), "{head}");
        assert_eq!(got.len(), content_length(head), "the whole body");
    }
    let many = raw(
        http_port,
        &format!("GET /stats HTTP/1.1\r\n{}\r\n", "X-A: b\r\n".repeat(70)),
    );
    assert!(
        many.starts_with("HTTP/1.1 431 Request Header Fields Too Large\r\n"),
        "{many}"
    );
    let bare = raw(http_port, "GET /stats HTTP/1.1\nHost: 127.0.0.1\n\n");
    assert!(bare.starts_with("HTTP/1.1 200 OK\r\n"), "{bare}");
    let mut s = TcpStream::connect(("127.0.0.1", http_port)).expect("connect");
    s.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    s.write_all(b"GET /stats HTTP/1.1\r\nHost: 127.0.0.1\r\n")
        .expect("request");
    s.shutdown(std::net::Shutdown::Write).expect("half-close");
    let mut cut = String::new();
    s.read_to_string(&mut cut).expect("answer");
    assert!(cut.starts_with("HTTP/1.1 400 Bad Request\r\n"), "{cut}");
    drop(router);
}
