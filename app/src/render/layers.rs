//! The layers a compositor expects (`composite --layers DIR`, the live shutter): the frame's own
//! passes drawn again, each alone, into float targets (`Rgba16Float`, multisampled like the
//! frame and resolved), read back in linear light:
//!
//! - background: the background pass alone;
//! - shadow matte: the ground pass over white — what the ground leaves of the background per
//!   channel, 1 = no change, 0 = black, above 1 (up to 2) where the model reflects more light
//!   onto the ground than it hides (the ground multiplies the background by it: a shadow keeps
//!   the colour of the light left in it);
//! - model: the model pass alone over transparent black — premultiplied RGBA, alpha = coverage;
//! - depth: the model's distance from the camera centre in metres (single-sampled, the model
//!   pass's own vertex stage), `+inf` where the model does not cover the pixel;
//!
//! and the beauty composed from them as the frame composes them (the ground darkens the
//! background, the model blends over it premultiplied): `beauty = model + (1 − α)·background·matte` per channel.
//! Targets and pipelines exist only once layers are asked for.

use super::passes::{background, ground, model};
use super::pipelines::{DEPTH_FORMAT, Pipelines};
use crate::gpu::{Gpu, Readback, build};
use anyhow::Result;
use glam::{Mat4, Vec3, Vec4};
use std::sync::Arc;

/// Colour format of the layer targets: float, blendable and multisampled on every WebGPU device.
pub const LAYER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The multi-layer EXR's name in a layers folder (`composite --layers`, the live shutter).
pub const EXR_FILE: &str = "layers.exr";

/// The EXR channel names, in the order of [`LayerImages::channels`]: the beauty as the file's
/// default layer (`R`, `G`, `B`, `A`, what any viewer shows), then `layer.channel`.
pub const CHANNELS: [&str; 15] = [
    "R",
    "G",
    "B",
    "A",
    "model.R",
    "model.G",
    "model.B",
    "model.A",
    "shadow.R",
    "shadow.G",
    "shadow.B",
    "background.R",
    "background.G",
    "background.B",
    "depth.Z",
];

/// The float twins of the background, ground and model pipelines, and the model's depth-only
/// pipeline: built on the first layers render at a sample count, shared by every compositor on
/// the device that draws its layers with that many.
pub struct LayerPipelines {
    background: wgpu::RenderPipeline,
    ground: wgpu::RenderPipeline,
    /// Without and with back faces culled, each indexed by `LightingMethod::shader_id`.
    model: [Vec<wgpu::RenderPipeline>; 2],
    /// Without and with back faces culled.
    depth: [wgpu::RenderPipeline; 2],
}

impl LayerPipelines {
    /// Made with the composite pipelines' bind-group layouts, so the passes' bind groups serve
    /// both; for layer targets of `samples` per pixel ([`LayerTargets::new`]), once per count.
    pub fn shared(gpu: &Gpu, pipelines: &Pipelines, samples: u32) -> Result<Arc<LayerPipelines>> {
        gpu.shared_per("the layer pipelines", samples, |gpu| {
            let device = &gpu.device;
            Ok(LayerPipelines {
                background: background::pipeline_for(device, &pipelines.background.layout, LAYER_FORMAT, samples),
                ground: ground::pipeline_for(
                    device,
                    (&pipelines.ground.layout, &ground::shader(device)),
                    (LAYER_FORMAT, samples),
                    ground::SunOnGround::Lookup,
                ),
                model: [false, true].map(|cull| {
                    let layouts = (&pipelines.model.layout, &pipelines.model.material_layout);
                    model::pipelines_for(device, layouts, (LAYER_FORMAT, samples), (true, cull))
                }),
                depth: [false, true].map(|cull| model::depth_pipeline(device, &pipelines.model, cull)),
            })
        })
    }

    pub fn background(&self) -> &wgpu::RenderPipeline {
        &self.background
    }

    pub fn ground(&self) -> &wgpu::RenderPipeline {
        &self.ground
    }

