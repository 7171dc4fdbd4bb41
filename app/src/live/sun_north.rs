//! True north from the sun in the live camera frame (issue 12): while the sun should be in view
//! — SPA's sun for the place and the clock, seen through the estimated pose — the camera is asked
//! for a short exposure frame now and then ([`SUN_FRAME_PERIOD_S`]; at [`SUN_FRAME_EXPOSURE`],
//! −4 EV, only the disc and the inner aureole clip), the one sun finder sights the sun in it
//! ([`sight_sun`]), and the azimuth difference against SPA is fused into the live filter as a
//! heading measurement with its own 1σ ([`OrientationFilter::sun_heading`]: a Kalman update on
//! yaw, blended in, not a jump). The compass's steady error (residual hard-iron offset, the
//! magnetic model) is what it removes.
//!
//! The request never waits ([`FrameSource::request_exposure_frame`]): a phone's short frame
//! comes a few stream frames later ([`crate::camera::short_exposure`]), so the poses of the last
//! second are kept and the sun is sighted with the pose at the short frame's own time. The
//! exposure the frame really had (in bright sun a sensor may already be near its shortest time)
//! is recorded ([`SunNorth::last_relative_exposure`]); the sun finder's own tests (size, shape,
//! contrast) decide whether the blob is the sun — in the simulator it is sighted as well at 0 EV
//! as at −4 EV (docs/capture.md, the live sun).
//!
//! The live session calls [`SunNorth::frame`] once per camera frame, after the sensors.

use crate::camera::FrameSource;
use crate::camera::short_exposure::{ExposureFrame, ShortFrame};
use crate::pose::Pose;
use crate::pose::fusion::OrientationFilter;
use crate::pose::sun_heading::{HeadingMeasurement, SUN_FRAME_EXPOSURE, heading_measurement, sight_sun, sun_in_view};
use anyhow::Result;
use glam::Vec3;
use std::collections::VecDeque;

/// A short exposure frame is asked for at most this often (seconds): one frame a second is
/// hidden from the preview (a phone shows the previous frame meanwhile).
pub const SUN_FRAME_PERIOD_S: f64 = 1.0;
/// The sun must be predicted this far inside the frame (degrees): a disc cut by the border has a
/// biased centre, and the pose's own error moves it.
pub const SUN_FRAME_MARGIN_DEG: f32 = 3.0;
/// Poses kept to place a short frame that arrives after its request (seconds; longer than the
/// camera's [`crate::camera::short_exposure::SHORT_FRAME_TIMEOUT_S`]).
const POSE_HISTORY_S: f64 = 1.0;

/// What the last camera frame did about the sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SunNorthState {
    /// No pose yet, or not yet time for another short frame.
    Waiting,
    /// The sun is below the horizon or not in the frame by the estimated pose.
    NotInView,
    /// The camera cannot take a short exposure frame (files; a phone camera without manual
    /// exposure).
    NoShortExposure,
    /// A short frame was asked for and has not come yet.
    Requested,
    /// The short frame did not come (the camera timed out, failed or was paused), or came from
    /// a time with no pose kept.
    Lost,
    /// A short frame was taken but no sun was sighted in it (clouds, something in front) or the
    /// sighting disagreed with SPA's elevation (a reflection, a street light).
    NotSeen,
    /// The sun was measured and fused: the heading error of the pose and its 1σ.
    Measured(HeadingMeasurement),
}

/// The live sun calibration's state: the request in flight, the recent poses, and counts.
#[derive(Clone, Debug)]
pub struct SunNorth {
    last_request_t: Option<f64>,
    /// A short frame was asked for and its outcome not taken yet.
    pending: bool,
    /// The poses of the last [`POSE_HISTORY_S`], oldest first, by camera frame time.
    poses: VecDeque<(f64, Pose)>,
    /// Short exposure frames taken, and those in which the sun was measured.
    pub frames: usize,
    pub measurements: usize,
    /// The last frame's outcome, and the last measurement (time, measurement).
    pub state: SunNorthState,
    pub last: Option<(f64, HeadingMeasurement)>,
    /// The exposure the last short frame really had, relative to the stream's.
    pub last_relative_exposure: Option<f64>,
}

