//! How the virtual phone turns scene radiance into 8-bit sRGB: auto-exposure that meters the
//! log-average luminance and maps it to middle grey, smoothed over time like a phone's, then a
//! filmic tone curve and the sRGB encoding.
//!
//! - Metering: Reinhard et al. 2002, "Photographic Tone Reproduction for Digital Images",
//!   eq. 1–2: L̄ = exp(mean(ln(δ + L))), exposure = key / L̄ with key 0.18 (middle grey).
//! - Adaptation: the exposure's log moves towards the metered target with time constant τ,
//!   e ← e + (e* − e)(1 − exp(−Δt/τ)) (the exponential adaptation used by game-engine eye
//!   adaptation); the first frame starts converged.
//! - Tone curve: K. Narkowicz 2015, "ACES Filmic Tone Mapping Curve" (the fit
//!   x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14), clamped to [0, 1]), then sRGB encoding
//!   (IEC 61966-2-1).

use crate::colour::{linear_to_srgb, luminance_bt709};
use anyhow::{Result, bail};

/// Middle grey: the scene-referred value the metered average is exposed to.
pub const MIDDLE_GREY: f32 = 0.18;
/// Default adaptation time constant in seconds (phones settle within about a second).
pub const DEFAULT_ADAPTATION_S: f32 = 0.4;
/// δ in the log average, keeps black pixels finite (Reinhard et al. 2002 eq. 1).
const LOG_DELTA: f32 = 1e-4;
/// Exposure is kept within 2^±20 so a black or blinding scene cannot produce inf or 0.
const LOG2_EXPOSURE_LIMIT: f32 = 20.0;

/// Narkowicz's ACES filmic fit; input is exposed linear light, output display-linear [0, 1].
pub fn aces_filmic(x: f32) -> f32 {
    let x = if x.is_finite() {
        x.max(0.0)
    } else if x > 0.0 {
        return 1.0;
    } else {
        0.0
    };
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// The inverse of [`aces_filmic`] on [0, 1): the exposed linear light that the curve maps to
/// display-linear `y` (the quadratic y·(2.43x² + 0.59x + 0.14) = 2.51x² + 0.03x solved for its
/// positive root). `y` ≥ 1 is the curve's white point, [`ACES_WHITE`]: a clipped value, whose
/// true light is anywhere above.
pub fn aces_filmic_inverse(y: f32) -> f32 {
    if y.is_nan() || y <= 0.0 {
        return 0.0;
    }
    if y >= 1.0 {
        return ACES_WHITE;
    }
    let (y, a) = (f64::from(y), 2.43 * f64::from(y) - 2.51);
    let b = 0.59 * y - 0.03;
    let c = 0.14 * y;
    ((-b - (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)) as f32
}

/// Where [`aces_filmic`] reaches 1: the positive root of 0.08x² − 0.56x − 0.14 = 0.
pub const ACES_WHITE: f32 = 7.241_657;

/// The known tone curve inverted: an 8-bit sRGB code value back to the exposed linear light
/// (`x` in [`tone_to_srgb8`]) at the code's centre. Code 255 is clipped: see
/// [`saturation_exposed`].
pub fn srgb8_to_exposed(code: u8) -> f32 {
    aces_filmic_inverse(crate::colour::srgb_to_linear(f32::from(code) / 255.0))
}

/// [`srgb8_to_exposed`] for every code value.
pub fn exposed_lut() -> [f32; 256] {
    std::array::from_fn(|i| srgb8_to_exposed(i as u8))
}

/// The exposed linear light at which the 8-bit output saturates (code 255 from here on: the
/// curve's value where the sRGB code rounds up to 255).
pub fn saturation_exposed() -> f32 {
    aces_filmic_inverse(crate::colour::srgb_to_linear(254.5 / 255.0))
}

/// Exposed linear light to an 8-bit sRGB code value: tone curve, sRGB encoding, rounding.
pub fn tone_to_srgb8(x: f32) -> u8 {
    (linear_to_srgb(aces_filmic(x)) * 255.0 + 0.5) as u8
}

/// [`tone_to_srgb8`] as a lookup table indexed by √(x / X_MAX), for the per-pixel loop.
/// Agrees with the exact curve within one code value (tested).
pub struct ToneLut {
    table: Vec<u8>,
}

impl ToneLut {
    /// Above this the curve is white (ACES fit reaches 1 at x ≈ 7.24).
    const X_MAX: f32 = 8.0;
    const N: usize = 4096;

    pub fn new() -> ToneLut {
        let table = (0..Self::N)
            .map(|i| {
                let s = i as f32 / (Self::N - 1) as f32;
                tone_to_srgb8(s * s * Self::X_MAX)
            })
            .collect();
        ToneLut { table }
    }

    #[inline]
    pub fn map(&self, x: f32) -> u8 {
        // NaN and negatives fall to 0 through the saturating float-to-int cast.
        let s = (x * (1.0 / Self::X_MAX)).sqrt() * (Self::N - 1) as f32 + 0.5;
        self.table[(s as usize).min(Self::N - 1)]
    }
}

impl Default for ToneLut {
    fn default() -> Self {
        ToneLut::new()
    }
}

/// Reinhard's log-average luminance of linear RGB samples; δ-floor for empty input.
pub fn log_average_luminance(samples: impl Iterator<Item = [f32; 3]>) -> f32 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for s in samples {
        let l = luminance_bt709(s);
        let l = if l.is_finite() { l.max(0.0) } else { 0.0 };
        sum += ((LOG_DELTA + l) as f64).ln();
        n += 1;
    }
    if n == 0 { LOG_DELTA } else { (sum / n as f64).exp() as f32 }
}

/// How exposure is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExposureMode {
    /// Meter every frame; expose the log average to `key`, adapting with time constant
    /// `adaptation_s` (0 = instantly).
    Auto { key: f32, adaptation_s: f32 },
    /// A fixed multiplier on scene radiance.
    Fixed(f32),
}

