//! The text `mavtables stats` prints from the router's `/stats` JSON, laid out like
//! `iptables -L -v -x`: every chain with one line per rule and its counters, the default
//! action, then a table of links. Exact numbers (no K/M rounding), so that scripts and
//! tests can compare them; fields the JSON lacks show as `-`.

use std::collections::HashMap;

use serde_json::Value;

use super::table::{Align, Table};

/// The drop reasons of a link, in the order they are listed, with their printed names.
const DROP_REASONS: &[(&str, &str)] = &[
    ("filter_rejected", "filter rejected"),
    ("no_route", "no route"),
    ("queue_full", "queue full"),
    ("send_error", "send error"),
    ("bad_crc", "bad checksum"),
    ("unknown_id", "unknown id"),
    ("bad_signature", "bad signature"),
    ("replayed", "replayed"),
    ("out_of_window", "out of window"),
    ("unsigned", "unsigned"),
    ("duplicate", "duplicate"),
];

/// Which rows of the links and sequence-gap tables are printed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct View {
    /// At most this many rows per table (`--top N`), troubled first, then the busiest.
    pub(crate) top: Option<usize>,
    /// Only rows whose link name, interface or addresses (or source, for sequence gaps)
    /// contain this text, ignoring case (`--filter TEXT`).
    pub(crate) filter: Option<String>,
}

impl View {
    /// Whether `text` passes the filter.
    fn matches(&self, texts: &[String]) -> bool {
        match &self.filter {
            None => true,
            Some(f) => {
                let f = f.to_lowercase();
                texts.iter().any(|t| t.to_lowercase().contains(&f))
            }
        }
    }

    /// Whether `link` passes the filter: its name, interface or one of its addresses.
    fn matches_link(&self, link: &Value) -> bool {
        if self.filter.is_none() {
            return true;
        }
        let mut texts = vec![text(link.get("name")), text(link.get("interface"))];
        texts.extend(list(link.get("addresses")).iter().map(|a| text(Some(a))));
        self.matches(&texts)
    }
}

/// The whole text for the statistics `stats` fetched from `source` (a URL), with the
/// rows `view` selects.
pub(crate) fn render(stats: &Value, source: &str, view: &View) -> String {
    let mut out = Vec::new();
    out.push(format!(
        "mavtables at {source}, up {}",
        uptime(stats.get("uptime_s"))
    ));
    chains(stats, &mut out);
    links(stats, view, &mut out);
    gaps(stats, view, &mut out);
    let mut text = out.join("\n");
    text.push('\n');
    text
}

fn chains(stats: &Value, out: &mut Vec<String>) {
    let columns = [
        ("packets", Align::Right),
        ("bytes", Align::Right),
        ("decided", Align::Right),
        ("rule", Align::Left),
    ];
    let mut tables = Vec::new();
    for chain in list(stats.get("chains")) {
        let mut table = Table::new(&columns);
        for rule in list(chain.get("rules")) {
            table.row(vec![
                int(rule.get("packets")),
                int(rule.get("bytes")),
                int(rule.get("decided")),
                text(rule.get("text")),
            ]);
        }
        tables.push((
            text(chain.get("name")),
            table,
            !list(chain.get("rules")).is_empty(),
        ));
    }
    // One set of widths for every chain, so their columns line up down the page.
    let mut widths = vec![0; columns.len()];
    for (_, table, _) in &tables {
        for (w, t) in widths.iter_mut().zip(table.widths()) {
            *w = (*w).max(t);
        }
    }
    for (name, table, has_rules) in &tables {
        out.push(String::new());
        out.push(format!("chain {name}"));
        if *has_rules {
            out.extend(table.lines(&widths, "  "));
        } else {
            out.push("  (no rules)".into());
        }
    }
    if let Some(default) = stats.get("default_action").filter(|d| d.is_object()) {
        out.push(String::new());
        out.push(format!(
            "default_action {}: {} packets, {} bytes",
            text(default.get("action")),
            int(default.get("packets")),
            int(default.get("bytes"))
        ));
    }
}

