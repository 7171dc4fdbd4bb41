//! `previz bench …`: measurements recorded in docs/PERFORMANCE.md.

use crate::bench::{frame, live, lod};
use crate::cli::composite::{SceneArgs, scene_from_args};
use crate::gpu::Gpu;
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, load_inputs};
use anyhow::{Result, bail};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Per-frame CPU and GPU time, medians after warm-up and ratios to the background-only floor,
    /// all in one run: the scene as drawn by default against its full-detail, full-shadow
    /// reference (mean FLIP), the same with the sun turning 0.5° a frame and with the camera
    /// walking round the model (2 % of its distance a frame: how often the vertex sun runs
    /// again), the same at a quarter of the fill, every lighting method, each
    /// colour correction, and 1x/2x/4x MSAA and FXAA (FLIP of the model's edges against a
    /// 16-sample render); then issue 11's goals, met or not; then where the main paths' time
    /// goes (the same frames with each pass timed alone; in --json too, not in --csv).
    Frame(FrameArgs),
    /// The live loop, stage by stage: camera frame (virtual phone, CPU), sensors + fusion, sun
    /// (SPA), compositor (GPU; frames that only turned the camera reproject the last shaded
    /// frame's model and ground, and the output says how many did): medians and 95th
    /// percentiles over the measured frames; then as many frames again with each pass timed
    /// alone (the profile rows; --json also as named passes); then as many turning the model 2°
    /// a frame, the ground's rays on their worker, and as many with the frame waiting for them;
    /// then as many under a new sky shape each, the ground's map recombined as a refold of the
    /// camera frame makes it (the frame's thread's time); then as many with reprojection off,
    /// every frame shading its model and ground.
    Live(LiveArgs),
    /// Accuracy against path-traced references: every method on every scene of --scenes with a
    /// reference in --references, drawn as a still (3 × 3 samples a pixel), and the default
    /// method with 1 × 1 and 2 × 2 (mean FLIP over the frame and the model + shadow, model
    /// luminance, time per frame: the median GPU time of 15 frames after 3 warm-up, with the wall
    /// clock including readback beside it), the path tracer's own 1/4/16/64-spp ladder, the
    /// default method against it at equal error (both per frame), and each scene's error
    /// budget (model vs shadow, sunlit vs shaded side, shadow colour, the background's FLIP
    /// around the model + shadow). `--export-reference DIR
    /// SCENE` instead writes SCENE as previz draws it for tests/reference/render_reference.py.
    Accuracy(AccuracyArgs),
    /// The model's level-of-detail chain in the scene: per level the triangles, the model's
    /// projected area per triangle (px²), the simplification error (model units and pixels at
    /// the model's distance), mean FLIP against the full-detail composite, GPU time and its ratio
    /// to the background-only floor (interleaved in one run), and the level the renderer draws
    /// (`render::frame::lod_level`).
    Lod(LodArgs),
}

#[derive(clap::Args, Debug)]
pub struct AccuracyArgs {
    /// The scene (same flags as `previz composite`).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Write frame.json, the placed meshes (PLY) and textures into DIR for the reference renderer.
    #[arg(long, value_name = "DIR")]
    pub export_reference: Option<PathBuf>,
    /// Folder of scene files (NAME.toml) to measure.
    #[arg(long, value_name = "DIR", default_value = "tests/reference/scenes")]
    pub scenes: PathBuf,
    /// Folder of references: NAME.png, NAME_roi.png, NAME_alpha.png, NAME_sppN.png/.json.
    #[arg(long, value_name = "DIR", default_value = "tests/reference/images")]
    pub references: PathBuf,
    /// Also draw the error-vs-cost chart (PNG).
    #[arg(long, value_name = "PNG")]
    pub chart: Option<PathBuf>,
    /// Each method's frame cost over the background-only floor: the CSV `previz bench frame
    /// --csv` wrote (its "method …" rows), put beside the error in the table, CSV and chart.
    #[arg(long, value_name = "CSV", default_value = "docs/bench_frame_goals.csv")]
    pub costs: PathBuf,
    /// Also write the rows as CSV.
    #[arg(long, value_name = "CSV")]
    pub csv: Option<PathBuf>,
    /// Print the rows as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
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
    /// Print the stages as JSON instead of a table: {"stages": [{stage, median_ms, p95_ms}],
    /// "compositor_over_floor", "profile": {"total_ms", "shadow_ms", "background_ms",
    /// "model_ms", "ground_ms", "counts": {"background", "model", "ground": {"triangles",
    /// "fragments"}}}} (the profile: GPU medians with each pass timed alone; null for a pass
    /// that did not run; counts: what the passes drew, from pipeline-statistics queries, null
    /// without them).
    #[arg(long)]
    pub json: bool,
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
    /// Print the rows as JSON instead of a table: {"rows": [...], "profile": [{path, frames,
    /// total_ms, shadow_ms, background_ms, model_ms, ground_ms, fxaa_ms, background_fragments,
    /// model_fragments, ground_fragments, model_triangles}]} (the profile: GPU medians of each
    /// pass timed alone and of what it drew, from pipeline-statistics queries; null for a pass
    /// that did not run or without the queries).
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Frame(a) => run_frame(a),
        What::Live(a) => run_live(a),
        What::Accuracy(a) => run_accuracy(a),
        What::Lod(a) => run_lod(a),
    }
}

/// What every rendering benchmark starts from: the scene and its inputs, a headless GPU, and a
/// progress bar counting frames.
struct Bench {
    scene: Scene,
    inputs: Inputs,
    gpu: Gpu,
    bar: indicatif::ProgressBar,
}

