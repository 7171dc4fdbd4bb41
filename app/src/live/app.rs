//! The one interactive app: what the desktop window (`previz live`) and the phone shells run.
//! It owns the modes (capture, composite), the UI state and the frame loop; a platform shell
//! only makes a [`LiveSession`] from its camera ([`crate::camera::FrameSource`]) and sensors
//! ([`crate::sensors::SensorSource`]), wraps it in an [`App`] and, per display frame, calls
//! [`App::frame`] (advance + draw into the compositor's target), runs one egui pass with
//! [`App::ui`], then [`App::apply`] (what the pass asked for: export, mode switch, model), and
//! forwards touch and mouse events to [`App::window_event`] and the lifecycle to
//! [`App::suspend`] / [`App::resume`].
//!
//! Modes:
//! - **Capture**: the camera image alone with the capture assistant's guidance over it (target
//!   marker, arrow to the next shot, "Hold still", a flash and a tick per shot, a progress ring
//!   of the six faces); the user taps to take the front, the other faces are taken as the
//!   camera holds still on them. When the six faces are in, they are assembled, saved as a
//!   capture folder (the format `previz capture` writes) in the export folder, and become the
//!   environment that lights the model; the faces are shown until the user goes on.
//! - **Composite**: the model over the camera image, the control panel (seed 000 Fig. 23), the
//!   method and model pickers, reset, the shutter, and the gestures on the model.
//!
//! Permissions: camera refused → a screen saying what is missing and how to grant it, nothing
//! else; location refused → the composite runs with the sun for a place and time set by hand.

use super::{LiveFrame, LiveSession};
use crate::capture::Mode as CaptureMode;
use crate::capture::aim_heading::AimHeading;
use crate::capture::assistant::{Assistant, AssistantConfig, Phase};
use crate::capture::gravity::GravityLog;
use crate::capture::projection::Pinhole;
use crate::capture::targets::Face;
use crate::gpu::Gpu;
use crate::render::Placement;
use crate::sensors::permissions::{Answer, Permission, refusal_message};
use crate::ui::capture_overlay::{THUMB, draw_capture_overlay, draw_faces_preview, draw_shot_feedback, thumbnail};
use crate::ui::controls::{Controls, apply_gesture, drag_on_ground, pinch_twist};
use anyhow::{Context, Result, bail};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Which mode the app is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AppMode {
    Composite,
    /// The assistant is taking the faces.
    Capturing,
    /// The capture is saved and lights the model; its faces are shown.
    CaptureDone,
}

/// One step of a scripted session (`previz live --script`, demos and tests): each runs as soon
/// as the app can do it, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Start capture mode.
    Capture,
    /// Wait for the capture to be saved, then composite with it.
    Composite,
    /// Wait for a pose (the model on screen), then press the shutter.
    Shutter,
    /// End the session.
    Quit,
}

impl Step {
    /// Parse a comma-separated list of `capture`, `composite`, `shutter`, `quit`.
    pub fn parse_list(text: &str) -> Result<Vec<Step>> {
        text.split(',')
            .map(|s| match s.trim() {
                "capture" => Ok(Step::Capture),
                "composite" => Ok(Step::Composite),
                "shutter" => Ok(Step::Shutter),
                "quit" => Ok(Step::Quit),
                other => anyhow::bail!("--script: unknown step {other:?} (steps: capture, composite, shutter, quit)"),
            })
            .collect()
    }
}

/// How long the flash and the tick of a shot stay on screen, seconds of camera time.
pub const SHOT_FEEDBACK_S: f64 = 0.6;
/// Side of the faces of a capture taken in the app (pixels).
pub const CAPTURE_FACE_SIZE: u32 = 256;

/// [`CaptureRun::thumb_sources`] of a thumbnail showing the finished capture's face.
const ASSEMBLED: usize = usize::MAX;

