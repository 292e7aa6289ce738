//! The configuration side of MAVLink 2 signing: `signing_key`, `allow_unsigned`,
//! `signing_state` and `if signed|unsigned`, their model, `--ast` and located errors, key
//! files (format, permissions) and that nothing secret is ever printed.

use crate::common;

use mavtables::address::{Address, Subnet};
use mavtables::config::{self, Condition, Config, Interface, InterfaceSigning, print_tree};
use mavtables::signing::SigningKey;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_mavtables");
const PASSPHRASE: &str = "Tr0ub4dor&3 over the hills";
const HEX_KEY: &str = "8f1e5b0c3a7d29e4b6c1f0a2d3e4f5061728394a5b6c7d8e9fa0b1c2d3e4f5a6";

fn load(src: &str) -> Config {
    match config::load(src) {
        Ok(l) => l.config,
        Err(e) => panic!("{}", config::render_errors("t", src, &e)),
    }
}

/// Every error of `src`, rendered for a file named `f`.
fn errors(src: &str) -> String {
    match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => config::render_errors("f", src, &e),
    }
}

fn tree(src: &str) -> String {
    match config::parse(src) {
        Ok(ast) => print_tree(&ast),
        Err(d) => panic!("{}", d.render("t", src)),
    }
}

/// A fresh empty directory under the target dir, named after the test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("signing-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// Writes `contents` to `dir/name` with permission bits `mode`; returns its path.
fn key_file(dir: &Path, name: &str, contents: &str, mode: u32) -> String {
    let path = dir.join(name);
    std::fs::write(&path, contents).expect("write key file");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
    path.display().to_string()
}

fn signing(key_file: &str, allow_unsigned: bool) -> Option<InterfaceSigning> {
    Some(InterfaceSigning {
        key_file: key_file.into(),
        allow_unsigned,
    })
}

#[test]
fn every_interface_kind_takes_a_key_and_allow_unsigned() {
    let c = load(
        "udp { port 14550; signing_key /etc/mavtables/gcs.key; }\n\
         tcp { signing_key keys/mavproxy.key; allow_unsigned yes; }\n\
         serial { device /dev/ttyACM0; allow_unsigned no; signing_key /k; }\n\
         udp { port 14551; }",
    );
    let got: Vec<_> = c.interfaces.iter().map(|i| i.signing().cloned()).collect();
    assert_eq!(
        got,
        [
            signing("/etc/mavtables/gcs.key", false),
            signing("keys/mavproxy.key", true),
            signing("/k", false),
            None,
        ]
    );
    assert!(matches!(&c.interfaces[0], Interface::Udp(u) if u.signing == got[0]));
    assert!(matches!(&c.interfaces[1], Interface::Tcp(t) if t.signing == got[1]));
    assert!(matches!(&c.interfaces[2], Interface::Serial(s) if s.signing == got[2]));
}

#[test]
fn repeated_statements_count_with_their_last_value() {
    let c = load(
        "udp { signing_key /a; allow_unsigned yes; signing_key /b; allow_unsigned no; }\n\
         serial { device /dev/x; allow_unsigned no; signing_key /c; allow_unsigned yes; }",
    );
    assert_eq!(c.interfaces[0].signing(), signing("/b", false).as_ref());
    assert_eq!(c.interfaces[1].signing(), signing("/c", true).as_ref());
}

