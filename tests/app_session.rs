//! The app's acceptance story on the virtual phone, headless (`live::app::App`): capture mode
//! with the simulated user following the assistant → the capture saved as a capture folder and
//! lighting the model → composite → gestures move the model → the shutter (pressed through
//! synthetic egui input) exports a frame that `previz composite` reproduces. Goldens of each
//! capture screen and of the composite panel; the refusal screen.

use crate::common;

use common::cli::{previz, tempdir};
use common::{gpu, inputs, scene};
use previz::capture::load_capture;
use previz::live::app::{App, AppMode, PERMISSION_POLL_FRAMES, PermissionSource};
use previz::live::export::FILES;
use previz::live::{LiveConfig, LiveSession, Sources};
use previz::render::{FrameParams, Rendered, Timings};
use previz::scene::Rgba8Image;
use previz::sensors::permissions::Answer;
use previz::sensors::sim::NoiseLevel;
use previz::setup::exposure;
use previz::ui::headless::HeadlessUi;
use std::sync::{Arc, Mutex};

const W: u32 = 480;
const H: u32 = 320;
const SCENE: &str = "width = 480\nheight = 320\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
[camera]\nheading = 90.0\npitch = -5.0\n";

fn config() -> LiveConfig {
    LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 15.0,
        duration_s: 60.0,
        noise: NoiseLevel::None,
        seed: 2,
    }
}

/// The app's UI drawn over the frame the session draws now, as a still (two passes: egui
/// windows size themselves in the first). A still waits for the model's sky and the ground's map
/// of the current turn, which the live view makes on threads of their own: a golden needs the
/// frame that does not depend on their timing.
fn screen(app: &mut App, ui: &mut HeadlessUi) -> Rendered {
    let frame = app.session_mut().render_still(gpu()).unwrap();
    let background = Rgba8Image { width: frame.width, height: frame.height, pixels: frame.rgba };
    ui.render(gpu(), &background, |ctx| app.ui(ctx, None, "15.0 fps")).unwrap();
    let img = ui.render(gpu(), &background, |ctx| app.ui(ctx, None, "15.0 fps")).unwrap();
    Rendered { width: img.width, height: img.height, rgba: img.pixels, timings: Timings::default() }
}

/// A headless UI whose windows appear at once: its clock stands still, so egui's fade-in would
/// never finish.
fn still_ui() -> HeadlessUi {
    let ui = HeadlessUi::new(gpu(), W, H, 1.0).unwrap();
    ui.context().all_styles_mut(|s| s.animation_time = 0.0);
    ui
}

/// Where the ground point `p` (world) appears on a `W`×`H` screen, pixels (y down).
fn project(params: &FrameParams, p: glam::Vec3) -> glam::Vec2 {
    let c = &params.camera;
    let d = c.pose.inverse() * (p - c.position);
    let t = (0.5 * c.vfov).tan();
    let ndc = glam::Vec2::new(d.x / (-d.z * t * W as f32 / H as f32), d.y / (-d.z * t));
    glam::Vec2::new((ndc.x + 1.0) * 0.5 * W as f32, (1.0 - ndc.y) * 0.5 * H as f32)
}

fn touch(id: u64, phase: winit::event::TouchPhase, at: glam::Vec2) -> winit::event::WindowEvent {
    winit::event::WindowEvent::Touch(winit::event::Touch {
        device_id: winit::event::DeviceId::dummy(),
        phase,
        location: winit::dpi::PhysicalPosition::new(f64::from(at.x), f64::from(at.y)),
        force: None,
        id,
    })
}

/// One egui pass of the app at the screen's size with `events`; the font atlas uploads a
/// renderer would take are drained.
fn pass(ctx: &egui::Context, app: &mut App, events: Vec<egui::Event>) -> egui::FullOutput {
    pass_at(ctx, app, events, egui::vec2(W as f32, H as f32))
}

/// [`pass`] on a screen of `size` points.
fn pass_at(ctx: &egui::Context, app: &mut App, events: Vec<egui::Event>, size: egui::Vec2) -> egui::FullOutput {
    let input = egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, size)), events, ..Default::default() };
    let mut out = ctx.run_pass(input, |ctx| app.ui(ctx, None, ""));
    out.textures_delta.set.drain().for_each(drop);
    out.textures_delta.free.drain().for_each(drop);
    out
}

