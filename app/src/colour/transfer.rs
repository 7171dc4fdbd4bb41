//! Statistical colour transfer: fitting the affine map in lαβ that gives the TARGET (the model,
//! the image being corrected) the colour statistics of the SOURCE (the environment, the
//! reference). Naming follows the seed (source = environment, target = model); note that
//! Reinhard et al. 2001 use the opposite names.
//!
//! Methods (all produce `out = A·x + b` in an lαβ space x, then back to RGB):
//! - Reinhard et al. 2001: per channel of log lαβ, `x' = (σ_s/σ_t)(x − μ_t) + μ_s`.
//!   The seed's Eq. 11b and its `correctColor` use σ_t/σ_s — inverted: the result would have
//!   σ_t²/σ_s instead of σ_s. We use the paper's ratio.
//! - CIELAB-approx (seed Eq. 11a, Reinhard et al. 2004): the same per-channel map in lαβ without
//!   the log (one 3×3 matrix from linear RGB).
//! - MKL, the linear Monge–Kantorovich map (Pitié & Kokaram 2007, "The linear
//!   Monge-Kantorovitch linear colour mapping for example-based colour transfer", Eq. 6):
//!   `T = Σ_t^{-½} (Σ_t^{½} Σ_s Σ_t^{½})^{½} Σ_t^{-½}`, `x' = T(x − μ_t) + μ_s`, the map with
//!   `T Σ_t Tᵀ = Σ_s` that moves pixels least. We apply it in log lαβ, so it matches the full
//!   lαβ covariance, not only the per-channel σ.
//!
//! The defining property (tested): at strength 1 and before clipping, the result's mean and σ
//! per channel of the method's space equal the source's (for MKL the whole covariance).
//!
//! Robustness (where the seed failed on single-colour textures, its Fig. 33):
//! - A (near-)constant target direction (σ_t below [`SIGMA_LO`]) would need gain σ_s/σ_t → ∞
//!   and amplify shading and noise without bound. In such directions the map is the identity
//!   (only the mean moves): the target's own variation — shading, which the texture prior does
//!   not see — is kept. Between [`SIGMA_LO`] and [`SIGMA_HI`] the source variance is blended
//!   smoothly with the target's; above [`SIGMA_HI`] the map is exact. For MKL the directions are
//!   the eigenvectors of Σ_t.
//! - A flat source (all σ_s below [`SIGMA_LO`]): the map is blended to the identity by the same
//!   smoothstep of the largest source σ, so a uniform environment shifts the model's colour
//!   but does not erase its shading.
//! - Gains (eigenvalues of A) are clamped to [1/[`MAX_GAIN`], [`MAX_GAIN`]].
//!
//! The exact property therefore holds when every target σ ≥ SIGMA_HI, the source is not flat
//! and the gains lie within the clamp — true for ordinary photographs and textures.

use super::lab::LabSpace;
use super::linalg::{sym_apply, sym_eigen};
use super::stats::ColourStats;
use glam::{DMat3, DVec3};

/// Below this σ (lαβ units: log10 for the log space, linear light for the log-free one) a
/// direction counts as constant. 0.002 in log10 is a 0.5 % luminance ripple — 8-bit noise.
pub const SIGMA_LO: f64 = 0.002;
/// Above this σ a direction is fully matched (0.01 in log10 ≈ 2.3 % ripple).
pub const SIGMA_HI: f64 = 0.01;
/// Largest gain the map may apply in any direction (and 1/MAX_GAIN the smallest).
pub const MAX_GAIN: f64 = 10.0;

/// A colour-correction method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum TransferMethod {
    /// No correction (a scene's default; not offered by `colour-transfer`).
    #[value(skip)]
    None,
    /// Brightness and contrast from the luminance priors (seed Eqs. 9–10b, corrected).
    BrightnessContrast,
    /// Reinhard et al. 2001: per-channel mean and σ in log lαβ.
    Reinhard,
    /// The seed's Eq. 11a space: per-channel mean and σ in lαβ without the log.
    CielabApprox,
    /// Linear Monge–Kantorovich (Pitié & Kokaram 2007): full covariance in log lαβ.
    Mkl,
}

impl TransferMethod {
    /// The methods that transfer colour statistics, in the order reports list them.
    pub const TRANSFERS: [TransferMethod; 3] = [TransferMethod::Reinhard, TransferMethod::CielabApprox, TransferMethod::Mkl];
    /// Every correcting method.
    pub const ALL: [TransferMethod; 4] =
        [TransferMethod::BrightnessContrast, TransferMethod::Reinhard, TransferMethod::CielabApprox, TransferMethod::Mkl];

