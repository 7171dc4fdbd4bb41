//! `previz bench frame`: what a frame costs, side by side with the floor (a frame that only draws
//! the background), in one run: the scene as drawn by default (its method, the level of detail
//! and shadow map the screen needs, the adapter's antialiasing) against the full-detail,
//! full-shadow reference of the same method, the same at a quarter of the fill, every lighting
//! method, each colour correction, and each antialiasing the adapter supports (1×/2×/4× MSAA, FXAA)
//! with the FLIP of its edges against a supersampled render. Issue 11's goals are read off these
//! rows ([`goals`]).

use super::median;
use crate::colour::transfer::TransferMethod;
use crate::gpu::Gpu;
use crate::render::{Antialiasing, ColourSettings, Compositor, FrameParams, Layer, LightingMethod};
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, camera_and_placement, prepare, prepare_antialiased};
use anyhow::{Result, anyhow};
use serde::Serialize;

/// One row of the benchmark: medians over the measured frames.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRow {
    /// What the path draws (see [`run`]).
    pub path: String,
    pub frames: usize,
    /// CPU time to write uniforms and record the passes, ms.
    pub cpu_encode_ms: f64,
    /// GPU time from the first pass to the last (timestamp queries), ms; NaN if unsupported.
    pub gpu_ms: f64,
    /// GPU time of the shadow pass alone, ms (NaN when it did not run).
    pub shadow_gpu_ms: f64,
    /// Wall time of the whole frame including submit, GPU and readback, ms.
    pub wall_ms: f64,
    /// gpu_ms / floor gpu_ms.
    pub gpu_ratio: f64,
    /// wall_ms / floor wall_ms.
    pub wall_ratio: f64,
    /// Mean FLIP of the last frame against its reference (NaN: none): the full-detail,
    /// full-shadow render for the default paths, the 4× MSAA frame for the other antialiasing
    /// paths (the whole frame: FXAA also softens the background).
    pub flip: f64,
    /// Mean FLIP over the model's silhouette pixels against a supersampled render (2× the
    /// resolution each way, 4× MSAA: 16 samples per pixel), for the antialiasing paths (NaN
    /// otherwise).
    pub edge_flip: f64,
}

/// Names of the rows [`goals`] reads.
pub const FLOOR: &str = "background-only";
pub const DEFAULT: &str = "default";
pub const REFERENCE: &str = "full detail + full shadow";
pub const NO_GROUND: &str = "default without the ground pass";
pub const QUARTER: &str = "quarter fill";
pub const QUARTER_REFERENCE: &str = "quarter fill, full detail + full shadow";

/// One path: which compositor draws which layer with which parameters.
struct PathSpec {
    name: String,
    compositor: usize,
    layer: Layer,
    params: FrameParams,
    /// Draw level 0 into the largest shadow map.
    full: bool,
    /// The path whose last frame is this one's FLIP reference.
    reference: Option<usize>,
    /// Score the silhouette against the supersampled render.
    edges: bool,
}

