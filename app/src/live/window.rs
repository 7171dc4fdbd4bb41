//! The live loop in a winit window: `previz live` on the desktop and the Android
//! NativeActivity ([`super::android`]). Each redraw advances the session one camera frame, the
//! compositor draws it into its target, and the UI pass (egui-wgpu) draws that target over the
//! whole window with the status overlay on top, into the window surface (DESIGN.md "One frame",
//! step 6).
//!
//! Lifecycle: `suspended` (the app went to the background, the phone's screen locked, Android
//! destroyed the native window) drops the surface, stops drawing and stops the camera and the
//! sensors ([`LiveSession::suspend`]); `resumed` starts them again, creates a new surface for the
//! window and carries on with the same session (GPU device, scene, filter).

use super::{LiveFrame, LiveSession};
use crate::gpu::Gpu;
use crate::render::Placement;
use crate::ui::controls::{Controls, apply_gesture, drag_on_ground, pinch_twist};
use anyhow::{Context, Result, anyhow};
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::{Window, WindowId};

/// Builds the session once the window's GPU device exists.
pub type MakeSession = Box<dyn FnOnce(&Gpu) -> Result<LiveSession>>;

/// Open a window and run the session until it ends or the window is closed.
pub fn run(title: &str, size: (u32, u32), make: MakeSession) -> Result<()> {
    let event_loop = EventLoop::new()
        .map_err(|e| anyhow!("cannot open a window ({e}); on a machine without a display run under Xvfb, or use --frames N -o DIR"))?;
    run_on(event_loop, title, size, std::env::current_dir().unwrap_or_default(), make)
}

/// Run the session in a window of `event_loop` (the platform shells build their own loop: the
/// Android one needs the `AndroidApp`); the shutter saves into `export_dir`.
pub fn run_on(event_loop: EventLoop<()>, title: &str, size: (u32, u32), export_dir: std::path::PathBuf, make: MakeSession) -> Result<()> {
    let mut app = App { title: title.to_string(), size, make: Some(make), state: None, error: None, export_dir };
    event_loop.run_app(&mut app).context("the window's event loop failed")?;
    app.error.map_or(Ok(()), Err)
}

struct App {
    title: String,
    size: (u32, u32),
    make: Option<MakeSession>,
    state: Option<State>,
    error: Option<anyhow::Error>,
    export_dir: std::path::PathBuf,
}

struct State {
    window: Arc<Window>,
    gpu: Gpu,
    /// None while suspended: no surface, no GPU work.
    surface: Option<wgpu::Surface<'static>>,
    config: wgpu::SurfaceConfiguration,
    session: LiveSession,
    egui: egui_winit::State,
    renderer: egui_wgpu::Renderer,
    frame_texture: egui::TextureId,
    last: Option<LiveFrame>,
    encode_ms: f64,
    frame_times: std::collections::VecDeque<Instant>,
    /// The control panel, and the scene's values and placement Reset goes back to.
    controls: Controls,
    initial: (Controls, Placement),
    /// Touches down (id → position, pixels) and the mouse drag in progress.
    touches: Vec<(u64, glam::Vec2)>,
    mouse: Option<glam::Vec2>,
    cursor: glam::Vec2,
    /// Where the shutter saves, and what the last press did.
    export_dir: std::path::PathBuf,
    status: String,
}

impl App {
    fn init(&mut self, el: &ActiveEventLoop) -> Result<State> {
        let make = self.make.take().context("the session was already started")?;
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
        let session = make(&gpu)?;
        let controls = Controls::from_params(session.params());
        let placement = session.params().placement;
        let inner = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, inner.width.max(1), inner.height.max(1))
            .context("the GPU cannot present to this window")?;
        // egui-wgpu blends in gamma space: it wants a non-sRGB surface where there is one.
        let caps = surface.get_capabilities(&gpu.adapter);
        config.format = caps.formats.iter().copied().find(|f| !f.is_srgb()).unwrap_or(config.format);
        surface.configure(&gpu.device, &config);
        let mut renderer = egui_wgpu::Renderer::new(&gpu.device, config.format, egui_wgpu::RendererOptions::default());
        let frame_texture = renderer.register_native_texture(&gpu.device, session.compositor().target_view(), wgpu::FilterMode::Linear);
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
            session,
            egui,
            renderer,
            frame_texture,
            last: None,
            encode_ms: 0.0,
            frame_times: Default::default(),
            controls,
            initial: (controls, placement),
            touches: Vec::new(),
            mouse: None,
            cursor: glam::Vec2::ZERO,
            export_dir: self.export_dir.clone(),
            status: String::new(),
        })
    }
}

