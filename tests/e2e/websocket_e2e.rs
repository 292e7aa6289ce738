//! The `websocket { }` interface end to end: the real `mavtables` binary, a UDP vehicle
//! (a plain socket of our own) and WebSocket clients made with `tungstenite`'s client
//! side, all on 127.0.0.1. Frames both ways, frames split across and packed into
//! messages, text and oversized messages, `max_peers` and `allow`, a connection that
//! never completes its handshake, a client that never reads, and a reload. Every wait is
//! bounded and ends on an event (a log line, a frame, a counters report, a closed socket).

use crate::common;

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use common::eventually;
use common::net::{
    ACCEPT_ALL, Counters, SECOND, attitude, connect, counters, free_tcp_port, heartbeat,
    numbered_large, status_bytes, udp_frames,
};
use common::router::{Router, Scratch, free_udp_port};
use tungstenite::{Message, WebSocket};

const MIB: u64 = 1024 * 1024;

/// A router with a UDP vehicle port and a `websocket` block (plus `extra` statements in
/// it, and `more` config): the router, the vehicle's UDP port and the WebSocket port.
fn router(s: &Scratch, extra: &str, more: &str) -> (Router, u16, u16) {
    let (udp, ws) = (free_udp_port(), free_tcp_port());
    let config = format!(
        "udp {{ port {udp}; address 127.0.0.1; }}\n\
         websocket {{ port {ws}; address 127.0.0.1;{extra} }}\n{more}{ACCEPT_ALL}"
    );
    (Router::start(s, &config, 1), udp, ws)
}

/// A vehicle on the router's UDP port that has said a heartbeat from `sys` (seen by the
/// router).
fn vehicle(router: &mut Router, port: u16, sys: u8) -> UdpSocket {
    let v = UdpSocket::bind("127.0.0.1:0").expect("bind");
    v.connect(format!("127.0.0.1:{port}")).expect("connect");
    v.send(&heartbeat(sys)).expect("send");
    router.wait_for(&format!("new component {sys}.1 on 127.0.0.1:"));
    v
}

type Client = WebSocket<TcpStream>;

/// A WebSocket client of the router's port, its handshake done.
fn ws_client(port: u16) -> Client {
    let stream = connect(&format!("127.0.0.1:{port}"));
    stream
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let (ws, _) =
        tungstenite::client(format!("ws://127.0.0.1:{port}/mavlink"), stream).expect("handshake");
    ws
}

/// A client whose receive buffer is small, so the router's writes to it soon block (it
/// has said a heartbeat from `sys`; its reads block).
fn small_window_client(router: &mut Router, port: u16, sys: u8) -> Client {
    let socket =
        socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    socket.set_recv_buffer_size(4096).expect("rcvbuf");
    let addr: std::net::SocketAddr = format!("127.0.0.1:{port}").parse().expect("addr");
    socket.connect(&addr.into()).expect("connect");
    let stream: TcpStream = socket.into();
    let (mut ws, _) =
        tungstenite::client(format!("ws://127.0.0.1:{port}/"), stream).expect("handshake");
    ws.send(Message::binary(heartbeat(sys))).expect("send");
    router.wait_for(&format!("new component {sys}.1 on ws:127.0.0.1:"));
    ws
}

/// A client that has said a heartbeat from `sys` (seen by the router, on a `ws:` link).
fn ws_join(router: &mut Router, port: u16, sys: u8) -> Client {
    let mut ws = ws_client(port);
    ws.send(Message::binary(heartbeat(sys))).expect("send");
    router.wait_for(&format!("new component {sys}.1 on ws:127.0.0.1:"));
    ws
}

/// The router's name for the link of client `ws`.
fn link_name(ws: &Client) -> String {
    format!("ws:{}", ws.get_ref().local_addr().expect("addr"))
}

