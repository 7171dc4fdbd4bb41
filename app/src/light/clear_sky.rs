//! Clear-sky broadband irradiance: the Bird & Hulstrom model (R. E. Bird, R. L. Hulstrom, "A
//! Simplified Clear Sky Model for Direct and Diffuse Insolation on Horizontal Surfaces",
//! SERI/TR-642-761, 1981), as pvlib implements it (`pvlib.clearsky.bird`), with Kasten's 1966
//! relative air mass. Used to restore a clipped sun: the model's direct-normal to
//! diffuse-horizontal ratio at the sun's elevation, times the diffuse light the map measures.

/// The atmosphere the model assumes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Atmosphere {
    /// Aerosol optical depth at 380 nm and 500 nm.
    pub aod380: f64,
    pub aod500: f64,
    /// Precipitable water, cm.
    pub precipitable_water: f64,
    /// Ozone column, atm-cm.
    pub ozone: f64,
    /// Surface pressure, Pa.
    pub pressure: f64,
    /// Extraterrestrial normal irradiance, W/m².
    pub dni_extra: f64,
    /// Aerosol asymmetry factor.
    pub asymmetry: f64,
    /// Ground albedo.
    pub albedo: f64,
}

impl Default for Atmosphere {
    /// pvlib's documented example atmosphere (a clear day): AOD 0.15 / 0.1, 1.42 cm water,
    /// 0.3 atm-cm ozone, sea-level pressure, 1364 W/m², asymmetry 0.85, albedo 0.2.
    fn default() -> Self {
        Atmosphere {
            aod380: 0.15,
            aod500: 0.1,
            precipitable_water: 1.42,
            ozone: 0.3,
            pressure: 101_325.0,
            dni_extra: 1364.0,
            asymmetry: 0.85,
            albedo: 0.2,
        }
    }
}

/// Direct and diffuse clear-sky irradiance, W/m².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClearSky {
    pub direct_normal: f64,
    pub diffuse_horizontal: f64,
    pub global_horizontal: f64,
}

/// Kasten (1966) relative optical air mass at apparent zenith angle `zenith_deg`; None at or
/// below the horizon.
pub fn kasten1966_airmass(zenith_deg: f64) -> Option<f64> {
    if !(0.0..90.0).contains(&zenith_deg) {
        return None;
    }
    Some(1.0 / (zenith_deg.to_radians().cos() + 0.15 * (93.885 - zenith_deg).powf(-1.253)))
}

/// Bird clear-sky irradiance at solar zenith `zenith_deg`; None with the sun at or below the
/// horizon.
pub fn bird(zenith_deg: f64, a: &Atmosphere) -> Option<ClearSky> {
    let am = kasten1966_airmass(zenith_deg)?;
    let am_p = am * a.pressure / 101_325.0;
    let t_rayleigh = (-0.0903 * am_p.powf(0.84) * (1.0 + am_p - am_p.powf(1.01))).exp();
    let am_o3 = a.ozone * am;
    let t_ozone =
        1.0 - 0.1611 * am_o3 * (1.0 + 139.48 * am_o3).powf(-0.3034) - 0.002715 * am_o3 / (1.0 + 0.044 * am_o3 + 0.0003 * am_o3 * am_o3);
    let t_gases = (-0.0127 * am_p.powf(0.26)).exp();
    let am_h2o = am * a.precipitable_water;
    let t_water = 1.0 - 2.4959 * am_h2o / ((1.0 + 79.034 * am_h2o).powf(0.6828) + 6.385 * am_h2o);
    // Broadband aerosol optical depth (Bird & Hulstrom 1980).
    let tau = 0.27583 * a.aod380 + 0.35 * a.aod500;
    let t_aerosol = (-(tau.powf(0.873)) * (1.0 + tau - tau.powf(0.7088)) * am.powf(0.9108)).exp();
    let taa = 1.0 - 0.1 * (1.0 - am + am.powf(1.06)) * (1.0 - t_aerosol);
    let rs = 0.0685 + (1.0 - a.asymmetry) * (1.0 - t_aerosol / taa);
    let direct_normal = 0.9662 * a.dni_extra * t_aerosol * t_water * t_gases * t_ozone * t_rayleigh;
    let cos_z = zenith_deg.to_radians().cos();
    let direct_horizontal = direct_normal * cos_z;
    let sky =
        a.dni_extra * cos_z * 0.79 * t_ozone * t_gases * t_water * taa * (0.5 * (1.0 - t_rayleigh) + a.asymmetry * (1.0 - t_aerosol / taa))
            / (1.0 - am + am.powf(1.02));
    let global_horizontal = (direct_horizontal + sky) / (1.0 - a.albedo * rs);
    Some(ClearSky { direct_normal, diffuse_horizontal: global_horizontal - direct_horizontal, global_horizontal })
}

/// Dominant wavelengths (µm) of the BT.709 / sRGB red, green and blue primaries: where the beam's
/// spectral transmittance is read for each channel in [`beam_colour`].
pub const PRIMARY_WAVELENGTHS_UM: [f64; 3] = [0.611, 0.549, 0.464];

