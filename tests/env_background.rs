//! The environment seen as the background when no photograph is given: an environment loaded
//! from an equirectangular image is looked up in that image (shaders/env_view_equirect.wgsl),
//! not through the cube map that lights the model, which would resample it a second time
//! (docs/accuracy.md, "Eighth session: the background looked up in the equirect").

use crate::common;

use common::{data, gpu, scene, triangle};
use previz::colour::linear_to_srgb;
use previz::render::passes::background::ENV_VIEW_TAPS;
use previz::render::{Layer, Rendered};
use previz::scene::environment::{Equirect, load_environment, load_environment_and_equirect};
use previz::setup::{Inputs, prepare};
use std::sync::Arc;

/// A 256×128 map with detail at the texel scale, 2-texel squares of 0.04 and 0.5, tinted red
/// growing with u and blue with v, so a lookup that is off in azimuth, in elevation or by half a
/// texel, or one that blurs, shows.
fn detailed_map() -> Equirect {
    let (w, h) = (256u32, 128u32);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let level = if (x / 2 + y / 2) % 2 == 0 { 0.04 } else { 0.5 };
            let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            pixels.push([level * (0.5 + u), level, level * (0.5 + v)]);
        }
    }
    Equirect::new(w, h, pixels).unwrap()
}

/// What the background pixel (x, y) must hold: the mean of n² lookups of `map` spread evenly
/// over the pixel (Equirect::sample_enu, the CPU's one lookup), times the exposure,
/// sRGB-encoded (IEC 61966-2-1) to 0..255. A still draws each pixel as k × k samples
/// (render::supersample) of ENV_VIEW_TAPS² lookups each: n = k · ENV_VIEW_TAPS.
fn expected(map: &Equirect, camera: &previz::render::Camera, (w, h): (u32, u32), heading: f32, exposure: f32, n: u32) -> Vec<[f32; 3]> {
    let t = (camera.vfov / 2.0).tan();
    let aspect = w as f32 / h as f32;
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            for j in 0..n {
                for i in 0..n {
                    let u = (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32;
                    let v = (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32;
                    let d_cam = glam::Vec3::new((2.0 * u - 1.0) * t * aspect, (1.0 - 2.0 * v) * t, -1.0);
                    let s = map.sample_enu((camera.pose * d_cam).normalize(), heading);
                    sum = std::array::from_fn(|c| sum[c] + s[c]);
                }
            }
            out.push(sum.map(|s| 255.0 * linear_to_srgb(s / (n * n) as f32 * exposure)));
        }
    }
    out
}

/// Largest and mean absolute difference (8-bit levels) of a rendered image from `expected`.
fn differences(r: &Rendered, expected: &[[f32; 3]]) -> (f32, f32) {
    let diffs: Vec<f32> =
        (r.rgba.chunks_exact(4).zip(expected)).flat_map(|(p, e)| (0..3).map(move |c| (f32::from(p[c]) - e[c]).abs())).collect();
    (diffs.iter().fold(0.0, |m, d| m.max(*d)), diffs.iter().sum::<f32>() / diffs.len() as f32)
}

