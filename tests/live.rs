//! The live frame loop (`live::LiveSession`, `previz live`): the camera image is the
//! background, the model is drawn at the estimated pose, the sun is the published SPA position
//! for the place and instant, and the night has no sunlight.

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use common::{data, gpu, scene};
use previz::camera::exposure::ExposureMode;
use previz::camera::sim::{SimSettings, VirtualPhone};
use previz::live::{LiveConfig, LiveSession, look_around_path};
use previz::render::Layer;
use previz::sensors::sim::NoiseLevel;
use previz::setup::{exposure, load_inputs};
use std::sync::Arc;

const SCENE: &str = "width = 240\nheight = 160\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
[camera]\nheading = 90.0\npitch = -5.0\n";
/// The same scene with its environment declared a capture of the session's place and moment:
/// the model is lit by SPA's sun for the clock.
fn captured_here() -> String {
    format!("{SCENE}[env]\ncaptured_here = true\n")
}

fn config(time: &str, noise: NoiseLevel) -> LiveConfig {
    LiveConfig {
        // NREL SPA's published test case: Golden, Colorado (Reda & Andreas 2004, Table A4.1).
        lat_deg: 39.742476,
        lon_deg: -105.1786,
        start: chrono::DateTime::parse_from_rfc3339(time).unwrap().with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: 4.0,
        noise,
        seed: 5,
    }
}

#[test]
fn camera_image_is_the_background_model_at_the_pose_sun_from_spa() {
    let s = scene(&captured_here());
    let inputs = load_inputs(&s, false).unwrap();
    let env = Arc::new(inputs.env);
    let cfg = config("2003-10-17T12:30:30-07:00", NoiseLevel::None);
    let mut session = LiveSession::simulated(gpu(), env.clone(), &inputs.model, &s, cfg.clone()).unwrap();
    // The same camera, independently: the virtual phone at the true pose of the same user path.
    let truth = look_around_path(s.camera.heading, s.camera.pitch, cfg.duration_s, cfg.seed).unwrap();
    let settings = SimSettings { width: s.width, height: s.height, vfov_deg: s.camera.vfov as f32, exposure: ExposureMode::Fixed(1.0) };
    let phone = VirtualPhone::new(env.clone(), &settings).unwrap();
    let e = exposure(&s, &env);

    let mut frames = 0;
    let (mut lit_before, mut suns_taken) = (None, 0);
    while let Some(f) = session.advance(gpu()).unwrap() {
        frames += 1;
        // The published SPA values for this place and instant (elevation 1830 m, 820 mbar, 11 °C,
        // ΔT 67 s there; sea level and standard-atmosphere defaults here move them < 0.05°).
        if frames == 1 {
            assert!((f.sun.azimuth_deg - 194.34024).abs() < 0.05, "azimuth {}", f.sun.azimuth_deg);
            assert!((f.sun.apparent_zenith_deg - 50.11162).abs() < 0.05, "zenith {}", f.sun.apparent_zenith_deg);
        }
        let (z, a) = (f.sun.apparent_zenith_deg.to_radians(), f.sun.azimuth_deg.to_radians());
        let expected = glam::Vec3::new((z.sin() * a.sin()) as f32, (z.sin() * a.cos()) as f32, z.cos() as f32);
        // The frame lights with SPA's sun as it was when it last moved by a step
        // (setup::light::sun_step): within a step of this instant's, and this instant's on the
        // frames where the session took it again.
        let lit = session.params().lighting.sun_dir;
        let off = previz::setup::light::sun_turn(lit, expected);
        assert!(off <= f64::from(previz::setup::light::MAX_SUN_STEP_RAD) * 1.001, "the frame's sun is {off} rad from SPA's");
        if lit_before != Some(lit) {
            assert!((lit - expected).length() < 1e-5);
            suns_taken += 1;
            lit_before = Some(lit);
        }
        assert!(f.sunlight > 0.5, "daylight at 12:30");
        if f.t < 2.0 || frames % 20 != 0 {
            continue;
        }
        // Without sensor noise the filter has settled on the true pose after two seconds.
        let err = f.pose_error_deg.expect("a pose after two seconds");
        assert!(err < 1.0, "t = {}: pose error {err}°", f.t);
        let r = session.render(gpu()).unwrap();
        let camera = phone.render_with_exposure(truth.orientation_at(f.t).as_quat(), e).unwrap();
        // Away from the model (top rows: sky and trees) the composite is the camera image.
        let w = r.width as usize;
        let mut max_diff = 0;
        for i in 0..(w * 20) {
            for c in 0..3 {
                max_diff = max_diff.max((i32::from(r.rgba[4 * i + c]) - i32::from(camera.pixels[4 * i + c])).abs());
            }
        }
        assert!(max_diff <= 2, "t = {}: background differs from the camera image by {max_diff}", f.t);
        // And the model is there, where the estimated pose puts it: where the model layer is
        // fully covered, the composite is not the camera image.
        let model = session.render_layer(gpu(), Layer::Model).unwrap();
        let covered: Vec<usize> = (0..w * r.height as usize).filter(|&i| model.rgba[4 * i + 3] == 255).collect();
        let changed = covered
            .iter()
            .filter(|&&i| (0..3).any(|c| (i32::from(r.rgba[4 * i + c]) - i32::from(camera.pixels[4 * i + c])).abs() > 8))
            .count();
        assert!(covered.len() > 500, "t = {}: the model covers only {} pixels", f.t, covered.len());
        assert!(changed * 10 >= covered.len() * 7, "t = {}: {changed} of {} model pixels differ from the camera", f.t, covered.len());
    }
    assert_eq!(frames, 121, "4 s at 30 frames per second, both ends included");
    // The sun moved about 0.017° in the 4 s (15°/h at the equinox, less by the cosine of the
    // declination): at least one step of at most 0.01° after the first frame's sun, and far
    // fewer suns than frames.
    assert!((2..=20).contains(&suns_taken), "{suns_taken} suns taken in 121 frames");
}

