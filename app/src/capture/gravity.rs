//! The capture's vertical from the accelerometer held at every shot.
//!
//! The overlaps fix the shots' orientations relative to each other ([`super::align`]); nothing
//! in the images says where level is. The fusion filter's tilt at a shot errs by a few tenths of
//! a degree — mostly the phone's own acceleration in the turn before it (the phone swings on a
//! lever arm in front of the pivot), low-passed over the filter's 2 s — and the mean of a
//! handful of such errors is the whole cube's tilt (0.1–0.45° on the six-face paths).
//!
//! Here each shot keeps the accelerometer of the last [`WINDOW_S`] before it ([`GravityLog`]):
//! every reading turned into the shot's frame by the gyroscope and averaged. For a phone turning
//! about a pivot at `−r` from the camera (camera frame), the mean of its own acceleration over a
//! window `[t₀, t₁]` is exactly the change of its velocity, `(Q₁(ω₁×r) − Q₀(ω₀×r)) / (t₁ − t₀)`
//! (`ω` the gyroscope's rates at the ends, `Q` the turns to the shot's frame), which is linear
//! in `r`: the window needs no steady phase, only its two ends. Then, over all shots with their
//! aligned orientations `R_k` ([`level`]): `R_k m_k = g ẑ + g γ×ẑ + R_k (b + D_k r + E_k c) + δg ẑ`,
//! with the capture's common tilt `γ`, a phone-fixed accelerometer bias `b`, the lever arm `r`, the
//! gyroscope's bias `c` not yet learnt (it turns the window's earlier readings by its rate times
//! their age; `E_k` the first-order change of the mean) and a gravity magnitude error `δg`
//! unknown — linear least squares with weak priors on `b`, `r` and `c`. The shots' attitudes
//! differ, so what is fixed in the phone separates from a tilt fixed in the world. Measured on
//! the simulator's captures in docs/capture.md ("Alignment from the images").

use crate::pose::frames::{DisplayRotation, camera_to_device};
use crate::sensors::{Reading, STANDARD_GRAVITY};
use glam::{DMat3, DQuat, DVec3, Quat};
use std::collections::VecDeque;

/// How long before each shot the accelerometer is averaged (s).
pub const WINDOW_S: f64 = 1.0;
/// A window must span at least this share of [`WINDOW_S`] to count.
const MIN_SPAN: f64 = 0.5;
/// A gap between gyroscope readings longer than this (s) restarts the log.
const MAX_GAP_S: f64 = 0.1;
/// Priors of the fit (1σ): per-shot noise of a held mean (m/s²), the accelerometer's bias
/// (m/s², a phone's after calibration is a few hundredths) and the lever arm (m).
const NOISE_SIGMA: f64 = 0.02;
const BIAS_SIGMA: f64 = 0.05;
const LEVER_SIGMA_M: f64 = 0.5;
/// ... and the gyroscope's bias not yet learnt (degrees/s).
const GYRO_BIAS_SIGMA: f64 = 0.3;
/// Fewest shots with held gravity for the fit; and the largest tilt it may correct (degrees:
/// more than the filter's tilt can be off means the model does not hold).
const MIN_SHOTS: usize = 3;
const MAX_CORRECTION_DEG: f64 = 2.0;

/// The accelerometer held over the window before one shot, in the camera frame at the shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldGravity {
    /// Mean specific force (m/s²): up times g, plus the bias and the phone's own acceleration.
    pub accel: DVec3,
    /// The phone's mean own acceleration is `lever · r` for a camera at `r` from its pivot.
    pub lever: DMat3,
    /// The mean errs by `gyro · c` for a gyroscope bias `c` (rad/s): the readings are turned
    /// into the shot's frame by the gyroscope, so a bias turns each by its rate times its age.
    pub gyro: DMat3,
}

