//! Android: accelerometer, gyroscope, magnetometer and rotation vector from the NDK's
//! `ASensorManager`, GPS and the display rotation through JNI ([`super::jni_location`]).
//! Compiled for Android only; the JNI half is tested on the host (tests/jni_location.rs).
//!
//! The process's `JavaVM` and activity come from `ndk-context`, which `android-activity` (the
//! winit backend) fills before `android_main` runs. Sensor event timestamps and
//! `Location.getElapsedRealtimeNanos` share the `elapsedRealtime` clock, so both are reported in
//! seconds of it.

use super::jni_location::{self, LocationBridge};
use super::platform::android_rotation_vector;
use super::{North, Reading, SensorSource, keep_valid};
use crate::pose::frames::DisplayRotation;
use anyhow::{Context, Result, bail};
use glam::DVec3;
use jni::objects::JObject;
use jni::refs::Global;
use jni::vm::JavaVM;
use ndk_sys as ffi;
use std::ffi::CString;
use std::ptr::NonNull;

/// Requested sampling interval (µs): 100 Hz, Android's `SENSOR_DELAY_GAME` is 50 Hz.
const RATE_US: i32 = 10_000;
/// Events read per `ASensorEventQueue_getEvents` call.
const BATCH: usize = 64;
/// Re-read the display rotation every this many polls (about once a second at 60 fps).
const ROTATION_EVERY: u32 = 60;

const SENSORS: [(u32, &str); 4] = [
    (ffi::ASENSOR_TYPE_ACCELEROMETER as u32, "accelerometer"),
    (ffi::ASENSOR_TYPE_GYROSCOPE as u32, "gyroscope"),
    (ffi::ASENSOR_TYPE_MAGNETIC_FIELD as u32, "magnetometer"),
    (ffi::ASENSOR_TYPE_ROTATION_VECTOR as u32, "rotation vector"),
];

/// The Android sensors and GPS.
pub struct AndroidSensors {
    manager: NonNull<ffi::ASensorManager>,
    queue: NonNull<ffi::ASensorEventQueue>,
    enabled: Vec<(*const ffi::ASensor, &'static str)>,
    missing: Vec<&'static str>,
    vm: JavaVM,
    activity: Global<JObject<'static>>,
    location: LocationBridge,
    rotation: DisplayRotation,
    polls: u32,
    rejected: u64,
    events: Vec<ffi::ASensorEvent>,
    /// Sensors disabled and location updates removed ([`SensorSource::pause`]).
    paused: bool,
}

impl AndroidSensors {
    /// Start the sensors (100 Hz) and the location bridge (which asks for the location
    /// permission on its first poll). Fails without an accelerometer.
    pub fn start() -> Result<Self> {
        let ctx = ndk_context::android_context();
        // SAFETY: android-activity stores the process's JavaVM pointer in ndk-context before
        // android_main runs; it stays valid for the life of the process.
        let vm = unsafe { JavaVM::from_raw(ctx.vm().cast()) };
        let (activity, location, package, rotation) = vm.attach_current_thread(|env| -> Result<_> {
            // SAFETY: ndk-context holds a global reference to the activity object for the life of
            // the process; we only borrow it here.
            let activity = unsafe { JObject::from_raw(env, ctx.context().cast()) };
            let location = LocationBridge::new(env, &activity)?;
            let package = jni_location::package_name(env, &activity)?;
            let rotation = jni_location::display_rotation(env, &activity).unwrap_or_default();
            let r = env.new_global_ref(&activity);
            let global = r.context("NewGlobalRef(activity)")?;
            Ok((global, location, package, rotation))
        })?;
        let package = CString::new(package).context("package name contains a NUL byte")?;
        // SAFETY: plain NDK calls with valid arguments; every pointer is checked for null.
        unsafe {
            let manager = NonNull::new(ffi::ASensorManager_getInstanceForPackage(package.as_ptr()))
                .context("ASensorManager_getInstanceForPackage returned null")?;
            let mut looper = ffi::ALooper_forThread();
            if looper.is_null() {
                looper = ffi::ALooper_prepare(ffi::ALOOPER_PREPARE_ALLOW_NON_CALLBACKS as i32);
            }
            let queue = NonNull::new(ffi::ASensorManager_createEventQueue(manager.as_ptr(), looper, 1, None, std::ptr::null_mut()))
                .context("ASensorManager_createEventQueue returned null")?;
            let mut s = AndroidSensors {
                manager,
                queue,
                enabled: Vec::new(),
                missing: Vec::new(),
                vm,
                activity,
                location,
                rotation,
                polls: 0,
                rejected: 0,
                events: Vec::with_capacity(BATCH),
                paused: false,
            };
            for (ty, name) in SENSORS {
                let sensor = ffi::ASensorManager_getDefaultSensor(manager.as_ptr(), ty as i32);
                if sensor.is_null() {
                    s.missing.push(name);
                    continue;
                }
                enable(queue, sensor, name)?;
                s.enabled.push((sensor, name));
            }
            if s.missing.contains(&"accelerometer") {
                bail!("this device has no accelerometer");
            }
            Ok(s)
        }
    }

    /// Sensors this device lacks (a phone without a gyroscope still works, more slowly).
    pub fn missing_sensors(&self) -> &[&'static str] {
        &self.missing
    }

