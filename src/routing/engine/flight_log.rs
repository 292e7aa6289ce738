//! The engine's side of the flight log: the logger set up from the `flight_log` block
//! (kept across a reload that leaves the block as it was), its frames queued for the
//! vehicle's links with the router's own frames, and its file writes handed to the
//! event loop (which gives them to the writer thread).

use std::sync::Arc;

use super::Engine;
use crate::config::Config;
use crate::flight_log::{FlightLogCounters, FlightLogger, LogWrite};
use crate::routing::Timestamp;

impl Engine {
    /// Takes `config`'s `flight_log` block: a new logger when it is new or changed (the
    /// log being received then ends), none without it.
    pub(super) fn apply_flight_log(&mut self, config: &Config, now: Timestamp) {
        let same = match (&self.core.flight_log, &config.flight_log) {
            (Some(running), Some(wanted)) => running.config() == wanted,
            (None, None) => true,
            _ => false,
        };
        if same {
            return;
        }
        if let Some(old) = self.core.flight_log.as_mut() {
            old.shutdown(now);
            self.send_flight_log_frames();
        }
        // The old logger's last writes (its End) are taken before it goes.
        if let Some(mut old) = self.core.flight_log.take() {
            old.drain_writes(&mut |w| self.flight_log_leftover.push(w));
        }
        self.core.flight_log = config.flight_log.as_ref().map(FlightLogger::new);
    }

    /// Queues the flight log's frames on the links of its vehicle.
    pub(super) fn send_flight_log_frames(&mut self) {
        let Some(log) = self.core.flight_log.as_mut().filter(|l| l.has_frames()) else {
            return;
        };
        let system = log.system();
        let router = &mut self.core.router;
        let out = &mut self.core.out;
        log.drain_frames(&mut |frame| router.queue_own_to(system, &Arc::from(frame), out));
    }

    /// Hands what the flight log's file needs to `take`, oldest first: call it every
    /// loop turn when a `flight_log` block is configured.
    pub fn poll_flight_log(&mut self, take: &mut impl FnMut(LogWrite)) {
        for w in self.flight_log_leftover.drain(..) {
            take(w);
        }
        if let Some(log) = self.core.flight_log.as_mut() {
            log.drain_writes(take);
        }
    }

    /// Ends the log being received (at shutdown): the stop request is queued for the
    /// vehicle and the file is closed.
    pub fn stop_flight_log(&mut self, now: Timestamp) {
        if let Some(log) = self.core.flight_log.as_mut() {
            log.shutdown(now);
        }
        self.take_output();
    }

    /// The flight log's stream counters and the extension of the log being received,
    /// when a `flight_log` block is configured.
    pub fn flight_log_counters(&self) -> Option<(FlightLogCounters, Option<&'static str>)> {
        let log = self.core.flight_log.as_ref()?;
        Some((log.counters(), log.streaming().map(|p| p.extension())))
    }
}
