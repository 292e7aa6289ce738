//! The status page (`src/stats/page.html`) in a real browser: headless Chromium loads it
//! over HTTP on 127.0.0.1 while the statistics change, lets its scripts run, and the
//! rendered DOM is checked; a screenshot is saved and checked to be a plausible PNG.

mod common;

use common::browser;
use common::http_fixture::{Answer, HttpFixture};
use common::router::Scratch;
use std::sync::atomic::{AtomicUsize, Ordering};

const PAGE: &str = include_str!("../src/stats/page.html");

/// Statistics that change with each request `n`, in the shape the router serves.
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
    HttpFixture::start(move |path, _| match path {
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
    })
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

#[test]
fn shows_links_rules_and_charts_live() {
    let scratch = Scratch::new("page");
    let server = serve(|_| false);
    let url = format!("{}/", server.url());
    let dom = browser::dom(&scratch, &url, 4000);
    assert_eq!(
        attribute(&dom, "<span id=\"state\"", "class"),
        Some("live"),
        "{dom}"
    );
    // Each link has its card with its name, and a chart of its history.
    for (name, points) in [("127.0.0.1:40001", None), ("/dev/ttyACM0", Some("1"))] {
        let card = format!("<section class=\"link\" data-link=\"{name}\"");
        let at = dom
            .find(&card)
            .unwrap_or_else(|| panic!("no card for {name}: {dom}"));
        let rest = &dom[at..];
        let rest = &rest[..rest[1..].find("<section").map_or(rest.len(), |i| i + 1)];
        let n: usize = attribute(rest, "<svg class=\"chart\"", "data-points")
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no chart for {name}: {rest}"));
        assert!(n > 0, "{name}: empty chart");
        if let Some(p) = points {
            assert_eq!(n.to_string(), p, "{name}");
        }
        assert!(rest.contains("<polyline class=\"in\" points=\""), "{rest}");
    }
    // The page asked more than once: the first link's history grew past its first size.
    let points: usize = attribute(&dom, "<svg class=\"chart\"", "data-points")
        .and_then(|p| p.parse().ok())
        .expect("points");
    assert!(points > 21, "the page did not refresh: {points} points");
    assert_eq!(text_after(&dom, "class=\"n rate-in-fps\""), Some("10.0"));
    assert_eq!(text_after(&dom, "class=\"n rate-out-fps\""), Some("1.0"));
    // Rules with their counters; the rule text is shown as text, never as markup.
    assert!(
        dom.contains("data-chain=\"default\" data-rule=\"0\""),
        "{dom}"
    );
    assert!(
        dom.contains("reject if &lt;b&gt;HEARTBEAT&lt;/b&gt; from 2.0/8"),
        "{dom}"
    );
    let packets: u64 = text_after(&dom, "class=\"n packets\"")
        .and_then(|t| t.replace(',', "").parse().ok())
        .expect("rule packets");
    assert!(packets > 1, "{packets}");
    assert!(dom.contains("drops: filter rejected"), "{dom}");

    let png = scratch.dir.join("status-page.png");
    browser::screenshot(&scratch, &url, 3000, &png);
    let bytes = std::fs::read(&png).expect("screenshot written");
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        bytes.len() > 20_000,
        "{} bytes: an empty page?",
        bytes.len()
    );
    if let Ok(keep) = std::env::var("MAVTABLES_KEEP_SCREENSHOT") {
        std::fs::copy(&png, keep).expect("keep screenshot");
    }
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
