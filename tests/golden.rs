//! Golden images of every shading path (seed 000 Figs. 24-28), compared with NVIDIA FLIP.
//! Re-bless on purpose only: `PREVIZ_BLESS=1 cargo test --test integration golden::`, then look at each image.

use crate::common;

use common::{assert_golden, data, render, render_with, scene};
use previz::render::Layer;
use previz::scene::Model;
use previz::setup::Inputs;
use std::sync::OnceLock;

const SIZE: &str = "width = 480\nheight = 320\n";

/// A smooth UV sphere of radius 1 (y-up, like model files), for the seed's sphere figures.
pub fn uv_sphere(stacks: u32, slices: u32) -> Model {
    let mut mesh = previz::scene::Mesh::default();
    for i in 0..=stacks {
        let theta = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / slices as f32;
            let n = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
            mesh.positions.push(n);
            mesh.normals.push(n);
            mesh.uvs.push([j as f32 / slices as f32, i as f32 / stacks as f32]);
        }
    }
    let row = slices + 1;
    for i in 0..stacks {
        for j in 0..slices {
            let a = i * row + j;
            let b = a + row;
            mesh.indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    Model { meshes: vec![mesh], materials: vec![previz::scene::Material { diffuse: [0.8, 0.8, 0.8], ..Default::default() }] }
}

fn park() -> &'static previz::scene::CubeMap {
    static ENV: OnceLock<previz::scene::CubeMap> = OnceLock::new();
    ENV.get_or_init(|| previz::scene::environment::load_environment(&data("cubemaps/humus_Park2_512")).unwrap())
}

fn sphere_inputs() -> Inputs {
    Inputs { model: uv_sphere(48, 96), env: park().clone(), env_equirect: None, background: None }
}

fn sphere_under_sun(name: &str, sun: &str) {
    let s = scene(&format!("{SIZE}method = \"blinn-phong\"\n[sun]\ndirection = {sun}\n"));
    assert_golden(name, &render_with(&s, &sphere_inputs(), Layer::Composite));
}

// Seed Fig. 24a-d: the sphere under four sun directions (camera looks North: East is right).
#[test]
fn sphere_sun_from_the_right() {
    sphere_under_sun("sphere_sun_right", "[1.0, 0.0, 0.2]");
}
#[test]
fn sphere_sun_from_the_left() {
    sphere_under_sun("sphere_sun_left", "[-1.0, 0.0, 0.2]");
}
#[test]
fn sphere_sun_from_above() {
    sphere_under_sun("sphere_sun_above", "[0.0, 0.0, 1.0]");
}
#[test]
fn sphere_sun_from_behind_the_camera() {
    sphere_under_sun("sphere_sun_front", "[0.3, -1.0, 0.5]");
}

fn bunny(method: &str, pitch: f64, name: &str) {
    let t = format!(
        "{SIZE}model = \"meshes/stanford-bunny.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\nmethod = \"{method}\"\n[camera]\npitch = {pitch}\n"
    );
    assert_golden(name, &render(&t));
}

// Seed Figs. 25-26: hemisphere lighting and hemisphere occlusion seen from top, front, bottom.
#[test]
fn hemisphere_top_front_bottom() {
    bunny("hemisphere", -89.0, "hemisphere_top");
    bunny("hemisphere", 0.0, "hemisphere_front");
    bunny("hemisphere", 89.0, "hemisphere_bottom");
}

#[test]
fn hemisphere_occlusion_top_front_bottom() {
    bunny("hemisphere-occlusion", -89.0, "hemisphere_occlusion_top");
    bunny("hemisphere-occlusion", 0.0, "hemisphere_occlusion_front");
    bunny("hemisphere-occlusion", 89.0, "hemisphere_occlusion_bottom");
}

// The default method (issue 9): light measured from the map, SH9 sky, coloured sun with soft
// shadows, GGX specular from the prefiltered map; the bunny seen from the top and the front.
#[test]
fn sh9_ggx_top_front() {
    bunny("sh9-ggx", -89.0, "sh9_ggx_top");
    bunny("sh9-ggx", 0.0, "sh9_ggx_front");
}

// Seed Fig. 27: cube-map reflection and refraction of the Stanford bunny.
#[test]
fn bunny_cube_reflection_and_refraction() {
    bunny("cube-reflection", 0.0, "bunny_cube_reflection");
    bunny("cube-refraction", 0.0, "bunny_cube_refraction");
}

// Seed Fig. 28: refraction (and reflection) of the live camera image.
#[test]
fn live_feed_refraction_and_reflection() {
    for (method, name) in [("live-refraction", "bunny_live_refraction"), ("live-reflection", "bunny_live_reflection")] {
        let t = format!(
            "{SIZE}model = \"meshes/stanford-bunny.obj\"\nenvironment = \"cubemaps/humus_Park2_512\"\nbackground = \"photos/colour_transfer/coffee.png\"\nmethod = \"{method}\"\n"
        );
        assert_golden(name, &render(&t));
    }
}

// A textured multi-material OBJ (5 materials, JPEG textures, Windows paths in the MTL).
#[test]
fn spider_textured_multi_material() {
    let t = format!(
        "{SIZE}model = \"textured_models/spider/spider.obj\"\nenvironment = \"cubemaps/humus_Bridge2\"\nmethod = \"hemisphere\"\n[camera]\npitch = -30.0\n[sun]\ndirection = [0.4, -1.0, 0.6]\n"
    );
    assert_golden("spider_textured", &render(&t));
}

// glTF with its base-colour texture, in an equirectangular HDR environment (quarry, visible sun).
#[test]
fn truck_in_hdr_equirect() {
    let t = format!(
        "{SIZE}model = \"textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.glb\"\nenvironment = \"hdri/polyhaven_1k/quarry_01_1k.hdr\"\nmethod = \"cube-reflection\"\n[effects]\nreflection = 0.25\n[placement]\nrotation = [0.0, 0.0, 30.0]\n"
    );
    assert_golden("truck_hdr_equirect", &render(&t));
}

// The built-in demo scene at golden size.
#[test]
fn demo_scene() {
    let args = previz::cli::composite::SceneArgs { width: Some(480), height: Some(320), ..Default::default() };
    let (s, demo) = previz::cli::composite::scene_from_args(&args, None).unwrap();
    assert!(demo);
    let i = previz::setup::load_inputs(&s, true).unwrap();
    assert_golden("demo", &render_with(&s, &i, Layer::Composite));
}
