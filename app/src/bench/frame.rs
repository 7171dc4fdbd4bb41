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
use crate::render::{Antialiasing, ColourSettings, Compositor, Detail, FrameParams, Layer, LightingMethod};
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, camera_and_placement, prepare_antialiased};
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
    /// GPU time of the shadow pass alone, ms: median over the measured frames that drew the
    /// map (NaN when none did).
    pub shadow_gpu_ms: f64,
    /// Share of the measured frames whose shadow pass drew the map (the others kept the map an
    /// earlier frame drew: same model and level, the sun moved less than an eighth of a texel).
    pub shadow_drawn: f64,
    /// Share of the measured frames that looked the model's sun up at its vertices and split its
    /// triangles again (render::passes::vertex_sun: a new map, or the camera moved past the
    /// split's margin).
    pub vertex_sun_ran: f64,
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
pub const SUN_MOVING: &str = "default, sun turning 0.5° a frame";
pub const CAMERA_WALKING: &str = "default, camera walking 2 % of its distance a frame";

/// How a path's frames change from one to the next. Every path's camera also turns by 1e-4 rad
/// a frame, so no frame's image can be reused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Nothing else moves: the shadow map and the split are kept.
    Still,
    /// The sun turns 0.5° about the vertical a frame: the shadow map is drawn every frame.
    SunTurning,
    /// The camera walks round the model's base, 2 % of its distance to it a frame ([`WALK_STEP`],
    /// a user 3 m away walking 1.8 m/s at 30 frames a second), still looking the same way at
    /// it: the shadow map is kept and the vertex-sun split runs again each time the camera has
    /// moved past its margin (render::passes::vertex_sun::SPLIT_CULL_MARGIN).
    CameraWalking,
}

/// How far the walking camera moves a frame, as a share of its distance to the model's base.
pub const WALK_STEP: f32 = 0.02;

impl Motion {
    /// Frame `i` of a path whose first frame is `p`.
    pub fn frame(self, p: &FrameParams, i: usize) -> FrameParams {
        let mut p = *p;
        p.camera.pose *= glam::Quat::from_rotation_y(1e-4 * i as f32);
        match self {
            Motion::Still => {}
            Motion::SunTurning => p.lighting.sun_dir = glam::Quat::from_rotation_z((0.5 * i as f32).to_radians()) * p.lighting.sun_dir,
            Motion::CameraWalking => {
                let base = p.placement.position;
                let from = p.camera.position - base;
                let radius = from.truncate().length();
                let angle = if radius > 0.0 { WALK_STEP * from.length() / radius * i as f32 } else { 0.0 };
                let turn = glam::Quat::from_rotation_z(angle);
                p.camera.position = base + turn * from;
                p.camera.pose = turn * p.camera.pose;
            }
        }
        p
    }
}

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
    motion: Motion,
}