struct CaptureRun {
    assistant: Assistant,
    /// The heading the guidance judges aims with (held from the tap, each landed shot's
    /// measured turn correcting its drift), and the pose it gave at the latest frame.
    aim: AimHeading,
    aim_pose: Option<crate::pose::Pose>,
    /// The accelerometer held before each shot: the capture's vertical (capture::gravity).
    gravity: GravityLog,
    thumbs: [Option<egui::TextureHandle>; 6],
    /// What each thumbnail shows: the face assembled from this many shots, [`ASSEMBLED`] (the
    /// finished capture's face), or nothing yet.
    thumb_sources: [Option<usize>; 6],
    /// The last shot's target name and camera time.
    last_shot: Option<(String, f64)>,
    /// The user tapped; used at the next frame with a pose.
    tap: bool,
    /// Where the finished capture was saved.
    saved: Option<PathBuf>,
    /// The assembled faces (in [`Face::ALL`] order) once the capture is finished: the preview
    /// shows these.
    assembled: Option<Vec<crate::scene::Rgba8Image>>,
}

/// A model the picker offers: the scene's, the bundled demo one, or a file the user opened.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelChoice {
    pub name: String,
    /// None: the bundled demo model.
    pub path: Option<PathBuf>,
}

/// The place and time the sun is computed for when location is not allowed (the panel's text).
#[derive(Clone, Debug, PartialEq)]
struct ManualPlace {
    lat: f64,
    lon: f64,
    time: String,
}

/// What one UI pass asked for; done by [`App::apply`].
#[derive(Default)]
struct Requests {
    shutter: bool,
    reset: bool,
    capture: bool,
    composite: bool,
    model: Option<usize>,
    place: bool,
    ask_permissions: bool,
}

/// The platform's permission answers, read by the app while it runs (the phone shells: Android
/// through JNI, iOS through AVFoundation and Core Location; the desktop has none and everything
/// is allowed).
pub trait PermissionSource {
    /// The camera's and location's answers now.
    fn answers(&mut self) -> Result<(Answer, Answer)>;
    /// The user pressed "Ask again" on the refusal screen: ask the system again.
    fn ask_again(&mut self) -> Result<()>;
}

/// The app reads the platform's answers every this many frames (about twice a second on a
/// phone): the user may allow or refuse in the system dialog or the settings at any time.
pub const PERMISSION_POLL_FRAMES: u32 = 15;

/// The interactive app (module docs).
pub struct App {
    session: LiveSession,
    capture: Option<CaptureRun>,
    controls: Controls,
    initial: (Controls, Placement),
    touches: Vec<(u64, glam::Vec2)>,
    mouse: Option<glam::Vec2>,
    cursor: glam::Vec2,
    export_dir: PathBuf,
    status: String,
    last: Option<LiveFrame>,
    camera_permission: Answer,
    location_permission: Answer,
    place: ManualPlace,
    models: Vec<ModelChoice>,
    model: usize,
    requests: Requests,
    script: VecDeque<Step>,
    last_export: Option<PathBuf>,
    /// The user asked for the place to be written into exports (the bar's `location` box).
    export_location: bool,
    captured: Option<PathBuf>,
    permissions: Option<Box<dyn PermissionSource>>,
    /// Frames since the answers were last read.
    since_poll: u32,
    quit: bool,
}

impl App {
    /// The app over `session`, in composite mode; the shutter and captures save into
    /// `export_dir`.
    pub fn new(mut session: LiveSession, export_dir: PathBuf) -> App {
        // Until a capture exists the camera frame, folded into a cube map, lights the model.
        session.fold_camera_into_environment();
        let controls = Controls::from_params(session.params());
        session.set_controls(controls);
        let placement = session.params().placement;
        let (lat, lon) = session.location();
        let time = session.config().start.to_rfc3339_opts(chrono::SecondsFormat::Secs, true);
        let scene_model = match &session.scene().model {
            Some(p) => ModelChoice { name: file_label(p), path: Some(p.clone()) },
            None => ModelChoice { name: "demo truck".into(), path: None },
        };
        let mut models = vec![scene_model];
        if models[0].path.is_some() {
            models.push(ModelChoice { name: "demo truck".into(), path: None });
        }
        App {
            session,
            capture: None,
            controls,
            initial: (controls, placement),
            touches: Vec::new(),
            mouse: None,
            cursor: glam::Vec2::ZERO,
            export_dir,
            status: String::new(),
            last: None,
            camera_permission: Answer::Granted,
            location_permission: Answer::Granted,
            place: ManualPlace { lat, lon, time },
            models,
            model: 0,
            requests: Requests::default(),
            script: VecDeque::new(),
            last_export: None,
            export_location: false,
            captured: None,
            permissions: None,
            since_poll: 0,
            quit: false,
        }
    }

