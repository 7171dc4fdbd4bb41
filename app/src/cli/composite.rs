//! `previz composite`: composite a lit model over a background; with no arguments, the bundled
//! demo scene.

use crate::gpu::Gpu;
use crate::render::Layer;
use crate::scene::demo;
use crate::setup::method_choice::{self, MethodRequest};
use crate::setup::scene_file::{Scene, SceneBuilder};
use crate::setup::{SceneLight, load_inputs, load_lighting, prepare_with_light, set_lighting_environment};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug, Default)]
#[command(after_help = "Every flag has a scene-file key (see README: Scene file); flags override the file, \
--set overrides both. With no scene file, --model or --env, the built-in demo scene is used. \
Key lighting.environment (with lighting.heading, lighting.exposure) names a separate map the model's \
reflections, sky ambient and colour priors come from (the app's export writes its folded camera frame \
there); the sun, the daylight level and, without --background, the background stay the environment's.")]
pub struct Args {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output image  [key: output]
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Also write composite.png, model_rgba.png (premultiplied, alpha = coverage), background.png and
    /// layers.exr (linear float: beauty R,G,B,A; model.R/G/B/A premultiplied; shadow.R/G/B matte, 1 = no
    /// change, above 1 where the model lights the ground; background.R/G/B; depth.Z camera distance in
    /// metres, inf where no model) into DIR
    #[arg(long, value_name = "DIR")]
    pub layers: Option<PathBuf>,
    /// Print outputs, size, model pixel count, method and timings as JSON
    #[arg(long)]
    pub json: bool,
}

/// The flags that describe a scene (shared by `composite` and `bench frame`).
#[derive(clap::Args, Debug, Default)]
pub struct SceneArgs {
    /// Scene file (TOML). Relative paths in it are relative to its folder.
    pub scene: Option<PathBuf>,
    /// Model: .obj (with .mtl), .gltf or .glb  [key: model]
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Environment: a folder of six cube faces, or an equirectangular .hdr/.exr  [key: environment]
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Background photograph (JPEG/PNG); default: the environment seen by the camera  [key: background]
    #[arg(long)]
    pub background: Option<PathBuf>,
    /// Output width in pixels  [key: width]
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub width: Option<u32>,
    /// Output height in pixels  [key: height]
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub height: Option<u32>,
    /// Vertical field of view, degrees  [key: camera.vfov]
    #[arg(long)]
    pub vfov: Option<f64>,
    /// Camera heading, degrees clockwise from true north  [key: camera.heading]
    #[arg(long, allow_hyphen_values = true)]
    pub heading: Option<f64>,
    /// Camera pitch, degrees, up positive  [key: camera.pitch]
    #[arg(long, allow_hyphen_values = true)]
    pub pitch: Option<f64>,
    /// Camera roll, degrees, clockwise positive  [key: camera.roll]
    #[arg(long, allow_hyphen_values = true)]
    pub roll: Option<f64>,
    /// Direction to the sun in ENU as X,Y,Z (East, North, Up)  [key: sun.direction]
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub sun_dir: Option<String>,
    /// Lighting method; auto (the default) picks it from the model's materials and the measured
    /// light, and --json says why  [key: method]
    #[arg(long, value_enum)]
    pub method: Option<MethodRequest>,
    /// Set any scene key, e.g. --set material.gloss=64 --set placement.rotation=[0,0,90]
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Parse "X,Y,Z" into three numbers, naming the flag on error.
fn parse_vec3(flag: &str, s: &str) -> Result<[f64; 3]> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        bail!("{flag} {s:?}: expected three comma-separated numbers X,Y,Z");
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p.parse().with_context(|| format!("{flag} {s:?}: {p:?} is not a number"))?;
    }
    Ok(v)
}

