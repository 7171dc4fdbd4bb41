//! The soft sun shadow (shaders/frame.wgsl `sun_visibility_soft`): on the model's own lit
//! surfaces a surface the sun grazes keeps its sun and a real occluder still shadows it; a
//! penumbra has the width of the sun's disc.

use crate::common;

use common::gpu;
use glam::{Mat4, Vec3};
use previz::render::{Compositor, FrameParams, Layer, LightingMethod, PassesRun, Rendered};
use previz::scene::{Mesh, Model};

/// A single-sided square grid of `n`×`n` quads, 2 model units wide, in the model's base plane
/// (y = 0, facing +y), grey; a closed red box 0.4 wide and 0.3 high standing on its centre, and
/// a red pole 0.1 wide and 2 high on its western corner.
fn grid_and_standing_box(n: u32) -> Model {
    let mut boxes = Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), material: 1 };
    // The box, and a pole 2 units high on the grid's western corner (its shadow falls off the
    // grid): the map then covers as much along the sun as across it, as a truck's.
    common::push_box(&mut boxes, Vec3::new(0.0, 0.15, 0.0), Vec3::new(0.2, 0.15, 0.2));
    common::push_box(&mut boxes, Vec3::new(-0.95, 1.0, -0.95), Vec3::new(0.05, 1.0, 0.05));
    common::grey_grid_red_boxes(common::flat_grid(n), boxes)
}

/// A 320×240 compositor without antialiasing over the grid and box at full detail, seen from 3 m
/// straight above the model's base (image up = North), lit by the sun alone (no ambient, no
/// specular, no colour correction, no ground pass: a grid pixel is its sun's visibility times
/// n·l times a constant) from the East at `elevation` degrees, of angular radius `radius`
/// degrees, with the sunlight scaled by 1 / sin(elevation) so that the lit grid's value does not
/// depend on the elevation.
fn frame(c: &mut Compositor, p: &FrameParams, elevation: f32, radius: f32) -> (Rendered, PassesRun) {
    let mut p = *p;
    let el = elevation.to_radians();
    p.lighting.sun_dir = Vec3::new(el.cos(), 0.0, el.sin());
    p.lighting.sun_angular_radius = radius.to_radians();
    p.lighting.sunlight = 0.5 / el.sin();
    let r = c.render(gpu(), &p, Layer::Composite).unwrap();
    let run = c.passes_run();
    // Then held for a frame, as a still scene is: a map redrawn on consecutive frames is looked
    // up per pixel (its per-vertex values would be thrown away next frame), so the next sun's
    // frame follows a frame that kept its map and takes the per-vertex path at once.
    c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(!c.passes_run().shadow_drawn, "the sun did not change, yet the map was drawn again");
    (r, run)
}

/// Metres per model unit: the grid is 8 m wide, the pole 8 m high (the truck is 4.5 m long), so
/// that the lookup's fixed 2 mm offset along the normal is as small against the map's texels as
/// on the truck.
const SCALE: f32 = 4.0;

fn set_up() -> (Compositor, FrameParams) {
    common::sun_alone_from_above(grid_and_standing_box(48), LightingMethod::Sh9Ggx, SCALE)
}

fn linear(srgb: u8) -> f64 {
    f64::from(previz::colour::srgb_to_linear(f32::from(srgb) / 255.0))
}

/// The green channel (linear) of the grid at the ground points (x, y) × SCALE (world metres, z = 0)
/// for (x, y) in the rectangle `x`×`y` of model units, on a 0.05-unit lattice, each point's
/// nearest pixel.
fn grid_values(r: &Rendered, view_proj: Mat4, x: (f32, f32), y: (f32, f32)) -> Vec<f64> {
    let mut out = Vec::new();
    let (x, y) = ((x.0 * SCALE, x.1 * SCALE), (y.0 * SCALE, y.1 * SCALE));
    let step = 0.05 * SCALE;
    let steps = |(a, b): (f32, f32)| (0..=((b - a) / step).round() as i32).map(move |k| a + step * k as f32);
    for wy in steps(y) {
        for wx in steps(x) {
            let ndc = view_proj.project_point3(Vec3::new(wx, wy, 0.0));
            let px = (((ndc.x * 0.5 + 0.5) * r.width as f32) as u32).min(r.width - 1);
            let py = (((0.5 - ndc.y * 0.5) * r.height as f32) as u32).min(r.height - 1);
            out.push(linear(r.rgba[4 * (py * r.width + px) as usize + 1]));
        }
    }
    out
}

