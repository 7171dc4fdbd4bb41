//! Simulated sensors: the readings a phone would give while following a true pose path, with a
//! noise model at three levels (`none`, `phone`, `bad`). Seeded and deterministic: each sensor
//! has its own random stream, so the readings do not depend on how often `poll` is called.
//!
//! What is modelled:
//! - gyroscope: white noise, a constant bias drawn per run and a bias random walk;
//! - accelerometer: gravity plus the phone's own acceleration (it swings on a lever arm in front
//!   of the user), white noise, constant bias;
//! - magnetometer: the World Magnetic Model field at the location and date, a hard-iron offset
//!   (fixed in the device), white noise, and transient disturbances (a field added in the world
//!   frame with raised-cosine ramps, as when passing a car or a steel post) at random times
//!   and/or at given times;
//! - GPS: 1 Hz fixes whose error is a first-order Gauss–Markov process (τ = 30 s) with the
//!   accuracy of seed 000 §4.1 (±10 m horizontally, ±15 m vertically, after the US Coast
//!   Guard Navigation Center figures it cites).
//!
//! `phone` noise uses the Bosch BMI160 datasheet densities (gyroscope 0.007 °/s/√Hz,
//! accelerometer 180 µg/√Hz) over a ~40 Hz bandwidth, rounded up; magnetometer noise (0.3 µT)
//! and the residual biases after the OS's calibration are assumptions of typical phone
//! behaviour, not datasheet values. `bad` is several times worse everywhere, with an
//! uncalibrated hard-iron offset and frequent disturbances.

use super::{GpsFix, Reading, SensorSource};
use crate::pose::frames::{DisplayRotation, device_from_camera_pose};
use crate::pose::magnetic::MagneticReference;
use crate::pose::trace::TruthTrace;
use anyhow::{Result, bail};
use glam::{DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Noise level presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum NoiseLevel {
    /// Exact readings (no noise, bias, offsets or disturbances; GPS exact).
    None,
    /// A typical phone after the OS's sensor calibration.
    Phone,
    /// A poor phone or an uncalibrated magnetometer in a magnetically busy place.
    Bad,
}

impl NoiseLevel {
    pub fn name(self) -> &'static str {
        match self {
            NoiseLevel::None => "none",
            NoiseLevel::Phone => "phone",
            NoiseLevel::Bad => "bad",
        }
    }
}

/// The noise model's parameters (1σ values unless stated).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseModel {
    /// Gyroscope white noise per sample (rad/s).
    pub gyro_white: f64,
    /// Gyroscope bias at the start, per axis (rad/s).
    pub gyro_bias: f64,
    /// Gyroscope bias random walk (rad/s per √s).
    pub gyro_bias_walk: f64,
    /// Accelerometer white noise per sample (m/s²).
    pub accel_white: f64,
    /// Accelerometer constant bias per axis (m/s²).
    pub accel_bias: f64,
    /// Magnetometer white noise per sample (µT).
    pub mag_white: f64,
    /// Hard-iron offset per axis (µT), constant in the device frame.
    pub hard_iron: f64,
    /// Random magnetic disturbances per second (Poisson rate).
    pub disturbance_rate: f64,
    /// Disturbance field magnitude range (µT).
    pub disturbance_ut: (f64, f64),
    /// Disturbance duration range (s).
    pub disturbance_s: (f64, f64),
    /// GPS horizontal error per axis (m) and vertical error (m).
    pub gps_horizontal: f64,
    pub gps_vertical: f64,
    /// Correlation time of the GPS error (s).
    pub gps_tau_s: f64,
    /// Accuracies the simulated GPS reports (m): horizontal 68 % radius, vertical 1σ.
    pub gps_reported: (f64, f64),
}

