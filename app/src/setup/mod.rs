//! Scene set-up: from a scene description to a ready compositor. Loads the model, environment
//! and background (or the bundled demo's), chooses the environment's exposure, and turns the
//! scene's camera, sun, material and placement into the parameters of a frame. Sits between the
//! renderer and the app / CLI (DESIGN.md "Layers"); the CLI, the live view, the benchmarks and
//! the tests all set scenes up through here.

use crate::gpu::Gpu;
use crate::render::{Camera, ColourSettings, Compositor, FrameParams, Lighting, MaterialTerms, Placement, view};
use crate::scene::{CubeMap, Model, Rgba8Image, demo};
use crate::setup::scene_file::Scene;
use anyhow::{Context, Result};
use glam::Vec3;

pub mod light;
pub mod scene_file;
pub use light::{LightTerms, SceneLight, light_terms, measure_environment};

/// Everything loaded from disk (or the embedded demo) for a scene.
pub struct Inputs {
    pub model: Model,
    pub env: CubeMap,
    pub background: Option<Rgba8Image>,
}

/// Load the scene's model, environment and background.
pub fn load_inputs(scene: &Scene, demo: bool) -> Result<Inputs> {
    let model = match &scene.model {
        Some(p) => crate::scene::model::load_model(p)?,
        None => demo::model()?,
    };
    let env = match &scene.environment {
        Some(p) => crate::scene::environment::load_environment(p)?,
        None => demo::environment()?,
    };
    let background = match (&scene.background, demo) {
        (Some(p), _) => Some(crate::scene::background::load_image(p)?),
        (None, true) => Some(demo::background()?),
        (None, false) => None,
    };
    let background = background.map(|b| crate::scene::background::fit(&b, scene.width, scene.height));
    Ok(Inputs { model, env, background })
}

/// Exposure for the environment: the scene's, else 1 for 8-bit maps (all values ≤ 1) and, for
/// HDR maps, the key-value rule of Reinhard et al. 2002 (log-average luminance → 0.18) over the
/// horizontal faces.
pub fn exposure(scene: &Scene, env: &CubeMap) -> f32 {
    if let Some(e) = scene.env.exposure {
        return e as f32;
    }
    let max = env.faces.iter().flatten().flat_map(|p| p.iter()).fold(0f32, |m, v| m.max(*v));
    if max <= 1.0 {
        return 1.0;
    }
    let (sum, n) = [0usize, 1, 4, 5]
        .iter()
        .flat_map(|&f| env.faces[f].iter())
        .map(|p| f64::from(crate::colour::luminance_bt709(*p)))
        .filter(|l| l.is_finite())
        .fold((0f64, 0usize), |(s, n), l| (s + (1e-4 + l).ln(), n + 1));
    if n == 0 {
        return 1.0;
    }
    (0.18 / (sum / n as f64).exp()) as f32
}

/// The camera and the model's placement a scene describes, given the loaded model's bounds.
pub fn camera_and_placement(scene: &Scene, bounds: (Vec3, Vec3)) -> (Camera, Placement) {
    let c = &scene.camera;
    let pose = view::camera_pose((c.heading as f32).to_radians(), (c.pitch as f32).to_radians(), (c.roll as f32).to_radians());
    let position = Vec3::new(0.0, 0.0, c.height as f32);
    let vfov = (c.vfov as f32).to_radians();
    let p = &scene.placement;
    let auto = view::auto_placement(bounds, pose, position, vfov, p.size as f32, p.fill as f32);
    let extent = (bounds.1 - bounds.0).max_element().max(f32::MIN_POSITIVE);
    let placement = Placement {
        position: p.position.map(|v| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)).unwrap_or(auto.position),
        rotation: Vec3::new(p.rotation[0] as f32, p.rotation[1] as f32, p.rotation[2] as f32) * (std::f32::consts::PI / 180.0),
        scale: p.scale.map(|s| s as f32).unwrap_or(p.size as f32 / extent),
    };
    (Camera { pose, position, vfov }, placement)
}

