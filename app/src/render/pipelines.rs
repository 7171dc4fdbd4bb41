//! The render pipelines of every pass (each pass builds its own, in its own file under
//! `passes/`) and the samplers they share: created once per device, then reused by every frame
//! and every composite in the process.

use super::passes::{background, ground, ground_sun, model, shadow, vertex_sun};
use super::shaders::{Technique, source};
use crate::gpu::Gpu;
use crate::gpu::build;
use anyhow::Result;
use std::sync::Arc;

/// Colour format of every render target: sRGB storage, linear shading.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Multisampling of a frame's float layers (render/layers.rs: offline, so the full 4× whatever
/// the frame's [`super::Antialiasing`]); a supersampled still's layers take its own samples.
pub const LAYER_SAMPLES: u32 = 4;

/// Interleaved model vertex: position, normal, uv, ambient occlusion, bent normal, the sky's
/// colour (72 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    /// Shares of the sky's light, of the ground's light where the sky lights it, and of the
    /// ground's light, that the vertex gets past the model, 0..1, and the model's own reflected
    /// light (scene::occlusion::model_sky_ground; shaders/model.wgsl `VertexIn.ao`, location
    /// [`AO_LOCATION`]); (1, 1, 1, 0) until the model's occlusion is computed.
    pub ao: [f32; 4],
    /// The mean direction (model space) of the rays that pass the model, along which the sky's
    /// colour is looked up (scene::occlusion::VertexLight::bent; shaders/model.wgsl
    /// `VertexIn.bent`, location [`BENT_LOCATION`]); the normal until the occlusion is computed.
    /// Its length over the normal's is the sky's light the vertex gets under the frame's sky
    /// (render::model_cache::PreparedModel::vertices_under, written before sh9-ggx draws).
    pub bent: [f32; 3],
    /// The colour of the sky's light the vertex gets through its own open rays and the model's
    /// bounces, each channel over its BT.709 luminance (render::model_cache::PreparedModel::
    /// vertices_under; shaders/model.wgsl `VertexIn.tint`, location [`TINT_LOCATION`]); 0 until
    /// computed, when sh9-ggx takes the sky's SH9 colour along the bent normal instead.
    pub tint: [f32; 3],
}

/// Shader location of [`Vertex::ao`].
pub const AO_LOCATION: u32 = 3;
/// Shader location of [`Vertex::bent`].
pub const BENT_LOCATION: u32 = 4;
/// Shader location of [`Vertex::tint`].
pub const TINT_LOCATION: u32 = 6;
/// Shader location of the sun's visibility per vertex (shaders/model.wgsl `VertexIn.sun`), a
/// second vertex buffer written by render::passes::vertex_sun.
pub const SUN_LOCATION: u32 = 5;
/// Shader locations of the light at a vertex (shaders/model.wgsl `LightIn`: what the albedo
/// multiplies, what is added), a third vertex buffer written by the vertex-light pass
/// (render::passes::model::ModelPass::encode_vertex_light).
pub const LIGHT_LOCATION: u32 = 7;
pub const LIGHT_SPECULAR_LOCATION: u32 = 8;

pub(super) fn pipeline(device: &wgpu::Device, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    pipeline_into(device, spec, COLOR_FORMAT)
}

/// A full-screen pass's pipeline (no vertex buffers, no depth write): `technique` with bind-group
/// `layout`, drawing into `format` targets of `samples` per pixel, blended with `blend`.
pub(super) fn screen_pipeline(
    device: &wgpu::Device,
    (technique, layout): (Technique, &wgpu::BindGroupLayout),
    (format, samples): (wgpu::TextureFormat, u32),
    blend: Option<wgpu::BlendState>,
) -> wgpu::RenderPipeline {
    let spec = PipelineSpec {
        technique,
        layouts: &[layout],
        vertex_buffers: &[],
        depth: depth_state(false, wgpu::DepthBiasState::default()),
        samples,
        blend: Some(blend),
    };
    pipeline_into(device, spec, format)
}

