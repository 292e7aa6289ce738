//! The text `mavtables stats` prints from the router's `/stats` JSON, laid out like
//! `iptables -L -v -x`: every chain with one line per rule and its counters, the default
//! action, then a table of links. Exact numbers (no K/M rounding), so that scripts and
//! tests can compare them; fields the JSON lacks show as `-`.

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

/// The whole text for the statistics `stats` fetched from `source` (a URL).
pub(crate) fn render(stats: &Value, source: &str) -> String {
    let mut out = Vec::new();
    out.push(format!(
        "mavtables at {source}, up {}",
        uptime(stats.get("uptime_s"))
    ));
    chains(stats, &mut out);
    links(stats, &mut out);
    gaps(stats, &mut out);
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

fn links(stats: &Value, out: &mut Vec<String>) {
    out.push(String::new());
    let links = list(stats.get("links"));
    if links.is_empty() {
        out.push("links: none yet (a link appears when its peer sends)".into());
        return;
    }
    let mut table = Table::new(&[
        ("link", Align::Left),
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
    for link in links {
        let name = text(link.get("name"));
        let drops = link.get("drops");
        let total: u64 = DROP_REASONS
            .iter()
            .filter_map(|(key, _)| drops.and_then(|d| d.get(*key)).and_then(Value::as_u64))
            .sum();
        let reasons: Vec<String> = DROP_REASONS
            .iter()
            .filter_map(|(key, label)| {
                let n = drops.and_then(|d| d.get(*key)).and_then(Value::as_u64)?;
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
            text(link.get("interface")),
            int(link.get("frames_in")),
            int(link.get("frames_out")),
            rate(link.get("rate_in_fps")),
            rate(link.get("rate_out_fps")),
            int(link.get("rate_in_bps")),
            int(link.get("rate_out_bps")),
            total.to_string(),
            int(link.get("queue_bytes")),
            int(link.get("queue_high_water")),
            if addresses.is_empty() {
                "-".into()
            } else {
                addresses.join(", ")
            },
        ]);
    }
    out.extend(table.lines(&table.widths(), ""));
    out.extend(details);
}

/// One line per source that lost frames (MAVLink sequence gaps).
fn gaps(stats: &Value, out: &mut Vec<String>) {
    let lossy: Vec<&Value> = list(stats.get("sequence_gaps"))
        .iter()
        .filter(|g| g.get("lost").and_then(Value::as_u64).is_some_and(|n| n > 0))
        .collect();
    if lossy.is_empty() {
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

link             interface          frames in  frames out  in/s  out/s  in bit/s  out bit/s  drops  queue  high-water  addresses
127.0.0.1:41219  udp 0.0.0.0:14550        120         118  10.0    9.8      2720       2670      4      0         312  1.1, 255.190
bad?[2Jname      -                          -           -     -      -         -          -      0      -           -  -
  drops of 127.0.0.1:41219: filter rejected 3, no route 1

sequence gaps
  source  received  lost
  1.1          120     3
";
        assert_eq!(render(&stats, "http://127.0.0.1:9100/stats"), expected);
    }

    #[test]
    fn anything_else_is_dashes_not_a_crash() {
        for v in [
            json!(null),
            json!([]),
            json!({"links": 3, "chains": [1, "x"]}),
        ] {
            let text = render(&v, "u");
            assert!(text.starts_with("mavtables at u, up -\n"), "{text}");
        }
        assert_eq!(uptime(Some(&json!(90061.0))), "1d 01:01:01");
        assert_eq!(int(Some(&json!(-3))), "-3");
        assert_eq!(int(Some(&json!(2.6))), "3");
    }
}
