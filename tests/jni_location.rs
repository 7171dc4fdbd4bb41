//! The Android location bridge (app/src/sensors/jni_location.rs) on the host JVM, against Java
//! test doubles of the Android classes it calls (tests/java/android/...) and our real listener
//! class (android/app/src/main/java/org/previz/LocationListenerBridge.java). The Java sources
//! are compiled with `javac` once per test process; one JVM per process (OnceLock).

use jni::objects::JObject;
use jni::vm::{InitArgsBuilder, JavaVM};
use jni::{Env, JValue, jni_sig, jni_str};
use previz::pose::DisplayRotation;
use previz::sensors::jni_location::{self, LocationBridge, LocationState};
use previz::sensors::permissions::{self, Answer, Permission, PermissionFlow};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

fn java_sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            java_sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "java") {
            out.push(p);
        }
    }
}

fn classes_dir() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("jni-location-classes");
    std::fs::create_dir_all(&out).unwrap();
    let mut srcs = Vec::new();
    java_sources(&root.join("tests/java"), &mut srcs);
    java_sources(&root.join("android/app/src/main/java"), &mut srcs);
    let status = std::process::Command::new("javac")
        .arg("-d")
        .arg(&out)
        .args(&srcs)
        .status()
        .expect("javac must be installed (OpenJDK 17) to test the JNI bridge");
    assert!(status.success(), "javac failed on {srcs:?}");
    out
}

fn jvm() -> &'static JavaVM {
    static JVM: OnceLock<JavaVM> = OnceLock::new();
    JVM.get_or_init(|| {
        let cp = classes_dir();
        let args = InitArgsBuilder::new().option(format!("-Djava.class.path={}", cp.display())).option("-Xcheck:jni").build().unwrap();
        JavaVM::new(args).expect("start the host JVM")
    })
}

/// The tests share one JVM; run them one at a time so Java state is not interleaved.
fn with_env<T>(f: impl FnOnce(&mut Env<'_>) -> anyhow::Result<T>) -> T {
    static LOCK: Mutex<()> = Mutex::new(());
    let _g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    jvm().attach_current_thread(|env| -> anyhow::Result<T> { f(env) }).unwrap()
}

fn new_activity<'l>(env: &mut Env<'l>) -> JObject<'l> {
    env.new_object(jni_str!("android/app/Activity"), jni_sig!("()V"), &[]).unwrap()
}

fn call<'l>(
    env: &mut Env<'l>,
    obj: &JObject<'_>,
    name: &'static jni::strings::JNIStr,
    sig: &'static str,
    args: &[JValue],
) -> jni::JValueOwned<'l> {
    let sig = jni::signature::RuntimeMethodSignature::from_str(sig).unwrap();
    env.call_method(obj, name, jni::signature::MethodSignature::from(&sig), args).unwrap()
}

fn manager<'l>(env: &mut Env<'l>, activity: &JObject<'_>) -> JObject<'l> {
    call(env, activity, jni_str!("testLocationManager"), "()Landroid/location/LocationManager;", &[]).l().unwrap()
}

fn location<'l>(env: &mut Env<'l>, lat: f64, lon: f64, alt: Option<f64>, acc: f32, nanos: i64) -> JObject<'l> {
    let p = env.new_string("gps").unwrap();
    let l = env.new_object(jni_str!("android/location/Location"), jni_sig!("(Ljava/lang/String;)V"), &[JValue::Object(&p)]).unwrap();
    call(env, &l, jni_str!("setLatitude"), "(D)V", &[JValue::Double(lat)]);
    call(env, &l, jni_str!("setLongitude"), "(D)V", &[JValue::Double(lon)]);
    if let Some(a) = alt {
        call(env, &l, jni_str!("setAltitude"), "(D)V", &[JValue::Double(a)]);
        call(env, &l, jni_str!("setVerticalAccuracyMeters"), "(F)V", &[JValue::Float(15.0)]);
    }
    call(env, &l, jni_str!("setAccuracy"), "(F)V", &[JValue::Float(acc)]);
    call(env, &l, jni_str!("setElapsedRealtimeNanos"), "(J)V", &[JValue::Long(nanos)]);
    l
}

