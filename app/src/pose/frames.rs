//! Frames and the angles shown to people.
//!
//! - World: ENU, +x East, +y North, +z Up.
//! - Camera: +x image right, +y image up, looking along −z. A pose rotates camera → world.
//! - Device: the Android sensor axes (iOS CoreMotion uses the same ones): +x to the right and
//!   +y to the top of the screen in the device's natural (portrait) orientation, +z out of the
//!   screen towards the user. The back camera looks along −z.
//!
//! Device and camera frames differ only by the display rotation, a turn about the shared z
//! axis: [`camera_to_device`] is the one place where that is written down.
//!
//! Heading, pitch and roll are derived for display and for the capture targets; the filter state
//! is always a quaternion.

use anyhow::{Result, bail};
use glam::{DQuat, DVec3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// How the image on screen is rotated relative to the device's natural orientation.
///
/// The value is the angle the drawn graphics are turned clockwise, which is the angle the
/// device has been turned counter-clockwise (as the user sees it): Android's
/// `Display.getRotation()` (`Surface.ROTATION_0/90/180/270`). On iOS the interface orientations
/// map as portrait = 0, landscapeRight (home button on the right) = 90, portraitUpsideDown = 180,
/// landscapeLeft = 270.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DisplayRotation {
    #[default]
    R0,
    R90,
    R180,
    R270,
}

impl DisplayRotation {
    /// From degrees (0, 90, 180, 270; negative or ≥ 360 values are wrapped first).
    pub fn from_degrees(deg: i32) -> Result<Self> {
        Ok(match deg.rem_euclid(360) {
            0 => DisplayRotation::R0,
            90 => DisplayRotation::R90,
            180 => DisplayRotation::R180,
            270 => DisplayRotation::R270,
            _ => bail!("display rotation must be a multiple of 90 degrees, got {deg}"),
        })
    }

    /// From Android's `Surface.ROTATION_*` constants (0, 1, 2, 3).
    pub fn from_android_surface_rotation(value: i32) -> Result<Self> {
        match value {
            0..=3 => Self::from_degrees(value * 90),
            _ => bail!("Android Display.getRotation() returned {value}, expected 0..=3"),
        }
    }

    pub fn degrees(self) -> i32 {
        match self {
            DisplayRotation::R0 => 0,
            DisplayRotation::R90 => 90,
            DisplayRotation::R180 => 180,
            DisplayRotation::R270 => 270,
        }
    }
}

/// The rotation taking camera-frame vectors to device-frame vectors for a display rotation:
/// a turn of −rotation about the shared z axis.
///
/// For `R90` (device turned counter-clockwise into landscape) image right is the device's −y
/// and image up its +x. This is Android's documented remapping for `ROTATION_90`,
/// `SensorManager.remapCoordinateSystem(inR, AXIS_Y, AXIS_MINUS_X, outR)`: the new y axis
/// coincides with the device x axis and the new −x with the device y axis.
pub fn camera_to_device(rotation: DisplayRotation) -> DQuat {
    DQuat::from_rotation_z(-f64::from(rotation.degrees()).to_radians())
}

/// Camera pose (camera → ENU) from the device orientation (device → ENU).
pub fn camera_pose_from_device(device_to_world: DQuat, rotation: DisplayRotation) -> DQuat {
    (device_to_world * camera_to_device(rotation)).normalize()
}

/// Device orientation (device → ENU) from a camera pose (camera → ENU).
pub fn device_from_camera_pose(camera_to_world: DQuat, rotation: DisplayRotation) -> DQuat {
    (camera_to_world * camera_to_device(rotation).inverse()).normalize()
}

/// Where the camera looks, in world coordinates.
pub fn forward(camera_to_world: DQuat) -> DVec3 {
    camera_to_world * DVec3::NEG_Z
}

/// Heading, pitch and roll of a camera pose, in radians, for display only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingPitchRoll {
    /// Clockwise from true north, in [0, 2π).
    pub heading: f64,
    /// Elevation of the viewing direction above the horizon, in [−π/2, π/2].
    pub pitch: f64,
    /// Turn about the viewing direction; positive when the image's right edge is lowered
    /// (the phone turned clockwise as its user sees it). In (−π, π].
    pub roll: f64,
}

/// The pose with the given heading, pitch and roll (radians, as in [`HeadingPitchRoll`]).
///
/// heading = pitch = roll = 0 looks north with image up = world up: camera +x → East,
/// +y → Up, −z → North. The pose is Rz(−heading)·Rx(pitch)·Rx(90°)·Rz(−roll).
pub fn from_heading_pitch_roll(heading: f64, pitch: f64, roll: f64) -> DQuat {
    DQuat::from_rotation_z(-heading) * DQuat::from_rotation_x(pitch + FRAC_PI_2) * DQuat::from_rotation_z(-roll)
}

