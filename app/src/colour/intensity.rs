//! Brightness and contrast matching to the environment's luminance priors (seed 000 §5.6.1,
//! Eqs. 8–10b and `correctGS` in Appendix E), as a corrected, well-defined version.
//!
//! What the seed does, and why we changed it:
//! - Eq. 8 is Haeberli & Voorhies' (1994) interpolation `mix(source, target, α)`.
//! - The fit: `t̂ = smoothstep(s_l, s_h, Y)` places the pixel's luminance Y in the
//!   environment's range [s_l, s_h] (darkest, brightest prior).
//! - Brightness (Eq. 9): `b = mix(s_l, s_h, t̂)` — the pixel's luminance smoothly clamped into the
//!   environment's range. The seed then multiplies the *colour* by b (`C_o = t·b`), which gives
//!   output luminance Y·b — in [0, s_h], not in [s_l, s_h] as the text promises ("never darker or
//!   lighter than the environment"). We make b the output luminance (colour scaled by b / Y).
//! - Contrast (Eqs. 10a/10b): as printed, `c = mix(s_l, s_μ, (t − s_l)/(s_μ − s_l))` is the
//!   identity c = t (the mix undoes the normalisation), so the "contrast factor" is the pixel
//!   itself, and `correctGS` compares the normalised t̂ with the un-normalised mean s_μ. It also
//!   divides by zero for a flat environment (s_μ = s_l or s_h = s_μ). We implement the biased
//!   contrast the text describes: a two-piece curve through the environment's (min, mean, max)
//!   with the pivot at the middle of the fitted range — `t̂ < ½ → mix(s_l, s_μ, 2t̂)`,
//!   else `mix(s_μ, s_h, 2t̂ − 1)` — so mid-tones go to the environment's mean.
//! - The seed's final `mix(brightness, contrast, 0.5)` is kept.
//!
//! Everything is in linear light; Y is BT.709 luminance. The chromaticity of the pixel is kept
//! (RGB scaled by Y_out / Y); a black pixel (Y ≈ 0) becomes grey Y_out. Degenerate priors (a flat
//! environment, s_l = s_μ = s_h) give Y_out = s_μ for every pixel, with no division by zero.

use glam::Vec3;

/// The environment's luminance levels that drive the correction (linear BT.709 Y).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct LuminanceLevels {
    pub low: f32,
    pub mean: f32,
    pub high: f32,
}

impl LuminanceLevels {
    /// Levels made safe to use: finite, ≥ 0 and ordered low ≤ mean ≤ high (mean clamped into
    /// [low, high]; NaN → 0).
    pub fn sanitized(self) -> LuminanceLevels {
        let f = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
        let (a, b) = (f(self.low), f(self.high));
        let (low, high) = if a <= b { (a, b) } else { (b, a) };
        LuminanceLevels { low, mean: f(self.mean).clamp(low, high), high }
    }
}

/// Smallest range treated as non-degenerate (linear luminance units).
pub const MIN_RANGE: f32 = 1e-6;

