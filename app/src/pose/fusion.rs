//! Sensor fusion: a Mahony-style complementary filter on the rotation group.
//!
//! The state is a unit quaternion (device → ENU, true north once the location is known) and a
//! gyroscope bias; no Euler angles, so any attitude, pitch ±90° included, is handled alike.
//! Each gyroscope sample propagates the quaternion by the bias-corrected rate plus two
//! corrections (Mahony, Hamel & Pflimlin 2008, "Nonlinear complementary filters on the special
//! orthogonal group", IEEE TAC 53(5), eq. 32 "explicit complementary filter"):
//!
//! - tilt: `k_acc · (â × v̂)`, where â is the measured and v̂ the estimated up direction in the
//!   device frame; readings whose magnitude is far from g (the phone accelerating) count less;
//! - heading: `k_mag · δ · (q⁻¹ ẑ)`, where δ is the angle between the measured field's
//!   horizontal direction and magnetic north as the model expects it (the declination).
//!   Acting only about the world vertical, it never disturbs the tilt (the "decoupled"
//!   magnetometer correction used by e.g. Madgwick's later AHRS work).
//!
//! The bias is the integral term, `k_bias`. A magnetometer reading whose magnitude or dip
//! differs from the World Magnetic Model's (by more than the configured tolerances) marks a
//! magnetic disturbance: heading then comes from the gyroscope alone until readings have agreed
//! with the model again for `recover_after_s`. The magnetometer's hard-iron offset is learnt
//! online ([`super::hard_iron`]) from readings taken as the phone turns.
//!
//! A capture (a few seconds of turning to known directions) needs the heading of each shot
//! *relative to the first* more than the absolute one:
//! - **Heading hold** ([`OrientationFilter::hold_heading`]): the magnetometer's heading
//!   correction is suspended and the heading propagates on the gyroscope alone, as Android's
//!   game rotation vector does for panoramas. The compass's error changes with heading (residual
//!   hard iron) and with small undetected disturbances — at `phone` noise by up to 10° within
//!   one capture — while a gyroscope with a learnt bias drifts a fraction of a degree in it.
//!
//! **True north from the sun** ([`OrientationFilter::sun_heading`], measured by
//! [`super::sun_heading`]): the sun seen in a frame gives the heading error of the estimate to
//! a fraction of a degree. It is fused as a measurement of the heading (a Kalman update on yaw
//! with the filter's heading 1σ as the prior and the measurement's own 1σ): the correction is
//! blended into the output over [`SUN_BLEND_S`] (no visible snap). The compass's own error
//! (its low-passed disagreement with the estimate less the measured error) is learnt as an
//! offset, so the magnetometer then corrects towards the sun-calibrated heading instead of
//! pulling it back to its steady error; and while the calibration is fresh the compass counts
//! only by its share of the two variances (an undetected disturbance cannot drag the heading).
//! The calibration's 1σ grows with time (k_mag × the compass floor per second: as fast as the
//! compass can move the heading) and with turning (a residual hard-iron error changes with
//! orientation), so the compass takes over again when the sun is no longer seen.

use super::frames::{DisplayRotation, angle_difference, camera_pose_from_device};
use super::hard_iron::HardIronCalibrator;
use super::magnetic::{MagneticReference, magnetic_to_true};
use super::tilt_compass::tilt_compass;
use super::{HeadingSource, OrientationEstimator, Pose};
use crate::sensors::{North, Reading};
use anyhow::Result;
use glam::{DMat3, DQuat, DVec3};

/// Standard gravity (m/s²).
const G: f64 = crate::sensors::STANDARD_GRAVITY;

/// When the magnetometer's reading is trusted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisturbanceConfig {
    /// Off: every magnetometer reading is used (for comparisons).
    pub enabled: bool,
    /// Largest accepted |‖m‖ − F| / F against the model's total intensity.
    pub magnitude_tolerance: f64,
    /// Largest accepted difference between measured and modelled dip (radians).
    pub dip_tolerance: f64,
    /// Seconds of agreeing readings before the magnetometer is trusted again.
    pub recover_after_s: f64,
}

impl Default for DisturbanceConfig {
    fn default() -> Self {
        DisturbanceConfig { enabled: true, magnitude_tolerance: 0.10, dip_tolerance: 5f64.to_radians(), recover_after_s: 1.0 }
    }
}

/// Filter gains and settings. Gains are in 1/s: a correction removes an error with time
/// constant 1/k.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusionConfig {
    pub k_acc: f64,
    pub k_mag: f64,
    /// Integral gain (1/s²) estimating the gyroscope bias; 0 disables bias estimation.
    pub k_bias: f64,
    /// Integral gain (1/s²) of the accelerometer's share of the bias estimate while the phone
    /// turns slower than `still_rate` (its readings are then gravity alone, without the
    /// lever-arm acceleration of a turn); at least `k_bias`.
    pub k_bias_still: f64,
    /// Accelerometer readings with |‖a‖ − g| above this fraction of g are ignored; below it
    /// their weight falls linearly from 1 (at ‖a‖ = g) to 0.
    pub accel_tolerance: f64,
    /// At start the gains are multiplied by `startup_gain`, ramping down to 1 over
    /// `startup_s` seconds, so the initial estimate (one noisy reading) settles quickly; the
    /// bias is not learnt during that time.
    pub startup_s: f64,
    pub startup_gain: f64,
    /// Output smoothing time constant (s); 0 = off. Applied to the pose, not the state.
    pub smoothing_tau_s: f64,
    /// Adaptive smoothing: full `smoothing_tau_s` while the phone turns slower than
    /// `still_rate` (rad/s), none above twice that rate, linear in between.
    pub adaptive_smoothing: bool,
    pub still_rate: f64,
    pub disturbance: DisturbanceConfig,
    /// Accuracy model: tilt error floor (accelerometer bias, radians).
    pub tilt_floor: f64,
    /// Accuracy model: heading error floor with a good magnetometer (residual calibration).
    pub heading_floor: f64,
    /// Accuracy model: how fast heading error grows in gyro-only mode once the gyroscope bias
    /// has been learnt (rad/s).
    pub gyro_drift: f64,
    /// Accuracy model: the gyroscope bias assumed before it is learnt (rad/s); its share of
    /// the gyro-only drift decays with a 60 s time constant of magnetometer-corrected running.
    pub initial_gyro_bias: f64,
    /// Accuracy model: heading error of a first heading taken from a field that does not match
    /// the model (radians).
    pub coarse_heading_sigma: f64,
    /// Estimate the magnetometer's hard-iron offset online from readings at many orientations
    /// ([`super::hard_iron`]) and remove it.
    pub hard_iron_calibration: bool,
    /// Use the platform's fused attitude readings (Android rotation vector, iOS CoreMotion)
    /// instead of fusing the raw sensors.
    pub use_platform_attitude: bool,
}

impl Default for FusionConfig {
    /// The setting chosen with `previz pose-stability` (docs/PERFORMANCE.md, pose section).
    fn default() -> Self {
        FusionConfig {
            k_acc: 0.5,
            k_mag: 0.2,
            k_bias: 0.01,
            k_bias_still: 0.1,
            accel_tolerance: 0.15,
            startup_s: 3.0,
            startup_gain: 10.0,
            smoothing_tau_s: 0.0,
            adaptive_smoothing: true,
            still_rate: 8f64.to_radians(),
            disturbance: DisturbanceConfig::default(),
            tilt_floor: 0.5f64.to_radians(),
            heading_floor: 2f64.to_radians(),
            gyro_drift: 0.05f64.to_radians(),
            initial_gyro_bias: 0.5f64.to_radians(),
            coarse_heading_sigma: 30f64.to_radians(),
            hard_iron_calibration: true,
            use_platform_attitude: false,
        }
    }
}

/// Time constant (s) over which a sun heading correction is blended into the estimate.
pub const SUN_BLEND_S: f64 = 0.25;
/// Time constant (s) of the compass disagreement the sun calibration learns the offset from.
const COMPASS_LP_S: f64 = 0.5;
/// Turning (radians, any axis) after which a sun calibration is worth no more than the compass.
const SUN_VALID_TURN: f64 = std::f64::consts::FRAC_PI_2;

/// A sun heading measurement taken into the filter.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SunFix {
    /// Time of the update (s).
    t: f64,
    /// Heading 1σ right after the update (radians).
    sigma: f64,
    /// Rotation (radians) since the update.
    turned: f64,
}

