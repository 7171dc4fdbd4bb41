//! The camera's orientation: frames, sensor fusion, true north.
//!
//! A pose is a unit quaternion rotating the camera frame (+x image right, +y image up, looking
//! along −z) into the ENU world (+x East, +y North, +z Up), see [`frames`]. [`fusion`] turns
//! accelerometer, gyroscope and magnetometer readings ([`crate::sensors`]) into poses with an
//! accuracy estimate, falling back to the gyroscope alone while the magnetometer is disturbed;
//! [`magnetic`] gives true north from the World Magnetic Model. [`trace`] reads the truth
//! traces the capture CLI replays and [`hand_motion`] makes plausible ones. [`stability`]
//! measures jitter, lag and failure cases (`previz pose-stability`).

use crate::sensors::Reading;
use anyhow::Result;
use glam::{DQuat, Quat};

pub mod frames;
pub mod fusion;
pub mod hand_motion;
pub mod hard_iron;
pub mod magnetic;
pub mod stability;
pub mod sun_heading;
pub mod sun_study;
pub mod tilt_compass;
pub mod trace;

pub use frames::DisplayRotation;
pub use fusion::{FusionConfig, OrientationFilter};

/// Where the heading of a pose comes from (the UI shows it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeadingSource {
    /// Magnetometer, corrected to true north when the location is known.
    Magnetometer,
    /// Gyroscope only: the magnetometer is disturbed; heading drifts slowly.
    GyroOnly,
    /// Calibrated against the sun seen in the camera (the magnetometer keeps correcting with
    /// the learnt offset).
    Sun,
    /// The platform's fused attitude (Android rotation vector, iOS CoreMotion).
    Platform,
    /// No heading yet (no magnetometer reading accepted so far).
    Unknown,
}

impl HeadingSource {
    /// The text the UI shows.
    pub fn label(self) -> &'static str {
        match self {
            HeadingSource::Magnetometer => "compass",
            HeadingSource::GyroOnly => "gyro only (magnetic disturbance)",
            HeadingSource::Sun => "sun",
            HeadingSource::Platform => "platform attitude",
            HeadingSource::Unknown => "no heading yet",
        }
    }
}

/// The camera's estimated orientation at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Seconds, the sensor source's clock.
    pub t: f64,
    /// Camera → ENU, unit length.
    pub q: Quat,
    /// Estimated 1σ orientation error (degrees): tilt and heading combined.
    pub accuracy_deg: f32,
    pub heading_accuracy_deg: f32,
    pub tilt_accuracy_deg: f32,
    pub heading_source: HeadingSource,
    /// The magnetometer reads a field unlike the model's (magnitude or dip): heading is gyro-only.
    pub magnetic_disturbance: bool,
}

/// Anything that turns sensor readings into poses (the fusion filter, the compass-only
/// baseline), so measurements can treat them alike.
pub trait OrientationEstimator {
    /// Feed one reading (readings must come in time order). Invalid readings are an error
    /// and leave the state unchanged.
    fn update(&mut self, reading: &Reading) -> Result<()>;
    /// The current camera pose for a display rotation, once the estimator is initialised.
    fn pose(&self, rotation: DisplayRotation) -> Option<Pose>;
    /// The current device → ENU orientation (unsmoothed where the estimator smooths).
    fn device_orientation(&self) -> Option<DQuat>;
}
