//! GNSS time as the units send it, converted to one representation: UTC as ns since the Unix
//! epoch. Shared by every codec (MIP's GPS week and time of week, VectorNav's GPS ns, Xsens'
//! UTC calendar fields), the simulator that produces them and the daemon that stamps with them.
//!
//! The calendar conversion is Howard Hinnant's `days_from_civil` (exact integer arithmetic on
//! the proleptic Gregorian calendar): ten lines, so a sans-IO codec crate does not take a date
//! library for it.

/// The GPS epoch, 1980-01-06T00:00:00 UTC, as s since the Unix epoch.
pub const GPS_EPOCH_UNIX_S: i64 = 315_964_800;
/// GPS time minus UTC, s: the leap seconds since the GPS epoch (18 since 2017-01-01; no leap
/// second has been announced since). A unit that reports its own leap-second count should be
/// converted with that instead ([`gps_ns_to_unix_ns_with_leap`]).
pub const GPS_MINUS_UTC_S: i64 = 18;
/// Seconds in a GPS week.
pub const SECONDS_PER_WEEK: i64 = 604_800;

/// The GNSS time a unit attached to one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GnssTime {
    /// The sample's time, UTC, ns since the Unix epoch (leap seconds removed).
    pub utc_ns: i64,
    /// The unit says this time is resolved (a fix, or a time solution it trusts). An invalid
    /// time is still reported, so that "GNSS time lost" can be told from "no GNSS time".
    pub valid: bool,
}

/// GPS time (ns since the GPS epoch, GPS time scale) to UTC ns since the Unix epoch with the
/// given GPS-minus-UTC leap seconds.
pub fn gps_ns_to_unix_ns_with_leap(gps_ns: u64, gps_minus_utc_s: i64) -> i64 {
    (gps_ns as i64).saturating_add((GPS_EPOCH_UNIX_S - gps_minus_utc_s) * 1_000_000_000)
}

/// GPS time (ns since the GPS epoch) to UTC ns since the Unix epoch, [`GPS_MINUS_UTC_S`].
pub fn gps_ns_to_unix_ns(gps_ns: u64) -> i64 {
    gps_ns_to_unix_ns_with_leap(gps_ns, GPS_MINUS_UTC_S)
}

/// GPS week and time of week (s) to UTC ns since the Unix epoch, [`GPS_MINUS_UTC_S`]. `None`
/// for a time of week outside [0, 604800) or not finite.
pub fn gps_week_tow_to_unix_ns(week: u32, tow_s: f64) -> Option<i64> {
    if !(tow_s.is_finite() && (0.0..SECONDS_PER_WEEK as f64).contains(&tow_s)) {
        return None;
    }
    let tow_ns = (tow_s * 1e9).round() as i64;
    let gps_ns = i64::from(week) * SECONDS_PER_WEEK * 1_000_000_000 + tow_ns;
    Some(gps_ns_to_unix_ns(gps_ns as u64))
}

/// UTC ns since the Unix epoch back to GPS ns since the GPS epoch, [`GPS_MINUS_UTC_S`] (what a
/// simulated unit sends).
pub fn unix_ns_to_gps_ns(utc_ns: i64) -> u64 {
    (utc_ns - (GPS_EPOCH_UNIX_S - GPS_MINUS_UTC_S) * 1_000_000_000).max(0) as u64
}

/// Days since 1970-01-01 of a proleptic Gregorian date (Hinnant's `days_from_civil`).
pub fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(month);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date of a day since 1970-01-01 (Hinnant's `civil_from_days`): (year, month, day).
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// UTC calendar fields to ns since the Unix epoch; `None` when a field is out of range (a
/// second of 60, a leap second, is accepted as the next minute's first).
pub fn utc_fields_to_unix_ns(
    year: u16,
    month: u8,
    day: u8,
    hour: u8,
    minute: u8,
    second: u8,
    nanosecond: u32,
) -> Option<i64> {
    if !(1..=12).contains(&month)
        || !(1..=31).contains(&day)
        || hour > 23
        || minute > 59
        || second > 60
        || nanosecond >= 1_000_000_000
    {
        return None;
    }
    let days = days_from_civil(i64::from(year), u32::from(month), u32::from(day));
    let s = days * 86_400 + i64::from(hour) * 3600 + i64::from(minute) * 60 + i64::from(second);
    Some(s * 1_000_000_000 + i64::from(nanosecond))
}

/// ns since the Unix epoch to UTC calendar fields (year, month, day, hour, minute, second,
/// nanosecond): what a simulated unit's UTC field carries.
pub fn unix_ns_to_utc_fields(utc_ns: i64) -> (u16, u8, u8, u8, u8, u8, u32) {
    let s = utc_ns.div_euclid(1_000_000_000);
    let ns = utc_ns.rem_euclid(1_000_000_000) as u32;
    let days = s.div_euclid(86_400);
    let sod = s.rem_euclid(86_400);
    let (y, m, d) = civil_from_days(days);
    (
        y as u16,
        m as u8,
        d as u8,
        (sod / 3600) as u8,
        (sod / 60 % 60) as u8,
        (sod % 60) as u8,
        ns,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(1980, 1, 6) * 86_400, GPS_EPOCH_UNIX_S);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(civil_from_days(11_017), (2000, 3, 1));
        // 2017-01-01T00:00:00 UTC is 1483228800 (the last leap second's end).
        assert_eq!(
            utc_fields_to_unix_ns(2017, 1, 1, 0, 0, 0, 0),
            Some(1_483_228_800_000_000_000)
        );
        assert_eq!(utc_fields_to_unix_ns(2017, 13, 1, 0, 0, 0, 0), None);
    }

    #[test]
    fn gps_week_and_tow() {
        // GPS week 1930 starts on Sunday 2017-01-01 00:00:00 GPS time, which UTC, 18 s
        // behind, calls 2016-12-31 23:59:42.
        let utc = gps_week_tow_to_unix_ns(1930, 0.0).unwrap();
        assert_eq!(utc, 1_483_228_800_000_000_000 - 18_000_000_000);
        assert_eq!(gps_week_tow_to_unix_ns(1930, 604_800.0), None);
        assert_eq!(gps_week_tow_to_unix_ns(1930, f64::NAN), None);
    }

    #[test]
    fn round_trips() {
        for utc_ns in [0_i64, 1_483_228_800_123_456_789, 1_800_000_000_999_999_999] {
            let (y, mo, d, h, mi, s, ns) = unix_ns_to_utc_fields(utc_ns);
            assert_eq!(utc_fields_to_unix_ns(y, mo, d, h, mi, s, ns), Some(utc_ns));
            if utc_ns > 400_000_000_000_000_000 {
                assert_eq!(gps_ns_to_unix_ns(unix_ns_to_gps_ns(utc_ns)), utc_ns);
            }
        }
    }
}
