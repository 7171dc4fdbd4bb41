//! True north from the sun (issue 12): the virtual phone in quarry_01 (sun 10° high), its
//! sensors at `phone` noise (hard-iron offset, disturbances), the fusion filter with and without
//! the sun heading measurements. Docs: docs/pose.md "True north from the sun".

use crate::common;

use glam::DQuat;
use previz::capture::guided_path::simulate_capture_path;
use previz::capture::replay::{ReplayConfig, replay};
use previz::capture::{Assistant, CubeCapture, Mode};
use previz::light::sun_finder::azimuth_elevation;
use previz::pose::HeadingSource;
use previz::pose::hand_motion::UserPathParams;
use previz::pose::sun_heading::{heading_measurement, sight_sun_in_capture};
use previz::pose::sun_study::{SunCase, SunWorld, pooled_rms, run_case, run_case_every, sun_world};
use previz::pose::trace::TruthTrace;
use previz::scene::environment::load_equirect;
use previz::sensors::sim::{NoiseLevel, SimSite};
use std::path::Path;
use std::sync::Arc;

fn world() -> SunWorld {
    let map = load_equirect(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
    sun_world(&map, SimSite::default(), 512).unwrap()
}

#[test]
fn the_sun_in_view_takes_the_heading_error_below_a_third_of_a_degree() {
    let w = world();
    // The map's sun (elevation 10.02°, sun_finder's test) is at SPA's elevation for Bristol on
    // 2026-11-21 in the afternoon (SPA's azimuth there is south-west).
    assert!((w.sun_elevation_deg - 10.0).abs() < 0.5, "{}", w.sun_elevation_deg);
    assert!((180.0..260.0).contains(&w.sun_azimuth_deg), "{}", w.sun_azimuth_deg);
    let runs: Vec<_> = (0..3).map(|seed| run_case(&w, SunCase::InView, NoiseLevel::Phone, seed, 30.0).unwrap()).collect();
    for r in &runs {
        eprintln!("{r:?}");
        assert!(r.measurements * 2 >= r.frames, "the sun was measured in {} of {} frames", r.measurements, r.frames);
        assert_eq!(r.source, HeadingSource::Sun);
    }
    let (before, after) = pooled_rms(&runs);
    eprintln!("RMS heading error over 3 seeds: compass {before:.3}°, with the sun {after:.3}°");
    assert!(after <= 0.3, "with the sun {after}°");
    assert!(after < before / 3.0, "compass {before}°, with the sun {after}°");
}

#[test]
fn without_the_sun_the_magnetic_heading_is_kept_and_said() {
    let w = world();
    for seed in 0..2 {
        let r = run_case(&w, SunCase::Hidden, NoiseLevel::Phone, seed, 20.0).unwrap();
        assert_eq!(r.measurements, 0);
        assert_eq!(r.rms_after_deg, r.rms_before_deg);
        assert!(matches!(r.source, HeadingSource::Magnetometer | HeadingSource::GyroOnly), "{:?}", r.source);
    }
}

/// The table in docs/pose.md: `cargo test --test integration sun_heading:: -- --ignored --nocapture` (the dev profile is optimised).
#[test]
#[ignore]
fn sun_heading_study() {
    let w = world();
    println!(
        "sun world: {} UTC, SPA azimuth {:.2}°, elevation {:.2}°, map heading {:.2}°",
        w.time, w.sun_azimuth_deg, w.sun_elevation_deg, w.map_heading_deg
    );
    println!("| noise | case | seeds | RMS compass (°) | RMS with sun (°) | max per-seed with sun (°) | frames with a measurement |");
    println!("|---|---|---|---|---|---|---|");
    for noise in [NoiseLevel::Phone, NoiseLevel::Bad] {
        for case in [SunCase::InView, SunCase::Hidden] {
            let runs: Vec<_> = (0..20).map(|seed| run_case(&w, case, noise, seed, 40.0).unwrap()).collect();
            let per_seed: Vec<String> = runs.iter().map(|r| format!("{:.2}", r.rms_after_deg)).collect();
            eprintln!("{} {}: per seed with sun {}", noise.name(), case.name(), per_seed.join(" "));
            let (before, after) = pooled_rms(&runs);
            let worst = runs.iter().map(|r| r.rms_after_deg).fold(0.0, f64::max);
            let (m, f) = runs.iter().fold((0, 0), |(m, f), r| (m + r.measurements, f + r.frames));
            println!("| {} | {} | 20 | {before:.2} | {after:.2} | {worst:.2} | {m}/{f} |", noise.name(), case.name());
        }
    }
}

#[test]
#[ignore]
fn sun_heading_series() {
    let w = world();
    let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(9);
    let r = run_case(&w, SunCase::InView, NoiseLevel::Phone, seed, 40.0).unwrap();
    for (t, b, a, m, d) in &r.series {
        println!("{t:5.1} compass {b:7.3} sun {a:7.3} measured {m:?} disturbed {d}");
    }
}

/// Heading error (degrees) of the capture as placed in the world, at the sun: the true sun
/// direction seen by the shot that has it nearest its centre, put back into the world through
/// that shot's recorded (estimated, then sun-calibrated) pose, minus the true azimuth.
fn placed_sun_error_deg(capture: &CubeCapture, trace: &TruthTrace, sun: glam::Vec3) -> f64 {
    let sun = sun.as_dvec3();
    let shot = capture
        .meta
        .shots
        .iter()
        .max_by(|a, b| {
            let c = |t: f64| (trace.orientation_at(t) * glam::DVec3::NEG_Z).dot(sun);
            c(a.t).total_cmp(&c(b.t))
        })
        .unwrap();
    let [w, x, y, z] = shot.pose_wxyz;
    let placed = DQuat::from_xyzw(x, y, z, w) * (trace.orientation_at(shot.t).inverse() * sun);
    let az = |d: glam::DVec3| f64::from(azimuth_elevation(d.as_vec3()).0).to_degrees();
    let e = az(placed) - az(sun);
    (e + 180.0).rem_euclid(360.0) - 180.0
}

fn sun_capture(env: &Arc<previz::scene::CubeMap>, w: &SunWorld, seed: u64) -> (CubeCapture, TruthTrace) {
    let cfg = ReplayConfig {
        mode: Mode::Stitch,
        vfov_deg: 100.0,
        width: 640,
        height: 480,
        face_size: 256,
        noise: NoiseLevel::Phone,
        seed,
        score: false,
        render_threads: 2,
        clock: Some(w.time),
        ..Default::default()
    };
    let targets: Vec<_> = Assistant::new(cfg.assistant().unwrap()).unwrap().targets().into_iter().cloned().collect();
    let path = simulate_capture_path(seed, &targets, &UserPathParams::default()).unwrap();
    let trace = TruthTrace::new(path.samples).unwrap();
    let r = replay(env, &trace, &cfg).unwrap();
    (r.capture.unwrap_or_else(|| panic!("seed {seed}: {:?}", r.incomplete)), trace)
}

#[test]
fn a_capture_with_the_sun_in_it_points_at_true_north() {
    let w = world();
    let mut sq = (0.0, 0.0);
    for seed in 0..2 {
        let (capture, trace) = sun_capture(&w.env, &w, seed);
        let h = capture.meta.heading.clone().unwrap();
        assert_eq!(h.source, "sun", "{h:?}");
        let turn = h.sun_correction_deg.unwrap();
        let after = placed_sun_error_deg(&capture, &trace, w.sun_enu);
        let before = after - turn;
        eprintln!("seed {seed}: capture heading error at the sun {before:.3}° -> {after:.3}° ({h:?})");
        assert!(after.abs() <= 0.3, "seed {seed}: {after}°");
        assert!(h.accuracy_deg.unwrap() < 0.3);
        sq.0 += before * before;
        sq.1 += after * after;
    }
    eprintln!("RMS over 2 seeds: {:.3}° -> {:.3}°", (sq.0 / 2.0f64).sqrt(), (sq.1 / 2.0f64).sqrt());
}

#[test]
fn a_capture_under_clouds_keeps_the_magnetic_heading_and_says_so() {
    // quarry_01 with its sun replaced by the sky around it (the sun finder's removal).
    let map = load_equirect(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
    let samples = previz::light::samples::from_equirect(&map, 0.0);
    let sun = previz::light::sun_finder::find_sun(&samples, &Default::default()).unwrap();
    let mut pixels = map.pixels().to_vec();
    previz::light::samples::apply_to_equirect(&mut pixels, &sun.removal());
    let cloudy = previz::scene::environment::Equirect::new(map.width(), map.height(), pixels).unwrap();
    let w = world();
    let env = Arc::new(cloudy.to_cube(512, w.map_heading_deg.to_radians() as f32));
    let (capture, _) = sun_capture(&env, &w, 0);
    let h = capture.meta.heading.clone().unwrap();
    assert_eq!(h.source, "magnetometer", "{h:?}");
    assert_eq!(h.sun_correction_deg, None);
    assert!(h.note.contains("no sun in the capture") && h.note.contains("magnetic heading kept"), "{}", h.note);
}

/// Captures with the sun (docs/pose.md): `cargo test --test integration sun_heading::capture_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn capture_study() {
    let w = world();
    let (mut before, mut after, mut n, mut worst) = (0.0, 0.0, 0, 0f64);
    for seed in 0..10 {
        let (capture, trace) = sun_capture(&w.env, &w, seed);
        let h = capture.meta.heading.clone().unwrap();
        let a = placed_sun_error_deg(&capture, &trace, w.sun_enu);
        let b = a - h.sun_correction_deg.unwrap_or(0.0);
        println!("seed {seed}: {} {b:.3}° -> {a:.3}° (1σ {:?})", h.source, h.accuracy_deg);
        before += b * b;
        after += a * a;
        worst = worst.max(a.abs());
        n += 1;
    }
    println!(
        "captures, phone, 100° stitch, {n} seeds: RMS {:.3}° -> {:.3}°, worst {worst:.3}°",
        (before / n as f64).sqrt(),
        (after / n as f64).sqrt()
    );
}

/// How often a sun frame is needed at `bad` noise: `cargo test --test integration sun_heading::bad_noise_frame_rate -- --ignored --nocapture`.
#[test]
#[ignore]
fn bad_noise_frame_rate() {
    let w = world();
    println!("| frame period (s) | seeds | RMS compass (°) | RMS with sun (°) | worst seed (°) |");
    println!("|---|---|---|---|---|");
    for period in [0.5, 0.2, 0.1, 0.05] {
        let runs: Vec<_> = (0..10).map(|seed| run_case_every(&w, SunCase::InView, NoiseLevel::Bad, seed, 40.0, period).unwrap()).collect();
        let (before, after) = pooled_rms(&runs);
        let worst = runs.iter().map(|r| r.rms_after_deg).fold(0.0, f64::max);
        println!("| {period} | 10 | {before:.2} | {after:.2} | {worst:.2} |");
    }
}

#[test]
fn the_sun_is_found_in_an_hdr_captures_faces_where_8_bit_faces_clip_around_it() {
    // The fallback of the capture's north (no short-exposure frame): the sun in the faces. At
    // the capture's exposure the 8-bit faces clip the sky around the low sun into a wide blob
    // (rejected); the HDR faces measure that sky, and only the disc clips (at clip_radiance).
    let w = world();
    let cfg = ReplayConfig {
        mode: Mode::Stitch,
        vfov_deg: 100.0,
        width: 640,
        height: 480,
        face_size: 256,
        noise: NoiseLevel::None,
        seed: 0,
        score: false,
        render_threads: 2,
        hdr: true,
        ..Default::default()
    };
    let targets: Vec<_> = Assistant::new(cfg.assistant().unwrap()).unwrap().targets().into_iter().cloned().collect();
    let trace = TruthTrace::new(simulate_capture_path(0, &targets, &UserPathParams::default()).unwrap().samples).unwrap();
    let r = replay(&w.env, &trace, &cfg).unwrap();
    let cap = r.capture.unwrap();
    let href = cap.meta.reference_heading_deg.to_radians();
    let clip = cap.meta.hdr.as_ref().unwrap().clip_radiance;
    let seen = sight_sun_in_capture(&cap.to_cube_map(), href, clip).expect("the sun in the HDR faces");
    let m = heading_measurement(&seen, w.sun_enu, 0.5f64.to_radians()).expect("at SPA's elevation");
    let truth = r.reference_heading_error_deg.unwrap();
    eprintln!("HDR faces: measured {:.3}° (1σ {:.3}°), reference heading error {truth:.3}°", m.error.to_degrees(), m.sigma.to_degrees());
    assert!((m.error.to_degrees() - truth).abs() < 0.3, "measured {} vs {truth}", m.error.to_degrees());
    let mut eight_bit = cap.clone();
    eight_bit.hdr = None;
    assert!(sight_sun_in_capture(&eight_bit.to_cube_map(), href, [1.0; 3]).is_none(), "the 8-bit faces' clipped blob is rejected");
}

/// One live session on the virtual phone (`live::sun_north`, the app's call): the user looks
/// around near the sun (`live::look_around_path`: heading ±20°, pitch ±4°, hand shake) for
/// `secs` seconds at `hz` camera frames a second, the sensors at `phone` noise with a hard-iron
/// offset of `hard_iron_ut` per axis (1σ, in the device frame), two filters fed the same
/// readings: the compass alone, and with the sun from short exposure frames. Returns the RMS
/// heading errors from 10 s on (degrees) and the short frames taken and measured.
fn live_sun_run(w: &SunWorld, seed: u64, hard_iron_ut: f64, secs: f64, hz: f64) -> (f64, f64, usize, usize) {
    use previz::camera::FrameSource;
    use previz::camera::exposure::ExposureMode;
    use previz::camera::sim::{SimSequence, SimSettings, VirtualPhone};
    use previz::live::sun_north::SunNorth;
    use previz::pose::frames::{angle_difference, heading_pitch_roll};
    use previz::pose::{FusionConfig, OrientationEstimator, OrientationFilter};
    use previz::sensors::SensorSource;
    use previz::sensors::sim::{SimConfig, SimSensors};
    let truth = previz::live::look_around_path(w.sun_azimuth_deg - 15.0, w.sun_elevation_deg - 3.0, secs, seed).unwrap();
    let (width, height, vfov) = (320, 240, 50.0);
    let phone =
        VirtualPhone::new(w.env.clone(), &SimSettings { width, height, vfov_deg: vfov, exposure: ExposureMode::default() }).unwrap();
    let poses = (0..=(secs * hz) as usize).map(|k| k as f64 / hz).map(|t| (t, truth.orientation_at(t).as_quat())).collect();
    let mut camera = SimSequence::new(phone, poses).unwrap();
    let mut cfg = SimConfig::new(NoiseLevel::Phone, seed);
    cfg.site = w.site;
    cfg.noise.hard_iron = hard_iron_ut;
    let rotation = cfg.rotation;
    let mut sensors = SimSensors::with_config(truth.clone(), cfg).unwrap();
    let mut compass = OrientationFilter::new(FusionConfig::default());
    compass.set_reference(sensors.magnetic_reference());
    let mut with_sun = compass.clone();
    let mut sun_north = SunNorth::new();
    let (mut sq, mut n) = ([0.0f64; 2], 0usize);
    let mut readings = Vec::new();
    while let Some(frame) = camera.next_frame().unwrap() {
        let t = frame.t;
        readings.clear();
        sensors.poll(t, &mut readings).unwrap();
        for r in &readings {
            compass.update(r).unwrap();
            with_sun.update(r).unwrap();
        }
        let pose = with_sun.pose(rotation);
        sun_north.frame(t, pose.as_ref(), w.sun_enu, (width, height), vfov, &mut camera, &mut with_sun).unwrap();
        let (Some(pc), Some(ps)) = (compass.pose(rotation), with_sun.pose(rotation)) else { continue };
        if t >= 10.0 {
            let h = heading_pitch_roll(truth.orientation_at(t)).heading;
            for (s, q) in sq.iter_mut().zip([pc.q, ps.q]) {
                *s += angle_difference(heading_pitch_roll(q.as_dquat()).heading, h).to_degrees().powi(2);
            }
            n += 1;
        }
    }
    let rms = sq.map(|s| (s / n.max(1) as f64).sqrt());
    (rms[0], rms[1], sun_north.frames, sun_north.measurements)
}

#[test]
fn the_live_app_takes_a_short_frame_of_the_sun_and_corrects_the_compass() {
    // A 4 µT hard-iron offset per axis (the `phone` preset has 1 µT) that the filter's
    // calibration cannot learn from a look around a point (its readings span too little of the
    // sphere): a steady compass error of degrees. The live sun frames take it to a fraction of
    // a degree.
    let w = world();
    for seed in 0..2 {
        let (before, after, frames, measured) = live_sun_run(&w, seed, 4.0, 30.0, 10.0);
        eprintln!("seed {seed}: heading RMS compass {before:.3}°, with the live sun {after:.3}° ({measured} of {frames} short frames)");
        assert!(measured * 2 >= frames && frames >= 10, "{measured} of {frames}");
        assert!(after <= 0.3, "seed {seed}: with the sun {after}°");
        assert!(after < before / 3.0, "seed {seed}: compass {before}°, with the sun {after}°");
    }
}

/// The live rows of docs/pose.md: `cargo test --test integration sun_heading::live_sun_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn live_sun_study() {
    let w = world();
    println!(
        "| hard-iron offset (µT, 1σ per axis) | seeds | RMS compass (°) | RMS with the live sun (°) | worst seed (°) | short frames measured |"
    );
    println!("|---|---|---|---|---|---|");
    for hard_iron in [1.0, 4.0] {
        let runs: Vec<_> = (0..10).map(|seed| live_sun_run(&w, seed, hard_iron, 40.0, 10.0)).collect();
        let rms = |f: fn(&(f64, f64, usize, usize)) -> f64| (runs.iter().map(|r| f(r).powi(2)).sum::<f64>() / runs.len() as f64).sqrt();
        let worst = runs.iter().map(|r| r.1).fold(0.0, f64::max);
        let (m, f) = runs.iter().fold((0, 0), |(m, f), r| (m + r.3, f + r.2));
        println!("| {hard_iron} | 10 | {:.2} | {:.2} | {worst:.2} | {m}/{f} |", rms(|r| r.0), rms(|r| r.1));
    }
}