#[test]
fn signing_state_and_its_defaults() {
    let no_env = |_: &str| None;
    // No interface has a key: no state file, written or not.
    let c = load("signing_state /tmp/s.state;\nudp {}");
    assert_eq!(c.signing_state.as_deref(), Some("/tmp/s.state"));
    assert_eq!(c.signing_state_path(no_env), None);
    assert_eq!(load("udp {}").signing_state, None);

    let keyed = "udp { signing_key /k; }";
    let c = load(keyed);
    assert_eq!(
        c.signing_state_path(no_env),
        Some(PathBuf::from("/var/lib/mavtables/signing.state"))
    );
    let systemd = |k: &str| (k == "STATE_DIRECTORY").then(|| "/var/lib/mavtables:/x".into());
    assert_eq!(
        c.signing_state_path(systemd),
        Some(PathBuf::from("/var/lib/mavtables/signing.state"))
    );
    let elsewhere = |k: &str| (k == "STATE_DIRECTORY").then(|| "/srv/state".into());
    assert_eq!(
        c.signing_state_path(elsewhere),
        Some(PathBuf::from("/srv/state/signing.state"))
    );
    let empty = |_: &str| Some(String::new());
    assert_eq!(
        c.signing_state_path(empty),
        Some(PathBuf::from("/var/lib/mavtables/signing.state"))
    );
    // Written: used as is, whatever the environment; the last one counts.
    let c = load(&format!(
        "signing_state a.state; {keyed} signing_state /run/m/b.state;"
    ));
    assert_eq!(
        c.signing_state_path(elsewhere),
        Some(PathBuf::from("/run/m/b.state"))
    );
}

#[test]
fn conditions_on_the_signed_bit() {
    let c = load(
        "chain default {\n\
           reject if unsigned COMMAND_LONG;\n\
           accept if signed from 255.0/8;\n\
           accept with priority 3 if signed;\n\
           accept if unsigned to 1.1;\n\
           accept if HEARTBEAT;\n\
         }",
    );
    let r: Vec<Condition> = c
        .chain(c.default_chain)
        .rules
        .iter()
        .map(|r| r.condition)
        .collect();
    let command_long = mavtables::dialect::by_name("COMMAND_LONG").map(|m| m.id);
    assert_eq!(
        r[0],
        Condition {
            signed: Some(false),
            message_id: command_long,
            source: None,
            dest: None,
        }
    );
    assert_eq!(r[1].signed, Some(true));
    assert_eq!(r[1].source, Subnet::with_prefix(Address::new(255, 0), 8));
    assert_eq!(
        r[2],
        Condition {
            signed: Some(true),
            ..Condition::default()
        }
    );
    assert_eq!(r[3].signed, Some(false));
    assert_eq!(r[4].signed, None);
    let (a, b) = (Address::new(255, 190), Address::new(1, 1));
    assert!(r[1].matches(0, a, b, true));
    assert!(!r[1].matches(0, a, b, false));
    assert!(r[4].matches(0, a, b, true) && r[4].matches(0, a, b, false));
    // `signed` is a keyword only where a condition starts: a chain may be called so.
    let c = load("chain default { call signed if signed; }\nchain signed { accept; }");
    assert_eq!(
        c.chain(c.default_chain).rules[0].condition.signed,
        Some(true)
    );
}

#[test]
fn ast_prints_every_new_node() {
    let src = "signing_state /var/lib/mavtables/signing.state;\n\
               udp {\n    port 14550;\n    signing_key /etc/mavtables/gcs.key;\n    allow_unsigned yes;\n}\n\
               tcp { signing_key k.key; allow_unsigned no; }\n\
               serial {\n    device /dev/ttyACM0;\n    signing_key /etc/mavtables/fc.key;\n}\n\
               chain default {\n    reject if unsigned COMMAND_LONG;\n    accept with priority 2 if signed from 255.0/8;\n    accept if\n        signed;\n}\n";
    assert_eq!(
        tree(src),
        ":001:  signing_state /var/lib/mavtables/signing.state\n\
         :002:  udp\n\
         :003:  |  port 14550\n\
         :004:  |  signing_key /etc/mavtables/gcs.key\n\
         :005:  |  allow_unsigned yes\n\
         :007:  tcp\n\
         :007:  |  signing_key k.key\n\
         :007:  |  allow_unsigned no\n\
         :008:  serial\n\
         :009:  |  device /dev/ttyACM0\n\
         :010:  |  signing_key /etc/mavtables/fc.key\n\
         :012:  chain default\n\
         :013:  |  reject\n\
         :013:  |  |  condition\n\
         :013:  |  |  |  unsigned\n\
         :013:  |  |  |  packet_type COMMAND_LONG\n\
         :014:  |  accept\n\
         :014:  |  |  priority 2\n\
         :014:  |  |  condition\n\
         :014:  |  |  |  signed\n\
         :014:  |  |  |  source 255.0/8\n\
         :015:  |  accept\n\
         :015:  |  |  condition\n\
         :016:  |  |  |  signed\n"
    );
    load(src);
}