    /// What the platform reported for the camera and location permissions.
    pub fn set_permissions(&mut self, camera: Answer, location: Answer) {
        self.camera_permission = camera;
        self.location_permission = location;
    }

    /// The platform's answers, read now and every [`PERMISSION_POLL_FRAMES`] frames; "Ask
    /// again" reaches it.
    pub fn set_permission_source(&mut self, source: Box<dyn PermissionSource>) {
        self.permissions = Some(source);
        self.poll_permissions();
    }

    /// Read the platform's answers (an error goes to the status line; the answers stay).
    fn poll_permissions(&mut self) {
        self.since_poll = 0;
        let Some(source) = &mut self.permissions else { return };
        match source.answers() {
            Ok((camera, location)) => self.set_permissions(camera, location),
            Err(e) => self.status = format!("cannot read the permissions: {e:#}"),
        }
    }

    pub fn permissions(&self) -> (Answer, Answer) {
        (self.camera_permission, self.location_permission)
    }

    /// Run these steps, in order, each as soon as the app can.
    pub fn set_script(&mut self, steps: Vec<Step>) {
        self.script = steps.into();
    }

    pub fn mode(&self) -> AppMode {
        match &self.capture {
            None => AppMode::Composite,
            Some(c) if c.saved.is_some() => AppMode::CaptureDone,
            Some(_) => AppMode::Capturing,
        }
    }

    pub fn session(&self) -> &LiveSession {
        &self.session
    }

    pub fn session_mut(&mut self) -> &mut LiveSession {
        &mut self.session
    }

    pub fn controls(&self) -> &Controls {
        &self.controls
    }

    /// The last frame the app advanced to.
    pub fn last_frame(&self) -> Option<&LiveFrame> {
        self.last.as_ref()
    }

    /// The folder of the last shutter press.
    pub fn last_export(&self) -> Option<&Path> {
        self.last_export.as_deref()
    }

    /// The capture folder saved by the current or last capture run.
    pub fn capture_folder(&self) -> Option<&Path> {
        self.captured.as_deref()
    }

    /// Which faces (in `Face::ALL` order) the capture screen showed a thumbnail of at its last
    /// UI pass (all false outside capture mode).
    pub fn capture_thumbnails(&self) -> [bool; 6] {
        self.capture.as_ref().map_or([false; 6], |run| run.thumbs.each_ref().map(Option::is_some))
    }

    /// The pose the capture's guidance judged aims with at the latest frame (the fused pose
    /// before the tap, the held heading after it); None outside capture mode.
    pub fn capture_aim_pose(&self) -> Option<crate::pose::Pose> {
        self.capture.as_ref().and_then(|c| c.aim_pose)
    }

    /// The capture assistant's guidance while capturing.
    pub fn guidance(&self) -> Option<crate::capture::assistant::Guidance> {
        self.capture.as_ref().map(|c| c.assistant.guidance())
    }

    /// The models the picker offers.
    pub fn models(&self) -> &[ModelChoice] {
        &self.models
    }

    /// Start capture mode (the camera image alone, the assistant's guidance over it).
    pub fn start_capture(&mut self) -> Result<()> {
        let s = self.session.scene();
        let camera = Pinhole::from_vfov(s.width, s.height, s.camera.vfov as f32)?;
        let mut cfg = AssistantConfig::new(CaptureMode::Stitch, camera);
        cfg.face_size = CAPTURE_FACE_SIZE;
        let assistant = Assistant::new(cfg)?;
        self.capture = Some(CaptureRun {
            assistant,
            aim: AimHeading::new(camera, true),
            aim_pose: None,
            gravity: GravityLog::new(self.session.display_rotation()),
            thumbs: Default::default(),
            thumb_sources: [None; 6],
            last_shot: None,
            tap: false,
            saved: None,
            assembled: None,
        });
        self.session.set_show_model(false);
        Ok(())
    }