impl NoiseModel {
    pub fn for_level(level: NoiseLevel) -> Self {
        let d = |x: f64| x.to_radians();
        // A 2-D Gaussian with σ per axis has its 68 % radius at 1.515σ: ±10 m → σ = 6.6 m.
        let h68 = 1.515;
        match level {
            NoiseLevel::None => NoiseModel {
                gyro_white: 0.0,
                gyro_bias: 0.0,
                gyro_bias_walk: 0.0,
                accel_white: 0.0,
                accel_bias: 0.0,
                mag_white: 0.0,
                hard_iron: 0.0,
                disturbance_rate: 0.0,
                disturbance_ut: (0.0, 0.0),
                disturbance_s: (0.0, 0.0),
                gps_horizontal: 0.0,
                gps_vertical: 0.0,
                gps_tau_s: 30.0,
                gps_reported: (0.0, 0.0),
            },
            NoiseLevel::Phone => NoiseModel {
                gyro_white: d(0.05),
                gyro_bias: d(0.1),
                gyro_bias_walk: d(0.002),
                accel_white: 0.015,
                accel_bias: 0.03,
                mag_white: 0.3,
                hard_iron: 1.0,
                disturbance_rate: 1.0 / 60.0,
                disturbance_ut: (5.0, 15.0),
                disturbance_s: (1.0, 4.0),
                gps_horizontal: 10.0 / h68,
                gps_vertical: 15.0,
                gps_tau_s: 30.0,
                gps_reported: (10.0, 15.0),
            },
            NoiseLevel::Bad => NoiseModel {
                gyro_white: d(0.2),
                gyro_bias: d(1.0),
                gyro_bias_walk: d(0.02),
                accel_white: 0.1,
                accel_bias: 0.2,
                mag_white: 1.5,
                hard_iron: 6.0,
                disturbance_rate: 1.0 / 15.0,
                disturbance_ut: (10.0, 40.0),
                disturbance_s: (2.0, 6.0),
                gps_horizontal: 30.0 / h68,
                gps_vertical: 45.0,
                gps_tau_s: 30.0,
                gps_reported: (30.0, 45.0),
            },
        }
    }
}

/// A magnetic disturbance: a field added in the world frame, ramped in and out over 0.3 s
/// (raised cosine) or a third of the duration if that is shorter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disturbance {
    pub start: f64,
    pub duration: f64,
    pub field_enu_ut: DVec3,
}

impl Disturbance {
    fn at(&self, t: f64) -> DVec3 {
        let u = t - self.start;
        if u <= 0.0 || u >= self.duration {
            return DVec3::ZERO;
        }
        let ramp = 0.3f64.min(self.duration / 3.0);
        let w = if u < ramp {
            0.5 - 0.5 * (std::f64::consts::PI * u / ramp).cos()
        } else if u > self.duration - ramp {
            0.5 - 0.5 * (std::f64::consts::PI * (self.duration - u) / ramp).cos()
        } else {
            1.0
        };
        self.field_enu_ut * w
    }
}

/// Where and when the simulated phone is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSite {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
    pub date: chrono::NaiveDate,
}

impl Default for SimSite {
    /// Bristol, UK (where seed 000's app was tried), on the project's reference date.
    fn default() -> Self {
        SimSite { lat_deg: 51.4545, lon_deg: -2.5879, alt_m: 20.0, date: chrono::NaiveDate::from_ymd_opt(2026, 11, 21).unwrap_or_default() }
    }
}

/// Simulation settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    pub noise: NoiseModel,
    pub seed: u64,
    /// How the app's display is rotated (the virtual phone is landscape: R90).
    pub rotation: DisplayRotation,
    pub accel_hz: f64,
    pub gyro_hz: f64,
    pub mag_hz: f64,
    pub gps_hz: f64,
    pub site: SimSite,
    /// Distance of the phone from the point it turns about (m); 0 = pure rotation.
    pub lever_arm_m: f64,
    /// Disturbances at given times, in addition to the noise model's random ones.
    pub disturbances: Vec<Disturbance>,
}

impl SimConfig {
    pub fn new(level: NoiseLevel, seed: u64) -> Self {
        SimConfig {
            noise: NoiseModel::for_level(level),
            seed,
            rotation: DisplayRotation::R90,
            accel_hz: 100.0,
            gyro_hz: 100.0,
            mag_hz: 50.0,
            gps_hz: 1.0,
            site: SimSite::default(),
            lever_arm_m: if level == NoiseLevel::None { 0.0 } else { 0.3 },
            disturbances: Vec::new(),
        }
    }
}

