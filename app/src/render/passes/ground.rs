//! The ground pass (step 4 of DESIGN.md "One frame"): an invisible shadow-catcher plane under the
//! model darkens the background where the shadow map says the sun is blocked, with a penumbra
//! that follows the sun's size (frame.wgsl `sun_visibility_soft`), and where the model hides its
//! sky: the ground's sky visibility under the placed model (render::model_cache
//! PreparedModel::ground_sky) is a small texture written once per placement and sky shape, never
//! per frame.

use super::super::uniforms::{InstanceUniforms, LightUniforms};
use crate::gpu::build;
use crate::render::frame::{GROUND_VERTICES, GroundMesh};
use crate::render::pipelines::{COLOR_FORMAT, Pipelines, depth_state};
use crate::render::shaders::{Technique, source};
use crate::render::shadow_fit;
use crate::scene::occlusion::{self, GroundSky};
use anyhow::{Result, bail};
use std::sync::Arc;
use wgpu::ShaderStages;

/// The ground's pipelines: with the sun's shadow lookup (where the shadow can fall) and without
/// (the rest of the ground), one bind-group layout.
pub struct GroundPipelines {
    pub layout: wgpu::BindGroupLayout,
    pub shadowed: wgpu::RenderPipeline,
    pub sky_only: wgpu::RenderPipeline,
}

/// The ground pipelines: triangles of [`GroundMesh`] corners; the background is multiplied by
/// one minus the shader's output per channel ([`DARKEN`]).
pub fn pipeline(device: &wgpu::Device, samples: u32) -> GroundPipelines {
    let fs = ShaderStages::FRAGMENT;
    let vs_fs = ShaderStages::VERTEX | fs;
    let layout = build::layout(
        device,
        "ground",
        &[
            build::uniform(0, vs_fs),
            build::uniform(1, vs_fs),
            build::depth_texture_entry(2, fs),
            build::sampler_entry(3, fs, wgpu::SamplerBindingType::Comparison),
            build::uniform(4, fs),
            build::texture_entry(5, fs, wgpu::TextureViewDimension::D2, true),
            build::sampler_entry(6, fs, wgpu::SamplerBindingType::Filtering),
            build::sampler_entry(7, fs, wgpu::SamplerBindingType::NonFiltering),
        ],
    );
    let shadowed = pipeline_for(device, &layout, (COLOR_FORMAT, samples), true);
    let sky_only = pipeline_for(device, &layout, (COLOR_FORMAT, samples), false);
    GroundPipelines { layout, shadowed, sky_only }
}

/// The ground pipeline with bind-group `layout`, drawing into `format` targets of `samples` per
/// pixel, with the sun's shadow lookup or without (`sun_shadow`, the shader's `SUN_SHADOW`).
pub fn pipeline_for(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    (format, samples): (wgpu::TextureFormat, u32),
    sun_shadow: bool,
) -> wgpu::RenderPipeline {
    let module = build::shader(device, "ground", source(Technique::Ground));
    const ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x2];
    let vertices = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<[f32; 2]>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    };
    build::render_pipeline(
        device,
        build::PipelineSpec {
            label: if sun_shadow { "ground" } else { "ground, sky only" },
            module: &module,
            layouts: &[layout],
            vertex_buffers: &[Some(vertices)],
            colour: Some(wgpu::ColorTargetState { format, blend: Some(DARKEN), write_mask: wgpu::ColorWrites::ALL }),
            depth: depth_state(false, wgpu::DepthBiasState::default()),
            samples,
            constants: &[("SUN_SHADOW", if sun_shadow { 1.0 } else { 0.0 })],
        },
    )
}

/// The ground's blend: `dst · (1 − src)` per colour channel (src = what the ground loses there,
/// shaders/ground.wgsl `ground_loss`), the target's alpha kept.
pub const DARKEN: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::Zero,
        dst_factor: wgpu::BlendFactor::OneMinusSrc,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::Zero,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
};

