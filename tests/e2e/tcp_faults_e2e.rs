//! Bad input and faults on TCP links, and nothing lost elsewhere: garbage before valid
//! frames, a peer that closes mid-frame, a peer that resets while the router writes to
//! it, a peer that stops reading, a server that goes away under a `tcp { connect }`
//! client, and a thousand short connections. The real `mavtables` binary and plain
//! sockets of our own on 127.0.0.1; every wait is bounded and ends on an event (a log
//! line, a received frame, a counters report, a count in `/proc`).

use crate::common;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use common::eventually;
use common::net::{
    ACCEPT_ALL, Counters, SECOND, attitude, chatty_late_reader, connect, connect_small, counters,
    fd_count, free_tcp_port, heartbeat, number_of, numbered, numbered_large, status_bytes,
    tcp_frames,
};
use common::router::{Router, Scratch, free_udp_port};
use mavtables::wire::Parser;

const MIB: u64 = 1024 * 1024;

/// A TCP server on a free port of 127.0.0.1 (plus `extra` config), started; and the
/// address to connect to.
fn tcp_server(s: &Scratch, extra: &str) -> (Router, String) {
    let port = free_tcp_port();
    let config = format!("tcp {{ port {port}; address 127.0.0.1; }}\n{extra}{ACCEPT_ALL}");
    (Router::start(s, &config, 1), format!("127.0.0.1:{port}"))
}

/// The router's name for the link of our connection `stream`.
fn link_name(stream: &TcpStream) -> String {
    format!("tcp:{}", stream.local_addr().expect("addr"))
}