impl Default for SunNorth {
    fn default() -> Self {
        SunNorth {
            last_request_t: None,
            pending: false,
            poses: VecDeque::new(),
            frames: 0,
            measurements: 0,
            state: SunNorthState::Waiting,
            last: None,
            last_relative_exposure: None,
        }
    }
}

impl SunNorth {
    pub fn new() -> SunNorth {
        SunNorth::default()
    }

    /// One camera frame at time `t` (the camera's and the sensors' clock): with the filter's
    /// `pose` for it and the sun's true direction `sun_enu` (SPA's for the place and instant),
    /// take the short exposure frame from `camera` (`size` pixels, vertical field of view
    /// `vfov_deg`) if one has come, sight the sun in it at the pose of its own time and fuse the
    /// heading error into `filter`; otherwise ask for one when the sun should be in the frame
    /// and [`SUN_FRAME_PERIOD_S`] has passed.
    #[allow(clippy::too_many_arguments)]
    pub fn frame(
        &mut self,
        t: f64,
        pose: Option<&Pose>,
        sun_enu: Vec3,
        size: (u32, u32),
        vfov_deg: f32,
        camera: &mut dyn FrameSource,
        filter: &mut OrientationFilter,
    ) -> Result<SunNorthState> {
        self.state = self.try_frame(t, pose, sun_enu, size, vfov_deg, camera, filter)?;
        Ok(self.state)
    }

    #[allow(clippy::too_many_arguments)]
    fn try_frame(
        &mut self,
        t: f64,
        pose: Option<&Pose>,
        sun_enu: Vec3,
        size: (u32, u32),
        vfov_deg: f32,
        camera: &mut dyn FrameSource,
        filter: &mut OrientationFilter,
    ) -> Result<SunNorthState> {
        if let Some(p) = pose {
            self.poses.retain(|(pt, _)| *pt < t && t - *pt <= POSE_HISTORY_S);
            self.poses.push_back((t, *p));
        }
        if self.pending {
            return Ok(match camera.take_exposure_frame()? {
                None => SunNorthState::Requested,
                Some(ShortFrame::Lost) => {
                    self.pending = false;
                    SunNorthState::Lost
                }
                Some(ShortFrame::Arrived(frame)) => {
                    self.pending = false;
                    self.sight(t, frame, sun_enu, vfov_deg, filter)?
                }
            });
        }
        let Some(pose) = pose else { return Ok(SunNorthState::Waiting) };
        if self.last_request_t.is_some_and(|last| t - last < SUN_FRAME_PERIOD_S) {
            return Ok(SunNorthState::Waiting);
        }
        if !(sun_enu.z > 0.0 && sun_in_view(pose.q, sun_enu, vfov_deg, size.0, size.1, SUN_FRAME_MARGIN_DEG)) {
            return Ok(SunNorthState::NotInView);
        }
        self.last_request_t = Some(t);
        if !camera.request_exposure_frame(SUN_FRAME_EXPOSURE)? {
            return Ok(SunNorthState::NoShortExposure);
        }
        self.pending = true;
        // The virtual phone's frame may already be there.
        self.try_frame(t, None, sun_enu, size, vfov_deg, camera, filter)
    }

    /// Sight the sun in a short frame at the pose of its time and fuse the measurement at `t`.
    fn sight(
        &mut self,
        t: f64,
        short: ExposureFrame,
        sun_enu: Vec3,
        vfov_deg: f32,
        filter: &mut OrientationFilter,
    ) -> Result<SunNorthState> {
        self.frames += 1;
        self.last_relative_exposure = Some(short.relative_exposure);
        let Some(pose) = pose_at(&self.poses, short.frame.t) else { return Ok(SunNorthState::Lost) };
        let tilt_sigma = f64::from(pose.tilt_accuracy_deg).to_radians();
        let measured =
            sight_sun(&short.frame.image, vfov_deg, pose.q)?.and_then(|s| heading_measurement(&s, sun_enu, tilt_sigma)).filter(|m| {
                // The filter takes it (it has a heading to correct).
                filter.sun_heading(t, m.error, m.sigma).is_some()
            });
        Ok(match measured {
            Some(m) => {
                self.measurements += 1;
                self.last = Some((t, m));
                SunNorthState::Measured(m)
            }
            None => SunNorthState::NotSeen,
        })
    }
}

