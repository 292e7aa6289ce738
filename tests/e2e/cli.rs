//! The real binary: options, exit codes, config search, --ast, --check and error output.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_mavtables");

/// A fresh empty directory under the target dir, named after the test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("cli-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// Runs the binary in `dir` with a clean environment (HOME pointing into `dir`).
fn run_in(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(BIN);
    cmd.args(args)
        .current_dir(dir)
        .env_clear()
        .env("HOME", dir.join("home"));
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run mavtables")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn repo(path: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(path)
        .display()
        .to_string()
}

#[test]
fn help_and_version() {
    let dir = scratch("help");
    for args in [
        &["-h"][..],
        &["--help"],
        &["--he"],
        &["--config", "nope", "--help"],
    ] {
        let out = run_in(&dir, args, &[]);
        assert_eq!(out.status.code(), Some(0));
        let stdout = text(&out.stdout);
        assert!(
            stdout.starts_with(&format!("usage: {BIN}:\n  -h [ --help ]  ")),
            "{stdout}"
        );
        for opt in [
            "--config arg",
            "--ast",
            "--check",
            "--version",
            "--loglevel arg",
        ] {
            assert!(stdout.contains(&format!("\n  {opt} ")), "{opt} missing");
        }
        for line in [
            "\n  inspect FILE...  ",
            "\n  replay FILE --to ...  ",
            "'mavtables SUBCOMMAND --help'",
        ] {
            assert!(stdout.contains(line), "{line} missing from\n{stdout}");
        }
        assert!(stdout.ends_with("\n\n"));
        // Every endpoint's example stands apart from its form.
        for line in stdout.lines().filter(|l| l.contains("e.g. ")) {
            assert!(line.contains("  e.g. "), "{line:?} runs together");
        }
    }
    let out = run_in(&dir, &["--ver"], &[]);
    assert_eq!(out.status.code(), Some(0));
    let v = text(&out.stdout);
    assert!(v.starts_with(&format!("mavtables {}\n", env!("CARGO_PKG_VERSION"))));
    assert!(v.contains("GPL-2.0-or-later"));
    assert!(!v.contains("Copyright"));
}

#[test]
fn option_errors_exit_1_with_the_original_texts() {
    let dir = scratch("opterr");
    let cases: [(&[&str], &str); 7] = [
        (&["--foo"], "error: unrecognised option '--foo'\n"),
        (
            &["--loglevel", "abc"],
            "error: the argument ('abc') for option '--loglevel' is invalid\n",
        ),
        (
            &["--config"],
            "error: the required argument for option '--config' is missing\n",
        ),
        (
            &["--loglevel", "99"],
            "error: the argument ('99') for option '--loglevel' is invalid: the log level is a number from 0 (nothing) to 3 (every packet and decision)\n",
        ),
        (
            &["--loglevel", "-1"],
            "error: the argument ('-1') for option '--loglevel' is invalid: the log level is a number from 0 (nothing) to 3 (every packet and decision)\n",
        ),
        (
            &["--config", "a", "--conf=b"],
            "error: option '--config' cannot be specified more than once\n",
        ),
        (
            &["--config", "missing.conf"],
            "error: mavtables could not locate a configuration file\n",
        ),
    ];
    for (args, want) in cases {
        let out = run_in(&dir, args, &[]);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        assert_eq!(text(&out.stderr), want, "{args:?}");
        assert!(out.stdout.is_empty());
    }
}

#[test]
fn check_the_example_config() {
    let out = run_in(
        Path::new(env!("CARGO_MANIFEST_DIR")),
        &["--check", "--config", "examples/mavtables.conf"],
        &[],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "examples/mavtables.conf: configuration is valid\n"
    );
    assert!(out.stderr.is_empty());
}

