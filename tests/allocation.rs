//! Per-frame work allocates no GPU resources, further frames reuse the pipelines, and a second
//! composite in the same process compiles no shaders. Alone in its own test binary: wgpu's
//! counters are per device, and other tests would allocate.

mod common;

use common::{FRAME_RESOURCES, assert_unchanged, gpu, scene, settled_counters, triangle};
use previz::render::{Antialiasing, Layer};
use previz::scene::CubeMap;
use previz::scene::environment::Equirect;
use previz::setup::{Inputs, prepare, prepare_antialiased};

#[test]
fn frames_allocate_no_gpu_resources_and_reuse_pipelines() {
    let s = scene("width = 160\nheight = 120\n");
    // The background is the environment's equirect, looked up directly (env_view_equirect.wgsl).
    let equirect = Equirect::new(8, 4, vec![[0.5; 3]; 32]).unwrap();
    let env = CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) };
    let inputs = Inputs { model: triangle(), env, env_equirect: Some(std::sync::Arc::new(equirect)), background: None };
    // Frames of the live view: one sample a pixel (a still, setup::prepare, is supersampled).
    let (mut compositor, mut params) = prepare_antialiased(gpu(), &s, &inputs, Antialiasing::STILL).unwrap();
    assert!(compositor.background_sees_equirect());
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    let start = params;
    let before = settled_counters();
    for i in 0..5 {
        params.camera.pose *= glam::Quat::from_rotation_y(0.1 * i as f32);
        for layer in [Layer::Composite, Layer::Model, Layer::Background] {
            compositor.render(gpu(), &params, layer).unwrap();
        }
    }
    let after = settled_counters();
    assert_unchanged(&before, &after, &FRAME_RESOURCES, "frames");
    // The uniform grey map has no sun: the ground's contact shadow is the model's occlusion of
    // the sky, computed once for the placement, not per frame.
    assert!(params.lighting.sky_occlusion > 0.99, "{}", params.lighting.sky_occlusion);
    assert_eq!(compositor.ground_sky_updates(), 1);
    // Where that occlusion is visible, once for the placement; the shadow's outline at most
    // once (the camera turning keeps the shadow map).
    let (outlines, sky_regions) = compositor.ground_regions_computed();
    assert!(outlines <= 1 && sky_regions == 1, "{outlines} outlines, {sky_regions} sky regions");
    placements_write_the_ground_sky_once_each(&mut compositor, &start);
    lod_switches_allocate_nothing();
    antialiased_frames_allocate_nothing();
    reprojected_frames_allocate_nothing();
    a_second_composite_reuses_the_pipelines();
}

/// Called from the one test: turning the model computes the ground's sky visibility again and
/// writes it into the texture made up front (no allocation), once per placement; moving it
/// alone does not.
fn placements_write_the_ground_sky_once_each(compositor: &mut previz::render::Compositor, params: &previz::render::FrameParams) {
    let before = settled_counters();
    let updates = compositor.ground_sky_updates();
    let regions = compositor.ground_regions_computed().1;
    for i in 1..=3 {
        let mut p = *params;
        p.placement.position.x += 0.2 * i as f32;
        p.placement.rotation.z = 0.3 * i as f32;
        for _ in 0..2 {
            compositor.render(gpu(), &p, Layer::Composite).unwrap();
        }
        assert_eq!(compositor.ground_sky_updates(), updates + i, "placement {i}");
        assert_eq!(compositor.ground_regions_computed().1, regions + i, "placement {i}: the sky's region once");
    }
    // Moving the model without turning or scaling it reuses the map (it moves with the model).
    let mut moved = *params;
    moved.placement.rotation.z = 0.3 * 3.0; // the last turn above
    for dx in [0.1, -0.3, 0.25] {
        moved.placement.position.x += dx;
        compositor.render(gpu(), &moved, Layer::Composite).unwrap();
    }
    assert_eq!(compositor.ground_sky_updates(), updates + 3, "moving the model computed the map again");
    assert_eq!(compositor.ground_regions_computed().1, regions + 3, "moving the model computed the sky's region again");
    let after = settled_counters();
    assert_unchanged(&before, &after, &FRAME_RESOURCES, "placements");
}

