//! `previz bench accuracy`: previz against path-traced references.
//!
//! The reference renderer (tests/reference/render_reference.py, Mitsuba 3) does not re-derive
//! previz's conventions: [`export_reference_scene`] writes the scene exactly as previz will draw
//! it — the placed model's triangles in world (ENU) coordinates, the camera's eye/target/up,
//! the field of view, the environment file with its heading and exposure, the ground height —
//! and the reference reads that.

use crate::render::view;
use crate::setup::scene_file::Scene;
use crate::setup::{Inputs, camera_and_placement, exposure};
use anyhow::{Context, Result, anyhow, bail};
use glam::{Mat3, Vec3};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// One mesh of the exported scene.
#[derive(Clone, Debug, Serialize)]
pub struct ExportedMesh {
    /// PLY file (binary little-endian; x y z nx ny nz u v per vertex, world coordinates).
    pub ply: String,
    /// Diffuse albedo, linear RGB (multiplies the texture).
    pub albedo: [f32; 3],
    /// sRGB-encoded PNG texture (v = 0 is the image's top row, as previz samples it).
    pub texture: Option<String>,
}

/// What the reference renderer needs to draw a scene as previz does (frame.json).
#[derive(Clone, Debug, Serialize)]
pub struct ExportedFrame {
    pub width: u32,
    pub height: u32,
    /// Vertical field of view, degrees.
    pub vfov_deg: f32,
    /// Camera position, the point it looks at (one metre ahead) and its up vector, ENU.
    pub eye: [f32; 3],
    pub target: [f32; 3],
    pub up: [f32; 3],
    /// Environment file (equirectangular .hdr/.exr) and the azimuth (degrees clockwise from
    /// North) its centre column faces.
    pub environment: String,
    pub env_heading_deg: f32,
    /// Linear scale applied to all radiance before sRGB encoding.
    pub exposure: f32,
    /// Height (ENU z) of the ground plane the model stands on.
    pub ground_z: f32,
    /// Radius of the model's bounding sphere in the world, metres.
    pub model_radius: f32,
    pub meshes: Vec<ExportedMesh>,
}

