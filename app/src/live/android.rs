//! The Android entry point: android-activity's NativeActivity glue (winit's
//! `android-native-activity` backend) exports `ANativeActivity_onCreate` and starts
//! [`android_main`] on its own thread; it runs the live window ([`super::window`]) in the
//! activity's native window.
//!
//! At start it asks for the camera and location permissions (one system dialog,
//! [`crate::sensors::permissions`]). The session is still the built-in demo scene on the virtual
//! phone with simulated sensors, as `previz live` runs on the desktop: the Camera2 camera
//! backend and the Android sensors are not plugged in yet (docs/mobile.md says what is missing).

use super::window;
use super::{LiveConfig, LiveSession};
use crate::scene::demo;
use crate::sensors::permissions::PermissionFlow;
use crate::sensors::sim::NoiseLevel;
use crate::setup::scene_file::SceneBuilder;
use anyhow::{Context, Result};
use jni::objects::JObject;
use jni::vm::JavaVM;
use std::sync::Arc;
use winit::event_loop::EventLoop;
use winit::platform::android::EventLoopBuilderExtAndroid;
use winit::platform::android::activity::AndroidApp;

/// Called by android-activity on the app's main Rust thread once the activity is created.
#[unsafe(no_mangle)]
fn android_main(app: AndroidApp) {
    if let Err(e) = run(app) {
        log(&format!("previz: {e:#}"));
    }
}

fn run(app: AndroidApp) -> Result<()> {
    // The first-start system dialog for the camera and location permissions. The answers are
    // not used yet: the session below still runs on the virtual phone (docs/mobile.md).
    if let Err(e) = ask_permissions() {
        log(&format!("previz: cannot ask for permissions: {e:#}"));
    }
    // The shutter saves into the app's private files folder.
    let export_dir = app.internal_data_path().unwrap_or_default();
    let event_loop = EventLoop::builder().with_android_app(app).build().context("cannot start the Android event loop")?;
    let scene = SceneBuilder::from_toml(demo::SCENE_TOML, std::path::Path::new("."))?.build()?;
    let env = Arc::new(demo::environment()?);
    let model = demo::model()?;
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::Utc::now(),
        frame_hz: 30.0,
        duration_s: 3600.0,
        noise: NoiseLevel::Phone,
        seed: 1,
    };
    let size = (scene.width, scene.height);
    window::run_on(event_loop, "Previz", size, export_dir, Box::new(move |gpu| LiveSession::simulated(gpu, env, &model, &scene, cfg)))
}

/// Ask for the camera and location permissions through JNI on the activity (ndk-context holds
/// it, filled by android-activity before `android_main`).
fn ask_permissions() -> Result<PermissionFlow> {
    let ctx = ndk_context::android_context();
    // SAFETY: android-activity stores the process's JavaVM pointer in ndk-context before
    // android_main runs; it stays valid for the life of the process.
    let vm = unsafe { JavaVM::from_raw(ctx.vm().cast()) };
    vm.attach_current_thread(|env| -> Result<PermissionFlow> {
        // SAFETY: ndk-context holds a global reference to the activity for the life of the
        // process; it is only borrowed here.
        let activity = unsafe { JObject::from_raw(env, ctx.context().cast()) };
        let mut flow = PermissionFlow::default();
        flow.start(env, &activity)?;
        Ok(flow)
    })
}

/// One line to logcat (tag "previz").
fn log(msg: &str) {
    let text = std::ffi::CString::new(msg.replace('\0', " ")).unwrap_or_default();
    // SAFETY: both strings are NUL-terminated and outlive the call.
    unsafe {
        ndk_sys::__android_log_write(ndk_sys::android_LogPriority::ANDROID_LOG_ERROR.0 as i32, c"previz".as_ptr(), text.as_ptr());
    }
}