impl Default for ExposureMode {
    fn default() -> Self {
        ExposureMode::Auto { key: MIDDLE_GREY, adaptation_s: DEFAULT_ADAPTATION_S }
    }
}

impl ExposureMode {
    pub fn validate(&self) -> Result<()> {
        match *self {
            ExposureMode::Auto { key, adaptation_s } => {
                if !(key.is_finite() && key > 0.0) {
                    bail!("auto-exposure key must be a positive number, got {key}");
                }
                if !(adaptation_s.is_finite() && adaptation_s >= 0.0) {
                    bail!("auto-exposure adaptation time must be >= 0 s, got {adaptation_s}");
                }
            }
            ExposureMode::Fixed(e) => {
                if !(e.is_finite() && e > 0.0) {
                    bail!("fixed exposure must be a positive number, got {e}");
                }
            }
        }
        Ok(())
    }
}

/// Exposure state across frames.
#[derive(Clone, Debug)]
pub struct AutoExposure {
    mode: ExposureMode,
    log2_exposure: Option<f32>,
}

impl AutoExposure {
    pub fn new(mode: ExposureMode) -> Result<AutoExposure> {
        mode.validate()?;
        Ok(AutoExposure { mode, log2_exposure: None })
    }

    pub fn mode(&self) -> ExposureMode {
        self.mode
    }

    /// Whether a frame needs metering (auto mode).
    pub fn is_auto(&self) -> bool {
        matches!(self.mode, ExposureMode::Auto { .. })
    }

    /// The exposure to use for a frame metered at log-average luminance `metered`, `dt`
    /// seconds after the previous one (ignored for the first frame; non-finite or negative
    /// counts as 0). In fixed mode `metered` is ignored.
    pub fn update(&mut self, metered: f32, dt: f64) -> f32 {
        let (key, tau) = match self.mode {
            ExposureMode::Fixed(e) => return e,
            ExposureMode::Auto { key, adaptation_s } => (key, adaptation_s),
        };
        let metered = if metered.is_finite() && metered > 0.0 { metered } else { LOG_DELTA };
        let target = (key / metered).log2().clamp(-LOG2_EXPOSURE_LIMIT, LOG2_EXPOSURE_LIMIT);
        let dt = if dt.is_finite() { dt.max(0.0) as f32 } else { 0.0 };
        let next = match self.log2_exposure {
            None => target,
            Some(_) if tau == 0.0 => target,
            Some(e) => e + (target - e) * (1.0 - (-dt / tau).exp()),
        };
        self.log2_exposure = Some(next);
        next.exp2()
    }

