//! Colour statistics of a set of pixels: the CPU reference for the priors (the GPU reduction in
//! `priors::gpu` computes the same numbers) and the statistics the colour-transfer tool reports.
//!
//! Encodings (the same everywhere in Previz):
//! - `rgb_mean`, `rgb_cov`: linear-light RGB.
//! - `lab_mean`, `lab_cov`: Reinhard lαβ **with the log** ([`LabSpace::Log`]) of linear RGB.
//!   The log-free lαβ statistics are derived exactly from the RGB ones (a linear map).
//! - `luminance`: BT.709 relative luminance Y of linear RGB.
//!
//! Moments are population moments (divide by n), accumulated in f64 in two passes (mean, then
//! centred products). Pixels with a non-finite channel are skipped; negative channels are
//! clamped to 0 (they cannot come from an image, only from a broken HDR file).

use super::lab::{rgb_to_linear_lab_matrix, rgb_to_log_lab_f64};
use anyhow::{Result, bail};
use glam::{DMat3, DVec3};

/// The lower robust percentile (as a fraction).
pub const PERCENTILE_LO: f64 = 0.01;
/// The upper robust percentile (as a fraction).
pub const PERCENTILE_HI: f64 = 0.99;

/// BT.709 luminance statistics (linear light).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LuminanceStats {
    pub min: f64,
    pub mean: f64,
    pub max: f64,
    /// The [`PERCENTILE_LO`] percentile, "inverted CDF" definition: the k-th smallest value
    /// with k = max(1, ⌈p·n⌉) (Hyndman & Fan 1996, definition 1).
    pub p_lo: f64,
    /// The [`PERCENTILE_HI`] percentile, same definition.
    pub p_hi: f64,
}

/// Statistics of one pixel population.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ColourStats {
    /// Pixels that entered the statistics.
    pub count: u64,
    /// Mean linear RGB.
    pub rgb_mean: [f64; 3],
    /// Covariance of linear RGB (population, row-major).
    pub rgb_cov: [[f64; 3]; 3],
    /// Mean of log lαβ.
    pub lab_mean: [f64; 3],
    /// Covariance of log lαβ (population, row-major).
    pub lab_cov: [[f64; 3]; 3],
    /// BT.709 luminance of linear RGB.
    pub luminance: LuminanceStats,
}

/// A pixel as it enters the statistics: non-finite → `None`, negative channels → 0.
pub fn sanitize(rgb: [f32; 3]) -> Option<[f32; 3]> {
    if rgb.iter().all(|c| c.is_finite()) { Some(rgb.map(|c| c.max(0.0))) } else { None }
}

/// BT.709 luminance in f64.
pub fn luminance_f64(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Index (0-based) of the inverted-CDF percentile `p` among `n` sorted values.
pub fn percentile_rank(p: f64, n: u64) -> u64 {
    let k = (p * n as f64).ceil().max(1.0) as u64;
    k.min(n).saturating_sub(1)
}

impl ColourStats {
    /// Statistics of `pixels` (linear RGB). Errors when no finite pixel is left.
    pub fn from_linear(pixels: &[[f32; 3]]) -> Result<ColourStats> {
        let clean: Vec<[f64; 3]> = pixels.iter().filter_map(|p| sanitize(*p)).map(|p| p.map(f64::from)).collect();
        if clean.is_empty() {
            bail!("no pixels to take statistics of ({} given, none finite)", pixels.len());
        }
        let n = clean.len() as f64;
        let labs: Vec<[f64; 3]> = clean.iter().map(|p| rgb_to_log_lab_f64(*p)).collect();
        let mut lums: Vec<f64> = clean.iter().map(|p| luminance_f64(*p)).collect();

        let mean3 = |v: &[[f64; 3]]| {
            let s = v.iter().fold(DVec3::ZERO, |acc, p| acc + DVec3::from_array(*p));
            s / n
        };
        let cov3 = |v: &[[f64; 3]], m: DVec3| {
            let mut c = [[0.0; 3]; 3];
            for p in v {
                let d = DVec3::from_array(*p) - m;
                for (i, row) in c.iter_mut().enumerate() {
                    for (j, x) in row.iter_mut().enumerate() {
                        *x += d[i] * d[j];
                    }
                }
            }
            c.map(|row| row.map(|x| x / n))
        };
        let rgb_mean = mean3(&clean);
        let lab_mean = mean3(&labs);
        let lum_mean = lums.iter().sum::<f64>() / n;
        let (min, max) = lums.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &y| (lo.min(y), hi.max(y)));
        let count = clean.len() as u64;
        let mut pick = |p: f64| {
            let k = percentile_rank(p, count) as usize;
            *lums.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let p_lo = pick(PERCENTILE_LO);
        let p_hi = pick(PERCENTILE_HI);
        Ok(ColourStats {
            count,
            rgb_mean: rgb_mean.to_array(),
            rgb_cov: cov3(&clean, rgb_mean),
            lab_mean: lab_mean.to_array(),
            lab_cov: cov3(&labs, lab_mean),
            luminance: LuminanceStats { min, mean: lum_mean, max, p_lo, p_hi },
        })
    }

    /// Statistics of sRGB-encoded 8-bit pixels (decoded to linear light first).
    pub fn from_srgb8(pixels: &[[u8; 3]]) -> Result<ColourStats> {
        let lut = srgb8_to_linear_table();
        let linear: Vec<[f32; 3]> = pixels.iter().map(|p| p.map(|c| lut[c as usize])).collect();
        ColourStats::from_linear(&linear)
    }

    /// Standard deviation of each log-lαβ channel.
    pub fn lab_sigma(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.lab_cov[i][i].max(0.0).sqrt())
    }

    /// Mean in the space `space` (log lαβ as stored, or log-free lαβ derived from RGB).
    pub fn mean_in(&self, space: super::lab::LabSpace) -> DVec3 {
        match space {
            super::lab::LabSpace::Log => DVec3::from_array(self.lab_mean),
            super::lab::LabSpace::Linear => rgb_to_linear_lab_matrix() * DVec3::from_array(self.rgb_mean),
        }
    }

    /// Covariance in the space `space` (log-free: P Σ_rgb Pᵀ, exact because P is linear).
    pub fn cov_in(&self, space: super::lab::LabSpace) -> DMat3 {
        match space {
            super::lab::LabSpace::Log => super::lab::mat3_f64(&self.lab_cov),
            super::lab::LabSpace::Linear => {
                let p = rgb_to_linear_lab_matrix();
                p * super::lab::mat3_f64(&self.rgb_cov) * p.transpose()
            }
        }
    }
}