/// Connects to `to` and says a heartbeat from `sys`; returns once the router has seen it.
fn join(router: &mut Router, to: &str, sys: u8) -> TcpStream {
    let mut stream = connect(to);
    stream.write_all(&heartbeat(sys)).expect("write");
    router.wait_for(&format!("new component {sys}.1 on tcp:127.0.0.1:"));
    stream
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

/// Deterministic noise (xorshift64*): the same bytes on every run.
fn noise(len: usize, mut seed: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(len + 8);
    while out.len() < len {
        seed ^= seed >> 12;
        seed ^= seed << 25;
        seed ^= seed >> 27;
        out.extend_from_slice(&seed.wrapping_mul(0x2545_f491_4f6c_dd1d).to_le_bytes());
    }
    out.truncate(len);
    out
}

/// Sends frames `make(sys, 0..count)` through `write` at `rate` frames per second, on a
/// steady schedule (each millisecond what is due by then). Returns when the first and
/// the last frame left.
fn send_steadily(
    mut write: impl FnMut(&[u8]),
    make: fn(u8, u32) -> Vec<u8>,
    sys: u8,
    count: u32,
    rate: u32,
) -> (Instant, Instant) {
    let start = Instant::now();
    let mut sent = 0u32;
    let mut batch = Vec::new();
    let mut first = None;
    while sent < count {
        let due = ((start.elapsed().as_secs_f64() * f64::from(rate)) as u32 + 1).min(count);
        if due > sent {
            batch.clear();
            for n in sent..due {
                batch.extend_from_slice(&make(sys, n));
            }
            write(&batch);
            first.get_or_insert_with(Instant::now);
            sent = due;
        }
        thread::sleep(Duration::from_millis(1));
    }
    (first.expect("sent"), Instant::now())
}

/// What a peer got: the numbered frames from one sender, each with when it arrived,
/// and the other frames (heartbeats aside).
#[derive(Default)]
struct Arrivals {
    numbered: Vec<(u32, Instant)>,
    others: Vec<Vec<u8>>,
}

/// What `read` gives until `want` numbered frames from `sys` arrived or `timeout` passed.
fn arrivals(
    mut read: impl FnMut(&mut [u8]) -> Option<usize>,
    sys: u8,
    want: usize,
    timeout: Duration,
) -> Arrivals {
    let deadline = Instant::now() + timeout;
    let mut parser = Parser::new();
    let mut got = Arrivals::default();
    let mut buf = vec![0u8; 65536];
    while got.numbered.len() < want && Instant::now() < deadline {
        if let Some(n) = read(&mut buf) {
            let now = Instant::now();
            parser.feed(&buf[..n], |f| {
                if f.message_id() == 0 {
                    return; // heartbeats
                }
                if f.source().system == sys {
                    got.numbered.push((number_of(f.as_bytes()), now));
                } else {
                    got.others.push(f.as_bytes().to_vec());
                }
            });
        }
    }
    got
}

/// A thread collecting what [`arrivals`] collects from TCP `stream`.
fn tcp_arrivals(
    mut stream: TcpStream,
    sys: u8,
    want: usize,
    timeout: Duration,
) -> JoinHandle<(Arrivals, TcpStream)> {
    stream
        .set_read_timeout(Some(Duration::from_millis(20)))
        .expect("timeout");
    thread::spawn(move || {
        let got = arrivals(
            |b| stream.read(b).ok().filter(|n| *n > 0),
            sys,
            want,
            timeout,
        );
        (got, stream)
    })
}

/// Asserts that `got` is `0..count` in order.
fn assert_all_in_order(got: &[(u32, Instant)], count: u32, who: &str) {
    let missing = count as usize - got.len().min(count as usize);
    let out_of_order = got
        .iter()
        .enumerate()
        .filter(|(i, (n, _))| *n as usize != *i)
        .count();
    assert!(
        got.len() == count as usize && out_of_order == 0,
        "{who}: {} of {count} frames, {missing} missing, {out_of_order} out of place",
        got.len()
    );
}

/// 1. A peer that sends a megabyte of garbage and then valid frames: the frames reach
///    another client, byte for byte and in order; the junk is counted on the sender's
///    connection; the router keeps routing both ways and exits cleanly.
#[test]
fn garbage_before_valid_frames_is_skipped_and_counted() {
    const JUNK: usize = 1_000_000;
    let s = Scratch::new("garbage");
    let (mut router, to) = tcp_server(&s, "");
    let mut b = join(&mut router, &to, 20);
    let mut a = connect(&to);
    let a_name = link_name(&a);
    a.write_all(&noise(JUNK, 0x9e37_79b9_7f4a_7c15))
        .expect("write junk");
    let frames: Vec<Vec<u8>> = (0..100).map(|n| numbered(10, n)).collect();
    a.write_all(&frames.concat()).expect("write frames");
    router.wait_for("new component 10.1 on tcp:127.0.0.1:");
    assert_eq!(tcp_frames(&mut b, 100, 10 * SECOND), frames);
    // Still routing, the other way too.
    b.write_all(&attitude(20, 7)).expect("write");
    assert_eq!(tcp_frames(&mut a, 1, 5 * SECOND), [attitude(20, 7)]);
    let c = counters(&mut router);
    let link = c.link(&a_name).expect("a's link");
    assert_eq!(link.frames_in, 100, "{}", c.text);
    let parsed = c.interface(&a_name).expect("a's interface");
    assert_eq!(parsed.frames, 100, "{}", c.text);
    assert_eq!(parsed.junk_bytes, JUNK as u64, "{}", c.text);
    let stopped = router.stop();
    assert!(stopped.took < 2 * SECOND, "took {:?}", stopped.took);
}

/// 2. A peer that sends half a frame and closes: its link is removed (gone from the
///    counters), the half frame is counted as junk by the server and reaches nobody;
///    the other client and a new one route as before.
#[test]
fn a_peer_closing_mid_frame_is_removed_and_nothing_else_changes() {
    let s = Scratch::new("mid-frame");
    let (mut router, to) = tcp_server(&s, "");
    let mut b = join(&mut router, &to, 20);
    let mut a = join(&mut router, &to, 10);
    let a_name = link_name(&a);
    assert_eq!(tcp_frames(&mut b, 1, 5 * SECOND), [heartbeat(10)]);
    assert!(counters(&mut router).link(&a_name).is_some());
    a.write_all(&attitude(10, 1)[..20]).expect("write");
    drop(a);
    let c = counters_until(&mut router, "a's link removed", |c| {
        c.link(&a_name).is_none()
    });
    assert!(c.interface(&a_name).is_none(), "{}", c.text);
    let server = c
        .interface(&format!("tcp {to}"))
        .expect("the server's line");
    assert_eq!((server.frames, server.junk_bytes), (1, 20), "{}", c.text);
    // B and a new client C route as before; B got nothing of the half frame.
    let mut cc = join(&mut router, &to, 30);
    b.write_all(&attitude(20, 9)).expect("write");
    assert_eq!(tcp_frames(&mut cc, 1, 5 * SECOND), [attitude(20, 9)]);
    assert_eq!(tcp_frames(&mut b, 1, 5 * SECOND), [heartbeat(30)]);
    let err = router.stop().stderr;
    let end = Counters::at_exit(&err);
    let names: Vec<&str> = end.links.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, [link_name(&b), link_name(&cc)], "{}", end.text);
}

