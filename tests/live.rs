//! The live frame loop (`live::LiveSession`, `previz live`): the camera image is the
//! background, the model is drawn at the estimated pose, the sun is the published SPA position
//! for the place and instant, and the night has no sunlight.

mod common;

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
    let s = scene(SCENE);
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
        assert!((session.params().lighting.sun_dir - expected).length() < 1e-5);
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
}

#[test]
fn no_sunlight_at_night_and_noisy_sensors_stay_within_a_few_degrees() {
    let s = scene(SCENE);
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
    for stage in ["camera frame", "sensors + fusion", "sun (SPA)", "compositor (GPU)", "whole frame"] {
        assert!(table.contains(stage), "{stage} missing from:\n{table}");
    }

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
    // -displayfd: Xvfb picks a free display and writes its number once it accepts connections,
    // so the test waits for exactly that (a generous deadline guards against a hung server).
    let mut xvfb = std::process::Command::new("Xvfb")
        .args(["-displayfd", "1", "-screen", "0", "640x480x24", "-nolisten", "tcp"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("Xvfb (apt-get install xvfb; .ci/run installs it)");
    let stdout = xvfb.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
        let _ = tx.send(line);
    });
    let number = rx.recv_timeout(std::time::Duration::from_secs(60)).expect("Xvfb did not report a display within 60 s");
    let number: u32 = number.trim().parse().unwrap_or_else(|_| panic!("Xvfb exited before it was ready (it printed {number:?})"));
    let display = format!(":{number}");
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
    let _ = xvfb.kill();
    let _ = xvfb.wait();
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
