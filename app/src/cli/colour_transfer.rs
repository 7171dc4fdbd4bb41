//! `previz colour-transfer`: give TARGET the colour statistics of SOURCE (as the model shader
//! does for model vs environment), and `previz colour-transfer bench`.

use crate::bench::colour as bench;
use crate::colour::correction::ColourCorrection;
use crate::colour::images::{apply, counted_linear, image_stats, load_rgba8};
use crate::colour::report::{HistogramSet, histogram_report};
use crate::colour::stats::ColourStats;
use crate::colour::transfer::TransferMethod;
use crate::output::{write_atomic, write_png_rgb8, write_png_rgba8};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// Transfer SOURCE's colour statistics onto TARGET.
///
/// Statistics use the pixels with alpha > 0 (and, with --green-screen, not pure green
/// (0,255,0) in TARGET); other pixels are copied unchanged. The images may differ in size:
/// only their statistics meet. All maths is in linear light; results above 1 are clipped per
/// channel when OUT is encoded as 8-bit sRGB.
#[derive(clap::Args, Debug)]
#[command(subcommand_negates_reqs = true, args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<Sub>,
    /// Image whose colour statistics are imposed (the environment's role).
    #[arg(long, required = true)]
    pub source: Option<PathBuf>,
    /// Image to correct (the model's role).
    #[arg(long, required = true)]
    pub target: Option<PathBuf>,
    /// Corrected TARGET, PNG (8-bit sRGB, alpha kept).
    #[arg(short = 'o', long = "output", required = true)]
    pub output: Option<PathBuf>,
    /// reinhard: Reinhard 2001 in log lαβ; cielab-approx: lαβ without the log (seed Eq. 11a);
    /// mkl: linear Monge–Kantorovich (full covariance); brightness-contrast: luminance only.
    #[arg(long, value_enum, default_value = "reinhard")]
    pub method: TransferMethod,
    /// 0 = TARGET unchanged, 1 = full correction.
    #[arg(long, default_value_t = 1.0, value_parser = parse_strength)]
    pub strength: f32,
    /// Ignore pure green (0,255,0) pixels of TARGET (statistics) and leave them unchanged.
    #[arg(long)]
    pub green_screen: bool,
    /// Also write histograms of luminance and of l, α, β (source, target, result) to this PNG.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Print the statistics of source, target and result as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Measure every method side by side: accuracy (distance of the result's lαβ distribution
    /// from the source's) and cost per 960x640 frame on the GPU (shader) and CPU (tool).
    Bench(BenchArgs),
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The shared data folder with the photos, cube maps and textures (`../shared/data` beside
    /// a Previz checkout).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Folder for colour-bench.json, colour-bench.md, colour-speed-accuracy.png and the
    /// single-colour figures (created if missing).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Timed runs per method and pair (the median is reported).
    #[arg(long, default_value_t = 9)]
    pub repeats: u32,
    /// Skip the GPU (CPU timings only).
    #[arg(long)]
    pub no_gpu: bool,
}

fn parse_strength(s: &str) -> std::result::Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("{s:?} is not a number"))?;
    if (0.0..=1.0).contains(&v) { Ok(v) } else { Err(format!("strength must be in 0..1, got {v}")) }
}

#[derive(serde::Serialize)]
struct ImageReport<'a> {
    path: &'a Path,
    width: u32,
    height: u32,
    stats: ColourStats,
    lab_sigma: [f64; 3],
}

fn image_report(path: &Path, w: u32, h: u32, stats: ColourStats) -> ImageReport<'_> {
    ImageReport { path, width: w, height: h, lab_sigma: stats.lab_sigma(), stats }
}

