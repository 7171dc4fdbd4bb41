//! `previz colour-transfer` and `previz priors` end to end: results, JSON, reports, and bad input
//! — a clear error, a non-zero exit, no panic and no output file left behind.

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use common::data;
use std::path::{Path, PathBuf};
use std::process::Output;

/// Write a w×h RGBA PNG from a pixel function.
fn png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)));
    img.save(path).unwrap();
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Mean and σ per channel of `which`'s statistics in the space the method matches: log lαβ
/// (reinhard, mkl) or lαβ without the log (cielab-approx), derived from the JSON.
fn lab(v: &serde_json::Value, which: &str, log: bool) -> ([f64; 3], [f64; 3]) {
    use glam::{DMat3, DVec3};
    let st = &v[which]["stats"];
    let vec3 = |x: &serde_json::Value| DVec3::from_array([0, 1, 2].map(|i| x[i].as_f64().unwrap()));
    let mat3 = |x: &serde_json::Value| DMat3::from_cols(vec3(&x[0]), vec3(&x[1]), vec3(&x[2]));
    let (m, c) = if log {
        (vec3(&st["lab_mean"]), mat3(&st["lab_cov"]))
    } else {
        let p = previz::colour::lab::rgb_to_linear_lab_matrix();
        (p * vec3(&st["rgb_mean"]), p * mat3(&st["rgb_cov"]) * p.transpose())
    };
    (m.to_array(), [0, 1, 2].map(|i| c.col(i)[i].sqrt()))
}

fn make_pair(dir: &Path) -> (PathBuf, PathBuf) {
    // Source: warm gradient 40×30; target: cool gradient 24×20 (different sizes on purpose).
    let s = dir.join("source.png");
    let t = dir.join("target.png");
    png(&s, 40, 30, |x, y| [120 + (x * 3) as u8, 60 + (y * 2) as u8, 30 + ((x + y) % 20) as u8, 255]);
    png(&t, 24, 20, |x, y| [20 + (y * 2) as u8, 60 + (x * 3) as u8, 140 + (x * 4) as u8, 255]);
    (s, t)
}

