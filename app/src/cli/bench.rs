//! `previz bench …`: measurements recorded in docs/PERFORMANCE.md.

use crate::bench::{frame, live, lod};
use crate::cli::composite::{SceneArgs, load_inputs, scene_from_args};
use crate::render::gpu::Gpu;
use anyhow::{Result, bail};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Per-frame CPU and GPU time of every lighting method, of the hemisphere method with each
    /// colour correction, and of the background-only floor,
    /// medians after warm-up, ratios to the floor (all in one run).
    Frame(FrameArgs),
    /// The live loop, stage by stage: camera frame (virtual phone, CPU), sensors + fusion, sun
    /// (SPA), compositor (GPU): medians and 95th percentiles over the measured frames.
    Live(LiveArgs),
    /// The model's level-of-detail chain in the scene: per level the triangles, the
    /// simplification error (model units and pixels at the model's distance), mean FLIP against
    /// the full-detail composite, GPU time, and the level the half-pixel rule draws.
    Lod(LodArgs),
}

#[derive(clap::Args, Debug)]
pub struct LodArgs {
    /// The scene (same flags as `previz composite`; default: the demo scene).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Frames rendered per level (GPU time is their median).
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
    /// Print the rows as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct LiveArgs {
    /// The scene (same flags as `previz composite`; default: the demo scene).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Measured frames (after warm-up).
    #[arg(long, default_value_t = 100)]
    pub frames: usize,
    /// Warm-up frames, not measured.
    #[arg(long, default_value_t = 10)]
    pub warmup: usize,
}

#[derive(clap::Args, Debug)]
pub struct FrameArgs {
    /// The scene to render (same flags as `previz composite`; default: the demo scene).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Measured frames per path (after warm-up).
    #[arg(long, default_value_t = 50)]
    pub frames: usize,
    /// Warm-up frames per path, not measured.
    #[arg(long, default_value_t = 5)]
    pub warmup: usize,
    /// Also write the rows as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Print the rows as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Frame(a) => run_frame(a),
        What::Live(a) => run_live(a),
        What::Lod(a) => run_lod(a),
    }
}

fn run_lod(a: LodArgs) -> Result<()> {
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let (scene, demo) = scene_from_args(&a.scene, None)?;
    let inputs = load_inputs(&scene, demo)?;
    let gpu = Gpu::headless()?;
    let bar = indicatif::ProgressBar::new(0);
    let t = std::time::Instant::now();
    let rows = lod::run(&gpu, &scene, &inputs, a.frames, &bar)?;
    bar.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "{}x{}, {} on {}; GPU ms = median of {} frames; run took {:.1} s\n",
            scene.width,
            scene.height,
            scene.method.name(),
            gpu.describe(),
            a.frames,
            t.elapsed().as_secs_f64()
        );
        print!("{}", lod::markdown(&rows));
    }
    Ok(())
}

fn run_frame(a: FrameArgs) -> Result<()> {
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let (scene, demo) = scene_from_args(&a.scene, None)?;
    let inputs = load_inputs(&scene, demo)?;
    let gpu = Gpu::headless()?;
    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template("{msg:>10} {bar:40} {pos}/{len} frames")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let rows = frame::run(&gpu, &scene, &inputs, a.frames, a.warmup, &bar)?;
    bar.finish_and_clear();
    if let Some(path) = &a.csv {
        let mut s = String::from("path,frames,cpu_encode_ms,gpu_ms,wall_ms,gpu_ratio,wall_ratio\n");
        for r in &rows {
            s += &format!("{},{},{},{},{},{},{}\n", r.path, r.frames, r.cpu_encode_ms, r.gpu_ms, r.wall_ms, r.gpu_ratio, r.wall_ratio);
        }
        crate::output::write_atomic(path, s.as_bytes())?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "{}x{}, {} triangles, {} on {}; medians of {} frames after {} warm-up\n",
            scene.width,
            scene.height,
            inputs.model.triangle_count(),
            scene.method.name(),
            gpu.describe(),
            a.frames,
            a.warmup
        );
        print!("{}", frame::markdown(&rows));
    }
    Ok(())
}

fn run_live(a: LiveArgs) -> Result<()> {
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let (scene, demo) = scene_from_args(&a.scene, None)?;
    let inputs = load_inputs(&scene, demo)?;
    let gpu = Gpu::headless()?;
    let triangles = inputs.model.triangle_count();
    let bar = indicatif::ProgressBar::new(0);
    let rows = live::run(&gpu, &scene, inputs, a.frames, a.warmup, &bar)?;
    bar.finish_and_clear();
    println!(
        "{}x{}, {triangles} model triangles, phone-grade simulated sensors, on {}; {} frames after {} warm-up\n",
        scene.width,
        scene.height,
        gpu.describe(),
        a.frames,
        a.warmup
    );
    print!("{}", live::markdown(&rows));
    Ok(())
}
