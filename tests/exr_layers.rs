//! The multi-layer OpenEXR of `composite --layers` (render/layers.rs): read back with the exr
//! crate's reader, its beauty is model over (background × shadow matte) to float precision, and
//! it is the renderer's frame — sRGB-encoded it matches the 8-bit composite PNG within the
//! quantisation of the 8-bit path; the matte's darkest value is the frame's shadow opacity; the
//! depth is the distance to the model's surface found by casting rays on the CPU.

use crate::common;

use common::cli::{previz, tempdir};
use common::{data, gpu, inputs, scene};
use previz::render::layers::CHANNELS;
use previz::setup::prepare;
use std::collections::HashMap;

/// The file's channels by name (each plane row-major from the top-left pixel), and its size.
fn read_exr(path: &std::path::Path) -> (HashMap<String, Vec<f32>>, usize, usize) {
    let image = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    let size = image.layer_data.size;
    let planes = image
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| {
            assert_eq!(c.sample_data.len(), size.area(), "{}", c.name);
            assert!(matches!(c.sample_data, exr::prelude::FlatSamples::F32(_)), "{} is not 32-bit float", c.name);
            (c.name.to_string(), c.sample_data.values_as_f32().collect())
        })
        .collect();
    (planes, size.0, size.1)
}

#[test]
fn the_layers_exr_composes_to_the_png_composite() {
    let dir = tempdir("exr-layers", "bunny");
    let (bunny, env) = (data("meshes/stanford-bunny.obj"), data("cubemaps/humus_Park2_512"));
    // The sun 48° high: the bunny's shadow falls on the ground in view (checked below); sunlight
    // 0.4 keeps the model below 1 (see the PNG comparison).
    let args = [
        "composite",
        "--model",
        bunny.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "--width",
        "320",
        "--height",
        "200",
        "--sun-dir",
        "0.3,0.6,0.75",
        "--set",
        "sun.sunlight=0.4",
        "--layers",
        "layers",
        "--json",
        "-o",
        "out.png",
    ];
    let out = previz(&dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["outputs"].as_array().unwrap().iter().any(|o| o.as_str().unwrap().ends_with("layers.exr")), "{json}");
    let (planes, w, h) = read_exr(&dir.join("layers/layers.exr"));
    let mut names: Vec<&str> = planes.keys().map(String::as_str).collect();
    names.sort();
    let mut documented = CHANNELS.to_vec();
    documented.sort();
    assert_eq!(names, documented);
    assert_eq!((w, h), (320, 200));
    let p = |name: &str| &planes[name];

    // beauty = model + (1 − α)·background·matte, per channel, to float precision.
    let mut worst = 0f32;
    for c in ["R", "G", "B"] {
        let (beauty, model, bg) = (p(c), p(&format!("model.{c}")), p(&format!("background.{c}")));
        for i in 0..w * h {
            let expected = model[i] + (1.0 - p("model.A")[i]) * (bg[i] * p(&format!("shadow.{c}"))[i]);
            worst = worst.max((beauty[i] - expected).abs() / expected.abs().max(1.0));
        }
    }
    assert!(worst <= 2.0 * f32::EPSILON, "beauty differs from model over background × matte by {worst} (relative)");

    // Not trivially so: the model covers part of the frame (with antialiased edges), and its
    // shadow darkens the ground (and its light brightens it, below): the ground loses opacity × (1 − sun visibility) + sky
    // occlusion × (1 − sky visibility) of its light's luminance (per channel each light its own
    // share, shaders/ground.wgsl ground_loss), so the sun's full shadow reaches
    // 1 − opacity and the contact point under the bunny, where both are lost, 1 − opacity − sky
    // occlusion (0 here: the two shares of the ground's light add up to 1).
    let alpha = p("model.A");
    // Light is never negative: sh9-ggx's sky colour from SH9 along a bent normal turned down at
    // a silhouette once gave the full-detail bunny's edge samples (1.1, -0.012, 0.002) (model.G
    // -0.0039 premultiplied at three pixels).
    for c in ["R", "G", "B"] {
        let lowest = p(&format!("model.{c}")).iter().copied().fold(f32::INFINITY, f32::min);
        assert!(lowest >= 0.0, "model.{c} reaches {lowest}");
    }
    let covered = alpha.iter().filter(|&&a| a > 0.0).count();
    assert!(covered > 1000 && covered < w * h / 2, "{covered} covered pixels");
    assert!(alpha.iter().any(|&a| a > 0.0 && a < 1.0), "no partial coverage");
    // The matte's luminance (BT.709): each channel keeps its own share of the light.
    let matte: Vec<f32> = (0..w * h).map(|i| 0.2126 * p("shadow.R")[i] + 0.7152 * p("shadow.G")[i] + 0.0722 * p("shadow.B")[i]).collect();
    let shadowed = matte.iter().filter(|&&m| m < 0.99).count();
    let opacity = json["light"]["shadow_opacity"].as_f64().unwrap() as f32;
    let darkest = matte.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(shadowed > 200, "only {shadowed} pixels in shadow");
    // The matte can exceed 1 where the bunny reflects more light onto the ground than it hides
    // (the ground pass's factor spans 0..2, render::passes::ground::SCALE), and does beside it.
    assert!(matte.iter().all(|&m| (0.0..=2.0).contains(&m)), "matte outside 0..2");
    let lit = matte.iter().filter(|&&m| m > 1.01).count();
    assert!(lit > 20, "only {lit} pixels where the bunny's light brightens the ground");
    let sky_occlusion = json["light"]["sky_occlusion"].as_f64().unwrap() as f32;
    assert!((opacity + sky_occlusion - 1.0).abs() < 1e-5, "shadow opacity {opacity} + sky occlusion {sky_occlusion}");
    assert!(darkest < 0.02, "darkest matte {darkest}: nothing under the bunny's contact point");
    let sun_shadow = matte.iter().filter(|&&m| m <= 1.0 - opacity + 0.01).count();
    assert!(sun_shadow > 200, "only {sun_shadow} pixels in the sun's full shadow (1 - {opacity}) or darker");
    // Depth: finite wherever the model covers fully, +inf wherever it does not cover at all.
    let depth = p("depth.Z");
    for i in 0..w * h {
        if alpha[i] == 1.0 {
            assert!(depth[i].is_finite() && depth[i] > 0.0, "pixel {i}: alpha 1, depth {}", depth[i]);
        }
        if alpha[i] == 0.0 {
            assert_eq!(depth[i], f32::INFINITY, "pixel {i}: alpha 0");
        }
    }

    // The renderer's frame: sRGB-encoded, the beauty is the 8-bit composite within one level.
    // (The 8-bit frame clips each sample at 1 before resolving while the EXR keeps highlights
    // above 1, so with sunlight 1 the two differ by up to 46 levels at bright antialiased edges;
    // sunlight 0.4 keeps every sample of this frame below 1: checked on the fully covered pixels.)
    let brightest = (0..w * h).filter(|&i| alpha[i] == 1.0).flat_map(|i| ["R", "G", "B"].map(|c| p(&format!("model.{c}"))[i]));
    let brightest = brightest.fold(0f32, f32::max);
    assert!(brightest < 0.9, "the model reaches {brightest}: the 8-bit frame would clip it");
    let png = image::open(dir.join("out.png")).unwrap().to_rgba8();
    let mut histogram = [0usize; 256];
    for i in 0..w * h {
        for (k, c) in ["R", "G", "B"].into_iter().enumerate() {
            let encoded = (previz::colour::linear_to_srgb(p(c)[i].clamp(0.0, 1.0)) * 255.0).round() as u8;
            histogram[usize::from(encoded.abs_diff(png.as_raw()[4 * i + k]))] += 1;
        }
    }
    let max_diff = histogram.iter().rposition(|&n| n > 0).unwrap();
    assert!(max_diff <= 1, "EXR beauty and PNG differ by up to {max_diff} levels: {:?}", &histogram[..=max_diff]);
    // Most values agree exactly; the rest by the 8-bit path's intermediate rounding. Measured
    // one sample a pixel: 190264 of 192000 (99 %). A supersampled still's 8-bit frame rounds
    // each of its samples before their mean (render::supersample::box_mean_srgb8) while the
    // EXR averages them in float: measured 165702 of 192000 (86 %) at 3 × 3 samples, the
    // largest difference still one level (above).
    let share = if json["supersample"].as_u64().unwrap_or(1) > 1 { 80 } else { 95 };
    assert!(histogram[0] * 100 >= share * 3 * w * h, "only {} of {} values agree exactly", histogram[0], 3 * w * h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Möller–Trumbore: the distance along `dir` (unit) from `origin` to the triangle, if hit.
fn ray_triangle(origin: glam::Vec3, dir: glam::Vec3, [a, b, c]: [glam::Vec3; 3]) -> Option<f32> {
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let t0 = origin - a;
    let u = t0.dot(p) / det;
    let q = t0.cross(e1);
    let v = dir.dot(q) / det;
    let t = e2.dot(q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
}

#[test]
fn depth_is_the_distance_to_the_model_surface() {
    let s = scene("width = 160\nheight = 120\nmodel = \"meshes/icosphere-320.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\n");
    let inp = inputs(&s);
    let (mut compositor, params) = prepare(gpu(), &s, &inp).unwrap();
    let layers = compositor.render_layers(gpu(), &params).unwrap();
    let data = compositor.frame_uniforms(&params).unwrap();
    let model = glam::Mat4::from_cols_array_2d(&data.instance.model);
    let inverse = glam::Mat4::from_cols_array_2d(&data.frame.view_proj).inverse();
    let camera = glam::Vec3::from(data.frame.camera_pos);
    let triangles: Vec<[glam::Vec3; 3]> = inp
        .model
        .meshes
        .iter()
        .flat_map(|m| m.indices.chunks_exact(3).map(|t| t.iter().map(|&i| model.transform_point3(m.positions[i as usize].into()))))
        .map(|mut t| [t.next().unwrap(), t.next().unwrap(), t.next().unwrap()])
        .collect();
    let (w, h) = (layers.width, layers.height);
    let (mut hits, mut misses) = (0, 0);
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            // The ray through the pixel centre: from the camera towards the far-plane point.
            let ndc = glam::Vec3::new(2.0 * (x as f32 + 0.5) / w as f32 - 1.0, 1.0 - 2.0 * (y as f32 + 0.5) / h as f32, 1.0);
            let dir = (inverse.project_point3(ndc) - camera).normalize();
            let nearest = triangles.iter().filter_map(|&t| ray_triangle(camera, dir, t)).fold(f32::INFINITY, f32::min);
            let depth = layers.depth[(y * w + x) as usize];
            if nearest.is_finite() {
                hits += 1;
                assert!((depth - nearest).abs() <= 1e-3 * nearest, "({x}, {y}): depth {depth}, ray {nearest}");
            } else {
                misses += 1;
                // A ray grazing an edge may be caught by rasterisation; none far from the model.
                assert!(depth == f32::INFINITY || layers.model[(y * w + x) as usize][3] > 0.0, "({x}, {y}): depth {depth}, no hit");
            }
        }
    }
    assert!(hits > 50 && misses > 50, "{hits} hits, {misses} misses");
}
