//! Live reload (SIGHUP) and the systemd notification protocol, end to end: the real
//! `mavtables` binary, plain UDP and TCP sockets of our own on 127.0.0.1, and a unix
//! datagram socket playing systemd. Every wait is bounded and ends on an event (a line
//! on the router's standard error or output, a received frame, a notification), never
//! on a sleep.

use crate::common;

use std::io::{Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr as UnixAddr, UnixDatagram};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use common::eventually;
use common::net::{
    SECOND, attitude, chatty_late_reader, connect, connect_small, counters, free_tcp_port,
    heartbeat, number_of, numbered, udp_frames,
};
use common::router::{BIN, Guard, Lines, Router, Scratch, free_udp_port, udp_port_bound};
use mavtables::wire::Parser;

const RELOADED: &str = "configuration reloaded: ";

/// A UDP socket of our own on 127.0.0.1 that says a heartbeat from `sys` to the router
/// at `port` and waits until the router has learned it.
fn udp_peer(router: &mut Router, port: u16, sys: u8) -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    s.connect(("127.0.0.1", port)).expect("connect");
    s.send(&heartbeat(sys)).expect("send");
    router.wait_for(&format!("new component {sys}.1 on 127.0.0.1:"));
    s
}

/// Rewrites the router's configuration file, sends SIGHUP and waits for the reload's
/// summary line on standard error (returned).
fn reload(router: &mut Router, config: &str) -> String {
    std::fs::write(&router.config, config).expect("write config");
    router.signal(libc::SIGHUP);
    router.err.wait_for(RELOADED, 10 * SECOND)
}

/// Numbered frames from system `sys` read from `read` (heartbeats and others skipped)
/// until `stop` is set and nothing more arrived for a moment, or `timeout` passed.
fn numbers_until(
    mut read: impl FnMut(&mut [u8]) -> Option<usize>,
    sys: u8,
    want: &AtomicBool,
    count: &std::sync::atomic::AtomicU32,
    timeout: Duration,
) -> Vec<u32> {
    let deadline = Instant::now() + timeout;
    let mut parser = Parser::new();
    let mut got = Vec::new();
    let mut buf = vec![0u8; 65536];
    while Instant::now() < deadline {
        let done = want.load(Ordering::Acquire);
        if done && got.len() >= count.load(Ordering::Acquire) as usize {
            break;
        }
        if let Some(n) = read(&mut buf) {
            parser.feed(&buf[..n], |f| {
                if f.message_id() == 30 && f.source().system == sys {
                    got.push(number_of(f.as_bytes()));
                }
            });
        }
    }
    got
}

/// The first frame `sock` receives that is `want` (others, such as the heartbeats of
/// peers that joined, are skipped); panics if it does not come within 5 s.
fn expect_frame(sock: &UdpSocket, want: &[u8]) {
    let deadline = Instant::now() + 5 * SECOND;
    let mut others = Vec::new();
    while Instant::now() < deadline {
        for frame in udp_frames(sock, 1, Duration::from_millis(200)) {
            if frame == want {
                return;
            }
            others.push(frame);
        }
    }
    panic!("{want:02x?} never came; got {others:02x?}");
}

/// Numbered frames from `sys` received on `sock` until `want` came or `timeout` passed.
fn numbered_from(sock: &UdpSocket, sys: u8, want: usize, timeout: Duration) -> Vec<u32> {
    let deadline = Instant::now() + timeout;
    let mut got = Vec::new();
    while got.len() < want && Instant::now() < deadline {
        for frame in udp_frames(sock, 1, Duration::from_millis(200)) {
            let f = mavtables::wire::Frame::parse_exact(&frame).expect("a frame");
            if f.message_id() == 30 && f.source().system == sys {
                got.push(number_of(&frame));
            }
        }
    }
    got
}

const TWO_RULES: &str = "chain default {\n    reject if PING from 9.9;\n    accept;\n}\n";
const OTHER_RULES: &str = "chain default {\n    reject if PING from 9.8;\n    accept;\n}\n";

/// SIGHUP used to end the router (the default action); now it reloads, and SIGTERM
/// still shuts down cleanly.
#[test]
fn sighup_reloads_and_no_longer_kills() {
    let s = Scratch::new("reload-hup");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address 127.0.0.1; }}\n{TWO_RULES}");
    let mut router = Router::start(&s, &config, 1);
    router.signal(libc::SIGHUP);
    let line = router.err.wait_for(RELOADED, 10 * SECOND);
    assert!(
        line.ends_with("2 rules (0 changed), +0 interfaces, -0, 0 changed"),
        "{line}"
    );
    // Still routing after a second SIGHUP.
    router.signal(libc::SIGHUP);
    router.err.wait_for(RELOADED, 10 * SECOND);
    let a = udp_peer(&mut router, port, 1);
    let b = udp_peer(&mut router, port, 2);
    a.send(&attitude(1, 7)).expect("send");
    assert_eq!(udp_frames(&b, 1, 5 * SECOND), [attitude(1, 7)]);
    let stopped = router.stop();
    assert_eq!(stopped.status.code(), Some(0));
}

