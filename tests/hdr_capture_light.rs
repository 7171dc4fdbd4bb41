//! Light from an HDR capture (issue 9): even the capture's darkest bracket (−4 EV) clips the sun's
//! disc, so its float faces hold only part of the sun. setup::light reads the capture's clip
//! level (capture.json `hdr.clip_radiance`) and restores the sun above it; the same faces
//! without the capture's metadata are a float map trusted as it is (the behaviour before).
//! Judged against the source map the virtual phone captured: the sun's irradiance and direction
//! the light measures, and the FLIP of the bunny's composite over the same background.

use crate::common;

use common::data;
use previz::bench::accuracy::{flip_map, masked_mean};
use previz::capture::guided_path::simulate_capture_path;
use previz::capture::replay::{ReplayConfig, replay};
use previz::capture::{Assistant, Mode, save_capture};
use previz::cli::composite::{SceneArgs, scene_from_args};
use previz::colour::luminance_bt709;
use previz::pose::hand_motion::UserPathParams;
use previz::pose::trace::TruthTrace;
use previz::render::{Layer, Rendered};
use previz::scene::environment::load_environment;
use previz::sensors::sim::NoiseLevel;
use previz::setup::light::map_to_world;
use previz::setup::scene_file::Scene;
use previz::setup::{exposure, load_inputs, measure_environment};
use std::path::Path;
use std::sync::Arc;

/// A noiseless HDR capture of quarry_01 (clear sky, sun 10° up), as tests/capture_hdr.rs makes
/// them: 100° lens, 640×480 shots, 64 px faces.
fn hdr_capture() -> previz::capture::CubeCapture {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let seed = 2;
    let mut cfg = ReplayConfig {
        mode: Mode::Stitch,
        noise: NoiseLevel::None,
        seed,
        vfov_deg: 100.0,
        width: 640,
        height: 480,
        face_size: 64,
        render_threads: 2,
        hdr: true,
        ..ReplayConfig::default()
    };
    cfg.score = false;
    let targets: Vec<_> = Assistant::new(cfg.assistant().unwrap()).unwrap().targets().into_iter().cloned().collect();
    let trace = TruthTrace::new(simulate_capture_path(seed, &targets, &UserPathParams::default()).unwrap().samples).unwrap();
    let r = replay(&env, &trace, &cfg).unwrap();
    assert!(r.incomplete.is_none(), "{:?}", r.incomplete);
    r.capture.unwrap()
}

/// The reference scene quarry_bunny (tests/reference/scenes) with `environment`, turned by
/// `heading` degrees, at `exposure`, over `background`.
fn bunny_scene(environment: &Path, heading: f64, exposure: Option<f64>, background: Option<&Path>) -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/scenes/quarry_bunny.toml");
    let (mut scene, _) = scene_from_args(&SceneArgs { scene: Some(root), ..Default::default() }, None).unwrap();
    scene.environment = Some(environment.to_path_buf());
    scene.env.heading = heading;
    scene.env.exposure = exposure;
    scene.background = background.map(Path::to_path_buf);
    scene
}

struct Lit {
    /// Sun irradiance (luminance, the map's units), the sun's world direction, the turbidity a
    /// restored sun was given, and the sun's share of the ground's light read from the ground.
    sun: f32,
    dir: glam::Vec3,
    turbidity: Option<f32>,
    ground: Option<f32>,
    composite: Rendered,
}

fn light_and_render(scene: &Scene) -> Lit {
    let inputs = load_inputs(scene, false).unwrap();
    let light = measure_environment(scene, &inputs.env).unwrap();
    let dir = map_to_world(light.sun_dir.expect("a sun"), (scene.env.heading as f32).to_radians());
    Lit {
        sun: luminance_bt709(light.sun_irradiance),
        dir,
        turbidity: light.turbidity,
        ground: light.ground_sun_over_sky,
        composite: common::render_with(scene, &inputs, Layer::Composite),
    }
}

