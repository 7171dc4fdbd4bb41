//! The model pass (step 5 of DESIGN.md "One frame"): shading, reflection/refraction and colour
//! correction in one fragment shader, over the background and ground in the multisampled target.
//! Also the model's GPU copy (vertex/index buffers and material bind groups), which the shadow pass
//! draws too.

use crate::colour::correction::ColourCorrection;
use crate::gpu::{Gpu, build};
use crate::light::ggx;
use crate::render::LightingMethod;
use crate::render::environment::EnvironmentViews;
use crate::render::mip_chain;
use crate::render::model_cache::PreparedModel;
use crate::render::params::MaterialTerms;
use crate::render::passes::vertex_sun;
use crate::render::pipelines::{
    AO_LOCATION, BENT_LOCATION, COLOR_FORMAT, LIGHT_LOCATION, LIGHT_SPECULAR_LOCATION, Pipelines, SUN_LOCATION, TINT_LOCATION, Vertex,
    depth_state,
};
use crate::render::shaders::{Technique, source};
use crate::render::uniforms::{FrameUniforms, InstanceUniforms, LightUniforms, MaterialUniforms, SplitLevelUniforms};
use crate::scene::lod::IndexRange;
use crate::scene::{Model, Sides};
use anyhow::{Result, anyhow};
use glam::Vec3;
use std::sync::Arc;
use wgpu::SamplerBindingType::{Comparison, Filtering, NonFiltering};
use wgpu::ShaderStages;
use wgpu::TextureViewDimension::{Cube, D2};
use wgpu::util::DeviceExt;

/// The longest triangle edge (pixels on screen at the model's nearest point) of a mesh whose
/// sun visibility the model pass may interpolate from its vertices ([`super::vertex_sun`]), over
/// the triangles that cover [`SUN_EDGE_AREA`] of the mesh's area; a mesh with longer edges
/// looks the shadow map up per pixel, since interpolating across a large triangle would spread
/// a shadow's edge over it (docs/PERFORMANCE.md, ninth and tenth sessions). The default of
/// [`ModelPass::set_sun_edge_limit`].
pub const MAX_SUN_EDGE_PX: f32 = 20.0;
/// The share of a mesh's area whose triangles' edges [`MAX_SUN_EDGE_PX`] bounds: a few long
/// slivers (a simplified level has some) cover little and do not decide.
pub const SUN_EDGE_AREA: f32 = 0.95;
/// The longest triangle edge (pixels on screen, as [`MAX_SUN_EDGE_PX`] measures it) of a mesh
/// drawn with sh9-ggx whose whole light is computed at its vertices and interpolated
/// ([`Shading::LightFromVertices`]), the albedo still per pixel; its normal must not turn more
/// than [`light_turn_limit`] across a triangle either. Lavapipe shades each small triangle's
/// whole 4×4 pixel blocks, so on `bench frame`'s dragon the model pass takes 30 % less time
/// (docs/PERFORMANCE.md, sixteenth session). Over 16 px the view's direction (for the
/// reflection) and the sun's shadow (20 px, [`MAX_SUN_EDGE_PX`]) change across a triangle. The
/// default of [`ModelPass::set_light_limits`].
pub const MAX_LIGHT_EDGE_PX: f32 = 16.0;
/// The largest mean turn of the normal across a triangle ([`mean_normal_turn`], radians) of a
/// matte mesh lit from its vertices: the light is a curved function of the normal, and what its
/// interpolation misses grows with that turn. The budget: mean FLIP 0.05 over the model against
/// the per-pixel light, what the level of detail a frame draws already costs `bench frame`'s
/// dragon (0.053 over its pixels against the full detail; the frame's goal, 0.01 over the frame,
/// holds with both: 0.0027). Measured on UV spheres in the sunny quarry (tests/vertex_light.rs
/// `bench_vertex_light`, 320×240): matte 0.0195 at 19.2°, 0.0217 at 23.0°; the dragon (23.0° at
/// the level drawn, the default material) 0.025.
pub const MAX_MATTE_LIGHT_TURN: f32 = 25.0 * std::f32::consts::PI / 180.0;
/// For a material with a specular term of strength F0 · s_c and GGX roughness α, the largest
/// mean turn of the normal is this times α / √(F0 · s_c) (radians; at most
/// [`MAX_MATTE_LIGHT_TURN`]): a sharper or stronger reflection takes a smaller turn. The same
/// budget on the same spheres: F0 · s_c 0.15, α 0.52 (Blinn-Phong 25) reaches 0.05 at about
/// 18° (0.0345 at 14.4°, 0.0540 at 19.2°); 0.15, α 0.37 (Blinn-Phong 100) at about 15° (0.0453 at
/// 14.4°, 0.0656 at 19.2°); 0.075, α 0.49 (the default material) at about 25° (0.0376 at 19.2°,
/// 0.0452 at 23.0°): 13.4°, 15.7°, 14.0° times α / √(F0 · s_c), so the smallest, 13.4°.
pub const LIGHT_TURN_PER_ROUGHNESS: f32 = 13.4 * std::f32::consts::PI / 180.0;

/// Which of a method's shading pipelines draws a mesh (the shader's override constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// Every triangle (after the mesh's depth pre-pass), the sun looked up per pixel.
    EveryTriangle,
    /// Back faces culled, the sun looked up per pixel.
    Culled,
    /// Back faces culled, the sun's visibility interpolated from the vertices (`VERTEX_SUN`, no
    /// shadow-map lookup: [`super::vertex_sun`]).
    SunFromVertices,
    /// Back faces culled, the whole light computed at the vertices from their sun's visibility
    /// by the vertex stage and interpolated, the albedo per pixel (the shader's `vs_light` and
    /// `fs_light`; sh9-ggx alone: the other methods' slots hold their
    /// [`Shading::SunFromVertices`] pipelines).
    LightFromVertices,
    /// As [`Shading::LightFromVertices`] for an untextured material: the whole colour at the
    /// vertices, the albedo being the same at every pixel (`vs_colour`, `fs_colour`).
    ColourFromVertices,
    /// As [`Shading::LightFromVertices`], the light read from what the vertex-light pass
    /// computed ([`ModelPass::encode_vertex_light`]; the shader's `LIGHT_KEPT`).
    LightKept,
    /// As [`Shading::ColourFromVertices`], the light read from what the vertex-light pass computed.
    ColourKept,
}

impl Shading {
    pub const ALL: [Shading; 7] = [
        Shading::EveryTriangle,
        Shading::Culled,
        Shading::SunFromVertices,
        Shading::LightFromVertices,
        Shading::ColourFromVertices,
        Shading::LightKept,
        Shading::ColourKept,
    ];

    /// The kind that takes a mesh's whole light from its vertices: with a texture or without,
    /// the light computed by the vertex-light pass (`kept`) or by the vertex stage.
    pub fn light_from_vertices(textured: bool, kept: bool) -> Shading {
        match (textured, kept) {
            (true, false) => Shading::LightFromVertices,
            (false, false) => Shading::ColourFromVertices,
            (true, true) => Shading::LightKept,
            (false, true) => Shading::ColourKept,
        }
    }

    /// Whether it is one of [`Shading::light_from_vertices`]'s (its pipelines have the light
    /// per vertex as a third vertex buffer, read or not).
    fn reads_vertex_light(self) -> bool {
        matches!(self, Shading::LightFromVertices | Shading::ColourFromVertices | Shading::LightKept | Shading::ColourKept)
    }
}

/// What the model pass's pipelines share.
pub struct ModelPipelines {
    /// Bind group 0: frame, instance, environment, background, shadow map (with a comparison
    /// and a gather sampler), colour correction, measured light, prefiltered environment,
    /// split-sum table.
    pub layout: wgpu::BindGroupLayout,
    /// Bind group 1: one per material.
    pub material_layout: wgpu::BindGroupLayout,
    /// The shading pipelines, indexed by [`shading_index`]: one per method (the shader's
    /// `METHOD` is a pipeline-override constant, so each compiles only its own branches), with
    /// and without colour correction (`COLOUR_CORRECTION` false: no correction code at all, for
    /// frames that ask for none), drawing every triangle or culling back faces (a single-sided
    /// material's, or a closed mesh's seen from outside, whose back faces are hidden); and those
    /// culling back faces again with the sun's visibility from the vertices (`VERTEX_SUN`: no
    /// shadow-map lookup at all, [`super::vertex_sun`]), and with sh9-ggx's whole light from them
    /// (`vs_light`, `fs_light`): [`Shading`].
    pub shading: Vec<wgpu::RenderPipeline>,
    /// The depth pre-pass of a mesh drawn without culling: its depth alone, so that the
    /// shading pipelines (depth test less-or-equal) shade each pixel once, not every surface
    /// behind the nearest. A culled mesh has no pre-pass: only where it overlaps itself is a
    /// pixel shaded twice (its triangles' draw order, `scene::lod::order`, puts the near ones
    /// first), which costs less on lavapipe than drawing it twice (docs/PERFORMANCE.md, seventh
    /// and eighth sessions).
    pub prepass: wgpu::RenderPipeline,
    /// The vertex-light pass (the shader's `cs_light`): bind groups 0 and 1 as the shading
    /// pipelines', 2 per mesh and level ([`ModelPipelines::light_mesh_layout`]).
    pub light: wgpu::ComputePipeline,
    /// Bind group 2 of the vertex-light pass: a mesh's vertices, its level's vertex list, its
    /// sun per vertex and its light per vertex (written).
    pub light_mesh_layout: wgpu::BindGroupLayout,
}