/// 50 reloads while about 1,000 frames a second flow from one UDP peer to another and
/// to a TCP connection: not one frame is lost or reordered, the connection never
/// closes, and no address is learned twice (none was forgotten).
#[test]
fn fifty_reloads_under_load_lose_nothing() {
    let s = Scratch::new("reload-load");
    let (udp_port, tcp_port) = (free_udp_port(), free_tcp_port());
    let interfaces = format!(
        "udp {{ port {udp_port}; address 127.0.0.1; }}\ntcp {{ port {tcp_port}; address 127.0.0.1; }}\n"
    );
    let mut router = Router::start(&s, &format!("{interfaces}{TWO_RULES}"), 1);
    let sender = udp_peer(&mut router, udp_port, 1);
    let receiver = udp_peer(&mut router, udp_port, 2);
    let mut tcp = connect(&format!("127.0.0.1:{tcp_port}"));
    tcp.write_all(&heartbeat(3)).expect("write");
    router.wait_for("new component 3.1 on tcp:127.0.0.1:");

    let done = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(std::sync::atomic::AtomicU32::new(0));
    let sending = {
        let (done, sent) = (done.clone(), sent.clone());
        thread::spawn(move || {
            // A steady 1,000 frames a second until told to stop.
            let start = Instant::now();
            let mut n = 0u32;
            while !done.load(Ordering::Acquire) || n == 0 {
                let due = (start.elapsed().as_secs_f64() * 1000.0) as u32 + 1;
                let mut batch = Vec::new();
                while n < due {
                    batch.push(numbered(1, n));
                    n += 1;
                }
                for frame in batch {
                    sender.send(&frame).expect("send");
                }
                sent.store(n, Ordering::Release);
                thread::sleep(Duration::from_millis(1));
            }
            n
        })
    };
    let stopped_sending = Arc::new(AtomicBool::new(false));
    let udp_reader = {
        let (stop, sent) = (stopped_sending.clone(), sent.clone());
        thread::spawn(move || {
            receiver
                .set_read_timeout(Some(Duration::from_millis(50)))
                .expect("timeout");
            numbers_until(|b| receiver.recv(b).ok(), 1, &stop, &sent, 60 * SECOND)
        })
    };
    let tcp_reader = {
        let (stop, sent) = (stopped_sending.clone(), sent.clone());
        let mut stream = tcp.try_clone().expect("clone");
        thread::spawn(move || {
            stream
                .set_read_timeout(Some(Duration::from_millis(50)))
                .expect("timeout");
            let closed = Arc::new(AtomicBool::new(false));
            let c = closed.clone();
            let got = numbers_until(
                |b| match stream.read(b) {
                    Ok(0) => {
                        c.store(true, Ordering::Release);
                        None
                    }
                    Ok(n) => Some(n),
                    Err(_) => None,
                },
                1,
                &stop,
                &sent,
                60 * SECOND,
            );
            (got, closed.load(Ordering::Acquire))
        })
    };
    for i in 0..50u32 {
        // Spread over about a second of traffic: a reload every 20 frames.
        eventually("the sender to go on", 10 * SECOND, || {
            sent.load(Ordering::Acquire) >= (i + 1) * 20
        });
        let rules = if i % 2 == 0 { OTHER_RULES } else { TWO_RULES };
        let line = reload(&mut router, &format!("{interfaces}{rules}"));
        assert!(
            line.ends_with("2 rules (1 changed, 1 removed), +0 interfaces, -0, 0 changed"),
            "{line}"
        );
    }
    done.store(true, Ordering::Release);
    let total = sending.join().expect("sender");
    stopped_sending.store(true, Ordering::Release);
    let want: Vec<u32> = (0..total).collect();
    let udp_got = udp_reader.join().expect("udp reader");
    let (tcp_got, closed) = tcp_reader.join().expect("tcp reader");
    assert!(
        total >= 200,
        "only {total} frames were sent during the reloads"
    );
    assert_eq!(udp_got.len(), want.len(), "UDP receiver: frames lost");
    assert_eq!(udp_got, want, "UDP receiver: frames out of order");
    assert_eq!(tcp_got.len(), want.len(), "TCP connection: frames lost");
    assert_eq!(tcp_got, want, "TCP connection: frames out of order");
    assert!(!closed, "the TCP connection was closed");
    // Still open both ways: a frame from the connection reaches the UDP peer... and the
    // addresses were never learned again.
    let stopped = router.stop();
    for sys in 1..=3 {
        let learned = stopped
            .stdout
            .iter()
            .filter(|l| l.contains(&format!("new component {sys}.1 ")))
            .count();
        assert_eq!(learned, 1, "system {sys} learned {learned} times");
    }
    assert!(
        !stopped.stderr.iter().any(|l| l.starts_with("reload: ")),
        "an interface changed: {:?}",
        stopped.stderr
    );
}

/// A rule added by a reload judges the very next packet, and removing it lets the same
/// message through again.
#[test]
fn a_rule_added_by_reload_applies_to_the_next_packet() {
    let s = Scratch::new("reload-rule");
    let port = free_udp_port();
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\n");
    let accept = "chain default {\n    accept;\n}\n";
    let reject = "chain default {\n    reject if ATTITUDE;\n    accept;\n}\n";
    let mut router = Router::start(&s, &format!("{udp}{accept}"), 1);
    let a = udp_peer(&mut router, port, 1);
    let b = udp_peer(&mut router, port, 2);
    a.send(&attitude(1, 1)).expect("send");
    assert_eq!(udp_frames(&b, 1, 5 * SECOND), [attitude(1, 1)]);

    let line = reload(&mut router, &format!("{udp}{reject}"));
    assert!(line.contains("2 rules (1 changed)"), "{line}");
    // The ATTITUDE is rejected; the HEARTBEAT behind it is the first frame to arrive.
    a.send(&attitude(1, 2)).expect("send");
    a.send(&heartbeat(1)).expect("send");
    assert_eq!(udp_frames(&b, 1, 5 * SECOND), [heartbeat(1)]);

    let line = reload(&mut router, &format!("{udp}{accept}"));
    assert!(line.contains("1 rule (0 changed, 1 removed)"), "{line}");
    a.send(&attitude(1, 3)).expect("send");
    assert_eq!(udp_frames(&b, 1, 5 * SECOND), [attitude(1, 3)]);
    router.stop();
}

