//! glTF 2.0 (.gltf with its buffers and images beside it, or a single .glb), through the gltf
//! crate: triangle primitives of the default scene with node transforms applied, TEXCOORD_0,
//! and the metallic-roughness material's base colour (factor and texture).

use super::{LoadedModel, finish_mesh};
use crate::scene::{Material, Mesh, Model, Rgba8Image};
use ::gltf::mesh::Mode;
use anyhow::{Context, Result, anyhow, bail};
use glam::{Mat3, Mat4, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// Node hierarchies deeper than this are refused (the spec forbids cycles; this guards
/// against files that have them anyway).
const MAX_NODE_DEPTH: usize = 256;

pub(super) fn load_gltf_file(path: &Path) -> Result<LoadedModel> {
    let (doc, buffers, images) = ::gltf::import(path).with_context(|| format!("cannot load glTF {}", path.display()))?;
    build(&doc, &buffers, &images, &path.display().to_string())
}

/// Load a self-contained glTF held in memory (a .glb, or a .gltf with data: URIs), e.g. the
/// built-in demo model.
pub fn load_glb_bytes(bytes: &[u8]) -> Result<Model> {
    let (doc, buffers, images) = ::gltf::import_slice(bytes).context("cannot load embedded glTF")?;
    let loaded = build(&doc, &buffers, &images, "embedded glTF")?;
    if loaded.model.triangle_count() == 0 {
        bail!("embedded glTF contains no triangles");
    }
    Ok(loaded.model)
}

fn build(doc: &::gltf::Document, buffers: &[::gltf::buffer::Data], images: &[::gltf::image::Data], what: &str) -> Result<LoadedModel> {
    let what = what.to_string();
    let mut out = Builder { what: &what, images, notes: Vec::new(), materials: Vec::new(), by_gltf: HashMap::new(), meshes: Vec::new() };

    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            // No scene: draw every node that is nobody's child.
            let children: std::collections::HashSet<usize> = doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
            out.notes.push(format!("{what}: no scene defined; using all root nodes"));
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    let mut stack: Vec<(::gltf::Node, Mat4, usize)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > MAX_NODE_DEPTH {
            bail!("{what}: node hierarchy deeper than {MAX_NODE_DEPTH} (a cycle?)");
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                out.add_primitive(&mesh, &prim, world, buffers)?;
            }
        }
        stack.extend(node.children().collect::<Vec<_>>().into_iter().rev().map(|c| (c, world, depth + 1)));
    }
    let Builder { notes, materials, meshes, .. } = out;
    Ok(LoadedModel { model: Model { meshes, materials }, notes })
}

/// Collects primitives into one mesh per material.
struct Builder<'a> {
    what: &'a str,
    images: &'a [::gltf::image::Data],
    notes: Vec<String>,
    materials: Vec<Material>,
    /// glTF material index (None: primitive without material) to index in `materials`.
    by_gltf: HashMap<Option<usize>, usize>,
    meshes: Vec<Mesh>,
}

impl Builder<'_> {
    fn add_primitive(
        &mut self,
        mesh: &::gltf::Mesh,
        prim: &::gltf::Primitive,
        world: Mat4,
        buffers: &[::gltf::buffer::Data],
    ) -> Result<()> {
        let label = format!("{}: mesh '{}' primitive {}", self.what, mesh.name().unwrap_or("?"), prim.index());
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.notes.push(format!("{label}: {mode:?} primitive skipped (only triangles are drawn)"));
            return Ok(());
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let positions: Vec<[f32; 3]> = reader.read_positions().ok_or_else(|| anyhow!("{label}: no POSITION attribute"))?.collect();
        let normals: Vec<[f32; 3]> = reader.read_normals().map(|n| n.collect()).unwrap_or_default();
        let uvs: Vec<[f32; 2]> = reader.read_tex_coords(0).map(|t| t.into_f32().collect()).unwrap_or_default();
        let raw: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let mut indices = match mode {
            Mode::TriangleStrip => strip_to_list(&raw),
            Mode::TriangleFan => fan_to_list(&raw),
            _ => raw,
        };
        indices.truncate(indices.len() / 3 * 3);

        // Node transform: points by the matrix, normals by its inverse transpose; a mirroring
        // transform (negative determinant) flips the winding, so swap two corners back.
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        let positions = positions.iter().map(|p| world.transform_point3(Vec3::from_array(*p)).to_array()).collect();
        let normals = normals.iter().map(|n| (normal_matrix * Vec3::from_array(*n)).normalize_or_zero().to_array()).collect();
        if world.determinant() < 0.0 {
            for t in indices.chunks_exact_mut(3) {
                t.swap(1, 2);
            }
        }
        let mut part = Mesh { positions, normals, uvs, indices, material: 0 };
        // glTF 2.0 spec §3.7.2.1: without normals, clients must compute flat normals.
        self.notes.extend(finish_mesh(&mut part, 0.0, &label)?);

        let material = self.material(prim.material())?;
        let target = match self.meshes.iter().position(|m| m.material == material) {
            Some(i) => i,
            None => {
                self.meshes.push(Mesh { material, ..Default::default() });
                self.meshes.len() - 1
            }
        };
        let dst = &mut self.meshes[target];
        let base = dst.positions.len() as u32;
        dst.positions.extend(part.positions);
        dst.normals.extend(part.normals);
        dst.uvs.extend(part.uvs);
        dst.indices.extend(part.indices.iter().map(|i| i + base));
        Ok(())
    }

    /// Our material for a glTF material, converted once.
    fn material(&mut self, mat: ::gltf::Material) -> Result<usize> {
        if let Some(&i) = self.by_gltf.get(&mat.index()) {
            return Ok(i);
        }
        let converted = match mat.index() {
            // No material on the primitive: our default (the spec's default is a white metal,
            // which looks wrong under a Blinn-Phong model).
            None => Material::default(),
            Some(index) => self.convert_material(&mat, index)?,
        };
        self.materials.push(converted);
        self.by_gltf.insert(mat.index(), self.materials.len() - 1);
        Ok(self.materials.len() - 1)
    }

    fn convert_material(&mut self, mat: &::gltf::Material, index: usize) -> Result<Material> {
        let name = mat.name().map_or_else(|| format!("material {index}"), str::to_string);
        let pbr = mat.pbr_metallic_roughness();
        let base = pbr.base_color_factor();
        let texture = match pbr.base_color_texture() {
            None => None,
            Some(info) => {
                if info.tex_coord() != 0 {
                    self.notes.push(format!(
                        "{}: material '{name}' uses TEXCOORD_{} for its base colour; only TEXCOORD_0 is read",
                        self.what,
                        info.tex_coord()
                    ));
                }
                let image_index = info.texture().source().index();
                let data = self.images.get(image_index).ok_or_else(|| anyhow!("{}: image {image_index} missing", self.what))?;
                Some(
                    rgba8_from_gltf(data)
                        .with_context(|| format!("{}: base-colour image {image_index} of material '{name}'", self.what))?,
                )
            }
        };
        let metallic = pbr.metallic_factor().clamp(0.0, 1.0);
        // glTF 2.0 spec, Appendix B: the specular reflectance at normal incidence is
        // F0 = mix(0.04, baseColor, metallic).
        let specular = [0, 1, 2].map(|i| 0.04 + (base[i] - 0.04) * metallic);
        Ok(Material {
            name,
            diffuse: [base[0], base[1], base[2]],
            texture,
            specular,
            shininess: blinn_phong_exponent(pbr.roughness_factor()),
            opacity: match mat.alpha_mode() {
                ::gltf::material::AlphaMode::Blend => base[3].clamp(0.0, 1.0),
                _ => 1.0,
            },
        })
    }
}