fn java_string(env: &mut Env<'_>, v: jni::JValueOwned<'_>) -> String {
    let o = v.l().unwrap();
    let s = env.cast_local::<jni::objects::JString>(o).unwrap();
    s.try_to_string(env).unwrap()
}

#[test]
fn permission_is_requested_once_then_updates_start_and_fixes_arrive() {
    with_env(|env| {
        let activity = new_activity(env);
        let mut bridge = LocationBridge::new(env, &activity)?;
        // No permission yet: the bridge asks, once, for fine and coarse location.
        assert_eq!(bridge.poll(env)?, None);
        assert_eq!(bridge.poll(env)?, None);
        assert_eq!(bridge.state(), LocationState::AwaitingPermission);
        assert_eq!(call(env, &activity, jni_str!("testRequestCount"), "()I", &[]).i()?, 1);
        let v = call(env, &activity, jni_str!("testLastRequested"), "()Ljava/lang/String;", &[]);
        assert_eq!(java_string(env, v), format!("{},{}", jni_location::FINE_LOCATION, jni_location::COARSE_LOCATION));
        assert_eq!(call(env, &activity, jni_str!("testLastRequestCode"), "()I", &[]).i()?, jni_location::PERMISSION_REQUEST_CODE);
        assert!(!bridge.has_permission(env)?);

        // The user grants it; a last-known network fix exists.
        call(env, &activity, jni_str!("testSetGranted"), "(Z)V", &[JValue::Bool(true)]);
        let lm = manager(env, &activity);
        let net = location(env, 51.45, -2.59, None, 800.0, 5_000_000_000);
        let p = env.new_string("network")?;
        call(
            env,
            &lm,
            jni_str!("testSetLastKnown"),
            "(Ljava/lang/String;Landroid/location/Location;)V",
            &[JValue::Object(&p), JValue::Object(&net)],
        );
        let first = bridge.poll(env)?.expect("the last-known fix comes at once");
        assert_eq!(bridge.state(), LocationState::Listening);
        assert_eq!((first.lat_deg, first.lon_deg, first.t), (51.45, -2.59, 5.0));
        assert_eq!(first.horizontal_accuracy_m, 800.0);
        // No altitude in that fix: altitude 0 with a large vertical uncertainty, never NaN.
        assert!(first.vertical_accuracy_m >= 1000.0);
        let v = call(env, &lm, jni_str!("testRequest"), "()Ljava/lang/String;", &[]);
        assert_eq!(java_string(env, v), format!("gps,{},0.0,org.previz.LocationListenerBridge", jni_location::UPDATE_INTERVAL_MS));
        // Nothing new until the system delivers a fix.
        assert_eq!(bridge.poll(env)?, None);
        let fix = location(env, 51.4545, -2.5879, Some(20.5), 8.0, 6_500_000_000);
        assert!(call(env, &lm, jni_str!("testDeliver"), "(Landroid/location/Location;)Z", &[JValue::Object(&fix)]).z()?);
        let got = bridge.poll(env)?.expect("delivered fix");
        assert_eq!((got.lat_deg, got.lon_deg, got.alt_m, got.t), (51.4545, -2.5879, 20.5, 6.5));
        assert_eq!((got.horizontal_accuracy_m, got.vertical_accuracy_m), (8.0, 15.0));
        // The same fix is not returned twice.
        assert_eq!(bridge.poll(env)?, None);
        bridge.stop(env)?;
        assert!(!call(env, &lm, jni_str!("testListening"), "()Z", &[]).z()?);
        assert_eq!(call(env, &lm, jni_str!("testRemoved"), "()I", &[]).i()?, 1);
        Ok(())
    });
}

