//! End-to-end tests of the transports beyond the original's: UDP clients (a ground
//! station that only listens), TCP servers and clients, IPv6 and host names, and the
//! limits on who may become a link. The real `mavtables` binary and plain sockets of our
//! own on 127.0.0.1 and [::1]; every wait is bounded and ends on an event.

use crate::common;

use std::io::Write;
use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::time::{Duration, Instant};

use common::net::{
    ACCEPT_ALL, SECOND, attitude, connect, free_tcp_port, heartbeat, number_of, numbered,
    tcp_frames, udp_frames,
};
use common::router::{Router, Scratch, free_udp_port};

/// A ground station that only listens (as QGroundControl does on UDP 14550) gets the
/// vehicle's heartbeats through a `udp { connect …; }` block: the router sends to it from
/// the start, before it has said anything.
#[test]
fn a_udp_client_reaches_a_ground_station_that_only_listens() {
    let s = Scratch::new("udp-client");
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let gcs_port = gcs.local_addr().expect("addr").port();
    let vehicle_port = free_udp_port();
    let config = format!(
        "udp {{ port {vehicle_port}; address 127.0.0.1; }}\nudp {{ connect 127.0.0.1:{gcs_port}; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let to = format!("127.0.0.1:{vehicle_port}");
    vehicle.send_to(&heartbeat(1), &to).expect("send");
    router.wait_for("new component 1.1 on 127.0.0.1:");
    gcs.set_read_timeout(Some(5 * SECOND)).expect("timeout");
    let mut buf = [0u8; 512];
    let (n, router_side) = gcs.recv_from(&mut buf).expect("a heartbeat within 5 s");
    assert_eq!(&buf[..n], &heartbeat(1)[..]);
    // The ground station answers where the heartbeat came from; the vehicle gets it.
    gcs.send_to(&heartbeat(255), router_side).expect("send");
    router.wait_for("new component 255.1 on 127.0.0.1:");
    assert_eq!(udp_frames(&vehicle, 1, 5 * SECOND), [heartbeat(255)]);
    router.stop();
}

/// A UDP socket is read one datagram per wake-up while traffic is light, and watched
/// level-triggered so that what is left wakes the loop again: datagrams that all queued
/// up while the router could not run (stopped with SIGSTOP) are forwarded, every one, in
/// order, with nothing else arriving to wake it.
#[test]
fn datagrams_queued_while_the_router_was_stopped_are_all_forwarded() {
    let s = Scratch::new("udp-queued");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address 127.0.0.1; }}\n{ACCEPT_ALL}");
    let mut router = Router::start(&s, &config, 1);
    let to = format!("127.0.0.1:{port}");
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind");
    gcs.send_to(&heartbeat(255), &to).expect("send");
    router.wait_for("new component 255.1 on 127.0.0.1:");
    vehicle.send_to(&numbered(1, 0), &to).expect("send");
    router.wait_for("new component 1.1 on 127.0.0.1:");
    assert_eq!(udp_frames(&gcs, 1, 5 * SECOND), [numbered(1, 0)]);
    router.signal(libc::SIGSTOP);
    const QUEUED: u32 = 20;
    for n in 1..=QUEUED {
        vehicle.send_to(&numbered(1, n), &to).expect("send");
    }
    router.signal(libc::SIGCONT);
    let got = udp_frames(&gcs, QUEUED as usize, 5 * SECOND);
    let numbers: Vec<u32> = got.iter().map(|f| number_of(f)).collect();
    assert_eq!(numbers, (1..=QUEUED).collect::<Vec<_>>());
    router.stop();
}

/// Two TCP clients of a `tcp { }` server are each a link: frames split across writes
/// and several frames in one write all arrive, in order, at the other client; the link
/// names say `tcp:`; a client that goes away is removed and the other keeps routing.
#[test]
fn a_tcp_server_takes_each_connection_as_a_link() {
    let s = Scratch::new("tcp-server");
    let port = free_tcp_port();
    let config = format!("tcp {{ port {port}; address 127.0.0.1; }}\n{ACCEPT_ALL}");
    let mut router = Router::start(&s, &config, 1);
    let to = format!("127.0.0.1:{port}");
    let mut a = connect(&to);
    let mut b = connect(&to);
    b.write_all(&heartbeat(20)).expect("write");
    router.wait_for("new component 20.1 on tcp:127.0.0.1:");
    a.write_all(&heartbeat(10)).expect("write");
    router.wait_for("new component 10.1 on tcp:127.0.0.1:");
    // A's heartbeat reached B.
    assert_eq!(tcp_frames(&mut b, 1, 5 * SECOND), [heartbeat(10)]);
    let frames: Vec<Vec<u8>> = (0..5).map(|n| attitude(10, n)).collect();
    // One frame cut in two writes, then four in one write.
    let (head, tail) = frames[0].split_at(7);
    a.write_all(head).expect("write");
    a.flush().expect("flush");
    std::thread::sleep(Duration::from_millis(20));
    a.write_all(tail).expect("write");
    a.write_all(&frames[1..].concat()).expect("write");
    assert_eq!(tcp_frames(&mut b, 5, 5 * SECOND), frames);
    // A leaves; B still reaches a third client.
    drop(a);
    let mut c = connect(&to);
    c.write_all(&heartbeat(30)).expect("write");
    router.wait_for("new component 30.1 on tcp:127.0.0.1:");
    b.write_all(&attitude(20, 9)).expect("write");
    let at_c = tcp_frames(&mut c, 2, 5 * SECOND);
    assert!(at_c.contains(&attitude(20, 9)), "{at_c:?}");
    let err = router.stop().stderr;
    let links = err
        .iter()
        .filter(|l| l.trim_start().starts_with("tcp:127.0.0.1:") && l.contains(": in "))
        .count();
    assert_eq!(links, 2, "two links left: {err:?}");
}

