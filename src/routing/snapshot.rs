//! The statistics snapshot of the routing core ([`crate::stats::StatsSnapshot`]): the
//! counters of every link, interface, rule and source, gathered in one pass.

use std::collections::HashMap;

use slab::Slab;

use super::interface::{Kind, LiveInterface};
use super::link::LinkId;
use super::router::Router;
use crate::config::{Config, DefaultAction};
use crate::dialect;
use crate::stats::rule_text::rule_text;
use crate::stats::{
    ChainStats, DefaultActionStats, Drops, History, InterfaceStats, LinkStats, RuleStats,
    SequenceStats, SigningStats, SourceStats, StatsSnapshot,
};
use crate::time::Timestamp;

/// What the statistics need of the configuration, kept from the start: chain names and
/// rule texts (in the filter's flat rule order), and the default action.
#[derive(Debug, Clone, Default)]
pub(crate) struct RuleBook {
    chains: Vec<(String, Vec<String>)>,
    default_action: &'static str,
}

impl RuleBook {
    /// The chains and default action of `config`.
    pub(crate) fn new(config: &Config) -> Self {
        RuleBook {
            chains: config
                .chains
                .iter()
                .map(|c| {
                    let texts = c.rules.iter().map(|r| rule_text(config, r)).collect();
                    (c.name.clone(), texts)
                })
                .collect(),
            default_action: match config.default_action {
                DefaultAction::Accept => "accept",
                DefaultAction::Reject => "reject",
            },
        }
    }
}

/// Everything [`snapshot`] reads.
pub(crate) struct Sources<'a> {
    /// The router.
    pub router: &'a mut Router,
    /// The interfaces.
    pub interfaces: &'a Slab<LiveInterface>,
    /// Chain names and rule texts.
    pub rules: &'a RuleBook,
    /// The rate history (updated).
    pub history: &'a mut History,
}

/// The snapshot at `now` (rates over the time since the previous snapshot).
pub(crate) fn snapshot(src: Sources<'_>, now: Timestamp) -> StatsSnapshot {
    let now_s = now.since_start().as_secs_f64();
    let dt = src.history.interval(now_s);
    let mut interfaces: Vec<InterfaceStats> = Vec::new();
    // Interface slot → index in `interfaces` (connections add into their server).
    let mut entry_of: HashMap<usize, usize> = HashMap::new();
    let mut link_interface: HashMap<LinkId, String> = HashMap::new();
    for (key, i) in src.interfaces.iter() {
        // A connection counts into its server; an interface a reload removed, still
        // sending its queue, is not shown (its links left routing already, and a
        // reopened one's successor has its label).
        if i.retiring.is_some()
            || matches!(
                i.kind,
                Kind::Stream {
                    accepted_by: Some(_),
                    ..
                }
            )
        {
            continue;
        }
        entry_of.insert(key, interfaces.len());
        interfaces.push(InterfaceStats {
            label: i.label.clone(),
            ..InterfaceStats::default()
        });
    }
    for (key, i) in src.interfaces.iter() {
        let server = match i.kind {
            Kind::Stream {
                accepted_by: Some(s),
                ..
            } => s.0,
            _ => key,
        };
        let Some(&e) = entry_of.get(&server) else {
            continue;
        };
        let e = &mut interfaces[e];
        let mut p = *i.parser.stats();
        p += i.closed_parsers;
        e.frames += p.frames;
        e.bad_crc += p.bad_crc;
        e.unknown_id += p.unknown_id;
        e.junk_bytes += p.junk_bytes;
        e.io_errors += i.io_errors;
        e.refused_not_allowed += i.refused.not_allowed_in_all();
        e.refused_max_peers += i.refused.full;
        if let Some(edge) = &i.signing {
            let g = e.signing.get_or_insert_with(SigningStats::default);
            *g += edge.counters;
        }
        match &i.kind {
            Kind::Datagram { remotes, .. } => {
                for (link, _) in remotes.iter() {
                    link_interface.insert(link, e.label.clone());
                }
            }
            Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => {
                link_interface.insert(*link, e.label.clone());
            }
            Kind::Listener { .. } => {}
        }
    }
    let mut links: Vec<LinkStats> = src
        .router
        .links()
        .map(|l| {
            let c = l.counters();
            LinkStats {
                id: l.id().0,
                name: l.name().to_string(),
                interface: link_interface.get(&l.id()).cloned().unwrap_or_default(),
                frames_in: c.frames_in,
                bytes_in: c.bytes_in,
                frames_out: c.frames_out,
                bytes_out: c.bytes_out,
                drops: Drops {
                    filter_rejected: c.filter_rejected,
                    no_route: c.no_route,
                    queue_full: l.queue().dropped(),
                    send_error: c.send_errors,
                    bad_crc: c.bad_crc,
                    unknown_id: c.unknown_id,
                    setup_signing: c.setup_signing,
                    bad_signature: c.signing.bad_signature,
                    replayed: c.signing.replayed,
                    out_of_window: c.signing.out_of_window,
                    unsigned: c.signing.unsigned,
                    duplicate: c.duplicate,
                },
                queue_bytes: l.queue().bytes() as u64,
                queue_high_water: l.queue().high_water() as u64,
                addresses: l.pool().addresses(now).map(|a| a.to_string()).collect(),
                ..LinkStats::default()
            }
        })
        .collect();
    src.history.sample(dt, &mut links);

    let counts = src.router.filter_counts();
    let mut flat = counts.rules.iter();
    let chains = src
        .rules
        .chains
        .iter()
        .map(|(name, texts)| ChainStats {
            name: name.clone(),
            rules: texts
                .iter()
                .map(|text| {
                    let c = flat.next().copied().unwrap_or_default();
                    RuleStats {
                        text: text.clone(),
                        packets: c.packets,
                        bytes: c.bytes,
                        decided: c.decided,
                        rate_limited: c.rate_limited,
                    }
                })
                .collect(),
        })
        .collect();
    let cache = src.router.filter_stats();
    let sequence_gaps = src
        .router
        .sequences()
        .all()
        .into_iter()
        .map(|(a, c)| SequenceStats {
            source: a.to_string(),
            received: c.received,
            lost: c.lost,
        })
        .collect();
    let sequence_untracked = src.router.sequences().untracked();
    let rate_streams_evicted = src.router.rate_streams_evicted();
    let table = src.router.sources_mut();
    let sources_evicted = table.evicted();
    let sources = table
        .sample(dt)
        .into_iter()
        .map(|x| SourceStats {
            source: x.source.to_string(),
            message: dialect::by_id(x.message_id)
                .map_or_else(|| x.message_id.to_string(), |m| m.name.to_string()),
            frames: x.frames,
            rate_fps: x.rate_fps,
        })
        .collect();
    StatsSnapshot {
        uptime_s: now_s,
        links,
        interfaces,
        chains,
        default_action: DefaultActionStats {
            action: src.rules.default_action.to_string(),
            packets: counts.default_packets,
            bytes: counts.default_bytes,
        },
        sources,
        sequence_gaps,
        sources_evicted,
        rate_streams_evicted,
        sequence_untracked,
        queued_bytes: src.router.queued_bytes() as u64,
        filter_cache_hits: cache.hits,
        filter_cache_misses: cache.misses,
        recording: None,
        flight_log: None,
    }
}
