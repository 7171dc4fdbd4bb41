//! Plausible paths of a person capturing a cube map: they aim at the front and tap, then turn
//! to the other five faces, holding each for a moment.
//!
//! The motion model, seeded and deterministic:
//! - each aim change is a minimum-jerk movement (Flash & Hogan 1985: position follows
//!   10s³ − 15s⁴ + 6s⁵), at a speed drawn around `mean_speed_deg_s` plus a reaction time;
//! - the movement over- or undershoots by a few percent and a short corrective movement
//!   follows (the primary + corrective submovements of Meyer et al. 1988);
//! - the held aim is off the exact target by up to `aim_error_deg` per axis and the roll is
//!   never quite level;
//! - the hand adds physiological tremor (8–12 Hz, Elble & Koller 1990) and a slow sway
//!   (0.2–0.8 Hz), as small rotations about the camera axes.
//!
//! Heading, pitch and roll parameterise the *truth* path (people turn and tilt); the output is
//! a quaternion per sample like any trace.

use super::frames::{from_heading_pitch_roll, heading_difference_deg};
use super::trace::TruthSample;
use anyhow::{Result, bail};
use glam::{DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The six cube faces as seen from the user's first (front) aim: the capture's faces.
pub use crate::capture::targets::Face as Target;

/// Heading offset from the front and pitch (degrees) a user aims at for a face: the face
/// centre, except that up and down are aimed at `vertical_pitch_deg` (people rarely tilt a
/// phone all the way to the vertical).
pub fn aim_heading_pitch_deg(face: Target, vertical_pitch_deg: f64) -> (f64, f64) {
    let (dh, p) = face.aim_deg();
    (dh, if p == 0.0 { 0.0 } else { vertical_pitch_deg.copysign(p) })
}

/// Orders in which people naturally go round after the front face.
const NATURAL_ORDERS: [[Target; 5]; 4] = [
    [Target::Right, Target::Back, Target::Left, Target::Up, Target::Down],
    [Target::Up, Target::Down, Target::Right, Target::Back, Target::Left],
    [Target::Left, Target::Back, Target::Right, Target::Up, Target::Down],
    [Target::Right, Target::Back, Target::Left, Target::Down, Target::Up],
];

/// Parameters of the simulated user.
#[derive(Clone, Debug, PartialEq)]
pub struct UserPathParams {
    /// Samples per second of the output trace.
    pub rate_hz: f64,
    /// Heading of the front face (degrees); `None` draws it uniformly.
    pub reference_heading_deg: Option<f64>,
    /// Pitch of the up/down face centres (degrees, 90 = straight up/down).
    pub vertical_pitch_deg: f64,
    /// Largest error of a held aim per axis (degrees).
    pub aim_error_deg: f64,
    /// Largest |roll| of a held aim (degrees).
    pub roll_deg: f64,
    /// How long each face is held (seconds, drawn uniformly).
    pub hold_s: (f64, f64),
    /// Average angular speed of a movement (degrees/s).
    pub mean_speed_deg_s: f64,
    /// Over-/undershoot of a movement as a fraction of it (negative = undershoot).
    pub overshoot: (f64, f64),
    /// Tremor amplitude per axis (degrees) at 8–12 Hz.
    pub tremor_deg: f64,
    /// Sway amplitude per axis (degrees) at 0.2–0.8 Hz.
    pub sway_deg: f64,
    /// Faces after the front, in order; `None` picks one of a few natural orders.
    pub order: Option<Vec<Target>>,
}

impl Default for UserPathParams {
    fn default() -> Self {
        UserPathParams {
            rate_hz: 100.0,
            reference_heading_deg: None,
            vertical_pitch_deg: 90.0,
            aim_error_deg: 0.8,
            roll_deg: 2.0,
            hold_s: (1.2, 2.0),
            mean_speed_deg_s: 80.0,
            overshoot: (-0.04, 0.10),
            // About 1.5°/s RMS angular rate per axis at 10 Hz, typical of a hand-held phone's
            // gyroscope while the user tries to hold still.
            tremor_deg: 0.035,
            sway_deg: 0.25,
            order: None,
        }
    }
}

/// A face held still by the simulated user.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    pub target: Target,
    pub start: f64,
    pub end: f64,
    /// The aim the user holds (camera → ENU, without tremor).
    pub aim: DQuat,
}