/// Binary messages read until `want` arrived or `timeout` passed (other messages are
/// skipped; a closed connection ends the wait).
fn messages(ws: &mut Client, want: usize, timeout: Duration) -> Vec<Vec<u8>> {
    let deadline = Instant::now() + timeout;
    let mut got = Vec::new();
    while got.len() < want && Instant::now() < deadline {
        match ws.read() {
            Ok(Message::Binary(b)) => got.push(b.to_vec()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
    }
    got
}

/// Whether the router closed client `ws` within `timeout` (and when).
fn closed_within(ws: &mut Client, timeout: Duration) -> Option<Duration> {
    let start = Instant::now();
    while start.elapsed() < timeout {
        match ws.read() {
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Ok(Message::Close(_)) | Err(_) => return Some(start.elapsed()),
            Ok(_) => {}
        }
    }
    None
}

/// Polls the counters report until `check` holds (at most 10 s); returns that report.
fn counters_until(router: &mut Router, what: &str, check: impl Fn(&Counters) -> bool) -> Counters {
    eventually(what, 10 * SECOND, || {
        let c = counters(router);
        if check(&c) {
            Ok(c)
        } else {
            Err(format!("last report:\n{}", c.text))
        }
    })
}

/// Frames go both ways between a UDP vehicle and a WebSocket client, one whole frame per
/// message from the router; what the client sends is one byte stream: several frames in
/// one message, and a frame split across two messages, all arrive, in order.
#[test]
fn frames_travel_both_ways_as_binary_messages() {
    let s = Scratch::new("ws-both-ways");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let mut ws = ws_join(&mut router, port, 255);
    // The client's heartbeat reached the vehicle.
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [heartbeat(255)]);
    // The vehicle's frames reach the client, one per message.
    let sent: Vec<Vec<u8>> = (0..5).map(|n| attitude(1, n)).collect();
    for f in &sent {
        v.send(f).expect("send");
    }
    assert_eq!(messages(&mut ws, 5, 5 * SECOND), sent);
    // Three frames in one message.
    let three: Vec<Vec<u8>> = (10..13).map(|n| attitude(255, n)).collect();
    ws.send(Message::binary(three.concat())).expect("send");
    assert_eq!(udp_frames(&v, 3, 5 * SECOND), three);
    // One frame in two messages.
    let split = attitude(255, 20);
    let (head, tail) = split.split_at(9);
    ws.send(Message::binary(head.to_vec())).expect("send");
    ws.send(Message::binary(tail.to_vec())).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [split]);
    // A ping is answered.
    ws.send(Message::Ping(b"are you there".to_vec().into()))
        .expect("ping");
    let deadline = Instant::now() + 5 * SECOND;
    let pong = loop {
        assert!(Instant::now() < deadline, "no pong within 5 s");
        match ws.read() {
            Ok(Message::Pong(p)) => break p.to_vec(),
            Ok(other) => panic!("{other:?} instead of a pong"),
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(e) => panic!("{e}"),
        }
    };
    assert_eq!(pong, b"are you there");
    let name = link_name(&ws);
    let c = counters(&mut router);
    let link = c.link(&name).expect("the client's link");
    assert_eq!((link.frames_in, link.frames_out), (5, 5), "{}", c.text);
    // A closing handshake removes the link; the router keeps routing for a new client.
    ws.close(None).expect("close");
    assert!(closed_within(&mut ws, 5 * SECOND).is_some());
    let mut again = ws_join(&mut router, port, 254);
    v.send(&attitude(1, 30)).expect("send");
    assert_eq!(messages(&mut again, 1, 5 * SECOND), [attitude(1, 30)]);
    let c = Counters::at_exit(&router.stop().stderr);
    let links = c.links.iter().filter(|l| l.name.starts_with("ws:")).count();
    assert_eq!(links, 1, "one ws link left:\n{}", c.text);
}

/// Text messages are not MAVLink: their bytes are counted as junk and dropped, and the
/// connection stays (a frame sent after them is routed).
#[test]
fn text_messages_are_counted_as_junk_and_ignored() {
    let s = Scratch::new("ws-text");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let mut ws = ws_join(&mut router, port, 255);
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [heartbeat(255)]);
    // Text that holds a whole frame's bytes would parse if it were fed to the parser.
    let frame_text: String = attitude(255, 1)
        .iter()
        .map(|&b| char::from(b & 0x7f))
        .collect();
    ws.send(Message::text("hello router")).expect("send");
    ws.send(Message::text(frame_text.clone())).expect("send");
    ws.send(Message::binary(attitude(255, 2))).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [attitude(255, 2)]);
    let junk = (12 + frame_text.len()) as u64;
    // Counted on the connection's own interface.
    let label = link_name(&ws);
    let c = counters_until(&mut router, "the text counted as junk", |c| {
        c.interface(&label).is_some_and(|i| i.junk_bytes == junk)
    });
    assert_eq!(
        c.interface(&label).expect("label").io_errors,
        0,
        "{}",
        c.text
    );
    router.stop();
}

