//! The compositor's render targets at one output size: the multisampled colour and depth that
//! the background, ground and model passes share, the resolved frame, and its readback.

use super::pipelines::{COLOR_FORMAT, DEPTH_FORMAT, SAMPLES};
use crate::gpu::{Readback, build};
use anyhow::Result;

pub struct Targets {
    msaa: wgpu::TextureView,
    depth: wgpu::TextureView,
    resolve: wgpu::Texture,
    resolve_view: wgpu::TextureView,
    /// The resolved frame as `Rgba8Unorm`: the sRGB-encoded bytes as they are.
    encoded_view: wgpu::TextureView,
    readback: Readback,
}

impl Targets {
    pub fn new(device: &wgpu::Device, (width, height): (u32, u32)) -> Result<Targets> {
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let msaa = build::texture(device, "msaa colour", (width, height, 1), COLOR_FORMAT, SAMPLES, attach);
        let depth = build::texture(device, "depth", (width, height, 1), DEPTH_FORMAT, SAMPLES, attach);
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
            msaa: msaa.create_view(&Default::default()),
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

    /// The pass that the background, ground and model draw into: multisampled colour cleared to
    /// `clear` and depth cleared to 1, resolved into the frame; only the resolve is kept.
    pub fn begin_composite<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        clear: wgpu::Color,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.msaa,
                depth_slice: None,
                resolve_target: Some(&self.resolve_view),
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Discard },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
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