/// Click the button labelled `label` with synthetic pointer events.
fn click(ctx: &egui::Context, app: &mut App, label: &str) {
    click_at(ctx, app, label, egui::vec2(W as f32, H as f32));
}

/// [`click`] on a screen of `size` points.
fn click_at(ctx: &egui::Context, app: &mut App, label: &str, size: egui::Vec2) {
    let pass = |ctx: &egui::Context, app: &mut App, events| pass_at(ctx, app, events, size);
    pass(ctx, app, vec![]);
    let out = pass(ctx, app, vec![]);
    let at = out
        .shapes
        .iter()
        .find_map(|s| match &s.shape {
            egui::Shape::Text(t) if t.galley.text() == label => Some(t.visual_bounding_rect().center()),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no {label:?} button on screen"));
    let button =
        |pressed| egui::Event::PointerButton { pos: at, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
    pass(ctx, app, vec![egui::Event::PointerMoved(at), button(true)]);
    pass(ctx, app, vec![button(false)]);
}

#[test]
fn capture_then_composite_with_it_then_export() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let env = Arc::new(inp.env);
    let cfg = config();
    let sources = Sources::simulated_capture(env.clone(), &s, exposure(&s, &env), &cfg).unwrap();
    let session = LiveSession::new(gpu(), &env, &inp.model, &s, cfg, sources).unwrap();
    let dir = tempdir("app_session", "story");
    let mut app = App::new(session, dir.clone());
    let mut ui = still_ui();

    // Capture mode: the camera image alone, the assistant waiting for the tap.
    app.start_capture().unwrap();
    assert_eq!(app.mode(), AppMode::Capturing);
    let (mut waiting, mut progress) = (false, false);
    let mut frames = 0;
    while app.mode() == AppMode::Capturing {
        assert!(app.frame(gpu()).unwrap(), "the session ended before the capture was complete");
        frames += 1;
        assert!(frames < 15 * 50, "no complete capture after 50 s of the simulated user following the assistant");
        let g = app.guidance().unwrap();
        if !waiting && app.last_frame().is_some_and(|f| f.pose.is_some() && f.t > 1.0) {
            waiting = true;
            assert_eq!(g.faces_done, 0);
            common::assert_golden("app_capture_waiting", &screen(&mut app, &mut ui));
        }
        if !progress && g.faces_done == 3 {
            progress = true;
            common::assert_golden("app_capture_progress", &screen(&mut app, &mut ui));
            // Every face some shot has seen shows a thumbnail, and no other (the golden shows
            // them; stitch mode sees faces through its extra views before their centres).
            let seen = g.face_progress.map(|p| p > 0.0);
            assert_eq!(app.capture_thumbnails(), seen, "thumbnails for the faces seen ({:?})", g.face_progress);
            assert!(seen.iter().filter(|s| **s).count() >= 4, "{:?}", g.face_progress);
        }
    }
    assert!(waiting && progress);
    assert_eq!(app.mode(), AppMode::CaptureDone);
    common::assert_golden("app_capture_faces", &screen(&mut app, &mut ui));

    // The capture folder is the format `previz capture` writes, and it is what lights the model.
    let folder = app.capture_folder().expect("a capture folder").to_path_buf();
    let capture = load_capture(&folder).unwrap();
    assert_eq!(app.session().scene().environment.as_deref(), Some(folder.as_path()));
    assert_eq!(app.session().scene().env.heading, capture.meta.reference_heading_deg);
    // The simulated user's front is the scene camera's heading (90°, within the aim error).
    assert!((capture.meta.reference_heading_deg - 90.0).abs() < 3.0, "front at {}°", capture.meta.reference_heading_deg);
    // Every face is covered by what the camera saw (stitch mode completes by coverage; measured
    // 1.0 for every face).
    for f in &capture.meta.faces {
        assert!(f.coverage >= 0.99, "{:?} covers {}", f.face, f.coverage);
    }
    // The faces match the map's faces (at the capture's reference heading and the phone's
    // exposure). The third session's app captured in stretch mode (the camera's centred square
    // stretched over the face's 90°), whose faces scored 9.6 to 11.0 dB against these (23.6 to
    // 32.4 dB against the stretched directions); the app now captures in stitch mode, as
    // `previz capture` does. Measured: front 28.6, up 26.3, right 28.6, left 29.8, back 26.9,
    // down 41.9 dB (the map's own down face is that dark: mean code 2.1); a face turned 90°
    // scores near 10 dB. Bound: the worst measured less 2.3 dB.
    assert_eq!(capture.meta.mode, previz::capture::Mode::Stitch);
    let lut = previz::camera::exposure::ToneLut::new();
    let to_world = previz::capture::projection::local_to_world(capture.meta.reference_heading_deg.to_radians()).as_quat();
    let phone_exposure = exposure(&s, &env);
    for f in &capture.faces {
        let mut map_face = Vec::with_capacity(f.rgb.len());
        for y in 0..f.size {
            for x in 0..f.size {
                let d = previz::capture::projection::face_pixel_dir_local(f.face.layer(), x, y, f.size, 1.0);
                map_face.extend(env.sample_enu(to_world * d).map(|v| lut.map(v * phone_exposure)));
            }
        }
        let psnr = previz::capture::replay::psnr(&f.rgb, &map_face).unwrap_or(f64::INFINITY);
        assert!(psnr >= 24.0, "{:?}: PSNR {psnr:.1} dB against the map's face", f.face);
    }

    // Composite with it: the model appears over the camera image.
    click(&egui::Context::default(), &mut app, "composite with it");
    app.apply(gpu()).unwrap();
    assert_eq!(app.mode(), AppMode::Composite);
    // Once the simulated user looks at the model again (the capture ended looking down).
    let mut n = 0;
    while n < 10 || app.session().params().camera.pose.mul_vec3(glam::Vec3::NEG_Z).z < -0.3 {
        assert!(app.frame(gpu()).unwrap(), "the session ended");
        n += 1;
    }
    // (The composite panel's golden is taken in a session without a capture: the capture's
    // folder name, shown in the panel, holds the time.)

    // A one-finger drag moves the model so that its ground point stays under the finger; two
    // fingers pinching apart to twice the distance and turning by 30° scale it 2x and turn it.
    let size = glam::Vec2::new(W as f32, H as f32);
    let p0 = app.session().params().placement;
    let from = project(app.session().params(), p0.position);
    let to = from + glam::Vec2::new(60.0, 25.0);
    use winit::event::TouchPhase::{Ended, Moved, Started};
    for e in [touch(1, Started, from), touch(1, Moved, to), touch(1, Ended, to)] {
        app.window_event(&e, size);
    }
    let p1 = app.session().params().placement;
    assert!((p1.position - p0.position).length() > 0.05, "the model moved: {:?} -> {:?}", p0.position, p1.position);
    assert!((p1.position.z - p0.position.z).abs() < 1e-6, "it stays on its ground plane");
    let seen = project(app.session().params(), p1.position);
    assert!((seen - to).length() < 0.5, "the model's ground point is under the finger: {seen} vs {to}");
    let (a, b0) = (glam::Vec2::new(200.0, 200.0), glam::Vec2::new(260.0, 200.0));
    let turn = 30f32.to_radians();
    let b1 = a + 120.0 * glam::Vec2::new(turn.cos(), -turn.sin());
    for e in [touch(2, Started, a), touch(3, Started, b0), touch(3, Moved, b1), touch(3, Ended, b1), touch(2, Ended, a)] {
        app.window_event(&e, size);
    }
    let p2 = app.session().params().placement;
    assert!((p2.scale / p1.scale - 2.0).abs() < 1e-4, "pinch to twice the distance: scale {} -> {}", p1.scale, p2.scale);
    let dz = (p2.rotation.z - p1.rotation.z).to_degrees();
    assert!((dz.abs() - 30.0).abs() < 1e-2, "a 30° twist turns the model 30° about the vertical, got {dz}°");

    // The shutter, pressed through the UI: the export names the capture as its environment and
    // `previz composite` renders the same frame again.
    click(&egui::Context::default(), &mut app, "shutter");
    app.apply(gpu()).unwrap();
    let export = app.last_export().expect("an export").to_path_buf();
    for name in FILES {
        assert!(export.join(name).is_file(), "{name} missing from {}", export.display());
    }
    let toml = std::fs::read_to_string(export.join("scene.toml")).unwrap();
    assert!(toml.contains(&*folder.file_name().unwrap().to_string_lossy()), "the capture is the environment:\n{toml}");
    let out = previz(&export, &["composite", "scene.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rgb = |p: &std::path::Path| image::open(p).unwrap().to_rgb8();
    let (exported, again) = (rgb(&export.join("composite.png")), rgb(&export.join("recomposite.png")));
    let flip = previz::capture::replay::mean_flip(exported.as_raw(), again.as_raw(), W, H).unwrap();
    assert!(flip <= 0.02, "mean FLIP {flip} between the exported frame and its recomposite\n{toml}");
}

/// A platform's permission answers (test double of the phone shells' `PermissionSource`): the
/// camera's answer as the test sets it, location granted; "Ask again" counted, and answered with
/// `on_ask` when set.
#[derive(Clone)]
struct Platform {
    state: Arc<Mutex<PlatformState>>,
}

struct PlatformState {
    camera: Answer,
    reads: u32,
    asked: u32,
    on_ask: Option<Answer>,
}

impl Platform {
    fn new(camera: Answer) -> Platform {
        Platform { state: Arc::new(Mutex::new(PlatformState { camera, reads: 0, asked: 0, on_ask: None })) }
    }
}

impl PermissionSource for Platform {
    fn answers(&mut self) -> anyhow::Result<(Answer, Answer)> {
        let mut s = self.state.lock().unwrap();
        s.reads += 1;
        Ok((s.camera, Answer::Granted))
    }

    fn ask_again(&mut self) -> anyhow::Result<()> {
        let mut s = self.state.lock().unwrap();
        s.asked += 1;
        if let Some(a) = s.on_ask {
            s.camera = a;
        }
        Ok(())
    }
}

#[test]
fn permissions_answered_while_the_app_runs_start_and_stop_the_picture() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
    let mut app = App::new(session, tempdir("app_session", "platform"));
    // The system dialog is up: the app runs (a phone camera would give grey frames).
    let platform = Platform::new(Answer::Pending);
    app.set_permission_source(Box::new(platform.clone()));
    assert!(app.frame(gpu()).unwrap());
    let t0 = app.last_frame().expect("frames advance while the answer is pending").t;
    // The user refuses: within one poll interval the frames stop and the refusal screen shows.
    platform.state.lock().unwrap().camera = Answer::DeniedForever;
    for _ in 0..PERMISSION_POLL_FRAMES {
        app.frame(gpu()).unwrap();
    }
    assert_eq!(app.permissions().0, Answer::DeniedForever);
    let stopped = app.last_frame().unwrap().t;
    assert!(stopped > t0);
    for _ in 0..3 {
        app.frame(gpu()).unwrap();
    }
    assert_eq!(app.last_frame().unwrap().t, stopped, "no frame advances while the camera is refused");
    // Allowed in the settings: read at the next poll, the frames go on.
    platform.state.lock().unwrap().camera = Answer::Granted;
    for _ in 0..PERMISSION_POLL_FRAMES {
        app.frame(gpu()).unwrap();
    }
    assert_eq!(app.permissions().0, Answer::Granted);
    assert!(app.last_frame().unwrap().t > stopped);
    // Read once at set-up and once per PERMISSION_POLL_FRAMES frames (3 + 2 polls' worth).
    let frames = 1 + 2 * PERMISSION_POLL_FRAMES + 3;
    assert_eq!(platform.state.lock().unwrap().reads, 1 + frames / PERMISSION_POLL_FRAMES);
}

#[test]
fn camera_refused_shows_what_is_missing_and_location_refused_composites_with_a_manual_place() {
    // The environment is declared a capture of this place and moment: the sun follows the
    // place and time the user types.
    let s = scene(&format!("{SCENE}[env]\ncaptured_here = true\n"));
    let inp = inputs(&s);
    let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
    let mut app = App::new(session, tempdir("app_session", "refused"));
    let mut ui = still_ui();

    // Camera refused for good: nothing advances, the screen names what is missing and where to
    // grant it, and offers no "Ask again" (Android will not ask).
    app.set_permissions(Answer::DeniedForever, Answer::Granted);
    assert!(app.frame(gpu()).unwrap());
    assert!(app.last_frame().is_none(), "no camera frame while the camera is refused");
    let ctx = egui::Context::default();
    pass(&ctx, &mut app, vec![]);
    let texts: Vec<String> = pass(&ctx, &mut app, vec![])
        .shapes
        .iter()
        .filter_map(|s| match &s.shape {
            egui::Shape::Text(t) => Some(t.galley.text().to_string()),
            _ => None,
        })
        .collect();
    let all = texts.join("\n");
    assert!(all.contains("Camera not allowed") && all.contains("Settings") && !all.contains("Ask again"), "{all}");
    common::assert_golden("app_camera_refused", &{
        let black = Rgba8Image { width: W, height: H, pixels: vec![0; (W * H * 4) as usize] };
        ui.render(gpu(), &black, |ctx| app.ui(ctx, None, "")).unwrap();
        let img = ui.render(gpu(), &black, |ctx| app.ui(ctx, None, "")).unwrap();
        Rendered { width: img.width, height: img.height, rgba: img.pixels, timings: Timings::default() }
    });
    // Refused once: "Ask again" reaches the platform once, and its new answer is read at once.
    let platform = Platform::new(Answer::Denied);
    app.set_permission_source(Box::new(platform.clone()));
    assert_eq!(app.permissions(), (Answer::Denied, Answer::Granted));
    click(&ctx, &mut app, "Ask again");
    platform.state.lock().unwrap().on_ask = Some(Answer::Granted);
    app.apply(gpu()).unwrap();
    assert_eq!(platform.state.lock().unwrap().asked, 1);
    assert_eq!(app.permissions(), (Answer::Granted, Answer::Granted));

    // Location refused: the composite runs, the sun comes from the place and time set by hand.
    app.set_permissions(Answer::Granted, Answer::Denied);
    assert!(app.frame(gpu()).unwrap());
    // On the desktop's window (at phone sizes the model panel holds the same fields, scrolled:
    // composite_panels_never_overlap_at_phone_sizes_portrait_and_landscape).
    let desktop = egui::vec2(1280.0, 800.0);
    let pass = |ctx: &egui::Context, app: &mut App, events| pass_at(ctx, app, events, desktop);
    let ctx = egui::Context::default();
    pass(&ctx, &mut app, vec![]);
    let out = pass(&ctx, &mut app, vec![]);
    let edit = out
        .shapes
        .iter()
        .find_map(|s| match &s.shape {
            egui::Shape::Text(t) if t.galley.text().starts_with("2026-06-21T14:00:00") => Some(t.visual_bounding_rect().center()),
            _ => None,
        })
        .expect("the time field shows the session's start");
    // Type a midnight time into the field and press "set place and time".
    let button =
        |pressed| egui::Event::PointerButton { pos: edit, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
    pass(&ctx, &mut app, vec![egui::Event::PointerMoved(edit), button(true), button(false)]);
    let select_all =
        egui::Event::Key { key: egui::Key::A, physical_key: None, pressed: true, repeat: false, modifiers: egui::Modifiers::COMMAND };
    pass(&ctx, &mut app, vec![select_all, egui::Event::Text("2026-06-21T00:00:00Z".into())]);
    click_at(&ctx, &mut app, "set place and time", desktop);
    app.apply(gpu()).unwrap();
    assert_eq!(app.session().config().start.to_rfc3339(), "2026-06-21T00:00:00+00:00");
    // Midnight in Bristol at midsummer: the sun is below the horizon, no sunlight.
    app.frame(gpu()).unwrap();
    let f = app.last_frame().unwrap();
    assert!(f.sun.apparent_elevation_deg() < -10.0 && f.sunlight == 0.0, "sun at {}°", f.sun.apparent_elevation_deg());
}

#[test]
fn x_y_z_sliders_turn_the_model_by_the_dragged_angle() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
    let mut app = App::new(session, tempdir("app_session", "xyz"));
    let ctx = egui::Context::default();
    // A taller screen so the whole panel shows.
    let input = |events| egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 900.0))),
        events,
        ..Default::default()
    };
    let run = |app: &mut App, events: Vec<egui::Event>| {
        let mut out = ctx.run_pass(input(events), |ctx| app.ui(ctx, None, ""));
        out.textures_delta.set.drain().for_each(drop);
        out.textures_delta.free.drain().for_each(drop);
        out
    };
    run(&mut app, vec![]);
    for (axis, label) in ["X", "Y", "Z"].into_iter().enumerate() {
        let out = run(&mut app, vec![]);
        let texts: Vec<(String, egui::Rect)> = out
            .shapes
            .iter()
            .filter_map(|s| match &s.shape {
                egui::Shape::Text(t) => Some((t.galley.text().to_string(), t.visual_bounding_rect())),
                _ => None,
            })
            .collect();
        let row = texts.iter().find(|(t, _)| t == label).unwrap_or_else(|| panic!("no {label} slider")).1;
        // The slider's value box ("0°") left of the label; press on the rail left of it and
        // drag to the far right: the rail's end is +180°.
        let value = texts
            .iter()
            .filter(|(t, r)| t.ends_with('°') && (r.center().y - row.center().y).abs() < 6.0 && r.right() <= row.left())
            .map(|(_, r)| *r)
            .max_by(|a, b| a.left().total_cmp(&b.left()))
            .expect("the value box");
        let press = egui::pos2(value.left() - 60.0, row.center().y);
        let far = egui::pos2(value.left() - 8.0, row.center().y);
        let button =
            |pos, pressed| egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
        run(&mut app, vec![egui::Event::PointerMoved(press), button(press, true)]);
        run(&mut app, vec![egui::Event::PointerMoved(far)]);
        run(&mut app, vec![button(far, false)]);
        let r = app.session().params().placement.rotation;
        let turned = [r.x, r.y, r.z][axis].to_degrees();
        assert!((turned - 180.0).abs() < 1e-3, "{label} dragged to the right end: the model turned {turned}° about {label}");
        assert_eq!(app.controls().rotation_deg[axis], 180.0);
    }

    // Reset: the scene's values and placement again.
    let size = egui::vec2(800.0, 900.0);
    click_at(&egui::Context::default(), &mut app, "reset", size);
    app.apply(gpu()).unwrap();
    assert_eq!(app.session().params().placement.rotation, glam::Vec3::ZERO, "reset turns the model back");
    assert_eq!(app.controls().rotation_deg, [0.0; 3]);

    // The place goes into an export only when the user ticks `location`.
    assert!(app.frame(gpu()).unwrap());
    let toml_of = |app: &App| std::fs::read_to_string(app.last_export().unwrap().join("scene.toml")).unwrap();
    click_at(&egui::Context::default(), &mut app, "shutter", size);
    app.apply(gpu()).unwrap();
    assert!(!toml_of(&app).contains("location"), "no place unless asked");
    click_at(&egui::Context::default(), &mut app, "location", size);
    click_at(&egui::Context::default(), &mut app, "shutter", size);
    app.apply(gpu()).unwrap();
    assert!(toml_of(&app).contains("# location: latitude 51.454500, longitude -2.587900"), "{}", toml_of(&app));
}

