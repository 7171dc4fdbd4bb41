//! The capture assistant as a state machine fed (frame, estimated pose, time).
//!
//! 1. Waiting for the tap: the user aims at what should be the front and taps; that frame is
//!    the front shot and its heading the reference (seed 000 Fig. 12b, lines 1–2).
//! 2. Capturing: every other target (up, down, right, back, left, and in stitch mode the extra
//!    aims) is taken automatically, in any order, once the camera has been on it *and* turning
//!    slower than `max_rate_deg_s` for `dwell_s` seconds — a shot taken while swinging through
//!    a target would be blurred and its pose stale.
//! 3. Complete: stretch mode, every face has its shot; stitch mode, every direction of the
//!    sphere is seen by some shot. [`Assistant::finish`] assembles the faces.
//!
//! "On a target" is judged with the pose *and its uncertainty* ([`Assistant::tolerance_now`]):
//! the aim tolerance is widened by `AIM_SIGMAS` times the pose's own 1σ accuracy estimate, so
//! an estimate a few degrees off (after a fast pan) cannot make a target unreachable — a user
//! aiming at the true target is within the widened box. Stitch mode completes by *coverage*,
//! not by hitting every planned aim: each shot marks the sphere samples its frame sees (by the
//! estimated pose), a planned target whose samples neighbouring shots already saw is dropped,
//! and when the planned targets are used up but some samples are still unseen the assistant adds
//! a repair target aimed at them. So a face is never left missing because one sub-shot's exact
//! direction was not hit, and the guidance always points at something that can be taken.
//!
//! The angular rate is measured from the estimated poses over the last `RATE_WINDOW_S`
//! seconds (robust to per-sample jitter). Frames are only needed when a shot is taken: the
//! driver can call [`Assistant::observe`] every frame and render/fetch the image only when
//! it returns a target ([`Assistant::feed`] does both for a ready frame).

use super::Mode;
use super::align::align_shots;
use super::folder::{AlignmentMeta, CaptureMeta, CubeCapture, FaceMeta, ShotMeta};
use super::projection::Pinhole;
use super::projection::face_pixel_dir_local;
use super::reproject::{FaceImage, Shot, assemble_face};
use super::targets::{Face, PLAN_MARGIN, Target, plan_targets, world_to_local};
use crate::pose::frames::{angle_between_f32, heading_pitch_roll, wrap_degrees_360};
use crate::pose::{HeadingSource, Pose};
use crate::scene::Rgba8Image;
use anyhow::{Result, bail};
use glam::{Quat, Vec2, Vec3};
use std::collections::VecDeque;
use std::sync::Arc;

/// Seconds of pose history the angular rate is measured over.
pub const RATE_WINDOW_S: f64 = 0.1;
/// The aim tolerance is widened by this many times the pose's 1σ accuracy estimate: the aim is
/// judged against the reference heading, itself an estimate, so the error of the difference can
/// reach twice one estimate's.
pub const AIM_SIGMAS: f64 = 2.0;
/// Largest accuracy estimate (degrees) credited to the tolerance: with no heading at all the
/// estimate is 180°, and a box that wide would take anything.
pub const MAX_SIGMA_DEG: f64 = 6.0;
/// Sphere samples per face side that judge stitch-mode coverage.
const COVER_SAMPLES: u32 = 16;
/// Stitch mode: a steady view on no target is taken when at least this fraction of the
/// coverage samples it sees (inside the frame shrunk by the plan margin), and at least
/// [`MIN_NEW_SAMPLES`] of them, are not seen yet.
pub const MIN_NEW_FRACTION: f64 = 0.25;
pub const MIN_NEW_SAMPLES: usize = 8;
/// A shot marks as seen the samples inside its frame shrunk by this much (degrees), so thin gaps
/// between frames that fall between the samples (about 5° apart) are caught.
const COVER_MARGIN_DEG: f64 = 2.0;
/// `on_target` marker for a steady view on no target.
const FREE_VIEW: usize = usize::MAX;
/// Stitch mode: once every target is taken or seen by others, a face counts as complete with
/// up to this fraction of its coverage samples unseen (a sliver at a seam, filled from the
/// nearest shot's edge and reported as the face's coverage); a bigger hole gets a repair
/// target.
pub const MAX_UNSEEN: f64 = 0.02;

/// Settings of the assistant.
#[derive(Clone, Debug, PartialEq)]
pub struct AssistantConfig {
    pub mode: Mode,
    /// The phone camera the frames come from.
    pub camera: Pinhole,
    /// Aim tolerance (degrees, ± on heading and pitch; seed 000: 2).
    pub tolerance_deg: f64,
    /// Above this angular rate (degrees/s) the user is asked to hold still and nothing is taken.
    pub max_rate_deg_s: f64,
    /// How long (s) the camera must stay on target and steady before the shot is taken.
    pub dwell_s: f64,
    /// Face size in pixels (a power of two; seed 000: 256).
    pub face_size: u32,
    /// Stitch mode: correct the shots' headings from their overlaps before assembly
    /// ([`super::align`]). On by default: on the quarry HDR at phone noise it raises the faces'
    /// PSNR against the ideal faces at the front's true heading by 3–4 dB (docs/capture.md).
    pub align: bool,
    /// Scale each shot's light to the front's from the overlaps before assembly
    /// ([`super::gain`]): undoes exposure and white balance that changed between shots. Off by
    /// default: a capture locks both at the tap; on when the camera could not lock them
    /// ([`crate::camera::FrameSource::lock_exposure`] returned false).
    pub gain_compensation: bool,
}

impl AssistantConfig {
    pub fn new(mode: Mode, camera: Pinhole) -> Self {
        AssistantConfig {
            mode,
            camera,
            tolerance_deg: 2.0,
            max_rate_deg_s: 10.0,
            dwell_s: 0.2,
            face_size: 256,
            align: true,
            gain_compensation: false,
        }
    }

    pub fn validate(&self) -> Result<()> {
        if !(self.tolerance_deg.is_finite() && self.tolerance_deg > 0.0 && self.tolerance_deg <= 45.0) {
            bail!("tolerance must be more than 0 and at most 45 degrees, got {}", self.tolerance_deg);
        }
        if !(self.max_rate_deg_s.is_finite() && self.max_rate_deg_s > 0.0) {
            bail!("the steadiness limit must be a positive angular rate, got {} deg/s", self.max_rate_deg_s);
        }
        if !(self.dwell_s.is_finite() && self.dwell_s >= 0.0) {
            bail!("the dwell time must be zero or more seconds, got {}", self.dwell_s);
        }
        if !self.face_size.is_power_of_two() || !(16..=4096).contains(&self.face_size) {
            bail!("face size must be a power of two from 16 to 4096 pixels, got {}", self.face_size);
        }
        Ok(())
    }
}

