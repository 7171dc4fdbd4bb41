//! The ground pass (step 4 of DESIGN.md "One frame"): an invisible shadow-catcher plane under the
//! model darkens the background where the shadow map says the sun is blocked, with a penumbra
//! that follows the sun's size (frame.wgsl `sun_visibility_soft`), and where the model hides its
//! sky: the ground's sky visibility under the placed model (render::model_cache
//! PreparedModel::ground_sky) is a small texture written once per placement and sky shape, never
//! per frame. The same texture carries the light the model reflects onto the ground
//! ([`bounce_light`], scene::occlusion Transfer::bounce), which brightens it (differential
//! rendering: the path-traced references' ground sees the lit model where it hides the sky).

use super::super::uniforms::{InstanceUniforms, LightUniforms};
use crate::gpu::build;
use crate::render::frame::{GROUND_VERTICES, GroundMesh};
use crate::render::pipelines::{COLOR_FORMAT, Pipelines, depth_state};
use crate::render::shaders::{Technique, source};
use crate::render::shadow_fit;
use crate::scene::occlusion::{self, BounceLight, GroundSky};
use anyhow::{Result, bail};
use std::sync::Arc;
use wgpu::ShaderStages;

/// How a part of the ground gets the sun's visibility (shaders/ground.wgsl's `SUN`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SunOnGround {
    /// None: the part where the sun's shadow cannot fall (the sky's occlusion alone).
    SkyOnly = 0,
    /// Looked up in the shadow map per pixel (frame.wgsl `sun_visibility_soft`).
    Lookup = 1,
    /// Sampled from the ground-space texture the ground-sun pass drew from the same map
    /// (render::passes::ground_sun).
    Baked = 2,
}

impl SunOnGround {
    /// The WGSL constants naming each value of `SUN` (prepended to shaders/ground.wgsl).
    pub fn wgsl_consts() -> String {
        [("SUN_NONE", SunOnGround::SkyOnly), ("SUN_LOOKUP", SunOnGround::Lookup), ("SUN_BAKED", SunOnGround::Baked)]
            .iter()
            .map(|(name, v)| format!("const {name}: u32 = {}u;\n", *v as u32))
            .collect()
    }
}

/// The ground's pipelines: with the sun's shadow looked up or baked (where the shadow can fall)
/// and without (the rest of the ground), one bind-group layout.
pub struct GroundPipelines {
    pub layout: wgpu::BindGroupLayout,
    pub shadowed: wgpu::RenderPipeline,
    pub baked: wgpu::RenderPipeline,
    pub sky_only: wgpu::RenderPipeline,
}

/// The ground pipelines: triangles of [`GroundMesh`] corners; the background is multiplied by
/// twice the shader's output per channel ([`SCALE`]).
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
            build::texture_entry(5, fs, wgpu::TextureViewDimension::D2Array, true),
            build::sampler_entry(6, fs, wgpu::SamplerBindingType::Filtering),
            build::sampler_entry(7, fs, wgpu::SamplerBindingType::NonFiltering),
            build::uniform(8, fs),
            build::texture_entry(9, fs, wgpu::TextureViewDimension::D2, true),
        ],
    );
    // One module for the three (each pipeline sets its own `SUN`).
    let module = shader(device);
    let with = |sun| pipeline_for(device, (&layout, &module), (COLOR_FORMAT, samples), sun);
    let (shadowed, baked, sky_only) = (with(SunOnGround::Lookup), with(SunOnGround::Baked), with(SunOnGround::SkyOnly));
    GroundPipelines { layout, shadowed, baked, sky_only }
}

/// The ground's shader module (shaders/ground.wgsl).
pub fn shader(device: &wgpu::Device) -> wgpu::ShaderModule {
    build::shader(device, "ground", source(Technique::Ground))
}

