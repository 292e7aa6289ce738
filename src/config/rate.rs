//! The rate of a `with rate R` rule option: `2/s`, `0.5/s`, `10/min`, `1/h`.
//!
//! A rate is kept as thousandths of packets per unit (so it stays exact, `Copy` and
//! `Eq`): `0.5/s` is 500 per second-thousandth. [`Rate::interval`] is the time between
//! two packets at that rate.

use std::fmt;
use std::time::Duration;

/// The shortest interval a rate may give (a million packets per second).
const MIN_INTERVAL: Duration = Duration::from_micros(1);
/// The longest interval a rate may give (one packet a day).
const MAX_INTERVAL: Duration = Duration::from_secs(86_400);

/// The time unit of a rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RateUnit {
    /// `/s`
    Second,
    /// `/min`
    Minute,
    /// `/h`
    Hour,
}

impl RateUnit {
    /// The unit written after `/`, if it is one.
    pub fn parse(text: &str) -> Option<RateUnit> {
        match text {
            "s" => Some(RateUnit::Second),
            "min" => Some(RateUnit::Minute),
            "h" => Some(RateUnit::Hour),
            _ => None,
        }
    }

    fn seconds(self) -> u64 {
        match self {
            RateUnit::Second => 1,
            RateUnit::Minute => 60,
            RateUnit::Hour => 3600,
        }
    }

    fn name(self) -> &'static str {
        match self {
            RateUnit::Second => "s",
            RateUnit::Minute => "min",
            RateUnit::Hour => "h",
        }
    }
}

/// Packets per unit of time, as written in `with rate N/UNIT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rate {
    /// Thousandths of packets per `unit` (at least 1).
    pub thousandths: u64,
    /// The unit.
    pub unit: RateUnit,
}

impl Rate {
    /// The rate written as `count` (`2`, `0.5`, at most three decimals) per `unit`
    /// (`s`, `min`, `h`), or why it is not one.
    pub fn parse(count: &str, unit: &str) -> Result<Rate, String> {
        let unit = RateUnit::parse(unit)
            .ok_or_else(|| format!("unknown rate unit '{unit}' (write /s, /min or /h)"))?;
        let thousandths = thousandths(count).ok_or_else(|| {
            format!("invalid rate ({count}): write a number with at most 3 decimals, e.g. 2 or 0.5")
        })?;
        if thousandths == 0 {
            return Err("a rate must be above 0".to_string());
        }
        let rate = Rate { thousandths, unit };
        let interval = rate.interval();
        if interval < MIN_INTERVAL || interval > MAX_INTERVAL {
            return Err(format!(
                "rate ({count}/{}) is outside of the allowed range (1/day - 1000000/s)",
                unit.name()
            ));
        }
        Ok(rate)
    }

    /// The time between two packets at this rate.
    pub fn interval(self) -> Duration {
        let nanos = u128::from(self.unit.seconds()) * 1_000_000_000_000
            / u128::from(self.thousandths.max(1));
        Duration::from_nanos(u64::try_from(nanos).unwrap_or(u64::MAX))
    }
}

impl fmt::Display for Rate {
    /// `2/s`, `0.5/s`, `10/min`: the shortest decimal form.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let whole = self.thousandths / 1000;
        let frac = self.thousandths % 1000;
        if frac == 0 {
            write!(f, "{whole}/{}", self.unit.name())
        } else {
            let digits = format!("{frac:03}");
            write!(
                f,
                "{whole}.{}/{}",
                digits.trim_end_matches('0'),
                self.unit.name()
            )
        }
    }
}

/// `D+` or `D+.D{1,3}` as thousandths.
fn thousandths(text: &str) -> Option<u64> {
    let (whole, frac) = text.split_once('.').unwrap_or((text, ""));
    if whole.is_empty() || !whole.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    if text.contains('.') && (frac.is_empty() || frac.len() > 3) {
        return None;
    }
    if !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let whole: u64 = whole.parse().ok()?;
    let mut f: u64 = if frac.is_empty() {
        0
    } else {
        frac.parse().ok()?
    };
    for _ in frac.len()..3 {
        f *= 10;
    }
    whole.checked_mul(1000)?.checked_add(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_read_and_print() {
        let r = |c, u| Rate::parse(c, u).map(|r| (r.to_string(), r.interval()));
        assert_eq!(r("2", "s"), Ok(("2/s".into(), Duration::from_millis(500))));
        assert_eq!(r("0.5", "s"), Ok(("0.5/s".into(), Duration::from_secs(2))));
        assert_eq!(
            r("0.250", "s"),
            Ok(("0.25/s".into(), Duration::from_secs(4)))
        );
        assert_eq!(
            r("10", "min"),
            Ok(("10/min".into(), Duration::from_secs(6)))
        );
        assert_eq!(r("1", "h"), Ok(("1/h".into(), Duration::from_secs(3600))));
        for (c, u) in [
            ("0", "s"),
            ("1.", "s"),
            (".5", "s"),
            ("0.0001", "s"),
            ("2", "ms"),
        ] {
            assert!(Rate::parse(c, u).is_err(), "{c}/{u}");
        }
        assert!(Rate::parse("2000000", "s").is_err());
        assert!(Rate::parse("0.01", "h").is_err());
        assert!(Rate::parse("99999999999999999999", "s").is_err());
    }
}