/// Where the assistant is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    WaitingForTap,
    Capturing,
    Complete,
}

/// What the overlay shows about the next target.
#[derive(Clone, Debug, PartialEq)]
pub struct NextTarget {
    pub index: usize,
    pub name: String,
    pub face: Face,
    /// Unit direction on screen (x right, y up) to turn towards; zero when on target.
    pub arrow: Vec2,
    /// Normalised image position (−1..1, y up) of the target when it is in view.
    pub on_screen: Option<Vec2>,
    /// Angle between the view direction and the target (degrees).
    pub angle_deg: f64,
    /// Within tolerance right now.
    pub within: bool,
    /// The tolerance in force (degrees): the configured one widened by the pose uncertainty.
    pub tolerance_deg: f64,
}

/// Everything the on-screen guidance needs, in one snapshot.
#[derive(Clone, Debug, PartialEq)]
pub struct Guidance {
    pub phase: Phase,
    pub next: Option<NextTarget>,
    /// Faces with all their shots taken (n of 6).
    pub faces_done: usize,
    pub shots_done: usize,
    pub shots_total: usize,
    /// Captured state per face, in [`Face::ALL`] order.
    pub face_done: [bool; 6],
    /// Progress per face, in [`Face::ALL`] order (0..1): stitch mode, the share of the face's
    /// coverage samples some shot has seen; stretch mode, 1 once its shot is taken. For the
    /// overlay's faces filling in.
    pub face_progress: [f64; 6],
    /// Fraction of the sphere some shot has seen (stitch mode; stretch mode counts faces).
    pub coverage: f64,
    /// The camera turns faster than the steadiness limit.
    pub hold_still: bool,
    pub rate_deg_s: f64,
    /// Steadiness on the view about to be taken (0..1): the share of the dwell time already
    /// held steady on it; 0 when not steady on anything that would be taken.
    pub steady_progress: f64,
    /// Where the pose's heading comes from, and its 1σ (degrees), for the overlay's compass
    /// status (`None` before the first pose).
    pub heading_source: Option<HeadingSource>,
    pub heading_accuracy_deg: Option<f32>,
    /// The pose's heading comes from the gyroscope alone (magnetometer disturbed).
    pub gyro_only: bool,
    /// One line for the user.
    pub message: String,
}

/// Per-target bookkeeping: the shot, and why it was not taken yet.
#[derive(Clone, Debug)]
struct TargetState {
    target: Target,
    shot: Option<Shot>,
    heading_source: Option<HeadingSource>,
    accuracy_deg: f32,
    /// Closest the view came (degrees) and when.
    closest_deg: f64,
    closest_t: f64,
    ever_within: bool,
    /// Slowest rate seen while within tolerance (degrees/s).
    slowest_within: f64,
    /// Longest stretch on target and steady (s).
    longest_dwell: f64,
    /// Sphere samples this target's shot sees when aimed exactly (stitch mode).
    planned: Vec<u32>,
    /// Stitch mode: every planned sample was seen by other shots, so the target is not needed.
    covered_by_others: bool,
}

impl TargetState {
    fn new(target: Target, planned: Vec<u32>) -> Self {
        TargetState {
            target,
            shot: None,
            heading_source: None,
            accuracy_deg: f32::NAN,
            closest_deg: f64::INFINITY,
            closest_t: f64::NAN,
            ever_within: false,
            slowest_within: f64::INFINITY,
            longest_dwell: 0.0,
            planned,
            covered_by_others: false,
        }
    }

    /// Nothing more to do for this target.
    fn done(&self) -> bool {
        self.shot.is_some() || self.covered_by_others
    }
}

/// The capture assistant (see the module documentation).
#[derive(Debug)]
pub struct Assistant {
    cfg: AssistantConfig,
    states: Vec<TargetState>,
    reference_heading_deg: Option<f64>,
    history: VecDeque<(f64, Quat)>,
    last_t: Option<f64>,
    rate_deg_s: f64,
    /// Target the camera is steadily on, and since when.
    on_target: Option<(usize, f64)>,
    last_pose: Option<Pose>,
    /// Stitch-mode coverage samples (capture-local unit directions, [`COVER_SAMPLES`]² per
    /// face in cube-layer order) and whether some shot has seen each.
    samples: Vec<Vec3>,
    covered: Vec<bool>,
    repairs: usize,
    /// Shots taken on no target because they saw enough that was missing.
    views: usize,
}

/// Largest deviation from unit length accepted for a pose quaternion.
const UNIT_TOLERANCE: f32 = 1e-3;

fn check_input(t: f64, pose: &Pose, last_t: Option<f64>) -> Result<Quat> {
    if !t.is_finite() {
        bail!("time {t} is not a finite number of seconds");
    }
    if let Some(last) = last_t
        && t < last
    {
        bail!("time went backwards: {t} s after {last} s");
    }
    let q = pose.q;
    if !q.is_finite() || (q.length() - 1.0).abs() > UNIT_TOLERANCE {
        bail!("pose at {t} s is not a unit quaternion: {q:?}");
    }
    Ok(q.normalize())
}

impl Assistant {
    pub fn new(cfg: AssistantConfig) -> Result<Assistant> {
        cfg.validate()?;
        let samples: Vec<Vec3> = (0..6)
            .flat_map(|layer| {
                (0..COVER_SAMPLES * COVER_SAMPLES)
                    .map(move |i| face_pixel_dir_local(layer, i % COVER_SAMPLES, i / COVER_SAMPLES, COVER_SAMPLES, 1.0))
            })
            .collect();
        let states = plan_targets(cfg.mode, &cfg.camera, cfg.tolerance_deg)
            .into_iter()
            .map(|target| {
                let planned = seen_samples(&cfg.camera, &samples, target.pose(0.0).as_quat(), cfg.tolerance_deg);
                TargetState::new(target, planned)
            })
            .collect();
        Ok(Assistant {
            covered: vec![false; samples.len()],
            samples,
            repairs: 0,
            views: 0,
            cfg,
            states,
            reference_heading_deg: None,
            history: VecDeque::new(),
            last_t: None,
            rate_deg_s: 0.0,
            on_target: None,
            last_pose: None,
        })
    }

    pub fn config(&self) -> &AssistantConfig {
        &self.cfg
    }

    /// Turn the gain compensation on or off ([`AssistantConfig::gain_compensation`]): on when
    /// the camera could not lock its exposure at the tap.
    pub fn set_gain_compensation(&mut self, on: bool) {
        self.cfg.gain_compensation = on;
    }

    /// All targets, the front first.
    pub fn targets(&self) -> Vec<&Target> {
        self.states.iter().map(|s| &s.target).collect()
    }

    /// The reference heading (degrees, clockwise from North) once the front is taken.
    pub fn reference_heading_deg(&self) -> Option<f64> {
        self.reference_heading_deg
    }

