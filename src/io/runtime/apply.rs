//! Applying a configuration in the event loop: the drivers for the interfaces the core
//! adds (at start and at a reload), and the reload itself (SIGHUP) — read the file
//! again, let the core decide what changes ([`Engine::configure`]), then close and open
//! exactly the sockets it names and restart what it says changed (recording, the
//! statistics endpoint, the signing state file). A file that does not load changes
//! nothing.
//!
//! [`Engine::configure`]: crate::routing::Engine::configure

use std::io;
use std::sync::Arc;

use mio::Waker;

use super::super::driver::Driver;
use super::super::log;
use super::super::serial::SerialDriver;
use super::super::tcp::{TcpListenerDriver, TcpStreamDriver};
use super::super::udp::UdpDriver;
use super::super::websocket;
use super::{
    RECORDER_FINISH, Runtime, open_state_file, start_flight_log, start_recording, start_stats,
};
use crate::config::{self, FromFile, Interface};
use crate::routing::{InterfaceId, Request, Timestamp};
use crate::signing::state::SavedState;

/// A driver for the core's new interface `id`, of block `iface`. A server binds now
/// (a port in use is an error naming the block); clients and serial ports open when the
/// core asks.
pub(super) fn driver_for(
    iface: &Interface,
    id: InterfaceId,
    waker: &Arc<Waker>,
) -> io::Result<Box<dyn Driver>> {
    Ok(match iface {
        Interface::Serial(s) => Box::new(SerialDriver::new(s, id)),
        Interface::Udp(u) => Box::new(UdpDriver::new(u, id, waker.clone())?),
        Interface::Tcp(t) if t.connect.is_none() => Box::new(TcpListenerDriver::bind(t, id)?),
        Interface::Tcp(t) => Box::new(TcpStreamDriver::client(t, id, waker.clone())),
        Interface::WebSocket(w) => Box::new(websocket::listener(w, id)?),
        #[cfg(feature = "zenoh")]
        Interface::Zenoh(z) => {
            Box::new(super::super::zenoh::ZenohDriver::new(z, id, waker.clone()))
        }
        // The configuration refuses a `zenoh` block in a router built without it.
        #[cfg(not(feature = "zenoh"))]
        Interface::Zenoh(_) => {
            return Err(io::Error::other(
                "zenoh: this router was built without Zenoh (cargo build --release --features zenoh)",
            ));
        }
    })
}

impl Runtime {
    /// Reads the configuration file again and applies it (SIGHUP), telling systemd
    /// around it. A file that cannot be read or does not load is reported, located, and
    /// the running configuration stays exactly as it was.
    pub(super) fn reload(&mut self, now: Timestamp) {
        if let Some(notifier) = &self.notifier {
            notifier.reloading();
        }
        // The loop is sound here; what follows may wait on disks for a few seconds.
        self.feed_watchdog_now(now);
        let status = match &self.source {
            None => {
                log::warn(
                    &"SIGHUP: the configuration came from command-line endpoints; there is no file to read again",
                );
                "routing (the configuration has no file to read again)".to_string()
            }
            Some(path) => match config::read_file(path) {
                Ok(file) => format!("routing; configuration reloaded: {}", self.apply(file, now)),
                Err(why) => {
                    log::stderr_text(&format!(
                        "error: configuration not reloaded, the running one is kept:\n{why}"
                    ));
                    "routing as before: the configuration file has errors, not reloaded (see the log)"
                        .to_string()
                }
            },
        };
        if let Some(notifier) = &self.notifier {
            notifier.ready_with(&status);
        }
    }

    /// Takes what the signing state file saved for the keys a reload added (`new_keys`,
    /// by fingerprint: say a key used before, taken out of the file and put back), so
    /// that their streams' last timestamps are known again and no old frame of theirs
    /// can be replayed. The streams of keys in use are left alone.
    fn restore_signing_state(&mut self, config: &config::Config, new_keys: &[[u8; 8]]) {
        let Some(path) = config.signing_state_path(|k| std::env::var(k).ok()) else {
            return;
        };
        let Ok(Some(bytes)) = config::read_signing_state(&path) else {
            return;
        };
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(mut state) = SavedState::parse(&text) {
            state.streams.retain(|s| new_keys.contains(&s.key));
            self.engine.restore_signing_streams(&state);
        }
    }

