//! Whether an interface that opens (a serial port, a TCP or UDP client) is open, and when
//! to try opening it again: at once at start, then with a backoff doubling from
//! [`FIRST_BACKOFF`] to [`MAX_BACKOFF`] while it stays missing.

use std::time::Duration;

use crate::time::Timestamp;

/// First wait before trying again to open a missing device.
pub(crate) const FIRST_BACKOFF: Duration = Duration::from_millis(100);
/// Longest wait between attempts to open a missing device.
pub(crate) const MAX_BACKOFF: Duration = Duration::from_secs(2);
/// Longest wait between attempts of a TCP client to reach its server, so that it is
/// connected again within a second of the server's return.
pub(crate) const MAX_RECONNECT_WAIT: Duration = Duration::from_secs(1);

/// The state of a stream's connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Connection {
    /// Open: bytes flow.
    Open,
    /// Closed; try again at `retry_at`.
    Closed {
        /// When the next attempt is due.
        retry_at: Timestamp,
        /// The wait after the next failure.
        backoff: Duration,
        /// The driver was asked to open it and has not answered yet.
        asked: bool,
    },
}

impl Connection {
    /// Closed, to be opened at `now`.
    pub fn new(now: Timestamp) -> Self {
        Connection::Closed {
            retry_at: now,
            backoff: FIRST_BACKOFF,
            asked: false,
        }
    }

    /// True when open.
    pub(crate) fn is_open(&self) -> bool {
        *self == Connection::Open
    }

    /// When an attempt is due and not yet asked for.
    pub(crate) fn retry_at(&self) -> Option<Timestamp> {
        match *self {
            Connection::Closed {
                retry_at,
                asked: false,
                ..
            } => Some(retry_at),
            _ => None,
        }
    }

    /// If an attempt is due at `now`, marks it asked for and returns true.
    pub(crate) fn ask_if_due(&mut self, now: Timestamp) -> bool {
        match self {
            Connection::Closed {
                retry_at, asked, ..
            } if !*asked && *retry_at <= now => {
                *asked = true;
                true
            }
            _ => false,
        }
    }

    /// The attempt failed at `now`: wait the backoff, then double it up to `cap`.
    /// Returns true if this is the first failure of an outage (the one worth saying).
    pub(crate) fn failed(&mut self, now: Timestamp, cap: Duration) -> bool {
        let backoff = match *self {
            Connection::Closed { backoff, .. } => backoff,
            Connection::Open => FIRST_BACKOFF,
        };
        *self = Connection::Closed {
            retry_at: now + backoff,
            backoff: (backoff * 2).min(cap),
            asked: false,
        };
        backoff == FIRST_BACKOFF
    }

    /// The device was lost at `now` (it was open): try again after `first_wait`, then
    /// with the backoff (failures after a loss are not said again: the loss was).
    pub(crate) fn lost(&mut self, now: Timestamp, first_wait: Duration) {
        *self = Connection::Closed {
            retry_at: now + first_wait,
            backoff: FIRST_BACKOFF * 2,
            asked: false,
        };
    }
}