    pub fn phase(&self) -> Phase {
        if self.reference_heading_deg.is_none() {
            Phase::WaitingForTap
        } else if match self.cfg.mode {
            Mode::Stretch => self.states.iter().all(TargetState::done),
            Mode::Stitch => Face::ALL.iter().all(|f| self.face_done(*f)),
        } {
            Phase::Complete
        } else {
            Phase::Capturing
        }
    }

    /// The aim tolerance in force now (degrees): the configured tolerance plus
    /// [`AIM_SIGMAS`] times the latest pose's 1σ accuracy estimate (at most [`MAX_SIGMA_DEG`]).
    pub fn tolerance_now(&self) -> f64 {
        let sigma = self.last_pose.map_or(0.0, |p| f64::from(p.accuracy_deg));
        let sigma = if sigma.is_finite() { sigma.clamp(0.0, MAX_SIGMA_DEG) } else { MAX_SIGMA_DEG };
        self.cfg.tolerance_deg + AIM_SIGMAS * sigma
    }

    /// Fraction of the sphere's coverage samples some shot has seen.
    pub fn coverage(&self) -> f64 {
        self.covered.iter().filter(|c| **c).count() as f64 / self.covered.len().max(1) as f64
    }

    /// The shot taken for target `index`, if any.
    pub fn shot(&self, index: usize) -> Option<&Shot> {
        self.states.get(index).and_then(|s| s.shot.as_ref())
    }

    /// The latest measured angular rate (degrees/s).
    pub fn rate_deg_s(&self) -> f64 {
        self.rate_deg_s
    }

    fn push_pose(&mut self, t: f64, q: Quat) {
        self.history.push_back((t, q));
        // Keep the samples inside the window, and always the previous one.
        while self.history.len() > 2 && self.history[0].0 < t - RATE_WINDOW_S {
            self.history.pop_front();
        }
        let (t0, q0) = self.history[0];
        self.rate_deg_s = if t > t0 { angle_between_f32(q0, q).to_degrees() / (t - t0) } else { self.rate_deg_s };
        self.last_t = Some(t);
    }

    /// The user taps the shutter: while waiting for the tap, `frame` becomes the front shot
    /// and the pose's heading the reference. Returns whether the tap was used (later taps are
    /// ignored: the other faces are taken automatically).
    pub fn tap(&mut self, t: f64, pose: &Pose, frame: Arc<Rgba8Image>) -> Result<bool> {
        let q = check_input(t, pose, self.last_t)?;
        if self.phase() != Phase::WaitingForTap {
            return Ok(false);
        }
        self.push_pose(t, q);
        self.last_pose = Some(*pose);
        let heading = heading_pitch_roll(q.as_dquat()).heading.to_degrees();
        self.reference_heading_deg = Some(heading);
        let front = self.states.iter().position(|s| s.target.primary && s.target.face == Face::Front).unwrap_or(0);
        self.store(front, t, pose, q, frame);
        Ok(true)
    }

    fn store(&mut self, index: usize, t: f64, pose: &Pose, q: Quat, image: Arc<Rgba8Image>) {
        let s = &mut self.states[index];
        s.shot = Some(Shot { target: index, t, pose: q, image, gravity: None });
        s.heading_source = Some(pose.heading_source);
        s.accuracy_deg = pose.accuracy_deg;
        self.on_target = None;
        if self.cfg.mode == Mode::Stitch
            && let Some(href) = self.reference_heading_deg
        {
            self.update_coverage(href, q);
        }
    }

    /// Stitch mode: mark what the new shot sees, drop planned targets already seen by others,
    /// and add a repair target when the plan is used up but samples are still unseen.
    fn update_coverage(&mut self, href: f64, q: Quat) {
        let local = world_to_local(href).as_quat() * q;
        for i in seen_samples(&self.cfg.camera, &self.samples, local, COVER_MARGIN_DEG) {
            self.covered[i as usize] = true;
        }
        let covered = &self.covered;
        for s in self.states.iter_mut().filter(|s| s.shot.is_none()) {
            if s.planned.iter().all(|&i| covered[i as usize]) {
                s.covered_by_others = true;
            }
        }
        if self.states.iter().all(TargetState::done)
            && !Face::ALL.iter().all(|f| self.face_done(*f))
            && let Some(target) = self.repair_target()
        {
            let planned = seen_samples(&self.cfg.camera, &self.samples, target.pose(0.0).as_quat(), self.cfg.tolerance_deg);
            self.states.push(TargetState::new(target, planned));
        }
    }

    /// A target aimed at the unseen samples: the unseen sample with the most unseen samples
    /// within a third of the lens's smaller half-angle, so one shot takes the whole hole.
    fn repair_target(&mut self) -> Option<Target> {
        let unseen: Vec<Vec3> = self.samples.iter().zip(&self.covered).filter(|(_, c)| !**c).map(|(d, _)| *d).collect();
        let reach = (self.cfg.camera.tan_half_h.min(self.cfg.camera.tan_half_v).atan() / 3.0).cos();
        let best = unseen.iter().max_by_key(|d| unseen.iter().filter(|e| d.dot(**e) >= reach).count())?;
        let mean = unseen.iter().filter(|e| best.dot(**e) >= reach).fold(Vec3::ZERO, |a, e| a + *e).normalize_or(*best);
        self.repairs += 1;
        let face = Face::of_local_dir(mean);
        let heading = f64::from(mean.x.atan2(mean.y).to_degrees());
        Some(Target {
            name: format!("{}+fix{}", face.name(), self.repairs),
            face,
            primary: false,
            heading_offset_deg: wrap_degrees_360(heading),
            pitch_deg: f64::from(mean.z.clamp(-1.0, 1.0).asin().to_degrees()),
        })
    }