pub struct GroundPass {
    pipeline: wgpu::RenderPipeline,
    sky_only: wgpu::RenderPipeline,
    /// The frame's [`GroundMesh`] corners ([`GROUND_VERTICES`], written each frame).
    vertices: wgpu::Buffer,
    /// Of them, drawn with the shadow lookup, then without.
    counts: (u32, u32),
    /// One per shadow map (in the order of `ShadowPass::maps`).
    bind_groups: Vec<wgpu::BindGroup>,
    /// The plane's transform (`InstanceUniforms`).
    instance: wgpu::Buffer,
    /// The ground's sky visibility under the model (R8, [`GROUND_TEXELS`]², 1 = whole sky), over
    /// the square in the `Light` uniform's `ground_square`.
    sky: wgpu::Texture,
}

/// Texels per side of the ground pass's sky-visibility texture.
pub const GROUND_TEXELS: u32 = occlusion::GROUND_TEXELS;

/// A sky-visibility map as R8 texels (0..=1 → 0..=255, rounded).
pub fn sky_texels(sky: &GroundSky) -> Vec<u8> {
    sky.visibility.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect()
}

/// The largest loss of light (the fraction the ground pass takes, [`DARKEN`]) that moves no
/// 8-bit sRGB-encoded value (IEC 61966-2-1) by more than one level: a loss L moves encoding e
/// by at most 255 · y e'(y) · L / (1 − L) with y the darkened value (e is concave), and y e'(y)
/// is largest at y = 1, 1.055 / 2.4; so 1 / (255 · 1.055 / 2.4 + 1). The ground skips the sky's
/// occlusion where it would darken less than this (one level of a smooth gradient is below
/// what the eye resolves; tests/lod.rs measures the frame against the whole square by FLIP).
pub const INVISIBLE_LOSS: f32 = 1.0 / (255.0 * 1.055 / 2.4 + 1.0);

/// The most any colour channel loses per unit of the sky's occlusion (the share of the sky the
/// model hides) where the sun's shadow is not looked up: shaders/ground.wgsl `ground_loss` with
/// no sun lost, for the `light` uniform and the frame's `shadow_opacity` (the sun's share).
pub fn sky_loss_per_occlusion(light: &LightUniforms, shadow_opacity: f32) -> f32 {
    let sky_share = light.ground_sky[0];
    let total = shadow_opacity + sky_share;
    if total <= 0.0 {
        return 0.0;
    }
    (0..3)
        .map(|c| {
            let (sun, sky) = (light.sun[c], light.ground_sky[c + 1]);
            let light = (shadow_opacity * sun + sky_share * sky) / total;
            sky_share * sky / light.max(1e-6)
        })
        .fold(0.0, f32::max)
}

/// The ground's regions (render::frame::GroundRegions) as last computed, and what for: the
/// shadow's outline once per shadow map drawn (sun camera, model transform, map size, sun size),
/// the sky's region once per sky map (a placement and sky shape: the `Arc` the model cache
/// hands out) and visible threshold. A frame whose map is kept recomputes neither.
#[derive(Debug, Default)]
pub struct RegionCache {
    outline: Option<([u32; 35], Vec<glam::Vec2>)>,
    sky: Option<(Arc<GroundSky>, u32, Vec<glam::Vec2>)>,
    /// How many outlines and sky regions were computed (the tests count them).
    pub outlines_computed: usize,
    pub sky_regions_computed: usize,
}

impl RegionCache {
    /// `shadow_fit::silhouette_outline` of `vertices` (model space, placed by `model`) in the
    /// map drawn through `light_view_proj`, onto the ground z = `ground_z`, for a `size`² map,
    /// a sun of angular radius tan = `tan_radius` and a model of bounding `radius`.
    pub fn outline<I: IntoIterator<Item = glam::Vec3>>(
        &mut self,
        (light_view_proj, model): (glam::Mat4, glam::Mat4),
        vertices: impl FnOnce() -> I,
        ground_z: f32,
        (size, tan_radius, radius): (u32, f32, f32),
    ) -> &[glam::Vec2] {
        let mut key = [0u32; 35];
        let values = light_view_proj.to_cols_array().into_iter().chain(model.to_cols_array()).chain([ground_z, tan_radius, radius]);
        for (k, v) in key.iter_mut().zip(values) {
            *k = v.to_bits();
        }
        key[34] = size;
        if self.outline.as_ref().is_none_or(|(held, _)| *held != key) {
            let outline = shadow_fit::silhouette_outline(light_view_proj, (model, vertices()), ground_z, (size, tan_radius, radius));
            self.outlines_computed += 1;
            self.outline = Some((key, outline));
        }
        self.outline.as_ref().map_or(&[], |(_, o)| o)
    }