/// The pose at time `t` from `poses` (by time, oldest first): a kept pose's own, or slerped
/// between the two around `t`; None outside their span.
fn pose_at(poses: &VecDeque<(f64, Pose)>, t: f64) -> Option<Pose> {
    let after = poses.iter().position(|(pt, _)| *pt >= t)?;
    let (t1, p1) = poses[after];
    if t1 == t {
        return Some(p1);
    }
    let (t0, p0) = poses.get(after.checked_sub(1)?)?;
    let s = ((t - t0) / (t1 - t0)) as f32;
    Some(Pose { t, q: p0.q.slerp(p1.q, s).normalize(), ..p1 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Frame;
    use crate::camera::short_exposure::{ExposureLimits, OneShot, SensorExposure, plan_exposure};
    use crate::pose::HeadingSource;
    use crate::scene::Rgba8Image;
    use glam::Quat;

    fn pose(t: f64, q: Quat) -> Pose {
        Pose {
            t,
            q,
            accuracy_deg: 2.0,
            heading_accuracy_deg: 2.0,
            tilt_accuracy_deg: 0.5,
            heading_source: HeadingSource::Magnetometer,
            magnetic_disturbance: false,
        }
    }

    #[test]
    fn a_late_frame_takes_the_pose_of_its_own_time() {
        let (a, b) = (Quat::from_rotation_z(0.0), Quat::from_rotation_z(0.2));
        let poses: VecDeque<_> = [(1.0, pose(1.0, a)), (1.1, pose(1.1, b))].into();
        // Halfway: a turn of 0.1 rad about z.
        let mid = pose_at(&poses, 1.05).unwrap();
        assert!(mid.q.angle_between(Quat::from_rotation_z(0.1)) < 1e-5, "{:?}", mid.q);
        assert_eq!(mid.t, 1.05);
        assert_eq!(pose_at(&poses, 1.1).unwrap().q, b);
        assert!(pose_at(&poses, 0.9).is_none() && pose_at(&poses, 1.2).is_none(), "outside the kept span");
    }

    /// A camera whose short frames come `latency` stream frames after the request, or never
    /// (`None`), through the same [`OneShot`] as the phones; its images are blank (no sun).
    struct SlowCamera {
        shot: OneShot,
        latency: Option<usize>,
        frames_since: usize,
        relative: f64,
    }

    impl SlowCamera {
        /// The frame loop's stream frame at `t`.
        fn stream_frame(&mut self, t: f64) {
            if let Some((id, plan)) = self.shot.in_flight() {
                self.frames_since += 1;
                if Some(self.frames_since) == self.latency {
                    let frame = Frame { image: Rgba8Image { width: 32, height: 24, pixels: vec![40; 32 * 24 * 4] }, t };
                    self.shot.arrived(id, frame, plan.exposure);
                }
            }
            self.shot.stream_frame(t, true);
        }
    }

    impl FrameSource for SlowCamera {
        fn next_frame(&mut self) -> Result<Option<Frame>> {
            Ok(None)
        }

        fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
            let current = SensorExposure { time_s: 1e-3, iso: 100.0 };
            // A sensor whose shortest time is `relative` × the current one, at a fixed ISO.
            let limits = ExposureLimits::new((1e-3 * self.relative, 1.0), (100.0, 100.0))?;
            self.frames_since = 0;
            Ok(self.shot.request(plan_exposure(current, f64::from(relative_exposure), &limits)?).is_some())
        }

        fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
            Ok(self.shot.take())
        }
    }

    /// Run `secs` of a 25 Hz stream looking at the sun (straight ahead of a level camera facing
    /// North, 10° up) and list the states.
    fn run(camera: &mut SlowCamera, secs: f64) -> (Vec<SunNorthState>, SunNorth) {
        let mut filter = OrientationFilter::new(crate::pose::FusionConfig::default());
        let mut n = SunNorth::new();
        let q = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        let sun = Vec3::new(0.0, 10f32.to_radians().cos(), 10f32.to_radians().sin());
        let mut states = Vec::new();
        for k in 0..(secs * 25.0) as usize {
            let t = k as f64 / 25.0;
            camera.stream_frame(t);
            states.push(n.frame(t, Some(&pose(t, q)), sun, (32, 24), 50.0, camera, &mut filter).unwrap());
        }
        (states, n)
    }

    #[test]
    fn a_late_short_frame_is_waited_for_without_blocking_and_a_lost_one_times_out() {
        // Arriving 4 stream frames after the request (asked at frame 0): 'requested' meanwhile,
        // then sighted at frame 4 (a blank image: not seen); asked again each second.
        // Its sensor reaches only −2 EV: the frame is still sighted, and the real factor recorded.
        let mut cam = SlowCamera { shot: OneShot::new(), latency: Some(4), frames_since: 0, relative: 0.25 };
        let (states, n) = run(&mut cam, 2.5);
        assert_eq!(&states[..4], &[SunNorthState::Requested; 4], "{states:?}");
        assert_eq!(states[4], SunNorthState::NotSeen, "{states:?}");
        assert_eq!(states[5], SunNorthState::Waiting);
        assert_eq!(states.iter().filter(|s| **s == SunNorthState::NotSeen).count(), 3, "at 0, 1 and 2 s: {states:?}");
        assert_eq!((n.frames, n.measurements), (3, 0));
        assert!((n.last_relative_exposure.unwrap() - 0.25).abs() < 1e-12);
        // Never arriving: lost when the camera's timeout passes (0.5 s after the first stream
        // frame after the request, frame 1 at 0.04 s: at frame 14, 0.56 s), and asked again a
        // second after the first request.
        let mut cam = SlowCamera { shot: OneShot::new(), latency: None, frames_since: 0, relative: 1.0 / 16.0 };
        let (states, n) = run(&mut cam, 1.5);
        let lost = states.iter().position(|s| *s == SunNorthState::Lost).unwrap();
        assert_eq!(lost, 14, "{states:?}");
        assert!(states[..lost].iter().all(|s| *s == SunNorthState::Requested));
        assert_eq!(states[lost + 1], SunNorthState::Waiting);
        assert_eq!(states[25], SunNorthState::Requested, "asked again at 1 s");
        assert_eq!(n.frames, 0);
    }

    #[test]
    fn a_frame_that_comes_late_is_sighted_with_the_pose_of_its_own_time() {
        use crate::camera::exposure::ExposureMode;
        use crate::camera::sim::{SimSettings, VirtualPhone};
        use crate::pose::OrientationEstimator;
        use crate::pose::frames::from_heading_pitch_roll;
        use crate::pose::sun_heading::sight_sun;
        use crate::scene::{CubeMap, cube_to_enu, environment::face_uv_to_cube_dir};
        use crate::sensors::Reading;
        // A grey sky with a 0.5° sun disc due North, 10° high.
        let sun = Vec3::new(0.0, 10f32.to_radians().cos(), 10f32.to_radians().sin());
        let size = 512;
        let faces = std::array::from_fn(|face| {
            (0..size * size)
                .map(|i| {
                    let (u, v) = (((i % size) as f32 + 0.5) / size as f32, ((i / size) as f32 + 0.5) / size as f32);
                    let d = cube_to_enu(face_uv_to_cube_dir(face, u, v)).normalize();
                    if d.dot(sun) > 0.5f32.to_radians().cos() { [5.0e4; 3] } else { [0.5; 3] }
                })
                .collect()
        });
        let phone = VirtualPhone::new(
            std::sync::Arc::new(CubeMap { size, faces }),
            &SimSettings { width: 320, height: 240, vfov_deg: 50.0, exposure: ExposureMode::Fixed(1.0) },
        )
        .unwrap();
        // The camera turns right at 20°/s (0.8° a frame at 25 Hz), 8° up, from 6° left of the sun;
        // the poses are exact. The short frame is exposed at the first frame after the request
        // and reaches the frame loop three frames later, as a phone's pipeline delivers it.
        let truth = |t: f64| from_heading_pitch_roll((20.0 * t - 6.0f64).to_radians(), 8f64.to_radians(), 0.0).as_quat();
        let mut filter = OrientationFilter::new(crate::pose::FusionConfig::default());
        let mut n = SunNorth::new();
        let mut shot = OneShot::new();
        let mut exposed: Option<Frame> = None;
        let mut measured = None;
        for k in 0..8 {
            let t = k as f64 / 25.0;
            // Lying still for the filter, which only needs a heading to correct.
            filter.update(&Reading::Accel { t, v: glam::DVec3::new(0.0, 0.0, 9.81) }).unwrap();
            filter.update(&Reading::Mag { t, v: glam::DVec3::new(0.0, 19.5, -44.6) }).unwrap();
            if let Some((id, plan)) = shot.in_flight() {
                match exposed.take() {
                    None => exposed = Some(Frame { image: phone.render_with_exposure(truth(t), 1.0 / 16.0).unwrap(), t }),
                    Some(f) if t - f.t < 0.1 => exposed = Some(f),
                    Some(f) => {
                        shot.arrived(id, f, plan.exposure);
                    }
                }
            }
            shot.stream_frame(t, true);
            let mut camera = Relay(&mut shot);
            let state = n.frame(t, Some(&pose(t, truth(t))), sun, (320, 240), 50.0, &mut camera, &mut filter).unwrap();
            if let SunNorthState::Measured(m) = state {
                measured = Some((t, m));
            }
        }
        let (t, m) = measured.expect("measured");
        assert!((t - 4.0 / 25.0).abs() < 1e-9, "arrived at frame 4, {t} s");
        // It is the measurement of that frame at the pose of its own time (frame 1)...
        let frame = phone.render_with_exposure(truth(1.0 / 25.0), 1.0 / 16.0).unwrap();
        let at = |q| {
            let s = sight_sun(&frame, 50.0, q).unwrap().unwrap();
            crate::pose::sun_heading::heading_measurement(&s, sun, 0.5f64.to_radians()).unwrap().error
        };
        assert!((m.error - at(truth(1.0 / 25.0))).abs() < 1e-9, "{} vs {}", m.error, at(truth(1.0 / 25.0)));
        // ... where the exact pose leaves only the sighting's error (0.12° measured: a binary
        // 0.5° disc on the map's 0.18° texels, seen in 0.2° pixels)...
        assert!(m.error.to_degrees().abs() < 0.2, "heading error {}° with exact poses", m.error.to_degrees());
        // ... not at the pose of its arrival (frame 4), which would take the 2.4° turned since for
        // the heading's error.
        let turn = (at(truth(t)) - m.error).to_degrees();
        assert!((turn - 2.4).abs() < 0.01, "{turn}°");
    }

    /// A camera whose short frame requests go to a [`OneShot`] the test drives.
    struct Relay<'a>(&'a mut OneShot);

    impl FrameSource for Relay<'_> {
        fn next_frame(&mut self) -> Result<Option<Frame>> {
            Ok(None)
        }

        fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
            let current = SensorExposure { time_s: 1.0, iso: 1.0 };
            Ok(self.0.request(plan_exposure(current, f64::from(relative_exposure), &ExposureLimits::UNLIMITED)?).is_some())
        }

        fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
            Ok(self.0.take())
        }
    }
}