    /// A new estimated pose at time `t`: updates the rate and the per-target records, and
    /// returns the target to take *now* (the caller then passes the current frame to
    /// [`Assistant::capture`]). Time must not go backwards; the pose must be a unit quaternion.
    pub fn observe(&mut self, t: f64, pose: &Pose) -> Result<Option<usize>> {
        let q = check_input(t, pose, self.last_t)?;
        self.push_pose(t, q);
        self.last_pose = Some(*pose);
        let Some(href) = self.reference_heading_deg else { return Ok(None) };
        let steady = self.rate_deg_s <= self.cfg.max_rate_deg_s;
        let tolerance = self.tolerance_now();
        let dq = q.as_dquat();
        let hpr = heading_pitch_roll(dq);
        let mut best: Option<(usize, f64)> = None;
        for (i, s) in self.states.iter_mut().enumerate().filter(|(_, s)| !s.done()) {
            let e = s.target.aim_error_hpr(href, dq, hpr);
            if e.angle_deg < s.closest_deg {
                s.closest_deg = e.angle_deg;
                s.closest_t = t;
            }
            if e.within(tolerance) {
                s.ever_within = true;
                s.slowest_within = s.slowest_within.min(self.rate_deg_s);
                if best.is_none_or(|(_, a)| e.angle_deg < a) {
                    best = Some((i, e.angle_deg));
                }
            }
        }
        match (best, steady) {
            (Some((i, _)), true) => {
                let since = match self.on_target {
                    Some((j, since)) if j == i => since,
                    _ => t,
                };
                self.on_target = Some((i, since));
                let s = &mut self.states[i];
                s.longest_dwell = s.longest_dwell.max(t - since);
                Ok((t - since >= self.cfg.dwell_s).then_some(i))
            }
            (None, true) if self.cfg.mode == Mode::Stitch && self.adds_coverage(href, q) => {
                // Steady on no target, but the view sees enough of what is still missing.
                let since = match self.on_target {
                    Some((FREE_VIEW, since)) => since,
                    _ => t,
                };
                self.on_target = Some((FREE_VIEW, since));
                if t - since < self.cfg.dwell_s {
                    return Ok(None);
                }
                self.views += 1;
                let local = world_to_local(href).as_quat() * (dq.as_quat() * Vec3::NEG_Z);
                let face = Face::of_local_dir(local);
                let target = Target {
                    name: format!("{}+view{}", face.name(), self.views),
                    face,
                    primary: false,
                    heading_offset_deg: wrap_degrees_360(f64::from(local.x.atan2(local.y).to_degrees())),
                    pitch_deg: f64::from(local.z.clamp(-1.0, 1.0).asin().to_degrees()),
                };
                self.states.push(TargetState::new(target, Vec::new()));
                Ok(Some(self.states.len() - 1))
            }
            _ => {
                self.on_target = None;
                Ok(None)
            }
        }
    }

    /// Stitch mode: whether a view at pose `q` (camera → world) would see at least
    /// [`MIN_NEW_FRACTION`] of its coverage samples (and [`MIN_NEW_SAMPLES`]) not yet seen.
    fn adds_coverage(&self, href: f64, q: Quat) -> bool {
        let local = world_to_local(href).as_quat() * q;
        let seen = seen_samples(&self.cfg.camera, &self.samples, local, self.cfg.tolerance_deg * PLAN_MARGIN);
        let new = seen.iter().filter(|&&i| !self.covered[i as usize]).count();
        new >= MIN_NEW_SAMPLES && new as f64 >= MIN_NEW_FRACTION * seen.len() as f64
    }

    /// The accelerometer held before the shot taken at time `t` (the tap or a capture;
    /// [`super::gravity::GravityLog::held`]): the joint alignment levels the capture with it.
    /// Nothing happens when no shot was taken at `t`.
    pub fn set_shot_gravity(&mut self, t: f64, gravity: Option<super::gravity::HeldGravity>) {
        if let Some(shot) = self.states.iter_mut().filter_map(|s| s.shot.as_mut()).find(|s| s.t == t) {
            shot.gravity = gravity;
        }
    }

    /// Take the shot for target `index` (as returned by [`Assistant::observe`]) from `frame`
    /// seen at pose `pose` and time `t`.
    pub fn capture(&mut self, index: usize, t: f64, pose: &Pose, frame: Arc<Rgba8Image>) -> Result<()> {
        let q = check_input(t, pose, None)?;
        let Some(s) = self.states.get(index) else { bail!("no capture target {index}") };
        if s.done() {
            bail!("target {} is already captured", s.target.name);
        }
        if self.phase() == Phase::WaitingForTap {
            bail!("the front must be taken (tap) before other targets");
        }
        if (frame.width, frame.height) != (self.cfg.camera.width, self.cfg.camera.height) {
            bail!(
                "frame is {}x{}, the assistant was set up for {}x{}",
                frame.width,
                frame.height,
                self.cfg.camera.width,
                self.cfg.camera.height
            );
        }
        self.store(index, t, pose, q, frame);
        Ok(())
    }

    /// One frame: tap (when `tap`), else observe and, if a target is due, take it from `frame`.
    /// Returns the target taken, if any.
    pub fn feed(&mut self, frame: &Arc<Rgba8Image>, pose: &Pose, t: f64, tap: bool) -> Result<Option<usize>> {
        if tap && self.phase() == Phase::WaitingForTap {
            self.tap(t, pose, frame.clone())?;
            return Ok(Some(0));
        }
        match self.observe(t, pose)? {
            Some(i) => {
                self.capture(i, t, pose, frame.clone())?;
                Ok(Some(i))
            }
            None => Ok(None),
        }
    }

    /// Stitch mode: how many of `face`'s coverage samples no shot has seen, of how many.
    fn face_unseen(&self, face: Face) -> (usize, usize) {
        let n = (COVER_SAMPLES * COVER_SAMPLES) as usize;
        (self.covered[face.layer() * n..(face.layer() + 1) * n].iter().filter(|c| !**c).count(), n)
    }

    /// Stitch mode: the share of `face`'s coverage samples some shot has seen.
    fn face_coverage(&self, face: Face) -> f64 {
        let (unseen, n) = self.face_unseen(face);
        (n - unseen) as f64 / n as f64
    }

    fn face_done(&self, face: Face) -> bool {
        match self.cfg.mode {
            Mode::Stretch => self.states.iter().filter(|s| s.target.face == face).all(TargetState::done),
            Mode::Stitch => {
                let (unseen, n) = self.face_unseen(face);
                unseen as f64 <= MAX_UNSEEN * n as f64
            }
        }
    }

