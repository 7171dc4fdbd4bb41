//! The app in a winit window: `previz live` on the desktop, the Android NativeActivity
//! ([`super::android`]) and the iPhone ([`super::ios`]). This is only the shell: it owns the window, the surface and egui's
//! winit state, and forwards everything to the [`App`] — each redraw [`App::frame`] advances
//! and draws into the compositor's target, one egui pass ([`App::ui`]) draws that target over
//! the whole window with the app's UI on top into the window surface (DESIGN.md "One frame",
//! step 6), then [`App::apply`] does what the pass asked for.
//!
//! Lifecycle: `suspended` (the app went to the background, the phone's screen locked, Android
//! destroyed the native window) drops the surface, stops drawing and stops the camera and the
//! sensors ([`App::suspend`]); `resumed` starts them again, creates a new surface for the window
//! and carries on with the same app (GPU device, scene, filter, capture in progress).

use super::app::App;
use crate::gpu::Gpu;
use anyhow::{Context, Result, anyhow};
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::{Window, WindowId};

/// Builds the app once the window's GPU device exists.
pub type MakeApp = Box<dyn FnOnce(&Gpu) -> Result<App>>;

/// Open a window and run the app until its session ends or the window is closed.
pub fn run(title: &str, size: (u32, u32), make: MakeApp) -> Result<()> {
    let event_loop = EventLoop::new()
        .map_err(|e| anyhow!("cannot open a window ({e}); on a machine without a display run under Xvfb, or use --frames N -o DIR"))?;
    run_app_on(event_loop, title, size, make)
}

/// Run the app in a window of `event_loop` (the platform shells build their own loop: the
/// Android one needs the `AndroidApp`).
pub fn run_app_on(event_loop: EventLoop<()>, title: &str, size: (u32, u32), make: MakeApp) -> Result<()> {
    let mut shell = Shell::new(title, size, make);
    event_loop.run_app(&mut shell).context("the window's event loop failed")?;
    shell.finish()
}

/// The winit application: what the event loop calls ([`ApplicationHandler`]). Public so that a
/// test can drive it inside its own handler (tests/app_window.rs sends it the `suspended` and
/// `resumed` events a phone would, under Xvfb) and read what it did.
pub struct Shell {
    title: String,
    size: (u32, u32),
    make: Option<MakeApp>,
    state: Option<State>,
    error: Option<anyhow::Error>,
}

struct State {
    window: Arc<Window>,
    gpu: Gpu,
    /// None while suspended: no surface, no GPU work.
    surface: Option<wgpu::Surface<'static>>,
    config: wgpu::SurfaceConfiguration,
    app: App,
    egui: egui_winit::State,
    renderer: egui_wgpu::Renderer,
    frame_texture: egui::TextureId,
    frame_times: std::collections::VecDeque<Instant>,
    /// Frames presented so far.
    presented: usize,
}

impl Shell {
    /// The shell of a window titled `title`, `size` pixels, whose app `make` builds once the
    /// window and its GPU device exist (at the first `resumed`).
    pub fn new(title: &str, size: (u32, u32), make: MakeApp) -> Shell {
        Shell { title: title.to_string(), size, make: Some(make), state: None, error: None }
    }

    /// The first error that ended the event loop, if any.
    pub fn finish(self) -> Result<()> {
        self.error.map_or(Ok(()), Err)
    }

    /// The app, once the window exists.
    pub fn app(&self) -> Option<&App> {
        self.state.as_ref().map(|s| &s.app)
    }

    /// Whether the window has a GPU surface now (none while suspended).
    pub fn has_surface(&self) -> bool {
        self.state.as_ref().is_some_and(|s| s.surface.is_some())
    }

    /// How many frames have been presented to the window.
    pub fn presented_frames(&self) -> usize {
        self.state.as_ref().map_or(0, |s| s.presented)
    }

    /// Ask the window for a redraw (what the platform does when the window is exposed).
    pub fn request_redraw(&self) {
        if let Some(s) = &self.state {
            s.window.request_redraw();
        }
    }

    fn init(&mut self, el: &ActiveEventLoop) -> Result<State> {
        let make = self.make.take().context("the window was already started")?;
        let attrs = Window::default_attributes()
            .with_title(self.title.clone())
            .with_inner_size(winit::dpi::PhysicalSize::new(self.size.0, self.size.1));
        let window = Arc::new(el.create_window(attrs).context("cannot create the window")?);
        let mut desc = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(el.owned_display_handle()));
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL | wgpu::Backends::METAL;
        }
        let instance = wgpu::Instance::new(desc);
        let surface = instance.create_surface(window.clone()).context("cannot create a GPU surface for the window")?;
        let gpu = Gpu::with_instance(instance, Some(&surface))?;
        let app = make(&gpu)?;
        let inner = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, inner.width.max(1), inner.height.max(1))
            .context("the GPU cannot present to this window")?;
        // egui-wgpu blends in gamma space: it wants a non-sRGB surface where there is one.
        let caps = surface.get_capabilities(&gpu.adapter);
        config.format = caps.formats.iter().copied().find(|f| !f.is_srgb()).unwrap_or(config.format);
        surface.configure(&gpu.device, &config);
        let mut renderer = egui_wgpu::Renderer::new(&gpu.device, config.format, egui_wgpu::RendererOptions::default());
        let frame_texture =
            renderer.register_native_texture(&gpu.device, app.session().compositor().target_view(), wgpu::FilterMode::Linear);
        let ctx = egui::Context::default();
        let egui = egui_winit::State::new(
            ctx,
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        window.request_redraw();
        Ok(State {
            window,
            gpu,
            surface: Some(surface),
            config,
            app,
            egui,
            renderer,
            frame_texture,
            frame_times: Default::default(),
            presented: 0,
        })
    }
}