#[test]
fn the_example_configs_commented_sketch_is_valid_too() {
    let src = std::fs::read_to_string(repo("examples/mavtables.conf")).expect("example");
    let sketch: String = src
        .lines()
        .skip_while(|l| !l.starts_with("# A sketch"))
        .skip(1)
        .map(|l| l.strip_prefix("# ").or(l.strip_prefix("#")).unwrap_or(l))
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(sketch.contains("chain from_vehicle"));
    if let Err(e) = mavtables::config::load(&sketch) {
        panic!(
            "{}",
            mavtables::config::render_errors("sketch", &sketch, &e)
        );
    }
}

#[test]
fn check_reports_located_errors_and_warnings() {
    let dir = scratch("check");
    std::fs::write(
        dir.join("bad.conf"),
        "chain default {\n    accept if PIN;\n}\n",
    )
    .expect("write");
    let out = run_in(&dir, &["--check", "--conf", "bad.conf"], &[]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.starts_with("bad.conf:2:15: Invalid packet name (\"PIN\").\n    accept if PIN;\n              ^^^\nnote: did you mean"),
        "{err}"
    );
    assert!(err.contains("'PING'"), "{err}");
    assert!(out.stdout.is_empty());

    std::fs::write(dir.join("nodefault.conf"), "udp { port 14550; }\n").expect("write");
    let out = run_in(&dir, &["--check", "--config=nodefault.conf"], &[]);
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(
        text(&out.stderr),
        "warning: nodefault.conf: no 'default' chain is defined, so every packet gets the default action (reject)\n"
    );
}

#[test]
fn ast_prints_header_and_tree_and_skips_semantics() {
    let dir = scratch("ast");
    std::fs::write(
        dir.join("a.conf"),
        "default_action accept;\nchain default {\n    call x if NOPE;\n}\n",
    )
    .expect("write");
    let out = run_in(&dir, &["--ast", "--config", "a.conf"], &[]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "===== a.conf =====\n:001:  default_action\n:001:  |  accept\n:002:  chain default\n\
         :003:  |  call x\n:003:  |  |  condition\n:003:  |  |  |  packet_type NOPE\n"
    );
    std::fs::write(dir.join("b.conf"), "udp {\n    port 14500\n}\n").expect("write");
    let out = run_in(&dir, &["--ast", "--config", "b.conf"], &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    assert_eq!(
        text(&out.stderr),
        "b.conf:2:15: expected end of statement ';' character\n    port 14500\n              ^\n"
    );
}

#[test]
fn golden_ast_through_the_binary() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["everything", "queue", "network"] {
        let conf = format!("tests/data/config/{name}.conf");
        let out = run_in(root, &["--ast", "--config", &conf], &[]);
        assert_eq!(out.status.code(), Some(0), "{name}");
        let want = std::fs::read_to_string(root.join(format!("tests/data/config/{name}.ast")))
            .expect("golden");
        assert_eq!(text(&out.stdout), want, "{name}");
    }
    // The network fixture (tcp blocks, clients, IPv6, limits) is valid as a whole.
    let conf = "tests/data/config/network.conf";
    let out = run_in(root, &["--check", "--config", conf], &[]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        format!("{conf}: configuration is valid\n")
    );
}