/// A file that does not load (a syntax error, an unreadable key, a `record` path whose
/// fixed name is a file mavtables did not write: a reload is checked like a start)
/// changes nothing: the error is located in the log, traffic and rules go on as before,
/// and the file named is left as it was.
#[test]
fn a_broken_file_changes_nothing() {
    let s = Scratch::new("reload-broken");
    let port = free_udp_port();
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\n");
    let reject = "chain default {\n    reject if ATTITUDE;\n    accept;\n}\n";
    let mut router = Router::start(&s, &format!("{udp}{reject}"), 1);
    let a = udp_peer(&mut router, port, 1);
    let b = udp_peer(&mut router, port, 2);

    let precious = s.path("precious.conf");
    std::fs::write(&precious, "keep me\n").expect("write");
    let broken = [
        (
            "udp { port 99999; }\nchain default { accept; }\n".to_string(),
            "mavtables.conf:1:",
        ),
        (
            format!(
                "udp {{ port {port}; address 127.0.0.1; signing_key {}; }}\nchain default {{ accept; }}\n",
                s.path("no-such.key")
            ),
            "mavtables.conf:1:",
        ),
        (
            format!("{udp}record {{ path {precious}; max_files 1; }}\ndefault_action accept;\n"),
            "mavtables.conf:2:",
        ),
    ];
    for (i, (text, at)) in broken.iter().enumerate() {
        std::fs::write(&router.config, text).expect("write");
        router.signal(libc::SIGHUP);
        router
            .err
            .wait_for("configuration not reloaded", 10 * SECOND);
        let located = router.err.wait_for(at, 10 * SECOND);
        assert!(located.contains(": "), "case {i}: {located}");
        // The old rules still hold: the ATTITUDE is rejected, the HEARTBEAT passes.
        a.send(&attitude(1, i as u8)).expect("send");
        a.send(&heartbeat(1)).expect("send");
        assert_eq!(udp_frames(&b, 1, 5 * SECOND), [heartbeat(1)], "case {i}");
    }
    let stopped = router.stop();
    assert!(
        !stopped.stderr.iter().any(|l| l.contains(RELOADED)),
        "{:?}",
        stopped.stderr
    );
    assert_eq!(
        std::fs::read_to_string(&precious).ok().as_deref(),
        Some("keep me\n")
    );
}

/// An added interface opens, a removed one closes (its connection too), and a changed
/// `max_bitrate` applies in place: the socket and its learned peers stay.
#[test]
fn interfaces_open_close_and_change_in_place() {
    let s = Scratch::new("reload-ifaces");
    let (a_port, b_port, t_port) = (free_udp_port(), free_udp_port(), free_tcp_port());
    let rules = "default_action accept;\n";
    let a = format!("udp {{ port {a_port}; address 127.0.0.1; }}\n");
    let t = format!("tcp {{ port {t_port}; address 127.0.0.1; }}\n");
    let mut router = Router::start(&s, &format!("{a}{t}{rules}"), 1);
    let sender = udp_peer(&mut router, a_port, 1);
    let receiver = udp_peer(&mut router, a_port, 2);
    let mut conn = connect(&format!("127.0.0.1:{t_port}"));
    conn.write_all(&heartbeat(3)).expect("write");
    router.wait_for("new component 3.1 on tcp:127.0.0.1:");
    assert!(!udp_port_bound(b_port));

    let socket_before = udp_inode(a_port);
    // 8,000 bit/s: 25 frames of 40 bytes a second.
    let a_paced = format!("udp {{ port {a_port}; address 127.0.0.1; max_bitrate 8000; }}\n");
    let b = format!("udp {{ port {b_port}; address 127.0.0.1; }}\n");
    let line = reload(&mut router, &format!("{a_paced}{b}{rules}"));
    assert!(line.ends_with("+1 interface, -1, 1 changed"), "{line}");
    let details: Vec<&String> = router
        .err
        .seen
        .iter()
        .filter(|l| l.starts_with("reload: "))
        .collect();
    let has = |text: &str| details.iter().any(|l| l.contains(text));
    assert!(
        has(&format!(
            "udp 127.0.0.1:{a_port} changed in place: max_bitrate"
        )),
        "{details:?}"
    );
    assert!(has(&format!("udp 127.0.0.1:{b_port} added")), "{details:?}");
    assert!(
        has(&format!("tcp 127.0.0.1:{t_port} removed")),
        "{details:?}"
    );

    assert_eq!(
        udp_inode(a_port),
        socket_before,
        "the changed interface's socket was reopened"
    );
    // The removed server's connection is closed, and nobody listens there any more.
    conn.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    let mut buf = [0u8; 512];
    let closed = loop {
        match conn.read(&mut buf) {
            Ok(0) => break true,
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break true,
            Err(_) => break false,
        }
    };
    assert!(closed, "the removed server's connection is still open");
    assert!(TcpStream::connect(("127.0.0.1", t_port)).is_err());
    // The added one is bound and routes.
    assert!(udp_port_bound(b_port));
    let newcomer = udp_peer(&mut router, b_port, 4);
    newcomer.send(&attitude(4, 1)).expect("send");
    expect_frame(&receiver, &attitude(4, 1));

    // The changed one kept its socket and its learned peers: no heartbeat needed, and
    // 50 frames now take about two seconds.
    let start = Instant::now();
    for n in 0..50 {
        sender.send(&numbered(1, n)).expect("send");
    }
    let got = numbered_from(&receiver, 1, 50, 10 * SECOND);
    let took = start.elapsed();
    assert_eq!(got, (0..50).collect::<Vec<u32>>());
    assert!(
        took >= Duration::from_millis(1500),
        "50 frames at 8,000 bit/s arrived in {took:?}"
    );
    let stopped = router.stop();
    let learned = stopped
        .stdout
        .iter()
        .filter(|l| l.contains("new component 2.1 "))
        .count();
    assert_eq!(learned, 1, "the receiver was learned again");
}

