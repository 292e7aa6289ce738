//! UTC calendar formatting of UNIX timestamps (no time-zone database needed).

/// (year, month, day) of a day count since 1970-01-01 (proleptic Gregorian calendar).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// (year, month, day, hour, minute, second) in UTC of a UNIX time in seconds.
pub(crate) fn calendar(unix_seconds: i64) -> (i64, u32, u32, u32, u32, u32) {
    let (y, m, d) = civil_from_days(unix_seconds.div_euclid(86_400));
    let sod = unix_seconds.rem_euclid(86_400) as u32;
    (y, m, d, sod / 3600, sod / 60 % 60, sod % 60)
}

/// `YYYY-MM-DD HH:MM:SS.uuuuuu` (UTC) for microseconds since the UNIX epoch.
pub(crate) fn format_micros(us: u64) -> String {
    let secs = (us / 1_000_000) as i64;
    let (y, m, d) = civil_from_days(secs.div_euclid(86_400));
    let sod = secs.rem_euclid(86_400);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{:06}",
        sod / 3600,
        sod / 60 % 60,
        sod % 60,
        us % 1_000_000
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(format_micros(0), "1970-01-01 00:00:00.000000");
        // rural.tlog starts 2024-08-15 15:02:45 UTC.
        assert_eq!(
            format_micros(1_723_734_165_250_001),
            "2024-08-15 15:02:45.250001"
        );
        assert_eq!(
            format_micros(951_782_400_000_000),
            "2000-02-29 00:00:00.000000"
        );
    }
}
