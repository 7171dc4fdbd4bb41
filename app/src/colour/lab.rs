//! Ruderman's decorrelated opponent space lαβ as used for colour transfer by Reinhard et al.
//! ("Color Transfer between Images", IEEE CG&A 21(5), 2001, §2), and the log-free variant the
//! seed calls "CIELAB-like" (Reinhard et al. 2004, "Real-time color blending of rendered and
//! captured video", seed 000 Eq. 11a).
//!
//! Pipeline: linear-light RGB → LMS (cone responses) → log10 → lαβ, and back. The WGSL copy
//! of these constants is in `shaders/colour_correct.wgsl`; a GPU test checks both agree.
//!
//! Encoding: the input is **linear-light** RGB (decode sRGB first). Reinhard 2001 does not say
//! whether its RGB is gamma-encoded; the log of cone responses is only meaningful on linear
//! light, and our shader works in linear light, so every lαβ statistic in Previz is of linear RGB.
//!
//! Robustness:
//! - log(0): black has L = M = S = 0. We use `log10(max(x, 0) + LOG_OFFSET)`: an exact
//!   bijection of [0, ∞) onto [log10(LOG_OFFSET), ∞) whose inverse is `10^y − LOG_OFFSET`.
//!   A pure log would send black to −∞ and let a few black pixels dominate σ.
//! - Negative LMS (only from out-of-gamut input) is treated as 0 by the log.
//! - The inverse of the log can give LMS down to −LOG_OFFSET, i.e. slightly negative RGB; the
//!   corrector clamps RGB at 0 after the transfer (see `correction`).

use glam::{Mat3, Vec3};

/// RGB → LMS, row-major as printed (Reinhard et al. 2001, the RGB→LMS matrix of §2).
///
/// The paper prints 0.1288 for the element (S, G). Its own printed inverse (LMS → RGB) and the
/// combined RGB → lαβ matrix of Reinhard et al. 2004 (seed Eq. 11a) both imply 0.1228
/// (inverting either gives 0.12282); we use 0.1228 so that the published matrices are
/// reproduced to about their printed precision (tests below).
pub const RGB_TO_LMS: [[f64; 3]; 3] = [[0.3811, 0.5783, 0.0402], [0.1967, 0.7244, 0.0782], [0.0241, 0.1228, 0.8444]];

/// LMS → RGB: the exact inverse of [`RGB_TO_LMS`] (computed in f64; the paper prints it
/// rounded to 4 decimals, tested below).
pub const LMS_TO_RGB: [[f64; 3]; 3] = [
    [4.467795416157, -3.586967404271, 0.119487772720],
    [-1.218527611928, 2.380764808674, -0.162471575129],
    [0.049693653737, -0.243855997231, 1.204490589890],
];

/// Offset added before the log (linear units, LMS of white ≈ 1). Black maps to −3; the darkest
/// non-black 8-bit sRGB value (1/255 → 3.0e-4 linear) maps to about −2.89, so black pixels stay
/// within a tenth of a decade of the darkest visible ones.
pub const LOG_OFFSET: f64 = 1e-3;

const INV_SQRT3: f64 = 0.577_350_269_189_625_8;
const INV_SQRT6: f64 = 0.408_248_290_463_863;
const INV_SQRT2: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// LMS (log or not) → lαβ: diag(1/√3, 1/√6, 1/√2) · [[1,1,1],[1,1,−2],[1,−1,0]]
/// (Reinhard et al. 2001, §2).
pub const LMS_TO_LAB: [[f64; 3]; 3] =
    [[INV_SQRT3, INV_SQRT3, INV_SQRT3], [INV_SQRT6, INV_SQRT6, -2.0 * INV_SQRT6], [INV_SQRT2, -INV_SQRT2, 0.0]];