/// What the heading estimate went through since the filter started, for measurements of how it
/// turned relative to the truth between two instants ([`OrientationFilter::relative_heading`]).
/// The estimate's yaw error ψ (anticlockwise about the world vertical, estimate against truth)
/// grows at `u · (b − b̂)` — `u` the world vertical in the device frame, `b` the gyroscope's
/// true bias and `b̂` the filter's estimate — plus the corrections turned in about the vertical.
/// So between two instants ψ₁ − ψ₀ = b · Δ`up_integral` − Δ`bias_integral` + Δ`turns`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct YawTrack {
    /// ∫ u dt (s): the lever of each component of the gyroscope's bias on the heading.
    pub up_integral: DVec3,
    /// ∫ u · b̂ dt (radians): what the bias estimate took off the heading.
    pub bias_integral: f64,
    /// Corrections turned in about the world vertical (radians, anticlockwise): the compass's,
    /// the sun's and image fixes ([`OrientationFilter::heading_fix`]). A caller that turns a
    /// pose taken at this instant adds that turn here.
    pub turns: f64,
}

/// 1σ per axis (rad/s) of the gyroscope bias left when image measurements of the heading's
/// drift start to learn it ([`OrientationFilter::relative_heading`]): a phone gyroscope's zero
/// rate offset after the OS's calibration is up to about 1°/s (the simulator's `bad` preset;
/// `phone`: 0.1°/s).
const RELATIVE_BIAS_SIGMA: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// Random walk (rad/s per √s) of that bias (the simulator's `bad` preset, 0.02°/s per √s).
const RELATIVE_BIAS_WALK: f64 = 0.02 * std::f64::consts::PI / 180.0;
/// Relative heading measurements whose innovation exceeds this many σ are rejected (a wrong
/// image match).
const RELATIVE_GATE_SIGMAS: f64 = 3.0;

/// Readings older than this (s) are not used for corrections.
const FRESH_S: f64 = 0.25;
/// A gap in gyroscope readings longer than this (s) restarts the integration.
const MAX_GYRO_GAP_S: f64 = 0.5;
/// Largest gyroscope bias the filter will believe (rad/s, about 6°/s).
const MAX_BIAS: f64 = 0.1;
/// Time constant (s) of the running innovation statistics behind the accuracy estimate.
const INNOVATION_TAU_S: f64 = 2.0;
/// Tilt error assumed for an orientation started from one accelerometer reading (radians).
const INITIAL_TILT_SIGMA: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Earth's field is 22–67 µT everywhere (WMM); without a model, readings outside a slightly
/// wider band are disturbed.
const EARTH_FIELD_RANGE_UT: (f64, f64) = (20.0, 70.0);

/// The fusion filter. Feed readings in time order with [`OrientationEstimator::update`].
#[derive(Clone, Debug)]
pub struct OrientationFilter {
    cfg: FusionConfig,
    reference: Option<MagneticReference>,
    /// The date used to evaluate the World Magnetic Model when a GPS fix arrives.
    date: Option<chrono::NaiveDate>,
    /// Device → ENU.
    q: DQuat,
    smoothed: DQuat,
    initialised: bool,
    init_t: f64,
    heading_known: bool,
    /// Declination already applied to `q`.
    applied_declination: f64,
    bias: DVec3,
    t: f64,
    gyro_t: Option<f64>,
    gyro_seen: bool,
    accel_step_t: Option<f64>,
    accel: Option<(f64, DVec3)>,
    mag: Option<(f64, DVec3)>,
    disturbed: bool,
    good_since: Option<f64>,
    gyro_only_since: Option<f64>,
    heading_sigma_at_loss: f64,
    tilt_innov_var: f64,
    heading_innov_var: f64,
    rate: f64,
    platform_accuracy: Option<f64>,
    gps_position: Option<(f64, f64)>,
    calibrator: HardIronCalibrator,
    /// When the magnetometer was last trusted again after a disturbance.
    boost_t: Option<f64>,
    /// Error carried over from a coarse start or a gyro-only stretch, decaying as the
    /// corrections remove it (radians).
    carried_heading_sigma: f64,
    carried_tilt_sigma: f64,
    /// Seconds of magnetometer-corrected running after start-up (bias learning time).
    mag_time: f64,
    /// Heading hold: since when, and the heading 1σ then (radians).
    hold: Option<(f64, f64)>,
    /// Learnt from the sun: how far clockwise of the model's magnetic north the (calibrated)
    /// magnetometer sees the field (radians); the magnetometer correction aims at
    /// declination + this. A compass-only heading is this much too far anticlockwise.
    compass_offset: f64,
    /// Heading correction from the sun not yet blended in (radians, to subtract).
    pending_turn: f64,
    sun: Option<SunFix>,
    /// Low-passed disagreement of the compass with the estimate (radians, before the offset).
    compass_lp: Option<f64>,
    yaw_track: YawTrack,
    /// Covariance (rad²/s²) of the gyroscope bias estimate as learnt from relative heading
    /// measurements; None before the first.
    bias_cov: Option<DMat3>,
}

impl OrientationFilter {
    pub fn new(cfg: FusionConfig) -> Self {
        OrientationFilter {
            cfg,
            reference: None,
            date: None,
            q: DQuat::IDENTITY,
            smoothed: DQuat::IDENTITY,
            initialised: false,
            init_t: 0.0,
            heading_known: false,
            applied_declination: 0.0,
            bias: DVec3::ZERO,
            t: 0.0,
            gyro_t: None,
            gyro_seen: false,
            accel_step_t: None,
            accel: None,
            mag: None,
            disturbed: false,
            good_since: None,
            gyro_only_since: None,
            heading_sigma_at_loss: 0.0,
            tilt_innov_var: 0.0,
            heading_innov_var: 0.0,
            rate: 0.0,
            platform_accuracy: None,
            gps_position: None,
            calibrator: HardIronCalibrator::default(),
            boost_t: None,
            carried_heading_sigma: 0.0,
            carried_tilt_sigma: 0.0,
            mag_time: 0.0,
            hold: None,
            compass_offset: 0.0,
            pending_turn: 0.0,
            sun: None,
            compass_lp: None,
            yaw_track: YawTrack::default(),
            bias_cov: None,
        }
    }

    /// Take a heading measurement from the sun ([`super::sun_heading::heading_measurement`]):
    /// `error` is the estimate's heading error at time `t` (radians, positive = estimate too
    /// far clockwise) with 1σ `sigma`. A Kalman update on yaw: gain K = P / (P + σ²) with P the
    /// filter's heading variance; K·error is taken off the heading (blended in over
    /// [`SUN_BLEND_S`]) and learnt as the compass's offset, and the heading variance becomes
    /// P·(1 − K). Returns the correction (radians), or None when the filter has no heading yet
    /// or the measurement is not finite and positive.
    pub fn sun_heading(&mut self, t: f64, error: f64, sigma: f64) -> Option<f64> {
        let (correction, after) = self.yaw_update(t, error, sigma)?;
        // The compass's own error now: its recent disagreement with the estimate less the
        // estimate's measured error; the offset follows it (halfway per measurement).
        if let Some(lp) = self.compass_lp {
            let c = angle_difference(lp, error);
            self.compass_offset = if self.sun.is_none() { c } else { self.compass_offset + 0.5 * angle_difference(c, self.compass_offset) };
        }
        self.sun = Some(SunFix { t, sigma: after, turned: 0.0 });
        self.carried_heading_sigma = 0.0;
        Some(correction)
    }

    /// Take a heading measurement of another kind than the sun (e.g. the images of a capture:
    /// a new shot matched against an earlier one, [`crate::capture::align::turn_against`]):
    /// the same Kalman update on yaw as [`OrientationFilter::sun_heading`] (gain P/(P + σ²),
    /// blended in over [`SUN_BLEND_S`], a held or gyro-only heading restarting its drift from
    /// the corrected value), but nothing is learnt about the compass. Returns the correction
    /// (radians) or None (no heading yet, a non-finite error, σ not positive).
    pub fn heading_fix(&mut self, t: f64, error: f64, sigma: f64) -> Option<f64> {
        self.yaw_update(t, error, sigma).map(|(correction, _)| correction)
    }

