//! I/O drivers: the event loop ([`run`]) and one driver per transport, which move bytes
//! between the operating system and the sans-IO routing core ([`crate::routing::Engine`])
//! and hold no routing policy.
//!
//! - `runtime`: the loop — wait, read, core, send, arm the one timer;
//! - `driver`: what every transport driver does for the loop;
//! - `udp`, `tcp`, `websocket`, `serial`, `zenoh` (feature `zenoh`): the drivers (`stream`: what serial and TCP share;
//!   `resolve`: host names of clients);
//! - `stats_server`: the HTTP statistics endpoint, on threads of its own;
//! - `notify`: systemd's readiness, reload and watchdog notifications;
//! - `log`: log lines and messages, written without ever blocking the loop;
//! - `recorder`: `.tlog` recordings, written by a thread of their own; `manifest`: the
//!   file listing the recordings it created (the only ones it removes);
//! - `flight_log`: the flight logs streamed from the autopilot, written by a thread of
//!   their own (sharing the recorder's list of created files and rotation);
//! - `writer_thread`: what both of those writers' threads share — the queue, the wake-up,
//!   the bounded wait at exit, the counters and the current path; `made_files`: their
//!   steps on the files they create (create afresh, remove listed ones, plan for room);
//! - `harness` (hidden): batched UDP sends for the benchmarks' load generators;
//! - `sys`: the only module with `unsafe` code — the system calls that the standard
//!   library and `mio` do not offer.

mod driver;
mod flight_log;
#[doc(hidden)]
pub mod harness;
mod log;
mod made_files;
pub(crate) mod manifest;
mod notify;
mod recorder;
mod resolve;
mod runtime;
mod serial;
mod state_file;
#[doc(hidden)]
pub mod stats_server;
mod stream;
#[allow(unsafe_code)]
mod sys;
mod tcp;
mod udp;
mod websocket;
mod writer_thread;
#[cfg(feature = "zenoh")]
mod zenoh;

pub(crate) use sys::effective_uid;

pub use runtime::run;
