//! Every frame mavtables forwards leaves exactly as it arrived: MAVLink 1, 2, truncated
//! 2, signed, with extension fields, a message of a `dialect` file and an unknown id under
//! `unknown_messages accept;` — through the real router binary over UDP on 127.0.0.1,
//! read back with pymavlink as the independent parser.

use crate::common;

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use common::router::{Router, Scratch, free_udp_port};
use mavtables::config;
use mavtables::wire::crc::frame_checksum;

/// A v2 frame from `source`, checksummed with `crc_extra`; `signed` adds a signature
/// block (not checked: the router has no key and trusts its wire).
fn v2(id: u32, seq: u8, source: (u8, u8), payload: &[u8], crc_extra: u8, signed: bool) -> Vec<u8> {
    let flags = u8::from(signed);
    let mut f = vec![0xFD, payload.len() as u8, flags, 0, seq, source.0, source.1];
    f.extend_from_slice(&id.to_le_bytes()[..3]);
    f.extend_from_slice(payload);
    let crc = frame_checksum(&f[1..], crc_extra);
    f.extend_from_slice(&crc.to_le_bytes());
    if signed {
        f.extend_from_slice(&[7, 1, 2, 3, 4, 5, 6, 0xA, 0xB, 0xC, 0xD, 0xE, 0xF]);
    }
    f
}

fn v1(id: u8, seq: u8, source: (u8, u8), payload: &[u8], crc_extra: u8) -> Vec<u8> {
    let mut f = vec![0xFE, payload.len() as u8, seq, source.0, source.1, id];
    f.extend_from_slice(payload);
    let crc = frame_checksum(&f[1..], crc_extra);
    f.extend_from_slice(&crc.to_le_bytes());
    f
}

#[test]
fn forwarded_frames_leave_byte_for_byte_as_they_arrived() {
    let scratch = Scratch::new("exact");
    let dialects = common::data("dialects");
    for f in ["payload.xml", "common.xml", "standard.xml", "minimal.xml"] {
        std::fs::copy(dialects.join(f), scratch.dir.join(f)).expect("copy dialect");
    }
    let port = free_udp_port();
    let conf = format!(
        "dialect payload.xml;\nunknown_messages accept;\nudp {{ port {port}; address 127.0.0.1; }}\ndefault_action accept;\n"
    );
    let loaded = config::load_in(&conf, &scratch.dir).expect("config loads");
    let status = loaded
        .config
        .dialect
        .by_name("MY_PAYLOAD_STATUS")
        .expect("loaded");
    let mut router = Router::start(&scratch, &conf, 1);
    let to_router = format!("127.0.0.1:{port}");

    // The receiver makes itself known (system 255) and waits to be a link.
    let receiver = UdpSocket::bind("127.0.0.1:0").expect("bind");
    receiver
        .set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    let hello = v2(0, 0, (255, 190), &[0, 0, 0, 0, 6, 8, 0, 0, 3], 50, false);
    receiver.send_to(&hello, &to_router).expect("send");
    router.wait_for("new component 255.190");

    let mut custom = vec![0u8; 47];
    custom[18] = 255; // target_system: the receiver
    custom[19] = 190; // target_component
    custom[38] = 9; // an extension field
    let mut sys_status = vec![0u8; 43];
    sys_status[0] = 1;
    sys_status[40] = 2; // an extension field
    let frames = vec![
        v1(0, 1, (1, 1), &[0, 0, 0, 0, 2, 3, 0x51, 4, 3], 50),
        v2(0, 2, (1, 1), &[0, 0, 0, 0, 2, 3, 0x51, 4, 3], 50, false),
        v2(1, 3, (1, 1), &sys_status[..1], 124, false), // truncated: trailing zeros cut
        v2(1, 4, (1, 1), &sys_status, 124, false),      // with extension fields
        v2(0, 5, (1, 1), &[0, 0, 0, 0, 2, 3, 0x51, 4, 3], 50, true),
        v2(60_123, 6, (1, 1), &custom, status.crc_extra, false),
        v2(60_123, 7, (1, 1), &custom[..20], status.crc_extra, false),
        v2(60_999, 8, (1, 1), &[1, 2, 3, 4, 5, 0], 0x11, false),
    ];
    let sender = UdpSocket::bind("127.0.0.1:0").expect("bind");
    for f in &frames {
        sender.send_to(f, &to_router).expect("send");
    }
    let mut got: Vec<Vec<u8>> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut buf = [0u8; 2048];
    while got.len() < frames.len() && Instant::now() < deadline {
        if let Ok((n, _)) = receiver.recv_from(&mut buf) {
            got.push(buf[..n].to_vec());
        }
    }
    let hex = |v: &[Vec<u8>]| v.iter().map(|f| common::hex(f)).collect::<Vec<_>>();
    assert_eq!(hex(&got), hex(&frames), "forwarded byte for byte, in order");

    // pymavlink reads what left: the same messages and lengths (the signature kept); it
    // checks the checksums of what its dialect knows (a bad one would be BAD_DATA) and
    // frames the rest by their length.
    let lines: String = got.iter().map(|f| common::hex(f) + "\n").collect();
    let parsed = common::run_py("frames_parse.py", &[], &lines);
    let parsed: Vec<&str> = parsed.lines().collect();
    assert_eq!(
        parsed,
        [
            "HEARTBEAT 17",
            "HEARTBEAT 21",
            "SYS_STATUS 13",
            "SYS_STATUS 55",
            "HEARTBEAT 34",
            "UNKNOWN_60123 59",
            "UNKNOWN_60123 32",
            "UNKNOWN_60999 18",
        ]
    );
    let stopped = router.stop();
    let counters = stopped.stderr.join("\n");
    assert!(counters.contains("1 unknown ids accepted"), "{counters}");
}
