//! The heading the guidance judges aims with, and the pose each shot is placed at.
//!
//! From the tap on, aims are judged with a copy of the fusion filter whose heading is held
//! ([`OrientationFilter::hold_heading`]): the heading relative to the front then comes from the
//! gyroscope, while the compass's error changes with heading by several degrees within a
//! capture. The gyroscope's bias about the world vertical, which nothing else observes (the
//! accelerometer sees only the tilt axes), makes that heading drift — ~1°/s at `bad` noise.
//! With the images on, each shot is matched against the earlier shots it overlaps
//! ([`turn_against`]); the measured turn is the held heading's drift since then, fed to the held
//! filter as a heading measurement ([`OrientationFilter::heading_fix`]), and the shot is placed
//! at the held heading (the joint alignment at the end weighs all overlaps). The same turn is
//! the gyroscope's bias integrated about the vertical between the two shots: the held filter
//! learns the bias from it ([`OrientationFilter::relative_heading`]), so the heading drifts less
//! from then on — also across shots that find no match. With the images off, shots keep the
//! compass-corrected pose.

use super::align::turn_against;
use super::projection::Pinhole;
use super::reproject::Shot;
use crate::pose::frames::DisplayRotation;
use crate::pose::fusion::{OrientationFilter, YawTrack};
use crate::pose::{OrientationEstimator, Pose};
use crate::scene::Rgba8Image;
use crate::sensors::Reading;
use anyhow::Result;
use glam::Quat;
use std::sync::Arc;

/// 1σ (degrees) of a heading drift measured by matching a shot against the earlier ones (the
/// match's fine search steps 0.1° and fits a parabola; a few texels of the small study frames).
pub const IMAGE_TURN_SIGMA_DEG: f64 = 0.3;

/// A shot's image match against an earlier shot while capturing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShotMatch {
    /// Time of the new shot (s).
    pub t: f64,
    /// Time of the earlier shot it was matched against (s).
    pub against_t: f64,
    /// The measured turn (degrees): the held heading's drift since the earlier shot, clockwise
    /// positive; the new shot is turned by it about the vertical.
    pub turn_deg: f64,
    /// Whether the held filter learnt its gyroscope bias from it (else rejected as
    /// inconsistent with the bias learnt so far).
    pub bias_learnt: bool,
}

/// Image matches teach the held filter the gyroscope bias only between views within this
/// elevation (degrees) of the horizon.
pub const BIAS_MATCH_ELEVATION_DEG: f64 = 30.0;

/// The guidance's heading during one capture (see the module documentation).
#[derive(Clone, Debug)]
pub struct AimHeading {
    camera: Pinhole,
    images: bool,
    held: Option<OrientationFilter>,
    /// The shots at the guidance's poses, each turned by its match against the earlier ones.
    shots: Vec<Shot>,
    /// Per shot, the held filter's [`YawTrack`] when it was taken (its turns including the
    /// shot's own).
    tracks: Vec<YawTrack>,
    matches: Vec<ShotMatch>,
}

impl AimHeading {
    /// `images`: use the shots' images to correct the drift and place the shots at the held
    /// heading.
    pub fn new(camera: Pinhole, images: bool) -> Self {
        AimHeading { camera, images, held: None, shots: Vec::new(), tracks: Vec::new(), matches: Vec::new() }
    }

    /// A sensor reading (the caller feeds its own fusion filter too).
    pub fn update(&mut self, r: &Reading) -> Result<()> {
        if let Some(f) = self.held.as_mut() {
            f.update(r)?;
        }
        Ok(())
    }

    /// The tap at time `t`: the heading is held from here, starting from `filter`'s state, and
    /// the front shot (`frame` at `pose`) is the first to match against.
    pub fn tap(&mut self, filter: &OrientationFilter, t: f64, pose: &Pose, frame: Arc<Rgba8Image>) {
        let mut held = filter.clone();
        held.hold_heading(t, true);
        self.tracks = vec![held.yaw_track()];
        self.matches.clear();
        self.held = Some(held);
        self.shots = vec![Shot { target: 0, t, pose: pose.q, image: frame, gravity: None }];
    }

