//! The status page (`src/stats/page.html`) in a real browser: headless Chromium loads it
//! from the router's statistics endpoint while traffic flows, lets its scripts run, and
//! the rendered DOM is checked; a screenshot is saved and checked to be a plausible PNG.
//! A fixture server stands in for a router that stops answering and comes back.

use crate::common;

use common::browser;
use common::eventually;
use common::http_fixture::{Answer, HttpFixture};
use common::net::{attitude, heartbeat};
use common::router::{Scratch, free_udp_port};
use common::stats_router;
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

const PAGE: &str = include_str!("../../src/stats/page.html");

/// Statistics that change with each request `n`, in the shape the router serves (for
/// the fixture server).
fn stats(n: usize) -> String {
    let n = n as u64;
    let history: Vec<f64> = (0..(n + 20).min(300)).map(|i| (i % 7) as f64).collect();
    serde_json::json!({
        "version": 1, "uptime_s": 100 + n, "history_interval_s": 1,
        "links": [
            {"id": 1, "name": "127.0.0.1:40001", "interface": "udp 127.0.0.1:14550",
             "frames_in": 10 * n, "bytes_in": 170 * n, "frames_out": n, "bytes_out": 17 * n,
             "rate_in_fps": 10.0, "rate_out_fps": 1.0, "rate_in_bps": 1360.0, "rate_out_bps": 136.0,
             "drops": {"filter_rejected": n, "no_route": 0},
             "queue_bytes": 0, "queue_high_water": 85, "addresses": ["1.1", "1.154"],
             "history_in_fps": history, "history_out_fps": [1.0, 1.0, 0.0]},
            {"id": 2, "name": "/dev/ttyACM0", "interface": "serial /dev/ttyACM0",
             "frames_in": 0, "bytes_in": 0, "frames_out": 9 * n, "bytes_out": 153 * n,
             "rate_in_fps": 0.0, "rate_out_fps": 9.0, "rate_in_bps": 0.0, "rate_out_bps": 1224.0,
             "drops": {}, "queue_bytes": 17, "queue_high_water": 170, "addresses": [],
             "history_in_fps": [0.0], "history_out_fps": [9.0]}
        ],
        "interfaces": [{"label": "udp 127.0.0.1:14550", "frames": 10 * n, "bad_crc": 0,
                        "unknown_id": 0, "junk_bytes": 0, "io_errors": 0, "signing": null}],
        "chains": [{"name": "default", "rules": [
            {"text": "reject if <b>HEARTBEAT</b> from 2.0/8", "packets": n, "bytes": 17 * n,
             "decided": n},
            {"text": "accept", "packets": 9 * n, "bytes": 153 * n, "decided": 9 * n}]}],
        "default_action": {"action": "reject", "packets": 0, "bytes": 0},
        "sources": [{"source": "1.1", "message": "ATTITUDE", "frames": 10 * n, "rate_fps": 10.0}],
        "sequence_gaps": [{"source": "1.1", "received": 10 * n, "lost": 2}],
        "recording": null
    })
    .to_string()
}

/// A server of the page at `/` and of [`stats`] at `/stats`, where the `n`th request
/// for `/stats` (from 1) finds nobody when `down(n)`.
fn serve(down: impl Fn(usize) -> bool + Send + 'static) -> HttpFixture {
    let asked = AtomicUsize::new(0);
    HttpFixture::start(
        move |path, _| match path.split('?').next().unwrap_or(path) {
            "/" => Answer::Http(200, "text/html; charset=utf-8", PAGE.as_bytes().to_vec()),
            "/stats" => {
                let n = asked.fetch_add(1, Ordering::SeqCst) + 1;
                if down(n) {
                    Answer::Close
                } else {
                    Answer::Http(200, "application/json", stats(n).into_bytes())
                }
            }
            _ => Answer::Http(404, "text/plain", b"not found".to_vec()),
        },
    )
}

