//! The files mavtables is given by name — the configuration, key files, the signing
//! state — must be regular files of sane size: a device, a FIFO, a directory or a huge
//! file is refused at once, with the file named (and located at its statement), never
//! read. Every run here is bounded: killed after [`TIME_LIMIT`] and limited to
//! [`MEMORY_LIMIT`] of address space, so a regression fails instead of hanging or eating
//! the machine's memory.

use crate::common;

use std::fs::File;
use std::io::Read;
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use common::router::{BIN, Guard, Scratch};

/// How long one run may take before it is killed (a refusal takes milliseconds).
const TIME_LIMIT: Duration = Duration::from_secs(10);

/// The address space one run may have (`prlimit --as`): far more than `--check` needs,
/// far less than reading `/dev/zero` or a 1 GiB file would take.
const MEMORY_LIMIT: u64 = 512 << 20;

/// How a bounded run ended.
#[derive(Debug)]
struct Ran {
    /// The exit status; `None` when it was killed at the time limit (or by a signal).
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

/// Runs the binary with `args` in `dir`, a clean environment plus `env`, under the
/// memory and time limits.
fn run_bounded(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Ran {
    let mut cmd = Command::new("prlimit");
    cmd.arg(format!("--as={MEMORY_LIMIT}"))
        .arg("--")
        .arg(BIN)
        .args(args)
        .current_dir(dir)
        .env_clear()
        .env("HOME", dir)
        .envs(env.iter().copied())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("spawn prlimit mavtables");
    let read = |stream: Option<Box<dyn Read + Send>>| {
        thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut s) = stream {
                let _ = s.read_to_string(&mut text);
            }
            text
        })
    };
    let stdout = read(child.stdout.take().map(|s| Box::new(s) as _));
    let stderr = read(child.stderr.take().map(|s| Box::new(s) as _));
    let mut guard = Guard(Some(child));
    let started = Instant::now();
    let status = guard.wait(TIME_LIMIT);
    // Killed (and reaped) here if still running, which closes its output.
    drop(guard);
    let ran = Ran {
        code: status.and_then(|s| s.code()),
        stdout: stdout.join().expect("stdout reader"),
        stderr: stderr.join().expect("stderr reader"),
    };
    assert!(
        status.is_some(),
        "{args:?} still running after {:?}: {ran:?}",
        started.elapsed()
    );
    ran
}

/// Makes a FIFO at `path` with mode `mode`.
fn mkfifo(path: &Path, mode: u32) {
    let made = Command::new("mkfifo")
        .arg("-m")
        .arg(format!("{mode:o}"))
        .arg(path)
        .status()
        .expect("mkfifo");
    assert!(made.success(), "mkfifo {}", path.display());
}

/// A sparse file of `len` bytes at `path` with mode `mode` (nothing is written).
fn sparse(path: &Path, len: u64, mode: u32) {
    File::create(path)
        .and_then(|f| f.set_len(len))
        .expect("sparse file");
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).expect("chmod");
}

fn symlink(target: &str, path: &Path) {
    std::os::unix::fs::symlink(target, path).expect("symlink");
}

fn s(path: &Path) -> String {
    path.display().to_string()
}

/// Asserts that `ran` failed with status 1, printing nothing on stdout and `want` first
/// on stderr.
#[track_caller]
fn assert_refused(ran: &Ran, want: &str) {
    assert_eq!(ran.code, Some(1), "{ran:?}");
    assert_eq!(ran.stdout, "", "{ran:?}");
    assert!(
        ran.stderr.starts_with(want),
        "want {want:?} first in:\n{}",
        ran.stderr
    );
}

#[test]
fn a_configuration_must_be_a_regular_file_of_at_most_16_mib() {
    let scratch = Scratch::new("limits-config");
    let dir = &scratch.dir;
    let fifo = dir.join("fifo.conf");
    mkfifo(&fifo, 0o600);
    let zero = dir.join("zero.conf");
    symlink("/dev/zero", &zero);
    let huge = dir.join("huge.conf");
    sparse(&huge, (16 << 20) + 1, 0o644);
    let cases = [
        (s(Path::new("/dev/zero")), "is a character device"),
        (s(&zero), "is a character device"),
        (s(&fifo), "is a FIFO"),
        (s(dir), "is a directory"),
    ];
    for (path, what) in &cases {
        let want = format!("error: configuration file {path} {what}, not a regular file\n");
        for args in [
            &["--check", "--config", path][..],
            &["--config", path],
            &["--ast", "--config", path],
        ] {
            let ran = run_bounded(dir, args, &[]);
            assert_refused(&ran, &want);
            assert_eq!(ran.stderr, want);
        }
        // The statistics command reads the configuration the same way.
        let ran = run_bounded(dir, &["stats", "--config", path], &[]);
        assert_refused(&ran, &want);
    }
    let huge = s(&huge);
    let want = format!("error: configuration file {huge} is larger than the limit of 16 MiB\n");
    for args in [
        &["--check", "--config", &huge][..],
        &["stats", "--config", &huge],
    ] {
        assert_refused(&run_bounded(dir, args, &[]), &want);
    }
    // Found by the search rather than named: the same.
    let ran = run_bounded(dir, &["--check"], &[("MAVTABLES_CONFIG_PATH", &s(&fifo))]);
    assert_refused(
        &ran,
        &format!("error: configuration file {} is a FIFO", s(&fifo)),
    );
}