/// A generated path: trace samples (one tap, on the front hold) and the holds.
#[derive(Clone, Debug)]
pub struct SimulatedPath {
    pub samples: Vec<TruthSample>,
    pub holds: Vec<Hold>,
    pub reference_heading_deg: f64,
}

/// Heading, pitch, roll in degrees (truth-path parameterisation only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Hpr {
    pub h: f64,
    pub p: f64,
    pub r: f64,
}

impl Hpr {
    pub fn quat(self) -> DQuat {
        from_heading_pitch_roll(self.h.to_radians(), self.p.to_radians(), self.r.to_radians())
    }

    pub fn lerp(a: Hpr, b: Hpr, u: f64) -> Hpr {
        Hpr { h: a.h + (b.h - a.h) * u, p: a.p + (b.p - a.p) * u, r: a.r + (b.r - a.r) * u }
    }
}

/// A stretch of the timeline: a hold (from == to) or a minimum-jerk movement.
#[derive(Clone, Copy, Debug)]
struct Segment {
    t0: f64,
    t1: f64,
    from: Hpr,
    to: Hpr,
}

/// The user's movements in time: holds and minimum-jerk turns, then sampled with the hand's
/// shake. Shared by the six-face path here and the capture assistant's guided user.
pub(crate) struct Timeline {
    segments: Vec<Segment>,
    /// End of the last segment, seconds.
    pub t: f64,
}

impl Timeline {
    /// Start held at `at` for `hold` seconds.
    pub fn start(at: Hpr, hold: f64) -> Timeline {
        Timeline { segments: vec![Segment { t0: 0.0, t1: hold, from: at, to: at }], t: hold }
    }

    /// Turn from `at` to `goal` (heading already unwrapped): a primary movement that over- or
    /// undershoots, then a corrective one when the miss is noticeable.
    pub fn turn(&mut self, rng: &mut ChaCha8Rng, params: &UserPathParams, at: Hpr, goal: Hpr) {
        let angle = super::frames::angle_between(at.quat(), goal.quat()).to_degrees();
        let os = uniform(rng, params.overshoot);
        let primary = Hpr::lerp(at, goal, 1.0 + os);
        let speed = params.mean_speed_deg_s * uniform(rng, (0.8, 1.25));
        let t1 = 0.2 + angle * (1.0 + os).abs() / speed;
        self.segments.push(Segment { t0: self.t, t1: self.t + t1, from: at, to: primary });
        self.t += t1;
        let corr = angle * os.abs();
        if corr > 0.2 {
            let t2 = 0.15 + corr / 30.0;
            self.segments.push(Segment { t0: self.t, t1: self.t + t2, from: primary, to: goal });
            self.t += t2;
        }
    }

    /// Hold `at` for `hold` seconds; returns the hold's (start, end).
    pub fn hold(&mut self, at: Hpr, hold: f64) -> (f64, f64) {
        let start = self.t;
        self.segments.push(Segment { t0: start, t1: start + hold, from: at, to: at });
        self.t += hold;
        (start, self.t)
    }

    /// Samples at `params.rate_hz` with the hand's shake; the tap on the sample nearest `tap_t`.
    pub fn sample(&self, params: &UserPathParams, shake: &HandShake, tap_t: f64) -> Vec<TruthSample> {
        let n = (self.t * params.rate_hz).floor() as usize;
        let tap_index = (tap_t * params.rate_hz).round() as usize;
        let mut samples = Vec::with_capacity(n + 1);
        let mut seg = 0;
        for i in 0..=n {
            let ti = i as f64 / params.rate_hz;
            while seg + 1 < self.segments.len() && ti >= self.segments[seg].t1 {
                seg += 1;
            }
            let s = &self.segments[seg];
            let base = Hpr::lerp(s.from, s.to, minimum_jerk((ti - s.t0) / (s.t1 - s.t0)));
            samples.push(TruthSample { t: ti, q: shake.apply(base.quat(), ti), tap: i == tap_index });
        }
        samples
    }
}

