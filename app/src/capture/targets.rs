//! Capture targets: the six face centres and, in stitch mode, the extra aims a narrow lens
//! needs; when the camera counts as "on" a target; how many extra targets a lens needs.
//!
//! Tolerance rule (seed 000 Fig. 12b, generalised): the camera is on a target when its pitch
//! is within ±tol of the target's pitch and its heading, measured along the target's circle
//! of latitude (heading error × cos(target pitch)), is within ±tol. For the four side faces
//! (pitch 0) this is the seed's ±2° box on azimuth and zenith angle; for up and down (pitch
//! ±90°) the heading term vanishes and only pitch counts, as in the seed's `ROLL > 88`.
//! Heading differences are taken the short way round, so 359° and 1° are 2° apart.

use super::Mode;
use super::projection::{Pinhole, local_to_world};
use crate::pose::frames::{HeadingPitchRoll, from_heading_pitch_roll, heading_difference_deg, heading_pitch_roll, wrap_degrees_360};
use glam::{DQuat, DVec3, Quat, Vec3};

/// The six faces of a capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Face {
    Front,
    Right,
    Back,
    Left,
    Up,
    Down,
}

impl Face {
    /// In the order the assistant lists them (front first, then any order).
    pub const ALL: [Face; 6] = [Face::Front, Face::Up, Face::Down, Face::Right, Face::Back, Face::Left];

    pub fn name(self) -> &'static str {
        match self {
            Face::Front => "front",
            Face::Right => "right",
            Face::Back => "back",
            Face::Left => "left",
            Face::Up => "up",
            Face::Down => "down",
        }
    }

    /// Cube layer in wgpu order (+X, −X, +Y, −Y, +Z, −Z) under the capture convention:
    /// +Z front, +X right, +Y up.
    pub fn layer(self) -> usize {
        match self {
            Face::Right => 0,
            Face::Left => 1,
            Face::Up => 2,
            Face::Down => 3,
            Face::Front => 4,
            Face::Back => 5,
        }
    }

    /// The face stored in cube layer `layer` (0..6).
    pub fn from_layer(layer: usize) -> Option<Face> {
        Face::ALL.into_iter().find(|f| f.layer() == layer)
    }

    /// File name in a capture folder (the common posx/negx/... naming of cube faces).
    pub fn file_name(self) -> &'static str {
        ["posx.png", "negx.png", "posy.png", "negy.png", "posz.png", "negz.png"][self.layer()]
    }

    /// Heading offset from the reference and pitch of the face centre, degrees.
    pub fn aim_deg(self) -> (f64, f64) {
        match self {
            Face::Front => (0.0, 0.0),
            Face::Right => (90.0, 0.0),
            Face::Back => (180.0, 0.0),
            Face::Left => (270.0, 0.0),
            Face::Up => (0.0, 90.0),
            Face::Down => (0.0, -90.0),
        }
    }

    /// The face a capture-local direction falls in.
    pub fn of_local_dir(d: Vec3) -> Face {
        let (layer, _, _) = crate::scene::cubemap::cube_dir_to_face_uv(crate::scene::enu_to_cube(d));
        Face::from_layer(layer).unwrap_or(Face::Front)
    }
}

/// One aim the user is guided to.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Target {
    /// "front", "up", ..., or "right+2" for the second extra shot within the right face.
    pub name: String,
    /// The face whose centre this is, or the face its aim falls in for extra targets.
    pub face: Face,
    /// Whether this is the face's own centre target (the shot stretch mode uses).
    pub primary: bool,
    /// Heading offset from the reference heading (degrees, clockwise) and pitch (degrees).
    pub heading_offset_deg: f64,
    pub pitch_deg: f64,
}

/// How far the camera is from a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AimError {
    /// Heading error along the target's circle of latitude (degrees, signed: + = turn right).
    pub heading_deg: f64,
    /// Pitch error (degrees, signed: + = tilt up).
    pub pitch_deg: f64,
    /// Angle between the viewing direction and the target's direction (degrees).
    pub angle_deg: f64,
}

impl AimError {
    pub fn within(&self, tolerance_deg: f64) -> bool {
        self.heading_deg.abs() <= tolerance_deg && self.pitch_deg.abs() <= tolerance_deg
    }
}

impl Target {
    pub fn for_face(face: Face) -> Target {
        let (h, p) = face.aim_deg();
        Target { name: face.name().into(), face, primary: true, heading_offset_deg: h, pitch_deg: p }
    }