/// The index in [`ModelPipelines::shading`] of `method`'s pipeline with or without colour
/// correction, of the kind `shading`.
pub fn shading_index(method: LightingMethod, corrected: bool, shading: Shading) -> usize {
    (2 * shading as usize + usize::from(corrected)) * LightingMethod::ALL.len() + method.shader_id() as usize
}

/// The model pipelines (one per method, `samples` per pixel) and their layouts.
pub fn pipelines(device: &wgpu::Device, samples: u32) -> ModelPipelines {
    let fs = ShaderStages::FRAGMENT;
    let vs_fs = ShaderStages::VERTEX | fs;
    // What sh9-ggx's light reads, which the vertex-light pass computes too (`cs_light`).
    let all = vs_fs | ShaderStages::COMPUTE;
    let layout = build::layout(
        device,
        "model",
        &[
            build::uniform(0, all),
            build::uniform(1, all),
            build::texture_entry(2, fs, Cube, true),
            build::sampler_entry(3, all, Filtering),
            build::texture_entry(4, fs, D2, true),
            build::sampler_entry(5, all, Filtering),
            build::depth_texture_entry(6, fs),
            build::sampler_entry(7, fs, Comparison),
            build::uniform(8, vs_fs),
            build::uniform(9, all),
            build::texture_entry(10, all, Cube, true),
            build::texture_entry(11, all, D2, true),
            build::sampler_entry(12, fs, NonFiltering),
        ],
    );
    let material_layout = build::layout(
        device,
        "material",
        &[build::uniform(0, all), build::texture_entry(1, fs, D2, true), build::sampler_entry(2, fs, Filtering)],
    );
    let cs = ShaderStages::COMPUTE;
    let light_mesh_layout = build::layout(
        device,
        "vertex light mesh",
        &[build::storage(0, cs, true), build::storage(1, cs, true), build::storage(2, cs, true), build::storage(3, cs, false)],
    );
    let module = build::shader(device, "model", source(Technique::Model));
    let mut shading: Vec<wgpu::RenderPipeline> = Vec::new();
    for kind in Shading::ALL {
        for corrected in [false, true] {
            for m in LightingMethod::ALL {
                // A method without the sun's shadow (the refractions) never draws with the sun
                // from the vertices, nor any method but sh9-ggx with its light from them: their
                // slots hold the pipeline they draw with instead, not another build (each costs
                // start-up time, docs/PERFORMANCE.md, tenth session).
                let instead = match kind {
                    Shading::SunFromVertices if vertex_sun::SunLookup::of(m).is_none() => Some(Shading::Culled),
                    k if k.reads_vertex_light() && m != LightingMethod::Sh9Ggx => Some(Shading::SunFromVertices),
                    _ => None,
                };
                let pipeline = match instead {
                    Some(other) => shading[shading_index(m, corrected, other)].clone(),
                    None => method_pipeline(device, &module, (&layout, &material_layout), (COLOR_FORMAT, samples), (corrected, kind), m),
                };
                shading.push(pipeline);
            }
        }
    }
    let prepass = prepass_pipeline(device, &module, (&layout, &material_layout), samples);
    let light = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("vertex light"),
        layout: Some(&device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("vertex light"),
            bind_group_layouts: &[Some(&layout), Some(&material_layout), Some(&light_mesh_layout)],
            immediate_size: 0,
        })),
        module: &module,
        entry_point: Some("cs_light"),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: &[("METHOD", f64::from(LightingMethod::Sh9Ggx.shader_id()))],
            ..Default::default()
        },
        cache: None,
    });
    ModelPipelines { layout, material_layout, shading, prepass, light, light_mesh_layout }
}

fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 6] = wgpu::vertex_attr_array![
        0 => Float32x3, 1 => Float32x3, 2 => Float32x2, AO_LOCATION => Float32x4, BENT_LOCATION => Float32x3, TINT_LOCATION => Float32x3
    ];
    wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    }
}

/// The second vertex buffer: the sun's visibility per vertex ([`super::vertex_sun`]).
fn sun_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![SUN_LOCATION => Float32];
    wgpu::VertexBufferLayout { array_stride: 4, step_mode: wgpu::VertexStepMode::Vertex, attributes: &ATTRIBUTES }
}

/// The bytes of the light per vertex (two RGBA32F: what the albedo multiplies, what is added).
const LIGHT_STRIDE: u64 = 32;

/// The third vertex buffer of the light from the vertices: the light per vertex the
/// vertex-light pass computed ([`ModelPass::encode_vertex_light`]).
fn light_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 2] =
        wgpu::vertex_attr_array![LIGHT_LOCATION => Float32x4, LIGHT_SPECULAR_LOCATION => Float32x4];
    wgpu::VertexBufferLayout { array_stride: LIGHT_STRIDE, step_mode: wgpu::VertexStepMode::Vertex, attributes: &ATTRIBUTES }
}

/// One model pipeline per method (indexed by [`LightingMethod::shader_id`]) with bind-group
/// layouts (`layout`, `material_layout`), drawing into `format` targets of `samples` per pixel,
/// with the colour correction (the shader's `COLOUR_CORRECTION`: `corrected`) or without,
/// culling back faces (`cull`) or not.
pub fn pipelines_for(
    device: &wgpu::Device,
    layouts: (&wgpu::BindGroupLayout, &wgpu::BindGroupLayout),
    target: (wgpu::TextureFormat, u32),
    (corrected, cull): (bool, bool),
) -> Vec<wgpu::RenderPipeline> {
    let module = build::shader(device, "model", source(Technique::Model));
    let kind = if cull { Shading::Culled } else { Shading::EveryTriangle };
    LightingMethod::ALL.iter().map(|&m| method_pipeline(device, &module, layouts, target, (corrected, kind), m)).collect()
}

/// The model pipeline of method `m` of `kind`, with or without colour correction (`corrected`).
fn method_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layouts: (&wgpu::BindGroupLayout, &wgpu::BindGroupLayout),
    (format, samples): (wgpu::TextureFormat, u32),
    (corrected, kind): (bool, Shading),
    m: LightingMethod,
) -> wgpu::RenderPipeline {
    // Every fragment of the model is opaque (alpha 1): written, not blended over what is behind.
    let colour = wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL };
    let flag = |on: bool| if on { 1.0 } else { 0.0 };
    let vertex_sun = kind == Shading::SunFromVertices || kind.reads_vertex_light();
    let kept = matches!(kind, Shading::LightKept | Shading::ColourKept);
    let constants = [
        ("METHOD", f64::from(m.shader_id())),
        ("COLOUR_CORRECTION", flag(corrected)),
        ("VERTEX_SUN", flag(vertex_sun)),
        ("LIGHT_KEPT", flag(kept)),
    ];
    // The light from the vertices has its own entry points, which interpolate only what its
    // fragment reads (model.wgsl LightOut, ColourOut).
    let (vs, fs) = match kind {
        Shading::LightFromVertices | Shading::LightKept => ("vs_light", "fs_light"),
        Shading::ColourFromVertices | Shading::ColourKept => ("vs_colour", "fs_colour"),
        _ => ("vs_main", "fs_main"),
    };
    let cull = kind != Shading::EveryTriangle;
    model_pipeline(device, (m.name(), module), (vs, Some((fs, colour))), layouts, samples, (&constants, cull, kind.reads_vertex_light()))
}