#[test]
fn no_sunlight_at_night_and_noisy_sensors_stay_within_a_few_degrees() {
    let s = scene(&captured_here());
    let inputs = load_inputs(&s, false).unwrap();
    // Local midnight in Golden: the sun is far below the horizon.
    let cfg = config("2003-10-17T00:30:00-07:00", NoiseLevel::Phone);
    let mut session = LiveSession::simulated(gpu(), Arc::new(inputs.env), &inputs.model, &s, cfg).unwrap();
    let mut worst_late = 0.0f64;
    while let Some(f) = session.advance(gpu()).unwrap() {
        assert!(f.sun.apparent_elevation_deg() < -30.0);
        assert_eq!(f.sunlight, 0.0);
        assert_eq!(session.params().lighting.sunlight, 0.0);
        if f.t > 3.0 {
            worst_late = worst_late.max(f.pose_error_deg.unwrap());
        }
    }
    // Phone-grade noise: the magnetometer's uncalibrated hard-iron offset dominates (docs/pose.md).
    assert!(worst_late < 15.0, "pose error {worst_late}° with phone noise");
}

#[test]
fn headless_cli_writes_frames_and_rejects_bad_flags() {
    let dir = tempdir("live", "ok");
    let env = data("cubemaps/humus_Park2_512");
    let model = data("meshes/stanford-bunny.obj");
    let (env, model) = (env.to_str().unwrap(), model.to_str().unwrap());
    let common_args = ["live", "--env", env, "--model", model, "--width", "160", "--height", "120", "--noise", "none"];
    let args: Vec<&str> =
        common_args.iter().copied().chain(["--time", "2026-06-21T12:00:00Z", "--frames", "3", "-o", ".", "--json"]).collect();
    let out = previz(&dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let names: Vec<String> = files(&dir).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["frame_0000.png", "frame_0001.png", "frame_0002.png"]);
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 3);
    assert!(lines[2]["sun_elevation_deg"].as_f64().unwrap() > 0.0);

    // The stage-by-stage benchmark runs and reports every stage.
    let out = previz(
        &dir,
        &["bench", "live", "--env", env, "--model", model, "--width", "96", "--height", "64", "--frames", "2", "--warmup", "1"],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8_lossy(&out.stdout);
    for stage in ["camera frame", "sensors + fusion", "sun (SPA)", "compositor (GPU)", "whole frame", "model turning", "sky changing"] {
        assert!(table.contains(stage), "{stage} missing from:\n{table}");
    }
    // --json: the same stages, the ratio, and the profile's passes by name (GPU ms).
    let out = previz(
        &dir,
        &["bench", "live", "--env", env, "--model", model, "--width", "96", "--height", "64", "--frames", "2", "--warmup", "1", "--json"],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["stages"].as_array().unwrap().len(), previz::bench::live::STAGES.len(), "{v}");
    assert!(v["compositor_over_floor"].as_f64().unwrap() > 0.0, "{v}");
    for pass in ["total_ms", "background_ms", "model_ms", "ground_ms"] {
        assert!(v["profile"][pass].as_f64().is_some_and(|ms| ms > 0.0), "{pass}: {v}");
    }
    // What they drew (lavapipe's pipeline statistics): the background's one triangle shades
    // each of the 96×64 pixels once (in 4×4 blocks: fewer than twice as many), the model and
    // the ground something.
    let counts = &v["profile"]["counts"];
    let fragments = |pass: &str| counts[pass]["fragments"].as_u64().unwrap_or_else(|| panic!("no {pass} count in {v}"));
    assert!((96 * 64..2 * 96 * 64).contains(&fragments("background")), "{counts}");
    // Its one triangle reaches past the screen; clipping cuts it into a few.
    assert!(counts["background"]["triangles"].as_u64().is_some_and(|t| (1..=4).contains(&t)), "{counts}");
    assert!(fragments("model") > 0 && fragments("ground") > 0, "{counts}");
    assert!(table.contains("the profile's passes drew"), "{table}");

    let bad = tempdir("live", "bad");
    // -o creates a missing folder, but not over a file.
    std::fs::write(bad.join("a_file"), b"not a folder").unwrap();
    let before = files(&bad);
    for (extra, needle) in [
        (vec!["--lat", "91", "--frames", "2", "-o", "."], "--lat"),
        (vec!["--time", "noon", "--frames", "2", "-o", "."], "--time"),
        (vec!["--fps", "0", "--frames", "2", "-o", "."], "--fps"),
        (vec!["--frames", "2", "-o", "a_file"], "a_file"),
        (vec!["--frames", "2"], "--output"),
    ] {
        let args: Vec<&str> = common_args.iter().copied().chain(extra).collect();
        assert_clean_failure(&previz(&bad, &args), &bad, &before, &[needle]);
    }
}