/// Blinn-Phong exponent matching a glTF roughness: glTF's microfacet α is roughness²
/// (spec Appendix B), and a Beckmann α corresponds to the Phong exponent 2/α² − 2 (Walter et al.
/// 2007, "Microfacet Models for Refraction through Rough Surfaces", §5.2). Clamped to [1, 8192];
/// a non-finite roughness counts as the spec's default, 1.
pub(crate) fn blinn_phong_exponent(roughness: f32) -> f32 {
    let roughness = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
    let alpha = (roughness * roughness).max(1e-3);
    (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 8192.0)
}

/// glTF spec §3.7.2.1: strip triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}).
fn strip_to_list(v: &[u32]) -> Vec<u32> {
    (0..v.len().saturating_sub(2)).flat_map(|i| [v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]]).collect()
}

/// glTF spec §3.7.2.1: fan triangle i is (v_{i+1}, v_{i+2}, v_0).
fn fan_to_list(v: &[u32]) -> Vec<u32> {
    (0..v.len().saturating_sub(2)).flat_map(|i| [v[i + 1], v[i + 2], v[0]]).collect()
}

/// A decoded glTF image as 8-bit RGBA (grey replicated, 16-bit rounded to 8).
fn rgba8_from_gltf(data: &::gltf::image::Data) -> Result<Rgba8Image> {
    use ::gltf::image::Format;
    let n = (data.width as usize) * (data.height as usize);
    let wide = |i: usize| -> u8 {
        let v = u16::from_ne_bytes([data.pixels[2 * i], data.pixels[2 * i + 1]]) as u32;
        ((v * 255 + 32767) / 65535) as u8
    };
    let (channels, bytes_per) = match data.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        other => bail!("unsupported pixel format {other:?} for a base-colour texture"),
    };
    if data.pixels.len() != n * channels * bytes_per {
        bail!("image data size does not match {}x{}", data.width, data.height);
    }
    let get = |i: usize| if bytes_per == 1 { data.pixels[i] } else { wide(i) };
    let mut pixels = Vec::with_capacity(n * 4);
    for p in 0..n {
        let c = |k: usize| get(p * channels + k);
        let rgba = match channels {
            1 => [c(0), c(0), c(0), 255],
            2 => [c(0), c(0), c(0), c(1)],
            3 => [c(0), c(1), c(2), 255],
            _ => [c(0), c(1), c(2), c(3)],
        };
        pixels.extend_from_slice(&rgba);
    }
    Ok(Rgba8Image { width: data.width, height: data.height, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_follow_the_spec() {
        // Strip 0,1,2,3,4: (0,1,2), (1,3,2), (2,3,4) — consistent counter-clockwise winding.
        assert_eq!(strip_to_list(&[0, 1, 2, 3, 4]), vec![0, 1, 2, 1, 3, 2, 2, 3, 4]);
        assert_eq!(fan_to_list(&[0, 1, 2, 3]), vec![1, 2, 0, 2, 3, 0]);
        assert!(strip_to_list(&[0, 1]).is_empty());
    }

    #[test]
    fn roughness_to_exponent() {
        // roughness 0.5: α = 0.25, 2/α² − 2 = 30 (Walter et al. 2007 eq. for the Phong exponent).
        assert!((blinn_phong_exponent(0.5) - 30.0).abs() < 1e-4);
        assert_eq!(blinn_phong_exponent(1.0), 1.0);
        assert_eq!(blinn_phong_exponent(0.0), 8192.0);
        assert_eq!(blinn_phong_exponent(f32::NAN), 1.0);
    }
}
