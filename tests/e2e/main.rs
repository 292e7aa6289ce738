//! The end-to-end tests, one binary: the `mavtables` binary and its subcommands run as
//! processes against real peers (UDP, TCP, pymavlink, MAVProxy, a browser), each file a
//! module. Tests of different files run in parallel in this one process: none changes
//! the environment or the working directory, every router gets free ports, and the two
//! load-sensitive floods (`signing_attacks`, `peer_flood_e2e`) stay binaries of their
//! own so that they still run with nothing of this binary beside them.

#![forbid(unsafe_code)]

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/signing.rs"]
mod signing;

mod capture_stream;
mod capture_stream_live;
mod capture_tools;
mod cli;
mod config_signing;
mod dialect_runtime;
mod file_limits;
mod flight_log_e2e;
mod flight_log_rotation;
mod forwarding_exact;
mod log_backpressure;
mod peers_mavproxy;
mod pgo_wrapper;
mod rate_caps_e2e;
mod recording_e2e;
mod redundant_links;
mod reload_e2e;
mod router_e2e;
mod signing_peers;
mod stats_command;
mod stats_e2e;
mod stats_page_browser;
mod stats_page_fleet;
mod tcp_faults_e2e;
mod transports_e2e;
mod websocket_browser;
mod websocket_e2e;
#[cfg(feature = "zenoh")]
mod zenoh_e2e;