/// 3. A peer that resets its connection (SO_LINGER 0, then close: RST) while the router
///    is writing a stream to it: its link is removed and another client gets every frame
///    of the stream, in order.
#[test]
fn a_peer_resetting_while_written_to_does_not_disturb_the_others() {
    const COUNT: u32 = 5_000;
    let s = Scratch::new("reset");
    let (mut router, to) = tcp_server(&s, "");
    let healthy = join(&mut router, &to, 20);
    let mut victim = join(&mut router, &to, 30);
    let victim_name = link_name(&victim);
    let mut sender = join(&mut router, &to, 10);
    let healthy_name = link_name(&healthy);
    let at_healthy = tcp_arrivals(healthy, 10, COUNT as usize, 30 * SECOND);
    let send = thread::spawn(move || {
        send_steadily(
            |b| sender.write_all(b).expect("send"),
            numbered,
            10,
            COUNT,
            5_000,
        );
        sender
    });
    // The victim reads a part of the stream, then resets.
    victim
        .set_read_timeout(Some(Duration::from_millis(20)))
        .expect("timeout");
    let read = arrivals(
        |b| victim.read(b).ok().filter(|n| *n > 0),
        10,
        500,
        10 * SECOND,
    );
    assert!(
        read.numbered.len() >= 500,
        "the victim got part of the stream"
    );
    // Its last words go out just before the reset.
    victim.write_all(&attitude(30, 99)).expect("write");
    socket2::SockRef::from(&victim)
        .set_linger(Some(Duration::ZERO))
        .expect("linger 0");
    drop(victim);
    let c = counters_until(&mut router, "the victim's link removed", |c| {
        c.link(&victim_name).is_none()
    });
    let _sender = send.join().expect("sender");
    let (got, _healthy) = at_healthy.join().expect("healthy reader");
    assert_all_in_order(&got.numbered, COUNT, "the healthy client");
    assert_eq!(got.others, [attitude(30, 99)], "the victim's last words");
    let c2 = counters(&mut router);
    let h = c2.link(&healthy_name).expect("healthy link");
    assert_eq!((h.queue_drops, h.send_errors), (0, 0), "{}", c2.text);
    assert!(c.link(&healthy_name).is_some());
    router.stop();
}