    /// What to show the user now.
    pub fn guidance(&self) -> Guidance {
        let phase = self.phase();
        let face_done = Face::ALL.map(|f| phase != Phase::WaitingForTap && self.face_done(f));
        let gyro_only = self.last_pose.is_some_and(|p| p.heading_source == HeadingSource::GyroOnly || p.magnetic_disturbance);
        let hold_still = self.rate_deg_s > self.cfg.max_rate_deg_s;
        let tolerance = self.tolerance_now();
        let next = match (self.reference_heading_deg, self.last_pose) {
            (Some(href), Some(pose)) => self
                .states
                .iter()
                .enumerate()
                .find(|(_, s)| !s.done())
                .map(|(i, s)| (i, s, s.target.aim_error(href, pose.q.as_dquat())))
                .map(|(i, s, e)| {
                    let dir = pose.q.inverse() * s.target.direction(href).as_vec3();
                    let within = e.within(tolerance);
                    NextTarget {
                        index: i,
                        name: s.target.name.clone(),
                        face: s.target.face,
                        arrow: if within { Vec2::ZERO } else { Vec2::new(dir.x, dir.y).normalize_or_zero() },
                        on_screen: self.cfg.camera.to_ndc(dir).filter(|n| n.abs().max_element() <= 1.0),
                        angle_deg: e.angle_deg,
                        within,
                        tolerance_deg: tolerance,
                    }
                }),
            _ => None,
        };
        let shots_done = self.states.iter().filter(|s| s.shot.is_some()).count();
        let face_progress = Face::ALL.map(|f| match (phase, self.cfg.mode) {
            (Phase::WaitingForTap, _) => 0.0,
            (_, Mode::Stitch) => self.face_coverage(f),
            (_, Mode::Stretch) => f64::from(u8::from(self.face_done(f))),
        });
        let steady_progress = match (self.on_target, self.last_t) {
            (Some((_, since)), Some(t)) if phase == Phase::Capturing && !hold_still => {
                if self.cfg.dwell_s > 0.0 {
                    ((t - since) / self.cfg.dwell_s).clamp(0.0, 1.0)
                } else {
                    1.0
                }
            }
            _ => 0.0,
        };
        let message = match (phase, &next) {
            (Phase::WaitingForTap, _) => "Aim at the front and tap".to_string(),
            (Phase::Complete, _) => "Capture complete".to_string(),
            _ if hold_still => "Hold still".to_string(),
            (_, Some(n)) if n.within => format!("Hold on {}…", n.name),
            (_, Some(n)) => format!("Turn to {}", n.name),
            (_, None) => String::new(),
        };
        Guidance {
            phase,
            next,
            faces_done: face_done.iter().filter(|d| **d).count(),
            shots_done,
            shots_total: self.states.iter().filter(|s| !s.covered_by_others).count(),
            face_done,
            face_progress,
            coverage: match self.cfg.mode {
                Mode::Stitch => self.coverage(),
                Mode::Stretch => face_done.iter().filter(|d| **d).count() as f64 / 6.0,
            },
            hold_still,
            rate_deg_s: self.rate_deg_s,
            steady_progress,
            heading_source: self.last_pose.map(|p| p.heading_source),
            heading_accuracy_deg: self.last_pose.map(|p| p.heading_accuracy_deg),
            gyro_only,
            message,
        }
    }

    /// The faces not complete yet, each with the reason in words.
    pub fn missing(&self) -> Vec<(Face, String)> {
        let tol = format!("{:.1}", self.tolerance_now());
        let n = (COVER_SAMPLES * COVER_SAMPLES) as usize;
        Face::ALL
            .iter()
            .filter(|&&f| self.reference_heading_deg.is_none() || !self.face_done(f))
            .map(|&f| {
                if self.reference_heading_deg.is_none() {
                    return (f, "no tap: the front (and with it the reference heading) was never taken".to_string());
                }
                let reasons: Vec<String> = self
                    .states
                    .iter()
                    .filter(|s| s.target.face == f && !s.done())
                    .map(|s| {
                        let why = if !s.ever_within {
                            if s.closest_deg.is_finite() {
                                format!("never within ±{tol}° (closest {:.1}° off, at {:.2} s)", s.closest_deg, s.closest_t)
                            } else {
                                "never aimed at after the tap".to_string()
                            }
                        } else if s.slowest_within > self.cfg.max_rate_deg_s {
                            format!(
                                "within ±{tol}° but never held steady (slowest {:.1}°/s, limit {}°/s)",
                                s.slowest_within, self.cfg.max_rate_deg_s
                            )
                        } else {
                            format!("held on target only {:.2} s (needs {} s)", s.longest_dwell, self.cfg.dwell_s)
                        };
                        if s.target.primary { why } else { format!("{}: {why}", s.target.name) }
                    })
                    .collect();
                // Stitch mode can leave many shots of a face untaken: name a few.
                const SHOWN: usize = 3;
                let mut text = reasons.iter().take(SHOWN).cloned().collect::<Vec<_>>().join("; ");
                if reasons.len() > SHOWN {
                    text += &format!("; and {} more shot(s) not taken", reasons.len() - SHOWN);
                }
                if self.cfg.mode == Mode::Stitch {
                    let unseen = self.covered[f.layer() * n..(f.layer() + 1) * n].iter().filter(|c| !**c).count();
                    let seen = format!("{:.0}% of the face unseen", 100.0 * unseen as f64 / n as f64);
                    text = if text.is_empty() { seen } else { format!("{seen}: {text}") };
                }
                (f, text)
            })
            .collect()
    }

    /// `face` as the shots taken so far assemble it, `size` texels a side, as [`Assistant::finish`]
    /// assembles it (stitch mode: every shot that sees a texel, blended; stretch mode: the face's
    /// own shot) but with the shots placed and exposed as taken — the joint alignment and the gain
    /// compensation run once, at the end. What the capture screen's thumbnails show. None before
    /// the tap and, in stretch mode, until the face's own shot is in.
    pub fn face_so_far(&self, face: Face, size: u32) -> Option<FaceImage> {
        let href = self.reference_heading_deg?;
        let shots: Vec<Shot> = self.states.iter().filter_map(|s| s.shot.clone()).collect();
        let primary = match self.cfg.mode {
            Mode::Stretch => {
                let i = self.states.iter().position(|s| s.target.primary && s.target.face == face)?;
                shots.iter().find(|s| s.target == i)?
            }
            // Stitch mode blends every shot; the primary is not used.
            Mode::Stitch => shots.first()?,
        };
        Some(assemble_face(face, self.cfg.mode, primary, &shots, &self.cfg.camera, href, size))
    }