    /// The Kalman update on yaw shared by [`OrientationFilter::sun_heading`] and
    /// [`OrientationFilter::heading_fix`]: returns the correction and the heading 1σ after it.
    fn yaw_update(&mut self, t: f64, error: f64, sigma: f64) -> Option<(f64, f64)> {
        if !(self.initialised && self.heading_known && error.is_finite() && sigma.is_finite() && sigma > 0.0) {
            return None;
        }
        self.t = self.t.max(t);
        let p = self.heading_sigma().powi(2);
        let k = p / (p + sigma * sigma);
        // The part of an earlier correction not yet blended in is already known.
        let correction = k * angle_difference(error, self.pending_turn);
        self.pending_turn += correction;
        let after = (p * (1.0 - k)).sqrt();
        // A held or gyro-only heading restarts its drift from the corrected value.
        if self.hold.is_some() {
            self.hold = Some((t, after));
        }
        if self.gyro_only_since.is_some() {
            self.gyro_only_since = Some(t);
            self.heading_sigma_at_loss = after;
        }
        Some((correction, after))
    }

    /// What the heading estimate went through so far ([`YawTrack`]): take it at an instant
    /// whose heading error relative to a later one will be measured.
    pub fn yaw_track(&self) -> YawTrack {
        self.yaw_track
    }

    /// A measurement of the heading's drift relative to the truth between an earlier instant
    /// and now: since `then` (the [`OrientationFilter::yaw_track`] of that instant) the
    /// estimate's heading became `error` radians more clockwise than the truth's (1σ `sigma`)
    /// — e.g. a new shot's image matched against an earlier shot's
    /// ([`crate::capture::align::turn_against`]). The drift is the gyroscope's residual bias
    /// integrated about the world vertical ([`YawTrack`]), which the accelerometer cannot see
    /// and a held heading does not take from the compass; each such measurement sees the bias
    /// along the device axes that were vertical in between, so as the phone turns through
    /// different attitudes all three components are learnt. A Kalman update of the bias
    /// (prior 1σ [`RELATIVE_BIAS_SIGMA`] per axis, random walk [`RELATIVE_BIAS_WALK`]); an
    /// innovation beyond [`RELATIVE_GATE_SIGMAS`] σ is rejected. The heading itself is not
    /// changed (that is [`OrientationFilter::heading_fix`]'s). Returns the change of the bias
    /// estimate (rad/s, device frame), or None (rejected, not initialised, or not finite).
    pub fn relative_heading(&mut self, then: &YawTrack, error: f64, sigma: f64) -> Option<DVec3> {
        if !(self.initialised && error.is_finite() && sigma.is_finite() && sigma > 0.0) {
            return None;
        }
        let now = self.yaw_track;
        let g = now.up_integral - then.up_integral;
        // ψ now − ψ then = −error = b · g − Δbias_integral + Δturns; the innovation is what the
        // bias left in the estimate now, (b − b̂)·g, explains of it.
        let innovation = -error + (now.bias_integral - then.bias_integral) - (now.turns - then.turns) - self.bias.dot(g);
        let p = *self.bias_cov.get_or_insert(DMat3::from_diagonal(DVec3::splat(RELATIVE_BIAS_SIGMA.powi(2))));
        let pg = p * g;
        let s = g.dot(pg) + sigma * sigma;
        if innovation * innovation > RELATIVE_GATE_SIGMAS.powi(2) * s {
            return None;
        }
        let k = pg / s;
        let before = self.bias;
        self.bias = (self.bias + k * innovation).clamp_length_max(MAX_BIAS);
        let p = p - DMat3::from_cols(k * pg.x, k * pg.y, k * pg.z);
        self.bias_cov = Some((p + p.transpose()) * 0.5);
        Some(self.bias - before)
    }

    /// How far clockwise of the model's magnetic north the magnetometer sees the field, as
    /// learnt from the sun (radians; 0 without a sun measurement).
    pub fn compass_offset(&self) -> f64 {
        self.compass_offset
    }

    /// Heading hold on or off at time `t` (see the module documentation): while on, the
    /// magnetometer does not correct the heading and the heading's 1σ grows with the
    /// gyroscope's drift from its value at `t`. A capture turns it on at the tap and off when
    /// complete.
    pub fn hold_heading(&mut self, t: f64, on: bool) {
        match (on, self.hold) {
            (true, None) => self.hold = Some((t, self.heading_sigma())),
            (false, Some(_)) => {
                self.carried_heading_sigma = self.heading_sigma();
                self.hold = None;
            }
            _ => {}
        }
    }

    /// Whether the heading is held ([`OrientationFilter::hold_heading`]).
    pub fn heading_held(&self) -> bool {
        self.hold.is_some()
    }

    pub fn config(&self) -> &FusionConfig {
        &self.cfg
    }

    /// The date for the World Magnetic Model: with it, the first GPS fix (and any fix more than
    /// about 10 km from the last one used) sets the magnetic reference.
    pub fn set_date(&mut self, date: chrono::NaiveDate) {
        self.date = Some(date);
    }

    /// Set the expected field directly (declination, dip, intensity). The current estimate is
    /// turned so that its heading becomes true-north referenced at once.
    pub fn set_reference(&mut self, reference: MagneticReference) {
        let d = reference.declination;
        if self.initialised {
            let turn = DQuat::from_rotation_z(-(d - self.applied_declination));
            self.q = (turn * self.q).normalize();
            self.smoothed = (turn * self.smoothed).normalize();
        }
        self.applied_declination = d;
        self.reference = Some(reference);
    }

    pub fn reference(&self) -> Option<&MagneticReference> {
        self.reference.as_ref()
    }

    /// The estimated gyroscope bias (rad/s, device frame).
    pub fn gyro_bias(&self) -> DVec3 {
        self.bias
    }

    pub fn magnetic_disturbance(&self) -> bool {
        self.disturbed
    }

    /// The hard-iron offset being removed from magnetometer readings (µT, device frame).
    pub fn hard_iron_offset(&self) -> DVec3 {
        self.calibrator.offset()
    }

    /// Gain multiplier: `startup_gain` at initialisation, falling linearly to 1 over
    /// `startup_s` (a ramped gain, as in x-io's Fusion AHRS), so the first, noisy tilt-compass
    /// estimate is averaged away quickly and the filter then settles to its steady gains.
    /// The same ramp restarts when the magnetometer is trusted again after a disturbance.
    fn gain_scale(&self) -> f64 {
        let ramp = |t0: f64| {
            let u = if self.cfg.startup_s > 0.0 { ((self.t - t0) / self.cfg.startup_s).clamp(0.0, 1.0) } else { 1.0 };
            1.0 + (self.cfg.startup_gain - 1.0).max(0.0) * (1.0 - u)
        };
        ramp(self.init_t).max(self.boost_t.map_or(1.0, ramp))
    }

    /// Whether the start-up ramp is still running (no bias learning, no dip check then: the
    /// estimate is not yet good enough to judge either).
    fn starting_up(&self) -> bool {
        self.t - self.init_t < self.cfg.startup_s
    }

    fn up_in_device(&self) -> DVec3 {
        self.q.inverse() * DVec3::Z
    }

    fn try_initialise(&mut self, t: f64) {
        let Some((_, a)) = self.accel else { return };
        // Tilt only: the shortest rotation taking device "up" to world up; heading unknown
        // until a magnetometer reading gives one.
        self.q = DQuat::from_rotation_arc(a.normalize(), DVec3::Z);
        self.smoothed = self.q;
        self.initialised = true;
        self.init_t = t;
        // One accelerometer reading: the phone's own acceleration tilts it by a few degrees.
        self.carried_tilt_sigma = INITIAL_TILT_SIGMA;
        if let Some((tm, m)) = self.mag
            && (t - tm).abs() < FRESH_S
        {
            self.take_heading(t, m);
        }
    }

    /// Take the heading from the tilt compass when it is still unknown. A reading that the
    /// disturbance test rejects but that is within Earth's range still gives a coarse heading
    /// (an uncalibrated magnetometer reads like that): better than none, reported as gyro-only
    /// with the coarse accuracy until readings agree with the model.
    fn take_heading(&mut self, t: f64, m: DVec3) {
        if self.heading_known || !(EARTH_FIELD_RANGE_UT.0..=EARTH_FIELD_RANGE_UT.1).contains(&m.length()) {
            return;
        }
        let Some((_, a)) = self.accel else { return };
        let Ok(q) = tilt_compass(a, m) else { return };
        self.q = magnetic_to_true(q, self.applied_declination);
        self.smoothed = self.q;
        self.heading_known = true;
        self.carried_heading_sigma = self.cfg.coarse_heading_sigma;
        if self.disturbed {
            self.heading_sigma_at_loss = self.cfg.coarse_heading_sigma;
            self.gyro_only_since = Some(t);
        }
    }

