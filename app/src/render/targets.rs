//! The compositor's render targets at one output size: the colour and depth that the
//! background, ground and model passes share (multisampled, or single-sampled for FXAA or no
//! antialiasing), the resolved frame, and its readback.

use super::antialiasing::Antialiasing;
use super::pipelines::{COLOR_FORMAT, DEPTH_FORMAT};
use crate::gpu::{Readback, build};
use anyhow::Result;

pub struct Targets {
    /// The multisampled colour (more than one sample per pixel).
    msaa: Option<wgpu::TextureView>,
    /// The single-sampled frame that the FXAA pass reads.
    aa_input: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
    resolve: wgpu::Texture,
    resolve_view: wgpu::TextureView,
    /// The resolved frame as `Rgba8Unorm`: the sRGB-encoded bytes as they are.
    encoded_view: wgpu::TextureView,
    readback: Readback,
}

impl Targets {
    pub fn new(device: &wgpu::Device, (width, height): (u32, u32), aa: Antialiasing) -> Result<Targets> {
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let samples = aa.samples();
        let msaa = (samples > 1).then(|| build::texture(device, "msaa colour", (width, height, 1), COLOR_FORMAT, samples, attach));
        let aa_input = (aa == Antialiasing::Fxaa).then(|| {
            let usage = attach | wgpu::TextureUsages::TEXTURE_BINDING;
            build::texture(device, "fxaa input", (width, height, 1), COLOR_FORMAT, 1, usage)
        });
        let depth = build::texture(device, "depth", (width, height, 1), DEPTH_FORMAT, samples, attach);
        // The resolved frame: read back (headless) or sampled by the window's UI pass (live),
        // which blends in gamma space and so samples the sRGB-encoded bytes as they are.
        let resolve = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("resolve"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: attach | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[COLOR_FORMAT.remove_srgb_suffix()],
        });
        let readback = Readback::for_texture(device, "readback", &resolve)?;
        Ok(Targets {
            msaa: msaa.map(|t| t.create_view(&Default::default())),
            aa_input: aa_input.map(|t| t.create_view(&Default::default())),
            depth: depth.create_view(&Default::default()),
            resolve_view: resolve.create_view(&Default::default()),
            encoded_view: resolve
                .create_view(&wgpu::TextureViewDescriptor { format: Some(COLOR_FORMAT.remove_srgb_suffix()), ..Default::default() }),
            resolve,
            readback,
        })
    }

    /// The resolved frame as an `Rgba8Unorm` view of its sRGB-encoded bytes.
    pub fn encoded_view(&self) -> &wgpu::TextureView {
        &self.encoded_view
    }

    /// The single-sampled frame the FXAA pass reads (None without FXAA).
    pub fn aa_input(&self) -> Option<&wgpu::TextureView> {
        self.aa_input.as_ref()
    }

    /// The pass that the background, ground and model draw into: colour cleared to `clear` and
    /// depth cleared to 1; multisampled colour is resolved into the frame (only the resolve is
    /// kept), single-sampled colour is the frame itself or, with FXAA, the FXAA pass's input.
    pub fn begin_composite<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        clear: wgpu::Color,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        self.begin_composite_part(encoder, Some(clear), true, timestamps)
    }

    /// One of several passes into the composite's targets (the frame's passes timed one by one,
    /// `Compositor::set_pass_timing`): the first clears (`clear`: Some), later ones load what
    /// the earlier stored; only the `last` resolves and lets the multisampled colour and the
    /// depth go.
    pub fn begin_composite_part<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        clear: Option<wgpu::Color>,
        last: bool,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        let single = self.aa_input.as_ref().unwrap_or(&self.resolve_view);
        let kept = if last { wgpu::StoreOp::Discard } else { wgpu::StoreOp::Store };
        let (view, resolve_target, store) = match &self.msaa {
            Some(msaa) => (msaa, last.then_some(single), kept),
            None => (single, None, wgpu::StoreOp::Store),
        };
        let load = clear.map_or(wgpu::LoadOp::Load, wgpu::LoadOp::Clear);
        let depth_load = if clear.is_some() { wgpu::LoadOp::Clear(1.0) } else { wgpu::LoadOp::Load };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations { load, store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth,
                depth_ops: Some(wgpu::Operations { load: depth_load, store: kept }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// The depth the composite's passes share (the frame's samples).
    pub fn depth_view(&self) -> &wgpu::TextureView {
        &self.depth
    }

    /// A pass drawing into `into` (single-sampled, the frame's colour format) through the
    /// frame's colour and depth targets: colour cleared to `clear` and resolved into
    /// `into` (multisampled) or drawn there (one sample), depth cleared to 1 and kept for a
    /// later pass (render::reprojection's model layer, then its matte).
    pub fn begin_into<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        (into, clear): (&wgpu::TextureView, wgpu::Color),
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        let (view, resolve_target, store) = match &self.msaa {
            Some(msaa) => (msaa, Some(into), wgpu::StoreOp::Discard),
            None => (into, None, wgpu::StoreOp::Store),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("layer of the composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// The FXAA pass: from [`Targets::aa_input`] into the frame.
    pub fn begin_fxaa<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("fxaa"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.resolve_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// Record the copy of the resolved frame into the readback buffer.
    pub fn copy_for_readback(&self, encoder: &mut wgpu::CommandEncoder) {
        self.readback.copy(encoder, &self.resolve);
    }

    /// The frame's bytes, after the copy was submitted.
    pub fn read(&self, gpu: &crate::gpu::Gpu) -> Result<Vec<u8>> {
        self.readback.read(gpu)
    }
}