/// A message over 64 KiB closes the connection (logged, counted as an I/O error); one of
/// exactly 64 KiB does not; another client keeps routing.
#[test]
fn an_oversized_message_closes_the_connection() {
    let s = Scratch::new("ws-oversized");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let mut big = ws_join(&mut router, port, 200);
    let mut other = ws_join(&mut router, port, 201);
    assert_eq!(udp_frames(&v, 2, 5 * SECOND).len(), 2);
    big.send(Message::binary(vec![0u8; 64 * 1024]))
        .expect("send");
    big.send(Message::binary(attitude(200, 1))).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [attitude(200, 1)]);
    big.send(Message::binary(vec![0u8; 64 * 1024 + 1]))
        .expect("send");
    router.err.wait_for("message over 65536 bytes", 10 * SECOND);
    assert_eq!(
        close_code(&mut big, 5 * SECOND),
        Some(1009),
        "said why (too big)"
    );
    other.send(Message::binary(attitude(201, 2))).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [attitude(201, 2)]);
    let label = format!("websocket 127.0.0.1:{port}");
    let c = counters_until(&mut router, "one I/O error", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 1)
    });
    assert!(c.link(&link_name(&big)).is_none(), "{}", c.text);
    // A frame a client sends unmasked breaks the protocol: closed, saying so.
    let mut raw = ws_join(&mut router, port, 202);
    raw.get_mut().write_all(&[0x82, 0x01, 0x00]).expect("write");
    assert_eq!(
        close_code(&mut raw, 5 * SECOND),
        Some(1002),
        "said why (protocol)"
    );
    counters_until(&mut router, "two I/O errors", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 2)
    });
    // A Close with a code the protocol does not allow (999, masked with a zero key) is
    // the peer's error too: answered 1002, said and counted.
    let mut odd = ws_join(&mut router, port, 203);
    odd.get_mut()
        .write_all(&[0x88, 0x82, 0, 0, 0, 0, 0x03, 0xE7])
        .expect("write");
    assert_eq!(close_code(&mut odd, 5 * SECOND), Some(1002));
    router.err.wait_for(
        "closed by the peer with code 1002: Protocol violation",
        10 * SECOND,
    );
    counters_until(&mut router, "three I/O errors", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 3)
    });
    router.stop();
}

/// A client the router is behind with (its window is full) still learns why it is
/// closed: the Close frame waits behind what the router has for it, and the router keeps
/// the socket until it is out. Closed at once with the client's message unread, the
/// connection would be reset, and the Close never sent.
#[test]
fn a_client_behind_on_reading_still_gets_its_close_frame() {
    behind_on_reading_then_too_big("ws-behind", false);
}

/// As above, for a client that ends its sending side right after the oversized message:
/// it can still read, and the Close still goes out to it.
#[test]
fn a_client_that_ends_its_side_still_gets_its_close_frame() {
    behind_on_reading_then_too_big("ws-behind-ended", true);
}

/// A client the router's writes to have blocked sends a message over 64 KiB (then ends
/// its sending side if `end`), and then reads: it must get the backlog and Close 1009.
fn behind_on_reading_then_too_big(scratch: &str, end: bool) {
    let s = Scratch::new(scratch);
    let (mut router, udp, port) = router(&s, "", "queue { link_bytes 100000; }\n");
    let v = vehicle(&mut router, udp, 1);
    let mut stuck = small_window_client(&mut router, port, 30);
    let name = link_name(&stuck);
    // Frames until the router's writes block and its queue for the client overflows.
    let mut n = 0;
    eventually("the stuck client's queue overflows", 20 * SECOND, || {
        for _ in 0..500 {
            v.send(&numbered_large(1, n)).expect("send");
            n += 1;
        }
        let c = counters(&mut router);
        match c.link(&name) {
            Some(l) if l.queue_drops > 0 => Ok(()),
            _ => Err(c.text),
        }
    });
    stuck
        .send(Message::binary(vec![0u8; 64 * 1024 + 1]))
        .expect("send");
    if end {
        stuck
            .get_ref()
            .shutdown(std::net::Shutdown::Write)
            .expect("shutdown");
    }
    router.err.wait_for("message over 65536 bytes", 10 * SECOND);
    stuck
        .get_ref()
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    assert_eq!(
        close_code(&mut stuck, 5 * SECOND),
        Some(1009),
        "the Close frame did not come after the backlog"
    );
    router.stop();
}

