//! `previz capture`: replay a true orientation path (a trace file, or a simulated user with
//! `--simulate`) through the virtual phone and simulated sensors into the capture assistant;
//! write the six faces and capture.json to OUT_DIR. `previz capture stability` runs the
//! stability study. See docs/capture.md.

use crate::capture::Mode;
use crate::capture::assistant::Assistant;
use crate::capture::folder::save_capture;
use crate::capture::guided_path::simulate_capture_path;
use crate::capture::replay::{ReplayConfig, replay};
use crate::capture::stability::{self, StudyConfig};
use crate::output::write_atomic;
use crate::pose::hand_motion::UserPathParams;
use crate::pose::trace::{TruthTrace, load_truth_trace, write_truth_trace};
use crate::scene::environment::load_environment;
use crate::sensors::sim::NoiseLevel;
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::sync::Arc;

/// The virtual phone's frame (landscape 4:3).
pub const FRAME_WIDTH: u32 = 640;
pub const FRAME_HEIGHT: u32 = 480;

/// The range of `--vfov` (degrees).
const MIN_VFOV_DEG: f32 = 20.0;
const MAX_VFOV_DEG: f32 = 120.0;

#[derive(clap::Args, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    after_help = "Trace format (CSV, header required): t,qw,qx,qy,qz,tap — time in seconds, the \
camera's true orientation (unit quaternion, camera frame -> ENU, camera looking along -z, image up +y), tap = 1 on the row where the \
user taps the shutter. See docs/capture.md."
)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<Sub>,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Stability study: many simulated captures per noise level and mode, and the hard cases;
    /// writes a CSV, a chart and a markdown report.
    Stability(StabilityArgs),
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Environment the virtual phone looks into: equirectangular .hdr/.exr or a folder of six faces
    #[arg(long, value_name = "ENV")]
    pub env: Option<PathBuf>,
    /// True orientation path to replay (CSV t,qw,qx,qy,qz,tap)
    #[arg(long, value_name = "TRACE.csv", conflicts_with = "simulate")]
    pub trace: Option<PathBuf>,
    /// Generate a plausible user path (seeded by --seed) instead of reading a trace
    #[arg(long)]
    pub simulate: bool,
    /// With --simulate: also write the generated path as a trace file
    #[arg(long, value_name = "TRACE.csv", requires = "simulate")]
    pub write_trace: Option<PathBuf>,
    /// Output folder for the six faces and capture.json (replaced if it holds a capture)
    #[arg(short = 'o', long = "output", value_name = "OUT_DIR")]
    pub output: Option<PathBuf>,
    /// Vertical field of view of the virtual phone (degrees, 20..=120; landscape 640x480 frame)
    #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
    pub vfov: f32,
    /// Sensor noise level
    #[arg(long, value_enum, default_value = "phone")]
    pub noise: NoiseLevel,
    /// Seed of the sensor noise (and of the simulated path)
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Aim tolerance in degrees (± on heading and pitch)
    #[arg(long, default_value_t = 2.0)]
    pub tolerance: f64,
    /// Face size in pixels (a power of two)
    #[arg(long = "face-size", default_value_t = 256)]
    pub face_size: u32,
    /// stretch: one shot per face stretched over it (seed 000); stitch: extra shots, full coverage
    #[arg(long, value_enum, default_value = "stitch")]
    pub mode: Mode,
    /// Do not use the shots' images for their poses: no correction of the guidance's heading
    /// drift while capturing (shots at the compass-corrected pose) and, in stitch mode, no
    /// alignment before assembly (both on by default, see docs/capture.md)
    #[arg(long = "no-align")]
    pub no_align: bool,
    /// Take an exposure bracket per view (-4, 0, +4 EV) and write HDR faces (posx.exr ...:
    /// scene radiance) beside the 8-bit ones
    #[arg(long)]
    pub hdr: bool,
    /// Print per-face capture time, orientation error, coverage, PSNR and mean FLIP as JSON
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct StabilityArgs {
    /// Environment to capture: .hdr/.exr or a folder of six faces (the recorded study used the
    /// shared data's hdri/polyhaven_1k/quarry_01_1k.hdr)
    #[arg(long, value_name = "ENV")]
    pub env: PathBuf,
    /// Random-heading runs per noise level and mode
    #[arg(long, default_value_t = 50)]
    pub runs: usize,
    /// Runs per hard case (wrap, poles, disturbance) and mode
    #[arg(long = "case-runs", default_value_t = 25)]
    pub case_runs: usize,
    /// Output folder for capture_stability.csv and capture_stability.png (the markdown report,
    /// a section of docs/PERFORMANCE.md, is printed)
    #[arg(short = 'o', long = "output", default_value = "docs")]
    pub output: PathBuf,
    /// Worker threads (default: one per core)
    #[arg(long)]
    pub threads: Option<usize>,
}

