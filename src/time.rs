//! Time as a value: the sans-IO layers (routing, signing, recording) never read a clock;
//! the caller passes "now" in as a [`Timestamp`], a monotonic instant.

use std::ops::Add;
use std::time::Duration;

/// A point in time, measured from an arbitrary start (the I/O layer uses the router's
/// start; tests use zero). Monotonic by contract: callers never pass a smaller "now".
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp(Duration);

impl Timestamp {
    /// The start of time.
    pub const ZERO: Timestamp = Timestamp(Duration::ZERO);

    /// The instant `since_start` after the start.
    pub const fn new(since_start: Duration) -> Self {
        Timestamp(since_start)
    }

    /// The instant `secs` seconds after the start.
    pub const fn from_secs(secs: u64) -> Self {
        Timestamp(Duration::from_secs(secs))
    }

    /// The instant `millis` milliseconds after the start.
    pub const fn from_millis(millis: u64) -> Self {
        Timestamp(Duration::from_millis(millis))
    }

    /// The instant `nanos` nanoseconds after the start.
    pub const fn from_nanos(nanos: u64) -> Self {
        Timestamp(Duration::from_nanos(nanos))
    }

    /// Time since the start.
    pub const fn since_start(self) -> Duration {
        self.0
    }

    /// Nanoseconds since the start.
    pub(crate) const fn as_nanos(self) -> u128 {
        self.0.as_nanos()
    }

    /// Time from `earlier` to `self`, or zero if `earlier` is later.
    pub fn saturating_since(self, earlier: Timestamp) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
}

impl Add<Duration> for Timestamp {
    type Output = Timestamp;

    /// Saturates instead of overflowing.
    fn add(self, d: Duration) -> Timestamp {
        Timestamp(self.0.saturating_add(d))
    }
}
