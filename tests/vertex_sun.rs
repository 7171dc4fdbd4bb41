//! The model's sun per vertex (render::passes::vertex_sun): the value looked up at each vertex
//! is what the per-pixel lookup gives there, the lookup runs once per shadow map drawn (not per
//! frame), and a mesh of large triangles keeps the per-pixel lookup.

use crate::common;

use common::gpu;
use glam::{Mat4, Quat, Vec3, Vec4};
use previz::render::passes::vertex_sun::SPLIT_CULL_MARGIN;
use previz::render::{Antialiasing, Compositor, FrameData, FrameParams, Layer, LightingMethod};
use previz::scene::{Material, Mesh, Model};

/// A single-sided square grid of `n`×`n` quads, 2 model units wide, in the model's base plane
/// (y = 0, facing +y), grey; and a closed box 0.5 wide floating from y = 0.35 to 0.85 above its
/// centre, red, which shadows it.
fn grid_and_box(n: u32) -> Model {
    let mut cube = Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), material: 1 };
    common::push_box(&mut cube, Vec3::new(0.0, 0.6, 0.0), Vec3::splat(0.25));
    common::grey_grid_red_boxes(common::flat_grid(n), cube)
}

/// A 320×240 compositor without antialiasing over the grid and box, full detail (the flat grid
/// would otherwise be simplified to two triangles), and a frame seen from 3 m straight above the
/// model's base (image up = North) with the sun in the East 60° high: lit by the sun alone (no
/// ambient, no specular, no colour correction, no ground pass), so a grid pixel's value is its
/// sun's visibility times a constant.
fn set_up(model: Model, method: LightingMethod) -> (Compositor, FrameParams) {
    let (c, mut p) = common::sun_alone_from_above(model, method, 1.0);
    let (el, az) = (60f32.to_radians(), 90f32.to_radians());
    p.lighting.sun_dir = Vec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
    p.lighting.sunlight = 1.0;
    (c, p)
}

/// Per triangle of `mesh` (in the frame whose uniforms are `data`), whether the split keeps it by
/// its rule (shaders/vertex_sun.wgsl `may_face_camera`), computed here in f64: its plane does not
/// have the camera behind it by more than [`SPLIT_CULL_MARGIN`] times the camera's distance to
/// the model's origin, counter-clockwise seen from the front; with the margin scaled by `scale`
/// (a triangle that near the bound may fall either way in the shader's f32).
fn kept_by_the_split(mesh: &Mesh, data: &FrameData, scale: f64) -> Vec<bool> {
    let model = Mat4::from_cols_array_2d(&data.instance.model).as_dmat4();
    let camera = Vec3::from(data.frame.camera_pos).as_dvec3();
    let margin = f64::from(SPLIT_CULL_MARGIN) * scale * camera.distance(model.w_axis.truncate());
    let world = |v: u32| model.transform_point3(Vec3::from(mesh.positions[v as usize]).as_dvec3());
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            let a = world(t[0]);
            let n = (world(t[1]) - a).cross(world(t[2]) - a);
            n.dot(camera - a) >= -margin * n.length()
        })
        .collect()
}

/// How many triangles of `mesh` the split keeps: the fewest and the most it may keep
/// ([`kept_by_the_split`] with the margin a ten-thousandth smaller and larger).
fn kept_count(mesh: &Mesh, data: &FrameData) -> (u32, u32) {
    let count = |scale: f64| kept_by_the_split(mesh, data, scale).iter().filter(|&&k| k).count() as u32;
    (count(0.9999), count(1.0001))
}

fn linear(srgb: u8) -> f64 {
    f64::from(previz::colour::srgb_to_linear(f32::from(srgb) / 255.0))
}

/// A grid vertex's visibility: the per-pixel frame's there (bilinear between the four pixel
/// centres around it, relative to the brightest grid pixel), how much those four differ (the
/// largest less the smallest), and the per-vertex value read back.
struct AtVertex {
    per_pixel: f64,
    spread: f64,
    per_vertex: f64,
}