    /// Whether a magnetometer reading agrees with the expected field.
    fn field_agrees(&self, m: DVec3) -> bool {
        let n = m.length();
        match self.reference {
            Some(r) => {
                let up = if self.initialised {
                    self.up_in_device()
                } else {
                    match self.accel {
                        Some((_, a)) => a.normalize_or_zero(),
                        None => return (n - r.total_ut).abs() <= self.cfg.disturbance.magnitude_tolerance * r.total_ut,
                    }
                };
                let dip = (-m.dot(up) / n).clamp(-1.0, 1.0).asin();
                (n - r.total_ut).abs() <= self.cfg.disturbance.magnitude_tolerance * r.total_ut
                    && (!self.initialised || self.starting_up() || (dip - r.inclination).abs() <= self.cfg.disturbance.dip_tolerance)
            }
            None => (EARTH_FIELD_RANGE_UT.0..=EARTH_FIELD_RANGE_UT.1).contains(&n),
        }
    }

    fn on_mag(&mut self, t: f64, raw: DVec3) {
        let m = if self.cfg.hard_iron_calibration {
            self.calibrator.add(raw, self.reference.map(|r| r.total_ut));
            raw - self.calibrator.offset()
        } else {
            raw
        };
        let agrees = !self.cfg.disturbance.enabled || self.field_agrees(m);
        if !agrees {
            if !self.disturbed && self.heading_known {
                self.heading_sigma_at_loss = self.heading_sigma_mag();
                self.gyro_only_since = Some(t);
            }
            self.disturbed = true;
            self.good_since = None;
        } else if self.disturbed {
            let since = *self.good_since.get_or_insert(t);
            if t - since >= self.cfg.disturbance.recover_after_s {
                self.carried_heading_sigma = self.heading_sigma();
                self.disturbed = false;
                self.good_since = None;
                self.gyro_only_since = None;
                // The heading drifted while gyro-only: trust the compass more for a while.
                self.boost_t = Some(t);
            }
        }
        self.mag = Some((t, m));
        if self.initialised {
            self.take_heading(t, m);
        }
    }

    fn on_gps(&mut self, lat: f64, lon: f64, alt: f64) {
        let Some(date) = self.date else { return };
        let moved_far = match self.gps_position {
            // About 10 km: the field changes by far less than the magnetometer noise over it.
            Some((la, lo)) => {
                (lat - la).abs() > 0.09
                    || angle_difference(lon.to_radians(), lo.to_radians()).abs()
                        > 0.09f64.to_radians() / lat.to_radians().cos().abs().max(0.01)
            }
            None => true,
        };
        if moved_far && let Ok(r) = MagneticReference::wmm(lat, lon, alt, date) {
            self.gps_position = Some((lat, lon));
            self.set_reference(r);
        }
    }

    /// Propagate to time `t` with the measured rate `omega` (zero without a gyroscope), then
    /// correct towards the latest accelerometer and magnetometer readings. Predicting first
    /// and correcting after means exact readings give exactly the true orientation.
    fn step(&mut self, t: f64, dt: f64, omega: DVec3, integrate_bias: bool) {
        let rate = omega - if integrate_bias { self.bias } else { DVec3::ZERO };
        self.rate = rate.length();
        let up = self.up_in_device();
        self.yaw_track.up_integral += up * dt;
        if integrate_bias {
            self.yaw_track.bias_integral += up.dot(self.bias) * dt;
        }
        if let Some(p) = self.bias_cov.as_mut() {
            *p += DMat3::from_diagonal(DVec3::splat(RELATIVE_BIAS_WALK * RELATIVE_BIAS_WALK * dt));
        }
        self.q = (self.q * DQuat::from_scaled_axis(rate * dt)).normalize();

        let scale = self.gain_scale();
        let mut correction = DVec3::ZERO;
        // The compass's and the accelerometer's shares of the bias error.
        let mut bias_error = DVec3::ZERO;
        let mut tilt_error = DVec3::ZERO;
        let innov_alpha = 1.0 - (-dt / INNOVATION_TAU_S).exp();

        if let Some((ta, a)) = self.accel
            && t - ta < FRESH_S
        {
            let n = a.length();
            let dev = (n - G).abs() / (self.cfg.accel_tolerance * G);
            let w = (1.0 - dev).max(0.0);
            if w > 0.0 {
                let e = (a / n).cross(self.up_in_device());
                correction += self.cfg.k_acc * scale * w * e;
                tilt_error += w * e;
                self.carried_tilt_sigma *= (-self.cfg.k_acc * scale * w * dt).exp();
                let angle = e.length().min(1.0).asin();
                self.tilt_innov_var += innov_alpha * (angle * angle - self.tilt_innov_var);
            }
        }

        if self.heading_known
            && !self.disturbed
            && self.hold.is_none()
            && let Some((tm, m)) = self.mag
            && t - tm < FRESH_S
        {
            let mw = self.q * m;
            let h = mw.x.hypot(mw.y);
            // A field (almost) along the vertical carries no heading.
            if h > 0.1 * m.length() {
                // Aimed at the sun-calibrated heading, less the part of a sun correction still
                // being blended in (or the compass would correct it a second time).
                let raw = angle_difference(mw.x.atan2(mw.y), self.applied_declination);
                let a = 1.0 - (-dt / COMPASS_LP_S).exp();
                self.compass_lp = Some(self.compass_lp.map_or(raw, |lp| lp + a * angle_difference(raw, lp)));
                let delta = angle_difference(raw, self.compass_offset + self.pending_turn);
                // Against a fresh sun calibration the compass counts by its share of the two
                // variances (a Kalman weighting): it barely moves a heading the sun has just
                // measured, and takes over again as that measurement ages.
                let weight = self.sun_sigma().map_or(1.0, |s| {
                    let m = self.heading_sigma_mag();
                    s * s / (s * s + m * m)
                });
                let z = self.up_in_device();
                correction += self.cfg.k_mag * scale * weight * delta * z;
                bias_error += weight * delta * z;
                self.carried_heading_sigma *= (-self.cfg.k_mag * scale * dt).exp();
                if !self.starting_up() {
                    self.mag_time += dt;
                }
                self.heading_innov_var += innov_alpha * (delta * delta - self.heading_innov_var);
            }
        }

        if integrate_bias && self.cfg.k_bias > 0.0 && !self.starting_up() {
            let k_tilt = if self.rate < self.cfg.still_rate { self.cfg.k_bias.max(self.cfg.k_bias_still) } else { self.cfg.k_bias };
            self.bias -= (self.cfg.k_bias * bias_error + k_tilt * tilt_error) * dt;
            self.bias = self.bias.clamp_length_max(MAX_BIAS);
        }
        // The correction's turn about the world vertical (device frame: along `up`).
        self.yaw_track.turns += correction.dot(self.up_in_device()) * dt;
        self.q = (self.q * DQuat::from_scaled_axis(correction * dt)).normalize();
        if self.pending_turn != 0.0 {
            // A turn about the world vertical by +θ takes θ off the heading (clockwise).
            let step = self.pending_turn * (1.0 - (-dt / SUN_BLEND_S).exp());
            let step = if self.pending_turn.abs() < 1e-9 { self.pending_turn } else { step };
            self.q = (DQuat::from_rotation_z(step) * self.q).normalize();
            self.pending_turn -= step;
            self.yaw_track.turns += step;
        }
        if let Some(fix) = self.sun.as_mut() {
            fix.turned += self.rate * dt;
        }

        let tau = self.smoothing_tau();
        self.smoothed = if tau > 0.0 {
            let alpha = 1.0 - (-dt / tau).exp();
            let target = if self.smoothed.dot(self.q) < 0.0 { -self.q } else { self.q };
            self.smoothed.slerp(target, alpha).normalize()
        } else {
            self.q
        };
    }