/// The last [`WINDOW_S`] of accelerometer and gyroscope readings, turned into one frame by the
/// gyroscope. Feed every reading ([`GravityLog::update`]); ask [`GravityLog::held`] at a shot.
#[derive(Clone, Debug)]
pub struct GravityLog {
    camera_to_device: DQuat,
    /// Device frame at the last gyroscope reading → the log's frame.
    q: DQuat,
    /// Gyroscope readings: time, attitude then, rate (rad/s, device frame; the mean rate over
    /// the interval ending at the reading, as Android's and the simulator's readings are).
    gyro: VecDeque<(f64, DQuat, DVec3)>,
    /// Accelerometer readings: time, specific force (device frame).
    accel: VecDeque<(f64, DVec3)>,
}

fn cross_matrix(v: DVec3) -> DMat3 {
    DMat3::from_cols(DVec3::new(0.0, v.z, -v.y), DVec3::new(-v.z, 0.0, v.x), DVec3::new(v.y, -v.x, 0.0))
}

impl GravityLog {
    pub fn new(rotation: DisplayRotation) -> Self {
        GravityLog { camera_to_device: camera_to_device(rotation), q: DQuat::IDENTITY, gyro: VecDeque::new(), accel: VecDeque::new() }
    }

    /// The attitude (device → log frame) at time `t` and the rate then: within the interval
    /// between two gyroscope readings, turned at the later one's rate; past the last, at its.
    fn attitude_at(&self, t: f64) -> Option<(DQuat, DVec3)> {
        let i = self.gyro.partition_point(|g| g.0 < t);
        if i == 0 || i == self.gyro.len() {
            let (tg, q, w) = if i == 0 { *self.gyro.front()? } else { *self.gyro.back()? };
            return Some(((q * DQuat::from_scaled_axis(w * (t - tg))).normalize(), w));
        }
        let ((t0, q0, _), (_, _, w)) = (self.gyro[i - 1], self.gyro[i]);
        Some(((q0 * DQuat::from_scaled_axis(w * (t - t0))).normalize(), w))
    }

    pub fn update(&mut self, r: &Reading) {
        match *r {
            Reading::Gyro { t, v } => {
                if let Some(&(t0, _, _)) = self.gyro.back() {
                    let dt = t - t0;
                    if !(0.0..=MAX_GAP_S).contains(&dt) {
                        self.gyro.clear();
                        self.accel.clear();
                    } else {
                        self.q = (self.q * DQuat::from_scaled_axis(v * dt)).normalize();
                    }
                }
                self.gyro.push_back((t, self.q, v));
                while self.gyro.front().is_some_and(|g| g.0 < t - 2.0 * WINDOW_S) {
                    self.gyro.pop_front();
                }
            }
            Reading::Accel { t, v } => {
                if !self.gyro.is_empty() {
                    self.accel.push_back((t, v));
                }
                while self.accel.front().is_some_and(|a| a.0 < t - 2.0 * WINDOW_S) {
                    self.accel.pop_front();
                }
            }
            _ => {}
        }
    }

