//! How steady and how quick the pose is, and where it fails (`previz pose-stability`).
//!
//! - Jitter: with the phone held still by hand (tremor and sway, `phone` noise), the sun's
//!   direction in camera space is computed from the estimated and from the true pose; the
//!   difference, minus its mean (a steady offset does not flicker), is the flicker a user sees
//!   on the model. Reported as RMS and peak in degrees.
//! - Lag: a 90° turn at 90°/s; the delay τ that best aligns estimated and true heading (with a
//!   free constant offset) over the turn and the holds around it.
//! - Failure cases with the default setting: headings across 0/360°, pitch to ±90°, a
//!   magnetic disturbance with and without the gyro-only fallback, and whole simulated captures
//!   (orientation error while the faces are held).
//!
//! Each setting sees exactly the same simulated readings (same seeds), so the comparison is
//! paired.

use super::fusion::{DisturbanceConfig, FusionConfig, OrientationFilter};
use super::hand_motion::{HandShake, UserPathParams, minimum_jerk};
use super::magnetic::MagneticReference;
use super::tilt_compass::CompassOnlyFilter;
use super::trace::{TruthSample, TruthTrace};
use super::{DisplayRotation, OrientationEstimator, Pose};
use crate::pose::frames::{angle_between, angle_difference, from_heading_pitch_roll, heading_pitch_roll};
use crate::sensors::sim::{Disturbance, NoiseLevel, SimConfig, SimSensors};
use crate::sensors::{Reading, SensorSource};
use anyhow::Result;
use glam::{DQuat, DVec3};

/// An estimator under test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimator {
    Fusion(FusionConfig),
    /// Seed 000's compass-only orientation, low-passed with this time constant (s).
    CompassOnly {
        tau_s: f64,
    },
}

/// A named estimator setting.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    pub name: String,
    pub estimator: Estimator,
}

impl Setting {
    pub fn build(&self, reference: MagneticReference) -> Box<dyn OrientationEstimator> {
        match self.estimator {
            Estimator::Fusion(cfg) => {
                let mut f = OrientationFilter::new(cfg);
                f.set_reference(reference);
                Box::new(f)
            }
            Estimator::CompassOnly { tau_s } => Box::new(CompassOnlyFilter::new(tau_s, reference.declination)),
        }
    }
}

/// The settings compared by default: a grid of fusion gains and output smoothing, and the
/// compass-only method at a few time constants. The first entry is [`FusionConfig::default`].
pub fn default_settings() -> Vec<Setting> {
    let mut v = vec![Setting { name: "default".into(), estimator: Estimator::Fusion(FusionConfig::default()) }];
    for k_acc in [0.1, 0.5, 2.0] {
        for k_mag in [0.05, 0.2, 1.0] {
            for (smooth, tau, adaptive) in [("raw", 0.0, false), ("adaptive0.2s", 0.2, true), ("lowpass0.2s", 0.2, false)] {
                let cfg = FusionConfig { k_acc, k_mag, smoothing_tau_s: tau, adaptive_smoothing: adaptive, ..FusionConfig::default() };
                if cfg == FusionConfig::default() {
                    continue;
                }
                v.push(Setting { name: format!("fusion kacc={k_acc} kmag={k_mag} {smooth}"), estimator: Estimator::Fusion(cfg) });
            }
        }
    }
    for tau_s in [0.0, 0.2, 0.5, 1.0] {
        v.push(Setting { name: format!("compass-only tau={tau_s}s"), estimator: Estimator::CompassOnly { tau_s } });
    }
    v
}

/// A fixed sun direction for the jitter measurement: azimuth 200°, elevation 35° (ENU).
pub fn default_sun() -> DVec3 {
    let (az, el) = (200f64.to_radians(), 35f64.to_radians());
    DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
}

/// Flicker and wander of a sequence of small direction errors (estimated − true unit vectors,
/// radians, small-angle) sampled at a fixed rate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JitterStats {
    /// RMS deviation of each error from the moving mean over `window` samples centred on it:
    /// the frame-to-frame flicker a user sees.
    pub flicker_rms: f64,
    pub flicker_peak: f64,
    /// RMS deviation of that moving mean from the overall mean: slow swimming of the model.
    pub wander_rms: f64,
    /// Length of the overall mean: a steady offset (a misplaced sun, no motion).
    pub offset: f64,
    pub samples: usize,
}

