//! The day-of-year ("Julian date") formula of seed 002 (Kolivand & Sunar 2014, PLOS ONE
//! 9(9) e108334, Eqs. 1–4), which is Preetham, Shirley & Smits, "A Practical Analytic Model for
//! Daylight" (SIGGRAPH 1999), Appendix A.6, after Iqbal, "An Introduction to Solar Radiation"
//! (1983). J is the day of the year (1–366), not an astronomical Julian date.
//!
//! As printed in the seed the formula has three faults, each shown by a test below:
//! - Eq. 1 reads `sin(4π(J−180)/373)`; Preetham has `J−80`. With 180 the equation of time on
//!   17 Oct 2003 is 2.0 min instead of SPA's 14.64 min.
//! - Eq. 2 reads `sin(2π(J−8)/368)`; Preetham has `J−81`. With 8 the declination is zero on
//!   8 January and 7.9° at the June solstice instead of 23.4°.
//! - Eq. 4 takes `πt/12` (zero at midnight) as its angle while Eq. 3's `−cos(πt/12)` makes the
//!   same symbol the hour angle plus π; and a plain arctangent loses the quadrant. Written with
//!   the hour angle H = π(t − 12)/12 and atan2 it is the standard azimuth (north, clockwise).
//!
//! [`horizontal`] is the corrected formula (the one offered at run time); [`horizontal_as_printed`]
//! keeps the seed's text, azimuth read as clockwise from north, for the accuracy chart only.

use std::f64::consts::PI;

use super::horizon::{self, Horizontal, wrap_360};
use super::time::civil_from_julian_day;

/// Years over which we offer the formula: it has no secular terms, so it is tied to the
/// Gregorian calendar of the present era (Iqbal fitted it to 20th-century data).
pub const VALID_YEARS: (i32, i32) = (1900, 2100);

/// Equation of time in hours for day of year `j` (Eq. 1 without the clock terms, corrected).
pub fn equation_of_time_hours(j: f64) -> f64 {
    0.170 * (4.0 * PI * (j - 80.0) / 373.0).sin() - 0.129 * (2.0 * PI * (j - 8.0) / 355.0).sin()
}

/// Solar declination in radians for day of year `j` (Eq. 2, corrected).
pub fn declination_rad(j: f64) -> f64 {
    0.4093 * (2.0 * PI * (j - 81.0) / 368.0).sin()
}

/// Day of year and UT hours of a Julian date.
fn day_and_hours(jd: f64) -> (f64, f64) {
    let c = civil_from_julian_day(jd);
    (f64::from(c.day_of_year), c.seconds_of_day / 3600.0)
}

/// Geometric elevation and azimuth from the corrected seed-002 formula. The standard meridian
/// is Greenwich (standard time = UT), so `12(SM − L)/π` becomes `longitude_deg / 15` hours
/// with east-positive longitude.
pub fn horizontal(jd: f64, lat_deg: f64, lon_deg: f64) -> Horizontal {
    let (j, ut_hours) = day_and_hours(jd);
    let solar_time = ut_hours + equation_of_time_hours(j) + lon_deg / 15.0;
    let hour_angle = PI * (solar_time - 12.0) / 12.0;
    horizon::from_equatorial(lat_deg.to_radians(), declination_rad(j), hour_angle)
}