/// A configuration in `dir` whose interface has `signing_key KEY` (`state`: a
/// `signing_state` statement first); its path, and the column of KEY on line 2.
fn keyed_config(dir: &Path, key: &str, state: Option<&str>) -> (String, usize) {
    let conf = dir.join("m.conf");
    let first = state.map_or("# signing\n".to_string(), |p| {
        format!("signing_state {p};\n")
    });
    std::fs::write(
        &conf,
        format!(
            "{first}udp {{ address 127.0.0.1; port 0; signing_key {key}; }}\n\
             chain default {{ accept; }}\n"
        ),
    )
    .expect("write config");
    let col = "udp { address 127.0.0.1; port 0; signing_key ".len() + 1;
    (s(&conf), col)
}

#[test]
fn a_key_file_must_be_a_regular_file_of_at_most_4_kib() {
    let scratch = Scratch::new("limits-key");
    let dir = &scratch.dir;
    let zero = dir.join("zero.key");
    symlink("/dev/zero", &zero);
    let fifo = dir.join("fifo.key");
    mkfifo(&fifo, 0o600);
    let huge = dir.join("huge.key");
    sparse(&huge, 1 << 30, 0o600);
    let over = dir.join("over.key");
    sparse(&over, 4097, 0o600);
    let state = s(&dir.join("signing.state"));
    for (key, what) in [
        (&zero, "is a character device, not a regular file"),
        (&fifo, "is a FIFO, not a regular file"),
        (&huge, "is larger than the limit of 4 KiB"),
        (&over, "is larger than the limit of 4 KiB"),
    ] {
        let key = s(key);
        let (conf, col) = keyed_config(dir, &key, Some(&state));
        let want = format!(
            "{conf}:2:{col}: key file {key} {what}\n\
             udp {{ address 127.0.0.1; port 0; signing_key {key}; }}\n{}{}\n",
            " ".repeat(col - 1),
            "^".repeat(key.len()),
        );
        let ran = run_bounded(dir, &["--check", "--config", &conf], &[]);
        assert_refused(&ran, &want);
        // Refused at start too, before anything is opened.
        let ran = run_bounded(dir, &["--config", &conf], &[]);
        assert_refused(&ran, &want);
    }
    // 4 KiB exactly is still a key file (a passphrase of NUL bytes, as it happens).
    let full = dir.join("full.key");
    sparse(&full, 4096, 0o600);
    let (conf, _) = keyed_config(dir, &s(&full), Some(&state));
    let ran = run_bounded(dir, &["--check", "--config", &conf], &[]);
    assert_eq!(ran.code, Some(0), "{ran:?}");
}

#[test]
fn the_signing_state_must_be_a_state_file_mavtables_wrote_of_at_most_1_mib() {
    let scratch = Scratch::new("limits-state");
    let dir = &scratch.dir;
    let key = dir.join("k.key");
    std::fs::write(&key, "a passphrase\n").expect("key");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    let key = s(&key);
    let zero = dir.join("zero.state");
    symlink("/dev/zero", &zero);
    let fifo = dir.join("fifo.state");
    mkfifo(&fifo, 0o600);
    let huge = dir.join("huge.state");
    sparse(&huge, (1 << 20) + 1, 0o600);
    // A file of the user's that is not a state: renaming a new file over it would lose it.
    let text = dir.join("text.state");
    std::fs::write(&text, "my notes\n").expect("write");
    let note = "note: mavtables reads this file at start and saves the state by renaming a new file over it: name a file it wrote, or a path where none exists yet\n";
    for (state, what) in [
        (&zero, "is a character device, not a regular file"),
        (&fifo, "is a FIFO, not a regular file"),
        (&huge, "is larger than the limit of 1 MiB"),
        (dir, "is a directory, not a regular file"),
        (
            &text,
            "does not hold a mavtables signing state (its first line is not \"mavtables signing state 1\")",
        ),
    ] {
        let state = s(state);
        let (conf, _) = keyed_config(dir, &key, Some(&state));
        let col = "signing_state ".len() + 1;
        let want = format!(
            "{conf}:1:{col}: signing state file {state} {what}\n\
             signing_state {state};\n{}{}\n{note}",
            " ".repeat(col - 1),
            "^".repeat(state.len()),
        );
        let ran = run_bounded(dir, &["--check", "--config", &conf], &[]);
        assert_refused(&ran, &want);
        assert_eq!(ran.stderr, want);
        let ran = run_bounded(dir, &["--config", &conf], &[]);
        assert_refused(&ran, &want);
    }
    // The default path (in $STATE_DIRECTORY) is checked the same way, and named.
    let state_dir = dir.join("state");
    std::fs::create_dir(&state_dir).expect("state dir");
    mkfifo(&state_dir.join("signing.state"), 0o600);
    let (conf, _) = keyed_config(dir, &key, None);
    let env = [("STATE_DIRECTORY", s(&state_dir))];
    let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
    let want = format!(
        "error: signing state file {}/signing.state is a FIFO, not a regular file; mavtables reads",
        s(&state_dir)
    );
    for args in [&["--check", "--config", &conf][..], &["--config", &conf]] {
        assert_refused(&run_bounded(dir, args, &env), &want);
    }
    // Missing is fine: the file is written later. (Only --check: starting would run.)
    let (conf, _) = keyed_config(dir, &key, Some(&s(&dir.join("new.state"))));
    let ran = run_bounded(dir, &["--check", "--config", &conf], &[]);
    assert_eq!(ran.code, Some(0), "{ran:?}");
    // So is a state file of mavtables' own whose lines after the first are damaged: a
    // warning when the router starts, which then replaces it.
    let damaged = dir.join("damaged.state");
    std::fs::write(&damaged, "mavtables signing state 1\nclock x\n").expect("write");
    let (conf, _) = keyed_config(dir, &key, Some(&s(&damaged)));
    let ran = run_bounded(dir, &["--check", "--config", &conf], &[]);
    assert_eq!(ran.code, Some(0), "{ran:?}");
    assert_eq!(std::fs::read_to_string(&text).expect("read"), "my notes\n");
}