/// Split errors into flicker and wander (see [`JitterStats`]). The moving mean's window is
/// centred and shrinks symmetrically at the ends, so a linear drift is all wander.
pub fn jitter(errors: &[DVec3], window: usize) -> JitterStats {
    let n = errors.len();
    if n == 0 {
        return JitterStats::default();
    }
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(DVec3::ZERO);
    for e in errors {
        let last = prefix[prefix.len() - 1];
        prefix.push(last + *e);
    }
    let mean = prefix[n] / n as f64;
    let half = window / 2;
    let (mut f2, mut peak, mut w2) = (0.0, 0f64, 0.0);
    for (i, e) in errors.iter().enumerate() {
        let h = half.min(i).min(n - 1 - i);
        let local = (prefix[i + h + 1] - prefix[i - h]) / (2 * h + 1) as f64;
        let f = (*e - local).length();
        f2 += f * f;
        peak = peak.max(f);
        w2 += (local - mean).length_squared();
    }
    JitterStats {
        flicker_rms: (f2 / n as f64).sqrt(),
        flicker_peak: peak,
        wander_rms: (w2 / n as f64).sqrt(),
        offset: mean.length(),
        samples: n,
    }
}

/// Pool per-run statistics (RMS values weighted by sample counts, peaks maximal).
pub fn pool(stats: &[JitterStats]) -> JitterStats {
    let n: usize = stats.iter().map(|s| s.samples).sum();
    if n == 0 {
        return JitterStats::default();
    }
    let w = |f: fn(&JitterStats) -> f64| (stats.iter().map(|s| f(s).powi(2) * s.samples as f64).sum::<f64>() / n as f64).sqrt();
    JitterStats {
        flicker_rms: w(|s| s.flicker_rms),
        flicker_peak: stats.iter().map(|s| s.flicker_peak).fold(0.0, f64::max),
        wander_rms: w(|s| s.wander_rms),
        offset: w(|s| s.offset),
        samples: n,
    }
}

/// The moving-mean window for flicker: 1 s at 100 Hz.
pub const FLICKER_WINDOW: usize = 101;

/// The delay τ (s, searched from −0.2 to 0.8 s in 1 ms steps) that best explains `estimated`
/// headings (time, radians) as `true_heading(t − τ)` plus a constant offset. Needs motion that
/// is not at constant rate everywhere (a turn with holds around it), or offset and delay mix.
pub fn estimate_lag(estimated: &[(f64, f64)], true_heading: impl Fn(f64) -> f64) -> f64 {
    let mut best = (f64::INFINITY, 0.0);
    for i in -200..=800 {
        let tau = f64::from(i) * 1e-3;
        let r: Vec<f64> = estimated.iter().map(|&(t, h)| angle_difference(h, true_heading(t - tau))).collect();
        let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
        let var = r.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>();
        if var < best.0 {
            best = (var, tau);
        }
    }
    best.1
}

/// Scripted truth paths (100 Hz) with a hand's tremor and sway.
fn scripted(seed: u64, secs: f64, base: impl Fn(f64) -> DQuat) -> Result<TruthTrace> {
    let hand = HandShake::seeded(seed, &UserPathParams::default());
    let n = (secs * 100.0).round() as usize;
    TruthTrace::new((0..=n).map(|i| i as f64 * 0.01).map(|t| TruthSample { t, q: hand.apply(base(t), t), tap: false }).collect())
}

/// Angle (radians) covered by time `t` of a turn of `total` radians at `rate` rad/s, starting
/// at `t0`, with linear ramps of the rate over `ramp` seconds.
fn trapezoid_turn(t: f64, t0: f64, total: f64, rate: f64, ramp: f64) -> f64 {
    let cruise = total / rate - ramp;
    let u = t - t0;
    let acc = rate / ramp;
    if u <= 0.0 {
        0.0
    } else if u < ramp {
        0.5 * acc * u * u
    } else if u < ramp + cruise {
        0.5 * rate * ramp + rate * (u - ramp)
    } else if u < 2.0 * ramp + cruise {
        let d = 2.0 * ramp + cruise - u;
        total - 0.5 * acc * d * d
    } else {
        total
    }
}

