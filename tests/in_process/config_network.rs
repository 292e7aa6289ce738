//! The network statements: `udp` clients, `tcp` blocks, IPv6, host names, server limits
//! (`max_peers`, `allow`) and `max_bitrate` on serial ports: their values, defaults and
//! located errors.

use mavtables::config::{
    self, DEFAULT_MAX_PEERS, Host, Interface, IpRange, PeerLimits, Remote, TcpInterface,
    UdpInterface,
};
use std::net::IpAddr;

fn interfaces(src: &str) -> Vec<Interface> {
    match config::load(src) {
        Ok(l) => l.config.interfaces,
        Err(e) => panic!("{}", config::render_errors("t", src, &e)),
    }
}

fn one(src: &str) -> Interface {
    interfaces(src).remove(0)
}

fn ip(s: &str) -> IpAddr {
    s.parse().expect("address")
}

/// Every error of `src`, rendered for a file named `f`.
fn all(src: &str) -> String {
    match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => config::render_errors("f", src, &e),
    }
}

/// The first line of every error.
fn firsts(src: &str) -> Vec<String> {
    all(src)
        .lines()
        .filter(|l| l.starts_with("f:"))
        .map(str::to_string)
        .collect()
}

#[track_caller]
fn check(src: &str, want: &str) {
    assert_eq!(firsts(src)[0], format!("f:{want}"), "source: {src:?}");
}

#[test]
fn udp_clients_connect_and_bind_any_local_port() {
    assert_eq!(
        one("udp { connect 192.168.1.50:14550; }"),
        Interface::Udp(UdpInterface {
            port: 0,
            address: None,
            max_bitrate: None,
            connect: Some(Remote {
                host: Host::Ip(ip("192.168.1.50")),
                port: 14550
            }),
            peers: PeerLimits::default(),
            signing: None,
        })
    );
    let Interface::Udp(u) = one("udp { connect [fd00::7]:14550; port 14551; address ::; }") else {
        panic!("udp")
    };
    assert_eq!(u.port, 14551);
    assert_eq!(u.address, Some(ip("::")));
    assert_eq!(
        u.connect.as_ref().map(|r| r.to_string()).as_deref(),
        Some("[fd00::7]:14550")
    );
    // No address: every address of the peer's family.
    let Interface::Udp(u) = one("udp { connect [::1]:5; }") else {
        panic!("udp")
    };
    assert_eq!(u.local_address(), ip("::"));
    let Interface::Udp(u) = one("udp { connect 10.0.0.1:5; }") else {
        panic!("udp")
    };
    assert_eq!(u.local_address(), ip("0.0.0.0"));
    // Host names are kept as written, not resolved.
    let Interface::Udp(u) = one("udp { connect gcs-1.local:14550; }") else {
        panic!("udp")
    };
    assert_eq!(
        u.connect,
        Some(Remote {
            host: Host::Name("gcs-1.local".into()),
            port: 14550
        })
    );
}

#[test]
fn tcp_blocks_and_their_defaults() {
    assert_eq!(
        one("tcp {}"),
        Interface::Tcp(TcpInterface {
            port: 5760,
            address: None,
            max_bitrate: None,
            connect: None,
            peers: PeerLimits {
                max_peers: DEFAULT_MAX_PEERS,
                allow: vec![]
            },
            signing: None,
        })
    );
    assert_eq!(DEFAULT_MAX_PEERS, 128);
    let Interface::Tcp(t) = one("tcp { port 5761; address 0.0.0.0; max_bitrate 0; }") else {
        panic!("tcp")
    };
    assert_eq!(
        (t.port, t.address, t.max_bitrate),
        (5761, Some(ip("0.0.0.0")), None)
    );
    let Interface::Tcp(t) = one("tcp { connect localhost:5760; max_bitrate 115200; }") else {
        panic!("tcp")
    };
    assert_eq!(
        t.connect.map(|r| r.to_string()).as_deref(),
        Some("localhost:5760")
    );
    assert_eq!(t.max_bitrate, Some(115_200));
    // A server's default port stays 14500 for udp.
    let Interface::Udp(u) = one("udp {}") else {
        panic!("udp")
    };
    assert_eq!((u.port, u.address, u.connect), (14500, None, None));
}

