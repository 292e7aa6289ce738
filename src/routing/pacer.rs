//! `max_bitrate`: decides when the next datagram of a UDP interface may leave.
//!
//! A token bucket (in its "generic cell rate" form) whose depth is one datagram: the
//! bucket fills at the configured bits per second up to [`DEFAULT_BURST`] bytes; a
//! datagram may leave when the bucket holds its size. So over any interval of length T at
//! most `rate·T + burst` bits leave (a burst of at most one datagram), and a sender that
//! is woken slightly late loses nothing of the long-run rate as long as the lateness fits
//! in the bucket's headroom. Arithmetic is exact integer time·rate products, so there is
//! no drift however long it runs (the original sent about twice the rate).
//!
//! Timer precision: the bucket's headroom (280 bytes minus the datagram) absorbs late
//! wake-ups. A 267-byte frame at 262 144 bit/s leaves only 0.4 ms of it: woken up to 0.5 ms
//! late the long-run rate stays within 0.2%, but up to 1 ms late (a millisecond timer) it
//! drops by about 2%. A driver with a coarse timer can use [`Pacer::with_burst`] with
//! `280 + rate × granularity` bytes, trading that much extra burst for the exact rate.
//!
//! Use: `pacer.check(now, len)` says [`Pace::Now`] or [`Pace::At`]; after sending, call
//! `pacer.sent(now, len)`. [`Pacer::try_send`] does both.

use std::time::Duration;

use crate::time::Timestamp;

/// Bucket depth by default: the largest MAVLink frame (a signed v2 frame with a 255-byte
/// payload), since the router sends one frame per datagram.
pub(crate) const DEFAULT_BURST: u32 = 280;

const NANOS_PER_SEC: u128 = 1_000_000_000;

/// The answer to "may I send this datagram now?".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// Yes.
    Now,
    /// Not before this instant.
    At(Timestamp),
}

/// Paces the datagrams of one UDP interface (shared by all its remotes).
#[derive(Debug, Clone)]
pub struct Pacer {
    /// Bits per second; 0 means unlimited.
    rate: u64,
    burst: u32,
    /// Theoretical time at which the bucket is full again, in ns·(bits/s) units.
    full_at: u128,
}

impl Pacer {
    /// A pacer for `bits_per_second` (0 = unlimited) with a one-datagram burst.
    pub fn new(bits_per_second: u64) -> Self {
        Pacer::with_burst(bits_per_second, DEFAULT_BURST)
    }

    /// A pacer that never waits.
    pub fn unlimited() -> Self {
        Pacer::new(0)
    }

    /// A pacer for `bits_per_second` (0 = unlimited) whose bucket holds `burst_bytes`.
    pub(crate) fn with_burst(bits_per_second: u64, burst_bytes: u32) -> Self {
        Pacer {
            rate: bits_per_second,
            burst: burst_bytes,
            full_at: 0,
        }
    }

    /// The configured rate in bits per second (0 = unlimited).
    pub(crate) fn rate(&self) -> u64 {
        self.rate
    }

    /// `bytes` as time at the configured rate, in ns·(bits/s) units.
    fn cost(bytes: u64) -> u128 {
        u128::from(bytes) * 8 * NANOS_PER_SEC
    }

    fn scaled_now(&self, now: Timestamp) -> u128 {
        now.as_nanos().saturating_mul(u128::from(self.rate))
    }

    /// Whether a datagram of `bytes` may leave at `now`, or the earliest instant it may.
    pub fn check(&self, now: Timestamp, bytes: usize) -> Pace {
        if self.rate == 0 {
            return Pace::Now;
        }
        let bytes = bytes as u64;
        // Room needed in the bucket: the datagram, or a full bucket for a larger one.
        let headroom = Self::cost(u64::from(self.burst).saturating_sub(bytes));
        let earliest = self.full_at.saturating_sub(headroom);
        let now_scaled = self.scaled_now(now);
        if earliest <= now_scaled {
            return Pace::Now;
        }
        let nanos = earliest.div_ceil(u128::from(self.rate));
        let nanos = u64::try_from(nanos).unwrap_or(u64::MAX);
        Pace::At(Timestamp::new(Duration::from_nanos(nanos)))
    }

    /// Records that a datagram of `bytes` left at `now`.
    pub fn sent(&mut self, now: Timestamp, bytes: usize) {
        if self.rate == 0 {
            return;
        }
        let start = self.full_at.max(self.scaled_now(now));
        self.full_at = start.saturating_add(Self::cost(bytes as u64));
    }

