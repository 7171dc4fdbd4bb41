//! The live view's reprojection (render::reprojection): a frame that only turned the camera
//! composes the last shaded frame's model and ground through the turn. Checked against the same
//! frames shaded in full (a compositor without reprojection, or the live session's pass-by-pass
//! path, which never reprojects), with issue 11's accuracy budget for what a frame may give up
//! for its cost: mean FLIP ≤ 0.01 against the full render.

use crate::common;

use common::{gpu, scene};
use previz::capture::replay::mean_flip;
use previz::live::{LiveConfig, LiveSession};
use previz::render::{Antialiasing, Compositor, Detail, FrameParams, Layer, Rendered};
use previz::scene::Rgba8Image;
use previz::sensors::sim::NoiseLevel;
use previz::setup::{Inputs, load_inputs, prepare_antialiased, prepare_reprojected};
use std::sync::Arc;

/// Issue 11: "mean FLIP ≤ 0.01 against the full-detail, full-shadow render".
const FLIP_BUDGET: f32 = 0.01;

fn rgb(r: &Rendered) -> Vec<u8> {
    r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

fn flip(reference: &Rendered, test: &Rendered) -> f32 {
    mean_flip(&rgb(reference), &rgb(test), test.width, test.height).unwrap()
}

#[test]
fn the_live_view_reprojects_while_the_user_looks_around_within_the_flip_budget() {
    let (frames, n) = (24, live_view_against_the_full_render(false, 24, 1.000_001));
    // The user turns the phone by under a pixel to a few pixels a frame, within the layers'
    // margin: most frames reproject (the first shades, and each fold of the camera frame into
    // the environment changes the light).
    assert!(n >= frames * 4 / 5, "{n} of {frames} frames reprojected");
}

#[test]
fn with_a_capture_of_the_place_the_sun_follows_the_clock_in_steps_and_turns_reproject() {
    // The environment a capture of here and now: SPA's sun for the clock lights every frame
    // and moves a little each frame; the session takes it again once it has moved by a step
    // (setup::light::sun_step), so the frames between differ only by the camera's turn.
    let (frames, n) = (12, live_view_against_the_full_render(true, 12, 1.000_002));
    assert!(n >= frames * 4 / 5, "{n} of {frames} frames reprojected");
}

/// The demo (the truck on the lawn, 960×640), held by the simulated user of `bench live` (a look
/// around the truck with the hand's tremor, phone-grade sensors), its environment a capture of
/// the place or not: `frames` frames each against issue 11's reference with the exact sun,
/// within the FLIP budget whether reprojected or shaded. Returns how many reprojected. The
/// truck is scaled by `scale` (a millionth or two): a model no other test in this process draws
/// (the device's model cache holds one ground map per model, which a frame must find unchanged
/// to reproject, and other tests draw the truck at other placements).
fn live_view_against_the_full_render(captured_here: bool, frames: usize, scale: f32) -> usize {
    let s = scene(&format!("{}[env]\ncaptured_here = {captured_here}\n", previz::scene::demo::SCENE_TOML));
    let mut inputs = load_inputs(&s, true).unwrap();
    for p in inputs.model.meshes.iter_mut().flat_map(|m| m.positions.iter_mut()) {
        *p = p.map(|c| c * scale);
    }
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: 2.0,
        noise: NoiseLevel::Phone,
        seed: 1,
    };
    let mut session = LiveSession::simulated(gpu(), Arc::new(inputs.env.clone()), &inputs.model, &s, cfg).unwrap();
    // Issue 11's reference: full detail and the full shadow (the largest map, looked up over the
    // whole ground, not fitted to the view as a frame's is), over the same camera image, and lit
    // by the sun where SPA has it at the frame's instant (the frame lights with the held one).
    let (mut reference, _) = prepare_antialiased(gpu(), &s, &inputs, Antialiasing::Msaa(1)).unwrap();
    reference.set_detail(Detail::Full);
    reference.set_full_shadow(true);
    let (mut reprojected, mut shaded) = (Vec::new(), Vec::new());
    while reprojected.len() + shaded.len() < frames {
        let f = session.advance(gpu()).unwrap().expect("the session ended early");
        let frame = session.render(gpu()).unwrap();
        reference.set_background(gpu(), session.camera_image()).unwrap();
        let mut exact = *session.params();
        if captured_here {
            let lit = exact.lighting.sun_dir;
            exact.lighting.sun_dir = f.sun.direction_enu();
            let off = previz::setup::light::sun_turn(lit, exact.lighting.sun_dir);
            assert!(off <= f64::from(previz::setup::light::MAX_SUN_STEP_RAD) * 1.001, "the frame's sun is {off} rad from SPA's");
        }
        let truth = reference.render(gpu(), &exact, Layer::Composite).unwrap();
        let e = flip(&truth, &frame);
        if frame.timings.reprojected {
            reprojected.push(e);
        } else {
            // The same frame shaded in full (pass by pass, which never reprojects).
            session.set_pass_timing(true);
            let full = session.render(gpu()).unwrap();
            session.set_pass_timing(false);
            assert_shaded_as_drawn(&full, &frame, &format!("frame {}", shaded.len() + reprojected.len()));
            shaded.push(e);
        }
    }
    let n = reprojected.len();
    assert_eq!(session.compositor().reprojection_counts(), (n, frames - n));
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
    let (r, sh) = (mean(&reprojected), mean(&shaded));
    assert!(r <= FLIP_BUDGET, "reprojected frames: mean FLIP {r} against the full render (shaded frames: {sh})");
    assert!(sh <= FLIP_BUDGET, "shaded frames: mean FLIP {sh} against the full render");
    eprintln!("captured here {captured_here}: {n} of {frames} reprojected, mean FLIP {r} (reprojected), {sh} (shaded)");
    n
}

