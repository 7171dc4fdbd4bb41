//! Colour priors (seed 000 §5.1): statistics of the environment (the "source") and of the
//! model's texture (the "target") that drive colour correction.
//!
//! Environment (a [`CubeMap`], linear light, faces +X, −X, +Y, −Y, +Z, −Z):
//! - `up_mean`, `down_mean`: mean linear RGB of the +Y (sky) and −Y (ground) faces.
//! - `horizontal`: [`ColourStats`] over the four horizontal faces ±X, ±Z — BT.709 luminance
//!   (linear) min / mean / max and 1st / 99th percentiles, linear-RGB and log-lαβ mean and
//!   covariance (σ = √diagonal).
//!
//! Model: the same [`ColourStats`] over its diffuse texture(s) (sRGB-encoded texels decoded to
//! linear light; Kd is not multiplied in), counting only texels that a UV triangle of a mesh
//! using that texture touches ([`mask::mark_uv_coverage`]), and never pure green (0,255,0)
//! texels (the seed's green screen) or fully transparent texels (alpha 0). A mesh without UVs
//! contributes its whole texture (minus green/transparent). A model with no texture at all gets
//! the statistics of its materials' diffuse colours, one sample per triangle.
//!
//! Every statistic is computed from linear light (see `colour::stats`). The CPU functions here
//! are the reference; [`gpu`] computes the same numbers with compute shaders.

pub mod gpu;
pub mod mask;

use crate::colour::stats::{ColourStats, sanitize, srgb8_to_linear_table};
use crate::scene::{CubeMap, Model, Rgba8Image};
use anyhow::{Result, bail};

/// Indices of the horizontal faces (±X, ±Z) in wgpu face order.
pub const HORIZONTAL_FACES: [usize; 4] = [0, 1, 4, 5];
/// Index of the up (+Y, sky) face.
pub const UP_FACE: usize = 2;
/// Index of the down (−Y, ground) face.
pub const DOWN_FACE: usize = 3;

/// Priors of an environment.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct EnvironmentPriors {
    /// Mean linear RGB of the +Y face (sky, hemisphere lighting's upper colour).
    pub up_mean: [f64; 3],
    /// Mean linear RGB of the −Y face (ground).
    pub down_mean: [f64; 3],
    /// Statistics of the four horizontal faces.
    pub horizontal: ColourStats,
}

/// Where a model's priors came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelPriorSource {
    /// Diffuse texture texels.
    Textures,
    /// No texture: the materials' diffuse colours.
    DiffuseColours,
}

/// Texel accounting for a model's texture priors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TexelCounts {
    pub total: u64,
    pub used: u64,
    pub not_covered_by_uvs: u64,
    pub green_screen: u64,
    pub transparent: u64,
}

/// Priors of a model.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModelPriors {
    pub source: ModelPriorSource,
    pub texels: TexelCounts,
    pub stats: ColourStats,
}

/// The horizontal, up and down pixels of a cube map (sanitised; non-finite pixels dropped).
pub struct CubeRegions {
    pub horizontal: Vec<[f32; 3]>,
    pub up: Vec<[f32; 3]>,
    pub down: Vec<[f32; 3]>,
}

/// Check a cube map's shape.
pub fn check_cube(cube: &CubeMap) -> Result<()> {
    let n = cube.size as usize * cube.size as usize;
    if n == 0 {
        bail!("the cube map has size 0");
    }
    for (i, face) in cube.faces.iter().enumerate() {
        if face.len() != n {
            bail!("cube-map face {} has {} pixels, expected {}×{}", crate::scene::FACE_NAMES[i], face.len(), cube.size, cube.size);
        }
    }
    Ok(())
}

/// Split a cube map into the regions the priors use.
pub fn cube_regions(cube: &CubeMap) -> Result<CubeRegions> {
    check_cube(cube)?;
    let clean = |f: usize| cube.faces[f].iter().filter_map(|p| sanitize(*p)).collect::<Vec<_>>();
    let horizontal: Vec<[f32; 3]> = HORIZONTAL_FACES.iter().flat_map(|&f| clean(f)).collect();
    Ok(CubeRegions { horizontal, up: clean(UP_FACE), down: clean(DOWN_FACE) })
}

fn mean_rgb(px: &[[f32; 3]], face: &str) -> Result<[f64; 3]> {
    if px.is_empty() {
        bail!("the {face} face of the cube map has no finite pixels");
    }
    let mut s = [0.0f64; 3];
    for p in px {
        for c in 0..3 {
            s[c] += f64::from(p[c]);
        }
    }
    Ok(s.map(|x| x / px.len() as f64))
}