    /// The accelerometer held over the [`WINDOW_S`] before `t`, or `None` when the log holds
    /// too little of it (just started, or a gap in the readings).
    pub fn held(&self, t: f64) -> Option<HeldGravity> {
        let inside: Vec<&(f64, DVec3)> = self.accel.iter().filter(|a| a.0 > t - WINDOW_S && a.0 <= t).collect();
        let (first, last) = (inside.first()?.0, inside.last()?.0);
        if inside.len() < 3 || last - first < MIN_SPAN * WINDOW_S {
            return None;
        }
        // The readings sample the window [first − dt/2, last + dt/2].
        let dt = (last - first) / (inside.len() - 1) as f64;
        let (t0, t1) = (first - 0.5 * dt, last + 0.5 * dt);
        let (qt, _) = self.attitude_at(t)?;
        let to_t = qt.inverse();
        let turned: Vec<(DMat3, DVec3)> = inside
            .iter()
            .filter_map(|(ti, v)| {
                let m = DMat3::from_quat(to_t * self.attitude_at(*ti)?.0);
                Some((m, m * *v))
            })
            .collect();
        let n = turned.len() as f64;
        let mean = turned.iter().fold(DVec3::ZERO, |s, (_, a)| s + *a) / n;
        let end = |tt: f64| self.attitude_at(tt).map(|(q, w)| DMat3::from_quat(to_t * q) * cross_matrix(w));
        let lever_device = (end(t1)? - end(t0)?) * (1.0 / (t1 - t0));
        // A gyroscope bias c turns the frame at t against the one at reading i by ∫ Q_s c ds
        // over (t_i, t]: the reading moves by (Q_i a_i) × that, to first order.
        let (mut since, mut gyro_device) = (DMat3::IDENTITY * (t - last), DMat3::ZERO);
        for (m, a) in turned.iter().rev() {
            gyro_device += cross_matrix(*a) * since;
            since += *m * dt;
        }
        // Device → camera frame.
        let c = DMat3::from_quat(self.camera_to_device);
        let ct = c.transpose();
        Some(HeldGravity { accel: ct * mean, lever: ct * lever_device * c, gyro: ct * (gyro_device * (1.0 / n)) * c })
    }
}

/// What [`level`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leveling {
    /// World-frame rotation that takes the shots' common tilt off (apply on the left).
    pub correction: Quat,
    /// Shots whose held gravity was used.
    pub shots: usize,
    /// The fitted accelerometer bias (m/s²), lever arm (m) and gyroscope bias (rad/s), camera
    /// frame.
    pub bias: DVec3,
    pub lever_m: DVec3,
    pub gyro_bias: DVec3,
}

impl Leveling {
    /// Size of the correction (degrees).
    pub fn angle_deg(&self) -> f64 {
        f64::from(self.correction.angle_between(Quat::IDENTITY).to_degrees())
    }
}