/// Write `frame.json`, one PLY per mesh and the textures into `dir` (created if missing).
/// The environment must be an equirectangular file (Mitsuba's `envmap` needs one).
pub fn export_reference_scene(scene: &Scene, inputs: &Inputs, dir: &Path) -> Result<ExportedFrame> {
    let env_path =
        scene.environment.as_ref().ok_or_else(|| anyhow!("the reference needs an environment file (the scene has the demo's)"))?;
    if env_path.is_dir() {
        bail!("{}: the reference renderer needs an equirectangular .hdr/.exr, not a cube-face folder", env_path.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let bounds = inputs.model.bounds().ok_or_else(|| anyhow!("the model has no vertices"))?;
    let (cam, placement) = camera_and_placement(scene, bounds);
    let model = view::model_matrix(bounds, &placement);
    let normal = Mat3::from_mat4(model).inverse().transpose();
    let mut meshes = Vec::new();
    for (i, mesh) in inputs.model.meshes.iter().enumerate() {
        let material = inputs.model.materials.get(mesh.material).cloned().unwrap_or_default();
        let ply = format!("mesh_{i}.ply");
        let positions: Vec<Vec3> = mesh.positions.iter().map(|p| model.transform_point3(Vec3::from(*p))).collect();
        let normals: Vec<Vec3> = mesh.normals.iter().map(|n| (normal * Vec3::from(*n)).normalize_or_zero()).collect();
        write_ply(&dir.join(&ply), &positions, &normals, &mesh.uvs, &mesh.indices)?;
        let texture = match &material.texture {
            Some(t) => {
                let name = format!("texture_{i}.png");
                crate::output::write_png_rgba8(&dir.join(&name), t.width, t.height, &t.pixels)?;
                Some(name)
            }
            None => None,
        };
        meshes.push(ExportedMesh { ply, albedo: material.diffuse, texture });
    }
    let forward = cam.pose * -Vec3::Z;
    let radius = 0.5 * (bounds.1 - bounds.0).length() * placement.scale;
    let frame = ExportedFrame {
        width: scene.width,
        height: scene.height,
        vfov_deg: cam.vfov.to_degrees(),
        eye: cam.position.to_array(),
        target: (cam.position + forward).to_array(),
        up: (cam.pose * Vec3::Y).to_array(),
        environment: std::path::absolute(env_path).unwrap_or_else(|_| PathBuf::from(env_path)).display().to_string(),
        env_heading_deg: scene.env.heading as f32,
        exposure: exposure(scene, &inputs.env),
        ground_z: placement.position.z,
        model_radius: radius,
        meshes,
    };
    let json = serde_json::to_string_pretty(&frame)?;
    std::fs::write(dir.join("frame.json"), json).with_context(|| format!("cannot write {}", dir.join("frame.json").display()))?;
    Ok(frame)
}

/// Binary little-endian PLY with float x y z nx ny nz u v and int triangle lists.
fn write_ply(path: &Path, positions: &[Vec3], normals: &[Vec3], uvs: &[[f32; 2]], indices: &[u32]) -> Result<()> {
    let n = positions.len();
    let mut out = Vec::with_capacity(n * 32 + indices.len() * 5);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        indices.len() / 3
    )?;
    for (i, p) in positions.iter().enumerate() {
        let nrm = normals.get(i).copied().unwrap_or(Vec3::Z);
        let uv = uvs.get(i).copied().unwrap_or([0.0; 2]);
        for v in [p.x, p.y, p.z, nrm.x, nrm.y, nrm.z, uv[0], uv[1]] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in indices.chunks_exact(3) {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    std::fs::write(path, out).with_context(|| format!("cannot write {}", path.display()))
}

/// One lighting method (or the path tracer at a sample count) on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct AccuracyRow {
    pub scene: String,
    pub method: String,
    /// Mean FLIP against the reference over the whole frame and over the region of interest
    /// (the model plus its shadow).
    pub flip_frame: f32,
    pub flip_roi: f32,
    /// Mean linear luminance over the reference's model pixels, this image / the reference.
    pub model_luminance_ratio: f32,
    /// Time per frame, ms, measured alike on both sides: previz, the median GPU time (timestamp
    /// queries, first pass to last) of [`MEASURED_FRAMES`] frames after [`WARM_UP_FRAMES`], as
    /// `previz bench frame` measures a frame; the path tracer, its lit renders per frame with its
    /// start-up excluded ([`score_ladder`]).
    pub ms: f64,
    /// previz's wall clock per image including submit and readback, ms: the median over the same
    /// frames (None for the path tracer). Shown beside [`AccuracyRow::ms`], never used for the
    /// equal-error ratio: what a still costs a caller, not what a frame costs the GPU.
    pub wall_ms: Option<f64>,
    /// The method's frame cost as a ratio of the background-only floor, measured by `previz
    /// bench frame` (bench::frame::MethodCost, GPU time, default scene and frame; issue 11's
    /// measure of cost); None for the path tracer and for a method the costs do not list.
    pub floor_ratio: Option<f64>,
}

/// Give each row its method's frame cost over the floor ([`AccuracyRow::floor_ratio`]) from
/// `costs` (`bench::frame::method_costs` of a `previz bench frame` run). Returns the names of the
/// previz methods the costs do not list.
pub fn attach_costs(rows: &mut [AccuracyRow], costs: &[crate::bench::frame::MethodCost]) -> Vec<String> {
    let mut missing = Vec::new();
    for r in rows.iter_mut() {
        // A frame draws one sample a pixel whatever a still's supersampling: the method's cost.
        r.floor_ratio = costs.iter().find(|c| c.method == base_method(&r.method)).map(|c| c.floor_ratio);
        if r.floor_ratio.is_none() && !r.method.starts_with("path tracer") && !missing.contains(&r.method) {
            missing.push(r.method.clone());
        }
    }
    missing
}

/// Rows as CSV (docs/accuracy.csv); `wall_ms` and `floor_ratio` are empty where there is none.
pub fn csv(rows: &[AccuracyRow]) -> String {
    let mut s = String::from("scene,method,flip_frame,flip_roi,model_luminance_ratio,ms,wall_ms,floor_ratio\n");
    for r in rows {
        let wall = r.wall_ms.map_or(String::new(), |v| v.to_string());
        let ratio = r.floor_ratio.map_or(String::new(), |v| v.to_string());
        s += &format!("{},{},{},{},{},{},{wall},{ratio}\n", r.scene, r.method, r.flip_frame, r.flip_roi, r.model_luminance_ratio, r.ms);
    }
    s
}

/// A reference: the composite (RGB8) with its region of interest and model mask.
pub struct Reference {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
    pub roi: Vec<bool>,
    pub model: Vec<bool>,
}

fn read_rgb8(path: &Path) -> Result<image::RgbImage> {
    Ok(image::open(path).with_context(|| format!("cannot read reference image {}", path.display()))?.to_rgb8())
}

fn read_mask(path: &Path, w: u32, h: u32) -> Result<Vec<bool>> {
    let m = image::open(path).with_context(|| format!("cannot read mask {}", path.display()))?.to_luma8();
    if (m.width(), m.height()) != (w, h) {
        bail!("{} is {}x{}, the reference is {w}x{h}", path.display(), m.width(), m.height());
    }
    Ok(m.pixels().map(|p| p.0[0] > 127).collect())
}

/// Load `NAME.png` with `NAME_roi.png` and `NAME_alpha.png` from `dir`.
pub fn load_reference(dir: &Path, name: &str) -> Result<Reference> {
    let img = read_rgb8(&dir.join(format!("{name}.png")))?;
    let (w, h) = img.dimensions();
    Ok(Reference {
        width: w,
        height: h,
        rgb: img.into_raw(),
        roi: read_mask(&dir.join(format!("{name}_roi.png")), w, h)?,
        model: read_mask(&dir.join(format!("{name}_alpha.png")), w, h)?,
    })
}

/// Per-pixel FLIP error of `test` against `reference` (RGB8, default 67 pixels per degree);
/// None where FLIP is not linked (mobile builds).
pub fn flip_map(reference: &[u8], test: &[u8], width: u32, height: u32) -> Option<Vec<f32>> {
    #[cfg(not(any(target_os = "android", target_os = "ios")))]
    {
        let error = nv_flip::flip(
            nv_flip::FlipImageRgb8::with_data(width, height, reference),
            nv_flip::FlipImageRgb8::with_data(width, height, test),
            nv_flip::DEFAULT_PIXELS_PER_DEGREE,
        );
        Some(error.to_vec())
    }
    #[cfg(any(target_os = "android", target_os = "ios"))]
    {
        let _ = (reference, test, width, height);
        None
    }
}

/// Mean of `values` where `mask` is set (NaN for an empty mask).
pub fn masked_mean(values: &[f32], mask: &[bool]) -> f32 {
    let (sum, n) = values.iter().zip(mask).filter(|(_, m)| **m).fold((0.0f64, 0usize), |(s, n), (v, _)| (s + f64::from(*v), n + 1));
    if n == 0 { f32::NAN } else { (sum / n as f64) as f32 }
}

/// Mean linear (sRGB-decoded) BT.709 luminance of RGB8 pixels where `mask` is set.
pub fn masked_luminance(rgb: &[u8], mask: &[bool]) -> f32 {
    let lum: Vec<f32> = rgb
        .chunks_exact(3)
        .map(|p| crate::colour::luminance_bt709([0, 1, 2].map(|k| crate::colour::srgb_to_linear(f32::from(p[k]) / 255.0))))
        .collect();
    masked_mean(&lum, mask)
}

/// Compare one RGB8 image with a reference.
pub fn score(reference: &Reference, test: &[u8]) -> Result<(f32, f32, f32)> {
    if test.len() != reference.rgb.len() {
        bail!("image is {} bytes, the reference {}x{} RGB is {}", test.len(), reference.width, reference.height, reference.rgb.len());
    }
    let map = flip_map(&reference.rgb, test, reference.width, reference.height)
        .ok_or_else(|| anyhow!("FLIP is not available on this platform"))?;
    let all = vec![true; map.len()];
    let lum_ratio = masked_luminance(test, &reference.model) / masked_luminance(&reference.rgb, &reference.model);
    Ok((masked_mean(&map, &all), masked_mean(&map, &reference.roi), lum_ratio))
}

/// Where a method's error in the region of interest comes from (docs/accuracy.md "Error
/// budget"): the model's pixels against its shadow's, and inside the model the sunlit side
/// against the side the sun does not reach.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorBudget {
    pub scene: String,
    pub method: String,
    /// Mean FLIP over the region of interest (the model plus its shadow).
    pub flip_roi: f32,
    /// Share of the region's pixels covered by the model (the rest is its shadow on the ground):
    /// flip_roi = model_share · flip_model + (1 − model_share) · flip_shadow.
    pub model_share: f32,
    pub flip_model: f32,
    pub flip_shadow: f32,
    /// Share of the model's pixels on its sunlit side: where the method's sun gives at least half
    /// of the pixel's light (the same frame without sunlight is at most half as bright).
    pub lit_share: f32,
    /// Mean linear luminance, this image / the reference, over the sunlit and the shaded side
    /// (NaN when a side has no pixels).
    pub luminance_lit: f32,
    pub luminance_shaded: f32,
    /// Mean linear R, G, B over the shadow region, this image / the reference.
    pub shadow_rgb: [f32; 3],
    /// Mean FLIP over the [`RING`] pixels around the region of interest ([`ring_around`]): the
    /// ground next to the shadow, which the model neither covers nor darkens by 5 % in the
    /// reference, where the two images differ by little but the background's resampling — the
    /// floor under [`ErrorBudget::flip_shadow`].
    pub flip_ring: f32,
}

/// Width in pixels of the ring around the region of interest that [`ErrorBudget::flip_ring`]
/// averages over.
pub const RING: usize = 8;

/// The pixels within `r` pixels (Chebyshev distance) of a pixel of `mask` (`w` × `h`, row-major)
/// that are not in it.
pub fn ring_around(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let near = |x: usize, y: usize| {
        let (x0, x1, y0, y1) = (x.saturating_sub(r), (x + r).min(w - 1), y.saturating_sub(r), (y + r).min(h - 1));
        (y0..=y1).any(|yy| mask[yy * w + x0..=yy * w + x1].iter().any(|&m| m))
    };
    (0..w * h).map(|i| !mask[i] && near(i % w, i / w)).collect()
}

/// Linear (sRGB-decoded) RGB of RGB8 pixels.
fn linear_rgb(rgb: &[u8]) -> Vec<[f32; 3]> {
    rgb.chunks_exact(3).map(|p| [0, 1, 2].map(|k| crate::colour::srgb_to_linear(f32::from(p[k]) / 255.0))).collect()
}

/// Mean of each channel where `mask` is set.
fn masked_rgb(rgb: &[[f32; 3]], mask: &[bool]) -> [f32; 3] {
    std::array::from_fn(|c| masked_mean(&rgb.iter().map(|p| p[c]).collect::<Vec<f32>>(), mask))
}

/// The error budget of `test` (RGB8) against `reference`; `without_sun` is the same frame drawn
/// with the sunlight multiplier at 0, which tells the sunlit side of the model from the shaded.
pub fn error_budget(reference: &Reference, test: &[u8], without_sun: &[u8]) -> Result<ErrorBudget> {
    if test.len() != reference.rgb.len() || without_sun.len() != reference.rgb.len() {
        bail!(
            "images are {} and {} bytes, the reference {}x{} RGB is {}",
            test.len(),
            without_sun.len(),
            reference.width,
            reference.height,
            reference.rgb.len()
        );
    }
    let map = flip_map(&reference.rgb, test, reference.width, reference.height)
        .ok_or_else(|| anyhow!("FLIP is not available on this platform"))?;
    let (ours, theirs, sky) = (linear_rgb(test), linear_rgb(&reference.rgb), linear_rgb(without_sun));
    let lum = |p: &[f32; 3]| crate::colour::luminance_bt709(*p);
    let shadow: Vec<bool> = reference.roi.iter().zip(&reference.model).map(|(r, m)| *r && !*m).collect();
    let lit: Vec<bool> = (0..ours.len()).map(|i| reference.model[i] && lum(&ours[i]) > 2.0 * lum(&sky[i])).collect();
    let shaded: Vec<bool> = reference.model.iter().zip(&lit).map(|(m, l)| *m && !*l).collect();
    let count = |m: &[bool]| m.iter().filter(|v| **v).count() as f32;
    let ratio = |mask: &[bool]| {
        let a: Vec<f32> = ours.iter().map(lum).collect();
        let b: Vec<f32> = theirs.iter().map(lum).collect();
        masked_mean(&a, mask) / masked_mean(&b, mask)
    };
    let (a, b) = (masked_rgb(&ours, &shadow), masked_rgb(&theirs, &shadow));
    Ok(ErrorBudget {
        scene: String::new(),
        method: String::new(),
        flip_roi: masked_mean(&map, &reference.roi),
        model_share: count(&reference.model) / count(&reference.roi),
        flip_model: masked_mean(&map, &reference.model),
        flip_shadow: masked_mean(&map, &shadow),
        lit_share: count(&lit) / count(&reference.model),
        luminance_lit: ratio(&lit),
        luminance_shaded: ratio(&shaded),
        shadow_rgb: std::array::from_fn(|c| a[c] / b[c]),
        flip_ring: masked_mean(&map, &ring_around(&reference.roi, reference.width as usize, reference.height as usize, RING)),
    })
}

/// RGB8 of a frame of `scene` drawn as a still composite.
fn render_rgb(gpu: &crate::gpu::Gpu, scene: &Scene, inputs: &Inputs) -> Result<Vec<u8>> {
    let (mut compositor, params) = crate::setup::prepare(gpu, scene, inputs)?;
    let r = compositor.render(gpu, &params, crate::render::Layer::Composite)?;
    Ok(r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect())
}

/// The error budget of the scene's own method (`auto` resolves as `previz composite` does).
pub fn budget_of_scene(gpu: &crate::gpu::Gpu, name: &str, scene: &Scene, inputs: &Inputs, reference: &Reference) -> Result<ErrorBudget> {
    let test = render_rgb(gpu, scene, inputs)?;
    let mut dark = scene.clone();
    dark.sun.sunlight = 0.0;
    let without_sun = render_rgb(gpu, &dark, inputs)?;
    let mut b = error_budget(reference, &test, &without_sun)?;
    b.scene = name.into();
    b.method = scene.method.method_or_ordinary().name().into();
    Ok(b)
}

/// Markdown table of error budgets.
pub fn budget_markdown(budgets: &[ErrorBudget]) -> String {
    let mut s = String::from(
        "| scene | method | FLIP ROI | model share of ROI | FLIP model | FLIP shadow | FLIP around the ROI (background floor) | lit share of model | luminance lit / ref | luminance shaded / ref | shadow R, G, B / ref |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for b in budgets {
        s += &format!(
            "| {} | {} | {:.3} | {:.2} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2}, {:.2}, {:.2} |\n",
            b.scene,
            b.method,
            b.flip_roi,
            b.model_share,
            b.flip_model,
            b.flip_shadow,
            b.flip_ring,
            b.lit_share,
            b.luminance_lit,
            b.luminance_shaded,
            b.shadow_rgb[0],
            b.shadow_rgb[1],
            b.shadow_rgb[2]
        );
    }
    s
}

/// Frames rendered and not measured before [`MEASURED_FRAMES`] (pipelines, the shadow map, the
/// ground's sky map and lavapipe's shader compilation settle in the first).
pub const WARM_UP_FRAMES: usize = 3;
/// Frames whose GPU time and wall clock give each method's medians ([`AccuracyRow::ms`]).
pub const MEASURED_FRAMES: usize = 15;

/// Render every lighting method for `scene` and score each against `reference`; each method's
/// time is the median over [`MEASURED_FRAMES`] frames after [`WARM_UP_FRAMES`]. Errors: an
/// adapter without timestamp queries (the GPU time is what the comparison needs).
pub fn score_methods(gpu: &crate::gpu::Gpu, name: &str, scene: &Scene, inputs: &Inputs, reference: &Reference) -> Result<Vec<AccuracyRow>> {
    if (scene.width, scene.height) != (reference.width, reference.height) {
        bail!("scene {name} renders {}x{} but its reference is {}x{}", scene.width, scene.height, reference.width, reference.height);
    }
    let mut rows = Vec::new();
    let still = crate::render::supersample::STILL_FACTOR;
    // Every method as a still draws it, then the default one with fewer samples a pixel: what
    // supersampling buys (render::supersample).
    let fewer = (1..still).map(|k| (crate::setup::method_choice::ORDINARY, k));
    for (method, k) in crate::render::LightingMethod::ALL.into_iter().map(|m| (m, still)).chain(fewer) {
        let mut s = scene.clone();
        s.method = crate::setup::method_choice::MethodRequest::Fixed(method);
        let (mut compositor, params) = crate::setup::prepare_supersampled(gpu, &s, inputs, k)?;
        let (mut gpu_ms, mut wall_ms, mut image) = (Vec::new(), Vec::new(), None);
        for i in 0..WARM_UP_FRAMES + MEASURED_FRAMES {
            let t = std::time::Instant::now();
            let r = compositor.render(gpu, &params, crate::render::Layer::Composite)?;
            let wall = t.elapsed().as_secs_f64() * 1e3;
            if i >= WARM_UP_FRAMES {
                let g = r
                    .timings
                    .gpu_ms
                    .ok_or_else(|| anyhow!("{} has no timestamp queries: bench accuracy times each frame on the GPU", gpu.describe()))?;
                gpu_ms.push(g);
                wall_ms.push(wall);
            }
            image = Some(r);
        }
        let r = image.ok_or_else(|| anyhow!("no frame rendered"))?;
        let rgb: Vec<u8> = r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        let (flip_frame, flip_roi, model_luminance_ratio) = score(reference, &rgb)?;
        rows.push(AccuracyRow {
            scene: name.into(),
            method: supersampled_name(method.name(), k, still),
            flip_frame,
            flip_roi,
            model_luminance_ratio,
            ms: super::median(&gpu_ms),
            wall_ms: Some(super::median(&wall_ms)),
            floor_ratio: None,
        });
    }
    Ok(rows)
}

/// A row's method name: the method's own at a still's supersampling (`still` samples a side),
/// else followed by its samples, "sh9-ggx 1x1".
pub fn supersampled_name(method: &str, k: u32, still: u32) -> String {
    if k == still { method.to_string() } else { format!("{method} {k}x{k}") }
}

/// The method a row's name (as [`supersampled_name`] writes it) is drawn with.
fn base_method(name: &str) -> &str {
    name.split(' ').next().unwrap_or(name)
}

/// Score the path tracer's own ladder: `NAME_sppN.png` (with `NAME_sppN.json` holding
/// `frame_seconds`: render_reference.py `--time-frame`, the lit renders' time per frame without
/// Mitsuba's start-up) in `dir` for every N found, against the high-sample reference.
pub fn score_ladder(dir: &Path, name: &str, reference: &Reference) -> Result<Vec<AccuracyRow>> {
    let mut rows = Vec::new();
    for spp in [1u32, 4, 16, 64] {
        let png = dir.join(format!("{name}_spp{spp}.png"));
        if !png.exists() {
            continue;
        }
        let json = dir.join(format!("{name}_spp{spp}.json"));
        let text = std::fs::read_to_string(&json).with_context(|| format!("cannot read {}", json.display()))?;
        let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{} is not JSON", json.display()))?;
        let seconds = v["frame_seconds"]
            .as_f64()
            .ok_or_else(|| anyhow!("{}: no \"frame_seconds\" (render it with render_reference.py --time-frame)", json.display()))?;
        let (flip_frame, flip_roi, model_luminance_ratio) = score(reference, read_rgb8(&png)?.as_raw())?;
        rows.push(AccuracyRow {
            scene: name.into(),
            method: format!("path tracer {spp} spp"),
            flip_frame,
            flip_roi,
            model_luminance_ratio,
            ms: seconds * 1e3,
            wall_ms: None,
            floor_ratio: None,
        });
    }
    Ok(rows)
}

/// Markdown table of rows.
pub fn markdown(rows: &[AccuracyRow]) -> String {
    let mut s = String::from(
        "| scene | method | FLIP frame | FLIP ROI | model luminance / ref | ms per frame (previz: GPU) | wall ms per image incl. readback | frame cost × floor |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let wall = r.wall_ms.map_or(String::new(), |v| format!("{v:.1}"));
        let ratio = r.floor_ratio.map_or(String::new(), |v| format!("{v:.1}"));
        s += &format!(
            "| {} | {} | {:.3} | {:.3} | {:.2} | {:.2} | {wall} | {ratio} |\n",
            r.scene, r.method, r.flip_frame, r.flip_roi, r.model_luminance_ratio, r.ms
        );
    }
    s
}

/// Chart size, pixels: two panels side by side.
const CHART_W: u32 = 1800;
const CHART_H: u32 = 760;

/// One method's means over the scenes.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodMean {
    pub method: String,
    /// Mean time per frame, ms ([`AccuracyRow::ms`]).
    pub ms: f64,
    /// Mean wall clock per image including readback, ms (None for the path tracer).
    pub wall_ms: Option<f64>,
    /// Mean FLIP in the region of interest.
    pub flip_roi: f64,
    /// The method's frame cost over the floor (the same on every scene: one `bench frame` run).
    pub floor_ratio: Option<f64>,
}

