//! The shutter: the current live frame as files a desktop reproduces. Into a folder it writes
//! the composite and its layers (the names `previz composite --layers` uses: `composite.png`,
//! `model_rgba.png`, `background.png`, the float layers in `layers.exr`), the camera image (`camera.png`) and `scene.toml`, the
//! scene of that moment — camera pose and field of view, sun direction and intensity, the panel's
//! values, the model's placement, the camera image as background — so that
//! `previz composite scene.toml` (run in the folder) renders the same frame into
//! `recomposite.png`. The place (latitude, longitude) is written, as a comment, only when asked.
//! While the camera frame folded into a cube map lights the model (before any capture), the fold
//! is written too, as a folder of six float faces ([`LIGHTING_DIR`]), and the scene names it as
//! its lighting environment (`lighting.environment`): the recomposite is lit as the frame was.

use super::LiveSession;
use crate::gpu::Gpu;
use crate::pose::frames::heading_pitch_roll;
use crate::render::Layer;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use toml::Value;

/// The files of one export, in the order written.
pub const FILES: [&str; 6] = ["composite.png", "model_rgba.png", "background.png", "camera.png", "layers.exr", "scene.toml"];

/// The folder the folded camera frame is written into (`posx.exr` … `negz.exr`, 32-bit float
/// linear R, G, B, each face stored as the loaders read it), when it lights the frame.
pub const LIGHTING_DIR: &str = "lighting";

/// Face file stems in cube-layer order (+X, −X, +Y, −Y, +Z, −Z), as `scene::environment` reads them.
const FACE_STEMS: [&str; 6] = ["posx", "negx", "posy", "negy", "posz", "negz"];

/// The scene of the session's current frame (model, environment, size and what the frame does
/// not change come from the scene the session was made from). Paths: the camera image is
/// `camera.png` beside the scene file, the output `recomposite.png`.
pub fn scene_toml(session: &LiveSession, location: Option<(f64, f64)>) -> Result<String> {
    let base = session.scene();
    let p = session.params();
    let hpr = heading_pitch_roll(p.camera.pose.as_dquat());
    let l = &p.lighting;
    let sun_dir = l.sun_dir.normalize();
    let fade = crate::sun::twilight::sunlight_factor_toward(sun_dir);
    // The scene's sunlight, daylight and shadow opacity are multipliers on the light measured
    // in the environment (setup::light); composite fades the sunlight by the sun's elevation
    // again.
    let unit = session.unit_light();
    let ratio = |v: f32, of: f32| if of > 0.0 { v / of } else { 0.0 };
    let sunlight = if fade > 0.0 { ratio(l.sunlight / fade, unit.sunlight) } else { 0.0 };
    let daylight = ratio(l.daylight, unit.daylight);
    // The ground's shadow strengths follow the sun (setup::light::ground_strengths): the
    // scene's multiplier on them is the session's.
    let shadow_opacity = base.effects.shadow_opacity as f32;
    let f = |v: f32| Value::Float(f64::from(v));
    let v3 = |v: glam::Vec3| Value::Array(vec![f(v.x), f(v.y), f(v.z)]);
    let table = |entries: Vec<(&str, Value)>| Value::Table(entries.into_iter().map(|(k, v)| (k.to_string(), v)).collect());
    let path = |p: &Path| Value::String(p.to_string_lossy().into_owned());

    let mut top = toml::map::Map::new();
    if let Some(m) = &base.model {
        top.insert("model".into(), path(&std::path::absolute(m).context("model path")?));
    }
    if let Some(e) = &base.environment {
        top.insert("environment".into(), path(&std::path::absolute(e).context("environment path")?));
    }
    top.insert("background".into(), Value::String("camera.png".into()));
    top.insert("output".into(), Value::String("recomposite.png".into()));
    top.insert("width".into(), Value::Integer(base.width.into()));
    top.insert("height".into(), Value::Integer(base.height.into()));
    top.insert("method".into(), Value::String(p.method.name().into()));
    top.insert(
        "camera".into(),
        table(vec![
            ("heading", Value::Float(hpr.heading.to_degrees())),
            ("pitch", Value::Float(hpr.pitch.to_degrees())),
            ("roll", Value::Float(hpr.roll.to_degrees())),
            ("vfov", f(p.camera.vfov.to_degrees())),
            ("height", f(p.camera.position.z)),
        ]),
    );
    top.insert("sun".into(), table(vec![("direction", v3(sun_dir)), ("sunlight", f(sunlight)), ("daylight", f(daylight))]));
    let mut material = vec![("ambient", f(l.material.ambient)), ("diffuse", f(l.material.diffuse)), ("specular", f(l.material.specular))];
    if let Some(g) = l.material.gloss {
        material.push(("gloss", f(g)));
    }
    top.insert("material".into(), table(material));
    let pl = &p.placement;
    top.insert(
        "placement".into(),
        table(vec![("position", v3(pl.position)), ("rotation", v3(pl.rotation * (180.0 / std::f32::consts::PI))), ("scale", f(pl.scale))]),
    );
    let mut env = vec![("heading", Value::Float(base.env.heading))];
    if let Some(e) = base.env.exposure {
        env.push(("exposure", Value::Float(e)));
    }
    top.insert("env".into(), table(env));
    if session.folded_environment().is_some() {
        // The fold is in the renderer's linear light, indexed by world directions.
        let lighting =
            vec![("environment", Value::String(LIGHTING_DIR.into())), ("heading", Value::Float(0.0)), ("exposure", Value::Float(1.0))];
        top.insert("lighting".into(), table(lighting));
    }
    top.insert(
        "effects".into(),
        table(vec![
            ("reflection", f(l.reflection)),
            ("ior", f(l.ior)),
            ("shadow_opacity", f(shadow_opacity)),
            ("live_depth", f(l.live_depth)),
        ]),
    );
    top.insert(
        "colour".into(),
        table(vec![("correction", Value::String(p.colour.method.name().into())), ("strength", f(p.colour.strength))]),
    );
    let mut text = String::from("# A frame exported from the Previz app: `previz composite scene.toml` in this folder renders it again.\n");
    if let Some((lat, lon)) = location {
        text.push_str(&format!("# location: latitude {lat:.6}, longitude {lon:.6}\n"));
    }
    text.push_str(&toml::to_string(&Value::Table(top)).context("writing the scene as TOML")?);
    Ok(text)
}