const HOLD_HEADING: f64 = 135.0;
const HOLD_PITCH: f64 = 10.0;
/// Turn scenario: starts at 5 s, 90° at 90°/s with 0.1 s ramps, ends at 6.1 s.
const TURN_START: f64 = 5.0;

fn hold_base(_t: f64) -> DQuat {
    from_heading_pitch_roll(HOLD_HEADING.to_radians(), HOLD_PITCH.to_radians(), 0.0)
}

fn turn_heading(t: f64) -> f64 {
    HOLD_HEADING.to_radians() + trapezoid_turn(t, TURN_START, 90f64.to_radians(), 90f64.to_radians(), 0.1)
}

fn turn_base(t: f64) -> DQuat {
    from_heading_pitch_roll(turn_heading(t), HOLD_PITCH.to_radians(), 0.0)
}

/// One simulated run: readings, truth and the magnetic reference the app would use.
struct Run {
    readings: Vec<Reading>,
    truth: TruthTrace,
    reference: MagneticReference,
    rotation: DisplayRotation,
}

fn simulate(truth: TruthTrace, noise: NoiseLevel, seed: u64, disturbances: Vec<Disturbance>) -> Result<Run> {
    let mut cfg = SimConfig::new(noise, seed);
    cfg.disturbances = disturbances;
    let rotation = cfg.rotation;
    let mut sim = SimSensors::with_config(truth.clone(), cfg)?;
    let mut readings = Vec::new();
    sim.poll(f64::INFINITY, &mut readings)?;
    Ok(Run { readings, truth, reference: sim.magnetic_reference(), rotation })
}

/// Feed a run to an estimator; call `visit(t, true pose, estimated pose)` after each gyroscope
/// reading (100 Hz).
fn evaluate(run: &Run, setting: &Setting, mut visit: impl FnMut(f64, DQuat, &Pose)) -> Result<()> {
    let mut est = setting.build(run.reference);
    for r in &run.readings {
        est.update(r)?;
        if let Reading::Gyro { t, .. } = *r
            && let Some(p) = est.pose(run.rotation)
        {
            visit(t, run.truth.orientation_at(t), &p);
        }
    }
    Ok(())
}

/// Jitter / lag trade-off of one setting at one noise level, pooled over seeds.
#[derive(Clone, Debug, PartialEq)]
pub struct TradeoffRow {
    pub noise: NoiseLevel,
    pub setting: String,
    pub seeds: u64,
    /// Sun-direction flicker (degrees): RMS and peak deviation from the 1 s moving mean.
    pub jitter_rms_deg: f64,
    pub jitter_peak_deg: f64,
    /// Slow swimming of the sun direction (degrees RMS of the 1 s moving mean about its mean).
    pub wander_rms_deg: f64,
    /// Mean sun-direction offset (degrees RMS over seeds): steady, so no flicker, but a
    /// misplaced shadow.
    pub sun_offset_deg: f64,
    /// RMS orientation error while held still (degrees).
    pub error_rms_deg: f64,
    /// Median over seeds of the lag in the 90°/s turn (ms).
    pub lag_ms: f64,
    /// Largest orientation error during the turn (degrees, max over seeds).
    pub turn_peak_error_deg: f64,
    /// Fraction of held-still samples whose true error is within the reported accuracy
    /// (NaN for estimators that do not report one).
    pub accuracy_coverage: f64,
}

/// One failure case with one setting.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseRow {
    pub noise: NoiseLevel,
    pub case: String,
    pub setting: String,
    pub max_error_deg: f64,
    pub rms_error_deg: f64,
    /// Fraction of the disturbance during which the filter flagged it (disturbance case), or
    /// of the held faces during which it was flagged (capture path).
    pub flagged_fraction: Option<f64>,
    /// Whether every pose and its heading/pitch/roll were finite.
    pub finite: bool,
}

/// Time per reading of each estimator on the same readings.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingRow {
    pub setting: String,
    pub ns_per_reading: f64,
}

