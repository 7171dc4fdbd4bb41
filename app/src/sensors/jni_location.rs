//! Location, permissions and display rotation through JNI: the Java calls the Android backend
//! makes, written against `jni::Env` only so they compile and are tested on any host with a
//! JVM (tests/jni_location.rs runs them against Java test doubles of the Android classes).
//!
//! Calls made (all public Android SDK API, level ≥ 26):
//! - `Context.checkSelfPermission(String)`, `Activity.requestPermissions(String[], int)` for
//!   `ACCESS_FINE_LOCATION` / `ACCESS_COARSE_LOCATION` (the run-time permission request);
//! - `Context.getSystemService("location")` → `LocationManager`: `isProviderEnabled`,
//!   `getLastKnownLocation`, `requestLocationUpdates(String, long, float, LocationListener,
//!   Looper)`, `removeUpdates`;
//! - `Location` getters (latitude, longitude, altitude, accuracies, `getElapsedRealtimeNanos`,
//!   the same clock as sensor event timestamps);
//! - `Context.getClassLoader().loadClass("org.previz.LocationListenerBridge")`: the one Java
//!   class of ours (android/app/src/main/java/org/previz/LocationListenerBridge.java), a
//!   `LocationListener` that keeps the newest fix for Rust to poll;
//! - `Activity.getWindowManager().getDefaultDisplay().getRotation()`, `Context.getPackageName()`.
//!
//! Android delivers the permission answer to `Activity.onRequestPermissionsResult`, which a
//! NativeActivity does not forward; the bridge instead re-checks the permission on each poll
//! and starts location updates as soon as it is granted.

use super::GpsFix;
use crate::pose::frames::DisplayRotation;
use anyhow::{Result, anyhow};
use jni::objects::{JObject, JString};
use jni::refs::Global;
use jni::{Env, JValue, jni_sig, jni_str};

pub const FINE_LOCATION: &str = "android.permission.ACCESS_FINE_LOCATION";
pub const COARSE_LOCATION: &str = "android.permission.ACCESS_COARSE_LOCATION";
/// `PackageManager.PERMISSION_GRANTED`.
pub const PERMISSION_GRANTED: i32 = 0;
/// The request code passed to `requestPermissions` ("PZ").
pub const PERMISSION_REQUEST_CODE: i32 = 0x505A;
/// `LocationManager.GPS_PROVIDER`.
pub const GPS_PROVIDER: &str = "gps";
/// `LocationManager.NETWORK_PROVIDER`, used only for a first, coarse fix.
pub const NETWORK_PROVIDER: &str = "network";
/// Our listener class, loaded through the activity's class loader (a native thread's
/// `FindClass` would only see system classes).
pub const LISTENER_CLASS: &str = "org.previz.LocationListenerBridge";
/// Requested interval between fixes (ms).
pub const UPDATE_INTERVAL_MS: i64 = 1000;

/// Turn a JNI error into an error naming the call; a pending Java exception is caught,
/// cleared (so the JVM stays usable) and reported with its class and message.
pub(crate) fn checked<T>(env: &mut Env<'_>, what: &str, r: jni::errors::Result<T>) -> Result<T> {
    r.map_err(|e| match e {
        jni::errors::Error::JavaException => match env.exception_catch() {
            Err(jni::errors::Error::CaughtJavaException { name, msg, .. }) => anyhow!("{what}: Java threw {name}: {msg}"),
            _ => anyhow!("{what}: a Java exception was thrown"),
        },
        other => anyhow!("{what}: {other}"),
    })
}

/// A new Java string.
pub(crate) fn jstring<'l>(env: &mut Env<'l>, s: &str) -> Result<JString<'l>> {
    let r = env.new_string(s);
    checked(env, "new String", r)
}

/// The state of the location bridge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LocationState {
    /// Permission asked for; waiting for the user's answer.
    AwaitingPermission,
    /// Updates requested from the GPS provider.
    Listening,
    /// The GPS provider is switched off in the system settings (re-checked on each poll).
    ProviderDisabled,
}

/// GPS through `LocationManager`, with the run-time permission request.
#[derive(Debug)]
pub struct LocationBridge {
    activity: Global<JObject<'static>>,
    manager: Option<Global<JObject<'static>>>,
    listener: Option<Global<JObject<'static>>>,
    requested_permission: bool,
    state: LocationState,
    last_fix_t: f64,
    rejected: u64,
}

