//! Shared test harness: one GPU device per test binary, scenes from TOML text, and golden-image
//! comparison with NVIDIA FLIP.
#![allow(dead_code)]

pub mod cli;
pub mod xvfb;

use previz::gpu::Gpu;
use previz::render::{Layer, Rendered};
use previz::scene::{Material, Mesh, Model};
use previz::setup::scene_file::{Scene, SceneBuilder};
use previz::setup::{Inputs, load_inputs, prepare};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The test data folder, tests/data (origin and licence of each file: tests/data/SOURCES.md).
pub fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
}

pub fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| Gpu::headless().expect("a Vulkan/GL adapter (lavapipe in CI)"))
}

/// A scene from TOML whose relative paths are relative to the test data folder.
pub fn scene(toml: &str) -> Scene {
    SceneBuilder::from_toml(toml, &data("")).unwrap().build().unwrap()
}

pub fn inputs(scene: &Scene) -> Inputs {
    load_inputs(scene, false).unwrap()
}

/// Render one layer of a scene with already-loaded inputs.
pub fn render_with(scene: &Scene, inputs: &Inputs, layer: Layer) -> Rendered {
    let (mut compositor, params) = prepare(gpu(), scene, inputs).unwrap();
    compositor.render(gpu(), &params, layer).unwrap()
}

/// Render the composite of a scene given as TOML.
pub fn render(toml: &str) -> Rendered {
    let s = scene(toml);
    let i = inputs(&s);
    render_with(&s, &i, Layer::Composite)
}

/// Linear-ish helpers on the 8-bit result.
pub fn pixel(r: &Rendered, x: u32, y: u32) -> [u8; 4] {
    let i = 4 * (y * r.width + x) as usize;
    [r.rgba[i], r.rgba[i + 1], r.rgba[i + 2], r.rgba[i + 3]]
}

/// Mean RGB (0..255) over a rectangle.
pub fn mean_rgb(r: &Rendered, x0: u32, y0: u32, x1: u32, y1: u32) -> [f64; 3] {
    let mut s = [0f64; 3];
    let mut n = 0f64;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = pixel(r, x, y);
            for c in 0..3 {
                s[c] += f64::from(p[c]);
            }
            n += 1.0;
        }
    }
    s.map(|v| v / n)
}