/// Heading error over time in the disturbance case (first seed), for the chart.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisturbanceSeries {
    pub t: Vec<f64>,
    pub error_with_fallback_deg: Vec<f64>,
    pub error_without_fallback_deg: Vec<f64>,
    pub flagged: Vec<bool>,
    pub window: (f64, f64),
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct StabilityReport {
    pub tradeoff: Vec<TradeoffRow>,
    pub cases: Vec<CaseRow>,
    pub timing: Vec<TimingRow>,
    pub disturbance: DisturbanceSeries,
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct StabilityConfig {
    pub seeds: u64,
    pub noise_levels: Vec<NoiseLevel>,
    pub sun_enu: DVec3,
    pub settings: Vec<Setting>,
    /// Length of the held-still recording (s); the first 5 s are not scored.
    pub hold_s: f64,
}

impl Default for StabilityConfig {
    fn default() -> Self {
        StabilityConfig {
            seeds: 20,
            noise_levels: vec![NoiseLevel::Phone, NoiseLevel::Bad],
            sun_enu: default_sun(),
            settings: default_settings(),
            hold_s: 30.0,
        }
    }
}

/// Not scored: the filter's start-up.
const WARM_UP_S: f64 = 5.0;

fn sun_error(sun: DVec3, truth: DQuat, est: &Pose) -> DVec3 {
    est.q.as_dquat().inverse() * sun - truth.inverse() * sun
}

/// Measure the trade-off for every setting and noise level. `progress` is called once per
/// (noise, seed).
pub fn measure_tradeoff(cfg: &StabilityConfig, mut progress: impl FnMut()) -> Result<Vec<TradeoffRow>> {
    let mut rows = Vec::new();
    for &noise in &cfg.noise_levels {
        let n = cfg.settings.len();
        let mut stats: Vec<Vec<JitterStats>> = vec![Vec::new(); n];
        let mut orient_sq = vec![(0.0, 0usize); n];
        let mut covered = vec![(0usize, 0usize); n];
        let mut lags: Vec<Vec<f64>> = vec![Vec::new(); n];
        let mut turn_peak = vec![0f64; n];
        for seed in 0..cfg.seeds {
            let hold = simulate(scripted(seed, cfg.hold_s, hold_base)?, noise, seed, Vec::new())?;
            let turn = simulate(scripted(seed, 9.0, turn_base)?, noise, seed, Vec::new())?;
            for (i, s) in cfg.settings.iter().enumerate() {
                let mut errors = Vec::new();
                evaluate(&hold, s, |t, truth, p| {
                    if t < WARM_UP_S {
                        return;
                    }
                    errors.push(sun_error(cfg.sun_enu, truth, p));
                    let e = angle_between(truth, p.q.as_dquat());
                    orient_sq[i].0 += e * e;
                    orient_sq[i].1 += 1;
                    if p.accuracy_deg.is_finite() {
                        covered[i].1 += 1;
                        if e.to_degrees() <= f64::from(p.accuracy_deg) {
                            covered[i].0 += 1;
                        }
                    }
                })?;
                stats[i].push(jitter(&errors, FLICKER_WINDOW));
                let mut est_heading = Vec::new();
                evaluate(&turn, s, |t, truth, p| {
                    if (TURN_START - 1.0..TURN_START + 3.0).contains(&t) {
                        est_heading.push((t, heading_pitch_roll(p.q.as_dquat()).heading));
                        turn_peak[i] = turn_peak[i].max(angle_between(truth, p.q.as_dquat()).to_degrees());
                    }
                })?;
                lags[i].push(estimate_lag(&est_heading, turn_heading));
            }
            progress();
        }
        for (i, s) in cfg.settings.iter().enumerate() {
            let j = pool(&stats[i]);
            lags[i].sort_by(f64::total_cmp);
            rows.push(TradeoffRow {
                noise,
                setting: s.name.clone(),
                seeds: cfg.seeds,
                jitter_rms_deg: j.flicker_rms.to_degrees(),
                jitter_peak_deg: j.flicker_peak.to_degrees(),
                wander_rms_deg: j.wander_rms.to_degrees(),
                sun_offset_deg: j.offset.to_degrees(),
                error_rms_deg: (orient_sq[i].0 / orient_sq[i].1.max(1) as f64).sqrt().to_degrees(),
                lag_ms: lags[i].get(lags[i].len() / 2).copied().unwrap_or(f64::NAN) * 1000.0,
                turn_peak_error_deg: turn_peak[i],
                accuracy_coverage: if covered[i].1 > 0 { covered[i].0 as f64 / covered[i].1 as f64 } else { f64::NAN },
            });
        }
    }
    Ok(rows)
}

/// The failure cases, each with `setting` (and the disturbance case also without the
/// fallback). Returns the rows and the disturbance series of the first seed at the first
/// noise level.
pub fn measure_cases(cfg: &StabilityConfig, setting: &Setting, mut progress: impl FnMut()) -> Result<(Vec<CaseRow>, DisturbanceSeries)> {
    let mut rows = Vec::new();
    let mut series = DisturbanceSeries::default();
    let no_fallback = match setting.estimator {
        Estimator::Fusion(f) => Some(Setting {
            name: format!("{} without fallback", setting.name),
            estimator: Estimator::Fusion(FusionConfig { disturbance: DisturbanceConfig { enabled: false, ..f.disturbance }, ..f }),
        }),
        Estimator::CompassOnly { .. } => None,
    };
    // A steel object passes: 25 µT for 6 s, from 8 s.
    let window = (8.0, 14.0);
    let disturbance =
        Disturbance { start: window.0, duration: window.1 - window.0, field_enu_ut: DVec3::new(0.8, -0.4, 0.45).normalize() * 25.0 };
    type Base = fn(f64) -> DQuat;
    let wrap_base: Base =
        |t| from_heading_pitch_roll(355f64.to_radians() + trapezoid_turn(t, 6.0, 20f64.to_radians(), 10f64.to_radians(), 0.3), 0.0, 0.0);
    let up_base: Base = |t| from_heading_pitch_roll(0.5, minimum_jerk((t - 6.0) / 1.5) * std::f64::consts::FRAC_PI_2, 0.0);
    let down_base: Base = |t| from_heading_pitch_roll(0.5, -minimum_jerk((t - 6.0) / 1.5) * std::f64::consts::FRAC_PI_2, 0.0);
    let cases: [(&str, f64, Base, bool); 4] = [
        ("heading across 0/360", 14.0, wrap_base, false),
        ("pitch to +90", 14.0, up_base, false),
        ("pitch to -90", 14.0, down_base, false),
        ("magnetic disturbance", 24.0, hold_base, true),
    ];
    for &noise in &cfg.noise_levels {
        for (name, secs, base, disturbed) in cases {
            let mut runs: Vec<(&Setting, f64, f64, usize, usize, usize, bool)> = Vec::new();
            let mut settings = vec![setting];
            if disturbed && let Some(nf) = &no_fallback {
                settings.push(nf);
            }
            for s in &settings {
                let (mut max_e, mut sum_sq, mut count, mut flagged, mut in_window, mut finite) = (0f64, 0.0, 0usize, 0usize, 0usize, true);
                for seed in 0..cfg.seeds {
                    let d = if disturbed { vec![disturbance] } else { Vec::new() };
                    let run = simulate(scripted(seed, secs, base)?, noise, seed, d)?;
                    let record = seed == 0 && noise == cfg.noise_levels[0] && disturbed;
                    let with_fallback = std::ptr::eq(*s, setting);
                    evaluate(&run, s, |t, truth, p| {
                        let hpr = heading_pitch_roll(p.q.as_dquat());
                        finite &= p.q.is_finite() && hpr.heading.is_finite() && hpr.pitch.is_finite() && hpr.roll.is_finite();
                        if t < WARM_UP_S {
                            return;
                        }
                        // Heading error for the wrap and disturbance cases, full orientation
                        // error at the poles (where heading is not defined).
                        let e = if name.starts_with("pitch") {
                            angle_between(truth, p.q.as_dquat())
                        } else {
                            angle_difference(hpr.heading, heading_pitch_roll(truth).heading).abs()
                        };
                        max_e = max_e.max(e);
                        sum_sq += e * e;
                        count += 1;
                        if disturbed && (window.0..window.1).contains(&t) {
                            in_window += 1;
                            flagged += usize::from(p.magnetic_disturbance);
                        }
                        if record {
                            if with_fallback {
                                series.t.push(t);
                                series.error_with_fallback_deg.push(e.to_degrees());
                                series.flagged.push(p.magnetic_disturbance);
                            } else {
                                series.error_without_fallback_deg.push(e.to_degrees());
                            }
                        }
                    })?;
                    progress();
                }
                runs.push((s, max_e, sum_sq, count, flagged, in_window, finite));
            }
            for (s, max_e, sum_sq, count, flagged, in_window, finite) in runs {
                rows.push(CaseRow {
                    noise,
                    case: name.to_string(),
                    setting: s.name.clone(),
                    max_error_deg: max_e.to_degrees(),
                    rms_error_deg: (sum_sq / count.max(1) as f64).sqrt().to_degrees(),
                    flagged_fraction: disturbed.then(|| flagged as f64 / in_window.max(1) as f64),
                    finite,
                });
            }
        }
    }
    // A whole simulated capture (hand_motion): orientation error while the faces are held.
    for &noise in &cfg.noise_levels {
        let (mut max_e, mut sum_sq, mut count, mut flagged, mut finite) = (0f64, 0.0, 0usize, 0usize, true);
        for seed in 0..cfg.seeds {
            let path = super::hand_motion::simulate_user_path(seed, &UserPathParams::default())?;
            let holds = path.holds.clone();
            let run = simulate(TruthTrace::new(path.samples)?, noise, seed, Vec::new())?;
            evaluate(&run, setting, |t, truth, p| {
                finite &= p.q.is_finite();
                if holds.iter().any(|h| (h.start..h.end).contains(&t)) {
                    let e = angle_between(truth, p.q.as_dquat());
                    max_e = max_e.max(e);
                    sum_sq += e * e;
                    count += 1;
                    flagged += usize::from(p.magnetic_disturbance);
                }
            })?;
            progress();
        }
        rows.push(CaseRow {
            noise,
            case: "capture path (holds)".into(),
            setting: setting.name.clone(),
            max_error_deg: max_e.to_degrees(),
            rms_error_deg: (sum_sq / count.max(1) as f64).sqrt().to_degrees(),
            flagged_fraction: Some(flagged as f64 / count.max(1) as f64),
            finite,
        });
    }
    series.window = window;
    Ok((rows, series))
}

/// Time each setting on the same readings (one held-still run at the first noise level).
pub fn measure_timing(cfg: &StabilityConfig, settings: &[Setting]) -> Result<Vec<TimingRow>> {
    let noise = cfg.noise_levels.first().copied().unwrap_or(NoiseLevel::Phone);
    let run = simulate(scripted(0, cfg.hold_s, hold_base)?, noise, 0, Vec::new())?;
    let mut rows = Vec::new();
    for s in settings {
        let mut best = f64::INFINITY;
        // Best of three: the least disturbed by the rest of the machine.
        for _ in 0..3 {
            let mut est = s.build(run.reference);
            let start = std::time::Instant::now();
            for r in &run.readings {
                est.update(r)?;
            }
            let pose = est.pose(run.rotation);
            let ns = start.elapsed().as_secs_f64() * 1e9 / run.readings.len() as f64;
            std::hint::black_box(pose);
            best = best.min(ns);
        }
        rows.push(TimingRow { setting: s.name.clone(), ns_per_reading: best });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_of_known_sequences() {
        // A constant offset neither flickers nor wanders.
        let c = vec![DVec3::new(0.01, 0.0, 0.0); 300];
        let j = jitter(&c, FLICKER_WINDOW);
        assert!(j.flicker_rms < 1e-15 && j.flicker_peak < 1e-15 && j.wander_rms < 1e-15);
        assert!((j.offset - 0.01).abs() < 1e-15);
        // ±δ alternating about an offset: flicker δ (the 101-sample mean is within δ/101 of
        // the offset; near the ends, where the window shrinks to 3 samples, up to 4δ/3), and
        // hardly any wander.
        let d = 0.002;
        let alt: Vec<DVec3> = (0..300).map(|i| DVec3::new(0.01 + if i % 2 == 0 { d } else { -d }, 0.0, 0.0)).collect();
        let j = jitter(&alt, FLICKER_WINDOW);
        assert!((j.flicker_rms - d).abs() < 0.02 * d, "{j:?}");
        assert!(j.flicker_peak >= d && j.flicker_peak <= 4.0 * d / 3.0 + 1e-12, "{j:?}");
        assert!(j.wander_rms < 0.1 * d, "{j:?}");
        // A linear drift from −a to +a is all wander: RMS a/√3 (uniform distribution).
        let a = 0.01;
        let ramp: Vec<DVec3> = (0..1001).map(|i| DVec3::new(-a + 2.0 * a * i as f64 / 1000.0, 0.0, 0.0)).collect();
        let j = jitter(&ramp, FLICKER_WINDOW);
        assert!(j.flicker_peak < 1e-12, "{j:?}");
        assert!((j.wander_rms - a / 3f64.sqrt()).abs() < 1e-3 * a, "{j:?}");
        assert_eq!(jitter(&[], FLICKER_WINDOW), JitterStats::default());
        // Pooling weights by samples.
        let p = pool(&[
            JitterStats { flicker_rms: 1.0, flicker_peak: 2.0, wander_rms: 0.0, offset: 0.0, samples: 3 },
            JitterStats { flicker_rms: 0.0, flicker_peak: 5.0, wander_rms: 0.0, offset: 0.0, samples: 1 },
        ]);
        assert!((p.flicker_rms - 0.75f64.sqrt()).abs() < 1e-15 && p.flicker_peak == 5.0 && p.samples == 4);
    }

    #[test]
    fn lag_estimate_recovers_a_known_delay_despite_an_offset() {
        let h = turn_heading;
        let est: Vec<(f64, f64)> = (400..800).map(|i| i as f64 * 0.01).map(|t| (t, h(t - 0.037) + 0.02)).collect();
        assert!((estimate_lag(&est, h) - 0.037).abs() < 1.5e-3);
    }

    #[test]
    fn trapezoid_turn_profile() {
        let (total, rate, ramp) = (90f64.to_radians(), 90f64.to_radians(), 0.1);
        assert_eq!(trapezoid_turn(0.0, 1.0, total, rate, ramp), 0.0);
        assert!((trapezoid_turn(10.0, 1.0, total, rate, ramp) - total).abs() < 1e-12);
        // Total time = total/rate + ramp = 1.1 s; symmetric, so half the angle at the middle.
        assert!((trapezoid_turn(1.55, 1.0, total, rate, ramp) - total / 2.0).abs() < 1e-12);
        // Cruise rate.
        let r = (trapezoid_turn(1.5, 1.0, total, rate, ramp) - trapezoid_turn(1.4, 1.0, total, rate, ramp)) / 0.1;
        assert!((r - rate).abs() < 1e-9);
    }

    /// A small end-to-end run: with phone noise the fusion filter's jitter is far below the
    /// compass-only method's, and the failure cases stay finite with the fallback flagging
    /// the disturbance.
    #[test]
    fn small_measurement_orders_methods_and_flags_disturbance() {
        let settings = vec![
            Setting { name: "default".into(), estimator: Estimator::Fusion(FusionConfig::default()) },
            Setting { name: "compass".into(), estimator: Estimator::CompassOnly { tau_s: 0.0 } },
        ];
        let cfg = StabilityConfig {
            seeds: 1,
            noise_levels: vec![NoiseLevel::Phone],
            sun_enu: default_sun(),
            settings: settings.clone(),
            hold_s: 10.0,
        };
        let rows = measure_tradeoff(&cfg, || {}).unwrap();
        assert_eq!(rows.len(), 2);
        assert!(rows[0].jitter_rms_deg * 5.0 < rows[1].jitter_rms_deg, "{rows:?}");
        assert!(rows[0].jitter_rms_deg > 0.0 && rows[0].lag_ms.abs() < 100.0, "{rows:?}");
        let (cases, series) = measure_cases(&cfg, &settings[0], || {}).unwrap();
        assert!(cases.iter().all(|c| c.finite), "{cases:?}");
        let with = cases.iter().find(|c| c.case == "magnetic disturbance" && c.setting == "default").unwrap();
        let without = cases.iter().find(|c| c.case == "magnetic disturbance" && c.setting != "default").unwrap();
        assert!(with.flagged_fraction.unwrap() > 0.8, "{with:?}");
        assert!(with.max_error_deg < without.max_error_deg, "{with:?} {without:?}");
        assert_eq!(series.t.len(), series.error_without_fallback_deg.len());
        for c in cases.iter().filter(|c| c.case.starts_with("pitch") || c.case.starts_with("heading")) {
            assert!(c.max_error_deg < 5.0, "{c:?}");
        }
    }
}
