//! Time as a value: the sans-IO layers (routing, signing, recording) never read a clock;
//! the caller passes "now" in as a [`Timestamp`], a monotonic instant.

use std::fmt;
use std::ops::Add;
use std::time::Duration;

/// A point in time, measured from an arbitrary start (the I/O layer uses the router's
/// start; tests use zero). Monotonic by contract: callers never pass a smaller "now".
/// Held as nanoseconds in one `u64` (584 years), so that the comparisons and sums every
/// frame makes are single instructions; later instants saturate.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp(u64);

/// The nanoseconds of `d`, saturating at `u64::MAX`.
const fn nanos_of(d: Duration) -> u64 {
    d.as_secs()
        .saturating_mul(1_000_000_000)
        .saturating_add(d.subsec_nanos() as u64)
}

impl Timestamp {
    /// The start of time.
    pub const ZERO: Timestamp = Timestamp(0);

    /// The instant `since_start` after the start.
    pub const fn new(since_start: Duration) -> Self {
        Timestamp(nanos_of(since_start))
    }

    /// The instant `secs` seconds after the start.
    pub const fn from_secs(secs: u64) -> Self {
        Timestamp(secs.saturating_mul(1_000_000_000))
    }

    /// The instant `millis` milliseconds after the start.
    pub const fn from_millis(millis: u64) -> Self {
        Timestamp(millis.saturating_mul(1_000_000))
    }

    /// The instant `nanos` nanoseconds after the start.
    pub const fn from_nanos(nanos: u64) -> Self {
        Timestamp(nanos)
    }

    /// Time since the start.
    pub const fn since_start(self) -> Duration {
        Duration::from_nanos(self.0)
    }

    /// Nanoseconds since the start.
    pub(crate) const fn as_nanos(self) -> u128 {
        self.0 as u128
    }

    /// Time from `earlier` to `self`, or zero if `earlier` is later.
    pub fn saturating_since(self, earlier: Timestamp) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl fmt::Debug for Timestamp {
    /// As the time since the start (`Timestamp(1.5s)`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Timestamp")
            .field(&self.since_start())
            .finish()
    }
}

impl Add<Duration> for Timestamp {
    type Output = Timestamp;

    /// Saturates instead of overflowing.
    fn add(self, d: Duration) -> Timestamp {
        Timestamp(self.0.saturating_add(nanos_of(d)))
    }
}