/// The app in its window under a virtual X server, scripted as a user would go through it: the
/// live view opens and presents (lavapipe), capture mode with the simulated user following the
/// assistant, composite with the new capture, the shutter, quit. It ends with the capture folder
/// and the exported files present. CI installs Xvfb (`.ci/run`).
#[test]
fn window_runs_a_scripted_capture_composite_export_session_under_xvfb() {
    let xvfb = common::xvfb::Xvfb::start(640, 480);
    let display = xvfb.display.clone();
    let env = data("cubemaps/humus_Park2_512");
    let model = data("meshes/stanford-bunny.obj");
    let dir = tempdir("live", "window");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_previz"))
        .current_dir(&dir)
        .env("DISPLAY", &display)
        .args(["live", "--env", env.to_str().unwrap(), "--model", model.to_str().unwrap(), "--width", "320", "--height", "240"])
        .args(["--duration", "60", "--fps", "15", "--noise", "none", "--time", "2026-06-21T12:00:00Z"])
        .args(["--script", "capture,composite,shutter,quit"])
        .output()
        .unwrap();
    drop(xvfb);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "previz live failed under Xvfb: {stderr}");
    assert!(!stderr.contains("GPU error") && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("first frame presented"), "the window never presented a frame: {stderr}");
    let made = files(&dir);
    let find = |prefix: &str| made.iter().find(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix)).cloned();
    let capture = find("previz-capture-").unwrap_or_else(|| panic!("no capture folder in {made:?}"));
    previz::capture::load_capture(&capture).unwrap();
    let export = find("previz-export-").unwrap_or_else(|| panic!("no export folder in {made:?}"));
    for name in previz::live::export::FILES {
        assert!(export.join(name).is_file(), "{name} missing from {}", export.display());
    }
    let toml = std::fs::read_to_string(export.join("scene.toml")).unwrap();
    assert!(toml.contains(&*capture.file_name().unwrap().to_string_lossy()), "the capture lights the exported frame:\n{toml}");
}

