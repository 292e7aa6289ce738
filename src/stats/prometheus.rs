//! The snapshot in the Prometheus text exposition format 0.0.4 (`/metrics`): every
//! metric family with `# HELP` and `# TYPE`, counters named `…_total`, label values
//! escaped (`\\`, `\"`, `\n`).

use std::fmt::Write;

use super::snapshot::{LinkStats, StatsSnapshot};
use crate::flight_log::FlightLogStats;
use crate::recording::RecorderStats;

/// The content type of the text format.
pub(crate) const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// `value` escaped for a label value.
pub(crate) fn escape_label(value: &str) -> String {
    let mut s = String::with_capacity(value.len());
    for c in value.chars() {
        match c {
            '\\' => s.push_str("\\\\"),
            '"' => s.push_str("\\\""),
            '\n' => s.push_str("\\n"),
            c => s.push(c),
        }
    }
    s
}

/// Writes metric families into one text.
struct Out(String);

impl Out {
    /// One unlabelled counter family per `(name, help, value)`.
    fn counters(&mut self, list: &[(&str, &str, u64)]) {
        for &(name, help, value) in list {
            self.family(name, "counter", help);
            self.sample(name, &[], value);
        }
    }

    fn family(&mut self, name: &str, kind: &str, help: &str) {
        let _ = writeln!(self.0, "# HELP {name} {help}");
        let _ = writeln!(self.0, "# TYPE {name} {kind}");
    }

    fn sample(&mut self, name: &str, labels: &[(&str, &str)], value: impl std::fmt::Display) {
        self.0.push_str(name);
        if !labels.is_empty() {
            self.0.push('{');
            for (i, (k, v)) in labels.iter().enumerate() {
                if i > 0 {
                    self.0.push(',');
                }
                let _ = write!(self.0, "{k}=\"{}\"", escape_label(v));
            }
            self.0.push('}');
        }
        let _ = writeln!(self.0, " {value}");
    }

    /// One family with a sample per link.
    fn per_link(
        &mut self,
        links: &[LinkStats],
        name: &str,
        kind: &str,
        help: &str,
        value: impl Fn(&LinkStats) -> f64,
    ) {
        self.family(name, kind, help);
        for l in links {
            let labels = [
                ("link", l.name.as_str()),
                ("interface", l.interface.as_str()),
            ];
            self.sample(name, &labels, value(l));
        }
    }
}

