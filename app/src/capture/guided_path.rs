//! A simulated user following the assistant through any list of targets (the six faces, or
//! the stitch mode's extra aims): aim at the front and tap, then turn to the next target of
//! the list (the plan's tour, [`super::targets::short_tour`]) — what the on-screen guidance
//! points at — hold it, and so on.
//!
//! The motion model is the one of [`crate::pose::hand_motion`] (minimum-jerk turns with an
//! over/undershoot and a corrective movement, held aims off the target by up to
//! `aim_error_deg` per axis, a slight roll, hand tremor and sway), generalised from the six
//! fixed faces to arbitrary targets.

use super::targets::Target;
use crate::pose::frames::{heading_difference_deg, wrap_degrees_360};
use crate::pose::hand_motion::{HandShake, Hpr, Timeline, UserPathParams, uniform};
use crate::pose::trace::TruthSample;
use anyhow::{Result, bail};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A held aim of the simulated user.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visit {
    /// Index into the target list.
    pub target: usize,
    pub start: f64,
    pub end: f64,
}

/// A generated path: samples (one tap, during the front hold) and the visits in order.
#[derive(Clone, Debug)]
pub struct CapturePath {
    pub samples: Vec<TruthSample>,
    pub visits: Vec<Visit>,
    pub reference_heading_deg: f64,
}

/// How far the user shifts their aim for a target from where it truly is (degrees): what the
/// on-screen guidance, drawn from the *estimated* pose, makes them do. Heading is along the
/// horizon (a true heading change), pitch is elevation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AimShift {
    pub heading_deg: f64,
    pub pitch_deg: f64,
    /// How long the user holds this target (s), when they move on as soon as the screen
    /// shows it taken; `None`: the drawn hold (`params.hold_s`). Ignored for the front (the
    /// tap falls within its drawn hold).
    pub hold_s: Option<f64>,
}

/// Generate the path of a user visiting `targets` (the first must be the front). Same seed
/// and parameters, same path. `params.order` is ignored (the user follows the guidance);
/// `params.vertical_pitch_deg` scales the pitch of targets at ±90°.
pub fn simulate_capture_path(seed: u64, targets: &[Target], params: &UserPathParams) -> Result<CapturePath> {
    simulate_guided_path(seed, targets, params, &[])
}

