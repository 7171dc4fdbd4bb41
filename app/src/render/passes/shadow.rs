//! The shadow pass (step 2 of DESIGN.md "One frame"): the model's depth seen from the sun (a
//! directional light) into a square shadow map, which the ground and model passes sample. One
//! map per size in `shadow_fit::SHADOW_MAP_SIZES`, allocated once; a frame draws into the one
//! its shadow's footprint on screen needs (switching allocates nothing).

use super::model::ModelGpu;
use crate::gpu::build;
use crate::render::pipelines::{DEPTH_FORMAT, PassPipeline, PipelineSpec, Pipelines, Vertex, depth_state, pipeline as make};
use crate::render::shaders::Technique;
use crate::render::shadow_fit::SHADOW_MAP_SIZES;
use wgpu::ShaderStages;

/// The shadow pipeline: model positions only, depth with a slope-scaled bias, no colour.
pub fn pipeline(device: &wgpu::Device) -> PassPipeline {
    let layout = build::layout(device, "shadow", &[build::uniform(0, ShaderStages::VERTEX), build::uniform(1, ShaderStages::VERTEX)]);
    let position_only = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3],
    };
    let pipeline = make(
        device,
        PipelineSpec {
            technique: Technique::Shadow,
            layouts: &[&layout],
            vertex_buffers: &[Some(position_only)],
            depth: depth_state(true, wgpu::DepthBiasState { constant: 2, slope_scale: 2.0, clamp: 0.0 }),
            samples: 1,
            blend: None,
        },
    );
    PassPipeline { layout, pipeline }
}

pub struct ShadowPass {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
    /// One depth map per side in `sizes`.
    maps: Vec<wgpu::TextureView>,
    /// Ascending sides of `maps`: SHADOW_MAP_SIZES up to what the device allows.
    sizes: Vec<u32>,
}

impl ShadowPass {
    /// The shadow maps (each size of SHADOW_MAP_SIZES the device allows, at least the smallest
    /// clamped to its limit), reading the frame and the model's instance uniforms.
    pub fn new(device: &wgpu::Device, pipelines: &Pipelines, frame: &wgpu::Buffer, instance: &wgpu::Buffer) -> ShadowPass {
        let limit = device.limits().max_texture_dimension_2d;
        let mut sizes: Vec<u32> = SHADOW_MAP_SIZES.iter().map(|&s| s.min(limit)).collect();
        sizes.dedup();
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let maps = sizes
            .iter()
            .map(|&size| build::texture(device, "shadow map", (size, size, 1), DEPTH_FORMAT, 1, usage).create_view(&Default::default()))
            .collect();
        let bind_group =
            build::bind_group(device, "shadow", &pipelines.shadow.layout, &[frame.as_entire_binding(), instance.as_entire_binding()]);
        ShadowPass { pipeline: pipelines.shadow.pipeline.clone(), bind_group, maps, sizes }
    }

    /// Clear every map to the far plane (nothing blocks the sun), once when the maps are made:
    /// a frame that skips the pass (no sunlight: every lookup is multiplied by it) samples a map
    /// that is either that or an earlier frame's shadow, never undefined depths.
    pub fn clear_all(&self, device: &wgpu::Device, queue: &wgpu::Queue) {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shadow maps cleared") });
        for index in 0..self.maps.len() {
            drop(self.begin(&mut encoder, index, None));
        }
        queue.submit([encoder.finish()]);
    }

    /// The depth views of the maps, in the order of [`ShadowPass::sizes`].
    pub fn maps(&self) -> &[wgpu::TextureView] {
        &self.maps
    }

    /// Sides of the square shadow maps in texels, ascending.
    pub fn sizes(&self) -> &[u32] {
        &self.sizes
    }

    /// Which map has side `size` (the largest if none has).
    pub fn index_of(&self, size: u32) -> usize {
        self.sizes.iter().position(|&s| s == size).unwrap_or(self.sizes.len() - 1)
    }

    /// Begin the pass into map `index`: cleared to the far plane.
    pub fn begin<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        index: usize,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.maps[index],
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// The model's depth at level of detail `level`.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, model: &ModelGpu, level: usize) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        model.draw_meshes(pass, None, level);
    }
}