/// The ground pipeline with bind-group `layout` and the ground's shader `module`, drawing into
/// `format` targets of `samples` per pixel, getting the sun's visibility as `sun` says (the
/// shader's `SUN`).
pub fn pipeline_for(
    device: &wgpu::Device,
    (layout, module): (&wgpu::BindGroupLayout, &wgpu::ShaderModule),
    (format, samples): (wgpu::TextureFormat, u32),
    sun: SunOnGround,
) -> wgpu::RenderPipeline {
    const ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x2];
    let vertices = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<[f32; 2]>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    };
    build::render_pipeline(
        device,
        build::PipelineSpec {
            label: match sun {
                SunOnGround::SkyOnly => "ground, sky only",
                SunOnGround::Lookup => "ground",
                SunOnGround::Baked => "ground, sun baked",
            },
            module,
            layouts: &[layout],
            vertex_buffers: &[Some(vertices)],
            colour: Some(wgpu::ColorTargetState { format, blend: Some(SCALE), write_mask: wgpu::ColorWrites::ALL }),
            depth: depth_state(false, wgpu::DepthBiasState::default()),
            samples,
            constants: &[("SUN", f64::from(sun as u32))],
        },
    )
}

/// The ground's blend: `src · dst + dst · src = dst · 2 src` per colour channel, the target's
/// alpha kept. The shader writes half the factor the ground's light changes by (shaders/
/// ground.wgsl: 1 − what it loses + what the model reflects onto it), so the factor spans 0..2
/// although an 8-bit target clamps what the shader writes to 0..1: the ground can brighten where
/// the model reflects more light onto it than it hides.
pub const SCALE: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::Dst,
        dst_factor: wgpu::BlendFactor::Src,
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
    baked: wgpu::RenderPipeline,
    sky_only: wgpu::RenderPipeline,
    /// The part where the sun's shadow can fall samples the ground-sun texture this frame
    /// instead of looking the map up ([`GroundPass::sun_baked`]).
    sun_baked: bool,
    /// The frame's [`GroundMesh`] corners ([`GROUND_VERTICES`], written each frame).
    vertices: wgpu::Buffer,
    /// Of them, drawn with the shadow lookup, then without.
    counts: (u32, u32),
    /// One per shadow map (in the order of `ShadowPass::maps`).
    bind_groups: Vec<wgpu::BindGroup>,
    /// The plane's transform (`InstanceUniforms`).
    instance: wgpu::Buffer,
    /// Three layers of Rgba16Float, [`GROUND_TEXELS`]², over the square in the `Light` uniform's
    /// `ground_square` ([`ground_texels`]): the ground's sky visibility under the model per
    /// channel (rgb, 1 = whole sky, in 255ths: [`sky_texels`]), the model's light on it (rgb:
    /// the gain on the ground's light per channel), and what they take from it where the sun's
    /// shadow is not looked up ([`sky_only_texels`]).
    sky: wgpu::Texture,
    /// The map and the light (the `Light` uniform's sun colour and sky share and colour, the
    /// frame's `shadow_opacity`, as bits) the third layer was computed for.
    sky_only_for: Option<(Arc<GroundSky>, [u32; 8])>,
}

/// Texels per side of the ground pass's sky-visibility texture.
pub const GROUND_TEXELS: u32 = occlusion::GROUND_TEXELS;