impl ApplicationHandler for Shell {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if let Some(state) = &mut self.state {
            if let Err(e) = state.resume() {
                self.error = Some(e);
                el.exit();
            }
            return;
        }
        if self.make.is_none() {
            return;
        }
        match self.init(el) {
            Ok(s) => self.state = Some(s),
            Err(e) => {
                self.error = Some(e);
                el.exit();
            }
        }
    }

    fn suspended(&mut self, el: &ActiveEventLoop) {
        if let Some(state) = &mut self.state {
            state.surface = None;
            if let Err(e) = state.app.suspend() {
                self.error = Some(e);
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(state) = &mut self.state else { return };
        let response = state.egui.on_window_event(&state.window, &event);
        if !response.consumed {
            let size = glam::Vec2::new(state.config.width as f32, state.config.height as f32);
            state.app.window_event(&event, size);
        }
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::DroppedFile(path) => {
                // A model file dropped on the window joins the model picker (errors go to the
                // status line).
                let _ = state.app.open_model(&state.gpu, &path);
            }
            WindowEvent::Resized(size) => {
                state.config.width = size.width.max(1);
                state.config.height = size.height.max(1);
                if let Some(surface) = &state.surface {
                    surface.configure(&state.gpu.device, &state.config);
                }
                state.window.request_redraw();
            }
            WindowEvent::RedrawRequested => match state.frame() {
                Ok(true) if state.surface.is_some() => state.window.request_redraw(),
                Ok(true) => {}
                Ok(false) => el.exit(),
                Err(e) => {
                    self.error = Some(e);
                    el.exit();
                }
            },
            _ => {}
        }
    }
}

impl State {
    /// A new surface for the window after a suspension, and the camera and sensors started again
    /// (the app is kept).
    fn resume(&mut self) -> Result<()> {
        self.app.resume()?;
        if self.surface.is_none() {
            let surface = self.gpu.instance.create_surface(self.window.clone()).context("cannot recreate the GPU surface")?;
            let size = self.window.inner_size();
            self.config.width = size.width.max(1);
            self.config.height = size.height.max(1);
            surface.configure(&self.gpu.device, &self.config);
            self.surface = Some(surface);
        }
        self.window.request_redraw();
        Ok(())
    }

    /// One frame; false when the session is over. Nothing is drawn while suspended.
    fn frame(&mut self) -> Result<bool> {
        let Some(surface) = &self.surface else { return Ok(true) };
        if !self.app.frame(&self.gpu)? {
            return Ok(false);
        }
        let now = Instant::now();
        self.frame_times.push_back(now);
        while self.frame_times.len() > 30 {
            self.frame_times.pop_front();
        }
        let fps = match (self.frame_times.front(), self.frame_times.len()) {
            (Some(first), n) if n > 1 => (n - 1) as f64 / now.duration_since(*first).as_secs_f64().max(1e-9),
            _ => 0.0,
        };

        let surface_texture = match surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => return Ok(true),
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                surface.configure(&self.gpu.device, &self.config);
                return Ok(true);
            }
            other => return Err(anyhow!("the window surface failed: {other:?}")),
        };
        let view = surface_texture.texture.create_view(&Default::default());

        let input = self.egui.take_egui_input(&self.window);
        let ctx = self.egui.egui_ctx().clone();
        let perf = format!("{fps:.1} fps");
        let mut output = ctx.run_pass(input, |ctx| self.app.ui(ctx, Some(self.frame_texture), &perf));
        // An action's error is shown in the app's status line; the session goes on.
        let _ = self.app.apply(&self.gpu);
        self.egui.handle_platform_output(&self.window, std::mem::take(&mut output.platform_output));
        let size = [self.config.width, self.config.height];
        let clear = wgpu::LoadOp::Clear(wgpu::Color::BLACK);
        crate::ui::paint::paint(&mut self.renderer, &self.gpu, &ctx, output, &view, size, clear).submit(&self.gpu, &mut self.renderer);
        self.window.pre_present_notify();
        self.gpu.queue.present(surface_texture);
        self.presented += 1;
        if self.presented == 1 {
            // The scripted sessions and tests wait for this line, not for a fixed time.
            eprintln!("previz live: first frame presented");
        }
        Ok(true)
    }
}
