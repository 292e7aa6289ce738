//! Two radios to one vehicle through the real binary: `dedup` and a `group` of two `udp`
//! interfaces (or of a serial port, a real pseudo-terminal, and a `udp` interface) make
//! them one path (the ground station gets each frame once, in order; one radio dying
//! loses nothing; a genuine resend after the window passes; a command goes out on both
//! radios). And the router's own `heartbeat`, waited for by a pymavlink peer behind
//! `udp { connect ...; }`.

use crate::common;

use std::io::{Read, Write};
use std::net::UdpSocket;
use std::time::Duration;

use serialport::SerialPort;

use common::net::{number_of, numbered, with_payload};
use common::router::{Router, Scratch, free_udp_port};

fn socket() -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    s.set_read_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    s
}

/// Frames `s` receives until `done` says so about the last one, within 10 s.
fn receive_until(s: &UdpSocket, mut done: impl FnMut(&[u8]) -> bool) -> Vec<Vec<u8>> {
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    common::eventually("the last frame", Duration::from_secs(10), || {
        if let Ok((n, _)) = s.recv_from(&mut buf) {
            got.push(buf[..n].to_vec());
            return done(&buf[..n]);
        }
        false
    });
    got
}

/// The counters of ATTITUDE frames from system 1 among `frames`, in order.
fn numbers(frames: &[Vec<u8>]) -> Vec<u32> {
    frames
        .iter()
        .filter(|f| f.len() == 40 && f[5] == 1)
        .map(|f| number_of(f))
        .collect()
}

/// Asserts that `g` receives the numbered frames of `range` from system 1, each once
/// and in order (other frames aside), within 10 s.
fn arrive_once_in_order(g: &UdpSocket, range: std::ops::RangeInclusive<u32>) {
    let last = *range.end();
    let got = receive_until(g, |f| f.len() == 40 && number_of(f) == last);
    assert_eq!(numbers(&got), range.collect::<Vec<_>>());
}

/// COMMAND_LONG from 255.1 for 1.1.
fn command(seq: u8) -> Vec<u8> {
    let mut payload = [0x11u8; 33];
    payload[30] = 1;
    payload[31] = 1;
    with_payload(76, 255, seq, &payload)
}

#[test]
fn two_radios_in_a_group_are_one_path_to_the_vehicle() {
    let scratch = Scratch::new("dedup");
    let (pa, pb, pg) = (free_udp_port(), free_udp_port(), free_udp_port());
    let conf = format!(
        "dedup 300ms;\n\
         udp {{ port {pa}; address 127.0.0.1; group radios; }}\n\
         udp {{ port {pb}; address 127.0.0.1; group radios; }}\n\
         udp {{ port {pg}; address 127.0.0.1; }}\n\
         default_action accept;\n"
    );
    let mut router = Router::start(&scratch, &conf, 1);
    let (a, b, gcs) = (
        format!("127.0.0.1:{pa}"),
        format!("127.0.0.1:{pb}"),
        format!("127.0.0.1:{pg}"),
    );
    let (va, vb, g) = (socket(), socket(), socket());
    g.send_to(&with_payload(0, 255, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]), &gcs)
        .expect("send");
    router.wait_for("new component 255.1");

    // Every frame on both radios: the ground station gets each once, in order.
    for n in 0..=200u32 {
        va.send_to(&numbered(1, n), &a).expect("send a");
        vb.send_to(&numbered(1, n), &b).expect("send b");
    }
    arrive_once_in_order(&g, 0..=200);

    // Radio A dies: B alone loses nothing; then B dies and A alone carries on.
    for n in 201..=300u32 {
        vb.send_to(&numbered(1, n), &b).expect("send b");
    }
    arrive_once_in_order(&g, 201..=300);
    for n in 301..=400u32 {
        va.send_to(&numbered(1, n), &a).expect("send a");
    }
    arrive_once_in_order(&g, 301..=400);

    // A genuine resend (the same bytes after the window) passes; a copy within it not.
    let resend = numbered(1, 500);
    va.send_to(&resend, &a).expect("send");
    receive_until(&g, |f| f == resend.as_slice());
    vb.send_to(&resend, &b).expect("copy within the window");
    std::thread::sleep(Duration::from_millis(400));
    va.send_to(&resend, &a).expect("resend after the window");
    va.send_to(&numbered(1, 501), &a).expect("marker");
    let got = receive_until(&g, |f| f.len() == 40 && number_of(f) == 501);
    assert_eq!(
        numbers(&got),
        vec![500, 501],
        "the resend once, the copy not"
    );

    // A command from the ground station reaches the vehicle on both radios.
    let cmd = command(9);
    g.send_to(&cmd, &gcs).expect("send command");
    for (name, radio) in [("a", &va), ("b", &vb)] {
        let got = receive_until(radio, |f| f == cmd.as_slice());
        let cmds = got.iter().filter(|f| **f == cmd).count();
        assert_eq!(cmds, 1, "radio {name}");
        let from_vehicle = got.iter().filter(|f| f.len() == 40 && f[5] == 1).count();
        assert_eq!(
            from_vehicle, 0,
            "radio {name} got the vehicle's own frames back"
        );
    }
    let stopped = router.stop();
    let counters = stopped.stderr.join("\n");
    assert!(counters.contains("duplicates dropped"), "{counters}");
}

