//! The ground pass (step 4 of DESIGN.md "One frame"): an invisible shadow-catcher plane under the
//! model darkens the background where the shadow map says the sun is blocked, with a penumbra
//! that follows the sun's size (frame.wgsl `sun_visibility_soft`), and where the model hides its
//! sky: the ground's sky visibility under the placed model (render::model_cache
//! PreparedModel::ground_sky) is a small texture written once per placement and sky shape, never
//! per frame.

use super::super::uniforms::InstanceUniforms;
use crate::gpu::build;
use crate::render::pipelines::{COLOR_FORMAT, PassPipeline, Pipelines, screen_pipeline};
use crate::render::shaders::Technique;
use crate::scene::occlusion::{self, GroundSky};
use anyhow::{Result, bail};
use wgpu::ShaderStages;

/// The ground pipeline: six vertices from the vertex index; the background is multiplied by one
/// minus the shader's output per channel ([`DARKEN`]).
pub fn pipeline(device: &wgpu::Device, samples: u32) -> PassPipeline {
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
    let pipeline = pipeline_for(device, &layout, COLOR_FORMAT, samples);
    PassPipeline { layout, pipeline }
}

/// The ground pipeline with bind-group `layout`, drawing into `format` targets of `samples` per
/// pixel.
pub fn pipeline_for(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
    samples: u32,
) -> wgpu::RenderPipeline {
    screen_pipeline(device, (Technique::Ground, layout), (format, samples), Some(DARKEN))
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
        GroundPass { pipeline: pipelines.ground.pipeline.clone(), bind_groups, instance, sky }
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

    /// This frame's plane transform.
    pub fn write(&self, queue: &wgpu::Queue, plane: &InstanceUniforms) {
        queue.write_buffer(&self.instance, 0, bytemuck::bytes_of(plane));
    }

    /// Draw the plane, sampling shadow map `shadow_index`.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, shadow_index: usize) {
        self.draw_with(pass, &self.pipeline, shadow_index);
    }

    /// Draw with `pipeline` (this pass's, or its float twin in render/layers.rs), sampling
    /// shadow map `shadow_index`.
    pub fn draw_with(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, shadow_index: usize) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind_groups[shadow_index], &[]);
        pass.draw(0..6, 0..1);
    }
}