/// 4. A peer that stops reading while another sends a steady stream that goes to it and
///    to a healthy peer: the healthy peer gets every frame at the rate sent; the stuck
///    peer's queue stays within its bound (`link_bytes`) and the drops are counted; the
///    router's peak memory hardly grows.
///
///    The frames are large (267 bytes) and the stream longer than the kernel's largest
///    send buffer twice over: on loopback the router's socket alone takes megabytes for
///    a peer that reads nothing, and only then does the router's own queue fill.
#[test]
fn a_peer_that_stops_reading_costs_the_others_nothing() {
    const RATE: u32 = 10_000;
    const LINK_BYTES: u64 = 100_000;
    const FRAME: u64 = 267;
    let wmem_max: u64 = std::fs::read_to_string("/proc/sys/net/ipv4/tcp_wmem")
        .ok()
        .and_then(|t| t.split_whitespace().nth(2).and_then(|n| n.parse().ok()))
        .unwrap_or(4 * MIB);
    let count = u32::try_from((2 * wmem_max + MIB) / FRAME)
        .expect("count")
        .max(20_000);
    let s = Scratch::new("stuck");
    let (mut router, to) = tcp_server(&s, &format!("queue {{ link_bytes {LINK_BYTES}; }}\n"));
    let pid = router.pid();
    let healthy = join(&mut router, &to, 20);
    let healthy_name = link_name(&healthy);
    // The stuck peer's receive buffer is small, so the router's writes soon block.
    let stuck = {
        let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None)
            .expect("socket");
        socket.set_recv_buffer_size(4096).expect("rcvbuf");
        let addr: SocketAddr = to.parse().expect("addr");
        socket.connect(&addr.into()).expect("connect");
        let mut stream: TcpStream = socket.into();
        stream.write_all(&heartbeat(30)).expect("write");
        router.wait_for("new component 30.1 on tcp:127.0.0.1:");
        stream
    };
    let stuck_name = link_name(&stuck);
    let mut sender = join(&mut router, &to, 10);
    let peak_before = status_bytes(pid, "VmHWM");
    let at_healthy = tcp_arrivals(healthy, 10, count as usize, 60 * SECOND);
    let (first_sent, last_sent) = send_steadily(
        |b| sender.write_all(b).expect("send"),
        numbered_large,
        10,
        count,
        RATE,
    );
    let (got, _healthy) = at_healthy.join().expect("healthy reader");
    let got = got.numbered;
    assert_all_in_order(&got, count, "the healthy peer");
    let sent_for = last_sent - first_sent;
    let received_for = got[got.len() - 1].1 - got[0].1;
    let ratio = received_for.as_secs_f64() / sent_for.as_secs_f64();
    eprintln!(
        "{count} frames sent over {sent_for:?}, received over {received_for:?} (ratio {ratio:.4})"
    );
    assert!(
        (0.97..=1.03).contains(&ratio),
        "sent over {sent_for:?}, received over {received_for:?}"
    );
    let c = counters(&mut router);
    eprintln!("{}", c.text);
    let st = c.link(&stuck_name).expect("the stuck link");
    assert!(st.high_water <= LINK_BYTES, "{}", c.text);
    assert!(st.queue_drops > 0, "{}", c.text);
    // Every frame for the stuck peer (the sender's heartbeat and stream) was written,
    // dropped, or still waits: in its queue, or one partly written.
    let queued_at_most = LINK_BYTES / (FRAME + 32) + 1;
    let for_stuck = u64::from(count) + 1;
    assert!(
        st.frames_out + st.queue_drops <= for_stuck
            && st.frames_out + st.queue_drops + queued_at_most >= for_stuck,
        "{}",
        c.text
    );
    let h = c.link(&healthy_name).expect("the healthy link");
    assert_eq!(
        (h.frames_out, h.queue_drops, h.send_errors),
        (u64::from(count) + 2, 0, 0),
        "{}",
        c.text
    );
    let peak_after = status_bytes(pid, "VmHWM");
    eprintln!("VmHWM {peak_before} -> {peak_after}");
    assert!(
        peak_after <= peak_before + 4 * MIB,
        "VmHWM grew from {peak_before} to {peak_after}"
    );
    drop(stuck);
    router.stop();
}