/// Seed 002's Eqs. 1–4 exactly as printed (see the module notes), for the chart only.
pub fn horizontal_as_printed(jd: f64, lat_deg: f64, lon_deg: f64) -> Horizontal {
    let (j, ut_hours) = day_and_hours(jd);
    let t = ut_hours + 0.17 * (4.0 * PI * (j - 180.0) / 373.0).sin() - 0.129 * (2.0 * PI * (j - 8.0) / 355.0).sin() + lon_deg / 15.0;
    let d = 0.4093 * (2.0 * PI * (j - 8.0) / 368.0).sin();
    let l = lat_deg.to_radians();
    let w = PI * t / 12.0;
    let zenith = PI / 2.0 - (l.sin() * d.sin() - l.cos() * d.cos() * w.cos()).clamp(-1.0, 1.0).asin();
    let azimuth = (-d.cos() * w.sin() / (l.cos() * d.sin() - l.sin() * d.cos() * w.cos())).atan();
    Horizontal { elevation_deg: 90.0 - zenith.to_degrees(), azimuth_deg: wrap_360(azimuth.to_degrees()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sun::{delta_t, horizon::angular_separation_deg, spa, time};

    fn jd(s: &str) -> f64 {
        time::julian_day(&time::parse_time(s, "t").unwrap().with_timezone(&chrono::Utc))
    }

    #[test]
    fn equation_of_time_on_the_spa_test_day() {
        // 17 Oct 2003 is day 290; SPA's published equation of time is 14.64 min. The two-term
        // fit is good to a few seconds of time here (6 s allowed); the printed one is 12 min off.
        let corrected = equation_of_time_hours(290.0) * 60.0;
        assert!((corrected - 14.64).abs() < 0.1, "{corrected}");
        let printed = (0.17 * (4.0 * PI * (290.0 - 180.0) / 373.0).sin() - 0.129 * (2.0 * PI * (290.0 - 8.0) / 355.0).sin()) * 60.0;
        assert!((printed - 14.64).abs() > 10.0, "{printed}");
    }

    #[test]
    fn declination_at_the_solstice_and_equinox() {
        // 2024-06-20T20:51Z was the June solstice (declination = obliquity ≈ 23.44°), day 172;
        // 2024-03-20T03:06Z the March equinox (declination 0), day 80. SPA gives the reference.
        for (when, day) in [("2024-06-20T20:51:00Z", 172.0), ("2024-03-20T03:06:00Z", 80.0)] {
            let spa_dec = spa::geocentric(jd(when), 69.0).delta_deg;
            let ours = declination_rad(day).to_degrees();
            assert!((ours - spa_dec).abs() < 0.5, "{when}: {ours} vs {spa_dec}");
        }
        let printed_june = (0.4093 * (2.0 * PI * (172.0 - 8.0) / 368.0).sin()).to_degrees();
        assert!(printed_june < 10.0, "{printed_june}");
    }

    #[test]
    fn noon_sun_is_due_south_and_the_corrected_formula_tracks_spa() {
        // Local solar noon at 40° N on 17 Oct 2003: azimuth 180° within the equation-of-time
        // error of the formula (about a minute of time = 0.25° of hour angle).
        let transit = jd("2003-10-17T18:46:05Z"); // SPA transit at Golden, CO (spa.rs tests)
        let h = horizontal(transit, 39.742_476, -105.1786);
        assert!((h.azimuth_deg - 180.0).abs() < 1.0, "{}", h.azimuth_deg);
        // Over a year of hourly daylight samples the corrected formula stays within 1° of SPA,
        // and the printed one does not.
        let (mut worst, mut worst_printed): (f64, f64) = (0.0, 0.0);
        for day in 0..365 {
            for hour in (0..24).step_by(3) {
                let t = jd("2023-01-01T00:00:00Z") + f64::from(day) + f64::from(hour) / 24.0;
                let s = spa::horizontal(t, delta_t::espenak_meeus(2023, 6), 48.0, 11.0, 0.0);
                let a = horizontal(t, 48.0, 11.0);
                let b = horizontal_as_printed(t, 48.0, 11.0);
                let err =
                    |h: Horizontal| angular_separation_deg(90.0 - h.elevation_deg, h.azimuth_deg, 90.0 - s.elevation_deg, s.azimuth_deg);
                worst = worst.max(err(a));
                worst_printed = worst_printed.max(err(b));
            }
        }
        assert!(worst < 1.0, "{worst}");
        assert!(worst_printed > 10.0, "{worst_printed}");
    }
}