impl LocationBridge {
    /// Keep a global reference to the activity (an `android.app.Activity`).
    pub fn new(env: &mut Env<'_>, activity: &JObject<'_>) -> Result<Self> {
        let r = env.new_global_ref(activity);
        let activity = checked(env, "NewGlobalRef(activity)", r)?;
        Ok(LocationBridge {
            activity,
            manager: None,
            listener: None,
            requested_permission: false,
            state: LocationState::AwaitingPermission,
            last_fix_t: f64::NEG_INFINITY,
            rejected: 0,
        })
    }

    pub fn state(&self) -> LocationState {
        self.state
    }

    /// Fixes dropped because a value was not finite or off the globe.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// Whether the app holds the fine-location permission.
    pub fn has_permission(&self, env: &mut Env<'_>) -> Result<bool> {
        let name = jstring(env, FINE_LOCATION)?;
        let r =
            env.call_method(&self.activity, jni_str!("checkSelfPermission"), jni_sig!("(Ljava/lang/String;)I"), &[JValue::Object(&name)]);
        let v = checked(env, "Context.checkSelfPermission", r)?;
        Ok(checked(env, "checkSelfPermission result", v.i())? == PERMISSION_GRANTED)
    }

    fn request_permission(&mut self, env: &mut Env<'_>) -> Result<()> {
        let fine = jstring(env, FINE_LOCATION)?;
        let coarse = jstring(env, COARSE_LOCATION)?;
        let r = env.new_object_array(2, jni_str!("java/lang/String"), &fine);
        let array = checked(env, "new String[]", r)?;
        let r = array.set_element(env, 1, &coarse);
        checked(env, "String[] store", r)?;
        let r = env.call_method(
            &self.activity,
            jni_str!("requestPermissions"),
            jni_sig!("([Ljava/lang/String;I)V"),
            &[JValue::Object(&array), JValue::Int(PERMISSION_REQUEST_CODE)],
        );
        checked(env, "Activity.requestPermissions", r)?;
        self.requested_permission = true;
        Ok(())
    }