/// Rayleigh optical depth of the standard atmosphere at wavelength `um` (µm), at sea level
/// (Bird & Riordan 1986, SPCTRAL2: τ_R = 1 / (λ⁴ (115.6406 − 1.335 / λ²))).
pub fn rayleigh_depth(um: f64) -> f64 {
    1.0 / (um.powi(4) * (115.6406 - 1.335 / (um * um)))
}

/// The colour of the direct beam at solar zenith `zenith_deg` through `a` (linear BT.709 RGB,
/// luminance 1): a white sun (equal energy in the three channels above the atmosphere)
/// attenuated along Kasten's air mass by Rayleigh scattering ([`rayleigh_depth`], scaled by
/// pressure) and the aerosol of `a` (Ångström's τ = β λ^−α through its 380 and 500 nm depths),
/// each channel at its primary's dominant wavelength ([`PRIMARY_WAVELENGTHS_UM`]). Ozone and water
/// vapour are left out (Chappuis band and near infrared: a few per cent in the visible). None
/// with the sun at or below the horizon.
pub fn beam_colour(zenith_deg: f64, a: &Atmosphere) -> Option<[f32; 3]> {
    let am = kasten1966_airmass(zenith_deg)?;
    let alpha = if a.aod380 > 0.0 && a.aod500 > 0.0 { (a.aod380 / a.aod500).ln() / (0.5f64 / 0.38).ln() } else { 0.0 };
    let beta = a.aod500 * 0.5f64.powf(alpha);
    let t = PRIMARY_WAVELENGTHS_UM.map(|um| (-am * (rayleigh_depth(um) * a.pressure / 101_325.0 + beta * um.powf(-alpha))).exp());
    let y = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
    (y > 0.0).then(|| t.map(|c| (c / y) as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_pvlib_bird() {
        // pvlib 0.16.1 `pvlib.clearsky.bird(zenith, airmass_relative=get_relative_airmass(zenith,
        // 'kasten1966'), aod380=0.15, aod500=0.1, precipitable_water=1.42)` (all other
        // arguments default), computed with pvlib 0.16.1 from PyPI (tests/reference/README.md gives the command).
        let cases: [(f64, [f64; 3]); 4] = PVLIB_BIRD;
        for (z, [dni, dhi, ghi]) in cases {
            let c = bird(z, &Atmosphere::default()).unwrap();
            for (ours, theirs, name) in
                [(c.direct_normal, dni, "dni"), (c.diffuse_horizontal, dhi, "dhi"), (c.global_horizontal, ghi, "ghi")]
            {
                assert!((ours - theirs).abs() < 1e-6 * theirs.max(1.0), "zenith {z} {name}: {ours} vs pvlib {theirs}");
            }
        }
        assert!(bird(90.0, &Atmosphere::default()).is_none());
        assert!(bird(-1.0, &Atmosphere::default()).is_none());
    }

    #[test]
    fn the_beam_reddens_towards_the_horizon() {
        // SPCTRAL2's Rayleigh depth at 0.5 µm by hand: 1 / (0.0625 · (115.6406 − 5.34)) = 0.14506.
        assert!((rayleigh_depth(0.5) - 0.145_06).abs() < 1e-4, "{}", rayleigh_depth(0.5));
        // Without aerosol, overhead (air mass 1): R, G, B transmit e^−τ at 611, 549, 464 nm.
        let clean = Atmosphere { aod380: 0.0, aod500: 0.0, ..Atmosphere::default() };
        let c = beam_colour(0.0, &clean).unwrap();
        let t = PRIMARY_WAVELENGTHS_UM.map(|um| (-kasten1966_airmass(0.0).unwrap() * rayleigh_depth(um)).exp());
        let y = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
        for k in 0..3 {
            assert!((f64::from(c[k]) - t[k] / y).abs() < 1e-6, "{c:?}");
        }
        // Luminance 1, and ever redder as the sun goes down: quarry_01's measured sun 10.1° up
        // (light::measure, RGB / luminance 1.37, 0.95, 0.37) lies between the colours at its
        // elevation for a clear and a hazy day.
        let a = Atmosphere::default();
        let (high, low) = (beam_colour(30.0, &a).unwrap(), beam_colour(79.9, &a).unwrap());
        assert!((0.2126 * low[0] + 0.7152 * low[1] + 0.0722 * low[2] - 1.0).abs() < 1e-5);
        assert!(low[0] / low[2] > high[0] / high[2] && high[0] / high[2] > c[0] / c[2], "{high:?} {low:?}");
        let hazy = beam_colour(79.9, &Atmosphere { aod380: 0.45, aod500: 0.3, ..a }).unwrap();
        let quarry = 1.37f32 / 0.37;
        assert!(low[0] / low[2] < quarry && quarry < hazy[0] / hazy[2], "{low:?} {hazy:?}");
        assert!(beam_colour(90.0, &a).is_none());
    }

    /// (zenith deg, [dni, dhi, ghi] W/m²) from pvlib.
    const PVLIB_BIRD: [(f64, [f64; 3]); 4] = [
        (0.0, [952.0935794060712, 123.84002418582725, 1075.9336035918984]),
        (45.0, [877.8613034600796, 109.90612352037624, 730.6478041382602]),
        (80.0, [461.6317786971633, 52.68076614550557, 132.8422832694117]),
        (89.0, [106.76541164799214, 1.305466989405043, 3.1687803469296942]),
    ];
}