/// Heading, pitch and roll of a camera pose. Works at pitch ±90°: when the camera looks
/// straight up or down the heading is read from the image's up direction and roll is 0.
pub fn heading_pitch_roll(camera_to_world: DQuat) -> HeadingPitchRoll {
    let q = camera_to_world.normalize();
    let f = q * DVec3::NEG_Z;
    let right = q * DVec3::X;
    let up = q * DVec3::Y;
    let pitch = f.z.clamp(-1.0, 1.0).asin();
    let horizontal = f.x.hypot(f.y);
    // Below this the viewing direction is vertical to double precision.
    if horizontal > 1e-9 {
        HeadingPitchRoll { heading: wrap_radians_tau(f.x.atan2(f.y)), pitch, roll: (-right.z).atan2(up.z) }
    } else {
        // Looking straight up, image up points opposite the heading; straight down, along it.
        let s = if f.z > 0.0 { -1.0 } else { 1.0 };
        HeadingPitchRoll {
            heading: wrap_radians_tau((s * up.x).atan2(s * up.y)),
            pitch: if f.z > 0.0 { FRAC_PI_2 } else { -FRAC_PI_2 },
            roll: 0.0,
        }
    }
}

/// An angle in radians wrapped into [0, 2π).
pub fn wrap_radians_tau(a: f64) -> f64 {
    let r = a.rem_euclid(TAU);
    // rem_euclid of a tiny negative number rounds up to exactly 2π.
    if r >= TAU { 0.0 } else { r }
}

/// An angle in degrees wrapped into [0, 360).
pub fn wrap_degrees_360(a: f64) -> f64 {
    let r = a.rem_euclid(360.0);
    if r >= 360.0 { 0.0 } else { r }
}

/// The signed smallest difference `a − b` of two angles in radians, in [−π, π).
pub fn angle_difference(a: f64, b: f64) -> f64 {
    wrap_radians_tau(a - b + PI) - PI
}

/// The signed smallest difference `a − b` of two headings in degrees, in [−180, 180).
pub fn heading_difference_deg(a: f64, b: f64) -> f64 {
    wrap_degrees_360(a - b + 180.0) - 180.0
}

/// The angle of the rotation taking `a` to `b`, in radians, in [0, π]. Sign-insensitive
/// (q and −q are the same rotation) and accurate for tiny angles (atan2, not acos).
pub fn angle_between(a: DQuat, b: DQuat) -> f64 {
    let d = a.inverse() * b;
    2.0 * d.xyz().length().atan2(d.w.abs())
}