/// The rectangles egui drew the composite mode's panels in, after a few passes of the app's UI
/// on a `w`×`h` screen.
fn panel_rects(app: &mut App, w: f32, h: f32) -> Vec<(&'static str, egui::Rect)> {
    use previz::ui::layout::{BAR_ID, CONTROLS_ID, MODEL_ID, STATUS_ID};
    let ctx = egui::Context::default();
    ctx.all_styles_mut(|s| s.animation_time = 0.0);
    for _ in 0..3 {
        let input =
            egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(w, h))), ..Default::default() };
        let mut out = ctx.run_pass(input, |ctx| app.ui(ctx, None, "15.0 fps"));
        out.textures_delta.set.drain().for_each(drop);
        out.textures_delta.free.drain().for_each(drop);
    }
    [("status", STATUS_ID), ("model", MODEL_ID), ("controls", CONTROLS_ID), ("bar", BAR_ID)]
        .into_iter()
        .map(|(name, id)| (name, ctx.memory(|m| m.area_rect(egui::Id::unique(id))).unwrap_or_else(|| panic!("{w}x{h}: no {name} panel"))))
        .collect()
}

#[test]
fn composite_panels_never_overlap_at_phone_sizes_portrait_and_landscape() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
    let mut app = App::new(session, tempdir("app_session", "layout"));
    for _ in 0..40 {
        app.frame(gpu()).unwrap();
    }
    // Phone screens in points (Android 360x640, iPhone 390x844) both ways, the golden's size;
    // with location allowed and refused (the model panel then holds the manual place and time).
    for location in [Answer::Granted, Answer::Denied] {
        app.set_permissions(Answer::Granted, location);
        for (w, h) in [(360.0, 640.0), (640.0, 360.0), (390.0, 844.0), (844.0, 390.0), (480.0, 320.0)] {
            let rects = panel_rects(&mut app, w, h);
            let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(w, h));
            for (name, r) in &rects {
                assert!(screen.contains_rect(*r), "{w}x{h} {location:?}: {name} {r:?} leaves the screen");
            }
            for (i, (a, ra)) in rects.iter().enumerate() {
                for (b, rb) in &rects[i + 1..] {
                    assert!(!ra.intersects(*rb), "{w}x{h} {location:?}: {a} {ra:?} overlaps {b} {rb:?}");
                }
            }
        }
    }
    // Goldens of a phone in portrait and in landscape (looked at).
    for (name, w, h) in [("app_composite_portrait", 360, 640), ("app_composite_landscape", 640, 360)] {
        let s = scene(&SCENE.replace("width = 480\nheight = 320", &format!("width = {w}\nheight = {h}")));
        assert_eq!((s.width, s.height), (w, h));
        let inp = inputs(&s);
        let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
        let mut app = App::new(session, tempdir("app_session", name));
        for _ in 0..40 {
            app.frame(gpu()).unwrap();
        }
        let mut ui = HeadlessUi::new(gpu(), w, h, 1.0).unwrap();
        ui.context().all_styles_mut(|s| s.animation_time = 0.0);
        let frame = app.session_mut().render_still(gpu()).unwrap();
        let background = Rgba8Image { width: frame.width, height: frame.height, pixels: frame.rgba };
        ui.render(gpu(), &background, |ctx| app.ui(ctx, None, "15.0 fps")).unwrap();
        let img = ui.render(gpu(), &background, |ctx| app.ui(ctx, None, "15.0 fps")).unwrap();
        common::assert_golden(name, &Rendered { width: img.width, height: img.height, rgba: img.pixels, timings: Timings::default() });
    }
}

