//! Headless Chromium (the Debian `chromium` package, which `scripts/test` installs) for
//! tests of the status page: load a URL, let its scripts run for a while of virtual time,
//! and take the rendered DOM or a screenshot. Every run is bounded in time. For pages
//! that talk over sockets, [`open`] runs the browser in real time until the test, having
//! seen the outcome on its own sockets, drops it.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use super::router::{Guard, Scratch};

/// The browser: `$MAVTABLES_CHROMIUM`, else `chromium` on the PATH. Panics with what to
/// do when there is none, so a missing browser fails the test instead of skipping it.
pub fn chromium() -> String {
    let bin = std::env::var("MAVTABLES_CHROMIUM").unwrap_or_else(|_| "chromium".into());
    let works = Command::new(&bin)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        works,
        "no headless browser: '{bin} --version' failed; run scripts/test (it installs the \
         chromium package) or name one in MAVTABLES_CHROMIUM"
    );
    bin
}

/// A browser left running on a page (in real time: virtual time would end the page while
/// its sockets are still busy). Dropping it kills the browser and its helpers (its
/// process group).
pub struct Browser {
    child: Option<std::process::Child>,
}

impl Drop for Browser {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let group = nix::unistd::Pid::from_raw(child.id() as i32);
            let _ = nix::sys::signal::killpg(group, nix::sys::signal::Signal::SIGKILL);
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Opens `url` in a headless browser of its own (profile in `scratch`, process group of
/// its own, output discarded) and leaves it running.
pub fn open(scratch: &Scratch, url: &str) -> Browser {
    use std::os::unix::process::CommandExt;
    let profile = scratch.dir.join("chromium-live");
    let child = Command::new(chromium())
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(url)
        .process_group(0)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn chromium");
    Browser { child: Some(child) }
}

/// Runs the browser headless on `url` with `extra` flags (a profile of its own in
/// `scratch`) and returns its standard output; panics if it fails or takes over 90 s.
fn run(scratch: &Scratch, url: &str, extra: &[String]) -> String {
    static RUNS: AtomicUsize = AtomicUsize::new(0);
    let profile = scratch
        .dir
        .join(format!("chromium-{}", RUNS.fetch_add(1, Ordering::Relaxed)));
    let mut child = Command::new(chromium())
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(url)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn chromium");
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let mut guard = Guard(Some(child));
    let status = guard.wait(Duration::from_secs(90));
    drop(guard);
    let stdout = reader.join().unwrap_or_default();
    let stderr = err_reader.join().unwrap_or_default();
    match status {
        Some(s) if s.success() => stdout,
        Some(s) => panic!("chromium exited with {s}: {stderr}"),
        None => panic!("chromium did not finish within 90 s: {stderr}"),
    }
}

/// The DOM of `url` after its scripts ran for `virtual_ms` of virtual time.
pub fn dom(scratch: &Scratch, url: &str, virtual_ms: u32) -> String {
    run(
        scratch,
        url,
        &[
            format!("--virtual-time-budget={virtual_ms}"),
            "--dump-dom".into(),
        ],
    )
}

/// Checks that `png` holds a picture of a page with something on it (a PNG of more
/// than 20 kB), and copies it where the environment variable `keep` names, if set.
pub fn check_screenshot(png: &Path, keep: &str) {
    let bytes = std::fs::read(png).expect("screenshot written");
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        bytes.len() > 20_000,
        "{} bytes: an empty page?",
        bytes.len()
    );
    if let Ok(path) = std::env::var(keep) {
        std::fs::copy(png, path).expect("keep screenshot");
    }
}

/// A 1280 × 900 screenshot of `url` after `virtual_ms` of virtual time, saved as `png`.
pub fn screenshot(scratch: &Scratch, url: &str, virtual_ms: u32, png: &Path) {
    run(
        scratch,
        url,
        &[
            format!("--virtual-time-budget={virtual_ms}"),
            "--window-size=1280,900".into(),
            format!("--screenshot={}", png.display()),
        ],
    );
}