#[test]
fn transfer_matches_source_statistics_for_every_method() {
    let dir = tempdir("colour-cli", "ok");
    let (s, t) = make_pair(&dir);
    for method in ["reinhard", "mkl", "cielab-approx"] {
        let out = previz(
            &dir,
            &[
                "colour-transfer",
                "--source",
                s.to_str().unwrap(),
                "--target",
                t.to_str().unwrap(),
                "-o",
                "out.png",
                "--method",
                method,
                "--json",
            ],
        );
        let v = json(&out);
        assert_eq!(v["sizes_differ"], true);
        let log = method != "cielab-approx";
        let (ms, ss) = lab(&v, "source", log);
        let (mt, _) = lab(&v, "target", log);
        let (mr, sr) = lab(&v, "result", log);
        // The result moved to the source: its mean is far closer than the target's was, and
        // (8-bit rounding and clipping aside) its σ matches.
        for i in 0..3 {
            assert!((mr[i] - ms[i]).abs() < 0.25 * (mt[i] - ms[i]).abs() + 0.01, "{method} mean {i}: {} {} {}", mr[i], ms[i], mt[i]);
            assert!((sr[i] - ss[i]).abs() < 0.3 * ss[i] + 0.01, "{method} σ {i}: {} vs {}", sr[i], ss[i]);
        }
        let img = image::open(dir.join("out.png")).unwrap();
        assert_eq!((img.width(), img.height()), (24, 20));
    }
    // Strength 0 reproduces the target exactly.
    let out = previz(
        &dir,
        &["colour-transfer", "--source", s.to_str().unwrap(), "--target", t.to_str().unwrap(), "-o", "same.png", "--strength", "0"],
    );
    assert!(out.status.success());
    assert_eq!(image::open(dir.join("same.png")).unwrap().to_rgba8(), image::open(&t).unwrap().to_rgba8());
    // The human-readable form says the sizes differ and that this is fine.
    assert!(String::from_utf8_lossy(&out.stderr).contains("fine"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn report_and_green_screen() {
    let dir = tempdir("colour-cli", "report");
    let (s, _) = make_pair(&dir);
    // Target: left half blue, right half green screen.
    let t = dir.join("green.png");
    png(&t, 16, 8, |x, _| if x < 8 { [30, 50, 200, 255] } else { [0, 255, 0, 255] });
    let out = previz(
        &dir,
        &[
            "colour-transfer",
            "--source",
            s.to_str().unwrap(),
            "--target",
            t.to_str().unwrap(),
            "-o",
            "out.png",
            "--green-screen",
            "--report",
            "report.png",
            "--method",
            "mkl",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r = image::open(dir.join("report.png")).unwrap();
    assert!(r.width() > 500 && r.height() > 400);
    let o = image::open(dir.join("out.png")).unwrap().to_rgba8();
    // Green-screen pixels are left as they were; the blue half took the source's warm colours.
    assert_eq!(o.get_pixel(12, 3).0, [0, 255, 0, 255]);
    let p = o.get_pixel(3, 3).0;
    assert!(p[0] > p[2], "{p:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_fails_cleanly() {
    let dir = tempdir("colour-cli", "bad");
    let (s, t) = make_pair(&dir);
    let (s, t) = (s.to_str().unwrap().to_string(), t.to_str().unwrap().to_string());
    let broken = dir.join("broken.png");
    std::fs::write(&broken, b"not an image").unwrap();
    let empty = dir.join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let clear = dir.join("clear.png");
    png(&clear, 8, 8, |_, _| [10, 20, 30, 0]);
    let green = dir.join("allgreen.png");
    png(&green, 8, 8, |_, _| [0, 255, 0, 255]);
    let before = files(&dir);
    let run = |args: &[&str]| previz(&dir, args);
    assert_clean_failure(
        &run(&["colour-transfer", "--source", broken.to_str().unwrap(), "--target", &t, "-o", "o.png"]),
        &dir,
        &before,
        &["SOURCE", "broken.png"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", empty.to_str().unwrap(), "-o", "o.png"]),
        &dir,
        &before,
        &["TARGET", "empty.png"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", "missing.png", "-o", "o.png"]),
        &dir,
        &before,
        &["missing.png"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", clear.to_str().unwrap(), "-o", "o.png"]),
        &dir,
        &before,
        &["TARGET", "transparent"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", clear.to_str().unwrap(), "--target", &t, "-o", "o.png"]),
        &dir,
        &before,
        &["SOURCE", "transparent"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", green.to_str().unwrap(), "-o", "o.png", "--green-screen"]),
        &dir,
        &before,
        &["TARGET", "green"],
    );
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", &t, "-o", "o.png", "--strength", "1.5"]),
        &dir,
        &before,
        &["strength"],
    );
    // The report cannot be written: no OUT either.
    assert_clean_failure(
        &run(&["colour-transfer", "--source", &s, "--target", &t, "-o", "o.png", "--report", "no/such/dir/r.png"]),
        &dir,
        &before,
        &["r.png"],
    );
    // OUT cannot be written.
    assert_clean_failure(&run(&["colour-transfer", "--source", &s, "--target", &t, "-o", "no/such/dir/o.png"]), &dir, &before, &["o.png"]);
    // Without a subcommand the three paths are required.
    assert_clean_failure(&run(&["colour-transfer", "--source", &s]), &dir, &before, &["--target"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn priors_of_an_environment_and_a_model() {
    let dir = tempdir("colour-cli", "priors");
    let env = data("cubemaps/humus_Park2_512");
    let obj = data("textured_models/spot/spot_triangulated.obj");
    let tex = data("textured_models/spot/spot_texture.png");
    let out = previz(
        &dir,
        &["priors", "--env", env.to_str().unwrap(), "--model", obj.to_str().unwrap(), "--texture", tex.to_str().unwrap(), "--json"],
    );
    let v = json(&out);
    assert!(v["encoding"].as_str().unwrap().contains("linear"));
    let h = &v["environment"]["horizontal"];
    assert_eq!(h["count"], 4 * 512 * 512); // four 512 px side faces
    let l = &h["luminance"];
    let f = |k: &str| l[k].as_f64().unwrap();
    assert!(f("min") <= f("p_lo") && f("p_lo") <= f("mean") && f("mean") <= f("p_hi") && f("p_hi") <= f("max"));
    assert!(f("max") <= 1.0 + 1e-9, "an 8-bit environment is at most 1 in linear light");
    let m = &v["model"];
    assert_eq!(m["source"], "textures");
    assert!(m["texels"]["not_covered_by_uvs"].as_u64().unwrap() > 0);
    // The table form prints the same without error.
    let out = previz(&dir, &["priors", "--env", env.to_str().unwrap()]);
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("horizontal"));
    // Bad input: a missing environment and an unreadable model.
    let before = files(&dir);
    assert_clean_failure(&previz(&dir, &["priors", "--env", "no/such/env"]), &dir, &before, &["--env", "no/such/env"]);
    let broken = dir.join("broken.obj");
    std::fs::write(&broken, b"v 0 0 0\nf 1 2 3\n").unwrap();
    let before = files(&dir);
    assert_clean_failure(
        &previz(&dir, &["priors", "--env", env.to_str().unwrap(), "--model", broken.to_str().unwrap()]),
        &dir,
        &before,
        &["--model"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