#[test]
fn nan_fixes_are_rejected_and_counted() {
    with_env(|env| {
        let activity = new_activity(env);
        call(env, &activity, jni_str!("testSetGranted"), "(Z)V", &[JValue::Bool(true)]);
        let mut bridge = LocationBridge::new(env, &activity)?;
        assert_eq!(bridge.poll(env)?, None);
        let lm = manager(env, &activity);
        let bad = location(env, f64::NAN, 10.0, Some(5.0), 5.0, 1_000_000_000);
        call(env, &lm, jni_str!("testDeliver"), "(Landroid/location/Location;)Z", &[JValue::Object(&bad)]);
        assert_eq!(bridge.poll(env)?, None);
        assert_eq!(bridge.rejected(), 1);
        let good = location(env, 10.0, 10.0, Some(5.0), 5.0, 2_000_000_000);
        call(env, &lm, jni_str!("testDeliver"), "(Landroid/location/Location;)Z", &[JValue::Object(&good)]);
        assert_eq!(bridge.poll(env)?.map(|f| f.lat_deg), Some(10.0));
        Ok(())
    });
}

#[test]
fn disabled_provider_and_java_exceptions_are_reported_and_recoverable() {
    with_env(|env| {
        let activity = new_activity(env);
        call(env, &activity, jni_str!("testSetGranted"), "(Z)V", &[JValue::Bool(true)]);
        let lm = manager(env, &activity);
        call(env, &lm, jni_str!("testSetGpsEnabled"), "(Z)V", &[JValue::Bool(false)]);
        let mut bridge = LocationBridge::new(env, &activity)?;
        assert_eq!(bridge.poll(env)?, None);
        assert_eq!(bridge.state(), LocationState::ProviderDisabled);
        // Switched on, but the system throws (permission revoked meanwhile): a clear error, the
        // exception cleared, and the JVM still usable for the next poll.
        call(env, &lm, jni_str!("testSetGpsEnabled"), "(Z)V", &[JValue::Bool(true)]);
        call(env, &lm, jni_str!("testSetThrowSecurity"), "(Z)V", &[JValue::Bool(true)]);
        let e = bridge.poll(env).unwrap_err().to_string();
        assert!(e.contains("requestLocationUpdates") && e.contains("SecurityException") && e.contains("ACCESS_FINE_LOCATION"), "{e}");
        assert!(!env.exception_check());
        call(env, &lm, jni_str!("testSetThrowSecurity"), "(Z)V", &[JValue::Bool(false)]);
        assert_eq!(bridge.poll(env)?, None);
        assert_eq!(bridge.state(), LocationState::Listening);
        Ok(())
    });
}

#[test]
fn display_rotation_and_package_name() {
    with_env(|env| {
        let activity = new_activity(env);
        for (value, expected) in
            [(0, DisplayRotation::R0), (1, DisplayRotation::R90), (2, DisplayRotation::R180), (3, DisplayRotation::R270)]
        {
            call(env, &activity, jni_str!("testSetRotation"), "(I)V", &[JValue::Int(value)]);
            assert_eq!(jni_location::display_rotation(env, &activity)?, expected);
        }
        call(env, &activity, jni_str!("testSetRotation"), "(I)V", &[JValue::Int(7)]);
        assert!(jni_location::display_rotation(env, &activity).is_err());
        assert_eq!(jni_location::package_name(env, &activity)?, "org.previz.app");
        Ok(())
    });
}

