//! A browser ground station over the `websocket { }` interface: headless Chromium opens
//! a small page (served by a fixture server on 127.0.0.1) whose script connects to the
//! router, decodes the vehicle's HEARTBEAT and ATTITUDE from binary messages, and sends
//! a COMMAND_LONG it encodes itself (checksum and all), which the router routes to the
//! vehicle, a UDP socket of our own. The block names the page's origin (`origin`), so
//! the browser's `Origin` header is checked too. The browser runs in real time; the outcome is seen
//! on the vehicle's socket: the command, carrying in its parameters what the page
//! decoded.

use crate::common;

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use common::browser;
use common::http_fixture::{Answer, HttpFixture};
use common::net::{ACCEPT_ALL, free_tcp_port, with_payload};
use common::router::{Router, Scratch, free_udp_port};
use mavtables::wire::{Frame, Parser};

/// The page: `__PORT__` is the router's WebSocket port.
const PAGE: &str = r#"<!doctype html>
<meta charset="utf-8"><title>mavtables over WebSocket</title>
<pre id="log"></pre>
<script>
"use strict";
const say = (t) => { document.getElementById("log").textContent += t + "\n"; };
// CRC-16/MCRF4XX, as MAVLink computes it.
function crc16(bytes, extra) {
  let crc = 0xffff;
  const add = (b) => {
    let t = (b ^ crc) & 0xff;
    t = (t ^ (t << 4)) & 0xff;
    crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xffff;
  };
  bytes.forEach(add);
  add(extra);
  return crc;
}
// A MAVLink 2 frame (trailing zeros of the payload cut, as MAVLink 2 does).
function encode(seq, sys, comp, id, crcExtra, payload) {
  let len = payload.length;
  while (len > 1 && payload[len - 1] === 0) len--;
  const out = new Uint8Array(12 + len);
  out.set([0xfd, len, 0, 0, seq, sys, comp, id & 0xff, (id >> 8) & 0xff, id >> 16]);
  out.set(payload.subarray(0, len), 10);
  const crc = crc16(out.subarray(1, 10 + len), crcExtra);
  out[10 + len] = crc & 0xff;
  out[11 + len] = crc >> 8;
  return out;
}
let pending = new Uint8Array(0);
let heartbeats = 0, attitude = null, sent = false;
const ws = new WebSocket("ws://127.0.0.1:__PORT__/");
ws.binaryType = "arraybuffer";
ws.onopen = () => say("open");
ws.onerror = () => say("error");
ws.onmessage = (event) => {
  if (!(event.data instanceof ArrayBuffer)) return;
  const joined = new Uint8Array(pending.length + event.data.byteLength);
  joined.set(pending);
  joined.set(new Uint8Array(event.data), pending.length);
  let at = 0;
  while (true) {
    while (at < joined.length && joined[at] !== 0xfd) at++;
    if (joined.length - at < 12) break;
    const len = joined[at + 1], signed = joined[at + 2] & 1;
    const size = 12 + len + (signed ? 13 : 0);
    if (joined.length - at < size) break;
    const sys = joined[at + 5];
    const id = joined[at + 7] | (joined[at + 8] << 8) | (joined[at + 9] << 16);
    const body = new Uint8Array(40);
    body.set(joined.subarray(at + 10, at + 10 + len));
    const view = new DataView(body.buffer);
    if (id === 0 && body[4] === 2 && body[8] === 3) heartbeats++;
    if (id === 30) attitude = { sys, roll: view.getFloat32(4, true), yaw: view.getFloat32(12, true) };
    at += size;
  }
  pending = joined.slice(at);
  if (!sent && heartbeats > 0 && attitude) {
    sent = true;
    const p = new Uint8Array(33);
    const v = new DataView(p.buffer);
    v.setFloat32(0, 1, true);              // param1: arm
    v.setFloat32(4, attitude.roll, true);  // param2, param3: what the page decoded
    v.setFloat32(8, attitude.yaw, true);
    v.setFloat32(12, heartbeats, true);    // param4: heartbeats seen
    v.setUint16(28, 400, true);            // MAV_CMD_COMPONENT_ARM_DISARM
    p[30] = attitude.sys;                  // target system, component
    p[31] = 1;
    ws.send(encode(0, 255, 190, 76, 152, p));
    say("sent COMMAND_LONG");
  }
};
</script>
"#;