    /// The lαβ space this method works in (None for the luminance-only method).
    pub fn space(self) -> Option<LabSpace> {
        match self {
            TransferMethod::Reinhard | TransferMethod::Mkl => Some(LabSpace::Log),
            TransferMethod::CielabApprox => Some(LabSpace::Linear),
            TransferMethod::None | TransferMethod::BrightnessContrast => None,
        }
    }

    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            TransferMethod::None => "none",
            TransferMethod::BrightnessContrast => "brightness-contrast",
            TransferMethod::Reinhard => "reinhard",
            TransferMethod::CielabApprox => "cielab-approx",
            TransferMethod::Mkl => "mkl",
        }
    }

    /// The id the shader switches on (`ColourCorrection::method`).
    pub fn shader_id(self) -> u32 {
        match self {
            TransferMethod::None => 0,
            TransferMethod::BrightnessContrast => 1,
            TransferMethod::Reinhard => 2,
            TransferMethod::CielabApprox => 3,
            TransferMethod::Mkl => 4,
        }
    }
}

/// An affine map in an lαβ space: `x' = matrix·x + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AffineLab {
    pub space: LabSpace,
    pub matrix: DMat3,
    pub offset: DVec3,
}

impl AffineLab {
    /// The identity map in `space`.
    pub fn identity(space: LabSpace) -> AffineLab {
        AffineLab { space, matrix: DMat3::IDENTITY, offset: DVec3::ZERO }
    }

    /// Apply to one linear-RGB colour; no clamping (the result may be negative or above 1).
    pub fn apply_unclipped(&self, rgb: glam::Vec3) -> glam::Vec3 {
        let lab = super::lab::rgb_to_lab(self.space, rgb).as_dvec3();
        let out = self.matrix * lab + self.offset;
        super::lab::lab_to_rgb(self.space, out.as_vec3())
    }
}

/// GLSL-style smoothstep in f64 (used for the degeneracy weights).
fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Fit the map for `method` that moves `target`'s statistics onto `source`'s. Returns `None`
/// for the methods that are not transfers (none, brightness-contrast).
pub fn fit(method: TransferMethod, source: &ColourStats, target: &ColourStats) -> Option<AffineLab> {
    let space = method.space()?;
    let (mu_s, mu_t) = (source.mean_in(space), target.mean_in(space));
    let (cov_s, cov_t) = (source.cov_in(space), target.cov_in(space));
    let matrix = match method {
        TransferMethod::Mkl => robust_mkl(cov_s, cov_t),
        _ => robust_diagonal(cov_s, cov_t),
    };
    if !matrix.is_finite() || !mu_s.is_finite() || !mu_t.is_finite() {
        return Some(AffineLab::identity(space));
    }
    Some(AffineLab { space, matrix, offset: mu_s - matrix * mu_t })
}

/// Weight of the source's statistics in a direction where the target has variance `var_t`.
fn target_weight(var_t: f64) -> f64 {
    smoothstep(SIGMA_LO, SIGMA_HI, var_t.max(0.0).sqrt())
}

/// Weight of the whole map given the source covariance (0 for a flat source).
fn source_weight(cov_s: DMat3) -> f64 {
    let largest = cov_s.col(0).x.max(cov_s.col(1).y).max(cov_s.col(2).z);
    smoothstep(SIGMA_LO, SIGMA_HI, largest.max(0.0).sqrt())
}

/// Per-channel gains σ_s/σ_t (Reinhard), with the robustness rules of the module docs.
pub fn robust_diagonal(cov_s: DMat3, cov_t: DMat3) -> DMat3 {
    let floor = SIGMA_LO * SIGMA_LO;
    let gains = DVec3::from_array([0, 1, 2].map(|i| {
        let var_t = cov_t.col(i)[i];
        let w = target_weight(var_t);
        let var_t = var_t.max(floor);
        let var_s = w * cov_s.col(i)[i].max(0.0) + (1.0 - w) * var_t;
        (var_s / var_t).sqrt()
    }));
    let ws = source_weight(cov_s);
    let gains = (DVec3::ONE * (1.0 - ws) + gains * ws).clamp(DVec3::splat(1.0 / MAX_GAIN), DVec3::splat(MAX_GAIN));
    DMat3::from_diagonal(gains)
}