#[test]
fn check_validates_the_queue_block() {
    let dir = scratch("queue");
    std::fs::write(
        dir.join("q.conf"),
        "queue {\n    link_bytes 8192;\n    total_bytes 4096;\n}\nchain default { accept; }\n",
    )
    .expect("write");
    let out = run_in(&dir, &["--check", "--config", "q.conf"], &[]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "q.conf:3:17: total_bytes (4096) must be at least link_bytes (8192)\n    total_bytes 4096;\n                ^^^^\n\
         note: all queues together need room for at least one full link queue\n"
    );
    std::fs::write(
        dir.join("ok.conf"),
        "queue { link_bytes 8192; }\nchain default { accept; }\n",
    )
    .expect("write");
    let out = run_in(&dir, &["--check", "--config", "ok.conf"], &[]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
}

#[test]
fn config_search_order() {
    let dir = scratch("search");
    std::fs::create_dir_all(dir.join("home")).expect("home");
    let conf = |name: &str, port: u16| {
        std::fs::write(
            dir.join(name),
            format!("udp {{ port {port}; }}\nchain default {{ accept; }}\n"),
        )
        .expect("write")
    };
    let ast_header = |env: &[(&str, &str)]| {
        let out = run_in(&dir, &["--ast"], env);
        (
            out.status.code(),
            text(&out.stdout)
                .lines()
                .next()
                .unwrap_or_default()
                .to_string(),
        )
    };
    // Nothing anywhere (and /etc/mavtables.conf is not expected on a build machine).
    if !Path::new("/etc/mavtables.conf").exists() {
        let out = run_in(&dir, &["--check"], &[]);
        assert_eq!(out.status.code(), Some(1));
        assert_eq!(
            text(&out.stderr),
            "error: mavtables could not locate a configuration file\n"
        );
    }
    conf("home/.mavtablesrc", 1);
    let home_rc = format!("{}/.mavtablesrc", dir.join("home").display());
    assert_eq!(ast_header(&[]), (Some(0), format!("===== {home_rc} =====")));
    conf(".mavtablesrc", 2);
    assert_eq!(
        ast_header(&[]),
        (Some(0), "===== ./.mavtablesrc =====".to_string())
    );
    conf("env.conf", 3);
    let env_path = dir.join("env.conf").display().to_string();
    assert_eq!(
        ast_header(&[("MAVTABLES_CONFIG_PATH", &env_path)]),
        (Some(0), format!("===== {env_path} ====="))
    );
    // A variable naming a missing file falls through to the next candidate.
    assert_eq!(
        ast_header(&[("MAVTABLES_CONFIG_PATH", "/nonexistent.conf")]),
        (Some(0), "===== ./.mavtablesrc =====".to_string())
    );
    // --config wins, and a missing --config path is an error even if others exist.
    let out = run_in(
        &dir,
        &["--ast", "--config", "home/.mavtablesrc"],
        &[("MAVTABLES_CONFIG_PATH", &env_path)],
    );
    assert!(text(&out.stdout).starts_with("===== home/.mavtablesrc =====\n"));
    let out = run_in(&dir, &["--ast", "--config", "nope"], &[]);
    assert_eq!(out.status.code(), Some(1));
}

#[test]
fn running_loads_and_validates_first() {
    let dir = scratch("run");
    std::fs::write(dir.join("bad.conf"), "udp { port 65536; }\n").expect("write");
    let out = run_in(&dir, &["--config", "bad.conf", "--loglevel", "3"], &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).starts_with("bad.conf:1:12: port number (65536) is outside"));
}

#[test]
fn subcommands_read_options_like_the_main_command() {
    let dir = scratch("subcommands");
    for args in [
        &["inspect", "-h"][..],
        &["inspect", "--he"],
        &["replay", "--help"],
    ] {
        let out = run_in(&dir, args, &[]);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        let want = format!("usage: mavtables {} ", args[0]);
        assert!(text(&out.stdout).starts_with(&want), "{args:?}");
    }
    let cases: [(&[&str], &str); 7] = [
        (
            &["inspect", "--bogus", "f"],
            "unrecognised option '--bogus'",
        ),
        (
            &["inspect", "--from"],
            "the required argument for option '--from' is missing",
        ),
        (
            &["inspect", "--json=yes", "f"],
            "option '--json' does not take any arguments",
        ),
        // Subnets on the command line are read by the config language's mask rules.
        (
            &["inspect", "--from", "1.1/17", "f"],
            "Forward slash mask (17) is outside of allowed range (0 - 16).",
        ),
        (
            &["inspect", "--to=1.1\\9", "f"],
            "Backslash mask (9) is outside of allowed range (0 - 8).",
        ),
        (
            &["replay", "f", "--speed"],
            "the required argument for option '--speed' is missing",
        ),
        // A unique prefix and `=` work as for the main command.
        (
            &["replay", "missing.cap", "--sp=2", "--t", "udp:127.0.0.1:9"],
            "cannot read missing.cap: it does not exist",
        ),
    ];
    for (args, want) in cases {
        let out = run_in(&dir, args, &[]);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        assert_eq!(text(&out.stderr), format!("error: {want}\n"), "{args:?}");
    }
}

