//! The Earth's field from the World Magnetic Model (WMM2025, `world_magnetic_model` crate): the
//! declination that turns magnetic north into true north, and the field a magnetometer should
//! see, against which magnetic disturbances are detected.

use anyhow::{Context, Result, bail};
use chrono::Datelike;
use glam::{DQuat, DVec3};
use world_magnetic_model::GeomagneticField;
use world_magnetic_model::time::Date;
use world_magnetic_model::uom::si::angle::{degree, radian};
use world_magnetic_model::uom::si::f32::{Angle, Length};
use world_magnetic_model::uom::si::length::meter;
use world_magnetic_model::uom::si::magnetic_flux_density::microtesla;

/// The expected geomagnetic field at one place and date.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagneticReference {
    /// Angle from true north to magnetic north, positive east (radians).
    pub declination: f64,
    /// The WMM error model's 1σ uncertainty of the declination at this place (radians).
    pub declination_sigma: f64,
    /// Dip of the field below the horizontal, positive down (radians).
    pub inclination: f64,
    /// Total intensity F (µT).
    pub total_ut: f64,
    /// The field vector in ENU (µT): x East, y North, z Up.
    pub field_enu_ut: DVec3,
}

impl MagneticReference {
    /// WMM at a WGS 84 position (degrees, metres above the ellipsoid) and date.
    ///
    /// A phone's GPS altitude may be above mean sea level rather than the ellipsoid; the
    /// difference (under 110 m) changes the field by far less than the model's own error.
    pub fn wmm(lat_deg: f64, lon_deg: f64, height_m: f64, date: chrono::NaiveDate) -> Result<Self> {
        if !(lat_deg.is_finite() && lon_deg.is_finite() && height_m.is_finite()) {
            bail!("WMM: position must be finite, got lat {lat_deg}, lon {lon_deg}, height {height_m}");
        }
        let lon = if lon_deg > 180.0 { lon_deg - 360.0 } else { lon_deg };
        let ordinal = u16::try_from(date.ordinal()).context("WMM: day of year out of range")?;
        let wmm_date = Date::from_ordinal_date(date.year(), ordinal).with_context(|| format!("WMM: cannot represent the date {date}"))?;
        let field = GeomagneticField::new(
            Length::new::<meter>(height_m as f32),
            Angle::new::<degree>(lat_deg as f32),
            Angle::new::<degree>(lon as f32),
            wmm_date,
        )
        .map_err(|e| anyhow::anyhow!("WMM cannot evaluate lat {lat_deg}, lon {lon_deg}, height {height_m} m on {date}: {e}"))?;
        // WMM components: X north, Y east, Z down.
        let north = f64::from(field.x().get::<microtesla>());
        let east = f64::from(field.y().get::<microtesla>());
        let down = f64::from(field.z().get::<microtesla>());
        Ok(MagneticReference {
            declination: f64::from(field.declination().get::<radian>()),
            declination_sigma: f64::from(field.declination_uncertainty().get::<radian>()),
            inclination: f64::from(field.inclination().get::<radian>()),
            total_ut: f64::from(field.f().get::<microtesla>()),
            field_enu_ut: DVec3::new(east, north, -down),
        })
    }

    /// A reference built from a field vector in ENU (µT), e.g. for tests or a local survey.
    pub fn from_field_enu(field_enu_ut: DVec3, declination_sigma: f64) -> Self {
        let h = field_enu_ut.x.hypot(field_enu_ut.y);
        MagneticReference {
            declination: field_enu_ut.x.atan2(field_enu_ut.y),
            declination_sigma,
            inclination: (-field_enu_ut.z).atan2(h),
            total_ut: field_enu_ut.length(),
            field_enu_ut,
        }
    }
}