#[test]
fn statement_errors_are_located() {
    assert_eq!(
        errors("udp {\n    port 14550;\n    allow_unsigned yes;\n}"),
        "f:3:5: 'allow_unsigned' needs a 'signing_key' in the same block\n    \
         allow_unsigned yes;\n    ^^^^^^^^^^^^^^\n\
         note: only a block with a signing key checks signatures; add 'signing_key PATH;' or leave out 'allow_unsigned'\n"
    );
    // Also in tcp and serial blocks, and with the other errors of the file.
    let all =
        errors("tcp { allow_unsigned no; }\nserial { device /d; allow_unsigned yes; baudrate 0; }");
    assert!(
        all.starts_with("f:1:7: 'allow_unsigned' needs a 'signing_key' in the same block\n"),
        "{all}"
    );
    assert!(
        all.contains("f:2:50: baud rate (0) is outside of the allowed range"),
        "{all}"
    );
    assert!(
        all.contains("f:2:21: 'allow_unsigned' needs a 'signing_key' in the same block\n"),
        "{all}"
    );
    assert_eq!(
        errors("udp { signing_key /k; allow_unsigned maybe; }"),
        "f:1:38: expected 'yes' or 'no'\nudp { signing_key /k; allow_unsigned maybe; }\n                                     ^^^^^\n"
    );
    assert!(
        errors("serial { device /d; allow_unsigned; }")
            .starts_with("f:1:35: expected 'yes' or 'no'\n")
    );
    assert!(
        errors("udp {\n    signing_key;\n}")
            .starts_with("f:2:16: expected the path of a signing key file\n")
    );
    assert!(
        errors("signing_state ;")
            .starts_with("f:1:15: expected the path of the signing state file\n")
    );
    assert!(
        errors("signing_state /a /b;")
            .starts_with("f:1:18: expected end of statement ';' character\n")
    );
    let misplaced = errors("signing_key /k;");
    assert!(
        misplaced.starts_with("f:1:1: unsupported statement\n"),
        "{misplaced}"
    );
    assert!(
        misplaced.contains(
            "note: 'signing_key' belongs in a 'udp' or 'tcp' or 'serial' or 'zenoh' block"
        ),
        "{misplaced}"
    );
    assert!(errors("queue { allow_unsigned yes; }").contains("belongs in a 'udp'"));
}

#[test]
fn condition_errors_are_located() {
    // After the type it is too late: the note shows the order.
    assert_eq!(
        errors("chain default { accept if PING signed; }"),
        "f:1:32: expected end of statement ';' character\n\
         chain default { accept if PING signed; }\n                               ^^^^^^\n\
         note: a rule is written: ACTION [with priority N] [if [signed|unsigned] [TYPE] [from SUBNET] [to SUBNET]];\n"
    );
    assert!(
        errors("chain default { accept if Signed; }")
            .starts_with("f:1:27: condition is empty or invalid\n")
    );
    assert!(
        errors("chain default { accept if signed unsigned; }")
            .starts_with("f:1:34: condition is empty or invalid\n")
    );
    assert!(
        errors("chain default { accept if signedPING; }")
            .starts_with("f:1:27: condition is empty or invalid\n")
    );
    assert!(
        errors("chain default { accept if signed HEARTBEET; }")
            .starts_with("f:1:34: Invalid packet name (\"HEARTBEET\").\n")
    );
}

/// `read_keys` of `src`, its errors rendered for a file named `f`.
fn read_keys(src: &str) -> Result<Vec<Option<SigningKey>>, String> {
    let c = load(src);
    config::read_keys(&c, src).map_err(|e| config::render_errors("f", src, &e))
}

