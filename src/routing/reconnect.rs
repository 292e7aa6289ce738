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
/// How long a connection must stay open for its loss to start the backoff afresh,
/// unless a frame came in on it. One lost sooner without a frame (a server that accepts
/// and closes at once: full, or refusing us) goes on with the backoff of the attempts
/// before it, so it is not opened again in a tight loop.
pub(crate) const STABLE: Duration = Duration::from_secs(2);

/// The state of a stream's connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Connection {
    /// Open: bytes flow.
    Open {
        /// When it opened.
        since: Timestamp,
        /// The wait before trying again if it is lost before [`STABLE`].
        backoff: Duration,
        /// The frames its interface had received when it opened.
        frames: u64,
    },
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

    /// Open at `now` (an accepted connection, which is never opened again).
    pub fn open(now: Timestamp) -> Self {
        Connection::Open {
            since: now,
            backoff: FIRST_BACKOFF,
            frames: 0,
        }
    }

    /// True when open.
    pub(crate) fn is_open(&self) -> bool {
        matches!(self, Connection::Open { .. })
    }

    /// It opened at `now`, its interface having received `frames` so far: the backoff of
    /// the attempts before is kept for a loss that comes soon (see [`STABLE`]).
    pub(crate) fn opened(&mut self, now: Timestamp, frames: u64) {
        let (Connection::Closed { backoff, .. } | Connection::Open { backoff, .. }) = *self;
        *self = Connection::Open {
            since: now,
            backoff,
            frames,
        };
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
            Connection::Open { .. } => FIRST_BACKOFF,
        };
        *self = Connection::Closed {
            retry_at: now + backoff,
            backoff: (backoff * 2).min(cap),
            asked: false,
        };
        backoff == FIRST_BACKOFF
    }

    /// The device was lost at `now` (it was open; its interface has received `frames`):
    /// try again after `first_wait`, then with the backoff doubling up to `cap` (failures
    /// after a loss are not said again: the loss was). Lost within [`STABLE`] of opening
    /// with no frame received meanwhile, it waits the backoff of the attempts before
    /// instead, doubled for the next: then it returns true.
    pub(crate) fn lost(
        &mut self,
        now: Timestamp,
        first_wait: Duration,
        cap: Duration,
        frames: u64,
    ) -> bool {
        match *self {
            Connection::Open {
                since,
                backoff,
                frames: before,
            } if now < since + STABLE && frames == before => {
                *self = Connection::Closed {
                    retry_at: now + backoff.max(first_wait),
                    backoff: (backoff * 2).min(cap).max(FIRST_BACKOFF),
                    asked: false,
                };
                true
            }
            _ => {
                *self = Connection::Closed {
                    retry_at: now + first_wait,
                    backoff: FIRST_BACKOFF * 2,
                    asked: false,
                };
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Opens `c` at `at`, loses it `open_for` later; returns when it is tried again.
    fn flap(c: &mut Connection, at: Timestamp, open_for: Duration, heard: u64) -> Timestamp {
        c.opened(at, 5);
        c.lost(at + open_for, Duration::ZERO, MAX_RECONNECT_WAIT, 5 + heard);
        c.retry_at().expect("closed")
    }

    #[test]
    fn a_connection_lost_right_after_it_opened_waits_longer_each_time() {
        let mut c = Connection::new(Timestamp::ZERO);
        let mut at = Timestamp::ZERO;
        let mut waits = Vec::new();
        for _ in 0..6 {
            let next = flap(&mut c, at, Duration::ZERO, 0);
            waits.push(next.saturating_since(at).as_millis());
            at = next;
        }
        assert_eq!(waits, [100, 200, 400, 800, 1000, 1000]);
        // One that stayed open starts afresh: at once, then from the first backoff.
        let next = flap(&mut c, at, STABLE, 0);
        assert_eq!(next, at + STABLE);
        let after = flap(&mut c, next, Duration::ZERO, 0);
        assert_eq!(after.saturating_since(next).as_millis(), 200);
        // So does one that brought a frame, however short.
        let again = flap(&mut c, after, Duration::ZERO, 1);
        assert_eq!(again, after);
    }
}
