//! True north from the sun in the live camera frame (issue 12): while the sun should be in view
//! — SPA's sun for the place and the clock, seen through the estimated pose — the camera takes
//! a short exposure frame now and then ([`SUN_FRAME_PERIOD_S`]; at
//! [`SUN_FRAME_EXPOSURE`], −4 EV, only the disc and the inner aureole clip), the one sun finder
//! sights the sun in it ([`sight_sun`]), and the azimuth difference against SPA is fused into
//! the live filter as a heading measurement with its own 1σ
//! ([`OrientationFilter::sun_heading`]: a Kalman update on yaw, blended in, not a jump). The
//! compass's steady error (residual hard-iron offset, the magnetic model) is what it removes.
//!
//! The live session calls [`SunNorth::frame`] once per camera frame, after the sensors.

use crate::camera::FrameSource;
use crate::pose::Pose;
use crate::pose::fusion::OrientationFilter;
use crate::pose::sun_heading::{HeadingMeasurement, SUN_FRAME_EXPOSURE, heading_measurement, sight_sun, sun_in_view};
use anyhow::Result;
use glam::Vec3;

/// A short exposure frame is taken at most this often (seconds): one frame a second is
/// hidden from the preview (a phone shows the previous frame meanwhile).
pub const SUN_FRAME_PERIOD_S: f64 = 1.0;
/// The sun must be predicted this far inside the frame (degrees): a disc cut by the border has a
/// biased centre, and the pose's own error moves it.
pub const SUN_FRAME_MARGIN_DEG: f32 = 3.0;

/// What the last camera frame did about the sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SunNorthState {
    /// No pose yet, or not yet time for another short frame.
    Waiting,
    /// The sun is below the horizon or not in the frame by the estimated pose.
    NotInView,
    /// The camera cannot take a short exposure frame (files; phone cameras for now).
    NoShortExposure,
    /// A short frame was taken but no sun was sighted in it (clouds, something in front) or the
    /// sighting disagreed with SPA's elevation (a reflection, a street light).
    NotSeen,
    /// The sun was measured and fused: the heading error of the pose and its 1σ.
    Measured(HeadingMeasurement),
}

/// The live sun calibration's state: when the last short frame was taken, and counts.
#[derive(Clone, Debug)]
pub struct SunNorth {
    last_frame_t: Option<f64>,
    /// Short exposure frames taken, and those in which the sun was measured.
    pub frames: usize,
    pub measurements: usize,
    /// The last frame's outcome, and the last measurement (time, measurement).
    pub state: SunNorthState,
    pub last: Option<(f64, HeadingMeasurement)>,
}

impl Default for SunNorth {
    fn default() -> Self {
        SunNorth { last_frame_t: None, frames: 0, measurements: 0, state: SunNorthState::Waiting, last: None }
    }
}

impl SunNorth {
    pub fn new() -> SunNorth {
        SunNorth::default()
    }

    /// One camera frame at time `t` (the camera's and the sensors' clock): with the filter's
    /// `pose` for it and the sun's true direction `sun_enu` (SPA's for the place and instant),
    /// take a short exposure frame from `camera` (`size` pixels, vertical field of view
    /// `vfov_deg`) when the sun should be in it and [`SUN_FRAME_PERIOD_S`] has passed, sight the
    /// sun and fuse the heading error into `filter`.
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
        let Some(pose) = pose else { return Ok(SunNorthState::Waiting) };
        if self.last_frame_t.is_some_and(|last| t - last < SUN_FRAME_PERIOD_S) {
            return Ok(SunNorthState::Waiting);
        }
        if !(sun_enu.z > 0.0 && sun_in_view(pose.q, sun_enu, vfov_deg, size.0, size.1, SUN_FRAME_MARGIN_DEG)) {
            return Ok(SunNorthState::NotInView);
        }
        self.last_frame_t = Some(t);
        let Some(frame) = camera.exposure_frame(SUN_FRAME_EXPOSURE)? else { return Ok(SunNorthState::NoShortExposure) };
        self.frames += 1;
        let tilt_sigma = f64::from(pose.tilt_accuracy_deg).to_radians();
        let measured = sight_sun(&frame.image, vfov_deg, pose.q)?.and_then(|s| heading_measurement(&s, sun_enu, tilt_sigma)).filter(|m| {
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