#[test]
fn the_live_session_calibrates_its_heading_from_the_sun_in_its_camera_frame() {
    // The app's one call (LiveSession::advance -> live::sun_north): the simulated session looks
    // 10° left of the quarry map's sun (the virtual phone's world is the map, so the map's sun
    // stands in for SPA's), sensors at `phone` noise.
    use previz::live::{LiveConfig, LiveSession};
    use previz::setup::load_inputs;
    let toml = "width = 240\nheight = 160\nenvironment = \"hdri/polyhaven_1k/quarry_01_1k.hdr\"\nmodel = \"meshes/stanford-bunny.obj\"\n";
    let inputs = load_inputs(&common::scene(toml), false).unwrap();
    let sun = previz::light::sun_finder::find_sun(&previz::light::samples::from_cube(&inputs.env), &Default::default()).unwrap().dir;
    let (az, el) = azimuth_elevation(sun);
    let (az, el) = (f64::from(az).to_degrees(), f64::from(el).to_degrees());
    let s = common::scene(&format!("{toml}[camera]\nheading = {}\npitch = {}\nvfov = 50.0\n", az - 10.0, el - 3.0));
    let cfg = LiveConfig { duration_s: 12.0, noise: NoiseLevel::Phone, seed: 3, ..LiveConfig::on_phone(afternoon()) };
    let mut session = LiveSession::simulated(common::gpu(), Arc::new(inputs.env.clone()), &inputs.model, &s, cfg).unwrap();
    let mut last = None;
    let mut errors = Vec::new();
    while let Some(f) = session.advance(common::gpu()).unwrap() {
        if f.t >= 2.0 {
            errors.push(f.pose_error_deg.unwrap());
        }
        last = Some(f);
    }
    let f = last.unwrap();
    let n = session.sun_north();
    eprintln!(
        "{} short frames, {} measured, last {:?}; pose error at 2 s {:.2}°, at the end {:.2}°",
        n.frames,
        n.measurements,
        n.last,
        errors[0],
        errors[errors.len() - 1]
    );
    assert!(n.measurements >= 5 && n.measurements * 2 >= n.frames, "{} of {}", n.measurements, n.frames);
    assert_eq!(f.pose.unwrap().heading_source, HeadingSource::Sun);
    assert!(f.pose_error_deg.unwrap() < 1.0, "{:?}", f.pose_error_deg);
}