/// Mean Earth radius (m, IUGG) for turning GPS errors in metres into degrees.
const EARTH_RADIUS_M: f64 = 6_371_008.8;

#[derive(Clone, Debug)]
struct Stream {
    rng: ChaCha8Rng,
    period: f64,
    next: u64,
}

impl Stream {
    fn new(seed: u64, id: u64, hz: f64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(id);
        Stream { rng, period: 1.0 / hz, next: 0 }
    }

    fn gauss(&mut self) -> f64 {
        self.rng.sample::<f64, _>(StandardNormal)
    }

    fn gauss3(&mut self) -> DVec3 {
        DVec3::new(self.gauss(), self.gauss(), self.gauss())
    }
}

/// The simulated sensors following a truth trace.
#[derive(Clone, Debug)]
pub struct SimSensors {
    cfg: SimConfig,
    level: Option<NoiseLevel>,
    truth: TruthTrace,
    field: MagneticReference,
    disturbances: Vec<Disturbance>,
    accel: Stream,
    gyro: Stream,
    mag: Stream,
    gps: Stream,
    gyro_bias: DVec3,
    accel_bias: DVec3,
    hard_iron: DVec3,
    gps_error: DVec3,
    pending: Vec<Reading>,
}

impl SimSensors {
    /// Sensors for a noise level preset.
    pub fn new(truth: TruthTrace, level: NoiseLevel, seed: u64) -> Result<Self> {
        let mut s = Self::with_config(truth, SimConfig::new(level, seed))?;
        s.level = Some(level);
        Ok(s)
    }

    pub fn with_config(truth: TruthTrace, cfg: SimConfig) -> Result<Self> {
        let rates = [cfg.accel_hz, cfg.gyro_hz, cfg.mag_hz, cfg.gps_hz];
        if rates.iter().any(|r| !r.is_finite() || *r <= 0.0) {
            bail!("sensor rates must be positive, got {rates:?}");
        }
        if !cfg.lever_arm_m.is_finite() || cfg.lever_arm_m < 0.0 {
            bail!("lever arm must be a non-negative length, got {}", cfg.lever_arm_m);
        }
        let site = cfg.site;
        let field = MagneticReference::wmm(site.lat_deg, site.lon_deg, site.alt_m, site.date)?;
        let n = cfg.noise;
        let mut setup = Stream::new(cfg.seed, 0, 1.0);
        let gyro_bias = setup.gauss3() * n.gyro_bias;
        let accel_bias = setup.gauss3() * n.accel_bias;
        let hard_iron = setup.gauss3() * n.hard_iron;
        let gps_error = DVec3::new(setup.gauss() * n.gps_horizontal, setup.gauss() * n.gps_horizontal, setup.gauss() * n.gps_vertical);
        let mut disturbances = cfg.disturbances.clone();
        if n.disturbance_rate > 0.0 {
            let mut t = truth.start();
            loop {
                let u: f64 = setup.rng.random_range(f64::EPSILON..1.0);
                t += -u.ln() / n.disturbance_rate;
                if t >= truth.end() {
                    break;
                }
                let dir = setup.gauss3().normalize_or(DVec3::X);
                let mag = setup.rng.random_range(n.disturbance_ut.0..=n.disturbance_ut.1);
                let duration = setup.rng.random_range(n.disturbance_s.0..=n.disturbance_s.1);
                disturbances.push(Disturbance { start: t, duration, field_enu_ut: dir * mag });
            }
        }
        Ok(SimSensors {
            accel: Stream::new(cfg.seed, 1, cfg.accel_hz),
            gyro: Stream::new(cfg.seed, 2, cfg.gyro_hz),
            mag: Stream::new(cfg.seed, 3, cfg.mag_hz),
            gps: Stream::new(cfg.seed, 4, cfg.gps_hz),
            cfg,
            level: None,
            truth,
            field,
            disturbances,
            gyro_bias,
            accel_bias,
            hard_iron,
            gps_error,
            pending: Vec::new(),
        })
    }

    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// The field the magnetometer sees without disturbances (the model at the site).
    pub fn magnetic_reference(&self) -> MagneticReference {
        self.field
    }