    /// The driver for the core's new interface `id`, of block `iface` (see
    /// [`driver_for`]). A UDP port still held by an interface the reload removed, which
    /// is sending its queue, is taken from it: that one closes now.
    fn make_driver(
        &mut self,
        iface: &Interface,
        id: InterfaceId,
        now: Timestamp,
    ) -> io::Result<Box<dyn Driver>> {
        let port = match iface {
            Interface::Udp(u) => Some(u.port),
            _ => None,
        };
        match driver_for(iface, id, &self.waker) {
            Err(e) if self.freed_port(&e, port, now) => driver_for(iface, id, &self.waker),
            made => made,
        }
    }

    /// Runs `file` from now on: the core keeps what did not change and names what the
    /// loop closes and opens.
    fn apply(&mut self, file: FromFile, now: Timestamp) -> String {
        for w in &file.warnings {
            log::warn(w);
        }
        let config = &file.config;
        let mut done = self.engine.configure(config, &file.keys, now);
        // A statistics endpoint that listens where it did only takes its new `allow`;
        // one that moves lets its port go before any interface opens (a reload may give
        // that port to one), and the new one starts after them.
        let stats_in_place = done.stats_changed
            && match (&self.stats, &config.stats) {
                (Some(server), Some(endpoint)) => server.reconfigure(endpoint),
                _ => false,
            };
        if done.stats_changed && !stats_in_place {
            self.stats = None;
        }
        for request in std::mem::take(&mut done.requests) {
            match request {
                Request::Close(id) => self.remove(id),
                Request::Retire(id) => self.retire(id),
                Request::Open(id, iface) => match self.make_driver(&iface, id, now) {
                    Ok(driver) => self.add(driver, false),
                    Err(e) => {
                        log::error(&format_args!(
                            "reload: cannot open {e}; it stays closed until a reload opens it"
                        ));
                        self.engine.unconfigure(id);
                        done.open_failed(id, "the error above; the next reload tries again");
                    }
                },
            }
        }
        for line in &done.details {
            log::stderr_text(&format!("reload: {line}\n"));
        }
        // Keys added by this reload sign from this turn on: the core learns the wall
        // clock now, whatever becomes of the state file.
        self.tell_wall_clock(now);
        if done.signing_state_changed {
            if let Some(file) = self.state_file.take() {
                self.feed_watchdog_now(self.now());
                file.finish(self.engine.signing_state(true, self.now()).as_ref());
            }
            match open_state_file(config, &mut self.engine, now) {
                Ok(file) => {
                    self.state_file = file;
                    log::stderr_text("reload: signing state file reopened\n");
                }
                // Checked before the reload; changed since: nothing is saved until the
                // next reload names a usable file.
                Err(e) => log::error(&format_args!(
                    "reload: {e}; the signing state is not saved until a reload names a usable file"
                )),
            }
        }
        if !done.new_keys.is_empty() && !done.signing_state_changed {
            self.restore_signing_state(config, &done.new_keys);
        }
        let wanted = config.flight_log.as_ref();
        if self.flight_log.as_ref().map(|w| w.config()) != wanted {
            // The engine ended the old log; its last writes go to the old writer.
            self.write_flight_log();
            if let Some(mut writer) = self.flight_log.take() {
                self.feed_watchdog_now(self.now());
                writer.finish(RECORDER_FINISH);
            }
            self.flight_log = start_flight_log(config);
        }
        if done.record_changed {
            self.record();
            if let Some(mut recorder) = self.recorder.take() {
                self.feed_watchdog_now(self.now());
                recorder.finish(RECORDER_FINISH);
            }
            self.engine.stop_recording();
            self.recorder = start_recording(config, &mut self.engine);
            match (&config.record, &self.recorder) {
                (None, _) => log::stderr_text("reload: recording stopped\n"),
                (Some(_), Some(_)) => log::stderr_text("reload: recording restarted\n"),
                // Said by the recorder; the next reload tries again.
                (Some(_), None) => self.engine.record_not_started(),
            }
        }
        if stats_in_place {
            log::stderr_text("reload: statistics endpoint's allow changed\n");
        } else if done.stats_changed {
            match start_stats(config) {
                Ok(None) => log::stderr_text("reload: statistics endpoint stopped\n"),
                Ok(Some(server)) => {
                    self.stats = Some(server);
                    log::stderr_text("reload: statistics endpoint restarted\n");
                }
                Err(e) => {
                    log::error(&format_args!("reload: {e}; the next reload tries again"));
                    self.engine.stats_not_started();
                }
            }
        }
        self.handle_notices(now);
        let summary = done.to_string();
        log::stderr_text(&format!("configuration reloaded: {summary}\n"));
        summary
    }
}
