//! Per-frame work allocates no GPU resources, further frames reuse the pipelines, and a second
//! composite in the same process compiles no shaders. Alone in its own test binary: wgpu's
//! counters are per device, and other tests would allocate.

mod common;

use common::{gpu, scene};
use previz::render::Layer;
use previz::scene::{CubeMap, Material, Mesh, Model};
use previz::setup::{Inputs, prepare};

fn triangle() -> Model {
    let mesh = Mesh {
        positions: vec![[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 3],
        uvs: vec![[0.0, 0.0]; 3],
        indices: vec![0, 1, 2],
        material: 0,
    };
    Model { meshes: vec![mesh], materials: vec![Material::default()] }
}

#[test]
fn frames_allocate_no_gpu_resources_and_reuse_pipelines() {
    let s = scene("width = 160\nheight = 120\n");
    let inputs =
        Inputs { model: triangle(), env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) }, background: None };
    let (mut compositor, mut params) = prepare(gpu(), &s, &inputs).unwrap();
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    let before = gpu().device.get_internal_counters().hal;
    // The counters only count with wgpu's `counters` feature; without it this test would be empty.
    assert!(before.buffers.read() > 0 && before.render_pipelines.read() > 0, "wgpu counters are not enabled");
    for i in 0..5 {
        params.camera.pose *= glam::Quat::from_rotation_y(0.1 * i as f32);
        for layer in [Layer::Composite, Layer::Model, Layer::Background] {
            compositor.render(gpu(), &params, layer).unwrap();
        }
    }
    let after = gpu().device.get_internal_counters().hal;
    for (name, a, b) in [
        ("buffers", &before.buffers, &after.buffers),
        ("textures", &before.textures, &after.textures),
        ("texture views", &before.texture_views, &after.texture_views),
        ("bind groups", &before.bind_groups, &after.bind_groups),
        ("render pipelines", &before.render_pipelines, &after.render_pipelines),
        ("shader modules", &before.shader_modules, &after.shader_modules),
        ("samplers", &before.samplers, &after.samplers),
    ] {
        assert_eq!(a.read(), b.read(), "{name} changed across frames");
    }
    lod_switches_allocate_nothing();
    a_second_composite_reuses_the_pipelines();
}

/// Called from the one test: a model moving away switches level of detail frame by frame
/// (every level was uploaded at set_model) without allocating.
fn lod_switches_allocate_nothing() {
    let s = scene(
        "width = 320
height = 240
[placement]
fill = 0.8
",
    );
    let model = previz::scene::model::load_model(&common::data("meshes/icosphere-320.obj")).unwrap();
    let inputs = Inputs { model, env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) }, background: None };
    let (mut compositor, params) = prepare(gpu(), &s, &inputs).unwrap();
    assert!(compositor.lod_triangles().unwrap().len() >= 3, "{:?}", compositor.lod_triangles());
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    let before = gpu().device.get_internal_counters().hal;
    let mut levels = Vec::new();
    for i in 0..8 {
        let mut p = params;
        let toward = p.placement.position - p.camera.position;
        p.placement.position = p.camera.position + toward * 2f32.powi(i);
        compositor.render(gpu(), &p, Layer::Composite).unwrap();
        levels.push(compositor.lod_level());
    }
    let after = gpu().device.get_internal_counters().hal;
    levels.dedup();
    assert!(levels.len() >= 3, "the level did not follow the distance: {levels:?}");
    for (name, a, b) in [
        ("buffers", &before.buffers, &after.buffers),
        ("textures", &before.textures, &after.textures),
        ("texture views", &before.texture_views, &after.texture_views),
        ("bind groups", &before.bind_groups, &after.bind_groups),
    ] {
        assert_eq!(a.read(), b.read(), "{name} changed across level switches");
    }
}

/// Called from the one test: the counters are per device and tests run in parallel.
fn a_second_composite_reuses_the_pipelines() {
    let s = scene("width = 96\nheight = 64\n");
    let inputs =
        Inputs { model: triangle(), env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) }, background: None };
    let (mut first, params) = prepare(gpu(), &s, &inputs).unwrap();
    first.render(gpu(), &params, Layer::Composite).unwrap();
    let before = gpu().device.get_internal_counters().hal;
    let (mut second, params) = prepare(gpu(), &s, &inputs).unwrap();
    second.render(gpu(), &params, Layer::Composite).unwrap();
    let after = gpu().device.get_internal_counters().hal;
    // The second compositor has its own targets and buffers, but no new pipeline or shader.
    assert!(after.buffers.read() > before.buffers.read(), "the second compositor allocated no buffers");
    for (name, a, b) in [
        ("render pipelines", &before.render_pipelines, &after.render_pipelines),
        ("shader modules", &before.shader_modules, &after.shader_modules),
        ("pipeline layouts", &before.pipeline_layouts, &after.pipeline_layouts),
        ("bind group layouts", &before.bind_group_layouts, &after.bind_group_layouts),
    ] {
        assert_eq!(a.read(), b.read(), "{name}: the second composite built new ones");
    }
}