/// [`AtVertex`] for each grid vertex away from the grid's border whose four nearest pixels all
/// show the grid (grey, not the red box).
fn compare_at_vertices(method: LightingMethod) -> Vec<AtVertex> {
    let n = 48;
    let (mut c, p) = set_up(grid_and_box(n), method);
    c.set_sun_edge_limit(0.0);
    let per_pixel = c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(!c.passes_run().vertex_sun, "{}: the per-vertex lookup ran with it off", method.name());
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    let per_vertex = c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(c.passes_run().vertex_sun, "{}: the grid's small triangles did not take the per-vertex lookup", method.name());
    let values = c.vertex_sun_values(gpu()).unwrap();
    let data = c.frame_uniforms(&p).unwrap();
    let (view_proj, model) = (Mat4::from_cols_array_2d(&data.frame.view_proj), Mat4::from_cols_array_2d(&data.instance.model));
    let (w, h) = (per_pixel.width, per_pixel.height);
    let at = |x: u32, y: u32| {
        let i = 4 * (y * w + x) as usize;
        [per_pixel.rgba[i], per_pixel.rgba[i + 1], per_pixel.rgba[i + 2]]
    };
    let grey = |[r, g, b]: [u8; 3]| r.abs_diff(g) <= 2 && g.abs_diff(b) <= 2;
    let lit = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| at(x, y))
        .filter(|&c| grey(c))
        .map(|c| linear(c[1]))
        .fold(0.0, f64::max);
    assert!(lit > 0.3, "no sunlit grid: brightest grey {lit}");
    let grid = &grid_and_box(n).meshes[0];
    let mut pairs = Vec::new();
    for (k, position) in grid.positions.iter().enumerate() {
        let (i, j) = (k as u32 % (n + 1), k as u32 / (n + 1));
        if i == 0 || j == 0 || i == n || j == n {
            continue;
        }
        let clip = view_proj * model * Vec4::from((Vec3::from(*position), 1.0));
        let (sx, sy) = ((clip.x / clip.w * 0.5 + 0.5) * w as f32 - 0.5, (0.5 - clip.y / clip.w * 0.5) * h as f32 - 0.5);
        let (x0, y0) = (sx.floor() as u32, sy.floor() as u32);
        let (fx, fy) = (f64::from(sx - sx.floor()), f64::from(sy - sy.floor()));
        let corners = [at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)];
        if !corners.iter().all(|&c| grey(c)) {
            continue;
        }
        let v = corners.map(|c| linear(c[1]) / lit);
        let bilinear = (v[0] * (1.0 - fx) + v[1] * fx) * (1.0 - fy) + (v[2] * (1.0 - fx) + v[3] * fx) * fy;
        let spread = v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min);
        pairs.push(AtVertex { per_pixel: bilinear, spread, per_vertex: f64::from(values[0][k]) });
    }
    let _ = per_vertex;
    pairs
}

/// At the vertices of a finely tessellated grid in and around a box's shadow, the visibility
/// the compute pass wrote is what the per-pixel lookup of the same method gives there (read from
/// the per-pixel frame, bilinear between the pixel centres around the vertex): for the 2×2
/// filter (hemisphere) and the soft PCSS (sh9-ggx). The grid's shadow, lit and penumbra vertices
/// are all compared. Where the four pixels around a vertex agree the two must agree to 0.02 (an
/// 8-bit level is under 0.005 here); across a penumbra the bilinear estimate of the per-pixel
/// value is itself uncertain by up to the four pixels' spread, which the bound adds. Measured
/// (2026-12-01): mean |difference| 0.0016 (hemisphere) and 0.0014 (sh9-ggx), largest 0.18 and
/// 0.21, all at vertices whose pixels spread by more than that.
#[test]
fn the_sun_at_a_vertex_is_the_per_pixel_lookup_there() {
    for method in [LightingMethod::Hemisphere, LightingMethod::Sh9Ggx] {
        let at = compare_at_vertices(method);
        let shadow = at.iter().filter(|a| a.per_pixel < 0.05).count();
        let penumbra = at.iter().filter(|a| a.per_pixel > 0.1 && a.per_pixel < 0.9).count();
        let lit = at.iter().filter(|a| a.per_pixel > 0.95).count();
        let error = |a: &AtVertex| (a.per_pixel - a.per_vertex).abs();
        let max = at.iter().map(error).fold(0.0, f64::max);
        let mean = at.iter().map(error).sum::<f64>() / at.len() as f64;
        let name = method.name();
        println!(
            "{name}: {} vertices ({shadow} shadow, {penumbra} penumbra, {lit} lit), |difference| mean {mean:.4} max {max:.4}",
            at.len()
        );
        assert!(shadow >= 20 && penumbra >= 20 && lit >= 500, "{name}: {shadow} shadow, {penumbra} penumbra, {lit} lit");
        assert!(mean < 0.005, "{name}: mean |per-vertex - per-pixel| {mean}");
        for a in &at {
            assert!(
                error(a) <= 0.02 + a.spread,
                "{name}: per pixel {:.3} (spread {:.3}), per vertex {:.3}",
                a.per_pixel,
                a.spread,
                a.per_vertex
            );
        }
    }
}

