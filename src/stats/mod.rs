//! Statistics of a running router, sans-IO: the [`StatsSnapshot`] the routing core takes
//! about once a second ([`crate::routing::Engine::stats`]), the one-second rate history
//! of each link (`history`), and the snapshot rendered as the `/stats` JSON ([`json`])
//! and as the Prometheus text format of `/metrics` (`prometheus`). The HTTP server
//! that serves them is `src/io/stats_server.rs`.

pub(crate) mod history;
#[doc(hidden)]
pub mod history_query;
#[doc(hidden)]
pub mod json;
pub(crate) mod prometheus;
#[doc(hidden)]
pub mod rule_text;
pub(crate) mod snapshot;

pub use history::{HISTORY_LEN, History};
pub use snapshot::{
    ChainStats, DefaultActionStats, Drops, InterfaceStats, LinkStats, RuleStats, SequenceStats,
    SigningStats, SourceStats, StatsSnapshot,
};

/// The status page served at `/`: one self-contained HTML file.
pub const STATUS_PAGE: &str = include_str!("page.html");
