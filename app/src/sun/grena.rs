//! R. Grena, "Five new algorithms for the computation of sun position from 2010 to 2110",
//! Solar Energy 86(5) 1323–1337 (2012), doi:10.1016/j.solener.2012.01.024.
//!
//! Each algorithm gives right ascension, declination and hour angle from fitted series in the
//! time t (days from 2060-01-01 0h UT); they share the horizontal conversion and the parallax
//! term. Stated maximum errors over 2010–2110 (the paper's 20-million-point test): Algorithm 1
//! 0.19°, 2 0.034°, 3 0.0094°, 4 0.0094°, 5 0.0027°.

use std::f64::consts::{PI, TAU};

use super::horizon::{self, Horizontal};

/// Years the algorithms were fitted for.
pub const VALID_YEARS: (i32, i32) = (2010, 2110);

/// Julian date of Grena's epoch, 2060-01-01 0h UT.
const JD_EPOCH_2060: f64 = 2_473_459.5;

/// Maximum error stated in the paper for Algorithms 1–5, degrees.
pub const STATED_MAX_ERROR_DEG: [f64; 5] = [0.19, 0.034, 0.0094, 0.0094, 0.0027];

/// Declination and Greenwich hour angle (before adding the longitude), radians.
struct Equatorial {
    dec: f64,
    hour_angle: f64,
}

/// Harmonics sin(kω), cos(kω) for k = 1..=3 by the recurrences the paper uses (one sin/cos).
fn harmonics(w: f64) -> [(f64, f64); 3] {
    let (s1, c1) = w.sin_cos();
    let (s2, c2) = (2.0 * s1 * c1, (c1 + s1) * (c1 - s1));
    let (s3, c3) = (s2 * c1 + c2 * s1, c2 * c1 - s2 * s1);
    [(s1, c1), (s2, c2), (s3, c3)]
}

fn algorithm1(t: f64, te: f64) -> Equatorial {
    let [(s1, c1), (s2, c2), _] = harmonics(0.017_202_786 * te);
    let ra = -1.388_80 + 1.720_279_20e-2 * te + 3.199e-2 * s1 - 2.65e-3 * c1 + 4.050e-2 * s2 + 1.525e-2 * c2;
    let dec = 6.57e-3 + 7.347e-2 * s1 - 3.9919e-1 * c1 + 7.3e-4 * s2 - 6.60e-3 * c2;
    Equatorial { dec, hour_angle: 1.752_83 + 6.300_388_1 * t - ra }
}

fn algorithm2(t: f64, te: f64) -> Equatorial {
    let [(s1, c1), (s2, c2), (s3, c3)] = harmonics(0.017_202_786 * te);
    let (s4, c4) = (2.0 * s2 * c2, (c2 + s2) * (c2 - s2));
    let ra = -1.388_80 + 1.720_279_20e-2 * te + 3.199e-2 * s1 - 2.65e-3 * c1
        + 4.050e-2 * s2
        + 1.525e-2 * c2
        + 1.33e-3 * s3
        + 3.8e-4 * c3
        + 7.3e-4 * s4
        + 6.2e-4 * c4;
    let dec = 6.57e-3 + 7.347e-2 * s1 - 3.9919e-1 * c1 + 7.3e-4 * s2 - 6.60e-3 * c2 + 1.50e-3 * s3 - 2.58e-3 * c3 + 6e-5 * s4 - 1.3e-4 * c4;
    Equatorial { dec, hour_angle: 1.752_83 + 6.300_388_1 * t - ra }
}

/// Right ascension and declination from the apparent ecliptic longitude λ and obliquity ε.
fn from_ecliptic(lambda: f64, epsilon: f64) -> (f64, f64) {
    let (sl, cl) = lambda.sin_cos();
    let (se, ce) = epsilon.sin_cos();
    ((sl * ce).atan2(cl), (sl * se).asin())
}

fn algorithm3(t: f64, te: f64) -> Equatorial {
    let w = 0.017_201_971_5 * te;
    let lambda = -1.388_803 + 1.720_279_216e-2 * te + 3.3366e-2 * (w - 0.06172).sin() + 3.53e-4 * (2.0 * w - 0.1163).sin();
    let (ra, dec) = from_ecliptic(lambda, 4.089_567e-1 - 6.19e-9 * te);
    Equatorial { dec, hour_angle: 1.752_831_1 + 6.300_388_099 * t - ra }
}

/// Algorithms 4 and 5 add nutation to a mean longitude `l` (radians).
fn with_nutation(t: f64, te: f64, l: f64) -> Equatorial {
    let nu = 9.282e-4 * te - 0.8;
    let dlam = 8.34e-5 * nu.sin();
    let (ra, dec) = from_ecliptic(l + PI + dlam, 4.089_567e-1 - 6.19e-9 * te + 4.46e-5 * nu.cos());
    Equatorial { dec, hour_angle: 1.752_831_1 + 6.300_388_099 * t - ra + 0.92 * dlam }
}

