//! I/O drivers: the event loop that owns UDP sockets and serial ports and drives the
//! sans-IO routing core.

pub mod sys;