/// GLSL/WGSL `smoothstep` (Hermite t²(3 − 2t), WGSL spec §17.5 "smoothstep"), defined also when
/// `e1 − e0 < MIN_RANGE`: then it is a step at e0 (0 below, 1 at or above). WGSL leaves that
/// case undefined.
pub fn smoothstep_safe(e0: f32, e1: f32, x: f32) -> f32 {
    if e1 - e0 < MIN_RANGE {
        return if x >= e0 { 1.0 } else { 0.0 };
    }
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Output luminance for input luminance `y` (see module docs). Non-decreasing in `y`, always in
/// [low, high].
pub fn fit_luminance(y: f32, levels: LuminanceLevels) -> f32 {
    let LuminanceLevels { low, mean, high } = levels;
    let t = smoothstep_safe(low, high, y);
    let brightness = low + (high - low) * t;
    let contrast = if t < 0.5 { low + (mean - low) * (2.0 * t) } else { mean + (high - mean) * (2.0 * t - 1.0) };
    0.5 * (brightness + contrast)
}

/// Luminance below which a pixel counts as black (its chromaticity is undefined).
pub const BLACK: f32 = 1e-6;

/// The brightness/contrast correction of one linear-RGB colour (strength 1).
pub fn correct_intensity(rgb: Vec3, levels: LuminanceLevels) -> Vec3 {
    let rgb = rgb.max(Vec3::ZERO);
    let y = super::luminance_bt709(rgb.to_array());
    let y_out = fit_luminance(y, levels);
    if y > BLACK { rgb * (y_out / y) } else { Vec3::splat(y_out) }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LEVELS: LuminanceLevels = LuminanceLevels { low: 0.05, mean: 0.2, high: 0.8 };

    #[test]
    fn smoothstep_matches_hermite_and_degenerates_to_a_step() {
        // Hermite values: t = 0.25 → 0.15625, t = 0.5 → 0.5 (WGSL/GLSL definition).
        assert!((smoothstep_safe(0.0, 4.0, 1.0) - 0.156_25).abs() < 1e-7);
        assert_eq!(smoothstep_safe(1.0, 3.0, 2.0), 0.5);
        assert_eq!(smoothstep_safe(1.0, 3.0, -5.0), 0.0);
        assert_eq!(smoothstep_safe(1.0, 3.0, 9.0), 1.0);
        assert_eq!(smoothstep_safe(0.3, 0.3, 0.29), 0.0);
        assert_eq!(smoothstep_safe(0.3, 0.3, 0.3), 1.0);
    }

    #[test]
    fn output_stays_in_range_and_is_monotonic() {
        let mut prev = f32::NEG_INFINITY;
        for i in 0..=1000 {
            let y = i as f32 / 500.0; // 0..2, beyond the environment's range on both sides
            let out = fit_luminance(y, LEVELS);
            assert!((LEVELS.low..=LEVELS.high).contains(&out), "y {y} → {out}");
            assert!(out >= prev - 1e-7, "not monotonic at {y}");
            prev = out;
        }
        // End points and pivot: below the range → low, above → high, middle of the range → the
        // average of the brightness (midpoint) and the contrast pivot (mean).
        assert_eq!(fit_luminance(0.0, LEVELS), LEVELS.low);
        assert_eq!(fit_luminance(5.0, LEVELS), LEVELS.high);
        let mid = 0.5 * (LEVELS.low + LEVELS.high);
        assert!((fit_luminance(mid, LEVELS) - 0.5 * (mid + LEVELS.mean)).abs() < 1e-6);
    }

    #[test]
    fn keeps_chromaticity_and_hits_the_luminance() {
        let c = Vec3::new(0.3, 0.1, 0.05);
        let out = correct_intensity(c, LEVELS);
        let y_out = crate::colour::luminance_bt709(out.to_array());
        assert!((y_out - fit_luminance(crate::colour::luminance_bt709(c.to_array()), LEVELS)).abs() < 1e-6);
        assert!((out / out.x - c / c.x).abs().max_element() < 1e-5);
    }

    #[test]
    fn degenerate_priors() {
        // Flat environment: every pixel goes to the one level, black included; no NaN.
        let flat = LuminanceLevels { low: 0.3, mean: 0.3, high: 0.3 };
        for y in [0.0, 0.1, 0.3, 0.9, 100.0] {
            assert_eq!(fit_luminance(y, flat), 0.3);
        }
        assert_eq!(correct_intensity(Vec3::ZERO, flat), Vec3::splat(0.3));
        // mean = min and max = mean: finite, in range, monotonic.
        for levels in [LuminanceLevels { low: 0.1, mean: 0.1, high: 0.6 }, LuminanceLevels { low: 0.1, mean: 0.6, high: 0.6 }] {
            let mut prev = 0.0;
            for i in 0..=100 {
                let out = fit_luminance(i as f32 / 100.0, levels);
                assert!(out.is_finite() && out >= prev - 1e-7 && (0.1..=0.6).contains(&out));
                prev = out;
            }
        }
        // Disordered / non-finite levels are repaired.
        let s = LuminanceLevels { low: 0.9, mean: f32::NAN, high: 0.1 }.sanitized();
        assert_eq!(s, LuminanceLevels { low: 0.1, mean: 0.1, high: 0.9 });
    }
}
