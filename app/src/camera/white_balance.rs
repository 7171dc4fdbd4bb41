//! How the virtual phone balances white: per-channel gains on scene radiance before the tone
//! curve (as a camera applies them to the raw image), chosen automatically from the view.
//!
//! - Estimate: the grey-world assumption (G. Buchsbaum 1980, "A spatial processor model for
//!   object colour perception", J. Franklin Inst. 310(1):1–26): the scene's average reflectance
//!   is achromatic, so the view's average colour is the illuminant's. The average is the
//!   geometric mean per channel over the metering grid (the log average the exposure also
//!   meters: a sun or a white wall does not dominate it). Gains `[Ḡ/R̄, 1, Ḡ/B̄]`, clamped to
//!   `[1/MAX_GAIN, MAX_GAIN]`.
//! - Adaptation: like the exposure ([`super::exposure`]), each gain's log moves towards the
//!   estimate with time constant τ; the first frame starts converged. A phone's AWB follows the
//!   view, so turning from blue sky to brown rock turns the colours of the frames between shots:
//!   what a capture that does not lock the white balance records.

use anyhow::{Result, bail};

/// The largest correction per channel (a factor either way).
pub const MAX_GAIN: f32 = 2.0;
/// Default adaptation time constant (s): white balance settles more slowly than exposure.
pub const DEFAULT_ADAPTATION_S: f32 = 1.0;
/// Neutral gains.
pub const NEUTRAL: [f32; 3] = [1.0; 3];

/// How the white balance is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WhiteBalanceMode {
    /// Grey world every frame, adapting with time constant `adaptation_s` (0 = instantly).
    Auto { adaptation_s: f32 },
    /// Fixed gains on R, G, B.
    Fixed([f32; 3]),
}

impl Default for WhiteBalanceMode {
    fn default() -> Self {
        WhiteBalanceMode::Auto { adaptation_s: DEFAULT_ADAPTATION_S }
    }
}

impl WhiteBalanceMode {
    pub fn validate(&self) -> Result<()> {
        match *self {
            WhiteBalanceMode::Auto { adaptation_s } => {
                if !(adaptation_s.is_finite() && adaptation_s >= 0.0) {
                    bail!("white balance adaptation time must be >= 0 s, got {adaptation_s}");
                }
            }
            WhiteBalanceMode::Fixed(g) => {
                if !g.iter().all(|v| v.is_finite() && *v > 0.0) {
                    bail!("white balance gains must be positive numbers, got {g:?}");
                }
            }
        }
        Ok(())
    }
}

/// Grey-world gains for a view whose per-channel geometric means are `mean_rgb` (linear):
/// green keeps gain 1, red and blue are scaled to green's mean, each clamped to
/// `[1/MAX_GAIN, MAX_GAIN]`. A channel without light (mean ≤ 0 or not finite) gets gain 1.
pub fn grey_world_gains(mean_rgb: [f32; 3]) -> [f32; 3] {
    let g = mean_rgb[1];
    let gain = |c: f32| {
        if c.is_finite() && c > 0.0 && g.is_finite() && g > 0.0 { (g / c).clamp(1.0 / MAX_GAIN, MAX_GAIN) } else { 1.0 }
    };
    [gain(mean_rgb[0]), 1.0, gain(mean_rgb[2])]
}

/// White balance state across frames.
#[derive(Clone, Debug)]
pub struct AutoWhiteBalance {
    mode: WhiteBalanceMode,
    log_gains: Option<[f32; 3]>,
}

impl AutoWhiteBalance {
    pub fn new(mode: WhiteBalanceMode) -> Result<AutoWhiteBalance> {
        mode.validate()?;
        Ok(AutoWhiteBalance { mode, log_gains: None })
    }

    pub fn is_auto(&self) -> bool {
        matches!(self.mode, WhiteBalanceMode::Auto { .. })
    }

    /// The gains for a frame whose view has per-channel geometric means `mean_rgb`, `dt`
    /// seconds after the previous frame (ignored for the first; non-finite or negative counts
    /// as 0). In fixed mode `mean_rgb` is ignored.
    pub fn update(&mut self, mean_rgb: [f32; 3], dt: f64) -> [f32; 3] {
        let tau = match self.mode {
            WhiteBalanceMode::Fixed(g) => return g,
            WhiteBalanceMode::Auto { adaptation_s } => adaptation_s,
        };
        let target = grey_world_gains(mean_rgb).map(f32::ln);
        let dt = if dt.is_finite() { dt.max(0.0) as f32 } else { 0.0 };
        let next = match self.log_gains {
            Some(g) if tau > 0.0 => {
                let k = 1.0 - (-dt / tau).exp();
                std::array::from_fn(|c| g[c] + (target[c] - g[c]) * k)
            }
            _ => target,
        };
        self.log_gains = Some(next);
        next.map(f32::exp)
    }

    /// The gains of the last frame, if any.
    pub fn current(&self) -> Option<[f32; 3]> {
        match self.mode {
            WhiteBalanceMode::Fixed(g) => Some(g),
            WhiteBalanceMode::Auto { .. } => self.log_gains.map(|g| g.map(f32::exp)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_world_makes_the_average_grey() {
        // A reddish view (geometric means 0.4, 0.2, 0.1): gains 0.5, 1, 2 bring every channel's
        // mean to green's 0.2.
        let g = grey_world_gains([0.4, 0.2, 0.1]);
        assert_eq!(g, [0.5, 1.0, 2.0]);
        // Clamped at a factor of 2, neutral for a grey view or a channel without light.
        assert_eq!(grey_world_gains([0.05, 0.2, 0.9]), [2.0, 1.0, 1.0 / MAX_GAIN]);
        assert_eq!(grey_world_gains([0.3; 3]), NEUTRAL);
        assert_eq!(grey_world_gains([0.0, 0.2, f32::NAN]), NEUTRAL);
    }

    #[test]
    fn auto_white_balance_adapts_exponentially_and_fixed_stays() {
        let mut wb = AutoWhiteBalance::new(WhiteBalanceMode::Auto { adaptation_s: 1.0 }).unwrap();
        // First frame converged.
        assert_eq!(wb.update([0.4, 0.2, 0.2], 0.0), [0.5, 1.0, 1.0]);
        // The view turns grey: after one τ the red gain's log has covered 1 − 1/e of the way
        // from ln 0.5 to 0.
        let g = wb.update([0.2; 3], 1.0);
        let expect = (0.5f32.ln() * (-1.0f32).exp()).exp();
        assert!((g[0] - expect).abs() < 1e-5, "{g:?} vs {expect}");
        assert!((wb.update([0.2; 3], 100.0)[0] - 1.0).abs() < 1e-5);
        assert!(wb.current().is_some());
        let mut fixed = AutoWhiteBalance::new(WhiteBalanceMode::Fixed([1.5, 1.0, 0.8])).unwrap();
        assert_eq!(fixed.update([9.0, 1.0, 0.1], 1.0), [1.5, 1.0, 0.8]);
        assert!(AutoWhiteBalance::new(WhiteBalanceMode::Fixed([0.0, 1.0, 1.0])).is_err());
        assert!(AutoWhiteBalance::new(WhiteBalanceMode::Auto { adaptation_s: -1.0 }).is_err());
    }
}
