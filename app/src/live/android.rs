//! The Android entry point: android-activity's NativeActivity glue (winit's
//! `android-native-activity` backend) exports `ANativeActivity_onCreate` and starts
//! [`android_main`] on its own thread; it runs the live window ([`super::window`]) in the
//! activity's native window.
//!
//! At start it asks for the camera and location permissions (one system dialog,
//! [`crate::sensors::permissions`]). The session runs on the phone's own sources: the back
//! camera through Camera2 ([`crate::camera::android::Camera2`], YUV planes converted on the GPU)
//! and the NDK sensors + GPS ([`crate::sensors::android::AndroidSensors`]). The camera's field of
//! view (its intrinsics, cropped to the stream) is the projection's, and the frame is the
//! camera's image turned upright for the screen. Until the camera permission is granted the
//! background is grey ([`OpeningCamera`] tries to open the camera again twice a second); the app
//! reads the permission answers while it runs ([`AndroidPermissions`]: the refusal screen, its
//! "Ask again", the manual place when location is refused).

use super::app::{App, PermissionSource};
use super::phone::{OpenCamera, OpeningCamera};
use super::window;
use super::{LiveConfig, LiveSession, Sources};
use crate::camera::FrameSource;
use crate::camera::android::{Camera2, query_back_camera};
use crate::pose::DisplayRotation;
use crate::scene::demo;
use crate::sensors::android::AndroidSensors;
use crate::sensors::jni_location;
use crate::sensors::permissions::{Answer, Permission, PermissionFlow};
use crate::setup::scene_file::SceneBuilder;
use anyhow::{Context, Result};
use jni::Env;
use jni::objects::JObject;
use jni::vm::JavaVM;
use std::sync::Arc;
use winit::event_loop::EventLoop;
use winit::platform::android::EventLoopBuilderExtAndroid;
use winit::platform::android::activity::AndroidApp;

/// The camera stream's size (YUV_420_888 at 1280×720 exists on every Camera2 device).
const CAMERA_SIZE: (u32, u32) = (1280, 720);
/// The vertical field of view when the camera reports no intrinsics, degrees (a typical phone
/// main camera's 16:9 stream).
const FALLBACK_VFOV_DEG: f64 = 45.0;

/// Called by android-activity on the app's main Rust thread once the activity is created.
#[unsafe(no_mangle)]
fn android_main(app: AndroidApp) {
    if let Err(e) = run(app) {
        log(&format!("previz: {e:#}"));
    }
}

fn run(app: AndroidApp) -> Result<()> {
    // The first-start system dialog for the camera and location permissions; the camera opens
    // once granted (OpeningCamera), the location bridge asks again on its first poll.
    let mut flow = PermissionFlow::default();
    if let Err(e) = with_activity(|env, activity| flow.start(env, activity)) {
        log(&format!("previz: cannot ask for permissions: {e:#}"));
    }
    // The app is landscape-only (AndroidManifest.xml): the rotation read now holds.
    let display = with_activity(jni_location::display_rotation).unwrap_or(DisplayRotation::R90);
    // The shutter saves into the app's private files folder.
    let export_dir = app.internal_data_path().unwrap_or_default();
    let event_loop = EventLoop::builder().with_android_app(app).build().context("cannot start the Android event loop")?;
    let info = query_back_camera(CAMERA_SIZE, display)?;
    let (width, height) = info.image_size();
    let mut scene = SceneBuilder::from_toml(demo::SCENE_TOML, std::path::Path::new("."))?.build()?;
    scene.width = width;
    scene.height = height;
    scene.camera.vfov = info.fov_deg().map_or(FALLBACK_VFOV_DEG, |(_, v)| v);
    let env = Arc::new(demo::environment()?);
    let model = demo::model()?;
    let cfg = LiveConfig::on_phone(chrono::Utc::now());
    let make = move |gpu: &crate::gpu::Gpu| -> Result<App> {
        let open: OpenCamera =
            Box::new(move || Ok(Box::new(Camera2::open(CAMERA_SIZE.0, CAMERA_SIZE.1, display)?) as Box<dyn FrameSource>));
        let sources = Sources {
            camera: Box::new(OpeningCamera::new(info.image_size(), open, log)),
            sensors: Box::new(AndroidSensors::start()?),
            rotation: display,
            truth: None,
        };
        let mut app = App::new(LiveSession::new(gpu, &env, &model, &scene, cfg, sources)?, export_dir);
        // The answers now (a refusal from an earlier start shows the refusal screen; a dialog
        // still open counts as pending) and about twice a second while the app runs.
        app.set_permission_source(Box::new(AndroidPermissions { flow }));
        Ok(app)
    };
    window::run_app_on(event_loop, "Previz", (width, height), Box::new(make))
}

/// The permission answers read back through JNI ([`PermissionFlow::refresh`]) while the app
/// runs; "Ask again" shows the system dialog again.
struct AndroidPermissions {
    flow: PermissionFlow,
}

impl PermissionSource for AndroidPermissions {
    fn answers(&mut self) -> Result<(Answer, Answer)> {
        let flow = &mut self.flow;
        with_activity(|env, activity| flow.refresh(env, activity))?;
        Ok((flow.answer(Permission::Camera), flow.answer(Permission::Location)))
    }

    fn ask_again(&mut self) -> Result<()> {
        let flow = &mut self.flow;
        with_activity(|env, activity| flow.ask_again(env, activity))
    }
}

/// Run `f` with the JNI environment of this thread and the activity (ndk-context holds both,
/// filled by android-activity before `android_main`).
fn with_activity<T>(f: impl FnOnce(&mut Env<'_>, &JObject<'_>) -> Result<T>) -> Result<T> {
    let ctx = ndk_context::android_context();
    // SAFETY: android-activity stores the process's JavaVM pointer in ndk-context before
    // android_main runs; it stays valid for the life of the process.
    let vm = unsafe { JavaVM::from_raw(ctx.vm().cast()) };
    vm.attach_current_thread(|env| -> Result<T> {
        // SAFETY: ndk-context holds a global reference to the activity for the life of the
        // process; it is only borrowed here.
        let activity = unsafe { JObject::from_raw(env, ctx.context().cast()) };
        f(env, &activity)
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