/// The split (shaders/vertex_sun.wgsl `split`): of the level's triangles, exactly those whose
/// sunlit vertices disagree on the sun by more than 1/64 (counted here from the values read
/// back, the facing from the normals and the sun of the frame's uniforms) are drawn with the
/// per-pixel lookup, the rest with the sun interpolated, every triangle once; on the grid and
/// box most triangles take the interpolated sun, and the frame differs from the per-pixel one
/// in few pixels. The box, whose triangles are large on screen, is drawn per pixel and not split. Measured (2026-12-01): see the printed counts.
#[test]
fn triangles_a_shadow_edge_crosses_are_drawn_per_pixel() {
    for method in [LightingMethod::Hemisphere, LightingMethod::Sh9Ggx] {
        let (mut c, p) = set_up(grid_and_box(48), method);
        c.set_sun_edge_limit(0.0);
        let per_pixel = c.render(gpu(), &p, Layer::Composite).unwrap();
        c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
        let per_vertex = c.render(gpu(), &p, Layer::Composite).unwrap();
        assert!(c.passes_run().vertex_sun, "{}: no per-vertex lookup", method.name());
        let values = c.vertex_sun_values(gpu()).unwrap();
        let split = c.vertex_sun_split(gpu()).unwrap();
        let data = c.frame_uniforms(&p).unwrap();
        let normal_matrix = Mat4::from_cols_array_2d(&data.instance.normal);
        let sun = Vec3::from(data.frame.sun_dir);
        let model = grid_and_box(48);
        let name = method.name();
        let chosen = c.sun_per_mesh();
        assert!(chosen[0].1, "{name}: the grid is not drawn per vertex: {chosen:?}");
        for (k, mesh) in model.meshes.iter().enumerate() {
            if !chosen[k].1 {
                // The box's large triangles are drawn per pixel: not split at all.
                assert_eq!(split[k], (0, 0), "{name}, mesh {k}: drawn per pixel, yet split");
                continue;
            }
            let facing = |v: u32| (normal_matrix * Vec4::from((Vec3::from(mesh.normals[v as usize]), 0.0))).truncate().dot(sun) > 0.0;
            let kept = kept_by_the_split(mesh, &data, 1.0);
            let (fewest, most) = kept_count(mesh, &data);
            let disagree = mesh
                .indices
                .chunks_exact(3)
                .zip(&kept)
                .filter(|(_, k)| **k)
                .map(|(t, _)| t)
                .filter(|t| {
                    let lit: Vec<f32> = t.iter().filter(|&&v| facing(v)).map(|&v| values[k][v as usize]).collect();
                    let (lo, hi) = lit.iter().fold((1.0f32, 0.0f32), |(lo, hi), &x| (lo.min(x), hi.max(x)));
                    hi - lo > 1.0 / 64.0
                })
                .count() as u32;
            let triangles = (mesh.indices.len() / 3) as u32;
            println!(
                "{name}, mesh {k}: {} of {triangles} triangles per vertex, {} per pixel ({disagree} disagree)",
                split[k].0, split[k].1
            );
            // The grid faces the camera above it: the split keeps every triangle, once.
            assert_eq!((fewest, most), (triangles, triangles), "{name}, mesh {k}: the camera sees the grid's back");
            assert_eq!(split[k].0 + split[k].1, triangles, "{name}, mesh {k}: every triangle once");
            assert_eq!(split[k].1, disagree, "{name}, mesh {k}: the triangles drawn per pixel");
        }
        assert!(split[0].1 > 0 && split[0].0 > 4 * split[0].1, "{name}: the grid's split {:?}", split[0]);
        let differ = per_pixel.rgba.chunks_exact(4).zip(per_vertex.rgba.chunks_exact(4)).filter(|(a, b)| a != b).count();
        println!("{name}: {differ} pixels differ from the per-pixel frame");
        assert!(differ < 200, "{name}: {differ} pixels differ from the per-pixel frame");
    }
}

/// [`common::uv_sphere`] (for 32 rings, quads whose diagonals are about 16 pixels at
/// [`set_up`]'s view), red (so its unlit side, black, and its sunlit side both differ from the
/// grey environment behind it).
fn sphere(rings: u32) -> Model {
    common::uv_sphere(rings, Material { diffuse: [0.8, 0.0, 0.0], specular: [0.0; 3], ..Material::default() })
}

/// The terminator: a sphere lit by the sun alone has nothing but itself to shadow it, so the
/// per-vertex frame must not be darker than the per-pixel one where the sun reaches. A vertex
/// facing away from the sun looks up the sphere's own shadow (0); interpolated as it is into
/// the sunlit part of the triangles across the terminator, it darkened them (the ninth
/// session's city_spot regression). Weighted by each vertex's n·l (model.wgsl `vertex_sun`),
/// those triangles take their sunlit vertices' value, and a triangle whose sunlit vertices
/// disagree (the PCSS lookup's self-shadowing near the terminator) is drawn per pixel (the
/// split). Per method, over the sphere's sunlit pixels: the red channel's linear sum per vertex
/// over per pixel, and the pixels darker per vertex by more than 4 levels. Measured
/// (2026-12-01, 32 rings): hemisphere 1.00001 and 0 pixels, sh9-ggx 1.00043 and 0 pixels; the
/// ninth session's plain interpolation gave sh9-ggx 208 darker pixels, and the n·l weighting
/// without the split 197, both over this test's bound of 20.
#[test]
fn the_terminator_is_not_darkened() {
    for method in [LightingMethod::Hemisphere, LightingMethod::Sh9Ggx] {
        let (mut c, p) = set_up(sphere(32), method);
        c.set_sun_edge_limit(0.0);
        let per_pixel = c.render(gpu(), &p, Layer::Composite).unwrap();
        c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
        let per_vertex = c.render(gpu(), &p, Layer::Composite).unwrap();
        assert!(c.passes_run().vertex_sun, "{}: the sphere did not take the per-vertex lookup: {:?}", method.name(), c.sun_per_mesh());
        let (mut sum_pixel, mut sum_vertex, mut darker, mut sunlit) = (0.0, 0.0, 0, 0);
        for (a, b) in per_pixel.rgba.chunks_exact(4).zip(per_vertex.rgba.chunks_exact(4)) {
            // The sphere's sunlit pixels: red, no green (the environment is grey).
            if a[1] > 2 || a[0] <= 2 {
                continue;
            }
            sunlit += 1;
            sum_pixel += linear(a[0]);
            sum_vertex += linear(b[0]);
            darker += usize::from(b[0] + 4 < a[0]);
        }
        if let Ok(dir) = std::env::var("PREVIZ_TERMINATOR_IMAGES") {
            for (img, label) in [(&per_pixel, "per_pixel"), (&per_vertex, "per_vertex")] {
                let path = format!("{dir}/{}_{label}.png", method.name());
                image::RgbaImage::from_raw(img.width, img.height, img.rgba.clone()).unwrap().save(path).unwrap();
            }
        }
        let ratio = sum_vertex / sum_pixel;
        println!(
            "{}: {sunlit} sunlit pixels, red sum per vertex / per pixel {ratio:.5}, {darker} pixels darker by > 4 levels",
            method.name()
        );
        assert!(sunlit > 2000, "{}: {sunlit} sunlit sphere pixels", method.name());
        assert!((ratio - 1.0).abs() < 0.002, "{}: red sum per vertex / per pixel {ratio}", method.name());
        assert!(darker < 20, "{}: {darker} of {sunlit} sunlit pixels darker per vertex", method.name());
    }
}

