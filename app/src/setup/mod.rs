//! Scene set-up: from a scene description to a ready compositor. Loads the model, environment
//! and background (or the bundled demo's), chooses the environment's exposure, and turns the
//! scene's camera, sun, material and placement into the parameters of a frame. Sits between the
//! renderer and the app / CLI (DESIGN.md "Layers"); the CLI, the live view, the benchmarks and
//! the tests all set scenes up through here.

use crate::gpu::Gpu;
use crate::render::{Antialiasing, Camera, ColourSettings, Compositor, Detail, FrameParams, Lighting, MaterialTerms, Placement, view};
use crate::scene::environment::Equirect;
use crate::scene::{CubeMap, Model, Rgba8Image, demo};
use crate::setup::scene_file::Scene;
use anyhow::{Context, Result};
use glam::Vec3;
use std::sync::Arc;

pub mod light;
pub mod method_choice;
pub mod scene_file;
pub use light::{LightTerms, SceneLight, light_terms, measure_environment};

/// The sun NREL SPA gives for the scene's place and instant (`sun.latitude`, `sun.longitude`,
/// `sun.time`), None when the scene gives no place: the direction to compare with the map's sun
/// (they agree once the map's heading is right and the map was taken there and then).
pub fn spa_sun(scene: &Scene) -> Result<Option<crate::sun::SunPosition>> {
    let Some((lat, lon, time)) = scene.sun.place_time()? else { return Ok(None) };
    let input = crate::sun::SunInput::new(time, lat, lon);
    crate::sun::position(&input, crate::sun::Algorithm::Spa).map(Some).context("the sun for sun.latitude, sun.longitude, sun.time")
}

/// Everything loaded from disk (or the embedded demo) for a scene.
pub struct Inputs {
    pub model: Model,
    pub env: CubeMap,
    /// The environment as the equirectangular image it was loaded from (None for cube faces):
    /// without a background image the camera sees this, looked up directly
    /// (Compositor::set_equirect_background), not through `env`.
    pub env_equirect: Option<Arc<Equirect>>,
    pub background: Option<Rgba8Image>,
}

/// Load the scene's model, environment and background.
pub fn load_inputs(scene: &Scene, demo: bool) -> Result<Inputs> {
    let model = match &scene.model {
        Some(p) => crate::scene::model::load_model(p)?,
        None => demo::model()?,
    };
    let (env, env_equirect) = match &scene.environment {
        Some(p) => crate::scene::environment::load_environment_and_equirect(p)?,
        None => (demo::environment()?, None),
    };
    let background = match (&scene.background, demo) {
        (Some(p), _) => Some(crate::scene::background::load_image(p)?),
        (None, true) => Some(demo::background()?),
        (None, false) => None,
    };
    let background = background.map(|b| crate::scene::background::fit(&b, scene.width, scene.height));
    Ok(Inputs { model, env, env_equirect: env_equirect.map(Arc::new), background })
}

/// Exposure for the environment: the scene's, else 1 for 8-bit maps (all values ≤ 1) and, for
/// HDR maps, the key-value rule of Reinhard et al. 2002 (log-average luminance → 0.18) over the
/// horizontal faces.
pub fn exposure(scene: &Scene, env: &CubeMap) -> f32 {
    scene.env.exposure.map_or_else(|| auto_exposure(env), |e| e as f32)
}