    fn smoothing_tau(&self) -> f64 {
        let tau = self.cfg.smoothing_tau_s;
        if tau <= 0.0 || !self.cfg.adaptive_smoothing {
            return tau.max(0.0);
        }
        let s = self.cfg.still_rate;
        tau * (1.0 - ((self.rate - s) / s).clamp(0.0, 1.0))
    }

    /// Heading 1σ while the magnetometer is in use (radians).
    fn heading_sigma_mag(&self) -> f64 {
        let k = self.cfg.k_mag * self.gain_scale();
        // Variance reduction of a first-order low-pass with gain α per step at about 50 Hz.
        let alpha = (k * 0.02).min(1.0);
        let filtered = self.heading_innov_var * alpha / (2.0 - alpha);
        let decl = self.reference.map_or(0.0, |r| r.declination_sigma);
        (self.cfg.heading_floor.powi(2) + filtered + decl * decl + self.carried_heading_sigma.powi(2)).sqrt()
    }

    fn tilt_sigma(&self) -> f64 {
        let alpha = (self.cfg.k_acc * self.gain_scale() * 0.01).min(1.0);
        (self.cfg.tilt_floor.powi(2) + self.tilt_innov_var * alpha / (2.0 - alpha) + self.carried_tilt_sigma.powi(2)).sqrt()
    }

    fn heading_sigma(&self) -> f64 {
        if !self.heading_known {
            return std::f64::consts::PI;
        }
        let drift = self.cfg.gyro_drift + self.cfg.initial_gyro_bias * (-self.mag_time / 60.0).exp();
        let gyro = |t0: f64, sigma0: f64| (sigma0 + drift * (self.t - t0)).min(std::f64::consts::PI);
        match (self.gyro_only_since, self.hold) {
            (Some(t0), Some((th, sh))) if th < t0 => gyro(th, sh),
            (Some(t0), _) => gyro(t0, self.heading_sigma_at_loss),
            (None, Some((th, sh))) => gyro(th, sh),
            (None, None) => {
                let mag = self.heading_sigma_mag();
                self.sun_sigma().map_or(mag, |sun| sun.min(mag))
            }
        }
    }

    /// Heading 1σ of the sun calibration now (radians): its value after the update, growing
    /// towards the compass floor as the phone turns away from where it was measured, and with
    /// time as fast as the compass can pull the heading when its error changes by the floor
    /// (an undetected disturbance): k_mag × floor per second. This process noise keeps later
    /// sun measurements weighty (a Kalman filter without it would trust its first fixes for
    /// ever and let the compass drift the heading away).
    fn sun_sigma(&self) -> Option<f64> {
        let fix = self.sun?;
        let turned = self.cfg.heading_floor * (fix.turned / SUN_VALID_TURN).min(1.0);
        let aged = self.cfg.k_mag * self.cfg.heading_floor * (self.t - fix.t).max(0.0);
        Some(fix.sigma.hypot(turned).hypot(aged))
    }

    fn heading_source(&self) -> HeadingSource {
        if self.platform_accuracy.is_some() && self.cfg.use_platform_attitude {
            HeadingSource::Platform
        } else if !self.heading_known {
            HeadingSource::Unknown
        } else if self.disturbed {
            HeadingSource::GyroOnly
        } else if self.sun_sigma().is_some_and(|s| s < self.heading_sigma_mag()) {
            HeadingSource::Sun
        } else {
            HeadingSource::Magnetometer
        }
    }
}

impl OrientationEstimator for OrientationFilter {
    fn update(&mut self, r: &Reading) -> Result<()> {
        r.validate()?;
        let t = r.t();
        self.t = self.t.max(t);
        match *r {
            Reading::Accel { t, v } => {
                self.accel = Some((t, v));
                if !self.initialised {
                    self.try_initialise(t);
                } else if !self.gyro_seen && !self.cfg.use_platform_attitude {
                    // No gyroscope: the same filter with zero rate (a plain complementary
                    // filter of the compass), stepping on accelerometer readings.
                    if let Some(t0) = self.accel_step_t {
                        let dt = t - t0;
                        if dt > 0.0 && dt < MAX_GYRO_GAP_S {
                            self.step(t, dt, DVec3::ZERO, false);
                        }
                    }
                    self.accel_step_t = Some(t);
                }
            }
            Reading::Mag { t, v } => {
                self.on_mag(t, v);
                if !self.initialised {
                    self.try_initialise(t);
                }
            }
            Reading::Gyro { t, v } => {
                self.gyro_seen = true;
                if self.initialised
                    && !self.cfg.use_platform_attitude
                    && let Some(t0) = self.gyro_t
                {
                    let dt = t - t0;
                    if dt > 0.0 && dt < MAX_GYRO_GAP_S {
                        self.step(t, dt, v, true);
                    }
                }
                self.gyro_t = Some(t);
            }
            Reading::Gps(f) => self.on_gps(f.lat_deg, f.lon_deg, f.alt_m),
            Reading::Attitude { q, north, heading_accuracy_rad, .. } => {
                if self.cfg.use_platform_attitude {
                    self.q = match north {
                        North::Magnetic => magnetic_to_true(q.normalize(), self.applied_declination),
                        North::True => q.normalize(),
                    };
                    self.smoothed = self.q;
                    self.initialised = true;
                    self.heading_known = true;
                    self.platform_accuracy = Some(heading_accuracy_rad.unwrap_or(self.cfg.heading_floor));
                }
            }
        }
        Ok(())
    }

    fn pose(&self, rotation: DisplayRotation) -> Option<Pose> {
        if !self.initialised {
            return None;
        }
        let (tilt, heading) = match (self.cfg.use_platform_attitude, self.platform_accuracy) {
            (true, Some(acc)) => (self.cfg.tilt_floor, acc),
            _ => (self.tilt_sigma(), self.heading_sigma()),
        };
        Some(Pose {
            t: self.t,
            q: camera_pose_from_device(self.smoothed, rotation).as_quat(),
            accuracy_deg: tilt.hypot(heading).to_degrees() as f32,
            heading_accuracy_deg: heading.to_degrees() as f32,
            tilt_accuracy_deg: tilt.to_degrees() as f32,
            heading_source: self.heading_source(),
            magnetic_disturbance: self.disturbed,
        })
    }