/// A model pipeline: the model shader's vertex entry point `vs` with override `constants` and,
/// when `fragment` gives one, the fragment entry point drawing into its colour target (none:
/// depth only), `samples` per pixel with depth written and tested, culling back faces
/// (counter-clockwise fronts) or not, reading the light per vertex (a third vertex buffer) or
/// not.
fn model_pipeline(
    device: &wgpu::Device,
    (label, module): (&str, &wgpu::ShaderModule),
    (vs, fragment): (&str, Option<(&str, wgpu::ColorTargetState)>),
    (layout, material_layout): (&wgpu::BindGroupLayout, &wgpu::BindGroupLayout),
    samples: u32,
    (constants, cull, light): (&[(&str, f64)], bool, bool),
) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout), Some(material_layout)],
        immediate_size: 0,
    });
    let options = wgpu::PipelineCompilationOptions { constants, ..Default::default() };
    let targets: Vec<Option<wgpu::ColorTargetState>> = fragment.iter().map(|(_, colour)| Some(colour.clone())).collect();
    let buffers = [Some(vertex_layout()), Some(sun_layout()), Some(light_layout())];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vs),
            compilation_options: options.clone(),
            buffers: &buffers[..if light { 3 } else { 2 }],
        },
        primitive: wgpu::PrimitiveState { cull_mode: cull.then_some(wgpu::Face::Back), ..Default::default() },
        depth_stencil: depth_state(true, wgpu::DepthBiasState::default()),
        multisample: wgpu::MultisampleState { count: samples, ..Default::default() },
        fragment: fragment.map(|(entry, _)| wgpu::FragmentState {
            module,
            entry_point: Some(entry),
            compilation_options: options.clone(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The depth pre-pass pipeline: the model pass's vertex stage (its position `@invariant`, so
/// both passes compute the same depth), colour writes masked, depth written, `samples` per
/// pixel into the composite's targets.
fn prepass_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layouts: (&wgpu::BindGroupLayout, &wgpu::BindGroupLayout),
    samples: u32,
) -> wgpu::RenderPipeline {
    let constants = [("METHOD", 0.0), ("COLOUR_CORRECTION", 0.0)];
    let colour = wgpu::ColorTargetState { format: COLOR_FORMAT, blend: None, write_mask: wgpu::ColorWrites::empty() };
    model_pipeline(
        device,
        ("model depth pre-pass", module),
        ("vs_main", Some(("fs_depth", colour))),
        layouts,
        samples,
        (&constants, false, false),
    )
}

/// The model's depth seen by the camera, single-sampled and without colour: the model pass's
/// vertex stage (so the same surface), for the depth layer (render/layers.rs), culling back
/// faces (`cull`) or not.
pub fn depth_pipeline(device: &wgpu::Device, pipelines: &ModelPipelines, cull: bool) -> wgpu::RenderPipeline {
    let module = build::shader(device, "model depth", source(Technique::Model));
    let constants = [("METHOD", 0.0), ("COLOUR_CORRECTION", 0.0)];
    model_pipeline(
        device,
        ("model depth", &module),
        ("vs_main", None),
        (&pipelines.layout, &pipelines.material_layout),
        1,
        (&constants, cull, false),
    )
}

/// A material's uniform for this frame: its own colours and sides with the frame's Eq. 3 terms,
/// and the frame's gloss exponent in place of its own when one is given.
pub fn material_uniforms(base: &MaterialUniforms, terms: &MaterialTerms) -> MaterialUniforms {
    let mut m = *base;
    m.terms = [terms.ambient, terms.diffuse, terms.specular, base.terms[3]];
    if let Some(g) = terms.gloss {
        m.specular[3] = g;
    }
    m
}

/// The split-sum table as RGBA16F texels (A, B, 0, 1), computed once per process.
fn brdf_lut_texels() -> &'static [half::f16] {
    static TEXELS: std::sync::OnceLock<Vec<half::f16>> = std::sync::OnceLock::new();
    TEXELS.get_or_init(|| {
        ggx::brdf_lut(ggx::LUT_SIZE, ggx::LUT_SAMPLES).iter().flat_map(|&[a, b]| [a, b, 0.0, 1.0]).map(half::f16::from_f32).collect()
    })
}

struct MeshGpu {
    vertices: wgpu::Buffer,
    /// Every level of detail's triangles, one after another (scene::lod::MeshLods).
    indices: wgpu::Buffer,
    levels: Vec<IndexRange>,
    material: wgpu::BindGroup,
    /// Per level, whether it is a closed surface (`MeshLods::closed`: its back faces may be
    /// culled).
    closed: Vec<bool>,
    /// Which faces its material shows.
    sides: Sides,
    /// The sun's visibility per vertex (written by [`super::vertex_sun`], read as vertex
    /// attribute [`SUN_LOCATION`]).
    sun: wgpu::Buffer,
    /// Per level, the vertex-sun pass's bind group 1 (vertices, the level's vertex indices,
    /// `sun`, and what its split reads and writes) and how many vertices and triangles the level
    /// has.
    sun_groups: Vec<(wgpu::BindGroup, u32, u32)>,
    /// The drawn level's triangles split by the vertex-sun pass (shaders/vertex_sun.wgsl
    /// `split`): those whose sunlit vertices agree on the sun from 0, the others from
    /// `second`; room for every triangle of the largest level in each.
    split: wgpu::Buffer,
    second: u32,
    /// The two lists' indexed indirect draws (`DrawIndexedIndirectArgs`, 20 bytes each).
    split_draws: wgpu::Buffer,
    /// Per level, the longest edge of the triangles that cover [`SUN_EDGE_AREA`] of its area
    /// (model units; [`edge_over_area`]).
    longest_edge: Vec<f32>,
    /// Per level, how far the normal turns across its triangles (radians; [`mean_normal_turn`]).
    normal_turn: Vec<f32>,
    /// The light per vertex (written by the vertex-light pass, [`ModelPass::encode_vertex_light`];
    /// read as attributes [`LIGHT_LOCATION`] and [`LIGHT_SPECULAR_LOCATION`]).
    light: wgpu::Buffer,
    /// Per level, the vertex-light pass's bind group 2 (vertices, the level's vertex indices,
    /// `sun`, `light`) and how many vertices the level has.
    light_groups: Vec<(wgpu::BindGroup, u32)>,
    /// Whether its material has a texture (else the light from the vertices carries its whole
    /// colour: [`Shading::ColourFromVertices`]).
    textured: bool,
}

/// Which back faces a frame may cull (`FrameData::cull`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Culling {
    /// None: the model's transform mirrors it, turning its faces inside out.
    #[default]
    Nothing,
    /// Those of single-sided materials ([`Sides::Front`]): the camera is inside the model's
    /// bounds, where a closed mesh's back faces may be what it sees.
    SingleSided,
    /// Those of single-sided materials and of closed meshes ([`Sides::Unspecified`] and
    /// `MeshLods::closed`): the camera is outside the model's bounds.
    SingleSidedAndClosed,
}

/// A model on the GPU.
pub struct ModelGpu {
    /// Which upload this is (one number per process): what the vertex-light pass computed for
    /// one model is not another's ([`LightKey`]).
    id: u64,
    meshes: Vec<MeshGpu>,
    /// Each mesh's material buffer and its values as loaded, rewritten each frame with the
    /// frame's material terms.
    materials: Vec<(wgpu::Buffer, MaterialUniforms)>,
    /// What was computed from the model's content (shared by every compositor on the device):
    /// the level-of-detail chain (the index buffers hold every level, so switching level
    /// allocates nothing), the colour statistics on demand, the ground under a placement.
    pub prepared: Arc<PreparedModel>,
}

impl ModelGpu {
    /// Rewrite the meshes' vertices with `vertices` (per mesh of the model, as
    /// [`PreparedModel::vertices`]: the same count; PreparedModel::vertices_under's sky).
    pub fn write_vertices(&self, queue: &wgpu::Queue, vertices: &[Vec<crate::render::pipelines::Vertex>]) {
        let drawn = vertices.iter().filter(|v| !v.is_empty());
        for (m, v) in self.meshes.iter().zip(drawn) {
            queue.write_buffer(&m.vertices, 0, bytemuck::cast_slice(v));
        }
    }