/// A frame that shaded its layers composes them as it drew them, nothing shifted: the same
/// light and shadow (the wider view may pick another shadow map size), the ground's matte
/// rounded once more (8-bit sRGB, packed with the model: render::reprojection::packed_clear),
/// which moves a value by at most one level, and within the FLIP budget.
fn assert_shaded_as_drawn(full: &Rendered, frame: &Rendered, what: &str) {
    let (a, b) = (rgb(full), rgb(frame));
    let within = a.iter().zip(&b).filter(|(x, y)| x.abs_diff(**y) <= 1).count() as f64 / a.len() as f64;
    assert!(within >= 0.995, "{what}: {:.3} % of values within one level", 100.0 * within);
    let e = flip(full, frame);
    assert!(e <= FLIP_BUDGET, "{what}: shaded frame FLIP {e}");
}

/// A sphere of `rings` on the Park2 lawn at 240×160 over a camera image (a reprojected frame
/// needs one). Each test draws a sphere no other test draws: the device's model cache (the
/// ground's map for a placement, which a frame must find unchanged to reproject) is shared by
/// every test in the process, and one test turning its model while another drew the same one
/// made the other's next frame shade (seen once in a full run under load).
fn sphere(rings: u32) -> (previz::setup::scene_file::Scene, Inputs) {
    let s = scene(
        "width = 240\nheight = 160\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
         [camera]\nheading = 90.0\npitch = -8.0\n",
    );
    let mut inputs = common::inputs(&s);
    let material = previz::scene::Material { diffuse: [0.7, 0.55, 0.3], ..Default::default() };
    inputs.model = common::uv_sphere(rings, material);
    // A camera image with detail everywhere (what the ground darkens and the model covers).
    let pixels = (0..s.width * s.height)
        .flat_map(|i| {
            let (x, y) = (i % s.width, i / s.width);
            [(40 + (x * 7 + y * 3) % 160) as u8, (60 + (x * 5) % 150) as u8, (30 + (y * 11) % 170) as u8, 255]
        })
        .collect();
    inputs.background = Some(Rgba8Image { width: s.width, height: s.height, pixels });
    (s, inputs)
}

fn turned(p: &FrameParams, heading_deg: f32, pitch_deg: f32) -> FrameParams {
    let mut q = *p;
    q.camera.pose =
        glam::Quat::from_rotation_z(-heading_deg.to_radians()) * p.camera.pose * glam::Quat::from_rotation_x(pitch_deg.to_radians());
    q
}