    /// The model layer's pipeline for `method`, culling back faces or not.
    pub fn model(&self, method: super::LightingMethod, cull: bool) -> &wgpu::RenderPipeline {
        &self.model[usize::from(cull)][method.shader_id() as usize]
    }

    /// The depth layer's pipeline, culling back faces or not.
    pub fn depth(&self, cull: bool) -> &wgpu::RenderPipeline {
        &self.depth[usize::from(cull)]
    }
}

/// Which layer a pass draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerPass {
    Background,
    Matte,
    Model,
}

impl LayerPass {
    /// What the layer starts from: black behind the background, white under the matte (nothing
    /// darkened), transparent black under the model.
    fn clear(self) -> wgpu::Color {
        match self {
            LayerPass::Background => wgpu::Color::BLACK,
            LayerPass::Matte => wgpu::Color::WHITE,
            LayerPass::Model => wgpu::Color::TRANSPARENT,
        }
    }
}

struct Resolved {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    readback: Readback,
}

/// The layer targets at one output size: one multisampled float colour and depth target that
/// every layer pass draws into, a resolved float texture per colour layer, the single-sampled
/// depth, and their readbacks.
pub struct LayerTargets {
    /// The multisampled colour target; None at one sample a pixel (drawn straight into the
    /// layers' textures).
    msaa: Option<wgpu::TextureView>,
    msaa_depth: wgpu::TextureView,
    background: Resolved,
    matte: Resolved,
    model: Resolved,
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    depth_readback: Readback,
}

impl LayerTargets {
    /// Targets of `width` × `height` pixels of `samples` each (resolved into single-sampled ones).
    pub fn new(device: &wgpu::Device, (width, height): (u32, u32), samples: u32) -> Result<LayerTargets> {
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let size = (width, height, 1);
        let msaa = (samples > 1).then(|| build::texture(device, "layer msaa colour", size, LAYER_FORMAT, samples, attach));
        let msaa_depth = build::texture(device, "layer msaa depth", size, DEPTH_FORMAT, samples, attach);
        let resolved = |label: &str| -> Result<Resolved> {
            let texture = build::texture(device, label, size, LAYER_FORMAT, 1, attach | wgpu::TextureUsages::COPY_SRC);
            let readback = Readback::for_texture(device, label, &texture)?;
            Ok(Resolved { view: texture.create_view(&Default::default()), texture, readback })
        };
        let depth = build::texture(device, "layer depth", size, DEPTH_FORMAT, 1, attach | wgpu::TextureUsages::COPY_SRC);
        Ok(LayerTargets {
            msaa: msaa.map(|t| t.create_view(&Default::default())),
            msaa_depth: msaa_depth.create_view(&Default::default()),
            background: resolved("background layer")?,
            matte: resolved("shadow matte layer")?,
            model: resolved("model layer")?,
            depth_view: depth.create_view(&Default::default()),
            depth_readback: Readback::for_texture(device, "depth layer", &depth)?,
            depth,
        })
    }

