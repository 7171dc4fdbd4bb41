//! Instants for the sun algorithms: parsing RFC 3339 times, Julian dates and calendar parts.
//!
//! Times are proleptic Gregorian (ISO 8601 / RFC 3339, as chrono counts them) for every year.
//! NREL's reference SPA code reads dates before 15 October 1582 as Julian-calendar dates; give
//! such dates here as their Gregorian equivalent. UTC is used for UT1 (they differ by < 0.9 s,
//! i.e. < 0.004° of hour angle).

use anyhow::{Context, Result, bail};
use chrono::{DateTime, FixedOffset, Utc};

/// Julian date of the Unix epoch, 1970-01-01T00:00:00Z (Meeus, Astronomical Algorithms, ch. 7).
pub const JD_UNIX_EPOCH: f64 = 2_440_587.5;

/// Julian date of J2000.0, 2000-01-01T12:00:00 (Meeus ch. 7; SPA Eq. 5 subtracts it).
pub const JD_J2000: f64 = 2_451_545.0;

/// Parse a time in RFC 3339 (`2003-10-17T12:30:30-07:00`, `2003-10-17T19:30:30Z`). Years
/// outside 0000–9999 may be written with a sign as ISO 8601 allows (`-0500-03-01T12:00:00Z`).
/// `what` names the input (a flag or a column) in the error.
pub fn parse_time(text: &str, what: &str) -> Result<DateTime<FixedOffset>> {
    let text = text.trim();
    if let Ok(t) = DateTime::parse_from_rfc3339(text) {
        return Ok(t);
    }
    // Signed or 5-digit years: chrono's %Y takes a leading sign; RFC 3339 itself has no form for them.
    if text.starts_with(['+', '-']) {
        let normalised = match text.strip_suffix(['Z', 'z']) {
            Some(head) => format!("{head}+00:00"),
            None => text.to_string(),
        };
        if let Ok(t) = DateTime::parse_from_str(&normalised, "%Y-%m-%dT%H:%M:%S%.f%:z") {
            return Ok(t);
        }
    }
    bail!(
        "{what}: cannot read {text:?} as a time; expected RFC 3339 with an offset, e.g. \
         2003-10-17T12:30:30-07:00 or 2003-10-17T19:30:30Z"
    )
}

/// Julian date (UT) of an instant: days since −4712-01-01T12:00 (Julian calendar).
pub fn julian_day(t: &DateTime<Utc>) -> f64 {
    let seconds = t.timestamp() as f64 + f64::from(t.timestamp_subsec_nanos()) * 1e-9;
    JD_UNIX_EPOCH + seconds / 86_400.0
}

/// The UTC instant of a Julian date (inverse of [`julian_day`], to the resolution of an f64
/// Julian date: about 40 µs).
pub fn from_julian_day(jd: f64) -> Result<DateTime<Utc>> {
    let micros = ((jd - JD_UNIX_EPOCH) * 86_400e6).round();
    if !micros.is_finite() || micros.abs() > 9.0e18 {
        bail!("Julian date {jd} is outside the representable range");
    }
    DateTime::<Utc>::from_timestamp_micros(micros as i64).with_context(|| format!("Julian date {jd} is outside the representable range"))
}

/// Proleptic Gregorian calendar parts of a Julian date (UT).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CivilTime {
    pub year: i64,
    pub month: u32,
    pub day: u32,
    /// Day of the year, 1 = 1 January.
    pub day_of_year: u32,
    /// Seconds since 00:00 UT of the day, 0 ≤ s < 86400.
    pub seconds_of_day: f64,
}