/// The scene the arguments describe (plus an output path), and whether it is the built-in demo.
pub fn scene_from_args(args: &SceneArgs, output: Option<&Path>) -> Result<(Scene, bool)> {
    let demo = args.scene.is_none() && args.model.is_none() && args.env.is_none();
    let mut b = match &args.scene {
        Some(path) => SceneBuilder::from_file(path)?,
        None if demo => SceneBuilder::from_toml(demo::SCENE_TOML, Path::new("."))?,
        None => SceneBuilder::new(),
    };
    let path_value = |p: &Path| toml::Value::String(p.to_string_lossy().into_owned());
    let cwd_path = |p: &PathBuf| -> Result<toml::Value> {
        // Flags are relative to the current directory, not to the scene file.
        Ok(path_value(&std::path::absolute(p).with_context(|| format!("bad path {}", p.display()))?))
    };
    if let Some(p) = &args.model {
        b.set("model", cwd_path(p)?)?;
    }
    if let Some(p) = &args.env {
        b.set("environment", cwd_path(p)?)?;
    }
    if let Some(p) = &args.background {
        b.set("background", cwd_path(p)?)?;
    }
    if let Some(p) = output {
        // An empty -o stays empty so that the check names it; others are made absolute.
        let value = if p.as_os_str().is_empty() { path_value(p) } else { cwd_path(&p.to_path_buf())? };
        b.set("output", value)?;
    }
    if let Some(v) = args.width {
        b.set("width", toml::Value::Integer(v.into()))?;
    }
    if let Some(v) = args.height {
        b.set("height", toml::Value::Integer(v.into()))?;
    }
    for (key, v) in [("camera.vfov", args.vfov), ("camera.heading", args.heading), ("camera.pitch", args.pitch), ("camera.roll", args.roll)]
    {
        if let Some(v) = v {
            b.set(key, toml::Value::Float(v)).with_context(|| format!("--{}", key.trim_start_matches("camera.")))?;
        }
    }
    if let Some(s) = &args.sun_dir {
        let v = parse_vec3("--sun-dir", s)?;
        b.set("sun.direction", toml::Value::Array(v.iter().map(|x| toml::Value::Float(*x)).collect()))?;
    }
    if let Some(m) = args.method {
        b.set("method", toml::Value::String(m.name().into()))?;
    }
    for s in &args.set {
        b.set_str(s)?;
    }
    let scene = b.build().map_err(|e| {
        let flag = flag_for_error(&format!("{e:#}"));
        match &args.scene {
            Some(file) => e.context(format!("{flag} in {}", file.display())),
            None => e.context(flag),
        }
    })?;
    Ok((scene, demo))
}

/// Name the flag a scene-key error came from, so the message points at what the user typed.
fn flag_for_error(msg: &str) -> String {
    for (key, flag) in [
        ("camera.vfov", "--vfov"),
        ("camera.heading", "--heading"),
        ("camera.pitch", "--pitch"),
        ("camera.roll", "--roll"),
        ("sun.direction", "--sun-dir"),
        ("width", "--width"),
        ("height", "--height"),
        ("output", "-o/--output"),
    ] {
        if msg.starts_with(key) {
            return format!("invalid scene ({flag} or scene key {key})");
        }
    }
    "invalid scene".into()
}

