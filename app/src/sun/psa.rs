//! The PSA algorithm (Plataforma Solar de Almería): M. Blanco-Muriel, D. C. Alarcón-Padilla,
//! T. López-Moratalla, M. Lara-Coira, "Computing the solar vector", Solar Energy 70(5) 431–441
//! (2001), doi:10.1016/S0038-092X(00)00156-0; coefficients refitted in M. J. Blanco,
//! K. Milidonis, A. Bonanos, "Updating the PSA sun position algorithm", Solar Energy 212
//! (2020), doi:10.1016/j.solener.2020.10.084. Both papers state an accuracy of 0.5′
//! (0.0083°) within their fitting periods, 1999–2015 and 2020–2050.
//!
//! The algorithm works in UT throughout (no ΔT): its coefficients absorb TT − UT over the
//! fitting period.

use std::f64::consts::TAU;

use super::horizon::{self, Horizontal};
use super::time::{JD_J2000, civil_from_julian_day};

/// The two published coefficient sets (the papers' Eqs. 3–7 and 10, numbered p1..p15 as in
/// the 2020 paper's table).
#[derive(Clone, Copy, Debug)]
pub struct Coefficients {
    /// Fitting period (years).
    pub valid_years: (i32, i32),
    p: [f64; 15],
}

/// Blanco-Muriel et al. 2001, valid 1999–2015.
pub const PSA_2001: Coefficients = Coefficients {
    valid_years: (1999, 2015),
    p: [
        2.1429,
        -0.001_039_459_4,
        4.895_063_0,
        0.017_202_791_698,
        6.240_060_0,
        0.017_201_969_9,
        0.033_416_07,
        0.000_348_94,
        -0.000_113_4,
        -0.000_020_3,
        0.409_092_8,
        -6.2140e-9,
        0.000_039_6,
        6.697_424_324_2,
        0.065_709_828_3,
    ],
};

/// Blanco et al. 2020 ("PSA+"), valid 2020–2050.
pub const PSA_2020: Coefficients = Coefficients {
    valid_years: (2020, 2050),
    p: [
        2.267_127_827,
        -9.300_339_267e-4,
        4.895_036_035,
        1.720_279_602e-2,
        6.239_468_336,
        1.720_200_135e-2,
        3.338_320_972e-2,
        3.497_596_876e-4,
        -1.544_353_226e-4,
        -8.689_729_360e-6,
        4.090_904_909e-1,
        -6.213_605_399e-9,
        4.418_094_944e-5,
        6.697_096_103,
        6.570_984_737e-2,
    ],
};

/// Mean Earth radius over the astronomical unit, both in km, as in the 2001 paper's code.
const EARTH_RADIUS_OVER_AU: f64 = 6371.01 / 149_597_890.0;

/// Topocentric elevation (without refraction) and azimuth for Julian date `jd` (UT).
pub fn horizontal(c: &Coefficients, jd: f64, lat_deg: f64, lon_deg: f64) -> Horizontal {
    let p = &c.p;
    let n = jd - JD_J2000;
    let hours = civil_from_julian_day(jd).seconds_of_day / 3600.0;
    // Ecliptic coordinates (Eqs. 3–7).
    let omega = p[0] + p[1] * n;
    let mean_longitude = p[2] + p[3] * n;
    let mean_anomaly = p[4] + p[5] * n;
    let ecliptic_longitude = mean_longitude + p[6] * mean_anomaly.sin() + p[7] * (2.0 * mean_anomaly).sin() + p[8] + p[9] * omega.sin();
    let obliquity = p[10] + p[11] * n + p[12] * omega.cos();
    // Celestial coordinates (Eqs. 8–9).
    let (sin_l, cos_l) = ecliptic_longitude.sin_cos();
    let ra = (obliquity.cos() * sin_l).atan2(cos_l).rem_euclid(TAU);
    let dec = (obliquity.sin() * sin_l).asin();
    // Sidereal time and hour angle (Eqs. 10–12).
    let gmst_hours = p[13] + p[14] * n + hours;
    let hour_angle = (gmst_hours * 15.0 + lon_deg).to_radians() - ra;
    let mut h = horizon::from_equatorial(lat_deg.to_radians(), dec, hour_angle);
    // Parallax (Eqs. 15–16): zenith += (R/AU)·sin(zenith).
    h.elevation_deg -= (EARTH_RADIUS_OVER_AU * h.elevation_deg.to_radians().cos()).to_degrees();
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sun::{delta_t, horizon::angular_separation_deg, spa, time};

    /// The stated 0.5′ accuracy, checked against SPA on a grid over each fitting period.
    fn worst_error(c: &Coefficients) -> f64 {
        let mut worst: f64 = 0.0;
        for year in c.valid_years.0..=c.valid_years.1 {
            for (month, hour) in [(2, 4), (5, 10), (8, 16), (11, 22)] {
                let t = time::parse_time(&format!("{year}-{month:02}-07T{hour:02}:41:00Z"), "t").unwrap();
                let jd = time::julian_day(&t.with_timezone(&chrono::Utc));
                let dt = delta_t::espenak_meeus(i64::from(year), month);
                for (lat, lon) in [(0.0, 0.0), (37.1, -2.4), (-45.0, 170.0), (70.0, 25.0)] {
                    let a = horizontal(c, jd, lat, lon);
                    let s = spa::horizontal(jd, dt, lat, lon, 0.0);
                    worst = worst.max(angular_separation_deg(90.0 - a.elevation_deg, a.azimuth_deg, 90.0 - s.elevation_deg, s.azimuth_deg));
                }
            }
        }
        worst
    }

    #[test]
    fn psa_2001_within_half_an_arcminute_of_spa() {
        let w = worst_error(&PSA_2001);
        assert!(w < 0.5 / 60.0, "{w}");
    }

    #[test]
    fn psa_2020_within_half_an_arcminute_of_spa() {
        let w = worst_error(&PSA_2020);
        assert!(w < 0.5 / 60.0, "{w}");
    }
}