/// 5. The server of a `tcp { connect }` client goes away for 3 s and comes back: the
///    client is connected again within 2 s of its return, and a pair of UDP peers
///    exchanging 200 frames/s each way through the router all along never see a pause
///    longer than 100 ms nor lose a frame.
#[test]
fn a_tcp_server_restarting_under_a_client_does_not_pause_udp_traffic() {
    const RATE: u32 = 200;
    const RUN: Duration = Duration::from_secs(9);
    let s = Scratch::new("restart");
    let server = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = server.local_addr().expect("addr").port();
    let udp_port = free_udp_port();
    let config = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}\ntcp {{ connect 127.0.0.1:{port}; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let (mut conn, _) = server.accept().expect("the router connects");
    let to = format!("127.0.0.1:{udp_port}");
    let peers: Vec<UdpSocket> = [1u8, 2]
        .iter()
        .map(|sys| {
            let p = UdpSocket::bind("127.0.0.1:0").expect("bind");
            p.connect(&to).expect("connect");
            p.send(&heartbeat(*sys)).expect("send");
            router.wait_for(&format!("new component {sys}.1 on 127.0.0.1:"));
            p
        })
        .collect();
    let count = RATE * RUN.as_secs() as u32;
    // Each peer sends `count` numbered frames to the other and collects what it gets.
    let mut threads = Vec::new();
    for (i, p) in peers.into_iter().enumerate() {
        let (me, other) = ([1u8, 2][i], [2u8, 1][i]);
        let rx = p.try_clone().expect("clone");
        rx.set_read_timeout(Some(Duration::from_millis(20)))
            .expect("timeout");
        threads.push(thread::spawn(move || {
            arrivals(
                |b| rx.recv(b).ok(),
                other,
                count as usize,
                RUN + 10 * SECOND,
            )
            .numbered
        }));
        thread::spawn(move || send_steadily(|b| send_frames(&p, b), numbered, me, count, RATE));
    }
    // The server keeps reading what the router sends, until told to stop.
    // The server's connection gets both peers' frames (400/s); half a second's worth
    // first, then it goes away.
    let before = tcp_frames(&mut conn, 200, 10 * SECOND).len();
    assert_eq!(before, 200, "the server got traffic before it went away");
    drop(conn);
    drop(server);
    router.err.wait_for("lost", 5 * SECOND);
    let gone = Instant::now();
    while gone.elapsed() < 3 * SECOND {
        thread::sleep(Duration::from_millis(50)); // the outage: its length is the test
    }
    let server = TcpListener::bind(format!("127.0.0.1:{port}")).expect("rebind");
    server.set_nonblocking(true).expect("nonblocking");
    let back = Instant::now();
    let mut conn = loop {
        match server.accept() {
            Ok((c, _)) => break c,
            Err(_) => {
                assert!(
                    back.elapsed() < 2 * SECOND + SECOND / 4,
                    "no reconnect within 2 s"
                );
                thread::sleep(Duration::from_millis(5));
            }
        }
    };
    let reconnected_after = back.elapsed();
    conn.set_nonblocking(false).expect("blocking");
    // Traffic reaches the server again (what waited over 2 s was dropped, not replayed).
    let after = tcp_frames(&mut conn, 100, 10 * SECOND);
    assert_eq!(
        after.len(),
        100,
        "the server got traffic after it came back"
    );
    for (i, t) in threads.into_iter().enumerate() {
        let got = t.join().expect("receiver");
        assert_all_in_order(&got, count, &format!("UDP peer {}", i + 1));
        let gap = got
            .windows(2)
            .map(|w| w[1].1 - w[0].1)
            .max()
            .expect("frames");
        eprintln!("peer {}: longest gap {gap:?}", i + 1);
        assert!(gap <= Duration::from_millis(100), "a pause of {gap:?}");
    }
    eprintln!("reconnected after {reconnected_after:?}");
    router.stop();
}

/// Sends the frames of `batch` (whole frames, back to back) one datagram each.
fn send_frames(sock: &UdpSocket, batch: &[u8]) {
    let mut parser = Parser::new();
    parser.feed(batch, |f| {
        sock.send(f.as_bytes()).expect("send");
    });
}

/// 6. A thousand connections that each send a heartbeat and close: afterwards the
///    router holds as many descriptors as before and its memory is within 1 MiB.
#[test]
fn a_thousand_short_connections_leave_nothing_behind() {
    const CYCLES: usize = 1_000;
    const WARM_UP: usize = 200;
    let s = Scratch::new("cycles");
    let (mut router, to) = tcp_server(&s, "");
    let pid = router.pid();
    let cycle = |i: usize| {
        let mut c = connect(&to);
        c.write_all(&heartbeat((i % 200 + 1) as u8)).expect("write");
    };
    // Warm up the same way (the allocator's pools and the tables grow to what this many
    // connections at once take); once the router has removed every link it holds the
    // descriptors it always holds.
    for i in 0..WARM_UP {
        cycle(i);
    }
    counters_until(&mut router, "the warm-up links removed", |c| {
        c.links.is_empty()
    });
    let baseline_fds = fd_count(pid);
    let rss_before = status_bytes(pid, "VmRSS");
    let start = Instant::now();
    for i in 0..CYCLES {
        cycle(i);
    }
    eventually("every connection closed", 20 * SECOND, || {
        fd_count(pid) == baseline_fds
    });
    let took = start.elapsed();
    let rss_after = status_bytes(pid, "VmRSS");
    eprintln!("{CYCLES} cycles in {took:?}; VmRSS {rss_before} -> {rss_after}");
    assert!(
        rss_after <= rss_before + MIB,
        "VmRSS grew from {rss_before} to {rss_after}"
    );
    assert!(took < 30 * SECOND, "took {took:?}");
    // Still serving: two new clients route to each other.
    let mut a = join(&mut router, &to, 250);
    let mut b = join(&mut router, &to, 251);
    a.write_all(&attitude(250, 1)).expect("write");
    assert_eq!(
        tcp_frames(&mut b, 1, 5 * SECOND),
        [attitude(250, 1)],
        "b gets a's frame"
    );
    let c = counters(&mut router);
    assert_eq!(c.links.len(), 2, "{}", c.text);
    let server = c.interface(&format!("tcp {to}")).expect("server line");
    assert_eq!(server.frames, (CYCLES + WARM_UP) as u64, "{}", c.text);
    router.stop();
}

/// 8. TCP loses nothing, so a frame whose pieces arrive 0.05, 0.5 and 3 s apart (a
///    retransmission, a cellular stall) is the start of the next frame until its last
///    byte comes: it reaches the other side once and intact — from a connection the
///    router accepted, and from the server its `tcp { connect }` client reached — and
///    not one byte of it is counted as junk.
#[test]
fn a_frame_in_pieces_with_long_pauses_arrives_whole_over_tcp() {
    let s = Scratch::new("tcp-pauses");
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let upstream = listener.local_addr().expect("addr").to_string();
    let client_config = format!("tcp {{ connect {upstream}; }}\n");
    let (mut router, to) = tcp_server(&s, &client_config);
    let (mut far, _) = listener.accept().expect("the router's client connects");
    far.write_all(&heartbeat(30)).expect("write");
    router.wait_for(&format!("new component 30.1 on tcp:{upstream}"));
    let mut b = join(&mut router, &to, 20);
    let a = join(&mut router, &to, 10);
    let a_name = link_name(&a);
    let pieces = |mut w: TcpStream, frame: Vec<u8>| {
        thread::spawn(move || {
            let cuts = [0, 3, 11, 25, frame.len()];
            let pauses = [0.05, 0.5, 3.0];
            for (i, piece) in cuts.windows(2).enumerate() {
                w.write_all(&frame[piece[0]..piece[1]]).expect("write");
                if let Some(p) = pauses.get(i) {
                    thread::sleep(Duration::from_secs_f64(*p));
                }
            }
            w
        })
    };
    let from_a = pieces(a, attitude(10, 1));
    let from_far = pieces(far, attitude(30, 2));
    // A's heartbeat, then the two frames.
    let mut got = tcp_frames(&mut b, 3, 15 * SECOND);
    got.retain(|f| f[7] != 0); // the heartbeat aside
    got.sort();
    let mut want = vec![attitude(10, 1), attitude(30, 2)];
    want.sort();
    assert_eq!(got, want, "each frame once, intact");
    // Nothing was left behind or doubled: the next frame is the next thing B gets.
    let mut a = from_a.join().expect("writer");
    let _far = from_far.join().expect("writer");
    a.write_all(&attitude(10, 3)).expect("write");
    assert_eq!(tcp_frames(&mut b, 1, 5 * SECOND), [attitude(10, 3)]);
    let c = counters(&mut router);
    let line = c.interface(&a_name).expect("a's interface");
    assert_eq!((line.frames, line.junk_bytes), (3, 0), "{}", c.text);
    router.stop();
}

/// At shutdown a ground station that keeps sending (a heartbeat every 5 ms) and reads
/// late (300 ms after the stop, through a small receive buffer) still gets every frame
/// the router says it sent it. Closing under the peer's next bytes would make the kernel
/// reset the connection and discard what the peer had not acknowledged; the router
/// shuts its sending side and closes once the peer has acknowledged it all (within a
/// second).
#[test]
fn a_peer_that_keeps_sending_gets_everything_at_shutdown() {
    let s = Scratch::new("tcp-linger");
    let udp = free_udp_port();
    let (mut router, to) = tcp_server(&s, &format!("udp {{ port {udp}; address 127.0.0.1; }}\n"));
    let mut gcs = connect_small(&to);
    gcs.write_all(&heartbeat(255)).expect("write");
    router.wait_for("new component 255.1 on tcp:127.0.0.1:");
    let name = link_name(&gcs);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    vehicle.connect(("127.0.0.1", udp)).expect("connect");
    vehicle.send(&heartbeat(1)).expect("send");
    router.wait_for("new component 1.1 on 127.0.0.1:");
    for n in 0..2000 {
        vehicle.send(&numbered(1, n)).expect("send");
    }
    // Sent, but not read by the ground station yet.
    counters_until(&mut router, "2,000 frames for the ground station", |c| {
        c.link(&name).is_some_and(|l| l.frames_out >= 2000)
    });
    let reader = chatty_late_reader(gcs, 255, Duration::from_millis(300));
    let stopped = router.stop();
    let frames = reader.join().expect("reader").len() as u64;
    let sent = Counters::at_exit(&stopped.stderr)
        .link(&name)
        .map(|l| l.frames_out)
        .expect("the ground station's link at exit");
    assert!(sent >= 2000, "{sent}");
    assert_eq!(
        frames, sent,
        "frames the ground station received of those sent"
    );
}

/// `n` connection attempts to `addr`, started without waiting for them (those the
/// server's full backlog drops stay under way).
fn connections_not_waited_for(addr: SocketAddr, n: usize) -> Vec<socket2::Socket> {
    (0..n)
        .filter_map(|_| {
            let c =
                socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).ok()?;
            c.set_nonblocking(true).ok()?;
            let _ = c.connect(&addr.into());
            Some(c)
        })
        .collect()
}