/// A client still sending an oversized message when the router closes it (its send
/// blocked until the router reads) completes the send, then reads the Close frame: the
/// router reads and drops the rest of the message meanwhile. Closed under the client's
/// bytes, the connection would be reset: the send fails, and the Close is never read.
#[test]
fn a_client_still_sending_an_oversized_message_reads_its_close_frame() {
    let s = Scratch::new("ws-still-sending");
    let (mut router, _, port) = router(&s, "", "");
    let mut big = ws_join(&mut router, port, 200);
    big.get_ref()
        .set_write_timeout(Some(10 * SECOND))
        .expect("timeout");
    // More than the client's send buffer and the router's receive buffer can hold.
    let sent = big.send(Message::binary(vec![0u8; 6 * MIB as usize]));
    assert!(sent.is_ok(), "the send failed: {sent:?}");
    assert_eq!(close_code(&mut big, 5 * SECOND), Some(1009));
    router.err.wait_for("message over 65536 bytes", 5 * SECOND);
    router.stop();
}

/// The code of the Close frame the router sends client `ws` within `timeout` (None: it
/// closed without one, or not at all).
fn close_code(ws: &mut Client, timeout: Duration) -> Option<u16> {
    let start = Instant::now();
    while start.elapsed() < timeout {
        match ws.read() {
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Ok(Message::Close(frame)) => return frame.map(|f| u16::from(f.code)),
            Err(_) => return None,
            Ok(_) => {}
        }
    }
    None
}

/// `max_peers` and `allow` as for `tcp`: a connection beyond the limit, or from outside
/// the ranges, is closed before its handshake (counted per reason); the others route.
#[test]
fn max_peers_and_allow_refuse_connections() {
    let s = Scratch::new("ws-limits");
    let (mut router, udp, port) = router(&s, " max_peers 1;", "");
    let fenced = free_tcp_port();
    let v = vehicle(&mut router, udp, 1);
    let mut first = ws_join(&mut router, port, 255);
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [heartbeat(255)]);
    let stream = connect(&format!("127.0.0.1:{port}"));
    assert!(
        tungstenite::client(format!("ws://127.0.0.1:{port}/"), stream).is_err(),
        "a second peer was taken"
    );
    router.err.wait_for("max_peers", 5 * SECOND);
    v.send(&attitude(1, 1)).expect("send");
    assert_eq!(messages(&mut first, 1, 5 * SECOND), [attitude(1, 1)]);
    router.stop();

    let config = format!(
        "udp {{ port {udp}; address 127.0.0.1; }}\n\
         websocket {{ port {fenced}; address 127.0.0.1; allow 10.0.0.0/8; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let stream = connect(&format!("127.0.0.1:{fenced}"));
    assert!(
        tungstenite::client(format!("ws://127.0.0.1:{fenced}/"), stream).is_err(),
        "a peer outside the ranges was taken"
    );
    router
        .err
        .wait_for("outside the allowed address ranges", 5 * SECOND);
    let err = router.stop().stderr.join("\n");
    assert!(
        err.contains("1 refused (not allowed), 0 refused (max_peers)"),
        "{err}"
    );
}

/// A connection that never completes its handshake (silent, or half a request) is closed
/// after about 5 s (logged, counted); one that completes it in time stays.
#[test]
fn a_connection_without_a_handshake_is_closed_after_5_s() {
    let s = Scratch::new("ws-silent");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let to = format!("127.0.0.1:{port}");
    let start = Instant::now();
    let mut silent = connect(&to);
    let mut half = connect(&to);
    half.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n")
        .expect("write");
    let mut ws = ws_join(&mut router, port, 255);
    for (name, stream) in [("silent", &mut silent), ("half", &mut half)] {
        stream.set_read_timeout(Some(10 * SECOND)).expect("timeout");
        let mut buf = [0u8; 64];
        let n = stream.read(&mut buf);
        let took = start.elapsed();
        assert!(
            matches!(n, Ok(0)) || n.is_err(),
            "{name}: read {n:?} instead of the end"
        );
        assert!(
            (Duration::from_millis(4500)..Duration::from_secs(8)).contains(&took),
            "{name}: closed after {took:?}"
        );
    }
    router
        .err
        .wait_for("handshake not completed within 5 s", 5 * SECOND);
    // The client that completed its handshake is still served.
    v.send(&attitude(1, 1)).expect("send");
    let got = messages(&mut ws, 2, 5 * SECOND);
    assert!(got.contains(&attitude(1, 1)), "{got:?}");
    let label = format!("websocket 127.0.0.1:{port}");
    let c = counters_until(&mut router, "two I/O errors", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 2)
    });
    assert_eq!(
        c.links.iter().filter(|l| l.name.starts_with("ws:")).count(),
        1,
        "{}",
        c.text
    );
    router.stop();
}

