//! End-to-end tests of the Zenoh interface on a real Zenoh network on loopback: a Zenoh
//! router from the PyPI `eclipse-zenoh` package (`tests/py/zenoh_router.py`: Zenoh's own
//! Rust implementation in a prebuilt wheel, whose sessions run in router mode; `zenohd`
//! from crates.io would add a long build to every fresh test run), mavtables
//! routers as its clients — three edge routers, each with a simulated vehicle behind a
//! UDP link, and a ground-station router with a UDP ground station — and mavtables
//! routers as Zenoh peers without a Zenoh router. An independent subscriber
//! (`tests/py/zenoh_listen.py`) decodes every publication with pymavlink, and MAVProxy
//! downloads the parameters of a vehicle behind an edge. Every wait is
//! bounded and ends on an event.

use crate::common;

use std::net::UdpSocket;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use common::mavproxy::{VehicleLink, ground_station_session};
use common::net::{ACCEPT_ALL, Counters, SECOND, free_listen_port, heartbeat, numbered};
use common::process::Proc;
use common::router::{Router, Scratch, free_udp_port};
use mavtables::wire::encode::{Header, encode_v2};
use mavtables::wire::{Frame, Parser};

const PREFIX: &str = "fleet/e2e";
/// The label of the Zenoh interface and the name of its link.
const LINK: &str = "zenoh fleet/e2e";
const COMMAND_LONG: u32 = 76;
const ATTITUDE: u32 = 30;

fn script(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/py")
        .join(name)
        .display()
        .to_string()
}

/// A Zenoh router (eclipse-zenoh, router mode) listening at `endpoint`.
fn zenoh_router(endpoint: &str) -> Proc {
    let mut cmd = Command::new(common::python());
    cmd.arg(script("zenoh_router.py")).arg(endpoint);
    let mut router = Proc::spawn(cmd, "zenoh router");
    router.wait_for("ready", 30 * SECOND);
    router
}

/// An eclipse-zenoh client of the router at `endpoint`, subscribed to `keys`, printing
/// what pymavlink decodes of each sample.
fn zenoh_listener(endpoint: &str, keys: &str) -> Proc {
    let mut cmd = Command::new(common::python());
    cmd.arg(script("zenoh_listen.py")).arg(endpoint).arg(keys);
    let mut listener = Proc::spawn(cmd, "zenoh listener");
    listener.wait_for("ready", 30 * SECOND);
    listener
}

/// COMMAND_LONG from the ground station (255.190) to `target`.1.
fn command_long(target: u8) -> Vec<u8> {
    let mut payload = [0u8; 33];
    payload[..4].copy_from_slice(&1.0f32.to_le_bytes());
    payload[28] = 176; // MAV_CMD_DO_SET_MODE
    payload[30] = target;
    payload[31] = 1;
    let header = Header {
        seq: 0,
        system: 255,
        component: 190,
    };
    let mut frame = Vec::new();
    encode_v2(header, COMMAND_LONG, &payload, None, &mut frame).expect("encode");
    frame
}

/// A mavtables router with a UDP server for its one local peer (a vehicle or a ground
/// station) and a `zenoh` block, and that peer's socket.
struct Site {
    router: Router,
    port: u16,
    peer: UdpSocket,
    parser: Parser,
    /// Every frame the peer received.
    got: Vec<Vec<u8>>,
    _scratch: Scratch,
}

impl Site {
    fn start(tag: &str, zenoh: &str) -> Site {
        let scratch = Scratch::new(tag);
        let port = free_udp_port();
        let config = format!("udp {{ port {port}; address 127.0.0.1; }}\n{zenoh}\n{ACCEPT_ALL}");
        let router = Router::start(&scratch, &config, 1);
        let peer = UdpSocket::bind("127.0.0.1:0").expect("bind");
        peer.set_nonblocking(true).expect("nonblocking");
        Site {
            router,
            port,
            peer,
            parser: Parser::new(),
            got: Vec::new(),
            _scratch: scratch,
        }
    }

    fn send(&self, frame: &[u8]) {
        self.peer
            .send_to(frame, ("127.0.0.1", self.port))
            .expect("send");
    }

    /// Takes what the peer received so far into `got`.
    fn take(&mut self) {
        let mut buf = [0u8; 4096];
        while let Ok(n) = self.peer.recv(&mut buf) {
            let got = &mut self.got;
            self.parser
                .feed(&buf[..n], |f| got.push(f.as_bytes().to_vec()));
        }
    }

