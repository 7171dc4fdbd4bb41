//! Colour correction in the model shader (seed 000 §5.6): the compositor builds the
//! `ColourCorrection` uniform from the environment's and the model's priors, and the model shader
//! applies it per fragment. Checked against the CPU twin (`colour::correction::correct`) on the
//! rendered pixels, and kept in golden images: a textured model before/after against two
//! environments.

use crate::common;

use common::{assert_golden, data, gpu, mean_rgb, render, scene};
use previz::colour::correction::{ColourCorrection, correct};
use previz::colour::transfer::TransferMethod;
use previz::colour::{linear_to_srgb, srgb_to_linear};
use previz::priors::{environment_priors_scaled, model_priors};
use previz::render::{ColourSettings, Layer};
use previz::scene::{Material, Mesh, Model, Rgba8Image};
use previz::setup::{Inputs, exposure, prepare};

/// An 8×8 texture: a 4×4 block of `centre` in the middle, a ring of varied colours around it
/// (so the texture's σ is not zero).
fn texture(centre: [u8; 3]) -> Rgba8Image {
    let mut pixels = Vec::with_capacity(256);
    for y in 0..8u32 {
        for x in 0..8u32 {
            let c = if (2..6).contains(&x) && (2..6).contains(&y) {
                centre
            } else {
                [(40 + 25 * x) as u8, (200 - 20 * y) as u8, (60 + 15 * (x + y)) as u8]
            };
            pixels.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }
    Rgba8Image { width: 8, height: 8, pixels }
}

/// A unit quad in the model's XY plane (y up, facing +z) with UVs 0..1, textured.
fn quad(tex: Rgba8Image) -> Model {
    let mesh = Mesh {
        positions: vec![[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 1.0, 0.0], [-0.5, 1.0, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        indices: vec![0, 1, 2, 0, 2, 3],
        material: 0,
    };
    Model { meshes: vec![mesh], materials: vec![Material { diffuse: [1.0; 3], texture: Some(tex), ..Default::default() }] }
}

/// Ambient light only (blinn-phong, no sun, no diffuse): the model's pixels are its
/// (corrected) albedo times the ambient light.
fn flat(env: &str, correction: TransferMethod, strength: f64) -> String {
    format!(
        "width = 320\nheight = 240\nmethod = \"blinn-phong\"\nenvironment = \"{env}\"\n\
[sun]\nsunlight = 0.0\ndaylight = 1.0\n[material]\nambient = 1.0\ndiffuse = 0.0\nspecular = 0.0\n\
[placement]\nrotation = [0.0, 0.0, 180.0]\nfill = 0.6\n[colour]\ncorrection = \"{}\"\nstrength = {strength}\n",
        correction.name()
    )
}

#[test]
fn shader_applies_the_correction_built_from_the_priors() {
    let centre = [150u8, 90, 60];
    let model = quad(texture(centre));
    let texel = glam::Vec3::from_array(centre.map(|c| srgb_to_linear(f32::from(c) / 255.0)));
    let target = model_priors(&model).unwrap().stats;
    for env_dir in ["cubemaps/humus_Park2_512", "hdri/polyhaven_1k/venice_sunset_1k.hdr"] {
        let env = previz::scene::environment::load_environment(&data(env_dir)).unwrap();
        let inputs = Inputs { model: model.clone(), env, env_equirect: None, background: None };
        // One compositor per environment; the correction is a per-frame setting.
        let s = scene(&flat(env_dir, TransferMethod::None, 1.0));
        let source = environment_priors_scaled(&inputs.env, exposure(&s, &inputs.env)).unwrap().horizontal;
        let (mut compositor, mut params) = prepare(gpu(), &s, &inputs).unwrap();
        // Ambient light exactly 1 (the scene's daylight is a multiplier on the measured sky).
        params.lighting.daylight = 1.0;
        let mut moved = 0.0f64;
        for method in std::iter::once(TransferMethod::None).chain(TransferMethod::ALL) {
            for strength in [1.0f32, 0.5] {
                let cc = if method == TransferMethod::None {
                    ColourCorrection::identity()
                } else {
                    ColourCorrection::new(method, strength, &source, &target)
                };
                let expected = correct(texel, &cc).min(glam::Vec3::ONE).to_array().map(|c| 255.0 * f64::from(linear_to_srgb(c)));
                params.colour = ColourSettings { method, strength };
                let r = compositor.render(gpu(), &params, Layer::Model).unwrap();
                let (cx, cy) = (r.width / 2, r.height / 2);
                assert_eq!(common::pixel(&r, cx, cy)[3], 255, "{env_dir}: the quad does not cover the centre");
                let got = mean_rgb(&r, cx - 2, cy - 2, cx + 3, cy + 3);
                for c in 0..3 {
                    assert!(
                        (got[c] - expected[c]).abs() <= 2.0,
                        "{env_dir} {} strength {strength}: pixel {got:?}, CPU reference {expected:?}",
                        method.name()
                    );
                }
                moved = moved.max((expected[0] - f64::from(centre[0])).abs());
            }
        }
        assert!(moved > 10.0, "{env_dir}: no method changed the colour noticeably");
    }
}

#[test]
fn a_correction_needs_model_statistics() {
    // Every texel pure green (the seed's green screen): no statistics, so a correction is an
    // error naming the reason, while no correction still renders.
    let mut model = quad(texture([0, 255, 0]));
    if let Some(t) = model.materials[0].texture.as_mut() {
        for p in t.pixels.chunks_exact_mut(4) {
            p.copy_from_slice(&[0, 255, 0, 255]);
        }
    }
    let env = previz::scene::environment::load_environment(&data("cubemaps/humus_Park2_512")).unwrap();
    let inputs = Inputs { model, env, env_equirect: None, background: None };
    let plain = scene(&flat("cubemaps/humus_Park2_512", TransferMethod::None, 1.0));
    let (mut compositor, params) = prepare(gpu(), &plain, &inputs).unwrap();
    assert!(compositor.render(gpu(), &params, Layer::Model).is_ok());
    let corrected = scene(&flat("cubemaps/humus_Park2_512", TransferMethod::Reinhard, 1.0));
    let (mut compositor, params) = prepare(gpu(), &corrected, &inputs).unwrap();
    let err = compositor.render(gpu(), &params, Layer::Model).err().map(|e| format!("{e:#}")).unwrap_or_default();
    assert!(err.contains("reinhard") && err.contains("green"), "{err}");
}

/// Seed Figs. 31/32: a textured model (the Cesium milk truck, glTF base-colour texture) before
/// and after Reinhard colour transfer, against a green park and a warm sunset.
#[test]
fn textured_model_before_and_after_in_two_environments() {
    for (env, tag) in [("cubemaps/humus_Park2_512", "park"), ("hdri/polyhaven_1k/venice_sunset_1k.hdr", "sunset")] {
        for (correction, state) in [("none", "before"), ("reinhard", "after")] {
            let t = format!(
                "width = 480\nheight = 320\nmodel = \"textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.glb\"\nenvironment = \"{env}\"\n\
method = \"hemisphere\"\n[placement]\nrotation = [0.0, 0.0, 30.0]\n[colour]\ncorrection = \"{correction}\"\n"
            );
            assert_golden(&format!("colour_truck_{tag}_{state}"), &render(&t));
        }
    }
}