/// Numbered frames from `sys` already waiting on `sock` (read without waiting: on
/// 127.0.0.1 a datagram is there once its sender's call returned).
fn numbered_waiting(sock: &UdpSocket, sys: u8) -> Vec<u32> {
    sock.set_nonblocking(true).expect("non-blocking");
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    while let Ok(n) = sock.recv(&mut buf) {
        let mut parser = Parser::new();
        parser.feed(&buf[..n], |f| {
            if f.message_id() == 30 && f.source().system == sys {
                got.push(number_of(f.as_bytes()));
            }
        });
    }
    sock.set_nonblocking(false).expect("blocking");
    got
}

/// A router (logging every decision) with blocks `a` and `b` (UDP servers on ports
/// `ports`), a sender (system 1) on `a`, a receiver (system 2) on `b`, and `n` numbered
/// frames of the sender that the router has queued for the receiver.
fn queued_for_b(
    s: &Scratch,
    [a, b]: [&str; 2],
    [a_port, b_port]: [u16; 2],
    n: u32,
) -> (Router, UdpSocket, UdpSocket) {
    let mut router = Router::start(s, &format!("{a}{b}default_action accept;\n"), 3);
    let sender = udp_peer(&mut router, a_port, 1);
    let receiver = udp_peer(&mut router, b_port, 2);
    for k in 0..n {
        sender.send(&numbered(1, k)).expect("send");
    }
    // Every frame is queued (the router said so) before what follows.
    for _ in 0..n {
        router.wait_for("accepted ATTITUDE (#30) from 1.1");
    }
    (router, sender, receiver)
}

