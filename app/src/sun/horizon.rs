//! From equatorial to horizontal coordinates: the one spherical-astronomy step every position
//! algorithm shares (SPA Eqs. 41 and 44–46; Meeus, Astronomical Algorithms, Eqs. 13.5–13.6).

/// Geometric elevation and azimuth of the sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Horizontal {
    /// Elevation above the horizon without refraction, degrees.
    pub elevation_deg: f64,
    /// Azimuth clockwise from true north, degrees in [0, 360).
    pub azimuth_deg: f64,
}

/// Elevation and azimuth for an observer at latitude `lat_rad` of a body at declination
/// `dec_rad` and local hour angle `hour_angle_rad` (measured westward from the meridian).
///
/// Azimuth is `atan2(sin H, cos H sin φ − tan δ cos φ) + 180°` (SPA Eqs. 44–46). At a pole the
/// formula stays finite and returns the limit reached by walking to the pole along the given
/// longitude's meridian (see `docs/sun.md`).
pub fn from_equatorial(lat_rad: f64, dec_rad: f64, hour_angle_rad: f64) -> Horizontal {
    let (sin_lat, cos_lat) = lat_rad.sin_cos();
    let (sin_dec, cos_dec) = dec_rad.sin_cos();
    let (sin_h, cos_h) = hour_angle_rad.sin_cos();
    let sin_e = (sin_lat * sin_dec + cos_lat * cos_dec * cos_h).clamp(-1.0, 1.0);
    let gamma = sin_h.atan2(cos_h * sin_lat - sin_dec / cos_dec * cos_lat);
    Horizontal { elevation_deg: sin_e.asin().to_degrees(), azimuth_deg: wrap_360(gamma.to_degrees() + 180.0) }
}

/// An angle in degrees brought into [0, 360) (never 360.0 itself, even for tiny negatives).
pub fn wrap_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 { 0.0 } else { w }
}

/// An angle in degrees brought into [−180, 180).
pub fn wrap_180(deg: f64) -> f64 {
    wrap_360(deg + 180.0) - 180.0
}

/// Angle in degrees between two sun directions given as (zenith, azimuth) in degrees. Uses
/// atan2(|a×b|, a·b), accurate for tiny and for large angles alike.
pub fn angular_separation_deg(zenith_a: f64, azimuth_a: f64, zenith_b: f64, azimuth_b: f64) -> f64 {
    let a = unit(zenith_a.to_radians(), azimuth_a.to_radians());
    let b = unit(zenith_b.to_radians(), azimuth_b.to_radians());
    let cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    sin.atan2(cos).to_degrees()
}

/// ENU unit vector of a direction with zenith θ and azimuth φ (clockwise from north), f64.
pub fn unit(zenith_rad: f64, azimuth_rad: f64) -> [f64; 3] {
    let (sin_z, cos_z) = zenith_rad.sin_cos();
    let (sin_a, cos_a) = azimuth_rad.sin_cos();
    [sin_z * sin_a, sin_z * cos_a, cos_z]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_checkable_cases() {
        // Equator, declination 0, hour angle 0: the sun is at the zenith.
        let h = from_equatorial(0.0, 0.0, 0.0);
        assert!((h.elevation_deg - 90.0).abs() < 1e-9);
        // Latitude 40° N, declination 0, noon: elevation 50°, due south (180°).
        let h = from_equatorial(40f64.to_radians(), 0.0, 0.0);
        assert!((h.elevation_deg - 50.0).abs() < 1e-9);
        assert!((h.azimuth_deg - 180.0).abs() < 1e-9);
        // Equinox at 40° N, hour angle −90° (6 h before noon): on the horizon due east (90°).
        let h = from_equatorial(40f64.to_radians(), 0.0, -std::f64::consts::FRAC_PI_2);
        assert!(h.elevation_deg.abs() < 1e-9);
        assert!((h.azimuth_deg - 90.0).abs() < 1e-9);
        // Southern hemisphere noon: the sun is due north (0°).
        let h = from_equatorial(-35f64.to_radians(), 0.2, 0.0);
        assert!(h.azimuth_deg.abs() < 1e-9 || (h.azimuth_deg - 360.0).abs() < 1e-9);
    }

    #[test]
    fn pole_is_finite_and_elevation_is_declination() {
        let dec = 20f64.to_radians();
        for h in [0.0, 1.0, 2.5, -3.0] {
            let p = from_equatorial(std::f64::consts::FRAC_PI_2, dec, h);
            assert!((p.elevation_deg - 20.0).abs() < 1e-9);
            assert!(p.azimuth_deg.is_finite() && (0.0..360.0).contains(&p.azimuth_deg));
        }
    }

    #[test]
    fn wrapping_and_separation() {
        assert_eq!(wrap_360(-1e-20), 0.0);
        assert_eq!(wrap_360(360.0), 0.0);
        assert!((wrap_360(-90.0) - 270.0).abs() < 1e-12);
        assert!((wrap_180(190.0) + 170.0).abs() < 1e-12);
        // Across the 0/360 seam: 359.5° and 0.5° on the horizon are 1° apart.
        assert!((angular_separation_deg(90.0, 359.5, 90.0, 0.5) - 1.0).abs() < 1e-9);
        // Near the zenith azimuth barely matters.
        assert!(angular_separation_deg(1e-6, 0.0, 1e-6, 180.0) < 3e-6);
        assert!((angular_separation_deg(0.0, 0.0, 180.0, 0.0) - 180.0).abs() < 1e-9);
    }
}
