//! The iOS entry point: the `previz` binary on an iPhone starts here (main.rs hands over before
//! the command line is parsed) and runs the live window ([`super::window`]) in winit's iOS event
//! loop (`UIApplicationMain`; it never returns). The session runs on the phone's own sources: the
//! back camera through AVFoundation ([`crate::camera::ios::IosCamera`], '420f' planes converted
//! on the GPU) and CoreMotion + CoreLocation ([`crate::sensors::ios::IosSensors`]); the camera's
//! field of view is the projection's. Both are created on the main thread once the window
//! exists (Core Location needs the main run loop). The shutter saves into the app's Documents
//! folder. Compiled for iOS only; linking and running need Xcode (docs/mobile.md).

use super::window;
use super::{LiveConfig, LiveSession, Sources};
use crate::camera::ios::{IosCamera, SIZE};
use crate::pose::DisplayRotation;
use crate::scene::demo;
use crate::sensors::ios::IosSensors;
use crate::sensors::sim::NoiseLevel;
use crate::setup::scene_file::SceneBuilder;
use anyhow::{Context, Result};
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

fn run() -> Result<()> {
    let event_loop = EventLoop::new().context("cannot start the iOS event loop")?;
    let export_dir = std::env::var_os("HOME").map(|h| std::path::PathBuf::from(h).join("Documents")).unwrap_or_default();
    let mut scene = SceneBuilder::from_toml(demo::SCENE_TOML, std::path::Path::new("."))?.build()?;
    (scene.width, scene.height) = SIZE;
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
    let make = move |gpu: &crate::gpu::Gpu| -> Result<LiveSession> {
        let camera = IosCamera::open()?;
        scene.camera.vfov = camera.vfov_deg().unwrap_or(FALLBACK_VFOV_DEG);
        // The interface is locked to landscape right (ios/Info.plist): 90° in this crate's
        // convention (pose::frames::DisplayRotation).
        let sources =
            Sources { camera: Box::new(camera), sensors: Box::new(IosSensors::start()?), rotation: DisplayRotation::R90, truth: None };
        LiveSession::new(gpu, &env, &model, &scene, cfg, sources)
    };
    window::run_on(event_loop, "Previz", SIZE, export_dir, Box::new(make))
}