#[test]
fn a_map_that_is_not_a_capture_of_here_and_now_lights_with_its_own_sun() {
    // Park2 is a downloaded map: its sun, not SPA's for the clock, lights the model, at noon and
    // at midnight alike (as `previz composite` does).
    let s = scene(SCENE);
    let inputs = load_inputs(&s, false).unwrap();
    let env = Arc::new(inputs.env);
    let (_, params, light) = previz::setup::compositor_and_light(gpu(), &s, &env, &inputs.model).unwrap();
    let map_sun = light.unit.map_sun_dir.expect("the 8-bit Park2 map has a (clipped) sun");
    assert!((params.lighting.sun_dir - map_sun).length() < 1e-6);
    for time in ["2003-10-17T12:30:30-07:00", "2003-10-17T00:30:00-07:00"] {
        let mut cfg = config(time, NoiseLevel::None);
        cfg.duration_s = 1.0;
        let mut session = LiveSession::simulated(gpu(), env.clone(), &inputs.model, &s, cfg).unwrap();
        for _ in 0..5 {
            let f = session.advance(gpu()).unwrap().expect("a camera frame");
            assert!((session.params().lighting.sun_dir - map_sun).length() < 1e-6, "{time}");
            assert_eq!(f.sunlight, params.lighting.sunlight, "{time}");
            // SPA's sun is still computed and reported: far from the map's at midnight.
            let spa_up = f.sun.apparent_elevation_deg() > 0.0;
            assert_eq!(spa_up, time.contains("12:30"));
        }
    }
    assert!(params.lighting.sunlight > 0.0);
}

/// The camera's truth: heading 90° (East, at the model) for 3 s, a half turn to 270° in 1 s,
/// West for 3 s; pitch −5°.
fn east_then_west() -> previz::pose::trace::TruthTrace {
    use previz::pose::frames::from_heading_pitch_roll;
    let samples = (0..=700)
        .map(|i| {
            let t = i as f64 / 100.0;
            let f = ((t - 3.0) / 1.0).clamp(0.0, 1.0);
            let heading = 90.0 + 180.0 * f * f * (3.0 - 2.0 * f);
            let q = from_heading_pitch_roll(heading.to_radians(), (-5f64).to_radians(), 0.0);
            previz::pose::trace::TruthSample { t, q, tap: false }
        })
        .collect();
    previz::pose::trace::TruthTrace::new(samples).unwrap()
}

/// Mean red and blue of the model layer where it covers the pixel (premultiplied: divided by
/// the coverage), and the pixels covered.
fn model_red_blue(session: &mut LiveSession) -> (f64, f64, usize) {
    let m = session.render_layer(gpu(), Layer::Model).unwrap();
    let (mut r, mut b, mut n) = (0.0, 0.0, 0usize);
    for p in m.rgba.chunks_exact(4).filter(|p| p[3] == 255) {
        r += f64::from(p[0]);
        b += f64::from(p[2]);
        n += 1;
    }
    (r / n.max(1) as f64, b / n.max(1) as f64, n)
}