/// Mean over scenes of time, FLIP ROI and cost per method, in the order methods first appear.
pub fn per_method_means(rows: &[AccuracyRow]) -> Vec<MethodMean> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.method.as_str()) {
            names.push(&r.method);
        }
    }
    names
        .iter()
        .map(|n| {
            let sel: Vec<&AccuracyRow> = rows.iter().filter(|r| r.method == *n).collect();
            let k = sel.len() as f64;
            MethodMean {
                method: n.to_string(),
                ms: sel.iter().map(|r| r.ms).sum::<f64>() / k,
                wall_ms: sel.iter().map(|r| r.wall_ms).sum::<Option<f64>>().map(|t| t / k),
                flip_roi: sel.iter().map(|r| f64::from(r.flip_roi)).sum::<f64>() / k,
                floor_ratio: sel.iter().find_map(|r| r.floor_ratio),
            }
        })
        .collect()
}

/// Error against cost, two panels sharing the error axis (mean FLIP in the model + shadow, log;
/// means over the scenes; the goal 0.06 dashed): left, against the time per frame (ms,
/// log; [`AccuracyRow::ms`]: previz's GPU time, the path tracer's per frame), one point per
/// previz method, the path tracer's ladder as a line, the default method's ratio to it at equal
/// error and, hollow, the default method's wall clock including readback; right, against
/// each previz method's frame cost as a ratio of the background-only floor
/// ([`AccuracyRow::floor_ratio`], `previz bench frame`), where the rows carry one. RGB8.
pub fn chart(rows: &[AccuracyRow]) -> Result<Vec<u8>> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| anyhow!("drawing the accuracy chart: {e}");
    crate::chart::register_font();
    let means = per_method_means(rows);
    if means.is_empty() {
        bail!("no rows to chart");
    }
    // The default method against the path tracer's mean curve at its mean error, and where the
    // issue's 1000x would put it.
    let ladder: Vec<super::equal_error::Rung> = means
        .iter()
        .filter_map(|m| Some(super::equal_error::Rung { spp: super::equal_error::spp_of(&m.method)?, flip_roi: m.flip_roi, ms: m.ms }))
        .collect();
    let default = crate::setup::method_choice::ORDINARY.name();
    let equal =
        means.iter().find(|m| m.method == default).and_then(|d| Some((d, super::equal_error::at_equal_error(&ladder, d.flip_roi)?)));
    let goal_ms = equal.map(|(_, at)| at.tracer_ms / 1000.0);
    let x_min = means.iter().map(|m| m.ms).chain(goal_ms).fold(f64::INFINITY, f64::min).max(1e-3) / 2.0;
    let x_max = means.iter().map(|m| m.ms).fold(0.0, f64::max) * 2.0;
    // Far enough below the lowest point that the legend, in the lower left, sits under the
    // points (at / 1.5 it covered the default method's point once its error fell to 0.076; at
    // / 3 the supersampling rows' points at 0.06, fourteenth session).
    let y_min = means.iter().map(|m| m.flip_roi).fold(0.06, f64::min) / 12.0;
    let y_max = means.iter().map(|m| m.flip_roi).fold(0.0, f64::max) * 1.5;
    let is_tracer = |m: &MethodMean| m.method.starts_with("path tracer");
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
        RGBColor(188, 189, 34),
        RGBColor(128, 0, 0),
        RGBColor(0, 0, 128),
    ];
    let methods: Vec<(&MethodMean, RGBColor)> =
        means.iter().filter(|m| !is_tracer(m)).enumerate().map(|(i, m)| (m, palette[i % palette.len()])).collect();
    let goal = RGBColor(44, 160, 44);
    let black = RGBColor(0, 0, 0);
    let mut buf = vec![0u8; (CHART_W * CHART_H * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (CHART_W, CHART_H)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let root = root.titled("Lighting accuracy vs cost (mean over the reference scenes)", ("sans-serif", 26)).map_err(|e| err(&e))?;
        let (left, right) = root.split_horizontally(CHART_W * 55 / 100);
        let mut c = ChartBuilder::on(&left)
            .caption(
                "against time per frame (previz: GPU timestamps, median; path tracer: per frame, start-up excluded)",
                ("sans-serif", 18),
            )
            .margin(20)
            .x_label_area_size(60)
            .y_label_area_size(80)
            .build_cartesian_2d((x_min..x_max).log_scale(), (y_min..y_max).log_scale())
            .map_err(|e| err(&e))?;
        c.configure_mesh()
            .x_desc("time per frame, ms (log scale)")
            .y_desc("mean FLIP in model + shadow (log scale)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            // Decades below 1 ms keep their digits (0.1, 0.01): "{:.0}" printed 0.1 as "0".
            .x_label_formatter(&|x| if *x >= 1.0 { format!("{x:.0}") } else { format!("{:.*}", (-x.log10()).ceil() as usize, x) })
            .y_label_formatter(&|y| format!("{y:.2}"))
            .draw()
            .map_err(|e| err(&e))?;
        c.draw_series(DashedLineSeries::new(vec![(x_min, 0.06), (x_max, 0.06)], 8, 6, goal.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label("goal: FLIP 0.06")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], goal.stroke_width(2)));
        let tracer: Vec<(f64, f64)> = means.iter().filter(|m| is_tracer(m)).map(|m| (m.ms, m.flip_roi)).collect();
        c.draw_series(LineSeries::new(tracer.clone(), black.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label("path tracer 1/4/16/64 spp vs 256 spp")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], black.stroke_width(2)));
        c.draw_series(tracer.iter().map(|p| Circle::new(*p, 5, black.filled()))).map_err(|e| err(&e))?;
        if let Some((d, at)) = equal {
            let grey = RGBColor(110, 110, 110);
            c.draw_series(DashedLineSeries::new(vec![(d.ms, d.flip_roi), (at.tracer_ms, d.flip_roi)], 4, 4, grey.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(format!("{default} vs path tracer at equal error: {:.0}x ({:.1} spp)", at.tracer_ms / d.ms, at.spp))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], grey.stroke_width(2)));
            if let Some(wall) = d.wall_ms {
                c.draw_series(std::iter::once(TriangleMarker::new((wall, d.flip_roi), 9, grey.stroke_width(2))))
                    .map_err(|e| err(&e))?
                    .label(format!("{default}, wall clock per image incl. readback: {:.0}x", at.tracer_ms / wall))
                    .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 7, grey.stroke_width(2)));
            }
            let goal_x = at.tracer_ms / 1000.0;
            c.draw_series(DashedLineSeries::new(vec![(goal_x, d.flip_roi), (d.ms, d.flip_roi)], 2, 4, goal.stroke_width(2)))
                .map_err(|e| err(&e))?;
            c.draw_series(std::iter::once(Cross::new((goal_x, d.flip_roi), 7, goal.stroke_width(3))))
                .map_err(|e| err(&e))?
                .label(format!("goal: 1000x the path tracer at {default}'s error = {goal_x:.2} ms per frame"))
                .legend(move |(x, y)| Cross::new((x + 9, y), 6, goal.stroke_width(3)));
        }
        for (m, col) in &methods {
            let col = *col;
            c.draw_series(std::iter::once(TriangleMarker::new((m.ms, m.flip_roi), 9, col.filled())))
                .map_err(|e| err(&e))?
                .label(m.method.clone())
                .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 7, col.filled()));
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;

        let costed: Vec<(&MethodMean, RGBColor, f64)> =
            methods.iter().filter_map(|(m, col)| m.floor_ratio.map(|r| (*m, *col, r))).collect();
        let c_max = costed.iter().map(|c| c.2).fold(1.0, f64::max) * 1.2;
        let mut c = ChartBuilder::on(&right)
            .caption("against frame cost (GPU, × the background-only frame; previz bench frame)", ("sans-serif", 18))
            .margin(20)
            .x_label_area_size(60)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..c_max, (y_min..y_max).log_scale())
            .map_err(|e| err(&e))?;
        c.configure_mesh()
            .x_desc("frame cost, × the background-only floor")
            .y_desc("mean FLIP in model + shadow (log scale)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.2}"))
            .draw()
            .map_err(|e| err(&e))?;
        c.draw_series(DashedLineSeries::new(vec![(0.0, 0.06), (c_max, 0.06)], 8, 6, goal.stroke_width(2))).map_err(|e| err(&e))?;
        for (m, col, ratio) in &costed {
            let col = *col;
            c.draw_series(std::iter::once(TriangleMarker::new((*ratio, m.flip_roi), 9, col.filled())))
                .map_err(|e| err(&e))?
                .label(format!("{} ({ratio:.1}x)", m.method))
                .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 7, col.filled()));
        }
        if costed.is_empty() {
            right.draw(&Text::new("no frame costs given (--costs)", (200, 380), ("sans-serif", 20).into_font())).map_err(|e| err(&e))?;
        } else {
            c.configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .label_font(("sans-serif", 16))
                .background_style(WHITE.mix(0.9))
                .border_style(BLACK)
                .draw()
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    Ok(buf)
}