    fn location_manager(&mut self, env: &mut Env<'_>) -> Result<Global<JObject<'static>>> {
        if let Some(m) = &self.manager {
            let r = env.new_global_ref(m);
            return checked(env, "NewGlobalRef(manager)", r);
        }
        let name = jstring(env, "location")?;
        let r = env.call_method(
            &self.activity,
            jni_str!("getSystemService"),
            jni_sig!("(Ljava/lang/String;)Ljava/lang/Object;"),
            &[JValue::Object(&name)],
        );
        let obj = checked(env, "Context.getSystemService(\"location\")", r.and_then(|v| v.l()))?;
        if obj.is_null() {
            anyhow::bail!("Context.getSystemService(\"location\") returned null: no location service");
        }
        let r = env.new_global_ref(&obj);
        let g = checked(env, "NewGlobalRef(manager)", r)?;
        let r = env.new_global_ref(&g);
        self.manager = Some(checked(env, "NewGlobalRef(manager)", r)?);
        Ok(g)
    }

    fn provider_enabled(&mut self, env: &mut Env<'_>, manager: &JObject<'_>) -> Result<bool> {
        let gps = jstring(env, GPS_PROVIDER)?;
        let r = env.call_method(manager, jni_str!("isProviderEnabled"), jni_sig!("(Ljava/lang/String;)Z"), &[JValue::Object(&gps)]);
        let v = checked(env, "LocationManager.isProviderEnabled", r)?;
        checked(env, "isProviderEnabled result", v.z())
    }

    fn start_updates(&mut self, env: &mut Env<'_>, manager: &JObject<'_>) -> Result<()> {
        // The listener class is ours: load it through the app's class loader.
        let r = env.call_method(&self.activity, jni_str!("getClassLoader"), jni_sig!("()Ljava/lang/ClassLoader;"), &[]);
        let loader = checked(env, "Context.getClassLoader", r.and_then(|v| v.l()))?;
        let class_name = jstring(env, LISTENER_CLASS)?;
        let r = env.call_method(
            &loader,
            jni_str!("loadClass"),
            jni_sig!("(Ljava/lang/String;)Ljava/lang/Class;"),
            &[JValue::Object(&class_name)],
        );
        let class_obj = checked(env, "ClassLoader.loadClass(org.previz.LocationListenerBridge)", r.and_then(|v| v.l()))?;
        let r = env.cast_local::<jni::objects::JClass>(class_obj);
        let class = checked(env, "cast to Class", r)?;
        let r = env.new_object(&class, jni_sig!("()V"), &[]);
        let listener = checked(env, "new LocationListenerBridge()", r)?;
        let r = env.call_static_method(jni_str!("android/os/Looper"), jni_str!("getMainLooper"), jni_sig!("()Landroid/os/Looper;"), &[]);
        let looper = checked(env, "Looper.getMainLooper", r.and_then(|v| v.l()))?;
        let gps = jstring(env, GPS_PROVIDER)?;
        let r = env.call_method(
            manager,
            jni_str!("requestLocationUpdates"),
            jni_sig!("(Ljava/lang/String;JFLandroid/location/LocationListener;Landroid/os/Looper;)V"),
            &[
                JValue::Object(&gps),
                JValue::Long(UPDATE_INTERVAL_MS),
                JValue::Float(0.0),
                JValue::Object(&listener),
                JValue::Object(&looper),
            ],
        );
        checked(env, "LocationManager.requestLocationUpdates", r)?;
        let r = env.new_global_ref(&listener);
        self.listener = Some(checked(env, "NewGlobalRef(listener)", r)?);
        Ok(())
    }

    /// Advance the permission / provider state machine and return the newest fix not returned
    /// before, if any. Call it every frame or so; it is cheap once listening.
    pub fn poll(&mut self, env: &mut Env<'_>) -> Result<Option<GpsFix>> {
        if self.listener.is_none() {
            if !self.has_permission(env)? {
                if !self.requested_permission {
                    self.request_permission(env)?;
                }
                self.state = LocationState::AwaitingPermission;
                return Ok(None);
            }
            let manager = self.location_manager(env)?;
            if !self.provider_enabled(env, &manager)? {
                self.state = LocationState::ProviderDisabled;
                return Ok(None);
            }
            self.start_updates(env, &manager)?;
            self.state = LocationState::Listening;
            // A first fix without waiting: the newest last-known location of GPS or network.
            let mut best: Option<GpsFix> = None;
            for provider in [GPS_PROVIDER, NETWORK_PROVIDER] {
                let p = jstring(env, provider)?;
                let r = env.call_method(
                    &manager,
                    jni_str!("getLastKnownLocation"),
                    jni_sig!("(Ljava/lang/String;)Landroid/location/Location;"),
                    &[JValue::Object(&p)],
                );
                let loc = checked(env, "LocationManager.getLastKnownLocation", r.and_then(|v| v.l()))?;
                if !loc.is_null()
                    && let Some(fix) = self.read_fix(env, &loc)?
                    && best.is_none_or(|b| fix.t > b.t)
                {
                    best = Some(fix);
                }
            }
            if let Some(fix) = best {
                self.last_fix_t = fix.t;
                return Ok(Some(fix));
            }
            return Ok(None);
        }
        let Some(listener) = &self.listener else { return Ok(None) };
        let r = env.call_method(listener, jni_str!("latest"), jni_sig!("()Landroid/location/Location;"), &[]);
        let loc = checked(env, "LocationListenerBridge.latest", r.and_then(|v| v.l()))?;
        if loc.is_null() {
            return Ok(None);
        }
        match self.read_fix(env, &loc)? {
            Some(fix) if fix.t > self.last_fix_t => {
                self.last_fix_t = fix.t;
                Ok(Some(fix))
            }
            _ => Ok(None),
        }
    }

    /// Read a `Location`; `None` (and counted) when a value is not usable.
    fn read_fix(&mut self, env: &mut Env<'_>, loc: &JObject<'_>) -> Result<Option<GpsFix>> {
        let double = |env: &mut Env<'_>, name: &'static jni::strings::JNIStr, what: &str| -> Result<f64> {
            let r = env.call_method(loc, name, jni_sig!("()D"), &[]);
            let v = checked(env, what, r)?;
            checked(env, what, v.d())
        };
        let lat = double(env, jni_str!("getLatitude"), "Location.getLatitude")?;
        let lon = double(env, jni_str!("getLongitude"), "Location.getLongitude")?;
        let alt = double(env, jni_str!("getAltitude"), "Location.getAltitude")?;
        let boolean = |env: &mut Env<'_>, name: &'static jni::strings::JNIStr, what: &str| -> Result<bool> {
            let r = env.call_method(loc, name, jni_sig!("()Z"), &[]);
            let v = checked(env, what, r)?;
            checked(env, what, v.z())
        };
        let has_alt = boolean(env, jni_str!("hasAltitude"), "Location.hasAltitude")?;
        let has_acc = boolean(env, jni_str!("hasAccuracy"), "Location.hasAccuracy")?;
        let has_vacc = boolean(env, jni_str!("hasVerticalAccuracy"), "Location.hasVerticalAccuracy")?;
        let float = |env: &mut Env<'_>, name: &'static jni::strings::JNIStr, what: &str| -> Result<f64> {
            let r = env.call_method(loc, name, jni_sig!("()F"), &[]);
            let v = checked(env, what, r)?;
            Ok(f64::from(checked(env, what, v.f())?))
        };
        let acc = float(env, jni_str!("getAccuracy"), "Location.getAccuracy")?;
        let vacc = float(env, jni_str!("getVerticalAccuracyMeters"), "Location.getVerticalAccuracyMeters")?;
        let r = env.call_method(loc, jni_str!("getElapsedRealtimeNanos"), jni_sig!("()J"), &[]);
        let v = checked(env, "Location.getElapsedRealtimeNanos", r)?;
        let nanos = checked(env, "Location.getElapsedRealtimeNanos", v.j())?;
        // Unknown accuracies become large (not NaN): the filter only needs "roughly here".
        let fix = GpsFix {
            t: nanos as f64 * 1e-9,
            lat_deg: lat,
            lon_deg: lon,
            alt_m: if has_alt { alt } else { 0.0 },
            horizontal_accuracy_m: if has_acc { acc } else { 1000.0 },
            vertical_accuracy_m: if has_vacc {
                vacc
            } else if has_alt {
                1000.0
            } else {
                10_000.0
            },
        };
        if super::Reading::Gps(fix).validate().is_err() {
            self.rejected += 1;
            return Ok(None);
        }
        Ok(Some(fix))
    }

    /// Stop location updates (also done on drop by the Android backend).
    pub fn stop(&mut self, env: &mut Env<'_>) -> Result<()> {
        if let (Some(manager), Some(listener)) = (&self.manager, self.listener.take()) {
            let r = env.call_method(
                manager,
                jni_str!("removeUpdates"),
                jni_sig!("(Landroid/location/LocationListener;)V"),
                &[JValue::Object(&listener)],
            );
            checked(env, "LocationManager.removeUpdates", r)?;
        }
        Ok(())
    }
}

/// `Activity.getWindowManager().getDefaultDisplay().getRotation()`.
pub fn display_rotation(env: &mut Env<'_>, activity: &JObject<'_>) -> Result<DisplayRotation> {
    let r = env.call_method(activity, jni_str!("getWindowManager"), jni_sig!("()Landroid/view/WindowManager;"), &[]);
    let wm = checked(env, "Activity.getWindowManager", r.and_then(|v| v.l()))?;
    let r = env.call_method(&wm, jni_str!("getDefaultDisplay"), jni_sig!("()Landroid/view/Display;"), &[]);
    let display = checked(env, "WindowManager.getDefaultDisplay", r.and_then(|v| v.l()))?;
    let r = env.call_method(&display, jni_str!("getRotation"), jni_sig!("()I"), &[]);
    let v = checked(env, "Display.getRotation", r)?;
    DisplayRotation::from_android_surface_rotation(checked(env, "Display.getRotation", v.i())?)
}

/// `Context.getPackageName()` (for `ASensorManager_getInstanceForPackage`).
pub fn package_name(env: &mut Env<'_>, activity: &JObject<'_>) -> Result<String> {
    let r = env.call_method(activity, jni_str!("getPackageName"), jni_sig!("()Ljava/lang/String;"), &[]);
    let obj = checked(env, "Context.getPackageName", r.and_then(|v| v.l()))?;
    let r = env.cast_local::<JString>(obj);
    let s = checked(env, "cast to String", r)?;
    let r = s.try_to_string(env);
    checked(env, "String contents", r)
}