/// A vehicle with a serial radio (a pseudo-terminal) and an IP link (UDP), both in one
/// group: the ground station gets every frame once and in order, also while only one of
/// them carries the traffic, and a command for the vehicle goes out on both.
#[test]
fn a_serial_radio_and_a_udp_link_in_a_group_are_one_path() {
    let scratch = Scratch::new("dedup-serial");
    let device = scratch.path("radio");
    let (mut master, _slave) = common::pty_at(&device);
    let (pa, pg) = (free_udp_port(), free_udp_port());
    let conf = format!(
        "dedup 300ms;\n\
         serial {{ device {device}; baudrate 115200; group vehicle; }}\n\
         udp {{ port {pa}; address 127.0.0.1; group vehicle; }}\n\
         udp {{ port {pg}; address 127.0.0.1; }}\n\
         default_action accept;\n"
    );
    let mut router = Router::start(&scratch, &conf, 1);
    let (a, gcs) = (format!("127.0.0.1:{pa}"), format!("127.0.0.1:{pg}"));
    let (va, g) = (socket(), socket());
    g.send_to(&with_payload(0, 255, 0, &[0, 0, 0, 0, 6, 8, 0, 0, 3]), &gcs)
        .expect("send");
    router.wait_for("new component 255.1");
    master
        .write_all(&with_payload(0, 1, 0, &[0, 0, 0, 0, 2, 3, 0, 0, 3]))
        .expect("serial heartbeat");
    router.wait_for(&format!("new component 1.1 on {device}"));

    for n in 0..=200u32 {
        master.write_all(&numbered(1, n)).expect("serial");
        va.send_to(&numbered(1, n), &a).expect("udp");
    }
    arrive_once_in_order(&g, 0..=200);
    // The serial radio alone, then the IP link alone.
    for n in 201..=300u32 {
        master.write_all(&numbered(1, n)).expect("serial");
    }
    arrive_once_in_order(&g, 201..=300);
    for n in 301..=400u32 {
        va.send_to(&numbered(1, n), &a).expect("udp");
    }
    arrive_once_in_order(&g, 301..=400);

    // A command for the vehicle goes out on the serial radio and on the IP link.
    let cmd = command(7);
    g.send_to(&cmd, &gcs).expect("send command");
    receive_until(&va, |f| f == cmd.as_slice());
    master
        .set_timeout(Duration::from_millis(100))
        .expect("timeout");
    let mut serial_in = Vec::new();
    let mut buf = [0u8; 1024];
    common::eventually(
        "the command on the serial radio",
        Duration::from_secs(10),
        || {
            if let Ok(n) = master.read(&mut buf) {
                serial_in.extend_from_slice(&buf[..n]);
            }
            serial_in.windows(cmd.len()).any(|w| w == cmd.as_slice())
        },
    );
    router.stop();
}

#[test]
fn a_silent_peer_hears_the_routers_heartbeat() {
    let scratch = Scratch::new("own-heartbeat");
    let port = free_udp_port();
    let conf = format!(
        "heartbeat {{ system 1; component 191; interval 200ms; }}\n\
         udp {{ connect 127.0.0.1:{port}; }}\n\
         default_action accept;\n"
    );
    let router = Router::start(&scratch, &conf, 1);
    let out = common::run_py("wait_heartbeat.py", &[&port.to_string(), "10"], "");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    let mut seqs = Vec::new();
    for line in &lines {
        let fields: Vec<&str> = line.split(' ').collect();
        // system, component, type 18, autopilot 8, base_mode 0, custom_mode 0,
        // MAV_STATE_ACTIVE, mavlink_version 3, then seq and MAVLink 2.
        assert_eq!(
            fields[..8],
            ["1", "191", "18", "8", "0", "0", "4", "3"],
            "{line}"
        );
        assert_eq!(fields[9], "1", "MAVLink 2: {line}");
        seqs.push(fields[8].parse::<u8>().expect("seq"));
    }
    assert_eq!(seqs[1], seqs[0].wrapping_add(1), "incrementing sequence");
    router.stop();
}