    /// True once the peer received a frame that `wanted` accepts.
    fn has(&mut self, wanted: impl Fn(&Frame<'_>) -> bool) -> bool {
        self.take();
        self.got
            .iter()
            .any(|f| Frame::parse_exact(f).is_ok_and(|f| wanted(&f)))
    }

    /// Frames of message `id` from system `sys` the peer received.
    fn count(&mut self, id: u32, sys: u8) -> usize {
        self.take();
        (self.got.iter())
            .filter(|f| {
                Frame::parse_exact(f).is_ok_and(|f| f.message_id() == id && f.system() == sys)
            })
            .count()
    }

    /// The frames received on the Zenoh link so far.
    fn zenoh_frames_in(&mut self) -> u64 {
        let counters = common::net::counters(&mut self.router);
        counters
            .link(LINK)
            .unwrap_or_else(|| panic!("no link {LINK} in {}", counters.text))
            .frames_in
    }

    /// The frames received on the Zenoh link, from the counters at exit.
    fn stop(self) -> u64 {
        let stopped = self.router.stop();
        let counters = Counters::at_exit(&stopped.stderr);
        counters
            .link(LINK)
            .unwrap_or_else(|| panic!("no link {LINK} in {}", counters.text))
            .frames_in
    }
}

/// Runs `step` (which sends what it sends each round, then says whether what was
/// awaited arrived) every 50 ms until it says so; panics after `timeout`, naming `what`.
fn until(what: &str, timeout: Duration, mut step: impl FnMut() -> bool) {
    let deadline = Instant::now() + timeout;
    while !step() {
        assert!(Instant::now() < deadline, "{what}: not within {timeout:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Sends the vehicle's frames numbered from `base` on (and the ground station's
/// heartbeat) until one of them reaches the ground station: nothing sent before (still
/// in a socket) counts. Panics after 30 s, with what both routers said and counted.
fn heard(gs: &mut Site, edge: &mut Site, base: u32) {
    let mut n = base;
    let deadline = Instant::now() + 30 * SECOND;
    loop {
        gs.send(&heartbeat(255));
        edge.send(&numbered(1, n));
        n += 1;
        if gs.has(|f| is(ATTITUDE, 1)(f) && common::net::number_of(f.as_bytes()) >= base) {
            return;
        }
        if Instant::now() >= deadline {
            let said = (gs.router.err.drain(), edge.router.err.drain());
            let counted = (
                common::net::counters(&mut gs.router).text,
                common::net::counters(&mut edge.router).text,
            );
            panic!(
                "the vehicle at the ground station: not within 30 s\n\
                 ground station said {:#?}\ncounted {}\nedge said {:#?}\ncounted {}",
                said.0, counted.0, said.1, counted.1
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The `zenoh` block of a ground station's peer listening at `endpoint`, receiving all.
fn listening_peer(endpoint: &str, prefix: &str) -> String {
    format!("zenoh {{ mode peer; listen {endpoint}; prefix {prefix}; receive all; }}")
}

/// The `zenoh` block of an edge's peer connecting to `endpoint`.
fn connecting_peer(endpoint: &str, prefix: &str) -> String {
    format!("zenoh {{ mode peer; connect {endpoint}; prefix {prefix}; }}")
}

fn is(id: u32, sys: u8) -> impl Fn(&Frame<'_>) -> bool {
    move |f| f.message_id() == id && f.system() == sys
}

/// A marker: ATTITUDE carrying a counter no other frame of these tests carries.
const MARKER: u32 = 0xC0FFEE;

fn is_marker(sys: u8, n: u32) -> impl Fn(&Frame<'_>) -> bool {
    move |f| {
        f.message_id() == ATTITUDE && f.system() == sys && common::net::number_of(f.as_bytes()) == n
    }
}

/// Every peer sends marker `n`, and every other peer receives it: Zenoh keeps each
/// publisher's order, so everything sent before has arrived everywhere by then.
fn exchange_markers(gs: &mut Site, edges: &mut [Site], n: u32) {
    for (i, site) in (1u8..).zip(edges.iter()) {
        site.send(&numbered(i, n));
    }
    gs.send(&numbered(255, n));
    until("every marker at every other peer", 10 * SECOND, || {
        let mut all = (1..=3).all(|i| gs.has(is_marker(i, n)));
        for (me, edge) in edges.iter_mut().enumerate() {
            for (j, sys) in [1u8, 2, 3, 255].into_iter().enumerate() {
                all &= j == me || edge.has(is_marker(sys, n));
            }
        }
        all
    });
}

/// Three edge routers with a vehicle each (systems 1, 2, 3) and a ground-station router
/// (`receive all;`) with a ground station (255), all clients of one Zenoh router:
/// every vehicle's telemetry reaches the ground station; a COMMAND_LONG for vehicle 2
/// reaches vehicle 2 only; each edge router receives exactly the publications for its
/// vehicle and the broadcasts of the others (Zenoh filtered the rest at the publishing
/// side); and an independent eclipse-zenoh subscriber decodes every publication with
/// pymavlink, under the documented keys.
#[test]
fn a_fleet_through_a_zenoh_router() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let mut zenohd = zenoh_router(&endpoint);
    let mut listener = zenoh_listener(&endpoint, &format!("{PREFIX}/**"));
    let block = |receive: &str| {
        format!("zenoh {{ mode client; connect {endpoint}; prefix {PREFIX}; {receive} }}")
    };
    let mut gs = Site::start("zenoh-gs", &block("receive all;"));
    let mut edges: Vec<Site> = (1..=3)
        .map(|i| Site::start(&format!("zenoh-edge-{i}"), &block("")))
        .collect();

    // Every router is connected and subscribed: every peer hears every other.
    until("every heartbeat at every other peer", 30 * SECOND, || {
        gs.send(&heartbeat(255));
        for (i, edge) in (1u8..).zip(&edges) {
            edge.send(&heartbeat(i));
        }
        let mut all = (1..=3).all(|i| gs.has(is(0, i)));
        for (me, edge) in edges.iter_mut().enumerate() {
            for (j, sys) in [1u8, 2, 3, 255].into_iter().enumerate() {
                all &= j == me || edge.has(is(0, sys));
            }
        }
        all
    });
    // From a quiet point on, what each edge receives is counted against what the
    // independent subscriber saw published.
    exchange_markers(&mut gs, &mut edges, MARKER);
    let before: Vec<u64> = edges.iter_mut().map(Site::zenoh_frames_in).collect();
    let gs_before = gs.zenoh_frames_in();
    until("the first marker at the subscriber", 10 * SECOND, || {
        listener.out.drain();
        let key = format!("{PREFIX}/all/255/1/ATTITUDE");
        listener
            .out
            .seen
            .iter()
            .filter(|l| l.starts_with(&key))
            .count()
            == 1
    });
    let skip = listener.out.seen.len();

    // Telemetry from every vehicle, and a command for vehicle 2: it reaches vehicle 2;
    // the others see the markers sent after it, and never the command.
    for n in 0..10 {
        for (i, edge) in (1u8..).zip(&edges) {
            edge.send(&numbered(i, n));
        }
    }
    gs.send(&command_long(2));
    until("the command at vehicle 2", 10 * SECOND, || {
        edges[1].has(is(COMMAND_LONG, 255))
    });
    exchange_markers(&mut gs, &mut edges, MARKER + 1);
    for (i, edge) in (1u8..).zip(edges.iter_mut()) {
        let commands = edge.count(COMMAND_LONG, 255);
        assert_eq!(
            commands,
            usize::from(i == 2),
            "vehicle {i} got {commands} commands"
        );
        for from in (1u8..=3).filter(|&f| f != i) {
            assert!(
                edge.count(ATTITUDE, from) >= 12,
                "vehicle {i}: telemetry of {from}"
            );
        }
    }
    assert_eq!(
        (1..=3).map(|i| gs.count(ATTITUDE, i)).sum::<usize>(),
        3 * 12
    );
    until(
        "every marker at the eclipse-zenoh subscriber",
        10 * SECOND,
        || {
            listener.out.drain();
            let seen = &listener.out.seen[skip..];
            // Ten frames and a marker from each vehicle, a marker from the ground station.
            [(1u8, 11), (2, 11), (3, 11), (255, 1)]
                .iter()
                .all(|(sys, n)| {
                    let key = format!("{PREFIX}/all/{sys}/1/ATTITUDE");
                    seen.iter().filter(|l| l.starts_with(&key)).count() == *n
                })
        },
    );

    // What the independent subscriber saw: one MAVLink frame per sample, under the key
    // its contents say.
    let lines = listener.finish(5 * SECOND);
    let samples: Vec<Vec<&str>> = lines[skip..]
        .iter()
        .filter(|l| l.starts_with(PREFIX) || l.starts_with("bad"))
        .map(|l| l.split(' ').collect())
        .collect();
    assert!(samples.len() >= 30, "{lines:?}");
    for s in &samples {
        assert_eq!(s.len(), 5, "one decoded frame per sample: {s:?}");
        let chunks: Vec<&str> = s[0].split('/').collect();
        let [_, _, destination, system, component, name] = chunks[..] else {
            panic!("key {}", s[0]);
        };
        assert_eq!(name, s[1], "{s:?}");
        assert_eq!((system, component), (s[2], s[3]), "{s:?}");
        assert!(destination == "all" || destination == s[4], "{s:?}");
    }
    let command_key = format!("{PREFIX}/2/255/190/COMMAND_LONG");
    assert!(samples.iter().any(|s| s[0] == command_key), "{lines:?}");

    // Each edge received exactly what was published for it: the broadcasts of the
    // others and the frames for its own vehicle, never the command for vehicle 2.
    let after: Vec<u64> = edges.into_iter().map(Site::stop).collect();
    for (i, (after, before)) in (1u8..).zip(after.into_iter().zip(before)) {
        let mine = i.to_string();
        let expected = (samples.iter())
            .filter(|s| {
                let chunks: Vec<&str> = s[0].split('/').collect();
                (chunks[2] == "all" || chunks[2] == mine) && chunks[3] != mine
            })
            .count() as u64;
        assert_eq!(after - before, expected, "edge {i}");
        eprintln!(
            "zenoh: edge {i} received {expected} of {} publications",
            samples.len()
        );
    }
    let from_vehicles = samples.iter().filter(|s| s[2] != "255").count() as u64;
    assert_eq!(
        gs.stop() - gs_before,
        from_vehicles,
        "the ground station router"
    );
    zenohd.finish(5 * SECOND);
}

/// The Zenoh router goes away and comes back on the same endpoint: the mavtables
/// clients reconnect by themselves (the time is printed), and from then on nothing is
/// lost: 200 numbered frames from a vehicle all reach the ground station, in order, and a
/// command reaches its vehicle.
#[test]
fn a_zenoh_router_restart_loses_nothing_after_reconnection() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let zenohd = zenoh_router(&endpoint);
    let block =
        |receive: &str| format!("zenoh {{ connect {endpoint}; prefix {PREFIX}; {receive} }}");
    let mut gs = Site::start("zenoh-restart-gs", &block("receive all;"));
    let mut edges: Vec<Site> = (1..=2)
        .map(|i| Site::start(&format!("zenoh-restart-edge-{i}"), &block("")))
        .collect();
    // Rounds of frames numbered from `base` on until the ground station has one of them
    // from each vehicle: nothing sent before (still in a socket) is taken for a sign of
    // life.
    let all_heard = |gs: &mut Site, edges: &[Site], base: u32| {
        let mut round = base;
        until("every vehicle at the ground station", 30 * SECOND, || {
            gs.send(&heartbeat(255));
            for (i, edge) in (1u8..).zip(edges) {
                edge.send(&numbered(i, round));
            }
            round += 1;
            (1..=2).all(|i| {
                gs.has(|f| is(ATTITUDE, i)(f) && common::net::number_of(f.as_bytes()) >= base)
            })
        });
    };
    all_heard(&mut gs, &edges, 1000);

    let mut zenohd = zenohd;
    zenohd.finish(5 * SECOND);
    drop(zenohd);
    let stopped = Instant::now();
    let mut zenohd = zenoh_router(&endpoint);
    let restarted = Instant::now();
    all_heard(&mut gs, &edges, 2000);
    eprintln!(
        "zenoh: every router reconnected {:?} after the restarted Zenoh router listened ({:?} after the old one stopped)",
        restarted.elapsed(),
        stopped.elapsed()
    );
    for n in 0..200 {
        edges[0].send(&numbered(1, n));
    }
    gs.send(&command_long(2));
    let first_200 = |gs: &mut Site| -> Vec<u32> {
        gs.take();
        (gs.got.iter())
            .filter_map(|f| Frame::parse_exact(f).ok())
            .filter(|f| f.message_id() == ATTITUDE && f.system() == 1)
            .map(|f| common::net::number_of(f.as_bytes()))
            .filter(|&n| n < 200)
            .collect()
    };
    until("200 frames at the ground station", 10 * SECOND, || {
        first_200(&mut gs).len() >= 200
    });
    assert_eq!(first_200(&mut gs), (0..200).collect::<Vec<u32>>());
    until("the command at vehicle 2", 10 * SECOND, || {
        edges[1].has(is(COMMAND_LONG, 255))
    });
    assert_eq!(edges[0].count(COMMAND_LONG, 255), 0);
    for site in edges {
        site.stop();
    }
    gs.stop();
    zenohd.finish(5 * SECOND);
}

/// Peers without a Zenoh router: the ground-station router listens, an edge router
/// connects to it; telemetry and a command go both ways.
#[test]
fn peers_without_a_zenoh_router() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let mut gs = Site::start("zenoh-peer-gs", &listening_peer(&endpoint, PREFIX));
    let mut edge = Site::start("zenoh-peer-edge", &connecting_peer(&endpoint, PREFIX));
    until(
        "the vehicle's heartbeat at the ground station",
        30 * SECOND,
        || {
            gs.send(&heartbeat(255));
            edge.send(&heartbeat(1));
            gs.has(is(0, 1)) && edge.has(is(0, 255))
        },
    );
    gs.send(&command_long(1));
    gs.send(&numbered(255, MARKER));
    until(
        "the command and the marker at the vehicle",
        10 * SECOND,
        || edge.has(is(COMMAND_LONG, 255)) && edge.has(is_marker(255, MARKER)),
    );
    let commands: Vec<u8> = (edge.got.iter())
        .filter_map(|f| Frame::parse_exact(f).ok())
        .filter(|f| f.message_id() == COMMAND_LONG)
        .filter_map(|f| f.target().map(|t| t.system))
        .collect();
    assert_eq!(
        commands,
        [1],
        "only the command for the vehicle behind the edge"
    );
    edge.stop();
    gs.stop();
}

/// A peer whose `connect` endpoint does not listen yet keeps trying it: an edge started
/// (and publishing) before the ground station's peer reaches it once it listens, and
/// again after that peer is restarted on the same endpoint.
#[test]
fn a_peer_keeps_trying_a_peer_that_is_not_listening_yet() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let mut edge = Site::start("zenoh-late-peer-edge", &connecting_peer(&endpoint, PREFIX));
    // The edge's session is open and publishing: its first try at the endpoint is over.
    until("the edge publishing", 10 * SECOND, || {
        edge.send(&heartbeat(1));
        let counters = common::net::counters(&mut edge.router);
        counters.link(LINK).is_some_and(|l| l.frames_out > 0)
    });
    let gs_block = listening_peer(&endpoint, PREFIX);
    for (round, tag) in ["zenoh-late-peer-gs", "zenoh-late-peer-gs-again"]
        .iter()
        .enumerate()
    {
        let mut gs = Site::start(tag, &gs_block);
        heard(&mut gs, &mut edge, 1000 * (round as u32 + 1));
        gs.stop();
    }
    edge.stop();
}

/// MAVProxy at the ground-station router downloads every parameter of a vehicle behind
/// an edge router, arms it and sets a parameter, all through a Zenoh router: the
/// requests (for system 1) reach the edge only because it subscribed to system 1.
#[test]
fn mavproxy_downloads_parameters_from_a_vehicle_behind_an_edge() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let mut zenohd = zenoh_router(&endpoint);
    let edge_scratch = Scratch::new("zenoh-mavproxy-edge");
    let edge_port = free_udp_port();
    let edge = Router::start(
        &edge_scratch,
        &format!(
            "udp {{ port {edge_port}; address 127.0.0.1; }}\nzenoh {{ connect {endpoint}; prefix {PREFIX}; }}\n{ACCEPT_ALL}"
        ),
        1,
    );
    let s = Scratch::new("zenoh-mavproxy-gs");
    let gs_port = free_udp_port();
    let config = format!(
        "udp {{ port {gs_port}; address 127.0.0.1; }}\nzenoh {{ connect {endpoint}; prefix {PREFIX}; receive all; }}\n{ACCEPT_ALL}"
    );
    let session = ground_station_session(
        &s,
        &config,
        &format!("udpout:127.0.0.1:{gs_port}"),
        VehicleLink::Udp(format!("127.0.0.1:{edge_port}")),
    );
    assert!(
        (session.router.stdout.iter()).any(|l| l.contains(&format!("new component 1.1 on {LINK}"))),
        "the ground-station router learned the vehicle over Zenoh: {:#?}",
        session.router.stdout
    );
    edge.stop();
    zenohd.finish(5 * SECOND);
    eprintln!("zenoh: the MAVProxy session took {:?}", session.took);
}

/// Signing applies at each edge as on any interface: with the fleet's key on both
/// `zenoh` blocks, the routers sign what they publish and check what they receive, so a
/// COMMAND_LONG put on the Zenoh network by anyone else (unsigned, under the right key)
/// is dropped and counted at the edge, while the ground station's command, signed by its
/// router, reaches the vehicle.
#[test]
fn signed_zenoh_edges_drop_what_anyone_else_publishes() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let mut zenohd = zenoh_router(&endpoint);
    let keys = Scratch::new("zenoh-signing-keys");
    let kf = crate::signing::key_file(&keys, "fleet.key", "fleet passphrase");
    let block = |receive: &str, state: &str| {
        format!(
            "zenoh {{ connect {endpoint}; prefix {PREFIX}; signing_key {kf}; {receive} }}\nsigning_state {};",
            keys.path(state)
        )
    };
    let mut gs = Site::start("zenoh-signing-gs", &block("receive all;", "gs.state"));
    let mut edge = Site::start("zenoh-signing-edge", &block("", "edge.state"));
    until(
        "the vehicle's heartbeat at the ground station",
        30 * SECOND,
        || {
            gs.send(&heartbeat(255));
            edge.send(&heartbeat(1));
            gs.has(is(0, 1)) && edge.has(is(0, 255))
        },
    );
    assert!(gs.has(|f| f.message_id() == 0 && f.system() == 1 && f.is_signed()));

    let forged = command_long(1);
    let mut cmd = Command::new(common::python());
    cmd.arg(script("zenoh_publish.py"))
        .arg(&endpoint)
        .arg(format!("{PREFIX}/1/255/190/COMMAND_LONG"))
        .arg(common::hex(&forged));
    let mut publisher = Proc::spawn(cmd, "zenoh publisher");
    publisher.wait_for("sent", 30 * SECOND);
    publisher.finish(5 * SECOND);
    common::eventually(
        "the forged command dropped at the edge",
        10 * SECOND,
        || {
            let counters = common::net::counters(&mut edge.router);
            let line = counters
                .text
                .lines()
                .find(|l| l.starts_with(LINK) && l.contains("signing: "))
                .unwrap_or("");
            line.contains(" 1 unsigned dropped")
        },
    );
    gs.send(&command_long(1));
    until(
        "the ground station's command at the vehicle",
        10 * SECOND,
        || edge.has(is(COMMAND_LONG, 255)),
    );
    let commands: Vec<bool> = (edge.got.iter())
        .filter_map(|f| Frame::parse_exact(f).ok())
        .filter(|f| f.message_id() == COMMAND_LONG)
        .map(|f| f.is_signed())
        .collect();
    assert_eq!(
        commands,
        [true],
        "only the signed command reached the vehicle"
    );
    edge.stop();
    gs.stop();
    zenohd.finish(5 * SECOND);
}

/// Routers started before their Zenoh router: each says once that it cannot open the
/// session and keeps trying (with the backoff of a TCP client); once the Zenoh router
/// listens, they open, say so, and route.
#[test]
fn clients_started_before_their_zenoh_router_wait_for_it() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let block =
        |receive: &str| format!("zenoh {{ connect {endpoint}; prefix {PREFIX}; {receive} }}");
    let mut gs = Site::start("zenoh-early-gs", &block("receive all;"));
    let mut edge = Site::start("zenoh-early-edge", &block(""));
    for site in [&mut gs, &mut edge] {
        site.router
            .err
            .wait_for(&format!("cannot open {LINK}: "), 10 * SECOND);
    }
    let mut zenohd = zenoh_router(&endpoint);
    for site in [&mut gs, &mut edge] {
        site.router
            .err
            .wait_for(&format!("{LINK} is back"), 10 * SECOND);
    }
    until(
        "the vehicle's heartbeat at the ground station",
        10 * SECOND,
        || {
            gs.send(&heartbeat(255));
            edge.send(&heartbeat(1));
            gs.has(is(0, 1)) && edge.has(is(0, 255))
        },
    );
    for site in [edge, gs] {
        let stopped = site.router.stop();
        let warnings = (stopped.stderr.iter())
            .filter(|l| l.contains("cannot open"))
            .count();
        assert_eq!(warnings, 1, "said once: {:#?}", stopped.stderr);
    }
    zenohd.finish(5 * SECOND);
}

/// A reload (SIGHUP) keeps a `zenoh` block that did not change, session and learned
/// addresses included, and replaces one whose prefix changed: the edge then publishes
/// under the new prefix, where the ground station's router (reloaded too) listens.
#[test]
fn a_reload_replaces_a_changed_zenoh_block_only() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let gs_block = |prefix: &str| listening_peer(&endpoint, prefix);
    let edge_block = |prefix: &str| connecting_peer(&endpoint, prefix);
    let mut gs = Site::start("zenoh-reload-gs", &gs_block(PREFIX));
    let mut edge = Site::start("zenoh-reload-edge", &edge_block(PREFIX));
    heard(&mut gs, &mut edge, 1000);
    let reload = |site: &mut Site, zenoh: &str| {
        let config = std::fs::read_to_string(&site.router.config).expect("config");
        let udp = config.lines().next().expect("the udp line");
        std::fs::write(&site.router.config, format!("{udp}\n{zenoh}\n{ACCEPT_ALL}"))
            .expect("write config");
        site.router.signal(libc::SIGHUP);
        site.router
            .err
            .wait_for("configuration reloaded: ", 10 * SECOND)
    };
    let same = reload(&mut gs, &gs_block(PREFIX));
    assert!(same.contains("+0 interfaces, -0, 0 changed"), "{same}");
    let changed = [
        reload(&mut gs, &gs_block("fleet/other")),
        reload(&mut edge, &edge_block("fleet/other")),
    ];
    for line in changed {
        // The prefix is part of the block's identity: the old one goes, a new one comes.
        assert!(line.contains("+1 interface, -1, 0 changed"), "{line}");
    }
    heard(&mut gs, &mut edge, 2000);
    edge.router.stop();
    let stopped = gs.router.stop();
    assert!(
        (stopped.stdout.iter()).any(|l| l.contains("new component 1.1 on zenoh fleet/other")),
        "{:#?}",
        stopped.stdout
    );
}