#[test]
fn a_model_file_opened_joins_the_picker_and_a_bad_one_is_named_and_changes_nothing() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, config()).unwrap();
    let dir = tempdir("app_session", "models");
    let mut app = App::new(session, dir.clone());
    // The composite panel once the pose has settled (seeded, noise-free: the same every run).
    for _ in 0..40 {
        assert!(app.frame(gpu()).unwrap());
    }
    assert!(app.last_frame().is_some_and(|f| f.pose.is_some()));
    common::assert_golden("app_composite_panel", &screen(&mut app, &mut still_ui()));
    // The scene's model and the bundled demo truck.
    assert_eq!(app.models().len(), 2);
    let bad = dir.join("not_a_model.obj");
    std::fs::write(&bad, b"v 1 2\nf 1 2 3 4 5\n").unwrap();
    let before = app.session().params().placement;
    let e = app.open_model(gpu(), &bad).unwrap_err();
    assert!(format!("{e:#}").contains("not_a_model.obj"), "{e:#}");
    assert_eq!(app.models().len(), 2, "a model that did not load is not offered");
    assert_eq!(app.session().params().placement, before);
    let teapot = common::data("meshes/suzanne.obj");
    app.open_model(gpu(), &teapot).unwrap();
    assert_eq!(app.models().len(), 3);
    assert_eq!(app.session().scene().model.as_deref(), Some(teapot.as_path()));
}