fn links(stats: &Value, view: &View, out: &mut Vec<String>) {
    out.push(String::new());
    let links = list(stats.get("links"));
    if links.is_empty() {
        out.push("links: none yet (a link appears when its peer sends)".into());
        return;
    }
    let lost = lost_by_source(stats);
    let mut rows: Vec<(&Value, State, f64)> = links
        .iter()
        .filter(|l| view.matches_link(l))
        .map(|l| (l, state(l, &lost), busy(l)))
        .collect();
    let matching = rows.len();
    // Troubled first, then the busiest; the router's order among equals.
    rows.sort_by(|a, b| {
        (a.1 == State::Ok)
            .cmp(&(b.1 == State::Ok))
            .then(b.2.total_cmp(&a.2))
    });
    rows.truncate(view.top.unwrap_or(usize::MAX));
    let mut table = Table::new(&[
        ("link", Align::Left),
        ("state", Align::Left),
        ("interface", Align::Left),
        ("frames in", Align::Right),
        ("frames out", Align::Right),
        ("in/s", Align::Right),
        ("out/s", Align::Right),
        ("in bit/s", Align::Right),
        ("out bit/s", Align::Right),
        ("drops", Align::Right),
        ("queue", Align::Right),
        ("high-water", Align::Right),
        ("addresses", Align::Left),
    ]);
    let mut details = Vec::new();
    for (link, state, _) in &rows {
        let name = text(link.get("name"));
        let reasons: Vec<String> = DROP_REASONS
            .iter()
            .filter_map(|(key, label)| {
                let n = link.get("drops")?.get(*key)?.as_u64()?;
                (n > 0).then(|| format!("{label} {n}"))
            })
            .collect();
        if !reasons.is_empty() {
            details.push(format!("  drops of {name}: {}", reasons.join(", ")));
        }
        let addresses: Vec<String> = list(link.get("addresses"))
            .iter()
            .map(|a| text(Some(a)))
            .collect();
        table.row(vec![
            name,
            state.name().into(),
            text(link.get("interface")),
            int(link.get("frames_in")),
            int(link.get("frames_out")),
            rate(link.get("rate_in_fps")),
            rate(link.get("rate_out_fps")),
            int(link.get("rate_in_bps")),
            int(link.get("rate_out_bps")),
            drop_total(link).to_string(),
            int(link.get("queue_bytes")),
            int(link.get("queue_high_water")),
            if addresses.is_empty() {
                "-".into()
            } else {
                addresses.join(", ")
            },
        ]);
    }
    if matching == 0 {
        out.push(format!("links: none of {} match the filter", links.len()));
    } else if !rows.is_empty() {
        out.extend(table.lines(&table.widths(), ""));
    }
    out.extend(details);
    if let Some(note) = hidden_note("links", links.len(), matching, rows.len()) {
        out.push(note);
    }
}

/// The line saying how many of `all` rows are not shown: `matching` passed the filter
/// and `shown` of them fit under `--top`. None when every row is shown.
fn hidden_note(what: &str, all: usize, matching: usize, shown: usize) -> Option<String> {
    let mut parts = Vec::new();
    if matching > shown {
        parts.push(format!("{} more hidden by --top", matching - shown));
    }
    if all > matching {
        parts.push(format!("{} not matching --filter", all - matching));
    }
    (!parts.is_empty()).then(|| format!("({what}: {} of {all} shown; {})", shown, parts.join(", ")))
}

/// What is wrong with a link, as the `state` column and the status page say it: the
/// first of `drops` (a frame of it was dropped since the router started), `gaps` (a
/// source learned on it lost frames: MAVLink sequence gaps), `silent` (it received no
/// frame over the last [`SILENT_SAMPLES`] samples of its rate history, 5 s at the
/// default one-second interval), else `ok`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum State {
    /// Nothing wrong.
    Ok,
    /// Frames of it were dropped.
    Drops,
    /// A source behind it lost frames.
    Gaps,
    /// It received nothing lately.
    Silent,
}

impl State {
    /// The word printed for it.
    pub(crate) fn name(self) -> &'static str {
        match self {
            State::Ok => "ok",
            State::Drops => "drops",
            State::Gaps => "gaps",
            State::Silent => "silent",
        }
    }
}

