//! egui without a window: draw a UI over an image into an offscreen texture with egui-wgpu and
//! read the pixels back (golden-image tests, screenshots, the CLI). The target is Rgba8Unorm
//! holding sRGB-encoded values, which is what egui-wgpu expects for correct (gamma-space)
//! blending; the background image is written into it unchanged.

use crate::render::gpu::Gpu;
use crate::scene::Rgba8Image;
use anyhow::{Context, Result, bail};

const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// An egui context and renderer drawing into a fixed-size offscreen target.
pub struct HeadlessUi {
    ctx: egui::Context,
    renderer: egui_wgpu::Renderer,
    target: wgpu::Texture,
    view: wgpu::TextureView,
    readback: wgpu::Buffer,
    width: u32,
    height: u32,
    padded_row: u32,
    pixels_per_point: f32,
}

impl HeadlessUi {
    /// A `width`×`height` target; `pixels_per_point` scales the UI (1 = one pixel per point).
    pub fn new(gpu: &Gpu, width: u32, height: u32, pixels_per_point: f32) -> Result<HeadlessUi> {
        let max = gpu.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            bail!("UI size {width}x{height} is outside 1..={max} pixels per side");
        }
        if !(pixels_per_point.is_finite() && pixels_per_point > 0.0) {
            bail!("pixels per point must be positive, got {pixels_per_point}");
        }
        let device = &gpu.device;
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("headless ui"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = target.create_view(&Default::default());
        let padded_row = (4 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("headless ui readback"),
            size: u64::from(padded_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        // Predictable output (no dithering, software filtering) so golden images are stable.
        let renderer = egui_wgpu::Renderer::new(device, FORMAT, egui_wgpu::RendererOptions::PREDICTABLE);
        let ctx = egui::Context::default();
        Ok(HeadlessUi { ctx, renderer, target, view, readback, width, height, padded_row, pixels_per_point })
    }

    /// The egui context (e.g. to load textures before drawing).
    pub fn context(&self) -> &egui::Context {
        &self.ctx
    }

    /// Draw `ui` over `background` (sRGB RGBA8 of the target's size) and return the result.
    /// Texture uploads and frees that egui asks for are applied (the `TexturesDelta` is
    /// drained every call).
    pub fn render(&mut self, gpu: &Gpu, background: &Rgba8Image, mut ui: impl FnMut(&egui::Context)) -> Result<Rgba8Image> {
        if (background.width, background.height) != (self.width, self.height)
            || background.pixels.len() != (self.width * self.height * 4) as usize
        {
            bail!("background is {}x{}, the UI target is {}x{}", background.width, background.height, self.width, self.height);
        }
        gpu.queue.write_texture(
            self.target.as_image_copy(),
            &background.pixels,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * self.width), rows_per_image: None },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
        let ppp = self.pixels_per_point;
        let size_points = egui::vec2(self.width as f32 / ppp, self.height as f32 / ppp);
        let mut input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, size_points)),
            max_texture_side: Some(gpu.device.limits().max_texture_dimension_2d as usize),
            time: Some(0.0),
            ..Default::default()
        };
        if let Some(v) = input.viewports.get_mut(&egui::ViewportId::ROOT) {
            v.native_pixels_per_point = Some(ppp);
        }
        let output = self.ctx.run_pass(input, |ctx| ui(ctx));
        let size = [self.width, self.height];
        let mut p = super::paint::paint(&mut self.renderer, gpu, &self.ctx, output, &self.view, size, wgpu::LoadOp::Load);
        p.encoder.copy_texture_to_buffer(
            self.target.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(self.padded_row), rows_per_image: Some(self.height) },
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
        p.submit(gpu, &mut self.renderer);
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        gpu.device.poll(wgpu::PollType::wait_indefinitely()).context("waiting for the GPU")?;
        rx.recv().context("readback channel closed")?.context("cannot map the UI readback buffer")?;
        let mut pixels = Vec::with_capacity((self.width * self.height * 4) as usize);
        {
            let data = slice.get_mapped_range().context("reading back the UI image failed")?;
            for row in data.chunks_exact(self.padded_row as usize) {
                pixels.extend_from_slice(&row[..(4 * self.width) as usize]);
            }
        }
        self.readback.unmap();
        Ok(Rgba8Image { width: self.width, height: self.height, pixels })
    }
}