    /// The target's direction in the world for a reference heading (degrees).
    pub fn direction(&self, reference_heading_deg: f64) -> DVec3 {
        let (h, p) = ((reference_heading_deg + self.heading_offset_deg).to_radians(), self.pitch_deg.to_radians());
        DVec3::new(h.sin() * p.cos(), h.cos() * p.cos(), p.sin())
    }

    /// The level camera pose (roll 0) aimed at the target, camera → world.
    pub fn pose(&self, reference_heading_deg: f64) -> DQuat {
        from_heading_pitch_roll((reference_heading_deg + self.heading_offset_deg).to_radians(), self.pitch_deg.to_radians(), 0.0)
    }

    /// Whether the heading is free (the target is so close to a pole that any heading is
    /// within tolerance).
    pub fn heading_free(&self, tolerance_deg: f64) -> bool {
        self.pitch_deg.to_radians().cos() * 180.0 <= tolerance_deg
    }

    /// How far a camera pose (camera → world) is from this target.
    pub fn aim_error(&self, reference_heading_deg: f64, pose: DQuat) -> AimError {
        self.aim_error_hpr(reference_heading_deg, pose, heading_pitch_roll(pose))
    }

    /// [`Target::aim_error`] with the pose's heading, pitch and roll already computed.
    pub fn aim_error_hpr(&self, reference_heading_deg: f64, pose: DQuat, hpr: HeadingPitchRoll) -> AimError {
        let target_heading = reference_heading_deg + self.heading_offset_deg;
        let dh = heading_difference_deg(hpr.heading.to_degrees(), target_heading);
        let forward = pose * DVec3::NEG_Z;
        let angle = forward.normalize().dot(self.direction(reference_heading_deg)).clamp(-1.0, 1.0).acos().to_degrees();
        AimError {
            heading_deg: dh * self.pitch_deg.to_radians().cos(),
            pitch_deg: hpr.pitch.to_degrees() - self.pitch_deg,
            angle_deg: angle,
        }
    }
}

/// Face samples per side used to plan coverage.
const PLAN_SAMPLES: u32 = 16;
/// Most roll (degrees) the planner allows the user while aiming; shots must cover their
/// part of a face at roll −r, 0 and +r.
pub const PLAN_ROLL_DEG: f64 = 5.0;
/// Plan margin on every side of a frame, as a fraction of the aim tolerance.
pub const PLAN_MARGIN: f64 = 0.75;
/// Most rings of views between the horizon and each pole the planner tries.
const MAX_SIDE_RINGS: usize = 4;

/// Which plan samples a shot surely covers, as a bitset.
fn coverage_bits(t: &Target, samples: &[Vec3], half_tan: (f32, f32), disc: f32, tolerance_deg: f64) -> Vec<u64> {
    let mut bits = vec![0u64; samples.len().div_ceil(64)];
    let rolls: Vec<Quat> = if t.heading_free(tolerance_deg) {
        vec![t.pose(0.0).as_quat().inverse()]
    } else {
        [-PLAN_ROLL_DEG, 0.0, PLAN_ROLL_DEG]
            .iter()
            .map(|roll| {
                from_heading_pitch_roll(t.heading_offset_deg.to_radians(), t.pitch_deg.to_radians(), roll.to_radians()).as_quat().inverse()
            })
            .collect()
    };
    for (i, d) in samples.iter().enumerate() {
        let inside = if t.heading_free(tolerance_deg) {
            let c = rolls[0] * *d;
            c.z < 0.0 && (c.x * c.x + c.y * c.y).sqrt() <= disc * -c.z
        } else {
            rolls.iter().all(|q| {
                let c = *q * *d;
                c.z < 0.0 && c.x.abs() <= half_tan.0 * -c.z && c.y.abs() <= half_tan.1 * -c.z
            })
        };
        if inside {
            bits[i / 64] |= 1 << (i % 64);
        }
    }
    bits
}