/// Of the pixels where `full` shows the model or its ground (differs from `background` by more
/// than `tol` levels), the share where some pixel of `test` within one pixel (its 3×3
/// neighbourhood) matches it to `tol` levels in every channel: a frame drawn from layers through
/// a turn reads each pixel from the layer texel nearest where the turn takes it, so its content
/// sits within half a pixel (a pixel diagonally) of where the full render has it.
fn within_a_pixel(full: &Rendered, test: &Rendered, background: &[u8], tol: u8) -> f64 {
    let (w, h) = (i64::from(full.width), i64::from(full.height));
    let at = |r: &[u8], x: i64, y: i64| -> [u8; 3] {
        let i = 4 * (y * w + x) as usize;
        [r[i], r[i + 1], r[i + 2]]
    };
    let close = |a: [u8; 3], b: [u8; 3]| a.iter().zip(&b).all(|(u, v)| u.abs_diff(*v) <= tol);
    let (mut content, mut matched) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let f = at(&full.rgba, x, y);
            if close(f, at(background, x, y)) {
                continue;
            }
            content += 1;
            let near = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)));
            let mut inside = near.filter(|&(u, v)| (0..w).contains(&u) && (0..h).contains(&v));
            matched += usize::from(inside.any(|(u, v)| close(at(&test.rgba, u, v), f)));
        }
    }
    matched as f64 / content.max(1) as f64
}

#[test]
fn a_turned_frame_puts_everything_within_a_pixel_of_the_full_render_multisampled_or_not() {
    let (s, inputs) = sphere(29);
    for aa in [Antialiasing::Msaa(1), Antialiasing::Msaa(4)] {
        let (mut live, p) = prepare_reprojected(gpu(), &s, &inputs, aa).unwrap();
        let (mut frame, _) = prepare_antialiased(gpu(), &s, &inputs, aa).unwrap();
        let first = live.render(gpu(), &p, Layer::Composite).unwrap();
        assert!(!first.timings.reprojected, "{aa:?}: the first frame shades");
        assert_shaded_as_drawn(&frame.render(gpu(), &p, Layer::Composite).unwrap(), &first, &format!("{aa:?}"));
        for (h, v) in [(1.5, 0.0), (-3.0, 1.0), (2.0, -2.5)] {
            let q = turned(&p, h, v);
            let reprojected = live.render(gpu(), &q, Layer::Composite).unwrap();
            assert!(reprojected.timings.reprojected, "{aa:?}: turned {h}°, {v}°");
            let full = frame.render(gpu(), &q, Layer::Composite).unwrap();
            let background = &inputs.background.as_ref().unwrap().pixels;
            let share = within_a_pixel(&full, &reprojected, background, 12);
            // Measured: 99.0–99.5 % at one sample a pixel, 95.9–96.4 % with 4× MSAA, whose edge
            // pixels blend the model with what is behind it at the layers' sample positions;
            // the rest are where the frame's shadow map, fitted to each view, moved an edge.
            assert!(share >= 0.93, "{aa:?}: turned {h}°, {v}°: {:.2} % within a pixel", 100.0 * share);
            // The check can fail: the layers as drawn, not turned (the model and its shadow a few
            // pixels off: f·tan 1.5° is 3.5 px here) match 51–83 %.
            let unturned = within_a_pixel(&full, &first, background, 12);
            assert!(unturned < 0.85, "{aa:?}: turned {h}°, {v}°: the unturned frame matched {:.2} %", 100.0 * unturned);
        }
    }
}

#[test]
fn anything_but_a_turn_of_the_camera_shades_again() {
    let (s, inputs) = sphere(31);
    let (mut live, p): (Compositor, FrameParams) = prepare_reprojected(gpu(), &s, &inputs, Antialiasing::Msaa(1)).unwrap();
    let mut render = |q: &FrameParams| live.render(gpu(), q, Layer::Composite).unwrap().timings.reprojected;
    assert!(!render(&p));
    assert!(render(&turned(&p, 2.0, 0.0)));
    // Past the turn limit (render::reprojection::MAX_TURN_DEG), the model turned, the sun moved,
    // the camera moved: each shades, and the frame after it reprojects again.
    let mut placed = p;
    placed.placement.rotation.z += 0.05;
    let mut sun = p;
    sun.lighting.sun_dir = (sun.lighting.sun_dir + glam::Vec3::new(0.05, 0.0, 0.0)).normalize();
    let mut moved = p;
    moved.camera.position.z += 0.05;
    for (what, q) in
        [("a 12° turn", turned(&p, 12.0, 0.0)), ("the model turned", placed), ("the sun moved", sun), ("the camera moved", moved)]
    {
        assert!(!render(&q), "{what} reprojected");
        assert!(render(&turned(&q, 0.5, 0.0)), "after {what}: a small turn did not reproject");
    }
}