    fn device_orientation(&self) -> Option<DQuat> {
        self.initialised.then_some(self.q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::{angle_between, from_heading_pitch_roll, heading_pitch_roll};

    const FIELD: DVec3 = DVec3::new(-0.4, 19.5, -44.6);

    /// Exact readings for a device rotating at a constant body rate from `q0` at `t0`. At
    /// t0 = 0 the first sample is fed too; otherwise it continues a previous call ending at t0.
    fn feed_rotation(f: &mut OrientationFilter, q0: DQuat, omega: DVec3, t0: f64, secs: f64, field: DVec3) -> DQuat {
        let dt = 0.01;
        let mut q = q0;
        let n = (secs / dt).round() as usize;
        for i in usize::from(t0 != 0.0)..=n {
            let t = t0 + i as f64 * dt;
            if i > 0 {
                q = (q * DQuat::from_scaled_axis(omega * dt)).normalize();
            }
            f.update(&Reading::Accel { t, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
            f.update(&Reading::Mag { t, v: q.inverse() * field }).unwrap();
            f.update(&Reading::Gyro { t, v: omega }).unwrap();
        }
        q
    }

    fn reference() -> MagneticReference {
        MagneticReference::from_field_enu(FIELD, 0.005)
    }

    #[test]
    fn exact_readings_track_rotations_through_the_poles() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        // Start flat on the table, screen up (camera looking straight down), then pitch over
        // the vertical both ways and spin about an oblique axis.
        let q0 = DQuat::from_rotation_z(0.3);
        let q = feed_rotation(&mut f, q0, DVec3::ZERO, 0.0, 1.0, FIELD);
        assert!(angle_between(f.device_orientation().unwrap(), q) < 1e-9);
        let q = feed_rotation(&mut f, q, DVec3::new(1.2, 0.0, 0.0), 1.0, 3.0, FIELD);
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() < 1e-6);
        let q = feed_rotation(&mut f, q, DVec3::new(-0.3, 0.8, 0.5), 4.0, 4.0, FIELD);
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() < 1e-6);
        assert_eq!(f.pose(DisplayRotation::R0).unwrap().heading_source, HeadingSource::Magnetometer);
    }

    #[test]
    fn learns_gyro_bias() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let truth = from_heading_pitch_roll(1.0, 0.2, 0.0);
        let bias = DVec3::new(0.01, -0.02, 0.015);
        let dt = 0.01;
        for i in 0..40_000 {
            let t = i as f64 * dt;
            f.update(&Reading::Accel { t, v: truth.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
            f.update(&Reading::Mag { t, v: truth.inverse() * FIELD }).unwrap();
            f.update(&Reading::Gyro { t, v: bias }).unwrap();
        }
        // Steady state: the integral term has absorbed the bias, no residual error.
        assert!((f.gyro_bias() - bias).length() < 1e-3, "{:?}", f.gyro_bias());
        assert!(angle_between(f.device_orientation().unwrap(), truth).to_degrees() < 0.05);
    }

    #[test]
    fn a_still_phone_learns_the_tilt_axes_of_the_bias_within_seconds() {
        // Heading held (no compass): only the accelerometer sees the bias, on the two axes
        // perpendicular to the vertical. Still, its share of the bias is learnt at
        // k_bias_still = 0.1/s² with k_acc = 0.5/s: a PI loop s² + 0.5 s + 0.1 whose slower root
        // decays with ~4 s (0.01/s², the moving gain: ~48 s).
        let truth = from_heading_pitch_roll(1.0, 0.2, 0.3);
        let up = truth.inverse() * DVec3::Z;
        let bias = DVec3::new(0.01, -0.02, 0.015);
        let tilt_bias = bias - bias.dot(up) * up;
        let learnt = |k_bias_still: f64| {
            let mut f = OrientationFilter::new(FusionConfig { k_bias_still, ..FusionConfig::default() });
            f.set_reference(reference());
            let dt = 0.01;
            for i in 0..2_300 {
                let t = i as f64 * dt;
                if i == 300 {
                    f.hold_heading(t, true);
                }
                f.update(&Reading::Accel { t, v: truth.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
                f.update(&Reading::Mag { t, v: truth.inverse() * FIELD }).unwrap();
                f.update(&Reading::Gyro { t, v: bias }).unwrap();
            }
            let b = f.gyro_bias();
            (b - b.dot(up) * up - tilt_bias).length() / tilt_bias.length()
        };
        let (still, moving) = (learnt(0.1), learnt(0.01));
        assert!(still < 0.05, "20 s still: {:.0}% of the tilt-axis bias left", 100.0 * still);
        assert!(moving > 0.4, "at the moving gain: {:.0}% left", 100.0 * moving);
    }

    #[test]
    fn declination_from_reference_makes_true_heading() {
        // Field 10° east of north: a device facing magnetic north faces true heading 10°.
        let d = 10f64.to_radians();
        let field = DVec3::new(d.sin() * 20.0, d.cos() * 20.0, -44.0);
        let mut f = OrientationFilter::new(FusionConfig::default());
        // Camera looking at the horizon towards magnetic north, portrait.
        let cam = from_heading_pitch_roll(d, 0.0, 0.0);
        let dev = crate::pose::frames::device_from_camera_pose(cam, DisplayRotation::R0);
        feed_rotation(&mut f, dev, DVec3::ZERO, 0.0, 0.5, field);
        // Without a reference the heading is magnetic (0°).
        let hpr = heading_pitch_roll(f.pose(DisplayRotation::R0).unwrap().q.as_dquat());
        assert!(angle_difference(hpr.heading, 0.0).abs().to_degrees() < 1e-3, "{hpr:?}");
        f.set_reference(MagneticReference::from_field_enu(field, 0.0));
        let hpr = heading_pitch_roll(f.pose(DisplayRotation::R0).unwrap().q.as_dquat());
        assert!(angle_difference(hpr.heading, d).abs().to_degrees() < 1e-3, "{hpr:?}");
    }

    #[test]
    fn disturbance_switches_to_gyro_only_and_back() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let q = DQuat::from_rotation_z(0.5) * DQuat::from_rotation_x(1.2);
        let dt = 0.01;
        let mut t = 0.0;
        let mut feed = |f: &mut OrientationFilter, secs: f64, extra: DVec3| {
            for _ in 0..(secs / dt) as usize {
                t += dt;
                f.update(&Reading::Accel { t, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
                f.update(&Reading::Mag { t, v: q.inverse() * (FIELD + extra) }).unwrap();
                f.update(&Reading::Gyro { t, v: DVec3::ZERO }).unwrap();
            }
        };
        feed(&mut f, 3.0, DVec3::ZERO);
        let p = f.pose(DisplayRotation::R0).unwrap();
        assert!(!p.magnetic_disturbance && p.heading_source == HeadingSource::Magnetometer);
        let acc_before = p.heading_accuracy_deg;
        // A steel object near the phone: 25 µT sideways for 5 s.
        feed(&mut f, 5.0, DVec3::new(25.0, 0.0, 0.0));
        let p = f.pose(DisplayRotation::R0).unwrap();
        assert!(p.magnetic_disturbance && p.heading_source == HeadingSource::GyroOnly);
        // Gyro-only: heading held (the gyro is perfect here), accuracy estimate grown.
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() < 1e-6);
        assert!(p.heading_accuracy_deg > acc_before);
        // Field back to normal: trusted again after `recover_after_s`.
        feed(&mut f, 0.5, DVec3::ZERO);
        assert!(f.magnetic_disturbance());
        feed(&mut f, 1.0, DVec3::ZERO);
        assert!(!f.magnetic_disturbance());
    }

    #[test]
    fn disturbance_ignored_when_detection_is_off() {
        let cfg = FusionConfig { disturbance: DisturbanceConfig { enabled: false, ..Default::default() }, ..Default::default() };
        let mut f = OrientationFilter::new(cfg);
        f.set_reference(reference());
        let q = DQuat::IDENTITY;
        feed_rotation(&mut f, q, DVec3::ZERO, 0.0, 2.0, FIELD);
        // 25 µT east added: the compass swings the heading towards the disturbed field.
        feed_rotation(&mut f, q, DVec3::ZERO, 2.0, 10.0, FIELD + DVec3::new(25.0, 0.0, 0.0));
        assert!(!f.magnetic_disturbance());
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() > 20.0);
    }

    #[test]
    fn heading_hold_ignores_a_compass_error_that_the_disturbance_test_cannot_see() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let q = DQuat::IDENTITY;
        feed_rotation(&mut f, q, DVec3::ZERO, 0.0, 5.0, FIELD);
        let before = f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg;
        f.hold_heading(5.0, true);
        assert!(f.heading_held());
        // The field turned by 8° about the vertical: same magnitude and dip, so no disturbance
        // is detected (a residual hard-iron offset does this as the phone turns).
        let turned = DQuat::from_rotation_z(8f64.to_radians()) * FIELD;
        feed_rotation(&mut f, q, DVec3::ZERO, 5.0, 10.0, turned);
        assert!(!f.magnetic_disturbance());
        // Exact gyroscope, held heading: still the true orientation.
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() < 0.01);
        // Its 1σ grows with the gyroscope's drift model (≥ 0.05°/s over the 10 s held).
        let held = f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg;
        assert!(held >= before + 0.5, "{before} -> {held}");
        // Released: the compass pulls the heading towards the turned field (time constant 5 s:
        // 1 − e⁻² = 86 % of 8° in 10 s).
        f.hold_heading(15.0, false);
        feed_rotation(&mut f, q, DVec3::ZERO, 15.0, 10.0, turned);
        let moved = angle_between(f.device_orientation().unwrap(), q).to_degrees();
        assert!(moved > 6.0 && moved < 8.5, "{moved}");
    }

    /// Heading error (radians, clockwise positive) of the filter against `truth` (device → ENU).
    fn heading_error(f: &OrientationFilter, truth: DQuat) -> f64 {
        let y = |q: DQuat| {
            let v = q * DVec3::Y;
            v.x.atan2(v.y)
        };
        angle_difference(y(f.device_orientation().unwrap()), y(truth))
    }

    #[test]
    fn a_sun_measurement_removes_the_compass_error_and_keeps_it_removed() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        // Phone upright looking north-east; the compass reads the field turned 3° clockwise
        // (same magnitude and dip: a residual hard-iron error the disturbance test cannot see).
        let q = from_heading_pitch_roll(0.8, 0.1, 0.0);
        let dev = crate::pose::frames::device_from_camera_pose(q, DisplayRotation::R0);
        let turned = DQuat::from_rotation_z(-3f64.to_radians()) * FIELD;
        feed_rotation(&mut f, dev, DVec3::ZERO, 0.0, 20.0, turned);
        let before = heading_error(&f, dev);
        assert!((before.to_degrees() + 3.0).abs() < 0.05, "compass-only error {}°", before.to_degrees());
        let p0 = f.pose(DisplayRotation::R0).unwrap();
        assert_eq!(p0.heading_source, HeadingSource::Magnetometer);
        // The sun measures that error with 1σ 0.1°: the Kalman gain is P/(P + R) with P ≥ the
        // 2° floor, so ≥ 99.7 % of it is taken off.
        let sigma = 0.1f64.to_radians();
        let k = f.sun_heading(20.0, before, sigma).unwrap() / before;
        let p = (f64::from(p0.heading_accuracy_deg).to_radians()).powi(2);
        assert!((k - p / (p + sigma * sigma)).abs() < 1e-9 && k > 0.997, "gain {k}");
        // 1σ right after: sqrt(P(1 − K)), just under the measurement's 0.1°.
        let right_after = f.pose(DisplayRotation::R0).unwrap();
        assert!((f64::from(right_after.heading_accuracy_deg) - (p * (1.0 - k)).sqrt().to_degrees()).abs() < 1e-3);
        assert_eq!(right_after.heading_source, HeadingSource::Sun);
        // Not a jump: blended in over 0.25 s; a frame later (10 ms) only ~4 % has moved.
        feed_rotation(&mut f, dev, DVec3::ZERO, 20.0, 0.01, turned);
        let moved = before - heading_error(&f, dev);
        assert!(moved.abs() < 0.1 * before.abs(), "moved {}° in 10 ms", moved.to_degrees());
        feed_rotation(&mut f, dev, DVec3::ZERO, 20.01, 2.0, turned);
        let after = heading_error(&f, dev);
        assert!(after.to_degrees().abs() < 0.02, "after the sun {}°", after.to_degrees());
        // 2 s on, the calibration's 1σ has grown by k_mag × 2° floor per second (0.8°), still
        // below the compass's.
        let p1 = f.pose(DisplayRotation::R0).unwrap();
        assert_eq!(p1.heading_source, HeadingSource::Sun);
        assert!((p1.heading_accuracy_deg - 0.81).abs() < 0.02, "{}", p1.heading_accuracy_deg);
        // The compass keeps correcting, now towards the calibrated heading: 30 s later (the
        // calibration aged: the source is the compass again) still right, and the learnt
        // offset is the compass's 3° error.
        feed_rotation(&mut f, dev, DVec3::ZERO, 22.01, 30.0, turned);
        assert!(heading_error(&f, dev).to_degrees().abs() < 0.02, "{}°", heading_error(&f, dev).to_degrees());
        assert_eq!(f.pose(DisplayRotation::R0).unwrap().heading_source, HeadingSource::Magnetometer);
        // The learnt offset: the field is seen 3° clockwise of where the model puts it.
        assert!((f.compass_offset().to_degrees() - 3.0).abs() < 0.05, "offset {}°", f.compass_offset().to_degrees());
        // No heading yet, a NaN error or a non-positive σ: not taken.
        assert_eq!(f.sun_heading(52.0, f64::NAN, sigma), None);
        assert_eq!(f.sun_heading(52.0, 0.01, 0.0), None);
        assert_eq!(OrientationFilter::new(FusionConfig::default()).sun_heading(0.0, 0.01, sigma), None);
    }