/// [`simulate_capture_path`] with the user's aim for target `i` shifted by `shifts[i]` (missing
/// entries: no shift). The random draws do not depend on the shifts, so a shifted path is the
/// same user making the same movements to slightly different places.
pub fn simulate_guided_path(seed: u64, targets: &[Target], params: &UserPathParams, shifts: &[AimShift]) -> Result<CapturePath> {
    if shifts.iter().any(|s| !(s.heading_deg.is_finite() && s.pitch_deg.is_finite())) {
        bail!("aim shifts must be finite: {shifts:?}");
    }
    let finite = [params.rate_hz, params.aim_error_deg, params.roll_deg, params.hold_s.0, params.hold_s.1, params.mean_speed_deg_s];
    if finite.iter().any(|v| !v.is_finite()) || params.rate_hz <= 0.0 || params.mean_speed_deg_s <= 0.0 || params.hold_s.0 <= 0.0 {
        bail!("user path parameters must be finite and positive: {params:?}");
    }
    if params.hold_s.1 < params.hold_s.0 || params.overshoot.1 < params.overshoot.0 {
        bail!("user path ranges must be ordered: {params:?}");
    }
    let Some(first) = targets.first().filter(|t| t.heading_offset_deg == 0.0 && t.pitch_deg == 0.0) else {
        bail!("the first target must be the front (heading offset 0, pitch 0)");
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let href = params.reference_heading_deg.unwrap_or_else(|| rng.random_range(0.0..360.0));
    let e = params.aim_error_deg;
    let pole_pitch = params.vertical_pitch_deg;
    let aim = |rng: &mut ChaCha8Rng, t: &Target, from_h: f64| {
        let ep = uniform(rng, (-e, e));
        let p = if t.pitch_deg.abs() >= 90.0 { pole_pitch * t.pitch_deg.signum() } else { t.pitch_deg };
        // The user cannot tilt past the vertical: err towards the horizon.
        let p = if p.abs() + ep > 90.0 { p - ep.abs() * p.signum() } else { p + ep };
        // Looking straight up or down people keep the heading they came from.
        let h = if t.pitch_deg.abs() >= 90.0 { from_h } else { href + t.heading_offset_deg + uniform(rng, (-e, e)) };
        Hpr { h, p, r: uniform(rng, (-params.roll_deg, params.roll_deg)) }
    };
    let front = aim(&mut rng, first, href);
    let start =
        Hpr { h: front.h + uniform(&mut rng, (-20.0, 20.0)), p: uniform(&mut rng, (-10.0, 10.0)), r: uniform(&mut rng, (-5.0, 5.0)) };
    let mut timeline = Timeline::start(start, 0.4);
    let mut at = start;
    let mut visits = Vec::with_capacity(targets.len());
    let mut todo: Vec<usize> = (1..targets.len()).collect();
    let mut tap_t = 0.0;
    let mut next = Some(0usize);
    while let Some(index) = next {
        let target = &targets[index];
        let goal = if index == 0 { front } else { aim(&mut rng, target, at.h) };
        let shift = shifts.get(index).copied().unwrap_or_default();
        // Shifts cannot take the aim past the vertical.
        let goal = Hpr { h: goal.h + shift.heading_deg, p: (goal.p + shift.pitch_deg).clamp(-90.0, 90.0), ..goal };
        let dh = heading_difference_deg(goal.h, at.h);
        let goal = Hpr { h: at.h + dh, ..goal };
        timeline.turn(&mut rng, params, at, goal);
        let drawn = uniform(&mut rng, params.hold_s);
        let hold = match shift.hold_s {
            Some(h) if index != 0 && h.is_finite() && h > 0.0 => h,
            _ => drawn,
        };
        if index == 0 {
            tap_t = timeline.t + uniform(&mut rng, (0.3, 0.6)).min(hold * 0.8);
        }
        let (start, end) = timeline.hold(goal, hold);
        visits.push(Visit { target: index, start, end });
        at = goal;
        // The next target of the plan's tour (as the guidance shows it).
        next = (!todo.is_empty()).then(|| todo.remove(0));
    }
    let shake = HandShake::seeded(rng.random(), params);
    let samples = timeline.sample(params, &shake, tap_t);
    Ok(CapturePath { samples, visits, reference_heading_deg: wrap_degrees_360(href) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::Mode;
    use crate::capture::projection::Pinhole;
    use crate::capture::targets::plan_targets;
    use crate::pose::trace::TruthTrace;

    #[test]
    fn visits_every_target_once_within_the_aim_error() {
        let cam = Pinhole::from_vfov(640, 480, 50.0).unwrap();
        let targets = plan_targets(Mode::Stitch, &cam, 2.0);
        let p = UserPathParams { reference_heading_deg: Some(359.6), ..UserPathParams::default() };
        let a = simulate_capture_path(4, &targets, &p).unwrap();
        let b = simulate_capture_path(4, &targets, &p).unwrap();
        assert_eq!(a.samples, b.samples);
        let mut seen: Vec<usize> = a.visits.iter().map(|v| v.target).collect();
        seen.sort();
        assert_eq!(seen, (0..targets.len()).collect::<Vec<_>>());
        assert_eq!(a.visits[0].target, 0);
        let trace = TruthTrace::new(a.samples.clone()).unwrap();
        let tap = trace.tap_times();
        assert_eq!(tap.len(), 1);
        assert!(tap[0] > a.visits[0].start && tap[0] < a.visits[0].end);
        for v in &a.visits {
            // Mid-hold the camera is within aim error + tremor/sway of the target (the
            // tolerance rule of the assistant, which the guided user satisfies).
            let mid = 0.5 * (v.start + v.end);
            let e = targets[v.target].aim_error(a.reference_heading_deg, trace.orientation_at(mid));
            assert!(e.within(p.aim_error_deg + 0.5), "{} {e:?}", targets[v.target].name);
        }
        assert!(simulate_capture_path(1, &targets[1..], &p).is_err());
        assert!(simulate_capture_path(1, &targets, &UserPathParams { rate_hz: f64::NAN, ..p }).is_err());
    }
}
