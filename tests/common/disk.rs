//! Disks for the tests of what the router writes: a small tmpfs (needs root) and file
//! dates set back, for the free-space and rotation rules.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A 1 MiB tmpfs mounted for one test, unmounted when dropped.
pub struct Tmpfs(PathBuf);

impl Tmpfs {
    /// Mounts one at `dir`; fails the test, saying what it needs, when it cannot.
    pub fn mount(dir: &Path) -> Tmpfs {
        fs::create_dir_all(dir).expect("mount point");
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=1m", "tmpfs"])
            .arg(dir)
            .output();
        match out {
            Ok(o) if o.status.success() => Tmpfs(dir.to_path_buf()),
            Ok(o) => panic!(
                "cannot mount a tmpfs ({}): the disk tests need root: run them as root (sudo scripts/test)",
                String::from_utf8_lossy(&o.stderr).trim()
            ),
            Err(e) => {
                panic!("cannot run mount ({e}): the disk tests need util-linux's mount, as root")
            }
        }
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// `year`-01-01 00:00:00 UTC.
pub fn new_year(year: i32) -> SystemTime {
    let days = (1970..year)
        .map(|y| if y % 4 == 0 { 366 } else { 365 })
        .sum::<u64>();
    UNIX_EPOCH + Duration::from_secs(days * 86_400)
}

/// Dates `path` back to `time` (its modification time: what rotation goes by).
pub fn date_back(path: &Path, time: SystemTime) {
    let file = fs::File::options()
        .write(true)
        .open(path)
        .expect("open to date back");
    file.set_modified(time).expect("set mtime");
}
