//! The shutter (`live::export`): a live frame — after the panel and a drag moved things — is
//! written as composite, layers, camera image and scene TOML, and `previz composite scene.toml`
//! renders the same frame again (mean FLIP ≤ 0.02, the golden-image bound).

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use common::{gpu, inputs, scene};
use previz::live::export::{FILES, LIGHTING_DIR, export};
use previz::live::{LiveConfig, LiveSession};
use previz::sensors::sim::NoiseLevel;
use previz::ui::controls::{Controls, apply_gesture};
use std::sync::Arc;

const SCENE: &str = "width = 240\nheight = 160\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
[camera]\nheading = 90.0\npitch = -5.0\n";

fn rgb(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

/// Three noiseless seconds at 10 Hz in Bristol on a June afternoon.
fn bristol_afternoon() -> LiveConfig {
    LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 10.0,
        duration_s: 3.0,
        noise: NoiseLevel::None,
        seed: 3,
    }
}

#[test]
fn an_exported_frame_is_reproduced_by_previz_composite() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let cfg = bristol_afternoon();
    let mut session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, cfg).unwrap();
    // Until the filter settles there is no model to export; two seconds in, there is.
    while session.advance(gpu()).unwrap().is_some_and(|f| f.t < 2.0) {}
    let mut controls = Controls::from_params(session.params());
    controls.sunlight = 0.6;
    controls.specular = 1.3;
    controls.rotation_deg = [0.0, 0.0, 35.0];
    session.set_controls(controls);
    apply_gesture(session.params_mut(), &mut controls, glam::Vec3::new(0.3, -0.2, 0.0), 1.2, 0.0);

    let dir = tempdir("app_export", "frame");
    let written = export(&mut session, gpu(), &dir, None).unwrap();
    let names: Vec<String> = written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, FILES);
    let toml = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    assert!(!toml.contains("location"), "no location unless asked:\n{toml}");

    let out = previz(&dir, &["composite", "scene.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let exported = image::open(dir.join("composite.png")).unwrap().to_rgba8();
    let again = image::open(dir.join("recomposite.png")).unwrap().to_rgba8();
    assert_eq!(exported.dimensions(), again.dimensions());
    let (w, h) = exported.dimensions();
    let flip = previz::capture::replay::mean_flip(&rgb(exported.as_raw()), &rgb(again.as_raw()), w, h).unwrap();
    assert!(flip <= 0.02, "mean FLIP {flip} between the exported frame and its recomposite\n{toml}");
    // And the frame is not trivially the camera image: the model is in it.
    let camera = image::open(dir.join("camera.png")).unwrap().to_rgba8();
    let differ = exported.as_raw().chunks_exact(4).zip(camera.as_raw().chunks_exact(4)).filter(|(a, b)| a != b).count();
    assert!(differ > 300, "only {differ} pixels differ from the camera image");

    // Location only when asked; an export into a missing folder is a clear error with no files.
    let asked = tempdir("app_export", "location");
    export(&mut session, gpu(), &asked, Some((51.4545, -2.5879))).unwrap();
    assert!(std::fs::read_to_string(asked.join("scene.toml")).unwrap().contains("# location: latitude 51.454500, longitude -2.587900"));
    let e = export(&mut session, gpu(), &dir.join("missing"), None).unwrap_err().to_string();
    assert!(e.contains("missing") && e.contains("not an existing directory"), "{e}");
}

/// Before any capture the app lights the model with the camera frame folded into a cube map; the
/// export writes the fold (`lighting/`, float faces) and names it `lighting.environment`, so
/// `previz composite` of the export lights the model as the app did. The world is red to the East
/// and blue to the West and the camera looks East: the fold is red, while the scene's map lights
/// the model's camera-facing side blue from behind the camera — the same export lit by the map
/// instead is far outside the bound.
#[test]
fn a_fold_lit_export_is_reproduced_with_the_fold_not_the_map() {
    let dir = tempdir("app_export", "fold");
    let world = dir.join("world");
    std::fs::create_dir(&world).unwrap();
    let cube = common::east_red_west_blue(32);
    for (stem, face) in ["posx", "negx", "posy", "negy", "posz", "negz"].iter().zip(&cube.faces) {
        let plane = |c: usize| face.iter().map(|t| t[c]).collect::<Vec<f32>>();
        let channels = vec![("R", plane(0)), ("G", plane(1)), ("B", plane(2))];
        previz::output::write_exr_f32(&world.join(format!("{stem}.exr")), cube.size, cube.size, channels).unwrap();
    }
    let s = scene(&format!(
        "width = 160\nheight = 120\nmodel = \"meshes/icosphere-320.obj\"\nmethod = \"sh9-ggx\"\nenvironment = {:?}\n\
         [camera]\nheading = 90.0\npitch = -5.0\n[material]\nspecular = 1.0\n",
        world.display().to_string()
    ));
    let inp = inputs(&s);
    let cfg = bristol_afternoon();
    let mut session = LiveSession::simulated(gpu(), Arc::new(inp.env), &inp.model, &s, cfg).unwrap();
    session.fold_camera_into_environment();
    while session.advance(gpu()).unwrap().is_some_and(|f| f.t < 2.0) {
        session.finish_fold(gpu()).unwrap();
    }
    assert!(session.folded_environment().is_some(), "the fold lights the model");

    let out_dir = dir.join("export");
    std::fs::create_dir(&out_dir).unwrap();
    let written = export(&mut session, gpu(), &out_dir, None).unwrap();
    for name in FILES.iter().map(|f| out_dir.join(f)).chain(["posx", "negz"].map(|f| out_dir.join(LIGHTING_DIR).join(format!("{f}.exr")))) {
        assert!(written.contains(&name), "{} not written", name.display());
    }
    let toml = std::fs::read_to_string(out_dir.join("scene.toml")).unwrap();
    let table: toml::Table = toml.parse().unwrap();
    assert_eq!(table["lighting"]["environment"].as_str(), Some(LIGHTING_DIR), "{toml}");

    let rgb = |name: &str| image::open(out_dir.join(name)).unwrap().to_rgb8();
    let flip_against_app = |name: &str| {
        let (app, again) = (rgb("composite.png"), rgb(name));
        previz::capture::replay::mean_flip(app.as_raw(), again.as_raw(), app.width(), app.height()).unwrap()
    };
    let out = previz(&out_dir, &["composite", "scene.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let fold_lit = flip_against_app("recomposite.png");
    // The same export without its lighting environment: lit by the scene's map.
    let mut map_lit = table.clone();
    map_lit.remove("lighting");
    map_lit.insert("output".into(), toml::Value::String("recomposite_map.png".into()));
    std::fs::write(out_dir.join("scene_map.toml"), toml::to_string(&map_lit).unwrap()).unwrap();
    let out = previz(&out_dir, &["composite", "scene_map.toml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let map_lit = flip_against_app("recomposite_map.png");
    eprintln!("mean FLIP against the app's frame: fold-lit recomposite {fold_lit:.4}, map-lit {map_lit:.4}");
    assert!(fold_lit <= 0.02, "mean FLIP {fold_lit} between the app's fold-lit frame and its recomposite\n{toml}");
    assert!(map_lit > 0.02, "lit by the map instead the recomposite would pass too (mean FLIP {map_lit}): the test cannot fail");
    // The model the app drew is red (the fold, looking East).
    let model = image::open(out_dir.join("model_rgba.png")).unwrap().to_rgba8();
    let (mut r, mut b) = (0f64, 0f64);
    for p in model.as_raw().chunks_exact(4).filter(|p| p[3] == 255) {
        r += f64::from(p[0]);
        b += f64::from(p[2]);
    }
    assert!(r > 2.0 * b, "the fold lit the model red: r {r} b {b}");

    // A lighting environment that is not there, or a bad value, is a clear error naming the
    // key, and nothing is written.
    let before = files(&out_dir);
    for (set, needles) in
        [("lighting.environment=missing", ["lighting.environment", "missing"]), ("lighting.exposure=-1", ["lighting.exposure", "-1"])]
    {
        let out = previz(&out_dir, &["composite", "scene.toml", "-o", "bad.png", "--set", set]);
        assert_clean_failure(&out, &out_dir, &before, &needles);
    }
}