/// A removed interface goes on sending what was queued for it after the reload, for at
/// most a second, then closes: every frame it had queued was either sent or counted in
/// the warning that says how many it dropped; none that arrived after the reload was
/// taken; its port is free afterwards. (At 800 bit/s a hundred frames of 40 bytes take
/// 40 s, however late the reload comes; that a queue sent in time closes the interface
/// at once is tested in the core, `tests/in_process/routing_reload.rs`.)
#[test]
fn a_removed_interface_sends_its_queue_for_at_most_a_second() {
    let s = Scratch::new("reload-flush");
    let (a_port, b_port) = (free_udp_port(), free_udp_port());
    let rules = "default_action accept;\n";
    let a = format!("udp {{ port {a_port}; address 127.0.0.1; }}\n");
    let b = format!("udp {{ port {b_port}; address 127.0.0.1; max_bitrate 800; }}\n");
    let (mut router, sender, slow) = queued_for_b(&s, [&a, &b], [a_port, b_port], 100);
    let before = numbered_waiting(&slow, 1);
    let line = reload(&mut router, &format!("{a}{rules}"));
    assert!(line.ends_with("+0 interfaces, -1, 0 changed"), "{line}");
    sender.send(&numbered(1, 100)).expect("send");
    let removed = (router.err.seen.iter())
        .find(|l| l.contains(&format!("udp 127.0.0.1:{b_port} removed")))
        .cloned()
        .unwrap_or_default();
    assert!(
        removed.contains(" queued frames are sent)"),
        "{:?}",
        router.err.seen
    );
    let warning = router
        .err
        .wait_for(&format!("udp 127.0.0.1:{b_port} closed: "), 5 * SECOND);
    let dropped: usize = (warning.split(" closed: ").nth(1))
        .and_then(|w| w.strip_suffix(" queued frames dropped"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{warning}"));
    eventually("its port is free", 5 * SECOND, || !udp_port_bound(b_port));
    let after = numbered_waiting(&slow, 1);
    assert!(!after.is_empty(), "nothing was sent after the reload");
    let got: Vec<u32> = before.iter().chain(&after).copied().collect();
    assert_eq!(
        got,
        (0..got.len() as u32).collect::<Vec<u32>>(),
        "in order, nothing lost but the tail, nothing routed after the reload"
    );
    assert_eq!(got.len() + dropped, 100, "every frame sent or counted");
    router.stop();
}

/// A TCP server removed by a reload ends its connection cleanly: a ground station that
/// keeps sending (a heartbeat every 5 ms) and reads late (300 ms after the reload,
/// through a small receive buffer) gets every frame queued for it before the reload,
/// in order, then the end. Closing under its next bytes would have the kernel reset
/// the connection and discard what it had not acknowledged.
#[test]
fn a_removed_servers_connection_gets_its_frames_though_it_keeps_sending() {
    let s = Scratch::new("reload-linger");
    let (udp, tcp) = (free_udp_port(), free_tcp_port());
    let u = format!("udp {{ port {udp}; address 127.0.0.1; }}\n");
    let t = format!("tcp {{ port {tcp}; address 127.0.0.1; }}\n");
    let rules = "default_action accept;\n";
    let mut router = Router::start(&s, &format!("{u}{t}{rules}"), 1);
    let mut gcs = connect_small(&format!("127.0.0.1:{tcp}"));
    gcs.write_all(&heartbeat(255)).expect("write");
    router.wait_for("new component 255.1 on tcp:127.0.0.1:");
    let vehicle = udp_peer(&mut router, udp, 1);
    for n in 0..2000 {
        vehicle.send(&numbered(1, n)).expect("send");
    }
    let name = format!("tcp:{}", gcs.local_addr().expect("addr"));
    eventually("2,000 frames for the ground station", 10 * SECOND, || {
        let c = counters(&mut router);
        c.link(&name).is_some_and(|l| l.frames_out >= 2000)
    });
    let reader = chatty_late_reader(gcs, 255, Duration::from_millis(300));
    reload(&mut router, &format!("{u}{rules}"));
    let got: Vec<u32> = (reader.join().expect("reader").iter())
        .filter(|f| f.len() > 7 && f[7] == 30)
        .map(|f| number_of(f))
        .collect();
    assert_eq!(got, (0..2000).collect::<Vec<u32>>());
    router.stop();
}

/// A reload that reopens a socket on the port it holds while it still sends its queue
/// (here: its address written out) closes the old one at once, what it had queued
/// dropped and said, and opens the new one: the port is not lost to the reload.
#[test]
fn a_reopened_socket_takes_its_port_from_the_retiring_one() {
    let s = Scratch::new("reload-reopen-port");
    let (a_port, b_port) = (free_udp_port(), free_udp_port());
    let rules = "default_action accept;\n";
    let a = format!("udp {{ port {a_port}; address 127.0.0.1; }}\n");
    // 800 bit/s: ten frames of 40 bytes take four seconds.
    let b = format!("udp {{ port {b_port}; max_bitrate 800; }}\n");
    let b_again = format!("udp {{ port {b_port}; address 0.0.0.0; max_bitrate 800; }}\n");
    let (mut router, sender, _receiver) = queued_for_b(&s, [&a, &b], [a_port, b_port], 10);
    let line = reload(&mut router, &format!("{a}{b_again}{rules}"));
    assert!(line.ends_with("+0 interfaces, -0, 1 changed"), "{line}");
    let said = router.err.seen.join("\n");
    assert!(
        said.contains(&format!("udp 0.0.0.0:{b_port} reopened")),
        "{said}"
    );
    assert!(
        said.contains(&format!("udp 0.0.0.0:{b_port} closed: ")),
        "the retiring socket was closed for the new one: {said}"
    );
    assert!(!said.contains("cannot open"), "{said}");
    // The new socket routes: a peer that joins it gets what the sender says.
    let receiver = udp_peer(&mut router, b_port, 2);
    sender.send(&attitude(1, 7)).expect("send");
    expect_frame(&receiver, &attitude(1, 7));
    router.stop();
}

/// The same for a UDP client with a fixed local port, which binds when it opens: its
/// new socket takes the port from the old one, which is still sending its queue.
#[test]
fn a_reopened_udp_client_takes_its_fixed_port_back() {
    let s = Scratch::new("reload-reopen-client");
    let (a_port, local) = (free_udp_port(), free_udp_port());
    let ground = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let g_port = ground.local_addr().expect("addr").port();
    let a = format!("udp {{ port {a_port}; address 127.0.0.1; }}\n");
    let client = |address: &str| {
        format!("udp {{ connect 127.0.0.1:{g_port}; port {local};{address} max_bitrate 800; }}\n")
    };
    let rules = "default_action accept;\n";
    let mut router = Router::start(&s, &format!("{a}{}{rules}", client("")), 3);
    let sender = udp_peer(&mut router, a_port, 1);
    for n in 0..100 {
        sender.send(&numbered(1, n)).expect("send");
    }
    for _ in 0..100 {
        router.wait_for("accepted ATTITUDE (#30) from 1.1");
    }
    let line = reload(
        &mut router,
        &format!("{a}{}{rules}", client(" address 127.0.0.1;")),
    );
    assert!(line.ends_with("+0 interfaces, -0, 1 changed"), "{line}");
    router.err.wait_for(
        &format!("udp connect 127.0.0.1:{g_port} closed: "),
        5 * SECOND,
    );
    // The new socket sends from the same port.
    eventually("a frame from the new socket", 10 * SECOND, || {
        sender.send(&attitude(1, 7)).expect("send");
        ground
            .set_read_timeout(Some(Duration::from_millis(200)))
            .expect("timeout");
        let mut buf = [0u8; 512];
        std::iter::from_fn(|| {
            let (n, from) = ground.recv_from(&mut buf).ok()?;
            Some(from.port() == local && buf[..n] == attitude(1, 7)[..])
        })
        .any(|new| new)
    });
    let said = router.err.seen.join("\n");
    assert!(!said.contains("cannot open"), "{said}");
    router.stop();
}

/// A serial port whose `baudrate` changes is reopened (its device opened again, said in
/// the log) and routes as before, while the UDP interface beside it keeps its socket;
/// a serial port left as it was is not touched.
#[test]
fn a_changed_serial_port_is_reopened_and_routes_again() {
    let s = Scratch::new("reload-serial");
    let device = s.path("radio");
    let (mut master, _slave) = common::pty_at(&device);
    let port = free_udp_port();
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\ndefault_action accept;\n");
    let serial = |baud: u32| format!("serial {{ device {device}; baudrate {baud}; }}\n");
    let mut router = Router::start(&s, &format!("{udp}{}", serial(57600)), 1);
    let gcs = udp_peer(&mut router, port, 255);
    let socket_before = udp_inode(port);
    master.write_all(&heartbeat(1)).expect("serial");
    router.wait_for(&format!("new component 1.1 on {device}"));
    master.write_all(&attitude(1, 1)).expect("serial");
    expect_frame(&gcs, &attitude(1, 1));

    let line = reload(&mut router, &format!("{udp}{}", serial(57600)));
    assert!(line.contains("0 changed"), "unchanged: {line}");
    std::fs::write(&router.config, format!("{udp}{}", serial(115200))).expect("write");
    router.signal(libc::SIGHUP);
    router
        .err
        .wait_for(&format!("serial device {device} reopened"), 10 * SECOND);
    let line = router.err.wait_for(RELOADED, 10 * SECOND);
    assert!(line.contains("1 changed"), "{line}");
    // The device is opened again: what the vehicle says now reaches the ground station.
    eventually("the reopened port routes", 10 * SECOND, || {
        let _ = master.write_all(&attitude(1, 2));
        gcs.set_read_timeout(Some(Duration::from_millis(200)))
            .expect("timeout");
        udp_frames(&gcs, 1, Duration::from_millis(300)).contains(&attitude(1, 2))
    });
    assert_eq!(udp_inode(port), socket_before, "the UDP socket was kept");
    router.stop();
}

/// The inode of the UDP socket bound to `port` (from /proc/net/udp): the same number
/// before and after means the same socket.
fn udp_inode(port: u16) -> String {
    let table = std::fs::read_to_string("/proc/net/udp").expect("/proc/net/udp");
    let wanted = format!(":{port:04X}");
    table
        .lines()
        .skip(1)
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .find(|f| f.get(1).is_some_and(|local| local.ends_with(&wanted)))
        .and_then(|f| f.get(9).map(|s| s.to_string()))
        .unwrap_or_else(|| panic!("no UDP socket on port {port}"))
}

/// Starts the router on `config` with `env` added to its environment.
fn start_with_env(s: &Scratch, config: &str, env: &[(&str, &str)]) -> (Guard, Lines) {
    let path = s.dir.join("mavtables.conf");
    std::fs::write(&path, config).expect("write config");
    let mut cmd = Command::new(BIN);
    cmd.arg("--config").arg(&path).args(["--loglevel", "1"]);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn mavtables");
    let err = Lines::new(child.stderr.take().expect("stderr"), "router stderr");
    (Guard(Some(child)), err)
}

/// The next notification systemd would get (`None` after `timeout`).
fn notification(socket: &UnixDatagram, timeout: Duration) -> Option<String> {
    socket.set_read_timeout(Some(timeout)).expect("timeout");
    let mut buf = [0u8; 4096];
    let n = socket.recv(&mut buf).ok()?;
    Some(String::from_utf8_lossy(&buf[..n]).into_owned())
}

/// Notifications until one contains `what` (within 10 s); returns it.
fn expect_notification(socket: &UnixDatagram, what: &str, seen: &mut Vec<String>) -> String {
    let deadline = Instant::now() + 10 * SECOND;
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        let Some(message) = notification(socket, left) else {
            break;
        };
        seen.push(message.clone());
        if message.contains(what) {
            return message;
        }
    }
    panic!("no {what:?} within 10 s; got {seen:?}");
}

fn signal(guard: &mut Guard, signal: i32) {
    let pid = nix::unistd::Pid::from_raw(guard.child().id() as i32);
    let signal = nix::sys::signal::Signal::try_from(signal).expect("a signal number");
    assert_eq!(nix::sys::signal::kill(pid, signal), Ok(()));
}

/// The test plays systemd: `READY=1` once the interfaces are open, `WATCHDOG=1` again
/// and again at half of `WATCHDOG_USEC`, `RELOADING=1` (with `MONOTONIC_USEC=`) then
/// `READY=1` around a SIGHUP, `STOPPING=1` at SIGTERM.
#[test]
fn systemd_hears_ready_reloading_watchdog_and_stopping() {
    let s = Scratch::new("reload-notify");
    let socket_path = s.path("notify.sock");
    let systemd = UnixDatagram::bind(&socket_path).expect("bind notify socket");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address 127.0.0.1; }}\n{TWO_RULES}");
    let (mut guard, mut err) = start_with_env(
        &s,
        &config,
        &[("NOTIFY_SOCKET", &socket_path), ("WATCHDOG_USEC", "200000")],
    );
    let mut seen = Vec::new();
    let ready = expect_notification(&systemd, "READY=1", &mut seen);
    assert!(
        udp_port_bound(port),
        "READY=1 before the interfaces were open"
    );
    assert!(!ready.contains("RELOADING"), "{ready}");
    // The watchdog, every 100 ms: five of them within a few seconds.
    let start = Instant::now();
    for _ in 0..5 {
        expect_notification(&systemd, "WATCHDOG=1", &mut seen);
    }
    assert!(start.elapsed() < 3 * SECOND, "watchdog too slow: {seen:?}");

    signal(&mut guard, libc::SIGHUP);
    let reloading = expect_notification(&systemd, "RELOADING=1", &mut seen);
    let usec = reloading
        .lines()
        .find_map(|l| l.strip_prefix("MONOTONIC_USEC="))
        .unwrap_or_else(|| panic!("no MONOTONIC_USEC in {reloading:?}"));
    assert!(usec.parse::<u64>().is_ok_and(|v| v > 0), "{reloading}");
    let ready = expect_notification(&systemd, "READY=1", &mut seen);
    assert!(
        ready.contains("STATUS=routing; configuration reloaded: 2 rules"),
        "{ready}"
    );
    err.wait_for(RELOADED, 10 * SECOND);
    // A broken file: the status says the running configuration is kept.
    std::fs::write(s.dir.join("mavtables.conf"), "udp { port x; }\n").expect("write");
    signal(&mut guard, libc::SIGHUP);
    expect_notification(&systemd, "RELOADING=1", &mut seen);
    let ready = expect_notification(&systemd, "READY=1", &mut seen);
    assert!(
        ready.contains("STATUS=routing as before: the configuration file has errors"),
        "{ready}"
    );

    signal(&mut guard, libc::SIGTERM);
    expect_notification(&systemd, "STOPPING=1", &mut seen);
    let status = guard.wait(5 * SECOND).expect("exit within 5 s");
    assert_eq!(status.code(), Some(0));
}

