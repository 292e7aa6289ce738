//! A real ground station session through the router: MAVProxy (the PyPI package that
//! `scripts/test` installs into `.venv`) on one side, the simulated vehicle
//! `tests/py/vehicle.py` on the other, the router in between.
//!
//! [`ground_station_session`] runs the whole scenario for any pair of links, so a test
//! for another transport only changes the router's config, MAVProxy's `--master` and the
//! vehicle's [`VehicleLink`]. MAVProxy's connection strings (pymavlink's), as checked
//! against the vehicle:
//!
//! | MAVProxy's side of the link | `--master` | the router's side |
//! | --- | --- | --- |
//! | UDP client (speaks first) | `udpout:127.0.0.1:PORT` | `udp { port PORT; }` |
//! | UDP server (waits for datagrams) | `udpin:0.0.0.0:PORT` | a UDP client to PORT |
//! | TCP client | `tcp:127.0.0.1:PORT` | a TCP server on PORT |
//! | TCP server | `tcpin:0.0.0.0:PORT` | a TCP client to PORT |
//!
//! MAVProxy 1.8.75 (pymavlink 2.4.50) has no IPv6 in these strings (`tcp:[::1]:PORT` is
//! refused: "TCP ports must be specified as host:port"); the vehicle has it.
//!
//! Every process is in a process group of its own and the group is killed when its
//! guard is dropped, so a failing assertion leaves nothing behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::process::Proc;
use super::python;
use super::router::{Router, Scratch, Stopped};

/// How many parameters the vehicle has (its default).
pub const PARAMS: usize = 300;

/// The whole of [`ground_station_session`] must fit in this.
pub const SESSION_LIMIT: Duration = Duration::from_secs(60);

/// The vehicle's side of its link to the router.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum VehicleLink {
    /// A pty the vehicle makes; the symlink at this path is what the router's `serial`
    /// block names as its `device`.
    Serial(String),
    /// Sends to a router's UDP server at `HOST:PORT`.
    Udp(String),
    /// Waits at `[HOST:]PORT` for a router's UDP client.
    UdpListen(String),
    /// Connects to a router's TCP server at `HOST:PORT`.
    Tcp(String),
    /// Accepts a router's TCP client at `[HOST:]PORT`.
    TcpListen(String),
}

impl VehicleLink {
    fn args(&self) -> [&str; 2] {
        match self {
            VehicleLink::Serial(p) => ["--serial", p],
            VehicleLink::Udp(a) => ["--udp", a],
            VehicleLink::UdpListen(a) => ["--udp-listen", a],
            VehicleLink::Tcp(a) => ["--tcp", a],
            VehicleLink::TcpListen(a) => ["--tcp-listen", a],
        }
    }

    /// True if the vehicle's end must exist before the router starts (the router opens
    /// the pty, or connects, or sends, to it).
    fn waits_for_router(&self) -> bool {
        matches!(
            self,
            VehicleLink::Serial(_) | VehicleLink::UdpListen(_) | VehicleLink::TcpListen(_)
        )
    }
}

/// The running vehicle (`tests/py/vehicle.py`).
pub struct Vehicle {
    proc: Proc,
}

impl Vehicle {
    /// Starts the vehicle on `link` and waits for its "ready" (its end of the link exists).
    pub fn start(link: &VehicleLink) -> Vehicle {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/py/vehicle.py");
        let mut cmd = Command::new(python());
        cmd.arg(script).args(link.args());
        let mut vehicle = Vehicle {
            proc: Proc::spawn(cmd, &format!("vehicle {link:?}")),
        };
        vehicle.wait_for("ready", Duration::from_secs(20));
        vehicle
    }

    /// The next line of the vehicle's containing `pattern`.
    pub fn wait_for(&mut self, pattern: &str, timeout: Duration) -> String {
        self.proc.out.wait_for(pattern, timeout)
    }

    /// Stops it (end of stdin) and returns every line it printed; it must say "end".
    pub fn stop(mut self) -> Vec<String> {
        let lines = self.proc.finish(Duration::from_secs(10));
        assert_eq!(
            lines.last().map(String::as_str),
            Some("end"),
            "the vehicle did not stop cleanly: {lines:#?}"
        );
        lines
    }
}