    /// The user taps (capture mode, before the front is taken: the front is the next frame).
    pub fn tap(&mut self) {
        if let Some(c) = &mut self.capture {
            c.tap = true;
        }
    }

    /// Leave capture mode for the composite (with the capture's environment once it is saved).
    pub fn composite(&mut self) {
        if let Err(e) = self.session.lock_camera_exposure(false) {
            self.status = format!("camera exposure stays locked: {e:#}");
        }
        self.capture = None;
        self.session.set_show_model(true);
    }

    /// Offer a model file the user opened (a file dropped on the window, say) and switch to it.
    /// An error (not a model, unreadable) is also shown in the status line; the current model
    /// stays.
    pub fn open_model(&mut self, gpu: &Gpu, path: &Path) -> Result<()> {
        let result = self.try_open_model(gpu, path);
        match &result {
            Ok(()) => self.status = format!("model {}", file_label(path)),
            Err(e) => self.status = format!("{}: {e:#}", path.display()),
        }
        result
    }

    fn try_open_model(&mut self, gpu: &Gpu, path: &Path) -> Result<()> {
        let choice = ModelChoice { name: file_label(path), path: Some(path.to_path_buf()) };
        if let Some(i) = self.models.iter().position(|m| *m == choice) {
            return self.select_model(gpu, i);
        }
        self.models.push(choice);
        let index = self.models.len() - 1;
        let result = self.select_model(gpu, index);
        if result.is_err() {
            self.models.pop();
        }
        result
    }

    fn select_model(&mut self, gpu: &Gpu, index: usize) -> Result<()> {
        let choice = self.models.get(index).context("no such model")?.clone();
        let model = match &choice.path {
            Some(p) => crate::scene::model::load_model(p)?,
            None => crate::scene::demo::model()?,
        };
        self.session.set_model(gpu, &model, choice.path.as_deref())?;
        self.model = index;
        self.initial.1 = self.session.params().placement;
        Ok(())
    }

    /// Advance to the next camera frame and draw it into the compositor's target: in capture
    /// mode the assistant sees the frame (and takes its shot); a scripted step runs when it can.
    /// False when the session is over. With the camera refused nothing advances.
    pub fn frame(&mut self, gpu: &Gpu) -> Result<bool> {
        if self.quit || self.script.front() == Some(&Step::Quit) {
            return Ok(false);
        }
        self.since_poll += 1;
        if self.since_poll >= PERMISSION_POLL_FRAMES {
            self.poll_permissions();
        }
        if refused(self.camera_permission) {
            return Ok(true);
        }
        self.script_step(gpu)?;
        let placed = self.session.placed();
        let Some(f) = self.session.advance(gpu)? else { return Ok(false) };
        // The model was just placed in front of where the phone points: Reset goes back there.
        if !placed && self.session.placed() {
            self.initial.1 = self.session.params().placement;
        }
        self.last = Some(f);
        self.capture_frame(gpu, &f)?;
        self.session.draw(gpu)?;
        Ok(true)
    }

    fn script_step(&mut self, gpu: &Gpu) -> Result<()> {
        let Some(step) = self.script.front().copied() else { return Ok(()) };
        let done = match step {
            Step::Capture => {
                self.start_capture()?;
                true
            }
            Step::Composite => match self.mode() {
                AppMode::Capturing => false,
                _ => {
                    self.composite();
                    true
                }
            },
            Step::Shutter => {
                let ready = self.capture.is_none() && self.last.is_some_and(|f| f.pose.is_some());
                if ready {
                    self.shutter(gpu)?;
                }
                ready
            }
            Step::Quit => false,
        };
        if done {
            self.script.pop_front();
        }
        Ok(())
    }

