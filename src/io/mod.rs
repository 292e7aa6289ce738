//! I/O drivers: the event loop that owns UDP sockets and serial ports and drives the
//! sans-IO routing core. Filled in by the live-router issue.