/// Render `warmup` + `frames` frames of each path, interleaved frame by frame, and report
/// medians, ratios to the floor and FLIP. The camera turns slightly each frame, so no frame's
/// image can be reused; the shadow map, which does not depend on the camera, is kept while the
/// sun and model stay put (as in the product), and drawn every frame on the sun-turning path.
/// Paths that would change what a compositor keeps for another path's frames (a moving sun,
/// another placement, method or antialiasing) each have a compositor of their own.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &Inputs,
    frames: usize,
    warmup: usize,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<FrameRow>> {
    // Frames drawn one after another: the adapter's antialiasing (a still would use 4x).
    let (default, base) = prepare_antialiased(gpu, scene, inputs, Antialiasing::for_adapter(&gpu.adapter.get_info()))?;
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
        motion: Motion::Still,
    };
    let mut paths = vec![
        path(FLOOR, 0, Layer::Background, base, false),
        path(DEFAULT, 0, Layer::Composite, base, false),
        path(REFERENCE, 0, Layer::Composite, base, true),
    ];
    paths[1].reference = Some(2);
    // A path on a compositor of its own: a compositor keeps its shadow map (and the sun at the
    // model's vertices looked up in it) while the sun and the model stay put, as the product
    // does; a path whose sun moves, or that draws another map or level of detail, would
    // otherwise redraw the default's every frame, or its own.
    let own = |compositors: &mut Vec<Compositor>| -> Result<usize> {
        compositors.push(prepare_antialiased(gpu, scene, inputs, default_aa)?.0);
        Ok(compositors.len() - 1)
    };
    // The default frame whose shadow map cannot be kept (a sun or a model that moves): the map
    // is drawn every frame.
    paths.push(PathSpec { motion: Motion::SunTurning, ..path(SUN_MOVING, own(&mut compositors)?, Layer::Composite, base, false) });
    // The default frame seen by a walking user: the map kept, the split run again now and then.
    paths.push(PathSpec { motion: Motion::CameraWalking, ..path(CAMERA_WALKING, own(&mut compositors)?, Layer::Composite, base, false) });
    // Profiling: the default frame without its ground pass (what the shadow catcher costs).
    // (No sun shadow and no sky occlusion: with either the ground pass runs.)
    let mut no_ground = base;
    (no_ground.lighting.shadow_opacity, no_ground.lighting.sky_occlusion) = (0.0, 0.0);
    paths.push(path(NO_GROUND, own(&mut compositors)?, Layer::Composite, no_ground, false));
    // The same model at a quarter of the fill (placed by the same rule, farther away).
    let quarter_scene = Scene {
        placement: crate::setup::scene_file::PlacementSection { fill: scene.placement.fill * 0.25, ..scene.placement.clone() },
        ..scene.clone()
    };
    let bounds = compositors[0].model_bounds().ok_or_else(|| anyhow!("no model"))?;
    let quarter = FrameParams { placement: camera_and_placement(&quarter_scene, bounds).1, ..base };
    // Its own compositor, for the reference too: its placement's ground map and model sky.
    let q = own(&mut compositors)?;
    paths.push(PathSpec { reference: Some(paths.len() + 1), ..path(QUARTER, q, Layer::Composite, quarter, false) });
    paths.push(path(QUARTER_REFERENCE, q, Layer::Composite, quarter, true));
    // Each method on a compositor of its own, as a user of that method has it (the reflections
    // and refractions draw the full mesh into their map).
    for m in LightingMethod::ALL {
        let name = format!("method {}", m.name());
        paths.push(path(&name, own(&mut compositors)?, Layer::Composite, FrameParams { method: m, ..base }, false));
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
    let mut drawn = vec![(0usize, 0usize); paths.len()];
    for i in 0..frames + warmup {
        progress.set_message(if i < warmup { "warm-up" } else { "measuring" });
        for (k, spec) in paths.iter().enumerate() {
            let p = spec.motion.frame(&spec.params, i);
            let c = &mut compositors[spec.compositor];
            c.set_detail(if spec.full { Detail::Full } else { Detail::Frame });
            c.set_full_shadow(spec.full);
            let t = std::time::Instant::now();
            let r = c.render(gpu, &p, spec.layer)?;
            let total = t.elapsed().as_secs_f64() * 1e3;
            if i >= warmup {
                samples[k].0.push(r.timings.encode_ms);
                samples[k].1.push(r.timings.gpu_ms.unwrap_or(f64::NAN));
                samples[k].2.push(total);
                samples[k].3.push(r.timings.shadow_gpu_ms.unwrap_or(f64::NAN));
                let run = c.passes_run();
                drawn[k].0 += usize::from(run.shadow_drawn);
                drawn[k].1 += usize::from(run.vertex_sun);
            }
            last[k] = rgb(&r.rgba);
            progress.inc(1);
        }
    }
    for c in &mut compositors {
        c.set_detail(Detail::Frame);
        c.set_full_shadow(false);
    }

    let (w, h) = (scene.width, scene.height);
    let turned = Motion::Still.frame(&base, frames + warmup - 1);
    let (supersampled, silhouette) = supersampled(gpu, scene, inputs, &turned)?;
    let flip = |a: &[u8], b: &[u8], mask: Option<&[bool]>| -> Result<f64> {
        let map = super::accuracy::flip_map(a, b, w, h).ok_or_else(|| anyhow!("FLIP is not available on this platform"))?;
        Ok(f64::from(match mask {
            Some(m) => super::accuracy::masked_mean(&map, m),
            None => super::accuracy::masked_mean(&map, &vec![true; map.len()]),
        }))
    };
    let mut rows = Vec::new();
    for (k, ((spec, (cpu, gpu_t, wall, shadow)), drawn)) in paths.iter().zip(samples).zip(drawn).enumerate() {
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
            shadow_gpu_ms: {
                let ran: Vec<f64> = shadow.into_iter().filter(|v| !v.is_nan()).collect();
                if ran.is_empty() { f64::NAN } else { median(&ran) }
            },
            shadow_drawn: drawn.0 as f64 / frames.max(1) as f64,
            vertex_sun_ran: drawn.1 as f64 / frames.max(1) as f64,
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

/// Where a path's frame time goes: each pass timed alone (`Compositor::set_pass_timing`),
/// medians over the measured frames (NaN: the pass did not run).
#[derive(Clone, Debug, Serialize)]
pub struct PassRow {
    pub path: String,
    pub frames: usize,
    /// The passes' sum (a little more than the frame drawn in one render pass costs).
    pub total_ms: f64,
    /// Over the frames that drew the map.
    pub shadow_ms: f64,
    /// Of those, the model's sun looked up at its vertices and its triangles split (render::
    /// passes::vertex_sun), over the frames that ran them.
    pub vertex_sun_ms: f64,
    pub background_ms: f64,
    pub model_ms: f64,
    pub ground_ms: f64,
    pub fxaa_ms: f64,
    /// Fragment-shader invocations of each composite pass and the model pass's triangles out of
    /// clipping, medians (gpu::PassCounter: on lavapipe 16 for each 4×4 block a triangle
    /// covers part of; they do not swing with the machine's load). None: no pipeline-statistics
    /// queries, or the pass did not run.
    pub background_fragments: Option<u64>,
    pub model_fragments: Option<u64>,
    pub ground_fragments: Option<u64>,
    pub model_triangles: Option<u64>,
}

/// The profile of [`run`]'s main paths: the floor, the default frame (its shadow map kept and
/// drawn every frame), its full-detail, full-shadow reference and the quarter fill, each pass
/// timed alone, interleaved frame by frame as in [`run`]. Each path has its own compositor, so
/// a path's shadow map is kept or drawn as it would be alone.
pub fn profile(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &Inputs,
    frames: usize,
    warmup: usize,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<PassRow>> {
    let aa = Antialiasing::for_adapter(&gpu.adapter.get_info());
    let (c, base) = prepare_antialiased(gpu, scene, inputs, aa)?;
    let quarter_scene = Scene {
        placement: crate::setup::scene_file::PlacementSection { fill: scene.placement.fill * 0.25, ..scene.placement.clone() },
        ..scene.clone()
    };
    let bounds = c.model_bounds().ok_or_else(|| anyhow!("no model"))?;
    let quarter = FrameParams { placement: camera_and_placement(&quarter_scene, bounds).1, ..base };
    // (name, layer, params, full detail and shadow, motion)
    let paths = [
        (FLOOR, Layer::Background, base, false, Motion::Still),
        (DEFAULT, Layer::Composite, base, false, Motion::Still),
        (SUN_MOVING, Layer::Composite, base, false, Motion::SunTurning),
        (CAMERA_WALKING, Layer::Composite, base, false, Motion::CameraWalking),
        (REFERENCE, Layer::Composite, base, true, Motion::Still),
        (QUARTER, Layer::Composite, quarter, false, Motion::Still),
    ];
    let mut compositors = vec![c];
    for _ in 1..paths.len() {
        compositors.push(prepare_antialiased(gpu, scene, inputs, aa)?.0);
    }
    progress.set_length(((frames + warmup) * paths.len()) as u64);
    progress.set_position(0);
    let mut samples = vec![Vec::new(); paths.len()];
    let mut counts = vec![Vec::new(); paths.len()];
    for i in 0..frames + warmup {
        for (k, &(_, layer, params, full, motion)) in paths.iter().enumerate() {
            let c = &mut compositors[k];
            c.set_pass_timing(true);
            let p = motion.frame(&params, i);
            c.set_detail(if full { Detail::Full } else { Detail::Frame });
            c.set_full_shadow(full);
            let r = c.render(gpu, &p, layer)?;
            if i >= warmup {
                samples[k].push(r.timings.passes.ok_or_else(|| anyhow!("no GPU timestamps on this adapter: nothing to profile"))?);
                counts[k].extend(r.timings.counts);
            }
            progress.inc(1);
        }
    }
    Ok(paths
        .iter()
        .zip(samples.iter().zip(&counts))
        .map(|(&(name, ..), (s, c))| {
            let of = |f: fn(&crate::render::PassTimes) -> Option<f64>| {
                let v: Vec<f64> = s.iter().filter_map(f).collect();
                median(&v)
            };
            let count = |f: fn(&crate::render::PassCounts) -> Option<u64>| {
                let mut v: Vec<u64> = c.iter().filter_map(f).collect();
                v.sort_unstable();
                v.get(v.len() / 2).copied()
            };
            PassRow {
                path: name.into(),
                frames,
                total_ms: median(&s.iter().map(|p| p.total()).collect::<Vec<_>>()),
                shadow_ms: of(|p| p.shadow),
                vertex_sun_ms: of(|p| p.vertex_sun.map(|[lookup, split]| lookup + split)),
                background_ms: of(|p| p.background),
                model_ms: of(|p| p.model),
                ground_ms: of(|p| p.ground),
                fxaa_ms: of(|p| p.fxaa),
                background_fragments: count(|c| c.background.map(|p| p.fragments)),
                model_fragments: count(|c| c.model.map(|p| p.fragments)),
                ground_fragments: count(|c| c.ground.map(|p| p.fragments)),
                model_triangles: count(|c| c.model.map(|p| p.triangles)),
            }
        })
        .collect())
}

/// The profile as a markdown table.
pub fn profile_markdown(rows: &[PassRow]) -> String {
    let mut s = String::from(
        "| path (each pass timed alone) | sum GPU ms | shadow | of which vertex sun | background | model | ground | FXAA | fragments: background / model / ground | model triangles |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let num = |v: f64| if v.is_nan() { "–".to_string() } else { format!("{v:.3}") };
    let count = |v: Option<u64>| v.map_or("–".to_string(), |v| v.to_string());
    for r in rows {
        s += &format!(
            "| {} | {:.3} | {} | {} | {} | {} | {} | {} | {} / {} / {} | {} |\n",
            r.path,
            r.total_ms,
            num(r.shadow_ms),
            num(r.vertex_sun_ms),
            num(r.background_ms),
            num(r.model_ms),
            num(r.ground_ms),
            num(r.fxaa_ms),
            count(r.background_fragments),
            count(r.model_fragments),
            count(r.ground_fragments),
            count(r.model_triangles)
        );
    }
    s
}

/// The frame `p` of `scene` rendered at twice the resolution each way with 4× MSAA, full detail
/// and full shadow, then averaged over 2×2 pixels (16 samples per pixel), as RGB8; and the
/// model's silhouette: the pixels its coverage (the model layer's alpha, averaged the same way)
/// covers partly.
fn supersampled(gpu: &Gpu, scene: &Scene, inputs: &Inputs, p: &FrameParams) -> Result<(Vec<u8>, Vec<bool>)> {
    let (w, h) = (scene.width, scene.height);
    let big = Scene { width: 2 * w, height: 2 * h, ..scene.clone() };
    let background = inputs.background.as_ref().map(|b| crate::scene::background::fit(b, 2 * w, 2 * h));
    let big_inputs = Inputs { model: inputs.model.clone(), env: inputs.env.clone(), env_equirect: inputs.env_equirect.clone(), background };
    let (mut c, big_params): (Compositor, FrameParams) = prepare_antialiased(gpu, &big, &big_inputs, Antialiasing::Msaa(4))?;
    c.set_detail(Detail::Full);
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

/// Prefix of the rows that draw the default scene with one lighting method ("method sh9-ggx").
pub const METHOD_ROW: &str = "method ";

/// One lighting method's frame cost, measured by [`run`] in the same run as the floor: what the
/// accuracy-versus-cost chart (bench::accuracy) puts on its cost axis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodCost {
    /// `LightingMethod::name`.
    pub method: String,
    /// Median GPU ms of the default frame drawn with the method.
    pub gpu_ms: f64,
    /// That over the background-only floor of the same run.
    pub floor_ratio: f64,
}

/// Every method's cost, read off the "method …" rows (in their order).
pub fn method_costs(rows: &[FrameRow]) -> Vec<MethodCost> {
    rows.iter()
        .filter_map(|r| {
            let method = r.path.strip_prefix(METHOD_ROW)?;
            Some(MethodCost { method: method.into(), gpu_ms: r.gpu_ms, floor_ratio: r.gpu_ratio })
        })
        .collect()
}

/// The CSV columns of [`csv`], in order.
const CSV_HEADER: &str =
    "path,frames,cpu_encode_ms,gpu_ms,shadow_gpu_ms,shadow_drawn,vertex_sun_ran,wall_ms,gpu_ratio,wall_ratio,flip,edge_flip";

/// The rows as CSV (`previz bench frame --csv`; docs/bench_frame_goals.csv). The path is
/// quoted (some hold commas).
pub fn csv(rows: &[FrameRow]) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for r in rows {
        s += &format!(
            "\"{}\",{},{},{},{},{},{},{},{},{},{},{}\n",
            r.path.replace('"', "'"),
            r.frames,
            r.cpu_encode_ms,
            r.gpu_ms,
            r.shadow_gpu_ms,
            r.shadow_drawn,
            r.vertex_sun_ran,
            r.wall_ms,
            r.gpu_ratio,
            r.wall_ratio,
            r.flip,
            r.edge_flip
        );
    }
    s
}

/// Rows back from [`csv`]'s text (e.g. docs/bench_frame_goals.csv, for the accuracy chart's
/// cost axis: `method_costs(&read_csv(text)?)`). Errors name the line and what is wrong.
pub fn read_csv(text: &str) -> Result<Vec<FrameRow>> {
    let mut lines = text.lines();
    match lines.next() {
        Some(h) if h.trim() == CSV_HEADER => {}
        other => return Err(anyhow!("bench frame CSV: header {other:?}, expected {CSV_HEADER:?}")),
    }
    lines
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, line)| {
            // "path",numbers...
            let (path, rest) = line
                .strip_prefix('"')
                .and_then(|l| l.split_once("\","))
                .ok_or_else(|| anyhow!("bench frame CSV line {}: no quoted path first", i + 2))?;
            let f: Vec<&str> = std::iter::once(path).chain(rest.split(',')).collect();
            if f.len() != 12 {
                return Err(anyhow!("bench frame CSV line {}: {} fields, expected 12", i + 2, f.len()));
            }
            let num = |k: usize| f[k].trim().parse::<f64>().map_err(|e| anyhow!("bench frame CSV line {}, field {}: {e}", i + 2, k + 1));
            Ok(FrameRow {
                path: f[0].into(),
                frames: f[1].trim().parse().map_err(|e| anyhow!("bench frame CSV line {}, frames: {e}", i + 2))?,
                cpu_encode_ms: num(2)?,
                gpu_ms: num(3)?,
                shadow_gpu_ms: num(4)?,
                shadow_drawn: num(5)?,
                vertex_sun_ran: num(6)?,
                wall_ms: num(7)?,
                gpu_ratio: num(8)?,
                wall_ratio: num(9)?,
                flip: num(10)?,
                edge_flip: num(11)?,
            })
        })
        .collect()
}

/// The rows as a markdown table, then the goals.
pub fn markdown(rows: &[FrameRow]) -> String {
    let mut s = String::from(
        "| path | CPU encode ms | GPU ms | shadow map drawn | of which shadow pass | vertex sun run | × floor (GPU) | wall ms | × floor (wall) | mean FLIP vs reference | edge FLIP vs 16 spp |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let num = |v: f64| if v.is_nan() { String::new() } else { format!("{v:.4}") };
    for r in rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {:.0} % | {} | {:.0} % | {:.2} | {:.2} | {:.2} | {} | {} |\n",
            r.path,
            r.cpu_encode_ms,
            r.gpu_ms,
            100.0 * r.shadow_drawn,
            num(r.shadow_gpu_ms),
            100.0 * r.vertex_sun_ran,
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
    fn method_costs_round_trip_through_the_csv() {
        let row = |path: &str, gpu_ms: f64| FrameRow {
            path: path.into(),
            frames: 3,
            cpu_encode_ms: 0.1,
            gpu_ms,
            shadow_gpu_ms: f64::NAN,
            shadow_drawn: 0.5,
            vertex_sun_ran: 0.25,
            wall_ms: gpu_ms + 1.0,
            gpu_ratio: gpu_ms / 8.0,
            wall_ratio: 1.0,
            flip: f64::NAN,
            edge_flip: f64::NAN,
        };
        let rows = [row(FLOOR, 8.0), row(QUARTER_REFERENCE, 40.0), row("method hemisphere", 24.0), row("method sh9-ggx", 32.0)];
        let back = read_csv(&csv(&rows)).unwrap();
        assert_eq!(back.len(), 4);
        assert_eq!(back[1].path, QUARTER_REFERENCE, "a path with a comma");
        assert!(back[0].shadow_gpu_ms.is_nan() && back[3].shadow_drawn == 0.5 && back[3].vertex_sun_ran == 0.25);
        // Floor 8 ms: hemisphere 24 ms is 3x, sh9-ggx 32 ms 4x; other rows are not methods.
        let costs = method_costs(&back);
        let expect = |m: &str, ms: f64, ratio: f64| MethodCost { method: m.into(), gpu_ms: ms, floor_ratio: ratio };
        assert_eq!(costs, vec![expect("hemisphere", 24.0, 3.0), expect("sh9-ggx", 32.0, 4.0)]);
        // A file of another shape is an error naming the problem.
        let err = read_csv("path,gpu_ms\nx,1\n").unwrap_err().to_string();
        assert!(err.contains("header"), "{err}");
        let bad = csv(&rows).replace("24,", "x,");
        let err = read_csv(&bad).unwrap_err().to_string();
        assert!(err.contains("line 4"), "{err}");
    }

    /// The walking camera keeps its distance to the model's base and its view of it (the base in
    /// the same place in the camera's frame), and moves 2 % of that distance a frame (the chord
    /// of the turn: 2 r sin(θ/2) for the turn θ about the vertical at horizontal radius r); the
    /// other motions leave the camera's position alone.
    #[test]
    fn the_walking_camera_circles_the_model_at_its_distance() {
        use crate::render::{Camera, Lighting, Placement};
        use glam::{Quat, Vec3};
        let p = FrameParams {
            // 5 m from the base, 4 m out from the vertical through it.
            camera: Camera { pose: Quat::from_rotation_x(0.9), position: Vec3::new(1.0, -2.0, 3.0), vfov: 1.0 },
            method: LightingMethod::Sh9Ggx,
            lighting: Lighting {
                sun_dir: Vec3::new(0.6, 0.0, 0.8),
                sunlight: 1.0,
                daylight: 0.3,
                material: crate::render::MaterialTerms { ambient: 1.0, diffuse: 1.0, specular: 0.0, gloss: None },
                reflection: 0.0,
                ior: 1.5,
                shadow_opacity: 1.0,
                sky_occlusion: 1.0,
                live_depth: 2.0,
                sky_sh: [[0.0; 3]; 9],
                sky_radiance: crate::light::sh9::SkyRadiance::UNIFORM,
                ground_radiance: [0.2; 3],
                sun_colour: [1.0; 3],
                sun_angular_radius: 0.005,
            },
            placement: Placement { position: Vec3::new(1.0, 2.0, 0.0), rotation: Vec3::ZERO, scale: 1.0 },
            colour: ColourSettings::NONE,
        };
        let seen = |q: &FrameParams| q.camera.pose.inverse() * (q.placement.position - q.camera.position);
        for i in [1usize, 2, 7] {
            let q = Motion::CameraWalking.frame(&p, i);
            assert!(((q.camera.position - q.placement.position).length() - 5.0).abs() < 1e-5);
            assert!((seen(&q) - seen(&Motion::Still.frame(&p, i))).length() < 1e-5, "frame {i}");
            let theta = 0.02 * 5.0 / 4.0 * i as f32;
            let chord = 2.0 * 4.0 * (theta / 2.0).sin();
            assert!(((q.camera.position - p.camera.position).length() - chord).abs() < 1e-5, "frame {i}");
        }
        // One frame: 0.02 of 5 m, to a tenth of a millimetre (the chord is a hair short of the arc).
        let step = (Motion::CameraWalking.frame(&p, 1).camera.position - Motion::CameraWalking.frame(&p, 0).camera.position).length();
        assert!((step - 0.1).abs() < 1e-4, "{step}");
        for m in [Motion::Still, Motion::SunTurning] {
            assert_eq!(m.frame(&p, 5).camera.position, p.camera.position);
        }
        assert_ne!(Motion::SunTurning.frame(&p, 5).lighting.sun_dir, p.lighting.sun_dir);
    }

    #[test]
    fn goals_are_ratios_to_the_floor() {
        let row = |path: &str, gpu_ms: f64, flip: f64| FrameRow {
            path: path.into(),
            frames: 1,
            cpu_encode_ms: 0.0,
            gpu_ms,
            shadow_gpu_ms: f64::NAN,
            shadow_drawn: 0.0,
            vertex_sun_ran: 0.0,
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