/// What the router answers to `request` on its WebSocket port `port`: everything it
/// wrote until it closed the connection (at most 5 s).
fn answer_to(port: u16, request: &str) -> String {
    let mut c = connect(&format!("127.0.0.1:{port}"));
    c.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    c.write_all(request.as_bytes()).expect("write");
    let mut answer = String::new();
    let _ = c.read_to_string(&mut answer);
    answer
}

/// A request that is not a WebSocket upgrade gets an HTTP answer that says why, not a
/// bare close: 426 naming the upgrade to a plain GET (a browser opening the port as a
/// page), 426 naming version 13 to another WebSocket version, 405 to another method,
/// 400 to what is not HTTP. Each is logged; the port still takes real clients.
#[test]
fn a_request_that_is_not_an_upgrade_is_answered() {
    let s = Scratch::new("ws-refusals");
    let (mut router, _, port) = router(&s, "", "");
    let page = answer_to(port, "GET / HTTP/1.1\r\nHost: x\r\n\r\n");
    assert!(
        page.starts_with("HTTP/1.1 426 Upgrade Required\r\n"),
        "{page:?}"
    );
    assert!(page.contains("\r\nUpgrade: websocket\r\n"), "{page:?}");
    assert!(
        page.ends_with("MAVLink frames in binary messages.\n"),
        "{page:?}"
    );
    router
        .err
        .wait_for("WebSocket handshake failed: ", 5 * SECOND);
    let version = answer_to(
        port,
        "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n",
    );
    assert!(version.starts_with("HTTP/1.1 426 "), "{version:?}");
    assert!(
        version.contains("\r\nSec-WebSocket-Version: 13\r\n"),
        "{version:?}"
    );
    let post = answer_to(
        port,
        "POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n",
    );
    assert!(
        post.starts_with("HTTP/1.1 405 Method Not Allowed\r\n"),
        "{post:?}"
    );
    assert!(post.contains("\r\nAllow: GET\r\n"), "{post:?}");
    // The answer to a HEAD has no body (RFC 9110 9.3.2).
    let head = answer_to(port, "HEAD / HTTP/1.1\r\nHost: x\r\n\r\n");
    assert!(
        head.starts_with("HTTP/1.1 405 ")
            && head.ends_with("Content-Length: 0\r\nConnection: close\r\n\r\n"),
        "{head:?}"
    );
    let junk = answer_to(port, "hello\r\n\r\n");
    assert!(junk.starts_with("HTTP/1.1 400 Bad Request\r\n"), "{junk:?}");
    let line = router
        .err
        .wait_for("(answered 400 Bad Request)", 5 * SECOND);
    assert!(line.contains("WebSocket handshake failed: "), "{line}");
    let _client = ws_join(&mut router, port, 5);
    router.stop();
}

/// A refused request's answer reaches a client that is still sending a body, and the
/// connection ends cleanly: the router reads and drops the rest of the body until the
/// client ends. Closed with the body unread, the connection would be reset: the
/// client's send fails, and a client such as curl then reports the reset, not the answer.
#[test]
fn a_refused_request_with_a_body_is_answered_without_a_reset() {
    const BODY: usize = 2 * 1024 * 1024;
    let s = Scratch::new("ws-refused-body");
    let (mut router, _, port) = router(&s, "", "");
    let mut c = connect(&format!("127.0.0.1:{port}"));
    c.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    let mut writer = c.try_clone().expect("clone");
    let sender = std::thread::spawn(move || {
        let head = format!("POST / HTTP/1.1\r\nHost: x\r\nContent-Length: {BODY}\r\n\r\n");
        writer.write_all(head.as_bytes())?;
        writer.write_all(&vec![b'x'; BODY])?;
        writer.shutdown(std::net::Shutdown::Write)
    });
    let mut answer = Vec::new();
    let read = c.read_to_end(&mut answer);
    let sent = sender.join().expect("sender");
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 405 "), "{answer:?}");
    assert!(read.is_ok(), "the answer ended with {read:?}");
    assert!(sent.is_ok(), "sending the body failed: {sent:?}");
    router
        .err
        .wait_for("(answered 405 Method Not Allowed)", 5 * SECOND);
    let _client = ws_join(&mut router, port, 5);
    router.stop();
}

