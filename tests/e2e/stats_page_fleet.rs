//! The status page at fleet scale: a fixture serves `/stats` of 1,000 generated links
//! (tests/common/fleet.rs) and headless Chromium runs the page. A small driver script,
//! added to the page by the fixture, clicks and types as a user would and reports what
//! the page then shows (and how long its refreshes took) to the fixture's `/report`.

use crate::common;

use common::browser;
use common::fleet;
use common::http_fixture::{Answer, HttpFixture};
use common::router::Scratch;
use mavtables::stats::history_query::{HistoryQuery, percent_decode};
use serde_json::Value;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

const PAGE: &str = include_str!("../../src/stats/page.html");
const LINKS: usize = 1000;

/// Clicks and types on the page once it has drawn, then reports a JSON object of what
/// it saw after each step to `report?JSON`.
const DRIVER: &str = r##"<script>
"use strict";
(async () => {
  const out = {};
  const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
  const main = document.getElementById("main");
  const refreshes = () => Number(main.getAttribute("data-refreshes") || 0);
  const rows = () => [...document.querySelectorAll("#links tbody tr")].map((tr) =>
    [tr.getAttribute("data-link"), tr.getAttribute("data-state"),
     tr.querySelector(".rate-in-fps").textContent]);
  const note = () => document.getElementById("links-note");
  try {
    while (refreshes() < 1) await sleep(20);
    out.first = rows();
    out.total = note().getAttribute("data-total");
    out.hidden = note().getAttribute("data-hidden");
    document.querySelector('th[data-sort="in"]').click();
    out.in_desc = rows();
    document.querySelector('th[data-sort="in"]').click();
    out.in_asc = rows();
    out.in_asc_sort = document.querySelector('th[data-sort="in"]').getAttribute("aria-sort");
    const box = document.getElementById("filter");
    box.value = "10.0.3.";
    box.dispatchEvent(new Event("input"));
    out.filtered = rows();
    out.filtered_hidden = note().getAttribute("data-hidden");
    document.querySelector("#links tbody tr:nth-child(2)").click();
    // Its whole history comes with the next answer, asked for at once.
    const clicked = performance.now();
    const points = () => document.querySelector("#charts section[data-chart] svg.chart")?.getAttribute("data-points");
    while (points() !== "300" && performance.now() - clicked < 5000) await sleep(10);
    out.chart_ms = performance.now() - clicked;
    const chart = document.querySelector("#charts section[data-chart]");
    out.chart = chart && [chart.getAttribute("data-chart"),
      chart.querySelector("svg.chart").getAttribute("data-points"),
      chart.querySelectorAll("polyline").length];
    out.selected = [...document.querySelectorAll("#links tbody tr.sel")].map((tr) => tr.getAttribute("data-link"));
    out.hash = location.hash;
    // The rows must survive the next refreshes as they are, the very elements (a click
    // that spans a refresh lands on its row).
    const firstRow = document.querySelector("#links tbody tr");
    const seen = refreshes();
    while (refreshes() < seen + 2) await sleep(20);
    out.after_refresh = rows();
    out.same_row = document.querySelector("#links tbody tr") === firstRow;
    while (refreshes() < 10) await sleep(50);
    out.refresh_ms = main.getAttribute("data-refresh-ms");
  } catch (e) {
    out.error = String(e && e.stack || e);
  }
  fetch("report?" + encodeURIComponent(JSON.stringify(out)));
})();
</script>"##;