    /// The magnetometer's hard-iron offset in this run (µT, device frame).
    pub fn hard_iron(&self) -> DVec3 {
        self.hard_iron
    }

    /// All disturbances of this run (given and random).
    pub fn disturbances(&self) -> &[Disturbance] {
        &self.disturbances
    }

    /// The true camera pose (camera → ENU) at `t`.
    pub fn true_camera_pose(&self, t: f64) -> DQuat {
        self.truth.orientation_at(t)
    }

    /// The true device orientation (device → ENU) at `t`.
    pub fn true_device_orientation(&self, t: f64) -> DQuat {
        device_from_camera_pose(self.truth.orientation_at(t), self.cfg.rotation)
    }

    /// Time of the last reading the simulation will produce.
    pub fn end(&self) -> f64 {
        self.truth.end()
    }

    fn disturbance_at(&self, t: f64) -> DVec3 {
        self.disturbances.iter().map(|d| d.at(t)).sum()
    }

    /// The phone's acceleration in the world (m/s²): it sits `lever_arm_m` in front of the
    /// point it turns about; second central difference over 20 ms.
    fn linear_acceleration(&self, t: f64) -> DVec3 {
        if self.cfg.lever_arm_m == 0.0 {
            return DVec3::ZERO;
        }
        let h = 0.02;
        let p = |t: f64| self.truth.orientation_at(t) * DVec3::new(0.0, 0.0, -self.cfg.lever_arm_m);
        (p(t + h) - 2.0 * p(t) + p(t - h)) / (h * h)
    }

    fn stream_time(&self, s: &Stream) -> f64 {
        self.truth.start() + s.next as f64 * s.period
    }

    fn generate(&mut self, until: f64) {
        let end = self.truth.end().min(until);
        let n = self.cfg.noise;
        let g = super::STANDARD_GRAVITY;
        while self.stream_time(&self.accel) <= end {
            let t = self.stream_time(&self.accel);
            let q = self.true_device_orientation(t);
            let f = self.linear_acceleration(t) + DVec3::new(0.0, 0.0, g);
            let noise = self.accel.gauss3() * n.accel_white;
            self.pending.push(Reading::Accel { t, v: q.inverse() * f + self.accel_bias + noise });
            self.accel.next += 1;
        }
        while self.stream_time(&self.mag) <= end {
            let t = self.stream_time(&self.mag);
            let q = self.true_device_orientation(t);
            let b = self.field.field_enu_ut + self.disturbance_at(t);
            let noise = self.mag.gauss3() * n.mag_white;
            self.pending.push(Reading::Mag { t, v: q.inverse() * b + self.hard_iron + noise });
            self.mag.next += 1;
        }
        while self.stream_time(&self.gps) <= end {
            let t = self.stream_time(&self.gps);
            if self.gps.next > 0 {
                let phi = (-self.gps.period / n.gps_tau_s).exp();
                let k = (1.0 - phi * phi).sqrt();
                let w = self.gps.gauss3();
                let sigma = DVec3::new(n.gps_horizontal, n.gps_horizontal, n.gps_vertical);
                self.gps_error = self.gps_error * phi + w * sigma * k;
            }
            let site = self.cfg.site;
            let e = self.gps_error;
            let lat = site.lat_deg + (e.y / EARTH_RADIUS_M).to_degrees();
            let lon = site.lon_deg + (e.x / (EARTH_RADIUS_M * site.lat_deg.to_radians().cos().max(1e-6))).to_degrees();
            self.pending.push(Reading::Gps(GpsFix {
                t,
                lat_deg: lat,
                lon_deg: lon,
                alt_m: site.alt_m + e.z,
                horizontal_accuracy_m: n.gps_reported.0,
                vertical_accuracy_m: n.gps_reported.1,
            }));
            self.gps.next += 1;
        }
        while self.stream_time(&self.gyro) <= end {
            let t = self.stream_time(&self.gyro);
            let dt = self.gyro.period;
            // The mean body rate over the sample interval (forward for the first sample), so
            // integrating noise-free readings reproduces the path.
            let (ta, tb) = if self.gyro.next == 0 { (t, t + dt) } else { (t - dt, t) };
            let qa = self.true_device_orientation(ta);
            let mut qb = self.true_device_orientation(tb);
            if qa.dot(qb) < 0.0 {
                qb = -qb;
            }
            let omega = (qa.inverse() * qb).to_scaled_axis() / dt;
            if self.gyro.next > 0 {
                let walk = self.gyro.gauss3() * n.gyro_bias_walk * dt.sqrt();
                self.gyro_bias += walk;
            }
            let noise = self.gyro.gauss3() * n.gyro_white;
            self.pending.push(Reading::Gyro { t, v: omega + self.gyro_bias + noise });
            self.gyro.next += 1;
        }
        // Time order; at equal times accelerometer, magnetometer and GPS before the gyroscope,
        // so a filter stepping on gyroscope readings sees the other readings of that instant.
        let rank = |r: &Reading| match r {
            Reading::Accel { .. } => 0,
            Reading::Mag { .. } => 1,
            Reading::Gps(_) => 2,
            Reading::Attitude { .. } => 3,
            Reading::Gyro { .. } => 4,
        };
        self.pending.sort_by(|a, b| a.t().total_cmp(&b.t()).then(rank(a).cmp(&rank(b))));
    }
}