fn rgb(r: &Rendered) -> Vec<u8> {
    r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

fn failures_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/golden-failures");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Mean FLIP must stay at or below wgpu's own bar (0.02) and the 99th percentile below 0.3
/// (at most 1% of pixels may differ visibly). `PREVIZ_BLESS=1` rewrites the golden instead —
/// only ever on purpose, after looking at the new image.
pub const MAX_MEAN_FLIP: f32 = 0.02;
pub const MAX_P99_FLIP: f32 = 0.3;

pub fn assert_golden(name: &str, r: &Rendered) {
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden").join(format!("{name}.png"));
    if std::env::var_os("PREVIZ_BLESS").is_some_and(|v| v == "1") {
        image::save_buffer(&golden, &rgb(r), r.width, r.height, image::ExtendedColorType::Rgb8).unwrap();
        eprintln!("blessed {}", golden.display());
        return;
    }
    let reference = image::open(&golden)
        .unwrap_or_else(|e| panic!("golden {} unreadable ({e}); render it with PREVIZ_BLESS=1 and look at it", golden.display()))
        .to_rgb8();
    assert_eq!((reference.width(), reference.height()), (r.width, r.height), "{name}: size differs from the golden");
    let actual = rgb(r);
    let error = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(r.width, r.height, reference.as_raw()),
        nv_flip::FlipImageRgb8::with_data(r.width, r.height, &actual),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let mut pool = nv_flip::FlipPool::from_image(&error);
    let mean = pool.mean();
    let p99 = pool.get_percentile(0.99, false);
    if mean > MAX_MEAN_FLIP || p99 > MAX_P99_FLIP {
        let dir = failures_dir();
        let actual_path = dir.join(format!("{name}-actual.png"));
        let diff_path = dir.join(format!("{name}-diff.png"));
        image::save_buffer(&actual_path, &actual, r.width, r.height, image::ExtendedColorType::Rgb8).unwrap();
        let diff = error.apply_color_lut(&nv_flip::magma_lut());
        image::save_buffer(&diff_path, &diff.to_vec(), r.width, r.height, image::ExtendedColorType::Rgb8).unwrap();
        panic!(
            "{name}: FLIP mean {mean:.4} (max {MAX_MEAN_FLIP}), p99 {p99:.4} (max {MAX_P99_FLIP}); wrote {} and {}",
            actual_path.display(),
            diff_path.display()
        );
    }
}

/// One upright triangle, 2 units tall, facing +z: the smallest model a compositor accepts.
pub fn triangle() -> Model {
    let mesh = Mesh {
        positions: vec![[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 3],
        uvs: vec![[0.0, 0.0]; 3],
        indices: vec![0, 1, 2],
        material: 0,
    };
    Model { meshes: vec![mesh], materials: vec![Material::default()] }
}

/// wgpu's resource counters (its `counters` feature) once the GPU is idle: staging buffers of
/// finished uploads (`write_buffer`/`write_texture`) are freed only when the device is polled, so
/// reading the counters without waiting counted 19 or 25 buffers depending on timing.
pub fn settled_counters() -> wgpu::HalCounters {
    gpu().device.poll(wgpu::PollType::wait_indefinitely()).expect("waiting for the GPU");
    let c = gpu().device.get_internal_counters().hal;
    assert!(c.buffers.read() > 0 && c.render_pipelines.read() > 0, "wgpu counters are not enabled");
    c
}

/// The count of one kind of GPU resource, by the name used in assertion messages.
fn count(c: &wgpu::HalCounters, name: &str) -> isize {
    match name {
        "buffers" => c.buffers.read(),
        "textures" => c.textures.read(),
        "texture views" => c.texture_views.read(),
        "bind groups" => c.bind_groups.read(),
        "render pipelines" => c.render_pipelines.read(),
        "compute pipelines" => c.compute_pipelines.read(),
        "shader modules" => c.shader_modules.read(),
        "samplers" => c.samplers.read(),
        "pipeline layouts" => c.pipeline_layouts.read(),
        "bind group layouts" => c.bind_group_layouts.read(),
        _ => panic!("no wgpu counter named {name}"),
    }
}

/// Every resource a frame could allocate.
pub const FRAME_RESOURCES: [&str; 8] =
    ["buffers", "textures", "texture views", "bind groups", "render pipelines", "compute pipelines", "shader modules", "samplers"];

/// Asserts that none of `names` changed between the two counter readings.
pub fn assert_unchanged(before: &wgpu::HalCounters, after: &wgpu::HalCounters, names: &[&str], across: &str) {
    for name in names {
        assert_eq!(count(before, name), count(after, name), "{name} changed across {across}");
    }
}

/// A synthetic world for the folded environment: every direction East of the meridian plane
/// (x > 0) red, West blue, both below 1 (an 8-bit map without a sun: ambient and reflections
/// only).
pub fn east_red_west_blue(size: u32) -> previz::scene::CubeMap {
    use previz::scene::cubemap::face_uv_to_cube_dir;
    let faces = std::array::from_fn(|layer| {
        (0..size * size)
            .map(|i| {
                let (x, y) = ((i % size) as f32 + 0.5, (i / size) as f32 + 0.5);
                let d = previz::scene::cube_to_enu(face_uv_to_cube_dir(layer, x / size as f32, y / size as f32));
                if d.x > 0.0 { [0.8, 0.08, 0.08] } else { [0.08, 0.08, 0.8] }
            })
            .collect()
    });
    previz::scene::CubeMap { size, faces }
}

/// A closed UV sphere of radius 0.8 around the model's origin, `rings` × 2·`rings` quads (two
/// triangles each, counter-clockwise seen from outside), single-sided, of `material`.
pub fn uv_sphere(rings: u32, material: Material) -> Model {
    let mut mesh = Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), material: 0 };
    let segments = 2 * rings;
    for j in 0..=rings {
        let theta = std::f32::consts::PI * j as f32 / rings as f32;
        for i in 0..=segments {
            let phi = std::f32::consts::TAU * i as f32 / segments as f32;
            let n = glam::Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            mesh.positions.push((0.8 * n).to_array());
            mesh.normals.push(n.to_array());
            mesh.uvs.push([0.0, 0.0]);
        }
    }
    let at = |i: u32, j: u32| j * (segments + 1) + i;
    for j in 0..rings {
        for i in 0..segments {
            mesh.indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Model { meshes: vec![mesh], materials: vec![Material { sides: previz::scene::Sides::Front, ..material }] }
}

/// A single-sided square grid of `n`×`n` quads, 2 model units wide, in the model's base plane
/// (y = 0, facing +y), material 0.
pub fn flat_grid(n: u32) -> Mesh {
    let mut grid = Mesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), material: 0 };
    for j in 0..=n {
        for i in 0..=n {
            grid.positions.push([2.0 * i as f32 / n as f32 - 1.0, 0.0, 2.0 * j as f32 / n as f32 - 1.0]);
            grid.normals.push([0.0, 1.0, 0.0]);
            grid.uvs.push([0.0, 0.0]);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            // Counter-clockwise seen from +y: x then -z.
            grid.indices.extend([at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    grid
}

/// Adds a closed box to `mesh`: centred at `centre`, `half` its half-extent on each axis, flat
/// faces wound counter-clockwise seen from outside.
pub fn push_box(mesh: &mut Mesh, centre: glam::Vec3, half: glam::Vec3) {
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let normal = glam::Vec3::from_array(std::array::from_fn(|k| if k == axis { sign } else { 0.0 }));
            let (u, v) = (normal.any_orthonormal_vector(), normal.cross(normal.any_orthonormal_vector()));
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push((centre + half * (normal + a * u + b * v)).to_array());
                mesh.normals.push(normal.to_array());
                mesh.uvs.push([0.0, 0.0]);
            }
            let quad = if u.cross(v).dot(normal) > 0.0 { [0, 1, 2, 0, 2, 3] } else { [0, 2, 1, 0, 3, 2] };
            mesh.indices.extend(quad.iter().map(|k| base + k));
        }
    }
}

/// `grid` (material 0, grey 0.8) and `boxes` (material 1, red), single-sided, no specular.
pub fn grey_grid_red_boxes(grid: Mesh, boxes: Mesh) -> Model {
    let material = |diffuse: [f32; 3]| Material { diffuse, specular: [0.0; 3], sides: previz::scene::Sides::Front, ..Material::default() };
    Model { meshes: vec![grid, boxes], materials: vec![material([0.8; 3]), material([0.8, 0.0, 0.0])] }
}

/// A 320×240 compositor without antialiasing over `model` drawn at full detail, and a frame
/// seen from `3 × scale` straight above the model's base (image up = North), the model at the
/// origin unturned and scaled by `scale`, lit by the sun alone (no ambient, no specular, no
/// colour correction, no ground pass): a pixel is its sun's visibility × n·l × a constant. The
/// map is a uniform grey cube.
pub fn sun_alone_from_above(
    model: Model,
    method: previz::render::LightingMethod,
    scale: f32,
) -> (previz::render::Compositor, previz::render::FrameParams) {
    use glam::{Quat, Vec3};
    let s = scene("width = 320\nheight = 240\n");
    let env = previz::scene::CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) };
    let inputs = Inputs { model, env, env_equirect: None, background: None };
    let (mut c, mut p) = previz::setup::prepare_antialiased(gpu(), &s, &inputs, previz::render::Antialiasing::Msaa(1)).unwrap();
    c.set_detail(previz::render::Detail::Full);
    p.method = method;
    (p.placement.position, p.placement.rotation, p.placement.scale) = (Vec3::ZERO, Vec3::ZERO, scale);
    p.camera.position = Vec3::new(0.0, 0.0, 3.0 * scale);
    p.camera.pose = Quat::IDENTITY;
    p.camera.vfov = 60f32.to_radians();
    (p.lighting.shadow_opacity, p.lighting.sky_occlusion) = (0.0, 0.0);
    p.lighting.material = previz::render::MaterialTerms { ambient: 0.0, diffuse: 1.0, specular: 0.0, gloss: None };
    p.colour.method = previz::colour::transfer::TransferMethod::None;
    (c, p)
}