/// The same as [`angle_between`] for single-precision poses.
pub fn angle_between_f32(a: glam::Quat, b: glam::Quat) -> f64 {
    angle_between(a.as_dquat(), b.as_dquat())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn display_rotation_r90_matches_android_remap() {
        // Android remapCoordinateSystem(AXIS_Y, AXIS_MINUS_X) for ROTATION_90: screen up is
        // the device +x, screen right the device −y.
        let c2d = camera_to_device(DisplayRotation::R90);
        assert!(close(c2d * DVec3::Y, DVec3::X));
        assert!(close(c2d * DVec3::X, DVec3::NEG_Y));
        assert!(close(c2d * DVec3::Z, DVec3::Z));
        // ROTATION_270: remap(AXIS_MINUS_Y, AXIS_X): screen right is device +y, up is −x.
        let c2d = camera_to_device(DisplayRotation::R270);
        assert!(close(c2d * DVec3::X, DVec3::Y));
        assert!(close(c2d * DVec3::Y, DVec3::NEG_X));
        // ROTATION_180: remap(AXIS_MINUS_X, AXIS_MINUS_Y).
        let c2d = camera_to_device(DisplayRotation::R180);
        assert!(close(c2d * DVec3::X, DVec3::NEG_X));
        assert!(close(c2d * DVec3::Y, DVec3::NEG_Y));
        assert!(close(camera_to_device(DisplayRotation::R0) * DVec3::X, DVec3::X));
    }

    #[test]
    fn device_camera_round_trip_and_back_camera_direction() {
        let device = DQuat::from_euler(glam::EulerRot::ZXY, 0.3, -0.7, 1.1);
        for r in [DisplayRotation::R0, DisplayRotation::R90, DisplayRotation::R180, DisplayRotation::R270] {
            let cam = camera_pose_from_device(device, r);
            assert!(angle_between(device_from_camera_pose(cam, r), device) < 1e-12);
            // Whatever the display rotation, the back camera looks out of the back (−z device).
            assert!(close(forward(cam), device * DVec3::NEG_Z));
        }
    }

    #[test]
    fn display_rotation_parsing() {
        assert_eq!(DisplayRotation::from_degrees(-90).unwrap(), DisplayRotation::R270);
        assert_eq!(DisplayRotation::from_android_surface_rotation(1).unwrap(), DisplayRotation::R90);
        assert!(DisplayRotation::from_degrees(45).is_err());
        assert!(DisplayRotation::from_android_surface_rotation(4).is_err());
    }

    #[test]
    fn heading_pitch_roll_hand_cases() {
        // Identity heading/pitch/roll looks north, image right east, image up up.
        let q = from_heading_pitch_roll(0.0, 0.0, 0.0);
        assert!(close(q * DVec3::NEG_Z, DVec3::Y));
        assert!(close(q * DVec3::X, DVec3::X));
        assert!(close(q * DVec3::Y, DVec3::Z));
        // Heading 90° looks east; pitch 30° raises the view.
        let q = from_heading_pitch_roll(90f64.to_radians(), 30f64.to_radians(), 0.0);
        let c = 30f64.to_radians().cos();
        let s = 30f64.to_radians().sin();
        assert!(close(forward(q), DVec3::new(c, 0.0, s)));
        // Roll +10°: the image's right edge drops below the horizon.
        let q = from_heading_pitch_roll(0.0, 0.0, 10f64.to_radians());
        assert!((q * DVec3::X).z < 0.0);
    }

    #[test]
    fn heading_pitch_roll_round_trip_including_wrap() {
        for &(h, p, r) in &[(0.0, 0.0, 0.0), (359.9, 10.0, -5.0), (0.05, -45.0, 170.0), (180.0, 89.0, 20.0), (270.0, -89.0, -20.0)] {
            let q = from_heading_pitch_roll(f64::to_radians(h), f64::to_radians(p), f64::to_radians(r));
            let e = heading_pitch_roll(q);
            assert!(heading_difference_deg(e.heading.to_degrees(), h).abs() < 1e-9, "{h} {p} {r}: {e:?}");
            assert!((e.pitch.to_degrees() - p).abs() < 1e-9);
            assert!(angle_difference(e.roll, r.to_radians()).abs() < 1e-9);
            assert!((0.0..TAU).contains(&e.heading));
        }
    }

    #[test]
    fn heading_pitch_roll_at_the_poles() {
        // Straight up and straight down: no NaN, pitch exactly ±90°, heading from image up, so
        // tilting up from heading 30° keeps heading 30°.
        for p in [90.0f64, -90.0] {
            let q = from_heading_pitch_roll(30f64.to_radians(), p.to_radians(), 0.0);
            let e = heading_pitch_roll(q);
            assert!(e.heading.is_finite() && e.roll == 0.0);
            assert!((e.pitch.to_degrees() - p).abs() < 1e-6);
            assert!(heading_difference_deg(e.heading.to_degrees(), 30.0).abs() < 1e-6, "{p}: {e:?}");
        }
        // Just off the pole the regular branch agrees with the pole branch.
        let q = from_heading_pitch_roll(30f64.to_radians(), (90.0f64 - 1e-6).to_radians(), 0.0);
        assert!(heading_difference_deg(heading_pitch_roll(q).heading.to_degrees(), 30.0).abs() < 1e-6);
    }

    #[test]
    fn wrap_and_differences() {
        assert_eq!(wrap_degrees_360(360.0), 0.0);
        assert_eq!(wrap_degrees_360(-1e-20), 0.0);
        assert_eq!(wrap_degrees_360(-10.0), 350.0);
        assert_eq!(wrap_radians_tau(-1e-20), 0.0);
        assert!((heading_difference_deg(1.0, 359.0) - 2.0).abs() < 1e-12);
        assert!((heading_difference_deg(359.0, 1.0) + 2.0).abs() < 1e-12);
        assert_eq!(heading_difference_deg(180.0, 0.0), -180.0);
        assert!((angle_difference(0.1, TAU - 0.1) - 0.2).abs() < 1e-12);
    }

    #[test]
    fn angle_between_quaternions() {
        let a = DQuat::from_rotation_y(0.4);
        let b = a * DQuat::from_rotation_x(0.25);
        assert!((angle_between(a, b) - 0.25).abs() < 1e-12);
        // q and −q are the same rotation.
        assert!(angle_between(a, -a) < 1e-12);
        // Tiny angles stay accurate (acos would lose them).
        let c = a * DQuat::from_rotation_z(1e-9);
        assert!((angle_between(a, c) - 1e-9).abs() < 1e-15);
        // Half a turn.
        assert!((angle_between(DQuat::IDENTITY, DQuat::from_rotation_z(PI)) - PI).abs() < 1e-12);
    }
}