/// How many of the latest history samples without a received frame make a link silent.
pub(crate) const SILENT_SAMPLES: usize = 5;

/// The state of `link`, given the frames lost by each source.
fn state(link: &Value, lost: &HashMap<String, u64>) -> State {
    if drop_total(link) > 0 {
        return State::Drops;
    }
    let gaps: u64 = list(link.get("addresses"))
        .iter()
        .filter_map(|a| lost.get(a.as_str()?))
        .fold(0u64, |total, n| total.saturating_add(*n));
    if gaps > 0 {
        return State::Gaps;
    }
    let history = list(link.get("history_in_fps"));
    let recent = &history[history.len().saturating_sub(SILENT_SAMPLES)..];
    if !recent.is_empty() && recent.iter().all(|v| v.as_f64().is_none_or(|f| f <= 0.0)) {
        return State::Silent;
    }
    State::Ok
}

/// Frames lost by each source (`sequence_gaps`), by its `SYS.COMP` text.
fn lost_by_source(stats: &Value) -> HashMap<String, u64> {
    list(stats.get("sequence_gaps"))
        .iter()
        .filter_map(|g| {
            let lost = g.get("lost")?.as_u64()?;
            Some((g.get("source")?.as_str()?.to_string(), lost))
        })
        .filter(|(_, lost)| *lost > 0)
        .collect()
}

/// The drops of `link`, all reasons together.
fn drop_total(link: &Value) -> u64 {
    DROP_REASONS
        .iter()
        .filter_map(|(key, _)| link.get("drops")?.get(*key)?.as_u64())
        .fold(0, u64::saturating_add)
}

/// How busy `link` is: frames per second in and out together.
fn busy(link: &Value) -> f64 {
    let r = |k: &str| {
        link.get(k)
            .and_then(Value::as_f64)
            .filter(|f| f.is_finite())
            .unwrap_or(0.0)
    };
    r("rate_in_fps") + r("rate_out_fps")
}

/// One line per source that lost frames (MAVLink sequence gaps), the most lost first.
fn gaps(stats: &Value, view: &View, out: &mut Vec<String>) {
    let all: Vec<&Value> = list(stats.get("sequence_gaps"))
        .iter()
        .filter(|g| g.get("lost").and_then(Value::as_u64).is_some_and(|n| n > 0))
        .collect();
    let mut lossy: Vec<&Value> = all
        .iter()
        .copied()
        .filter(|g| view.matches(&[text(g.get("source"))]))
        .collect();
    let matching = lossy.len();
    lossy.sort_by_key(|g| std::cmp::Reverse(g.get("lost").and_then(Value::as_u64)));
    lossy.truncate(view.top.unwrap_or(usize::MAX));
    let note = hidden_note("sources", all.len(), matching, lossy.len());
    if lossy.is_empty() {
        out.extend(note);
        return;
    }
    out.push(String::new());
    let mut table = Table::new(&[
        ("source", Align::Left),
        ("received", Align::Right),
        ("lost", Align::Right),
    ]);
    for g in lossy {
        table.row(vec![
            text(g.get("source")),
            int(g.get("received")),
            int(g.get("lost")),
        ]);
    }
    out.push("sequence gaps".into());
    out.extend(table.lines(&table.widths(), "  "));
    out.extend(note);
}

/// The array `v` holds, or none.
fn list(v: Option<&Value>) -> &[Value] {
    v.and_then(Value::as_array).map_or(&[], Vec::as_slice)
}

/// A string as it is, any other value as JSON, a missing one as `-`. Control characters
/// are replaced, so a name from the network cannot move the terminal's cursor.
fn text(v: Option<&Value>) -> String {
    let raw = match v {
        Some(Value::String(s)) => s.clone(),
        Some(Value::Null) | None => "-".into(),
        Some(other) => other.to_string(),
    };
    raw.chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}

