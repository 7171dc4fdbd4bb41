//! `previz bench frame`: per-frame CPU and GPU time of every lighting method, and of the
//! hemisphere method with each colour correction, side by side with the floor (a frame that
//! only draws the background), in one run.

use super::median;
use crate::colour::transfer::TransferMethod;
use crate::gpu::Gpu;
use crate::render::{ColourSettings, FrameParams, Layer, LightingMethod};
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, prepare};
use anyhow::Result;
use serde::Serialize;

/// One row of the benchmark: medians over the measured frames.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRow {
    /// A method name, "hemisphere+CORRECTION" for a colour correction at full strength, or
    /// "background-only" for the floor.
    pub path: String,
    pub frames: usize,
    /// CPU time to write uniforms and record the passes, ms.
    pub cpu_encode_ms: f64,
    /// GPU time from the first pass to the last (timestamp queries), ms; NaN if unsupported.
    pub gpu_ms: f64,
    /// Wall time of the whole frame including submit, GPU and readback, ms.
    pub wall_ms: f64,
    /// gpu_ms / floor gpu_ms.
    pub gpu_ratio: f64,
    /// wall_ms / floor wall_ms.
    pub wall_ratio: f64,
}

/// Render `warmup` + `frames` frames of each path and report medians and ratios to the floor.
/// The camera turns slightly each frame so nothing can be cached between frames.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &Inputs,
    frames: usize,
    warmup: usize,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<FrameRow>> {
    let (mut compositor, base) = prepare(gpu, scene, inputs)?;
    let none = ColourSettings::NONE;
    let mut paths: Vec<(String, Layer, LightingMethod, ColourSettings)> =
        vec![("background-only".into(), Layer::Background, scene.method, none)];
    paths.extend(LightingMethod::ALL.iter().map(|m| (m.name().to_string(), Layer::Composite, *m, none)));
    paths.extend(TransferMethod::ALL.iter().map(|c| {
        let name = format!("{}+{}", LightingMethod::Hemisphere.name(), c.name());
        (name, Layer::Composite, LightingMethod::Hemisphere, ColourSettings { method: *c, strength: 1.0 })
    }));
    progress.set_length(((frames + warmup) * paths.len()) as u64);
    // Paths are interleaved frame by frame, so a slow spell of a shared machine (or a clock
    // change) lands on every path alike instead of on whichever path was running.
    let mut samples = vec![(Vec::new(), Vec::new(), Vec::new()); paths.len()];
    for i in 0..frames + warmup {
        progress.set_message(if i < warmup { "warm-up" } else { "measuring" });
        for ((_, layer, method, colour), (cpu, gpu_t, wall)) in paths.iter().zip(samples.iter_mut()) {
            let mut p: FrameParams = base;
            p.method = *method;
            p.colour = *colour;
            p.camera.pose *= glam::Quat::from_rotation_y(1e-4 * i as f32);
            let t = std::time::Instant::now();
            let r = compositor.render(gpu, &p, *layer)?;
            let total = t.elapsed().as_secs_f64() * 1e3;
            if i >= warmup {
                cpu.push(r.timings.encode_ms);
                gpu_t.push(r.timings.gpu_ms.unwrap_or(f64::NAN));
                wall.push(total);
            }
            progress.inc(1);
        }
    }
    let mut rows: Vec<FrameRow> = paths
        .into_iter()
        .zip(samples)
        .map(|((name, ..), (cpu, gpu_t, wall))| FrameRow {
            path: name,
            frames,
            cpu_encode_ms: median(&cpu),
            gpu_ms: median(&gpu_t),
            wall_ms: median(&wall),
            gpu_ratio: 0.0,
            wall_ratio: 0.0,
        })
        .collect();
    let (floor_gpu, floor_wall) = (rows[0].gpu_ms, rows[0].wall_ms);
    for r in &mut rows {
        r.gpu_ratio = r.gpu_ms / floor_gpu;
        r.wall_ratio = r.wall_ms / floor_wall;
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[FrameRow]) -> String {
    let mut s =
        String::from("| path | CPU encode ms | GPU ms | × floor (GPU) | wall ms | × floor (wall) |\n|---|---:|---:|---:|---:|---:|\n");
    for r in rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} |\n",
            r.path, r.cpu_encode_ms, r.gpu_ms, r.gpu_ratio, r.wall_ms, r.wall_ratio
        );
    }
    s
}