/// Refused requests whose clients never end wait for them at most 64 at a time: beyond,
/// a connection is closed at once, so a flood of bad requests cannot hold the router's
/// descriptors. Each still gets its answer.
#[test]
fn at_most_64_refused_connections_wait_for_their_clients() {
    let s = Scratch::new("ws-parting-cap");
    let (mut router, _, port) = router(&s, "", "");
    let pid = router.pid();
    let descriptors = || {
        std::fs::read_dir(format!("/proc/{pid}/fd"))
            .expect("the router's descriptors")
            .count()
    };
    let before = descriptors();
    let mut clients: Vec<TcpStream> = (0..100)
        .map(|_| {
            let mut c = connect(&format!("127.0.0.1:{port}"));
            c.set_read_timeout(Some(5 * SECOND)).expect("timeout");
            c.write_all(b"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\nxxxx")
                .expect("write");
            c
        })
        .collect();
    for (i, c) in clients.iter_mut().enumerate() {
        // The answer, then the end (or a reset, for those closed at once).
        let mut answer = Vec::new();
        let mut buf = [0u8; 1024];
        while let Ok(n @ 1..) = c.read(&mut buf) {
            answer.extend_from_slice(&buf[..n]);
        }
        assert!(
            answer.starts_with(b"HTTP/1.1 405 "),
            "client {i}: {:?}",
            String::from_utf8_lossy(&answer)
        );
    }
    // The clients are still connected, none has ended: those waiting still hold theirs
    // (the router may have opened a descriptor or two of its own since `before`).
    let held = descriptors().saturating_sub(before);
    assert!(
        held <= 64 + 4,
        "{held} descriptors held for 100 refused clients"
    );
    router.stop();
}

/// A client handshaking with `origin` as its `Origin` header (None: without one).
fn ws_client_from(port: u16, origin: Option<&str>) -> tungstenite::Result<Client> {
    ws_client_with_origins(port, origin.as_slice())
}

/// A client handshaking with one `Origin` header for each of `origins`.
fn ws_client_with_origins(port: u16, origins: &[&str]) -> tungstenite::Result<Client> {
    use tungstenite::client::IntoClientRequest;
    let stream = connect(&format!("127.0.0.1:{port}"));
    stream
        .set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let mut request = format!("ws://127.0.0.1:{port}/")
        .into_client_request()
        .expect("request");
    for origin in origins {
        request
            .headers_mut()
            .append("Origin", origin.parse().expect("header"));
    }
    tungstenite::client(request, stream)
        .map(|(ws, _)| ws)
        .map_err(|e| match e {
            tungstenite::HandshakeError::Failure(e) => e,
            tungstenite::HandshakeError::Interrupted(_) => panic!("blocking client interrupted"),
        })
}

/// With `origin` statements, a browser's request from another origin is refused with
/// 403 (logged, counted); a listed origin (in any case) and a request without an
/// `Origin` header (not a web page) are taken.
#[test]
fn origin_statements_refuse_other_sites_pages() {
    let s = Scratch::new("ws-origin");
    let (mut router, udp, port) = router(
        &s,
        " origin http://127.0.0.1:8080; origin https://ground.example;",
        "",
    );
    let v = vehicle(&mut router, udp, 1);
    match ws_client_from(port, Some("https://evil.example")) {
        Err(tungstenite::Error::Http(r)) => assert_eq!(r.status(), 403),
        other => panic!("{:?} instead of 403", other.map(|_| ())),
    }
    router
        .err
        .wait_for("origin is not one the block allows", 5 * SECOND);
    // A listed origin beside another (no browser sends two) is refused too.
    match ws_client_with_origins(port, &["https://ground.example", "https://evil.example"]) {
        Err(tungstenite::Error::Http(r)) => assert_eq!(r.status(), 403),
        other => panic!("{:?} instead of 403", other.map(|_| ())),
    }
    router
        .err
        .wait_for("origin is not one the block allows", 5 * SECOND);
    let mut listed = ws_client_from(port, Some("HTTPS://ground.example")).expect("listed");
    let mut tool = ws_client_from(port, None).expect("no origin");
    v.send(&attitude(1, 1)).expect("send");
    assert_eq!(messages(&mut listed, 1, 5 * SECOND), [attitude(1, 1)]);
    assert_eq!(messages(&mut tool, 1, 5 * SECOND), [attitude(1, 1)]);
    let label = format!("websocket 127.0.0.1:{port}");
    counters_until(&mut router, "two I/O errors", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 2)
    });
    router.stop();
}