    /// A layer's pass: the multisampled float target cleared for `layer` (depth cleared to 1),
    /// resolved into the layer's texture.
    pub fn begin<'e>(&self, encoder: &'e mut wgpu::CommandEncoder, layer: LayerPass) -> wgpu::RenderPass<'e> {
        let resolve = match layer {
            LayerPass::Background => &self.background.view,
            LayerPass::Matte => &self.matte.view,
            LayerPass::Model => &self.model.view,
        };
        // One sample a pixel draws into the layer's texture itself (nothing to resolve).
        let (view, resolve_target, store) = match &self.msaa {
            None => (resolve, None, wgpu::StoreOp::Store),
            Some(msaa) => (msaa, Some(resolve), wgpu::StoreOp::Discard),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("layer"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(layer.clear()), store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.msaa_depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// The depth layer's pass: single-sampled depth only, cleared to 1 (no surface), kept.
    pub fn begin_depth<'e>(&self, encoder: &'e mut wgpu::CommandEncoder) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("depth layer"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// Record the copies of every layer into its readback buffer.
    pub fn copy_for_readback(&self, encoder: &mut wgpu::CommandEncoder) {
        for r in [&self.background, &self.matte, &self.model] {
            r.readback.copy(encoder, &r.texture);
        }
        self.depth_readback.copy(encoder, &self.depth);
    }

    /// The layers after the copies were submitted; `view_proj` and `camera` (world) turn the
    /// depth buffer into camera distances.
    pub fn read(&self, gpu: &Gpu, view_proj: Mat4, camera: Vec3) -> Result<LayerImages> {
        let (width, height) = (self.depth.width(), self.depth.height());
        let rgba = |r: &Resolved| -> Result<Vec<[f32; 4]>> {
            let bytes = r.readback.read(gpu)?;
            Ok(bytes
                .chunks_exact(8)
                .map(|t| std::array::from_fn(|c| half::f16::from_le_bytes([t[2 * c], t[2 * c + 1]]).to_f32()))
                .collect())
        };
        let background = rgba(&self.background)?;
        let matte: Vec<[f32; 3]> = rgba(&self.matte)?.iter().map(|p| [p[0], p[1], p[2]]).collect();
        let model = rgba(&self.model)?;
        let inverse = view_proj.inverse();
        let depth = self
            .depth_readback
            .read(gpu)?
            .chunks_exact(4)
            .enumerate()
            .map(|(i, b)| {
                let pixel = ((i as u32 % width) as f32 + 0.5, (i as u32 / width) as f32 + 0.5);
                camera_distance(inverse, camera, pixel, (width, height), f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            })
            .collect();
        let beauty = model.iter().zip(&background).zip(&matte).map(|((&m, &b), &s)| compose(m, b, s)).collect();
        Ok(LayerImages { width, height, beauty, model, matte, background, depth })
    }
}

/// The layers of one frame, linear light, row-major from the top-left pixel.
#[derive(Clone, Debug)]
pub struct LayerImages {
    pub width: u32,
    pub height: u32,
    /// [`compose`] of the layers below.
    pub beauty: Vec<[f32; 4]>,
    /// Premultiplied RGBA, alpha = coverage.
    pub model: Vec<[f32; 4]>,
    /// 1 = the ground leaves the background as it is, 0 = black.
    pub matte: Vec<[f32; 3]>,
    pub background: Vec<[f32; 4]>,
    /// Camera distance in metres; `+inf` where the model does not cover the pixel centre.
    pub depth: Vec<f32>,
}

impl LayerImages {
    /// Every channel as a plane, named and ordered as [`CHANNELS`].
    pub fn channels(&self) -> Vec<(&'static str, Vec<f32>)> {
        let plane = |v: &[[f32; 4]], c: usize| v.iter().map(|p| p[c]).collect::<Vec<f32>>();
        let planes = [
            plane(&self.beauty, 0),
            plane(&self.beauty, 1),
            plane(&self.beauty, 2),
            plane(&self.beauty, 3),
            plane(&self.model, 0),
            plane(&self.model, 1),
            plane(&self.model, 2),
            plane(&self.model, 3),
            self.matte.iter().map(|p| p[0]).collect(),
            self.matte.iter().map(|p| p[1]).collect(),
            self.matte.iter().map(|p| p[2]).collect(),
            plane(&self.background, 0),
            plane(&self.background, 1),
            plane(&self.background, 2),
            self.depth.clone(),
        ];
        CHANNELS.into_iter().zip(planes).collect()
    }
}

/// The frame's composition of one pixel: the ground darkens the background (`matte`), the
/// premultiplied model goes over it (Porter–Duff "over": `model + (1 − α)·under`). Alpha likewise.
pub fn compose(model: [f32; 4], background: [f32; 4], matte: [f32; 3]) -> [f32; 4] {
    let under = [background[0] * matte[0], background[1] * matte[1], background[2] * matte[2], background[3]];
    std::array::from_fn(|c| model[c] + (1.0 - model[3]) * under[c])
}

/// Distance from `camera` (world) to the surface whose depth-buffer value at `pixel` (from the
/// top-left corner, in pixels) of a `size` image is `depth` (wgpu clip space: 0 near, 1 far),
/// through the inverse of the frame's view-projection; `+inf` for a cleared (1.0) depth.
pub fn camera_distance(inverse_view_proj: Mat4, camera: Vec3, pixel: (f32, f32), size: (u32, u32), depth: f32) -> f32 {
    if depth >= 1.0 {
        return f32::INFINITY;
    }
    let ndc = Vec4::new(2.0 * pixel.0 / size.0 as f32 - 1.0, 1.0 - 2.0 * pixel.1 / size.1 as f32, depth, 1.0);
    let world = inverse_view_proj * ndc;
    (world.truncate() / world.w - camera).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compose_is_premultiplied_over_the_darkened_background() {
        // Uncovered: the background times the matte. Half-covered by premultiplied (0.4, 0, 0,
        // 0.5): 0.4 + 0.5 × 0.8 × 0.5 = 0.6 in red, 0.5 × 0.6 × 0.5 = 0.15 in green.
        assert_eq!(compose([0.0; 4], [0.8, 0.6, 0.2, 1.0], [0.5; 3]), [0.4, 0.3, 0.1, 1.0]);
        assert_eq!(compose([0.4, 0.0, 0.0, 0.5], [0.8, 0.6, 0.2, 1.0], [0.5; 3]), [0.6, 0.15, 0.05, 1.0]);
        // A coloured matte darkens each channel by its own factor.
        assert_eq!(compose([0.0; 4], [0.8, 0.6, 0.2, 1.0], [0.5, 1.0, 0.25]), [0.4, 0.6, 0.05, 1.0]);
        // Fully covered: the model alone, whatever lies under it.
        assert_eq!(compose([0.1, 0.2, 0.3, 1.0], [9.0, 9.0, 9.0, 1.0], [0.0; 3]), [0.1, 0.2, 0.3, 1.0]);
    }

    #[test]
    fn camera_distance_inverts_the_projection() {
        // A camera at (1, 2, 3) looking down −z (identity orientation), 90° vertical field of
        // view, square image, near 0.1, far 100 (wgpu depth 0..1). A point 5 m straight ahead
        // and one at (+2 m, +2 m) off-axis 4 m ahead (distance √(4+4+16) = √24).
        let camera = Vec3::new(1.0, 2.0, 3.0);
        let proj = glam::camera::rh::proj::directx::perspective(std::f32::consts::FRAC_PI_2, 1.0, 0.1, 100.0);
        let view_proj = proj * Mat4::from_translation(-camera);
        let size = (200, 200);
        for (offset, expected) in [(Vec3::new(0.0, 0.0, -5.0), 5.0f32), (Vec3::new(2.0, 2.0, -4.0), 24f32.sqrt())] {
            let clip = view_proj * (camera + offset).extend(1.0);
            let ndc = clip.truncate() / clip.w;
            let pixel = ((ndc.x + 1.0) * 100.0, (1.0 - ndc.y) * 100.0);
            let d = camera_distance(view_proj.inverse(), camera, pixel, size, ndc.z);
            assert!((d - expected).abs() < 1e-4, "{offset}: {d} vs {expected}");
        }
        assert_eq!(camera_distance(view_proj.inverse(), camera, (5.0, 5.0), size, 1.0), f32::INFINITY);
    }

    #[test]
    fn channels_follow_the_documented_names() {
        let images = LayerImages {
            width: 1,
            height: 1,
            beauty: vec![[1.0, 2.0, 3.0, 4.0]],
            model: vec![[5.0, 6.0, 7.0, 8.0]],
            matte: vec![[9.0, 10.0, 11.0]],
            background: vec![[12.0, 13.0, 14.0, 1.0]],
            depth: vec![15.0],
        };
        let channels = images.channels();
        assert_eq!(channels.iter().map(|c| c.0).collect::<Vec<_>>(), CHANNELS);
        assert_eq!(channels.iter().map(|c| c.1[0]).collect::<Vec<_>>(), (1..=15).map(|v| v as f32).collect::<Vec<_>>());
    }
}
