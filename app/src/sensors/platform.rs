//! Conversions of the platforms' own orientation outputs into device → ENU quaternions. Pure
//! functions, compiled and tested on every host; the Android and iOS backends call them.

use anyhow::{Result, bail};
use glam::{DQuat, DVec3};

/// Android `TYPE_ROTATION_VECTOR` event values → (device → ENU with magnetic north, heading
/// accuracy in radians if reported).
///
/// Android documents the values as x·sin(θ/2), y·sin(θ/2), z·sin(θ/2), then optionally
/// cos(θ/2) and the estimated heading accuracy in radians (−1 if unavailable);
/// `SensorManager.getQuaternionFromVector` computes w = √(1 − x² − y² − z²) when cos(θ/2) is
/// absent. The rotation maps device to world (East, North, Up) like `getRotationMatrix`.
pub fn android_rotation_vector(values: &[f32]) -> Result<(DQuat, Option<f64>)> {
    if values.len() < 3 {
        bail!("rotation vector has {} values, expected at least 3", values.len());
    }
    let v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
    if v.iter().take(5).any(|x| !x.is_finite()) {
        bail!("rotation vector has a non-finite value: {values:?}");
    }
    let (x, y, z) = (v[0], v[1], v[2]);
    let w = if v.len() >= 4 { v[3] } else { (1.0 - x * x - y * y - z * z).max(0.0).sqrt() };
    let q = DQuat::from_xyzw(x, y, z, w);
    super::check_unit_quaternion(q)?;
    let accuracy = v.get(4).copied().filter(|a| *a >= 0.0);
    Ok((q.normalize(), accuracy))
}

/// The turn from CoreMotion's `XTrueNorthZVertical` reference frame (x true north, z up, so y
/// west) to ENU: a quarter turn about z, taking x_ref → North and y_ref → West.
pub fn ios_reference_to_enu() -> DQuat {
    DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2)
}

/// Which way round CoreMotion's attitude quaternion maps frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AttitudeConvention {
    /// The quaternion maps device vectors into the reference frame.
    DeviceToReference,
    /// The quaternion maps reference-frame vectors into the device frame.
    ReferenceToDevice,
}

/// Device → ENU from a CoreMotion attitude quaternion under a convention.
pub fn ios_attitude_to_enu(q: DQuat, convention: AttitudeConvention) -> DQuat {
    let device_to_ref = match convention {
        AttitudeConvention::DeviceToReference => q,
        AttitudeConvention::ReferenceToDevice => q.inverse(),
    };
    (ios_reference_to_enu() * device_to_ref).normalize()
}

/// Apple's documentation does not say in which direction `CMAttitude.quaternion` rotates, so
/// decide it from the same sample's `CMDeviceMotion.gravity` (device frame, in g, pointing
/// down): the right convention predicts it. `None` while the two conventions predict nearly
/// the same gravity (attitudes close to a half turn about the vertical or to identity), where
/// the choice does not matter yet.
pub fn ios_attitude_convention(q: DQuat, gravity_g: DVec3) -> Option<AttitudeConvention> {
    let g = gravity_g.normalize_or_zero();
    if g == DVec3::ZERO {
        return None;
    }
    let predict = |c| ios_attitude_to_enu(q, c).inverse() * DVec3::NEG_Z;
    let a = predict(AttitudeConvention::DeviceToReference).distance(g);
    let b = predict(AttitudeConvention::ReferenceToDevice).distance(g);
    if (a - b).abs() < 0.2 {
        None
    } else if a < b {
        Some(AttitudeConvention::DeviceToReference)
    } else {
        Some(AttitudeConvention::ReferenceToDevice)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::angle_between;

    #[test]
    fn android_rotation_vector_parsing() {
        // A 90° turn about z (device y pointing west): x = y = 0, z = sin 45°, w = cos 45°.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let (q, acc) = android_rotation_vector(&[0.0, 0.0, s, s, 0.05]).unwrap();
        assert!(angle_between(q, DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2)) < 1e-6);
        assert!((acc.unwrap() - 0.05).abs() < 1e-7);
        // Device y (top) points West: (−1, 0, 0) in ENU.
        assert!((q * DVec3::Y - DVec3::NEG_X).length() < 1e-6);
        // Without cos(θ/2), w is recovered; −1 accuracy means "unknown".
        let (q3, acc3) = android_rotation_vector(&[0.0, 0.0, s]).unwrap();
        assert!(angle_between(q3, q) < 1e-6 && acc3.is_none());
        assert!(android_rotation_vector(&[0.0, 0.0, s, s, -1.0]).unwrap().1.is_none());
        assert!(android_rotation_vector(&[f32::NAN, 0.0, 0.0, 1.0]).is_err());
        assert!(android_rotation_vector(&[0.5, 0.5, 0.5, 0.9]).is_err());
        assert!(android_rotation_vector(&[0.0, 0.0]).is_err());
    }

    #[test]
    fn ios_reference_frame_to_enu() {
        let r = ios_reference_to_enu();
        assert!((r * DVec3::X - DVec3::Y).length() < 1e-12); // x_ref = North
        assert!((r * DVec3::Y - DVec3::NEG_X).length() < 1e-12); // y_ref = West
        assert!((r * DVec3::Z - DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn ios_convention_is_decided_by_gravity() {
        let device_to_enu = DQuat::from_euler(glam::EulerRot::ZXY, 0.7, 1.1, -0.3);
        let device_to_ref = ios_reference_to_enu().inverse() * device_to_enu;
        let gravity = device_to_enu.inverse() * DVec3::NEG_Z;
        for (q, c) in
            [(device_to_ref, AttitudeConvention::DeviceToReference), (device_to_ref.inverse(), AttitudeConvention::ReferenceToDevice)]
        {
            assert_eq!(ios_attitude_convention(q, gravity), Some(c));
            assert!(angle_between(ios_attitude_to_enu(q, c), device_to_enu) < 1e-12);
        }
        // Flat and level, both conventions predict the same gravity: undecided.
        assert_eq!(ios_attitude_convention(DQuat::from_rotation_z(0.3), DVec3::NEG_Z), None);
        assert_eq!(ios_attitude_convention(DQuat::IDENTITY, DVec3::ZERO), None);
    }
}