/// Turn an orientation referenced to magnetic north (device or camera → ENU with y = magnetic
/// north, as Android's rotation-vector sensor gives it) into one referenced to true north.
/// A direction at magnetic heading 0 has true heading `declination` (east positive).
pub fn magnetic_to_true(q_magnetic: DQuat, declination: f64) -> DQuat {
    (DQuat::from_rotation_z(-declination) * q_magnetic).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use chrono::NaiveDate;

    /// NOAA/BGS WMM2025 report, table of test values (WMM2025testvalues.pdf, the same numbers as
    /// WMM2025_TestValues.txt in WMM2025COF.zip): decimal year, height (km), lat, lon,
    /// X, Y, Z (nT), D (deg). 2025.0 = 1 January 2025; 2027.5 = 2 July 2027.
    /// (decimal year, height km, lat, lon, X, Y, Z, D).
    type TestValue = (f64, f64, f64, f64, f64, f64, f64, f64);
    const WMM2025_TEST_VALUES: [TestValue; 6] = [
        (2025.0, 0.0, 80.0, 0.0, 6521.6, 145.9, 54791.5, 1.28),
        (2025.0, 0.0, 0.0, 120.0, 39677.8, -109.6, -10580.2, -0.16),
        (2025.0, 0.0, -80.0, 240.0, 6117.5, 15751.9, -52022.5, 68.78),
        (2027.5, 0.0, 80.0, 0.0, 6500.8, 294.5, 54869.4, 2.59),
        (2027.5, 0.0, 0.0, 120.0, 39701.6, -167.4, -10381.8, -0.24),
        (2027.5, 0.0, -80.0, 240.0, 6200.7, 15730.3, -51783.7, 68.49),
    ];

    #[test]
    fn declination_and_field_match_published_wmm2025_test_values() {
        for &(year, h_km, lat, lon, x, y, z, d) in &WMM2025_TEST_VALUES {
            let date =
                if year == 2025.0 { NaiveDate::from_ymd_opt(2025, 1, 1).unwrap() } else { NaiveDate::from_ymd_opt(2027, 7, 2).unwrap() };
            let r = MagneticReference::wmm(lat, lon, h_km * 1000.0, date).unwrap();
            // Published to 0.01°; the crate computes in f32 (its own tests allow 0.006°).
            assert!((r.declination.to_degrees() - d).abs() < 0.012, "{lat},{lon} {year}: D {} vs {d}", r.declination.to_degrees());
            // Components in ENU (µT); published to 0.1 nT, the date is rounded to a whole day.
            let expected = DVec3::new(y, x, -z) / 1000.0;
            assert!((r.field_enu_ut - expected).abs().max_element() < 0.003, "{lat},{lon}: {:?} vs {expected:?}", r.field_enu_ut);
            assert!((r.total_ut - expected.length()).abs() < 0.003);
            assert!(r.declination_sigma > 0.0 && r.declination_sigma.to_degrees() < 10.0);
        }
    }

    #[test]
    fn from_field_vector_gives_declination_and_dip() {
        // A field pointing 10° east of north, dipping 60° down.
        let (d, i) = (10f64.to_radians(), 60f64.to_radians());
        let v = DVec3::new(d.sin() * i.cos(), d.cos() * i.cos(), -i.sin()) * 48.0;
        let r = MagneticReference::from_field_enu(v, 0.0);
        assert!((r.declination - d).abs() < 1e-12 && (r.inclination - i).abs() < 1e-12);
        assert!((r.total_ut - 48.0).abs() < 1e-12);
    }

    #[test]
    fn magnetic_north_becomes_true_heading_of_declination() {
        // A direction along magnetic north (ENU-magnetic +y) points 5° east of true north.
        let q = magnetic_to_true(DQuat::IDENTITY, 5f64.to_radians());
        let v = q * DVec3::Y;
        assert!((v.x.atan2(v.y).to_degrees() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn bad_positions_are_errors() {
        let date = NaiveDate::from_ymd_opt(2026, 11, 21).unwrap();
        assert!(MagneticReference::wmm(f64::NAN, 0.0, 0.0, date).is_err());
        assert!(MagneticReference::wmm(95.0, 0.0, 0.0, date).is_err());
        assert!(MagneticReference::wmm(51.45, -2.59, 1e7, date).is_err());
        // Longitude 0..360 is accepted.
        let a = MagneticReference::wmm(10.0, 240.0, 0.0, date).unwrap();
        let b = MagneticReference::wmm(10.0, -120.0, 0.0, date).unwrap();
        assert_eq!(a, b);
    }
}