    /// `shadow_fit::sky_region` of `sky` where its occlusion reaches `min_occlusion`. The map's
    /// texels hide whole 255ths of the sky, so the region only changes when the threshold
    /// crosses one.
    pub fn sky(&mut self, sky: &Arc<GroundSky>, min_occlusion: f32) -> &[glam::Vec2] {
        let levels = (min_occlusion.max(0.0) * 255.0 - 1e-3).ceil().clamp(1.0, 256.0) as u32;
        if self.sky.as_ref().is_none_or(|(held, l, _)| !Arc::ptr_eq(held, sky) || *l != levels) {
            let region = shadow_fit::sky_region(sky, levels as f32 / 255.0);
            self.sky_regions_computed += 1;
            self.sky = Some((sky.clone(), levels, region));
        }
        self.sky.as_ref().map_or(&[], |(_, _, r)| r)
    }
}

impl GroundPass {
    /// Reads the Frame and Light uniform buffers, one of the sun's `shadow_maps` per frame and the
    /// ground's sky visibility.
    pub fn new(
        (device, queue): (&wgpu::Device, &wgpu::Queue),
        pipelines: &Pipelines,
        (frame, light): (&wgpu::Buffer, &wgpu::Buffer),
        shadow_maps: &[wgpu::TextureView],
    ) -> GroundPass {
        let instance = build::uniform_buffer::<InstanceUniforms>(device, "ground plane");
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let side = GROUND_TEXELS;
        let sky = build::texture(device, "ground sky visibility", (side, side, 1), wgpu::TextureFormat::R8Unorm, 1, usage);
        // The whole sky everywhere until a model is placed.
        build::write_layer(queue, &sky, 0, &vec![255; (side * side) as usize]);
        let sky_view = sky.create_view(&Default::default());
        let bind_groups = shadow_maps
            .iter()
            .map(|map| {
                build::bind_group(
                    device,
                    "ground",
                    &pipelines.ground.layout,
                    &[
                        frame.as_entire_binding(),
                        instance.as_entire_binding(),
                        wgpu::BindingResource::TextureView(map),
                        wgpu::BindingResource::Sampler(&pipelines.shadow_sampler),
                        light.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&sky_view),
                        wgpu::BindingResource::Sampler(&pipelines.linear_sampler),
                        wgpu::BindingResource::Sampler(&pipelines.shadow_gather_sampler),
                    ],
                )
            })
            .collect();
        let size = (GROUND_VERTICES * std::mem::size_of::<[f32; 2]>()) as u64;
        let usage = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
        let vertices = build::buffer(device, "ground triangles", size, usage);
        GroundPass {
            pipeline: pipelines.ground.shadowed.clone(),
            sky_only: pipelines.ground.sky_only.clone(),
            vertices,
            counts: (0, 0),
            bind_groups,
            instance,
            sky,
        }
    }

    /// The ground's sky visibility under the model as placed now (once per placement). A map of
    /// another size than [`GROUND_TEXELS`] is an error.
    pub fn write_sky(&self, queue: &wgpu::Queue, sky: &GroundSky) -> Result<()> {
        if sky.size != GROUND_TEXELS || sky.visibility.len() != (sky.size * sky.size) as usize {
            bail!("a ground sky map of {} texels a side; the ground pass holds {GROUND_TEXELS}", sky.size);
        }
        build::write_layer(queue, &self.sky, 0, &sky_texels(sky));
        Ok(())
    }

    /// This frame's plane transform and triangles.
    pub fn write(&mut self, queue: &wgpu::Queue, plane: &InstanceUniforms, mesh: &GroundMesh) {
        queue.write_buffer(&self.instance, 0, bytemuck::bytes_of(plane));
        let used = (mesh.shadowed + mesh.sky_only) as usize;
        if used > 0 {
            queue.write_buffer(&self.vertices, 0, bytemuck::cast_slice(&mesh.vertices[..used]));
        }
        self.counts = (mesh.shadowed, mesh.sky_only);
    }

    /// The vertices drawn with the shadow lookup and without.
    pub fn counts(&self) -> (u32, u32) {
        self.counts
    }

    /// Draw the ground, sampling shadow map `shadow_index`: the part where the sun's shadow can
    /// fall with the shadow lookup, the rest without.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, shadow_index: usize) {
        let (shadowed, sky_only) = self.counts;
        pass.set_bind_group(0, &self.bind_groups[shadow_index], &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        if shadowed > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.draw(0..shadowed, 0..1);
        }
        if sky_only > 0 {
            pass.set_pipeline(&self.sky_only);
            pass.draw(shadowed..shadowed + sky_only, 0..1);
        }
    }

    /// Draw all of the ground with `pipeline` (the float twin of the shadowed pipeline in
    /// render/layers.rs), sampling shadow map `shadow_index`.
    pub fn draw_with(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, shadow_index: usize) {
        let (shadowed, sky_only) = self.counts;
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind_groups[shadow_index], &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.draw(0..shadowed + sky_only, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colour::linear_to_srgb;

    #[test]
    fn an_invisible_loss_moves_no_srgb_value_by_more_than_a_level() {
        // 1 / (255 * 1.055 / 2.4 + 1) = 1 / 113.094 = 0.0088422.
        assert!((INVISIBLE_LOSS - 0.008_842_2).abs() < 1e-6, "{INVISIBLE_LOSS}");
        let moved = |x: f32, loss: f32| 255.0 * (linear_to_srgb(x) - linear_to_srgb(x * (1.0 - loss)));
        let worst = (1..=10_000).map(|i| moved(i as f32 / 10_000.0, INVISIBLE_LOSS)).fold(0.0, f32::max);
        // Tight: white moves by just under a level; twice the loss moves it by two.
        assert!(worst <= 1.0 && worst > 0.98, "{worst}");
        assert!(moved(1.0, 2.0 * INVISIBLE_LOSS) > 1.97);
    }

    #[test]
    fn the_sky_loss_per_occlusion_is_the_skys_share_per_channel() {
        let light = |sun: [f32; 3], sky_share: f32, sky: [f32; 3]| LightUniforms {
            sh: [[0.0; 4]; 9],
            sun: [sun[0], sun[1], sun[2], 0.0],
            ground_square: [0.0; 4],
            ground: [0.0; 4],
            ground_sky: [sky_share, sky[0], sky[1], sky[2]],
        };
        // Grey light: the sky's share of the ground's light, 0.3 / (0.7 + 0.3).
        assert!((sky_loss_per_occlusion(&light([1.0; 3], 0.3, [1.0; 3]), 0.7) - 0.3).abs() < 1e-6);
        // Overcast (no sun share): the sky's own strength.
        assert!((sky_loss_per_occlusion(&light([1.0; 3], 0.6, [1.0; 3]), 0.0) - 0.6).abs() < 1e-6);
        // A warm sun (1.2, 1, 0.6) under a blue sky (0.8, 1, 1.4), shares 0.7 : 0.3: blue loses
        // most, 0.3 * 1.4 / ((0.7 * 0.6 + 0.3 * 1.4) / 1.0) = 0.42 / 0.84 = 0.5.
        assert!((sky_loss_per_occlusion(&light([1.2, 1.0, 0.6], 0.3, [0.8, 1.0, 1.4]), 0.7) - 0.5).abs() < 1e-6);
        assert_eq!(sky_loss_per_occlusion(&light([1.0; 3], 0.0, [1.0; 3]), 0.0), 0.0);
    }
}
