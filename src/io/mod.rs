//! I/O drivers: the event loop that owns UDP sockets and serial ports and drives the
//! sans-IO routing core ([`crate::routing`]).
//!
//! One thread, one `mio` poller: sockets and serial ports are non-blocking and
//! edge-triggered; a `timerfd` wakes the loop when a `max_bitrate` pacer allows the next
//! datagram; the poll timeout covers the once-a-second expiry tick and the reopening of
//! lost serial devices. Nothing busy-waits: an idle router sleeps in `epoll_wait`.

pub mod counters;
pub mod frames;
pub mod log;
pub mod runtime;
pub mod serial;
pub mod sys;
pub mod udp;

pub use runtime::run;
