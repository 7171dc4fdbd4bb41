//! `previz priors`: print the colour priors of an environment (and a model), and
//! `previz priors bench`: CPU vs GPU time of computing them.

use crate::output::write_atomic;
use crate::priors::{EnvironmentPriors, ModelPriors};
use anyhow::{Context, Result, bail};
use std::path::PathBuf;

/// Print the colour priors of an environment and optionally a model.
///
/// Every statistic is of linear-light RGB: means in linear RGB, luminance = BT.709 Y, lαβ =
/// Reinhard 2001 log lαβ. Environment: up/down = mean of the +Y/−Y faces; the rest over the four
/// horizontal faces. Model: its diffuse textures, only texels a UV triangle touches, without
/// green-screen (0,255,0) or transparent texels.
#[derive(clap::Args, Debug)]
#[command(subcommand_negates_reqs = true, args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<Sub>,
    /// Environment: a folder of six cube-map faces (posx/px …), or an equirectangular
    /// .hdr/.exr/.jpg/.png (docs/assets.md).
    #[arg(long, required = true)]
    pub env: Option<PathBuf>,
    /// Model (OBJ / glTF / GLB) whose texture priors to add.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Diffuse texture for the model's materials that have none (an OBJ without .mtl).
    #[arg(long, requires = "model")]
    pub texture: Option<PathBuf>,
    /// Compute with the GPU compute reduction instead of the CPU reference.
    #[arg(long)]
    pub gpu: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Time the priors of a 6x512² cube map and a 960x640 frame on the CPU and on the GPU.
    Bench(BenchArgs),
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The shared data folder, `../shared/data` beside a Previz checkout (uses cubemaps/pisa_hdr
    /// and photos/colour_transfer/astronaut.png).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Timed runs per path (the median is reported).
    #[arg(long, default_value_t = 9)]
    pub repeats: u32,
    /// Also write the table (markdown) and the rows (JSON, same name with .json) here.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    if let Some(Sub::Bench(b)) = args.command {
        return run_bench(b);
    }
    let Some(env_path) = &args.env else { bail!("--env is required") };
    let cube = crate::scene::environment::load_environment(env_path).with_context(|| format!("--env {}", env_path.display()))?;
    let model = match &args.model {
        Some(p) => {
            let options = crate::scene::model::ModelOptions { texture: args.texture.clone(), ..Default::default() };
            Some(crate::scene::model::load_model_with(p, &options).with_context(|| format!("--model {}", p.display()))?.model)
        }
        None => None,
    };
    // Name the files whose texels were counted, so that "no pixels" (an all-green-screen or
    // fully transparent texture) points at the file at fault.
    let model_what = match (&args.model, &args.texture) {
        (Some(m), Some(t)) => format!("model priors of --model {} with --texture {}", m.display(), t.display()),
        (Some(m), None) => format!("model priors of --model {} (its textures)", m.display()),
        _ => "model priors".to_string(),
    };
    let (env, model_priors) = if args.gpu {
        let gpu = crate::gpu::Gpu::headless()?;
        let mut reducer = crate::priors::gpu::PriorsReducer::new(&gpu)?;
        let env = reducer.environment(&gpu, &cube).context("environment priors")?;
        let m = match &model {
            Some(m) => Some(reducer.model(&gpu, m).context(model_what.clone())?),
            None => None,
        };
        (env, m)
    } else {
        let env = crate::priors::environment_priors(&cube).context("environment priors")?;
        let m = match &model {
            Some(m) => Some(crate::priors::model_priors(m).context(model_what.clone())?),
            None => None,
        };
        (env, m)
    };
    if args.json {
        let json = serde_json::json!({
            "encoding": "linear-light RGB; luminance = BT.709 Y of linear RGB; lab = Reinhard 2001 log lαβ of linear RGB",
            "computed_on": if args.gpu { "gpu" } else { "cpu" },
            "environment": env,
            "environment_lab_sigma": env.horizontal.lab_sigma(),
            "model": model_priors,
            "model_lab_sigma": model_priors.map(|m| m.stats.lab_sigma()),
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print_table(&env, model_priors.as_ref());
    }
    Ok(())
}

fn print_table(env: &EnvironmentPriors, model: Option<&ModelPriors>) {
    let f3 = |v: [f64; 3]| format!("{:.4} {:.4} {:.4}", v[0], v[1], v[2]);
    println!("Colour priors (all from linear-light RGB)");
    println!("environment, up (+Y) mean RGB      {}", f3(env.up_mean));
    println!("environment, down (-Y) mean RGB    {}", f3(env.down_mean));
    let mut rows = vec![("environment, horizontal faces", env.horizontal)];
    if let Some(m) = model {
        println!(
            "model: {} texels used of {} ({} not covered by UVs, {} green screen, {} transparent); source {:?}",
            m.texels.used, m.texels.total, m.texels.not_covered_by_uvs, m.texels.green_screen, m.texels.transparent, m.source
        );
        rows.push(("model", m.stats));
    }
    for (name, s) in rows {
        let l = s.luminance;
        println!("{name}: {} pixels", s.count);
        println!("  mean RGB (linear)                {}", f3(s.rgb_mean));
        println!("  luminance Y min / mean / max     {:.4} / {:.4} / {:.4}", l.min, l.mean, l.max);
        println!("  luminance Y 1st / 99th pct       {:.4} / {:.4}", l.p_lo, l.p_hi);
        println!("  lαβ mean                         {}", f3(s.lab_mean));
        println!("  lαβ σ                            {}", f3(s.lab_sigma()));
    }
}

fn run_bench(args: BenchArgs) -> Result<()> {
    let gpu = crate::gpu::Gpu::headless()?;
    let (cube, frame) = crate::bench::priors::default_inputs(&args.data)?;
    let rows = crate::bench::priors::run(&gpu, &cube, &frame, args.repeats)?;
    let md = crate::bench::priors::markdown(&rows, &gpu.describe(), args.repeats);
    if let Some(out) = &args.output {
        let json = serde_json::to_string_pretty(&rows)?;
        write_atomic(out, md.as_bytes())?;
        write_atomic(&out.with_extension("json"), json.as_bytes())?;
    }
    print!("{md}");
    Ok(())
}