/// The minimum-jerk position profile on [0, 1].
pub fn minimum_jerk(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
}

/// Sum of sinusoids per axis: (frequency Hz, amplitude rad, phase) triples.
#[derive(Clone, Debug)]
struct Wobble {
    terms: Vec<[(f64, f64, f64); 3]>,
}

impl Wobble {
    fn new(rng: &mut ChaCha8Rng, n: usize, f_range: (f64, f64), amplitude_deg: f64) -> Self {
        let a = amplitude_deg.to_radians() / (n as f64).sqrt();
        let terms = (0..n)
            .map(|_| {
                std::array::from_fn(|_| {
                    (rng.random_range(f_range.0..f_range.1), a * rng.random_range(0.5..1.5), rng.random_range(0.0..std::f64::consts::TAU))
                })
            })
            .collect();
        Wobble { terms }
    }

    fn at(&self, t: f64) -> DVec3 {
        let mut v = DVec3::ZERO;
        for axes in &self.terms {
            for (k, (f, a, ph)) in axes.iter().enumerate() {
                v[k] += a * (std::f64::consts::TAU * f * t + ph).sin();
            }
        }
        v
    }
}

/// The hand's involuntary motion: tremor plus sway, as a small rotation in the camera frame.
#[derive(Clone, Debug)]
pub struct HandShake {
    tremor: Wobble,
    sway: Wobble,
}

impl HandShake {
    fn new(rng: &mut ChaCha8Rng, params: &UserPathParams) -> Self {
        HandShake { tremor: Wobble::new(rng, 3, (8.0, 12.0), params.tremor_deg), sway: Wobble::new(rng, 2, (0.2, 0.8), params.sway_deg) }
    }

    /// A hand with the given parameters' tremor and sway, seeded.
    pub fn seeded(seed: u64, params: &UserPathParams) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(1);
        Self::new(&mut rng, params)
    }

    /// Rotation vector (radians, camera frame) of the shake at time `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        self.tremor.at(t) + self.sway.at(t)
    }

    /// A camera pose with the shake applied.
    pub fn apply(&self, pose: DQuat, t: f64) -> DQuat {
        (pose * DQuat::from_scaled_axis(self.at(t))).normalize()
    }
}

fn check_params(p: &UserPathParams) -> Result<()> {
    let finite = [
        p.rate_hz,
        p.vertical_pitch_deg,
        p.aim_error_deg,
        p.roll_deg,
        p.hold_s.0,
        p.hold_s.1,
        p.mean_speed_deg_s,
        p.overshoot.0,
        p.overshoot.1,
        p.tremor_deg,
        p.sway_deg,
    ];
    if finite.iter().any(|v| !v.is_finite()) || p.reference_heading_deg.is_some_and(|h| !h.is_finite()) {
        bail!("user path parameters must be finite: {p:?}");
    }
    if p.rate_hz <= 0.0 || p.mean_speed_deg_s <= 0.0 || p.hold_s.0 <= 0.0 || p.hold_s.1 < p.hold_s.0 || p.overshoot.1 < p.overshoot.0 {
        bail!("user path parameters out of range (rate, speed and holds must be positive, ranges ordered): {p:?}");
    }
    if !(0.0..=90.0).contains(&p.vertical_pitch_deg) {
        bail!("vertical pitch must be within 0..=90 degrees, got {}", p.vertical_pitch_deg);
    }
    if let Some(o) = &p.order
        && (o.contains(&Target::Front) || o.len() != 5 || (0..o.len()).any(|i| o[i + 1..].contains(&o[i])))
    {
        bail!("the face order must list right, back, left, up and down once each, got {o:?}");
    }
    Ok(())
}

