//! Motion and location sensors behind one trait, [`SensorSource`].
//!
//! Units and frames (the same for every backend):
//! - time: seconds on the source's clock (Android: `elapsedRealtimeNanos` base; iOS: system
//!   uptime; sim/replay: the trace's time);
//! - accelerometer: m/s², specific force in the device frame, so a phone lying face-up reads
//!   about +9.81 on z (Android's sign; iOS readings are converted, see [`ios_accel_to_device`]);
//! - gyroscope: rad/s about the device axes, right-handed;
//! - magnetometer: µT in the device frame;
//! - GPS: WGS 84 latitude/longitude in degrees, altitude in metres, accuracies in metres
//!   (horizontal: radius of 68 % confidence, as Android reports it);
//! - platform attitude (Android rotation vector, iOS CoreMotion attitude): device → ENU.
//!
//! The device frame is Android's sensor frame (see [`crate::pose::frames`]). Every reading is
//! checked by [`Reading::validate`]: a NaN or infinite value is an error, never a state.
//!
//! Backends: [`sim`] (synthetic readings from a true pose path with a noise model), [`replay`]
//! (a recorded trace CSV), `android` and `ios` (only on those targets).

use anyhow::{Result, bail};
use glam::{DQuat, DVec3};

pub mod csv;
pub mod jni_location;
pub mod permissions;
pub mod platform;
pub mod replay;
pub mod sim;

#[cfg(target_os = "android")]
pub mod android;
#[cfg(target_os = "ios")]
pub mod ios;

/// Standard gravity (m/s², CGPM 1901), used to convert iOS readings given in g.
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// A GPS (or fused location) fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpsFix {
    pub t: f64,
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Metres (above the WGS 84 ellipsoid on Android; above mean sea level on iOS).
    pub alt_m: f64,
    /// Horizontal accuracy (m, 68 % radius).
    pub horizontal_accuracy_m: f64,
    /// Vertical accuracy (m, 1σ); NaN is not allowed, use a large value when unknown.
    pub vertical_accuracy_m: f64,
}

/// Which north a platform attitude is referenced to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum North {
    /// Android's rotation-vector sensor: y axis towards magnetic north.
    Magnetic,
    /// iOS `CMAttitudeReferenceFrameXTrueNorthZVertical` (converted to ENU).
    True,
}

/// One sensor reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reading {
    /// Specific force (m/s², device frame).
    Accel {
        t: f64,
        v: DVec3,
    },
    /// Angular rate (rad/s, device frame).
    Gyro {
        t: f64,
        v: DVec3,
    },
    /// Magnetic field (µT, device frame).
    Mag {
        t: f64,
        v: DVec3,
    },
    Gps(GpsFix),
    /// The platform's own fused orientation, device → ENU.
    Attitude {
        t: f64,
        q: DQuat,
        north: North,
        heading_accuracy_rad: Option<f64>,
    },
}

impl Reading {
    pub fn t(&self) -> f64 {
        match *self {
            Reading::Accel { t, .. } | Reading::Gyro { t, .. } | Reading::Mag { t, .. } => t,
            Reading::Gps(f) => f.t,
            Reading::Attitude { t, .. } => t,
        }
    }

    /// The sensor's name as used in trace files.
    pub fn sensor_name(&self) -> &'static str {
        match self {
            Reading::Accel { .. } => "accel",
            Reading::Gyro { .. } => "gyro",
            Reading::Mag { .. } => "mag",
            Reading::Gps(_) => "gps",
            Reading::Attitude { north: North::Magnetic, .. } => "attitude_magnetic",
            Reading::Attitude { north: North::True, .. } => "attitude_true",
        }
    }

    /// Reject readings a filter must never see: non-finite values, impossible coordinates,
    /// negative accuracies, quaternions that are not unit length (tolerance 1e-3).
    pub fn validate(&self) -> Result<()> {
        let name = self.sensor_name();
        if !self.t().is_finite() {
            bail!("{name} reading has a non-finite timestamp {}", self.t());
        }
        match *self {
            Reading::Accel { v, .. } | Reading::Gyro { v, .. } | Reading::Mag { v, .. } => {
                if !v.is_finite() {
                    bail!("{name} reading at t={} is not finite: {v:?}", self.t());
                }
            }
            Reading::Gps(f) => {
                let vals = [f.lat_deg, f.lon_deg, f.alt_m, f.horizontal_accuracy_m, f.vertical_accuracy_m];
                if vals.iter().any(|v| !v.is_finite()) {
                    bail!("gps fix at t={} has a non-finite value: {f:?}", f.t);
                }
                if f.lat_deg.abs() > 90.0 || !(-180.0..=360.0).contains(&f.lon_deg) {
                    bail!("gps fix at t={} is off the globe: lat {}, lon {}", f.t, f.lat_deg, f.lon_deg);
                }
                if f.horizontal_accuracy_m < 0.0 || f.vertical_accuracy_m < 0.0 {
                    bail!("gps fix at t={} has a negative accuracy", f.t);
                }
            }
            Reading::Attitude { q, heading_accuracy_rad, t, .. } => {
                check_unit_quaternion(q).map_err(|e| anyhow::anyhow!("{name} reading at t={t}: {e}"))?;
                if heading_accuracy_rad.is_some_and(|a| !a.is_finite() || a < 0.0) {
                    bail!("{name} reading at t={t} has an invalid heading accuracy {heading_accuracy_rad:?}");
                }
            }
        }
        Ok(())
    }
}

