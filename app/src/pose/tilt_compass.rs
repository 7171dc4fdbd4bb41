//! Orientation from one accelerometer and one magnetometer reading: the tilt-compensated
//! compass. It starts the fusion filter, and on its own (smoothed) it is the compass-only method
//! of seed 000 that the stability measurement compares against.

use super::frames::{DisplayRotation, camera_pose_from_device};
use super::magnetic::magnetic_to_true;
use super::{HeadingSource, OrientationEstimator, Pose};
use crate::sensors::Reading;
use anyhow::{Result, bail};
use glam::{DMat3, DQuat, DVec3};

/// Device → ENU (magnetic north) from specific force `accel` and field `mag`, both in the
/// device frame. This is Android's `SensorManager.getRotationMatrix`: East = mag × accel,
/// North = accel × East, rows (E, N, U) map device vectors into the world. Fails in free fall
/// and when the field is (nearly) vertical, where north is undefined.
pub fn tilt_compass(accel: DVec3, mag: DVec3) -> Result<DQuat> {
    let up = accel.normalize_or_zero();
    let east = mag.cross(accel);
    // Android rejects |E| < 0.1 with readings in SI units; the same relative test, scale-free.
    if up == DVec3::ZERO || east.length() < 1e-3 * accel.length() * mag.length() {
        bail!("tilt compass undefined: free fall or a vertical magnetic field");
    }
    let east = east.normalize();
    let north = up.cross(east);
    let world_from_device = DMat3::from_cols(east, north, up).transpose();
    Ok(DQuat::from_mat3(&world_from_device).normalize())
}

/// Seed 000's method: the compass-only orientation of each accelerometer + magnetometer pair,
/// low-pass filtered (slerp towards each new value with time constant `tau_s`). No gyroscope.
#[derive(Clone, Debug)]
pub struct CompassOnlyFilter {
    tau_s: f64,
    declination: f64,
    accel: Option<DVec3>,
    q: Option<DQuat>,
    t: f64,
}

impl CompassOnlyFilter {
    pub fn new(tau_s: f64, declination: f64) -> Self {
        CompassOnlyFilter { tau_s: tau_s.max(0.0), declination, accel: None, q: None, t: 0.0 }
    }
}

impl OrientationEstimator for CompassOnlyFilter {
    fn update(&mut self, r: &Reading) -> Result<()> {
        r.validate()?;
        match *r {
            Reading::Accel { v, .. } => self.accel = Some(v),
            Reading::Mag { t, v } => {
                let Some(a) = self.accel else { return Ok(()) };
                let Ok(q_mag) = tilt_compass(a, v) else { return Ok(()) };
                let target = magnetic_to_true(q_mag, self.declination);
                self.q = Some(match self.q {
                    Some(q) if self.tau_s > 0.0 => {
                        let alpha = 1.0 - (-(t - self.t).max(0.0) / self.tau_s).exp();
                        let target = if q.dot(target) < 0.0 { -target } else { target };
                        q.slerp(target, alpha).normalize()
                    }
                    _ => target,
                });
                self.t = t;
            }
            _ => {}
        }
        Ok(())
    }

    fn pose(&self, rotation: DisplayRotation) -> Option<Pose> {
        let q = self.q?;
        Some(Pose {
            t: self.t,
            q: camera_pose_from_device(q, rotation).as_quat(),
            accuracy_deg: f32::NAN,
            heading_accuracy_deg: f32::NAN,
            tilt_accuracy_deg: f32::NAN,
            heading_source: HeadingSource::Magnetometer,
            magnetic_disturbance: false,
        })
    }

    fn device_orientation(&self) -> Option<DQuat> {
        self.q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::angle_between;

    #[test]
    fn identity_when_flat_and_facing_north() {
        // Android docs: R is the identity when the device's x points East, y North and the
        // screen faces the sky. Field: north and dipping down.
        let q = tilt_compass(DVec3::new(0.0, 0.0, 9.81), DVec3::new(0.0, 20.0, -40.0)).unwrap();
        assert!(angle_between(q, DQuat::IDENTITY) < 1e-12);
    }

    #[test]
    fn recovers_any_orientation_including_vertical_views() {
        let field = DVec3::new(-0.5, 19.0, -44.0);
        for q in [
            DQuat::from_euler(glam::EulerRot::ZXY, 2.0, 0.4, -0.3),
            DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2),
            DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2) * DQuat::from_rotation_z(1.0),
            DQuat::from_rotation_y(3.0),
        ] {
            let a = q.inverse() * DVec3::new(0.0, 0.0, 9.81);
            let m = q.inverse() * field;
            let mag_north = DQuat::from_rotation_z(-field.x.atan2(field.y));
            let est = tilt_compass(a, m).unwrap();
            // The estimate is referenced to magnetic north, i.e. rotated by the declination.
            assert!(angle_between(magnetic_to_true(est, field.x.atan2(field.y)), q) < 1e-9, "{q:?}");
            assert!(angle_between(est, mag_north.inverse() * q) < 1e-9);
        }
    }

    #[test]
    fn degenerate_inputs_fail() {
        assert!(tilt_compass(DVec3::ZERO, DVec3::Y).is_err());
        assert!(tilt_compass(DVec3::Z, DVec3::new(0.0, 0.0, -40.0)).is_err());
    }

    #[test]
    fn compass_only_filter_rejects_nan_and_tracks() {
        let mut f = CompassOnlyFilter::new(0.0, 0.0);
        assert!(f.update(&Reading::Mag { t: 0.0, v: DVec3::NAN }).is_err());
        f.update(&Reading::Accel { t: 0.0, v: DVec3::new(0.0, 0.0, 9.81) }).unwrap();
        f.update(&Reading::Mag { t: 0.0, v: DVec3::new(0.0, 20.0, -40.0) }).unwrap();
        assert!(angle_between(f.device_orientation().unwrap(), DQuat::IDENTITY) < 1e-12);
    }
}