pub fn run(args: Args) -> Result<()> {
    if let Some(Sub::Bench(b)) = args.command {
        return run_bench(b);
    }
    let (Some(source_path), Some(target_path), Some(out)) = (&args.source, &args.target, &args.output) else {
        bail!("--source, --target and -o are required");
    };
    let method = args.method;
    let source = load_rgba8(source_path).context("SOURCE")?;
    let target = load_rgba8(target_path).context("TARGET")?;
    let source_stats = image_stats(&source, false, "SOURCE")?;
    let target_stats = image_stats(&target, args.green_screen, "TARGET")?;
    let cc = ColourCorrection::new(method, args.strength, &source_stats, &target_stats);
    let result = apply(&target, &cc, args.green_screen);
    let result_pixels = counted_linear(&result.image, args.green_screen);
    let result_stats = ColourStats::from_linear(&result_pixels)?;
    let sizes_differ = (source.width, source.height) != (target.width, target.height);

    // Render everything before writing anything, so a failure leaves no partial output.
    let report = match &args.report {
        Some(path) => {
            let s = counted_linear(&source, false);
            let t = counted_linear(&target, args.green_screen);
            let raster = histogram_report(&[
                HistogramSet { name: "source", pixels: &s },
                HistogramSet { name: "target", pixels: &t },
                HistogramSet { name: "result", pixels: &result_pixels },
            ])?;
            Some((path, raster))
        }
        None => None,
    };
    write_png_rgba8(out, result.image.width, result.image.height, &result.image.pixels)?;
    if let Some((path, raster)) = report
        && let Err(e) = write_png_rgb8(path, raster.width, raster.height, &raster.rgb)
    {
        let _ = std::fs::remove_file(out);
        return Err(e);
    }

    let counted = result_pixels.len() as f64;
    if args.json {
        let json = serde_json::json!({
            "method": method,
            "strength": cc.strength,
            "green_screen": args.green_screen,
            "encoding": "statistics of linear-light RGB: rgb_* linear RGB, lab_* log lαβ (Reinhard 2001), luminance BT.709 Y",
            "sizes_differ": sizes_differ,
            "out_of_gamut_pixels": result.out_of_gamut,
            "out_of_gamut_fraction": if counted > 0.0 { result.out_of_gamut as f64 / counted } else { 0.0 },
            "source": image_report(source_path, source.width, source.height, source_stats),
            "target": image_report(target_path, target.width, target.height, target_stats),
            "result": image_report(out, result.image.width, result.image.height, result_stats),
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        if sizes_differ {
            eprintln!(
                "note: SOURCE is {}x{} and TARGET {}x{}; only their statistics are compared, so this is fine",
                source.width, source.height, target.width, target.height
            );
        }
        println!("method {} strength {:.2}; wrote {}", method.name(), cc.strength, out.display());
        println!("{:<8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}", "", "mean l", "mean α", "mean β", "σ l", "σ α", "σ β", "mean Y");
        for (name, s) in [("source", &source_stats), ("target", &target_stats), ("result", &result_stats)] {
            let sg = s.lab_sigma();
            println!(
                "{name:<8} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                s.lab_mean[0], s.lab_mean[1], s.lab_mean[2], sg[0], sg[1], sg[2], s.luminance.mean
            );
        }
        if result.out_of_gamut > 0 {
            println!(
                "{} pixels ({:.2} %) left the gamut (a channel below 0 or above 1) and were clipped",
                result.out_of_gamut,
                100.0 * result.out_of_gamut as f64 / counted
            );
        }
        if let Some(path) = &args.report {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

fn run_bench(args: BenchArgs) -> Result<()> {
    std::fs::create_dir_all(&args.output).with_context(|| format!("cannot create {}", args.output.display()))?;
    let pairs = bench::default_pairs(&args.data);
    let gpu = if args.no_gpu { None } else { Some(crate::gpu::Gpu::headless()?) };
    let steps = (pairs.len() * bench::METHODS.len()) as u64;
    let bar = indicatif::ProgressBar::new(steps).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}").unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = bench::run(&pairs, gpu.as_ref(), args.repeats, |msg| {
        bar.set_message(msg.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    let md = bench::markdown(&report);
    let chart = bench::chart(&report)?;
    // The single-colour figure against two environments.
    let mut figures = Vec::new();
    for (name, face, colour) in
        [("park2", "cubemaps/humus_Park2/posz.jpg", [200u8, 40, 30]), ("bridge2", "cubemaps/humus_Bridge2/posx.jpg", [60, 90, 200])]
    {
        let env = load_rgba8(&args.data.join(face))?;
        let stats = image_stats(&env, false, "environment")?;
        figures.push((format!("colour-single-colour-{name}.png"), bench::single_colour_figure(&env, &stats, colour)?));
    }
    let dir = &args.output;
    write_atomic(&dir.join("colour-bench.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    write_atomic(&dir.join("colour-bench.md"), md.as_bytes())?;
    write_png_rgb8(&dir.join("colour-speed-accuracy.png"), chart.width, chart.height, &chart.rgb)?;
    for (name, r) in &figures {
        write_png_rgb8(&dir.join(name), r.width, r.height, &r.rgb)?;
    }
    print!("{md}");
    println!("\nwrote colour-bench.json, colour-bench.md, colour-speed-accuracy.png and the single-colour figures to {}", dir.display());
    Ok(())
}