/// A sky-visibility map per channel ([`GroundSky::channels`]) in whole 255ths (0..=1 →
/// 0..=255, rounded), as the ground pass holds it.
pub fn sky_texels(sky: &GroundSky) -> Vec<[u8; 3]> {
    (0..sky.visibility.len()).map(|i| sky.channels(i).map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
}

/// The ground pass's two layers of a map, as Rgba16Float: the visibility per channel in 255ths
/// ([`sky_texels`]; alpha 1), and the model's light per channel (0 without any; alpha 0).
pub fn ground_texels(sky: &GroundSky) -> [Vec<half::f16>; 2] {
    let f = half::f16::from_f32;
    let visibility = sky_texels(sky).iter().flat_map(|v| [v[0], v[1], v[2], 255].map(|c| f(f32::from(c) / 255.0))).collect();
    let bounce = (0..sky.visibility.len())
        .flat_map(|i| {
            let b = sky.bounce.get(i).copied().unwrap_or([0.0; 3]);
            [f(b[0]), f(b[1]), f(b[2]), half::f16::ZERO]
        })
        .collect();
    [visibility, bounce]
}

/// The light the model reflects onto the ground, as the ground map takes it
/// (occlusion::GroundTransfer::map, [`BounceLight`]): what the model's surface facing n
/// reflects, albedo × E(n)/π, in units of the ground's own E/π, per channel. E(n) is the light
/// of the frame's `lighting` as the model's own shading gives it (shaders/sh9_ggx.wgsl
/// `sky_and_ground`, each part by the surface's light shares): the sky (`sky_sh`, the map's
/// frame turned by `heading` into the world), the uniform ground below the horizon
/// (`ground_radiance`: E/π = L (1 − n_z)/2; lit by the sky and by the sun in the proportion
/// render::frame::sun_share_on_ground) and the sun (`sun_colour`, max(n·s, 0), unshadowed by
/// the model itself). Their strengths
/// are the ground's shares of its light, as the ground pass darkens it: the sky gives the
/// ground `sky_occlusion`, the sun `shadow_opacity` (of luminance 1 in all), so the bounce is a
/// gain on the ground's light whatever the method's daylight scale. None without either share.
pub fn bounce_light(lighting: &crate::render::Lighting, heading: f32, albedo: [f32; 3]) -> BounceLight {
    use crate::light::sh9::{basis, world_coeffs};
    let lum = crate::colour::luminance_bt709;
    let mut light = BounceLight::NONE;
    // The sky in the world, per channel, and the light it gives the ground (n = up).
    let sky: [[f32; 9]; 3] = std::array::from_fn(|c| world_coeffs(&std::array::from_fn(|k| lighting.sky_sh[k][c]), heading));
    let up = basis(glam::Vec3::Z);
    let sky_up: [f32; 3] = std::array::from_fn(|c| sky[c].iter().zip(up).map(|(a, y)| a * y).sum::<f32>().max(0.0));
    let sky_scale = if lum(sky_up) > 0.0 { lighting.sky_occlusion.max(0.0) / lum(sky_up) } else { 0.0 };
    let sun_share = crate::render::frame::sun_share_on_ground(lighting);
    let mut ground = [0.0f32; 3];
    for c in 0..3 {
        ground[c] += sky_scale * sky_up[c];
        for (k, l) in light.sky.iter_mut().enumerate() {
            l[c] = sky_scale * sky[c][k];
        }
        let g = sky_scale * lighting.ground_radiance[c];
        light.ground[0][c] = g * (1.0 - sun_share);
        light.ground[1][c] = g * sun_share;
    }
    // The sun: E_sun/π · max(n·s, 0), E_sun/π · s_z being its share of the ground's light.
    let s = lighting.sun_dir.normalize_or_zero();
    // Without sunlight (the live view's SL at 0) the ground pass draws no sun shadow and the
    // model no sunlit side: no sun in the bounce either, whatever its direction.
    if lighting.shadow_opacity > 0.0 && lighting.sunlight > 0.0 && s.z > 1e-3 {
        for ((g, sun), colour) in ground.iter_mut().zip(&mut light.sun).zip(lighting.sun_colour) {
            *g += lighting.shadow_opacity * colour;
            *sun = lighting.shadow_opacity / s.z * colour;
        }
        // Rounded (about 0.1°) so that a frame whose sun barely moves keeps the map.
        light.sun_dir = s.to_array().map(|v| (v * 1024.0).round() / 1024.0);
    }
    // Per unit of the ground's light, times the albedo; rounded (to 1/256) so that a frame whose
    // light barely moves keeps the map.
    let scale: [f32; 3] = std::array::from_fn(|c| if ground[c] > 0.0 { albedo[c] / ground[c] } else { 0.0 });
    let per_ground = |l: &mut [f32; 3]| (0..3).for_each(|c| l[c] = (l[c] * scale[c] * 256.0).round() / 256.0);
    light.sky.iter_mut().chain(&mut light.ground).chain(std::iter::once(&mut light.sun)).for_each(per_ground);
    light
}

/// The largest loss of light (the fraction the ground pass takes, [`SCALE`]) that moves no
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
    sky_loss_per_channel(light, shadow_opacity).into_iter().fold(0.0, f32::max)
}