/// Render `warmup` + `frames` frames of each path, interleaved frame by frame, and report
/// medians, ratios to the floor and FLIP. The camera turns slightly each frame so nothing can be
/// cached between frames.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &Inputs,
    frames: usize,
    warmup: usize,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<FrameRow>> {
    let (default, base) = prepare(gpu, scene, inputs)?;
    let default_aa = default.antialiasing();
    let mut compositors = vec![default];
    let path = |name: &str, compositor, layer, params, full| PathSpec {
        name: name.into(),
        compositor,
        layer,
        params,
        full,
        reference: None,
        edges: false,
    };
    let mut paths = vec![
        path(FLOOR, 0, Layer::Background, base, false),
        path(DEFAULT, 0, Layer::Composite, base, false),
        path(REFERENCE, 0, Layer::Composite, base, true),
    ];
    paths[1].reference = Some(2);
    // Profiling: the default frame without its ground pass (what the shadow catcher costs).
    let mut no_ground = base;
    no_ground.lighting.shadow_opacity = 0.0;
    paths.push(path(NO_GROUND, 0, Layer::Composite, no_ground, false));
    // The same model at a quarter of the fill (placed by the same rule, farther away).
    let quarter_scene = Scene {
        placement: crate::setup::scene_file::PlacementSection { fill: scene.placement.fill * 0.25, ..scene.placement.clone() },
        ..scene.clone()
    };
    let bounds = compositors[0].model_bounds().ok_or_else(|| anyhow!("no model"))?;
    let quarter = FrameParams { placement: camera_and_placement(&quarter_scene, bounds).1, ..base };
    paths.push(PathSpec { reference: Some(paths.len() + 1), ..path(QUARTER, 0, Layer::Composite, quarter, false) });
    paths.push(path(QUARTER_REFERENCE, 0, Layer::Composite, quarter, true));
    for m in LightingMethod::ALL {
        paths.push(path(&format!("method {}", m.name()), 0, Layer::Composite, FrameParams { method: m, ..base }, false));
    }
    for c in TransferMethod::TRANSFERS {
        let colour = ColourSettings { method: c, strength: 1.0 };
        paths.push(path(&format!("correction {}", c.name()), 0, Layer::Composite, FrameParams { colour, ..base }, false));
    }
    let first_aa = paths.len();
    let supported: Vec<Antialiasing> = Antialiasing::ALL.into_iter().filter(|aa| aa.supported(gpu)).collect();
    // The antialiasing paths are scored against the 4× MSAA frame (whole frame: FXAA also
    // softens the background) and on the model's silhouette against a 16-sample render.
    let msaa4 = supported.iter().position(|aa| *aa == Antialiasing::Msaa(4)).map(|i| first_aa + i);
    for &aa in &supported {
        let index = if aa == default_aa {
            0
        } else {
            compositors.push(prepare_antialiased(gpu, scene, inputs, aa)?.0);
            compositors.len() - 1
        };
        let name = format!("antialiasing {}", aa.name());
        let reference = msaa4.filter(|_| aa != Antialiasing::Msaa(4));
        paths.push(PathSpec { edges: true, reference, ..path(&name, index, Layer::Composite, base, false) });
    }

    progress.set_length(((frames + warmup) * paths.len()) as u64);
    // Paths are interleaved frame by frame, so a slow spell of a shared machine (or a clock
    // change) lands on every path alike instead of on whichever path was running.
    let mut samples = vec![(Vec::new(), Vec::new(), Vec::new(), Vec::new()); paths.len()];
    let mut last: Vec<Vec<u8>> = vec![Vec::new(); paths.len()];
    let turn = |i: usize| glam::Quat::from_rotation_y(1e-4 * i as f32);
    for i in 0..frames + warmup {
        progress.set_message(if i < warmup { "warm-up" } else { "measuring" });
        for (k, spec) in paths.iter().enumerate() {
            let mut p = spec.params;
            p.camera.pose *= turn(i);
            let c = &mut compositors[spec.compositor];
            c.set_full_detail(spec.full);
            c.set_full_shadow(spec.full);
            let t = std::time::Instant::now();
            let r = c.render(gpu, &p, spec.layer)?;
            let total = t.elapsed().as_secs_f64() * 1e3;
            if i >= warmup {
                samples[k].0.push(r.timings.encode_ms);
                samples[k].1.push(r.timings.gpu_ms.unwrap_or(f64::NAN));
                samples[k].2.push(total);
                samples[k].3.push(r.timings.shadow_gpu_ms.unwrap_or(f64::NAN));
            }
            last[k] = rgb(&r.rgba);
            progress.inc(1);
        }
    }
    for c in &mut compositors {
        c.set_full_detail(false);
        c.set_full_shadow(false);
    }

    let (w, h) = (scene.width, scene.height);
    let mut turned = base;
    turned.camera.pose *= turn(frames + warmup - 1);
    let (supersampled, silhouette) = supersampled(gpu, scene, inputs, &turned)?;
    let flip = |a: &[u8], b: &[u8], mask: Option<&[bool]>| -> Result<f64> {
        let map = super::accuracy::flip_map(a, b, w, h).ok_or_else(|| anyhow!("FLIP is not available on this platform"))?;
        Ok(f64::from(match mask {
            Some(m) => super::accuracy::masked_mean(&map, m),
            None => super::accuracy::masked_mean(&map, &vec![true; map.len()]),
        }))
    };
    let mut rows = Vec::new();
    for (k, (spec, (cpu, gpu_t, wall, shadow))) in paths.iter().zip(samples).enumerate() {
        let reference_flip = match spec.reference {
            Some(r) => flip(&last[r], &last[k], None)?,
            None => f64::NAN,
        };
        let edge_flip = if spec.edges { flip(&supersampled, &last[k], Some(&silhouette))? } else { f64::NAN };
        rows.push(FrameRow {
            path: spec.name.clone(),
            frames,
            cpu_encode_ms: median(&cpu),
            gpu_ms: median(&gpu_t),
            shadow_gpu_ms: if shadow.iter().any(|v| v.is_nan()) { f64::NAN } else { median(&shadow) },
            wall_ms: median(&wall),
            gpu_ratio: 0.0,
            wall_ratio: 0.0,
            flip: reference_flip,
            edge_flip,
        });
    }
    let (floor_gpu, floor_wall) = (rows[0].gpu_ms, rows[0].wall_ms);
    for r in &mut rows {
        r.gpu_ratio = r.gpu_ms / floor_gpu;
        r.wall_ratio = r.wall_ms / floor_wall;
    }
    Ok(rows)
}

