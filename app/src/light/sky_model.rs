//! The clear sky's luminance distribution, read from a map to know how hazy the day is: the
//! Perez all-weather model (R. Perez, R. Seals, J. Michalsky, "All-weather model for sky
//! luminance distribution — preliminary configuration and validation", Solar Energy 50(3),
//! 1993) with the luminance coefficients of a clear sky of turbidity T from A. J. Preetham,
//! P. Shirley, B. Smits, "A Practical Analytic Model for Daylight" (SIGGRAPH 1999, Appendix
//! A.2). A clipped map has lost its sun but keeps the sky around it; the turbidity that best
//! explains that sky's shape gives the aerosol of the clear-sky model
//! ([`super::clear_sky::bird`]) that restores the sun (light::measure::restore_sun).

use super::clear_sky::Atmosphere;
use super::samples::DirSample;
use crate::colour::luminance_bt709;
use glam::Vec3;

/// Perez's relative luminance F(θ, γ) = (1 + A e^{B / cos θ}) (1 + C e^{D γ} + E cos² γ) of the
/// sky element at zenith angle `theta` (rad), `gamma` (rad) from the sun, for coefficients
/// `[A, B, C, D, E]`. The sky's luminance is L = L_zenith · F(θ, γ) / F(0, θ_sun).
pub fn perez(theta: f64, gamma: f64, [a, b, c, d, e]: [f64; 5]) -> f64 {
    let cos_theta = theta.cos().max(1e-3);
    (1.0 + a * (b / cos_theta).exp()) * (1.0 + c * (d * gamma).exp() + e * gamma.cos().powi(2))
}

/// Preetham et al. 1999 (Appendix A.2): Perez's luminance (Y) coefficients A..E of a clear sky
/// of turbidity `t` (2: very clear, 3: clear, 6: hazy, 10+: thin fog).
pub fn luminance_coefficients(t: f64) -> [f64; 5] {
    [0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771, -0.0670 * t + 0.3703]
}

/// Ångström's turbidity coefficient β of turbidity `t` (Preetham et al. 1999, Appendix A.3).
pub fn angstrom_beta(t: f64) -> f64 {
    0.04608365822050 * t - 0.04586025928522
}

/// Ångström's wavelength exponent α that Preetham et al. use (1.3, "a good average").
pub const ANGSTROM_ALPHA: f64 = 1.3;

/// The clear-sky atmosphere of turbidity `t`: the aerosol optical depth at 380 and 500 nm by
/// Ångström's law τ(λ) = β λ^−α (λ in µm), everything else as [`Atmosphere::default`].
pub fn atmosphere_for_turbidity(t: f64) -> Atmosphere {
    let beta = angstrom_beta(t).max(0.0);
    Atmosphere { aod380: beta * 0.38f64.powf(-ANGSTROM_ALPHA), aod500: beta * 0.5f64.powf(-ANGSTROM_ALPHA), ..Atmosphere::default() }
}

/// Turbidities searched by [`fit_turbidity`]: the range Preetham's fit covers.
pub const TURBIDITY_RANGE: (f64, f64) = (1.7, 10.0);

/// Lowest elevation (rad, 5°) of the sky samples [`fit_turbidity`] uses: nearer the horizon a
/// map mostly holds terrain, trees and buildings, not sky.
pub const MIN_FIT_ELEVATION: f32 = 0.087_266_46;

/// Largest RMS residual (log luminance) of a fit whose turbidity is used: a clear sky's shape
/// explains the map's sky to about 0.12 (quarry_01, sky above 5°), while a sky seen through
/// trees and past buildings is far off (Humus Park2 1.51, Bridge2 0.78; 2026-12-01).
pub const MAX_FIT_RMS: f64 = 0.3;