/// A `tcp { connect …; }` client connects at start, sends what the vehicle sends, and
/// after the server goes away and comes back it is connected again within 2 s.
#[test]
fn a_tcp_client_reconnects_when_its_server_comes_back() {
    let s = Scratch::new("tcp-client");
    let server = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = server.local_addr().expect("addr").port();
    let vehicle_port = free_udp_port();
    let config = format!(
        "udp {{ port {vehicle_port}; address 127.0.0.1; }}\ntcp {{ connect localhost:{port}; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let (mut conn, _) = server.accept().expect("the router connects");
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let to = format!("127.0.0.1:{vehicle_port}");
    vehicle.send_to(&heartbeat(1), &to).expect("send");
    assert_eq!(tcp_frames(&mut conn, 1, 5 * SECOND), [heartbeat(1)]);
    // The server goes away (listener and connection), then comes back on its port.
    drop(conn);
    drop(server);
    router.err.wait_for("lost", 5 * SECOND);
    std::thread::sleep(Duration::from_millis(300));
    let server = TcpListener::bind(format!("127.0.0.1:{port}")).expect("rebind");
    let back = Instant::now();
    server.set_nonblocking(true).expect("nonblocking");
    let mut conn = loop {
        match server.accept() {
            Ok((c, _)) => break c,
            Err(_) => {
                assert!(
                    back.elapsed() < 2 * SECOND + SECOND / 2,
                    "no reconnect within 2 s"
                );
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    };
    conn.set_nonblocking(false).expect("blocking");
    vehicle.send_to(&attitude(1, 5), &to).expect("send");
    assert_eq!(tcp_frames(&mut conn, 1, 5 * SECOND), [attitude(1, 5)]);
    router.stop();
}

/// IPv6 end to end: a UDP server on [::1] routes between two IPv6 peers.
#[test]
fn ipv6_peers_route_through_a_udp_server_on_loopback() {
    common::needs::ipv6_loopback();
    let a = UdpSocket::bind("[::1]:0").expect("bind [::1]");
    let b = UdpSocket::bind("[::1]:0").expect("bind b");
    let s = Scratch::new("ipv6");
    let port = free_udp_port();
    let config = format!("udp {{ port {port}; address ::1; }}\n{ACCEPT_ALL}");
    let mut router = Router::start(&s, &config, 1);
    let to: SocketAddr = format!("[::1]:{port}").parse().expect("addr");
    b.send_to(&heartbeat(20), to).expect("send");
    router.wait_for("new component 20.1 on [::1]:");
    a.send_to(&attitude(10, 1), to).expect("send");
    assert_eq!(udp_frames(&b, 1, 5 * SECOND), [attitude(10, 1)]);
    router.stop();
}

/// IPv6 over TCP and for a UDP client: a vehicle on a TCP server on [::1] reaches a
/// ground station that only listens on [::1], through `udp { connect [::1]:P; }`, and a
/// TCP client of the router connected to an IPv6 server gets the same.
#[test]
fn ipv6_tcp_server_tcp_client_and_udp_client() {
    common::needs::ipv6_loopback();
    let gcs = UdpSocket::bind("[::1]:0").expect("bind [::1]");
    let gcs_port = gcs.local_addr().expect("addr").port();
    let upstream = TcpListener::bind("[::1]:0").expect("bind");
    let upstream_port = upstream.local_addr().expect("addr").port();
    let s = Scratch::new("ipv6-tcp");
    let port = free_tcp_port();
    let config = format!(
        "tcp {{ port {port}; address ::1; }}
         udp {{ connect [::1]:{gcs_port}; }}
         tcp {{ connect [::1]:{upstream_port}; }}
{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let (mut up, _) = upstream.accept().expect("the router connects over IPv6");
    let mut vehicle = connect(&format!("[::1]:{port}"));
    vehicle.write_all(&heartbeat(1)).expect("write");
    router.wait_for("new component 1.1 on tcp:[::1]:");
    assert_eq!(udp_frames(&gcs, 1, 5 * SECOND), [heartbeat(1)]);
    assert_eq!(tcp_frames(&mut up, 1, 5 * SECOND), [heartbeat(1)]);
    router.stop();
}

/// `max_peers` and `allow`: remotes beyond the limit or outside the ranges are refused,
/// counted per reason and said once; the links that exist keep routing.
#[test]
fn server_limits_refuse_remotes_and_count_them() {
    let s = Scratch::new("limits");
    let (full, fenced) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ port {full}; address 127.0.0.1; max_peers 2; }}\nudp {{ port {fenced}; address 127.0.0.1; allow 10.0.0.0/8; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let peers: Vec<UdpSocket> = (0..3)
        .map(|_| UdpSocket::bind("127.0.0.1:0").expect("bind"))
        .collect();
    let to = format!("127.0.0.1:{full}");
    peers[0].send_to(&heartbeat(1), &to).expect("send");
    router.wait_for("new component 1.1 on 127.0.0.1:");
    peers[1].send_to(&heartbeat(2), &to).expect("send");
    router.wait_for("new component 2.1 on 127.0.0.1:");
    for _ in 0..5 {
        peers[2].send_to(&heartbeat(3), &to).expect("send");
    }
    peers[2]
        .send_to(&heartbeat(4), format!("127.0.0.1:{fenced}"))
        .expect("send");
    router.err.wait_for("max_peers", 5 * SECOND);
    router
        .err
        .wait_for("outside the allowed address ranges", 5 * SECOND);
    // The two links still route: 1's frame reaches 2.
    peers[0].send_to(&attitude(1, 1), &to).expect("send");
    let at_2 = udp_frames(&peers[1], 2, 5 * SECOND);
    assert!(at_2.contains(&attitude(1, 1)), "{at_2:?}");
    let err = router.stop().stderr.join("\n");
    assert!(
        err.contains("0 refused (not allowed), 5 refused (max_peers)"),
        "{err}"
    );
    assert!(
        err.contains("1 refused (not allowed), 0 refused (max_peers)"),
        "{err}"
    );
    assert_eq!(
        err.matches("max_peers); new remotes are refused").count(),
        1,
        "{err}"
    );
}

/// A TCP port already in use at start is a clear error naming the block, exit 1.
#[test]
fn a_tcp_port_in_use_stops_the_start_naming_the_block() {
    let s = Scratch::new("in-use");
    let taken = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = taken.local_addr().expect("addr").port();
    let path = s.dir.join("mavtables.conf");
    std::fs::write(
        &path,
        format!("tcp {{ port {port}; address 127.0.0.1; }}\n"),
    )
    .expect("write");
    let out = std::process::Command::new(common::router::BIN)
        .arg("--config")
        .arg(&path)
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("tcp 127.0.0.1:{port}: ")), "{err}");
    assert!(err.contains("in use"), "{err}");
}

/// A client whose host name does not resolve stops nothing: the other links route, and
/// the router says it keeps trying (the look-up runs off the loop).
#[test]
fn a_client_name_that_does_not_resolve_stops_nothing() {
    let s = Scratch::new("unresolved");
    let port = free_udp_port();
    let config = format!(
        "udp {{ port {port}; address 127.0.0.1; }}\n\
         tcp {{ connect no-such-host.invalid:5760; }}\n\
         udp {{ connect no-such-host.invalid:14550; }}\n{ACCEPT_ALL}"
    );
    let mut router = Router::start(&s, &config, 1);
    let (a, b) = (
        UdpSocket::bind("127.0.0.1:0").expect("bind"),
        UdpSocket::bind("127.0.0.1:0").expect("bind"),
    );
    let to = format!("127.0.0.1:{port}");
    b.send_to(&heartbeat(20), &to).expect("send");
    router.wait_for("new component 20.1 on 127.0.0.1:");
    a.send_to(&attitude(10, 3), &to).expect("send");
    let at_b = udp_frames(&b, 1, 5 * SECOND);
    assert_eq!(at_b, [attitude(10, 3)]);
    // The two look-ups finish in either order.
    for said in [
        "cannot open tcp connect no-such-host.invalid:5760",
        "cannot open udp connect no-such-host.invalid:14550",
    ] {
        if !router.err.seen.iter().any(|l| l.contains(said)) {
            router.err.wait_for(said, 10 * SECOND);
        }
    }
    router.stop();
}