impl Bench {
    /// Check `--frames`, load the scene, start the GPU.
    fn set_up(scene: &SceneArgs, frames: usize) -> Result<Bench> {
        if frames == 0 {
            bail!("--frames must be at least 1");
        }
        let (scene, demo) = scene_from_args(scene, None)?;
        let inputs = load_inputs(&scene, demo)?;
        let gpu = Gpu::headless()?;
        let bar = indicatif::ProgressBar::new(0).with_style(
            indicatif::ProgressStyle::with_template("{msg:>10} {bar:40} {pos}/{len} frames")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Ok(Bench { scene, inputs, gpu, bar })
    }
}

fn run_lod(a: LodArgs) -> Result<()> {
    let Bench { scene, inputs, gpu, bar } = Bench::set_up(&a.scene, a.frames)?;
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
    let Bench { scene, inputs, gpu, bar } = Bench::set_up(&a.scene, a.frames)?;
    let rows = frame::run(&gpu, &scene, &inputs, a.frames, a.warmup, &bar)?;
    let profile = frame::profile(&gpu, &scene, &inputs, a.frames, a.warmup, &bar)?;
    bar.finish_and_clear();
    if let Some(path) = &a.csv {
        crate::output::write_atomic(path, frame::csv(&rows).as_bytes())?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&serde_json::json!({ "rows": rows, "profile": profile }))?);
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
        println!("\nWhere the time goes (the same paths again, each pass timed alone):\n");
        print!("{}", frame::profile_markdown(&profile));
    }
    Ok(())
}

fn run_live(a: LiveArgs) -> Result<()> {
    let Bench { scene, inputs, gpu, bar } = Bench::set_up(&a.scene, a.frames)?;
    let triangles = inputs.model.triangle_count();
    let bench = live::run(&gpu, &scene, inputs, a.frames, a.warmup, &bar)?;
    bar.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&live::json(&bench))?);
        return Ok(());
    }
    println!(
        "{}x{}, {triangles} model triangles, phone-grade simulated sensors, on {}; {} frames after {} warm-up\n",
        scene.width,
        scene.height,
        gpu.describe(),
        a.frames,
        a.warmup
    );
    print!("{}", live::markdown(&bench));
    Ok(())
}

fn run_accuracy(a: AccuracyArgs) -> Result<()> {
    use crate::bench::accuracy;
    if let Some(dir) = &a.export_reference {
        let (scene, demo) = scene_from_args(&a.scene, None)?;
        let inputs = load_inputs(&scene, demo)?;
        let frame = accuracy::export_reference_scene(&scene, &inputs, dir)?;
        println!("{}", serde_json::to_string_pretty(&frame)?);
        return Ok(());
    }
    let entries = std::fs::read_dir(&a.scenes).map_err(|e| anyhow::anyhow!("--scenes {}: {e}", a.scenes.display()))?;
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| e.path().file_name().and_then(|n| n.to_str()).and_then(|n| n.strip_suffix(".toml")).map(String::from))
        .filter(|n| a.references.join(format!("{n}.png")).exists())
        .collect();
    names.sort();
    if names.is_empty() {
        bail!("no scene in {} has a reference NAME.png in {}", a.scenes.display(), a.references.display());
    }
    let costs_text = std::fs::read_to_string(&a.costs).map_err(|e| anyhow::anyhow!("--costs {}: {e}", a.costs.display()))?;
    let costs = crate::bench::frame::method_costs(
        &crate::bench::frame::read_csv(&costs_text).map_err(|e| anyhow::anyhow!("--costs {}: {e}", a.costs.display()))?,
    );
    let gpu = Gpu::headless()?;
    let bar = indicatif::ProgressBar::new(names.len() as u64);
    let mut rows = Vec::new();
    let mut budgets = Vec::new();
    for name in &names {
        bar.set_message(name.clone());
        let reference = accuracy::load_reference(&a.references, name)?;
        let args = SceneArgs { scene: Some(a.scenes.join(format!("{name}.toml"))), ..Default::default() };
        let (scene, demo) = scene_from_args(&args, None)?;
        let inputs = load_inputs(&scene, demo)?;
        rows.extend(accuracy::score_methods(&gpu, name, &scene, &inputs, &reference)?);
        rows.extend(accuracy::score_ladder(&a.references, name, &reference)?);
        budgets.push(accuracy::budget_of_scene(&gpu, name, &scene, &inputs, &reference)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let missing = accuracy::attach_costs(&mut rows, &costs);
    if !missing.is_empty() {
        bail!("--costs {}: no \"method …\" row for {}", a.costs.display(), missing.join(", "));
    }
    if let Some(path) = &a.chart {
        accuracy::write_chart(&rows, path)?;
    }
    if let Some(path) = &a.csv {
        crate::output::write_atomic(path, accuracy::csv(&rows).as_bytes())?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!("{} scenes on {}; references in {}\n", names.len(), gpu.describe(), a.references.display());
        print!("{}", accuracy::markdown(&rows));
        let default = crate::setup::method_choice::ORDINARY.name();
        println!("\nThe default method ({default}) against the path tracer at equal error (bench::equal_error):\n");
        print!("{}", crate::bench::equal_error::markdown(&crate::bench::equal_error::scene_ratios(&rows, default)));
        println!("\nError budget of each scene's own method (docs/accuracy.md):\n");
        print!("{}", accuracy::budget_markdown(&budgets));
    }
    Ok(())
}
