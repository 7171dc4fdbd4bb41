//! Level of detail is invisible: the level the half-pixel rule draws renders within a mean FLIP
//! of 0.01 of the full-detail render (the bar), and it has fewer triangles.

mod common;

use common::{gpu, inputs, scene};
use previz::bench::lod::{model_at_level, screen_level};
use previz::render::Layer;
use previz::scene::lod::LodChain;
use previz::setup::{Inputs, prepare};

fn rgb(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
}

#[test]
fn the_selected_level_is_invisible_and_coarser_levels_are_not() {
    let s = scene(
        "width = 320\nheight = 240\nmodel = \"meshes/stanford-bunny.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\n[placement]\nfill = 0.25\n",
    );
    let full = inputs(&s);
    let chain = LodChain::build(&full.model);
    assert!(chain.len() >= 6, "the bunny's chain: {:?}", chain.triangles);
    let render = |model| {
        let i = Inputs { model, env: full.env.clone(), background: None };
        let (mut c, p) = prepare(gpu(), &s, &i).unwrap();
        c.set_full_detail(true);
        rgb(&c.render(gpu(), &p, Layer::Composite).unwrap().rgba)
    };
    let reference = render(full.model.clone());
    let (c, p) = prepare(gpu(), &s, &full).unwrap();
    let (chosen, ..) = screen_level(&chain, c.model_bounds().unwrap(), &p, s.height);
    assert!(chosen >= 1, "at a quarter fill a 70k-triangle bunny needs fewer triangles: {:?}", chain.triangles);
    let flip =
        |k: usize| previz::capture::replay::mean_flip(&reference, &render(model_at_level(&full.model, &chain, k)), 320, 240).unwrap();
    let chosen_flip = flip(chosen);
    assert!(chosen_flip <= 0.01, "level {chosen} ({} triangles): mean FLIP {chosen_flip}", chain.triangles[chosen]);
    // The rule is not vacuous: the coarsest level is visibly different.
    let coarsest = chain.len() - 1;
    let coarse_flip = flip(coarsest);
    assert!(coarse_flip > chosen_flip, "level {coarsest}: {coarse_flip} vs level {chosen}: {chosen_flip}");
    // The compositor draws that level by itself (all levels uploaded once, chosen per frame),
    // and what it draws is the chosen level's image.
    let (mut c, p) = prepare(gpu(), &s, &full).unwrap();
    let drawn = rgb(&c.render(gpu(), &p, Layer::Composite).unwrap().rgba);
    assert_eq!(c.lod_level(), chosen);
    assert_eq!(c.lod_triangles().unwrap(), &chain.triangles[..]);
    let drawn_flip = previz::capture::replay::mean_flip(&reference, &drawn, 320, 240).unwrap();
    // Not bit-identical since per-vertex ambient occlusion: the drawn level's is computed against
    // the full mesh, the level-alone model's against its own coarser triangles (measured
    // difference 1.7e-6 on this bunny).
    assert!((drawn_flip - chosen_flip).abs() < 1e-5, "drawn {drawn_flip} vs level {chosen} alone {chosen_flip}");
    // Moved twice as far away, it draws a coarser level.
    let mut far = p;
    let toward = far.placement.position - far.camera.position;
    far.placement.position += toward;
    c.render(gpu(), &far, Layer::Composite).unwrap();
    assert!(c.lod_level() > chosen, "level {} at twice the distance vs {chosen}", c.lod_level());
}

/// Computed (crease-split) normals are no seam: the 100k dragon, whose normals the loader
/// computes, simplifies to under 2 000 triangles (before welding by position the chain stopped
/// at 11k, every split vertex pinned; measured now 100 000 -> ... -> 1 582 -> ... -> 98).
#[test]
fn the_dragon_chain_reaches_a_few_thousand_triangles() {
    let model = previz::scene::model::load_model(&common::data("meshes/stanford-dragon-100k.obj")).unwrap();
    let chain = LodChain::build(&model);
    let (first, last) = (chain.triangles[0], *chain.triangles.last().unwrap());
    assert!(first >= 99_000, "{first}");
    assert!(last <= 2_000, "the dragon's chain: {:?}", chain.triangles);
    for w in chain.errors.windows(2) {
        assert!(w[1] >= w[0], "errors must not decrease: {:?}", chain.errors);
    }
}

/// The shadow and ground passes run only when they have something to do: with the sun up and
/// the model in view both run; with no measured sun or the sun below the horizon the ground
/// pass is skipped (the model still samples the map); looking away, neither.
#[test]
fn shadow_and_ground_passes_run_only_when_needed() {
    let s = scene("width = 160\nheight = 120\nmodel = \"meshes/icosphere-320.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\n");
    let i = inputs(&s);
    let (mut c, p) = prepare(gpu(), &s, &i).unwrap();
    let run = |c: &mut previz::render::Compositor, p: &previz::render::FrameParams| {
        c.render(gpu(), p, Layer::Composite).unwrap();
        (c.passes_run(),)
    };
    let mut up = p;
    up.lighting.sun_dir = glam::Vec3::new(0.3, -0.6, 0.7);
    up.lighting.sunlight = 1.0;
    up.lighting.shadow_opacity = 0.6;
    assert_eq!(run(&mut c, &up).0, previz::render::PassesRun { shadow: true, ground: true });
    let mut overcast = up;
    overcast.lighting.sunlight = 0.0;
    assert_eq!(run(&mut c, &overcast).0, previz::render::PassesRun { shadow: true, ground: false });
    let mut down = up;
    down.lighting.sun_dir = glam::Vec3::new(0.3, -0.6, -0.2);
    assert_eq!(run(&mut c, &down).0, previz::render::PassesRun { shadow: true, ground: false });
    let mut away = up;
    away.camera.pose *= glam::Quat::from_rotation_y(std::f32::consts::PI);
    assert_eq!(run(&mut c, &away).0, previz::render::PassesRun { shadow: false, ground: false });
}