    fn capture_frame(&mut self, gpu: &Gpu, f: &LiveFrame) -> Result<()> {
        let Some(run) = &mut self.capture else { return Ok(()) };
        if run.saved.is_some() {
            return Ok(());
        }
        run.tap |= f.user_tapped;
        for r in self.session.readings() {
            run.aim.update(r)?;
            run.gravity.update(r);
        }
        let Some(pose) = f.pose else { return Ok(()) };
        // From the tap on, aims are judged with the heading held at the tap and corrected by
        // the shots' images (capture::aim_heading, as `previz capture` does).
        let aim_pose = run.aim.aim_pose(pose, self.session.display_rotation());
        run.aim_pose = Some(aim_pose);
        // A phone camera's YUV frame stays on the GPU: read back only when a shot is taken.
        let image = || self.session.camera_frame(gpu).map(Arc::new);
        if run.tap && run.assistant.phase() == Phase::WaitingForTap {
            run.tap = false;
            // Every shot shares the front's exposure and white balance: locked at the tap
            // (after this frame). A camera that cannot lock them gets each shot's gain
            // estimated from the overlaps instead.
            let front = image()?;
            let locked = self.session.lock_camera_exposure(true)?;
            run.assistant.set_gain_compensation(!locked);
            run.assistant.tap(f.t, &pose, front.clone())?;
            run.aim.tap(self.session.orientation_filter(), f.t, &pose, front);
            run.assistant.set_shot_gravity(f.t, run.gravity.held(f.t));
            run.last_shot = Some((Face::Front.name().to_string(), f.t));
        } else if let Some(i) = run.assistant.observe(f.t, &aim_pose)? {
            let frame = image()?;
            let shot_pose = run.aim.shot(i, f.t, aim_pose, pose, frame.clone());
            run.assistant.capture(i, f.t, &shot_pose, frame)?;
            run.assistant.set_shot_gravity(f.t, run.gravity.held(f.t));
            let name = run.assistant.targets().get(i).map_or_else(String::new, |t| t.name.clone());
            run.last_shot = Some((name, f.t));
        }
        run.tap = false;
        if run.assistant.phase() == Phase::Complete {
            self.finish_capture(gpu)?;
        }
        Ok(())
    }

    /// Assemble the faces, save them as a capture folder and light the model with them.
    fn finish_capture(&mut self, gpu: &Gpu) -> Result<()> {
        self.session.lock_camera_exposure(false)?;
        let Some(run) = &mut self.capture else { return Ok(()) };
        let mut capture = run.assistant.finish()?;
        let (lat, lon) = self.session.location();
        capture.meta.location = Some(crate::capture::folder::Location { lat_deg: lat, lon_deg: lon, alt_m: 0.0 });
        let dir = new_folder(&self.export_dir, "previz-capture", self.session.now())?;
        if let Err(e) = crate::capture::save_capture(&capture, &dir) {
            let _ = std::fs::remove_dir(&dir);
            return Err(e);
        }
        run.assembled = Some(
            Face::ALL
                .iter()
                .map(|f| {
                    let face = capture.face(*f);
                    let pixels = face.rgb.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect();
                    crate::scene::Rgba8Image { width: face.size, height: face.size, pixels }
                })
                .collect(),
        );
        run.thumbs = Default::default();
        run.thumb_sources = [None; 6];
        let env = capture.to_cube_map();
        self.session.set_environment(gpu, &env, &dir, capture.meta.reference_heading_deg)?;
        let daylight = self.session.params().lighting.daylight;
        self.controls.daylight = daylight;
        self.initial.0.daylight = daylight;
        self.session.set_controls(self.controls);
        self.status = format!("capture saved: {}", folder_name(&dir));
        run.saved = Some(dir.clone());
        self.captured = Some(dir);
        Ok(())
    }

    /// Export the current frame into a new folder `previz-export-<time>` of the export folder.
    pub fn shutter(&mut self, gpu: &Gpu) -> Result<PathBuf> {
        let dir = new_folder(&self.export_dir, "previz-export", self.session.now())?;
        // The place only when the user asked for it.
        let location = self.export_location.then(|| self.session.location());
        if let Err(e) = super::export::export(&mut self.session, gpu, &dir, location) {
            let _ = std::fs::remove_dir(&dir);
            return Err(e);
        }
        self.last_export = Some(dir.clone());
        Ok(dir)
    }