/// Runs the command line in-process (program name included) and gives the outcome.
fn outcome(args: &[&str]) -> (mavtables::cli::Outcome, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = args.iter().map(|s| s.to_string()).collect();
    let o = mavtables::cli::run(args, &mut out, &mut err);
    (o, text(&out), text(&err))
}

#[test]
fn endpoints_are_the_configuration_in_the_order_given() {
    use mavtables::config::{DefaultAction, Host, Interface, Remote};
    let (o, out, err) = outcome(&[
        "mavtables",
        "serial:/dev/ttyACM0:115200",
        "udp-client:127.0.0.1:14550",
        "not-an-endpoint",
        "udp-server:0.0.0.0:14551",
        "tcp-server:[::]:5760",
        "tcp-client:localhost:5761",
        "udp-client:[::1]:14552",
        "--loglevel",
        "2",
    ]);
    assert!(out.is_empty() && err.is_empty(), "{out}{err}");
    let mavtables::cli::Outcome::Run {
        config,
        keys,
        path,
        options,
    } = o
    else {
        panic!("expected to run")
    };
    assert_eq!(path, mavtables::cli::ENDPOINTS_SOURCE);
    // Endpoints have no signing keys: one `None` per link.
    assert_eq!(keys, vec![None; 6]);
    assert_eq!(options.loglevel, 2);
    assert_eq!(config.default_action, DefaultAction::Accept);
    assert_eq!(config.chains.len(), 1);
    assert!(config.chain(config.default_chain).rules.is_empty());
    let i = &config.interfaces;
    assert_eq!(i.len(), 6);
    assert!(
        matches!(&i[0], Interface::Serial(s) if s.device == "/dev/ttyACM0" && s.baudrate == 115_200)
    );
    let remote = |host: &str, port| Remote {
        host: Host::Ip(host.parse().expect("ip")),
        port,
    };
    assert!(
        matches!(&i[1], Interface::Udp(u) if u.connect == Some(remote("127.0.0.1", 14550)) && u.port == 0)
    );
    assert!(
        matches!(&i[2], Interface::Udp(u) if u.connect.is_none() && u.port == 14551 && u.address == Some("0.0.0.0".parse().expect("ip")))
    );
    assert!(
        matches!(&i[3], Interface::Tcp(t) if t.connect.is_none() && t.port == 5760 && t.address == Some("::".parse().expect("ip")))
    );
    assert!(
        matches!(&i[4], Interface::Tcp(t) if t.connect == Some(Remote {
            host: Host::Name("localhost".into()),
            port: 5761
        }))
    );
    assert!(matches!(&i[5], Interface::Udp(u) if u.connect == Some(remote("::1", 14552))));
}