/// The targets for a mode and lens. Stretch mode: the six face centres. Stitch mode: the
/// fewest views, laid out in rings of latitude, that cover the whole sphere from the lens's field
/// of view: one view at each pole, a ring on the horizon starting at the front, and
/// `s` rings between the horizon and each pole (`s` = 0..[`MAX_SIDE_RINGS`], evenly spaced in
/// pitch); each ring gets the fewest evenly spaced views that cover its band of latitude (less
/// what the pole views see). A greedy set cover over a 5° lattice of aims, starting from the
/// front, competes with the ring layouts; the plan with the fewest views wins. Coverage is counted on the frame shrunk by the tolerance
/// plus one degree on every side — that margin is both the room for aim and pose error and the
/// overlap neighbouring shots share (2 × margin) — with the view rolled by up to
/// ±[`PLAN_ROLL_DEG`]; near the poles, where the heading is free, only on the disc inscribed in the
/// shrunk frame. A 100° lens gets 7 views (4:3 landscape), a 50° one 24 (tolerance 2°). Views that
/// land on a face centre are that face's named target. The targets come in the order the
/// guidance visits them, the front first: a short tour ([`short_tour`]). Plans are cached per
/// (mode, lens, tolerance).
pub fn plan_targets(mode: Mode, camera: &Pinhole, tolerance_deg: f64) -> Vec<Target> {
    type Key = (Mode, u32, u32, u64);
    static CACHE: std::sync::OnceLock<std::sync::Mutex<std::collections::HashMap<Key, Vec<Target>>>> = std::sync::OnceLock::new();
    let key = (mode, camera.tan_half_h.to_bits(), camera.tan_half_v.to_bits(), tolerance_deg.to_bits());
    let cache = CACHE.get_or_init(Default::default);
    if let Some(t) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return t.clone();
    }
    let targets = short_tour(plan_uncached(mode, camera, tolerance_deg));
    cache.lock().unwrap_or_else(|e| e.into_inner()).insert(key, targets.clone());
    targets
}

/// Total turn (radians) of visiting `targets` in order (angles between successive aims).
pub fn tour_length(targets: &[Target]) -> f64 {
    targets.windows(2).map(|w| w[0].direction(0.0).angle_between(w[1].direction(0.0))).sum()
}

/// The level camera pose (roll 0) a user holds on `target` arriving with heading
/// `from_heading_deg` (relative to the reference): a target at a pole keeps the heading they
/// came from, as people looking straight up or down do ([`super::guided_path`]). Returns the
/// heading held and the pose.
fn held_pose(target: &Target, from_heading_deg: f64) -> (f64, DQuat) {
    let h = if target.pitch_deg.abs() >= 90.0 { from_heading_deg } else { target.heading_offset_deg };
    (h, from_heading_pitch_roll(h.to_radians(), target.pitch_deg.to_radians(), 0.0))
}

/// Total rotation (degrees) of the phone visiting `targets` in order: the angle of the
/// rotation between successive held poses ([`held_pose`]), what a turn takes time for (the
/// simulated hand moves at an angular speed, [`crate::pose::hand_motion`]). Not the angle
/// between the aims: turning along a ring of latitude at pitch p by Δh moves the aim by only
/// 2·asin(cos p · sin(Δh/2)), but turns the phone by Δh (at ±45°, 41° against 60°).
pub fn tour_turn_deg(targets: &[Target]) -> f64 {
    let order: Vec<usize> = (0..targets.len()).collect();
    turn_of(targets, &order)
}

fn turn_of(targets: &[Target], order: &[usize]) -> f64 {
    let Some(&first) = order.first() else { return 0.0 };
    let (mut h, mut q) = held_pose(&targets[first], targets[first].heading_offset_deg);
    let mut sum = 0.0;
    for &i in &order[1..] {
        let (h2, q2) = held_pose(&targets[i], h);
        sum += crate::pose::frames::angle_between(q, q2);
        (h, q) = (h2, q2);
    }
    sum.to_degrees()
}

/// Restarts of the tour's local search (the first from the tour short in aim angles, the
/// others from seeded random orders).
const TOUR_RESTARTS: usize = 24;

