//! The `websocket { }` block: its values and defaults, how `--ast` prints it, its located
//! errors, the TCP ports it shares with `tcp` blocks, a reload that keeps it, and its
//! command-line endpoint `ws-server:ADDRESS:PORT`.

use mavtables::cli::endpoints;
use mavtables::config::{
    self, DEFAULT_MAX_PEERS, Interface, IpRange, PeerLimits, WebSocketInterface, parse, print_tree,
};
use std::net::IpAddr;

fn one(src: &str) -> Interface {
    match config::load(src) {
        Ok(mut l) => l.config.interfaces.remove(0),
        Err(e) => panic!("{}", config::render_errors("t", src, &e)),
    }
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

fn tree(src: &str) -> String {
    match parse(src) {
        Ok(ast) => print_tree(&ast),
        Err(d) => panic!("{}", d.render("t", src)),
    }
}

#[test]
fn websocket_blocks_and_their_defaults() {
    assert_eq!(
        one("websocket {}"),
        Interface::WebSocket(WebSocketInterface {
            port: 8765,
            address: None,
            max_bitrate: None,
            peers: PeerLimits {
                max_peers: DEFAULT_MAX_PEERS,
                allow: vec![],
            },
            signing: None,
            origins: vec![],
        })
    );
    let Interface::WebSocket(w) = one(
        "websocket {\n    port 8766;\n    address 127.0.0.1;\n    allow 10.0.0.0/8;\n    max_peers 4;\n    max_bitrate 57600;\n}",
    ) else {
        panic!("websocket")
    };
    assert_eq!(
        (w.port, w.address, w.max_bitrate, w.peers.max_peers),
        (8766, Some(ip("127.0.0.1")), Some(57_600), 4)
    );
    assert_eq!(
        w.peers.allow,
        [IpRange {
            address: ip("10.0.0.0"),
            prefix: 8
        }]
    );
}

#[test]
fn websocket_blocks_print_in_the_ast_like_tcp_blocks() {
    assert_eq!(
        tree(
            "websocket\n{\n    port 8765;\n    address 127.0.0.1;\n    allow 10.0.0.0/8;\n    max_peers 4;\n}"
        ),
        ":001:  websocket\n:003:  |  port 8765\n:004:  |  address 127.0.0.1\n:005:  |  allow 10.0.0.0/8\n:006:  |  max_peers 4\n"
    );
    assert_eq!(tree("websocket {}"), ":001:  websocket\n");
}

#[test]
fn websocket_errors_are_located() {
    let e = all("websocket {\n    connect 127.0.0.1:8765;\n}");
    assert!(
        e.starts_with("f:2:13: a websocket block is a server only"),
        "{e}"
    );
    assert!(
        e.contains("note: browsers connect to it; leave out 'connect'"),
        "{e}"
    );
    let e = all("websocket { port 70000; }");
    assert!(e.starts_with("f:1:18: "), "{e}");
    let e = all("websocket { max_peers 0; }");
    assert!(e.starts_with("f:1:23: "), "{e}");
    let e = all("websocket { address 300.0.0.1; }");
    assert!(e.starts_with("f:1:21: Address octet (300)"), "{e}");
    let e = all("websocket { prot 1; }");
    assert!(e.starts_with("f:1:13: unsupported statement"), "{e}");
    assert!(e.contains("did you mean 'port'?"), "{e}");
    let e = all("websocket { port 1 }");
    assert!(
        e.starts_with("f:1:20: expected end of statement ';' character"),
        "{e}"
    );
    let e = all("websockets { }");
    assert!(e.contains("did you mean 'websocket'?"), "{e}");
}

#[test]
fn a_websocket_port_clashes_with_a_tcp_port() {
    let e = all("tcp { port 8765; }\nwebsocket { address 127.0.0.1; }");
    assert!(
        e.starts_with(
            "f:2:1: websocket interface 127.0.0.1:8765 clashes with the tcp interface on line 1 (0.0.0.0:8765)"
        ),
        "{e}"
    );
    let e = all("websocket {}\nwebsocket { port 8765; }");
    assert!(e.starts_with("f:2:1: websocket interface"), "{e}");
    // UDP on the same port number does not clash.
    one("udp { port 8765; }\nwebsocket {}");
}

#[test]
fn the_ws_server_endpoint_stands_for_a_websocket_block() {
    let e = endpoints::parse("ws-server:127.0.0.1:8770")
        .expect("valid")
        .expect("an endpoint");
    assert_eq!(
        e.interface,
        Interface::WebSocket(WebSocketInterface {
            port: 8770,
            address: Some(ip("127.0.0.1")),
            ..WebSocketInterface::default()
        })
    );
    let e = endpoints::parse("ws-server:[::1]:8770")
        .expect("valid")
        .expect("an endpoint");
    assert!(matches!(e.interface, Interface::WebSocket(w) if w.address == Some(ip("::1"))));
    let err = endpoints::parse("ws-server:localhost:8770").expect_err("a host name");
    assert!(err.contains("write ws-server:ADDRESS:PORT"), "{err}");
}

#[test]
fn origin_statements_name_the_pages_that_may_connect() {
    let Interface::WebSocket(w) = one(
        "websocket {\n    origin http://localhost:8080;\n    origin HTTPS://Example.org;\n    origin http://[::1]:3000;\n}",
    ) else {
        panic!("websocket")
    };
    assert_eq!(
        w.origins,
        [
            "http://localhost:8080",
            "https://example.org",
            "http://[::1]:3000"
        ]
    );
    assert_eq!(
        tree("websocket { origin http://localhost:8080; }"),
        ":001:  websocket\n:001:  |  origin http://localhost:8080\n"
    );
    for (src, want) in [
        (
            "tcp { origin http://a; }",
            "f:1:14: 'origin' applies to websocket blocks only",
        ),
        (
            "websocket { origin localhost:8080; }",
            "f:1:20: expected an origin starting with http:// or https://",
        ),
        (
            "websocket { origin http://localhost:8080/app; }",
            "f:1:41: an origin has no path, query or user",
        ),
        (
            "websocket { origin http://local host; }",
            "f:1:33: expected end of statement ';' character",
        ),
        (
            "websocket { origin http://:80; }",
            "f:1:27: expected a host name or address",
        ),
        (
            "websocket { origin http://a:0; }",
            "f:1:29: expected a port number (1 - 65535)",
        ),
        (
            "websocket { origin ; }",
            "f:1:20: expected a web origin, e.g. http://localhost:8080",
        ),
    ] {
        let e = all(src);
        assert!(e.starts_with(want), "{src}: {e}");
    }
}