/// The compute pass runs with the shadow pass, not per frame: the same frame again, or the
/// camera turned, keeps both the map and the values; another method's lookup runs the compute
/// pass alone on the kept map; the sun moved draws the map and runs it again. A kept frame is
/// the same image byte for byte.
#[test]
fn a_kept_shadow_map_does_not_run_the_vertex_sun_again() {
    let (mut c, p) = set_up(grid_and_box(48), LightingMethod::Hemisphere);
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    let mut run = |p: &FrameParams| {
        let r = c.render(gpu(), p, Layer::Composite).unwrap();
        (c.passes_run().shadow_drawn, c.passes_run().vertex_sun, r.rgba)
    };
    let (drawn, computed, first) = run(&p);
    assert!(drawn && computed, "the first frame: shadow drawn {drawn}, vertex sun {computed}");
    let (drawn, computed, again) = run(&p);
    assert!(!drawn && !computed, "the same frame: shadow drawn {drawn}, vertex sun {computed}");
    assert!(first == again, "the kept frame differs from the first");
    let mut turned = p;
    turned.camera.pose *= Quat::from_rotation_y(0.01);
    let (drawn, computed, _) = run(&turned);
    assert!(!drawn && !computed, "the camera turned: shadow drawn {drawn}, vertex sun {computed}");
    let soft = FrameParams { method: LightingMethod::Sh9Ggx, ..p };
    let (drawn, computed, _) = run(&soft);
    assert!(!drawn && computed, "another lookup: shadow drawn {drawn}, vertex sun {computed}");
    let (drawn, computed, _) = run(&soft);
    assert!(!drawn && !computed, "that lookup again: shadow drawn {drawn}, vertex sun {computed}");
    let mut moved = soft;
    moved.lighting.sun_dir = Quat::from_rotation_z(2f32.to_radians()) * moved.lighting.sun_dir;
    let (drawn, computed, _) = run(&moved);
    assert!(drawn && computed, "the sun moved: shadow drawn {drawn}, vertex sun {computed}");
}

/// The split leaves out the triangles whose backs the camera sees, and holds while the camera
/// stays within [`SPLIT_CULL_MARGIN`] of its distance to the model's origin (3 m above it here:
/// 0.15 m). Moved 0.1 m, the frame keeps the map, the values and the split, and every sphere
/// triangle the moved camera sees the front of is among those the split kept; moved 0.2 m, the
/// split runs again (with the lookup, on the kept map) and keeps what the new camera may see.
#[test]
fn the_split_runs_again_when_the_camera_moves_past_its_margin() {
    let (mut c, p) = set_up(coarse_grid_and_fine_sphere(), LightingMethod::Sh9Ggx);
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(c.passes_run().vertex_sun, "{:?}", c.passes_run());
    let sphere = &coarse_grid_and_fine_sphere().meshes[1];
    let kept_first = kept_by_the_split(sphere, &c.frame_uniforms(&p).unwrap(), 1.0);
    let split_first = c.vertex_sun_split(gpu()).unwrap()[1];
    for (shift, again) in [(0.1, false), (0.2, true)] {
        let mut moved = p;
        moved.camera.position += Vec3::new(shift, 0.0, 0.0);
        c.render(gpu(), &moved, Layer::Composite).unwrap();
        let run = c.passes_run();
        assert!(!run.shadow_drawn && run.vertex_sun == again, "moved {shift} m: {run:?}");
        let data = c.frame_uniforms(&moved).unwrap();
        let kept = c.vertex_sun_split(gpu()).unwrap()[1];
        let kept = kept.0 + kept.1;
        if again {
            let (fewest, most) = kept_count(sphere, &data);
            assert!((fewest..=most).contains(&kept), "moved {shift} m: the split keeps {kept}, not {fewest}..={most}");
        } else {
            // Seen from the front by the moved camera (no margin): kept by the first split.
            let seen = kept_by_the_split(sphere, &data, 0.0);
            let lost = seen.iter().zip(&kept_first).filter(|(s, k)| **s && !**k).count();
            assert_eq!(lost, 0, "moved {shift} m: {lost} triangles the camera sees the front of were left out");
            assert_eq!(kept, split_first.0 + split_first.1, "moved {shift} m: the lists changed");
        }
    }
}