/// Export the current frame into `dir` (an existing folder): the files of [`FILES`], and the
/// folded camera frame's faces in [`LIGHTING_DIR`] while it lights the model. Nothing is left
/// behind when a write fails.
pub fn export(session: &mut LiveSession, gpu: &Gpu, dir: &Path, location: Option<(f64, f64)>) -> Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        bail!("export folder {}: not an existing directory", dir.display());
    }
    let camera = session.camera_frame(gpu).context("nothing to export")?;
    let composite = session.render_layer(gpu, Layer::Composite)?;
    let model = session.render_layer(gpu, Layer::Model)?;
    let background = session.render_layer(gpu, Layer::Background)?;
    let layers = session.render_float_layers(gpu)?;
    let toml = scene_toml(session, location)?;
    let mut written = Vec::new();
    let mut made_dir = None;
    let result = (|| -> Result<()> {
        for (name, w, h, rgba) in [
            (FILES[0], composite.width, composite.height, &composite.rgba),
            (FILES[1], model.width, model.height, &model.rgba),
            (FILES[2], background.width, background.height, &background.rgba),
            (FILES[3], camera.width, camera.height, &camera.pixels),
        ] {
            let path = dir.join(name);
            crate::output::write_png_rgba8(&path, w, h, rgba).with_context(|| format!("writing {}", path.display()))?;
            written.push(path);
        }
        let path = dir.join(FILES[4]);
        crate::output::write_exr_f32(&path, layers.width, layers.height, layers.channels())?;
        written.push(path);
        if let Some(cube) = session.folded_environment() {
            let faces = dir.join(LIGHTING_DIR);
            std::fs::create_dir(&faces).with_context(|| format!("cannot create {}", faces.display()))?;
            made_dir = Some(faces.clone());
            for (stem, face) in FACE_STEMS.iter().zip(&cube.faces) {
                let path = faces.join(format!("{stem}.exr"));
                let plane = |c: usize| face.iter().map(|t| t[c]).collect::<Vec<f32>>();
                crate::output::write_exr_f32(&path, cube.size, cube.size, vec![("R", plane(0)), ("G", plane(1)), ("B", plane(2))])?;
                written.push(path);
            }
        }
        let path = dir.join(FILES[5]);
        std::fs::write(&path, &toml).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
        Ok(())
    })();
    if let Err(e) = result {
        for p in &written {
            let _ = std::fs::remove_file(p);
        }
        if let Some(d) = made_dir {
            let _ = std::fs::remove_dir(d);
        }
        return Err(e);
    }
    Ok(written)
}