    /// Bounds in model space.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.prepared.bounds
    }

    /// Per level of detail, the simplification error (model units, non-decreasing from 0).
    pub fn lod_errors(&self) -> &[f32] {
        &self.prepared.chain.errors
    }

    /// Per level of detail, the model's triangle count.
    pub fn lod_triangles(&self) -> &[usize] {
        &self.prepared.chain.triangles
    }

    /// For each mesh `chosen` names (in mesh order: [`ModelPass::vertex_sun_meshes`], the meshes
    /// the model pass draws with the sun from their vertices this frame; a mesh past its end is
    /// not chosen), the vertex-sun pass's bind group 1 at level of detail `level` (clamped) and
    /// how many vertices and triangles that level has. The meshes drawn per pixel are left out:
    /// nothing reads their buffers this frame.
    pub fn sun_groups<'a>(&'a self, level: usize, chosen: &'a [bool]) -> impl Iterator<Item = (&'a wgpu::BindGroup, u32, u32)> {
        self.meshes.iter().zip(chosen).filter(|(_, c)| **c).map(move |(m, _)| {
            let (group, vertices, triangles) = &m.sun_groups[level.min(m.sun_groups.len() - 1)];
            (group, *vertices, *triangles)
        })
    }

    /// Zero each mesh's split draws (one instance each, the second list at its start) before a
    /// vertex-sun pass counts its triangles into them.
    pub fn reset_split_draws(&self, queue: &wgpu::Queue) {
        for m in &self.meshes {
            let args = [0, 1, 0, 0, 0, 0, 1, m.second, 0, 0u32];
            queue.write_buffer(&m.split_draws, 0, bytemuck::cast_slice(&args));
        }
    }

    /// Per mesh, its buffer of the sun's visibility per vertex.
    pub fn sun_buffers(&self) -> impl Iterator<Item = &wgpu::Buffer> {
        self.meshes.iter().map(|m| &m.sun)
    }

    /// Per mesh, its split's two indexed indirect draws (triangles whose vertices agree, then
    /// the others).
    pub fn split_draw_buffers(&self) -> impl Iterator<Item = &wgpu::Buffer> {
        self.meshes.iter().map(|m| &m.split_draws)
    }

    /// Draw every mesh at level of detail `level` (clamped to the chain); `material_group`:
    /// where to bind each mesh's material (None: no materials, the shadow pass).
    pub fn draw_meshes(&self, pass: &mut wgpu::RenderPass<'_>, material_group: Option<u32>, level: usize) {
        for mesh in &self.meshes {
            mesh.draw(pass, material_group, level);
        }
    }
}

impl MeshGpu {
    /// Draw the mesh at level of detail `level` (clamped to its chain), its material bound at
    /// `material_group` (None: not bound).
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, material_group: Option<u32>, level: usize) {
        if let Some(group) = material_group {
            pass.set_bind_group(group, &self.material, &[]);
            pass.set_vertex_buffer(1, self.sun.slice(..));
        }
        let r = self.levels[level.min(self.levels.len() - 1)];
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(r.first..r.first + r.count, 0, 0..1);
    }

    /// Draw the level the vertex-sun pass last split: its triangles whose sunlit vertices agree
    /// with `per_vertex` (the sun interpolated; with the light per vertex when `light`), the
    /// others with `per_pixel`.
    fn draw_split(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        (per_vertex, per_pixel): (&wgpu::RenderPipeline, &wgpu::RenderPipeline),
        light: bool,
    ) {
        pass.set_bind_group(1, &self.material, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_vertex_buffer(1, self.sun.slice(..));
        if light {
            pass.set_vertex_buffer(2, self.light.slice(..));
        }
        pass.set_index_buffer(self.split.slice(..), wgpu::IndexFormat::Uint32);
        pass.set_pipeline(per_vertex);
        pass.draw_indexed_indirect(&self.split_draws, 0);
        pass.set_pipeline(per_pixel);
        pass.draw_indexed_indirect(&self.split_draws, 20);
    }
}

pub struct ModelPass {
    /// Indexed by [`shading_index`].
    shading: Vec<wgpu::RenderPipeline>,
    prepass: wgpu::RenderPipeline,
    /// Which back faces this frame may cull.
    cull: Culling,
    /// Whether culling is on ([`ModelPass::set_culling`]).
    culling: bool,
    /// Whether this frame corrects the model's colour (its `ColourCorrection` is not "none").
    corrected: bool,
    /// The longest edge on screen (pixels) of a mesh that takes its sun's visibility from its
    /// vertices ([`ModelPass::set_sun_edge_limit`]; 0: none does).
    sun_edge_limit: f32,
    layout: wgpu::BindGroupLayout,
    /// The vertex-sun pass's bind group 1 layout (each mesh's groups are made at upload).
    sun_mesh_layout: wgpu::BindGroupLayout,
    /// Per mesh, as the last frame written drew it: its longest edge on screen (pixels; None:
    /// not measured) ...
    sun_edges: Vec<Option<f32>>,
    /// ... and whether it took the sun from its vertices (the choice [`ModelPass::write`] makes
    /// once a frame; the vertex-sun pass runs for these meshes alone) ...
    sun_chosen: Vec<bool>,
    /// ... and, of those, whether it took its whole light from them ([`Shading::LightFromVertices`]).
    light_chosen: Vec<bool>,
    /// Per mesh, as the last frame written drew it: how far its normal turns across a triangle
    /// (radians, [`mean_normal_turn`] at the level drawn).
    light_turns: Vec<f32>,
    /// The longest edge on screen (pixels) of a mesh that takes its whole light from its vertices
    /// ([`ModelPass::set_light_limits`]; 0: none does).
    light_edge_limit: f32,
    /// What [`light_turn_limit`] is multiplied by ([`ModelPass::set_light_limits`]).
    light_turn_scale: f32,
    material_layout: wgpu::BindGroupLayout,
    linear_sampler: wgpu::Sampler,
    repeat_sampler: wgpu::Sampler,
    shadow_sampler: wgpu::Sampler,
    shadow_gather_sampler: wgpu::Sampler,
    /// The colour correction (`ColourCorrection`).
    colour: wgpu::Buffer,
    /// The texture of untextured materials.
    white: wgpu::TextureView,
    /// The split-sum BRDF table (light::ggx::brdf_lut): A, B in red and green.
    brdf_lut: wgpu::TextureView,
    /// Bind group 0 per shadow map (in the order of `ShadowPass::maps`), once there is an
    /// environment.
    bind_groups: Vec<wgpu::BindGroup>,
    /// The vertex-light pass ([`ModelPipelines::light`]) and its bind group 2 layout.
    light: wgpu::ComputePipeline,
    light_mesh_layout: wgpu::BindGroupLayout,
    /// Each mesh's material as the last frame wrote it (what the vertex light reads of it).
    material_values: Vec<MaterialUniforms>,
    /// What the light buffers were last computed for (None: nothing, or not known) ...
    light_key: Option<LightKey>,
    /// ... what the last frame's light depended on ...
    last_light_key: Option<LightKey>,
    /// ... and whether this frame reads them (else its vertex stage computes the light).
    light_kept: bool,
}

/// What the vertex-light pass's light depends on besides the model's own buffers (whose
/// changes the compositor reports: a vertex-sun pass, new vertices): the model uploaded, the
/// frame's uniforms but its view and the shadow camera's (a camera that only turns computes
/// nothing; the shadow camera reaches the light through the sun per vertex alone), the model's
/// placement, the measured light, the materials as the frame writes them, the level of detail
/// and which meshes read it. Compared whole: equal keys, equal light.
#[derive(Clone, Debug, PartialEq)]
pub struct LightKey(Vec<u8>);

impl LightKey {
    pub fn new(
        model: u64,
        (frame, instance, light): (&FrameUniforms, &InstanceUniforms, &LightUniforms),
        materials: &[MaterialUniforms],
        (level, meshes): (usize, &[bool]),
    ) -> LightKey {
        let frame = FrameUniforms { view_proj: [[0.0; 4]; 4], view: [[0.0; 4]; 4], light_view_proj: [[0.0; 4]; 4], ..*frame };
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&model.to_le_bytes());
        bytes.extend_from_slice(bytemuck::bytes_of(&frame));
        bytes.extend_from_slice(bytemuck::bytes_of(instance));
        bytes.extend_from_slice(bytemuck::bytes_of(light));
        bytes.extend_from_slice(bytemuck::cast_slice(materials));
        bytes.extend_from_slice(&(level as u64).to_le_bytes());
        bytes.extend(meshes.iter().map(|&m| u8::from(m)));
        LightKey(bytes)
    }
}

/// Whether the vertex-light pass runs and whether the frame reads its buffers (the pair), for a
/// frame whose light depends on `key` (None: no mesh takes its light from its vertices), the last
/// frame's having depended on `last`, and the buffers holding the light for `held`: read while
/// they hold the frame's; computed and read when the key is the last frame's (the view stopped
/// changing); otherwise neither (the vertex stage computes the light).
pub fn light_plan(key: Option<&LightKey>, last: Option<&LightKey>, held: Option<&LightKey>) -> (bool, bool) {
    match key {
        None => (false, false),
        Some(k) if held == Some(k) => (false, true),
        Some(k) if last == Some(k) => (true, true),
        Some(_) => (false, false),
    }
}

/// The fields of the frame's uniform that [`LightKey`] leaves out, which the vertex-light pass
/// must therefore not read (this module's tests check both: `cs_light` on naga's IR, the key
/// on frames that differ in these fields alone).
pub const LIGHT_IGNORES: [&str; 3] = ["view_proj", "view", "light_view_proj"];

