//! `previz priors bench`: the priors of a 6×512² cube map and of one 960×640 camera frame,
//! computed on the CPU (reference) and on the GPU (compute reductions), side by side.

use super::median;
use crate::colour::images::{counted_linear, load_rgba8};
use crate::colour::stats::ColourStats;
use crate::gpu::Gpu;
use crate::priors::gpu::PriorsReducer;
use crate::scene::{CubeMap, Rgba8Image};
use anyhow::{Context, Result, bail};
use std::path::Path;
use std::time::Instant;

/// One row of the comparison.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PriorsRow {
    pub input: String,
    pub pixels: u64,
    /// CPU reference, median wall time, ms.
    pub cpu_ms: f64,
    /// GPU path, median wall time including upload and readback, ms.
    pub gpu_wall_ms: f64,
    /// GPU time of the six compute passes (timestamps), median ms.
    pub gpu_ms: Option<f64>,
    /// Largest |GPU − CPU| over the statistics, relative to max(1, |CPU|).
    pub max_difference: f64,
}

/// A cube map from six face images (+X, −X, +Y, −Y, +Z, −Z) resized to `size`², assembled by
/// the environment loader (8-bit faces decoded from sRGB, float faces linear).
pub fn cube_from_face_files(files: &[std::path::PathBuf; 6], size: u32) -> Result<CubeMap> {
    let mut faces = Vec::with_capacity(6);
    for path in files {
        let img = crate::scene::decode::decode_file(path, &[]).context("cube-map face")?.image;
        faces.push(img.resize_exact(size, size, image::imageops::FilterType::Triangle));
    }
    let faces: [image::DynamicImage; 6] = faces.try_into().map_err(|_| anyhow::anyhow!("expected six faces"))?;
    crate::scene::environment::cube_from_faces(faces)
}

fn max_difference(g: &ColourStats, c: &ColourStats) -> f64 {
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for i in 0..3 {
        pairs.push((g.rgb_mean[i], c.rgb_mean[i]));
        pairs.push((g.lab_mean[i], c.lab_mean[i]));
        for j in 0..3 {
            pairs.push((g.rgb_cov[i][j], c.rgb_cov[i][j]));
            pairs.push((g.lab_cov[i][j], c.lab_cov[i][j]));
        }
    }
    let (a, b) = (g.luminance, c.luminance);
    pairs.extend([(a.min, b.min), (a.mean, b.mean), (a.max, b.max), (a.p_lo, b.p_lo), (a.p_hi, b.p_hi)]);
    pairs.iter().map(|(x, y)| (x - y).abs() / y.abs().max(1.0)).fold(0.0, f64::max)
}

fn time_ms<T>(repeats: u32, mut f: impl FnMut() -> Result<T>) -> Result<(Vec<f64>, T)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        last = Some(f()?);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    match last {
        Some(v) => Ok((times, v)),
        None => bail!("nothing was timed"),
    }
}

/// Run the comparison on `cube` and `frame`.
pub fn run(gpu: &Gpu, cube: &CubeMap, frame: &Rgba8Image, repeats: u32) -> Result<Vec<PriorsRow>> {
    let mut reducer = PriorsReducer::new(gpu)?;
    let mut rows = Vec::new();
    // Cube map.
    let (cpu_t, cpu) = time_ms(repeats, || crate::priors::environment_priors(cube))?;
    reducer.environment(gpu, cube)?; // warm-up (pipeline compilation, buffer allocation)
    let mut gpu_times = Vec::new();
    let (wall_t, g) = time_ms(repeats, || {
        let input = crate::priors::gpu::GpuInput::from_cube(cube)?;
        let r = reducer.reduce(gpu, &input)?;
        gpu_times.extend(r.gpu_ms);
        Ok(r)
    })?;
    rows.push(PriorsRow {
        input: format!("cube map 6×{}²", cube.size),
        pixels: 6 * u64::from(cube.size) * u64::from(cube.size),
        cpu_ms: median(&cpu_t),
        gpu_wall_ms: median(&wall_t),
        gpu_ms: (!gpu_times.is_empty()).then(|| median(&gpu_times)),
        max_difference: max_difference(&g.main, &cpu.horizontal),
    });
    // Camera frame (8-bit sRGB).
    let (cpu_t, cpu) = time_ms(repeats, || ColourStats::from_linear(&counted_linear(frame, false)))?;
    reducer.frame(gpu, frame)?;
    let mut gpu_times = Vec::new();
    let (wall_t, g) = time_ms(repeats, || {
        let r = reducer.frame(gpu, frame)?;
        gpu_times.extend(r.gpu_ms);
        Ok(r)
    })?;
    rows.push(PriorsRow {
        input: format!("camera frame {}×{}", frame.width, frame.height),
        pixels: u64::from(frame.width) * u64::from(frame.height),
        cpu_ms: median(&cpu_t),
        gpu_wall_ms: median(&wall_t),
        gpu_ms: (!gpu_times.is_empty()).then(|| median(&gpu_times)),
        max_difference: max_difference(&g.main, &cpu),
    });
    Ok(rows)
}

/// The default inputs: the Pisa HDR cube map at 512² and the astronaut photo as a 960×640 frame.
pub fn default_inputs(data: &Path) -> Result<(CubeMap, Rgba8Image)> {
    let faces = ["px", "nx", "py", "ny", "pz", "nz"].map(|f| data.join(format!("cubemaps/pisa_hdr/{f}.hdr")));
    let cube = cube_from_face_files(&faces, 512)?;
    let frame = crate::bench::colour::to_frame(&load_rgba8(&data.join("photos/colour_transfer/astronaut.png"))?)?;
    Ok((cube, frame))
}

/// Markdown table of the rows.
pub fn markdown(rows: &[PriorsRow], device: &str, repeats: u32) -> String {
    use std::fmt::Write;
    let mut s = format!("Device: {device}; median of {repeats} runs.\n\n");
    let _ = writeln!(
        s,
        "| input | pixels | CPU ms | GPU ms (wall, incl. upload + readback) | GPU ms (passes, timestamps) | CPU / GPU wall | max rel. difference |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let passes = r.gpu_ms.map(|g| format!("{g:.2}")).unwrap_or_else(|| "–".into());
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {passes} | {:.1}× | {:.1e} |",
            r.input,
            r.pixels,
            r.cpu_ms,
            r.gpu_wall_ms,
            r.cpu_ms / r.gpu_wall_ms,
            r.max_difference
        );
    }
    s
}
