//! Painting one egui pass with egui-wgpu into a texture view: shared by the headless renderer
//! and the live window.

use crate::gpu::Gpu;

/// An encoded UI pass, ready to submit: the caller may add work (a readback) to `encoder`.
pub struct UiPaint {
    pub encoder: wgpu::CommandEncoder,
    /// Command buffers egui-wgpu asks to run before the pass.
    extra: Vec<wgpu::CommandBuffer>,
    /// Textures egui frees once the pass has been submitted.
    frees: Vec<egui::TextureId>,
}

/// Apply the pass's texture uploads (the `TexturesDelta` is drained: egui panics on an
/// undrained delta), tessellate, and encode one render pass into `view` (`size` pixels),
/// loading it with `load` first.
pub fn paint(
    renderer: &mut egui_wgpu::Renderer,
    gpu: &Gpu,
    ctx: &egui::Context,
    mut output: egui::FullOutput,
    view: &wgpu::TextureView,
    size: [u32; 2],
    load: wgpu::LoadOp<wgpu::Color>,
) -> UiPaint {
    for (id, deltas) in output.textures_delta.set.drain() {
        for delta in &deltas {
            renderer.update_texture(&gpu.device, &gpu.queue, id, delta);
        }
    }
    let frees = output.textures_delta.free.drain().collect();
    let jobs = ctx.tessellate(output.shapes, output.pixels_per_point);
    let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: size, pixels_per_point: output.pixels_per_point };
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ui") });
    let extra = renderer.update_buffers(&gpu.device, &gpu.queue, &mut encoder, &jobs, &screen);
    {
        let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("ui"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load, store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let mut pass = pass.forget_lifetime();
        renderer.render(&mut pass, &jobs, &screen);
    }
    UiPaint { encoder, extra, frees }
}

impl UiPaint {
    /// Submit the pass, then free the textures egui released.
    pub fn submit(self, gpu: &Gpu, renderer: &mut egui_wgpu::Renderer) {
        gpu.queue.submit(self.extra.into_iter().chain([self.encoder.finish()]));
        for id in &self.frees {
            renderer.free_texture(id);
        }
    }
}
