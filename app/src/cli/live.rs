//! `previz live`: the live frame loop (virtual phone + simulated sensors + pose fusion + sun +
//! compositor) in a window, or headless for N frames written as PNG.

use super::composite::{SceneArgs, scene_from_args};
use crate::gpu::Gpu;
use crate::live::{LiveConfig, LiveFrame, LiveSession};
use crate::sensors::sim::NoiseLevel;
use crate::setup::load_inputs;
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(clap::Args, Debug)]
#[command(after_help = "The scene flags are those of `previz composite`; the scene's camera heading and pitch are where the \
simulated user looks (panning ±20° and ±4° around them), and the model is placed there. The camera image comes from the \
virtual phone looking into the environment; the model is drawn at the pose the fusion filter estimates from the \
simulated sensors, lit by the sun for --lat/--lon/--time.")]
pub struct Args {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Latitude of the user, degrees
    #[arg(long, default_value_t = 51.4545, allow_hyphen_values = true)]
    pub lat: f64,
    /// Longitude of the user, degrees (east positive)
    #[arg(long, default_value_t = -2.5879, allow_hyphen_values = true)]
    pub lon: f64,
    /// Instant of the first frame, RFC 3339 (default: now)
    #[arg(long)]
    pub time: Option<String>,
    /// Sensor noise of the simulated phone
    #[arg(long, value_enum, default_value_t = NoiseLevel::Phone)]
    pub noise: NoiseLevel,
    /// Seed of the simulated user and sensors
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Camera frames per second
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Length of the session, seconds
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Headless: render this many frames into --output instead of opening a window
    #[arg(long, requires = "output")]
    pub frames: Option<usize>,
    /// Headless: folder for frame_NNNN.png (created if missing)
    #[arg(short = 'o', long = "output", requires = "frames")]
    pub output: Option<PathBuf>,
    /// Headless: print each frame's pose, pose error and sun as JSON lines
    #[arg(long)]
    pub json: bool,
    /// Window: run these steps in order, each as soon as it can (comma-separated: capture,
    /// composite, shutter, quit). With `capture` the simulated user follows the capture
    /// assistant first (taps at the front, holds each face), then looks around
    #[arg(long, conflicts_with = "frames")]
    pub script: Option<String>,
}

pub fn run(a: Args) -> Result<()> {
    let (scene, demo) = scene_from_args(&a.scene, None)?;
    let start = match &a.time {
        Some(t) => crate::sun::time::parse_time(t, "--time")?.with_timezone(&chrono::Utc),
        None => chrono::Utc::now(),
    };
    let cfg = LiveConfig { lat_deg: a.lat, lon_deg: a.lon, start, frame_hz: a.fps, duration_s: a.duration, noise: a.noise, seed: a.seed };
    cfg.validate()?;
    if let Some(n) = a.frames {
        // The session has duration × fps camera frames; asking for more used to stop silently.
        let available = (a.duration * a.fps).floor();
        if n == 0 || (available.is_finite() && n as f64 > available) {
            bail!("--frames {n}: must be 1..={available} (--duration {} s × --fps {})", a.duration, a.fps);
        }
    }
    if let Some(dir) = &a.output {
        std::fs::create_dir_all(dir).with_context(|| format!("--output {}: cannot create the directory", dir.display()))?;
    }
    let script = a.script.as_deref().map(crate::live::app::Step::parse_list).transpose()?;
    let inputs = load_inputs(&scene, demo)?;
    let env = Arc::new(inputs.env);
    let model = inputs.model;
    match (a.frames, &a.output) {
        (Some(n), Some(dir)) => headless(&scene, env, &model, cfg, n, dir, a.json),
        _ => run_window(scene, env, model, cfg, script.unwrap_or_default()),
    }
}

fn frame_json(f: &LiveFrame) -> serde_json::Value {
    serde_json::json!({
        "t": f.t,
        "pose_wxyz": f.pose.map(|p| [p.q.w, p.q.x, p.q.y, p.q.z]),
        "pose_accuracy_deg": f.pose.map(|p| p.accuracy_deg),
        "heading_source": f.pose.map(|p| p.heading_source.label()),
        "pose_error_deg": f.pose_error_deg,
        "sun_azimuth_deg": f.sun.azimuth_deg,
        "sun_elevation_deg": f.sun.apparent_elevation_deg(),
        "sunlight": f.sunlight,
    })
}

fn headless(
    scene: &crate::setup::scene_file::Scene,
    env: Arc<crate::scene::CubeMap>,
    model: &crate::scene::Model,
    cfg: LiveConfig,
    n: usize,
    dir: &std::path::Path,
    json: bool,
) -> Result<()> {
    let gpu = Gpu::headless()?;
    let mut session = LiveSession::simulated(&gpu, env, model, scene, cfg)?;
    // As the app: the folded camera frame lights the model until a capture exists; each due
    // fold is applied before its frame is written, so the frames repeat run to run.
    session.fold_camera_into_environment();
    let bar = indicatif::ProgressBar::new(n as u64).with_style(
        indicatif::ProgressStyle::with_template("live {bar:40} {pos}/{len} frames")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut written = 0;
    for i in 0..n {
        let Some(frame) = session.advance(&gpu)? else { break };
        session.finish_fold(&gpu)?;
        let image = session.render(&gpu)?;
        let path = dir.join(format!("frame_{i:04}.png"));
        crate::output::write_png_rgba8(&path, image.width, image.height, &image.rgba)
            .with_context(|| format!("writing {}", path.display()))?;
        if json {
            bar.suspend(|| println!("{}", frame_json(&frame)));
        }
        written += 1;
        bar.inc(1);
    }
    bar.finish_and_clear();
    eprintln!("wrote {written} frames to {}", dir.display());
    Ok(())
}

/// The app on the virtual phone in a window; the shutter and captures save into the working
/// directory.
#[cfg(not(any(target_os = "android", target_os = "ios")))]
fn run_window(
    scene: crate::setup::scene_file::Scene,
    env: Arc<crate::scene::CubeMap>,
    model: crate::scene::Model,
    cfg: LiveConfig,
    script: Vec<crate::live::app::Step>,
) -> Result<()> {
    use crate::live::Sources;
    use crate::live::app::{App, Step};
    let size = (scene.width, scene.height);
    let export_dir = std::env::current_dir().context("the working directory")?;
    crate::live::window::run(
        "previz live",
        size,
        Box::new(move |gpu: &Gpu| {
            let exposure = crate::setup::exposure(&scene, &env);
            let sources = if script.contains(&Step::Capture) {
                Sources::simulated_capture(env.clone(), &scene, exposure, &cfg)?
            } else {
                Sources::simulated(env.clone(), &scene, exposure, &cfg)?
            };
            let session = LiveSession::new(gpu, &env, &model, &scene, cfg, sources)?;
            let mut app = App::new(session, export_dir);
            app.set_script(script);
            Ok(app)
        }),
    )
}

#[cfg(any(target_os = "android", target_os = "ios"))]
fn run_window(
    _: crate::setup::scene_file::Scene,
    _: Arc<crate::scene::CubeMap>,
    _: crate::scene::Model,
    _: LiveConfig,
    _: Vec<crate::live::app::Step>,
) -> Result<()> {
    bail!("the desktop window is not available on phones")
}
