//! `previz composite` end to end: the demo with no arguments, layers and JSON, and bad input —
//! each a clear error naming the file or flag, a non-zero exit, no panic, no output file.

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use common::data;
use std::process::Command;

#[test]
fn demo_with_no_arguments_writes_composite_png() {
    let dir = tempdir("cli", "demo");
    let out = previz(&dir, &["composite"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(dir.join("composite.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (960, 640));
    // The truck stands in the lower middle of the frame and is not the background colour.
    let demo_bg = image::load_from_memory(include_bytes!("../assets/demo/background.jpg")).unwrap().to_rgb8();
    let bg = image::imageops::resize(
        &image::imageops::crop_imm(&demo_bg, 0, 171, 1024, 683).to_image(),
        960,
        640,
        image::imageops::FilterType::Triangle,
    );
    let changed = img.pixels().zip(bg.pixels()).filter(|(a, b)| a.0.iter().zip(b.0.iter()).any(|(x, y)| x.abs_diff(*y) > 40)).count();
    assert!(changed > 960 * 640 / 50, "only {changed} pixels differ from the background");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn layers_and_json() {
    let dir = tempdir("cli", "layers");
    let layers = dir.join("layers");
    std::fs::create_dir(&layers).unwrap();
    let bunny = data("meshes/stanford-bunny.obj");
    let env = data("cubemaps/humus_Park2_512");
    let out = previz(
        &dir,
        &[
            "composite",
            "--model",
            bunny.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "--width",
            "320",
            "--height",
            "200",
            "--layers",
            "layers",
            "--json",
            "--set",
            "colour.correction=reinhard",
            "-o",
            "out.png",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["width"], 320);
    assert_eq!(json["height"], 200);
    // The default is auto: the bunny (matte, opaque) gets the ordinary method, and says why.
    assert_eq!(json["method"], "sh9-ggx");
    assert_eq!(json["method_choice"]["requested"], "auto");
    let why: Vec<&str> = json["method_choice"]["why"].as_array().unwrap().iter().filter_map(|w| w.as_str()).collect();
    assert!(why.iter().any(|w| w.contains("no refraction")) && why.iter().any(|w| w.contains("no specular")), "{why:?}");
    assert_eq!(json["colour_correction"]["method"], "reinhard");
    assert_eq!(json["colour_correction"]["strength"], 1.0);
    let pixels = json["model_pixels"].as_u64().unwrap();
    for key in ["load", "upload", "readback", "total"] {
        assert!(json["timings_ms"][key].as_f64().unwrap() >= 0.0, "{key}");
    }
    assert_eq!(json["outputs"].as_array().unwrap().len(), 5);
    // The model layer: premultiplied, alpha = coverage; its opaque pixel count is the JSON's.
    let model = image::open(layers.join("model_rgba.png")).unwrap().to_rgba8();
    let covered = model.pixels().filter(|p| p[3] > 0).count() as u64;
    assert_eq!(covered, pixels);
    // Auto placement: the bounding sphere spans half the vertical field of view, a circle of
    // radius ≈ 200/4 px; the bunny fills a good part of it and never more.
    let circle = std::f64::consts::PI * 50f64.powi(2);
    assert!(pixels as f64 > 0.15 * circle && (pixels as f64) < 1.1 * circle, "{pixels} model pixels");
    // Premultiplied in linear light, then sRGB-encoded: no channel exceeds the encoded alpha,
    // and uncovered pixels are transparent black.
    for p in model.pixels() {
        let a = previz::colour::linear_to_srgb(f32::from(p[3]) / 255.0) * 255.0 + 1.5;
        assert!(p.0[..3].iter().all(|&c| f32::from(c) <= a), "{p:?} is not premultiplied");
        assert!(p[3] > 0 || p.0 == [0, 0, 0, 0]);
    }
    // Edges are antialiased: some partial coverage.
    assert!(model.pixels().any(|p| p[3] > 0 && p[3] < 255));
    // Background + model layer composited "over" reproduces the composite away from the
    // ground shadow (where the model covers fully, the composite is the model).
    let comp = image::open(dir.join("out.png")).unwrap().to_rgba8();
    let layered = image::open(layers.join("composite.png")).unwrap().to_rgba8();
    assert_eq!(comp.as_raw(), layered.as_raw());
    let full = model.pixels().zip(comp.pixels()).filter(|(m, _)| m[3] == 255);
    for (m, c) in full {
        assert_eq!(&m.0[..3], &c.0[..3]);
    }
    assert!(layers.join("background.png").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_flags_are_named() {
    let dir = tempdir("cli", "flags");
    // `--layers` creates a missing folder (tests/cli_errors.rs); a path through a file cannot be.
    std::fs::write(dir.join("afile"), "not a folder").unwrap();
    let before = files(&dir);
    for (args, needles) in [
        (vec!["composite", "--pitch", "NaN"], vec!["--pitch", "finite"]),
        (vec!["composite", "--vfov", "500"], vec!["--vfov", "out of range"]),
        (vec!["composite", "--sun-dir", "0,0,0"], vec!["sun.direction", "zero"]),
        (vec!["composite", "--sun-dir", "1,2"], vec!["--sun-dir"]),
        (vec!["composite", "--width", "0"], vec!["width"]),
        (vec!["composite", "--set", "effects.ior=0.2"], vec!["effects.ior"]),
        (vec!["composite", "--set", "nonsense"], vec!["KEY=VALUE"]),
        (vec!["composite", "--method", "phong"], vec!["phong"]),
        (vec!["composite", "--layers", "afile/layers"], vec!["--layers", "afile/layers"]),
        (vec!["composite", "missing-scene.toml"], vec!["missing-scene.toml"]),
    ] {
        let out = previz(&dir, &args);
        assert_clean_failure(&out, &dir, &before, &needles);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_files_are_named() {
    let dir = tempdir("cli", "files");
    // Malformed OBJ.
    std::fs::write(dir.join("bad.obj"), "v 1 2\nf 1 2 x\n").unwrap();
    // OBJ whose MTL names a texture that does not exist.
    std::fs::write(dir.join("tex.mtl"), "newmtl m\nKd 1 1 1\nmap_Kd missing_texture.png\n").unwrap();
    std::fs::write(dir.join("tex.obj"), "mtllib tex.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
        .unwrap();
    // Cube folders: mismatched sizes and non-square faces.
    let faces = ["posx", "negx", "posy", "negy", "posz", "negz"];
    for (name, size_of) in
        [("mismatched", (|i: usize| if i == 3 { (8, 8) } else { (16, 16) }) as fn(usize) -> (u32, u32)), ("nonsquare", |_| (16, 8))]
    {
        let d = dir.join(name);
        std::fs::create_dir(&d).unwrap();
        for (i, f) in faces.iter().enumerate() {
            let (w, h) = size_of(i);
            image::RgbImage::new(w, h).save(d.join(format!("{f}.png"))).unwrap();
        }
    }
    // An unreadable image.
    std::fs::write(dir.join("broken.jpg"), b"this is not a jpeg").unwrap();
    let before = files(&dir);
    let env = data("cubemaps/humus_Park2_512");
    let env = env.to_str().unwrap();
    let bunny = data("meshes/stanford-bunny.obj");
    let bunny = bunny.to_str().unwrap();
    for (args, needles) in [
        (vec!["composite", "--model", "bad.obj", "--env", env], vec!["bad.obj"]),
        (vec!["composite", "--model", "tex.obj", "--env", env], vec!["missing_texture.png"]),
        (vec!["composite", "--model", bunny, "--env", "mismatched"], vec!["mismatched"]),
        (vec!["composite", "--model", bunny, "--env", "nonsquare"], vec!["nonsquare"]),
        (vec!["composite", "--model", bunny, "--env", env, "--background", "broken.jpg"], vec!["broken.jpg"]),
        (vec!["composite", "--model", "nothing-here.obj", "--env", env], vec!["nothing-here.obj"]),
    ] {
        let out = previz(&dir, &args);
        assert_clean_failure(&out, &dir, &before, &needles);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn no_gpu_adapter_says_how_to_install_lavapipe() {
    let dir = tempdir("cli", "nogpu");
    // Point the Vulkan loader at no driver and allow only Vulkan: no adapter can be found.
    let out = Command::new(env!("CARGO_BIN_EXE_previz"))
        .current_dir(&dir)
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env("WGPU_BACKEND", "vulkan")
        .args(["composite"])
        .output()
        .unwrap();
    assert_clean_failure(&out, &dir, &[], &["no GPU adapter", "mesa-vulkan-drivers"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn json_reports_the_spa_sun_for_the_scenes_place_and_time() {
    let dir = tempdir("cli", "spa_json");
    let sphere = data("meshes/icosphere-320.obj");
    let env = data("cubemaps/humus_Park2_512");
    let common =
        ["composite", "--model", sphere.to_str().unwrap(), "--env", env.to_str().unwrap(), "--width", "64", "--height", "48", "--json"];
    // NREL SPA's published test case (Reda & Andreas 2004, Table A4.1): Golden, Colorado,
    // 2003-10-17 12:30:30 −7 h: azimuth 194.34024°, topocentric zenith 50.11162° (elevation
    // 1830 m, 820 mbar, 11 °C there; sea level and standard-atmosphere defaults move it < 0.05°).
    let place = ["--set", "sun.latitude=39.742476", "--set", "sun.longitude=-105.1786", "--set", "sun.time=\"2003-10-17T12:30:30-07:00\""];
    let args: Vec<&str> = common.iter().chain(&place).chain(&["-o", "spa.png"]).copied().collect();
    let out = previz(&dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let light = &json["light"];
    let spa = &light["spa_sun_dir"];
    assert!((spa["azimuth_deg"].as_f64().unwrap() - 194.34024).abs() < 0.05, "{spa}");
    assert!((spa["elevation_deg"].as_f64().unwrap() - (90.0 - 50.11162)).abs() < 0.05, "{spa}");
    // The angle to the sun used is the one between the two reported directions.
    let v = |d: &serde_json::Value| glam::DVec3::from_array(std::array::from_fn(|i| d["enu"][i].as_f64().unwrap())).normalize();
    let angle = v(spa).angle_between(v(&light["sun_dir"])).to_degrees();
    assert!((light["used_to_spa_deg"].as_f64().unwrap() - angle).abs() < 0.01, "{light}");
    // Without a place: no SPA sun.
    let args: Vec<&str> = common.iter().chain(&["-o", "none.png"]).copied().collect();
    let out = previz(&dir, &args);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["light"]["spa_sun_dir"].is_null() && json["light"]["map_to_spa_deg"].is_null());
    // A place without a time, or a time that is not one: the keys are named, nothing is written.
    let before = files(&dir);
    for (extra, needle) in [
        (vec!["--set", "sun.latitude=39.7"], "sun.latitude, sun.longitude and sun.time"),
        (vec!["--set", "sun.latitude=39.7", "--set", "sun.longitude=-105", "--set", "sun.time=\"noon\""], "sun.time"),
        (vec!["--set", "sun.latitude=95", "--set", "sun.longitude=-105", "--set", "sun.time=\"2003-10-17T12:30:30Z\""], "sun.latitude"),
    ] {
        let args: Vec<&str> = common.iter().copied().chain(extra).chain(["-o", "bad.png"]).collect();
        assert_clean_failure(&previz(&dir, &args), &dir, &before, &[needle]);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
