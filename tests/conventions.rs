//! Tests that would catch a wrong convention: cube-map face mapping seen through the camera and
//! through reflection, the sun's side, the hemisphere's sky, camera tilt.

use crate::common;

use common::{mean_rgb, render_with, scene};
use previz::render::{Layer, Rendered};
use previz::scene::{CubeMap, Material, Mesh, Model};
use previz::setup::Inputs;

/// Cube map whose faces are solid colours (linear), in wgpu order +X, −X, +Y, −Y, +Z, −Z.
fn solid_cube(colours: [[f32; 3]; 6]) -> CubeMap {
    let size = 8;
    CubeMap { size, faces: colours.map(|c| vec![c; (size * size) as usize]) }
}

const RED: [f32; 3] = [1.0, 0.0, 0.0];
const CYAN: [f32; 3] = [0.0, 1.0, 1.0];
const GREEN: [f32; 3] = [0.0, 1.0, 0.0];
const MAGENTA: [f32; 3] = [1.0, 0.0, 1.0];
const BLUE: [f32; 3] = [0.0, 0.0, 1.0];
const YELLOW: [f32; 3] = [1.0, 1.0, 0.0];
/// +X East red, −X West cyan, +Y Up green, −Y Down magenta, +Z North blue, −Z South yellow.
const FACES: [[f32; 3]; 6] = [RED, CYAN, GREEN, MAGENTA, BLUE, YELLOW];

fn sphere() -> Model {
    let mut mesh = Mesh::default();
    let (stacks, slices) = (64u32, 128u32);
    for i in 0..=stacks {
        let theta = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / slices as f32;
            let n = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
            mesh.positions.push(n);
            mesh.normals.push(n);
        }
    }
    for i in 0..stacks {
        for j in 0..slices {
            let a = i * (slices + 1) + j;
            let b = a + slices + 1;
            mesh.indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    Model { meshes: vec![mesh], materials: vec![Material { diffuse: [0.8, 0.8, 0.8], specular: [0.0; 3], ..Default::default() }] }
}

/// Which face colour a pixel shows (nearest of the six, in 8-bit sRGB).
fn nearest_face(p: [f64; 3]) -> usize {
    let dist = |c: [f32; 3]| (0..3).map(|i| (p[i] - 255.0 * f64::from(c[i])).powi(2)).sum::<f64>();
    (0..6).min_by(|&a, &b| dist(FACES[a]).total_cmp(&dist(FACES[b]))).unwrap()
}

fn patch(r: &Rendered, fx: f64, fy: f64) -> [f64; 3] {
    let x = (fx * f64::from(r.width)) as u32;
    let y = (fy * f64::from(r.height)) as u32;
    mean_rgb(r, x - 2, y - 2, x + 3, y + 3)
}

/// Apparent radius of the auto-placed unit sphere, as a fraction of the (square) image side:
/// its bounding box's sphere (radius √3 · scale) spans `fill` of the field of view.
fn sphere_radius() -> f64 {
    let s = scene("width = 240\nheight = 240\n");
    let vfov = s.camera.vfov.to_radians();
    let scale = s.placement.size / 2.0;
    let distance = 3f64.sqrt() * scale / (s.placement.fill * vfov * 0.5).tan();
    ((scale / distance).asin().tan() / (vfov * 0.5).tan()) * 0.5
}

fn render(toml: &str, env: CubeMap, layer: Layer) -> Rendered {
    let s = scene(&format!("width = 240\nheight = 240\n{toml}"));
    render_with(&s, &Inputs { model: sphere(), env, env_equirect: None, background: None }, layer)
}

#[test]
fn environment_seen_by_the_camera_shows_the_right_faces() {
    for (heading, pitch, face) in
        [(0.0, 0.0, 4), (90.0, 0.0, 0), (180.0, 0.0, 5), (270.0, 0.0, 1), (-90.0, 0.0, 1), (0.0, 89.0, 2), (0.0, -89.0, 3)]
    {
        let r = render(&format!("[camera]\nheading = {heading}\npitch = {pitch}\n"), solid_cube(FACES), Layer::Background);
        assert_eq!(nearest_face(patch(&r, 0.5, 0.5)), face, "heading {heading} pitch {pitch}");
    }
    // Looking North with a wide lens: East (+X, red) at the right edge, West (cyan) at the left.
    let r = render("[camera]\nvfov = 120.0\n", solid_cube(FACES), Layer::Background);
    assert_eq!(nearest_face(patch(&r, 0.98, 0.5)), 0);
    assert_eq!(nearest_face(patch(&r, 0.02, 0.5)), 1);
    assert_eq!(nearest_face(patch(&r, 0.5, 0.02)), 2);
    assert_eq!(nearest_face(patch(&r, 0.5, 0.98)), 3);
}

#[test]
fn environment_heading_rotates_the_map() {
    // A map whose front (+Z) faces East: looking East shows the front face.
    let r = render("[camera]\nheading = 90.0\n[env]\nheading = 90.0\n", solid_cube(FACES), Layer::Background);
    assert_eq!(nearest_face(patch(&r, 0.5, 0.5)), 4);
}

#[test]
fn mirror_sphere_reflects_known_directions() {
    // A perfect mirror looking North: the centre reflects the camera's own direction back
    // (South, yellow); where the normal is 45° right (East-South) the reflection points East
    // (red); 45° up -> Up (green); left -> West (cyan); down -> Down (magenta).
    let r = render("method = \"cube-reflection\"\n[effects]\nreflection = 1.0\n", solid_cube(FACES), Layer::Model);
    let (cx, cy) = (0.5, 0.5);
    let off = sphere_radius() * 0.707;
    assert_eq!(nearest_face(patch(&r, cx, cy)), 5, "centre");
    assert_eq!(nearest_face(patch(&r, cx + off, cy)), 0, "right");
    assert_eq!(nearest_face(patch(&r, cx - off, cy)), 1, "left");
    assert_eq!(nearest_face(patch(&r, cx, cy - off)), 2, "top");
    assert_eq!(nearest_face(patch(&r, cx, cy + off)), 3, "bottom");
}

/// Linear-light BT.709 luminance of an 8-bit sRGB colour.
fn luma(p: [f64; 3]) -> f64 {
    let lin = p.map(|c| f64::from(previz::colour::srgb_to_linear((c / 255.0) as f32)));
    0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]
}