/// The interpreter of [`python`], checked to have MAVProxy too.
pub fn python_with_mavproxy() -> PathBuf {
    let py = python();
    let ok = Command::new(&py)
        .args(["-c", "import MAVProxy.mavproxy"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        ok,
        "{} has no MAVProxy; run scripts/test, which installs it into .venv",
        py.display()
    );
    py
}

/// `mavproxy.py --master=MASTER EXTRA…` with its state (logs, parameter files) and its
/// home directory (so no `~/.mavinit.scr` or signing keys of the user's) inside `scratch`.
pub fn mavproxy_command(scratch: &Scratch, master: &str, extra: &[&str]) -> Command {
    let home = scratch.dir.join("mavproxy-home");
    let state = scratch.dir.join("mavproxy-state");
    for dir in [&home, &state] {
        std::fs::create_dir_all(dir).expect("mavproxy dirs");
    }
    let mut cmd = Command::new(python_with_mavproxy());
    cmd.args(["-m", "MAVProxy.mavproxy"])
        .arg(format!("--master={master}"))
        .arg(format!("--state-basedir={}", state.display()))
        .args(extra)
        .current_dir(&scratch.dir)
        .env("HOME", &home)
        .env("PYTHONUNBUFFERED", "1")
        .env_remove("DISPLAY");
    cmd
}

/// A running MAVProxy, driven through its command line on stdin.
pub struct MavProxy {
    proc: Proc,
}

impl MavProxy {
    /// Starts [`mavproxy_command`] and waits until its master link is open.
    pub fn start(scratch: &Scratch, master: &str) -> MavProxy {
        let cmd = mavproxy_command(scratch, master, &[]);
        let mut gcs = MavProxy {
            proc: Proc::spawn(cmd, &format!("mavproxy --master={master}")),
        };
        // Printed after the master link is made (a listening one is bound by then).
        gcs.wait_for("Log Directory:", Duration::from_secs(30));
        gcs
    }

    /// Types `line` at MAVProxy's prompt.
    pub fn command(&mut self, line: &str) {
        self.proc.send_line(line);
    }

    /// The next line of MAVProxy's containing `pattern`.
    pub fn wait_for(&mut self, pattern: &str, timeout: Duration) -> String {
        self.proc.out.wait_for(pattern, timeout)
    }

    /// Ends its input (MAVProxy then unloads its modules and exits) and returns every line
    /// it printed.
    pub fn stop(mut self) -> Vec<String> {
        self.proc.finish(Duration::from_secs(10))
    }
}

/// Polls /proc/net/tcp and tcp6 until something listens on `port` (the router's TCP
/// server, before MAVProxy connects: MAVProxy exits if its first connect fails).
pub fn wait_tcp_listening(port: u16, timeout: Duration) {
    let wanted = format!(":{port:04X}");
    super::eventually(
        format!("something listening on TCP port {port}"),
        timeout,
        || {
            ["/proc/net/tcp", "/proc/net/tcp6"].iter().any(|f| {
                std::fs::read_to_string(f)
                    .unwrap_or_default()
                    .lines()
                    .skip(1)
                    .any(|l| {
                        let cols: Vec<&str> = l.split_whitespace().collect();
                        cols.len() > 3 && cols[1].ends_with(&wanted) && cols[3] == "0A"
                    })
            })
        },
    );
}

/// What a finished session printed.
pub struct Session {
    /// Every line of MAVProxy's (stdout and stderr, with its prompts).
    pub mavproxy: Vec<String>,
    /// Every line of the vehicle's.
    pub vehicle: Vec<String>,
    /// The router's end (it exited cleanly).
    pub router: Stopped,
    /// From the router's start to the last assertion.
    pub took: Duration,
}

/// The part of `line` from `pattern` on (MAVProxy's prompt may stand before it).
fn from<'a>(line: &'a str, pattern: &str) -> &'a str {
    &line[line.find(pattern).expect("pattern")..]
}