impl ModelPass {
    pub fn new(gpu: &Gpu, pipelines: &Pipelines) -> ModelPass {
        let device = &gpu.device;
        ModelPass {
            shading: pipelines.model.shading.clone(),
            cull: Culling::Nothing,
            culling: true,
            prepass: pipelines.model.prepass.clone(),
            corrected: false,
            sun_edge_limit: MAX_SUN_EDGE_PX,
            layout: pipelines.model.layout.clone(),
            sun_mesh_layout: pipelines.vertex_sun.mesh_layout.clone(),
            sun_edges: Vec::new(),
            sun_chosen: Vec::new(),
            light_chosen: Vec::new(),
            light_turns: Vec::new(),
            light_edge_limit: MAX_LIGHT_EDGE_PX,
            light_turn_scale: 1.0,
            material_layout: pipelines.model.material_layout.clone(),
            linear_sampler: pipelines.linear_sampler.clone(),
            repeat_sampler: pipelines.repeat_sampler.clone(),
            shadow_sampler: pipelines.shadow_sampler.clone(),
            shadow_gather_sampler: pipelines.shadow_gather_sampler.clone(),
            colour: build::uniform_buffer::<ColourCorrection>(device, "colour correction"),
            white: build::sampled_texture(device, &gpu.queue, "white", (1, 1), COLOR_FORMAT, &[255; 4]),
            brdf_lut: build::sampled_texture(
                device,
                &gpu.queue,
                "split-sum BRDF",
                (ggx::LUT_SIZE, ggx::LUT_SIZE),
                wgpu::TextureFormat::Rgba16Float,
                bytemuck::cast_slice(brdf_lut_texels()),
            ),
            bind_groups: Vec::new(),
            light: pipelines.model.light.clone(),
            light_mesh_layout: pipelines.model.light_mesh_layout.clone(),
            material_values: Vec::new(),
            light_key: None,
            last_light_key: None,
            light_kept: false,
        }
    }

