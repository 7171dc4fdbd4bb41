//! The iOS entry point: the `previz` binary on an iPhone starts here (main.rs hands over before
//! the command line is parsed) and runs the app ([`super::app::App`], in the window of
//! [`super::window`]) in winit's iOS event loop (`UIApplicationMain`; it never returns). The
//! session runs on the phone's own sources: the back camera through AVFoundation
//! ([`crate::camera::ios::IosCamera`], '420f' planes converted on the GPU) and CoreMotion +
//! CoreLocation ([`crate::sensors::ios::IosSensors`]); the camera's field of view is the
//! projection's. Both are created on the main thread once the window exists (Core Location needs
//! the main run loop). A camera that cannot open yet (access not decided or refused) gives grey
//! frames and is tried again ([`OpeningCamera`]); the app reads the camera and location
//! authorisation while it runs ([`IosPermissions`]: the refusal screen, the manual place). The
//! shutter saves into the app's Documents folder. Compiled for iOS only; linking and running
//! need Xcode (docs/mobile.md).

use super::app::{App, PermissionSource};
use super::phone::{OpenCamera, OpeningCamera, ios_authorization_answer};
use super::window;
use super::{LiveConfig, LiveSession, Sources};
use crate::camera::FrameSource;
use crate::camera::ios::{IosCamera, SIZE};
use crate::pose::DisplayRotation;
use crate::scene::demo;
use crate::sensors::ios::IosSensors;
use crate::sensors::permissions::Answer;
use crate::setup::scene_file::SceneBuilder;
use anyhow::{Context, Result};
use objc2::rc::Retained;
use objc2_av_foundation::{AVCaptureDevice, AVMediaTypeVideo};
use objc2_core_location::CLLocationManager;
use std::sync::Arc;
use winit::event_loop::EventLoop;

/// The vertical field of view when the camera reports none, degrees.
const FALLBACK_VFOV_DEG: f64 = 45.0;

/// Run the app; the exit code for `main` if the event loop ever returns.
pub fn main_exit_code() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("previz: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The camera's and location's authorisation (`AVCaptureDevice.authorizationStatusForMediaType`,
/// `CLLocationManager.authorizationStatus`). iOS shows its prompt once: a refusal can only be
/// undone in the Settings app, so "Ask again" has nothing to ask.
struct IosPermissions {
    location: Retained<CLLocationManager>,
}

impl PermissionSource for IosPermissions {
    fn answers(&mut self) -> Result<(Answer, Answer)> {
        // SAFETY: class and instance methods with valid arguments, on the main thread; the
        // static is AVFoundation's constant.
        unsafe {
            let media = AVMediaTypeVideo.context("AVMediaTypeVideo is missing")?;
            let camera = AVCaptureDevice::authorizationStatusForMediaType(media).0 as i64;
            let location = self.location.authorizationStatus().0 as i64;
            Ok((ios_authorization_answer(camera), ios_authorization_answer(location)))
        }
    }

    fn ask_again(&mut self) -> Result<()> {
        Ok(())
    }
}

fn run() -> Result<()> {
    let event_loop = EventLoop::new().context("cannot start the iOS event loop")?;
    let export_dir = std::env::var_os("HOME").map(|h| std::path::PathBuf::from(h).join("Documents")).unwrap_or_default();
    let mut scene = SceneBuilder::from_toml(demo::SCENE_TOML, std::path::Path::new("."))?.build()?;
    (scene.width, scene.height) = SIZE;
    let env = Arc::new(demo::environment()?);
    let model = demo::model()?;
    let cfg = LiveConfig::on_phone(chrono::Utc::now());
    let make = move |gpu: &crate::gpu::Gpu| -> Result<App> {
        // The first attempt shows the camera prompt; the field of view is the camera's once it
        // opens at start, else the fallback.
        let mut first = IosCamera::open().inspect_err(|e| log(&format!("camera not open yet: {e:#}"))).ok();
        scene.camera.vfov = first.as_ref().and_then(IosCamera::vfov_deg).unwrap_or(FALLBACK_VFOV_DEG);
        let open: OpenCamera = Box::new(move || {
            let camera = match first.take() {
                Some(c) => c,
                None => IosCamera::open()?,
            };
            Ok(Box::new(camera) as Box<dyn FrameSource>)
        });
        // The interface is locked to landscape right (ios/Info.plist): 90° in this crate's
        // convention (pose::frames::DisplayRotation).
        let sources = Sources {
            camera: Box::new(OpeningCamera::new(SIZE, open, log)),
            sensors: Box::new(IosSensors::start()?),
            rotation: DisplayRotation::R90,
            truth: None,
        };
        let mut app = App::new(LiveSession::new(gpu, &env, &model, &scene, cfg, sources)?, export_dir);
        // SAFETY: a plain allocation and init, on the main thread.
        let location = unsafe { CLLocationManager::new() };
        app.set_permission_source(Box::new(IosPermissions { location }));
        Ok(app)
    };
    window::run_app_on(event_loop, "Previz", SIZE, Box::new(make))
}

/// One line to the device log (stderr reaches Xcode's console).
fn log(msg: &str) {
    eprintln!("previz: {msg}");
}