fn linear(p: [f64; 3]) -> [f64; 3] {
    p.map(|c| f64::from(previz::colour::srgb_to_linear((c / 255.0) as f32)))
}

/// A grey sky of 32² faces with a small bright sun (2×2 texels, radiance 500) just above the
/// horizon at the centre of `face`: the sun the light comes from (setup::light finds it).
fn grey_with_sun(face: usize) -> CubeMap {
    let size = 32;
    let mut cube = CubeMap { size, faces: [[0.3f32; 3]; 6].map(|c| vec![c; (size * size) as usize]) };
    for y in 12..14 {
        for x in 15..17 {
            cube.faces[face][(y * size + x) as usize] = [500.0; 3];
        }
    }
    cube
}

#[test]
fn sun_from_the_left_lights_the_left_side() {
    let off = 0.7 * sphere_radius();
    // Camera looks North, so its left is West; the map's sun is in the West (−X face), a little
    // up, and dominates the ambient.
    let r = render("method = \"blinn-phong\"\n[sun]\ndaylight = 0.2\n", grey_with_sun(1), Layer::Model);
    let left = luma(patch(&r, 0.5 - off, 0.5));
    let right = luma(patch(&r, 0.5 + off, 0.5));
    assert!(left > 2.0 * right, "left {left} right {right}");
    // And from the right (East) the other way round.
    let r = render("method = \"blinn-phong\"\n[sun]\ndaylight = 0.2\n", grey_with_sun(0), Layer::Model);
    let left = luma(patch(&r, 0.5 - off, 0.5));
    let right = luma(patch(&r, 0.5 + off, 0.5));
    assert!(right > 2.0 * left, "left {left} right {right}");
}