/// Per colour channel, what the ground loses per unit of the sky's occlusion where the sun's
/// shadow is not looked up (shaders/ground.wgsl `ground_loss` with no sun lost, before its clamp).
pub fn sky_loss_per_channel(light: &LightUniforms, shadow_opacity: f32) -> [f32; 3] {
    let sky_share = light.ground_sky[0];
    let total = shadow_opacity + sky_share;
    if total <= 0.0 {
        return [0.0; 3];
    }
    std::array::from_fn(|c| {
        let (sun, sky) = (light.sun[c], light.ground_sky[c + 1]);
        let light = (shadow_opacity * sun + sky_share * sky) / total;
        sky_share * sky / light.max(1e-6)
    })
}

/// What the ground loses where the sun's shadow is not looked up, per texel of the map's two
/// layers as the pass holds them ([`ground_texels`]): min(per_channel · (1 − visibility), 1) −
/// bounce per channel, 1 minus the factor shaders/ground.wgsl `fs_main` gives with no sun lost,
/// `per_channel` from [`sky_loss_per_channel`]. The map's third layer: the sky-only part of the
/// ground samples it once instead of the two layers and the loss (docs/PERFORMANCE.md,
/// seventeenth session). Held as 1 − the factor because half floats are finest near 0, where
/// most of the ground is (as the factor, its rounding moved 8-bit values by a level in 0.1 % of
/// tests/lod.rs's sky-only pixels). Linear in the texels but for the clamp, so its bilinear sample
/// is the loss of the bilinear samples where no channel loses its whole light.
pub fn sky_only_texels([visibility, bounce]: &[Vec<half::f16>; 2], per_channel: [f32; 3]) -> Vec<half::f16> {
    visibility
        .chunks_exact(4)
        .zip(bounce.chunks_exact(4))
        .flat_map(|(v, b)| {
            let lost = |c: usize| (per_channel[c] * (1.0 - v[c].to_f32())).min(1.0) - b[c].to_f32();
            [lost(0), lost(1), lost(2), 0.0].map(half::f16::from_f32)
        })
        .collect()
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

    /// `shadow_fit::sky_region` of `sky` where its occlusion reaches `min_occlusion` or the
    /// model's light on it [`INVISIBLE_LOSS`]. The map's texels hide whole 255ths of the sky, so
    /// the region only changes when the threshold crosses one.
    pub fn sky(&mut self, sky: &Arc<GroundSky>, min_occlusion: f32) -> &[glam::Vec2] {
        let levels = (min_occlusion.max(0.0) * 255.0 - 1e-3).ceil().clamp(1.0, 256.0) as u32;
        if self.sky.as_ref().is_none_or(|(held, l, _)| !Arc::ptr_eq(held, sky) || *l != levels) {
            // A gain g brightens an 8-bit sRGB value by at most 255 · 1.055/2.4 · g levels, less
            // than the loss that darkens it by one: INVISIBLE_LOSS keeps it under a level.
            let region = shadow_fit::sky_region(sky, levels as f32 / 255.0, INVISIBLE_LOSS);
            self.sky_regions_computed += 1;
            self.sky = Some((sky.clone(), levels, region));
        }
        self.sky.as_ref().map_or(&[], |(_, _, r)| r)
    }
}