/// Lowers the open-file limit of process `pid` to `n` (util-linux's `prlimit`).
fn limit_descriptors(pid: u32, n: usize) {
    let status = std::process::Command::new("prlimit")
        .arg("--pid")
        .arg(pid.to_string())
        .arg(format!("--nofile={n}:{n}"))
        .status()
        .unwrap_or_else(|e| panic!("prlimit (util-linux; apt install util-linux): {e}"));
    assert!(
        status.success(),
        "prlimit --pid {pid} --nofile={n}:{n}: {status}"
    );
}

#[test]
fn a_tcp_server_out_of_descriptors_accepts_again_once_it_has_some() {
    let s = Scratch::new("tcp-emfile");
    let udp_port = free_udp_port();
    let (mut router, to) = tcp_server(
        &s,
        &format!("udp {{ port {udp_port}; address 127.0.0.1; }}\n"),
    );
    common::mavproxy::wait_tcp_listening(
        to.rsplit(':')
            .next()
            .and_then(|p| p.parse().ok())
            .expect("port"),
        10 * SECOND,
    );
    let ground = UdpSocket::bind("127.0.0.1:0").expect("bind");
    ground
        .send_to(&heartbeat(9), ("127.0.0.1", udp_port))
        .expect("send");
    router.wait_for("new component 9.1 on 127.0.0.1:");
    let pid = router.pid();
    limit_descriptors(pid, 40);
    // Far more connections than the router has descriptors for, and than its listener's
    // backlog holds: the ones it cannot take wait in the backlog until it is full.
    let addr: SocketAddr = to.parse().expect("address");
    let waiting = connections_not_waited_for(addr, 300);
    router.err.wait_for("receive failed", 10 * SECOND);
    // They all go; the router gets its descriptors back as it finds them closed.
    drop(waiting);
    // A new client is taken and heard (its SYN found no room while the backlog was full
    // of closed connections nobody accepted, before the listener tried again).
    let mut client = eventually("a new connection accepted", 30 * SECOND, || {
        let mut c = TcpStream::connect_timeout(&addr, 2 * SECOND).map_err(|e| e.to_string())?;
        c.write_all(&heartbeat(7)).map_err(|e| e.to_string())?;
        let _ = ground.set_read_timeout(Some(2 * SECOND));
        let mut buf = [0u8; 300];
        loop {
            let n = ground
                .recv(&mut buf)
                .map_err(|e| format!("the ground station heard nothing of 7: {e}"))?;
            let mut from_7 = false;
            Parser::new().feed(&buf[..n], |f| from_7 |= f.source().system == 7);
            if from_7 {
                return Ok::<_, String>(c);
            }
        }
    });
    router.wait_for("new component 7.1 on tcp:127.0.0.1:");
    client.write_all(&heartbeat(7)).expect("write");
    assert!(fd_count(pid) <= 40, "within its limit");
}