/// Before any capture the app lights the model with the camera frame folded into a cube map on
/// the GPU (seed 004): the model's reflections and ambient follow what the camera sees, refreshed
/// as it turns, where the map lights the model's camera-facing side from behind the camera; the
/// refreshes allocate nothing; a capture replaces the fold.
#[test]
fn the_folded_camera_frame_lights_the_model_and_follows_the_camera() {
    let toml = "width = 160\nheight = 120\nmodel = \"meshes/icosphere-320.obj\"\nmethod = \"sh9-ggx\"\n\
                [camera]\nheading = 90.0\npitch = -5.0\n[material]\nspecular = 1.0\n";
    let s = scene(toml);
    let model = load_inputs(&s, false).unwrap().model;
    let env = Arc::new(common::east_red_west_blue(32));
    let mut cfg = config("2026-06-21T12:00:00Z", NoiseLevel::None);
    cfg.frame_hz = 15.0;
    cfg.duration_s = 7.0;
    let session_with = |fold: bool| {
        let sources = previz::live::Sources::simulated_along(env.clone(), &s, 1.0, &cfg, east_then_west()).unwrap();
        let mut session = LiveSession::new(gpu(), &env, &model, &s, cfg.clone(), sources).unwrap();
        if fold {
            session.fold_camera_into_environment();
        }
        session
    };
    // Runs the session through the path: the model's colour looking East at 2.9 s, and looking
    // West at the end with the model dragged in front of the camera (half a turn about the
    // camera's vertical).
    let run = |session: &mut LiveSession| {
        let mut east = None;
        let mut refreshes = Vec::new();
        while let Some(f) = session.advance(gpu()).unwrap() {
            // Each due fold applied before the next frame (the app lets it finish on its own).
            session.finish_fold(gpu()).unwrap();
            refreshes.push((f.t, session.fold_refreshes().map(|r| r.0)));
            if east.is_none() && f.t >= 2.9 {
                east = Some(model_red_blue(session));
            }
        }
        let p = &mut session.params_mut().placement;
        let camera = session_camera(&s);
        p.position = glam::Vec3::new(2.0 * camera.x - p.position.x, 2.0 * camera.y - p.position.y, p.position.z);
        (east.unwrap(), model_red_blue(session), refreshes)
    };
    fn session_camera(s: &previz::setup::scene_file::Scene) -> glam::Vec3 {
        glam::Vec3::new(0.0, 0.0, s.camera.height as f32)
    }

    let mut folded = session_with(true);
    let ((er, eb, en), (wr, wb, wn), refreshes) = run(&mut folded);
    assert!(en > 300 && wn > 300, "the model covers {en} / {wn} pixels");
    // Looking East the camera sees only red: the fold lights the model red; West: blue.
    assert!(er > 2.0 * eb, "looking East (red) the folded frame lights the model red: r {er:.1} b {eb:.1}");
    assert!(wb > 2.0 * wr, "looking West (blue) the folded frame lights the model blue: r {wr:.1} b {wb:.1}");
    // Folded at the first pose, then as the camera turned (10° steps through the half turn) and
    // every 2 s while it held still; never per frame while it held still.
    let count = |from: f64, to: f64| {
        let at = |t: f64| refreshes.iter().rfind(|(ft, _)| *ft <= t).and_then(|r| r.1).unwrap_or(0);
        at(to) - at(from)
    };
    assert!(count(3.0, 4.1) >= 8, "the half turn refreshed the fold {} times", count(3.0, 4.1));
    assert!(count(4.5, 6.5) <= 2, "holding still refreshed the fold {} times in 2 s", count(4.5, 6.5));

    // The map instead: its light on the model's camera-facing side comes from behind the
    // camera (West when looking East), whatever the camera sees.
    let mut mapped = session_with(false);
    let ((mer, meb, _), (mwr, mwb, _), _) = run(&mut mapped);
    assert!(meb > mer && mwr > mwb, "map-lit: East r {mer:.1} b {meb:.1}, West r {mwr:.1} b {mwb:.1}");

    // A capture replaces the fold for good: the environment is the capture's from then on.
    let grey = previz::scene::CubeMap { size: 32, faces: std::array::from_fn(|_| vec![[0.3; 3]; 32 * 32]) };
    folded.set_environment(gpu(), &grey, std::path::Path::new("capture"), 0.0).unwrap();
    assert_eq!(folded.fold_refreshes(), None);
    let (r, b, _) = model_red_blue(&mut folded);
    assert!((r - b).abs() < 0.1 * r.max(b), "grey capture: r {r:.1} b {b:.1}");
}