/// An abstract socket name (`@name`, as systemd may give) works too; without
/// `WATCHDOG_USEC` no watchdog message is sent.
#[test]
fn an_abstract_notify_socket_works_and_no_watchdog_unless_asked() {
    let s = Scratch::new("reload-notify-abstract");
    let name = format!("mavtables-test-{}-{}", std::process::id(), free_udp_port());
    let addr = UnixAddr::from_abstract_name(name.as_bytes()).expect("abstract name");
    let systemd = UnixDatagram::bind_addr(&addr).expect("bind abstract socket");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address 127.0.0.1; }}\n{TWO_RULES}");
    let (mut guard, _err) = start_with_env(&s, &config, &[("NOTIFY_SOCKET", &format!("@{name}"))]);
    let mut seen = Vec::new();
    expect_notification(&systemd, "READY=1", &mut seen);
    signal(&mut guard, libc::SIGTERM);
    expect_notification(&systemd, "STOPPING=1", &mut seen);
    assert!(guard.wait(5 * SECOND).is_some_and(|s| s.success()));
    assert!(!seen.iter().any(|m| m.contains("WATCHDOG")), "{seen:?}");
}

/// `GET /stats` from the endpoint on `port`: the JSON, or `None` if nothing answers.
fn stats_json(port: u16) -> Option<serde_json::Value> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(5 * SECOND)).ok()?;
    s.write_all(b"GET /stats HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .ok()?;
    let mut answer = String::new();
    s.read_to_string(&mut answer).ok()?;
    serde_json::from_str(answer.split_once("\r\n\r\n")?.1).ok()
}

