//! The systemd notification protocol (`sd_notify`), for a unit of `Type=notify`: one
//! datagram of `KEY=VALUE` lines to the unix socket named in `$NOTIFY_SOCKET` (a path,
//! or an abstract name written `@name`) for each state change — `READY=1` once the
//! interfaces are open, `RELOADING=1` with `MONOTONIC_USEC=` and `READY=1` again around
//! a reload, `STOPPING=1` at shutdown — and `WATCHDOG=1` at half the interval given in
//! `$WATCHDOG_USEC`, which the event loop sends from its own turns: a loop that is
//! stuck stops feeding the watchdog, and systemd restarts the service.
//!
//! Without `$NOTIFY_SOCKET` (not under systemd) there is no notifier and nothing is
//! sent. A message that cannot be sent is dropped: the router never stops for it.

use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr, UnixDatagram};
use std::time::Duration;

use super::sys;

/// Where systemd listens, and the watchdog interval it asked for.
pub(super) struct Notifier {
    socket: UnixDatagram,
    to: SocketAddr,
    watchdog: Option<Duration>,
}

impl Notifier {
    /// The notifier `$NOTIFY_SOCKET` and `$WATCHDOG_USEC` (for this process, if
    /// `$WATCHDOG_PID` names one) ask for; `None` when not under systemd.
    pub(super) fn from_env() -> Option<Notifier> {
        let env = |k: &str| std::env::var(k).ok();
        let path = env("NOTIFY_SOCKET").filter(|p| !p.is_empty())?;
        let to = match path.strip_prefix('@') {
            Some(name) => SocketAddr::from_abstract_name(name.as_bytes()),
            None => SocketAddr::from_pathname(&path),
        };
        let to = match to {
            Ok(to) => to,
            Err(e) => {
                super::log::warn(&format_args!("NOTIFY_SOCKET={path}: {e}"));
                return None;
            }
        };
        let socket = match UnixDatagram::unbound() {
            Ok(s) => s,
            Err(e) => {
                super::log::warn(&format_args!("NOTIFY_SOCKET: {e}"));
                return None;
            }
        };
        let for_us = env("WATCHDOG_PID")
            .is_none_or(|pid| pid.trim().parse::<u32>().ok() == Some(std::process::id()));
        let watchdog = env("WATCHDOG_USEC")
            .and_then(|v| v.trim().parse::<u64>().ok())
            .filter(|&us| us > 0 && for_us)
            .map(|us| Duration::from_micros(us / 2).max(Duration::from_millis(1)));
        // Non-blocking: a full queue at systemd drops a message rather than the loop.
        let _ = socket.set_nonblocking(true);
        Some(Notifier {
            socket,
            to,
            watchdog,
        })
    }

    /// How often the watchdog wants `WATCHDOG=1` (half of `$WATCHDOG_USEC`), if at all.
    pub(super) fn watchdog_interval(&self) -> Option<Duration> {
        self.watchdog
    }

    fn send(&self, message: &str) {
        let _ = self.socket.send_to_addr(message.as_bytes(), &self.to);
    }

    /// `READY=1`: started.
    pub(super) fn ready(&self) {
        self.ready_with("routing");
    }

    /// `READY=1` with `status` (one line: what `systemctl status` shows), after a reload
    /// that worked or did not.
    pub(super) fn ready_with(&self, status: &str) {
        let status = status.replace(['\n', '\r'], " ");
        self.send(&format!("READY=1\nSTATUS={status}\n"));
    }

    /// `RELOADING=1` with the monotonic time the reload began.
    pub(super) fn reloading(&self) {
        self.send(&format!(
            "RELOADING=1\nSTATUS=reloading the configuration\nMONOTONIC_USEC={}\n",
            sys::monotonic_micros()
        ));
    }

    /// `STOPPING=1`: shutting down.
    pub(super) fn stopping(&self) {
        self.send("STOPPING=1\nSTATUS=stopping\n");
    }

    /// `WATCHDOG=1`: the loop is alive.
    pub(super) fn watchdog(&self) {
        self.send("WATCHDOG=1\n");
    }
}