/// A mesh whose triangles are large on screen keeps the per-pixel lookup: the same grid in 4×4
/// quads (edges of ~70 pixels) runs no compute pass, and its frame is the per-pixel one byte for
/// byte.
#[test]
fn large_triangles_keep_the_per_pixel_lookup() {
    let (mut c, p) = set_up(grid_and_box(4), LightingMethod::Sh9Ggx);
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    let with = c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(c.passes_run().shadow_drawn && !c.passes_run().vertex_sun, "{:?}", c.passes_run());
    c.set_sun_edge_limit(0.0);
    let without = c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(with.rgba == without.rgba, "the large triangles' frame is not the per-pixel one");
}

/// The grid of [`grid_and_box`] in 4×4 quads (edges of ~70 pixels on screen: drawn per pixel)
/// under a finely tessellated sphere of radius 0.25 at the box's place (edges of a few pixels:
/// drawn per vertex), whose shadow falls on the grid.
fn coarse_grid_and_fine_sphere() -> Model {
    let mut model = grid_and_box(4);
    let mut ball = sphere(32);
    for p in &mut ball.meshes[0].positions {
        *p = (Vec3::from(*p) * (0.25 / 0.8) + Vec3::Y * 0.6).to_array();
    }
    ball.meshes[0].material = 1;
    model.meshes[1] = ball.meshes.remove(0);
    model
}

/// The vertex sun runs for the meshes the model pass draws per vertex and no other: of a
/// coarse grid (per pixel) under a fine sphere (per vertex), only the sphere's triangles are
/// split (the grid's indirect draws stay at zero, its visibility buffer at the 1 it was made
/// with, though the sphere's shadow covers some of its vertices); every sphere triangle the
/// camera above may see the front of is in one of its two lists, those of its lower half not.
/// With every mesh allowed per vertex on the same kept map, the grid is looked up and split too
/// (the buffers held another set of meshes). A model whose meshes are all per pixel runs no
/// vertex sun at all: [`large_triangles_keep_the_per_pixel_lookup`].
#[test]
fn only_the_meshes_drawn_per_vertex_are_looked_up() {
    let model = coarse_grid_and_fine_sphere();
    let triangles: Vec<u32> = model.meshes.iter().map(|m| (m.indices.len() / 3) as u32).collect();
    let (mut c, p) = set_up(model, LightingMethod::Sh9Ggx);
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    c.render(gpu(), &p, Layer::Composite).unwrap();
    let chosen: Vec<bool> = c.sun_per_mesh().iter().map(|m| m.1).collect();
    assert_eq!(chosen, [false, true], "per mesh (edges on screen px, per vertex): {:?}", c.sun_per_mesh());
    assert!(c.passes_run().shadow_drawn && c.passes_run().vertex_sun, "{:?}", c.passes_run());
    let split = c.vertex_sun_split(gpu()).unwrap();
    let values = c.vertex_sun_values(gpu()).unwrap();
    println!("split per mesh (per vertex, per pixel): {split:?} of {triangles:?} triangles");
    assert_eq!(split[0], (0, 0), "the grid, drawn per pixel, was split");
    assert!(values[0].iter().all(|&v| v == 1.0), "the grid's visibility was looked up: {:?}", values[0]);
    let data = c.frame_uniforms(&p).unwrap();
    let model = coarse_grid_and_fine_sphere();
    let (fewest, most) = kept_count(&model.meshes[1], &data);
    let kept = split[1].0 + split[1].1;
    assert!((fewest..=most).contains(&kept), "the sphere's split keeps {kept} triangles, not {fewest}..={most}");
    assert!(kept < triangles[1] * 3 / 5, "the sphere's split keeps {kept} of {} triangles", triangles[1]);
    assert!(values[1].iter().any(|&v| v < 0.5), "the sphere's own shadow was not looked up");
    // Every mesh allowed per vertex: the map is kept, and the grid is looked up and split on it.
    c.set_sun_edge_limit(f32::INFINITY);
    c.render(gpu(), &p, Layer::Composite).unwrap();
    assert!(!c.passes_run().shadow_drawn && c.passes_run().vertex_sun, "{:?}", c.passes_run());
    let split = c.vertex_sun_split(gpu()).unwrap();
    let values = c.vertex_sun_values(gpu()).unwrap();
    assert_eq!(split[0].0 + split[0].1, triangles[0], "the grid's split, every mesh per vertex");
    assert!((fewest..=most).contains(&(split[1].0 + split[1].1)), "the sphere's split, every mesh per vertex: {:?}", split[1]);
    assert!(values[0].iter().any(|&v| v < 0.5), "no grid vertex in the sphere's shadow: {:?}", values[0]);
}