/// A ground station session through the router:
///
/// 1. starts the vehicle, the router (`router_config`) and MAVProxy (`--master=MASTER`),
///    each end that listens before the end that reaches it;
/// 2. MAVProxy sees the vehicle's HEARTBEAT ("Detected vehicle 1:1");
/// 3. MAVProxy downloads every parameter: it tries MAVLink FTP first, the vehicle
///    refuses, and it falls back to PARAM_REQUEST_LIST; it must report exactly
///    "Received 300 parameters" (and show SIM_P299 with the vehicle's value);
/// 4. `arm throttle`: the vehicle prints the COMMAND_LONG (400) and arms, MAVProxy gets
///    the COMMAND_ACK and sees the armed HEARTBEAT;
/// 5. `param set SIM_P007 42`: the vehicle stores it, and a `param fetch SIM_P007` reads
///    42 back;
/// 6. stops MAVProxy and the vehicle (end of their input) and the router (SIGTERM, clean
///    exit), and checks the router learned both ends.
///
/// `scratch` holds the config, MAVProxy's state and whatever paths the links name (a
/// pty's symlink). Everything is bounded by [`SESSION_LIMIT`].
pub fn ground_station_session(
    scratch: &Scratch,
    router_config: &str,
    master: &str,
    vehicle_link: VehicleLink,
) -> Session {
    let start = Instant::now();
    let deadline = start + SESSION_LIMIT;
    let left = || deadline.saturating_duration_since(Instant::now());
    let gcs_listens = master.starts_with("udpin:") || master.starts_with("tcpin:");

    let vehicle = vehicle_link
        .waits_for_router()
        .then(|| Vehicle::start(&vehicle_link));
    let gcs = gcs_listens.then(|| MavProxy::start(scratch, master));
    let router = Router::start(scratch, router_config, 1);
    if let Some(port) = master.strip_prefix("tcp:") {
        let port = port.rsplit(':').next().expect("tcp:HOST:PORT");
        wait_tcp_listening(port.parse().expect("port"), left());
    }
    let mut vehicle = vehicle.unwrap_or_else(|| Vehicle::start(&vehicle_link));
    let mut gcs = gcs.unwrap_or_else(|| MavProxy::start(scratch, master));

    // 2. The vehicle's HEARTBEAT, through the router.
    gcs.wait_for("Detected vehicle 1:1", left());

    // 3. Every parameter.
    let received = gcs.wait_for("Received ", left());
    assert_eq!(
        from(&received, "Received "),
        format!("Received {PARAMS} parameters"),
        "MAVProxy's parameter download"
    );
    vehicle.wait_for(&format!("param list sent {PARAMS}"), left());
    gcs.command("param show SIM_P299");
    let shown = gcs.wait_for("SIM_P299 ", left());
    assert_eq!(
        from(&shown, "SIM_P299 ")
            .split_whitespace()
            .collect::<Vec<_>>(),
        ["SIM_P299", "75.75"],
        "SIM_P299 as MAVProxy has it (the vehicle's 1 + 299 * 0.25)"
    );

    // 4. A command.
    gcs.command("arm throttle");
    vehicle.wait_for("command 400 from 255.", left());
    vehicle.wait_for("armed", left());
    gcs.wait_for("COMPONENT_ARM_DISARM: ACCEPTED", left());
    gcs.wait_for("ARMED", left());

    // 5. A parameter set, and read back.
    gcs.command("param set SIM_P007 42");
    vehicle.wait_for("param set SIM_P007 42", left());
    gcs.command("param fetch SIM_P007");
    gcs.wait_for("SIM_P007 = 42.0000000", left());
    let took = start.elapsed();

    // 6. Everyone stops.
    let mavproxy = gcs.stop();
    let vehicle = vehicle.stop();
    let router = router.stop();
    for who in ["1.1", "255."] {
        assert!(
            router
                .stdout
                .iter()
                .any(|l| l.contains(&format!("new component {who}"))),
            "the router never learned {who}: {:#?}",
            router.stdout
        );
    }
    Session {
        mavproxy,
        vehicle,
        router,
        took,
    }
}