/// lαβ → LMS: [[1,1,1],[1,1,−1],[1,−2,0]] · diag(√3/3, √6/6, √2/2) (Reinhard et al. 2001, §2).
pub const LAB_TO_LMS: [[f64; 3]; 3] =
    [[INV_SQRT3, INV_SQRT6, INV_SQRT2], [INV_SQRT3, INV_SQRT6, -INV_SQRT2], [INV_SQRT3, -2.0 * INV_SQRT6, 0.0]];

/// Which lαβ: with the log (Reinhard 2001) or without (Reinhard 2004 / seed Eq. 11a).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LabSpace {
    /// RGB → LMS → log10(· + LOG_OFFSET) → lαβ (Reinhard et al. 2001).
    Log,
    /// RGB → LMS → lαβ with no log: one 3×3 matrix (seed Eq. 11a, Reinhard et al. 2004).
    Linear,
}

/// A row-major constant as a glam (column-major) f32 matrix.
pub fn mat3_f32(rows: &[[f64; 3]; 3]) -> Mat3 {
    Mat3::from_cols_array_2d(&[
        [rows[0][0] as f32, rows[1][0] as f32, rows[2][0] as f32],
        [rows[0][1] as f32, rows[1][1] as f32, rows[2][1] as f32],
        [rows[0][2] as f32, rows[1][2] as f32, rows[2][2] as f32],
    ])
}

/// A row-major constant as a glam (column-major) f64 matrix.
pub fn mat3_f64(rows: &[[f64; 3]; 3]) -> glam::DMat3 {
    glam::DMat3::from_cols_array_2d(&[
        [rows[0][0], rows[1][0], rows[2][0]],
        [rows[0][1], rows[1][1], rows[2][1]],
        [rows[0][2], rows[1][2], rows[2][2]],
    ])
}

/// The combined RGB → lαβ matrix of the log-free space (seed Eq. 11a), f64.
pub fn rgb_to_linear_lab_matrix() -> glam::DMat3 {
    mat3_f64(&LMS_TO_LAB) * mat3_f64(&RGB_TO_LMS)
}

/// Linear RGB → LMS.
pub fn rgb_to_lms(rgb: Vec3) -> Vec3 {
    mat3_f32(&RGB_TO_LMS) * rgb
}

/// LMS → linear RGB.
pub fn lms_to_rgb(lms: Vec3) -> Vec3 {
    mat3_f32(&LMS_TO_RGB) * lms
}

/// log10(max(x, 0) + LOG_OFFSET) per channel.
pub fn lms_to_log(lms: Vec3) -> Vec3 {
    let o = LOG_OFFSET as f32;
    Vec3::new((lms.x.max(0.0) + o).log10(), (lms.y.max(0.0) + o).log10(), (lms.z.max(0.0) + o).log10())
}

/// Inverse of [`lms_to_log`] for LMS ≥ 0: 10^y − LOG_OFFSET.
pub fn log_to_lms(log: Vec3) -> Vec3 {
    let o = LOG_OFFSET as f32;
    Vec3::new(10f32.powf(log.x) - o, 10f32.powf(log.y) - o, 10f32.powf(log.z) - o)
}

/// Linear RGB → lαβ in `space`.
pub fn rgb_to_lab(space: LabSpace, rgb: Vec3) -> Vec3 {
    let lms = rgb_to_lms(rgb);
    let lms = match space {
        LabSpace::Log => lms_to_log(lms),
        LabSpace::Linear => lms,
    };
    mat3_f32(&LMS_TO_LAB) * lms
}

/// lαβ in `space` → linear RGB (not clamped: can be negative or above 1).
pub fn lab_to_rgb(space: LabSpace, lab: Vec3) -> Vec3 {
    let lms = mat3_f32(&LAB_TO_LMS) * lab;
    let lms = match space {
        LabSpace::Log => log_to_lms(lms),
        LabSpace::Linear => lms,
    };
    lms_to_rgb(lms)
}