/// Called from the one test: with FXAA (its pass and input texture) and with 4× MSAA, frames
/// allocate nothing either.
fn antialiased_frames_allocate_nothing() {
    let s = scene("width = 160\nheight = 120\n");
    let inputs = Inputs {
        model: triangle(),
        env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) },
        env_equirect: None,
        background: None,
    };
    for aa in [Antialiasing::Fxaa, Antialiasing::Msaa(4)] {
        let (mut compositor, mut params) = prepare_antialiased(gpu(), &s, &inputs, aa).unwrap();
        assert_eq!(compositor.antialiasing(), aa);
        compositor.render(gpu(), &params, Layer::Composite).unwrap();
        let before = settled_counters();
        for i in 0..3 {
            params.camera.pose *= glam::Quat::from_rotation_y(0.1 * i as f32);
            compositor.render(gpu(), &params, Layer::Composite).unwrap();
        }
        assert_unchanged(&before, &settled_counters(), &FRAME_RESOURCES, &format!("frames with {}", aa.name()));
    }
}

/// Called from the one test: the live view's reprojection (render::reprojection) allocates its
/// layers when it is turned on; frames that compose them through a turn and frames that shade
/// them again (a new placement) allocate nothing, one sample a pixel (packed) or four.
fn reprojected_frames_allocate_nothing() {
    let s = scene("width = 160\nheight = 120\n");
    let background = previz::scene::Rgba8Image { width: 160, height: 120, pixels: vec![128; 4 * 160 * 120] };
    let inputs = Inputs {
        model: triangle(),
        env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) },
        env_equirect: None,
        background: Some(background),
    };
    for aa in [Antialiasing::Msaa(1), Antialiasing::Msaa(4)] {
        let (mut compositor, mut params) = previz::setup::prepare_reprojected(gpu(), &s, &inputs, aa).unwrap();
        compositor.render(gpu(), &params, Layer::Composite).unwrap();
        let before = settled_counters();
        for i in 0..6 {
            params.camera.pose *= glam::Quat::from_rotation_y(0.01 * i as f32);
            if i == 3 {
                params.placement.rotation.z += 0.2;
            }
            compositor.render(gpu(), &params, Layer::Composite).unwrap();
        }
        let (reprojected, shaded) = compositor.reprojection_counts();
        assert!(reprojected >= 4 && shaded >= 2, "{reprojected} reprojected, {shaded} shaded");
        assert_unchanged(&before, &settled_counters(), &FRAME_RESOURCES, &format!("reprojected frames, {}", aa.name()));
    }
}