    /// Bind group 0 for a new environment: the frame, instance and light uniforms, the
    /// environment cube map and its prefiltered levels, the background, the shadow map and the
    /// colour correction.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        (frame, instance, light): (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer),
        env: &EnvironmentViews,
        background: &wgpu::TextureView,
        shadow_map: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        use wgpu::BindingResource::{Sampler, TextureView};
        build::bind_group(
            device,
            "model",
            &self.layout,
            &[
                frame.as_entire_binding(),
                instance.as_entire_binding(),
                TextureView(&env.cube),
                Sampler(&self.linear_sampler),
                TextureView(background),
                Sampler(&self.linear_sampler),
                TextureView(shadow_map),
                Sampler(&self.shadow_sampler),
                self.colour.as_entire_binding(),
                light.as_entire_binding(),
                TextureView(&env.specular),
                TextureView(&self.brdf_lut),
                Sampler(&self.shadow_gather_sampler),
            ],
        )
    }

    /// Bind group 0 for each shadow map, from [`ModelPass::bind_group`].
    pub fn set_bind_groups(&mut self, bind_groups: Vec<wgpu::BindGroup>) {
        self.bind_groups = bind_groups;
        // A new environment: its prefiltered reflection lights the vertices.
        self.light_key = None;
    }

    /// Upload a prepared model (render/model_cache.rs): one vertex/index buffer and material
    /// bind group per mesh. Returns the GPU copy without touching the current one (the caller
    /// swaps it in once the GPU accepted the upload).
    pub fn upload(&self, gpu: &Gpu, model: &Model, prepared: Arc<PreparedModel>) -> Result<ModelGpu> {
        let device = &gpu.device;
        // Each texture with its whole mip chain (render/mip_chain.rs), sampled trilinearly; a
        // texture that an earlier material holds too (the truck's two materials share one) is
        // built and uploaded once.
        let mut textures: Vec<Option<wgpu::TextureView>> = Vec::with_capacity(model.materials.len());
        for (i, m) in model.materials.iter().enumerate() {
            let view = match &m.texture {
                None => None,
                Some(t) => {
                    let same = |o: &crate::scene::Material| {
                        o.texture.as_ref().is_some_and(|o| (o.width, o.height) == (t.width, t.height) && o.pixels == t.pixels)
                    };
                    match model.materials[..i].iter().position(same) {
                        Some(j) => textures[j].clone(),
                        None => Some(mip_chain::upload(device, &gpu.queue, &m.name, t)?),
                    }
                }
            };
            textures.push(view);
        }
        let mut meshes = Vec::new();
        let mut materials = Vec::new();
        for ((mesh, lods), vertices) in model.meshes.iter().zip(&prepared.chain.meshes).zip(&prepared.vertices) {
            if mesh.indices.is_empty() {
                continue;
            }
            let material =
                model.materials.get(mesh.material).ok_or_else(|| anyhow!("a mesh refers to missing material {}", mesh.material))?;
            let uniforms = MaterialUniforms {
                albedo: [material.diffuse[0], material.diffuse[1], material.diffuse[2], if material.texture.is_some() { 1.0 } else { 0.0 }],
                specular: [material.specular[0], material.specular[1], material.specular[2], material.shininess],
                terms: [1.0, 1.0, 1.0, if material.sides == Sides::Both { 1.0 } else { 0.0 }],
            };
            let material_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("material"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
            let texture = textures[mesh.material].as_ref().unwrap_or(&self.white);
            let bind = build::bind_group(
                device,
                "material",
                &self.material_layout,
                &[
                    material_buf.as_entire_binding(),
                    wgpu::BindingResource::TextureView(texture),
                    wgpu::BindingResource::Sampler(&self.repeat_sampler),
                ],
            );
            let vertex_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vertices"),
                contents: bytemuck::cast_slice(vertices),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            });
            // Lit until the vertex-sun pass writes it.
            let sun = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sun per vertex"),
                contents: bytemuck::cast_slice(&vec![1.0f32; vertices.len()]),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
            let align = u64::from(device.limits().min_storage_buffer_offset_alignment);
            let (lists, offsets, counts) = vertex_sun::level_vertex_lists(&lods.indices, &lods.levels, vertices.len(), align);
            let lists = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vertices per level"),
                contents: bytemuck::cast_slice(&lists),
                usage: wgpu::BufferUsages::STORAGE,
            });
            let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("indices"),
                contents: bytemuck::cast_slice(&lods.indices),
                usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
            });
            // The split lists, each with room for the largest level (at least one triangle).
            let second = lods.levels.iter().map(|r| r.count).max().unwrap_or(0).max(3);
            let split = build::buffer(
                device,
                "sun split triangles",
                8 * u64::from(second),
                wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
            );
            let split_draws = build::buffer(
                device,
                "sun split draws",
                40,
                wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            );
            let uniform_align = u64::from(device.limits().min_uniform_buffer_offset_alignment).max(16);
            let mut level_bytes = vec![0u8; uniform_align as usize * lods.levels.len()];
            for (l, r) in lods.levels.iter().enumerate() {
                let u = SplitLevelUniforms { first: r.first, count: r.count, second, unused: 0 };
                level_bytes[l * uniform_align as usize..][..16].copy_from_slice(bytemuck::bytes_of(&u));
            }
            // Per level (at the device's uniform-offset alignment), where its triangles are.
            let split_levels = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sun split levels"),
                contents: &level_bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let light = build::buffer(
                device,
                "light per vertex",
                LIGHT_STRIDE * vertices.len().max(1) as u64,
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
            );
            // Per level, the vertex-sun pass's and the vertex-light pass's bind groups, both over
            // the level's list of vertices.
            let (sun_groups, light_groups): (Vec<_>, Vec<_>) = offsets
                .iter()
                .zip(&counts)
                .zip(&lods.levels)
                .enumerate()
                .map(|(l, ((&offset, &count), r))| {
                    let size = wgpu::BufferSize::new(4 * u64::from(count.max(1)));
                    let list = || wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: &lists, offset, size });
                    let level =
                        wgpu::BufferBinding { buffer: &split_levels, offset: l as u64 * uniform_align, size: wgpu::BufferSize::new(16) };
                    let sun_group = build::bind_group(
                        device,
                        "vertex sun mesh",
                        &self.sun_mesh_layout,
                        &[
                            vertex_buf.as_entire_binding(),
                            list(),
                            sun.as_entire_binding(),
                            indices.as_entire_binding(),
                            split.as_entire_binding(),
                            split_draws.as_entire_binding(),
                            wgpu::BindingResource::Buffer(level),
                        ],
                    );
                    let light_group = build::bind_group(
                        device,
                        "vertex light mesh",
                        &self.light_mesh_layout,
                        &[vertex_buf.as_entire_binding(), list(), sun.as_entire_binding(), light.as_entire_binding()],
                    );
                    ((sun_group, count, r.count / 3), (light_group, count))
                })
                .unzip();
            let positions: Vec<Vec3> = vertices.iter().map(|v| Vec3::from(v.position)).collect();
            let normals: Vec<Vec3> = vertices.iter().map(|v| Vec3::from(v.normal)).collect();
            let level = |r: &IndexRange| &lods.indices[r.first as usize..][..r.count as usize];
            let longest_edge = lods.levels.iter().map(|r| edge_over_area(&positions, level(r), SUN_EDGE_AREA)).collect();
            let normal_turn = lods.levels.iter().map(|r| mean_normal_turn(&positions, &normals, level(r))).collect();
            meshes.push(MeshGpu {
                vertices: vertex_buf,
                indices,
                levels: lods.levels.clone(),
                material: bind,
                closed: lods.closed.clone(),
                sides: material.sides,
                sun,
                sun_groups,
                split,
                second,
                split_draws,
                longest_edge,
                normal_turn,
                light,
                light_groups,
                textured: material.texture.is_some(),
            });
            materials.push((material_buf, uniforms));
        }
        static UPLOADS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let id = UPLOADS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(ModelGpu { id, meshes, materials, prepared })
    }

    /// This frame's colour correction and material terms; a frame without correction draws
    /// with the pipelines that have no correction code. `cull`: which back faces the frame may
    /// cull. `sun_px`: pixels on screen per model unit at the model's nearest point, None where
    /// every mesh looks the sun up per pixel (a full-shadow reference, a camera inside the
    /// model's box). A mesh drawn at `level` with its back faces culled and its edges on screen
    /// within [`ModelPass::set_sun_edge_limit`]'s (over [`SUN_EDGE_AREA`] of its area)
    /// interpolates the sun's visibility from its vertices (the back
    /// faces' condition: the vertex's value is looked up on the side its normal faces, which a
    /// visible back face turns away from); one whose edges are within
    /// [`ModelPass::set_light_limits`]'s too takes its whole light from its vertices
    /// ([`Shading::LightFromVertices`], sh9-ggx) where `light` allows it (not in a still). Returns whether any mesh takes the sun from its
    /// vertices.
    pub fn write(
        &mut self,
        queue: &wgpu::Queue,
        model: &ModelGpu,
        (colour, terms): (&ColourCorrection, &MaterialTerms),
        cull: Culling,
        (level, sun_px, light): (usize, Option<f32>, bool),
    ) -> bool {
        self.cull = if self.culling { cull } else { Culling::Nothing };
        queue.write_buffer(&self.colour, 0, bytemuck::bytes_of(colour));
        self.corrected = colour.method != crate::colour::transfer::TransferMethod::None.shader_id();
        self.sun_edges.clear();
        self.sun_chosen.clear();
        self.light_chosen.clear();
        self.light_turns.clear();
        self.material_values.clear();
        // One material buffer per mesh (ModelGpu::materials).
        for (mesh, (buf, base)) in model.meshes.iter().zip(&model.materials) {
            let uniforms = material_uniforms(base, terms);
            queue.write_buffer(buf, 0, bytemuck::bytes_of(&uniforms));
            self.material_values.push(uniforms);
            let turn_limit = light_turn_limit(&uniforms);
            let edge_px = sun_px.map(|px| px * mesh.longest_edge[level.min(mesh.longest_edge.len() - 1)]);
            let within = |limit: f32| limit > 0.0 && edge_px.is_some_and(|e| e <= limit);
            let per_vertex = self.culls(mesh, level) && within(self.sun_edge_limit);
            self.sun_edges.push(edge_px);
            self.sun_chosen.push(per_vertex);
            let turn = mesh.normal_turn[level.min(mesh.normal_turn.len() - 1)];
            self.light_turns.push(turn);
            self.light_chosen.push(light && per_vertex && within(self.light_edge_limit) && turn <= turn_limit * self.light_turn_scale);
        }
        self.sun_chosen.contains(&true)
    }

    /// Whether the vertex-sun buffers and split hold this frame's values for the meshes
    /// [`ModelPass::write`] chose (the compositor's bookkeeping); if not, every mesh looks the
    /// sun up per pixel this frame.
    pub fn vertex_sun_valid(&mut self, valid: bool) {
        if !valid {
            self.sun_chosen.fill(false);
            self.light_chosen.fill(false);
        }
    }

    /// Per mesh, whether the last frame written draws it with the sun from its vertices (what
    /// [`ModelGpu::sun_groups`] takes: the vertex-sun pass runs for these meshes alone).
    /// Whether the vertex-light pass must run this frame (after [`ModelPass::write`] and
    /// [`ModelPass::vertex_sun_valid`]), and notes whether the frame reads its buffers. Those
    /// hold the light for the [`LightKey`] they were computed for, unless `changed` (the sun per
    /// vertex was looked up again, or the vertices rewritten, this frame). A frame whose key is
    /// the last frame's, while the buffers hold another, runs the pass and reads them; one whose
    /// key changed since the last frame (a camera moving, a sun turning) computes the light in
    /// the vertex stage instead, as a pass run every frame costs more (docs/PERFORMANCE.md,
    /// twenty-seventh session). `uniforms`: the frame's, as written.
    pub fn vertex_light_due(
        &mut self,
        model: &ModelGpu,
        uniforms: (&FrameUniforms, &InstanceUniforms, &LightUniforms),
        level: usize,
        changed: bool,
    ) -> bool {
        if changed {
            self.light_key = None;
        }
        let key = self
            .light_chosen
            .contains(&true)
            .then(|| LightKey::new(model.id, uniforms, &self.material_values, (level, &self.light_chosen)));
        let (run, kept) = light_plan(key.as_ref(), self.last_light_key.as_ref(), self.light_key.as_ref());
        if run {
            self.light_key = key.clone();
        }
        self.last_light_key = key;
        self.light_kept = kept;
        run
    }

    /// The vertex-light pass: the light at every vertex of the drawn level (`level`) of each
    /// mesh that takes its light from its vertices, into its light buffer ([`LIGHT_STRIDE`] bytes
    /// a vertex), with the frame's bind group 0 for shadow map `shadow_index`. Run when
    /// [`ModelPass::vertex_light_due`] says so, after the vertex-sun pass.
    pub fn encode_vertex_light(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        model: &ModelGpu,
        (level, shadow_index): (usize, usize),
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let Some(bind_group) = self.bind_groups.get(shadow_index) else { return };
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("vertex light"), timestamp_writes: timestamps });
        pass.set_pipeline(&self.light);
        pass.set_bind_group(0, bind_group, &[]);
        for (mesh, _) in model.meshes.iter().zip(&self.light_chosen).filter(|(_, c)| **c) {
            let (group, count) = &mesh.light_groups[level.min(mesh.light_groups.len() - 1)];
            if *count > 0 {
                pass.set_bind_group(1, &mesh.material, &[]);
                pass.set_bind_group(2, group, &[]);
                pass.dispatch_workgroups(count.div_ceil(64), 1, 1);
            }
        }
    }

    pub fn vertex_sun_meshes(&self) -> &[bool] {
        &self.sun_chosen
    }

    /// Per mesh, as the last frame written drew it: its longest edge on screen (pixels at the
    /// model's nearest point; None where not measured) and whether it took the sun's visibility
    /// from its vertices.
    pub fn sun_per_mesh(&self) -> Vec<(Option<f32>, bool)> {
        self.sun_edges.iter().copied().zip(self.sun_chosen.iter().copied()).collect()
    }

    /// Per mesh, as the last frame written drew it: how far its normal turns across a triangle
    /// (degrees, [`mean_normal_turn`] at the level drawn) and whether it took its
    /// whole light from its vertices ([`Shading::LightFromVertices`]; a method other than
    /// sh9-ggx then draws it with the sun from them alone).
    pub fn light_per_mesh(&self) -> Vec<(f32, bool)> {
        self.light_turns.iter().map(|t| t.to_degrees()).zip(self.light_chosen.iter().copied()).collect()
    }

    /// Let the meshes whose edges on screen are at most `px` pixels long (over
    /// [`SUN_EDGE_AREA`] of their area), whose normal turns by at most `turn_scale` times
    /// [`light_turn_limit`] across a triangle, and whose sun comes from their vertices, take
    /// their whole light from their vertices, from the next frame written ([`MAX_LIGHT_EDGE_PX`]
    /// and 1 by default); `px` 0 shades every pixel.
    pub fn set_light_limits(&mut self, px: f32, turn_scale: f32) {
        (self.light_edge_limit, self.light_turn_scale) = (px, turn_scale);
    }

    /// Let the meshes whose edges on screen are at most `px` pixels long (over
    /// [`SUN_EDGE_AREA`] of their area) take the sun's visibility from their vertices, from the
    /// next frame written ([`MAX_SUN_EDGE_PX`] by default); 0 looks it up per pixel everywhere.
    pub fn set_sun_edge_limit(&mut self, px: f32) {
        self.sun_edge_limit = px;
    }

    /// Cull back faces where the frame may (true, the default) or draw every triangle after a
    /// depth pre-pass, from the next frame written. For a closed mesh seen from outside the two
    /// draw the same pixels (what the tests check); a single-sided material's back faces, which
    /// glTF culls, are then drawn as if it were double-sided.
    pub fn set_culling(&mut self, on: bool) {
        self.culling = on;
    }

    /// Draw `model` with `method`'s pipelines at level of detail `level`, sampling shadow map
    /// `shadow_index`: a single-sided material, and a closed mesh seen from outside, with its
    /// back faces culled; any other after its depth pre-pass.
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        model: &ModelGpu,
        method: LightingMethod,
        (level, shadow_index): (usize, usize),
    ) -> Result<()> {
        let bind_group = self.bind_groups.get(shadow_index).ok_or_else(|| anyhow!("no environment set"))?;
        pass.set_bind_group(0, bind_group, &[]);
        for mesh in model.meshes.iter().filter(|m| !self.culls(m, level)) {
            pass.set_pipeline(&self.prepass);
            mesh.draw(pass, Some(1), level);
        }
        for (k, mesh) in model.meshes.iter().enumerate() {
            let per_pixel = if self.culls(mesh, level) { Shading::Culled } else { Shading::EveryTriangle };
            let per_pixel = &self.shading[shading_index(method, self.corrected, per_pixel)];
            if self.sun_chosen.get(k).is_some_and(|&c| c) {
                let light = self.light_chosen.get(k).is_some_and(|&c| c);
                let per_vertex = match light {
                    false => Shading::SunFromVertices,
                    true => Shading::light_from_vertices(mesh.textured, self.light_kept),
                };
                mesh.draw_split(pass, (&self.shading[shading_index(method, self.corrected, per_vertex)], per_pixel), light);
            } else {
                pass.set_pipeline(per_pixel);
                mesh.draw(pass, Some(1), level);
            }
        }
        Ok(())
    }

    /// Whether this frame culls `mesh`'s back faces at `level`.
    fn culls(&self, mesh: &MeshGpu, level: usize) -> bool {
        match mesh.sides {
            Sides::Front => self.cull != Culling::Nothing,
            Sides::Both => false,
            Sides::Unspecified => self.cull == Culling::SingleSidedAndClosed && mesh.closed[level.min(mesh.closed.len() - 1)],
        }
    }

    /// Draw `model` with `pipeline(cull)` (a layer pipeline from render/layers.rs, culling back
    /// faces or not: each mesh culls as this frame's model pass does) at level of detail
    /// `level`, sampling shadow map `shadow_index` (the layers, offline, look the sun up per
    /// pixel on every mesh).
    pub fn draw_with<'p>(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: impl Fn(bool) -> &'p wgpu::RenderPipeline,
        model: &ModelGpu,
        (level, shadow_index): (usize, usize),
    ) -> Result<()> {
        let bind_group = self.bind_groups.get(shadow_index).ok_or_else(|| anyhow!("no environment set"))?;
        pass.set_bind_group(0, bind_group, &[]);
        for mesh in &model.meshes {
            pass.set_pipeline(pipeline(self.culls(mesh, level)));
            mesh.draw(pass, Some(1), level);
        }
        Ok(())
    }
}