/// A flat grid the sun grazes at 6° (n·l 0.10, the truck's sides in quarry_truck) keeps its sun:
/// east of the box and north and south of its shadow (nothing between it and the sun) each
/// point is, relative to the same point
/// under a 60° sun (where the lookup has always kept the whole sun; the sunlight scaled by
/// 1 / sin(elevation) so that both are the same when nothing shadows), at least 0.98 on
/// average and 0.95 at worst; and the box's shadow, which runs west over the grid, keeps it
/// shadowed (mean under 0.05 inside it). Both the per-pixel lookup and the per-vertex one, at
/// quarry_01's measured sun (tan of its radius 0.0296) and the real sun's size (0.27°).
/// Measured 2026-12-02 (debug, lavapipe): main's lookup, whose blocker search counted the grid's
/// own texels as blockers, kept 0.779 (worst point 0.663) per pixel at quarry's sun size; with
/// the sun's cone on the model's own surface every case keeps 1.0000 (worst 1.0000) and the
/// box's shadow 0.0000 (docs/accuracy.md, eleventh session). Without the pole the map covers
/// the flat grid nearly edge-on, with texels fine enough along the slope that main's lookup kept
/// it lit as well.
#[test]
fn a_grazing_sun_keeps_its_light_on_a_lit_surface_and_an_occluder_still_shadows() {
    let (mut c, p) = set_up();
    let view_proj = Mat4::from_cols_array_2d(&c.frame_uniforms(&p).unwrap().frame.view_proj);
    for (lookup, edge_limit) in [("per pixel", 0.0), ("per vertex", previz::render::passes::model::MAX_SUN_EDGE_PX)] {
        c.set_sun_edge_limit(edge_limit);
        for radius in [0.0296f32.atan().to_degrees(), 0.27] {
            let (high, _) = frame(&mut c, &p, 60.0, radius);
            let (low, run) = frame(&mut c, &p, 6.0, radius);
            assert_eq!(run.vertex_sun, edge_limit > 0.0, "{lookup}: {run:?}");
            // The grid east of the box, and north and south of the box's shadow (clear of the pole).
            let lit_regions = [((0.35, 0.85), (-0.85, 0.85)), ((-0.85, 0.3), (0.35, 0.85)), ((-0.85, 0.3), (-0.85, -0.35))];
            let values = |r: &Rendered| lit_regions.iter().flat_map(|&(x, y)| grid_values(r, view_proj, x, y)).collect::<Vec<f64>>();
            let reference = values(&high);
            let lit: Vec<f64> = values(&low).iter().zip(&reference).map(|(l, h)| l / h).collect();
            let mean = lit.iter().sum::<f64>() / lit.len() as f64;
            let worst = lit.iter().copied().fold(f64::MAX, f64::min);
            // Inside the box's shadow: west of it, its middle half across.
            let shadow = grid_values(&low, view_proj, (-0.9, -0.4), (-0.1, 0.1));
            let shadow_mean = shadow.iter().sum::<f64>() / shadow.len() as f64 / (reference.iter().sum::<f64>() / reference.len() as f64);
            println!(
                "{lookup}, sun radius {radius:.2} deg: lit grid keeps {mean:.4} of its sun (worst {worst:.4}, {} points, unshadowed {:.3}); box's shadow {shadow_mean:.4}",
                lit.len(),
                reference.iter().sum::<f64>() / reference.len() as f64
            );
            assert!(reference.iter().all(|&h| h > 0.2), "{lookup}: the 60° frame's lit grid is dark");
            assert!(mean >= 0.98 && worst >= 0.95, "{lookup}, radius {radius}: the lit grid keeps {mean:.4} (worst {worst:.4})");
            assert!(shadow_mean < 0.05, "{lookup}, radius {radius}: the box's shadow keeps {shadow_mean:.4} of the sun");
        }
    }
}

/// A thin square plate floating above the ground (model units: 0.4 wide, 0.0025 thick, its
/// underside at height 0.25; x from 0.25 to 0.65, z from -0.2 to 0.2), nothing else.
fn floating_plate() -> Model {
    let mut plate = Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), material: 1 };
    common::push_box(&mut plate, Vec3::new(0.45, 0.25125, 0.0), Vec3::new(0.2, 0.00125, 0.2));
    let mut empty = common::flat_grid(1);
    empty.indices.clear();
    common::grey_grid_red_boxes(empty, plate)
}