/// `snapshot` as Prometheus text.
pub(crate) fn render(s: &StatsSnapshot) -> String {
    let mut o = Out(String::with_capacity(4096));
    o.family(
        "mavtables_uptime_seconds",
        "gauge",
        "Seconds since the router started.",
    );
    o.sample("mavtables_uptime_seconds", &[], s.uptime_s);
    let links = &s.links;
    type Field = (
        &'static str,
        &'static str,
        &'static str,
        fn(&LinkStats) -> f64,
    );
    let per_link: [Field; 10] = [
        (
            "mavtables_link_frames_in_total",
            "counter",
            "Valid frames received from the link.",
            |l| l.frames_in as f64,
        ),
        (
            "mavtables_link_bytes_in_total",
            "counter",
            "Bytes of the frames received from the link.",
            |l| l.bytes_in as f64,
        ),
        (
            "mavtables_link_frames_out_total",
            "counter",
            "Frames sent to the link.",
            |l| l.frames_out as f64,
        ),
        (
            "mavtables_link_bytes_out_total",
            "counter",
            "Bytes of the frames sent to the link.",
            |l| l.bytes_out as f64,
        ),
        (
            "mavtables_link_rate_in_fps",
            "gauge",
            "Frames received per second over the last second.",
            |l| l.rate_in_fps,
        ),
        (
            "mavtables_link_rate_out_fps",
            "gauge",
            "Frames sent per second over the last second.",
            |l| l.rate_out_fps,
        ),
        (
            "mavtables_link_rate_in_bps",
            "gauge",
            "Bits received per second over the last second.",
            |l| l.rate_in_bps,
        ),
        (
            "mavtables_link_rate_out_bps",
            "gauge",
            "Bits sent per second over the last second.",
            |l| l.rate_out_bps,
        ),
        (
            "mavtables_queue_bytes",
            "gauge",
            "Bytes the link's queue holds.",
            |l| l.queue_bytes as f64,
        ),
        (
            "mavtables_queue_high_water_bytes",
            "gauge",
            "The most bytes the link's queue held at once.",
            |l| l.queue_high_water as f64,
        ),
    ];
    for (name, kind, help, value) in per_link {
        o.per_link(links, name, kind, help, value);
    }
    o.family(
        "mavtables_drops_total",
        "counter",
        "Frames dropped, by link and reason.",
    );
    for l in links {
        for (reason, n) in l.drops.named() {
            let labels = [
                ("link", l.name.as_str()),
                ("interface", l.interface.as_str()),
                ("reason", reason),
            ];
            o.sample("mavtables_drops_total", &labels, n);
        }
    }
    type IfField = (
        &'static str,
        &'static str,
        fn(&super::InterfaceStats) -> u64,
    );
    let per_interface: [IfField; 5] = [
        (
            "mavtables_interface_frames_total",
            "Valid frames the interface's parser found.",
            |i| i.frames,
        ),
        (
            "mavtables_interface_bad_crc_total",
            "Frames with a bad checksum.",
            |i| i.bad_crc,
        ),
        (
            "mavtables_interface_unknown_id_total",
            "Frames with a message id outside the dialect.",
            |i| i.unknown_id,
        ),
        (
            "mavtables_interface_junk_bytes_total",
            "Bytes that were not part of any frame.",
            |i| i.junk_bytes,
        ),
        (
            "mavtables_interface_io_errors_total",
            "Receive, send and open errors.",
            |i| i.io_errors,
        ),
    ];
    for (name, help, value) in per_interface {
        o.family(name, "counter", help);
        for i in &s.interfaces {
            o.sample(name, &[("interface", i.label.as_str())], value(i));
        }
    }
    o.family(
        "mavtables_interface_refused_total",
        "counter",
        "Remotes a server refused, by reason: not_allowed (outside allow), max_peers.",
    );
    for i in &s.interfaces {
        for (reason, n) in [
            ("not_allowed", i.refused_not_allowed),
            ("max_peers", i.refused_max_peers),
        ] {
            let labels = [("interface", i.label.as_str()), ("reason", reason)];
            o.sample("mavtables_interface_refused_total", &labels, n);
        }
    }
    o.family(
        "mavtables_interface_signing_total",
        "counter",
        "Signing on interfaces with a key, by result: verified, refused (bad_signature, replayed, out_of_window, unsigned), signed_out.",
    );
    for i in &s.interfaces {
        let Some(g) = &i.signing else { continue };
        for (result, n) in [
            ("verified", g.verified),
            ("bad_signature", g.bad_signature),
            ("replayed", g.replayed),
            ("out_of_window", g.out_of_window),
            ("unsigned", g.unsigned),
            ("signed_out", g.signed_out),
        ] {
            let labels = [("interface", i.label.as_str()), ("result", result)];
            o.sample("mavtables_interface_signing_total", &labels, n);
        }
    }
    type RuleField = (&'static str, &'static str, fn(&super::RuleStats) -> u64);
    let per_rule: [RuleField; 4] = [
        (
            "mavtables_rule_packets_total",
            "(Packet, destination) evaluations the rule's condition matched.",
            |r| r.packets,
        ),
        (
            "mavtables_rule_bytes_total",
            "Frame bytes of the evaluations the rule's condition matched.",
            |r| r.bytes,
        ),
        (
            "mavtables_rule_decided_total",
            "Evaluations the rule decided (accept or reject).",
            |r| r.decided,
        ),
        (
            "mavtables_rule_rate_limited_total",
            "Frames the rule accepted for a link that its `with rate` dropped.",
            |r| r.rate_limited,
        ),
    ];
    for (name, help, value) in per_rule {
        o.family(name, "counter", help);
        for c in &s.chains {
            for (i, r) in c.rules.iter().enumerate() {
                let index = i.to_string();
                let labels = [
                    ("chain", c.name.as_str()),
                    ("rule", index.as_str()),
                    ("text", r.text.as_str()),
                ];
                o.sample(name, &labels, value(r));
            }
        }
    }
    let d = &s.default_action;
    let action = [("action", d.action.as_str())];
    o.family(
        "mavtables_default_action_packets_total",
        "counter",
        "Evaluations no rule decided.",
    );
    o.sample("mavtables_default_action_packets_total", &action, d.packets);
    o.family(
        "mavtables_default_action_bytes_total",
        "counter",
        "Frame bytes of the evaluations no rule decided.",
    );
    o.sample("mavtables_default_action_bytes_total", &action, d.bytes);
    o.family(
        "mavtables_source_frames_total",
        "counter",
        "Frames received per source address and message type (bounded table).",
    );
    for x in &s.sources {
        let labels = [
            ("source", x.source.as_str()),
            ("message", x.message.as_str()),
        ];
        o.sample("mavtables_source_frames_total", &labels, x.frames);
    }
    o.family(
        "mavtables_sequence_received_total",
        "counter",
        "Frames received per source address.",
    );
    for x in &s.sequence_gaps {
        o.sample(
            "mavtables_sequence_received_total",
            &[("source", x.source.as_str())],
            x.received,
        );
    }
    o.family(
        "mavtables_sequence_lost_total",
        "counter",
        "Frames lost before the router, by the source's sequence numbers.",
    );
    for x in &s.sequence_gaps {
        o.sample(
            "mavtables_sequence_lost_total",
            &[("source", x.source.as_str())],
            x.lost,
        );
    }
    o.family(
        "mavtables_rate_streams_evicted_total",
        "counter",
        "Rate-capped streams forgotten because their bounded table was full.",
    );
    o.sample(
        "mavtables_rate_streams_evicted_total",
        &[],
        s.rate_streams_evicted,
    );
    let scalars: [(&str, &str, u64); 4] = [
        (
            "mavtables_sources_evicted_total",
            "(Source, message) pairs that lost their place in the bounded table.",
            s.sources_evicted,
        ),
        (
            "mavtables_sequence_untracked_total",
            "Frames of sources beyond the sequence table's bound.",
            s.sequence_untracked,
        ),
        (
            "mavtables_filter_cache_hits_total",
            "Filter lookups answered by the verdict memo.",
            s.filter_cache_hits,
        ),
        (
            "mavtables_filter_cache_misses_total",
            "Filter lookups that walked the rules.",
            s.filter_cache_misses,
        ),
    ];
    o.counters(&scalars);
    o.family(
        "mavtables_queued_bytes",
        "gauge",
        "Bytes all queues hold together.",
    );
    o.sample("mavtables_queued_bytes", &[], s.queued_bytes);
    if let Some(r) = &s.recording {
        recording(&mut o, r);
    }
    if let Some(f) = &s.flight_log {
        flight_log(&mut o, f);
    }
    o.0
}