/// The model stands in front of where the phone points when the session starts, not where the
/// scene's camera heading (90°) would put it: the virtual phone held at two start headings.
#[test]
fn the_model_is_placed_where_the_phone_points_at_start() {
    let s = scene(SCENE);
    let inputs = load_inputs(&s, false).unwrap();
    let env = Arc::new(inputs.env);
    let mut cfg = config("2026-06-21T12:00:00Z", NoiseLevel::None);
    cfg.duration_s = 2.0;
    let scene_placement = previz::setup::camera_and_placement(&s, {
        let (c, _) = previz::setup::compositor_for(gpu(), &s, &env, &inputs.model).unwrap();
        c.model_bounds().unwrap()
    })
    .1;
    let bearing = |p: glam::Vec3| f64::from(p.x.atan2(p.y).to_degrees()).rem_euclid(360.0);
    assert!((bearing(scene_placement.position) - 90.0).abs() < 0.5, "the scene alone places it East");
    for start_heading in [20.0, 215.0] {
        let truth = look_around_path(start_heading, s.camera.pitch, cfg.duration_s, cfg.seed).unwrap();
        let sources = previz::live::Sources::simulated_along(env.clone(), &s, exposure(&s, &env), &cfg, truth).unwrap();
        let mut session = LiveSession::new(gpu(), &env, &inputs.model, &s, cfg.clone(), sources).unwrap();
        assert!(!session.placed());
        let first = loop {
            let f = session.advance(gpu()).unwrap().expect("a frame");
            if let Some(pose) = f.pose {
                break pose;
            }
        };
        assert!(session.placed());
        let placed = session.params().placement;
        // In front of the first pose's heading (the filter's first attitude, within a few
        // degrees of the phone's), at the scene's distance and scale.
        let heading = previz::pose::frames::heading_pitch_roll(first.q.as_dquat()).heading.to_degrees();
        let off = (bearing(placed.position) - heading + 540.0).rem_euclid(360.0) - 180.0;
        assert!(off.abs() < 1.0, "start {start_heading}°: model at bearing {:.1}°, pose heading {heading:.1}°", bearing(placed.position));
        let off_start = (bearing(placed.position) - start_heading + 540.0).rem_euclid(360.0) - 180.0;
        assert!(off_start.abs() < 5.0, "start {start_heading}°: model at bearing {:.1}°", bearing(placed.position));
        let horizontal = |p: glam::Vec3| glam::Vec2::new(p.x, p.y).length();
        assert!((horizontal(placed.position) - horizontal(scene_placement.position)).abs() < 0.05 * horizontal(scene_placement.position));
        assert_eq!(placed.scale, scene_placement.scale);
        // And it is on screen, near the middle: the model layer covers the centre column.
        let m = session.render_layer(gpu(), Layer::Model).unwrap();
        let (w, h) = (m.width as usize, m.height as usize);
        let covered = (0..h).filter(|&y| m.rgba[4 * (y * w + w / 2) + 3] > 0).count();
        assert!(covered > h / 10, "start {start_heading}°: the model covers {covered} rows of the centre column");
        // Later poses do not move it.
        for _ in 0..10 {
            session.advance(gpu()).unwrap().expect("a frame");
        }
        assert_eq!(session.params().placement, placed);
    }
}

