//! The sun's share of the ground's light, read from the colours of the ground a map shows (issue 9,
//! clipped maps): a clipped map has lost its sun, but the ground below the horizon still holds
//! what the sun did to it.
//!
//! Model: an open ground of one albedo chromaticity ĉ (each texel its own brightness a) lit by two
//! illuminants, the sun (colour s, luminance 1) and the sky (colour k: the sky's irradiance on the
//! ground, luminance 1). A texel holds C = a (x E_sun s + E_sky k) ⊙ ĉ, where x is its share of
//! the sun (0 in shade, its facet's cosine in sunlight), so every texel's colour lies in the plane
//! through the origin spanned by u = ĉ ⊙ s and v = ĉ ⊙ k. The plane's normal n (the eigenvector
//! of Σ C Cᵀ with the least eigenvalue) is perpendicular to both, which gives the albedo's
//! chromaticity: ĉ ∝ (n ⊙ s) × (n ⊙ k). The ground's mean colour decomposed on u and v is
//! A u + B v with A / B = mean(a x) E_sun / (mean(a) E_sky); over an open ground whose facets'
//! orientation is independent of their albedo, the facets together intercept the sun's
//! horizontal irradiance (energy conservation), mean(a x) = mean(a) sin(elevation), so
//! A / B = E_sun sin(elevation) / E_sky: the sun's direct-normal irradiance over the sky's
//! diffuse horizontal one, times sin(elevation). No clear-sky model, no albedo, no
//! sunlit/shaded classification of texels is needed (quarry_01's sunlit and shaded sand are one
//! luminance mode at 1k: the shadows of its tyre tracks are smaller than a texel).
//!
//! The model holds where the ground is one material under the sky and the sun (a sandy quarry,
//! a field). Grass beside paths, furniture on a floor, a floor lit by lamps, or no sun at all
//! put the colours off any plane, or on a line: [`split`] then says None and the caller
//! keeps the clear-sky restore. Measured on every HDR of ../shared/data/hdri with a sun (docs/
//! accuracy.md, "Ninth session — clipped maps"): quarry_01's ground is within 1.7·10⁻⁵ of a plane
//! (4.4·10⁻⁵ quantised to 8 bits), every other map's 1.3·10⁻⁴ or more.

use super::samples::DirSample;
use crate::colour::linalg::sym_eigen;
use crate::colour::luminance_bt709;
use glam::{DMat3, DVec3};

/// The ground used: texels between these elevations below the horizon (rad; 5° and 60°). Nearer
/// the horizon a map holds walls, trees and far terrain; further down, the tripod and the
/// photographer.
pub const GROUND_BAND: (f32, f32) = (0.087_266_46, std::f32::consts::FRAC_PI_3);

/// Largest share of the ground colours' second moment off the plane (least eigenvalue over the
/// trace) for a ground that the two-illuminant model explains. quarry_01: 1.7·10⁻⁵ (float),
/// 4.4·10⁻⁵ (8-bit); the other maps' grounds 1.3·10⁻⁴ (city) to 4.9·10⁻³ (Humus Park2). A
/// virtual-phone 8-bit capture of quarry_01 (white-balanced, tone-mapped) is 1.2·10⁻⁴ off and
/// would read a 3× sun: not linear radiance, rightly left to the clear-sky restore.
pub const MAX_OFF_PLANE: f64 = 1e-4;

/// Largest least-over-middle eigenvalue: the plane must be spanned, not a line (a ground under
/// the sky alone, or in sunlight alone, has colours on a line, and its plane is noise).
/// quarry_01: 0.003 (float), 0.008 (8-bit).
pub const MAX_LEAST_OVER_MIDDLE: f64 = 0.05;

/// Least share of the ground band's solid angle that must hold usable (unclipped, not black)
/// texels.
pub const MIN_GROUND_SHARE: f32 = 0.5;

/// What the ground's colours say, when the two-illuminant model explains them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundSplit {
    /// E_sun sin(elevation) / E_sky: the sun's irradiance on the ground over the sky's (luminance).
    pub sun_over_sky: f64,
    /// The ground's albedo chromaticity ĉ, summing to 1.
    pub albedo_chromaticity: [f64; 3],
    /// Least eigenvalue of the colours' second moment over its trace.
    pub off_plane: f64,
    /// Least over middle eigenvalue.
    pub least_over_middle: f64,
}