/// A HEARTBEAT of a quadrotor (type 2, ArduPilot, MAVLink version 3) from `sys`.1.
fn heartbeat(sys: u8, seq: u8) -> Vec<u8> {
    with_payload(0, sys, seq, &[0, 0, 0, 0, 2, 3, 0x51, 4, 3])
}

/// An ATTITUDE from `sys`.1 with `roll` and `yaw` (radians).
fn attitude(sys: u8, seq: u8, roll: f32, yaw: f32) -> Vec<u8> {
    let mut p = Vec::with_capacity(28);
    p.extend_from_slice(&1000u32.to_le_bytes());
    for v in [roll, 0.125, yaw, 0.0, 0.0, 0.0] {
        p.extend_from_slice(&v.to_le_bytes());
    }
    with_payload(30, sys, seq, &p)
}

fn f32_at(payload: &[u8], at: usize) -> f32 {
    let mut b = [0u8; 4];
    b.copy_from_slice(&payload[at..at + 4]);
    f32::from_le_bytes(b)
}

/// The page in Chromium gets the vehicle's HEARTBEAT and ATTITUDE over the router's
/// WebSocket and its COMMAND_LONG reaches the vehicle, with what it decoded.
#[test]
fn a_browser_page_commands_a_vehicle_over_websocket() {
    let s = Scratch::new("ws-browser");
    let (udp, port) = (free_udp_port(), free_tcp_port());
    let page = PAGE.replace("__PORT__", &port.to_string());
    let site = HttpFixture::start(move |path, _| match path {
        "/" => Answer::Http(200, "text/html; charset=utf-8", page.clone().into_bytes()),
        _ => Answer::Http(404, "text/plain", b"not found".to_vec()),
    });
    // Only the test's site may connect: the browser's Origin header must match it.
    let config = format!(
        "udp {{ port {udp}; address 127.0.0.1; }}\n\
         websocket {{ port {port}; address 127.0.0.1; origin {}; }}\n{ACCEPT_ALL}",
        site.url()
    );
    let mut router = Router::start(&s, &config, 1);
    let vehicle = UdpSocket::bind("127.0.0.1:0").expect("bind");
    vehicle
        .connect(format!("127.0.0.1:{udp}"))
        .expect("connect");
    vehicle
        .set_read_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    vehicle.send(&heartbeat(1, 0)).expect("send");
    router.wait_for("new component 1.1 on 127.0.0.1:");
    let (roll, yaw) = (0.25f32, -1.5f32);
    let _browser = browser::open(&s, &format!("{}/", site.url()));
    // The vehicle's telemetry, ten times a second, until the command comes (at most 60 s:
    // a cold browser start on a loaded machine takes seconds).
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut parser = Parser::new();
    let mut command = None;
    let mut seq = 1u8;
    let mut buf = [0u8; 512];
    while command.is_none() && Instant::now() < deadline {
        vehicle.send(&heartbeat(1, seq)).expect("send");
        vehicle.send(&attitude(1, seq, roll, yaw)).expect("send");
        seq = seq.wrapping_add(1);
        if let Ok(n) = vehicle.recv(&mut buf) {
            parser.feed(&buf[..n], |f| {
                if f.message_id() == 76 {
                    command = Some(f.as_bytes().to_vec());
                }
            });
        }
    }
    let command = command.expect("no COMMAND_LONG from the page within 60 s");
    router.wait_for("new component 255.190 on ws:127.0.0.1:");
    // Our own parser checked its checksum (with COMMAND_LONG's CRC extra); now its fields.
    let f = Frame::parse_exact(&command).expect("a valid frame");
    assert_eq!((f.system(), f.component()), (255, 190));
    let p = f.payload_padded();
    assert_eq!(u16::from_le_bytes([p[28], p[29]]), 400, "command");
    assert_eq!((p[30], p[31]), (1, 1), "target");
    assert_eq!(f32_at(&p, 0), 1.0, "param1");
    assert_eq!(
        (f32_at(&p, 4), f32_at(&p, 8)),
        (roll, yaw),
        "the decoded ATTITUDE"
    );
    assert!(f32_at(&p, 12) >= 1.0, "heartbeats seen: {}", f32_at(&p, 12));
    router.stop();
}
