//! mavtables: a MAVLink router and firewall.
//!
//! The crate is layered: each module below imports only modules listed before it, with
//! one exception, noted at [`config`].
//! - [`time`]: the monotonic [`Timestamp`](time::Timestamp) every sans-IO layer is
//!   handed as "now" (none of them reads a clock);
//! - [`address`]: MAVLink addresses and subnets;
//! - `files`: bounded reads of the files the router is given (configuration, keys,
//!   signing state);
//! - `utc`: UTC calendar formatting of timestamps (logs and `inspect`);
//! - [`dialect`]: generated message tables (ids, names, CRC_EXTRA, lengths, fields);
//! - [`wire`]: MAVLink v1/v2 framing, CRC, the streaming parser, encoding, the shared
//!   bytes of a frame ([`Packet`](wire::Packet)) and the signature's cryptography and
//!   byte edits (pure);
//! - [`capture`]: reading raw, `.tlog`, `.pcap` and `.pcapng` captures (pure);
//! - `condition`: the `if …` condition of filter rules and of the recording filter;
//! - [`signing`]: MAVLink 2 signing at the router's edge: keys (read from their files),
//!   the check of signed frames and replay protection, the signatures the router adds,
//!   its signing clock and the saved stream table (sans-IO apart from reading keys);
//! - [`recording`]: which frames are recorded, the core's tap of them, file name
//!   patterns, the list of recordings and rotation (sans-IO; the writer is in [`io`]);
//! - [`config`]: the configuration language, its diagnostics and model, and the reading
//!   of the files a configuration names (keys, signing state, a fixed recording name —
//!   the one upward arrow: whether that file is a recording is read through
//!   `io::manifest`);
//! - [`flight_log`]: the autopilot's flight log streamed to the router: when to ask
//!   for it, acknowledgements, block order (sans-IO; the writer is in [`io`]);
//! - [`filter`]: the filter chains;
//! - [`stats`]: statistics of a running router (snapshots, rate history, the `/stats`
//!   JSON and the Prometheus text), sans-IO;
//! - [`routing`]: the sans-IO routing core (learning, decisions, queues, pacing);
//! - [`io`]: the event loop, the UDP / TCP / serial drivers, the recorder thread, the
//!   statistics server, logging, signals and systemd notification;
//! - [`commands`]: the `inspect`, `replay` and `stats` subcommands; [`cli`]: the command
//!   line.

// Every public item says what it is for (CI turns this warning into an error).
#![warn(missing_docs)]
// The only exception is `io::sys`, the one module of system calls.
#![deny(unsafe_code)]

pub mod address;
pub mod capture;
pub mod cli;
pub mod commands;
pub(crate) mod condition;
pub mod config;
pub mod dialect;
pub(crate) mod files;
pub mod filter;
pub mod flight_log;
pub mod io;
pub mod recording;
pub mod routing;
pub mod signing;
pub mod stats;
pub mod time;
pub(crate) mod utc;
pub mod wire;