/// The longest edge among the shortest-edged `triangles` (indices into `positions`, three a
/// triangle) that together cover `share` of their area: the triangles sorted by their longest
/// edge, the edge of the one where the running area reaches `share` (0 for none).
fn edge_over_area(positions: &[Vec3], triangles: &[u32], share: f32) -> f32 {
    let at = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let mut edges: Vec<(f32, f32)> = triangles
        .chunks_exact(3)
        .map(|t| {
            let (a, b, c) = (at(t[0]), at(t[1]), at(t[2]));
            let longest = a.distance_squared(b).max(b.distance_squared(c)).max(c.distance_squared(a)).sqrt();
            (longest, 0.5 * (b - a).cross(c - a).length())
        })
        .collect();
    edges.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f32 = edges.iter().map(|e| e.1).sum();
    let mut covered = 0.0;
    for &(edge, area) in &edges {
        covered += area;
        if covered >= share * total {
            return edge;
        }
    }
    edges.last().map_or(0.0, |e| e.0)
}

/// How far the normal turns across `triangles` (indices into `positions` and `normals`, three a
/// triangle): per triangle the largest angle between its vertex normals (radians), its mean
/// over the triangles weighted by their area (0 for none).
fn mean_normal_turn(positions: &[Vec3], normals: &[Vec3], triangles: &[u32]) -> f32 {
    let at = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let normal = |i: u32| normals.get(i as usize).copied().unwrap_or(Vec3::Z).normalize_or_zero();
    let (mut sum, mut total) = (0.0f64, 0.0f64);
    for t in triangles.chunks_exact(3) {
        let area = 0.5 * f64::from((at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0])).length());
        let (a, b, c) = (normal(t[0]), normal(t[1]), normal(t[2]));
        let cos = a.dot(b).min(b.dot(c)).min(c.dot(a)).clamp(-1.0, 1.0);
        sum += area * f64::from(cos.acos());
        total += area;
    }
    if total > 0.0 { (sum / total) as f32 } else { 0.0 }
}

