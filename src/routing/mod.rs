//! The sans-IO routing core: it never touches a socket, a thread or a clock. Bytes and
//! the current time go in; what to send, when to wake up, and what to log come out.
//!
//! The event loop talks to one type, [`Engine`] (see its module, `engine`, for the
//! calls and their order). Inside it:
//! - `router`: the [`Router`] — every link, address learning, the per-link decision
//!   (`dispatch`) through the shared filter, and the bounded priority queues
//!   (`queue`); links are offered every packet in creation order (serial links first,
//!   then UDP peers in the order their first frame arrived), as in the original, and
//!   every accepting link queues the same shared bytes ([`Packet`]), never re-encoded;
//! - `interface`: one configured interface — its parser, `stale` (when held-back
//!   bytes stop waiting), `pacer` (`max_bitrate`), and for a datagram interface its
//!   peers (`remotes`: peer ↔ link and the round robin), for a stream its
//!   `reconnect` backoff;
//! - `intake`: frames from a parser into the router (links created on a peer's first
//!   valid frame, unknown ids reported once, copies within the `dedup` window dropped
//!   first: `dedup`);
//! - `router::redundancy`: `group`s of links that are one path to a vehicle, and the
//!   router's own address; `own_heartbeat`: the `heartbeat` block's frames, on the
//!   core's own deadline; the engine drives the `flight_log` block's
//!   [`FlightLogger`](crate::flight_log::FlightLogger) (the stream's frames taken in
//!   `intake`, its requests and ACKs queued to the vehicle's links, its deadline among
//!   the engine's);
//! - `reload`: what a new configuration changes (interfaces matched by identity, rules
//!   by text), which [`Engine::configure`] applies at start and at every reload;
//! - `link`, `pool` (addresses with expiry), `counters`, `event` (log events and
//!   the original's exact texts), [`time`] (time as a value).
//!
//! Tests drive the same calls with a simulated clock (`tests/routing/`).

pub(crate) mod admission;
pub(crate) mod counters;
pub(crate) mod dedup;
pub(crate) mod dispatch;
pub(crate) mod engine;
pub(crate) mod event;
pub(crate) mod intake;
pub(crate) mod interface;
pub(crate) mod link;
pub(crate) mod notice;
pub(crate) mod own_heartbeat;
pub(crate) mod pacer;
pub(crate) mod pool;
pub(crate) mod queue;
pub(crate) mod rate_limit;
pub(crate) mod reconnect;
pub(crate) mod reload;
pub(crate) mod remotes;
pub(crate) mod router;
pub(crate) mod snapshot;
pub(crate) mod sources;
pub(crate) mod stale;

pub use crate::time::Timestamp;
pub use counters::{InterfaceReport, LinkCounters, LinkReport};
pub use dispatch::Decision;
pub use engine::{
    CLOSE_FLUSH, Engine, FORGET_AFTER, Reconfigured, Request, SEND_TURN, SystemSet, Transmit,
};
pub use event::{Event, LinkRef, PacketSummary};
pub use interface::InterfaceId;
pub use link::{GroupId, Link, LinkId, LinkKind};
pub use notice::Notice;
pub use pacer::{Pace, Pacer};
pub use pool::{AddressPool, MAX_ADDRESSES};
pub use queue::{Packet, PacketQueue, PushOutcome};
pub use router::{Output, Router, RouterOptions};

// `super::time::Timestamp` in the submodules names the crate's time type.
use crate::time;