/// A shadow map drawn on consecutive frames (the sun turning) is moving: those frames look the
/// sun up per pixel and run no vertex sun (their image is the per-pixel one byte for byte), and
/// the first frame that keeps the map runs it and draws per vertex again. A single redraw after
/// a kept frame (the sun moved once) still runs it at once.
#[test]
fn a_moving_shadow_map_is_looked_up_per_pixel() {
    let (mut c, p) = set_up(grid_and_box(48), LightingMethod::Hemisphere);
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    let turned = |p: &FrameParams, degrees: f32| {
        let mut q = *p;
        q.lighting.sun_dir = Quat::from_rotation_z(degrees.to_radians()) * q.lighting.sun_dir;
        q
    };
    let run = |c: &mut Compositor, p: &FrameParams| {
        let r = c.render(gpu(), p, Layer::Composite).unwrap();
        (c.passes_run().shadow_drawn, c.passes_run().vertex_sun, r.rgba)
    };
    let (drawn, computed, _) = run(&mut c, &p);
    assert!(drawn && computed, "the first frame: shadow drawn {drawn}, vertex sun {computed}");
    let (drawn, computed, _) = run(&mut c, &p);
    assert!(!drawn && !computed, "the same frame: shadow drawn {drawn}, vertex sun {computed}");
    let once = turned(&p, 2.0);
    let (drawn, computed, _) = run(&mut c, &once);
    assert!(drawn && computed, "the sun moved after a kept frame: shadow drawn {drawn}, vertex sun {computed}");
    let moving = turned(&p, 4.0);
    let (drawn, computed, moving_frame) = run(&mut c, &moving);
    assert!(drawn && !computed, "the sun moved on the next frame too: shadow drawn {drawn}, vertex sun {computed}");
    assert!(c.sun_per_mesh().iter().all(|m| !m.1), "a moving map's frame drew a mesh per vertex: {:?}", c.sun_per_mesh());
    // The same frame looked up per pixel on purpose (the map kept): the same image.
    c.set_sun_edge_limit(0.0);
    let (drawn, computed, per_pixel) = run(&mut c, &moving);
    assert!(!drawn && !computed);
    assert!(moving_frame == per_pixel, "the moving map's frame is not the per-pixel one");
    // The map held still: the vertex sun runs on it, and the grid is drawn per vertex.
    c.set_sun_edge_limit(previz::render::passes::model::MAX_SUN_EDGE_PX);
    let (drawn, computed, still) = run(&mut c, &moving);
    assert!(!drawn && computed, "the map held still: shadow drawn {drawn}, vertex sun {computed}");
    assert!(c.sun_per_mesh()[0].1, "{:?}", c.sun_per_mesh());
    let differ = still.chunks_exact(4).zip(per_pixel.chunks_exact(4)).filter(|(a, b)| a != b).count();
    println!("{differ} pixels differ between the still map's frame (per vertex) and the per-pixel one");
    assert!(differ > 0, "the still map's frame was not drawn per vertex");
}