    /// The location bridge's state (for the UI: "waiting for permission", "GPS off").
    pub fn location_state(&self) -> jni_location::LocationState {
        self.location.state()
    }
}

/// Enable one sensor on the queue at [`RATE_US`].
///
/// # Safety
/// `queue` and `sensor` are valid (the sensor from this process's `ASensorManager`).
unsafe fn enable(queue: NonNull<ffi::ASensorEventQueue>, sensor: *const ffi::ASensor, name: &str) -> Result<()> {
    // SAFETY: the caller's contract.
    unsafe {
        if ffi::ASensorEventQueue_enableSensor(queue.as_ptr(), sensor) < 0 {
            bail!("cannot enable the {name}");
        }
        // A device may refuse the rate; it then runs at its own, which is fine.
        let _ = ffi::ASensorEventQueue_setEventRate(queue.as_ptr(), sensor, RATE_US);
    }
    Ok(())
}

/// One NDK sensor event as a reading (`None` for types we did not ask for).
fn event_to_reading(e: &ffi::ASensorEvent) -> Option<Reading> {
    let t = e.timestamp as f64 * 1e-9;
    // SAFETY: every sensor event carries 16 floats in the `data` view of the union.
    let d = unsafe { e.__bindgen_anon_1.__bindgen_anon_1.data };
    let v = DVec3::new(f64::from(d[0]), f64::from(d[1]), f64::from(d[2]));
    match e.type_ as u32 {
        x if x == ffi::ASENSOR_TYPE_ACCELEROMETER as u32 => Some(Reading::Accel { t, v }),
        x if x == ffi::ASENSOR_TYPE_GYROSCOPE as u32 => Some(Reading::Gyro { t, v }),
        x if x == ffi::ASENSOR_TYPE_MAGNETIC_FIELD as u32 => Some(Reading::Mag { t, v }),
        x if x == ffi::ASENSOR_TYPE_ROTATION_VECTOR as u32 => match android_rotation_vector(&d[..5]) {
            Ok((q, heading_accuracy_rad)) => Some(Reading::Attitude { t, q, north: North::Magnetic, heading_accuracy_rad }),
            // Keep it so keep_valid counts it as rejected.
            Err(_) => Some(Reading::Attitude { t, q: glam::DQuat::NAN, north: North::Magnetic, heading_accuracy_rad: None }),
        },
        _ => None,
    }
}

impl SensorSource for AndroidSensors {
    fn poll(&mut self, _until: f64, out: &mut Vec<Reading>) -> Result<()> {
        if self.paused {
            return Ok(());
        }
        let start = out.len();
        loop {
            // SAFETY: the queue is valid until drop; the buffer has room for BATCH events.
            let n = unsafe { ffi::ASensorEventQueue_getEvents(self.queue.as_ptr(), self.events.as_mut_ptr(), BATCH) };
            if n < 0 {
                bail!("ASensorEventQueue_getEvents failed ({n})");
            }
            // SAFETY: getEvents initialised the first n events.
            unsafe { self.events.set_len(n as usize) };
            let readings: Vec<Reading> = self.events.iter().filter_map(event_to_reading).collect();
            keep_valid(readings, out, &mut self.rejected);
            self.events.clear();
            if (n as usize) < BATCH {
                break;
            }
        }
        self.polls = self.polls.wrapping_add(1);
        let check_rotation = self.polls.is_multiple_of(ROTATION_EVERY);
        let (location, activity) = (&mut self.location, &self.activity);
        let (fix, rotation) = self.vm.attach_current_thread(|env| -> Result<_> {
            let fix = location.poll(env)?;
            let rotation = if check_rotation { Some(jni_location::display_rotation(env, activity)?) } else { None };
            Ok((fix, rotation))
        })?;
        if let Some(r) = rotation {
            self.rotation = r;
        }
        if let Some(f) = fix {
            keep_valid([Reading::Gps(f)], out, &mut self.rejected);
        }
        out[start..].sort_by(|a, b| a.t().total_cmp(&b.t()));
        Ok(())
    }

    fn describe(&self) -> String {
        if self.missing.is_empty() { "Android sensors".into() } else { format!("Android sensors (no {})", self.missing.join(", ")) }
    }

    fn rejected(&self) -> u64 {
        self.rejected + self.location.rejected()
    }

    fn display_rotation(&mut self) -> Option<DisplayRotation> {
        Some(self.rotation)
    }

    /// Disable every sensor (no more events, no battery drain) and remove the location updates.
    fn pause(&mut self) -> Result<()> {
        if self.paused {
            return Ok(());
        }
        // SAFETY: the sensors were enabled on this queue, which lives until drop.
        unsafe {
            for &(s, _) in &self.enabled {
                ffi::ASensorEventQueue_disableSensor(self.queue.as_ptr(), s);
            }
        }
        let location = &mut self.location;
        self.vm.attach_current_thread(|env| location.stop(env))?;
        self.paused = true;
        Ok(())
    }

    /// Enable the sensors again; location updates restart on the next poll (after checking the
    /// permission again: the user may have revoked it meanwhile).
    fn resume(&mut self) -> Result<()> {
        if !self.paused {
            return Ok(());
        }
        for &(s, name) in &self.enabled {
            // SAFETY: the queue lives until drop; the sensor came from its manager.
            unsafe { enable(self.queue, s, name)? };
        }
        self.paused = false;
        Ok(())
    }
}

impl Drop for AndroidSensors {
    fn drop(&mut self) {
        // SAFETY: the sensors were enabled on this queue, which is destroyed exactly once here.
        unsafe {
            if !self.paused {
                for &(s, _) in &self.enabled {
                    ffi::ASensorEventQueue_disableSensor(self.queue.as_ptr(), s);
                }
            }
            ffi::ASensorManager_destroyEventQueue(self.manager.as_ptr(), self.queue.as_ptr());
        }
        let location = &mut self.location;
        let _ = self.vm.attach_current_thread(|env| location.stop(env));
    }
}
