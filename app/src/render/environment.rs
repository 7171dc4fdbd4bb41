//! The environment on the GPU: the cube map as half floats (linear light after exposure) and
//! what the frame maths needs from it (hemisphere priors, colour statistics, heading).

use super::params::HemispherePriors;
use crate::colour::stats::ColourStats;
use crate::gpu::{Gpu, build};
use crate::light::ggx;
use crate::priors;
use crate::scene::{CubeMap, FACE_NAMES};
use anyhow::{Context, Result, bail};

/// What the frame needs from the environment besides its texture.
pub struct Environment {
    pub priors: HemispherePriors,
    /// Colour statistics of the horizontal faces after exposure, the correction's source.
    pub colour: ColourStats,
    pub exposure: f32,
    /// World heading (radians, clockwise from North) of the cube map's front (+Z) face.
    pub heading: f32,
}

/// One face's RGB texels as RGBA16F (alpha 1). The map is radiance: a negative value (which a
/// loader should already have repaired) is clamped to 0.
pub fn rgba16f_texels(face: &[[f32; 3]]) -> Vec<half::f16> {
    face.iter().flat_map(|p| [p[0], p[1], p[2], 1.0]).map(|v| half::f16::from_f32(v.max(0.0))).collect()
}

/// The environment's views on the GPU.
pub struct EnvironmentViews {
    /// The map as given.
    pub cube: wgpu::TextureView,
    /// The map convolved with the GGX lobe, one mip level per roughness (light::ggx::prefilter).
    pub specular: wgpu::TextureView,
}

/// The environment's textures, made once per face size: the map and its GGX-prefiltered levels.
/// [`EnvironmentTextures::write`] refreshes them in place (write_texture only), so a new map of
/// the same size — a refreshed fold of the camera frame, a capture — allocates nothing and keeps
/// every bind group that holds the views.
pub struct EnvironmentTextures {
    cube: wgpu::Texture,
    specular: wgpu::Texture,
    pub views: EnvironmentViews,
}

impl EnvironmentTextures {
    /// Textures for maps of `size`×`size` faces.
    pub fn new(gpu: &Gpu, size: u32) -> EnvironmentTextures {
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let cube = build::texture(&gpu.device, "environment", (size, size, 6), wgpu::TextureFormat::Rgba16Float, 1, usage);
        let specular = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("prefiltered environment"),
            size: wgpu::Extent3d { width: ggx::PREFILTER_SIZE, height: ggx::PREFILTER_SIZE, depth_or_array_layers: 6 },
            mip_level_count: ggx::PREFILTER_LEVELS,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage,
            view_formats: &[],
        });
        let views = EnvironmentViews { cube: build::cube_view(&cube), specular: build::cube_view(&specular) };
        EnvironmentTextures { cube, specular, views }
    }

    /// Face size of the map these textures hold.
    pub fn size(&self) -> u32 {
        self.cube.width()
    }

    /// Write `cube` (of this size) and its GGX-prefiltered `levels` ([`prepare`]) into the
    /// textures.
    pub fn write(&self, gpu: &Gpu, cube: &CubeMap, levels: &[CubeMap]) -> Result<()> {
        if cube.size != self.size() {
            bail!("environment of {}-texel faces written into textures of {}", cube.size, self.size());
        }
        for (layer, face) in cube.faces.iter().enumerate() {
            build::write_layer(&gpu.queue, &self.cube, layer as u32, bytemuck::cast_slice(&rgba16f_texels(face)));
        }
        if levels.len() != ggx::PREFILTER_LEVELS as usize {
            bail!("{} prefiltered environment levels, expected {}", levels.len(), ggx::PREFILTER_LEVELS);
        }
        for (mip, level) in levels.iter().enumerate() {
            for (layer, face) in level.faces.iter().enumerate() {
                gpu.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.specular,
                        mip_level: mip as u32,
                        origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytemuck::cast_slice(&rgba16f_texels(face)),
                    wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(8 * level.size), rows_per_image: None },
                    wgpu::Extent3d { width: level.size, height: level.size, depth_or_array_layers: 1 },
                );
            }
        }
        Ok(())
    }
}

/// What the GPU and the frame need from a map besides its texels, computed on the CPU (on any
/// thread: the live view prepares its folded camera frame off the frame's thread).
pub struct Prepared {
    /// The map convolved with the GGX lobe, one level per roughness (light::ggx::prefilter).
    pub levels: Vec<CubeMap>,
    pub env: Environment,
}

/// Check `cube`, `exposure` and `heading`; prefilter the map and compute its priors.
pub fn prepare(cube: &CubeMap, exposure: f32, heading: f32) -> Result<Prepared> {
    let env = measure(cube, exposure, heading)?;
    Ok(Prepared { levels: ggx::prefilter(cube), env })
}

/// Check `cube`, `exposure` and `heading`, and compute what the frame needs from the map (its
/// priors after exposure). Touches no GPU state.
pub fn measure(cube: &CubeMap, exposure: f32, heading: f32) -> Result<Environment> {
    if !(exposure.is_finite() && exposure > 0.0) {
        bail!("environment exposure must be a positive number, got {exposure}");
    }
    if !heading.is_finite() {
        bail!("environment heading must be a finite angle");
    }
    let size = cube.size;
    if let Some(layer) = cube.faces.iter().position(|face| face.len() != (size * size) as usize) {
        bail!("cube-map face {} has {} pixels, expected {size}x{size}", FACE_NAMES[layer], cube.faces[layer].len());
    }
    let env_priors = priors::environment_priors_scaled(cube, exposure).context("environment colour priors")?;
    Ok(Environment { priors: HemispherePriors::from_environment(&env_priors), colour: env_priors.horizontal, exposure, heading })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_are_rgba_halves_with_negatives_clamped() {
        let t = rgba16f_texels(&[[0.5, -2.0, 1000.0], [0.0, 0.25, 65504.0]]);
        let f: Vec<f32> = t.iter().map(|h| h.to_f32()).collect();
        // 0.5, 0.25, 1000 and 65504 (the largest finite half) are exact in f16.
        assert_eq!(f, [0.5, 0.0, 1000.0, 1.0, 0.0, 0.25, 65504.0, 1.0]);
    }
}