/// Environment priors, CPU reference.
pub fn environment_priors(cube: &CubeMap) -> Result<EnvironmentPriors> {
    environment_priors_scaled(cube, 1.0)
}

/// Environment priors of the cube map's radiance multiplied by `scale` (an exposure): what the
/// compositor shows and corrects towards. Computed from the scaled pixels, because the log-lαβ
/// statistics do not scale exactly (the log's offset).
pub fn environment_priors_scaled(cube: &CubeMap, scale: f32) -> Result<EnvironmentPriors> {
    if !(scale.is_finite() && scale > 0.0) {
        bail!("environment scale must be a positive number, got {scale}");
    }
    let mut r = cube_regions(cube)?;
    if scale != 1.0 {
        for p in r.horizontal.iter_mut().chain(r.up.iter_mut()).chain(r.down.iter_mut()) {
            *p = p.map(|c| c * scale);
        }
    }
    if r.horizontal.is_empty() {
        bail!("the horizontal faces of the cube map have no finite pixels");
    }
    Ok(EnvironmentPriors {
        up_mean: mean_rgb(&r.up, "+Y (up)")?,
        down_mean: mean_rgb(&r.down, "-Y (down)")?,
        horizontal: ColourStats::from_linear(&r.horizontal)?,
    })
}

/// Which texels of `texture` count, given the meshes that use it.
/// Returns the mask (row-major, true = used) and the counts.
pub fn texture_mask(texture: &Rgba8Image, meshes: &[&crate::scene::Mesh]) -> Result<(Vec<bool>, TexelCounts)> {
    let (w, h) = (texture.width, texture.height);
    let n = w as usize * h as usize;
    if n == 0 || texture.pixels.len() != n * 4 {
        bail!("texture is {w}x{h} with {} bytes: no pixels or wrong size", texture.pixels.len());
    }
    let mut covered = vec![false; n];
    let mut any_uv = false;
    for m in meshes {
        any_uv |= mask::mark_uv_coverage(m, w, h, &mut covered);
    }
    if !any_uv {
        covered.iter_mut().for_each(|c| *c = true);
    }
    let mut counts = TexelCounts { total: n as u64, ..Default::default() };
    let mut used = vec![false; n];
    for (i, px) in texture.pixels.chunks_exact(4).enumerate() {
        if !covered[i] {
            counts.not_covered_by_uvs += 1;
        } else if mask::is_green_screen([px[0], px[1], px[2]]) {
            counts.green_screen += 1;
        } else if px[3] == 0 {
            counts.transparent += 1;
        } else {
            used[i] = true;
            counts.used += 1;
        }
    }
    Ok((used, counts))
}

/// The distinct textures of a model, each with all the meshes that use it (materials that
/// share one image — loaders give each material its own copy — are merged, so no texel counts
/// twice; materials without a texture are skipped).
pub fn model_textures(model: &Model) -> Vec<(&Rgba8Image, Vec<&crate::scene::Mesh>)> {
    let mut groups: Vec<(&Rgba8Image, Vec<&crate::scene::Mesh>)> = Vec::new();
    for (i, mat) in model.materials.iter().enumerate() {
        let Some(tex) = mat.texture.as_ref() else { continue };
        let meshes = model.meshes.iter().filter(|m| m.material == i);
        match groups.iter_mut().find(|(t, _)| (t.width, t.height) == (tex.width, tex.height) && t.pixels == tex.pixels) {
            Some((_, list)) => list.extend(meshes),
            None => groups.push((tex, meshes.collect())),
        }
    }
    groups.retain(|(_, meshes)| !meshes.is_empty());
    groups
}

fn add_counts(a: &mut TexelCounts, b: TexelCounts) {
    a.total += b.total;
    a.used += b.used;
    a.not_covered_by_uvs += b.not_covered_by_uvs;
    a.green_screen += b.green_screen;
    a.transparent += b.transparent;
}

fn no_texels_error(c: TexelCounts) -> anyhow::Error {
    anyhow::anyhow!(
        "the model's textures have no usable texels: of {} texels, {} are not covered by any UV triangle, {} are green screen (0,255,0) and {} are transparent",
        c.total,
        c.not_covered_by_uvs,
        c.green_screen,
        c.transparent
    )
}

