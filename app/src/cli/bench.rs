//! `previz bench …`: measurements recorded in docs/PERFORMANCE.md.

use crate::bench::frame;
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
    }
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
    let cfg = crate::live::LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00")?.with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: ((a.frames + a.warmup) as f64 / 30.0).ceil() + 1.0,
        noise: crate::sensors::sim::NoiseLevel::Phone,
        seed: 1,
    };
    let model_triangles = inputs.model.triangle_count();
    let mut session = crate::live::LiveSession::simulated(&gpu, std::sync::Arc::new(inputs.env), &inputs.model, &scene, cfg)?;
    let bar = indicatif::ProgressBar::new((a.frames + a.warmup) as u64);
    let mut rows: [Vec<f64>; 5] = Default::default();
    for i in 0..a.frames + a.warmup {
        let t = std::time::Instant::now();
        let f = session.advance(&gpu)?.ok_or_else(|| anyhow::anyhow!("the simulated session ended early"))?;
        let r = session.render(&gpu)?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        if i >= a.warmup {
            for (v, x) in rows.iter_mut().zip([f.camera_ms, f.pose_ms, f.sun_ms, r.timings.gpu_ms.unwrap_or(f64::NAN), wall]) {
                v.push(x);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    println!(
        "{}x{}, {} model triangles, phone-grade simulated sensors, on {}; {} frames after {} warm-up\n",
        scene.width,
        scene.height,
        model_triangles,
        gpu.describe(),
        a.frames,
        a.warmup
    );
    println!("| stage | median ms | p95 ms |\n|---|---:|---:|");
    let names = [
        "camera frame (virtual phone, CPU) + upload",
        "sensors + fusion",
        "sun (SPA)",
        "compositor (GPU)",
        "whole frame incl. readback (wall)",
    ];
    for (name, v) in names.iter().zip(&rows) {
        println!("| {name} | {:.3} | {:.3} |", crate::bench::median(v), crate::bench::percentile(v, 0.95));
    }
    Ok(())
}