/// Largest deviation of |q| from 1 accepted from files and platforms (they store 6–7 digits).
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// Check that a quaternion is finite and of unit length (within [`UNIT_QUATERNION_TOLERANCE`]).
pub fn check_unit_quaternion(q: DQuat) -> Result<()> {
    if !q.is_finite() {
        bail!("quaternion is not finite: {q:?}");
    }
    let n = q.length();
    if (n - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
        bail!("quaternion is not unit length (norm {n:.6})");
    }
    Ok(())
}

/// A source of sensor readings.
pub trait SensorSource {
    /// Append to `out`, in time order, the readings with timestamps up to `until` (seconds, the
    /// source's clock) that have not been delivered yet. Live sources deliver whatever has
    /// arrived (pass `f64::INFINITY`); simulated and replayed ones stop exactly at `until`.
    /// Invalid readings from a live sensor are dropped and counted, never delivered.
    fn poll(&mut self, until: f64, out: &mut Vec<Reading>) -> Result<()>;

    /// A short description for logs and the UI ("sim (phone noise, seed 3)").
    fn describe(&self) -> String;

    /// How many readings were dropped because [`Reading::validate`] rejected them.
    fn rejected(&self) -> u64 {
        0
    }

    /// The display rotation the source knows of (live Android, the simulator), if any.
    fn display_rotation(&mut self) -> Option<crate::pose::frames::DisplayRotation> {
        None
    }

    /// Stop the sensors' callbacks (the app went to the background): no reading is produced or
    /// queued until [`SensorSource::resume`]. Replayed and simulated sources have none.
    fn pause(&mut self) -> Result<()> {
        Ok(())
    }

    /// Start the sensors again after [`SensorSource::pause`].
    fn resume(&mut self) -> Result<()> {
        Ok(())
    }
}

/// Convert an iOS CoreMotion acceleration (in g, and with the opposite sign convention: a phone
/// face-up reads z = −1) to this module's convention (m/s², face-up reads +9.81). CoreMotion's
/// `CMDeviceMotion.gravity + userAcceleration` or `CMAccelerometerData.acceleration` both use it.
pub fn ios_accel_to_device(g_units: DVec3) -> DVec3 {
    -g_units * STANDARD_GRAVITY
}

/// Keep only valid readings, counting the others (for live backends).
pub fn keep_valid(readings: impl IntoIterator<Item = Reading>, out: &mut Vec<Reading>, rejected: &mut u64) {
    for r in readings {
        if r.validate().is_ok() {
            out.push(r);
        } else {
            *rejected += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_and_impossible_readings_are_rejected() {
        assert!(Reading::Accel { t: 0.0, v: DVec3::new(0.0, f64::NAN, 9.8) }.validate().is_err());
        assert!(Reading::Gyro { t: f64::NAN, v: DVec3::ZERO }.validate().is_err());
        assert!(Reading::Mag { t: 1.0, v: DVec3::new(f64::INFINITY, 0.0, 0.0) }.validate().is_err());
        let fix = GpsFix { t: 0.0, lat_deg: 51.45, lon_deg: -2.59, alt_m: 20.0, horizontal_accuracy_m: 10.0, vertical_accuracy_m: 15.0 };
        assert!(Reading::Gps(fix).validate().is_ok());
        assert!(Reading::Gps(GpsFix { lat_deg: f64::NAN, ..fix }).validate().is_err());
        assert!(Reading::Gps(GpsFix { lat_deg: 91.0, ..fix }).validate().is_err());
        assert!(Reading::Gps(GpsFix { horizontal_accuracy_m: -1.0, ..fix }).validate().is_err());
        let att = |q| Reading::Attitude { t: 0.0, q, north: North::True, heading_accuracy_rad: None };
        assert!(att(DQuat::IDENTITY).validate().is_ok());
        assert!(att(DQuat::from_xyzw(0.0, 0.0, 0.0, 1.01)).validate().is_err());
        assert!(att(DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0)).validate().is_err());
    }

    #[test]
    fn keep_valid_counts_rejects() {
        let mut out = Vec::new();
        let mut rejected = 0;
        let rs = [Reading::Gyro { t: 0.0, v: DVec3::ZERO }, Reading::Gyro { t: 0.1, v: DVec3::NAN }, Reading::Gyro { t: 0.2, v: DVec3::X }];
        keep_valid(rs, &mut out, &mut rejected);
        assert_eq!(out.len(), 2);
        assert_eq!(rejected, 1);
    }

    #[test]
    fn ios_acceleration_sign_and_units() {
        // Apple: a device lying flat on a table, screen up, reads (0, 0, −1) g.
        let a = ios_accel_to_device(DVec3::new(0.0, 0.0, -1.0));
        assert!((a - DVec3::new(0.0, 0.0, STANDARD_GRAVITY)).length() < 1e-12);
    }
}