#[test]
fn hemisphere_sky_colour_dominates_upward_normals_at_any_tilt() {
    let grey = [0.2; 3];
    let env = || solid_cube([grey, grey, RED, BLUE, grey, grey]);
    let base = "method = \"hemisphere\"\n[sun]\nsunlight = 0.0\n";
    let off = 0.8 * sphere_radius();
    // In linear light the blend a = 0.5 + 0.5 cos(angle to Up) is 0.9 at 0.8 of the radius
    // (cos = 0.8), so the sky's red is 9 times the ground's blue there.
    let dominated = |p: [f64; 3], by: usize, over: usize| {
        let l = linear(p);
        l[by] > 4.0 * l[over]
    };
    let r = render(base, env(), Layer::Model);
    let (top, bottom) = (patch(&r, 0.5, 0.5 - off), patch(&r, 0.5, 0.5 + off));
    assert!(dominated(top, 0, 2), "top {top:?}");
    assert!(dominated(bottom, 2, 0), "bottom {bottom:?}");
    // Roll the camera 90° clockwise: world Up appears at the image's left.
    let r = render(&format!("{base}[camera]\nroll = 90.0\n"), env(), Layer::Model);
    let (left, right) = (patch(&r, 0.5 - off, 0.5), patch(&r, 0.5 + off, 0.5));
    assert!(dominated(left, 0, 2), "left {left:?}");
    assert!(dominated(right, 2, 0), "right {right:?}");
    // Pitch down 60° (looking down on the sphere): the image centre now shows a normal 60°
    // from Up (a = 0.75: red three times blue), still sky-dominated.
    let r = render(&format!("{base}[camera]\npitch = -60.0\n"), env(), Layer::Model);
    let centre = linear(patch(&r, 0.5, 0.5));
    assert!(centre[0] > 2.0 * centre[2], "pitched {centre:?}");
}