/// The value of attribute `name` in the first tag of `dom` that starts with `tag_start`.
fn attribute<'a>(dom: &'a str, tag_start: &str, name: &str) -> Option<&'a str> {
    let at = dom.find(tag_start)?;
    let tag = &dom[at..at + dom[at..].find('>')?];
    let key = format!(" {name}=\"");
    let from = tag.find(&key)? + key.len();
    Some(&tag[from..from + tag[from..].find('"')?])
}

/// Text of the first element of `dom` whose opening tag contains `marker`.
fn text_after<'a>(dom: &'a str, marker: &str) -> Option<&'a str> {
    let at = dom.find(marker)?;
    let open_end = at + dom[at..].find('>')? + 1;
    Some(&dom[open_end..open_end + dom[open_end..].find('<')?])
}

/// Row of the link `name` in the links table of `dom`.
fn row<'a>(dom: &'a str, name: &str) -> &'a str {
    let start = format!("<tr data-link=\"{name}\"");
    let at = dom
        .find(&start)
        .unwrap_or_else(|| panic!("no row for {name}: {dom}"));
    let rest = &dom[at..];
    &rest[..rest.find("</tr>").unwrap_or(rest.len())]
}

/// Chart card of the selected link `name` in `dom`: its section.
fn card<'a>(dom: &'a str, name: &str) -> &'a str {
    let start = format!("<section class=\"chart-card\" data-chart=\"{name}\"");
    let at = dom
        .find(&start)
        .unwrap_or_else(|| panic!("no chart for {name}: {dom}"));
    let rest = &dom[at..];
    &rest[..rest.find("</section>").unwrap_or(rest.len())]
}