/// The frame `p` of `scene` rendered at twice the resolution each way with 4× MSAA, full detail
/// and full shadow, then averaged over 2×2 pixels (16 samples per pixel), as RGB8; and the
/// model's silhouette: the pixels its coverage (the model layer's alpha, averaged the same way)
/// covers partly.
fn supersampled(gpu: &Gpu, scene: &Scene, inputs: &Inputs, p: &FrameParams) -> Result<(Vec<u8>, Vec<bool>)> {
    let (w, h) = (scene.width, scene.height);
    let big = Scene { width: 2 * w, height: 2 * h, ..scene.clone() };
    let background = inputs.background.as_ref().map(|b| crate::scene::background::fit(b, 2 * w, 2 * h));
    let big_inputs = Inputs { model: inputs.model.clone(), env: inputs.env.clone(), background };
    let (mut c, big_params): (Compositor, FrameParams) = prepare_antialiased(gpu, &big, &big_inputs, Antialiasing::Msaa(4))?;
    c.set_full_detail(true);
    c.set_full_shadow(true);
    // Same camera and placement as `p` (the bigger scene places the model by the same rule).
    let params = FrameParams { camera: p.camera, placement: p.placement, ..big_params };
    let composite = downsample(&c.render(gpu, &params, Layer::Composite)?.rgba, 2 * w, 2 * h);
    let model = downsample(&c.render(gpu, &params, Layer::Model)?.rgba, 2 * w, 2 * h);
    let silhouette = model.chunks_exact(4).map(|px| (8..=247).contains(&px[3])).collect();
    Ok((rgb(&composite), silhouette))
}

/// RGBA8 of `w`×`h` averaged over 2×2 blocks (in the encoded values: the edge test compares
/// coverage, and FLIP reads sRGB).
fn downsample(rgba: &[u8], w: u32, h: u32) -> Vec<u8> {
    let (w, h) = (w as usize, h as usize);
    let mut out = Vec::with_capacity(w * h);
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            for c in 0..4 {
                let at = |dx: usize, dy: usize| u32::from(rgba[4 * ((y + dy) * w + x + dx) + c]);
                out.push(((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8);
            }
        }
    }
    out
}