/// The frame's light and where it came from: the sun used (the scene's or the map's), the sun
/// found in the map and the sun SPA gives for the scene's place and time (when it has them),
/// as ENU directions with azimuth/elevation in degrees.
fn light_json(
    scene: &crate::setup::scene_file::Scene,
    light: &SceneLight,
    params: &crate::render::FrameParams,
    spa: Option<glam::Vec3>,
) -> serde_json::Value {
    let measured = &light.measured;
    let dir = |d: glam::Vec3| {
        let (az, el) = crate::light::sun_finder::azimuth_elevation(d);
        serde_json::json!({ "enu": d.to_array(), "azimuth_deg": az.to_degrees(), "elevation_deg": el.to_degrees() })
    };
    let l = &params.lighting;
    let angle = |a: Option<glam::Vec3>, b: Option<glam::Vec3>| a.zip(b).map(|(a, b)| a.normalize().angle_between(b).to_degrees());
    serde_json::json!({
        "sun_from": if scene.sun.direction.is_some() { "scene" } else { "map" },
        "sun_dir": dir(l.sun_dir),
        "map_sun_dir": light.unit.map_sun_dir.map(dir),
        "spa_sun_dir": spa.map(dir),
        "map_to_spa_deg": angle(light.unit.map_sun_dir, spa),
        "used_to_spa_deg": angle(Some(l.sun_dir), spa),
        "map_sun": format!("{:?}", measured.source).to_lowercase(),
        "map_sun_irradiance": measured.sun_irradiance,
        "map_sun_turbidity": measured.turbidity,
        "map_sun_ground_over_sky": measured.ground_sun_over_sky,
        "map_sun_beam_turbidity": measured.beam_turbidity,
        "sunlight": l.sunlight,
        "daylight": l.daylight,
        "shadow_opacity": l.shadow_opacity,
        "sky_occlusion": l.sky_occlusion,
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

pub fn run(args: Args) -> Result<()> {
    let t_total = Instant::now();
    let (scene, demo) = scene_from_args(&args.scene, args.output.as_deref())?;
    // Before anything is written: a place/time SPA cannot take is an error with no output.
    let spa_sun = crate::setup::spa_sun(&scene)?;
    if let Some(dir) = &args.layers {
        std::fs::create_dir_all(dir).with_context(|| format!("--layers {}: cannot create the directory", dir.display()))?;
    }
    let t_load = Instant::now();
    let inputs = load_inputs(&scene, demo)?;
    let lighting = load_lighting(&scene)?;
    let load_ms = ms(t_load);

    let t_upload = Instant::now();
    let gpu = Gpu::headless()?;
    let (mut compositor, mut params, light) = prepare_with_light(&gpu, &scene, &inputs)?;
    if let Some(map) = &lighting {
        set_lighting_environment(&gpu, &mut compositor, &mut params, &scene, map)?;
    }
    let upload_ms = ms(t_upload);

    let composite = compositor.render(&gpu, &params, Layer::Composite)?;
    let model_layer = if args.json || args.layers.is_some() { Some(compositor.render(&gpu, &params, Layer::Model)?) } else { None };
    let background_layer = if args.layers.is_some() { Some(compositor.render(&gpu, &params, Layer::Background)?) } else { None };
    let float_layers = if args.layers.is_some() { Some(compositor.render_layers(&gpu, &params)?) } else { None };

    // Encode everything first, then write: an error leaves no output behind.
    let mut outputs: Vec<(PathBuf, &crate::render::Rendered)> = vec![(scene.output.clone(), &composite)];
    if let Some(dir) = &args.layers {
        outputs.push((dir.join("composite.png"), &composite));
        if let Some(m) = &model_layer {
            outputs.push((dir.join("model_rgba.png"), m));
        }
        if let Some(b) = &background_layer {
            outputs.push((dir.join("background.png"), b));
        }
    }
    let mut written = Vec::new();
    for (path, image) in &outputs {
        if let Err(e) = crate::output::write_image_rgba8(path, image.width, image.height, &image.rgba) {
            for p in &written {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        written.push(path.clone());
    }
    if let (Some(dir), Some(layers)) = (&args.layers, &float_layers) {
        let path = dir.join(crate::render::layers::EXR_FILE);
        if let Err(e) = crate::output::write_exr_f32(&path, layers.width, layers.height, layers.channels()) {
            for p in &written {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        written.push(path);
    }

    if args.json {
        // The same choice prepare made (pure and cheap: the materials and the measured light).
        let choice = method_choice::resolve(scene.method, &inputs.model, &light.measured);
        let model_pixels = model_layer.as_ref().map(|m| m.rgba.chunks_exact(4).filter(|p| p[3] > 0).count()).unwrap_or(0);
        let out = serde_json::json!({
            "outputs": written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "width": scene.width,
            "height": scene.height,
            "model_pixels": model_pixels,
            "supersample": compositor.supersample(),
            "method": params.method.name(),
            "method_choice": {
                "requested": choice.requested.name(),
                "method": choice.method.name(),
                "why": choice.why,
            },
            "colour_correction": { "method": scene.colour.correction.name(), "strength": scene.colour.strength },
            "light": light_json(&scene, &light, &params, spa_sun.map(|s| s.direction_enu())),
            "adapter": gpu.describe(),
            "timings_ms": {
                "load": load_ms,
                "upload": upload_ms,
                "gpu_render": composite.timings.gpu_ms,
                "readback": composite.timings.readback_ms,
                "total": ms(t_total),
            },
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sun_dir_flag_parsing() {
        assert_eq!(parse_vec3("--sun-dir", "1, -2,3.5").unwrap(), [1.0, -2.0, 3.5]);
        assert!(format!("{:#}", parse_vec3("--sun-dir", "1,2").unwrap_err()).contains("--sun-dir"));
        assert!(format!("{:#}", parse_vec3("--sun-dir", "1,x,2").unwrap_err()).contains("--sun-dir"));
    }
}