/// A fixture serving the page (with `driver` added) and the fleet's statistics; each
/// `/report?JSON` is sent to the returned receiver.
fn serve(driver: &'static str) -> (HttpFixture, mpsc::Receiver<Value>) {
    let pictures: Vec<Picture> = (1..=3).map(Picture::new).collect();
    let page = PAGE.replace("</body>", &format!("{driver}</body>"));
    let (tx, rx) = mpsc::channel();
    let tx = Arc::new(Mutex::new(tx));
    let server = HttpFixture::start(move |path, n| {
        if path == "/" || path.starts_with("/#") {
            Answer::Http(200, "text/html; charset=utf-8", page.clone().into_bytes())
        } else if path == "/stats" || path.starts_with("/stats?") {
            // As the router answers: the history the query asks for.
            let query = HistoryQuery::parse(path.split_once('?').map_or("", |(_, q)| q));
            // The counters move with each request, the order does not.
            let picture = &pictures[n % 3];
            let links: Vec<&str> = (0..LINKS)
                .map(|i| match query.last() {
                    Some(5) if !query.charts(&fleet::name(i)) => picture.short[i].as_str(),
                    _ => picture.full[i].as_str(),
                })
                .collect();
            let body = picture
                .frame
                .replace("\"@LINKS@\"", &format!("[{}]", links.join(",")));
            Answer::Http(200, "application/json", body.into_bytes())
        } else if let Some(q) = path.strip_prefix("/report?") {
            let text = percent_decode(q);
            let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
            let _ = tx.lock().map(|t| t.send(v));
            Answer::Http(200, "text/plain", b"ok".to_vec())
        } else {
            Answer::Http(404, "text/plain", b"not found".to_vec())
        }
    });
    (server, rx)
}

/// The fleet's statistics at one request, prepared so that the fixture's answers cost
/// next to nothing (its time is part of the refresh the page measures): each link's
/// JSON with 5 samples of history and with all 300, and the rest around them.
struct Picture {
    short: Vec<String>,
    full: Vec<String>,
    frame: String,
}

impl Picture {
    fn new(n: u64) -> Picture {
        let texts = |v: &Value| -> Vec<String> {
            v["links"]
                .as_array()
                .map(|l| l.iter().map(Value::to_string).collect())
                .unwrap_or_default()
        };
        let mut short = fleet::stats_window(LINKS, n, 300, |_| 5);
        let full = texts(&fleet::stats(LINKS, n, 300));
        let short_links = texts(&short);
        short["links"] = Value::String("@LINKS@".into());
        Picture {
            short: short_links,
            full,
            frame: short.to_string(),
        }
    }
}