/// Linear RGB → log lαβ in f64 (statistics accumulate in f64 on the CPU).
pub fn rgb_to_log_lab_f64(rgb: [f64; 3]) -> [f64; 3] {
    let lms = mat3_f64(&RGB_TO_LMS) * glam::DVec3::from_array(rgb);
    let log = glam::DVec3::new(
        (lms.x.max(0.0) + LOG_OFFSET).log10(),
        (lms.y.max(0.0) + LOG_OFFSET).log10(),
        (lms.z.max(0.0) + LOG_OFFSET).log10(),
    );
    (mat3_f64(&LMS_TO_LAB) * log).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    fn assert_rows_close(a: DMat3, rows: [[f64; 3]; 3], tol: f64) {
        let b = mat3_f64(&rows);
        for c in 0..3 {
            for r in 0..3 {
                let (x, y) = (a.col(c)[r], b.col(c)[r]);
                assert!((x - y).abs() <= tol, "element ({r},{c}): {x} vs {y}");
            }
        }
    }

    #[test]
    fn exact_inverses() {
        assert_rows_close(mat3_f64(&RGB_TO_LMS) * mat3_f64(&LMS_TO_RGB), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], 1e-9);
        assert_rows_close(mat3_f64(&LMS_TO_LAB) * mat3_f64(&LAB_TO_LMS), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], 1e-12);
    }

    #[test]
    fn reproduces_published_matrices() {
        // Reinhard et al. 2001, printed LMS → RGB (4 decimals).
        assert_rows_close(mat3_f64(&LMS_TO_RGB), [[4.4679, -3.5873, 0.1193], [-1.2186, 2.3809, -0.1624], [0.0497, -0.2439, 1.2045]], 5e-4);
        // Reinhard et al. 2004 / seed 000 Eq. 11a: RGB → lαβ without the log, and its inverse.
        assert_rows_close(
            rgb_to_linear_lab_matrix(),
            [[0.3475, 0.8231, 0.5559], [0.2162, 0.4316, -0.6411], [0.1304, -0.1033, -0.0269]],
            1e-4,
        );
        assert_rows_close(
            rgb_to_linear_lab_matrix().inverse(),
            [[0.5773, 0.2621, 5.6947], [0.5774, 0.6072, -2.5444], [0.5832, -1.0627, 0.2073]],
            2e-3,
        );
    }

    #[test]
    fn grey_has_no_chroma_and_round_trips() {
        // Equal RGB → near-equal LMS (rows of RGB_TO_LMS sum to ~1) → α, β ≈ 0.
        for space in [LabSpace::Log, LabSpace::Linear] {
            let lab = rgb_to_lab(space, Vec3::splat(0.5));
            assert!(lab.y.abs() < 0.01 && lab.z.abs() < 0.01, "{space:?} {lab}");
            for rgb in [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.02, 0.5, 0.9), Vec3::splat(40.0)] {
                let back = lab_to_rgb(space, rgb_to_lab(space, rgb));
                assert!((back - rgb).abs().max_element() < 2e-4 * rgb.max_element().max(1.0), "{space:?} {rgb} -> {back}");
            }
        }
    }

    #[test]
    fn log_of_black_is_finite() {
        let lab = rgb_to_lab(LabSpace::Log, Vec3::ZERO);
        // log10(LOG_OFFSET) = −3 in each LMS channel → l = −3·√3, α = β = 0.
        assert!((lab.x + 3.0 * 3f32.sqrt()).abs() < 1e-5 && lab.y.abs() < 1e-6 && lab.z.abs() < 1e-6);
        // Negative (out-of-gamut) input is treated as zero cone response, not NaN.
        assert!(rgb_to_lab(LabSpace::Log, Vec3::new(-1.0, -1.0, -1.0)).is_finite());
        let f = rgb_to_log_lab_f64([0.0, 0.0, 0.0]);
        assert!((f[0] as f32 - lab.x).abs() < 1e-5);
    }
}