#[test]
fn shows_links_rules_and_charts_while_traffic_flows() {
    let scratch = Scratch::new("page");
    let (air, ground) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ address 127.0.0.1; port {air}; }}\n\
         udp {{ address 127.0.0.1; port {ground}; }}\n\
         chain default {{\n    reject if HEARTBEAT from 2.0/8;\n    \
         accept with priority 3 if ATTITUDE;\n    accept;\n}}\n\
         default_action reject;\n"
    );
    let (_router, port) = stats_router::start(&scratch, &config);
    let peer = |to: u16| {
        let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
        s.connect(("127.0.0.1", to)).expect("connect");
        s
    };
    let (gcs, vehicle, intruder) = (peer(ground), peer(air), peer(air));
    let name = |s: &UdpSocket| s.local_addr().expect("addr").to_string();
    let (g, v, x) = (name(&gcs), name(&vehicle), name(&intruder));
    gcs.send(&heartbeat(255)).expect("send");
    eventually("the ground station's link", Duration::from_secs(10), || {
        stats_router::stats(port)["links"]
            .as_array()
            .is_some_and(|l| l.len() == 1)
    });
    for _ in 0..3 {
        intruder.send(&heartbeat(2)).expect("send");
    }
    // The vehicle streams ATTITUDE at 20 Hz until the test ends.
    let stop = Arc::new(AtomicBool::new(false));
    let stopper = Arc::clone(&stop);
    let streamer = std::thread::spawn(move || {
        let mut n = 0u8;
        while !stopper.load(Ordering::SeqCst) {
            let _ = vehicle.send(&attitude(1, n));
            n = n.wrapping_add(1);
            std::thread::sleep(Duration::from_millis(50));
        }
    });
    eventually("the vehicle's rate", Duration::from_secs(10), || {
        let s = stats_router::stats(port);
        s["links"].as_array().is_some_and(|links| {
            links
                .iter()
                .any(|l| l["name"] == v.as_str() && l["rate_in_fps"].as_f64() > Some(0.0))
        })
    });

    // The three links selected in the address's fragment, so that each is charted.
    let url = format!("http://127.0.0.1:{port}/#sel={g}&sel={v}&sel={x}");
    let dom = browser::dom(&scratch, &url, 4000);
    assert_eq!(
        attribute(&dom, "<span id=\"state\"", "class"),
        Some("live"),
        "{dom}"
    );
    // A row per link, named as the router names it; a chart of its history for each
    // selected one.
    for link in [&g, &v, &x] {
        let c = card(&dom, link);
        let points: usize = attribute(c, "<svg class=\"chart\"", "data-points")
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no chart for {link}: {c}"));
        assert!(points > 0, "{link}: empty chart");
        assert!(c.contains("<polyline class=\"in\" points=\""), "{c}");
    }
    // The vehicle sends, the ground station receives: non-zero rates on both cards.
    let rate = |c: &str, class: &str| -> f64 {
        text_after(c, &format!("class=\"n {class}\""))
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("no {class} in {c}"))
    };
    assert!(rate(row(&dom, &v), "rate-in-fps") > 0.0, "{dom}");
    assert!(rate(row(&dom, &g), "rate-out-fps") > 0.0, "{dom}");
    assert!(
        row(&dom, &v).contains("<td class=\"addr\">1.1</td>"),
        "{dom}"
    );
    // The intruder's HEARTBEATs were kept from the ground station: a link with drops.
    assert!(row(&dom, &g).contains("data-state=\"drops\""), "{dom}");
    assert!(row(&dom, &g).contains("title=\"filter rejected "), "{dom}");
    assert!(card(&dom, &g).contains("drops: filter rejected "), "{dom}");
    // The rules with their counters: the intruder's HEARTBEATs were rejected by rule 0,
    // the ATTITUDE stream accepted by rule 1.
    let counter = |rule: usize, class: &str| -> u64 {
        let row = format!("data-chain=\"default\" data-rule=\"{rule}\"");
        let at = dom
            .find(&row)
            .unwrap_or_else(|| panic!("no rule {rule}: {dom}"));
        text_after(&dom[at..], &format!("class=\"n {class}\""))
            .and_then(|t| t.replace(',', "").parse().ok())
            .unwrap_or_else(|| panic!("rule {rule} {class}"))
    };
    assert!(counter(0, "packets") >= 3 && counter(0, "decided") >= 3);
    assert!(counter(1, "packets") > 0 && counter(1, "decided") > 0);
    assert!(dom.contains("reject if HEARTBEAT from 2.0/8"), "{dom}");
    // Without a flight_log block its section says so.
    assert!(dom.contains("no flight_log block"), "{dom}");

    let png = scratch.dir.join("status-page.png");
    browser::screenshot(&scratch, &url, 3000, &png);
    stop.store(true, Ordering::SeqCst);
    let _ = streamer.join();
    browser::check_screenshot(&png, "MAVTABLES_KEEP_SCREENSHOT");
}

#[test]
fn says_when_the_router_does_not_answer_and_recovers() {
    let scratch = Scratch::new("page-down");
    // The 2nd to 4th requests for the statistics find nobody; the others are answered.
    let server = serve(|n| (2..=4).contains(&n));
    let url = format!("{}/", server.url());
    let dom = browser::dom(&scratch, &url, 8000);
    assert_eq!(
        attribute(&dom, "<span id=\"state\"", "class"),
        Some("live"),
        "{dom}"
    );
    assert_eq!(
        attribute(&dom, "<span id=\"state\"", "data-outages"),
        Some("1"),
        "{dom}"
    );
    assert!(server.requests.load(Ordering::SeqCst) > 6);

    // Stopped for good: the page says so and keeps the last figures, greyed out.
    let scratch2 = Scratch::new("page-gone");
    let server = serve(|n| n > 2);
    let dom = browser::dom(&scratch2, &format!("{}/", server.url()), 4000);
    assert_eq!(
        attribute(&dom, "<span id=\"state\"", "class"),
        Some("down"),
        "{dom}"
    );
    assert!(
        text_after(&dom, "<span id=\"state\"")
            .is_some_and(|t| t.starts_with("router not answering since ")),
        "{dom}"
    );
    assert_eq!(attribute(&dom, "<main id=\"main\"", "class"), Some("stale"));
    assert!(dom.contains("data-link=\"127.0.0.1:40001\""), "{dom}");
}