/// The rows of a report step: (name, state, in/s text).
fn rows(report: &Value, step: &str) -> Vec<(String, String, String)> {
    report[step]
        .as_array()
        .unwrap_or_else(|| panic!("no {step} in {report}"))
        .iter()
        .map(|r| {
            let s = |i: usize| r[i].as_str().unwrap_or_default().to_string();
            (s(0), s(1), s(2))
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn a_thousand_links_table_sort_filter_charts_fragment_and_refresh_time() {
    let scratch = Scratch::new("page-fleet");
    let (server, reports) = serve(DRIVER);
    let browser = browser::open(&scratch, &format!("{}/", server.url()));
    let report = reports
        .recv_timeout(Duration::from_secs(60))
        .expect("the driver's report within 60 s");
    drop(browser);
    assert!(report.get("error").is_none(), "{report}");

    // 100 rows of 1,000, troubled first (each with its state), then the busiest.
    let first = rows(&report, "first");
    assert_eq!(first.len(), 100, "{report}");
    assert_eq!(report["total"], "1000");
    assert_eq!(report["hidden"], "900");
    let expected: Vec<(String, String)> = fleet::order(LINKS, |_| true)[..100]
        .iter()
        .map(|&i| (fleet::name(i), fleet::state(i).to_string()))
        .collect();
    let got: Vec<(String, String)> = first.iter().map(|r| (r.0.clone(), r.1.clone())).collect();
    assert_eq!(got, expected);
    let troubled = (0..LINKS).filter(|&i| fleet::troubled(i)).count();
    assert!(first[..troubled].iter().all(|r| r.1 != "ok"));
    assert_eq!(first[troubled].1, "ok");

    // A click on "in/s" sorts by it, the busiest first; another, the quietest first.
    let rate = |r: &(String, String, String)| r.2.parse::<f64>().expect("a rate");
    let desc = rows(&report, "in_desc");
    let mut busiest: Vec<usize> = (0..LINKS).collect();
    busiest.sort_by(|&a, &b| fleet::rate_in(b).total_cmp(&fleet::rate_in(a)));
    assert_eq!(desc[0].0, fleet::name(busiest[0]), "{report}");
    assert!(desc.windows(2).all(|w| rate(&w[0]) >= rate(&w[1])));
    let asc = rows(&report, "in_asc");
    assert!(asc.windows(2).all(|w| rate(&w[0]) <= rate(&w[1])));
    assert_eq!(asc[0].1, "silent");
    assert_eq!(report["in_asc_sort"], "ascending");

    // The filter narrows the table to the links 768 to 999 (10.0.3.x).
    let filtered = rows(&report, "filtered");
    assert_eq!(filtered.len(), 100);
    assert!(
        filtered.iter().all(|r| r.0.starts_with("10.0.3.")),
        "{report}"
    );
    assert_eq!(
        report["filtered_hidden"], "900",
        "132 beyond 100 and 768 others"
    );

    // Selecting the second row charts that link, from its 300 samples.
    let chosen = &filtered[1].0;
    assert_eq!(
        report["chart"][0].as_str(),
        Some(chosen.as_str()),
        "{report}"
    );
    assert_eq!(report["chart"][1], "300");
    assert_eq!(report["chart"][2], 2, "in and out");
    assert_eq!(report["selected"][0].as_str(), Some(chosen.as_str()));
    // Refreshes keep the view.
    let after: Vec<String> = rows(&report, "after_refresh")
        .into_iter()
        .map(|r| r.0)
        .collect();
    let before: Vec<String> = filtered.iter().map(|r| r.0.clone()).collect();
    assert_eq!(after, before);
    assert_eq!(report["same_row"], true, "{report}");

    // The whole refresh (request, JSON of 1,000 links with 300 samples each, drawing),
    // as the page measured it.
    let times: Vec<f64> = report["refresh_ms"]
        .as_str()
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect();
    assert!(times.len() >= 8, "{report}");
    let (med, max) = (
        median(times.clone()),
        times.iter().copied().fold(0.0, f64::max),
    );
    println!(
        "status page, 1,000 links: whole refresh median {med:.1} ms, max {max:.1} ms over {} refreshes",
        times.len()
    );
    assert!(med < 600.0, "median refresh {med} ms: {times:?}");

    // The fragment restores the view: reloaded from the address alone (no driver), the
    // page shows the same sort, filter and selection.
    let hash = report["hash"].as_str().expect("hash").to_string();
    assert!(
        hash.contains("sort=in") && hash.contains("dir=asc"),
        "{hash}"
    );
    assert!(
        hash.contains("filter=10.0.3.") && hash.contains("sel="),
        "{hash}"
    );
    let (plain, _) = serve("");
    let dom = browser::dom(&scratch, &format!("{}/{hash}", plain.url()), 3000);
    let names: Vec<&str> = dom
        .split("<tr data-link=\"")
        .skip(1)
        .filter_map(|r| r.split('"').next())
        .collect();
    assert_eq!(names, before, "the same rows in the same order");
    assert!(
        dom.contains(&format!("<tr data-link=\"{chosen}\" data-state=")),
        "{dom}"
    );
    assert!(
        dom.contains(&format!(
            "<section class=\"chart-card\" data-chart=\"{chosen}\""
        )),
        "{dom}"
    );
    let th = dom
        .split("<th ")
        .find(|t| t.starts_with("data-sort=\"in\""))
        .and_then(|t| t.split('>').next())
        .unwrap_or_else(|| panic!("no in/s header: {dom}"));
    assert!(th.contains("aria-sort=\"ascending\""), "{th}");

    // A screenshot for the docs: two troubled links charted (docs/status-page-fleet.png
    // is this, kept with MAVTABLES_KEEP_FLEET_SCREENSHOT=PATH).
    let png = scratch.dir.join("status-page-fleet.png");
    let shot = format!(
        "{}/#sel={}&sel={}",
        plain.url(),
        fleet::name(expected_first(0)),
        fleet::name(expected_first(1))
    );
    browser::screenshot(&scratch, &shot, 3000, &png);
    browser::check_screenshot(&png, "MAVTABLES_KEEP_FLEET_SCREENSHOT");
    drop(plain);
    drop(server);
}

/// The `k`th link of the fleet in the default order.
fn expected_first(k: usize) -> usize {
    fleet::order(LINKS, |_| true)[k]
}

#[test]
fn a_real_router_with_200_udp_links() {
    use common::net::heartbeat;
    use common::router::{BIN, free_udp_port};
    use common::stats_router;
    let scratch = Scratch::new("page-fleet-router");
    let udp = free_udp_port();
    // max_peers: the default 128 would turn peers away.
    let config = format!(
        "udp {{ address 127.0.0.1; port {udp}; max_peers 1000; }}\nchain default {{ accept; }}\n"
    );
    let (router, port) = stats_router::start(&scratch, &config);
    // 200 peers, each a vehicle of its own system id: 200 links.
    let peers: Vec<std::net::UdpSocket> = (1..=200u8)
        .map(|sys| {
            let s = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
            s.connect(("127.0.0.1", udp)).expect("connect");
            s.send(&heartbeat(sys)).expect("send");
            s
        })
        .collect();
    common::eventually("200 links", Duration::from_secs(20), || {
        stats_router::stats(port)["links"]
            .as_array()
            .is_some_and(|l| l.len() == 200)
    });

    // The page: 100 rows of 200, and it says so.
    let dom = browser::dom(&scratch, &format!("http://127.0.0.1:{port}/"), 3000);
    assert_eq!(dom.matches("<tr data-link=\"").count(), 100, "{dom}");
    assert!(
        dom.contains("data-total=\"200\" data-shown=\"100\" data-hidden=\"100\""),
        "{dom}"
    );

    // What the page asks for: 5 samples of history per link, all of the charted one's.
    let charted = peers[7].local_addr().expect("addr").to_string();
    let history = |l: &Value| l["history_in_fps"].as_array().map_or(0, Vec::len);
    common::eventually("more than 5 samples", Duration::from_secs(15), || {
        let len = stats_router::stats(port)["links"]
            .as_array()
            .map_or(0, |l| history(&l[0]));
        len > 6
    });
    let body = get(
        port,
        &format!("/stats?history=5&chart={}", charted.replace(':', "%3A")),
    );
    let answer: Value = serde_json::from_str(&body).expect("JSON");
    let links = answer["links"].as_array().expect("links");
    for l in links {
        let n = history(l);
        if l["name"] == charted.as_str() {
            assert!(n > 5, "{l}");
        } else {
            assert!(n <= 5, "{l}");
        }
    }

    // The command: 10 rows, 190 hidden; a filter by one peer's address finds its link.
    let run = |args: &[&str]| {
        let out = std::process::Command::new(BIN)
            .arg("stats")
            .args(["--url", &format!("http://127.0.0.1:{port}")])
            .args(args)
            .output()
            .expect("run mavtables stats");
        assert!(out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let out = run(&["--top", "10"]);
    let rows = out
        .lines()
        .skip_while(|l| !l.starts_with("link "))
        .skip(1)
        .take_while(|l| l.starts_with("127.0.0.1:"))
        .count();
    assert_eq!(rows, 10, "{out}");
    assert!(
        out.contains("(links: 10 of 200 shown; 190 more hidden by --top)"),
        "{out}"
    );
    let name = peers[41].local_addr().expect("addr").to_string();
    let out = run(&["--filter", &name]);
    let line = out
        .lines()
        .find(|l| l.starts_with(&name))
        .unwrap_or_else(|| panic!("no {name}: {out}"));
    assert!(line.ends_with(" 42.0") || line.contains(" 42."), "{line}");
    assert!(out.contains("199 not matching --filter"), "{out}");
    router.stop();
}

/// The body of `GET target` from the router's statistics endpoint on `port`.
fn get(port: u16, target: &str) -> String {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect");
    c.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    write!(c, "GET {target} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").expect("send");
    let mut answer = String::new();
    let _ = c.read_to_string(&mut answer);
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    answer
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_string())
        .unwrap_or_default()
}
