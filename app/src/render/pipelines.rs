//! Bind-group layouts, samplers and render pipelines: created once per device and target
//! format, then reused by every frame and every composite in the process.

use super::shaders::{Technique, source};
use crate::gpu::Gpu;
use crate::gpu::build::{self, depth_texture_entry, layout, sampler_entry, texture_entry, uniform};
use anyhow::Result;
use std::sync::Arc;
use wgpu::ShaderStages;

/// Colour format of every render target: sRGB storage, linear shading.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Multisampling of the composite (coverage becomes the model layer's alpha).
pub const SAMPLES: u32 = 4;
/// Side of the square sun shadow map.
pub const SHADOW_MAP_SIZE: u32 = 2048;

/// Interleaved model vertex: position, normal, uv.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

pub struct Pipelines {
    pub env_view_layout: wgpu::BindGroupLayout,
    pub background_layout: wgpu::BindGroupLayout,
    pub shadow_layout: wgpu::BindGroupLayout,
    pub ground_layout: wgpu::BindGroupLayout,
    pub model_layout: wgpu::BindGroupLayout,
    pub material_layout: wgpu::BindGroupLayout,
    pub env_view: wgpu::RenderPipeline,
    pub background: wgpu::RenderPipeline,
    pub shadow: wgpu::RenderPipeline,
    pub ground: wgpu::RenderPipeline,
    pub model: wgpu::RenderPipeline,
    pub linear_sampler: wgpu::Sampler,
    pub repeat_sampler: wgpu::Sampler,
    pub shadow_sampler: wgpu::Sampler,
}

fn pipeline(device: &wgpu::Device, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let label = format!("{:?}", spec.technique);
    let module = build::shader(device, &label, source(spec.technique));
    build::render_pipeline(
        device,
        build::PipelineSpec {
            label: &label,
            module: &module,
            layouts: spec.layouts,
            vertex_buffers: spec.vertex_buffers,
            colour: spec.blend.map(|blend| wgpu::ColorTargetState { format: COLOR_FORMAT, blend, write_mask: wgpu::ColorWrites::ALL }),
            depth: spec.depth,
            samples: spec.samples,
            constants: &[],
        },
    )
}

struct PipelineSpec<'a> {
    technique: Technique,
    layouts: &'a [&'a wgpu::BindGroupLayout],
    vertex_buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    depth: Option<wgpu::DepthStencilState>,
    samples: u32,
    /// None: depth-only pipeline.
    blend: Option<Option<wgpu::BlendState>>,
}

fn depth_state(write: bool, bias: wgpu::DepthBiasState) -> Option<wgpu::DepthStencilState> {
    Some(wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        depth_compare: Some(wgpu::CompareFunction::LessEqual),
        stencil: Default::default(),
        bias,
    })
}

impl Pipelines {
    /// The pipelines of `gpu`'s device: built once, inside a validation scope, and shared by
    /// every compositor on it (a second composite in the same process compiles no shaders).
    pub fn shared(gpu: &Gpu) -> Result<Arc<Pipelines>> {
        gpu.shared("the render pipelines", |gpu| Ok(Pipelines::new(&gpu.device)))
    }

    fn new(device: &wgpu::Device) -> Pipelines {
        use wgpu::SamplerBindingType::{Comparison, Filtering};
        use wgpu::TextureViewDimension::{Cube, D2};
        const FS: ShaderStages = ShaderStages::FRAGMENT;
        let vs_fs = ShaderStages::VERTEX | ShaderStages::FRAGMENT;
        let env_view_layout =
            layout(device, "env_view", &[uniform(0, vs_fs), texture_entry(1, FS, Cube, true), sampler_entry(2, FS, Filtering)]);
        let background_layout = layout(device, "background", &[texture_entry(0, FS, D2, true), sampler_entry(1, FS, Filtering)]);
        let shadow_layout = layout(device, "shadow", &[uniform(0, ShaderStages::VERTEX), uniform(1, ShaderStages::VERTEX)]);
        let ground_layout =
            layout(device, "ground", &[uniform(0, vs_fs), uniform(1, vs_fs), depth_texture_entry(2, FS), sampler_entry(3, FS, Comparison)]);
        let model_layout = layout(
            device,
            "model",
            &[
                uniform(0, vs_fs),
                uniform(1, vs_fs),
                texture_entry(2, FS, Cube, true),
                sampler_entry(3, FS, Filtering),
                texture_entry(4, FS, D2, true),
                sampler_entry(5, FS, Filtering),
                depth_texture_entry(6, FS),
                sampler_entry(7, FS, Comparison),
                uniform(8, FS),
            ],
        );
        let material_layout =
            layout(device, "material", &[uniform(0, FS), texture_entry(1, FS, D2, true), sampler_entry(2, FS, Filtering)]);

        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2],
        };
        let position_only = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3],
        };
        let no_bias = wgpu::DepthBiasState::default();
        let premultiplied_over = Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING);

        let env_view = pipeline(
            device,
            PipelineSpec {
                technique: Technique::EnvView,
                layouts: &[&env_view_layout],
                vertex_buffers: &[],
                depth: None,
                samples: 1,
                blend: Some(None),
            },
        );
        let background = pipeline(
            device,
            PipelineSpec {
                technique: Technique::Background,
                layouts: &[&background_layout],
                vertex_buffers: &[],
                depth: depth_state(false, no_bias),
                samples: SAMPLES,
                blend: Some(None),
            },
        );
        let shadow = pipeline(
            device,
            PipelineSpec {
                technique: Technique::Shadow,
                layouts: &[&shadow_layout],
                vertex_buffers: &[Some(position_only)],
                depth: depth_state(true, wgpu::DepthBiasState { constant: 2, slope_scale: 2.0, clamp: 0.0 }),
                samples: 1,
                blend: None,
            },
        );
        let ground = pipeline(
            device,
            PipelineSpec {
                technique: Technique::Ground,
                layouts: &[&ground_layout],
                vertex_buffers: &[],
                depth: depth_state(false, no_bias),
                samples: SAMPLES,
                blend: Some(Some(wgpu::BlendState::ALPHA_BLENDING)),
            },
        );
        let model = pipeline(
            device,
            PipelineSpec {
                technique: Technique::Model,
                layouts: &[&model_layout, &material_layout],
                vertex_buffers: &[Some(vertex_layout)],
                depth: depth_state(true, no_bias),
                samples: SAMPLES,
                blend: Some(premultiplied_over),
            },
        );

        let linear_sampler = build::linear_sampler(device, "clamp", wgpu::AddressMode::ClampToEdge);
        let repeat_sampler = build::linear_sampler(device, "repeat", wgpu::AddressMode::Repeat);
        let shadow_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            compare: Some(wgpu::CompareFunction::LessEqual),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Pipelines {
            env_view_layout,
            background_layout,
            shadow_layout,
            ground_layout,
            model_layout,
            material_layout,
            env_view,
            background,
            shadow,
            ground,
            model,
            linear_sampler,
            repeat_sampler,
            shadow_sampler,
        }
    }
}