/// The common tilt of shots at orientations `poses` (camera → world, aligned to each other)
/// from their held gravity (see the module documentation). `None` with fewer than three shots
/// with gravity, or when the fit asks for more than a plausible tilt.
pub fn level(poses: &[Quat], held: &[Option<HeldGravity>]) -> Option<Leveling> {
    let g = STANDARD_GRAVITY;
    // Unknowns: γx, γy, b (3), r (3), δg, c (3).
    const N: usize = 12;
    let mut h = vec![vec![0.0f64; N]; N];
    let mut rhs = vec![0.0f64; N];
    let mut shots = 0;
    for (pose, held) in poses.iter().zip(held) {
        let Some(held) = held else { continue };
        shots += 1;
        let r = DMat3::from_quat(pose.as_dquat());
        let mut y = r * held.accel;
        y.z -= g;
        let rd = r * held.lever;
        let rc = r * held.gyro;
        for row in 0..3 {
            let mut j = [0.0f64; N];
            match row {
                0 => j[1] = g,
                1 => j[0] = -g,
                _ => j[8] = 1.0,
            }
            for c in 0..3 {
                j[2 + c] = r.col(c)[row];
                j[5 + c] = rd.col(c)[row];
                j[9 + c] = rc.col(c)[row];
            }
            for p in 0..N {
                rhs[p] += j[p] * y[row];
                for q in 0..N {
                    h[p][q] += j[p] * j[q];
                }
            }
        }
    }
    if shots < MIN_SHOTS {
        return None;
    }
    for c in 0..3 {
        h[2 + c][2 + c] += (NOISE_SIGMA / BIAS_SIGMA).powi(2);
        h[5 + c][5 + c] += (NOISE_SIGMA / LEVER_SIGMA_M).powi(2);
        h[9 + c][9 + c] += (NOISE_SIGMA / GYRO_BIAS_SIGMA.to_radians()).powi(2);
    }
    let (x, full_rank) = super::dense_solve::solve_dense(h, rhs);
    let gamma = DVec3::new(x[0], x[1], 0.0);
    if !full_rank || !x.iter().all(|v| v.is_finite()) || gamma.length().to_degrees() > MAX_CORRECTION_DEG {
        return None;
    }
    Some(Leveling {
        correction: DQuat::from_scaled_axis(-gamma).as_quat(),
        shots,
        bias: DVec3::new(x[2], x[3], x[4]),
        lever_m: DVec3::new(x[5], x[6], x[7]),
        gyro_bias: DVec3::new(x[9], x[10], x[11]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::from_heading_pitch_roll;

    /// Readings of a phone (landscape, R90) following `orientation(t)` (camera → world) about a
    /// pivot at `−r` from the camera, with an accelerometer bias `b` and a gyroscope bias `c`
    /// (device frame), at 100 Hz.
    fn feed(log: &mut GravityLog, orientation: &dyn Fn(f64) -> DQuat, r: DVec3, (b, c): (DVec3, DVec3), from: f64, to: f64) {
        let to_device = camera_to_device(DisplayRotation::R90);
        let device = |t: f64| orientation(t) * to_device.inverse();
        let g = STANDARD_GRAVITY;
        let n = ((to - from) * 100.0).round() as usize;
        for k in 0..=n {
            let t = from + k as f64 / 100.0;
            let h = 1e-4;
            // Position of the camera and its second derivative (central differences).
            let p = |t: f64| orientation(t) * r;
            let acc = (p(t + h) - 2.0 * p(t) + p(t - h)) / (h * h);
            log.update(&Reading::Accel { t, v: device(t).inverse() * (acc + DVec3::Z * g) + b });
            // The mean body rate over the interval ending at the reading.
            let dq = device(t - 0.01).inverse() * device(t);
            log.update(&Reading::Gyro { t, v: dq.to_scaled_axis() / 0.01 + c });
        }
    }

    #[test]
    fn held_gravity_of_a_still_phone_is_up_in_the_camera_frame() {
        // Camera pitched up 30°, rolled 10°: up in the camera frame is the world's ẑ turned back.
        let pose = from_heading_pitch_roll(0.4, 30f64.to_radians(), 10f64.to_radians());
        let mut log = GravityLog::new(DisplayRotation::R90);
        feed(&mut log, &|_| pose, DVec3::ZERO, (DVec3::ZERO, DVec3::ZERO), 0.0, 1.5);
        let held = log.held(1.5).unwrap();
        let want = pose.inverse() * DVec3::Z * STANDARD_GRAVITY;
        assert!((held.accel - want).length() < 1e-6, "{:?} vs {want:?}", held.accel);
        // A gyroscope bias of 0.2°/s turns the earlier readings of the window (by up to 0.2°):
        // the mean moves by ~0.1° of g, as the `gyro` term predicts.
        let c = DVec3::new(0.2, -0.1, 0.1).normalize() * 0.2f64.to_radians();
        let mut biased = GravityLog::new(DisplayRotation::R90);
        feed(&mut biased, &|_| pose, DVec3::ZERO, (DVec3::ZERO, c), 0.0, 1.5);
        let held = biased.held(1.5).unwrap();
        let c_cam = camera_to_device(DisplayRotation::R90).inverse() * c;
        assert!((held.accel - want).length() > 0.01, "{:?}", held.accel - want);
        assert!((held.accel - want - held.gyro * c_cam).length() < 2e-4, "{:?}", held.accel - want - held.gyro * c_cam);
        // Not enough readings yet.
        let mut fresh = GravityLog::new(DisplayRotation::R90);
        feed(&mut fresh, &|_| pose, DVec3::ZERO, (DVec3::ZERO, DVec3::ZERO), 0.0, 0.3);
        assert!(fresh.held(0.3).is_none());
    }

    #[test]
    fn a_turning_phone_on_a_lever_arm_is_predicted_by_the_velocity_change() {
        // A turn of 40° in heading, under way when the window opens and ending 0.4 s before the
        // shot, the camera 0.3 m in front of the pivot: the window's mean specific force is
        // gravity plus the lever term, D·r (the turn's velocity at the window's start).
        let turn = |t: f64| {
            let s = ((t + 0.3) / 0.9).clamp(0.0, 1.0);
            let s = s * s * (3.0 - 2.0 * s);
            from_heading_pitch_roll(0.7 * s, 0.1, 0.0)
        };
        let r = DVec3::new(0.0, 0.0, -0.3);
        let mut log = GravityLog::new(DisplayRotation::R90);
        feed(&mut log, &turn, r, (DVec3::ZERO, DVec3::ZERO), -0.5, 1.0);
        let held = log.held(1.0).unwrap();
        let up = turn(1.0).inverse() * DVec3::Z * STANDARD_GRAVITY;
        let predicted = up + held.lever * r;
        // Without the lever term the mean is off by the turn's velocity change.
        assert!((held.accel - up).length() > 0.05, "{:?}", held.accel - up);
        assert!((held.accel - predicted).length() < 0.01, "{:?}", held.accel - predicted);
    }

    #[test]
    fn a_common_tilt_is_found_apart_from_a_phone_fixed_bias_and_the_lever_arm() {
        // Six shots at the six face centres (and a seventh between), each after a turn, the
        // accelerometer biased by 0.04 m/s² per axis, the gyroscope by ~0.15°/s; the poses as
        // "aligned" share a common tilt of 0.3° about a horizontal axis.
        let aims = [(0.0, 0.0), (90.0, 0.0), (180.0, 0.0), (270.0, 0.0), (0.0, 89.0), (0.0, -89.0), (45.0, 40.0)];
        let r = DVec3::new(0.01, -0.02, -0.35);
        let b = DVec3::new(0.04, -0.04, 0.04);
        let c = DVec3::new(0.1, -0.08, 0.06f64).to_array().map(f64::to_radians);
        let c = DVec3::from_array(c);
        let common = DQuat::from_scaled_axis(DVec3::new(0.2, -0.22, 0.0).normalize() * 0.3f64.to_radians());
        let (mut poses, mut held) = (Vec::new(), Vec::new());
        for (k, &(h, p)) in aims.iter().enumerate() {
            let (h, p): (f64, f64) = (h, p);
            let from = from_heading_pitch_roll((h - 30.0 - 5.0 * k as f64).to_radians(), (p * 0.8).to_radians(), 0.0);
            let to = from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.02);
            let path = |t: f64| {
                let s = ((t + 0.2) / (0.8 + 0.05 * k as f64)).clamp(0.0, 1.0);
                from.slerp(to, s * s * (3.0 - 2.0 * s))
            };
            let mut log = GravityLog::new(DisplayRotation::R90);
            feed(&mut log, &path, r, (b, c), -0.5, 1.0);
            held.push(log.held(1.0));
            poses.push((common * to).as_quat());
        }
        assert!(held.iter().all(Option::is_some));
        let l = level(&poses, &held).unwrap();
        let residual = (l.correction.as_dquat() * common).angle_between(DQuat::IDENTITY).to_degrees();
        eprintln!("{l:?}: residual {residual:.4}°");
        assert_eq!(l.shots, 7);
        assert!(residual < 0.01, "{residual}");
        // The bias and the lever arm come back too, roughly (the bias in the camera frame; the
        // fit's priors and the gyroscope bias trade off with them: measured 0.012 m/s² and
        // 0.02 m off). The tilt is what the fit is for.
        let b_cam = camera_to_device(DisplayRotation::R90).inverse() * b;
        assert!((l.bias - b_cam).length() < 0.02, "{:?} vs {b_cam:?}", l.bias);
        assert!((l.lever_m - r).length() < 0.03, "{:?}", l.lever_m);
        // Fewer than three shots, or a tilt beyond what the filter's can be off (3°): no fit.
        assert!(level(&poses[..2], &held[..2]).is_none());
        let far = Quat::from_rotation_x(3f32.to_radians());
        assert!(level(&poses.iter().map(|p| far * *p).collect::<Vec<_>>(), &held).is_none());
    }
}