/// Calendar date and time of day of a Julian date, without chrono (cheap enough for the inner
/// loops of the accuracy chart). Uses H. Hinnant's `civil_from_days` (public domain,
/// <https://howardhinnant.github.io/date_algorithms.html>).
pub fn civil_from_julian_day(jd: f64) -> CivilTime {
    let days_since_epoch = jd - JD_UNIX_EPOCH;
    let whole = days_since_epoch.floor();
    let seconds_of_day = ((days_since_epoch - whole) * 86_400.0).clamp(0.0, 86_400.0 - 1e-9);
    // Clamped so that absurd inputs (NaN, ±1e300) give a date rather than an overflow.
    let z = whole.clamp(-1e15, 1e15) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // day of era, 0..=146096
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // 0..=399
    let doy_march = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of year from 1 March, 0..=365
    let mp = (5 * doy_march + 2) / 153;
    let day = (doy_march - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    const CUMULATIVE: [u32; 12] = [0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334];
    let day_of_year = CUMULATIVE[(month - 1) as usize] + day + u32::from(leap && month > 2);
    CivilTime { year, month, day, day_of_year, seconds_of_day }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chrono::{Datelike, TimeZone};

    #[test]
    fn julian_day_of_the_published_spa_case() {
        // NREL/TP-560-34302 Table A5.1: 17 Oct 2003 12:30:30 at UTC−7 is JD 2452930.312847.
        let t = parse_time("2003-10-17T12:30:30-07:00", "--time").unwrap();
        let jd = julian_day(&t.with_timezone(&Utc));
        assert!((jd - 2_452_930.312_847).abs() < 5e-7, "{jd}");
    }

    #[test]
    fn julian_day_of_j2000_and_meeus_examples() {
        // J2000.0 = 2000-01-01T12:00:00 (Meeus ch. 7); Meeus Example 7.a: 1957 Oct 4.81 = 2436116.31.
        let j2000 = Utc.with_ymd_and_hms(2000, 1, 1, 12, 0, 0).unwrap();
        assert_eq!(julian_day(&j2000), JD_J2000);
        let sputnik = Utc.with_ymd_and_hms(1957, 10, 4, 19, 26, 24).unwrap();
        assert!((julian_day(&sputnik) - 2_436_116.31).abs() < 1e-6);
    }

    #[test]
    fn julian_day_round_trips() {
        for s in ["1600-02-29T23:59:59.5Z", "2024-02-29T12:00:00Z", "2999-12-31T00:00:01Z"] {
            let t = parse_time(s, "t").unwrap().with_timezone(&Utc);
            let back = from_julian_day(julian_day(&t)).unwrap();
            // An f64 Julian date near 2.3e6 resolves 2^-31 day ≈ 40 µs.
            assert!((back - t).num_microseconds().unwrap().abs() <= 50, "{s}");
        }
    }

    #[test]
    fn parses_offsets_signed_years_and_rejects_garbage() {
        let a = parse_time("2003-10-17T12:30:30-07:00", "t").unwrap();
        let b = parse_time("2003-10-17T19:30:30Z", "t").unwrap();
        assert_eq!(a, b);
        let old = parse_time("-0500-03-01T12:00:00Z", "t").unwrap();
        assert_eq!(old.year(), -500);
        let far = parse_time("+5999-01-01T00:00:00+01:00", "t").unwrap();
        assert_eq!(far.year(), 5999);
        for bad in ["", "yesterday", "2003-10-17", "2003-13-01T00:00:00Z", "2003-02-29T00:00:00Z"] {
            let e = parse_time(bad, "--time").unwrap_err().to_string();
            assert!(e.contains("--time"), "{e}");
        }
        // 2024 is a leap year, 2100 is not (Gregorian rule).
        assert!(parse_time("2024-02-29T00:00:00Z", "t").is_ok());
        assert!(parse_time("2100-02-29T00:00:00Z", "t").is_err());
    }

    #[test]
    fn civil_parts_match_chrono() {
        // Absurd inputs do not overflow.
        let _ = civil_from_julian_day(f64::NAN);
        let _ = civil_from_julian_day(1e300);
        for s in ["2024-02-29T06:00:00Z", "2023-12-31T23:59:59Z", "1600-03-01T00:00:00Z", "-1999-07-04T18:30:00Z", "5999-12-31T12:00:00Z"] {
            let t = parse_time(s, "t").unwrap().with_timezone(&Utc);
            let c = civil_from_julian_day(julian_day(&t));
            assert_eq!(c.year, i64::from(t.year()), "{s}");
            assert_eq!((c.month, c.day, c.day_of_year), (t.month(), t.day(), t.ordinal()), "{s}");
            let sod = f64::from(chrono::Timelike::num_seconds_from_midnight(&t));
            assert!((c.seconds_of_day - sod).abs() < 1e-3, "{s}");
        }
    }
}
