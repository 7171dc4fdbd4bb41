//! The colour-correction uniform shared with `shaders/colour_correct.wgsl`, its constructor from
//! the priors, and [`correct`], the CPU twin of the WGSL `colour_correct` (the tool uses it; a GPU
//! test checks both agree).
//!
//! Encoding: input and output of [`correct`] are linear-light RGB. Out of gamut: negative
//! channels are clamped to 0; values above 1 are kept (the caller clips or tone-maps — the
//! `colour-transfer` tool clips per channel when it writes 8-bit sRGB).

use super::intensity::{LuminanceLevels, correct_intensity};
use super::lab::{LabSpace, lab_to_rgb, rgb_to_lab};
use super::stats::ColourStats;
use super::transfer::{TransferMethod, fit};
use glam::{Mat3, Vec3};

/// The WGSL functions (no bindings); shaders that correct colour concatenate it in front.
pub const COLOUR_CORRECT_WGSL: &str = include_str!("../../../shaders/colour_correct.wgsl");

/// Mirror of the WGSL `struct ColourCorrection` (std140-compatible uniform layout).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ColourCorrection {
    /// 3×3 map in lαβ, as three columns padded to 16 bytes (WGSL `mat3x3<f32>`).
    pub transfer: [[f32; 4]; 3],
    /// Added after `transfer`.
    pub offset: [f32; 3],
    /// [`TransferMethod::shader_id`].
    pub method: u32,
    /// 0..1.
    pub strength: f32,
    /// Environment luminance levels for brightness-contrast (linear BT.709 Y).
    pub lum_low: f32,
    pub lum_mean: f32,
    pub lum_high: f32,
}

impl ColourCorrection {
    /// No correction.
    pub fn identity() -> ColourCorrection {
        ColourCorrection {
            transfer: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
            offset: [0.0; 3],
            method: TransferMethod::None.shader_id(),
            strength: 0.0,
            lum_low: 0.0,
            lum_mean: 0.0,
            lum_high: 0.0,
        }
    }

    /// The correction that gives `target` (the model) the statistics of `source` (the
    /// environment). Brightness-contrast uses the source's robust luminance levels
    /// (1st percentile, mean, 99th percentile). `strength` is clamped to 0..1 (NaN → 0).
    pub fn new(method: TransferMethod, strength: f32, source: &ColourStats, target: &ColourStats) -> ColourCorrection {
        let lum = source.luminance;
        let levels = LuminanceLevels { low: lum.p_lo as f32, mean: lum.mean as f32, high: lum.p_hi as f32 };
        let mut cc = ColourCorrection::identity().with_levels(levels);
        cc.method = method.shader_id();
        cc.strength = if strength.is_nan() { 0.0 } else { strength.clamp(0.0, 1.0) };
        if let Some(map) = fit(method, source, target) {
            let m = map.matrix.as_mat3();
            cc.transfer = [m.x_axis.extend(0.0).to_array(), m.y_axis.extend(0.0).to_array(), m.z_axis.extend(0.0).to_array()];
            cc.offset = map.offset.as_vec3().to_array();
        }
        cc
    }

    /// Replace the luminance levels (sanitised: finite, ordered).
    pub fn with_levels(mut self, levels: LuminanceLevels) -> ColourCorrection {
        let l = levels.sanitized();
        (self.lum_low, self.lum_mean, self.lum_high) = (l.low, l.mean, l.high);
        self
    }

    /// The luminance levels.
    pub fn levels(&self) -> LuminanceLevels {
        LuminanceLevels { low: self.lum_low, mean: self.lum_mean, high: self.lum_high }
    }

    fn transfer_mat3(&self) -> Mat3 {
        let c = |i: usize| Vec3::new(self.transfer[i][0], self.transfer[i][1], self.transfer[i][2]);
        Mat3::from_cols(c(0), c(1), c(2))
    }
}

/// The correction before clamping and strength (WGSL `colour_correct_unclipped`).
pub fn correct_unclipped(rgb: Vec3, cc: &ColourCorrection) -> Vec3 {
    match cc.method {
        1 => correct_intensity(rgb, cc.levels()),
        2..=4 => {
            let space = if cc.method == 3 { LabSpace::Linear } else { LabSpace::Log };
            let lab = rgb_to_lab(space, rgb);
            lab_to_rgb(space, cc.transfer_mat3() * lab + Vec3::from_array(cc.offset))
        }
        _ => rgb,
    }
}

/// The model's colour correction (WGSL `colour_correct`): negatives clamped to 0, then
/// `mix(input, corrected, strength)`.
pub fn correct(rgb: Vec3, cc: &ColourCorrection) -> Vec3 {
    finish(rgb, correct_unclipped(rgb, cc), cc)
}

/// The last step of [`correct`] given the unclipped correction `raw` of `rgb`.
pub fn finish(rgb: Vec3, raw: Vec3, cc: &ColourCorrection) -> Vec3 {
    let s = cc.strength.clamp(0.0, 1.0);
    rgb + (raw.max(Vec3::ZERO) - rgb) * s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colour::transfer::tests::cloud;

    #[test]
    fn wgsl_validates_and_layout_matches_naga() {
        let module = crate::gpu::wgsl::validate(COLOUR_CORRECT_WGSL).unwrap();
        crate::assert_wgsl_layout!(
            module,
            ColourCorrection,
            "ColourCorrection",
            [transfer, offset, method, strength, lum_low, lum_mean, lum_high]
        );
    }

    #[test]
    fn strength_zero_is_identity_and_half_is_halfway() {
        let src = ColourStats::from_linear(&cloud(500, [0.2, 0.3, 0.6], [0.3, 0.3, 0.3], 0.1)).unwrap();
        let tgt = ColourStats::from_linear(&cloud(500, [0.6, 0.4, 0.2], [0.4, 0.3, 0.2], 0.1)).unwrap();
        let c = Vec3::new(0.5, 0.4, 0.3);
        for method in TransferMethod::ALL {
            let full = correct(c, &ColourCorrection::new(method, 1.0, &src, &tgt));
            assert!((full - c).length() > 1e-3, "{method:?} did nothing");
            assert_eq!(correct(c, &ColourCorrection::new(method, 0.0, &src, &tgt)), c);
            let half = correct(c, &ColourCorrection::new(method, 0.5, &src, &tgt));
            assert!((half - (c + full) * 0.5).abs().max_element() < 1e-6);
            assert_eq!(ColourCorrection::new(method, f32::NAN, &src, &tgt).strength, 0.0);
            assert_eq!(ColourCorrection::new(method, 7.0, &src, &tgt).strength, 1.0);
        }
    }

    #[test]
    fn output_is_finite_and_non_negative_on_extremes() {
        let src = ColourStats::from_linear(&cloud(500, [0.9, 0.1, 0.1], [0.2, 0.1, 0.1], 0.0)).unwrap();
        let tgt = ColourStats::from_linear(&cloud(500, [0.1, 0.1, 0.9], [0.1, 0.1, 0.2], 0.0)).unwrap();
        for method in TransferMethod::ALL {
            let cc = ColourCorrection::new(method, 1.0, &src, &tgt);
            for c in [Vec3::ZERO, Vec3::ONE, Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 0.0), Vec3::splat(50.0)] {
                let out = correct(c, &cc);
                assert!(out.is_finite() && out.min_element() >= 0.0, "{method:?} {c} → {out}");
            }
        }
    }
}