    /// Draw the UI of the current mode. `frame` is the compositor's target registered with the
    /// egui renderer (None when the caller draws the frame itself, as the headless tests do);
    /// `perf` is the shell's frame-rate line.
    pub fn ui(&mut self, ctx: &egui::Context, frame: Option<egui::TextureId>, perf: &str) {
        if let Some(texture) = frame {
            let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            ctx.layer_painter(egui::LayerId::background()).image(texture, ctx.viewport_rect(), uv, egui::Color32::WHITE);
        }
        if refused(self.camera_permission) {
            self.refusal_screen(ctx);
            return;
        }
        match self.mode() {
            AppMode::Composite => self.composite_ui(ctx, perf),
            AppMode::Capturing | AppMode::CaptureDone => self.capture_ui(ctx),
        }
    }

    fn refusal_screen(&mut self, ctx: &egui::Context) {
        // (The bundled font has no arrow glyph.)
        let text = refusal_message(Permission::Camera, self.camera_permission).unwrap_or_default().replace('→', ">");
        let ask = self.camera_permission == Answer::Denied;
        // A dark screen: there is no camera image to show.
        ctx.layer_painter(egui::LayerId::background()).rect_filled(ctx.content_rect(), 0.0, egui::Color32::from_gray(24));
        egui::Window::new("Camera not allowed")
            .anchor(egui::Align2::CENTER_CENTER, egui::vec2(0.0, 0.0))
            .collapsible(false)
            .resizable(false)
            .max_width(ctx.content_rect().width() * 0.8)
            .show(ctx, |ui| {
                ui.label(egui::RichText::new(text).size(18.0));
                ui.add_space(12.0);
                if ask && ui.button("Ask again").clicked() {
                    self.requests.ask_permissions = true;
                }
            });
    }

    fn composite_ui(&mut self, ctx: &egui::Context, perf: &str) {
        use crate::ui::layout::{BAR_ID, MODEL_ID, STATUS_ID, composite_regions};
        // Each panel in its own part of the screen, none over another (ui::layout).
        let regions = composite_regions(ctx.content_rect());
        let sensors = self.session.sensors();
        egui::Window::new("previz live").id(egui::Id::unique(STATUS_ID)).fixed_rect(regions.status).vscroll(true).collapsible(true).show(
            ctx,
            |ui| {
                ui.label(perf);
                for line in status_lines(self.last.as_ref(), &sensors) {
                    ui.label(line);
                }
                let env = self.session.scene().environment.as_deref().map_or_else(|| "demo".to_string(), file_label);
                ui.label(format!("environment: {env}"));
            },
        );
        let mut controls = self.controls;
        self.requests.reset |= controls.show(ctx, regions.controls);
        if controls != self.controls {
            self.controls = controls;
            self.session.set_controls(controls);
        }
        egui::Window::new("model").id(egui::Id::unique(MODEL_ID)).fixed_rect(regions.model).vscroll(true).collapsible(true).show(
            ctx,
            |ui| {
                let mut chosen = self.model;
                egui::ComboBox::from_id_salt("model-picker")
                    .selected_text(self.models[self.model].name.clone())
                    .width(ui.available_width() - 8.0)
                    .show_ui(ui, |ui| {
                        for (i, m) in self.models.iter().enumerate() {
                            ui.selectable_value(&mut chosen, i, m.name.clone());
                        }
                    });
                if chosen != self.model {
                    self.requests.model = Some(chosen);
                }
                ui.label("(drop a model file on the window to add it)");
                if self.location_permission != Answer::Granted {
                    ui.separator();
                    ui.label(refusal_message(Permission::Location, self.location_permission).unwrap_or_default().replace('→', ">"));
                    ui.horizontal_wrapped(|ui| {
                        ui.add(egui::DragValue::new(&mut self.place.lat).range(-90.0..=90.0).speed(0.01).prefix("lat "));
                        ui.add(egui::DragValue::new(&mut self.place.lon).range(-180.0..=180.0).speed(0.01).prefix("lon "));
                    });
                    ui.add(egui::TextEdit::singleline(&mut self.place.time).desired_width(ui.available_width().min(200.0)));
                    self.requests.place |= ui.button("set place and time").clicked();
                }
            },
        );
        // The buttons and the status message in the bar along the bottom.
        egui::Area::new(egui::Id::unique(BAR_ID)).fixed_pos(regions.bar.min).show(ctx, |ui| {
            ui.set_max_size(regions.bar.size());
            ui.horizontal(|ui| {
                self.requests.capture |= ui.button("capture").clicked();
                self.requests.shutter |= ui.button("shutter").clicked();
                ui.checkbox(&mut self.export_location, "location").on_hover_text("write the place into exports");
                if !self.status.is_empty() {
                    ui.add(egui::Label::new(&self.status).truncate());
                }
            });
        });
    }