impl ApplicationHandler for App {
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
            if let Err(e) = state.session.suspend() {
                self.error = Some(e);
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(state) = &mut self.state else { return };
        let response = state.egui.on_window_event(&state.window, &event);
        if !response.consumed {
            state.gesture(&event);
        }
        match event {
            WindowEvent::CloseRequested => el.exit(),
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
    /// Touch and mouse gestures on the model (events egui did not take): one finger or the
    /// left mouse button drags it across the ground, two fingers pinch to scale and twist to turn.
    fn gesture(&mut self, event: &WindowEvent) {
        use winit::event::{ElementState, MouseButton, TouchPhase};
        let size = glam::Vec2::new(self.config.width as f32, self.config.height as f32);
        let mut moved = glam::Vec3::ZERO;
        let (mut scale, mut twist) = (1.0, 0.0);
        match event {
            WindowEvent::MouseInput { state, button: MouseButton::Left, .. } => {
                self.mouse = (*state == ElementState::Pressed).then_some(self.cursor);
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor = glam::Vec2::new(position.x as f32, position.y as f32);
                if let Some(from) = self.mouse.replace(self.cursor) {
                    moved = drag_on_ground(self.session.params(), size, from, self.cursor);
                }
            }
            WindowEvent::Touch(t) => {
                let at = glam::Vec2::new(t.location.x as f32, t.location.y as f32);
                let i = self.touches.iter().position(|(id, _)| *id == t.id);
                match (t.phase, i) {
                    (TouchPhase::Started, None) => self.touches.push((t.id, at)),
                    (TouchPhase::Moved, Some(i)) => {
                        let before = self.touches.clone();
                        self.touches[i].1 = at;
                        match before.as_slice() {
                            [(_, from)] => moved = drag_on_ground(self.session.params(), size, *from, at),
                            [(_, a0), (_, b0), ..] => (scale, twist) = pinch_twist(*a0, *b0, self.touches[0].1, self.touches[1].1),
                            _ => {}
                        }
                    }
                    (TouchPhase::Ended | TouchPhase::Cancelled, Some(i)) => {
                        self.touches.remove(i);
                    }
                    _ => {}
                }
            }
            _ => return,
        }
        let before = self.controls;
        apply_gesture(self.session.params_mut(), &mut self.controls, moved, scale, twist);
        if self.controls != before {
            self.session.set_controls(self.controls);
        }
    }

    /// The shutter: export the current frame into a new folder `previz-export-<time>` in the
    /// export folder (the working directory on the desktop).
    fn export(&mut self) -> Result<std::path::PathBuf> {
        let dir = self.export_dir.join(format!("previz-export-{}", chrono::Utc::now().format("%Y%m%d-%H%M%S%.3f")));
        std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
        super::export::export(&mut self.session, &self.gpu, &dir, None)?;
        Ok(dir)
    }

    /// A new surface for the window after a suspension, and the camera and sensors started again
    /// (the session is kept).
    fn resume(&mut self) -> Result<()> {
        self.session.resume()?;
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
        let Some(frame) = self.session.advance(&self.gpu)? else { return Ok(false) };
        self.encode_ms = self.session.draw(&self.gpu)?;
        self.last = Some(frame);
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
        let (texture, last, encode_ms, sensors) = (self.frame_texture, self.last, self.encode_ms, self.session.sensors());
        let mut controls = self.controls;
        let (mut reset, mut shutter) = (false, false);
        let status = self.status.clone();
        let mut output = ctx.run_pass(input, |ctx| {
            overlay(ctx, texture, last.as_ref(), encode_ms, fps, &sensors);
            reset = controls.show(ctx);
            shutter = shutter_button(ctx, &status);
        });
        if shutter {
            self.status = match self.export() {
                Ok(dir) => format!("saved {}", dir.display()),
                Err(e) => format!("export failed: {e:#}"),
            };
        }
        if reset {
            controls = Controls { open: controls.open, ..self.initial.0 };
            self.session.params_mut().placement = self.initial.1;
        }
        if controls != self.controls || self.session.controls().is_none() {
            self.controls = controls;
            self.session.set_controls(controls);
        }
        self.egui.handle_platform_output(&self.window, std::mem::take(&mut output.platform_output));
        let size = [self.config.width, self.config.height];
        let clear = wgpu::LoadOp::Clear(wgpu::Color::BLACK);
        crate::ui::paint::paint(&mut self.renderer, &self.gpu, &ctx, output, &view, size, clear).submit(&self.gpu, &mut self.renderer);
        self.window.pre_present_notify();
        self.gpu.queue.present(surface_texture);
        Ok(true)
    }
}

/// The camera view filling the window and the status panel over it.
fn overlay(ctx: &egui::Context, frame: egui::TextureId, last: Option<&LiveFrame>, encode_ms: f64, fps: f64, sensors: &str) {
    let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
    ctx.layer_painter(egui::LayerId::background()).image(frame, ctx.viewport_rect(), uv, egui::Color32::WHITE);
    egui::Window::new("previz live").anchor(egui::Align2::LEFT_TOP, egui::vec2(8.0, 8.0)).resizable(false).show(ctx, |ui| {
        for line in status_lines(last, encode_ms, fps, sensors) {
            ui.label(line);
        }
    });
}

/// The shutter button at the bottom centre, and the last export's message beside it; true when
/// pressed.
fn shutter_button(ctx: &egui::Context, status: &str) -> bool {
    let mut pressed = false;
    egui::Area::new(egui::Id::unique("shutter")).anchor(egui::Align2::CENTER_BOTTOM, egui::vec2(0.0, -12.0)).show(ctx, |ui| {
        ui.horizontal(|ui| {
            pressed = ui.button("shutter").clicked();
            if !status.is_empty() {
                ui.label(status);
            }
        });
    });
    pressed
}

/// The overlay's text (pure, so it is tested without a window).
pub fn status_lines(last: Option<&LiveFrame>, encode_ms: f64, fps: f64, sensors: &str) -> Vec<String> {
    let mut lines = vec![format!("{fps:.1} fps, encode {encode_ms:.2} ms"), format!("sensors: {sensors}")];
    let Some(f) = last else {
        lines.push("waiting for the first camera frame".into());
        return lines;
    };
    match f.pose {
        Some(p) => {
            let hpr = crate::pose::frames::heading_pitch_roll(p.q.as_dquat());
            lines.push(format!(
                "heading {:.1}°, pitch {:.1}° (±{:.1}°, {})",
                hpr.heading.to_degrees(),
                hpr.pitch.to_degrees(),
                p.accuracy_deg,
                p.heading_source.label()
            ));
        }
        None => lines.push("pose: settling (camera image only)".into()),
    }
    lines.push(format!(
        "sun: azimuth {:.1}°, elevation {:.1}°, sunlight l_s {:.2}",
        f.sun.azimuth_deg,
        f.sun.apparent_elevation_deg(),
        f.sunlight
    ));
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{HeadingSource, Pose};
    use crate::sun::{Algorithm, SunInput, position};

    #[test]
    fn status_lines_name_the_pose_and_the_sun() {
        let waiting = status_lines(None, 0.1, 0.0, "sim");
        assert!(waiting.iter().any(|l| l.contains("waiting")));
        let time = chrono::DateTime::parse_from_rfc3339("2003-10-17T12:30:30-07:00").unwrap().with_timezone(&chrono::Utc);
        let sun = position(&SunInput::new(time, 39.742476, -105.1786), Algorithm::Spa).unwrap();
        // Camera looking East (heading 90°), level: camera −z → +x (East), +y → Up.
        let q = crate::pose::frames::from_heading_pitch_roll(90f64.to_radians(), 0.0, 0.0).as_quat();
        let pose = Pose {
            t: 1.0,
            q,
            accuracy_deg: 2.0,
            heading_accuracy_deg: 2.0,
            tilt_accuracy_deg: 0.5,
            heading_source: HeadingSource::GyroOnly,
            magnetic_disturbance: true,
        };
        let frame =
            LiveFrame { t: 1.0, pose: Some(pose), pose_error_deg: None, sun, sunlight: 0.8, camera_ms: 0.0, pose_ms: 0.0, sun_ms: 0.0 };
        let lines = status_lines(Some(&frame), 0.1, 30.0, "sim").join("\n");
        assert!(lines.contains("heading 90.0°, pitch 0.0° (±2.0°, gyro only"), "{lines}");
        assert!(lines.contains("sun: azimuth 194.3°"), "{lines}");
        assert!(lines.contains("30.0 fps"), "{lines}");
    }
}