/// The recorder's families (only when the router records).
fn recording(o: &mut Out, r: &RecorderStats) {
    o.family(
        "mavtables_recording_records_total",
        "counter",
        "Frames written to recordings.",
    );
    o.sample("mavtables_recording_records_total", &[], r.written);
    o.family(
        "mavtables_recording_bytes_total",
        "counter",
        "Bytes written to recordings, timestamps included.",
    );
    o.sample("mavtables_recording_bytes_total", &[], r.bytes);
    o.family(
        "mavtables_recording_dropped_total",
        "counter",
        "Records dropped (never packets), by reason.",
    );
    for (reason, n) in [
        ("queue_full", r.dropped_queue_full),
        ("disk", r.dropped_disk),
        ("no_space", r.dropped_no_space),
    ] {
        o.sample(
            "mavtables_recording_dropped_total",
            &[("reason", reason)],
            n,
        );
    }
    o.family(
        "mavtables_recording_files_total",
        "counter",
        "Recording files opened (one at start, one per rotation).",
    );
    o.sample("mavtables_recording_files_total", &[], r.files);
}

/// The flight log's families (only with a `flight_log` block).
fn flight_log(o: &mut Out, f: &FlightLogStats) {
    let s = &f.stream;
    let counters = [
        (
            "mavtables_flight_log_blocks_written_total",
            "Log blocks (ulog chunks) written to flight log files.",
            f.blocks_written,
        ),
        (
            "mavtables_flight_log_bytes_written_total",
            "Bytes written to flight log files.",
            f.bytes_written,
        ),
        (
            "mavtables_flight_log_blocks_resent_total",
            "Missing log blocks that came after the router asked for them again.",
            s.resent,
        ),
        (
            "mavtables_flight_log_blocks_lost_total",
            "Log blocks that never came (given up), or ulog chunks lost.",
            s.lost,
        ),
        (
            "mavtables_flight_log_nacks_total",
            "Missing log blocks asked for again (NACKs sent).",
            s.nacks,
        ),
        (
            "mavtables_flight_log_files_total",
            "Flight log files created.",
            f.files,
        ),
    ];
    o.counters(&counters);
    o.family(
        "mavtables_flight_log_blocks_dropped_total",
        "counter",
        "Log blocks received but not written, by reason.",
    );
    for (reason, n) in [("queue_full", s.dropped), ("disk", f.blocks_dropped_disk)] {
        o.sample(
            "mavtables_flight_log_blocks_dropped_total",
            &[("reason", reason)],
            n,
        );
    }
    o.family(
        "mavtables_flight_log_streaming",
        "gauge",
        "1 while a flight log is being streamed from the autopilot.",
    );
    o.sample(
        "mavtables_flight_log_streaming",
        &[],
        u64::from(f.streaming.is_some()),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::snapshot::LinkStats;

    #[test]
    fn labels_are_escaped_and_every_family_is_typed() {
        let s = StatsSnapshot {
            links: vec![LinkStats {
                name: "a\"b\\c\nd".into(),
                frames_in: 7,
                ..LinkStats::default()
            }],
            ..StatsSnapshot::default()
        };
        let text = render(&s);
        assert!(text.contains(
            "mavtables_link_frames_in_total{link=\"a\\\"b\\\\c\\nd\",interface=\"\"} 7\n"
        ));
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            let name = line.split(['{', ' ']).next().unwrap_or("");
            assert!(text.contains(&format!("# TYPE {name} ")), "{name} untyped");
        }
    }

    #[test]
    fn every_number_of_the_json_has_a_metric() {
        let s = StatsSnapshot {
            interfaces: vec![crate::stats::InterfaceStats {
                label: "tcp 0.0.0.0:5760".into(),
                refused_not_allowed: 3,
                refused_max_peers: 4,
                signing: Some(crate::stats::SigningStats {
                    verified: 5,
                    replayed: 6,
                    ..Default::default()
                }),
                ..Default::default()
            }],
            sources_evicted: 7,
            sequence_untracked: 8,
            filter_cache_hits: 9,
            filter_cache_misses: 10,
            ..StatsSnapshot::default()
        };
        let text = render(&s);
        for sample in [
            "mavtables_interface_refused_total{interface=\"tcp 0.0.0.0:5760\",reason=\"not_allowed\"} 3",
            "mavtables_interface_refused_total{interface=\"tcp 0.0.0.0:5760\",reason=\"max_peers\"} 4",
            "mavtables_interface_signing_total{interface=\"tcp 0.0.0.0:5760\",result=\"verified\"} 5",
            "mavtables_interface_signing_total{interface=\"tcp 0.0.0.0:5760\",result=\"replayed\"} 6",
            "mavtables_sources_evicted_total 7",
            "mavtables_sequence_untracked_total 8",
            "mavtables_filter_cache_hits_total 9",
            "mavtables_filter_cache_misses_total 10",
        ] {
            assert!(
                text.contains(&format!("{sample}\n")),
                "{sample} missing:\n{text}"
            );
        }
    }
}