#[test]
fn keys_are_read_for_each_interface_in_order() {
    let dir = scratch("read");
    let pass = key_file(&dir, "pass.key", &format!("{PASSPHRASE}\n"), 0o600);
    let hex = key_file(&dir, "hex.key", &format!("{HEX_KEY}\r\n"), 0o400);
    let src = format!(
        "udp {{ signing_key {pass}; }}\nudp {{ port 1; }}\nserial {{ device /d; signing_key {hex}; }}"
    );
    let keys = read_keys(&src).expect("keys");
    let mut raw = [0u8; 32];
    for (i, b) in raw.iter_mut().enumerate() {
        *b = u8::from_str_radix(&HEX_KEY[2 * i..2 * i + 2], 16).expect("hex");
    }
    assert_eq!(
        keys,
        [
            Some(SigningKey::from_passphrase(PASSPHRASE)),
            None,
            Some(SigningKey::from_bytes(raw)),
        ]
    );
}

#[test]
fn a_key_others_can_read_is_refused_naming_its_mode() {
    let dir = scratch("mode");
    let path = key_file(&dir, "open.key", PASSPHRASE, 0o644);
    let src = format!("udp {{\n    signing_key {path};\n}}\n");
    let col = "    signing_key ".len() + 1;
    let want = format!(
        "f:2:{col}: key file {path} can be read or written by other users (mode 0644)\n    \
         signing_key {path};\n{}{}\n\
         note: a signing key must be private to its owner: run 'chmod 600 {path}'\n",
        " ".repeat(col - 1),
        "^".repeat(path.len()),
    );
    assert_eq!(read_keys(&src), Err(want));
    for mode in [0o640, 0o604, 0o620, 0o660, 0o602, 0o610] {
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
        let e = read_keys(&src).expect_err("refused");
        assert!(e.contains(&format!("(mode {mode:04o})")), "{e}");
    }
    for mode in [0o600, 0o400, 0o700] {
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).expect("chmod");
        assert!(read_keys(&src).is_ok(), "mode {mode:o}");
    }
}

#[test]
fn missing_empty_and_odd_key_files_are_located_errors() {
    let dir = scratch("bad");
    let missing = dir.join("nope.key").display().to_string();
    let empty = key_file(&dir, "empty.key", "", 0o600);
    let blank = key_file(&dir, "blank.key", " \n", 0o600);
    let directory = dir.display().to_string();
    let src = format!(
        "udp {{ signing_key {missing}; }}\ntcp {{ signing_key {empty}; }}\n\
         serial {{ device /d; signing_key {blank}; }}\nudp {{ port 9; signing_key {directory}; }}\n"
    );
    let e = read_keys(&src).expect_err("errors");
    let want = format!(
        "f:1:19: key file {missing} does not exist\n\
         udp {{ signing_key {missing}; }}\n                  {}\n\
         f:2:19: key file {empty} is empty\n\
         tcp {{ signing_key {empty}; }}\n                  {}\n\
         note: write the key as 64 hexadecimal digits, or a passphrase (the key is its SHA-256, as MAVProxy's 'signing setup')\n\
         f:3:33: key file {blank} is empty\n\
         serial {{ device /d; signing_key {blank}; }}\n                                {}\n\
         note: write the key as 64 hexadecimal digits, or a passphrase (the key is its SHA-256, as MAVProxy's 'signing setup')\n\
         f:4:27: key file {directory} is a directory, not a regular file\n\
         udp {{ port 9; signing_key {directory}; }}\n                          {}\n",
        "^".repeat(missing.len()),
        "^".repeat(empty.len()),
        "^".repeat(blank.len()),
        "^".repeat(directory.len()),
    );
    assert_eq!(e, want);
}

#[test]
fn passphrase_keys_equal_pythons_hashlib() {
    let dir = scratch("python");
    let path = key_file(&dir, "p.key", &format!("{PASSPHRASE}\n"), 0o600);
    let ours = SigningKey::read_file(Path::new(&path)).expect("key");
    let out = Command::new(common::python())
        .args([
            "-c",
            "import hashlib, sys; print(hashlib.sha256(sys.argv[1].encode()).hexdigest())",
            PASSPHRASE,
        ])
        .output()
        .expect("python");
    assert!(out.status.success());
    let python = String::from_utf8_lossy(&out.stdout).trim().to_string();
    assert_eq!(common::hex(ours.as_bytes()), python);
}

