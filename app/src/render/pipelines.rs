//! Bind-group layouts, samplers and render pipelines: created once per device and target
//! format, then reused by every frame and every composite in the process.

use super::shaders::{Technique, source};
use wgpu::{BindingType, ShaderStages};

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

fn uniform(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

fn texture(binding: u32, view_dimension: wgpu::TextureViewDimension) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: ShaderStages::FRAGMENT,
        ty: BindingType::Texture { sample_type: wgpu::TextureSampleType::Float { filterable: true }, view_dimension, multisampled: false },
        count: None,
    }
}

fn depth_texture(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: ShaderStages::FRAGMENT,
        ty: BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Depth,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

fn sampler(binding: u32, ty: wgpu::SamplerBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility: ShaderStages::FRAGMENT, ty: BindingType::Sampler(ty), count: None }
}

fn layout(device: &wgpu::Device, label: &str, entries: &[wgpu::BindGroupLayoutEntry]) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
}

struct PipelineSpec<'a> {
    technique: Technique,
    layouts: &'a [Option<&'a wgpu::BindGroupLayout>],
    vertex_buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    depth: Option<wgpu::DepthStencilState>,
    samples: u32,
    /// None: depth-only pipeline.
    blend: Option<Option<wgpu::BlendState>>,
}

fn pipeline(device: &wgpu::Device, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let label = format!("{:?}", spec.technique);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&label),
        source: wgpu::ShaderSource::Wgsl(source(spec.technique).into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(&label),
        bind_group_layouts: spec.layouts,
        immediate_size: 0,
    });
    let targets =
        spec.blend.map(|blend| [Some(wgpu::ColorTargetState { format: COLOR_FORMAT, blend, write_mask: wgpu::ColorWrites::ALL })]);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(&label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: spec.vertex_buffers,
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: spec.depth,
        multisample: wgpu::MultisampleState { count: spec.samples, ..Default::default() },
        fragment: targets.as_ref().map(|targets| wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
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
    pub fn new(device: &wgpu::Device) -> Pipelines {
        use wgpu::SamplerBindingType::{Comparison, Filtering};
        use wgpu::TextureViewDimension::{Cube, D2};
        let vs_fs = ShaderStages::VERTEX | ShaderStages::FRAGMENT;
        let env_view_layout = layout(device, "env_view", &[uniform(0, vs_fs), texture(1, Cube), sampler(2, Filtering)]);
        let background_layout = layout(device, "background", &[texture(0, D2), sampler(1, Filtering)]);
        let shadow_layout = layout(device, "shadow", &[uniform(0, ShaderStages::VERTEX), uniform(1, ShaderStages::VERTEX)]);
        let ground_layout = layout(device, "ground", &[uniform(0, vs_fs), uniform(1, vs_fs), depth_texture(2), sampler(3, Comparison)]);
        let model_layout = layout(
            device,
            "model",
            &[
                uniform(0, vs_fs),
                uniform(1, vs_fs),
                texture(2, Cube),
                sampler(3, Filtering),
                texture(4, D2),
                sampler(5, Filtering),
                depth_texture(6),
                sampler(7, Comparison),
                uniform(8, ShaderStages::FRAGMENT),
            ],
        );
        let material_layout = layout(device, "material", &[uniform(0, ShaderStages::FRAGMENT), texture(1, D2), sampler(2, Filtering)]);

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
                layouts: &[Some(&env_view_layout)],
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
                layouts: &[Some(&background_layout)],
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
                layouts: &[Some(&shadow_layout)],
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
                layouts: &[Some(&ground_layout)],
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
                layouts: &[Some(&model_layout), Some(&material_layout)],
                vertex_buffers: &[Some(vertex_layout)],
                depth: depth_state(true, no_bias),
                samples: SAMPLES,
                blend: Some(premultiplied_over),
            },
        );

        let linear = |address: wgpu::AddressMode| wgpu::SamplerDescriptor {
            address_mode_u: address,
            address_mode_v: address,
            address_mode_w: address,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        };
        let linear_sampler = device.create_sampler(&linear(wgpu::AddressMode::ClampToEdge));
        let repeat_sampler = device.create_sampler(&linear(wgpu::AddressMode::Repeat));
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
