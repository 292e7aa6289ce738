//! The real router with its statistics endpoint (`stats { port N; }`) for the tests of
//! the clients of `/stats`: starting it, waiting until the endpoint answers, reading it.

use std::time::Duration;

use mavtables::commands::stats::{Endpoint, fetch};
use serde_json::Value;

use super::eventually;
use super::net::free_tcp_port;
use super::router::{Router, Scratch};

/// A router running `config` plus a `stats` block on a free port of 127.0.0.1; returns
/// once `/stats` answers. The port is the second value.
pub fn start(scratch: &Scratch, config: &str) -> (Router, u16) {
    let port = free_tcp_port();
    let config = format!("{config}\nstats {{ address 127.0.0.1; port {port}; }}\n");
    let router = Router::start(scratch, &config, 0);
    eventually(
        "the statistics endpoint answers",
        Duration::from_secs(10),
        || fetch(&endpoint(port)).is_ok(),
    );
    (router, port)
}

/// The endpoint on 127.0.0.1:`port`.
pub fn endpoint(port: u16) -> Endpoint {
    Endpoint::of_listener([127, 0, 0, 1].into(), port)
}

/// The router's `/stats` now (panics if it does not answer).
pub fn stats(port: u16) -> Value {
    fetch(&endpoint(port)).unwrap_or_else(|e| panic!("/stats: {e}"))
}

/// Waits (at most 15 s) until every link's rates are back to zero: the figures then no
/// longer change while nothing is sent.
pub fn wait_quiet(port: u16) {
    eventually("every rate back to 0", Duration::from_secs(15), || {
        let s = stats(port);
        s["links"].as_array().is_some_and(|links| {
            links.iter().all(|l| {
                ["rate_in_fps", "rate_out_fps", "rate_in_bps", "rate_out_bps"]
                    .iter()
                    .all(|k| l[*k].as_f64() == Some(0.0))
            })
        })
    });
}