    /// Assemble the six faces (in parallel) once every target has its shot; otherwise an
    /// error naming each missing face and why.
    pub fn finish(&self) -> Result<CubeCapture> {
        let missing = self.missing();
        let Some(href) = self.reference_heading_deg.filter(|_| missing.is_empty()) else {
            let lines: Vec<String> = missing.iter().map(|(f, why)| format!("  {}: {why}", f.name())).collect();
            bail!("capture incomplete: {} face(s) missing\n{}", missing.len(), lines.join("\n"));
        };
        let cfg = &self.cfg;
        let taken: Vec<Shot> = self.states.iter().filter_map(|s| s.shot.clone()).collect();
        // The front (the tap) is the first shot and keeps its pose and light: it defines the
        // reference heading and the exposure. The alignment compares shots whose light was
        // scaled to the front's (estimated with the sensor poses); the final gains are estimated
        // again with the aligned poses, on the shots as taken.
        let compensate = |shots: &[Shot]| super::gain::compensate(&cfg.camera, shots, 0);
        let (taken, alignment) = match cfg.mode {
            Mode::Stitch if cfg.align => {
                let (aligned, a) = if cfg.gain_compensation {
                    align_shots(&cfg.camera, &compensate(&taken).0, 0)
                } else {
                    align_shots(&cfg.camera, &taken, 0)
                };
                (taken.iter().zip(aligned).map(|(raw, al)| Shot { pose: al.pose, ..raw.clone() }).collect(), Some(a))
            }
            _ => (taken, None),
        };
        let (shots, gains) = if cfg.gain_compensation {
            let (shots, g) = compensate(&taken);
            (shots, Some(g.gains))
        } else {
            (taken, None)
        };
        // The face's own shot: stretch mode, its centre target's; stitch mode, the shot whose
        // view axis is closest to the face centre (the centre target may have been dropped).
        let to_local = world_to_local(href).as_quat();
        let primary = |face: Face| -> Option<&Shot> {
            match cfg.mode {
                Mode::Stretch => {
                    let i = self.states.iter().position(|s| s.target.primary && s.target.face == face)?;
                    shots.iter().find(|s| s.target == i)
                }
                Mode::Stitch => {
                    let centre = face_pixel_dir_local(face.layer(), 0, 0, 1, 1.0);
                    let axis = |s: &Shot| (to_local * s.pose * Vec3::NEG_Z).dot(centre);
                    shots.iter().max_by(|a, b| axis(a).total_cmp(&axis(b)))
                }
            }
        };
        let faces: Vec<FaceImage> = std::thread::scope(|scope| {
            let handles: Vec<_> = Face::ALL
                .iter()
                .filter_map(|&face| {
                    let shot = primary(face)?;
                    let shots = &shots;
                    Some(scope.spawn(move || assemble_face(face, cfg.mode, shot, shots, &cfg.camera, href, cfg.face_size)))
                })
                .collect();
            handles.into_iter().filter_map(|h| h.join().ok()).collect()
        });
        if faces.len() != 6 {
            bail!("face assembly failed for {} face(s)", 6 - faces.len());
        }
        let face_meta = faces
            .iter()
            .filter_map(|f| {
                let shot = primary(f.face)?;
                let s = &self.states[shot.target];
                Some(FaceMeta::new(f.face, shot, s.heading_source, s.accuracy_deg, f.coverage))
            })
            .collect();
        let shot_meta = shots
            .iter()
            .enumerate()
            .map(|(k, shot)| {
                let s = &self.states[shot.target];
                let mut m = ShotMeta::new(&s.target, shot, s.heading_source);
                m.alignment_turn_deg = alignment.as_ref().and_then(|a| a.turns_deg.get(k).copied());
                m.gain = gains.as_ref().and_then(|g| g.get(k).copied());
                m
            })
            .collect();
        let mut meta = CaptureMeta::new(cfg, href, face_meta, shot_meta);
        meta.alignment = alignment.map(|a| AlignmentMeta {
            pairs: a.pairs.len(),
            dropped_pairs: a.dropped,
            vertical_correction_deg: a.leveling.map(|l| l.angle_deg()),
            vertical_shots: a.leveling.map_or(0, |l| l.shots),
        });
        CubeCapture::new(meta, faces)
    }
}

