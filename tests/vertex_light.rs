//! The model's whole light from its vertices (render::passes::model::Shading::LightFromVertices):
//! a mesh whose triangles are a few pixels on screen is lit at its vertices and the light
//! interpolated, and looks as the per-pixel light does; a mesh of larger triangles keeps the
//! per-pixel light, byte for byte.

use crate::common;

use common::gpu;
use previz::render::passes::model::MAX_LIGHT_EDGE_PX;
use previz::render::{Antialiasing, Compositor, Detail, FrameParams, Layer};
use previz::scene::{Material, Model};

/// A matte orange, a glossy blue (GGX roughness 0.52 from the Blinn-Phong exponent 25:
/// light::ggx::roughness_from_exponent) and a shinier blue (exponent 100, roughness 0.37).
fn materials() -> [(&'static str, Material); 4] {
    [
        ("matte", Material { diffuse: [0.8, 0.35, 0.1], specular: [0.0; 3], ..Material::default() }),
        ("glossy", Material { diffuse: [0.1, 0.2, 0.6], specular: [0.5; 3], shininess: 25.0, ..Material::default() }),
        ("shiny", Material { diffuse: [0.1, 0.2, 0.6], specular: [0.5; 3], shininess: 100.0, ..Material::default() }),
        ("default", Material::default()),
    ]
}

/// A frame of `model` in the sunny quarry (its own sun, sky and ground), sh9-ggx, one sample a
/// pixel, every triangle drawn (so the tessellation is the sphere's own), the model `fill` of
/// the view high; two compositors: the light from the vertices allowed on every mesh that takes
/// the sun from them (`rule`: as the default limits allow it), and on none.
fn set_up(model: Model, size: u32, fill: f32, rule: bool) -> ([Compositor; 2], FrameParams) {
    let scene = common::scene(&format!(
        "environment = \"hdri/polyhaven_1k/quarry_01_1k.hdr\"\nwidth = {size}\nheight = {}\nmethod = \"sh9-ggx\"\n[placement]\nfill = {fill}\n",
        size * 3 / 4
    ));
    let mut inputs = common::inputs(&scene);
    inputs.model = model;
    let make = |limits: (f32, f32)| {
        let (mut c, p) = previz::setup::prepare_antialiased(gpu(), &scene, &inputs, Antialiasing::Msaa(1)).unwrap();
        c.set_detail(Detail::Full);
        c.set_light_limits(limits.0, limits.1);
        (c, p)
    };
    let (per_vertex, p) = make(if rule { (MAX_LIGHT_EDGE_PX, 1.0) } else { (f32::INFINITY, f32::INFINITY) });
    let (per_pixel, _) = make((0.0, 1.0));
    ([per_vertex, per_pixel], p)
}

/// Mean FLIP over the model's pixels (its layer's coverage) of the frame with the light from
/// the vertices against the per-pixel frame, the share of those pixels that differ by more than
/// two 8-bit levels, and the mesh's longest edge on screen as the rule measures it (pixels).
struct Compared {
    flip: f64,
    differ: f64,
    edge_px: f32,
    turn: f32,
    per_vertex: bool,
    identical: bool,
}

fn compare(cs: &mut [Compositor; 2], p: &FrameParams) -> Compared {
    let [a, b] = cs;
    let with = a.render(gpu(), p, Layer::Composite).unwrap();
    let (turn, per_vertex) = a.light_per_mesh()[0];
    let edge_px = a.sun_per_mesh()[0].0.unwrap();
    let without = b.render(gpu(), p, Layer::Composite).unwrap();
    assert!(!b.light_per_mesh()[0].1);
    let coverage = b.render(gpu(), p, Layer::Model).unwrap();
    let mask: Vec<bool> = coverage.rgba.chunks_exact(4).map(|px| px[3] == 255).collect();
    let rgb = |rgba: &[u8]| rgba.chunks_exact(4).flat_map(|px| [px[0], px[1], px[2]]).collect::<Vec<u8>>();
    let map = previz::bench::accuracy::flip_map(&rgb(&without.rgba), &rgb(&with.rgba), with.width, with.height).unwrap();
    let flip = f64::from(previz::bench::accuracy::masked_mean(&map, &mask));
    let covered = mask.iter().filter(|&&m| m).count();
    assert!(covered > 1000, "the model covers {covered} pixels");
    let differ = with
        .rgba
        .chunks_exact(4)
        .zip(without.rgba.chunks_exact(4))
        .zip(&mask)
        .filter(|((x, y), m)| **m && x.iter().zip(y.iter()).any(|(u, v)| u.abs_diff(*v) > 2))
        .count() as f64
        / covered as f64;
    Compared { flip, differ, edge_px, turn, per_vertex, identical: with.rgba == without.rgba }
}

/// Within the limits, the light from the vertices looks as the per-pixel light does: over the
/// sphere's pixels, mean FLIP within the budget [`previz::render::passes::model::MAX_MATTE_LIGHT_TURN`]
/// names (0.05) for a matte, a glossy, a shinier and the default material, and it is used;
/// past them the mesh is lit per pixel and the frame is the per-pixel one byte for byte. At
/// 320×240, 10 rings put the sphere's edges past the limit, 16 rings its normal's turn (14.4°)
/// past the shinier material's limit (12.8°) and within the others', 48 and 96 rings within
/// every limit. Measured (2026-12-02): see the printed values.
#[test]
fn small_triangles_take_their_light_from_their_vertices() {
    let mut used = 0;
    for (name, material) in materials() {
        for rings in [10, 16, 48, 96] {
            let (mut cs, p) = set_up(common::uv_sphere(rings, material.clone()), 320, 0.5, true);
            let c = compare(&mut cs, &p);
            println!(
                "{name}, {rings} rings: edges {:.1} px, normal turn {:.1}°, from the vertices {}, mean FLIP {:.4}, {:.1} % of pixels differ by > 2 levels",
                c.edge_px,
                c.turn,
                c.per_vertex,
                c.flip,
                100.0 * c.differ
            );
            if c.per_vertex {
                used += 1;
                assert!(c.edge_px <= MAX_LIGHT_EDGE_PX, "{name}, {rings} rings: edges {} px", c.edge_px);
                assert!(!c.identical, "{name}, {rings} rings: lit from the vertices, yet the per-pixel frame");
                assert!(c.flip < 0.05, "{name}, {rings} rings: mean FLIP {}", c.flip);
            } else {
                assert!(c.identical, "{name}, {rings} rings: lit per pixel, yet not the per-pixel frame");
            }
            if rings == 10 || (rings == 16 && name == "shiny") {
                assert!(!c.per_vertex, "{name}, {rings} rings: lit from the vertices");
            } else {
                assert!(c.per_vertex, "{name}, {rings} rings: lit per pixel");
            }
        }
    }
    assert_eq!(used, 11);
}

/// The measurement behind [`MAX_LIGHT_EDGE_PX`] and the turn limits (docs/PERFORMANCE.md,
/// sixteenth session): the sphere at tessellations from 10 to 96 rings, matte, glossy and
/// shiny, at 320×240 and 960×720, its light from its vertices whatever the limits (where it
/// takes the sun from them): the mesh's longest edge on screen and its normal's mean turn (the
/// rule's statistics) against the mean FLIP over the sphere of the light from the vertices
/// against the per-pixel light. Run:
/// `cargo test --release --test integration vertex_light:: -- --ignored --nocapture bench_vertex_light`.
#[test]
#[ignore = "a measurement; run it in release with --ignored --nocapture"]
fn bench_vertex_light() {
    println!(
        "| width | material | rings | edges on screen px | normal turn ° | mean FLIP over the sphere | pixels differing by > 2 levels |"
    );
    println!("|---:|---|---:|---:|---:|---:|---:|");
    for width in [320, 960] {
        for (name, material) in materials() {
            for rings in [10, 12, 16, 24, 32, 48, 64, 96] {
                let (mut cs, p) = set_up(common::uv_sphere(rings, material.clone()), width, 0.5, false);
                let c = compare(&mut cs, &p);
                println!("| {width} | {name} | {rings} | {:.1} | {:.1} | {:.4} | {:.1} % |", c.edge_px, c.turn, c.flip, 100.0 * c.differ);
            }
        }
    }
}

/// The same on `bench frame`'s dragon (960×640, the level of detail a frame draws): over the
/// dragon's pixels, the mean FLIP of the per-pixel frame and of the frame with the light from
/// the vertices, each against the full-detail per-pixel frame, and of the two against each
/// other: what the light from the vertices costs beside what the level of detail costs. Run as
/// [`bench_vertex_light`].
#[test]
#[ignore = "a measurement; run it in release with --ignored --nocapture"]
fn bench_vertex_light_dragon() {
    let shared = |rel: &str| format!("{}/../shared/data/{rel}", env!("CARGO_MANIFEST_DIR"));
    let scene = common::scene(&format!(
        "model = \"{}\"\nenvironment = \"{}\"\nbackground = \"{}\"\n",
        shared("meshes/stanford-dragon-100k.obj"),
        shared("cubemaps/pisa_ldr_png"),
        shared("photos/colour_transfer/coffee.png")
    ));
    let inputs = common::inputs(&scene);
    let frame = |detail: Detail, limit: f32| {
        let (mut c, p) = previz::setup::prepare_antialiased(gpu(), &scene, &inputs, Antialiasing::Msaa(1)).unwrap();
        c.set_detail(detail);
        c.set_light_limits(limit, 1.0);
        let r = c.render(gpu(), &p, Layer::Composite).unwrap();
        let model = c.render(gpu(), &p, Layer::Model).unwrap();
        println!(
            "{detail:?}, limit {limit}: level {}, per mesh {:?}, light from the vertices {:?}",
            c.lod_level(),
            c.sun_per_mesh(),
            c.light_per_mesh()
        );
        (r, model)
    };
    let (full, coverage) = frame(Detail::Full, 0.0);
    let (per_pixel, _) = frame(Detail::Frame, 0.0);
    let (per_vertex, _) = frame(Detail::Frame, MAX_LIGHT_EDGE_PX);
    let mask: Vec<bool> = coverage.rgba.chunks_exact(4).map(|px| px[3] > 0).collect();
    let rgb = |rgba: &[u8]| rgba.chunks_exact(4).flat_map(|px| [px[0], px[1], px[2]]).collect::<Vec<u8>>();
    let flip = |a: &[u8], b: &[u8]| {
        let map = previz::bench::accuracy::flip_map(&rgb(a), &rgb(b), full.width, full.height).unwrap();
        (previz::bench::accuracy::masked_mean(&map, &mask), previz::bench::accuracy::masked_mean(&map, &vec![true; mask.len()]))
    };
    println!("dragon pixels {}", mask.iter().filter(|&&m| m).count());
    println!("per pixel vs full detail (model, frame): {:?}", flip(&full.rgba, &per_pixel.rgba));
    println!("light from the vertices vs full detail: {:?}", flip(&full.rgba, &per_vertex.rgba));
    println!("light from the vertices vs per pixel: {:?}", flip(&per_pixel.rgba, &per_vertex.rgba));
}

/// The light at the vertices computed by the vertex-light pass is the vertex stage's: the first
/// frame of a view computes it in the vertex stage, the second (the same view) runs the pass
/// and reads its buffer, and later frames read that buffer while the camera only turns, with
/// no pass; each frame within one 8-bit level of the vertex stage's light, a turned frame of a
/// fresh compositor's. A camera that moves computes the light in the vertex stage again, and
/// the pass runs once it stops. The sphere of 48 rings, glossy and of the default material
/// (untextured: the whole colour from the vertices), and of the default material under an 8×8
/// checker texture (the light from the vertices, the albedo per pixel).
#[test]
fn the_light_kept_from_the_vertex_light_pass_is_the_vertex_stages() {
    let checker: Vec<u8> = (0..64).flat_map(|i| if (i % 8 + i / 8) % 2 == 0 { [230, 200, 60, 255] } else { [40, 90, 200, 255] }).collect();
    let texture = previz::scene::Rgba8Image { width: 8, height: 8, pixels: checker };
    let textured = ("textured", Material { texture: Some(texture), ..Material::default() });
    for (name, material) in [materials()[1].clone(), materials()[3].clone(), textured] {
        let compositor = || set_up(common::uv_sphere(48, material.clone()), 320, 0.5, true);
        let ([mut c, _], p) = compositor();
        let frame = |c: &mut Compositor, p: &FrameParams| {
            let r = c.render(gpu(), p, Layer::Composite).unwrap();
            assert!(c.light_per_mesh()[0].1, "{name}: not lit from its vertices");
            (r.rgba, c.passes_run().vertex_light)
        };
        let close = |a: &[u8], b: &[u8], what: &str| {
            let worst = a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
            let differ = a.chunks_exact(4).zip(b.chunks_exact(4)).filter(|(x, y)| x != y).count();
            println!("{name}, {what}: {differ} pixels differ, by at most {worst} levels");
            assert!(worst <= 1, "{name}, {what}: a channel differs by {worst} levels");
        };
        let (vertex_stage, ran) = frame(&mut c, &p);
        assert!(!ran, "{name}: the pass ran on a view's first frame");
        let (computed, ran) = frame(&mut c, &p);
        assert!(ran, "{name}: the pass did not run on the view's second frame");
        close(&vertex_stage, &computed, "the pass's light against the vertex stage's");
        let (kept, ran) = frame(&mut c, &p);
        assert!(!ran && kept == computed, "{name}: a frame of the same view ran the pass again or drew another image");
        // The camera turns 3° about its own vertical axis: the light is kept.
        let mut turned = p;
        turned.camera.pose *= glam::Quat::from_rotation_y(3f32.to_radians());
        let (turned_kept, ran) = frame(&mut c, &turned);
        assert!(!ran, "{name}: the pass ran for a turn of the camera");
        assert_ne!(turned_kept, kept, "{name}: the turn moved nothing");
        let ([mut fresh, _], _) = compositor();
        let (turned_fresh, ran) = frame(&mut fresh, &turned);
        assert!(!ran);
        close(&turned_kept, &turned_fresh, "a turn with the light kept against a fresh compositor's");
        // The camera steps sideways: the vertex stage lights the new view's first frame, the
        // pass its second.
        let mut moved = turned;
        moved.camera.position += glam::Vec3::new(0.05, 0.0, 0.0);
        let (moved_first, ran) = frame(&mut c, &moved);
        assert!(!ran, "{name}: the pass ran on a moving camera's frame");
        assert_ne!(moved_first, turned_kept, "{name}: the step moved nothing");
        let (moved_second, ran) = frame(&mut c, &moved);
        assert!(ran, "{name}: the pass did not run once the camera stopped");
        close(&moved_first, &moved_second, "after a step");
    }
}