/// The frames received on link `name` according to the endpoint on `port`, once it
/// counts at least `least` of them (within 10 s).
fn frames_in_at_least(port: u16, name: &str, least: u64) -> u64 {
    let mut last = None;
    eventually("the endpoint counts the frames", 10 * SECOND, || {
        last = stats_json(port).and_then(|s| {
            s["links"].as_array()?.iter().find(|l| l["name"] == name)?["frames_in"].as_u64()
        });
        last.is_some_and(|n| n >= least)
    });
    last.unwrap_or(0)
}

/// A `stats` block left as it was keeps its endpoint and every counter across a
/// reload; one moved to another port is restarted there and the old port is closed.
#[test]
fn the_stats_endpoint_is_kept_or_moved_by_a_reload() {
    let s = Scratch::new("reload-stats");
    let (port, http_a, http_b) = (free_udp_port(), free_tcp_port(), free_tcp_port());
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\ndefault_action accept;\n");
    let with_stats = |http: u16| format!("{udp}stats {{ port {http}; }}\n");
    let mut router = Router::start(&s, &with_stats(http_a), 1);
    let a = udp_peer(&mut router, port, 1);
    let name = a.local_addr().expect("addr").to_string();
    for n in 0..5 {
        a.send(&attitude(1, n)).expect("send");
    }
    let before = frames_in_at_least(http_a, &name, 6);

    // Unchanged: the same endpoint, the counts go on from where they were.
    let line = reload(&mut router, &format!("{}# a comment\n", with_stats(http_a)));
    assert!(line.contains("+0 interfaces, -0, 0 changed"), "{line}");
    a.send(&attitude(1, 9)).expect("send");
    assert_eq!(frames_in_at_least(http_a, &name, before + 1), before + 1);

    // Moved: the new port answers with the same counts, the old one is closed.
    reload(&mut router, &with_stats(http_b));
    assert_eq!(frames_in_at_least(http_b, &name, before + 1), before + 1);
    eventually("the old port closed", 5 * SECOND, || {
        TcpStream::connect(("127.0.0.1", http_a)).is_err()
    });
    router.stop();
}