/// The turbidity whose Perez sky shape best explains the samples' luminance, with the sun at unit
/// direction `sun`: the least squares of log luminance against log F(θ, γ) + a free scale (the
/// map's units), weighted by solid angle, over the samples `usable` keeps (unclipped sky above
/// [`MIN_FIT_ELEVATION`]); a coarse search over [`TURBIDITY_RANGE`] refined to 0.05. Returns
/// (turbidity, RMS residual in log luminance); None without usable samples.
pub fn fit_turbidity(samples: &[DirSample], sun: Vec3, usable: impl Fn(usize) -> bool) -> Option<(f64, f64)> {
    let theta_sun = f64::from(sun.z.clamp(-1.0, 1.0).acos());
    // (θ, γ, log L, weight) of each usable sample.
    let points: Vec<(f64, f64, f64, f64)> = samples
        .iter()
        .enumerate()
        .filter(|(i, s)| s.dir.z > MIN_FIT_ELEVATION.sin() && usable(*i) && luminance_bt709(s.radiance) > 0.0)
        .map(|(_, s)| {
            let gamma = f64::from(s.dir.dot(sun).clamp(-1.0, 1.0).acos());
            (f64::from(s.dir.z.acos()), gamma, f64::from(luminance_bt709(s.radiance)).ln(), f64::from(s.solid_angle))
        })
        .collect();
    let total: f64 = points.iter().map(|p| p.3).sum();
    if points.is_empty() || total <= 0.0 {
        return None;
    }
    let error = |t: f64| {
        let c = luminance_coefficients(t);
        let f0 = perez(0.0, theta_sun, c).ln();
        let r: Vec<f64> = points.iter().map(|p| p.2 - (perez(p.0, p.1, c).ln() - f0)).collect();
        let mean = r.iter().zip(&points).map(|(r, p)| r * p.3).sum::<f64>() / total;
        r.iter().zip(&points).map(|(r, p)| (r - mean).powi(2) * p.3).sum::<f64>() / total
    };
    let best = |from: f64, to: f64, step: f64| {
        let n = ((to - from) / step).round() as usize;
        (0..=n).map(|k| from + step * k as f64).map(|t| (t, error(t))).min_by(|a, b| a.1.total_cmp(&b.1))
    };
    let (coarse, _) = best(TURBIDITY_RANGE.0, TURBIDITY_RANGE.1, 0.25)?;
    let (t, e) = best((coarse - 0.25).max(TURBIDITY_RANGE.0), (coarse + 0.25).min(TURBIDITY_RANGE.1), 0.05)?;
    Some((t, e.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::clear_sky::bird;

    #[test]
    fn preetham_coefficients_and_perez_shape() {
        // Preetham 1999 Appendix A.2 at T = 2 and 6, by hand: A = 0.1787 T − 1.4630, ...
        let c = luminance_coefficients(2.0);
        for (got, want) in c.iter().zip([-1.1056, -0.2833, 5.2797, -2.3359, 0.2363]) {
            assert!((got - want).abs() < 1e-4, "{c:?}");
        }
        let c6 = luminance_coefficients(6.0);
        for (got, want) in c6.iter().zip([-0.3908, -1.7049, 5.1889, -1.8535, -0.0317]) {
            assert!((got - want).abs() < 1e-4, "{c6:?}");
        }
        // A clear sky is brightest around the sun and darkest about 90° from it, and brighter
        // at the horizon than at the zenith (A < 0): Perez's shape.
        let sun_theta = 60f64.to_radians();
        let at = |theta: f64, gamma: f64| perez(theta, gamma, c);
        assert!(at(sun_theta, 0.05) > 5.0 * at(sun_theta, 90f64.to_radians()));
        assert!(at(85f64.to_radians(), 120f64.to_radians()) > at(0.0, sun_theta));
        // A hazier sky has a flatter circumsolar peak relative to its dark region.
        let peak = |c: [f64; 5]| perez(sun_theta, 0.05, c) / perez(sun_theta, 90f64.to_radians(), c);
        assert!(peak(c6) < peak(c));
    }

    #[test]
    fn turbidity_gives_the_angstrom_aerosol_and_a_lower_direct_to_diffuse_ratio() {
        // β(2) = 0.04630, τ500 = β · 0.5^−1.3 = 2.4623 β = 0.1140 (Ångström's law by hand).
        assert!((angstrom_beta(2.0) - 0.046307).abs() < 1e-5);
        let a = atmosphere_for_turbidity(2.0);
        assert!((a.aod500 - 0.11402).abs() < 1e-4 && (a.aod380 - 0.16298).abs() < 1e-4, "{a:?}");
        // Haze moves light from the sun into the sky: Bird's DNI/DHI falls with turbidity.
        let ratio = |t: f64| {
            let c = bird(60.0, &atmosphere_for_turbidity(t)).unwrap();
            c.direct_normal / c.diffuse_horizontal
        };
        assert!(ratio(2.0) > ratio(3.0) && ratio(3.0) > ratio(6.0), "{} {} {}", ratio(2.0), ratio(3.0), ratio(6.0));
    }

    #[test]
    fn the_fit_recovers_the_turbidity_of_a_perez_sky() {
        // Skies drawn from the model itself at T = 2.5 and 6 (sun 20° up), in arbitrary units,
        // with a ground and a blocked patch that the fit is told to skip.
        let sun = Vec3::new(0.0, 20f32.to_radians().cos(), 20f32.to_radians().sin());
        let mut samples = Vec::new();
        let n = 90;
        for i in 0..n {
            for j in 0..2 * n {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let phi = std::f32::consts::PI * (j as f32 + 0.5) / n as f32;
                let r = (1.0 - z * z).sqrt();
                samples.push(DirSample { dir: Vec3::new(r * phi.cos(), r * phi.sin(), z), radiance: [0.0; 3], solid_angle: 1.0 });
            }
        }
        for t in [2.5, 6.0] {
            let c = luminance_coefficients(t);
            let theta_sun = f64::from(sun.z.acos());
            let sky: Vec<DirSample> = samples
                .iter()
                .map(|s| {
                    let l = if s.dir.z > 0.0 {
                        let g = f64::from(s.dir.dot(sun).clamp(-1.0, 1.0).acos());
                        (7.0 * perez(f64::from(s.dir.z.acos()), g, c) / perez(0.0, theta_sun, c)) as f32
                    } else {
                        0.2
                    };
                    DirSample { radiance: [l; 3], ..*s }
                })
                .collect();
            let blocked = |i: usize| sky[i].dir.dot(sun) > 0.99;
            let (fit, rms) = fit_turbidity(&sky, sun, |i| !blocked(i)).unwrap();
            assert!((fit - t).abs() <= 0.05 + 1e-9 && rms < 1e-3, "T {t}: fitted {fit}, rms {rms}");
        }
        assert!(fit_turbidity(&samples, sun, |_| false).is_none());
    }
}