/// The measurement behind the choice (docs/PERFORMANCE.md, ninth session): the truck of the
/// demo scene and the dragon of `bench frame`, each drawn by three compositors in one process,
/// frames interleaved: the sun per vertex on every culled mesh (no edge limit), with a 30-pixel
/// limit, with the default limit, and per pixel everywhere. Per compositor (each pass timed
/// alone; minimum and median of `PREVIZ_FRAMES`, default 30): the model pass of a frame whose
/// map was drawn after a kept one (the vertex sun run), the vertex sun's lookup and split (timed
/// each alone, on a kept map), a frame of the sun turning (the map drawn on consecutive frames:
/// its shadow pass and its model pass, per pixel), and the frame's pixels that differ from the
/// per-pixel one and their mean FLIP; per mesh its edges on screen. With
/// `PREVIZ_CROPS=dir`, writes the frames and 2× crops (per pixel | per vertex without a limit)
/// around where those two differ most. Run:
/// `cargo test --release --test integration vertex_sun:: -- --ignored --nocapture bench_vertex_sun`.
#[test]
#[ignore = "a benchmark; run it in release with --ignored --nocapture"]
fn bench_vertex_sun() {
    use previz::render::passes::model::MAX_SUN_EDGE_PX;
    use previz::setup::scene_file::SceneBuilder;
    let shared = |rel: &str| format!("{}/../shared/data/{rel}", env!("CARGO_MANIFEST_DIR"));
    let demo = SceneBuilder::from_toml(previz::scene::demo::SCENE_TOML, std::path::Path::new(".")).unwrap().build().unwrap();
    let dragon = common::scene(&format!(
        "model = \"{}\"\nenvironment = \"{}\"\nbackground = \"{}\"\n",
        shared("meshes/stanford-dragon-100k.obj"),
        shared("cubemaps/pisa_ldr_png"),
        shared("photos/colour_transfer/coffee.png")
    ));
    let frames: usize = std::env::var("PREVIZ_FRAMES").ok().and_then(|f| f.parse().ok()).unwrap_or(30);
    let crops = std::env::var("PREVIZ_CROPS").ok().map(std::path::PathBuf::from);
    let limits = [
        ("per vertex, no limit", f32::INFINITY),
        ("per vertex, limit 30 px", 30.0),
        ("per vertex, default limit", MAX_SUN_EDGE_PX),
        ("per pixel", 0.0),
    ];
    for (name, s, demo_inputs) in [("truck", &demo, true), ("dragon", &dragon, false)] {
        let i = previz::setup::load_inputs(s, demo_inputs).unwrap();
        let aa = Antialiasing::for_adapter(&gpu().adapter.get_info());
        let mut cs: Vec<(Compositor, FrameParams)> =
            limits.iter().map(|_| previz::setup::prepare_antialiased(gpu(), s, &i, aa).unwrap()).collect();
        for ((c, _), (_, limit)) in cs.iter_mut().zip(&limits) {
            c.set_sun_edge_limit(*limit);
            c.set_pass_timing(true);
        }
        let n = limits.len();
        let (mut model_ms, mut shadow_ms, mut moving_ms) = (vec![Vec::new(); n], vec![Vec::new(); n], vec![Vec::new(); n]);
        let mut after_shadow_ms: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n];
        let mut totals: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n];
        let (mut lookup_ms, mut split_ms, mut last, mut ran) = (vec![Vec::new(); n], vec![Vec::new(); n], vec![Vec::new(); n], vec![0; n]);
        for f in 0..frames + 2 {
            for (k, (c, p)) in cs.iter_mut().enumerate() {
                let mut q = *p;
                q.camera.pose *= Quat::from_rotation_y(1e-4 * f as f32);
                // After a kept map (the last frame of the loop): the map drawn, the vertex sun run.
                let r = c.render(gpu(), &q, Layer::Composite).unwrap();
                // The sun turned on the next frame: the map drawn again (moving), per pixel.
                let mut turning = q;
                turning.lighting.sun_dir = Quat::from_rotation_z((0.5 * f as f32 + 0.25).to_radians()) * q.lighting.sun_dir;
                let t = c.render(gpu(), &turning, Layer::Composite).unwrap();
                ran[k] += usize::from(c.passes_run().vertex_sun);
                // The same frame again: the map kept, the vertex sun run alone on it.
                let kept = c.render(gpu(), &turning, Layer::Composite).unwrap();
                if f >= 2 {
                    // The two frames that draw the map, whole (their passes' sum).
                    totals[k].push((r.timings.passes.unwrap().total(), t.timings.passes.unwrap().total()));
                    if let Some([lookup, split]) = r.timings.passes.unwrap().vertex_sun {
                        after_shadow_ms[k].push((lookup, split));
                    }
                    model_ms[k].push(r.timings.passes.unwrap().model.unwrap());
                    shadow_ms[k].push(t.timings.passes.unwrap().shadow.unwrap());
                    moving_ms[k].push(t.timings.passes.unwrap().model.unwrap());
                    if let Some([lookup, split]) = kept.timings.passes.unwrap().vertex_sun {
                        lookup_ms[k].push(lookup);
                        split_ms[k].push(split);
                    }
                }
                if f == frames + 1 {
                    // The unturned sun again for the images: its map drawn afresh.
                    last[k] = c.render(gpu(), &q, Layer::Composite).unwrap().rgba;
                }
            }
        }
        let stats = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.first().map_or((f64::NAN, f64::NAN), |&min| (min, v[v.len() / 2]))
        };
        let (w, h) = (s.width, s.height);
        let rgb = |rgba: &[u8]| rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect::<Vec<u8>>();
        println!(
            "\n{name}: level {}, {} frames (+2 warm-up), uptime {:?}",
            cs[0].0.lod_level(),
            frames,
            std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim()
        );
        let mut flips = Vec::new();
        for (k, (label, _)) in limits.iter().enumerate() {
            let (m_min, m_med) = stats(&mut model_ms[k]);
            let (s_min, s_med) = stats(&mut shadow_ms[k]);
            let (mv_min, mv_med) = stats(&mut moving_ms[k]);
            let (l_min, l_med) = stats(&mut lookup_ms[k]);
            let (sp_min, sp_med) = stats(&mut split_ms[k]);
            let (a_min, a_med) = stats(&mut after_shadow_ms[k].iter().map(|t| t.0).collect());
            let (b_min, b_med) = stats(&mut after_shadow_ms[k].iter().map(|t| t.1).collect());
            let (r_min, r_med) = stats(&mut totals[k].iter().map(|t| t.0).collect());
            let (t_min, t_med) = stats(&mut totals[k].iter().map(|t| t.1).collect());
            let flip = previz::bench::accuracy::flip_map(&rgb(&last[n - 1]), &rgb(&last[k]), w, h).unwrap();
            let mean_flip = flip.iter().map(|&v| f64::from(v)).sum::<f64>() / flip.len() as f64;
            let differ = last[k].chunks_exact(4).zip(last[n - 1].chunks_exact(4)).filter(|(a, b)| a != b).count();
            println!(
                "  {label}: per mesh (edges on screen px, per vertex) {:?}; split (triangles per vertex, per pixel) {:?}",
                cs[k].0.sun_per_mesh(),
                cs[k].0.vertex_sun_split(gpu()).unwrap()
            );
            println!(
                "    model pass min {m_min:.2} median {m_med:.2} ms; vertex sun on a kept map: lookup min {l_min:.2} median {l_med:.2} ms, split min {sp_min:.2} median {sp_med:.2} ms; {differ} pixels differ from per pixel, mean FLIP {mean_flip:.5}"
            );
            println!(
                "    vertex sun after the shadow pass (from its end): lookup min {a_min:.2} median {a_med:.2} ms, split min {b_min:.2} median {b_med:.2} ms"
            );
            println!(
                "    frame drawing the map, passes' sum: after a kept map (vertex sun run) min {r_min:.2} median {r_med:.2} ms, on consecutive frames (per pixel) min {t_min:.2} median {t_med:.2} ms"
            );
            println!(
                "    sun turning: shadow pass min {s_min:.2} median {s_med:.2} ms, model pass min {mv_min:.2} median {mv_med:.2} ms; vertex sun ran in {} of {} of those frames",
                ran[k],
                frames + 2
            );
            flips.push(flip);
        }
        if let Some(dir) = &crops {
            std::fs::create_dir_all(dir).unwrap();
            // The 160×120 window with the largest FLIP sum, 2× (nearest): per pixel | no limit.
            let flip = &flips[0];
            let (cw, ch) = (160u32, 120u32);
            let mut best = (0.0f64, 0u32, 0u32);
            for y in (0..h - ch).step_by(8) {
                for x in (0..w - cw).step_by(8) {
                    let window = (y..y + ch).step_by(2).flat_map(|yy| (x..x + cw).step_by(2).map(move |xx| (xx, yy)));
                    let sum: f64 = window.map(|(xx, yy)| f64::from(flip[(yy * w + xx) as usize])).sum();
                    if sum > best.0 {
                        best = (sum, x, y);
                    }
                }
            }
            let (_, x0, y0) = best;
            let mut out = image::RgbaImage::new(4 * cw + 8, 2 * ch);
            for (k, side) in [(n - 1, 0u32), (0, 2 * cw + 8)] {
                for y in 0..2 * ch {
                    for x in 0..2 * cw {
                        let at = (4 * ((y0 + y / 2) * w + x0 + x / 2)) as usize;
                        let p = &last[k][at..at + 4];
                        out.put_pixel(side + x, y, image::Rgba([p[0], p[1], p[2], 255]));
                    }
                }
            }
            out.save(dir.join(format!("{name}_crop_x{x0}_y{y0}_per_pixel_vs_per_vertex.png"))).unwrap();
            for (k, label) in [(0, "per_vertex"), (n - 1, "per_pixel")] {
                image::RgbaImage::from_raw(w, h, last[k].clone()).unwrap().save(dir.join(format!("{name}_{label}.png"))).unwrap();
            }
        }
    }
}