/// The colours of a map's ground: their second moment's eigen-decomposition and their mean,
/// when they lie near a plane through the origin (the two-illuminant model's precondition,
/// which does not depend on the illuminants' colours).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundColours {
    /// The plane's normal: the eigenvector of Σ C Cᵀ with the least eigenvalue.
    normal: DVec3,
    /// The solid-angle weighted sum of the colours.
    mean: DVec3,
    off_plane: f64,
    least_over_middle: f64,
}

impl GroundColours {
    /// The ground of `samples` (a whole sphere, ENU): texels of [`GROUND_BAND`], those with a
    /// channel at 0.99 `clip` or above left out. None where too little ground is seen or its
    /// colours are not near a plane (see the module's doc).
    pub fn of(samples: &[DirSample], clip: f32) -> Option<GroundColours> {
        let (top, bottom) = (-GROUND_BAND.0.sin(), -GROUND_BAND.1.sin());
        let (mut m, mut mean, mut band, mut used) = (DMat3::ZERO, DVec3::ZERO, 0f64, 0f64);
        for s in samples.iter().filter(|s| s.dir.z < top && s.dir.z > bottom) {
            let w = f64::from(s.solid_angle);
            band += w;
            if s.radiance.iter().any(|&c| !(c.is_finite() && c < 0.99 * clip)) || luminance_bt709(s.radiance) <= 0.0 {
                continue;
            }
            used += w;
            let c = DVec3::from_array(s.radiance.map(f64::from));
            mean += w * c;
            m += DMat3::from_cols(c * (w * c.x), c * (w * c.y), c * (w * c.z));
        }
        if band <= 0.0 || used < f64::from(MIN_GROUND_SHARE) * band {
            return None;
        }
        let (values, vectors) = sym_eigen(m);
        let trace = values.element_sum();
        if trace <= 0.0 || values.y <= 0.0 {
            return None;
        }
        let (off_plane, least_over_middle) = (values.z / trace, values.z / values.y);
        if off_plane > MAX_OFF_PLANE || least_over_middle > MAX_LEAST_OVER_MIDDLE {
            return None;
        }
        Some(GroundColours { normal: vectors.z_axis, mean, off_plane, least_over_middle })
    }

    /// The split of these colours with the sun's colour `sun` and the sky's irradiance colour
    /// `sky` (linear RGB, any scale). None where the two colours are the same, or they give a
    /// negative albedo or a negative share.
    pub fn split(&self, sun: [f32; 3], sky: [f32; 3]) -> Option<GroundSplit> {
        let unit = |c: [f32; 3]| {
            let y = f64::from(luminance_bt709(c));
            (y > 0.0).then(|| DVec3::from_array(c.map(|v| f64::from(v) / y)))
        };
        let (s, k) = (unit(sun)?, unit(sky)?);
        let n = self.normal;
        let albedo = (n * s).cross(n * k);
        let total = albedo.element_sum();
        if total == 0.0 || !total.is_finite() {
            return None;
        }
        let albedo = albedo / total;
        if albedo.min_element() <= 0.0 {
            return None;
        }
        // The mean colour on u = ĉ⊙s and v = ĉ⊙k (least squares in RGB).
        let (u, v, mean) = (albedo * s, albedo * k, self.mean);
        let (uu, uv, vv, um, vm) = (u.dot(u), u.dot(v), v.dot(v), u.dot(mean), v.dot(mean));
        let det = uu * vv - uv * uv;
        if det.abs() <= 1e-12 * uu * vv {
            return None;
        }
        let (a, b) = ((vv * um - uv * vm) / det, (uu * vm - uv * um) / det);
        (a > 0.0 && b > 0.0).then_some(GroundSplit {
            sun_over_sky: a / b,
            albedo_chromaticity: albedo.to_array(),
            off_plane: self.off_plane,
            least_over_middle: self.least_over_middle,
        })
    }
}