/// Runs the binary with `args` in `dir`.
fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .env_clear()
        .env("HOME", dir)
        .output()
        .expect("run mavtables")
}

/// Fails if anything of the secrets shows in what the binary printed.
#[track_caller]
fn assert_no_secret(out: &Output) {
    let all = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let derived = common::hex(SigningKey::from_passphrase(PASSPHRASE).as_bytes());
    for secret in [
        PASSPHRASE,
        "Tr0ub4dor",
        HEX_KEY,
        &HEX_KEY[..16],
        &derived[..16],
    ] {
        assert!(!all.contains(secret), "{secret:?} printed in:\n{all}");
    }
}

#[test]
fn the_binary_never_prints_a_key() {
    let dir = scratch("bin");
    let pass = key_file(&dir, "pass.key", PASSPHRASE, 0o600);
    let hex = key_file(&dir, "hex.key", HEX_KEY, 0o600);
    let conf = dir.join("m.conf");
    let conf_s = conf.display().to_string();
    std::fs::write(
        &conf,
        format!(
            "udp {{ signing_key {pass}; allow_unsigned yes; }}\n\
             serial {{ device /dev/null; signing_key {hex}; }}\n\
             chain default {{ accept if signed; }}\n"
        ),
    )
    .expect("conf");

    let out = run(&dir, &["--check", "--config", &conf_s]);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        format!("{conf_s}: configuration is valid\n")
    );
    assert_no_secret(&out);

    let out = run(&dir, &["--ast", "--config", &conf_s]);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let ast = String::from_utf8_lossy(&out.stdout);
    assert!(
        ast.contains(&format!(":001:  |  signing_key {pass}\n")),
        "{ast}"
    );
    assert_no_secret(&out);

    // A key others can read: refused by --check, and the error shows only the path.
    std::fs::set_permissions(&hex, std::fs::Permissions::from_mode(0o644)).expect("chmod");
    let out = run(&dir, &["--check", "--config", &conf_s]);
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stdout.is_empty());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with(&format!(
            "{conf_s}:2:40: key file {hex} can be read or written by other users (mode 0644)\n"
        )),
        "{err}"
    );
    assert!(err.contains(&format!("run 'chmod 600 {hex}'")), "{err}");
    assert_no_secret(&out);

    // The same when running: nothing is opened, nothing secret is said.
    let out = run(&dir, &["--config", &conf_s]);
    assert_eq!(out.status.code(), Some(1));
    assert_no_secret(&out);
}

/// A `zenoh` block is an interface like the others: a key error after it (or in it) is
/// located at its own `signing_key` statement, not at the file's start.
#[cfg(feature = "zenoh")]
#[test]
fn key_errors_after_a_zenoh_block_are_located_at_their_statement() {
    let dir = scratch("zenoh-located");
    let good = key_file(&dir, "good.key", PASSPHRASE, 0o600);
    let open = key_file(&dir, "open.key", PASSPHRASE, 0o644);
    for (zenoh_key, udp_key, line, col, bad) in [
        (&good, &open, 2, "udp { signing_key ".len() + 1, &open),
        (
            &open,
            &good,
            1,
            "zenoh { mode peer; listen tcp/127.0.0.1:7447; prefix p; signing_key ".len() + 1,
            &open,
        ),
    ] {
        let src = format!(
            "zenoh {{ mode peer; listen tcp/127.0.0.1:7447; prefix p; signing_key {zenoh_key}; }}\nudp {{ signing_key {udp_key}; }}\n"
        );
        let e = read_keys(&src).expect_err("refused");
        assert!(
            e.starts_with(&format!(
                "f:{line}:{col}: key file {bad} can be read or written"
            )),
            "{e}"
        );
    }
}
