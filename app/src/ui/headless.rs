//! egui without a window: draw a UI over an image into an offscreen texture with egui-wgpu and
//! read the pixels back (golden-image tests, screenshots, the CLI). The target is Rgba8Unorm
//! holding sRGB-encoded values, which is what egui-wgpu expects for correct (gamma-space)
//! blending; the background image is written into it unchanged.

use crate::gpu::{Gpu, Readback, build};
use crate::scene::Rgba8Image;
use anyhow::{Result, bail};

const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// An egui context and renderer drawing into a fixed-size offscreen target.
pub struct HeadlessUi {
    ctx: egui::Context,
    renderer: egui_wgpu::Renderer,
    target: wgpu::Texture,
    view: wgpu::TextureView,
    readback: Readback,
    width: u32,
    height: u32,
    pixels_per_point: f32,
}

impl HeadlessUi {
    /// A `width`×`height` target; `pixels_per_point` scales the UI (1 = one pixel per point).
    pub fn new(gpu: &Gpu, width: u32, height: u32, pixels_per_point: f32) -> Result<HeadlessUi> {
        gpu.check_size("UI", width, height)?;
        if !(pixels_per_point.is_finite() && pixels_per_point > 0.0) {
            bail!("pixels per point must be positive, got {pixels_per_point}");
        }
        gpu.checked("the headless UI target", || {
            let device = &gpu.device;
            use wgpu::TextureUsages as U;
            let target =
                build::texture(device, "headless ui", (width, height, 1), FORMAT, 1, U::RENDER_ATTACHMENT | U::COPY_SRC | U::COPY_DST);
            let view = target.create_view(&Default::default());
            let readback = Readback::for_texture(device, "headless ui readback", &target)?;
            // Predictable output (no dithering, software filtering) so golden images are stable.
            let renderer = egui_wgpu::Renderer::new(device, FORMAT, egui_wgpu::RendererOptions::PREDICTABLE);
            let ctx = egui::Context::default();
            Ok(HeadlessUi { ctx, renderer, target, view, readback, width, height, pixels_per_point })
        })
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
        gpu.checked("the headless UI", || self.render_unchecked(gpu, background, &mut ui))
    }

    fn render_unchecked(&mut self, gpu: &Gpu, background: &Rgba8Image, ui: &mut impl FnMut(&egui::Context)) -> Result<Rgba8Image> {
        build::write_layer(&gpu.queue, &self.target, 0, &background.pixels);
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
        self.readback.copy(&mut p.encoder, &self.target);
        p.submit(gpu, &mut self.renderer);
        let pixels = self.readback.read(gpu)?;
        Ok(Rgba8Image { width: self.width, height: self.height, pixels })
    }
}
