//! End to end with a real ground station: MAVProxy talks through the router to a simulated
//! ArduPilot quadrotor (`tests/py/vehicle.py`, 300 parameters), downloads every parameter,
//! arms it and sets a parameter. See `tests/common/mavproxy.rs` for the scenario.
//!
//! One test per pair of transports. Adding one takes the router's config, MAVProxy's
//! `--master` and the vehicle's link, nothing else, e.g. MAVProxy as a TCP client of a
//! router TCP server, the vehicle on serial:
//!
//! ```ignore
//! let s = Scratch::new("mavproxy-tcp");
//! let dev = s.path("vehicle");
//! let port = /* a free TCP port */;
//! let config = format!("serial {{ device {dev}; baudrate 115200; }}\n\
//!                       tcp {{ port {port}; }}\ndefault_action accept;\n");
//! ground_station_session(&s, &config, &format!("tcp:127.0.0.1:{port}"), VehicleLink::Serial(dev));
//! ```
//!
//! `tcpin:0.0.0.0:PORT` makes MAVProxy the TCP server for a router TCP client, and
//! `udpin:0.0.0.0:PORT` the UDP server for a router UDP client (the session starts
//! MAVProxy before the router then). The vehicle can equally be the network end:
//! `VehicleLink::Udp("127.0.0.1:P")`, `Tcp("127.0.0.1:P")` or `TcpListen("P")`.
//! A scratch tag must not contain "udp": `Router::start` finds the UDP ports by that word.

use crate::common;

use std::collections::BTreeSet;

use common::mavproxy::{VehicleLink, ground_station_session};
use common::router::{Scratch, free_udp_port};

/// The vehicle on a serial line (a pty), MAVProxy a UDP client of the router's UDP
/// server: `udpout` speaks first, so its heartbeats teach the router where it is.
#[test]
fn mavproxy_on_udp_server_vehicle_on_serial() {
    let s = Scratch::new("mavproxy-serial");
    let dev = s.path("vehicle");
    let port = free_udp_port();
    let config = format!(
        "serial {{ device {dev}; baudrate 115200; }}\n\
         udp {{ port {port}; }}\n\
         default_action accept;\n"
    );
    let session = ground_station_session(
        &s,
        &config,
        &format!("udpout:127.0.0.1:{port}"),
        VehicleLink::Serial(dev.clone()),
    );
    // Both ends were learned on the links this config names.
    let learned = |who: &str, link: &str| {
        session
            .router
            .stdout
            .iter()
            .any(|l| l.contains(&format!("new component {who}")) && l.contains(link))
    };
    assert!(learned("1.1 ", &dev), "{:#?}", session.router.stdout);
    assert!(
        learned("255.", "127.0.0.1:"),
        "{:#?}",
        session.router.stdout
    );
    // MAVProxy tried FTP first; the vehicle's NAK made it ask for the list instead.
    assert!(
        session.vehicle.iter().any(|l| l.starts_with("ftp nak")),
        "{:#?}",
        session.vehicle
    );
    eprintln!("session took {:?}", session.took);
}

/// Both ends UDP clients of one router UDP server: the vehicle's link is pluggable, and
/// the router tells the two apart by their source ports.
#[test]
fn mavproxy_and_vehicle_on_one_udp_server() {
    let s = Scratch::new("mavproxy-net");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; }}\ndefault_action accept;\n");
    let session = ground_station_session(
        &s,
        &config,
        &format!("udpout:127.0.0.1:{port}"),
        VehicleLink::Udp(format!("127.0.0.1:{port}")),
    );
    // "new component 1.1 on 127.0.0.1:PORT": two components, on two links.
    let links: BTreeSet<&str> = session
        .router
        .stdout
        .iter()
        .filter_map(|l| l.split_once("new component ")?.1.split_once(" on "))
        .map(|(_, link)| link)
        .collect();
    assert_eq!(links.len(), 2, "{:#?}", session.router.stdout);
    assert!(
        links.iter().all(|l| l.starts_with("127.0.0.1:")),
        "{links:?}"
    );
    eprintln!("session took {:?}", session.took);
}

fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// The vehicle on serial, MAVProxy a TCP client of the router's TCP server: the
/// accepted connection is a link of its own.
#[test]
fn mavproxy_as_tcp_client_of_a_tcp_server() {
    let s = Scratch::new("mavproxy-tcp-server");
    let dev = s.path("vehicle");
    let port = free_tcp_port();
    let config = format!(
        "serial {{ device {dev}; baudrate 115200; }}\n\
         tcp {{ port {port}; address 127.0.0.1; }}\n\
         default_action accept;\n"
    );
    let session = ground_station_session(
        &s,
        &config,
        &format!("tcp:127.0.0.1:{port}"),
        VehicleLink::Serial(dev),
    );
    assert!(
        session
            .router
            .stdout
            .iter()
            .any(|l| l.contains("new component 255.") && l.contains(" on tcp:127.0.0.1:")),
        "{:#?}",
        session.router.stdout
    );
}

/// The vehicle on serial, MAVProxy listening for TCP (`tcpin`) and the router its TCP
/// client, connecting at start.
#[test]
fn mavproxy_as_tcp_server_for_a_tcp_client() {
    let s = Scratch::new("mavproxy-tcp-client");
    let dev = s.path("vehicle");
    let port = free_tcp_port();
    let config = format!(
        "serial {{ device {dev}; baudrate 115200; }}\n\
         tcp {{ connect 127.0.0.1:{port}; }}\n\
         default_action accept;\n"
    );
    let session = ground_station_session(
        &s,
        &config,
        &format!("tcpin:127.0.0.1:{port}"),
        VehicleLink::Serial(dev),
    );
    eprintln!("session took {:?}", session.took);
}

/// The vehicle on serial, MAVProxy listening on UDP (`udpin`), never speaking first
/// until it hears the vehicle: the router's `udp { connect …; }` sends from the start.
#[test]
fn mavproxy_as_udp_server_for_a_udp_client() {
    let s = Scratch::new("mavproxy-connect");
    let dev = s.path("vehicle");
    let port = free_udp_port();
    let config = format!(
        "serial {{ device {dev}; baudrate 115200; }}\n\
         udp {{ connect 127.0.0.1:{port}; }}\n\
         default_action accept;\n"
    );
    let session = ground_station_session(
        &s,
        &config,
        &format!("udpin:127.0.0.1:{port}"),
        VehicleLink::Serial(dev),
    );
    eprintln!("session took {:?}", session.took);
}