/// The largest [`mean_normal_turn`] (radians) of a mesh of `material` (this frame's uniforms)
/// whose whole light may come from its vertices: [`MAX_MATTE_LIGHT_TURN`], and for a material
/// with a specular term (F0 · s_c > 0, as sh9_ggx.wgsl tests it) at most
/// [`LIGHT_TURN_PER_ROUGHNESS`] · α / √(F0 · s_c) (α its GGX roughness): the sharper or stronger
/// the reflection, the less of a turn its interpolation takes.
pub fn light_turn_limit(material: &MaterialUniforms) -> f32 {
    let [r, g, b, exponent] = material.specular;
    let strength = r.max(g).max(b) * material.terms[2];
    if strength > 0.0 {
        MAX_MATTE_LIGHT_TURN.min(LIGHT_TURN_PER_ROUGHNESS * ggx::roughness_from_exponent(exponent) / strength.sqrt())
    } else {
        MAX_MATTE_LIGHT_TURN
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytemuck::Zeroable;

    #[test]
    fn the_edge_over_a_share_of_the_area() {
        // A right triangle of legs 1 (area 0.5, longest edge √2) and one of legs 1 and 4 (area 2,
        // longest edge √17): the small one covers a fifth of the area.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 4.0, 0.0)];
        let both = [0, 1, 2, 0, 1, 3];
        assert_eq!(edge_over_area(&p, &[0, 1, 2], 0.95), 2f32.sqrt());
        assert_eq!(edge_over_area(&p, &both, 0.15), 2f32.sqrt());
        assert_eq!(edge_over_area(&p, &both, 0.25), 17f32.sqrt());
        assert_eq!(edge_over_area(&p, &[], 0.95), 0.0);
    }

    #[test]
    fn the_mean_turn_of_the_normal_weighs_triangles_by_area() {
        // Two triangles: normals turning by 90° in one of area 0.5, by 0 in one of area 1.5.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 4.0, 0.0), Vec3::new(0.0, 4.0, 0.0)];
        let n = [Vec3::Z, Vec3::X, Vec3::Z, Vec3::Z, Vec3::Z];
        let turn = mean_normal_turn(&p, &n, &[0, 1, 2, 2, 3, 4]);
        assert!((turn - std::f32::consts::FRAC_PI_2 * 0.5 / 2.0).abs() < 1e-6, "{turn}");
        // Opposite normals turn by 180°; no triangles, 0.
        assert!((mean_normal_turn(&p, &[Vec3::Z, -Vec3::Z, Vec3::Z], &[0, 1, 2]) - std::f32::consts::PI).abs() < 1e-6);
        assert_eq!(mean_normal_turn(&p, &n, &[]), 0.0);
    }

    #[test]
    fn a_sharper_reflection_takes_a_smaller_turn() {
        let material = |f0: f32, exponent: f32, s_c: f32| MaterialUniforms {
            albedo: [0.5; 4],
            specular: [f0, f0, f0, exponent],
            terms: [1.0, 1.0, s_c, 0.0],
        };
        // Matte: no F0, or no specular term.
        assert_eq!(light_turn_limit(&material(0.0, 25.0, 1.0)), MAX_MATTE_LIGHT_TURN);
        assert_eq!(light_turn_limit(&material(0.5, 25.0, 0.0)), MAX_MATTE_LIGHT_TURN);
        // Blinn-Phong 25: GGX roughness (2 / 27)^(1/4) = 0.52172; 100: (2 / 102)^(1/4) = 0.37420.
        let k = LIGHT_TURN_PER_ROUGHNESS;
        assert!((light_turn_limit(&material(0.5, 25.0, 0.3)) - k * 0.52172 / 0.15f32.sqrt()).abs() < 1e-4);
        assert!((light_turn_limit(&material(0.5, 100.0, 1.0)) - k * 0.37420 / 0.5f32.sqrt()).abs() < 1e-4);
        // A weak, rough one keeps the matte limit.
        assert_eq!(light_turn_limit(&material(0.04, 0.0, 0.3)), MAX_MATTE_LIGHT_TURN);
    }

    #[test]
    fn the_light_key_follows_what_the_vertex_light_reads() {
        let frame = FrameUniforms::zeroed();
        let (instance, light) = (InstanceUniforms::zeroed(), LightUniforms::zeroed());
        let material = MaterialUniforms { albedo: [0.5; 4], specular: [0.04, 0.04, 0.04, 25.0], terms: [1.0, 1.0, 1.0, 0.0] };
        let key = |f: &FrameUniforms, i: &InstanceUniforms, l: &LightUniforms, m: &MaterialUniforms, level: usize| {
            LightKey::new(3, (f, i, l), std::slice::from_ref(m), (level, &[true]))
        };
        let k = key(&frame, &instance, &light, &material, 2);
        // A camera that only turns (its view, and the shadow camera fitted to it) keeps the key.
        let turned = FrameUniforms { view_proj: [[1.0; 4]; 4], view: [[2.0; 4]; 4], light_view_proj: [[3.0; 4]; 4], ..frame };
        assert_eq!(key(&turned, &instance, &light, &material, 2), k);
        // Its position, the sun, the daylight, the placement, the sky, the material, the level,
        // the model and the meshes drawn so change it.
        assert_ne!(key(&FrameUniforms { camera_pos: [0.0, 0.0, 1e-6], ..frame }, &instance, &light, &material, 2), k);
        assert_ne!(key(&FrameUniforms { sun_dir: [0.0, 0.6, 0.8], ..frame }, &instance, &light, &material, 2), k);
        assert_ne!(key(&FrameUniforms { daylight: 0.5, ..frame }, &instance, &light, &material, 2), k);
        let moved = InstanceUniforms { model: [[0.0, 0.0, 0.0, 0.0], [0.0; 4], [0.0; 4], [1.0, 0.0, 0.0, 1.0]], ..instance };
        assert_ne!(key(&frame, &moved, &light, &material, 2), k);
        let mut sky = light;
        sky.sh[4][1] = 0.25;
        assert_ne!(key(&frame, &instance, &sky, &material, 2), k);
        assert_ne!(key(&frame, &instance, &light, &MaterialUniforms { terms: [1.0, 0.5, 1.0, 0.0], ..material }, 2), k);
        assert_ne!(key(&frame, &instance, &light, &material, 1), k);
        assert_ne!(LightKey::new(4, (&frame, &instance, &light), &[material], (2, &[true])), k);
        assert_ne!(LightKey::new(3, (&frame, &instance, &light), &[material, material], (2, &[true, false])), k);
    }

    #[test]
    fn the_light_is_computed_once_the_view_stops_changing_and_read_while_it_holds() {
        let key = |x: u8| LightKey(vec![x]);
        let (a, b) = (key(1), key(2));
        // No mesh lit from its vertices: nothing to do.
        assert_eq!(light_plan(None, Some(&a), Some(&a)), (false, false));
        // A new view (the camera moving): the vertex stage computes the light.
        assert_eq!(light_plan(Some(&b), Some(&a), Some(&a)), (false, false));
        assert_eq!(light_plan(Some(&a), None, None), (false, false));
        // The same view a second frame: the pass runs and the frame reads it ...
        assert_eq!(light_plan(Some(&b), Some(&b), Some(&a)), (true, true));
        assert_eq!(light_plan(Some(&b), Some(&b), None), (true, true));
        // ... and then frames read it while the key holds, whatever came between.
        assert_eq!(light_plan(Some(&b), Some(&b), Some(&b)), (false, true));
        assert_eq!(light_plan(Some(&b), Some(&a), Some(&b)), (false, true));
    }

    /// The vertex-light pass (`cs_light` and every function it calls) reads no field of the
    /// frame's uniform that [`LightKey`] leaves out ([`LIGHT_IGNORES`]): a turn of the camera
    /// that keeps the key keeps its light. Reads are member accesses on the `frame` global, on a
    /// load of it, or on a function argument of type Frame (how the shaders pass it).
    #[test]
    fn the_vertex_light_reads_no_frame_field_its_key_leaves_out() {
        use naga::{Expression, Statement};
        let module = crate::gpu::wgsl::validate(&source(Technique::Model)).unwrap();
        let frame_ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("Frame")).expect("struct Frame").0;
        let naga::TypeInner::Struct { members, .. } = &module.types[frame_ty].inner else { panic!("Frame is not a struct") };
        let global = module.global_variables.iter().find(|(_, g)| g.name.as_deref() == Some("frame")).expect("global frame").0;
        fn calls(block: &naga::Block, out: &mut Vec<naga::Handle<naga::Function>>) {
            for s in block.iter() {
                match s {
                    Statement::Call { function, .. } => out.push(*function),
                    Statement::Block(b) => calls(b, out),
                    Statement::If { accept, reject, .. } => {
                        calls(accept, out);
                        calls(reject, out);
                    }
                    Statement::Switch { cases, .. } => cases.iter().for_each(|c| calls(&c.body, out)),
                    Statement::Loop { body, continuing, .. } => {
                        calls(body, out);
                        calls(continuing, out);
                    }
                    _ => {}
                }
            }
        }
        let entry = module.entry_points.iter().find(|e| e.name == "cs_light").expect("cs_light");
        let mut todo = Vec::new();
        calls(&entry.function.body, &mut todo);
        let mut reached: Vec<&naga::Function> = vec![&entry.function];
        let mut seen = std::collections::HashSet::new();
        while let Some(f) = todo.pop() {
            if seen.insert(f) {
                calls(&module.functions[f].body, &mut todo);
                reached.push(&module.functions[f]);
            }
        }
        assert!(reached.len() > 3, "cs_light calls sh9-ggx's light");
        let mut read = std::collections::BTreeSet::new();
        for f in reached {
            let is_frame = |e: naga::Handle<Expression>| match f.expressions[e] {
                Expression::GlobalVariable(g) => g == global,
                Expression::Load { pointer } => matches!(f.expressions[pointer], Expression::GlobalVariable(g) if g == global),
                Expression::FunctionArgument(i) => f.arguments[i as usize].ty == frame_ty,
                _ => false,
            };
            for (_, e) in f.expressions.iter() {
                if let Expression::AccessIndex { base, index } = *e
                    && is_frame(base)
                {
                    read.insert(members[index as usize].name.clone().unwrap_or_default());
                }
            }
        }
        assert!(read.contains("camera_pos") && read.contains("env_rotation"), "{read:?}");
        for ignored in LIGHT_IGNORES {
            assert!(!read.contains(ignored), "cs_light reads frame.{ignored}, which LightKey leaves out");
        }
        // The key zeroes exactly these fields.
        let names: Vec<&str> = members.iter().filter_map(|m| m.name.as_deref()).collect();
        assert!(LIGHT_IGNORES.iter().all(|f| names.contains(f)));
    }

    #[test]
    fn material_terms_replace_the_loaded_ones() {
        let base = MaterialUniforms { albedo: [0.5, 0.6, 0.7, 1.0], specular: [0.1, 0.2, 0.3, 40.0], terms: [1.0; 4] };
        let terms = MaterialTerms { ambient: 0.2, diffuse: 0.8, specular: 0.4, gloss: None };
        let m = material_uniforms(&base, &terms);
        // The terms replaced, the material's sides (w: double-sided) kept.
        assert_eq!((m.albedo, m.specular, m.terms), (base.albedo, base.specular, [0.2, 0.8, 0.4, 1.0]));
        let m = material_uniforms(&base, &MaterialTerms { gloss: Some(8.0), ..terms });
        assert_eq!(m.specular, [0.1, 0.2, 0.3, 8.0]);
    }
}