/// A reload that changes only the `allow` ranges of the statistics endpoint keeps its
/// port (every time: it used to be restarted on the same port, which the old listener
/// could still hold); one that gives the endpoint's port to an interface opens that
/// interface, and a request naming another site than this machine is refused.
#[test]
fn the_stats_endpoint_keeps_its_port_when_only_allow_changes_and_can_give_it_up() {
    let s = Scratch::new("reload-stats-allow");
    let (port, http, http_b) = (free_udp_port(), free_tcp_port(), free_tcp_port());
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\ndefault_action accept;\n");
    let with_allow = |range: &str| format!("{udp}stats {{ port {http}; allow {range}; }}\n");
    let mut router = Router::start(&s, &with_allow("127.0.0.0/8"), 1);
    let a = udp_peer(&mut router, port, 1);
    let name = a.local_addr().expect("addr").to_string();
    a.send(&attitude(1, 1)).expect("send");
    let mut before = frames_in_at_least(http, &name, 2);
    for n in 0..20 {
        let range = if n % 2 == 0 {
            "127.0.0.1/32"
        } else {
            "127.0.0.0/8"
        };
        reload(&mut router, &with_allow(range));
        a.send(&attitude(1, 2)).expect("send");
        before = frames_in_at_least(http, &name, before + 1);
    }
    let seen = &router.err.seen;
    let said = |text: &str| seen.iter().filter(|l| l.contains(text)).count();
    assert_eq!(
        said("reload: statistics endpoint's allow changed"),
        20,
        "{seen:?}"
    );
    assert_eq!(said("cannot listen"), 0, "{seen:?}");
    // A web page whose name was pointed at 127.0.0.1 is not answered.
    let mut c = TcpStream::connect(("127.0.0.1", http)).expect("connect");
    c.write_all(b"GET /stats HTTP/1.1\r\nHost: evil.example:9100\r\n\r\n")
        .expect("write");
    let mut answer = String::new();
    c.read_to_string(&mut answer).expect("read");
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    // The endpoint moves, and a new TCP server takes its old port in the same reload.
    let line = reload(
        &mut router,
        &format!("{udp}stats {{ port {http_b}; }}\ntcp {{ port {http}; address 127.0.0.1; }}\n"),
    );
    assert!(line.contains("+1 interface, -0, 0 changed"), "{line}");
    assert!(!line.contains("not opened"), "{line}");
    let mut conn = connect(&format!("127.0.0.1:{http}"));
    conn.write_all(&heartbeat(3)).expect("write");
    router.wait_for("new component 3.1 on tcp:127.0.0.1:");
    assert!(frames_in_at_least(http_b, &name, before) >= before);
    router.stop();
}

/// What a reload cannot open (a port taken) is said as not opened, not as added, and
/// the next reload of the same file opens it; a statistics endpoint that cannot listen
/// is not said to be restarted, and the next reload starts it. The summary counts
/// removed rules and names other settings that changed.
#[test]
fn what_a_reload_cannot_open_is_said_and_the_next_reload_opens_it() {
    let s = Scratch::new("reload-not-opened");
    let (port, t_port, http) = (free_udp_port(), free_tcp_port(), free_tcp_port());
    let udp = format!("udp {{ port {port}; address 127.0.0.1; }}\n");
    let mut router = Router::start(&s, &format!("{udp}{TWO_RULES}"), 1);
    let a = udp_peer(&mut router, port, 1);
    let name = a.local_addr().expect("addr").to_string();
    let taken_t = std::net::TcpListener::bind(("127.0.0.1", t_port)).expect("take the port");
    let taken_http = std::net::TcpListener::bind(("127.0.0.1", http)).expect("take the port");
    let more = format!(
        "{udp}tcp {{ port {t_port}; address 127.0.0.1; }}\nstats {{ port {http}; address 127.0.0.1; }}\ndedup 200ms;\nchain default {{\n    accept;\n}}\n"
    );
    let line = reload(&mut router, &more);
    assert!(
        line.ends_with("1 rule (0 changed, 1 removed), +0 interfaces, -0, 0 changed, 1 not opened, dedup changed, stats changed"),
        "{line}"
    );
    let seen = router.err.seen.clone();
    let has = |text: &str| seen.iter().any(|l| l.contains(text));
    assert!(
        has(&format!("reload: tcp 127.0.0.1:{t_port} not opened: ")),
        "{seen:?}"
    );
    assert!(!has(&format!("tcp 127.0.0.1:{t_port} added")), "{seen:?}");
    assert!(
        has(&format!("stats: cannot listen on 127.0.0.1:{http}")),
        "{seen:?}"
    );
    assert!(!has("statistics endpoint restarted"), "{seen:?}");

    drop((taken_t, taken_http));
    let line = reload(&mut router, &more);
    // The endpoint that could not listen is started now, so it counts as changed again.
    assert!(
        line.ends_with("1 rule (0 changed), +1 interface, -0, 0 changed, stats changed"),
        "{line}"
    );
    assert!(
        router
            .err
            .seen
            .iter()
            .any(|l| l.contains("statistics endpoint restarted"))
    );
    let mut conn = connect(&format!("127.0.0.1:{t_port}"));
    conn.write_all(&heartbeat(3)).expect("write");
    router.wait_for("new component 3.1 on tcp:127.0.0.1:");
    a.send(&attitude(1, 1)).expect("send");
    assert!(frames_in_at_least(http, &name, 2) >= 2);
    router.stop();
}