    #[test]
    fn a_heading_fix_turns_a_held_heading_and_teaches_the_compass_nothing() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let q = from_heading_pitch_roll(0.8, 0.1, 0.0);
        let dev = crate::pose::frames::device_from_camera_pose(q, DisplayRotation::R0);
        feed_rotation(&mut f, dev, DVec3::ZERO, 0.0, 5.0, FIELD);
        f.hold_heading(5.0, true);
        feed_rotation(&mut f, dev, DVec3::ZERO, 5.0, 4.0, FIELD);
        let p = f64::from(f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg).to_radians().powi(2);
        // The images say the held heading is 3° too far clockwise, with 1σ 0.3°.
        let sigma = 0.3f64.to_radians();
        let c = f.heading_fix(9.0, 3f64.to_radians(), sigma).unwrap();
        let k = p / (p + sigma * sigma);
        assert!((c / 3f64.to_radians() - k).abs() < 1e-5 && k > 0.9, "gain {} vs {k}", c / 3f64.to_radians());
        let after = f64::from(f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg).to_radians();
        assert!((after - (p * (1.0 - k)).sqrt()).abs() < 1e-4, "{after}");
        // Blended in, and held there: the compass (still held off) does not pull it back.
        feed_rotation(&mut f, dev, DVec3::ZERO, 9.0, 3.0, FIELD);
        let moved = -heading_error(&f, dev);
        assert!((moved - c).abs() < 0.01f64.to_radians(), "moved {}° of {}°", moved.to_degrees(), c.to_degrees());
        assert_eq!(f.compass_offset(), 0.0);
        assert_eq!(f.heading_fix(12.0, f64::NAN, sigma), None);
        assert_eq!(f.heading_fix(12.0, 0.01, 0.0), None);
    }

    #[test]
    fn an_uncertain_sun_measurement_moves_the_heading_by_its_weight() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let q = DQuat::IDENTITY;
        feed_rotation(&mut f, q, DVec3::ZERO, 0.0, 10.0, FIELD);
        let p = f64::from(f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg).to_radians().powi(2);
        // A measurement as uncertain as the compass (σ² = P) takes half of its 4° reading.
        let c = f.sun_heading(10.0, 4f64.to_radians(), p.sqrt()).unwrap();
        assert!((c.to_degrees() - 2.0).abs() < 1e-6, "{}", c.to_degrees());
        let after = f64::from(f.pose(DisplayRotation::R0).unwrap().heading_accuracy_deg).to_radians();
        assert!((after - (p / 2.0).sqrt()).abs() < 1e-3, "{} vs {}", after.to_degrees(), (p / 2.0).sqrt().to_degrees());
    }

    #[test]
    fn nan_readings_are_rejected_without_changing_state() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        feed_rotation(&mut f, DQuat::IDENTITY, DVec3::ZERO, 0.0, 0.5, FIELD);
        let before = f.device_orientation().unwrap();
        assert!(f.update(&Reading::Gyro { t: 0.6, v: DVec3::new(f64::NAN, 0.0, 0.0) }).is_err());
        assert!(f.update(&Reading::Accel { t: 0.6, v: DVec3::splat(f64::INFINITY) }).is_err());
        assert!(f.update(&Reading::Mag { t: f64::NAN, v: FIELD }).is_err());
        assert_eq!(f.device_orientation().unwrap(), before);
        assert!(f.device_orientation().unwrap().is_finite());
    }

    #[test]
    fn tilt_only_start_then_heading_when_the_field_arrives() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        let q = from_heading_pitch_roll(2.0, 0.1, 0.0);
        f.update(&Reading::Accel { t: 0.0, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
        let p = f.pose(DisplayRotation::R0).unwrap();
        assert_eq!(p.heading_source, HeadingSource::Unknown);
        assert!(p.heading_accuracy_deg >= 179.0);
        f.update(&Reading::Mag { t: 0.01, v: q.inverse() * FIELD }).unwrap();
        assert!(angle_between(f.device_orientation().unwrap(), magnetic_to_true(q, -FIELD.x.atan2(FIELD.y))) < 1e-9);
    }

    #[test]
    fn works_without_a_gyroscope() {
        // Without gyroscope readings the filter is a complementary filter of the compass: it
        // follows a change of orientation with the correction time constants.
        let mut f = OrientationFilter::new(FusionConfig::default());
        f.set_reference(reference());
        let q1 = from_heading_pitch_roll(0.7, -0.4, 0.1);
        let q2 = from_heading_pitch_roll(1.2, 0.1, -0.2);
        let dt = 0.01;
        for i in 0..3200 {
            let t = i as f64 * dt;
            let q = if t < 2.0 { q1 } else { q2 };
            f.update(&Reading::Accel { t, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
            f.update(&Reading::Mag { t, v: q.inverse() * FIELD }).unwrap();
            if i == 190 {
                assert!(angle_between(f.device_orientation().unwrap(), q1) < 1e-9);
            }
        }
        assert!(angle_between(f.device_orientation().unwrap(), q2).to_degrees() < 0.2);
    }

    #[test]
    fn hard_iron_offset_is_learnt_while_turning() {
        // An uncalibrated magnetometer: 6 µT offsets, enough to look like a disturbance.
        let offset = DVec3::new(6.0, -4.0, 3.0);
        let run = |cfg: FusionConfig| {
            let mut f = OrientationFilter::new(cfg);
            f.set_reference(reference());
            let dt = 0.01;
            let mut q = DQuat::from_rotation_z(0.4);
            let mut disturbed = 0;
            let n = 6000;
            for i in 0..n {
                let t = i as f64 * dt;
                // Tumbling about a slowly changing axis, like a figure-of-eight.
                let omega = DVec3::new((0.3 * t).sin(), (0.23 * t).cos(), 0.5) * 1.2;
                if i > 0 {
                    q = (q * DQuat::from_scaled_axis(omega * dt)).normalize();
                }
                f.update(&Reading::Accel { t, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
                f.update(&Reading::Mag { t, v: q.inverse() * FIELD + offset }).unwrap();
                f.update(&Reading::Gyro { t, v: omega }).unwrap();
                disturbed += usize::from(f.magnetic_disturbance());
            }
            (f, q, disturbed as f64 / n as f64)
        };
        let (f, q, disturbed) = run(FusionConfig::default());
        assert!((f.hard_iron_offset() - offset).length() < 0.05, "{:?}", f.hard_iron_offset());
        assert!(!f.magnetic_disturbance() && disturbed < 0.2, "{disturbed}");
        assert!(angle_between(f.device_orientation().unwrap(), q).to_degrees() < 0.2);
        // Without calibration the same readings look disturbed much of the time.
        let (g, _, disturbed) = run(FusionConfig { hard_iron_calibration: false, ..Default::default() });
        assert_eq!(g.hard_iron_offset(), DVec3::ZERO);
        assert!(disturbed > 0.3, "{disturbed}");
    }

    #[test]
    fn gps_fix_with_a_date_sets_the_wmm_reference() {
        let mut f = OrientationFilter::new(FusionConfig::default());
        let fix = crate::sensors::GpsFix {
            t: 0.0,
            lat_deg: 51.4545,
            lon_deg: -2.5879,
            alt_m: 20.0,
            horizontal_accuracy_m: 10.0,
            vertical_accuracy_m: 15.0,
        };
        // Without a date the model cannot be evaluated: no reference.
        f.update(&Reading::Gps(fix)).unwrap();
        assert!(f.reference().is_none());
        let date = chrono::NaiveDate::from_ymd_opt(2026, 11, 21).unwrap();
        f.set_date(date);
        f.update(&Reading::Gps(fix)).unwrap();
        let here = MagneticReference::wmm(51.4545, -2.5879, 20.0, date).unwrap();
        assert_eq!(f.reference(), Some(&here));
        // A fix 1 km away keeps it; one 50 km away re-evaluates the model there.
        f.update(&Reading::Gps(crate::sensors::GpsFix { lat_deg: 51.4635, ..fix })).unwrap();
        assert_eq!(f.reference(), Some(&here));
        f.update(&Reading::Gps(crate::sensors::GpsFix { lat_deg: 51.9, ..fix })).unwrap();
        assert_eq!(f.reference(), Some(&MagneticReference::wmm(51.9, -2.5879, 20.0, date).unwrap()));
        assert!(f.update(&Reading::Gps(crate::sensors::GpsFix { lon_deg: f64::NAN, ..fix })).is_err());
    }

    /// Yaw (radians, anticlockwise about the world vertical) of the error rotation est · truth⁻¹.
    fn yaw_error(est: DQuat, truth: DQuat) -> f64 {
        let e = est * truth.inverse();
        let e = if e.w < 0.0 { -e } else { e };
        2.0 * e.z.atan2(e.w)
    }

    #[test]
    fn relative_heading_measurements_teach_the_gyroscope_bias_about_every_axis() {
        // Exact accelerometer and magnetometer readings, a gyroscope with a constant bias of
        // ~1°/s per axis (the simulator's `bad` preset). After start-up the heading is held
        // (a capture), and the phone turns through six attitudes; at each, the true change of
        // the estimate's heading error since the previous one is given as a relative heading
        // measurement (what matching two shots' images measures). The bias about every axis
        // is learnt from them — the accelerometer alone, in the same time, learns only what
        // was horizontal — so the held heading then barely drifts.
        let bias = DVec3::new(0.015, -0.018, 0.016);
        let turns = [
            DVec3::new(0.0, 0.8, 0.0),
            DVec3::new(0.7, 0.0, 0.0),
            DVec3::new(0.0, -0.8, 0.3),
            DVec3::new(-0.7, 0.2, 0.0),
            DVec3::new(0.0, 0.0, 0.9),
            DVec3::new(0.5, 0.5, 0.0),
        ];
        let run = |measure: bool| {
            let mut f = OrientationFilter::new(FusionConfig::default());
            f.set_reference(reference());
            let dt = 0.01;
            // Upright, as a phone held to take a picture.
            let mut q = DQuat::from_rotation_z(0.3) * DQuat::from_rotation_x(1.2);
            let mut t = 0.0;
            let mut feed = |f: &mut OrientationFilter, q: &mut DQuat, omega: DVec3, secs: f64| {
                for _ in 0..(secs / dt).round() as usize {
                    t += dt;
                    *q = (*q * DQuat::from_scaled_axis(omega * dt)).normalize();
                    f.update(&Reading::Accel { t, v: q.inverse() * DVec3::new(0.0, 0.0, G) }).unwrap();
                    f.update(&Reading::Mag { t, v: q.inverse() * FIELD }).unwrap();
                    f.update(&Reading::Gyro { t, v: omega + bias }).unwrap();
                }
                t
            };
            let t0 = feed(&mut f, &mut q, DVec3::ZERO, 4.0);
            f.hold_heading(t0, true);
            let mut last = (f.yaw_track(), yaw_error(f.device_orientation().unwrap(), q));
            let mut learnt = 0;
            for omega in turns {
                feed(&mut f, &mut q, omega, 1.0);
                feed(&mut f, &mut q, DVec3::ZERO, 1.0);
                let psi = yaw_error(f.device_orientation().unwrap(), q);
                if measure && f.relative_heading(&last.0, -(psi - last.1), 0.1f64.to_radians()).is_some() {
                    learnt += 1;
                }
                last = (f.yaw_track(), psi);
            }
            // Then the drift of the held heading over 10 s still in the last attitude.
            let before = yaw_error(f.device_orientation().unwrap(), q);
            feed(&mut f, &mut q, DVec3::ZERO, 10.0);
            let drift = (yaw_error(f.device_orientation().unwrap(), q) - before).to_degrees();
            ((f.gyro_bias() - bias).length().to_degrees(), drift, learnt)
        };
        let (without, drift_without, _) = run(false);
        let (with, drift_with, learnt) = run(true);
        eprintln!("bias error {without:.3} -> {with:.3} deg/s; drift over 10 s {drift_without:.2} -> {drift_with:.2} deg; {learnt} learnt");
        assert_eq!(learnt, turns.len());
        assert!(with < 0.1 && without > 0.3, "{without} {with}");
        assert!(drift_with.abs() < 0.5 && drift_without.abs() > 3.0, "{drift_without} {drift_with}");
    }

    #[test]
    fn platform_attitude_with_magnetic_north_is_corrected() {
        let cfg = FusionConfig { use_platform_attitude: true, ..Default::default() };
        let mut f = OrientationFilter::new(cfg);
        let d = 3f64.to_radians();
        f.set_reference(MagneticReference::from_field_enu(DVec3::new(d.sin(), d.cos(), -2.0) * 20.0, 0.0));
        f.update(&Reading::Attitude { t: 0.0, q: DQuat::IDENTITY, north: North::Magnetic, heading_accuracy_rad: Some(0.1) }).unwrap();
        let p = f.pose(DisplayRotation::R0).unwrap();
        assert_eq!(p.heading_source, HeadingSource::Platform);
        assert!((p.heading_accuracy_deg - 0.1f32.to_degrees()).abs() < 1e-3);
        let y = f.device_orientation().unwrap() * DVec3::Y;
        assert!((y.x.atan2(y.y) - d).abs() < 1e-12);
    }
}
