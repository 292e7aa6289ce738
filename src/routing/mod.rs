//! The sans-IO routing core: address learning, per-link decisions, priority queues and
//! bitrate pacing. It takes frames, link ids and the current time in, and gives queued
//! packets and log events out. It never touches a socket, a thread or a clock.
//!
//! # How the event loop drives it
//!
//! ```text
//! start:      router = Router::new(&config)              (one filter shared by all links)
//!             for each serial interface, in file order:
//!                 id = router.add_serial_link(device, &preload, now, &mut out)
//!             pacer = Pacer::new(max_bitrate)            (one per UDP interface; 0 = none)
//! datagram:   for each valid frame from remote ip:port:
//!                 id = known id, or router.add_udp_link("a.b.c.d:port", now)
//!                 router.receive(id, &frame, now, &mut out)
//! serial rx:  router.receive(serial_id, &frame, now, &mut out)
//! after each: print out.events (Display gives the text; add the timestamp prefix), and
//!             want "writable" for every link in out.queued; then out.clear()
//! writable:   serial: while let Some(p) = router.pop(id) { write p }
//!             udp:    p = router.peek(id); match pacer.check(now, p.len()) {
//!                         Pace::Now => { send router.pop(id); pacer.sent(now, len) }
//!                         Pace::At(t) => wake up at t }
//! every ~1 s: for id in router.tick(now) { forget the ip:port of link id }
//! ```
//!
//! Links are offered every packet in creation order (serial links first, then UDP remotes
//! in the order their first frame arrived), as in the original. Every accepting link
//! queues the same shared bytes ([`Packet`]), never re-encoded.
//!
//! Parts: [`time`] (time as a value), [`pool`] (addresses with expiry), [`queue`] (bounded
//! priority queue), [`dispatch`] (the per-link decision of spec §1.3), [`link`], [`event`]
//! (log events and their exact texts), [`pacer`] (`max_bitrate`), [`router`].

pub mod dispatch;
pub mod event;
pub mod link;
pub mod pacer;
pub mod pool;
pub mod queue;
pub mod router;
pub mod time;

pub use dispatch::Decision;
pub use event::{Event, LinkRef, PacketSummary};
pub use link::{Link, LinkId, LinkKind};
pub use pacer::{Pace, Pacer};
pub use pool::AddressPool;
pub use queue::{Packet, PacketQueue, PushOutcome};
pub use router::{Output, Router, RouterOptions};
pub use time::Timestamp;
