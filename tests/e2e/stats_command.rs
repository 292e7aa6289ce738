//! `mavtables stats` as users run it: the real binary asking an HTTP endpoint over
//! 127.0.0.1, its exact output, its one-line errors and `--watch` without a terminal.

use crate::common;

use std::io::Read;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use common::eventually;
use common::http_fixture::{Answer, HttpFixture};
use common::net::{SECOND, attitude, heartbeat, udp_frames};
use common::router::{BIN, Guard, Scratch, free_udp_port};
use common::stats_router;
use std::net::UdpSocket;

/// Starts `mavtables stats --watch ARGS` (standard output a pipe, not a terminal):
/// its pid, its guard, and a thread that returns all it printed once it ends.
fn watch(args: &[&str]) -> (i32, Guard, std::thread::JoinHandle<String>) {
    let mut child = Command::new(BIN)
        .args(["stats", "--watch"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let mut out = child.stdout.take().expect("stdout");
    let pid = child.id() as i32;
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    (pid, Guard(Some(child)), reader)
}

/// Ctrl-C to our own child `pid`: SIGINT.
fn ctrl_c(pid: i32) -> nix::Result<()> {
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(pid),
        nix::sys::signal::Signal::SIGINT,
    )
}

/// Runs `mavtables stats ARGS` to its end (at most 20 s): status, stdout, stderr.
fn stats(args: &[&str]) -> (Option<i32>, String, String) {
    let mut child = Command::new(BIN)
        .arg("stats")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn mavtables stats");
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let mut guard = Guard(Some(child));
    let status = guard
        .wait(Duration::from_secs(20))
        .expect("mavtables stats did not end within 20 s");
    let mut e = String::new();
    let _ = err.read_to_string(&mut e);
    (status.code(), reader.join().expect("stdout"), e)
}

/// Statistics in the shape the router serves, with `n` in some counters.
fn fixture_stats(n: u64) -> String {
    serde_json::json!({
        "version": 1, "uptime_s": 61.9, "history_interval_s": 1,
        "links": [{
            "id": 1, "name": "127.0.0.1:40001", "interface": "udp 127.0.0.1:14550",
            "frames_in": n, "bytes_in": 17 * n, "frames_out": 2, "bytes_out": 34,
            "rate_in_fps": 4.0, "rate_out_fps": 0.5, "rate_in_bps": 544.0, "rate_out_bps": 68.0,
            "drops": {"filter_rejected": 2, "no_route": 0, "queue_full": 1, "send_error": 0,
                      "bad_crc": 0, "unknown_id": 0, "bad_signature": 0, "replayed": 0,
                      "out_of_window": 0, "unsigned": 0},
            "queue_bytes": 0, "queue_high_water": 51, "addresses": ["1.1"],
            "history_in_fps": [4.0, 4.0], "history_out_fps": [0.0, 0.5]
        }],
        "interfaces": [],
        "chains": [{"name": "default", "rules": [
            {"text": "reject if HEARTBEAT from 2.0/8", "packets": 2, "bytes": 34, "decided": 2},
            {"text": "accept", "packets": n, "bytes": 17 * n, "decided": n}
        ]}],
        "default_action": {"action": "reject", "packets": 0, "bytes": 0},
        "sources": [], "sequence_gaps": [], "recording": null
    })
    .to_string()
}

fn json(body: String) -> Answer {
    Answer::Http(200, "application/json", body.into_bytes())
}

/// Sends `frame` from `from` to the router; every frame of the scenario is processed
/// before the next is sent (the test waits for what it causes).
fn send(from: &UdpSocket, frame: &[u8]) {
    from.send(frame).expect("send to the router");
}

#[test]
fn counts_of_a_scripted_scenario_exactly() {
    let scratch = Scratch::new("stats-cmd");
    let (air, ground) = (free_udp_port(), free_udp_port());
    let config = format!(
        "udp {{ address 127.0.0.1; port {air}; }}\n\
         udp {{ address 127.0.0.1; port {ground}; }}\n\
         chain default {{\n    reject if HEARTBEAT from 2.0/8;\n    accept;\n}}\n\
         default_action reject;\n"
    );
    let (router, port) = stats_router::start(&scratch, &config);
    let peer = |to: u16| {
        let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
        s.connect(("127.0.0.1", to)).expect("connect");
        s
    };
    let (gcs, vehicle, intruder) = (peer(ground), peer(air), peer(air));
    let name = |s: &UdpSocket| s.local_addr().expect("addr").to_string();

    // The ground station speaks first: the router learns it (nowhere to send yet).
    send(&gcs, &heartbeat(255));
    eventually("the ground station's link", Duration::from_secs(10), || {
        stats_router::stats(port)["links"]
            .as_array()
            .is_some_and(|l| l.len() == 1)
    });
    // The vehicle: a HEARTBEAT and 10 ATTITUDE, each forwarded to the ground station.
    send(&vehicle, &heartbeat(1));
    assert_eq!(udp_frames(&gcs, 1, 5 * SECOND).len(), 1);
    for n in 0..10 {
        send(&vehicle, &attitude(1, n));
        assert_eq!(udp_frames(&gcs, 1, 5 * SECOND).len(), 1, "ATTITUDE {n}");
    }
    // An intruder from system 2: its 3 HEARTBEATs are rejected by the first rule.
    for _ in 0..3 {
        send(&intruder, &heartbeat(2));
    }
    // One more ATTITUDE from the vehicle, after the intruder's frames on the same socket:
    // once it arrives, they were handled.
    send(&vehicle, &attitude(1, 10));
    assert_eq!(udp_frames(&gcs, 1, 5 * SECOND).len(), 1, "ATTITUDE 10");
    stats_router::wait_quiet(port);
    // Then until every link has been silent for 5 samples, so its state is certain.
    eventually("every link silent", Duration::from_secs(15), || {
        stats_router::stats(port)["links"]
            .as_array()
            .is_some_and(|links| {
                links.iter().all(|l| {
                    let h = l["history_in_fps"].as_array().cloned().unwrap_or_default();
                    h.len() >= 5 && h[h.len() - 5..].iter().all(|v| v.as_f64() == Some(0.0))
                })
            })
    });

    // Rule 0 decided the intruder's 3 HEARTBEATs for 2 destinations each (6 × 21 bytes);
    // rule 1 the vehicle's HEARTBEAT and 11 ATTITUDE for the ground station and the last
    // ATTITUDE for the intruder too (21 + 12 × 40 bytes). Rejections count on the link
    // they were kept from; the ground station's first HEARTBEAT had nowhere to go. One
    // frame at a time was queued (40 bytes and the queue's 32 of bookkeeping).
    let config_path = router.config.display().to_string();
    let (code, out, err) = stats(&["--config", &config_path]);
    assert_eq!(code, Some(0), "stderr: {err}");
    let (g, v, x) = (name(&gcs), name(&vehicle), name(&intruder));
    let uptime = out
        .lines()
        .next()
        .and_then(|l| l.rsplit_once(", up "))
        .map(|(_, u)| u.to_string())
        .expect("first line");
    let expected = format!(
        "\
mavtables at http://127.0.0.1:{port}/stats, up {uptime}

chain default
  packets  bytes  decided  rule
        6    126        6  reject if HEARTBEAT from 2.0/8
       13    501       13  accept

default_action reject: 0 packets, 0 bytes

link             state   interface            frames in  frames out  in/s  out/s  in bit/s  out bit/s  drops  queue  high-water  addresses
{g}  drops   udp 127.0.0.1:{ground}          1          12   0.0    0.0         0          0      4      0          72  255.1
{v}  drops   udp 127.0.0.1:{air}         12           0   0.0    0.0         0          0      3      0           0  1.1
{x}  silent  udp 127.0.0.1:{air}          3           1   0.0    0.0         0          0      0      0          72  2.1
  drops of {g}: filter rejected 3, no route 1
  drops of {v}: filter rejected 3
"
    );
    assert_eq!(out, expected, "{out}");
    assert_eq!(err, "");
    router.stop();
}

#[test]
fn errors_are_one_line_and_exit_1() {
    // Nothing listens on a port that was just free.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("free port")
        .port();
    let (code, out, err) = stats(&["--url", &format!("http://127.0.0.1:{port}")]);
    assert_eq!(code, Some(1));
    assert_eq!(out, "");
    assert!(
        err.starts_with(&format!("error: cannot connect to 127.0.0.1:{port}: ")),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");

    let cases: [(Answer, &str); 4] = [
        (
            Answer::Http(404, "text/plain", b"not here".to_vec()),
            "(GET /stats?history=5): answered 404 Not OK",
        ),
        (Answer::Close, "closed the connection without answering"),
        (
            Answer::Raw(b"SSH-2.0-OpenSSH_9.2\r\n\r\n".to_vec()),
            "not an HTTP answer",
        ),
        (
            json("{\"links\": [".into()),
            "/stats is not statistics JSON: ",
        ),
    ];
    for (answer, want) in cases {
        let answer = std::sync::Mutex::new(Some(answer));
        let server = HttpFixture::start(move |_, _| {
            answer
                .lock()
                .ok()
                .and_then(|mut a| a.take())
                .unwrap_or(Answer::Close)
        });
        let (code, out, err) = stats(&["--url", &server.url()]);
        assert_eq!(code, Some(1), "{want}: {err}");
        assert_eq!(out, "");
        assert!(
            err.starts_with("error: ") && err.contains(want),
            "wanted {want:?} in {err:?}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
    }

    let scratch = Scratch::new("stats-cmd-errors");
    let no_block = scratch.path("none.conf");
    std::fs::write(&no_block, "udp { port 14550; }\n").expect("write");
    let any_port = scratch.path("any.conf");
    std::fs::write(&any_port, "stats { port 0; }\n").expect("write");
    let broken = scratch.path("broken.conf");
    std::fs::write(&broken, "stats { port 9100 }\n").expect("write");
    for (args, want) in [
        (&["--config", &no_block][..], "has no stats block"),
        (&["--config", &any_port], "says port 0 (any free port)"),
        (&["--config", &broken], "is not a valid configuration"),
        (&["--url", "ftp://x:1"], "only http:// is understood"),
        (
            &["--url", "http://a:1", "--config", "b"],
            "use either --config or --url",
        ),
        (&["--config", "/nonexistent/m.conf"], "does not exist"),
        (&["extra"], "unexpected argument 'extra'"),
    ] {
        let (code, _, err) = stats(args);
        assert_eq!(code, Some(1), "{args:?}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn watch_redraws_every_second_and_ends_cleanly_on_ctrl_c() {
    let served = Arc::new(AtomicU64::new(0));
    let counter = Arc::clone(&served);
    let server = HttpFixture::start(move |_, n| {
        counter.store(n as u64, Ordering::SeqCst);
        // The second request finds the router gone; the others see it counting up.
        if n == 2 {
            Answer::Close
        } else {
            json(fixture_stats(100 * n as u64))
        }
    });
    let (pid, mut guard, reader) = watch(&["--url", &server.url()]);
    let started = Instant::now();
    while served.load(Ordering::SeqCst) < 3 {
        assert!(
            started.elapsed() < Duration::from_secs(15),
            "three pictures not asked for within 15 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // Three requests take two full periods: one per second, not faster.
    assert!(started.elapsed() >= Duration::from_millis(1900));
    assert_eq!(ctrl_c(pid), Ok(()));
    let status = guard
        .wait(Duration::from_secs(5))
        .expect("--watch did not end within 5 s of Ctrl-C");
    assert_eq!(status.code(), Some(0), "Ctrl-C ends --watch with status 0");
    let text = reader.join().expect("stdout");
    // Not a terminal: plain text, no escape codes; pictures one after the other.
    assert!(!text.contains('\x1b'), "{text:?}");
    assert!(
        text.contains("      100   1700      100  accept\n"),
        "{text}"
    );
    assert!(text.contains("router not answering: "), "{text}");
    assert!(
        text.contains("      300   5100      300  accept\n"),
        "{text}"
    );
    let first_100 = text.find("100  accept").expect("first");
    let gone = text.find("router not answering").expect("gone");
    let third = text.find("300  accept").expect("third");
    assert!(first_100 < gone && gone < third, "{text}");
}

#[test]
fn watch_on_a_terminal_redraws_in_place_and_gives_the_terminal_back() {
    let server = HttpFixture::start(|_, n| json(fixture_stats(100 * n as u64)));
    // No termios and no window size given, as openpty(3) with null pointers.
    let pty = nix::pty::openpty(None, None).expect("openpty");
    let (master, slave) = (std::fs::File::from(pty.master), pty.slave);
    let child = Command::new(BIN)
        .args(["stats", "--watch", "--url", &server.url()])
        .stdin(Stdio::null())
        .stdout(Stdio::from(slave))
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let pid = child.id() as i32;
    let mut guard = Guard(Some(child));
    // The terminal's output, read until the child's end closes the last slave descriptor.
    let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
    std::thread::spawn(move || {
        let mut master = master;
        let mut buf = [0u8; 4096];
        while let Ok(n) = master.read(&mut buf) {
            if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                break;
            }
        }
    });
    let mut screen = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(15);
    while !String::from_utf8_lossy(&screen).contains("      200   3400      200  accept") {
        assert!(Instant::now() < deadline, "no second picture: {screen:?}");
        if let Ok(bytes) = rx.recv_timeout(Duration::from_millis(100)) {
            screen.extend(bytes);
        }
    }
    assert_eq!(ctrl_c(pid), Ok(()));
    let status = guard
        .wait(Duration::from_secs(5))
        .expect("--watch did not end within 5 s of Ctrl-C");
    assert_eq!(status.code(), Some(0));
    while let Ok(bytes) = rx.recv_timeout(Duration::from_millis(500)) {
        screen.extend(bytes);
    }
    let text = String::from_utf8_lossy(&screen);
    // The alternate screen and a hidden cursor while it runs; each picture drawn from
    // the top-left corner; on Ctrl-C the cursor and the normal screen come back.
    assert!(text.starts_with("\x1b[?1049h\x1b[?25l\x1b[H"), "{text:?}");
    assert!(text.matches("\x1b[H").count() >= 2, "{text:?}");
    assert!(text.ends_with("\x1b[?25h\x1b[?1049l"), "{text:?}");
}

/// Rows of the links table in `out`: (name, state).
fn link_rows(out: &str) -> Vec<(String, String)> {
    out.lines()
        .skip_while(|l| !l.starts_with("link "))
        .skip(1)
        .take_while(|l| !l.is_empty() && !l.starts_with(' ') && !l.starts_with('('))
        .map(|l| {
            let mut w = l.split_whitespace();
            (
                w.next().unwrap_or_default().to_string(),
                w.next().unwrap_or_default().to_string(),
            )
        })
        .collect()
}

#[test]
fn a_fleet_of_a_thousand_links_top_and_filter() {
    use common::fleet;
    let body = fleet::stats(1000, 1, 10).to_string();
    let server = HttpFixture::start(move |_, _| json(body.clone()));
    let url = server.url();
    let expect = |order: &[usize]| -> Vec<(String, String)> {
        order
            .iter()
            .map(|&i| (fleet::name(i), fleet::state(i).to_string()))
            .collect()
    };

    // Every link, troubled first (each with its state), then the busiest.
    let (code, out, err) = stats(&["--url", &url]);
    assert_eq!(code, Some(0), "{err}");
    let all = fleet::order(1000, |_| true);
    assert_eq!(link_rows(&out), expect(&all));
    let troubled = (0..1000).filter(|&i| fleet::troubled(i)).count();
    assert!((20..100).contains(&troubled), "{troubled}");
    assert!(!out.contains("hidden"), "nothing is hidden without --top");

    // --top 5: the five first of that order and how many are hidden.
    let (code, out, err) = stats(&["--url", &url, "--top", "5"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(link_rows(&out), expect(&all[..5]), "{out}");
    assert!(link_rows(&out).iter().all(|(_, s)| s != "ok"), "{out}");
    assert!(
        out.contains("(links: 5 of 1000 shown; 995 more hidden by --top)\n"),
        "{out}"
    );

    // --filter: the links whose name contains the text (10.0.3.x: links 768 to 999).
    let (code, out, err) = stats(&["--url", &url, "--filter", "10.0.3.", "--top", "3"]);
    assert_eq!(code, Some(0), "{err}");
    let third = fleet::order(1000, |i| fleet::name(i).contains("10.0.3."));
    assert_eq!(third.len(), 232);
    assert_eq!(link_rows(&out), expect(&third[..3]), "{out}");
    assert!(
        out.contains(
            "(links: 3 of 1000 shown; 229 more hidden by --top, 768 not matching --filter)\n"
        ),
        "{out}"
    );
    // A source's address finds its link.
    let (code, out, err) = stats(&["--url", &url, "--filter", &fleet::source(5)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        link_rows(&out).contains(&(fleet::name(5), "gaps".to_string())),
        "{out}"
    );
    // A bad --top is one line.
    let (code, _, err) = stats(&["--url", &url, "--top", "many"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("--top 'many': expected a number"), "{err}");
    // --help says both.
    let (code, out, _) = stats(&["--help"]);
    assert_eq!(code, Some(0));
    assert!(
        out.contains("--top N") && out.contains("--filter TEXT"),
        "{out}"
    );

    // --watch with both: every picture has the same three rows and says what it hid.
    let before = server.requests.load(Ordering::SeqCst);
    let (pid, mut guard, reader) = watch(&["--url", &url, "--top", "3", "--filter", "10.0.3."]);
    let started = Instant::now();
    // Two pictures asked for (a picture begun is finished before Ctrl-C ends the loop).
    while server.requests.load(Ordering::SeqCst) < before + 2 {
        assert!(
            started.elapsed() < Duration::from_secs(15),
            "no 2nd picture"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(ctrl_c(pid), Ok(()));
    let status = guard.wait(Duration::from_secs(5)).expect("--watch ends");
    assert_eq!(status.code(), Some(0));
    let text = reader.join().expect("stdout");
    let pictures: Vec<&str> = text.split("mavtables at ").skip(1).collect();
    assert!(pictures.len() >= 2, "{text}");
    for p in pictures {
        assert_eq!(link_rows(p), expect(&third[..3]), "{p}");
        assert!(p.contains("229 more hidden by --top"), "{p}");
    }
}