impl SensorSource for SimSensors {
    fn poll(&mut self, until: f64, out: &mut Vec<Reading>) -> Result<()> {
        if until.is_nan() {
            bail!("sim sensors: poll time is NaN");
        }
        self.generate(until);
        out.append(&mut self.pending);
        Ok(())
    }

    fn describe(&self) -> String {
        let level = self.level.map_or("custom", NoiseLevel::name);
        format!("sim ({level} noise, seed {}, display rotation {}°)", self.cfg.seed, self.cfg.rotation.degrees())
    }

    fn display_rotation(&mut self) -> Option<DisplayRotation> {
        Some(self.cfg.rotation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::{angle_between, from_heading_pitch_roll};
    use crate::pose::trace::TruthSample;

    fn spin_trace(secs: f64) -> TruthTrace {
        let n = (secs * 100.0) as usize;
        TruthTrace::new(
            (0..=n)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    TruthSample { t, q: from_heading_pitch_roll(0.8 * t, 0.3 * (1.3 * t).sin(), 0.1 * t), tap: false }
                })
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn noiseless_readings_match_the_truth() {
        let mut s = SimSensors::new(spin_trace(3.0), NoiseLevel::None, 1).unwrap();
        let field = s.magnetic_reference().field_enu_ut;
        let mut out = Vec::new();
        s.poll(f64::INFINITY, &mut out).unwrap();
        let mut q = s.true_device_orientation(0.0);
        let mut last_gyro_t = None;
        for r in &out {
            match *r {
                Reading::Accel { t, v } => {
                    let q = s.true_device_orientation(t);
                    assert!((q * v - DVec3::new(0.0, 0.0, 9.80665)).length() < 1e-9);
                }
                Reading::Mag { t, v } => {
                    assert!((s.true_device_orientation(t) * v - field).length() < 1e-9);
                }
                Reading::Gyro { t, v } => {
                    // Integrating the rates reproduces the true path.
                    if let Some(t0) = last_gyro_t {
                        q = (q * DQuat::from_scaled_axis(v * (t - t0))).normalize();
                        assert!(angle_between(q, s.true_device_orientation(t)) < 1e-9, "t={t}");
                    }
                    last_gyro_t = Some(t);
                }
                Reading::Gps(f) => {
                    assert_eq!((f.lat_deg, f.lon_deg), (51.4545, -2.5879));
                }
                Reading::Attitude { .. } => unreachable!(),
            }
        }
        assert_eq!(out.iter().filter(|r| matches!(r, Reading::Gyro { .. })).count(), 301);
        assert_eq!(out.iter().filter(|r| matches!(r, Reading::Mag { .. })).count(), 151);
        assert_eq!(out.iter().filter(|r| matches!(r, Reading::Gps(_))).count(), 4);
    }

    #[test]
    fn deterministic_and_independent_of_poll_steps() {
        let mut a = SimSensors::new(spin_trace(4.0), NoiseLevel::Phone, 42).unwrap();
        let mut b = SimSensors::new(spin_trace(4.0), NoiseLevel::Phone, 42).unwrap();
        let mut ra = Vec::new();
        a.poll(f64::INFINITY, &mut ra).unwrap();
        let mut rb = Vec::new();
        let mut t = 0.0;
        while t < 5.0 {
            t += 0.037;
            b.poll(t, &mut rb).unwrap();
        }
        assert_eq!(ra, rb);
        assert!(ra.windows(2).all(|w| w[0].t() <= w[1].t()));
        let mut c = SimSensors::new(spin_trace(4.0), NoiseLevel::Phone, 43).unwrap();
        let mut rc = Vec::new();
        c.poll(f64::INFINITY, &mut rc).unwrap();
        assert_ne!(ra, rc);
        assert!(a.poll(f64::NAN, &mut rc).is_err());
    }

    /// Statistics of the noise match the model (here with a still phone).
    #[test]
    fn noise_statistics_match_the_model() {
        let still = TruthTrace::new(vec![
            TruthSample { t: 0.0, q: DQuat::IDENTITY, tap: false },
            TruthSample { t: 600.0, q: DQuat::IDENTITY, tap: false },
        ])
        .unwrap();
        let mut cfg = SimConfig::new(NoiseLevel::Phone, 5);
        cfg.noise.disturbance_rate = 0.0;
        cfg.noise.gyro_bias_walk = 0.0;
        let n = cfg.noise;
        let mut s = SimSensors::with_config(still, cfg).unwrap();
        let mut out = Vec::new();
        s.poll(f64::INFINITY, &mut out).unwrap();
        let gyro: Vec<DVec3> = out.iter().filter_map(|r| if let Reading::Gyro { v, .. } = r { Some(*v) } else { None }).collect();
        let mean = gyro.iter().sum::<DVec3>() / gyro.len() as f64;
        let var = gyro.iter().map(|v| (*v - mean) * (*v - mean)).sum::<DVec3>() / gyro.len() as f64;
        // 60,000 samples: the standard deviation is within 2 % of the model's.
        for k in 0..3 {
            assert!((var[k].sqrt() / n.gyro_white - 1.0).abs() < 0.02, "{var:?}");
        }
        // GPS error: Gauss–Markov with σ_h per axis; over 600 s (20 τ) the spread is near σ.
        let fixes: Vec<GpsFix> = out.iter().filter_map(|r| if let Reading::Gps(f) = r { Some(*f) } else { None }).collect();
        let north: Vec<f64> = fixes.iter().map(|f| (f.lat_deg - 51.4545).to_radians() * EARTH_RADIUS_M).collect();
        let rms = (north.iter().map(|x| x * x).sum::<f64>() / north.len() as f64).sqrt();
        assert!(rms > 0.4 * n.gps_horizontal && rms < 2.0 * n.gps_horizontal, "north rms {rms}");
        assert!(fixes.iter().all(|f| f.horizontal_accuracy_m == 10.0 && f.vertical_accuracy_m == 15.0));
    }

    #[test]
    fn disturbances_add_a_ramped_world_field() {
        let d = Disturbance { start: 1.0, duration: 2.0, field_enu_ut: DVec3::new(20.0, 0.0, 0.0) };
        assert_eq!(d.at(0.9), DVec3::ZERO);
        assert!((d.at(1.15).x - 10.0).abs() < 1e-9);
        assert_eq!(d.at(2.0), DVec3::new(20.0, 0.0, 0.0));
        assert_eq!(d.at(3.1), DVec3::ZERO);
        let mut cfg = SimConfig::new(NoiseLevel::None, 0);
        cfg.disturbances.push(d);
        let mut s = SimSensors::with_config(spin_trace(3.0), cfg).unwrap();
        let field = s.magnetic_reference().field_enu_ut;
        let mut out = Vec::new();
        s.poll(f64::INFINITY, &mut out).unwrap();
        for r in out {
            if let Reading::Mag { t, v } = r {
                let world = s.true_device_orientation(t) * v;
                assert!((world - field - d.at(t)).length() < 1e-9);
            }
        }
    }
}