/// Any afternoon instant: the simulated session's sun is the map's, whatever the clock.
fn afternoon() -> chrono::DateTime<chrono::Utc> {
    chrono::DateTime::parse_from_rfc3339("2026-11-21T14:00:00Z").unwrap().with_timezone(&chrono::Utc)
}

/// The short frame's exposure (docs/capture.md, the live sun): the sun sighted in quarry_01 at
/// 28 views around it (heading ±18°, pitch −6..+3° about the sun; exact poses; the virtual
/// phone auto-exposed for each view), the short frame at −4 .. 0 EV of that exposure:
/// `cargo test --test integration sun_heading::short_frame_exposure_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn short_frame_exposure_study() {
    use previz::camera::exposure::ExposureMode;
    use previz::camera::sim::{SimSettings, VirtualPhone};
    use previz::pose::frames::from_heading_pitch_roll;
    use previz::pose::sun_heading::sight_sun;
    let w = world();
    let settings = SimSettings { width: 320, height: 240, vfov_deg: 50.0, exposure: ExposureMode::default() };
    let mut phone = VirtualPhone::new(w.env.clone(), &settings).unwrap();
    println!("| short frame | views with a measurement | RMS heading error (°) | worst (°) |");
    println!("|---|---|---|---|");
    let mut t = 0.0;
    for ev in [-4.0f32, -3.0, -2.0, -1.0, 0.0] {
        let (mut n, mut seen, mut sq, mut worst) = (0, 0, 0.0f64, 0.0f64);
        for dh in [-18.0, -12.0, -6.0, 0.0, 6.0, 12.0, 18.0] {
            for dp in [-6.0, -3.0, 0.0, 3.0] {
                let q =
                    from_heading_pitch_roll((w.sun_azimuth_deg + dh).to_radians(), (w.sun_elevation_deg + dp).to_radians(), 0.0).as_quat();
                // A stream frame (10 s after the last: converged) sets the exposure.
                t += 10.0;
                phone.render(q, t).unwrap();
                let image = phone.render_with_exposure(q, phone.exposure().unwrap() * ev.exp2()).unwrap();
                n += 1;
                if let Some(m) = sight_sun(&image, 50.0, q).unwrap().and_then(|s| heading_measurement(&s, w.sun_enu, 0.0)) {
                    seen += 1;
                    sq += m.error.to_degrees().powi(2);
                    worst = worst.max(m.error.to_degrees().abs());
                }
            }
        }
        println!("| {ev:+.0} EV | {seen}/{n} | {:.3} | {worst:.3} |", (sq / seen.max(1) as f64).sqrt());
    }
}