/// The sun's penumbra has the width of its disc seen from the shadowed point: a plate floats
/// h = 1 m above the ground (model scale 4), the sun comes from the East at 60° with angular
/// radius r (tan r 0.0296, quarry_01's measured sun, and 0.06), so the plate's northern edge,
/// parallel to the sun's azimuth, casts on the ground an edge at y = 0.8 m whose penumbra runs
/// ρ = d·tan r either side of it across (d = h / sin 60°, the distance along the sun's ray;
/// across the sun's azimuth the disc is not foreshortened). Seen from 6 m above the edge with a
/// 12° field of view (4.4 mm a pixel; ρ = 34 and 69 mm), the ground's shadow (the ground pass
/// with the sun's whole share of its light: a pixel is the background times the visibility)
/// across the edge, normalised between the umbra and the light far outside, is compared with a
/// uniform disc's: the fraction of a disc of radius ρ beyond a line at distance x, whose spread
/// (the standard deviation of the visibility's rise across the edge) is ρ / 2 and whose 10–90 %
/// width is 1.374 ρ. Both within 20 %, and the middle of the edge (visibility 0.5) within ρ / 4
/// of the plate's edge projected along the sun. Measured 2026-12-02 (debug, lavapipe): spread
/// 0.512 / 0.527 ρ, width 1.375 / 1.371 ρ, middle −4.7 / −5.1 mm; main's filter (taps 0.83 ρ
/// apart) gave spread 0.682 ρ and width 1.668 ρ at tan r 0.0296 (docs/accuracy.md, twelfth
/// session). The ground is the receiver because the model's own surface, lit side, counts only
/// blockers inside the sun's cone at the search's corners, which cuts the outer part of a
/// penumbra there (same plate over the grid: spread 0.37 ρ, width 0.91 ρ; docs/accuracy.md).
#[test]
fn a_penumbra_has_the_width_of_the_suns_disc() {
    let (mut c, mut p) = common::sun_alone_from_above(floating_plate(), LightingMethod::Sh9Ggx, SCALE);
    p.lighting.shadow_opacity = 1.0;
    let edge = 0.2 * SCALE;
    let h = 0.25 * SCALE;
    p.camera.position = Vec3::new(0.75, edge, 6.0);
    p.camera.vfov = 12f32.to_radians();
    let view_proj = Mat4::from_cols_array_2d(&c.frame_uniforms(&p).unwrap().frame.view_proj);
    let elevation = 60f32;
    let d = h / elevation.to_radians().sin();
    for tan_r in [0.0296f32, 0.06] {
        let (r, _) = frame(&mut c, &p, elevation, tan_r.atan().to_degrees());
        let rho = d * tan_r;
        // The green channel along y in 1 mm steps over ±4ρ, each step the mean of the nearest
        // pixels of 9 points from x = 0.55 to 0.95 m (inside the shadow's run from the east,
        // x = 0.42-2.02 m, and clear of the plate as the camera sees it).
        let steps = (8.0 * rho / 0.001) as i32;
        let ys: Vec<f32> = (0..=steps).map(|k| edge - 4.0 * rho + 0.001 * k as f32).collect();
        let across = |y: f32| {
            (0..9)
                .map(|i| {
                    let ndc = view_proj.project_point3(Vec3::new(0.55 + 0.05 * i as f32, y, 0.0));
                    let px = (((ndc.x * 0.5 + 0.5) * r.width as f32) as u32).min(r.width - 1);
                    let py = (((0.5 - ndc.y * 0.5) * r.height as f32) as u32).min(r.height - 1);
                    linear(r.rgba[4 * (py * r.width + px) as usize + 1])
                })
                .sum::<f64>()
                / 9.0
        };
        let (lit, umbra) = (across(edge + 6.0 * rho), across(edge - 6.0 * rho));
        let v: Vec<f64> = ys.iter().map(|&y| (across(y) - umbra) / (lit - umbra)).collect();
        // Spread: the standard deviation of y weighted by the visibility's rise across the edge.
        let (mut w, mut m1, mut m2) = (0.0, 0.0, 0.0);
        for k in 1..v.len() {
            let dv = (v[k] - v[k - 1]).max(0.0);
            let y = f64::from(0.5 * (ys[k] + ys[k - 1]));
            (w, m1, m2) = (w + dv, m1 + dv * y, m2 + dv * y * y);
        }
        let mean = m1 / w;
        let spread = (m2 / w - mean * mean).max(0.0).sqrt();
        let crossing = |t: f64| f64::from(ys[v.iter().position(|&x| x >= t).unwrap_or(v.len() - 1)]);
        let width = crossing(0.9) - crossing(0.1);
        let middle = crossing(0.5) - f64::from(edge);
        let rho = f64::from(rho);
        println!(
            "tan r {tan_r}: rho {:.1} mm; spread {:.1} mm = {:.3} rho (disc 0.5), 10-90 % width {:.1} mm = {:.3} rho (disc 1.374), middle {:+.1} mm from the edge; lit {lit:.3}, umbra {umbra:.3}",
            rho * 1e3,
            spread * 1e3,
            spread / rho,
            width * 1e3,
            width / rho,
            middle * 1e3,
        );
        assert!(lit > 0.2 && umbra < 0.05 * lit, "tan r {tan_r}: lit {lit:.3}, umbra {umbra:.3}");
        assert!((spread / rho - 0.5).abs() <= 0.1, "tan r {tan_r}: the penumbra's spread is {:.3} rho, the disc's 0.5", spread / rho);
        assert!(
            (width / rho - 1.374).abs() <= 0.275,
            "tan r {tan_r}: the penumbra's 10-90 % width is {:.3} rho, the disc's 1.374",
            width / rho
        );
        assert!(middle.abs() <= rho / 4.0, "tan r {tan_r}: the edge's middle is {:.1} mm off", middle * 1e3);
    }
}