#[test]
fn server_limits() {
    let Interface::Udp(u) = one(
        "udp { port 14550; max_peers 16; allow 192.168.1.0/24; allow fd00::/8; allow 10.0.0.7; }",
    ) else {
        panic!("udp")
    };
    assert_eq!(u.peers.max_peers, 16);
    assert_eq!(
        u.peers.allow,
        [
            IpRange {
                address: ip("192.168.1.0"),
                prefix: 24
            },
            IpRange {
                address: ip("fd00::"),
                prefix: 8
            },
            IpRange {
                address: ip("10.0.0.7"),
                prefix: 32
            },
        ]
    );
    assert!(u.peers.allows(ip("192.168.1.200")));
    assert!(u.peers.allows(ip("::ffff:10.0.0.7")));
    assert!(!u.peers.allows(ip("10.0.0.8")));
    assert!(!u.peers.allows(ip("fe80::1")));
    // Without `allow`, any address.
    assert!(PeerLimits::default().allows(ip("203.0.113.9")));
    let Interface::Tcp(t) = one("tcp { max_peers 65535; max_peers 1; allow ::1; }") else {
        panic!("tcp")
    };
    assert_eq!(t.peers.max_peers, 1);
    assert_eq!(
        t.peers.allow,
        [IpRange {
            address: ip("::1"),
            prefix: 128
        }]
    );
}

#[test]
fn serial_max_bitrate_and_ipv6_addresses() {
    let c = interfaces(
        "serial { device /dev/ttyUSB0; baudrate 57600; max_bitrate 57600; }\n\
         serial { device /dev/ttyUSB1; max_bitrate 0; }\n\
         udp { address fd00::7; port 1; }\nudp { address ::ffff:127.0.0.1; port 2; }",
    );
    assert!(matches!(&c[0], Interface::Serial(s) if s.max_bitrate == Some(57_600)));
    assert!(matches!(&c[1], Interface::Serial(s) if s.max_bitrate.is_none()));
    assert!(matches!(&c[2], Interface::Udp(u) if u.address == Some(ip("fd00::7"))));
    assert!(matches!(&c[3], Interface::Udp(u) if u.address == Some(ip("::ffff:127.0.0.1"))));
}

#[test]
fn bad_hosts_and_ports_in_connect() {
    check(
        "udp { connect 300.1.1.1:5; }",
        "1:15: '300.1.1.1' is not a valid IPv4 address: 300 is outside of the allowed range (0 - 255)",
    );
    check(
        "udp { connect 1.2.3:5; }",
        "1:15: '1.2.3' is not a valid IPv4 address",
    );
    check(
        "udp { connect exa_mple:5; }",
        "1:18: 'exa_mple' is not a valid host name: '_' is not allowed",
    );
    check(
        "tcp { connect -bad.host:5; }",
        "1:15: '-bad.host' is not a valid host name: each part between dots needs 1 - 63 characters and cannot start or end with '-'",
    );
    check(
        "udp { connect 10.0.0.1; }",
        "1:23: expected ':' and a port number after the host",
    );
    check(
        "udp {\n    connect 10.0.0.1\n}",
        "2:21: expected ':' and a port number after the host",
    );
    check(
        "udp { connect 10.0.0.1:; }",
        "1:24: expected a port number after ':'",
    );
    check(
        "udp { connect :5; }",
        "1:15: expected a host (an IP address or a host name) before ':'",
    );
    check(
        "udp { connect 10.0.0.1:0; }",
        "1:24: port number (0) is outside of the allowed range (1 - 65535)",
    );
    check(
        "udp { connect 10.0.0.1:65536; }",
        "1:24: port number (65536) is outside of the allowed range (1 - 65535)",
    );
    check(
        "udp { connect 10.0.0.1:14550x; }",
        "1:24: expected a valid port number",
    );
    check(
        "udp { connect fd00::7:14550; }",
        "1:15: an IPv6 address must be written in brackets",
    );
    assert!(all("udp { connect fd00::7:14550; }").contains("note: write [fd00::7]:14550\n"));
    check(
        "udp { connect [fd00::7:1; }",
        "1:25: expected ']' closing the IPv6 address",
    );
    check(
        "udp { connect [::1]; }",
        "1:20: expected ':' and a port number after ']'",
    );
    check(
        "udp { connect [1.2.3.4]:1; }",
        "1:16: '1.2.3.4' is not a valid IPv6 address",
    );
    check("udp { connect; }", "1:14: expected a host and port");
    check(
        "udp { connect a:1; connect b:2; }",
        "1:28: a block connects to one peer only",
    );
}

