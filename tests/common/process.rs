//! A child process in a process group of its own, its output read line by line; the
//! whole group is killed when it is dropped, so a failing assertion leaves nothing
//! behind.

use std::io::Write;
use std::os::unix::process::CommandExt;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::Duration;

use super::router::Lines;

/// A child in a process group of its own, with its stdout and stderr merged into one
/// line stream.
pub struct Proc {
    /// None once reaped.
    child: Option<Child>,
    stdin: Option<ChildStdin>,
    /// Its output, stdout and stderr merged.
    pub out: Lines,
}

impl Proc {
    /// Starts `cmd` (named `what` in messages) in a process group of its own.
    pub fn spawn(mut cmd: Command, what: &str) -> Proc {
        let (reader, writer) = std::io::pipe().expect("pipe");
        let err = writer.try_clone().expect("pipe clone");
        let mut child = cmd
            .process_group(0)
            .stdin(Stdio::piped())
            .stdout(writer)
            .stderr(err)
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {what}: {e}"));
        // `cmd` still holds the write ends; without dropping it the stream never closes.
        drop(cmd);
        Proc {
            stdin: child.stdin.take(),
            child: Some(child),
            out: Lines::new(reader, what),
        }
    }

    /// Writes `line` and a newline to its stdin.
    pub fn send_line(&mut self, line: &str) {
        let stdin = self.stdin.as_mut().expect("stdin open");
        stdin
            .write_all(format!("{line}\n").as_bytes())
            .and_then(|()| stdin.flush())
            .unwrap_or_else(|e| panic!("write {line:?}: {e}"));
    }

    /// Closes stdin (the helpers stop on its end) and reads the output until the
    /// stream closes, at most `timeout`; then kills whatever is left of the group.
    pub fn finish(&mut self, timeout: Duration) -> Vec<String> {
        self.stdin = None;
        let mut all = std::mem::take(&mut self.out.seen);
        all.extend(self.out.rest(timeout));
        self.out.seen.clone_from(&all);
        self.kill_group();
        all
    }

    fn kill_group(&mut self) {
        // The leader is reaped only here, after the kill, so its pid, which is the group's
        // id, cannot have been reused by then.
        let Some(mut child) = self.child.take() else {
            return;
        };
        let _ = nix::sys::signal::killpg(
            nix::unistd::Pid::from_raw(child.id() as i32),
            nix::sys::signal::Signal::SIGKILL,
        );
        let _ = child.wait();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.stdin = None;
        self.kill_group();
    }
}

impl Proc {
    /// The next output line containing `pattern`; panics if none comes within `timeout`.
    pub fn wait_for(&mut self, pattern: &str, timeout: Duration) -> String {
        self.out.wait_for(pattern, timeout)
    }
}
