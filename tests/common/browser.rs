//! Headless Chromium (the Debian `chromium` package, which `scripts/test` installs) for
//! tests of the status page: load a URL, let its scripts run for a while of virtual time,
//! and take the rendered DOM or a screenshot. Every run is bounded in time.

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