/// sRGB 8-bit code → linear light, all 256 values (IEC 61966-2-1).
pub fn srgb8_to_linear_table() -> [f32; 256] {
    std::array::from_fn(|i| super::srgb_to_linear(i as f32 / 255.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_moments() {
        // Two pixels, black and white: mean 0.5, population variance 0.25 per RGB channel,
        // perfectly correlated channels; luminance min 0, max 1, mean 0.5.
        let s = ColourStats::from_linear(&[[0.0; 3], [1.0; 3]]).unwrap();
        assert_eq!(s.count, 2);
        for i in 0..3 {
            assert!((s.rgb_mean[i] - 0.5).abs() < 1e-12);
            for j in 0..3 {
                assert!((s.rgb_cov[i][j] - 0.25).abs() < 1e-12);
            }
        }
        assert!((s.luminance.mean - 0.5).abs() < 1e-12 && s.luminance.min == 0.0 && (s.luminance.max - 1.0).abs() < 1e-12);
        // l of black = −3√3 (log offset 1e-3); of white = √3·log10(1 + 1e-3 ± row-sum error).
        let l_black = -3.0 * 3f64.sqrt();
        let l_white = rgb_to_log_lab_f64([1.0; 3])[0];
        assert!((s.lab_mean[0] - 0.5 * (l_black + l_white)).abs() < 1e-12);
        assert!((s.lab_sigma()[0] - 0.5 * (l_white - l_black)).abs() < 1e-12);
    }

    #[test]
    fn percentiles_inverted_cdf() {
        // Values 1..=200 (as grey luminance): the 1st percentile (k = ⌈2⌉ = 2) is 2, the 99th
        // (k = 198) is 198 — numpy.percentile(method="inverted_cdf") gives the same.
        let px: Vec<[f32; 3]> = (1..=200).map(|i| [i as f32; 3]).collect();
        let s = ColourStats::from_linear(&px).unwrap();
        assert!((s.luminance.p_lo - 2.0).abs() < 1e-4, "{}", s.luminance.p_lo);
        assert!((s.luminance.p_hi - 198.0).abs() < 1e-3, "{}", s.luminance.p_hi);
        assert_eq!(percentile_rank(0.01, 1), 0);
        assert_eq!(percentile_rank(0.99, 1), 0);
        assert_eq!(percentile_rank(0.99, 100), 98);
    }

    #[test]
    fn degenerate_and_bad_input() {
        assert!(ColourStats::from_linear(&[]).is_err());
        assert!(ColourStats::from_linear(&[[f32::NAN, 0.0, 0.0], [f32::INFINITY; 3]]).is_err());
        // A single colour: zero covariance, all luminance statistics equal.
        let s = ColourStats::from_linear(&[[0.2, 0.4, 0.6]; 7]).unwrap();
        assert!(s.lab_sigma().iter().all(|&x| x < 1e-7));
        assert_eq!(s.luminance.min, s.luminance.max);
        assert_eq!(s.luminance.p_lo, s.luminance.p_hi);
        // NaN pixels are skipped, negatives clamped.
        let s = ColourStats::from_linear(&[[f32::NAN, 1.0, 1.0], [-1.0, 0.0, 0.0]]).unwrap();
        assert_eq!(s.count, 1);
        assert_eq!(s.rgb_mean, [0.0; 3]);
    }

    #[test]
    fn log_free_space_is_a_linear_image_of_rgb() {
        let px: Vec<[f32; 3]> = (0..50).map(|i| [i as f32 / 50.0, (i * 7 % 50) as f32 / 50.0, 0.3]).collect();
        let s = ColourStats::from_linear(&px).unwrap();
        let p = rgb_to_linear_lab_matrix();
        let labs: Vec<DVec3> = px.iter().map(|c| p * DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)).collect();
        let m = labs.iter().fold(DVec3::ZERO, |a, b| a + *b) / 50.0;
        let var_a = labs.iter().map(|v| (v.y - m.y).powi(2)).sum::<f64>() / 50.0;
        let space = crate::colour::lab::LabSpace::Linear;
        assert!((s.mean_in(space) - m).abs().max_element() < 1e-9);
        assert!((s.cov_in(space).col(1).y - var_a).abs() < 1e-9);
    }
}
