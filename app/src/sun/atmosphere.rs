//! The air between the observer and the sun: default pressure and temperature when the user has
//! no weather data, and atmospheric refraction (shared by every position algorithm, so the
//! algorithms differ only in geometry).

/// The sun's apparent radius used by SPA for rise/set and the refraction cut-off (degrees).
pub const SUN_RADIUS_DEG: f64 = 0.26667;

/// Refraction at the horizon assumed by SPA (`atmos_refract`, degrees).
pub const HORIZON_REFRACTION_DEG: f64 = 0.5667;

/// Sea-level pressure (mbar = hPa) and temperature (°C) of the standard atmosphere.
const P0_MBAR: f64 = 1013.25;
const T0_K: f64 = 288.15;
/// Temperature lapse rate of the troposphere, K/m.
const LAPSE_K_PER_M: f64 = 0.0065;
/// g0·M/(R*·L) for the troposphere (U.S. Standard Atmosphere 1976, Eq. 33a).
const BAROMETRIC_EXPONENT: f64 = 5.255_877;
/// Effective Earth radius for geopotential altitude, m (U.S. Standard Atmosphere 1976, Eq. 18).
const R0_M: f64 = 6_356_766.0;

/// Geopotential altitude (the standard atmosphere's height variable) of a geometric elevation.
fn geopotential_m(elevation_m: f64) -> f64 {
    R0_M * elevation_m / (R0_M + elevation_m)
}

/// Lowest and highest elevations accepted (metres): the Dead Sea shore is at −430 m; above
/// 11 km the troposphere formula of [`standard_pressure_mbar`] no longer holds.
pub const ELEVATION_RANGE_M: (f64, f64) = (-1000.0, 11_000.0);

/// Pressure of the U.S. Standard Atmosphere 1976 at an elevation in the troposphere (mbar).
pub fn standard_pressure_mbar(elevation_m: f64) -> f64 {
    P0_MBAR * (1.0 - LAPSE_K_PER_M * geopotential_m(elevation_m) / T0_K).powf(BAROMETRIC_EXPONENT)
}

/// Temperature of the U.S. Standard Atmosphere 1976 at an elevation in the troposphere (°C):
/// 15 °C at sea level falling 6.5 K per km.
pub fn standard_temperature_c(elevation_m: f64) -> f64 {
    T0_K - LAPSE_K_PER_M * geopotential_m(elevation_m) - 273.15
}

/// Atmospheric refraction (degrees, to add to the geometric elevation) for a true topocentric
/// elevation `e0_deg`: SPA Eq. 42 (Reda & Andreas 2004, after Sæmundsson's formula as given in
/// Meeus ch. 16), applied only while the sun's upper limb can be above the horizon
/// (`e0 ≥ −(0.26667° + 0.5667°)`); below that SPA adds nothing.
pub fn refraction_deg(e0_deg: f64, pressure_mbar: f64, temperature_c: f64) -> f64 {
    if e0_deg >= -(SUN_RADIUS_DEG + HORIZON_REFRACTION_DEG) {
        let arg = (e0_deg + 10.3 / (e0_deg + 5.11)).to_radians();
        (pressure_mbar / 1010.0) * (283.0 / (273.0 + temperature_c)) * 1.02 / (60.0 * arg.tan())
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_atmosphere_table_values() {
        // U.S. Standard Atmosphere 1976, Table I (geometric altitude): pressure (hPa) and
        // temperature (K) at 0, 1000, 2000 and 5000 m.
        for (z, p, t_k) in [(0.0, 1013.25, 288.150), (1000.0, 898.76, 281.651), (2000.0, 795.01, 275.154), (5000.0, 540.48, 255.676)] {
            assert!((standard_pressure_mbar(z) - p).abs() < 0.02, "{z}: {}", standard_pressure_mbar(z));
            assert!((standard_temperature_c(z) + 273.15 - t_k).abs() < 0.001, "{z}");
        }
    }

    #[test]
    fn refraction_of_the_spa_test_case() {
        // NREL SPA test case: e0 = 39.872046°, 820 mbar, 11 °C → Δe = 0.016332° (pvlib test_spa).
        let de = refraction_deg(39.872_046, 820.0, 11.0);
        assert!((de - 0.016_332).abs() < 5e-7, "{de}");
    }

    #[test]
    fn refraction_at_the_horizon_and_below() {
        // Standard conditions (1010 mbar, 10 °C): about 34′ at the horizon (Meeus ch. 16: 0.48–0.57°).
        let horizon = refraction_deg(0.0, 1010.0, 10.0);
        assert!((0.47..0.58).contains(&horizon), "{horizon}");
        // Cut-off: just above it refraction applies, just below it is zero.
        let cut = -(SUN_RADIUS_DEG + HORIZON_REFRACTION_DEG);
        assert!(refraction_deg(cut + 1e-9, 1010.0, 10.0) > 0.5);
        assert_eq!(refraction_deg(cut - 1e-9, 1010.0, 10.0), 0.0);
        assert_eq!(refraction_deg(f64::NAN, 1010.0, 10.0), 0.0);
        // At the zenith refraction vanishes.
        assert!(refraction_deg(90.0, 1010.0, 10.0).abs() < 1e-4);
    }
}