/// `mavtables udp-server:… ws-server:…` (no file) routes between a UDP vehicle and a
/// WebSocket client.
#[test]
fn the_ws_server_endpoint_routes_without_a_file() {
    let (udp, port) = (free_udp_port(), free_tcp_port());
    let child = std::process::Command::new(common::router::BIN)
        .arg(format!("udp-server:127.0.0.1:{udp}"))
        .arg(format!("ws-server:127.0.0.1:{port}"))
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn mavtables");
    let _guard = common::router::Guard(Some(child));
    let mut ws = ws_client(port);
    let v = UdpSocket::bind("127.0.0.1:0").expect("bind");
    v.connect(format!("127.0.0.1:{udp}")).expect("connect");
    // The vehicle is known once its heartbeat reached the client.
    v.send(&heartbeat(1)).expect("send");
    assert_eq!(messages(&mut ws, 1, 5 * SECOND), [heartbeat(1)]);
    ws.send(Message::binary(attitude(255, 1))).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [attitude(255, 1)]);
}

/// A request that is not a WebSocket upgrade, and an endless request head (garbage with
/// no blank line), are closed at once (the head after 64 KiB), logged and counted; a
/// client beside them is still served.
#[test]
fn a_bad_handshake_is_closed_at_once() {
    let s = Scratch::new("ws-bad-handshake");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let to = format!("127.0.0.1:{port}");
    let mut ws = ws_join(&mut router, port, 255);
    let mut plain = connect(&to);
    plain
        .write_all(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .expect("write");
    let mut endless = connect(&to);
    endless
        .set_write_timeout(Some(2 * SECOND))
        .expect("timeout");
    let garbage = vec![b'x'; 8192];
    // Writes fail once the router has closed the connection (the kernel's buffers may
    // take a megabyte or so before that shows).
    for _ in 0..256 {
        if endless.write_all(&garbage).is_err() {
            break;
        }
    }
    for (name, stream) in [("plain", &mut plain), ("endless", &mut endless)] {
        stream.set_read_timeout(Some(2 * SECOND)).expect("timeout");
        let mut buf = [0u8; 256];
        // Whatever comes, the end follows within 2 s.
        let deadline = Instant::now() + 2 * SECOND;
        loop {
            assert!(Instant::now() < deadline, "{name}: still open");
            match stream.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(_) => {}
            }
        }
    }
    router
        .err
        .wait_for("WebSocket handshake failed", 5 * SECOND);
    v.send(&attitude(1, 1)).expect("send");
    assert_eq!(messages(&mut ws, 1, 5 * SECOND), [attitude(1, 1)]);
    let label = format!("websocket 127.0.0.1:{port}");
    counters_until(&mut router, "two I/O errors", |c| {
        c.interface(&label).is_some_and(|i| i.io_errors == 2)
    });
    router.stop();
}

