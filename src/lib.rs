//! mavtables: a MAVLink router and firewall.
//!
//! The crate is layered so that the folder layout shows the architecture:
//! - [`capture`]: reading raw, `.tlog`, `.pcap` and `.pcapng` captures (pure);
//! - [`wire`]: MAVLink v1/v2 framing, CRC, the streaming parser, signatures (pure);
//! - [`dialect`]: generated message tables (ids, names, CRC_EXTRA, lengths, fields);
//! - [`config`]: the configuration language and its diagnostics;
//! - [`filter`]: the filter chains;
//! - [`routing`]: the sans-IO routing core (learning, decisions, queues, pacing);
//! - [`io`]: the event loop and the UDP / serial drivers;
//! - [`recording`]: recording received frames to `.tlog` files (the sans-IO parts);
//! - [`cli`]: the command line; [`commands`]: the `inspect` and `replay` subcommands;
//! - [`files`]: bounded reads of the files the router is given (configuration, keys,
//!   signing state);
//! - [`utc`]: UTC calendar formatting of timestamps (logs and `inspect`);
//! - [`address`]: MAVLink addresses and subnets.

// Every public item says what it is for (CI turns this warning into an error).
#![warn(missing_docs)]
// The only exception is `io::sys`, the one module of system calls.
#![deny(unsafe_code)]

pub mod address;
pub mod capture;
pub mod cli;
pub mod commands;
pub mod condition;
pub mod config;
pub mod dialect;
pub mod files;
pub mod filter;
pub mod io;
pub mod recording;
pub mod routing;
pub mod signing;
pub mod stats;
pub mod time;
pub mod utc;
pub mod wire;