fn rgb(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

/// Issue 11's goals read off the rows: (goal, measured, met).
pub fn goals(rows: &[FrameRow]) -> Vec<(String, String, bool)> {
    let row = |name: &str| rows.iter().find(|r| r.path == name);
    let mut out = Vec::new();
    if let (Some(floor), Some(d)) = (row(FLOOR), row(DEFAULT)) {
        out.push(("default frame <= 2.0x the floor (GPU)".into(), format!("{:.2}x", d.gpu_ratio), d.gpu_ratio <= 2.0));
        out.push(("its mean FLIP vs full detail + full shadow <= 0.01".into(), format!("{:.4}", d.flip), d.flip <= 0.01));
        if let Some(q) = row(QUARTER) {
            let share = (q.gpu_ms - floor.gpu_ms) / (d.gpu_ms - floor.gpu_ms);
            out.push(("quarter fill's cost above the floor <= 0.5x the default fill's".into(), format!("{share:.2}x"), share <= 0.5));
        }
    }
    out
}

/// The rows as a markdown table, then the goals.
pub fn markdown(rows: &[FrameRow]) -> String {
    let mut s = String::from(
        "| path | CPU encode ms | GPU ms | of which shadow pass | × floor (GPU) | wall ms | × floor (wall) | mean FLIP vs reference | edge FLIP vs 16 spp |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let num = |v: f64| if v.is_nan() { String::new() } else { format!("{v:.4}") };
    for r in rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {} | {:.2} | {:.2} | {:.2} | {} | {} |\n",
            r.path,
            r.cpu_encode_ms,
            r.gpu_ms,
            num(r.shadow_gpu_ms),
            r.gpu_ratio,
            r.wall_ms,
            r.wall_ratio,
            num(r.flip),
            num(r.edge_flip)
        );
    }
    s += "\n| goal | measured | met |\n|---|---:|:---:|\n";
    for (goal, measured, met) in goals(rows) {
        s += &format!("| {goal} | {measured} | {} |\n", if met { "yes" } else { "no" });
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsampling_averages_two_by_two_blocks() {
        // 4×2 pixels: the left block is black and white, the right one all 100.
        let mut rgba = vec![0u8; 4 * 8];
        for (i, px) in rgba.chunks_exact_mut(4).enumerate() {
            let v = match i % 4 {
                0 | 1 => (i / 4 * 255) as u8,
                _ => 100,
            };
            px.copy_from_slice(&[v; 4]);
        }
        // Left block: rows 0 (0, 0) and 1 (255, 255): mean 127.5 rounds to 128.
        assert_eq!(downsample(&rgba, 4, 2), vec![128, 128, 128, 128, 100, 100, 100, 100]);
    }

    #[test]
    fn goals_are_ratios_to_the_floor() {
        let row = |path: &str, gpu_ms: f64, flip: f64| FrameRow {
            path: path.into(),
            frames: 1,
            cpu_encode_ms: 0.0,
            gpu_ms,
            shadow_gpu_ms: f64::NAN,
            wall_ms: gpu_ms,
            gpu_ratio: gpu_ms / 10.0,
            wall_ratio: gpu_ms / 10.0,
            flip,
            edge_flip: f64::NAN,
        };
        // Floor 10 ms, default 18 ms (1.8×, 8 above), quarter 14 ms (4 above: half of 8).
        let rows = [row(FLOOR, 10.0, f64::NAN), row(DEFAULT, 18.0, 0.004), row(QUARTER, 14.0, 0.001)];
        let g = goals(&rows);
        assert_eq!(g.len(), 3);
        assert_eq!((g[0].1.as_str(), g[0].2), ("1.80x", true));
        assert_eq!((g[1].1.as_str(), g[1].2), ("0.0040", true));
        assert_eq!((g[2].1.as_str(), g[2].2), ("0.50x", true));
        let rows = [row(FLOOR, 10.0, f64::NAN), row(DEFAULT, 25.0, 0.02), row(QUARTER, 20.0, 0.0)];
        assert!(goals(&rows).iter().all(|(_, _, met)| !met));
    }
}
