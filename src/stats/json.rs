//! The snapshot as the `/stats` JSON (version 1; fields are only ever added, never
//! renamed; `docs/configuration.md` lists them).

use serde_json::{Map, Value, json};

use super::history::HISTORY_LEN;
use super::snapshot::{LinkStats, StatsSnapshot};
use crate::flight_log::FlightLogStats;
use crate::recording::RecorderStats;

/// The version of the JSON's shape.
pub const VERSION: u64 = 1;

/// `snapshot` as a JSON value.
pub fn to_value(s: &StatsSnapshot) -> Value {
    json!({
        "version": VERSION,
        "uptime_s": s.uptime_s,
        "history_interval_s": 1,
        "history_len": HISTORY_LEN,
        "links": s.links.iter().map(link).collect::<Vec<_>>(),
        "interfaces": s.interfaces.iter().map(|i| json!({
            "label": i.label,
            "frames": i.frames,
            "bad_crc": i.bad_crc,
            "unknown_id": i.unknown_id,
            "junk_bytes": i.junk_bytes,
            "io_errors": i.io_errors,
            "refused_not_allowed": i.refused_not_allowed,
            "refused_max_peers": i.refused_max_peers,
            "signing": i.signing.map(|g| json!({
                "verified": g.verified,
                "bad_signature": g.bad_signature,
                "replayed": g.replayed,
                "out_of_window": g.out_of_window,
                "unsigned": g.unsigned,
                "signed_out": g.signed_out,
            })),
        })).collect::<Vec<_>>(),
        "chains": s.chains.iter().map(|c| json!({
            "name": c.name,
            "rules": c.rules.iter().map(|r| json!({
                "text": r.text,
                "packets": r.packets,
                "bytes": r.bytes,
                "decided": r.decided,
                "rate_limited": r.rate_limited,
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "default_action": {
            "action": s.default_action.action,
            "packets": s.default_action.packets,
            "bytes": s.default_action.bytes,
        },
        "sources": s.sources.iter().map(|x| json!({
            "source": x.source,
            "message": x.message,
            "frames": x.frames,
            "rate_fps": x.rate_fps,
        })).collect::<Vec<_>>(),
        "sources_evicted": s.sources_evicted,
        "rate_streams_evicted": s.rate_streams_evicted,
        "sequence_gaps": s.sequence_gaps.iter().map(|x| json!({
            "source": x.source,
            "received": x.received,
            "lost": x.lost,
        })).collect::<Vec<_>>(),
        "sequence_untracked": s.sequence_untracked,
        "queued_bytes": s.queued_bytes,
        "filter_cache": {"hits": s.filter_cache_hits, "misses": s.filter_cache_misses},
        "recording": s.recording.as_ref().map_or(Value::Null, recording),
        "flight_log": s.flight_log.as_ref().map_or(Value::Null, flight_log),
    })
}

fn link(l: &LinkStats) -> Value {
    let drops: Map<String, Value> = l
        .drops
        .named()
        .iter()
        .map(|(k, v)| ((*k).to_string(), Value::from(*v)))
        .collect();
    json!({
        "id": l.id,
        "name": l.name,
        "interface": l.interface,
        "frames_in": l.frames_in,
        "bytes_in": l.bytes_in,
        "frames_out": l.frames_out,
        "bytes_out": l.bytes_out,
        "rate_in_fps": l.rate_in_fps,
        "rate_out_fps": l.rate_out_fps,
        "rate_in_bps": l.rate_in_bps,
        "rate_out_bps": l.rate_out_bps,
        "drops": drops,
        "queue_bytes": l.queue_bytes,
        "queue_high_water": l.queue_high_water,
        "addresses": l.addresses,
        "history_in_fps": l.history_in_fps,
        "history_out_fps": l.history_out_fps,
    })
}

/// `snapshot` as JSON text.
pub fn render(s: &StatsSnapshot) -> String {
    to_value(s).to_string()
}

/// The recorder's counters.
fn recording(r: &RecorderStats) -> Value {
    json!({
        "written": r.written,
        "bytes": r.bytes,
        "dropped_queue_full": r.dropped_queue_full,
        "dropped_disk": r.dropped_disk,
        "dropped_no_space": r.dropped_no_space,
        "files": r.files,
        "removed": r.removed,
        "current_path": r.current_path,
    })
}

/// The flight log's counters.
fn flight_log(f: &FlightLogStats) -> Value {
    let s = &f.stream;
    json!({
        "streaming": f.streaming,
        "logs": s.logs,
        "blocks": s.blocks,
        "nacks": s.nacks,
        "resent": s.resent,
        "lost": s.lost,
        "duplicates": s.duplicates,
        "late": s.late,
        "dropped_queue_full": s.dropped,
        "blocks_written": f.blocks_written,
        "bytes_written": f.bytes_written,
        "dropped_disk": f.blocks_dropped_disk,
        "files": f.files,
        "removed": f.removed,
        "current_path": f.current_path,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::snapshot::{Drops, LinkStats};

    #[test]
    fn names_are_escaped_and_fields_present() {
        let s = StatsSnapshot {
            links: vec![LinkStats {
                name: "a\"b\\c\n".into(),
                drops: Drops {
                    no_route: 2,
                    ..Drops::default()
                },
                ..LinkStats::default()
            }],
            ..StatsSnapshot::default()
        };
        let text = render(&s);
        let back: Value = serde_json::from_str(&text).expect("valid JSON");
        assert_eq!(back["version"], 1);
        assert_eq!(back["links"][0]["name"], "a\"b\\c\n");
        assert_eq!(back["links"][0]["drops"]["no_route"], 2);
        assert_eq!(back["links"][0]["drops"]["unsigned"], 0);
        assert!(back["recording"].is_null());
    }
}
