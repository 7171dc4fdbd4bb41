//! The shutter (`live::export`): a live frame — after the panel and a drag moved things — is
//! written as composite, layers, camera image and scene TOML, and `previz composite scene.toml`
//! renders the same frame again (mean FLIP ≤ 0.02, the golden-image bound).

mod common;

use common::cli::{previz, tempdir};
use common::{gpu, inputs, scene};
use previz::live::export::{FILES, export};
use previz::live::{LiveConfig, LiveSession};
use previz::sensors::sim::NoiseLevel;
use previz::ui::controls::{Controls, apply_gesture};
use std::sync::Arc;

const SCENE: &str = "width = 240\nheight = 160\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
[camera]\nheading = 90.0\npitch = -5.0\n";

fn rgb(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

#[test]
fn an_exported_frame_is_reproduced_by_previz_composite() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 10.0,
        duration_s: 3.0,
        noise: NoiseLevel::None,
        seed: 3,
    };
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
