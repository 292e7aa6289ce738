//! The in-process tests, one binary: the configuration language, the filter, the wire
//! format, the dialect, signing and the routing core driven on a simulated clock
//! (`routing`), each file a module. Some check against pymavlink (`common::python`).

#![forbid(unsafe_code)]

#[path = "../common/mod.rs"]
mod common;
#[path = "../routing/mod.rs"]
mod routing;

mod config_ast;
mod config_errors;
mod config_flight_log;
mod config_model;
mod config_network;
mod config_paths;
mod config_props;
mod config_rates;
mod config_sizes;
mod config_text;
mod config_websocket;
mod dialect_crosscheck;
mod docs_examples;
mod filter_memo;
mod rate_caps;
mod routing_cases;
mod routing_direct_props;
mod routing_engine;
mod routing_flight_log;
mod routing_queues_props;
mod routing_ready;
mod routing_redundancy;
mod routing_reload;
mod routing_scenarios;
mod routing_signing;
mod wire_properties;
mod wire_signing_pymavlink;
mod wire_vectors;
