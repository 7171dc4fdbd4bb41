//! `previz bench lod`: each level of the model's LOD chain rendered in the scene, against the
//! full-detail render: triangles, simplification error (model units and projected pixels at
//! the scene's distance), mean FLIP and GPU time, and which level the screen rule picks.

use super::median;
use crate::capture::replay::mean_flip;
use crate::gpu::Gpu;
use crate::render::{FrameParams, Layer};
use crate::scene::lod::LodChain;
use crate::scene::{Mesh, Model};
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, compositor_for};
use anyhow::Result;
use glam::Vec3;
use serde::Serialize;

/// One level of the chain, measured.
#[derive(Clone, Debug, Serialize)]
pub struct LodRow {
    pub level: usize,
    pub triangles: usize,
    /// Simplification error, model units.
    pub error: f32,
    /// The error projected at the model's distance, pixels.
    pub error_px: f32,
    /// The model's projected bounding sphere over the level's triangles, px² per triangle
    /// (what `scene::lod::finest_worth_drawing` compares with `MIN_TRIANGLE_AREA_PX`).
    pub area_per_triangle_px: f32,
    /// Mean FLIP of the composite against level 0's (None on mobile builds).
    pub flip_mean: Option<f32>,
    /// Median GPU time of the frame, ms (NaN without timestamp queries).
    pub gpu_ms: f64,
    /// gpu_ms over the background-only floor's, measured in the same run.
    pub floor_ratio: f64,
    /// The level the renderer draws at this distance (`render::frame::lod_level`).
    pub selected: bool,
}

/// The model with level `k` of `chain`'s index lists (same vertices).
pub fn model_at_level(model: &Model, chain: &LodChain, k: usize) -> Model {
    let meshes = model
        .meshes
        .iter()
        .zip(&chain.meshes)
        .map(|(m, l)| {
            let r = l.levels[k];
            Mesh { indices: l.indices[r.first as usize..][..r.count as usize].to_vec(), ..m.clone() }
        })
        .collect();
    Model { meshes, materials: model.materials.clone() }
}

/// The level of `chain` a frame draws (`render::frame::lod_level`, `Detail::Frame`) for a model with `bounds` (model space) drawn
/// with `params` into an image `height_px` rows high; also the model's distance and the focal
/// length in pixels.
pub fn screen_level(chain: &LodChain, bounds: (Vec3, Vec3), params: &FrameParams, height_px: u32) -> (usize, f32, f32) {
    crate::render::frame::lod_level(&chain.errors, &chain.triangles, bounds, params, height_px, crate::scene::lod::MIN_TRIANGLE_AREA_PX)
}

/// Build the chain of `inputs.model`, render every level `frames` times, interleaved frame by
/// frame with the background-only floor (so a slow spell of a shared machine lands on every
/// level alike), and compare each level's composite with the full-detail one.
pub fn run(gpu: &Gpu, scene: &Scene, inputs: &Inputs, frames: usize, progress: &indicatif::ProgressBar) -> Result<Vec<LodRow>> {
    let chain = LodChain::build(&inputs.model);
    // Every level keeps the vertex list, so it has level 0's bounds and placement.
    let bounds = inputs.model.bounds().ok_or_else(|| anyhow::anyhow!("the model has no vertices"))?;
    let mut compositors = Vec::with_capacity(chain.len());
    for k in 0..chain.len() {
        let (mut c, params) = compositor_for(gpu, scene, &inputs.env, &model_at_level(&inputs.model, &chain, k))?;
        c.set_background(gpu, inputs.background.as_ref())?;
        // Each compositor draws exactly its level, not a coarser one its own chain allows.
        c.set_detail(crate::render::Detail::Full);
        compositors.push((c, params));
    }
    let params = compositors[0].1;
    let (chosen, distance, focal) = screen_level(&chain, bounds, &params, scene.height);
    let area = crate::render::frame::model_area_px(bounds, &params, scene.height);
    progress.set_length(((chain.len() + 1) * frames) as u64);
    let mut gpu_ms = vec![Vec::new(); chain.len() + 1];
    let mut images = vec![Vec::new(); chain.len()];
    for _ in 0..frames {
        let r = compositors[0].0.render(gpu, &params, Layer::Background)?;
        gpu_ms[chain.len()].push(r.timings.gpu_ms.unwrap_or(f64::NAN));
        progress.inc(1);
        for (k, (c, p)) in compositors.iter_mut().enumerate() {
            let r = c.render(gpu, p, Layer::Composite)?;
            gpu_ms[k].push(r.timings.gpu_ms.unwrap_or(f64::NAN));
            images[k] = r.rgba;
            progress.inc(1);
        }
    }
    let floor = median(&gpu_ms[chain.len()]);
    let rgb = |rgba: &[u8]| -> Vec<u8> { rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect() };
    let reference = rgb(&images[0]);
    let mut rows = Vec::new();
    for k in 0..chain.len() {
        let level_ms = median(&gpu_ms[k]);
        rows.push(LodRow {
            level: k,
            triangles: chain.triangles[k],
            error: chain.errors[k],
            error_px: chain.errors[k] * params.placement.scale * focal / distance.max(f32::MIN_POSITIVE),
            area_per_triangle_px: area / chain.triangles[k].max(1) as f32,
            flip_mean: mean_flip(&reference, &rgb(&images[k]), scene.width, scene.height),
            gpu_ms: level_ms,
            floor_ratio: level_ms / floor,
            selected: k == chosen,
        });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[LodRow]) -> String {
    let mut s = String::from(
        "| level | triangles | px² per triangle | error (model units) | error px | mean FLIP vs level 0 | GPU ms | × floor (GPU) | drawn |\n|---:|---:|---:|---:|---:|---:|---:|---:|:---:|\n",
    );
    for r in rows {
        let flip = r.flip_mean.map_or("-".into(), |f| format!("{f:.5}"));
        s += &format!(
            "| {} | {} | {:.2} | {:.3e} | {:.3} | {} | {:.3} | {:.2} | {} |\n",
            r.level,
            r.triangles,
            r.area_per_triangle_px,
            r.error,
            r.error_px,
            flip,
            r.gpu_ms,
            r.floor_ratio,
            if r.selected { "yes" } else { "" }
        );
    }
    s
}