/// What the vertex sun adds to start-up (docs/PERFORMANCE.md, tenth session): the model pass's
/// pipelines as built (per-pixel culled and not, the `VERTEX_SUN` set and the
/// light-from-vertices set, each with and without correction: 64 slots, 46 built: the
/// refractions' `VERTEX_SUN` slots reuse their per-pixel pipelines, and every
/// light-from-vertices slot but sh9-ggx's its `VERTEX_SUN` one), 16 more of the per-pixel culled
/// kind built the same way (what a set of 16 such pipelines costs; they differ only by override
/// constants), and the
/// vertex sun's three compute pipelines; `PREVIZ_ROUNDS` rounds (default 5) interleaved, the
/// first round (a cold shader cache) and the minimum of each. Run:
/// `cargo test --release --test integration vertex_sun:: -- --ignored --nocapture bench_pipeline_start_up`.
#[test]
#[ignore = "a benchmark; run it in release with --ignored --nocapture"]
fn bench_pipeline_start_up() {
    use previz::render::passes::{model, vertex_sun};
    use std::time::Instant;
    let device = &gpu().device;
    let rounds: usize = std::env::var("PREVIZ_ROUNDS").ok().and_then(|f| f.parse().ok()).unwrap_or(5);
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let (mut all, mut sixteen, mut compute) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        let t = Instant::now();
        let set = model::pipelines(device, 4);
        all.push(ms(t));
        let t = Instant::now();
        let layouts = (&set.layout, &set.material_layout);
        let more: Vec<_> = [false, true]
            .into_iter()
            .flat_map(|corrected| model::pipelines_for(device, layouts, (previz::render::pipelines::COLOR_FORMAT, 4), (corrected, true)))
            .collect();
        sixteen.push(ms(t));
        let t = Instant::now();
        let c = vertex_sun::pipelines(device);
        compute.push(ms(t));
        assert_eq!((set.shading.len(), more.len()), (64, 16));
        drop((set, more, c));
    }
    let show = |name: &str, v: &[f64]| {
        let min = v.iter().copied().fold(f64::MAX, f64::min);
        println!("{name}: first {:.1} ms, min {min:.1} ms over {} rounds", v[0], v.len());
    };
    println!("uptime {:?}", std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim());
    show("model pipelines (64 slots, 46 built, 12 of them VERTEX_SUN, 2 light from vertices)", &all);
    show("16 culled per-pixel model pipelines", &sixteen);
    show("vertex sun compute pipelines (3)", &compute);
}