/// The first-start permission flow (sensors::permissions) with the user's answer scripted in the
/// Activity double: `answer` 1 allow, 2 deny, 3 deny + don't ask again.
fn flow_with_answer<'l>(env: &mut Env<'l>, answer: i32) -> anyhow::Result<(JObject<'l>, PermissionFlow)> {
    let activity = new_activity(env);
    call(env, &activity, jni_str!("testSetAnswer"), "(I)V", &[JValue::Int(answer)]);
    let mut flow = PermissionFlow::default();
    assert_eq!(flow.answer(Permission::Camera), Answer::Pending, "before the dialog");
    flow.start(env, &activity)?;
    // One dialog for both, with the three names.
    assert_eq!(call(env, &activity, jni_str!("testRequestCount"), "()I", &[]).i()?, 1);
    let v = call(env, &activity, jni_str!("testLastRequested"), "()Ljava/lang/String;", &[]);
    assert_eq!(java_string(env, v), format!("{},{},{}", permissions::CAMERA, jni_location::FINE_LOCATION, jni_location::COARSE_LOCATION));
    assert_eq!(call(env, &activity, jni_str!("testLastRequestCode"), "()I", &[]).i()?, permissions::REQUEST_CODE);
    // Asking again before the answer is read does not open a second dialog.
    flow.start(env, &activity)?;
    assert_eq!(call(env, &activity, jni_str!("testRequestCount"), "()I", &[]).i()?, 1);
    // The dialog closed (the activity has focus again): read the answers.
    flow.refresh(env, &activity)?;
    Ok((activity, flow))
}

#[test]
fn permission_flow_granted() {
    with_env(|env| {
        let (_, flow) = flow_with_answer(env, 1)?;
        assert_eq!(flow.answer(Permission::Camera), Answer::Granted);
        assert_eq!(flow.answer(Permission::Location), Answer::Granted);
        assert_eq!(permissions::refusal_message(Permission::Camera, flow.answer(Permission::Camera)), None);
        Ok(())
    });
}

#[test]
fn permission_flow_denied_can_ask_again() {
    with_env(|env| {
        let (activity, mut flow) = flow_with_answer(env, 2)?;
        assert_eq!(flow.answer(Permission::Camera), Answer::Denied);
        assert_eq!(flow.answer(Permission::Location), Answer::Denied);
        let msg = permissions::refusal_message(Permission::Camera, Answer::Denied).unwrap();
        assert!(msg.contains("Ask again"), "{msg}");
        // "Ask again": a second dialog; this time the user allows.
        call(env, &activity, jni_str!("testSetAnswer"), "(I)V", &[JValue::Int(1)]);
        flow.ask_again(env, &activity)?;
        assert_eq!(call(env, &activity, jni_str!("testRequestCount"), "()I", &[]).i()?, 2);
        flow.refresh(env, &activity)?;
        assert_eq!(flow.answer(Permission::Camera), Answer::Granted);
        assert_eq!(flow.answer(Permission::Location), Answer::Granted);
        Ok(())
    });
}

#[test]
fn permission_flow_denied_forever_points_to_the_settings() {
    with_env(|env| {
        let (activity, mut flow) = flow_with_answer(env, 3)?;
        assert_eq!(flow.answer(Permission::Camera), Answer::DeniedForever);
        assert_eq!(flow.answer(Permission::Location), Answer::DeniedForever);
        let msg = permissions::refusal_message(Permission::Camera, Answer::DeniedForever).unwrap();
        assert!(msg.contains("Settings → Apps → Previz → Permissions → Camera"), "{msg}");
        let loc = permissions::refusal_message(Permission::Location, Answer::DeniedForever).unwrap();
        assert!(loc.contains("place and time set in the panel"), "{loc}");
        // Asking again shows nothing (Android will not ask) and the answer stays.
        call(env, &activity, jni_str!("testSetAnswer"), "(I)V", &[JValue::Int(1)]);
        flow.ask_again(env, &activity)?;
        flow.refresh(env, &activity)?;
        assert_eq!(flow.answer(Permission::Camera), Answer::DeniedForever);
        // The user allows it in the settings; the next refresh (on resume) sees it.
        call(env, &activity, jni_str!("testSetGranted"), "(Z)V", &[JValue::Bool(true)]);
        flow.refresh(env, &activity)?;
        assert_eq!(flow.answer(Permission::Location), Answer::Granted);
        assert_eq!(flow.answer(Permission::Camera), Answer::DeniedForever);
        Ok(())
    });
}