/// The targets reordered into a short open tour from the first (the front), short in the phone's
/// rotation ([`tour_turn_deg`]): a local search by 2-opt (reverse any stretch of the tour; Croes
/// 1958, "A method for solving traveling-salesman problems", Operations Research 6(6)) and
/// or-opt moves (move one target elsewhere; Or 1976), from the tour short in the angle between
/// aims ([`aim_angle_tour`]) and from seeded random orders, the best kept. On the 24-view plan of a 50° lens the tour turns the phone
/// through 1132° in all; the earlier tour, short in the angle between aims, turned it through
/// 1218° (it ran along the ±45° rings, where each 60° step moves the aim only 41°).
pub fn short_tour(mut targets: Vec<Target>) -> Vec<Target> {
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    let n = targets.len();
    if n < 3 {
        return targets;
    }
    let cost = |order: &[usize]| turn_of(&targets, order);
    let by_aims = aim_angle_tour(&targets);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x7047);
    let mut best: Option<(Vec<usize>, f64)> = None;
    for restart in 0..TOUR_RESTARTS {
        let mut order = if restart == 0 {
            by_aims.clone()
        } else {
            let mut rest: Vec<usize> = (1..n).collect();
            rest.shuffle(&mut rng);
            std::iter::once(0).chain(rest).collect()
        };
        let mut here = cost(&order);
        let mut improved = true;
        while improved {
            improved = false;
            // 2-opt: reverse order[i..=j] (the start stays the front).
            for i in 1..n - 1 {
                for j in i + 1..n {
                    order[i..=j].reverse();
                    let c = cost(&order);
                    if c + 1e-9 < here {
                        here = c;
                        improved = true;
                    } else {
                        order[i..=j].reverse();
                    }
                }
            }
            // Or-opt: move the target at i to position j.
            for i in 1..n {
                for j in 1..n {
                    if i == j {
                        continue;
                    }
                    let x = order.remove(i);
                    order.insert(j, x);
                    let c = cost(&order);
                    if c + 1e-9 < here {
                        here = c;
                        improved = true;
                    } else {
                        let x = order.remove(j);
                        order.insert(i, x);
                    }
                }
            }
        }
        if best.as_ref().is_none_or(|(_, b)| here + 1e-9 < *b) {
            best = Some((order, here));
        }
    }
    let order = best.map_or_else(|| (0..n).collect(), |(o, _)| o);
    let mut slots: Vec<Option<Target>> = targets.drain(..).map(Some).collect();
    order.into_iter().filter_map(|i| slots[i].take()).collect()
}

/// The earlier tour, short in the angle between aims: nearest neighbour from the front, then
/// 2-opt on that angle. The rotation tour's local search starts from it (so of tours that turn
/// the phone equally, e.g. the six faces' 480°, it keeps this one).
fn aim_angle_tour(targets: &[Target]) -> Vec<usize> {
    let n = targets.len();
    let dirs: Vec<DVec3> = targets.iter().map(|t| t.direction(0.0)).collect();
    let d = |a: usize, b: usize| dirs[a].angle_between(dirs[b]);
    let mut order = vec![0usize];
    let mut left: Vec<usize> = (1..n).collect();
    while !left.is_empty() {
        let here = order[order.len() - 1];
        let k = (0..left.len()).min_by(|&a, &b| d(here, left[a]).total_cmp(&d(here, left[b]))).unwrap_or(0);
        order.push(left.swap_remove(k));
    }
    // Reversing order[i..=j] replaces the edges (i−1, i) and (j, j+1) (the latter absent at the end).
    let mut improved = true;
    while improved {
        improved = false;
        for i in 1..n.saturating_sub(1) {
            for j in i + 1..n {
                let before = d(order[i - 1], order[i]) + if j + 1 < n { d(order[j], order[j + 1]) } else { 0.0 };
                let after = d(order[i - 1], order[j]) + if j + 1 < n { d(order[i], order[j + 1]) } else { 0.0 };
                if after + 1e-9 < before {
                    order[i..=j].reverse();
                    improved = true;
                }
            }
        }
    }
    order
}

fn aim_target(heading_offset_deg: f64, pitch_deg: f64) -> Target {
    let (h, p) = (wrap_degrees_360(heading_offset_deg), pitch_deg);
    if let Some(face) = Face::ALL.into_iter().find(|f| {
        let (fh, fp) = f.aim_deg();
        (fp - p).abs() < 1e-9 && (fp.abs() == 90.0 || heading_difference_deg(fh, h).abs() < 1e-9)
    }) {
        return Target::for_face(face);
    }
    let (hr, pr) = (h.to_radians(), p.to_radians());
    let dir = Vec3::new((hr.sin() * pr.cos()) as f32, (hr.cos() * pr.cos()) as f32, pr.sin() as f32);
    Target { name: String::new(), face: Face::of_local_dir(dir), primary: false, heading_offset_deg: h, pitch_deg: p }
}