#[test]
fn a_client_whose_server_closes_at_once_tries_again_with_a_growing_wait() {
    let s = Scratch::new("tcp-flap");
    // A server that accepts and closes at once (full, or refusing this client).
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = listener.local_addr().expect("addr").port();
    let config = format!("tcp {{ connect 127.0.0.1:{port}; }}\n{ACCEPT_ALL}");
    let mut router = Router::start(&s, &config, 1);
    drop(listener.accept().expect("first connection"));
    let start = Instant::now();
    listener.set_nonblocking(true).expect("nonblocking");
    let mut accepted = 1;
    while start.elapsed() < 3 * SECOND {
        match listener.accept() {
            Ok((stream, _)) => {
                accepted += 1;
                drop(stream);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                thread::sleep(Duration::from_millis(1));
            }
            Err(e) => panic!("accept: {e}"),
        }
    }
    // Tried again after 0.1, 0.2, 0.4, 0.8, 1 and 1 s: about 6 connections in 3 s.
    assert!(
        (3..=12).contains(&accepted),
        "{accepted} connections in 3 s"
    );
    router
        .err
        .wait_for("lost again right after it opened", 5 * SECOND);
}

#[test]
fn a_client_gives_up_an_attempt_nobody_answers_and_connects_once_the_server_answers() {
    let s = Scratch::new("tcp-silent-server");
    // A server whose backlog is full: the system drops further attempts unanswered, as
    // a network that went down does.
    let server =
        socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    server
        .bind(&SocketAddr::from(([127, 0, 0, 1], 0)).into())
        .expect("bind");
    server.listen(0).expect("listen");
    let addr = server
        .local_addr()
        .ok()
        .and_then(|a| a.as_socket())
        .expect("addr");
    let filling = connections_not_waited_for(addr, 8);
    let config = format!("tcp {{ connect {addr}; }}\n{ACCEPT_ALL}");
    let mut router = Router::start(&s, &config, 1);
    let said = router.err.wait_for("no answer within 5 s", 10 * SECOND);
    assert!(said.contains(&format!("tcp connect {addr}")), "{said}");
    // The server answers again: the next attempt connects.
    drop(filling);
    let listener: TcpListener = server.into();
    listener.set_nonblocking(true).expect("nonblocking");
    // Ours were closed (they read as ended); the router's is open.
    let mut stream = eventually("the router connected", 15 * SECOND, || {
        let (c, _) = listener.accept().ok()?;
        c.set_nonblocking(true).ok()?;
        match (&c).read(&mut [0u8; 1]) {
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Some(c),
            _ => None,
        }
    });
    stream.set_nonblocking(false).expect("blocking");
    stream.write_all(&heartbeat(5)).expect("write");
    router.wait_for(&format!("new component 5.1 on tcp:{addr}"));
}