/// Split the ground of `samples` (a whole sphere, ENU) into the sun's and the sky's light, with
/// the sun's colour `sun` and the sky's irradiance colour `sky` (linear RGB, any scale); texels
/// with a channel at 0.99 `clip` or above are left out. None where the model does not explain
/// the ground (see the module's doc), where the two colours are the same, or where too little
/// ground is seen: [`GroundColours::of`] then [`GroundColours::split`].
pub fn split(samples: &[DirSample], clip: f32, sun: [f32; 3], sky: [f32; 3]) -> Option<GroundSplit> {
    GroundColours::of(samples, clip)?.split(sun, sky)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A ground band of texels under a warm sun and a blue sky: texel i has brightness a_i and
    /// sun share x_i from the lists (cycled), albedo chromaticity `albedo`.
    fn ground(albedo: [f32; 3], sun: [f32; 3], sky: [f32; 3], e_sun: f32, brightness: &[f32], share: &[f32]) -> Vec<DirSample> {
        let n = 4000;
        (0..n)
            .map(|i| {
                // Evenly spread over the band's elevations (−6° .. −59°), equal solid angles.
                let el = -(6.0 + 53.0 * i as f32 / n as f32).to_radians();
                let (a, x) = (brightness[i % brightness.len()], share[(i / brightness.len()) % share.len()]);
                let radiance = std::array::from_fn(|c| a * albedo[c] * (x * e_sun * sun[c] + sky[c]));
                DirSample { dir: Vec3::new(el.cos(), 0.0, el.sin()), radiance, solid_angle: 1e-3 }
            })
            .collect()
    }

    fn unit(c: [f32; 3]) -> [f32; 3] {
        let y = luminance_bt709(c);
        c.map(|v| v / y)
    }

    #[test]
    fn a_ground_of_one_albedo_gives_the_suns_share_of_its_light() {
        // Sun colour (quarry's measured sun), sky irradiance colour (a blue sky), a sandy albedo;
        // E_sun = 3 E_sky; texels in shade (x 0) and in sunlight on facets of cosine 0.1..0.5,
        // brightness 0.5..1.3, independent of the share: the mean share is 0.2, so
        // E_sun · mean(x) / E_sky = 0.6 whatever the brightnesses.
        let (sun, sky, albedo) = (unit([1.37, 0.95, 0.37]), unit([0.8, 0.95, 1.3]), [0.45, 0.35, 0.25]);
        let samples = ground(albedo, sun, sky, 3.0, &[0.5, 0.7, 1.3, 1.0, 0.9], &[0.0, 0.1, 0.5, 0.2, 0.2]);
        let g = split(&samples, f32::INFINITY, sun, sky).expect("a split");
        assert!((g.sun_over_sky - 0.6).abs() < 1e-6, "{g:?}");
        let want = albedo.map(|c| f64::from(c) / 1.05);
        assert!(g.albedo_chromaticity.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6), "{g:?}");
        assert!(g.off_plane < 1e-12, "{g:?}");
        // The sky's and the sun's colours scale nothing: any scale of either gives the same.
        let again = split(&samples, f32::INFINITY, sun.map(|c| c * 7.0), sky.map(|c| c * 0.1)).unwrap();
        assert!((again.sun_over_sky - 0.6).abs() < 1e-6);
    }

    #[test]
    fn grounds_the_model_does_not_explain_give_nothing() {
        let (sun, sky) = (unit([1.37, 0.95, 0.37]), unit([0.8, 0.95, 1.3]));
        // No sun: every colour on one line (the plane is not spanned).
        let shade = ground([0.45, 0.35, 0.25], sun, sky, 0.0, &[0.5, 0.7, 1.3], &[0.0]);
        assert_eq!(split(&shade, f32::INFINITY, sun, sky), None);
        // Two materials (grass and a grey path) under the same light: off the plane.
        let mut mixed = ground([0.2, 0.5, 0.1], sun, sky, 3.0, &[0.5, 1.0], &[0.0, 0.3]);
        mixed.extend(ground([0.33, 0.33, 0.33], sun, sky, 3.0, &[0.5, 1.0], &[0.0, 0.3]));
        let g = split(&mixed, f32::INFINITY, sun, sky);
        assert_eq!(g, None, "{g:?}");
        // Clipped or black ground, or none in the band: nothing to read.
        let samples = ground([0.45, 0.35, 0.25], sun, sky, 3.0, &[0.5, 1.0], &[0.0, 0.3]);
        assert_eq!(split(&samples, 0.01, sun, sky), None);
        let black: Vec<DirSample> = samples.iter().map(|s| DirSample { radiance: [0.0; 3], ..*s }).collect();
        assert_eq!(split(&black, f32::INFINITY, sun, sky), None);
        let sky_only: Vec<DirSample> = samples.iter().map(|s| DirSample { dir: -s.dir, ..*s }).collect();
        assert_eq!(split(&sky_only, f32::INFINITY, sun, sky), None);
        // A sun of the sky's colour cannot be told from it.
        assert_eq!(split(&samples, f32::INFINITY, sky, sky), None);
    }
}