    /// [`Pacer::check`], and [`Pacer::sent`] if the answer is [`Pace::Now`].
    pub fn try_send(&mut self, now: Timestamp, bytes: usize) -> Pace {
        let pace = self.check(now, bytes);
        if pace == Pace::Now {
            self.sent(now, bytes);
        }
        pace
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ns(n: u64) -> Timestamp {
        Timestamp::from_nanos(n)
    }

    #[test]
    fn unlimited_never_waits() {
        let mut p = Pacer::unlimited();
        for _ in 0..1000 {
            assert_eq!(p.try_send(Timestamp::ZERO, 280), Pace::Now);
        }
    }

    #[test]
    fn after_idle_one_datagram_goes_then_the_next_waits_its_time() {
        // 8000 bit/s = 1000 bytes/s: 280 bytes take 280 ms.
        let mut p = Pacer::new(8000);
        let t0 = Timestamp::from_secs(10);
        assert_eq!(p.try_send(t0, 280), Pace::Now);
        assert_eq!(
            p.try_send(t0, 280),
            Pace::At(t0 + Duration::from_millis(280))
        );
        assert_eq!(p.try_send(t0 + Duration::from_millis(280), 280), Pace::Now);
    }

    #[test]
    fn small_datagrams_may_use_the_headroom_but_never_exceed_one_datagram_of_burst() {
        let mut p = Pacer::new(8000);
        let t0 = Timestamp::from_secs(10);
        // 100 + 100 bytes fit in the 280-byte bucket; the third 100 needs 20 ms more.
        assert_eq!(p.try_send(t0, 100), Pace::Now);
        assert_eq!(p.try_send(t0, 100), Pace::Now);
        assert_eq!(
            p.try_send(t0, 100),
            Pace::At(t0 + Duration::from_millis(20))
        );
    }

    #[test]
    fn a_datagram_larger_than_the_bucket_waits_for_a_full_bucket() {
        let mut p = Pacer::new(8000);
        assert_eq!(p.try_send(ns(0), 100), Pace::Now);
        assert_eq!(
            p.try_send(ns(0), 1000),
            Pace::At(Timestamp::from_millis(100))
        );
        assert_eq!(p.try_send(Timestamp::from_millis(100), 1000), Pace::Now);
        assert_eq!(
            p.check(Timestamp::from_millis(100), 280),
            Pace::At(Timestamp::from_millis(1100))
        );
    }

    /// Drives the pacer like the event loop would for a simulated hour: always a datagram
    /// waiting, woken at the instant the pacer names plus some timer lateness.
    fn saturated_hour(rate: u64, sizes: &[usize], lateness_ns: impl Fn(u64) -> u64) -> (f64, u64) {
        let mut p = Pacer::new(rate);
        let hour = 3_600_000_000_000u64;
        let mut now = 0u64;
        let mut bits = 0u64;
        let mut i = 0u64;
        let mut sends: Vec<(u64, u64)> = Vec::new();
        while now < hour {
            let len = sizes[(i as usize) % sizes.len()];
            match p.try_send(ns(now), len) {
                Pace::Now => {
                    bits += 8 * len as u64;
                    sends.push((now, 8 * len as u64));
                    i += 1;
                }
                Pace::At(t) => {
                    let at = u64::try_from(t.as_nanos()).unwrap_or(u64::MAX);
                    assert!(at > now);
                    now = at + lateness_ns(i);
                }
            }
        }
        // Worst burst: bits sent in any window beyond rate × window.
        let mut worst_excess = 0f64;
        let mut start = 0;
        let mut window_bits = 0u64;
        for end in 0..sends.len() {
            window_bits += sends[end].1;
            while sends[end].0 - sends[start].0 > 5_000_000_000 {
                window_bits -= sends[start].1;
                start += 1;
            }
            let span = (sends[end].0 - sends[start].0) as f64 / 1e9;
            worst_excess = worst_excess.max(window_bits as f64 - rate as f64 * span);
        }
        (bits as f64 / 3600.0, worst_excess as u64)
    }

    #[test]
    fn simulated_hour_exact_wakeups_rate_within_1_percent() {
        for (rate, sizes) in [
            (262_144u64, vec![267usize]),
            (65_536, vec![17, 280, 44, 267, 9]),
            (57_600, vec![280]),
            (1_000_000, vec![30, 30, 51, 100]),
        ] {
            let (measured, burst_bits) = saturated_hour(rate, &sizes, |_| 0);
            let err = (measured - rate as f64).abs() / rate as f64;
            assert!(err < 0.01, "rate {rate}: measured {measured:.1} bit/s");
            assert!(
                burst_bits <= 8 * 280,
                "rate {rate}: burst {burst_bits} bits"
            );
        }
    }

    #[test]
    fn simulated_hour_with_late_wakeups_keeps_the_rate() {
        // A timer that fires up to 1 ms late (mio's millisecond granularity).
        let rate = 262_144;
        let (measured, burst_bits) = saturated_hour(rate, &[100], |i| (i * 7919 % 1000) * 1000);
        let err = (measured - rate as f64).abs() / rate as f64;
        assert!(err < 0.01, "measured {measured:.1} bit/s");
        assert!(burst_bits <= 8 * 280, "burst {burst_bits} bits");
    }
}
