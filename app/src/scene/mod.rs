//! Scene inputs: models, environments (cube maps), backgrounds and the scene file.
//!
//! The types here are what the renderer consumes; loaders fill them.

use glam::Vec3;

/// An 8-bit RGBA image, sRGB-encoded (textures, backgrounds).
#[derive(Clone, Debug)]
pub struct Rgba8Image {
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first, 4 bytes per pixel.
    pub pixels: Vec<u8>,
}

/// A surface material (seed 000 Eq. 3 terms plus what the loaders give).
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    /// Diffuse colour, linear RGB (MTL `Kd`, glTF base-colour factor).
    pub diffuse: [f32; 3],
    /// Diffuse texture (MTL `map_Kd`, glTF base-colour texture), sRGB-encoded.
    pub texture: Option<Rgba8Image>,
    /// Specular colour, linear RGB (MTL `Ks`).
    pub specular: [f32; 3],
    /// Blinn-Phong exponent (MTL `Ns`).
    pub shininess: f32,
    /// 1 = opaque; below 1 the material is drawn as the transparent material of Eq. 7.
    pub opacity: f32,
    /// Which faces of its triangles are seen (glTF `doubleSided`).
    pub sides: Sides,
}

/// Which faces of a material's triangles are seen: glTF 2.0 §3.9.5 ("Double Sided"), where a
/// material without `doubleSided` is single-sided. Front faces wind counter-clockwise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sides {
    /// Not said (an OBJ has no such flag): every face is drawn; back faces are culled only where
    /// they are hidden anyway (a closed surface seen from outside, `scene::lod::is_closed`).
    #[default]
    Unspecified,
    /// glTF `doubleSided: false` (its default): back faces are culled.
    Front,
    /// glTF `doubleSided: true`: both faces are drawn, a back face lit with its normal reversed.
    Both,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            diffuse: [0.8, 0.8, 0.8],
            texture: None,
            specular: [0.25, 0.25, 0.25],
            shininess: 32.0,
            opacity: 1.0,
            sides: Sides::Unspecified,
        }
    }
}

/// Triangles sharing one material. Positions/normals in model space as the file gives them.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Texture coordinates (0,0 = top-left of the image, as wgpu samples); zeros when absent.
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
    /// Index into `Model::materials`.
    pub material: usize,
}

/// A loaded model: meshes and their materials. Model files are y-up (OBJ, glTF); the renderer
/// turns model +y into world up.
#[derive(Clone, Debug, Default)]
pub struct Model {
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
}

impl Model {
    /// Axis-aligned bounds (min, max) over all meshes, in model space.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.meshes.iter().flat_map(|m| m.positions.iter()).map(|p| Vec3::from_array(*p));
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Total triangle count.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len() / 3).sum()
    }
}

/// Cube-map face order, as wgpu/Vulkan store the layers of a cube texture.
pub const FACE_NAMES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];

/// An environment as a cube map in linear light (HDR kept in float).
///
/// Faces in wgpu order +X, −X, +Y, −Y, +Z, −Z, each `size`×`size`, row-major, top row first.
/// How world (ENU) directions map to faces is defined once, in [`enu_to_cube`].
#[derive(Clone, Debug)]
pub struct CubeMap {
    pub size: u32,
    pub faces: [Vec<[f32; 3]>; 6],
}

/// The one place world directions become cube-map sampling directions.
///
/// Cube sampling follows the Vulkan/GL rule, which is left-handed with +Y up. We map
/// ENU (x East, y North, z Up) to cube space as (x, z, y): so +X = East, −X = West,
/// +Y = Up (sky), −Y = Down (ground), +Z = North (the "front" of a captured map: the capture's
/// reference heading is rotated onto North), −Z = South. Seen from inside, every face then
/// appears unmirrored with image-up towards the sky (for the side faces).
pub fn enu_to_cube(d: Vec3) -> Vec3 {
    Vec3::new(d.x, d.z, d.y)
}

/// Inverse of [`enu_to_cube`] (the swap is its own inverse).
pub fn cube_to_enu(c: Vec3) -> Vec3 {
    Vec3::new(c.x, c.z, c.y)
}

pub mod background;
pub mod cubemap;
pub mod decode;
pub mod demo;
pub mod environment;
pub mod lod;
pub mod model;
pub mod normals;
pub mod occlusion;