/// `mavtables udp-server:… zenoh-client:tcp/…` (no file) at a vehicle's site and at a
/// ground station's, through a real Zenoh router: each hears the other's heartbeat, and a
/// command for the vehicle reaches it.
#[test]
fn command_line_endpoints_join_a_zenoh_network() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_listen_port());
    let _zenohd = zenoh_router(&endpoint);
    let start = |udp: u16| {
        let child = Command::new(common::router::BIN)
            .arg(format!("udp-server:127.0.0.1:{udp}"))
            .arg(format!("zenoh-client:{endpoint}"))
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("spawn mavtables");
        common::router::Guard(Some(child))
    };
    let (vehicle_port, gs_port) = (free_udp_port(), free_udp_port());
    let _vehicle_router = start(vehicle_port);
    let _gs_router = start(gs_port);
    let socket = |port: u16| {
        let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
        s.connect(("127.0.0.1", port)).expect("connect");
        s.set_nonblocking(true).expect("nonblocking");
        s
    };
    let (vehicle, gs) = (socket(vehicle_port), socket(gs_port));
    let received = |s: &UdpSocket, wanted: &dyn Fn(&Frame<'_>) -> bool| {
        let mut buf = [0u8; 4096];
        let mut found = false;
        while let Ok(n) = s.recv(&mut buf) {
            let mut parser = Parser::new();
            parser.feed(&buf[..n], |f| found |= wanted(&f));
        }
        found
    };
    let (mut vehicle_heard, mut gs_heard) = (false, false);
    until("each side's heartbeat at the other", 30 * SECOND, || {
        let _ = vehicle.send(&heartbeat(1));
        let _ = gs.send(&heartbeat(255));
        vehicle_heard |= received(&vehicle, &is(0, 255));
        gs_heard |= received(&gs, &is(0, 1));
        vehicle_heard && gs_heard
    });
    let mut got_command = false;
    until("the command at the vehicle", 10 * SECOND, || {
        let _ = gs.send(&command_long(1));
        got_command |= received(&vehicle, &is(COMMAND_LONG, 255));
        got_command
    });
}