#[test]
fn an_equirect_background_is_its_direct_lookup_and_the_cube_is_not() {
    let (w, h) = (96, 64);
    let s = scene(&format!(
        "width = {w}\nheight = {h}\n[camera]\nheading = 40.0\npitch = 25.0\nroll = 5.0\nvfov = 50.0\n[env]\nheading = 25.0\nexposure = 0.8\n"
    ));
    let map = detailed_map();
    let env = map.to_cube(map.default_face_size(), 0.0);
    let inputs = Inputs { model: triangle(), env, env_equirect: Some(Arc::new(map)), background: None };
    let (mut compositor, params) = prepare(gpu(), &s, &inputs).unwrap();
    assert!(compositor.background_sees_equirect());
    let map = inputs.env_equirect.as_deref().unwrap();
    let n = ENV_VIEW_TAPS * compositor.supersample();
    let want = expected(map, &params.camera, (w, h), 25f32.to_radians(), 0.8, n);
    let direct = compositor.render(gpu(), &params, Layer::Background).unwrap();
    let (direct_max, direct_mean) = differences(&direct, &want);
    // The same lookup on the GPU, stored in 8 bits: rounding alone leaves up to half a level (a
    // quarter on average); half-float texels, the sampler's filter weights and lavapipe's sRGB
    // store (which rounds some values up) add a little. Measured 2026-12-01 (lavapipe), one
    // sample a pixel: largest 0.65, mean 0.257 levels. A supersampled still rounds twice, each
    // sample as it is stored (up to half a level, which their mean keeps) and the mean itself
    // (another half): measured 2026-12-02 at 3 × 3 samples, largest 1.01, mean 0.266 levels.
    eprintln!("direct lookup: largest difference {direct_max:.2}, mean {direct_mean:.3} levels");
    let rounding = if compositor.supersample() > 1 { 1.0 } else { 0.5 };
    assert!(direct_max <= rounding + 0.5 && direct_mean <= 0.3, "direct lookup: largest {direct_max}, mean {direct_mean} levels");

    // Through the cube map (64-texel faces, each averaging four lookups) the squares blur:
    // measured largest 63.9, mean 14.5 levels.
    compositor.set_equirect_background(gpu(), None).unwrap();
    assert!(!compositor.background_sees_equirect());
    let cube = compositor.render(gpu(), &params, Layer::Background).unwrap();
    let (cube_max, cube_mean) = differences(&cube, &want);
    eprintln!("through the cube map: largest difference {cube_max:.2}, mean {cube_mean:.3} levels");
    assert!(cube_mean > 5.0 * direct_mean && cube_max > 20.0, "cube map: largest {cube_max}, mean {cube_mean} levels");

    // Across the map's seam (u = 0 and 1 meet at azimuth 25° + 180°) and up at the zenith, where
    // the rows stop (the sampler wraps in u and clamps in v, as Equirect::sample_uv does).
    compositor.set_equirect_background(gpu(), Some(map)).unwrap();
    for (heading, pitch) in [(205.0f32, 0.0f32), (205.0, 80.0), (10.0, -80.0)] {
        let mut p = params;
        p.camera.pose = previz::render::view::camera_pose(heading.to_radians(), pitch.to_radians(), 0.0);
        let want = expected(map, &p.camera, (w, h), 25f32.to_radians(), 0.8, n);
        let (max, mean) = differences(&compositor.render(gpu(), &p, Layer::Background).unwrap(), &want);
        eprintln!("heading {heading}°, pitch {pitch}°: largest difference {max:.2}, mean {mean:.3} levels");
        assert!(max <= 1.0 && mean <= 0.3, "heading {heading}°, pitch {pitch}°: largest {max}, mean {mean} levels");
    }

    // Set again, then a new environment: the cube map is seen until its equirect is set again.
    compositor.set_equirect_background(gpu(), Some(map)).unwrap();
    assert_eq!(differences(&compositor.render(gpu(), &params, Layer::Background).unwrap(), &want), (direct_max, direct_mean));
    compositor.set_environment(gpu(), &inputs.env, 0.8, 25f32.to_radians()).unwrap();
    assert!(!compositor.background_sees_equirect());
}

#[test]
fn an_equirect_file_keeps_its_image_and_a_face_folder_has_none() {
    let path = data("hdri/polyhaven_1k/quarry_01_1k.hdr");
    let (cube, equirect) = load_environment_and_equirect(&path).unwrap();
    let equirect = equirect.expect("an .hdr is equirectangular");
    assert_eq!((equirect.width(), equirect.height()), (1024, 512));
    let plain = load_environment(&path).unwrap();
    assert_eq!(cube.size, 256);
    assert!(cube.size == plain.size && cube.faces == plain.faces, "the same cube map as load_environment");
    let (faces, none) = load_environment_and_equirect(&data("cubemaps/humus_Bridge2")).unwrap();
    assert!(none.is_none());
    assert_eq!(faces.faces, load_environment(&data("cubemaps/humus_Bridge2")).unwrap().faces);
    let Err(missing) = load_environment_and_equirect(&data("hdri/no_such_map.hdr")) else { panic!("a missing file loads") };
    assert!(format!("{missing:#}").contains("no_such_map.hdr"), "{missing:#}");
}

/// The background pass loads each pixel's own texel of the camera image (shaders/background.wgsl):
/// a background-only frame is the image, byte for byte, with one sample per pixel (the live view
/// on lavapipe) and with 4× MSAA (stills). The image is noise at the pixel scale and its size odd,
/// so a lookup off by a pixel or half of one, a filter, or a flip would show.
#[test]
fn a_photograph_background_comes_out_pixel_for_pixel() {
    use previz::render::Antialiasing;
    use previz::scene::Rgba8Image;
    let (w, h) = (97u32, 61u32);
    let mut state = 0x2545_f491_u32;
    let mut next = || {
        // xorshift32: a fixed, reproducible noise.
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let pixels: Vec<u8> = (0..w * h).flat_map(|_| (next().to_le_bytes()[..3].to_vec()).into_iter().chain([255])).collect();
    let image = Rgba8Image { width: w, height: h, pixels };
    let s = scene(&format!("width = {w}\nheight = {h}\n"));
    let env = common::east_red_west_blue(16);
    let inputs = Inputs { model: triangle(), env, env_equirect: None, background: Some(image.clone()) };
    for aa in [Antialiasing::Msaa(1), Antialiasing::STILL] {
        let (mut compositor, params) = previz::setup::prepare_antialiased(gpu(), &s, &inputs, aa).unwrap();
        let frame = compositor.render(gpu(), &params, Layer::Background).unwrap();
        let differ = frame.rgba.chunks_exact(4).zip(image.pixels.chunks_exact(4)).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{aa:?}: {differ} of {} pixels differ from the image", w * h);
    }
}