pub fn run(args: Args) -> Result<()> {
    match args.command {
        Some(Sub::Stability(s)) => run_stability(s),
        None => run_capture(args.run),
    }
}

fn run_capture(a: RunArgs) -> Result<()> {
    let env_path = a.env.as_deref().context("--env is required (an .hdr/.exr or a folder of six faces)")?;
    let out = a.output.as_deref().context("-o/--output OUT_DIR is required")?;
    if a.trace.is_none() && !a.simulate {
        bail!("give --trace TRACE.csv or --simulate");
    }
    // A phone camera's vertical field of view; far outside it the assistant would wait forever
    // for coverage (1e-9 degrees "captured" 0 % of every face).
    if !(a.vfov.is_finite() && (MIN_VFOV_DEG..=MAX_VFOV_DEG).contains(&a.vfov)) {
        bail!("--vfov {}: must be {MIN_VFOV_DEG}..={MAX_VFOV_DEG} degrees", a.vfov);
    }
    let cfg = ReplayConfig {
        mode: a.mode,
        width: FRAME_WIDTH,
        height: FRAME_HEIGHT,
        vfov_deg: a.vfov,
        noise: a.noise,
        seed: a.seed,
        tolerance_deg: a.tolerance,
        face_size: a.face_size,
        score: true,
        align: !a.no_align,
        hdr: a.hdr,
        ..ReplayConfig::default()
    };
    let assistant_cfg = cfg.assistant().context("bad --vfov, --tolerance or --face-size")?;
    let trace = match &a.trace {
        Some(p) => TruthTrace::new(load_truth_trace(p)?).with_context(|| format!("trace {}", p.display()))?,
        None => {
            let targets: Vec<_> = Assistant::new(assistant_cfg)?.targets().into_iter().cloned().collect();
            let path = simulate_capture_path(a.seed, &targets, &UserPathParams::default())?;
            if let Some(p) = &a.write_trace {
                write_truth_trace(p, &path.samples)?;
            }
            TruthTrace::new(path.samples)?
        }
    };
    // A simulated user in a simulated world: the environment's own sun is put where SPA has the
    // sun for the simulated phone's place (its GPS fix) at a simulated time, so the capture's
    // north is calibrated from the sun (docs/capture.md). Face folders, maps without a sun, or
    // a replayed trace: the map as it is, and no sun position.
    let (env, cfg) = match a.simulate.then(|| simulated_world(env_path)).transpose()?.flatten() {
        Some(w) => (w.env, ReplayConfig { clock: Some(w.time), ..cfg }),
        None => (Arc::new(load_environment(env_path).with_context(|| format!("cannot load the environment {}", env_path.display()))?), cfg),
    };
    let result = replay(&env, &trace, &cfg)?;
    let Some(capture) = &result.capture else {
        bail!("{}", result.incomplete.unwrap_or_else(|| "capture incomplete".into()));
    };
    save_capture(capture, out)?;
    if a.json {
        let json = serde_json::json!({
            "output": out,
            "mode": a.mode.name(),
            "noise": a.noise.name(),
            "seed": a.seed,
            "vfov_deg": a.vfov,
            "tolerance_deg": a.tolerance,
            "face_size": a.face_size,
            "reference_heading_deg": capture.meta.reference_heading_deg,
            "reference_heading_error_deg": result.reference_heading_error_deg,
            "exposure": capture.meta.exposure,
            "tap_t": result.tap_t,
            "time_to_complete_s": result.time_to_complete(),
            "shots": result.shots,
            "aligned_pairs": capture.meta.alignment.map(|a| a.pairs),
            "time_utc": capture.meta.time_utc,
            "heading": capture.meta.heading,
            "hdr": capture.meta.hdr,
            "faces": result.faces.iter().map(|f| serde_json::json!({
                "face": f.face.name(),
                "file": f.face.file_name(),
                "capture_t": f.capture_t,
                "orientation_error_deg": f.orientation_error_deg,
                "max_shot_error_deg": f.max_shot_error_deg,
                "coverage": f.coverage,
                "psnr_db": f.psnr_db,
                "mean_flip": f.mean_flip,
                "stitch_psnr_db": f.stitch_psnr_db,
                "stitch_flip": f.stitch_flip,
                "heading_source": f.heading_source,
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&json).context("cannot encode the JSON report")?);
    } else {
        println!(
            "captured {} ({} mode, {} shots, {:.1} s after the tap, reference heading {:.1}°)",
            out.display(),
            a.mode.name(),
            result.shots,
            result.time_to_complete().unwrap_or(0.0),
            capture.meta.reference_heading_deg
        );
        if let Some(h) = &capture.meta.heading {
            println!("  north: {} (1σ {}): {}", h.source, h.accuracy_deg.map_or("unknown".into(), |a| format!("{a:.2}°")), h.note);
        }
        if capture.hdr.is_some() {
            println!("  HDR faces: posx.exr ... negz.exr (brackets -4, 0, +4 EV)");
        }
        for f in &result.faces {
            println!(
                "  {:<5} t={:>6.2} s  error {:.2}°  coverage {:>5.1}%  PSNR {} dB  FLIP {}",
                f.face.name(),
                f.capture_t,
                f.orientation_error_deg,
                100.0 * f.coverage,
                f.psnr_db.map_or("inf".into(), |p| format!("{p:.1}")),
                f.mean_flip.map_or("-".into(), |p| format!("{p:.3}")),
            );
        }
    }
    Ok(())
}

/// The simulated world of `--simulate` for an equirectangular map with a sun
/// ([`crate::pose::sun_study::sun_world`] at the simulated phone's site); None for a face folder
/// or a map whose sun is not found or never at its elevation there.
fn simulated_world(env_path: &std::path::Path) -> Result<Option<crate::pose::sun_study::SunWorld>> {
    if env_path.is_dir() {
        return Ok(None);
    }
    let map = crate::scene::environment::load_equirect(env_path)
        .with_context(|| format!("cannot load the environment {}", env_path.display()))?;
    let size = (map.width() / 4).max(1).next_power_of_two().min(2048);
    Ok(crate::pose::sun_study::sun_world(&map, crate::sensors::sim::SimSite::default(), size).ok())
}

fn run_stability(a: StabilityArgs) -> Result<()> {
    if a.runs == 0 {
        bail!("--runs must be at least 1");
    }
    if !a.output.is_dir() {
        bail!("output folder {} does not exist", a.output.display());
    }
    let env_path = a.env.clone();
    let env = Arc::new(load_environment(&env_path).with_context(|| format!("cannot load the environment {}", env_path.display()))?);
    let mut cfg = StudyConfig { runs: a.runs, case_runs: a.case_runs, ..StudyConfig::default() };
    if let Some(t) = a.threads {
        cfg.threads = t.max(1);
    }
    let jobs = stability::jobs(&cfg);
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} captures ({eta} left)")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message("capture stability");
    let started = std::time::Instant::now();
    let rows = stability::run_study(&env, &cfg, &jobs, || bar.inc(1))?;
    bar.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    let summaries = stability::summarise(&rows);
    let csv = a.output.join("capture_stability.csv");
    let png = a.output.join("capture_stability.png");
    write_atomic(&csv, stability::rows_csv(&rows).as_bytes())?;
    stability::draw_chart(&png, &summaries)?;
    let report = format!(
        "## Capture stability (`previz capture stability`)\n\n\
Machine: {} logical CPUs ({}), date {}. {} simulated captures in {:.0} s on {} threads; \
environment `{}`; virtual phone {}x{} at {}° vertical FOV; faces {} px; tolerance ±{}°. Every run: simulated user \
path (`capture::guided_path`) → virtual phone + simulated sensors → fusion filter (default setting) → assistant → faces, \
scored against the ideal faces (same exposure and tone curve). Random headings: {} runs per noise level and mode; hard \
cases: {} runs per mode at `phone` noise. Raw rows: `docs/capture_stability.csv`; chart: `docs/capture_stability.png`.\n\n\
{}\n\
Per-face PSNR (dB, random headings):\n\n{}\n",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        std::env::consts::ARCH,
        chrono::Local::now().format("%Y-%m-%d"),
        rows.len(),
        elapsed,
        cfg.threads,
        env_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        cfg.width,
        cfg.height,
        cfg.vfov_deg,
        cfg.face_size,
        cfg.tolerance_deg,
        cfg.runs,
        cfg.case_runs,
        stability::summary_markdown(&summaries),
        stability::face_psnr_markdown(&summaries),
    );
    print!("{report}");
    println!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}