#[test]
fn endpoint_mistakes_and_conflicts() {
    let err = |args: &[&str]| {
        let (o, out, err) = outcome(args);
        assert!(matches!(o, mavtables::cli::Outcome::Exit(1)), "{args:?}");
        assert!(out.is_empty());
        err
    };
    assert_eq!(
        err(&["m", "udp-client:nohost"]),
        "error: endpoint 'udp-client:nohost': expected ':' and a port number after the host; \
         write udp-client:HOST:PORT, e.g. udp-client:127.0.0.1:14550\n"
    );
    assert!(
        err(&["m", "udp-client:300.1.1.1:5"]).contains("'300.1.1.1' is not a valid IPv4 address")
    );
    assert!(
        err(&["m", "tcp-client:a:0"])
            .contains("port number (0) is outside of the allowed range (1 - 65535)")
    );
    assert!(err(&["m", "udp-client:::1:5"]).contains("(write [::1]:5)"));
    assert!(err(&["m", "tcp-server:localhost:5760"]).contains("a server listens on an IP address"));
    assert!(err(&["m", "serial:/dev/ttyACM0"]).contains("write serial:DEVICE:BAUD"));
    assert_eq!(
        err(&["m", "--config", "x.conf", "tcp-client:a:1"]),
        "error: use either --config or endpoints: endpoints are a whole configuration\n"
    );
    assert_eq!(
        err(&["m", "--ast", "tcp-client:a:1"]),
        "error: --ast prints the syntax tree of a configuration file, and endpoints have no file\n"
    );
    assert_eq!(
        err(&[
            "m",
            "udp-server:0.0.0.0:14550",
            "udp-server:127.0.0.1:14550"
        ]),
        "error: endpoint 'udp-server:127.0.0.1:14550' clashes with endpoint \
         'udp-server:0.0.0.0:14550': both need udp 0.0.0.0:14550\n"
    );
    assert!(
        err(&["m", "serial:/dev/a:9600", "serial:/dev/a:57600"])
            .contains("both need serial /dev/a")
    );
    // TCP and UDP on one port do not clash; neither do two clients.
    let (o, out, _) = outcome(&[
        "m",
        "--check",
        "udp-server:0.0.0.0:5760",
        "tcp-server:0.0.0.0:5760",
        "udp-client:10.0.0.1:1",
        "udp-client:10.0.0.2:1",
    ]);
    assert!(matches!(o, mavtables::cli::Outcome::Exit(0)));
    assert_eq!(out, "command-line endpoints: configuration is valid\n");
}

#[test]
fn endpoints_through_the_binary() {
    let dir = scratch("endpoints");
    // A config found by the search does not matter when endpoints are given.
    std::fs::write(dir.join(".mavtablesrc"), "udp { port 70000; }\n").expect("write");
    let out = run_in(
        &dir,
        &[
            "--check",
            "serial:/dev/ttyACM0:115200",
            "udp-client:[::1]:14550",
        ],
        &[],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "command-line endpoints: configuration is valid\n"
    );
    // Without endpoints that config is used (and refused); other positionals are ignored.
    let out = run_in(&dir, &["--check", "ignored", "udp:1.2.3.4:5"], &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).starts_with("./.mavtablesrc:1:12: port number (70000)"));
    let out = run_in(&dir, &["udp-client:nohost"], &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).starts_with("error: endpoint 'udp-client:nohost': "));
    let out = run_in(&dir, &["--help"], &[]);
    let help = text(&out.stdout);
    for line in [
        "\n  serial:DEVICE:BAUD ",
        "\n  udp-server:ADDRESS:PORT ",
        "\n  udp-client:HOST:PORT ",
        "\n  tcp-server:ADDRESS:PORT ",
        "\n  tcp-client:HOST:PORT ",
        "\n  ws-server:ADDRESS:PORT ",
        "udp-client:[::1]:14550",
    ] {
        assert!(help.contains(line), "{line} missing from\n{help}");
    }
}

#[test]
fn the_example_configs_commented_blocks_are_valid() {
    let src = std::fs::read_to_string(repo("examples/mavtables.conf")).expect("example");
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in src.lines() {
        let body = line.strip_prefix("# ").unwrap_or("");
        if ["udp {", "tcp {", "serial {", "queue {"].contains(&body) {
            current = Some(String::new());
        }
        if let Some(block) = current.as_mut() {
            block.push_str(body);
            block.push('\n');
            if body == "}" {
                blocks.extend(current.take());
            }
        }
    }
    assert_eq!(blocks.len(), 4, "{blocks:?}");
    assert!(
        blocks
            .iter()
            .any(|b| b.contains("connect 127.0.0.1:14550;"))
    );
    for block in blocks {
        if let Err(e) = mavtables::config::load(&block) {
            panic!(
                "{}",
                mavtables::config::render_errors("example", &block, &e)
            );
        }
    }
}