    fn capture_ui(&mut self, ctx: &egui::Context) {
        let now = self.last.map_or(0.0, |f| f.t);
        let Some(run) = &mut self.capture else { return };
        // Thumbnails: while capturing, every face some shot has seen shows the face as the shots
        // taken so far assemble it (`Assistant::face_so_far`, thumbnail-sized), made again only
        // when a shot lands; once finished, the capture's faces.
        let g = run.assistant.guidance();
        let targets = run.assistant.targets();
        let taken: Vec<usize> = (0..targets.len()).filter(|&k| run.assistant.shot(k).is_some()).collect();
        for (i, face) in Face::ALL.iter().enumerate() {
            let source = match &run.assembled {
                Some(_) => Some(ASSEMBLED),
                None => {
                    let seen = g.face_progress[i] > 0.0 || taken.iter().any(|&k| targets[k].face == *face);
                    seen.then_some(taken.len())
                }
            };
            if source == run.thumb_sources[i] {
                continue;
            }
            let image = match (source, &run.assembled) {
                (Some(ASSEMBLED), Some(faces)) => faces.get(i).cloned(),
                (Some(_), _) => run.assistant.face_so_far(*face, THUMB as u32).map(|f| {
                    let pixels = f.rgb.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect();
                    crate::scene::Rgba8Image { width: f.size, height: f.size, pixels }
                }),
                (None, _) => None,
            };
            let Some(image) = image else { continue };
            run.thumbs[i] = Some(ctx.load_texture(face.name(), thumbnail(&image, THUMB as usize), egui::TextureOptions::LINEAR));
            run.thumb_sources[i] = source;
        }
        let g = run.assistant.guidance();
        if run.saved.is_some() {
            draw_faces_preview(ctx, &run.thumbs);
        } else {
            draw_capture_overlay(ctx, &g, &run.thumbs);
            if let Some((name, t)) = &run.last_shot {
                draw_shot_feedback(ctx, name, now - t, SHOT_FEEDBACK_S);
            }
        }
        let waiting = g.phase == Phase::WaitingForTap;
        let done = run.saved.is_some();
        // Top left, clear of the thumbnails and the progress ring.
        egui::Area::new(egui::Id::unique("capture-buttons")).anchor(egui::Align2::LEFT_TOP, egui::vec2(8.0, 8.0)).show(ctx, |ui| {
            ui.horizontal(|ui| {
                if waiting && ui.button("tap").clicked() {
                    run.tap = true;
                }
                let label = if done { "composite with it" } else { "cancel" };
                self.requests.composite |= ui.button(label).clicked();
            });
        });
    }

    /// Do what the last UI pass asked for. Errors of an action are shown in the status line and
    /// returned.
    pub fn apply(&mut self, gpu: &Gpu) -> Result<()> {
        let r = std::mem::take(&mut self.requests);
        let mut result = Ok(());
        if r.ask_permissions {
            if let Some(source) = &mut self.permissions {
                result = source.ask_again();
            }
            self.poll_permissions();
        }
        if r.reset {
            self.controls = Controls { open: self.controls.open, ..self.initial.0 };
            self.session.params_mut().placement = self.initial.1;
            self.session.set_controls(self.controls);
        }
        if r.capture {
            result = result.and(self.start_capture());
        }
        if r.composite {
            self.composite();
        }
        if let Some(i) = r.model {
            result = result.and(self.select_model(gpu, i));
        }
        if r.place {
            let place = self.place.clone();
            let set = crate::sun::time::parse_time(&place.time, "time")
                .and_then(|t| self.session.set_place(place.lat, place.lon, t.with_timezone(&chrono::Utc)));
            result = result.and(set);
        }
        if r.shutter {
            result = result.and_then(|_| self.shutter(gpu).map(|dir| self.status = format!("saved {}", folder_name(&dir))));
        }
        if let Err(e) = &result {
            self.status = format!("{e:#}");
        }
        result
    }

