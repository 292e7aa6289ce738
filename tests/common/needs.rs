//! What some tests need of the machine, checked up front: a test that cannot run here
//! fails with what to install or how to run it, never passes without checking anything.
//!
//! Tests that need root or the release build are also `#[ignore]`d with the reason, so
//! a plain `cargo test` lists them as not run; `scripts/test` (the README's test command)
//! runs them with `--include-ignored`.

use std::net::UdpSocket;

/// Panics unless the IPv6 loopback `[::1]` can be bound.
pub fn ipv6_loopback() {
    if let Err(e) = UdpSocket::bind("[::1]:0") {
        panic!(
            "the IPv6 loopback [::1] cannot be used here ({e}); these tests need it: enable IPv6 on lo (sysctl -w net.ipv6.conf.lo.disable_ipv6=0)"
        );
    }
}

/// The optimised router `scripts/test` builds and names in `MAVTABLES_RELEASE_ROUTER`;
/// panics with how to get it when it is not there.
pub fn release_router() -> String {
    super::router::release_binary().unwrap_or_else(|| {
        panic!(
            "this test runs the release router at full rate: run scripts/test (it builds it), or cargo build --release --bin mavtables and set MAVTABLES_RELEASE_ROUTER=$PWD/target/release/mavtables"
        )
    })
}

/// Panics, saying what `what` needs, when the tests do not run as root.
pub fn root(what: &str) {
    // The effective uid of this process, as /proc tells it.
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let euid = status
        .lines()
        .find_map(|l| l.strip_prefix("Uid:"))
        .and_then(|v| v.split_whitespace().nth(1));
    if euid != Some("0") {
        panic!("{what} needs root: run the tests as root (sudo scripts/test)");
    }
}