/// A client that never reads while the vehicle sends a long stream of large frames: its
/// queue stays within its bound and the drops are counted, the router's memory hardly
/// grows, and another client gets every frame.
#[test]
fn a_client_that_never_reads_is_bounded_like_a_tcp_client() {
    const LINK_BYTES: u64 = 100_000;
    const COUNT: u32 = 30_000;
    let s = Scratch::new("ws-stuck");
    let (mut router, udp, port) =
        router(&s, "", &format!("queue {{ link_bytes {LINK_BYTES}; }}\n"));
    let pid = router.pid();
    let v = vehicle(&mut router, udp, 1);
    let stuck = small_window_client(&mut router, port, 30);
    let stuck_name = link_name(&stuck);
    let mut healthy = ws_join(&mut router, port, 20);
    let peak_before = status_bytes(pid, "VmHWM");
    let reader = std::thread::spawn(move || {
        let mut got = 0u32;
        let deadline = Instant::now() + 60 * SECOND;
        while got < COUNT && Instant::now() < deadline {
            got += messages(&mut healthy, (COUNT - got) as usize, SECOND)
                .iter()
                .filter(|m| m.len() == 267)
                .count() as u32;
        }
        got
    });
    // Paced so that neither the vehicle's socket nor the healthy client drops (1 ms
    // per 10 frames: 10,000 frames/s).
    for n in 0..COUNT {
        v.send(&numbered_large(1, n)).expect("send");
        if n % 10 == 9 {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    assert_eq!(
        reader.join().expect("reader"),
        COUNT,
        "the healthy client lost frames"
    );
    let c = counters(&mut router);
    let st = c.link(&stuck_name).expect("the stuck link");
    assert!(st.high_water <= LINK_BYTES, "{}", c.text);
    assert!(st.queue_drops > 0, "{}", c.text);
    let peak_after = status_bytes(pid, "VmHWM");
    assert!(
        peak_after <= peak_before + 4 * MIB,
        "VmHWM grew from {peak_before} to {peak_after}"
    );
    drop(stuck);
    router.stop();
}

/// A reload (SIGHUP) that changes the block's `max_peers` keeps the connection: it
/// routes both ways afterwards.
#[test]
fn a_reload_keeps_websocket_connections() {
    let s = Scratch::new("ws-reload");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let mut ws = ws_join(&mut router, port, 255);
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [heartbeat(255)]);
    let config = format!(
        "udp {{ port {udp}; address 127.0.0.1; }}\n\
         websocket {{ port {port}; address 127.0.0.1; max_peers 4; }}\n{ACCEPT_ALL}"
    );
    std::fs::write(&router.config, config).expect("write config");
    router.signal(libc::SIGHUP);
    let line = router.err.wait_for("configuration reloaded: ", 10 * SECOND);
    assert!(line.ends_with("1 changed"), "{line}");
    v.send(&attitude(1, 1)).expect("send");
    assert_eq!(messages(&mut ws, 1, 5 * SECOND), [attitude(1, 1)]);
    ws.send(Message::binary(attitude(255, 2))).expect("send");
    assert_eq!(udp_frames(&v, 1, 5 * SECOND), [attitude(255, 2)]);
    router.stop();
}

/// At shutdown a WebSocket client is told why its connection ends: a Close frame with
/// code 1001 (going away), not a bare close that a page sees as 1006.
#[test]
fn a_client_is_told_the_router_goes_away() {
    let s = Scratch::new("ws-going-away");
    let (mut router, _, port) = router(&s, "", "");
    let mut ws = ws_join(&mut router, port, 5);
    let told = std::thread::spawn(move || close_code(&mut ws, 5 * SECOND));
    router.stop();
    assert_eq!(told.join().expect("client"), Some(1001));
}

/// A client that streams frames which never end a message (empty continuation frames
/// add nothing to it, so no size limit is reached) cannot hold the router in one read:
/// the other links are served while it sends.
#[test]
fn a_message_that_never_ends_does_not_hold_the_router() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let s = Scratch::new("ws-endless");
    let (mut router, udp, port) = router(&s, "", "");
    let v = vehicle(&mut router, udp, 1);
    let ground = vehicle(&mut router, udp, 2);
    ground
        .set_read_timeout(Some(Duration::from_millis(5)))
        .expect("timeout");
    let ws = ws_client(port);
    let mut raw = ws.get_ref().try_clone().expect("clone");
    raw.set_write_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    // A binary frame that is not the last of its message, then continuation frames,
    // each empty and masked (with a zero key), for as long as the test runs.
    raw.write_all(&[0x02, 0x80, 0, 0, 0, 0])
        .expect("first frame");
    let stop = Arc::new(AtomicBool::new(false));
    let flood = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let chunk = [0x00u8, 0x80, 0, 0, 0, 0].repeat(10_000);
            let until = Instant::now() + 20 * SECOND;
            while !stop.load(Ordering::Relaxed) && Instant::now() < until {
                let _ = raw.write(&chunk);
            }
        })
    };
    // While it floods: the vehicle's frames, and how many reach the ground station
    // before the flood ends.
    let mut buf = [0u8; 512];
    let mut during = 0;
    let start = Instant::now();
    let mut sent = 0u8;
    while start.elapsed() < 3 * SECOND && during < 20 {
        v.send(&attitude(1, sent)).expect("send");
        sent = sent.wrapping_add(1);
        if ground.recv(&mut buf).is_ok() {
            during += 1;
        }
    }
    stop.store(true, Ordering::Relaxed);
    flood.join().expect("flood");
    assert!(
        during >= 20,
        "{during} of {sent} frames came through during the flood"
    );
    drop(ws);
    router.stop();
}
