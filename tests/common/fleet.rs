//! A generated fleet for tests of the statistics clients (the status page and `mavtables
//! stats`) at scale: `/stats` as a ground-station router of `links` vehicle links would
//! serve it, with a few troubled links whose positions the tests know.

use serde_json::{Value, json};

/// The name of link `i` (as the router names a UDP peer).
pub fn name(i: usize) -> String {
    format!("10.{}.{}.{}:14550", i / 65536, i / 256 % 256, i % 256)
}

/// The source (`SYS.COMP`) behind link `i`: distinct for up to 250 × 255 links.
pub fn source(i: usize) -> String {
    format!("{}.{}", i % 250 + 1, i / 250 + 1)
}

/// Whether link `i` dropped frames.
pub fn drops(i: usize) -> bool {
    i % 97 == 3
}

/// Whether the source behind link `i` lost frames (and it has no drops).
pub fn gaps(i: usize) -> bool {
    i % 89 == 5 && !drops(i)
}

/// Whether link `i` received nothing over the last samples (and has neither of the above).
pub fn silent(i: usize) -> bool {
    i % 101 == 7 && !drops(i) && !gaps(i)
}

/// Whether link `i` is troubled (drops, gaps or silent).
pub fn troubled(i: usize) -> bool {
    drops(i) || gaps(i) || silent(i)
}

/// Frames per second received on link `i`, distinct for every link (0 when silent).
pub fn rate_in(i: usize) -> f64 {
    if silent(i) {
        0.0
    } else {
        10.0 + ((i * 7919) % 1000) as f64 / 10.0
    }
}

/// The statistics of a fleet of `links` links at the `n`th request, with `samples` of
/// history per link (the router keeps 300).
pub fn stats(links: usize, n: u64, samples: usize) -> Value {
    stats_window(links, n, samples, |_| samples)
}

/// The statistics as a router answers `/stats?history=N&chart=...`: of the `samples`
/// of history of link `i`, the last `keep(i)`.
pub fn stats_window(links: usize, n: u64, samples: usize, keep: impl Fn(usize) -> usize) -> Value {
    let list: Vec<Value> = (0..links)
        .map(|i| {
            let fps = rate_in(i);
            let from = samples.saturating_sub(keep(i));
            let history: Vec<f64> = (from..samples)
                .map(|s| {
                    if silent(i) && s + 10 >= samples {
                        0.0
                    } else {
                        let wave = ((s as f64 / 9.0) + i as f64).sin() * 0.3 + 0.7;
                        (fps * wave * 10.0).round() / 10.0
                    }
                })
                .collect();
            let frames_in = (fps * 100.0) as u64 + 10 * n;
            json!({
                "id": i + 1, "name": name(i), "interface": "udp 0.0.0.0:14550",
                "frames_in": frames_in, "bytes_in": 40 * frames_in,
                "frames_out": 3 * n, "bytes_out": 60 * n,
                "rate_in_fps": fps, "rate_out_fps": 1.0,
                "rate_in_bps": fps * 320.0, "rate_out_bps": 160.0,
                "drops": {"filter_rejected": if drops(i) { 5 + n } else { 0 }, "no_route": 0},
                "queue_bytes": 0, "queue_high_water": 80, "addresses": [source(i)],
                "history_in_fps": history, "history_out_fps": vec![1.0; samples - from]
            })
        })
        .collect();
    let sources: Vec<Value> = (0..links)
        .map(|i| {
            json!({"source": source(i), "message": "ATTITUDE", "frames": 100 + n,
                         "rate_fps": rate_in(i)})
        })
        .collect();
    let gap_list: Vec<Value> = (0..links)
        .map(|i| {
            json!({"source": source(i), "received": 100 + n,
                         "lost": if gaps(i) { 3 } else { 0 }})
        })
        .collect();
    json!({
        "version": 1, "uptime_s": 3600 + n, "history_interval_s": 1,
        "links": list,
        "interfaces": [{"label": "udp 0.0.0.0:14550", "frames": 1000 * n, "bad_crc": 0,
                        "unknown_id": 0, "junk_bytes": 0, "io_errors": 0, "signing": null}],
        "chains": [{"name": "default", "rules": [
            {"text": "accept", "packets": 1000 * n, "bytes": 40000 * n, "decided": 1000 * n}]}],
        "default_action": {"action": "reject", "packets": 0, "bytes": 0},
        "sources": sources, "sequence_gaps": gap_list, "recording": null
    })
}

/// The links of a fleet of `links` that pass `keep`, in the order `mavtables stats` and
/// the status page show them by default: troubled first, then the busiest.
pub fn order(links: usize, keep: impl Fn(usize) -> bool) -> Vec<usize> {
    let mut order: Vec<usize> = (0..links).filter(|&i| keep(i)).collect();
    order.sort_by(|&a, &b| {
        troubled(b)
            .cmp(&troubled(a))
            .then(rate_in(b).total_cmp(&rate_in(a)))
    });
    order
}

/// The state of link `i` as both clients name it.
pub fn state(i: usize) -> &'static str {
    if drops(i) {
        "drops"
    } else if gaps(i) {
        "gaps"
    } else if silent(i) {
        "silent"
    } else {
        "ok"
    }
}