/// The frame parameters a scene describes, given the loaded model's bounds and the light terms
/// measured from its environment ([`light_terms`]).
pub fn frame_params(scene: &Scene, bounds: (Vec3, Vec3), light: &LightTerms) -> FrameParams {
    let (camera, placement) = camera_and_placement(scene, bounds);
    let m = &scene.material;
    FrameParams {
        camera,
        method: scene.method,
        lighting: Lighting {
            sun_dir: light.sun_dir,
            sunlight: light.sunlight,
            daylight: light.daylight,
            material: MaterialTerms {
                ambient: m.ambient as f32,
                diffuse: m.diffuse as f32,
                specular: m.specular as f32,
                gloss: m.gloss.map(|g| g as f32),
            },
            reflection: scene.effects.reflection as f32,
            ior: scene.effects.ior as f32,
            shadow_opacity: light.shadow_opacity,
            live_depth: scene.effects.live_depth as f32,
        },
        placement,
        colour: ColourSettings { method: scene.colour.correction, strength: scene.colour.strength as f32 },
    }
}

/// GPU resources for a scene and the parameters of its frame: what `run`, the tests and the
/// benchmark share.
pub fn prepare(gpu: &Gpu, scene: &Scene, inputs: &Inputs) -> Result<(Compositor, FrameParams)> {
    prepare_with_light(gpu, scene, inputs).map(|(c, p, _)| (c, p))
}

/// [`prepare`], and the light measured in the environment (for reporting it without measuring
/// the map again).
pub fn prepare_with_light(gpu: &Gpu, scene: &Scene, inputs: &Inputs) -> Result<(Compositor, FrameParams, SceneLight)> {
    let (mut compositor, params, light) = compositor_and_light(gpu, scene, &inputs.env, &inputs.model)?;
    compositor.set_background(gpu, inputs.background.as_ref())?;
    Ok((compositor, params, light))
}

/// A compositor with the scene's environment (at its exposure and heading) and model, and the
/// parameters of the scene's frame; the background is the caller's (a photo, or the live
/// camera frame by frame).
pub fn compositor_for(gpu: &Gpu, scene: &Scene, env: &CubeMap, model: &Model) -> Result<(Compositor, FrameParams)> {
    compositor_and_light(gpu, scene, env, model).map(|(c, p, _)| (c, p))
}

/// [`compositor_for`], and the light measured in the environment ([`SceneLight`]).
pub fn compositor_and_light(gpu: &Gpu, scene: &Scene, env: &CubeMap, model: &Model) -> Result<(Compositor, FrameParams, SceneLight)> {
    let mut compositor = Compositor::new(gpu, scene.width, scene.height)?;
    let (exposure, heading) = (exposure(scene, env), (scene.env.heading as f32).to_radians());
    compositor.set_environment(gpu, env, exposure, heading)?;
    compositor.set_model(gpu, model)?;
    let bounds = compositor.model_bounds().context("model bounds")?;
    let priors = compositor.priors().context("environment priors")?;
    let (light, scene_light) = environment_light(scene, env, &priors, exposure, heading);
    let params = frame_params(scene, bounds, &light);
    Ok((compositor, params, scene_light))
}

/// The light of `scene` measured in `env` (uploaded with `priors`, at `exposure` and `heading`
/// radians): the frame's light terms, and the measured light with the unit terms (the scene's
/// multipliers at 1, before the twilight fade).
pub fn environment_light(
    scene: &Scene,
    env: &CubeMap,
    priors: &crate::render::HemispherePriors,
    exposure: f32,
    heading: f32,
) -> (LightTerms, SceneLight) {
    let measured = measure_environment(scene, env);
    let light = light_terms(scene, &measured, priors, exposure, heading);
    let mut unit = scene.clone();
    unit.sun.sunlight = 1.0;
    unit.sun.daylight = 1.0;
    unit.effects.shadow_opacity = 1.0;
    let mut unit = light_terms(&unit, &measured, priors, exposure, heading);
    let fade = crate::sun::twilight::sunlight_factor_toward(unit.sun_dir);
    unit.sunlight = if fade > 0.0 { unit.sunlight / fade } else { 0.0 };
    (light, SceneLight { measured, unit })
}