/// A GPS fix moves the place the sun is computed for: a session set to a manual place (0° N,
/// 0° E) whose simulated phone reports fixes at Golden, Colorado takes Golden's sun — NREL SPA's
/// published azimuth and zenith there — from the first fix on.
#[test]
fn a_gps_fix_moves_the_place_the_sun_is_computed_for() {
    let s = scene(&captured_here());
    let inputs = load_inputs(&s, false).unwrap();
    let mut cfg = config("2003-10-17T12:30:30-07:00", NoiseLevel::None);
    cfg.duration_s = 1.0;
    let mut session = LiveSession::simulated(gpu(), Arc::new(inputs.env), &inputs.model, &s, cfg.clone()).unwrap();
    session.set_place(0.0, 0.0, cfg.start).unwrap();
    assert_eq!(session.location(), (0.0, 0.0));
    let f = session.advance(gpu()).unwrap().unwrap();
    let (lat, lon) = session.location();
    assert!((lat - 39.742476).abs() < 1e-9 && (lon + 105.1786).abs() < 1e-9, "the fix's place: {lat}, {lon}");
    assert!((f.sun.azimuth_deg - 194.34024).abs() < 0.05, "azimuth {}", f.sun.azimuth_deg);
    assert!((f.sun.apparent_zenith_deg - 50.11162).abs() < 0.05, "zenith {}", f.sun.apparent_zenith_deg);
}

#[test]
fn turning_the_model_does_not_make_a_frame_wait_for_the_grounds_rays() {
    // A model no other test loads: the device's model cache (its counts, its placement's ground
    // and the ground's worker) is shared by every test in this process, and a test drawing the
    // same model at another placement meanwhile would change what this one's frames find (it
    // was Suzanne until tests/app_session.rs opened Suzanne in the app too; it failed once).
    let s = scene(&SCENE.replace("meshes/stanford-bunny.obj", "meshes/teapot-blender-with-normals.obj"));
    let inputs = load_inputs(&s, false).unwrap();
    let cfg = config("2003-10-17T12:30:30-07:00", NoiseLevel::None);
    let mut session = LiveSession::simulated(gpu(), Arc::new(inputs.env), &inputs.model, &s, cfg).unwrap();
    session.advance(gpu()).unwrap().unwrap();
    session.render(gpu()).unwrap();
    let prepared = session.compositor().prepared_model().unwrap().clone();
    // The first placement has no map to keep: its frame waited for the rays and uploaded the map.
    let (waits, updates) = (prepared.ground_waits(), session.compositor().ground_sky_updates());
    assert_eq!((waits, updates), (1, 1));
    // A turn: the frame draws with the previous placement's map, its rays cast on the worker.
    session.params_mut().placement.rotation.z += 0.6;
    session.advance(gpu()).unwrap().unwrap();
    let during = session.render(gpu()).unwrap();
    assert_eq!(prepared.ground_waits(), waits, "the turned frame waited for the ground's rays");
    assert_eq!(session.compositor().ground_sky_updates(), updates, "the previous map stays until the new one is in");
    // The turn's map arrives; the next frame uploads it, and draws what a still of the same frame
    // (which waits for the current placement's rays) draws.
    prepared.finish_ground();
    let live = session.render(gpu()).unwrap();
    assert_eq!(session.compositor().ground_sky_updates(), updates + 1);
    let still = session.render_layer(gpu(), Layer::Composite).unwrap();
    assert!(live.rgba == still.rgba, "the live frame's ground differs from the still's");
    assert!(during.rgba != still.rgba, "the turned frame drew the previous placement's map");
    assert_eq!((prepared.ground_waits(), prepared.ground_rays_cast()), (waits, 2));
}
