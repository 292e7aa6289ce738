//! The sans-IO routing core: it never touches a socket, a thread or a clock. Bytes and
//! the current time go in; what to send, when to wake up, and what to log come out.
//!
//! The event loop talks to one type, [`Engine`] (see its module, [`engine`], for the
//! calls and their order). Inside it:
//! - [`router`]: the [`Router`] — every link, address learning, the per-link decision
//!   ([`dispatch`]) through the shared filter, and the bounded priority queues
//!   ([`queue`]); links are offered every packet in creation order (serial links first,
//!   then UDP peers in the order their first frame arrived), as in the original, and
//!   every accepting link queues the same shared bytes ([`Packet`]), never re-encoded;
//! - [`interface`]: one configured interface — its parser, [`stale`] (when held-back
//!   bytes stop waiting), [`pacer`] (`max_bitrate`), and for a datagram interface its
//!   peers ([`remotes`]: peer ↔ link and the round robin), for a stream its
//!   [`reconnect`] backoff;
//! - [`intake`]: frames from a parser into the router (links created on a peer's first
//!   valid frame, unknown ids reported once);
//! - [`reload`]: what a new configuration changes (interfaces matched by identity, rules
//!   by text), which [`Engine::configure`] applies at start and at every reload;
//! - [`link`], [`pool`] (addresses with expiry), [`counters`], [`event`] (log events and
//!   the original's exact texts), [`time`] (time as a value).
//!
//! Tests drive the same calls with a simulated clock (`tests/routing/`).

pub mod admission;
pub mod counters;
pub mod dispatch;
pub mod engine;
pub mod event;
pub mod intake;
pub mod interface;
pub mod link;
pub mod pacer;
pub mod pool;
pub mod queue;
pub mod rate_limit;
pub mod reconnect;
pub mod reload;
pub mod remotes;
pub mod router;
pub mod snapshot;
pub mod sources;
pub mod stale;
pub mod time;

pub use counters::{InterfaceReport, LinkCounters, LinkReport};
pub use dispatch::Decision;
pub use engine::{Engine, Notice, Reconfigured, Request, Transmit};
pub use event::{Event, LinkRef, PacketSummary};
pub use interface::InterfaceId;
pub use link::{Link, LinkId, LinkKind};
pub use pacer::{Pace, Pacer};
pub use pool::AddressPool;
pub use queue::{Packet, PacketQueue, PushOutcome};
pub use router::{Output, Router, RouterOptions};
pub use time::Timestamp;