    /// The exposure of the last frame, if any.
    pub fn current(&self) -> Option<f32> {
        match self.mode {
            ExposureMode::Fixed(e) => Some(e),
            ExposureMode::Auto { .. } => self.log2_exposure.map(f32::exp2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aces_fit_values() {
        // By hand from the published formula: f(1) = 2.54 / 3.16, f(0.18) = 0.086724 / 0.324932.
        assert!((aces_filmic(1.0) - 2.54 / 3.16).abs() < 1e-6);
        assert!((aces_filmic(0.18) - 0.086_724 / 0.324_932).abs() < 1e-5);
        assert_eq!(aces_filmic(0.0), 0.0);
        assert_eq!(aces_filmic(100.0), 1.0);
        assert_eq!(aces_filmic(-1.0), 0.0);
        assert_eq!(aces_filmic(f32::NAN), 0.0);
        assert_eq!(aces_filmic(f32::INFINITY), 1.0);
        // Monotonic.
        let mut last = 0.0;
        for i in 0..2000 {
            let y = aces_filmic(i as f32 * 0.005);
            assert!(y >= last);
            last = y;
        }
    }

    #[test]
    fn the_inverse_tone_curve_undoes_the_curve() {
        // The white point: f(7.241657) = 1 (0.08x² − 0.56x − 0.14 = 0 at x = (0.56 + √0.3584)/0.16).
        assert!((aces_filmic(ACES_WHITE) - 1.0).abs() < 1e-6);
        assert!((ACES_WHITE - (0.56 + 0.3584f32.sqrt()) / 0.16).abs() < 1e-4);
        for i in 1..2000 {
            let x = i as f32 * 0.0035;
            let back = aces_filmic_inverse(aces_filmic(x));
            assert!((back - x).abs() <= 1e-4 * x.max(1.0), "x = {x}: {back}");
        }
        assert_eq!(aces_filmic_inverse(0.0), 0.0);
        assert_eq!(aces_filmic_inverse(f32::NAN), 0.0);
        assert_eq!(aces_filmic_inverse(1.5), ACES_WHITE);
        // Every code's light maps back to that code.
        for code in 1..255u8 {
            assert_eq!(tone_to_srgb8(srgb8_to_exposed(code)), code, "code {code}");
        }
        // Code 255 starts at the saturation point: just below it is 254.
        let s = saturation_exposed();
        assert_eq!(tone_to_srgb8(s * 1.001), 255);
        assert_eq!(tone_to_srgb8(s * 0.999), 254);
    }

    #[test]
    fn lut_matches_exact_curve_within_one_code() {
        let lut = ToneLut::new();
        for i in 0..200_000 {
            let x = (i as f32 / 200_000.0).powi(3) * 12.0;
            let (a, b) = (lut.map(x) as i32, tone_to_srgb8(x) as i32);
            assert!((a - b).abs() <= 1, "x = {x}: lut {a} exact {b}");
        }
        assert_eq!(lut.map(0.0), 0);
        assert_eq!(lut.map(f32::NAN), 0);
        assert_eq!(lut.map(-3.0), 0);
        assert_eq!(lut.map(1e9), 255);
        assert_eq!(lut.map(f32::INFINITY), 255);
    }

    #[test]
    fn log_average_is_geometric_mean() {
        // Two grey samples of luminance 0.01 and 1: geometric mean 0.1 (δ negligible).
        let l = log_average_luminance([[0.01; 3], [1.0; 3]].into_iter());
        assert!((l - 0.1).abs() < 1e-3, "{l}");
        assert_eq!(log_average_luminance(std::iter::empty()), LOG_DELTA);
        // All black: δ, finite.
        assert!((log_average_luminance([[0.0; 3]; 4].into_iter()) - LOG_DELTA).abs() < 1e-9);
    }

    #[test]
    fn auto_exposure_converges_exponentially() {
        let mut ae = AutoExposure::new(ExposureMode::Auto { key: 0.18, adaptation_s: 0.5 }).unwrap();
        // First frame converged: metered 0.72 -> exposure 0.25.
        assert!((ae.update(0.72, 0.0) - 0.25).abs() < 1e-6);
        // Scene 4x darker: target exposure 1.0 (log2: -2 -> 0). After one τ the log exposure
        // has covered 1 − 1/e of the way.
        let e = ae.update(0.18, 0.5);
        let expect = (-2.0 + 2.0 * (1.0 - (-1.0f32).exp())).exp2();
        assert!((e - expect).abs() < 1e-5, "{e} vs {expect}");
        // Time not moving: no change. Bad dt: no change.
        assert!((ae.update(0.18, 0.0) - e).abs() < 1e-7);
        assert!((ae.update(0.18, f64::NAN) - e).abs() < 1e-7);
        // Long after: converged.
        assert!((ae.update(0.18, 100.0) - 1.0).abs() < 1e-5);
        // Black scene: exposure stays finite and bounded.
        let mut ae = AutoExposure::new(ExposureMode::default()).unwrap();
        let e = ae.update(0.0, 0.0);
        assert!(e.is_finite() && e <= 2f32.powf(LOG2_EXPOSURE_LIMIT));
    }

    #[test]
    fn fixed_and_invalid_modes() {
        let mut ae = AutoExposure::new(ExposureMode::Fixed(2.0)).unwrap();
        assert_eq!(ae.update(123.0, 1.0), 2.0);
        assert!(AutoExposure::new(ExposureMode::Fixed(0.0)).is_err());
        assert!(AutoExposure::new(ExposureMode::Fixed(f32::NAN)).is_err());
        assert!(AutoExposure::new(ExposureMode::Auto { key: -1.0, adaptation_s: 0.1 }).is_err());
        assert!(AutoExposure::new(ExposureMode::Auto { key: 0.18, adaptation_s: f32::INFINITY }).is_err());
    }
}
