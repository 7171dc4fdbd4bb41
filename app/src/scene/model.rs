//! Loading 3D models: Wavefront OBJ (+MTL) through tobj, glTF 2.0 (.gltf/.glb) through gltf.
//!
//! Formats and conventions are documented in `docs/assets.md`. Whatever the file, the result
//! is a [`Model`]: meshes grouped by material, unit normals on every vertex, texture
//! coordinates with (0,0) at the image's top-left (as wgpu samples), textures sRGB-encoded.

mod gltf;
mod obj;

use super::background::load_image;
use super::normals::{DEFAULT_CREASE_DEG, compute_crease_normals};
use super::{Mesh, Model};
use anyhow::{Context, Result, bail};
use glam::Vec3;
use std::path::{Path, PathBuf};

pub use gltf::load_glb_bytes;
pub use obj::{load_obj_bytes, load_obj_mtl_bytes};

/// How to load a model.
#[derive(Clone, Debug)]
pub struct ModelOptions {
    /// Where an OBJ mesh has no normals, edges sharper than this (degrees) stay hard.
    pub crease_angle_deg: f32,
    /// A diffuse texture (JPEG/PNG) for every material that has none, e.g. for an OBJ that
    /// comes without an .mtl but with a texture beside it (Keenan Crane's Spot).
    pub texture: Option<PathBuf>,
}

impl Default for ModelOptions {
    fn default() -> Self {
        ModelOptions { crease_angle_deg: DEFAULT_CREASE_DEG, texture: None }
    }
}

/// A loaded model plus what the loader tolerated or repaired on the way (a missing .mtl,
/// normals it computed, ...), one human-readable line each.
#[derive(Clone, Debug)]
pub struct LoadedModel {
    pub model: Model,
    pub notes: Vec<String>,
}

/// Load a model file (.obj, .gltf or .glb, by extension) with default options.
pub fn load_model(path: &Path) -> Result<Model> {
    Ok(load_model_with(path, &ModelOptions::default())?.model)
}

/// Load a model file (.obj, .gltf or .glb, by extension).
pub fn load_model_with(path: &Path, options: &ModelOptions) -> Result<LoadedModel> {
    if !(options.crease_angle_deg.is_finite() && (0.0..=180.0).contains(&options.crease_angle_deg)) {
        bail!("crease angle must be between 0 and 180 degrees, got {}", options.crease_angle_deg);
    }
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let mut loaded = match ext.as_str() {
        "obj" => obj::load_obj_file(path, options)?,
        "gltf" | "glb" => gltf::load_gltf_file(path)?,
        _ => bail!("{}: unsupported model format (expected .obj, .gltf or .glb)", path.display()),
    };
    if loaded.model.triangle_count() == 0 {
        bail!("{}: the file contains no triangles", path.display());
    }
    if let Some(tex) = &options.texture {
        let image = load_image(tex).with_context(|| format!("texture given for model {}", path.display()))?;
        for m in loaded.model.materials.iter_mut().filter(|m| m.texture.is_none()) {
            m.texture = Some(image.clone());
        }
        loaded.notes.push(format!("{}: texture {} applied to materials without one", path.display(), tex.display()));
    }
    Ok(loaded)
}

/// Check a finished mesh and fill what is missing: normals (computed with `crease_deg` when
/// absent or wrong in count), normalised normals (a zero one is replaced, with a note), zero
/// UVs when absent. Errors on non-finite positions, normals or texture coordinates and on bad
/// indices.
fn finish_mesh(mesh: &mut Mesh, crease_deg: f32, what: &str) -> Result<Option<String>> {
    if let Some(i) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        bail!("{what}: vertex {i} has a non-finite position {:?}", mesh.positions[i]);
    }
    if !mesh.indices.len().is_multiple_of(3) {
        bail!("{what}: index count {} is not a multiple of 3", mesh.indices.len());
    }
    if let Some(&i) = mesh.indices.iter().find(|&&i| i as usize >= mesh.positions.len()) {
        bail!("{what}: index {i} out of range ({} vertices)", mesh.positions.len());
    }
    if let Some(i) = mesh.normals.iter().position(|n| !n.iter().all(|c| c.is_finite())) {
        bail!("{what}: vertex {i} has a non-finite normal {:?}", mesh.normals[i]);
    }
    if let Some(i) = mesh.uvs.iter().position(|t| !t.iter().all(|c| c.is_finite())) {
        bail!("{what}: vertex {i} has a non-finite texture coordinate {:?}", mesh.uvs[i]);
    }
    if mesh.uvs.len() != mesh.positions.len() {
        mesh.uvs = vec![[0.0, 0.0]; mesh.positions.len()];
    }
    if mesh.normals.len() == mesh.positions.len() {
        let repaired = repair_normals(mesh);
        return Ok((repaired > 0).then(|| format!("{what}: {repaired} zero or invalid normal(s) replaced by the mean of their faces")));
    }
    let reason = if mesh.normals.is_empty() { "no normals" } else { "normals on only some vertices" };
    compute_crease_normals(mesh, crease_deg).with_context(|| what.to_string())?;
    let how = if crease_deg == 0.0 { "flat normals".to_string() } else { format!("smooth normals with a {crease_deg} deg crease angle") };
    Ok(Some(format!("{what}: {reason}; computed {how}")))
}

/// Normalise a mesh's own normals; a zero or non-finite one becomes the area-weighted mean of
/// the triangles using that vertex (or +y if they are all degenerate). Returns how many.
fn repair_normals(mesh: &mut Mesh) -> usize {
    // Scaled by the largest component first: (1e24, 0, −1) has a length that overflows f32.
    let scaled = |n: &[f32; 3]| {
        let v = Vec3::from_array(*n);
        let m = v.abs().max_element();
        if m.is_finite() && m > 0.0 { v / m } else { Vec3::ZERO }
    };
    let bad: Vec<bool> = mesh.normals.iter().map(|n| scaled(n) == Vec3::ZERO).collect();
    let count = bad.iter().filter(|b| **b).count();
    if count > 0 {
        let mut sums = vec![Vec3::ZERO; mesh.positions.len()];
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
            if bad[a] || bad[b] || bad[c] {
                let p = |i: usize| Vec3::from_array(mesh.positions[i]);
                // Twice the area times the unit normal: area weighting for free.
                let n = (p(b) - p(a)).cross(p(c) - p(a));
                for i in [a, b, c] {
                    sums[i] += n;
                }
            }
        }
        for (i, n) in mesh.normals.iter_mut().enumerate().filter(|(i, _)| bad[*i]) {
            *n = sums[i].try_normalize().unwrap_or(Vec3::Y).to_array();
        }
    }
    for n in &mut mesh.normals {
        *n = scaled(n).normalize().to_array();
    }
    count
}