    /// Touch and mouse gestures on the model (events egui did not take), in composite mode:
    /// one finger or the left mouse button drags it across the ground, two fingers pinch to
    /// scale and twist to turn it. `size` is the view's size in the events' pixels.
    pub fn window_event(&mut self, event: &winit::event::WindowEvent, size: glam::Vec2) {
        use winit::event::{ElementState, MouseButton, TouchPhase, WindowEvent};
        if self.capture.is_some() {
            // Capture mode: a tap anywhere (not on a button) takes the front.
            let tapped = match event {
                WindowEvent::MouseInput { state: ElementState::Pressed, button: MouseButton::Left, .. } => true,
                WindowEvent::Touch(t) => t.phase == TouchPhase::Started,
                _ => false,
            };
            if tapped {
                self.tap();
            }
            return;
        }
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

    /// The app went to the background: camera and sensors stop; everything is kept.
    pub fn suspend(&mut self) -> Result<()> {
        self.session.suspend()
    }

    pub fn resume(&mut self) -> Result<()> {
        self.session.resume()
    }
}

fn refused(a: Answer) -> bool {
    matches!(a, Answer::Denied | Answer::DeniedForever)
}

fn file_label(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// A new, empty folder `<prefix>-<time>` in `parent` (made if missing); `-2`, `-3`, ... are
/// added when a folder of that name exists, so an export never lands in an earlier one.
fn new_folder(parent: &std::path::Path, prefix: &str, time: chrono::DateTime<chrono::Utc>) -> Result<PathBuf> {
    std::fs::create_dir_all(parent).with_context(|| format!("cannot create the export folder {}", parent.display()))?;
    let name = format!("{prefix}-{}", time.format("%Y%m%d-%H%M%S%.3f"));
    for n in 1..1000 {
        let dir = parent.join(if n == 1 { name.clone() } else { format!("{name}-{n}") });
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e).with_context(|| format!("cannot create {}", dir.display())),
        }
    }
    bail!("{} holds 999 folders named {name}: choose another export folder", parent.display())
}

/// The last part of `dir` (the status line names a folder of the export folder without the
/// export folder's own path).
fn folder_name(dir: &std::path::Path) -> String {
    dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// The status panel's text (pure, so it is tested without a window).
pub fn status_lines(last: Option<&LiveFrame>, sensors: &str) -> Vec<String> {
    let mut lines = vec![format!("sensors: {sensors}")];
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
        let waiting = status_lines(None, "sim");
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
        let frame = LiveFrame {
            t: 1.0,
            pose: Some(pose),
            pose_error_deg: None,
            sun,
            sunlight: 0.8,
            camera_ms: 0.0,
            pose_ms: 0.0,
            sun_ms: 0.0,
            user_tapped: false,
        };
        let lines = status_lines(Some(&frame), "sim").join("\n");
        assert!(lines.contains("heading 90.0°, pitch 0.0° (±2.0°, gyro only"), "{lines}");
        // NREL SPA's published azimuth for this place and instant (Reda & Andreas 2004): 194.34°.
        assert!(lines.contains("sun: azimuth 194.3°"), "{lines}");
    }

    #[test]
    fn script_steps_parse_and_unknown_ones_are_named() {
        assert_eq!(
            Step::parse_list("capture, composite,shutter,quit").unwrap(),
            [Step::Capture, Step::Composite, Step::Shutter, Step::Quit]
        );
        let e = Step::parse_list("capture,jump").unwrap_err().to_string();
        assert!(e.contains("--script") && e.contains("jump"), "{e}");
    }
}