fn rgb(r: &Rendered) -> Vec<u8> {
    r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

#[test]
fn an_hdr_capture_lights_the_model_as_its_source_map_does() {
    let dir = common::cli::tempdir("hdr_capture_light", "quarry");
    let capture = hdr_capture();
    let folder = dir.join("capture");
    save_capture(&capture, &folder).unwrap();
    // The same float faces without capture.json: a float map trusted as it is.
    let faces_only = dir.join("faces_only");
    std::fs::create_dir_all(&faces_only).unwrap();
    for f in capture.meta.hdr.as_ref().unwrap().files.iter() {
        std::fs::copy(folder.join(f), faces_only.join(f)).unwrap();
    }
    let heading = capture.meta.reference_heading_deg;
    // The source map over its own background; both captures over that same background and at
    // the source's exposure, so their composites differ from it only in the model and its shadow.
    let source_map = data("hdri/polyhaven_1k/quarry_01_1k.hdr");
    let plain = bunny_scene(&source_map, 0.0, None, None);
    let plain_inputs = load_inputs(&plain, false).unwrap();
    let exp = f64::from(exposure(&plain, &plain_inputs.env));
    let background = common::render_with(&plain, &plain_inputs, Layer::Background);
    let background_png = dir.join("background.png");
    previz::output::write_png_rgba8(&background_png, background.width, background.height, &background.rgba).unwrap();
    let source = light_and_render(&bunny_scene(&source_map, 0.0, Some(exp), Some(&background_png)));
    let model = common::render_with(&bunny_scene(&source_map, 0.0, Some(exp), Some(&background_png)), &plain_inputs, Layer::Model);
    let hdr = light_and_render(&bunny_scene(&folder, heading, Some(exp), Some(&background_png)));
    let trusted = light_and_render(&bunny_scene(&faces_only, heading, Some(exp), Some(&background_png)));

    // Region of interest: the model (coverage) and its shadow (where the source's composite
    // differs from the background).
    let (w, h) = (source.composite.width, source.composite.height);
    let bg = rgb(&background);
    let src = rgb(&source.composite);
    let roi: Vec<bool> = (0..(w * h) as usize)
        .map(|i| model.rgba[4 * i + 3] > 0 || (0..3).any(|c| (i32::from(src[3 * i + c]) - i32::from(bg[3 * i + c])).abs() > 2))
        .collect();
    let flip = |l: &Lit| masked_mean(&flip_map(&src, &rgb(&l.composite), w, h).unwrap(), &roi);
    let angle = |l: &Lit| l.dir.angle_between(source.dir).to_degrees();
    let (hdr_flip, trusted_flip) = (flip(&hdr), flip(&trusted));
    eprintln!(
        "source sun {:.2}; HDR capture with its clip level: sun {:.2} ({:.2}x, turbidity {:?}, ground's sun/sky {:?}), {:.2} deg off, ROI FLIP {hdr_flip:.3}; \
         the same faces trusted as they are: sun {:.2} ({:.2}x), {:.2} deg off, ROI FLIP {trusted_flip:.3}; ROI {} px",
        source.sun,
        hdr.sun,
        hdr.sun / source.sun,
        hdr.turbidity,
        hdr.ground,
        angle(&hdr),
        trusted.sun,
        trusted.sun / source.sun,
        angle(&trusted),
        roi.iter().filter(|v| **v).count()
    );
    // Measured 2026-12-01: the capture's disc holds 0.10x the source's sun (one texel clipped at
    // R 110, G 139; the rest of the disc blurred over its neighbours). Restored above the clip
    // level: by Bird's clear sky at the disc's elevation (turbidity read from the sky) it was
    // 1.98x — the clear-sky model's own error, as on quarry_01 clipped at 1.0 (1.83x,
    // docs/accuracy.md) — and the composite's ROI FLIP against the source map's 0.155 (0.185 with
    // a white sun). Since the ninth session the sun's share of the ground's light is read from
    // the sand's colours (light::ground_split): **1.03x**, 0.64 deg from the source's sun, ROI
    // FLIP **0.036**, against 0.220 with the faces trusted as they are. Bounds: the sun within a
    // factor 1.15 either way (log error 0.14, where the trusted faces' is 2.3), the ground read,
    // its direction within 1.5 deg, the FLIP the measurement + 0.01. Tenth session (2026-12-01):
    // the restored sun given the real sun's angular size (the clipped texels are not the disc),
    // centred on the aureole around them (light::aureole), its colour the beam's through the
    // atmosphere that has the ground's direct-to-diffuse ratio (light::measure::beam_turbidity):
    // **1.04x**, 0.36 deg off, ROI FLIP **0.030** (the faces trusted: 0.229); bounds tightened to
    // 1.10x, 0.5 deg and 0.040.
    let within = |l: &Lit| (l.sun / source.sun).ln().abs() <= 1.10f32.ln();
    assert!(within(&hdr), "restored sun {} vs the source's {}", hdr.sun, source.sun);
    assert!(hdr.ground.is_some(), "the capture's ground shows the sun's share");
    assert!(angle(&hdr) <= 0.5, "sun {} deg off", angle(&hdr));
    assert!(hdr_flip <= 0.040, "ROI FLIP {hdr_flip}");
    // Without the clip level, the same faces fail the sun's bound and the FLIP bound.
    assert!(!within(&trusted) && trusted_flip > 0.040, "trusted faces: sun {}, FLIP {trusted_flip}", trusted.sun);
    std::fs::remove_dir_all(&dir).unwrap();
}