/// The app's capture mode judges aims with the heading held at the tap and corrected by each
/// landed shot's image match (`capture::aim_heading`), as `previz capture` does: at `bad` sensor
/// noise, through the app's own loop on the virtual phone, the capture completes and, at the
/// frames a shot landed, the guidance's turn since the tap is closer to the camera's true turn
/// than the fused pose's (whose compass error changes with heading). Measured (seed 2, with
/// the tour by the phone's rotation): rms 4.20° against 14.74° for the fused pose, worst 7.98°
/// against 21.60°, one repair view left after the pre-recorded path. The same run judging aims with the fused pose (the app before AimHeading) was still
/// incomplete after 825 frames (55 s). A suspend → resume after the fifth shot keeps the capture
/// in progress.
#[test]
fn the_capture_guidance_holds_its_heading_at_bad_noise() {
    use previz::pose::frames::{heading_difference_deg, heading_pitch_roll};
    let s = scene(SCENE);
    let inp = inputs(&s);
    let env = Arc::new(inp.env);
    let cfg = LiveConfig { noise: NoiseLevel::Bad, ..config() };
    let camera = previz::capture::projection::Pinhole::from_vfov(W, H, s.camera.vfov as f32).unwrap();
    let truth = previz::live::capture_then_look_around_path(&camera, s.camera.heading, s.camera.pitch, cfg.duration_s, cfg.seed).unwrap();
    let sources = Sources::simulated_capture(env.clone(), &s, exposure(&s, &env), &cfg).unwrap();
    let session = LiveSession::new(gpu(), &env, &inp.model, &s, cfg, sources).unwrap();
    let mut app = App::new(session, tempdir("app_session", "aim"));
    app.start_capture().unwrap();
    let heading = |q: glam::DQuat| heading_pitch_roll(q).heading.to_degrees();
    // (aim, fused, true) headings at the tap, then the largest error of the turn since the tap.
    let mut at_tap: Option<(f64, f64, f64)> = None;
    let (mut aim_worst, mut fused_worst, mut compared) = (0f64, 0f64, 0usize);
    // The same at the frames a shot landed (the aims the guidance judged while held still).
    let (mut aim_shots, mut fused_shots) = (Vec::new(), Vec::new());
    let mut shots = 0;
    let mut frames = 0;
    while app.mode() == AppMode::Capturing && frames < 15 * 55 {
        assert!(app.frame(gpu()).unwrap(), "the session ended");
        frames += 1;
        let (Some(f), Some(aim)) = (app.last_frame(), app.capture_aim_pose()) else { continue };
        let (Some(fused), Some(g)) = (f.pose, app.guidance()) else { continue };
        if g.phase == previz::capture::assistant::Phase::WaitingForTap {
            continue;
        }
        let t = truth.orientation_at(f.t);
        // Heading is undefined looking straight up or down: compare where the camera is within
        // 60° of the horizon.
        if heading_pitch_roll(t).pitch.to_degrees().abs() > 60.0 {
            continue;
        }
        let now = (heading(aim.q.as_dquat()), heading(fused.q.as_dquat()), heading(t));
        let tap = *at_tap.get_or_insert(now);
        let turned = heading_difference_deg(now.2, tap.2);
        let aim_error = heading_difference_deg(heading_difference_deg(now.0, tap.0), turned).abs();
        let fused_error = heading_difference_deg(heading_difference_deg(now.1, tap.1), turned).abs();
        aim_worst = aim_worst.max(aim_error);
        fused_worst = fused_worst.max(fused_error);
        compared += 1;
        if g.shots_done > std::mem::replace(&mut shots, g.shots_done) {
            aim_shots.push(aim_error);
            fused_shots.push(fused_error);
            // Mid-capture the app goes to the background and comes back (another app, the
            // screen locked): the capture in progress survives and goes on.
            if shots == 5 {
                app.suspend().unwrap();
                assert!(app.frame(gpu()).is_err(), "a suspended app advances no frame");
                app.resume().unwrap();
                assert_eq!((app.mode(), app.guidance().unwrap().shots_done), (AppMode::Capturing, 5));
            }
        }
    }
    let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let max = |v: &[f64]| v.iter().fold(0f64, |m, e| m.max(*e));
    eprintln!(
        "bad noise: {} after {frames} frames; error of the turn since the tap, guidance / fused pose: worst {aim_worst:.2} / {fused_worst:.2} deg over {compared} frames; at the {} shots worst {:.2} / {:.2}, rms {:.2} / {:.2} deg",
        if app.mode() == AppMode::CaptureDone { "capture complete" } else { "capture incomplete" },
        aim_shots.len(),
        max(&aim_shots),
        max(&fused_shots),
        rms(&aim_shots),
        rms(&fused_shots),
    );
    assert!(compared > 100, "only {compared} frames compared");
    // The path is pre-recorded: its user visits the plan's views once, in the guidance's tour,
    // and never a repair view the guidance would add for a gap the held heading's error left.
    // With the rotation tour (sixth session) seed 2 ended one repair short (front 97.7 % seen);
    // since the held heading's image matches search the relative tilt and teach it the
    // gyroscope's bias (capture::aim_heading), its views land where they were taken and the
    // capture completes.
    let left = app.guidance().map(|g| (g.face_progress, g.shots_done, g.shots_total, g.next.map(|n| n.name)));
    eprintln!("left (faces seen, shots, of, next): {left:?}");
    assert_eq!(app.mode(), AppMode::CaptureDone, "the capture at bad noise did not complete in 55 s: {left:?}");
    assert!(aim_shots.len() >= 6, "{} shots compared", aim_shots.len());
    assert!(
        rms(&aim_shots) <= 0.75 * rms(&fused_shots),
        "the held heading is not closer to the truth than the fused pose at the shots: rms {:.2} vs {:.2} deg",
        rms(&aim_shots),
        rms(&fused_shots)
    );
}