/// Draw [`chart`] into a PNG.
pub fn write_chart(rows: &[AccuracyRow], path: &Path) -> Result<()> {
    let rgb = chart(rows)?;
    crate::output::write_png_rgb8(path, CHART_W, CHART_H, &rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chart_means_per_method_and_draws() {
        let row = |scene: &str, method: &str, roi: f32, ms: f64| AccuracyRow {
            scene: scene.into(),
            method: method.into(),
            flip_frame: 0.0,
            flip_roi: roi,
            model_luminance_ratio: 1.0,
            ms,
            wall_ms: (!method.starts_with("path tracer")).then_some(2.0 * ms),
            floor_ratio: None,
        };
        let mut rows = [row("a", "hemisphere", 0.2, 10.0), row("b", "hemisphere", 0.4, 30.0), row("a", "path tracer 1 spp", 0.1, 1000.0)];
        let m = per_method_means(&rows);
        assert_eq!(m.len(), 2);
        assert_eq!(m[0].method, "hemisphere");
        assert!((m[0].ms - 20.0).abs() < 1e-9 && (m[0].flip_roi - 0.3).abs() < 1e-6 && m[0].floor_ratio.is_none());
        assert_eq!((m[0].wall_ms, m[1].wall_ms), (Some(40.0), None));
        let img = chart(&rows).unwrap();
        assert_eq!(img.len(), (CHART_W * CHART_H * 3) as usize);
        // Something other than white was drawn.
        assert!(img.iter().any(|&v| v < 128));
        assert!(chart(&[]).is_err());
        // Costs from bench frame: the method's ratio on its rows, none on the path tracer's; a
        // method the costs lack is named. The right panel then draws its marker (the palette's
        // first colour, hemisphere's).
        let cost = |m: &str, r: f64| crate::bench::frame::MethodCost { method: m.into(), gpu_ms: 4.5 * r, floor_ratio: r };
        assert_eq!(attach_costs(&mut rows, &[cost("sh9-ggx", 10.8)]), vec!["hemisphere".to_string()]);
        assert_eq!(attach_costs(&mut rows, &[cost("hemisphere", 7.7), cost("sh9-ggx", 10.8)]), Vec::<String>::new());
        assert_eq!(rows.iter().map(|r| r.floor_ratio).collect::<Vec<_>>(), vec![Some(7.7), Some(7.7), None]);
        assert_eq!(per_method_means(&rows)[0].floor_ratio, Some(7.7));
        let blue = |img: &[u8], x0: u32| {
            img.chunks_exact(3).enumerate().filter(|(i, p)| (*i as u32 % CHART_W) >= x0 && p[0] < 60 && p[1] > 100 && p[2] > 160).count()
        };
        let with_costs = chart(&rows).unwrap();
        let right = CHART_W * 55 / 100;
        assert!(blue(&with_costs, right) > 20 && blue(&img, right) == 0, "{} {}", blue(&with_costs, right), blue(&img, right));
        let text = csv(&rows);
        assert!(text.starts_with("scene,method,flip_frame,flip_roi,model_luminance_ratio,ms,wall_ms,floor_ratio\n"));
        assert!(text.contains(",10,20,7.7\n") && text.ends_with(",1000,,\n"), "{text}");
    }

    #[test]
    fn error_budget_splits_model_and_shadow() {
        // 16x16: the left half is the model (its top rows sunlit), the right half's top rows its
        // shadow; the rest is background outside the region of interest.
        let (w, h) = (16u32, 16u32);
        let n = (w * h) as usize;
        let model: Vec<bool> = (0..n).map(|i| i as u32 % w < 8).collect();
        let roi: Vec<bool> = (0..n).map(|i| i as u32 % w < 8 || (i as u32 / w) < 8).collect();
        let rgb: Vec<u8> = (0..n).flat_map(|i| if model[i] { [160, 160, 160] } else { [100, 120, 140] }).collect();
        let reference = Reference { width: w, height: h, rgb: rgb.clone(), roi, model: model.clone() };
        // Identical image: no error, every ratio 1; the sky-only frame at a quarter of the light
        // on the top half makes it the sunlit side (half of the model).
        let without_sun: Vec<u8> = (0..n).flat_map(|i| if (i as u32 / w) < 8 { [40u8; 3] } else { [150u8; 3] }).collect();
        let b = error_budget(&reference, &rgb, &without_sun).unwrap();
        assert_eq!((b.flip_roi, b.flip_model, b.flip_shadow), (0.0, 0.0, 0.0));
        assert!((b.model_share - 128.0 / 192.0).abs() < 1e-6, "{}", b.model_share);
        assert!((b.lit_share - 0.5).abs() < 1e-6 && b.luminance_lit == 1.0 && b.luminance_shaded == 1.0, "{b:?}");
        assert_eq!(b.shadow_rgb, [1.0; 3]);
        // A bluer shadow: the error is the shadow's (FLIP's spatial filter spills a little over
        // the model's edge) and only the shadow's blue ratio moves.
        let test: Vec<u8> = (0..n)
            .flat_map(|i| if !model[i] && (i as u32 / w) < 8 { [100, 120, 200] } else { [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]] })
            .collect();
        let b = error_budget(&reference, &test, &without_sun).unwrap();
        assert!(b.flip_shadow > 0.05 && b.flip_model < 0.3 * b.flip_shadow, "{b:?}");
        let parts = b.model_share * b.flip_model + (1.0 - b.model_share) * b.flip_shadow;
        assert!((b.flip_roi - parts).abs() < 1e-5, "{b:?}");
        let blue = crate::colour::srgb_to_linear(200.0 / 255.0) / crate::colour::srgb_to_linear(140.0 / 255.0);
        assert!((b.shadow_rgb[2] - blue).abs() < 1e-5 && b.shadow_rgb[0] == 1.0, "{b:?}");
        assert!(error_budget(&reference, &test[3..], &without_sun).is_err());
        // The ring: the bottom-right quarter, outside the region of interest and within 8 px of
        // it; identical there above, and only there in an image whose background differs there.
        assert!(ring_around(&reference.roi, 16, 16, RING) == reference.roi.iter().map(|r| !r).collect::<Vec<_>>());
        let b = error_budget(&reference, &rgb, &without_sun).unwrap();
        assert_eq!(b.flip_ring, 0.0);
        let test: Vec<u8> =
            (0..n).flat_map(|i| if !reference.roi[i] { [60, 60, 60] } else { [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]] }).collect();
        let b = error_budget(&reference, &test, &without_sun).unwrap();
        assert!(b.flip_ring > 0.05 && b.flip_ring > 2.0 * b.flip_roi, "{b:?}");
    }

    #[test]
    fn the_ring_around_a_pixel_is_its_neighbours() {
        // One pixel in the middle of 7x7: radius 1 gives its 8 neighbours, radius 3 the rest of
        // the image; at a corner, radius 1 gives 3.
        let mut mask = vec![false; 49];
        mask[3 * 7 + 3] = true;
        let ring = ring_around(&mask, 7, 7, 1);
        assert_eq!(ring.iter().filter(|&&v| v).count(), 8);
        assert!(ring[2 * 7 + 2] && ring[4 * 7 + 4] && !ring[3 * 7 + 3] && !ring[7 + 3]);
        assert_eq!(ring_around(&mask, 7, 7, 3).iter().filter(|&&v| v).count(), 48);
        let mut corner = vec![false; 49];
        corner[0] = true;
        assert_eq!(ring_around(&corner, 7, 7, 1).iter().filter(|&&v| v).count(), 3);
    }

    #[test]
    fn masked_statistics_by_hand() {
        assert_eq!(masked_mean(&[1.0, 2.0, 3.0, 4.0], &[true, false, true, false]), 2.0);
        assert!(masked_mean(&[1.0], &[false]).is_nan());
        // sRGB 255 is linear 1, sRGB 0 is 0: luminance of white and black pixels.
        let rgb = [255, 255, 255, 0, 0, 0];
        assert!((masked_luminance(&rgb, &[true, false]) - 1.0).abs() < 1e-6);
        assert!((masked_luminance(&rgb, &[true, true]) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn flip_of_identical_images_is_zero_and_grows_with_difference() {
        let (w, h) = (32, 32);
        let a: Vec<u8> = (0..w * h * 3).map(|i| (i % 251) as u8).collect();
        let same = flip_map(&a, &a, w, h).unwrap();
        assert!(same.iter().all(|v| *v == 0.0));
        let darker: Vec<u8> = a.iter().map(|v| v / 2).collect();
        let black = vec![0u8; a.len()];
        let m1 = masked_mean(&flip_map(&a, &darker, w, h).unwrap(), &vec![true; (w * h) as usize]);
        let m2 = masked_mean(&flip_map(&a, &black, w, h).unwrap(), &vec![true; (w * h) as usize]);
        assert!(0.0 < m1 && m1 < m2, "{m1} {m2}");
    }
}