pub(crate) fn uniform(rng: &mut ChaCha8Rng, (lo, hi): (f64, f64)) -> f64 {
    if hi > lo { rng.random_range(lo..hi) } else { lo }
}

/// Generate a user path (see the module documentation). Same seed and parameters, same path.
pub fn simulate_user_path(seed: u64, params: &UserPathParams) -> Result<SimulatedPath> {
    check_params(params)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let href = params.reference_heading_deg.unwrap_or_else(|| rng.random_range(0.0..360.0));
    let order: Vec<Target> = match &params.order {
        Some(o) => o.clone(),
        None => NATURAL_ORDERS[rng.random_range(0..NATURAL_ORDERS.len())].to_vec(),
    };
    let e = params.aim_error_deg;
    let aim = |rng: &mut ChaCha8Rng, target: Target| {
        let (dh, p) = aim_heading_pitch_deg(target, params.vertical_pitch_deg);
        let ep = uniform(rng, (-e, e));
        // The user cannot tilt past the vertical: err towards the horizon.
        let p = if p.abs() + ep > 90.0 { p - ep.abs() * p.signum() } else { p + ep };
        Hpr { h: href + dh + uniform(rng, (-e, e)), p, r: uniform(rng, (-params.roll_deg, params.roll_deg)) }
    };

    let mut holds = Vec::new();
    let front = aim(&mut rng, Target::Front);
    let start =
        Hpr { h: front.h + uniform(&mut rng, (-20.0, 20.0)), p: uniform(&mut rng, (-10.0, 10.0)), r: uniform(&mut rng, (-5.0, 5.0)) };
    let mut timeline = Timeline::start(start, 0.4);
    let mut at = start;
    let mut tap_t = 0.0;
    for target in std::iter::once(Target::Front).chain(order) {
        let goal = if target == Target::Front { front } else { aim(&mut rng, target) };
        // Unwrap the heading so the movement takes the short way (a half turn either way).
        let mut dh = heading_difference_deg(goal.h, at.h);
        if (dh.abs() - 180.0).abs() < 1e-9 && rng.random_bool(0.5) {
            dh = -dh;
        }
        let goal = Hpr { h: at.h + dh, ..goal };
        timeline.turn(&mut rng, params, at, goal);
        let hold = uniform(&mut rng, params.hold_s);
        if target == Target::Front {
            tap_t = timeline.t + uniform(&mut rng, (0.3, 0.6)).min(hold * 0.8);
        }
        let (start, end) = timeline.hold(goal, hold);
        holds.push(Hold { target, start, end, aim: goal.quat() });
        at = goal;
    }
    let shake = HandShake::new(&mut rng, params);
    let samples = timeline.sample(params, &shake, tap_t);
    Ok(SimulatedPath { samples, holds, reference_heading_deg: super::frames::wrap_degrees_360(href) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::{angle_between, heading_pitch_roll};

    #[test]
    fn faces_are_aimed_at_their_centres_and_up_down_at_the_vertical_pitch() {
        assert_eq!(aim_heading_pitch_deg(Target::Right, 80.0), (90.0, 0.0));
        assert_eq!(aim_heading_pitch_deg(Target::Left, 80.0), (270.0, 0.0));
        assert_eq!(aim_heading_pitch_deg(Target::Up, 80.0), (0.0, 80.0));
        assert_eq!(aim_heading_pitch_deg(Target::Down, 80.0), (0.0, -80.0));
    }

    #[test]
    fn minimum_jerk_profile_values() {
        // Flash & Hogan: x(τ) = 10τ³ − 15τ⁴ + 6τ⁵; x(0.5) = 0.5, zero speed at both ends.
        assert_eq!(minimum_jerk(0.0), 0.0);
        assert_eq!(minimum_jerk(1.0), 1.0);
        assert!((minimum_jerk(0.5) - 0.5).abs() < 1e-15);
        assert!((minimum_jerk(0.25) - 0.103515625).abs() < 1e-15);
        let h = 1e-6;
        assert!(minimum_jerk(h) / h < 1e-9);
        // Peak speed 1.875 (× average) at the midpoint.
        assert!(((minimum_jerk(0.5 + h) - minimum_jerk(0.5 - h)) / (2.0 * h) - 1.875).abs() < 1e-6);
    }

    #[test]
    fn path_visits_every_face_with_one_tap_and_is_deterministic() {
        let p = UserPathParams::default();
        let a = simulate_user_path(7, &p).unwrap();
        let b = simulate_user_path(7, &p).unwrap();
        assert_eq!(a.samples, b.samples);
        assert_ne!(simulate_user_path(8, &p).unwrap().samples, a.samples);
        assert_eq!(a.samples.iter().filter(|s| s.tap).count(), 1);
        let mut targets: Vec<_> = a.holds.iter().map(|h| h.target.name()).collect();
        targets.sort();
        assert_eq!(targets, ["back", "down", "front", "left", "right", "up"]);
        let trace = crate::pose::trace::TruthTrace::new(a.samples.clone()).unwrap();
        // The tap happens while the front is held.
        let tap = trace.tap_times()[0];
        assert!(tap >= a.holds[0].start && tap <= a.holds[0].end);
        for h in &a.holds {
            // During each hold the camera stays within tremor + sway of the aim, and the aim
            // within the aim error of the face centre.
            let mid = 0.5 * (h.start + h.end);
            assert!(angle_between(trace.orientation_at(mid), h.aim).to_degrees() < 1.0, "{h:?}");
            let (dh, pitch) = aim_heading_pitch_deg(h.target, p.vertical_pitch_deg);
            let hpr = heading_pitch_roll(h.aim);
            assert!((hpr.pitch.to_degrees() - pitch).abs() <= p.aim_error_deg + 1e-9, "{h:?} {hpr:?}");
            if pitch.abs() < 89.0 {
                let dhead = heading_difference_deg(hpr.heading.to_degrees(), a.reference_heading_deg + dh);
                assert!(dhead.abs() <= p.aim_error_deg + 1e-9, "{h:?} {dhead}");
            }
        }
    }

    #[test]
    fn motion_is_human_speed_and_smooth() {
        let a = simulate_user_path(3, &UserPathParams::default()).unwrap();
        let dt = 0.01;
        let mut peak = 0f64;
        let mut still_rates = Vec::new();
        for w in a.samples.windows(2) {
            let rate = angle_between(w[0].q, w[1].q).to_degrees() / dt;
            peak = peak.max(rate);
            let t = w[1].t;
            if a.holds.iter().any(|h| t > h.start + 0.2 && t < h.end) {
                still_rates.push(rate);
            }
        }
        // Head-and-arm turns: peaks of a few hundred degrees per second at most.
        assert!(peak > 60.0 && peak < 400.0, "peak {peak}");
        let rms = (still_rates.iter().map(|r| r * r).sum::<f64>() / still_rates.len() as f64).sqrt();
        // Holding still by hand: a few degrees per second of tremor, not zero, not a turn.
        assert!(rms > 0.3 && rms < 6.0, "still rms {rms}");
    }

    #[test]
    fn reference_heading_near_wrap_and_bad_params() {
        let p = UserPathParams { reference_heading_deg: Some(359.7), ..Default::default() };
        let a = simulate_user_path(1, &p).unwrap();
        assert!((a.reference_heading_deg - 359.7).abs() < 1e-9);
        let hpr = heading_pitch_roll(a.holds[0].aim);
        assert!(heading_difference_deg(hpr.heading.to_degrees(), 359.7).abs() <= 0.8 + 1e-9);
        assert!(simulate_user_path(1, &UserPathParams { rate_hz: 0.0, ..Default::default() }).is_err());
        assert!(simulate_user_path(1, &UserPathParams { tremor_deg: f64::NAN, ..Default::default() }).is_err());
        assert!(simulate_user_path(1, &UserPathParams { order: Some(vec![Target::Up; 5]), ..Default::default() }).is_err());
    }
}
