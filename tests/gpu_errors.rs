//! Every GPU entry point reports what the GPU rejects as an `Err` naming the work, instead of a
//! line on stderr from the uncaptured-error handler: each is fed input beyond a device whose
//! limits were lowered on purpose, and no error may escape to the handler.

use previz::capture::frame_fold::{FrameFold, ScreenBox};
use previz::colour::correction::ColourCorrection;
use previz::colour::gpu::CorrectPass;
use previz::gpu::Gpu;
use previz::priors::gpu::PriorsReducer;
use previz::render::{Compositor, Layer};
use previz::scene::{CubeMap, Material, Mesh, Model, Rgba8Image};
use previz::setup::scene_file::SceneBuilder;
use previz::setup::{Inputs, prepare};
use previz::ui::headless::HeadlessUi;

/// A device whose 2D textures may be at most 256 texels per side, with `adjust`'s changes and
/// otherwise the default limits.
fn small_gpu(adjust: impl FnOnce(&mut wgpu::Limits)) -> Gpu {
    let mut limits = wgpu::Limits { max_texture_dimension_2d: 256, ..Default::default() };
    adjust(&mut limits);
    Gpu::headless_with_limits(limits).expect("a Vulkan/GL adapter (lavapipe in CI)")
}

fn grey(width: u32, height: u32) -> Rgba8Image {
    Rgba8Image { width, height, pixels: vec![128; (4 * width * height) as usize] }
}

fn cube(size: u32) -> CubeMap {
    CubeMap { size, faces: std::array::from_fn(|_| vec![[0.5, 0.5, 0.5]; (size * size) as usize]) }
}

/// One textured triangle.
fn model(texture: Rgba8Image) -> Model {
    let mesh = Mesh {
        positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 3],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        indices: vec![0, 1, 2],
        material: 0,
    };
    Model { meshes: vec![mesh], materials: vec![Material { texture: Some(texture), ..Default::default() }] }
}

#[track_caller]
fn assert_rejected<T>(result: anyhow::Result<T>, what: &str) {
    match result {
        Ok(_) => panic!("{what}: accepted input beyond the device's limits"),
        Err(e) => assert!(format!("{e:#}").contains(what), "error does not name {what:?}: {e:#}"),
    }
}

#[test]
fn every_entry_point_returns_gpu_errors() {
    let gpu = small_gpu(|_| {});
    // The compositor: a 300-texel environment face and a 300×300 model texture exceed 256.
    let mut compositor = Compositor::new(&gpu, 64, 48).unwrap();
    assert_rejected(compositor.set_environment(&gpu, &cube(300), 1.0, 0.0), "the GPU rejected the environment cube map");
    assert_rejected(compositor.set_model(&gpu, &model(grey(300, 300))), "the GPU rejected the model's buffers and textures");
    // The output size itself is checked before any GPU work, with the limit in the message.
    assert_rejected(Compositor::new(&gpu, 300, 48), "outside 1..=256");
    // The frame fold, the colour pass and the headless UI.
    let mut fold = FrameFold::new(&gpu, 32).unwrap();
    let pose = glam::Quat::IDENTITY;
    assert_rejected(fold.render(&gpu, &grey(300, 8), pose, ScreenBox::FULL), "the GPU rejected the frame fold");
    let pass = CorrectPass::new(&gpu).unwrap();
    assert_rejected(pass.run(&gpu, &grey(300, 8), &ColourCorrection::identity(), 1), "the GPU rejected the colour-correction pass");
    assert_rejected(HeadlessUi::new(&gpu, 300, 8, 1.0), "outside 1..=256");
    // Valid work on the same device still succeeds afterwards.
    assert!(fold.render(&gpu, &grey(64, 48), pose, ScreenBox::FULL).is_ok());
    assert!(pass.run(&gpu, &grey(16, 8), &ColourCorrection::identity(), 1).is_ok());
    assert_eq!(gpu.uncaptured_errors(), 0, "GPU errors escaped to stderr");
}

#[test]
fn pipeline_creation_and_the_priors_reduction_return_gpu_errors() {
    // The model pass needs two bind groups: with one allowed, the render pipelines fail.
    let gpu = small_gpu(|l| l.max_bind_groups = 1);
    assert_rejected(Compositor::new(&gpu, 64, 48), "the GPU rejected the render pipelines");
    assert_eq!(gpu.uncaptured_errors(), 0, "GPU errors escaped to stderr");

    // The reduction binds four storage buffers per stage.
    let gpu = small_gpu(|l| l.max_storage_buffers_per_shader_stage = 2);
    assert_rejected(PriorsReducer::new(&gpu), "the GPU rejected the priors reduction pipelines");
    assert_eq!(gpu.uncaptured_errors(), 0, "GPU errors escaped to stderr");

    // 64 KiB storage bindings: a 512×512 frame is split into 16 chunks, whose partial sums
    // (16 × 256 rows × 72 bytes) no longer fit one binding.
    let gpu = small_gpu(|l| l.max_storage_buffer_binding_size = 64 * 1024);
    let mut reducer = PriorsReducer::new(&gpu).unwrap();
    let frame = Rgba8Image { width: 512, height: 512, pixels: [90, 120, 200, 255].repeat(512 * 512) };
    assert_rejected(reducer.frame(&gpu, &frame), "the GPU rejected the priors reduction");
    // A frame that fits one chunk still reduces.
    assert!(reducer.frame(&gpu, &grey(64, 64)).is_ok());
    assert_eq!(gpu.uncaptured_errors(), 0, "GPU errors escaped to stderr");
}

#[test]
fn a_rejected_model_or_environment_leaves_the_current_one() {
    let gpu = small_gpu(|_| {});
    let scene = SceneBuilder::from_toml("width = 64\nheight = 48\n", std::path::Path::new(".")).unwrap().build().unwrap();
    let inputs = Inputs { model: model(grey(8, 8)), env: cube(8), env_equirect: None, background: None };
    let (mut compositor, params) = prepare(&gpu, &scene, &inputs).unwrap();
    let before = compositor.render(&gpu, &params, Layer::Composite).unwrap().rgba;
    let background = compositor.render(&gpu, &params, Layer::Background).unwrap().rgba;
    assert_ne!(before, background, "the model is not in the frame, so the test could not see it change");
    let bounds = compositor.model_bounds();

    // A larger model whose texture is beyond the device's limits: rejected, the old one stays.
    let mut big = model(grey(300, 300));
    big.meshes[0].positions.iter_mut().flatten().for_each(|c| *c *= 10.0);
    assert_rejected(compositor.set_model(&gpu, &big), "the GPU rejected the model's buffers and textures");
    assert_eq!(compositor.model_bounds(), bounds);
    // A model with a bad index is rejected before any GPU work.
    let mut broken = model(grey(8, 8));
    broken.meshes[0].indices[2] = 7;
    assert!(compositor.set_model(&gpu, &broken).is_err());
    // A brighter environment too large for the device: rejected, the old one stays.
    let mut bright = cube(300);
    bright.faces.iter_mut().flatten().for_each(|p| *p = [4.0; 3]);
    assert_rejected(compositor.set_environment(&gpu, &bright, 1.0, 0.0), "the GPU rejected the environment cube map");

    let after = compositor.render(&gpu, &params, Layer::Composite).unwrap().rgba;
    assert!(before == after, "the frame changed after rejected uploads");
    assert_eq!(gpu.uncaptured_errors(), 0, "GPU errors escaped to stderr");
}