/// The used texels of all the model's textures, linear RGB, with the counts.
pub fn model_texels(model: &Model) -> Result<(Vec<[f32; 3]>, TexelCounts)> {
    let lut = srgb8_to_linear_table();
    let mut texels = Vec::new();
    let mut counts = TexelCounts::default();
    for (tex, meshes) in model_textures(model) {
        let (used, c) = texture_mask(tex, &meshes)?;
        add_counts(&mut counts, c);
        texels.extend(
            tex.pixels
                .chunks_exact(4)
                .zip(&used)
                .filter(|(_, u)| **u)
                .map(|(p, _)| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]),
        );
    }
    Ok((texels, counts))
}

/// The diffuse-colour fallback: one sample per triangle of its material's Kd (linear).
fn diffuse_samples(model: &Model) -> Vec<[f32; 3]> {
    model
        .meshes
        .iter()
        .flat_map(|m| {
            let kd = model.materials.get(m.material).map(|mat| mat.diffuse).unwrap_or(crate::scene::Material::default().diffuse);
            std::iter::repeat_n(kd, m.indices.len() / 3)
        })
        .collect()
}

/// Model priors, CPU reference.
pub fn model_priors(model: &Model) -> Result<ModelPriors> {
    if model.triangle_count() == 0 {
        bail!("the model has no triangles");
    }
    if model_textures(model).is_empty() {
        let samples = diffuse_samples(model);
        let stats = ColourStats::from_linear(&samples)?;
        return Ok(ModelPriors { source: ModelPriorSource::DiffuseColours, texels: TexelCounts::default(), stats });
    }
    let (texels, counts) = model_texels(model)?;
    if texels.is_empty() {
        return Err(no_texels_error(counts));
    }
    Ok(ModelPriors { source: ModelPriorSource::Textures, texels: counts, stats: ColourStats::from_linear(&texels)? })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::{Material, Mesh};

    /// A cube map whose faces are solid colours, except the given face patterns.
    pub fn solid_cube(size: u32, colours: [[f32; 3]; 6]) -> CubeMap {
        let n = (size * size) as usize;
        CubeMap { size, faces: colours.map(|c| vec![c; n]) }
    }

    /// A model: one quad with UVs covering the left half of its texture.
    pub fn half_quad_model(texture: Rgba8Image) -> Model {
        let mesh = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![],
            uvs: vec![[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0]],
            indices: vec![0, 1, 2, 0, 2, 3],
            material: 0,
        };
        Model { meshes: vec![mesh], materials: vec![Material { texture: Some(texture), ..Default::default() }] }
    }

    #[test]
    fn environment_from_solid_faces() {
        // +X red, −X green, +Y sky blue, −Y brown, +Z white, −Z black (linear).
        let cube = solid_cube(4, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.4, 0.9], [0.3, 0.2, 0.1], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]);
        let p = environment_priors(&cube).unwrap();
        assert_eq!(p.up_mean, [0.2f32 as f64, 0.4f32 as f64, 0.9f32 as f64]);
        assert_eq!(p.down_mean, [0.3f32 as f64, 0.2f32 as f64, 0.1f32 as f64]);
        let h = p.horizontal;
        assert_eq!(h.count, 64);
        // Mean of red, green, white, black = (0.5, 0.5, 0.25).
        assert!((h.rgb_mean[0] - 0.5).abs() < 1e-12 && (h.rgb_mean[1] - 0.5).abs() < 1e-12 && (h.rgb_mean[2] - 0.25).abs() < 1e-12);
        // BT.709 luminance: black 0, red 0.2126, green 0.7152, white 1.
        assert_eq!(h.luminance.min, 0.0);
        assert!((h.luminance.max - 1.0).abs() < 1e-12);
        assert!((h.luminance.mean - (0.2126 + 0.7152 + 1.0) / 4.0).abs() < 1e-12);
        // 1st percentile of 64 values (k = 1): black; 99th (k = 64): white.
        assert_eq!(h.luminance.p_lo, 0.0);
        assert!((h.luminance.p_hi - 1.0).abs() < 1e-12);
    }

    #[test]
    fn environment_errors() {
        let mut cube = solid_cube(2, [[0.5; 3]; 6]);
        cube.faces[3].pop();
        assert!(environment_priors(&cube).unwrap_err().to_string().contains("-Y"));
        let mut cube = solid_cube(2, [[0.5; 3]; 6]);
        cube.faces[2] = vec![[f32::NAN; 3]; 4];
        assert!(environment_priors(&cube).unwrap_err().to_string().contains("+Y"));
        assert!(environment_priors(&CubeMap { size: 0, faces: Default::default() }).is_err());
    }

    fn texture(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Rgba8Image {
        let pixels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).flat_map(|(x, y)| f(x, y)).collect();
        Rgba8Image { width: w, height: h, pixels }
    }

    #[test]
    fn model_uses_only_covered_non_green_texels() {
        // Left half red (covered by the UVs), right half yellow background (not covered), plus
        // one green-screen texel and one transparent texel inside the covered half.
        let tex = texture(8, 8, |x, y| match (x, y) {
            (1, 1) => [0, 255, 0, 255],
            (2, 2) => [9, 9, 9, 0],
            (x, _) if x < 4 => [255, 0, 0, 255],
            _ => [255, 255, 0, 255],
        });
        let p = model_priors(&half_quad_model(tex)).unwrap();
        assert_eq!(p.source, ModelPriorSource::Textures);
        assert_eq!(p.texels, TexelCounts { total: 64, used: 30, not_covered_by_uvs: 32, green_screen: 1, transparent: 1 });
        // Only red left: σ = 0, mean linear (1, 0, 0).
        assert_eq!(p.stats.rgb_mean, [1.0, 0.0, 0.0]);
        assert!(p.stats.lab_sigma().iter().all(|s| *s < 1e-7));
    }

    #[test]
    fn a_texture_shared_by_two_materials_counts_once() {
        let tex = texture(8, 8, |x, _| if x < 4 { [255, 0, 0, 255] } else { [0, 0, 255, 255] });
        let mut m = half_quad_model(tex.clone());
        // A second material with a copy of the same image, used by a quad over the right half.
        m.materials.push(Material { texture: Some(tex), ..Default::default() });
        let mut right = m.meshes[0].clone();
        right.uvs = vec![[0.5, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 1.0]];
        right.material = 1;
        m.meshes.push(right);
        let p = model_priors(&m).unwrap();
        assert_eq!(p.texels, TexelCounts { total: 64, used: 64, ..Default::default() });
        assert!((p.stats.rgb_mean[0] - 0.5).abs() < 1e-12 && (p.stats.rgb_mean[2] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn all_green_texture_is_an_error_and_untextured_model_falls_back() {
        let tex = texture(4, 4, |_, _| [0, 255, 0, 255]);
        let err = model_priors(&half_quad_model(tex)).unwrap_err().to_string();
        assert!(err.contains("no usable texels") && err.contains("green"), "{err}");
        let mut m = half_quad_model(texture(1, 1, |_, _| [0; 4]));
        m.materials[0].texture = None;
        m.materials[0].diffuse = [0.1, 0.2, 0.3];
        let p = model_priors(&m).unwrap();
        assert_eq!(p.source, ModelPriorSource::DiffuseColours);
        assert_eq!(p.stats.count, 2);
        assert!((p.stats.rgb_mean[2] - 0.3).abs() < 1e-7);
        assert!(model_priors(&Model::default()).is_err());
    }

    /// Keenan Crane's Spot (OBJ without .mtl) with its texture.
    pub fn spot() -> Model {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/textured_models/spot/");
        let options = crate::scene::model::ModelOptions { texture: Some(format!("{dir}spot_texture.png").into()), ..Default::default() };
        crate::scene::model::load_model_with(std::path::Path::new(&format!("{dir}spot_triangulated.obj")), &options).unwrap().model
    }

    #[test]
    fn spot_texture_priors_skip_texels_no_uv_covers() {
        let p = model_priors(&spot()).unwrap();
        let t = p.texels;
        assert_eq!(t.total, 1024 * 1024);
        assert_eq!(t.used + t.not_covered_by_uvs + t.green_screen + t.transparent, t.total);
        // Spot's UV islands cover about half the texture. An independent raster of the same UVs
        // (Pillow's ImageDraw.polygon fill of every triangle, v flipped, 1024²) covers 49.38 %;
        // ours is conservative (edge texels count), so slightly more, but not much.
        let covered = t.used as f64 / t.total as f64;
        assert!((0.4938..0.51).contains(&covered), "{t:?}");
        assert_eq!(p.stats.count, t.used);
        // With the mask the statistics differ from the whole texture's.
        let all = ColourStats::from_srgb8(
            &spot().materials[0].texture.as_ref().unwrap().pixels.chunks(4).map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>(),
        )
        .unwrap();
        assert!((all.rgb_mean[0] - p.stats.rgb_mean[0]).abs() > 1e-3 || (all.rgb_mean[2] - p.stats.rgb_mean[2]).abs() > 1e-3);
    }
}