impl GroundPass {
    /// Reads the Frame and Light uniform buffers, one of the sun's `shadow_maps` per frame, the
    /// ground's sky visibility and the ground-sun pass's uniform and texture (`ground_sun`).
    pub fn new(
        (device, queue): (&wgpu::Device, &wgpu::Queue),
        pipelines: &Pipelines,
        (frame, light): (&wgpu::Buffer, &wgpu::Buffer),
        shadow_maps: &[wgpu::TextureView],
        ground_sun: (&wgpu::Buffer, &wgpu::TextureView),
    ) -> GroundPass {
        let instance = build::uniform_buffer::<InstanceUniforms>(device, "ground plane");
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let side = GROUND_TEXELS;
        let sky = build::texture(device, "ground sky visibility", (side, side, 3), wgpu::TextureFormat::Rgba16Float, 1, usage);
        // The whole sky and no bounce everywhere until a model is placed: nothing lost.
        let (one, zero) = (half::f16::ONE, half::f16::ZERO);
        for (layer, texel) in [[one; 4], [zero; 4], [zero; 4]].iter().enumerate() {
            build::write_layer(queue, &sky, layer as u32, bytemuck::cast_slice(&texel.repeat((side * side) as usize)));
        }
        let sky_view =
            sky.create_view(&wgpu::TextureViewDescriptor { dimension: Some(wgpu::TextureViewDimension::D2Array), ..Default::default() });
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
                        ground_sun.0.as_entire_binding(),
                        wgpu::BindingResource::TextureView(ground_sun.1),
                    ],
                )
            })
            .collect();
        let size = (GROUND_VERTICES * std::mem::size_of::<[f32; 2]>()) as u64;
        let usage = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
        let vertices = build::buffer(device, "ground triangles", size, usage);
        GroundPass {
            pipeline: pipelines.ground.shadowed.clone(),
            baked: pipelines.ground.baked.clone(),
            sky_only: pipelines.ground.sky_only.clone(),
            sun_baked: false,
            vertices,
            counts: (0, 0),
            bind_groups,
            instance,
            sky,
            sky_only_for: None,
        }
    }

    /// The ground's sky visibility under the model as placed now (once per placement). A map of
    /// another size than [`GROUND_TEXELS`] is an error.
    pub fn write_sky(&self, queue: &wgpu::Queue, sky: &GroundSky) -> Result<()> {
        if sky.size != GROUND_TEXELS || sky.visibility.len() != (sky.size * sky.size) as usize {
            bail!("a ground sky map of {} texels a side; the ground pass holds {GROUND_TEXELS}", sky.size);
        }
        for (layer, texels) in ground_texels(sky).iter().enumerate() {
            build::write_layer(queue, &self.sky, layer as u32, bytemuck::cast_slice(texels));
        }
        Ok(())
    }

    /// The map's third layer for the frame's light ([`sky_only_texels`]): written when the map
    /// `sky` (as [`GroundPass::write_sky`] wrote it) or the light changed since the last.
    pub fn write_sky_only(&mut self, queue: &wgpu::Queue, sky: &Arc<GroundSky>, light: &LightUniforms, shadow_opacity: f32) {
        let mut key = [0u32; 8];
        for (k, v) in key.iter_mut().zip(light.sun[..3].iter().chain(&light.ground_sky).chain([&shadow_opacity])) {
            *k = v.to_bits();
        }
        if self.sky_only_for.as_ref().is_some_and(|(held, k)| Arc::ptr_eq(held, sky) && *k == key) {
            return;
        }
        let texels = sky_only_texels(&ground_texels(sky), sky_loss_per_channel(light, shadow_opacity));
        build::write_layer(queue, &self.sky, 2, bytemuck::cast_slice(&texels));
        self.sky_only_for = Some((sky.clone(), key));
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

    /// Whether this frame's part where the sun's shadow can fall samples the ground-sun texture
    /// (render::passes::ground_sun) instead of looking the map up.
    pub fn sun_baked(&mut self, on: bool) {
        self.sun_baked = on;
    }

    /// Whether the part where the sun's shadow can fall samples the ground-sun texture.
    pub fn is_sun_baked(&self) -> bool {
        self.sun_baked && self.counts.0 > 0
    }

    /// The vertices drawn with the shadow lookup and without.
    pub fn counts(&self) -> (u32, u32) {
        self.counts
    }

    /// Draw the ground, sampling shadow map `shadow_index`: the part where the sun's shadow can
    /// fall with the sun's visibility (looked up, or baked: [`GroundPass::sun_baked`]), the rest
    /// without.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, shadow_index: usize) {
        self.draw_parts(pass, [&self.pipeline, &self.baked, &self.sky_only], shadow_index);
    }

    /// [`GroundPass::draw`] with other targets' twins of its pipelines (looked up, baked, sky
    /// only; render::reprojection's matte).
    pub fn draw_parts(&self, pass: &mut wgpu::RenderPass<'_>, [lookup, baked, sky]: [&wgpu::RenderPipeline; 3], shadow_index: usize) {
        let (shadowed, sky_only) = self.counts;
        pass.set_bind_group(0, &self.bind_groups[shadow_index], &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        if shadowed > 0 {
            pass.set_pipeline(if self.sun_baked { baked } else { lookup });
            pass.draw(0..shadowed, 0..1);
        }
        if sky_only > 0 {
            pass.set_pipeline(sky);
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

    /// A frame's lighting with only the terms [`bounce_light`] reads set.
    fn lit(sky_sh: [[f32; 3]; 9], ground_radiance: [f32; 3], sun: (glam::Vec3, f32), sky_occlusion: f32) -> crate::render::Lighting {
        use crate::render::{Lighting, MaterialTerms};
        Lighting {
            sun_dir: sun.0,
            sunlight: 1.0,
            daylight: 0.3,
            material: MaterialTerms { ambient: 1.0, diffuse: 1.0, specular: 0.0, gloss: None },
            reflection: 0.0,
            ior: 1.5,
            shadow_opacity: sun.1,
            sky_occlusion,
            live_depth: 2.0,
            sky_sh,
            sky_radiance: crate::light::sh9::SkyRadiance::UNIFORM,
            ground_radiance,
            sun_colour: [1.0; 3],
            sun_angular_radius: 0.005,
        }
    }

    /// What an open model surface facing unit `n` reflects under `light`, per channel: the
    /// sky's, the sun's and the ground's parts (occlusion::Transfer::reflected for one hit).
    fn reflected(light: &BounceLight, n: glam::Vec3) -> [f32; 3] {
        let y = crate::light::sh9::basis(n);
        let down = 0.5 * (1.0 - n.z);
        let sun = n.dot(glam::Vec3::from(light.sun_dir)).max(0.0);
        std::array::from_fn(|c| {
            let sky: f32 = light.sky.iter().zip(y).map(|(l, y)| l[c] * y).sum();
            sky + sun * light.sun[c] + down * (light.ground[0][c] + light.ground[1][c])
        })
    }

    #[test]
    fn the_model_reflects_its_albedo_times_its_light_over_the_grounds() {
        let albedo = [0.8, 0.5, 0.2];
        let close = |a: [f32; 3], b: [f32; 3], tol: f32| a.iter().zip(b).all(|(a, b)| (a - b).abs() < tol);
        let normals = [glam::Vec3::Z, -glam::Vec3::Z, glam::Vec3::X, glam::Vec3::new(0.6, 0.0, -0.8)];
        // A uniform sky over the upper hemisphere (E/π = (1 + n_z)/2, exact in SH9: 0.5/Y00 and
        // 0.5/Y10's constant) over a ground of the same radiance: every surface gets what the
        // ground gets, so each reflects its albedo (a gain of ρ on the ground's light, whatever
        // the sky's share).
        let mut sky = [[0.0; 3]; 9];
        sky[0] = [0.5 / 0.282_095; 3];
        sky[2] = [0.5 / 0.488_603; 3];
        for heading in [0.0, 1.0] {
            let light = bounce_light(&lit(sky, [1.0; 3], (glam::Vec3::Z, 0.0), 0.7), heading, albedo);
            for n in normals {
                assert!(close(reflected(&light, n), albedo, 0.01), "{n}: {:?}", reflected(&light, n));
            }
        }
        // The same sky over a black ground: a surface facing down gets nothing, one facing up all.
        let light = bounce_light(&lit(sky, [0.0; 3], (glam::Vec3::Z, 0.0), 1.0), 0.0, albedo);
        assert!(close(reflected(&light, -glam::Vec3::Z), [0.0; 3], 0.01) && close(reflected(&light, glam::Vec3::Z), albedo, 0.01));
        // The sun alone, 30° up: a surface facing it gets 1/sin 30° = 2 times the ground's light,
        // one facing away or edge-on none, one facing straight up sin 30° / sin 30° = 1.
        let s = glam::Vec3::new(0.0, 3f32.sqrt(), 1.0).normalize();
        let light = bounce_light(&lit([[0.0; 3]; 9], [0.0; 3], (s, 1.0), 0.0), 0.0, albedo);
        assert!(close(reflected(&light, s), albedo.map(|a| a * 2.0), 0.01), "{:?}", reflected(&light, s));
        assert!(close(reflected(&light, glam::Vec3::Z), albedo, 0.01), "{:?}", reflected(&light, glam::Vec3::Z));
        assert_eq!(reflected(&light, -s), [0.0; 3]);
        assert_eq!(reflected(&light, glam::Vec3::X), [0.0; 3]);
        // No light on the ground: no bounce.
        assert_eq!(bounce_light(&lit([[0.0; 3]; 9], [0.0; 3], (s, 0.0), 0.0), 0.0, albedo), BounceLight::NONE);
    }

    #[test]
    fn the_ground_texels_hold_the_visibility_in_255ths_and_the_bounce() {
        let mut sky = GroundSky {
            min: glam::Vec2::ZERO,
            max: glam::Vec2::ONE,
            z: 0.0,
            size: 2,
            visibility: vec![1.0, 0.5, 0.0, 0.25],
            visibility_rgb: Vec::new(),
            bounce: Vec::new(),
        };
        let layers = |sky: &GroundSky| ground_texels(sky).map(|l| l.iter().map(|v| v.to_f32()).collect::<Vec<f32>>());
        // Without colour, the visibility in every channel (0.5 → 128 of 255); no bounce.
        let [v, b] = layers(&sky);
        assert!(v[4..7].iter().all(|c| (c - 128.0 / 255.0).abs() < 1e-3) && v[7] == 1.0 && v[0] == 1.0, "{v:?}");
        assert!(b.iter().all(|&c| c == 0.0), "{b:?}");
        sky.bounce = vec![[0.0; 3], [0.25, 0.5, 1.5], [0.0; 3], [0.0; 3]];
        sky.visibility_rgb = vec![[1.0; 3], [0.4, 0.5, 0.6], [0.0; 3], [0.2, 0.25, 0.3]];
        let [v, b] = layers(&sky);
        assert_eq!(b[4..8], [0.25, 0.5, 1.5, 0.0]);
        // 0.4, 0.5, 0.6 → 102, 128, 153 (rounded) of 255, in half floats.
        for (got, want) in v[4..7].iter().zip([102.0f32, 128.0, 153.0]) {
            assert!((got - want / 255.0).abs() < 1e-3, "{v:?}");
        }
        assert_eq!(sky_texels(&sky)[3], [51, 64, 77]);
    }

    #[test]
    fn the_sky_only_loss_is_one_minus_what_the_shader_gives_with_no_sun_lost() {
        let f = half::f16::from_f32;
        // One texel: visibility 0.4, 1, 0 per channel, bounce 0.1, 0, 0.25.
        let layers = [vec![f(0.4), f(1.0), f(0.0), f(1.0)], vec![f(0.1), f(0.0), f(0.25), f(0.0)]];
        let texels = sky_only_texels(&layers, [0.5, 0.5, 2.0]);
        let got: Vec<f32> = texels.iter().map(|h| h.to_f32()).collect();
        // R: 0.5 * 0.6 - 0.1 = 0.2 (the factor 0.8); G: nothing hidden, 0; B: 2 * 1 clamps to the
        // whole light lost, 1 - 0.25. (f16 holds them to 2^-11 relative.)
        for (g, want) in got.iter().zip([0.2, 0.0, 0.75, 0.0]) {
            assert!((g - want).abs() < 5e-4, "{got:?}");
        }
        // Without a model's map (the whole sky, no bounce) nothing is lost whatever the light.
        let whole = [vec![f(1.0); 4], vec![f(0.0); 4]];
        assert!(sky_only_texels(&whole, [3.0, 0.2, 1.0]).iter().all(|h| h.to_f32() == 0.0));
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