fn plan_uncached(mode: Mode, camera: &Pinhole, tolerance_deg: f64) -> Vec<Target> {
    if mode == Mode::Stretch {
        return Face::ALL.iter().map(|&f| Target::for_face(f)).collect();
    }
    let samples: Vec<Vec3> = (0..6)
        .flat_map(|layer| {
            (0..PLAN_SAMPLES * PLAN_SAMPLES)
                .map(move |i| super::projection::face_pixel_dir_local(layer, i % PLAN_SAMPLES, i / PLAN_SAMPLES, PLAN_SAMPLES, 1.0))
        })
        .collect();
    let margin = (PLAN_MARGIN * tolerance_deg).to_radians() as f32;
    // Half-angles of the usable frame, as tangents.
    let th = (camera.tan_half_h.atan() - margin).max(0.0).tan();
    let tv = (camera.tan_half_v.atan() - margin).max(0.0).tan();
    let bits = |t: &Target| coverage_bits(t, &samples, (th, tv), th.min(tv), tolerance_deg);
    let words = samples.len().div_ceil(64);
    let or = |acc: &mut Vec<u64>, b: &[u64]| acc.iter_mut().zip(b).for_each(|(a, x)| *a |= x);
    let pitch_of = |d: &Vec3| f64::from(d.z.clamp(-1.0, 1.0).asin().to_degrees());
    let mut best: Option<Vec<Target>> = None;
    for side in 0..=MAX_SIDE_RINGS {
        // Ring pitches from the south pole to the north pole; the poles are single views.
        let step = 90.0 / (side + 1) as f64;
        let pitches: Vec<f64> = (-(side as i32 + 1)..=side as i32 + 1).map(|j| f64::from(j) * step).collect();
        let mut plan: Vec<Target> = [90.0, -90.0].map(|p| aim_target(0.0, p)).to_vec();
        let mut all = vec![0u64; words];
        for t in &plan {
            or(&mut all, &bits(t));
        }
        let poles = all.clone();
        let mut ok = true;
        for (j, &p) in pitches.iter().enumerate().filter(|(_, p)| p.abs() < 90.0) {
            // The ring's band: half-way to its neighbours in pitch, less what the poles see.
            let (lo, hi) = (0.5 * (pitches[j - 1] + p), 0.5 * (pitches[j + 1] + p));
            let band: Vec<usize> =
                (0..samples.len()).filter(|&i| (lo..=hi).contains(&pitch_of(&samples[i])) && poles[i / 64] >> (i % 64) & 1 == 0).collect();
            let found = (1..=72).find_map(|n| {
                let ring: Vec<Target> = (0..n).map(|k| aim_target(360.0 * k as f64 / n as f64, p)).collect();
                let mut acc = vec![0u64; words];
                for t in &ring {
                    or(&mut acc, &bits(t));
                }
                band.iter().all(|&i| acc[i / 64] >> (i % 64) & 1 == 1).then_some((ring, acc))
            });
            let Some((ring, acc)) = found else {
                ok = false;
                break;
            };
            or(&mut all, &acc);
            plan.extend(ring);
        }
        let complete = all.iter().map(|w| w.count_ones() as usize).sum::<usize>() == samples.len();
        if ok && complete && best.as_ref().is_none_or(|b| plan.len() < b.len()) {
            best = Some(plan);
        }
    }
    // Greedy set cover over a 5° lattice of aims (and the poles), from the front: sometimes fewer
    // views than the rings.
    {
        let mut covered = bits(&Target::for_face(Face::Front));
        let mut plan = vec![Target::for_face(Face::Front)];
        let candidates: Vec<(Target, Vec<u64>)> = (-16..=16)
            .flat_map(|j| (0..72).map(move |i| aim_target(f64::from(i) * 5.0, f64::from(j) * 5.0)))
            .chain([90.0, -90.0].map(|p| aim_target(0.0, p)))
            .map(|t| {
                let b = bits(&t);
                (t, b)
            })
            .collect();
        let count = |c: &[u64]| c.iter().map(|w| w.count_ones() as usize).sum::<usize>();
        while count(&covered) < samples.len() && plan.len() < 200 {
            let gain = |b: &[u64]| b.iter().zip(&covered).map(|(x, c)| (x & !c).count_ones() as usize).sum::<usize>();
            let Some((t, b)) = candidates.iter().max_by_key(|(_, b)| gain(b)).filter(|(_, b)| gain(b) > 0) else { break };
            or(&mut covered, b);
            plan.push(t.clone());
        }
        if count(&covered) == samples.len() && best.as_ref().is_none_or(|b| plan.len() < b.len()) {
            best = Some(plan);
        }
    }
    // A lens too narrow for any layout: the widest-ring plan, its holes show as coverage.
    let plan = best.unwrap_or_else(|| {
        let n = 72;
        let mut v: Vec<Target> = (0..n).map(|k| aim_target(360.0 * k as f64 / n as f64, 0.0)).collect();
        v.extend([Target::for_face(Face::Up), Target::for_face(Face::Down)]);
        v
    });
    // The front first (the tap), then the rest; extra views named after the face they fall in.
    let mut targets: Vec<Target> = vec![Target::for_face(Face::Front)];
    let mut per_face = [0u32; 6];
    for t in plan.into_iter().filter(|t| *t != Target::for_face(Face::Front)) {
        if t.primary {
            targets.push(t);
        } else {
            let k = &mut per_face[t.face.layer()];
            *k += 1;
            targets.push(Target { name: format!("{}+{}", t.face.name(), *k), ..t });
        }
    }
    targets
}

