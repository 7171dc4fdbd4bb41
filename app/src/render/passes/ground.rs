//! The ground pass (step 4 of DESIGN.md "One frame"): an invisible shadow-catcher plane under the
//! model darkens the background where the shadow map says the sun is blocked, with a penumbra
//! that follows the sun's size (frame.wgsl `sun_visibility_soft`).

use super::super::uniforms::InstanceUniforms;
use crate::gpu::build;
use crate::render::pipelines::{PassPipeline, PipelineSpec, Pipelines, SAMPLES, depth_state, pipeline as make};
use crate::render::shaders::Technique;
use wgpu::ShaderStages;

/// The ground pipeline: six vertices from the vertex index, alpha-blended over the background.
pub fn pipeline(device: &wgpu::Device) -> PassPipeline {
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
        ],
    );
    let pipeline = make(
        device,
        PipelineSpec {
            technique: Technique::Ground,
            layouts: &[&layout],
            vertex_buffers: &[],
            depth: depth_state(false, wgpu::DepthBiasState::default()),
            samples: SAMPLES,
            blend: Some(Some(wgpu::BlendState::ALPHA_BLENDING)),
        },
    );
    PassPipeline { layout, pipeline }
}

pub struct GroundPass {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
    /// The plane's transform (`InstanceUniforms`).
    instance: wgpu::Buffer,
}

impl GroundPass {
    /// Reads the Frame and Light uniform buffers and the sun's `shadow_map`.
    pub fn new(
        device: &wgpu::Device,
        pipelines: &Pipelines,
        (frame, light): (&wgpu::Buffer, &wgpu::Buffer),
        shadow_map: &wgpu::TextureView,
    ) -> GroundPass {
        let instance = build::uniform_buffer::<InstanceUniforms>(device, "ground plane");
        let bind_group = build::bind_group(
            device,
            "ground",
            &pipelines.ground.layout,
            &[
                frame.as_entire_binding(),
                instance.as_entire_binding(),
                wgpu::BindingResource::TextureView(shadow_map),
                wgpu::BindingResource::Sampler(&pipelines.shadow_sampler),
                light.as_entire_binding(),
            ],
        );
        GroundPass { pipeline: pipelines.ground.pipeline.clone(), bind_group, instance }
    }

    /// This frame's plane transform.
    pub fn write(&self, queue: &wgpu::Queue, plane: &InstanceUniforms) {
        queue.write_buffer(&self.instance, 0, bytemuck::bytes_of(plane));
    }

    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..6, 0..1);
    }
}