#[test]
fn an_overcast_sky_darkens_the_ground_under_the_model_and_nowhere_else() {
    // A uniform grey sky: no sun, all of the ground's light comes from the sky, so where the
    // model hides a share of the (cosine-weighted) sky the ground keeps the rest.
    let s = scene("width = 240\nheight = 240\nmethod = \"sh9-ggx\"\n[camera]\npitch = -30.0\n");
    // A black sphere: it reflects no light onto the ground (render::passes::ground::bounce_light),
    // so the ground keeps exactly the sky it does not hide.
    let mut black = sphere();
    black.materials.iter_mut().for_each(|m| m.diffuse = [0.0; 3]);
    let inputs = Inputs { model: black, env: solid_cube([[0.3; 3]; 6]), env_equirect: None, background: None };
    let (mut compositor, params) = previz::setup::prepare(common::gpu(), &s, &inputs).unwrap();
    assert_eq!(params.lighting.shadow_opacity, 0.0);
    assert!((params.lighting.sky_occlusion - 1.0).abs() < 1e-6, "{}", params.lighting.sky_occlusion);
    let [composite, background, model] =
        [Layer::Composite, Layer::Background, Layer::Model].map(|l| compositor.render(common::gpu(), &params, l).unwrap());
    let view_proj = glam::Mat4::from_cols_array_2d(&compositor.frame_uniforms(&params).unwrap().frame.view_proj);
    let pixel_of = |p: glam::Vec3| {
        let ndc = view_proj.project_point3(p);
        ((ndc.x * 0.5 + 0.5) * 240.0, (0.5 - ndc.y * 0.5) * 240.0)
    };
    let at = |r: &Rendered, (x, y): (f32, f32)| mean_rgb(r, x as u32 - 1, y as u32 - 1, x as u32 + 2, y as u32 + 2);
    // The unit sphere scaled by R rests on the ground at the placement's position. From a ground
    // point x from the contact the sphere is a cap of angular radius asin(R/D), D = √(x² + R²),
    // touching the horizon, whose centre is at elevation asin(R/D): its cosine-weighted share
    // of the sky is sin²(radius)·sin(elevation) = (R/D)³, so the ground keeps 1 − (R/D)³.
    // (Measured 2026-12-01: within 0.011 at these five points; 64 rays a texel, 8-bit output.)
    let (r, contact) = (params.placement.scale, params.placement.position);
    // The default grey sphere (albedo 0.8) in the same light reflects some of it back: every
    // surface it shows a ground point gets at most the ground's own light (sky and ground below
    // of the same radiance), so the ground keeps more than under the black one and at most
    // 1 − F + 0.8 F.
    let grey = Inputs { model: sphere(), env: solid_cube([[0.3; 3]; 6]), env_equirect: None, background: None };
    let (mut grey_compositor, grey_params) = previz::setup::prepare(common::gpu(), &s, &grey).unwrap();
    let grey_composite = grey_compositor.render(common::gpu(), &grey_params, Layer::Composite).unwrap();
    for (dx, dy) in [(1.6f32, 0.0f32), (-1.6, 0.0), (0.0, -1.5), (2.2, 0.0), (0.0, -2.5)] {
        let p = contact + glam::Vec3::new(dx, dy, 0.0) * r;
        let px = pixel_of(p);
        assert_eq!(at(&model, px), [0.0; 3], "the ground point ({dx}, {dy})·R is hidden by the sphere");
        let kept = luma(at(&composite, px)) / luma(at(&background, px));
        let hidden = f64::from(1.0 / (1.0 + dx * dx + dy * dy)).powf(1.5);
        let expected = 1.0 - hidden;
        assert!((kept - expected).abs() < 0.025, "ground at ({dx}, {dy})·R keeps {kept:.3} of its light, expected {expected:.3}");
        let kept_grey = luma(at(&grey_composite, px)) / luma(at(&background, px));
        assert!(
            kept_grey > kept + 0.01 && kept_grey <= 1.0 - 0.2 * hidden + 0.025,
            "grey sphere: ({dx}, {dy})·R keeps {kept_grey:.3}, black {kept:.3}"
        );
    }
    // Far from the model the ground keeps all of it: every pixel outside the model that the
    // composite darkens lies within the ground square of twice the model's height around it
    // (scene::occlusion::ground_square: half side 5R), seen from the camera.
    let corners = [(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)].map(|(x, y)| pixel_of(contact + glam::Vec3::new(x, y, 0.0) * r));
    let (lo, hi) = corners
        .iter()
        .fold(((f32::MAX, f32::MAX), (f32::MIN, f32::MIN)), |(lo, hi), &(x, y)| ((lo.0.min(x), lo.1.min(y)), (hi.0.max(x), hi.1.max(y))));
    let mut darkened = 0;
    for y in 0..240u32 {
        for x in 0..240u32 {
            let i = 4 * (y * 240 + x) as usize;
            if model.rgba[i + 3] == 0 && composite.rgba[i..i + 3] != background.rgba[i..i + 3] {
                darkened += 1;
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                assert!(fx >= lo.0 - 1.0 && fx <= hi.0 + 1.0 && fy >= lo.1 - 1.0 && fy <= hi.1 + 1.0, "pixel ({x}, {y}) darkened far away");
            }
        }
    }
    assert!(darkened > 500, "only {darkened} pixels of ground darkened");
    // Moved without turning, the model takes its map along (the compositor does not compute it
    // again): the same frame as a compositor that computes it at the new place.
    let mut moved = params;
    moved.placement.position += glam::Vec3::new(0.7, 0.4, 0.0) * r;
    let updates = compositor.ground_sky_updates();
    let reused = compositor.render(common::gpu(), &moved, Layer::Composite).unwrap();
    assert_eq!(compositor.ground_sky_updates(), updates);
    let (mut fresh, _) = previz::setup::prepare(common::gpu(), &s, &inputs).unwrap();
    let computed = fresh.render(common::gpu(), &moved, Layer::Composite).unwrap();
    let worst = reused.rgba.iter().zip(&computed.rgba).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    assert!(worst <= 1, "the moved map differs from one computed in place by {worst} levels");
}