/// A whole number (a fractional one rounded), or `-`.
fn int(v: Option<&Value>) -> String {
    match v {
        Some(Value::Number(n)) => match (n.as_u64(), n.as_i64(), n.as_f64()) {
            (Some(u), _, _) => u.to_string(),
            (None, Some(i), _) => i.to_string(),
            (None, None, Some(f)) if f.is_finite() => format!("{:.0}", f),
            _ => "-".into(),
        },
        _ => "-".into(),
    }
}

/// A rate with one decimal, or `-`.
fn rate(v: Option<&Value>) -> String {
    match v.and_then(Value::as_f64) {
        Some(f) if f.is_finite() => format!("{f:.1}"),
        _ => "-".into(),
    }
}

/// Seconds as `H:MM:SS` (with days in front past a day), or `-`.
fn uptime(v: Option<&Value>) -> String {
    let Some(s) = v
        .and_then(Value::as_f64)
        .filter(|s| s.is_finite() && *s >= 0.0)
    else {
        return "-".into();
    };
    let s = s as u64;
    let (d, h, m, s) = (s / 86_400, s / 3600 % 24, s / 60 % 60, s % 60);
    if d > 0 {
        format!("{d}d {h:02}:{m:02}:{s:02}")
    } else {
        format!("{h}:{m:02}:{s:02}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn counters_near_the_top_of_u64_add_up_without_overflow() {
        let link = json!({
            "drops": {"filter_rejected": u64::MAX, "no_route": 1, "queue_full": 0},
            "addresses": ["1.1", "2.1"],
        });
        assert_eq!(drop_total(&link), u64::MAX);
        let lost = HashMap::from([("1.1".to_string(), u64::MAX), ("2.1".to_string(), 5)]);
        let quiet = json!({"addresses": ["1.1", "2.1"]});
        assert!(matches!(state(&quiet, &lost), State::Gaps));
    }

    #[test]
    fn the_contracts_example() {
        let stats = json!({
            "version": 1, "uptime_s": 3725.5, "history_interval_s": 1,
            "links": [{
                "id": 3, "name": "127.0.0.1:41219", "interface": "udp 0.0.0.0:14550",
                "frames_in": 120, "bytes_in": 4080, "frames_out": 118, "bytes_out": 4012,
                "rate_in_fps": 10.0, "rate_out_fps": 9.8, "rate_in_bps": 2720.0,
                "rate_out_bps": 2670.4,
                "drops": {"filter_rejected": 3, "no_route": 1, "queue_full": 0},
                "queue_bytes": 0, "queue_high_water": 312,
                "addresses": ["1.1", "255.190"],
                "history_in_fps": [9.0], "history_out_fps": [9.0]
            }, {"id": 4, "name": "bad\u{1b}[2Jname", "addresses": []}],
            "chains": [
                {"name": "default", "rules": [
                    {"text": "accept with priority 3 if PING from 1.0/8", "packets": 10,
                     "bytes": 280, "decided": 10},
                    {"text": "call gcs", "packets": 1234567, "bytes": 2, "decided": 0}]},
                {"name": "gcs", "rules": []}
            ],
            "default_action": {"action": "reject", "packets": 2, "bytes": 40},
            "sequence_gaps": [{"source": "1.1", "received": 120, "lost": 3},
                              {"source": "2.1", "received": 5, "lost": 0}]
        });
        let expected = "\
mavtables at http://127.0.0.1:9100/stats, up 1:02:05

chain default
  packets  bytes  decided  rule
       10    280       10  accept with priority 3 if PING from 1.0/8
  1234567      2        0  call gcs

chain gcs
  (no rules)

default_action reject: 2 packets, 40 bytes

link             state  interface          frames in  frames out  in/s  out/s  in bit/s  out bit/s  drops  queue  high-water  addresses
127.0.0.1:41219  drops  udp 0.0.0.0:14550        120         118  10.0    9.8      2720       2670      4      0         312  1.1, 255.190
bad?[2Jname      ok     -                          -           -     -      -         -          -      0      -           -  -
  drops of 127.0.0.1:41219: filter rejected 3, no route 1

sequence gaps
  source  received  lost
  1.1          120     3
";
        assert_eq!(
            render(&stats, "http://127.0.0.1:9100/stats", &View::default()),
            expected
        );
    }

    /// A link named `name` with `fps` frames/s in, these drops and history.
    fn link(name: &str, fps: f64, dropped: u64, history: &[f64], addresses: &[&str]) -> Value {
        json!({"name": name, "interface": "udp 0.0.0.0:14550", "rate_in_fps": fps,
               "rate_out_fps": 0.0, "drops": {"no_route": dropped},
               "history_in_fps": history, "addresses": addresses})
    }

    /// The link names of the links table in `text`, with their states, in order.
    fn rows(text: &str) -> Vec<(String, String)> {
        text.lines()
            .skip_while(|l| !l.starts_with("link "))
            .skip(1)
            .take_while(|l| !l.starts_with(' ') && !l.is_empty() && !l.starts_with('('))
            .map(|l| {
                let mut w = l.split_whitespace();
                (
                    w.next().expect("a name").into(),
                    w.next().expect("a state").into(),
                )
            })
            .collect()
    }

    #[test]
    fn troubled_first_then_busiest_with_top_and_filter() {
        let stats = json!({"links": [
            link("quiet", 1.0, 0, &[1.0], &["1.1"]),
            link("busy", 50.0, 0, &[50.0], &["2.1"]),
            link("lossy", 2.0, 0, &[2.0], &["3.1"]),
            link("dropping", 0.5, 7, &[0.5], &["4.1"]),
            link("mute", 0.0, 0, &[3.0, 0.0, 0.0, 0.0, 0.0, 0.0], &["5.1"]),
            link("young", 0.0, 0, &[], &[])],
            "sequence_gaps": [{"source": "3.1", "received": 9, "lost": 1},
                              {"source": "1.1", "received": 9, "lost": 0}]});
        let all = render(&stats, "u", &View::default());
        let pairs = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        assert_eq!(
            rows(&all),
            pairs(&[
                ("lossy", "gaps"),
                ("dropping", "drops"),
                ("mute", "silent"),
                ("busy", "ok"),
                ("quiet", "ok"),
                ("young", "ok")
            ]),
            "{all}"
        );
        assert!(!all.contains("hidden"), "{all}");
        let top = View {
            top: Some(2),
            filter: None,
        };
        let text = render(&stats, "u", &top);
        assert_eq!(
            rows(&text),
            pairs(&[("lossy", "gaps"), ("dropping", "drops")])
        );
        assert!(
            text.contains("(links: 2 of 6 shown; 4 more hidden by --top)\n"),
            "{text}"
        );
        let filter = View {
            top: Some(1),
            filter: Some("uS".into()),
        };
        let text = render(&stats, "u", &filter);
        assert_eq!(rows(&text), pairs(&[("busy", "ok")]), "{text}");
        assert!(
            text.contains("(links: 1 of 6 shown; 5 not matching --filter)\n(sources: 0 of 1 shown; 1 not matching --filter)\n"),
            "{text}"
        );
        let none = View {
            top: None,
            filter: Some("nothing".into()),
        };
        let text = render(&stats, "u", &none);
        assert!(
            text.contains("links: none of 6 match the filter\n"),
            "{text}"
        );
        assert!(!text.contains("sequence gaps"), "{text}");
        let zero = View {
            top: Some(0),
            filter: None,
        };
        let text = render(&stats, "u", &zero);
        assert!(
            text.ends_with(
                "\n(links: 0 of 6 shown; 6 more hidden by --top)\n\
                 (sources: 0 of 1 shown; 1 more hidden by --top)\n"
            ),
            "{text}"
        );
    }

    #[test]
    fn anything_else_is_dashes_not_a_crash() {
        for v in [
            json!(null),
            json!([]),
            json!({"links": 3, "chains": [1, "x"]}),
        ] {
            let text = render(&v, "u", &View::default());
            assert!(text.starts_with("mavtables at u, up -\n"), "{text}");
        }
        assert_eq!(uptime(Some(&json!(90061.0))), "1d 01:01:01");
        assert_eq!(int(Some(&json!(-3))), "-3");
        assert_eq!(int(Some(&json!(2.6))), "3");
    }
}