    /// The pose to judge aims with: the fused `pose` before the tap; after it, its orientation
    /// from the held filter (with the fused filter's accuracy: the held filter's own 1σ assumes
    /// an unlearnt gyroscope bias and would widen the aim boxes to ±14° within seconds, so far
    /// that neighbouring shots leave gaps).
    pub fn aim_pose(&self, pose: Pose, rotation: DisplayRotation) -> Pose {
        self.held.as_ref().and_then(|f| f.pose(rotation)).map_or(pose, |held| Pose { q: held.q, ..pose })
    }

    /// A shot for target `target` at time `t`: `aim` is the aim pose it was taken at, `pose` the
    /// fused one. Returns the pose to record for it.
    pub fn shot(&mut self, target: usize, t: f64, aim: Pose, pose: Pose, frame: Arc<Rgba8Image>) -> Pose {
        let images = self.images;
        let Some(held) = self.held.as_mut().filter(|_| images) else { return pose };
        let mut shot = Shot { target, t, pose: aim.q, image: frame, gravity: None };
        let mut track = held.yaw_track();
        if let Some((against, turn)) = turn_against(&self.camera, &self.shots, &shot) {
            let sigma = IMAGE_TURN_SIGMA_DEG.to_radians();
            // The bias is learnt from matches between views near the horizon only: there the
            // overlaps are wide and textured, while on the ±45° rings (narrow overlaps of sky or
            // gravel) a match errs by up to ~2° now and then (measured at `phone` noise, seed 2:
            // 1.75° against 0.1° for every match on the horizon), and one such error, taken as
            // a bias, turns the held heading for the rest of the capture.
            let horizon = |pose: Quat| (pose * glam::Vec3::NEG_Z).z.abs() < BIAS_MATCH_ELEVATION_DEG.to_radians().sin() as f32;
            let bias_learnt = horizon(shot.pose)
                && horizon(self.shots[against].pose)
                && held.relative_heading(&self.tracks[against], turn.to_radians(), sigma).is_some();
            self.matches.push(ShotMatch { t, against_t: self.shots[against].t, turn_deg: turn, bias_learnt });
            held.heading_fix(t, turn.to_radians(), sigma);
            shot.pose = (Quat::from_rotation_z((turn as f32).to_radians()) * shot.pose).normalize();
            track.turns += turn.to_radians();
        }
        self.shots.push(shot);
        self.tracks.push(track);
        aim
    }

    /// Shots whose image match corrected the drift so far.
    pub fn drift_fixes(&self) -> usize {
        self.matches.len()
    }

    /// The image matches so far, in shot order.
    pub fn matches(&self) -> &[ShotMatch] {
        &self.matches
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::HeadingSource;
    use crate::pose::fusion::FusionConfig;

    fn pose(q: Quat) -> Pose {
        Pose {
            t: 0.0,
            q,
            accuracy_deg: 2.0,
            heading_accuracy_deg: 2.0,
            tilt_accuracy_deg: 0.5,
            heading_source: HeadingSource::Magnetometer,
            magnetic_disturbance: false,
        }
    }

    #[test]
    fn before_the_tap_and_without_images_the_fused_pose_is_used() {
        let cam = Pinhole::from_vfov(64, 48, 50.0).unwrap();
        let frame = Arc::new(Rgba8Image { width: 64, height: 48, pixels: vec![128; 64 * 48 * 4] });
        let fused = pose(Quat::from_rotation_z(0.3));
        for images in [false, true] {
            let mut aim = AimHeading::new(cam, images);
            // No tap yet: nothing held, the fused pose judges the aims.
            assert_eq!(aim.aim_pose(fused, DisplayRotation::R90), fused);
            aim.tap(&OrientationFilter::new(FusionConfig::default()), 1.0, &fused, frame.clone());
            // The held copy of an uninitialised filter has no pose yet: still the fused one.
            let other = pose(Quat::from_rotation_z(0.5));
            let placed = aim.shot(1, 2.0, other, fused, frame.clone());
            // Without images the shot keeps the fused pose; with them, the aim pose (a flat
            // frame matches nothing, so no drift is measured).
            assert_eq!(placed, if images { other } else { fused });
            assert_eq!(aim.drift_fixes(), 0);
        }
    }
}