#[test]
fn client_blocks_refuse_server_statements() {
    check(
        "tcp { connect localhost:5760; port 5761; }",
        "1:36: a TCP client has no local port to set",
    );
    // A UDP client may choose its local port.
    interfaces("udp { connect localhost:14550; port 14551; }");
    assert_eq!(
        firsts("udp { connect a:1; max_peers 3; allow 1.2.3.4; }"),
        [
            "f:1:30: 'max_peers' applies to server blocks only",
            "f:1:39: 'allow' applies to server blocks only",
        ]
    );
    assert!(all("tcp { connect a:1; allow ::1; }").contains(
        "note: this tcp block is a client of a:1 (it has 'connect'); a client has one peer"
    ));
    check(
        "udp { connect 1.2.3.4:5; address ::; }",
        "1:34: address :: is IPv6, but the block connects to the IPv4 address 1.2.3.4",
    );
    check(
        "tcp { address 10.0.0.1; connect [fd00::7]:5760; }",
        "1:15: address 10.0.0.1 is IPv4, but the block connects to the IPv6 address fd00::7",
    );
    // A host name could be either family: any address is allowed.
    interfaces("udp { connect localhost:5; address ::1; }");
}

#[test]
fn allow_ranges_and_max_peers_are_checked() {
    assert_eq!(
        firsts("udp { allow 10.0.0.0/33; allow fd00::/129; allow ::/128; allow 0.0.0.0/0; }"),
        [
            "f:1:22: prefix length (33) is outside of the allowed range (0 - 32)",
            "f:1:39: prefix length (129) is outside of the allowed range (0 - 128)",
        ]
    );
    check(
        "udp { allow 10.300.0.0/8; }",
        "1:16: Address octet (300) is outside of the allowed range (0 - 255).",
    );
    check(
        "udp { allow 1.2.3.4/; }",
        "1:21: expected a prefix length (a number of bits) after '/'",
    );
    check("udp { allow x; }", "1:13: expected a valid IP address");
    check(
        "udp { max_peers 0; }",
        "1:17: max_peers (0) is outside of the allowed range (1 - 65535)",
    );
    check(
        "tcp { max_peers 65536; }",
        "1:17: max_peers (65536) is outside of the allowed range (1 - 65535)",
    );
    check(
        "udp { max_peers many; }",
        "1:17: expected a valid number of peers",
    );
    check(
        "udp { address fd00:::1; }",
        "1:15: expected a valid IP address",
    );
    check(
        "serial { device a; max_bitrate x; }",
        "1:32: expected a valid bitrate",
    );
    check("tcp { baudrate 1; }", "1:7: unsupported statement");
    assert!(all("tcp { conect a:1; }").contains("note: did you mean 'connect'?"));
}

#[test]
fn two_blocks_claiming_one_local_socket() {
    check(
        "tcp {}\ntcp { port 5760; address 127.0.0.1; }",
        "2:1: tcp interface 127.0.0.1:5760 clashes with the tcp interface on line 1 (0.0.0.0:5760)",
    );
    check(
        "udp { address ::; port 14550; }\nudp { port 14550; address 10.0.0.1; }",
        "2:1: udp interface 10.0.0.1:14550 clashes with the udp interface on line 1 ([::]:14550)",
    );
    check(
        "udp { connect [::1]:5; port 14550; }\nudp { port 14550; address ::1; }",
        "2:1: udp interface [::1]:14550 clashes with the udp interface on line 1 ([::]:14550)",
    );
    for ok in [
        // TCP and UDP do not clash; TCP clients hold no chosen port; UDP clients bind any
        // free port unless told.
        "tcp { port 14550; }\nudp { port 14550; }",
        "tcp { connect a:5760; }\ntcp { connect b:5760; }\ntcp {}",
        "udp { connect a:1; }\nudp { connect b:1; }\nudp { port 0; }",
        // Specific addresses of different families, and IPv4 any beside an IPv6 address.
        "udp { port 1; address 0.0.0.0; }\nudp { port 1; address ::1; }",
        "tcp { address fd00::1; }\ntcp { address fd00::2; }",
    ] {
        assert!(config::load(ok).is_ok(), "{ok}");
    }
}

#[test]
fn existing_forms_keep_their_meaning() {
    // Punctuation without spaces, and IPv4 addresses, read as before.
    let Interface::Udp(u) = one("udp{port 14500;address 127.0.0.1;}") else {
        panic!("udp")
    };
    assert_eq!((u.port, u.address), (14500, Some(ip("127.0.0.1"))));
    assert!(config::load("udp { address 0.0.0.0; }\nudp { port 14501; }").is_ok());
}