/// [`exposure`] for a map the scene gives no exposure for.
fn auto_exposure(env: &CubeMap) -> f32 {
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

/// The scene's lighting environment (`lighting.environment`), loaded; None when it names none.
pub fn load_lighting(scene: &Scene) -> Result<Option<CubeMap>> {
    let Some(path) = &scene.lighting.environment else { return Ok(None) };
    crate::scene::environment::load_environment(path).map(Some).with_context(|| format!("lighting.environment {}", path.display()))
}

/// Light and reflect the model of a prepared scene with `map`, its lighting environment
/// ([`load_lighting`]): the reflections, the colour priors and the sky's SH9 ambient (colour and
/// direction) come from `map` at `lighting.exposure` and `lighting.heading`; the sun and the
/// ambient level stay the ones measured in the scene's environment — what the app does with the
/// camera frame folded into a cube map. Without a `background` the environment stays the
/// background: the frame's background is rendered from it first and kept as the image.
pub fn set_lighting_environment(
    gpu: &Gpu,
    compositor: &mut Compositor,
    params: &mut FrameParams,
    scene: &Scene,
    map: &CubeMap,
) -> Result<()> {
    if scene.background.is_none() {
        let b = compositor.render(gpu, params, crate::render::Layer::Background)?;
        compositor.set_background(gpu, Some(&Rgba8Image { width: b.width, height: b.height, pixels: b.rgba }))?;
    }
    let exposure = scene.lighting.exposure.map_or_else(|| auto_exposure(map), |e| e as f32);
    let heading = (scene.lighting.heading as f32).to_radians();
    compositor.set_environment(gpu, map, exposure, heading)?;
    let priors = compositor.priors().context("lighting environment priors")?;
    let light = environment_light(scene, map, &priors, exposure, heading)?.0;
    params.lighting.sky_sh = light.sky_sh;
    params.lighting.sky_radiance = light.sky_radiance;
    params.lighting.ground_radiance = light.ground_radiance;
    Ok(())
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
/// measured from its environment ([`light_terms`]): the scene's sunlight, daylight and shadow
/// multipliers and the sun's twilight fade apply here, once. The method is the scene's, resolved
/// by [`compositor_and_light`] (an unresolved `auto` draws `method_choice::ORDINARY`).
pub fn frame_params(scene: &Scene, bounds: (Vec3, Vec3), light: &LightTerms) -> FrameParams {
    let (camera, placement) = camera_and_placement(scene, bounds);
    FrameParams {
        camera,
        method: scene.method.method_or_ordinary(),
        lighting: lighting(scene, light),
        placement,
        colour: ColourSettings { method: scene.colour.correction, strength: scene.colour.strength as f32 },
    }
}

/// The lighting of a scene's frame from the unit light terms of its environment: the scene's
/// sunlight, daylight and shadow multipliers and the sun's twilight fade apply here, once.
pub fn lighting(scene: &Scene, light: &LightTerms) -> Lighting {
    let m = &scene.material;
    let fade = crate::sun::twilight::sunlight_factor_toward(light.sun_dir);
    let (sl, dl) = (scene.sun.sunlight as f32, scene.sun.daylight as f32);
    let (shadow_opacity, sky_occlusion) =
        light::ground_strengths(sl * light.sunlight * fade, light.sun_dir, dl * light.ground_sky, scene.effects.shadow_opacity as f32);
    Lighting {
        sun_dir: light.sun_dir,
        sunlight: sl * light.sunlight * fade,
        daylight: dl * light.daylight,
        material: MaterialTerms {
            ambient: m.ambient as f32,
            diffuse: m.diffuse as f32,
            specular: m.specular as f32,
            gloss: m.gloss.map(|g| g as f32),
        },
        reflection: scene.effects.reflection as f32,
        ior: scene.effects.ior as f32,
        shadow_opacity,
        sky_occlusion,
        live_depth: scene.effects.live_depth as f32,
        sky_sh: light.sky_sh,
        sky_radiance: light.sky_radiance,
        ground_radiance: light.ground_radiance,
        sun_colour: light.sun_colour,
        sun_angular_radius: light.sun_angular_radius,
    }
}

/// GPU resources for a still image of a scene and the parameters of its frame: what `previz
/// composite`, the golden tests and the accuracy benchmark share. A still has no frame budget:
/// it is supersampled ([`Compositor::supersampled`]: each pixel the mean of k × k samples,
/// which antialias its edges too) and draws [`Detail::Still`] (triangles down to a sample). The
/// live view's frames follow the adapter and the screen ([`compositor_for`]).
pub fn prepare(gpu: &Gpu, scene: &Scene, inputs: &Inputs) -> Result<(Compositor, FrameParams)> {
    prepare_with_light(gpu, scene, inputs).map(|(c, p, _)| (c, p))
}

/// [`prepare`], and the light measured in the environment (for reporting it without measuring
/// the map again).
pub fn prepare_with_light(gpu: &Gpu, scene: &Scene, inputs: &Inputs) -> Result<(Compositor, FrameParams, SceneLight)> {
    prepare_still(gpu, scene, inputs, crate::render::supersample::STILL_FACTOR)
}

/// [`prepare`] with up to `k` × `k` samples a pixel instead of a still's own (`previz bench
/// accuracy` charts what each factor buys).
pub fn prepare_supersampled(gpu: &Gpu, scene: &Scene, inputs: &Inputs, k: u32) -> Result<(Compositor, FrameParams)> {
    prepare_still(gpu, scene, inputs, k).map(|(c, p, _)| (c, p))
}

fn prepare_still(gpu: &Gpu, scene: &Scene, inputs: &Inputs, k: u32) -> Result<(Compositor, FrameParams, SceneLight)> {
    let compositor = Compositor::supersampled(gpu, scene.width, scene.height, k)?;
    let (mut compositor, params, light) = set_up(gpu, compositor, scene, &inputs.env, &inputs.model)?;
    compositor.set_detail(Detail::Still);
    set_background(gpu, &mut compositor, inputs)?;
    Ok((compositor, params, light))
}

/// [`prepare`] with the antialiasing given instead of the adapter's (the study in `previz bench
/// frame`).
pub fn prepare_antialiased(gpu: &Gpu, scene: &Scene, inputs: &Inputs, aa: Antialiasing) -> Result<(Compositor, FrameParams)> {
    let compositor = Compositor::with_antialiasing(gpu, scene.width, scene.height, aa)?;
    let (mut compositor, params, _) = set_up(gpu, compositor, scene, &inputs.env, &inputs.model)?;
    set_background(gpu, &mut compositor, inputs)?;
    Ok((compositor, params))
}

/// [`prepare_antialiased`] with the live view's reprojection on (render::reprojection), turned
/// on before the environment and the model are set so that its shading compositor gets them.
pub fn prepare_reprojected(gpu: &Gpu, scene: &Scene, inputs: &Inputs, aa: Antialiasing) -> Result<(Compositor, FrameParams)> {
    let mut compositor = Compositor::with_antialiasing(gpu, scene.width, scene.height, aa)?;
    compositor.set_reprojection(gpu, true)?;
    let (mut compositor, params, _) = set_up(gpu, compositor, scene, &inputs.env, &inputs.model)?;
    set_background(gpu, &mut compositor, inputs)?;
    Ok((compositor, params))
}

/// The inputs' background image, or without one the environment seen by the camera: in its
/// equirectangular image when it was loaded from one (uploaded only then), else in the cube map.
fn set_background(gpu: &Gpu, compositor: &mut Compositor, inputs: &Inputs) -> Result<()> {
    let equirect = inputs.env_equirect.as_deref().filter(|_| inputs.background.is_none());
    compositor.set_equirect_background(gpu, equirect)?;
    compositor.set_background(gpu, inputs.background.as_ref())
}

/// A compositor with the scene's environment (at its exposure and heading) and model, and the
/// parameters of the scene's frame; the background is the caller's (a photo, or the live
/// camera frame by frame).
pub fn compositor_for(gpu: &Gpu, scene: &Scene, env: &CubeMap, model: &Model) -> Result<(Compositor, FrameParams)> {
    compositor_and_light(gpu, scene, env, model).map(|(c, p, _)| (c, p))
}

/// [`compositor_for`], and the light measured in the environment ([`SceneLight`]).
pub fn compositor_and_light(gpu: &Gpu, scene: &Scene, env: &CubeMap, model: &Model) -> Result<(Compositor, FrameParams, SceneLight)> {
    set_up(gpu, Compositor::new(gpu, scene.width, scene.height)?, scene, env, model)
}

/// [`compositor_and_light`] for the live view: a turn or scale of the model casts the ground's
/// rays off the frame's thread, and a frame that only turns the camera composes the last shaded
/// frame's model and ground through the turn (render::reprojection).
pub fn live_compositor_and_light(gpu: &Gpu, scene: &Scene, env: &CubeMap, model: &Model) -> Result<(Compositor, FrameParams, SceneLight)> {
    let mut compositor = Compositor::new(gpu, scene.width, scene.height)?;
    compositor.set_ground_in_background(true);
    compositor.set_reprojection(gpu, true)?;
    set_up(gpu, compositor, scene, env, model)
}

/// Give `compositor` the scene's environment and model; the frame's parameters and light.
fn set_up(
    gpu: &Gpu,
    mut compositor: Compositor,
    scene: &Scene,
    env: &CubeMap,
    model: &Model,
) -> Result<(Compositor, FrameParams, SceneLight)> {
    let (exposure, heading) = (exposure(scene, env), (scene.env.heading as f32).to_radians());
    compositor.set_environment(gpu, env, exposure, heading)?;
    compositor.set_model(gpu, model)?;
    let bounds = compositor.model_bounds().context("model bounds")?;
    let priors = compositor.priors().context("environment priors")?;
    let measured = measure_environment(scene, env)?;
    // `auto` becomes the method the model and the measured light need.
    let choice = method_choice::resolve(scene.method, model, &measured);
    let scene = &Scene { method: method_choice::MethodRequest::Fixed(choice.method), ..scene.clone() };
    let (light, scene_light) = environment_light_measured(scene, measured, &priors, exposure, heading);
    let params = frame_params(scene, bounds, &light);
    Ok((compositor, params, scene_light))
}

/// The light of `scene` measured in `env` (uploaded with `priors`, at `exposure` and `heading`
/// radians): the light terms with the scene's multipliers at 1, before the twilight fade
/// ([`lighting`] applies them), and the measured light with those terms. Errors: see
/// [`measure_environment`].
pub fn environment_light(
    scene: &Scene,
    env: &CubeMap,
    priors: &crate::render::HemispherePriors,
    exposure: f32,
    heading: f32,
) -> Result<(LightTerms, SceneLight)> {
    Ok(environment_light_measured(scene, measure_environment(scene, env)?, priors, exposure, heading))
}

/// [`environment_light`] with the environment already measured.
fn environment_light_measured(
    scene: &Scene,
    measured: crate::light::measure::MeasuredLight,
    priors: &crate::render::HemispherePriors,
    exposure: f32,
    heading: f32,
) -> (LightTerms, SceneLight) {
    let unit = light_terms(scene, &measured, priors, exposure, heading);
    (unit, SceneLight { measured, unit })
}