fn algorithm4(t: f64, te: f64) -> Equatorial {
    let w = 0.017_201_971_5 * te;
    let l = 1.752_790 + 1.720_279_216e-2 * te + 3.3366e-2 * (w - 0.06172).sin() + 3.53e-4 * (2.0 * w - 0.1163).sin();
    with_nutation(t, te, l)
}

fn algorithm5(t: f64, te: f64) -> Equatorial {
    let [(s1, c1), (s2, c2), (s3, c3)] = harmonics(0.017_201_971_5 * te);
    // Planetary and lunar perturbations: (amplitude, frequency per day, phase).
    const PERTURBATIONS: [(f64, f64, f64); 7] = [
        (1.27e-5, 1.49e-3, -2.337),
        (1.21e-5, 4.31e-3, 3.065),
        (2.33e-5, 1.076e-2, -1.533),
        (3.49e-5, 1.575e-2, -2.358),
        (2.67e-5, 2.152e-2, 0.074),
        (1.28e-5, 3.152e-2, 1.547),
        (3.14e-5, 2.1277e-1, -0.488),
    ];
    let l = 1.752_790_1 + 1.720_279_215_9e-2 * te + 3.330_24e-2 * s1 - 2.0582e-3 * c1 + 3.512e-4 * s2 - 4.07e-5 * c2 + 5.2e-6 * s3
        - 9e-7 * c3
        - 8.23e-5 * s1 * (2.92e-5 * te).sin()
        + PERTURBATIONS.iter().map(|&(a, f, p)| a * (f * te + p).sin()).sum::<f64>();
    with_nutation(t, te, l)
}

/// Topocentric elevation (without refraction) and azimuth with Grena's algorithm `n` (1–5)
/// for Julian date `jd` (UT), ΔT in seconds, latitude and longitude in degrees.
pub fn horizontal(n: u8, jd: f64, delta_t_s: f64, lat_deg: f64, lon_deg: f64) -> Horizontal {
    let t = jd - JD_EPOCH_2060;
    let te = t + delta_t_s / 86_400.0;
    let eq = match n {
        1 => algorithm1(t, te),
        2 => algorithm2(t, te),
        3 => algorithm3(t, te),
        4 => algorithm4(t, te),
        _ => algorithm5(t, te),
    };
    let hour_angle = (eq.hour_angle + lon_deg.to_radians() + PI).rem_euclid(TAU) - PI;
    let mut h = horizon::from_equatorial(lat_deg.to_radians(), eq.dec, hour_angle);
    // Parallax: Earth radius / AU = 4.26e-5 rad times cos(elevation) (the topocentric correction common to Grena's five algorithms).
    h.elevation_deg -= (4.26e-5 * h.elevation_deg.to_radians().cos()).to_degrees();
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sun::{horizon::angular_separation_deg, spa, time};

    fn at(s: &str) -> f64 {
        time::julian_day(&time::parse_time(s, "t").unwrap().with_timezone(&chrono::Utc))
    }

    #[test]
    fn algorithm3_matches_the_solar_positioning_crate() {
        // solar-positioning 0.7 implements Grena's Algorithm 3 independently (MIT licence);
        // compare geometric positions (no refraction) at a few places and times.
        use solar_positioning::{Location, SolarPositions, time::JulianDate};
        for (s, lat, lon) in
            [("2023-06-15T10:30:00Z", 48.21, 16.37), ("2011-01-01T00:00:00Z", -33.9, 151.2), ("2109-12-31T18:45:00Z", 64.1, -21.9)]
        {
            let jd = at(s);
            let h = horizontal(3, jd, 69.2, lat, lon);
            let theirs = SolarPositions::grena3()
                .at_from_julian(JulianDate::new(jd, 69.2).unwrap(), Location { latitude: lat, longitude: lon }, 0.0, None)
                .unwrap();
            assert!((90.0 - h.elevation_deg - theirs.zenith_angle()).abs() < 1e-7, "{s}");
            assert!((h.azimuth_deg - theirs.azimuth()).abs() < 1e-7, "{s}");
        }
    }

    #[test]
    fn within_the_stated_error_of_spa_on_a_grid() {
        // Grena's stated maximum errors, checked against SPA on a coarse grid of the valid range.
        for n in 1..=5u8 {
            let mut worst: f64 = 0.0;
            for year in (2010..=2110).step_by(10) {
                for (month, hour) in [(1, 3), (4, 9), (7, 15), (10, 21)] {
                    let jd = at(&format!("{year}-{month:02}-11T{hour:02}:17:00Z"));
                    let dt = crate::sun::delta_t::espenak_meeus(year, month);
                    for (lat, lon) in [(0.0, 0.0), (45.0, 100.0), (-60.0, -170.0), (80.0, 10.0)] {
                        let g = horizontal(n, jd, dt, lat, lon);
                        let s = spa::horizontal(jd, dt, lat, lon, 0.0);
                        let e = angular_separation_deg(90.0 - g.elevation_deg, g.azimuth_deg, 90.0 - s.elevation_deg, s.azimuth_deg);
                        worst = worst.max(e);
                    }
                }
            }
            assert!(worst < STATED_MAX_ERROR_DEG[n as usize - 1], "algorithm {n}: {worst}");
        }
    }
}