/// Rotation taking a world direction to the capture's local frame.
pub fn world_to_local(reference_heading_deg: f64) -> DQuat {
    local_to_world(reference_heading_deg.to_radians()).inverse()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn aim(h: f64, p: f64) -> DQuat {
        from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.0)
    }

    #[test]
    fn seed_fig_12b_boxes_and_the_wrap() {
        let tol = 2.0;
        let right = Target::for_face(Face::Right);
        // Seed 000 Fig. 12b: right when REFERENCE+88 < HEADING < REFERENCE+92 and |ROLL| < 2.
        assert!(right.aim_error(10.0, aim(101.5, 1.5)).within(tol));
        assert!(!right.aim_error(10.0, aim(97.5, 0.0)).within(tol));
        assert!(!right.aim_error(10.0, aim(100.0, 2.5)).within(tol));
        // Across 0/360: reference 300°, right target at 30° (=390°); 28.5° and 31.9° are on it.
        assert!(right.aim_error(300.0, aim(28.5, 0.0)).within(tol));
        assert!(right.aim_error(300.0, aim(31.9, 0.0)).within(tol));
        assert!(!right.aim_error(300.0, aim(27.9, 0.0)).within(tol));
        // Front with reference 359.5: heading 1.0 is 1.5° off, signed (turn left).
        let e = Target::for_face(Face::Front).aim_error(359.5, aim(1.0, 0.0));
        assert!((e.heading_deg - 1.5).abs() < 1e-9 && e.within(tol), "{e:?}");
        // Up/down: pitch only (seed: ROLL > 88), any heading, any roll.
        let up = Target::for_face(Face::Up);
        assert!(up.aim_error(0.0, from_heading_pitch_roll(3.0, 88.5f64.to_radians(), 0.7)).within(tol));
        assert!(up.aim_error(0.0, from_heading_pitch_roll(1.0, 90f64.to_radians(), 0.0)).within(tol));
        assert!(!up.aim_error(0.0, aim(0.0, 87.5)).within(tol));
        let down = Target::for_face(Face::Down);
        assert!(down.aim_error(123.0, aim(250.0, -89.0)).within(tol));
        assert!(!down.aim_error(123.0, aim(250.0, 89.0)).within(tol));
        // The angle to the target is the true angular distance: 90° from front to up.
        assert!((Target::for_face(Face::Front).aim_error(0.0, aim(0.0, 90.0)).angle_deg - 90.0).abs() < 1e-6);
    }

    #[test]
    fn a_turn_along_a_ring_turns_the_phone_by_the_heading_change() {
        // Two aims 60° apart in heading at pitch 45°: the aims are 2·asin(cos 45° · sin 30°) =
        // 41.41° apart, but the level phone turns by 60° about the vertical.
        let at = |h: f64, p: f64| Target { name: String::new(), face: Face::Front, primary: false, heading_offset_deg: h, pitch_deg: p };
        let ring = [at(0.0, 45.0), at(60.0, 45.0)];
        assert!((tour_length(&ring).to_degrees() - 41.41).abs() < 0.01, "{}", tour_length(&ring).to_degrees());
        assert!((tour_turn_deg(&ring) - 60.0).abs() < 1e-6, "{}", tour_turn_deg(&ring));
        // Straight up keeps the heading the user came from: from (30°, 0°) up is a 90° tilt,
        // and on to (120°, 45°) a turn of the image by 90° combined with a 45° tilt:
        // cos θ = (tr R − 1)/2 with R = Rz(90°)·Rx(−45°) gives θ = 98.42°.
        let up = [at(30.0, 0.0), Target::for_face(Face::Up), at(120.0, 45.0)];
        let expected = 90.0 + ((0.5 * (std::f64::consts::FRAC_1_SQRT_2 - 1.0)).acos()).to_degrees();
        assert!((tour_turn_deg(&up) - expected).abs() < 1e-6, "{} vs {expected}", tour_turn_deg(&up));
    }

    #[test]
    fn face_layers_and_files_follow_the_cube_convention() {
        for f in Face::ALL {
            assert_eq!(Face::from_layer(f.layer()), Some(f));
            // The face centre target points at the middle of its own cube layer.
            let d = world_to_local(37.0) * Target::for_face(f).direction(37.0);
            assert_eq!(Face::of_local_dir(d.as_vec3()), f, "{f:?}");
        }
        assert_eq!(Face::Front.file_name(), "posz.png");
        assert_eq!(Face::Right.file_name(), "posx.png");
        assert_eq!(Face::Up.file_name(), "posy.png");
        assert_eq!(Face::Left.file_name(), "negx.png");
    }

    #[test]
    fn stitch_plan_covers_every_face_and_scales_with_the_lens() {
        let narrow = Pinhole::from_vfov(640, 480, 50.0).unwrap();
        let wide = Pinhole::from_vfov(640, 480, 100.0).unwrap();
        assert_eq!(plan_targets(Mode::Stretch, &narrow, 2.0).len(), 6);
        let n = plan_targets(Mode::Stitch, &narrow, 2.0);
        let w = plan_targets(Mode::Stitch, &wide, 2.0);
        assert!(n.len() > 6 && n.len() > w.len(), "narrow {} wide {}", n.len(), w.len());
        // A 100° lens (115.6° wide): each face centre plus a few views on the horizon. Six
        // shots are not enough once the up/down shots may be turned any way: their inscribed
        // disc (50° − 1.5° margin) ends at 41.5° elevation, while four side shots reach only
        // 40° at the azimuths between them (tan⁻¹(tan 50° · cos 45°)).
        assert!(w.len() <= 7, "{} views", w.len());
        assert!(w.iter().filter(|t| t.primary).count() >= 3);
        // The 50° lens: fewer views than the 32 the earlier planner needed (24 measured).
        assert!(n.len() <= 24, "{} views", n.len());
        // Every direction on a fine face grid lies inside some level, exactly aimed shot.
        for targets in [&n, &w] {
            let cam = if targets.len() == n.len() { &narrow } else { &wide };
            for layer in 0..6 {
                for i in 0..(40 * 40) {
                    let d = super::super::projection::face_pixel_dir_local(layer, i % 40, i / 40, 40, 1.0);
                    assert!(targets.iter().any(|t| cam.sees(t.pose(0.0).as_quat(), d, 0.0)), "layer {layer} sample {i}");
                }
            }
        }
        // In tour order from the front, turning the phone less than visiting the nearest target
        // left (by the angle between aims, as the earlier tour did): 1132° against the 2-opt tour
        // by aim angles' 1218° (measured), and shorter than nearest-first.
        assert_eq!(n[0].face, Face::Front);
        assert!(n[0].primary);
        let mut nearest = vec![n[0].clone()];
        let mut left: Vec<Target> = n[1..].to_vec();
        while !left.is_empty() {
            let here = nearest[nearest.len() - 1].direction(0.0);
            let k = (0..left.len())
                .min_by(|&a, &b| left[a].direction(0.0).angle_between(here).total_cmp(&left[b].direction(0.0).angle_between(here)))
                .unwrap();
            nearest.push(left.remove(k));
        }
        let (tour, greedy) = (tour_turn_deg(&n), tour_turn_deg(&nearest));
        eprintln!("rotation: tour {tour:.0}°, nearest-first by aim angle {greedy:.0}°, aim-angle tour {:.0}°", {
            let by_aims = aim_angle_tour(&n);
            turn_of(&n, &by_aims)
        });
        assert!(tour < 0.95 * greedy, "tour {tour:.0}° nearest-first {greedy:.0}°");
        // Names are unique.
        let mut names: Vec<_> = n.iter().map(|t| t.name.clone()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), n.len());
    }
}
