//! iOS: CoreMotion device motion referenced to true north (`XTrueNorthZVertical`, falling back
//! to magnetic north where the device lacks it) and CoreLocation, through objc2. Compiled for
//! iOS only.
//!
//! Readings are pulled (no delegates): `CMMotionManager.deviceMotion` and
//! `CLLocationManager.location` hold the newest sample; a poll emits each new one once. From a
//! device-motion sample come the accelerometer (gravity + user acceleration, converted from g
//! with iOS's sign to this module's convention), the bias-corrected gyroscope, the calibrated
//! magnetometer (skipped while uncalibrated) and the platform attitude. Timestamps are seconds
//! of system uptime, the clock of `CMLogItem.timestamp`. Create it on the main thread (Core
//! Location needs a run loop to deliver updates and show the permission prompt).

use super::platform::{AttitudeConvention, ios_attitude_convention, ios_attitude_to_enu};
use super::{GpsFix, North, Reading, SensorSource, ios_accel_to_device, keep_valid};
use anyhow::{Result, bail};
use glam::{DQuat, DVec3};
use objc2::rc::Retained;
use objc2_core_location::{CLLocationManager, kCLLocationAccuracyNearestTenMeters};
use objc2_core_motion::{CMAttitudeReferenceFrame, CMMagneticFieldCalibrationAccuracy, CMMotionManager};
use objc2_foundation::NSProcessInfo;

/// Device-motion update interval (s): 100 Hz.
const MOTION_INTERVAL_S: f64 = 0.01;

/// The iOS sensors and location.
pub struct IosSensors {
    motion: Retained<CMMotionManager>,
    location: Retained<CLLocationManager>,
    north: North,
    convention: Option<AttitudeConvention>,
    last_motion_t: f64,
    last_fix_t: f64,
    rejected: u64,
}

impl IosSensors {
    /// Start device motion and location updates (the latter asks for "when in use" permission;
    /// Info.plist must carry `NSLocationWhenInUseUsageDescription` and
    /// `NSMotionUsageDescription`).
    pub fn start() -> Result<Self> {
        // SAFETY: plain Objective-C calls on objects we own, with valid arguments.
        unsafe {
            let motion = CMMotionManager::new();
            if !motion.isDeviceMotionAvailable() {
                bail!("CoreMotion: device motion is not available on this device");
            }
            motion.setDeviceMotionUpdateInterval(MOTION_INTERVAL_S);
            let frames = CMMotionManager::availableAttitudeReferenceFrames();
            let (frame, north) = if frames.contains(CMAttitudeReferenceFrame::XTrueNorthZVertical) {
                (CMAttitudeReferenceFrame::XTrueNorthZVertical, North::True)
            } else if frames.contains(CMAttitudeReferenceFrame::XMagneticNorthZVertical) {
                (CMAttitudeReferenceFrame::XMagneticNorthZVertical, North::Magnetic)
            } else {
                bail!("CoreMotion: no north-referenced attitude frame on this device");
            };
            motion.startDeviceMotionUpdatesUsingReferenceFrame(frame);

            let location = CLLocationManager::new();
            location.setDesiredAccuracy(kCLLocationAccuracyNearestTenMeters);
            location.requestWhenInUseAuthorization();
            location.startUpdatingLocation();
            Ok(IosSensors {
                motion,
                location,
                north,
                convention: None,
                last_motion_t: f64::NEG_INFINITY,
                last_fix_t: f64::NEG_INFINITY,
                rejected: 0,
            })
        }
    }
}

impl SensorSource for IosSensors {
    fn poll(&mut self, _until: f64, out: &mut Vec<Reading>) -> Result<()> {
        let mut readings = Vec::with_capacity(5);
        // SAFETY: property reads on objects we own.
        unsafe {
            if let Some(dm) = self.motion.deviceMotion() {
                let t = dm.timestamp();
                if t > self.last_motion_t {
                    self.last_motion_t = t;
                    let g = dm.gravity();
                    let u = dm.userAcceleration();
                    let gravity = DVec3::new(g.x, g.y, g.z);
                    readings.push(Reading::Accel { t, v: ios_accel_to_device(gravity + DVec3::new(u.x, u.y, u.z)) });
                    let w = dm.rotationRate();
                    readings.push(Reading::Gyro { t, v: DVec3::new(w.x, w.y, w.z) });
                    let m = dm.magneticField();
                    if m.accuracy != CMMagneticFieldCalibrationAccuracy::Uncalibrated {
                        readings.push(Reading::Mag { t, v: DVec3::new(m.field.x, m.field.y, m.field.z) });
                    }
                    let cq = dm.attitude().quaternion();
                    let q = DQuat::from_xyzw(cq.x, cq.y, cq.z, cq.w);
                    if self.convention.is_none() {
                        self.convention = ios_attitude_convention(q, gravity);
                    }
                    if let Some(c) = self.convention {
                        readings.push(Reading::Attitude { t, q: ios_attitude_to_enu(q, c), north: self.north, heading_accuracy_rad: None });
                    }
                }
            }
            if let Some(loc) = self.location.location() {
                let now = NSProcessInfo::processInfo().systemUptime();
                let t = now + loc.timestamp().timeIntervalSinceNow();
                let h_acc = loc.horizontalAccuracy();
                // Negative accuracies mean "invalid" in Core Location.
                if t > self.last_fix_t && h_acc >= 0.0 {
                    self.last_fix_t = t;
                    let c = loc.coordinate();
                    let v_acc = loc.verticalAccuracy();
                    readings.push(Reading::Gps(GpsFix {
                        t,
                        lat_deg: c.latitude,
                        lon_deg: c.longitude,
                        alt_m: if v_acc >= 0.0 { loc.altitude() } else { 0.0 },
                        horizontal_accuracy_m: h_acc,
                        vertical_accuracy_m: if v_acc >= 0.0 { v_acc } else { 10_000.0 },
                    }));
                }
            }
        }
        keep_valid(readings, out, &mut self.rejected);
        Ok(())
    }

    fn describe(&self) -> String {
        match self.north {
            North::True => "iOS CoreMotion (true north) + CoreLocation".into(),
            North::Magnetic => "iOS CoreMotion (magnetic north) + CoreLocation".into(),
        }
    }

    fn rejected(&self) -> u64 {
        self.rejected
    }
}

impl Drop for IosSensors {
    fn drop(&mut self) {
        // SAFETY: stopping updates we started.
        unsafe {
            self.motion.stopDeviceMotionUpdates();
            self.location.stopUpdatingLocation();
        }
    }
}