/// Called from the one test: a model moving away switches level of detail and shadow-map size
/// frame by frame, and draws the ground's sun into its texture, without allocating (every level,
/// every map and the ground-sun texture were allocated up front).
fn lod_switches_allocate_nothing() {
    let s = scene(
        "width = 320
height = 240
[placement]
fill = 0.8
",
    );
    let model = previz::scene::model::load_model(&common::data("meshes/icosphere-320.obj")).unwrap();
    let inputs = Inputs {
        model,
        env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) },
        env_equirect: None,
        background: None,
    };
    let (mut compositor, params) = prepare(gpu(), &s, &inputs).unwrap();
    // Frames drawn one after another: the levels the screen allows, and the ground's sun drawn
    // into its texture (render::passes::ground_sun) whenever the map holds still.
    compositor.set_detail(previz::render::Detail::Frame);
    // The sun per vertex wherever a mesh may take it (the default limit would let the sphere
    // take it only at some distances), with its split and indirect draws.
    compositor.set_sun_edge_limit(f32::INFINITY);
    assert!(compositor.lod_triangles().unwrap().len() >= 3, "{:?}", compositor.lod_triangles());
    // A colour correction (the first asks for the model's statistics) and the sun up, so the
    // ground is drawn in two parts.
    let corrected = previz::render::ColourSettings { method: previz::colour::transfer::TransferMethod::TRANSFERS[0], strength: 1.0 };
    let mut params = params;
    params.lighting.sun_dir = glam::Vec3::new(0.3, -0.6, 0.7);
    (params.lighting.sunlight, params.lighting.shadow_opacity, params.lighting.sky_occlusion) = (1.0, 0.6, 0.5);
    compositor.render(gpu(), &previz::render::FrameParams { colour: corrected, ..params }, Layer::Composite).unwrap();
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    let before = settled_counters();
    let (mut levels, mut maps, mut grounds, mut vertex_suns) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for i in -2..8 {
        let mut p = params;
        let toward = p.placement.position - p.camera.position;
        p.placement.position = p.camera.position + toward * 2f32.powi(i);
        // Every other frame corrected (its own pipelines), every third with the sun down (the
        // ground without the shadow lookup), every fourth with each pass timed alone, every
        // fifth with every triangle drawn (the closed sphere is culled in the others).
        if i % 2 == 0 {
            p.colour = corrected;
        }
        if i % 3 == 0 {
            p.lighting.sun_dir.z = -0.2;
        }
        compositor.set_pass_timing(i % 4 == 0);
        compositor.set_culling(i % 5 != 0);
        compositor.render(gpu(), &p, Layer::Composite).unwrap();
        vertex_suns += usize::from(compositor.passes_run().vertex_sun);
        // The same frame again: a map drawn on consecutive frames runs no vertex sun until it
        // holds still, so the kept map's frame runs it (with its split and indirect draws).
        compositor.render(gpu(), &p, Layer::Composite).unwrap();
        levels.push(compositor.lod_level());
        maps.push(compositor.shadow_map_size());
        grounds.push(compositor.ground_vertices());
        vertex_suns += usize::from(compositor.passes_run().vertex_sun);
    }
    compositor.set_pass_timing(false);
    compositor.set_culling(true);
    // The same frame again keeps its shadow map, and with it the shadow's outline.
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    let outlines = compositor.ground_regions_computed().0;
    compositor.render(gpu(), &params, Layer::Composite).unwrap();
    assert!(!compositor.passes_run().shadow_drawn && outlines > 0);
    assert_eq!(compositor.ground_regions_computed().0, outlines, "a kept map computed the outline again");
    let after = settled_counters();
    levels.dedup();
    maps.dedup();
    grounds.sort_unstable();
    grounds.dedup();
    assert!(levels.len() >= 3, "the level did not follow the distance: {levels:?}");
    // The model's sun per vertex was looked up into the buffers made at upload.
    assert!(vertex_suns >= 2, "the sun per vertex was looked up in {vertex_suns} frames");
    let (bakes, _) = compositor.ground_sun_bakes();
    assert!(bakes >= 2, "the ground's sun was drawn into its texture {bakes} times");
    assert!(maps.len() >= 2, "the shadow map did not follow the footprint: {maps:?}");
    assert!(grounds.len() >= 2 && grounds.iter().any(|g| g.0 == 0), "the ground's split did not follow the sun: {grounds:?}");
    assert_unchanged(
        &before,
        &after,
        &FRAME_RESOURCES,
        "level, shadow-map, ground-split, ground-sun, colour-correction, pass-timing, culling and sun-per-vertex switches",
    );
}

/// Called from the one test: the counters are per device and tests run in parallel.
fn a_second_composite_reuses_the_pipelines() {
    let s = scene("width = 96\nheight = 64\n");
    let inputs = Inputs {
        model: triangle(),
        env: CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) },
        env_equirect: None,
        background: None,
    };
    let (mut first, params) = prepare(gpu(), &s, &inputs).unwrap();
    first.render(gpu(), &params, Layer::Composite).unwrap();
    let before = settled_counters();
    let (mut second, params) = prepare(gpu(), &s, &inputs).unwrap();
    second.render(gpu(), &params, Layer::Composite).unwrap();
    let after = settled_counters();
    // The second compositor has its own targets and buffers, but no new pipeline or shader.
    assert!(after.buffers.read() > before.buffers.read(), "the second compositor allocated no buffers");
    assert_unchanged(
        &before,
        &after,
        &["render pipelines", "compute pipelines", "shader modules", "pipeline layouts", "bind group layouts"],
        "a second composite (it must build no new pipelines)",
    );
}