/// The linear Monge–Kantorovich map (Pitié & Kokaram 2007), with the robustness rules of the
/// module docs. Computed in the eigenbasis U of Σ_t, where Σ_t = diag(λ).
pub fn robust_mkl(cov_s: DMat3, cov_t: DMat3) -> DMat3 {
    let floor = SIGMA_LO * SIGMA_LO;
    let (lambda, u) = sym_eigen(cov_t);
    let w = DVec3::new(target_weight(lambda.x), target_weight(lambda.y), target_weight(lambda.z));
    let lambda = lambda.max(DVec3::splat(floor));
    // Source covariance in U, with degenerate target directions replaced by the target's own
    // variance: S' = D_w^½ S D_w^½ + diag((1 − w) λ) — a sum of PSD matrices, so PSD.
    let s = u.transpose() * cov_s * u;
    let sw = DVec3::new(w.x.sqrt(), w.y.sqrt(), w.z.sqrt());
    let dw = DMat3::from_diagonal(sw);
    let s = dw * s * dw + DMat3::from_diagonal((DVec3::ONE - w) * lambda);
    // T = Λ^{-½} (Λ^{½} S' Λ^{½})^{½} Λ^{-½}.
    let half = DMat3::from_diagonal(DVec3::new(lambda.x.sqrt(), lambda.y.sqrt(), lambda.z.sqrt()));
    let inv_half = DMat3::from_diagonal(DVec3::new(1.0 / lambda.x.sqrt(), 1.0 / lambda.y.sqrt(), 1.0 / lambda.z.sqrt()));
    let mid = super::linalg::sym_sqrt(half * s * half);
    let t = inv_half * mid * inv_half;
    let t = u * t * u.transpose();
    let ws = source_weight(cov_s);
    let t = DMat3::IDENTITY * (1.0 - ws) + t * ws;
    // T is symmetric positive semi-definite: clamp its eigenvalues (gains).
    let t = 0.5 * (t + t.transpose());
    let (g, v) = sym_eigen(t);
    sym_apply(g, v, |x| x.clamp(1.0 / MAX_GAIN, MAX_GAIN))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::colour::stats::ColourStats;
    use glam::Vec3;

    /// A deterministic, in-gamut, correlated pixel cloud (no RNG: a low-discrepancy sequence).
    pub(crate) fn cloud(n: usize, base: [f32; 3], spread: [f32; 3], twist: f32) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let a = (i as f32 * 0.618_034).fract() - 0.5;
                let b = (i as f32 * 0.754_878).fract() - 0.5;
                let c = (i as f32 * 0.569_840).fract() - 0.5;
                [
                    (base[0] + spread[0] * a).clamp(0.0, 1.0),
                    (base[1] + spread[1] * (b + twist * a)).clamp(0.0, 1.0),
                    (base[2] + spread[2] * (c + twist * b)).clamp(0.0, 1.0),
                ]
            })
            .collect()
    }

    fn apply_all(map: &AffineLab, px: &[[f32; 3]]) -> Vec<[f32; 3]> {
        px.iter().map(|p| map.apply_unclipped(Vec3::from_array(*p)).to_array()).collect()
    }

    /// Stats of unclipped results: computed in the map's own space without the sanitising clamp
    /// (the log-free space is linear in RGB so negatives are fine; the log space's inverse
    /// yields LMS ≥ −offset, which the log maps back exactly only when ≥ 0 — checked below).
    fn space_stats(space: LabSpace, px: &[[f32; 3]]) -> (DVec3, DMat3) {
        let labs: Vec<DVec3> = px.iter().map(|p| crate::colour::lab::rgb_to_lab(space, Vec3::from_array(*p)).as_dvec3()).collect();
        let n = labs.len() as f64;
        let m = labs.iter().fold(DVec3::ZERO, |a, b| a + *b) / n;
        let mut c = DMat3::ZERO;
        for v in &labs {
            let d = *v - m;
            c += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        }
        (m, c * (1.0 / n))
    }

    #[test]
    fn property_mean_and_sigma_match_source() {
        let target = cloud(4000, [0.5, 0.35, 0.2], [0.5, 0.3, 0.2], 0.4);
        let source = cloud(3000, [0.25, 0.3, 0.45], [0.3, 0.35, 0.4], -0.3);
        let (ts, ss) = (ColourStats::from_linear(&target).unwrap(), ColourStats::from_linear(&source).unwrap());
        for method in TransferMethod::TRANSFERS {
            let map = fit(method, &ss, &ts).unwrap();
            let out = apply_all(&map, &target);
            // The log space maps back exactly while LMS stays ≥ 0; for these clouds it does.
            let (m, c) = space_stats(map.space, &out);
            let (ms, cs) = space_stats(map.space, &source);
            for i in 0..3 {
                assert!((m[i] - ms[i]).abs() < 2e-4, "{method:?} mean {i}: {} vs {}", m[i], ms[i]);
                let (s1, s2) = (c.col(i)[i].sqrt(), cs.col(i)[i].sqrt());
                assert!((s1 - s2).abs() < 2e-4 * s2.max(0.01) + 1e-5, "{method:?} σ {i}: {s1} vs {s2}");
            }
            if method == TransferMethod::Mkl {
                // MKL also matches the off-diagonal covariance.
                for i in 0..3 {
                    for j in 0..3 {
                        assert!((c.col(i)[j] - cs.col(i)[j]).abs() < 1e-4 * cs.col(i)[i].max(1e-4), "{i}{j}");
                    }
                }
            }
        }
    }

    #[test]
    fn mkl_formula_matches_pitie_closed_form_in_1d_and_commuting_case() {
        // Diagonal covariances commute: T = diag(σ_s/σ_t) (Pitié & Kokaram 2007, §3).
        let cs = DMat3::from_diagonal(DVec3::new(0.04, 0.09, 0.01));
        let ct = DMat3::from_diagonal(DVec3::new(0.16, 0.01, 0.01));
        let t = robust_mkl(cs, ct);
        let expect = DMat3::from_diagonal(DVec3::new(0.5, 3.0, 1.0));
        assert!((0..3).all(|c| (t.col(c) - expect.col(c)).abs().max_element() < 1e-9), "{t}");
        // T Σ_t Tᵀ = Σ_s for a correlated pair.
        let cs = DMat3::from_cols(DVec3::new(0.05, 0.01, 0.0), DVec3::new(0.01, 0.03, 0.005), DVec3::new(0.0, 0.005, 0.02));
        let ct = DMat3::from_cols(DVec3::new(0.02, -0.008, 0.002), DVec3::new(-0.008, 0.04, 0.0), DVec3::new(0.002, 0.0, 0.03));
        let t = robust_mkl(cs, ct);
        let back = t * ct * t.transpose();
        assert!((0..3).all(|c| (back.col(c) - cs.col(c)).abs().max_element() < 1e-10));
        assert!((0..3).all(|c| (t.col(c) - t.transpose().col(c)).abs().max_element() < 1e-12), "T symmetric");
    }

    #[test]
    fn seed_ratio_is_inverted() {
        // The seed's Eq. 11b gain σ_t/σ_s: for σ_t = 0.2, σ_s = 0.1 it gives σ_out = 0.4, the
        // paper's σ_s/σ_t gives the source's 0.1. Ours:
        let g = robust_diagonal(DMat3::from_diagonal(DVec3::splat(0.01)), DMat3::from_diagonal(DVec3::splat(0.04)));
        assert!((g.col(0).x - 0.5).abs() < 1e-12);
    }

    #[test]
    fn constant_target_only_shifts_the_mean() {
        // A single-colour texture (σ_t = 0): gains are 1, the mean moves to the source's.
        let target = ColourStats::from_linear(&[[0.6, 0.1, 0.1]; 10]).unwrap();
        let source = ColourStats::from_linear(&cloud(2000, [0.3, 0.4, 0.5], [0.4, 0.4, 0.4], 0.2)).unwrap();
        for method in TransferMethod::TRANSFERS {
            let map = fit(method, &source, &target).unwrap();
            assert!((0..3).all(|c| (map.matrix.col(c) - DMat3::IDENTITY.col(c)).abs().max_element() < 1e-9), "{method:?} {}", map.matrix);
            let out = map.apply_unclipped(Vec3::new(0.6, 0.1, 0.1));
            let lab = crate::colour::lab::rgb_to_lab(map.space, out).as_dvec3();
            assert!((lab - source.mean_in(map.space)).abs().max_element() < 1e-4, "{method:?}");
            // A shading variation of the flat texture survives unamplified.
            let darker = map.apply_unclipped(Vec3::new(0.3, 0.05, 0.05));
            assert!(darker.is_finite() && darker.max_element() < out.max_element());
        }
    }

    #[test]
    fn flat_source_keeps_target_variation_and_gains_are_bounded() {
        let flat = ColourStats::from_linear(&[[0.4, 0.4, 0.4]; 5]).unwrap();
        let target = ColourStats::from_linear(&cloud(1000, [0.5, 0.3, 0.2], [0.5, 0.3, 0.2], 0.0)).unwrap();
        for method in TransferMethod::TRANSFERS {
            let map = fit(method, &flat, &target).unwrap();
            assert!((0..3).all(|c| (map.matrix.col(c) - DMat3::IDENTITY.col(c)).abs().max_element() < 1e-9), "{method:?}");
        }
        // Tiny but not degenerate target σ with a wide source: clamped at MAX_GAIN.
        let g = robust_diagonal(DMat3::from_diagonal(DVec3::splat(1.0)), DMat3::from_diagonal(DVec3::splat(0.02 * 0.02)));
        assert_eq!(g.col(0).x, MAX_GAIN);
        let t = robust_mkl(DMat3::from_diagonal(DVec3::splat(1.0)), DMat3::from_diagonal(DVec3::splat(0.02 * 0.02)));
        assert!((t.col(0).x - MAX_GAIN).abs() < 1e-9);
        // Non-finite statistics fall back to the identity instead of producing NaN.
        let mut bad = target;
        bad.lab_cov[0][0] = f64::NAN;
        let map = fit(TransferMethod::Mkl, &bad, &target).unwrap();
        assert!(map.matrix.is_finite() && map.offset.is_finite());
    }
}
