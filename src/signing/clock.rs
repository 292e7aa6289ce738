//! The router's signing clock: MAVLink 2 signature time (10 µs units since
//! 2015-01-01 00:00:00 UTC), kept from the wall clock the I/O layer reports and never
//! going back, not even across a restart (the saved state gives its floor).

use std::time::Duration;

use crate::time::Timestamp;
use crate::wire::signing::SigningTime;

/// 2015-01-01 00:00:00 UTC in seconds since the Unix epoch.
pub const EPOCH_2015_UNIX_SECS: u64 = 1_420_070_400;

/// Signature time units per second (one unit is 10 µs).
pub const UNITS_PER_SEC: u64 = 100_000;

/// The largest signature timestamp (48 bits).
pub const MAX_TIMESTAMP: SigningTime = (1 << 48) - 1;

/// Signature time of a wall-clock reading given as time since the Unix epoch (0 before
/// 2015).
pub(crate) fn units_from_unix(since_unix_epoch: Duration) -> SigningTime {
    let since_2015 = since_unix_epoch.saturating_sub(Duration::from_secs(EPOCH_2015_UNIX_SECS));
    let units = since_2015.as_micros() / 10;
    u64::try_from(units).unwrap_or(u64::MAX).min(MAX_TIMESTAMP)
}

/// Signature time units in `d`.
pub(crate) fn units_of(d: Duration) -> u64 {
    u64::try_from(d.as_micros() / 10).unwrap_or(u64::MAX)
}

/// The router's signing clock.
#[derive(Debug, Clone, Default)]
pub struct SigningClock {
    /// The last wall-clock reading: when (core time) and what (signature time).
    reading: Option<(Timestamp, SigningTime)>,
    /// Nothing earlier than this is told (the last timestamp issued or restored).
    floor: SigningTime,
}

impl SigningClock {
    /// Notes that at `now` the wall clock read `units` (signature time).
    pub(crate) fn set_wall(&mut self, now: Timestamp, units: SigningTime) {
        self.reading = Some((now, units));
    }

    /// Raises the floor to `units` (a timestamp from a previous run).
    pub(crate) fn raise_floor(&mut self, units: SigningTime) {
        self.floor = self.floor.max(units.min(MAX_TIMESTAMP));
    }

    /// Signature time at `now`: the wall clock advanced by core time since it was read,
    /// never below the floor.
    pub(crate) fn now(&self, now: Timestamp) -> SigningTime {
        let wall = self.reading.map_or(0, |(at, units)| {
            units.saturating_add(units_of(now.saturating_since(at)))
        });
        wall.max(self.floor).min(MAX_TIMESTAMP)
    }

    /// A timestamp for a signature the router makes at `now`: the clock's time, or one
    /// past the last one issued, whichever is later (strictly increasing).
    pub(crate) fn issue(&mut self, now: Timestamp) -> SigningTime {
        let t = self
            .now(now)
            .max(self.floor.saturating_add(1))
            .min(MAX_TIMESTAMP);
        self.floor = t;
        t
    }

    /// The floor to save: no timestamp issued so far is above it.
    pub(crate) fn floor(&self) -> SigningTime {
        self.floor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_2015_epoch_is_zero_and_units_are_10_us() {
        assert_eq!(
            units_from_unix(Duration::from_secs(EPOCH_2015_UNIX_SECS)),
            0
        );
        assert_eq!(units_from_unix(Duration::from_secs(10)), 0);
        let one_s_later = Duration::from_secs(EPOCH_2015_UNIX_SECS + 1) + Duration::from_micros(25);
        assert_eq!(units_from_unix(one_s_later), 100_002);
    }

    #[test]
    fn issued_timestamps_strictly_increase_and_follow_the_wall_clock() {
        let mut c = SigningClock::default();
        c.set_wall(Timestamp::ZERO, 1_000);
        assert_eq!(c.issue(Timestamp::ZERO), 1_000);
        assert_eq!(c.issue(Timestamp::ZERO), 1_001);
        assert_eq!(c.issue(Timestamp::ZERO), 1_002);
        assert_eq!(c.issue(Timestamp::from_secs(1)), 101_000);
        // The wall clock steps back: issued time does not.
        c.set_wall(Timestamp::from_secs(1), 0);
        assert_eq!(c.issue(Timestamp::from_secs(1)), 101_001);
    }

    #[test]
    fn a_restored_floor_holds_when_the_wall_clock_is_behind() {
        let mut c = SigningClock::default();
        c.set_wall(Timestamp::ZERO, 5);
        c.raise_floor(9_000_000);
        assert_eq!(c.now(Timestamp::ZERO), 9_000_000);
        assert_eq!(c.issue(Timestamp::ZERO), 9_000_001);
    }
}