/// Indices of the `samples` (capture-local directions) a camera with capture-local pose `local`
/// sees, inside its frame shrunk by `margin_deg` on every side.
fn seen_samples(camera: &Pinhole, samples: &[Vec3], local: Quat, margin_deg: f64) -> Vec<u32> {
    let m = margin_deg.to_radians() as f32;
    let th = (camera.tan_half_h.atan() - m).max(0.0).tan() / camera.tan_half_h;
    let tv = (camera.tan_half_v.atan() - m).max(0.0).tan() / camera.tan_half_v;
    let inv = local.inverse();
    (0..samples.len() as u32)
        .filter(|&i| camera.to_ndc(inv * samples[i as usize]).is_some_and(|n| n.x.abs() <= th && n.y.abs() <= tv))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::projection::local_to_world;
    use crate::pose::frames::from_heading_pitch_roll;

    fn pose(q: glam::DQuat) -> Pose {
        Pose {
            t: 0.0,
            q: q.as_quat(),
            accuracy_deg: 1.0,
            heading_accuracy_deg: 1.0,
            tilt_accuracy_deg: 0.5,
            heading_source: HeadingSource::Magnetometer,
            magnetic_disturbance: false,
        }
    }

    fn aim(h: f64, p: f64) -> Pose {
        pose(from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.0))
    }

    fn frame(cam: &Pinhole) -> Arc<Rgba8Image> {
        Arc::new(Rgba8Image { width: cam.width, height: cam.height, pixels: vec![128; (cam.width * cam.height * 4) as usize] })
    }

    fn assistant(mode: Mode) -> (Assistant, Arc<Rgba8Image>) {
        let cam = Pinhole::from_vfov(64, 48, 60.0).unwrap();
        let mut cfg = AssistantConfig::new(mode, cam);
        cfg.face_size = 16;
        (Assistant::new(cfg).unwrap(), frame(&cam))
    }

    /// Hold an aim from t0 for `secs` at 30 Hz; returns the targets taken.
    fn hold(a: &mut Assistant, f: &Arc<Rgba8Image>, p: Pose, t0: f64, secs: f64) -> Vec<usize> {
        let mut taken = Vec::new();
        let n = (secs * 30.0) as usize;
        for k in 0..=n {
            if let Some(i) = a.feed(f, &p, t0 + k as f64 / 30.0, false).unwrap() {
                taken.push(i);
            }
        }
        taken
    }

    /// The face assembled so far blends every shot taken: a front face seen half by a shot
    /// turned left and half by one turned right shows both halves (the world's colour at each
    /// texel's direction), where the front shot alone shows neither.
    #[test]
    fn a_face_seen_by_two_half_covering_shots_shows_both_halves() {
        // 40°x30° lens; the world is red left of heading -25°, blue right of +25°, grey between.
        let cam = Pinhole::from_vfov(80, 60, 30.0).unwrap();
        let colour = |d: Vec3| -> [u8; 3] {
            let az = d.x.atan2(d.y).to_degrees();
            if az < -25.0 {
                [200, 20, 20]
            } else if az > 25.0 {
                [20, 20, 200]
            } else {
                [120, 120, 120]
            }
        };
        let shot = |h: f64| (aim(h, 0.0), Arc::new(super::super::reproject::render_synthetic(&cam, aim(h, 0.0).q, &colour)));
        let mut a = Assistant::new(AssistantConfig::new(Mode::Stitch, cam)).unwrap();
        assert!(a.face_so_far(Face::Front, 32).is_none(), "nothing before the tap");
        let (p, f) = shot(0.0);
        a.tap(1.0, &p, f).unwrap();
        // The share of the front face's texels showing the world's colour in their direction.
        let matching = |a: &Assistant| {
            let face = a.face_so_far(Face::Front, 32).unwrap();
            let n = face.rgb.len() / 3;
            let ok = (0..n)
                .filter(|&i| {
                    let d = face_pixel_dir_local(Face::Front.layer(), (i % 32) as u32, (i / 32) as u32, 32, 1.0);
                    let want = colour(local_to_world(0.0).as_quat() * d);
                    (0..3).all(|c| (i32::from(face.rgb[3 * i + c]) - i32::from(want[c])).abs() <= 30)
                })
                .count();
            ok as f64 / n as f64
        };
        let front_only = matching(&a);
        // Two shots, 32° left and right: together they see the face's width (±45°).
        let free: Vec<usize> = (0..a.targets().len()).filter(|&i| a.shot(i).is_none()).take(2).collect();
        for (k, h) in [(free[0], -32.0), (free[1], 32.0)] {
            let (p, f) = shot(h);
            a.capture(k, 2.0, &p, f).unwrap();
        }
        let both = matching(&a);
        eprintln!("texels matching the world: front shot alone {front_only:.3}, with both half-covering shots {both:.3}");
        assert!(both >= 0.95, "the face shows both halves: {:.1}% of its texels match the world", 100.0 * both);
        assert!(front_only < 0.7, "the front shot alone shows neither half: {:.1}% match", 100.0 * front_only);
    }

    #[test]
    fn faces_in_any_order_across_the_wrap() {
        let (mut a, f) = assistant(Mode::Stretch);
        assert_eq!(a.guidance().message, "Aim at the front and tap");
        // Nothing is taken before the tap, even on a face target.
        assert!(hold(&mut a, &f, aim(0.0, 90.0), 0.0, 1.0).is_empty());
        // Tap facing 358.5°: reference heading 358.5.
        assert!(a.tap(1.1, &aim(358.5, 0.0), f.clone()).unwrap());
        assert!((a.reference_heading_deg().unwrap() - 358.5).abs() < 1e-3);
        assert_eq!(a.phase(), Phase::Capturing);
        let mut t = 1.2;
        // Right is at 88.5°, back at 178.5°, left at 268.5° (across 0/360 from the reference).
        for (h, p, name) in [(0.0, -89.0, "down"), (87.0, 1.0, "right"), (268.5, -1.5, "left"), (180.0, 0.5, "back"), (40.0, 88.2, "up")] {
            let taken = hold(&mut a, &f, aim(h, p), t, 0.5);
            assert_eq!(taken.len(), 1, "{name}: {taken:?}");
            assert_eq!(a.targets()[taken[0]].name, name);
            t += 0.6;
        }
        assert_eq!(a.phase(), Phase::Complete);
        let g = a.guidance();
        assert_eq!((g.faces_done, g.shots_done, g.shots_total), (6, 6, 6));
        let cap = a.finish().unwrap();
        assert_eq!(cap.faces.len(), 6);
        assert!((cap.meta.reference_heading_deg - 358.5).abs() < 1e-3);
    }

    #[test]
    fn off_target_or_moving_takes_nothing_and_says_why() {
        let (mut a, f) = assistant(Mode::Stretch);
        a.tap(0.0, &aim(10.0, 0.0), f.clone()).unwrap();
        // The pose claims 1° accuracy: the tolerance is 2° + 2σ = 4°. 4.5° off the right face:
        // never taken.
        assert_eq!(a.tolerance_now(), 4.0);
        assert!(hold(&mut a, &f, aim(104.5, 0.0), 0.1, 1.0).is_empty());
        // Sweeping through the back target at 30°/s: within tolerance but too fast.
        let mut t = 1.2;
        for k in 0..60 {
            let h = 180.0 + (k as f64 - 30.0) * 1.0;
            assert_eq!(a.feed(&f, &aim(h, 0.0), t, false).unwrap(), None, "at {h}");
            t += 1.0 / 30.0;
        }
        assert!(a.guidance().hold_still);
        let err = format!("{:#}", a.finish().unwrap_err());
        assert!(err.contains("5 face(s) missing"), "{err}");
        assert!(err.contains("right: never within ±4.0° (closest 4.5° off"), "{err}");
        assert!(err.contains("back: within ±4.0° but never held steady"), "{err}");
        assert!(err.contains("up: never within"), "{err}");
        // Steady but for less than the dwell time: not taken, and the reason says so.
        assert!(hold(&mut a, &f, aim(100.0, 0.0), 5.0, 0.15).is_empty());
        assert!(format!("{:#}", a.finish().unwrap_err()).contains("right: held on target only 0.1"));
    }

    #[test]
    fn bad_input_is_refused() {
        let (mut a, f) = assistant(Mode::Stretch);
        a.tap(1.0, &aim(0.0, 0.0), f.clone()).unwrap();
        assert!(a.observe(0.5, &aim(0.0, 0.0)).unwrap_err().to_string().contains("backwards"));
        let mut bad = aim(0.0, 0.0);
        bad.q = Quat::from_xyzw(0.0, 0.0, 0.0, 2.0);
        assert!(a.observe(2.0, &bad).unwrap_err().to_string().contains("unit quaternion"));
        bad.q = Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0);
        assert!(a.observe(2.0, &bad).is_err());
        assert!(a.observe(f64::NAN, &aim(0.0, 0.0)).is_err());
        let small = Arc::new(Rgba8Image { width: 2, height: 2, pixels: vec![0; 16] });
        assert!(a.capture(1, 3.0, &aim(0.0, 90.0), small).is_err());
        assert!(a.capture(99, 3.0, &aim(0.0, 90.0), f.clone()).is_err());
        let cam = Pinhole::from_vfov(64, 48, 60.0).unwrap();
        let mut cfg = AssistantConfig::new(Mode::Stretch, cam);
        cfg.face_size = 100;
        assert!(Assistant::new(cfg.clone()).unwrap_err().to_string().contains("power of two"));
        cfg.face_size = 256;
        cfg.tolerance_deg = f64::NAN;
        assert!(Assistant::new(cfg).is_err());
        // No tap at all: every face missing, the reason says so.
        let (b, _) = assistant(Mode::Stretch);
        assert!(format!("{:#}", b.finish().unwrap_err()).contains("front: no tap"));
    }

    #[test]
    fn guidance_points_at_the_next_target_of_the_tour_and_flags_gyro_only() {
        let (mut a, f) = assistant(Mode::Stretch);
        // The stretch plan's tour from the front: up, then round the horizon, then down.
        let names: Vec<&str> = a.targets().iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["front", "up", "left", "back", "right", "down"]);
        a.tap(0.0, &aim(0.0, 0.0), f.clone()).unwrap();
        // A quick turn to heading 60: "Hold still" while the rate is high.
        a.observe(0.1, &aim(60.0, 0.0)).unwrap();
        assert!(a.guidance().hold_still);
        assert_eq!(a.guidance().message, "Hold still");
        // Held there: the next target is up (90° away), arrow straight up, not in view.
        a.observe(0.25, &aim(60.0, 0.0)).unwrap();
        let g = a.guidance();
        assert!(!g.hold_still);
        let n = g.next.unwrap();
        assert_eq!(n.name, "up");
        assert!((n.angle_deg - 90.0).abs() < 1e-3);
        assert!(n.arrow.y > 0.99 && n.arrow.x.abs() < 1e-3, "{:?}", n.arrow);
        assert!(n.on_screen.is_none());
        assert_eq!(g.message, "Turn to up");
        assert_eq!(g.faces_done, 1);
        // Up taken: next is left (heading 270), 30° to the left of a view at heading 300.
        hold(&mut a, &f, aim(0.0, 90.0), 0.4, 0.5);
        a.observe(1.0, &aim(300.0, 0.0)).unwrap();
        let n = a.guidance().next.unwrap();
        assert_eq!(n.name, "left");
        assert!(n.arrow.x < -0.99, "{:?}", n.arrow);
        // Hfov of a 4:3 60° lens is 75.2°: 30° off is in view, left of centre.
        assert!(n.on_screen.unwrap().x < -0.5);
        let mut p = aim(300.0, 0.0);
        p.heading_source = HeadingSource::GyroOnly;
        a.observe(1.1, &p).unwrap();
        let g = a.guidance();
        assert!(g.gyro_only);
        assert_eq!(g.heading_source, Some(HeadingSource::GyroOnly));
        // Stretch mode: front and up are in (Face::ALL: front, up, down, right, back, left).
        assert_eq!(g.face_progress, [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn guidance_shows_steadiness_and_faces_filling_in() {
        let (mut a, f) = assistant(Mode::Stitch);
        assert_eq!(a.guidance().face_progress, [0.0; 6]);
        a.tap(0.0, &aim(0.0, 0.0), f.clone()).unwrap();
        // The front shot (a 60° lens) sees part of the front face only (Face::ALL: front, up,
        // down, right, back, left).
        let g = a.guidance();
        let front = g.face_progress[0];
        assert!(front > 0.3 && front < 1.0, "{:?}", g.face_progress);
        assert_eq!(g.face_progress[4], 0.0);
        assert_eq!(g.steady_progress, 0.0);
        // Steady on a target of the right face (dwell 0.2 s): 0.05 s in, a quarter held.
        let right = a.targets().iter().position(|t| t.face == Face::Right).unwrap();
        let r = aim(a.targets()[right].heading_offset_deg, a.targets()[right].pitch_deg);
        // Arriving at 1.0 s after a 90° turn is not steady; from 1.05 s the rate over the last
        // 0.1 s of poses is 0.
        assert_eq!(a.observe(1.0, &r).unwrap(), None);
        assert!(a.guidance().hold_still && a.guidance().steady_progress == 0.0);
        assert_eq!(a.observe(1.05, &r).unwrap(), None);
        assert_eq!(a.guidance().steady_progress, 0.0);
        assert_eq!(a.observe(1.1, &r).unwrap(), None);
        assert!((a.guidance().steady_progress - 0.25).abs() < 1e-9, "{}", a.guidance().steady_progress);
        assert_eq!(a.observe(1.15, &r).unwrap(), None);
        assert!((a.guidance().steady_progress - 0.5).abs() < 1e-9);
        // Turning away fast: not steady, no progress.
        a.observe(1.2, &aim(60.0, 30.0)).unwrap();
        assert_eq!(a.guidance().steady_progress, 0.0);
        // Taking the right view fills the right face in.
        hold(&mut a, &f, r, 2.0, 0.5);
        assert!(a.guidance().face_progress[3] > 0.3, "{:?}", a.guidance().face_progress);
    }

    /// A user who turns to whatever the guidance points at, while the estimate of each held
    /// aim is off by up to ±`err` degrees in heading and pitch (the pose claiming `sigma`).
    /// Returns whether the capture completed within `max_steps` holds, and the holds used.
    fn follow_guidance(mode: Mode, vfov: f32, err: f64, sigma: f32, max_steps: usize) -> (Assistant, usize) {
        let cam = Pinhole::from_vfov(64, 48, vfov).unwrap();
        let mut cfg = AssistantConfig::new(mode, cam);
        cfg.face_size = 16;
        let mut a = Assistant::new(cfg).unwrap();
        let f = frame(&cam);
        let claim = |mut p: Pose| {
            p.accuracy_deg = sigma;
            p
        };
        a.tap(0.0, &claim(aim(359.0, 0.0)), f.clone()).unwrap();
        let mut t = 0.1;
        for step in 0..max_steps {
            if a.phase() == Phase::Complete {
                return (a, step);
            }
            t += 1.0;
            a.observe(t, &claim(aim(359.0, 0.0))).unwrap();
            let next = a.guidance().next.expect("the guidance names a target while capturing");
            let target = a.targets()[next.index].clone();
            // Deterministic errors spanning ±err.
            let (eh, ep) = (err * ((step as f64) * 2.39).sin(), err * ((step as f64) * 1.77).cos());
            let (h, p) = (359.0 + target.heading_offset_deg + eh, (target.pitch_deg + ep).clamp(-90.0, 90.0));
            hold(&mut a, &f, claim(aim(h, p)), t + 0.1, 0.5);
        }
        (a, max_steps)
    }

    #[test]
    fn an_estimate_off_by_its_own_uncertainty_still_completes() {
        // Stretch and stitch, narrow and wide lens: every held aim's estimate is off by up to
        // 2.9° — more than the 2° tolerance — and the pose says its 1σ is 2.5°. Following the
        // guidance always finishes, and stitch mode sees the whole sphere.
        for (mode, vfov) in [(Mode::Stretch, 60.0), (Mode::Stitch, 60.0), (Mode::Stitch, 100.0)] {
            let (a, steps) = follow_guidance(mode, vfov, 2.9, 2.5, 200);
            assert_eq!(a.phase(), Phase::Complete, "{mode:?} {vfov}: {:?}", a.missing());
            let planned = plan_targets(mode, &a.config().camera, 2.0).len();
            assert!(steps <= planned + 3, "{mode:?} {vfov}: {steps} holds for {planned} planned targets");
            if mode == Mode::Stitch {
                assert!(a.coverage() >= 1.0 - MAX_UNSEEN, "{}", a.coverage());
            }
            let cap = a.finish().unwrap();
            assert_eq!(cap.faces.len(), 6);
        }
        // A pose that claims to be exact (σ 0) held 2.9° off: the plain ±2° box, not taken.
        let (mut a, f) = assistant(Mode::Stretch);
        let exact = |h, p| Pose { accuracy_deg: 0.0, ..aim(h, p) };
        a.tap(0.0, &exact(0.0, 0.0), f.clone()).unwrap();
        assert!(hold(&mut a, &f, exact(92.9, 0.0), 0.1, 1.0).is_empty());
        assert!(hold(&mut a, &f, Pose { accuracy_deg: 2.5, ..aim(92.9, 0.0) }, 1.2, 1.0).len() == 1);
    }
}