/// A pass's pipeline drawing into `format` targets (the float layers, render/layers.rs).
pub(super) fn pipeline_into(device: &wgpu::Device, spec: PipelineSpec<'_>, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
    let label = format!("{:?}", spec.technique);
    let module = build::shader(device, &label, source(spec.technique));
    build::render_pipeline(
        device,
        build::PipelineSpec {
            label: &label,
            module: &module,
            layouts: spec.layouts,
            vertex_buffers: spec.vertex_buffers,
            colour: spec.blend.map(|blend| wgpu::ColorTargetState { format, blend, write_mask: wgpu::ColorWrites::ALL }),
            depth: spec.depth,
            samples: spec.samples,
            constants: &[],
        },
    )
}

pub(super) struct PipelineSpec<'a> {
    pub technique: Technique,
    pub layouts: &'a [&'a wgpu::BindGroupLayout],
    pub vertex_buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    pub depth: Option<wgpu::DepthStencilState>,
    pub samples: u32,
    /// None: depth-only pipeline.
    pub blend: Option<Option<wgpu::BlendState>>,
}

pub(super) fn depth_state(write: bool, bias: wgpu::DepthBiasState) -> Option<wgpu::DepthStencilState> {
    Some(wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        depth_compare: Some(wgpu::CompareFunction::LessEqual),
        stencil: Default::default(),
        bias,
    })
}

/// A pass's render pipeline and the layout of its bind group 0 (the pass's own resources).
pub struct PassPipeline {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::RenderPipeline,
}

pub struct Pipelines {
    /// Samples per pixel of the composite's targets that these pipelines draw into.
    pub samples: u32,
    pub env_view: PassPipeline,
    /// The environment view of an equirectangular map (no cube map in between).
    pub env_view_equirect: PassPipeline,
    pub background: PassPipeline,
    pub shadow: PassPipeline,
    pub ground: ground::GroundPipelines,
    /// The ground's sun visibility in ground space (render::passes::ground_sun).
    pub ground_sun: PassPipeline,
    pub model: model::ModelPipelines,
    /// The model's sun per vertex (compute).
    pub vertex_sun: vertex_sun::VertexSunPipelines,
    /// The post-process antialiasing pass (render/antialiasing.rs).
    pub fxaa: PassPipeline,
    pub linear_sampler: wgpu::Sampler,
    pub repeat_sampler: wgpu::Sampler,
    /// Linear, wrapping around horizontally and clamped vertically: an equirectangular map's
    /// azimuth goes round, its elevation stops at the poles.
    pub equirect_sampler: wgpu::Sampler,
    pub shadow_sampler: wgpu::Sampler,
    /// Nearest texel, no comparison: the soft shadow's blocker search gathers the map's depths
    /// with it (frame.wgsl `sun_visibility_soft`).
    pub shadow_gather_sampler: wgpu::Sampler,
}

impl Pipelines {
    /// The pipelines of `gpu`'s device for composites of `samples` samples per pixel: built
    /// once per sample count, inside a validation scope, and shared by every compositor on it
    /// (a second composite in the same process compiles no shaders).
    pub fn shared(gpu: &Gpu, samples: u32) -> Result<Arc<Pipelines>> {
        gpu.shared_per("the render pipelines", samples, |gpu| Ok(Pipelines::new(&gpu.device, samples)))
    }

    fn new(device: &wgpu::Device, samples: u32) -> Pipelines {
        Pipelines {
            samples,
            env_view: background::env_view_pipeline(device),
            env_view_equirect: background::env_view_equirect_pipeline(device),
            background: background::pipeline(device, samples),
            shadow: shadow::pipeline(device),
            ground: ground::pipeline(device, samples),
            ground_sun: ground_sun::pipeline(device),
            model: model::pipelines(device, samples),
            vertex_sun: vertex_sun::pipelines(device),
            fxaa: super::antialiasing::fxaa_pipeline(device),
            linear_sampler: build::linear_sampler(device, "clamp", wgpu::AddressMode::ClampToEdge),
            repeat_sampler: build::linear_sampler(device, "repeat", wgpu::AddressMode::Repeat),
            equirect_sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("equirect"),
                address_mode_u: wgpu::AddressMode::Repeat,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            }),
            shadow_sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("shadow"),
                compare: Some(wgpu::CompareFunction::LessEqual),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            }),
            shadow_gather_sampler: device.create_sampler(&wgpu::SamplerDescriptor { label: Some("shadow gather"), ..Default::default() }),
        }
    }
}
