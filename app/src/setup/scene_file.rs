//! The scene file (TOML): everything `previz composite` flags hold. Flags and `--set KEY=VALUE`
//! override the file by writing into the same table before it is checked, so there is one
//! set of names, one set of defaults and one validation for all three.

use anyhow::{Context, Result, anyhow, bail};
use serde::Deserialize;
use std::path::{Path, PathBuf};

use crate::colour::transfer::TransferMethod;
#[cfg(test)]
use crate::render::LightingMethod;
use crate::setup::method_choice::MethodRequest;

/// A complete, validated scene description. Paths are resolved against the scene file's folder.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// Model file (.obj, .gltf, .glb). None: the built-in demo model.
    pub model: Option<PathBuf>,
    /// Environment: a folder of six faces, or an equirectangular .hdr/.exr. None: built-in demo.
    pub environment: Option<PathBuf>,
    /// Background photograph (JPEG/PNG). None: the environment as seen by the camera.
    pub background: Option<PathBuf>,
    /// Output image.
    pub output: PathBuf,
    pub width: u32,
    pub height: u32,
    /// Lighting method: `auto` (the default: `setup::method_choice`) or one by name.
    pub method: MethodRequest,
    pub camera: CameraSection,
    pub sun: SunSection,
    pub material: MaterialSection,
    pub placement: PlacementSection,
    pub env: EnvSection,
    /// A separate map the model is lit and reflects with.
    pub lighting: LightingSection,
    pub effects: EffectsSection,
    pub colour: ColourSection,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSection {
    /// Degrees clockwise from true north.
    pub heading: f64,
    /// Degrees, up positive, −90..90.
    pub pitch: f64,
    /// Degrees, clockwise positive, −180..180.
    pub roll: f64,
    /// Vertical field of view, degrees.
    pub vfov: f64,
    /// Camera height above the world origin (the ground under an explicitly placed model), metres.
    pub height: f64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SunSection {
    /// Direction to the sun in ENU (need not be unit length); unset: the sun found in the
    /// environment map (setup::light).
    pub direction: Option<[f64; 3]>,
    /// Multiplier on the sunlight measured in the environment (faded to 0 through twilight as
    /// the sun sets).
    pub sunlight: f64,
    /// Multiplier on the daylight (sky without the sun) measured in the environment.
    pub daylight: f64,
    /// Where and when the scene is (degrees north, degrees east, RFC 3339 time): reported
    /// beside the map's sun as the sun NREL SPA gives there and then (all three or none).
    pub latitude: Option<f64>,
    pub longitude: Option<f64>,
    pub time: Option<String>,
}

impl SunSection {
    /// The scene's place and instant, when it gives them (checked by `Scene::validate`).
    pub fn place_time(&self) -> Result<Option<(f64, f64, chrono::DateTime<chrono::Utc>)>> {
        match (self.latitude, self.longitude, &self.time) {
            (None, None, None) => Ok(None),
            (Some(lat), Some(lon), Some(t)) => {
                let t = chrono::DateTime::parse_from_rfc3339(t)
                    .with_context(|| format!("sun.time = {t:?} is not an RFC 3339 time (e.g. 2003-10-17T12:30:30-07:00)"))?;
                Ok(Some((lat, lon, t.with_timezone(&chrono::Utc))))
            }
            _ => bail!("sun.latitude, sun.longitude and sun.time go together: give all three or none"),
        }
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialSection {
    /// a_c of Eq. 3.
    pub ambient: f64,
    /// d_c of Eq. 3.
    pub diffuse: f64,
    /// s_c of Eq. 3.
    pub specular: f64,
    /// g_f of Eq. 3; absent: each material's own exponent (MTL Ns).
    pub gloss: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PlacementSection {
    /// World position (ENU metres) of the model's base centre; absent: auto-placed in front of
    /// the camera.
    pub position: Option<[f64; 3]>,
    /// Rotation about East, North, Up in degrees (seed 000's X/Y/Z controls).
    pub rotation: [f64; 3],
    /// Model units → metres; absent: fitted so the largest dimension is `size`.
    pub scale: Option<f64>,
    /// Fitted size (metres) of the model's largest dimension when `scale` is absent.
    pub size: f64,
    /// Auto-placement: fraction of the vertical field of view the model's bounding sphere spans.
    pub fill: f64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct EnvSection {
    /// Linear scale of the environment's radiance; absent: 1 for 8-bit maps, and for HDR maps
    /// the value mapping the log-average luminance of the horizontal faces to 0.18.
    pub exposure: Option<f64>,
    /// Heading (degrees clockwise from north) of the map's front (+Z) face.
    pub heading: f64,
    /// The map is a capture of the live session's place and moment: `previz live` lights the
    /// model with NREL SPA's sun for the clock. False (a downloaded map, the demo's): the map's
    /// own sun (or `sun.direction`), whatever the clock says.
    pub captured_here: bool,
}

/// A lighting environment apart from the scene's `environment`: the map the model's reflections,
/// its sky ambient (SH9 colour and direction) and the colour priors come from, as the app's
/// camera frame folded into a cube map lights it before any capture exists. The sun (direction,
/// intensity, colour, shadows) and the ambient level (daylight) are still measured in
/// `environment`, which also stays the background when no `background` is given.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LightingSection {
    /// The map (a folder of six faces, or an equirectangular image). None: `environment` lights.
    pub environment: Option<PathBuf>,
    /// Heading (degrees clockwise from north) of its front (+Z) face; 0: its faces are the world's.
    pub heading: f64,
    /// Linear scale of its radiance; absent: the rule of `env.exposure` applied to this map.
    pub exposure: Option<f64>,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct EffectsSection {
    /// Reflection mix 0..1 for the reflection methods.
    pub reflection: f64,
    /// Refractive index of the model (refraction methods), 1..3.
    pub ior: f64,
    /// Multiplier (0..1) on how dark the model's shadow makes the ground: by default the
    /// sun's measured share of the ground's light.
    pub shadow_opacity: f64,
    /// Live-feed refraction: distance behind the surface where the refracted ray meets the scene (metres).
    pub live_depth: f64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ColourSection {
    /// Colour correction of the model towards the environment's horizontal faces (seed §5.6):
    /// none, brightness-contrast, reinhard, cielab-approx or mkl.
    pub correction: TransferMethod,
    /// 0..1: how much of the correction is applied (the seed's CC slider).
    pub strength: f64,
}

impl Default for ColourSection {
    fn default() -> Self {
        ColourSection { correction: TransferMethod::None, strength: 1.0 }
    }
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            model: None,
            environment: None,
            background: None,
            output: PathBuf::from("composite.png"),
            width: 960,
            height: 640,
            method: MethodRequest::Auto,
            camera: CameraSection::default(),
            sun: SunSection::default(),
            material: MaterialSection::default(),
            placement: PlacementSection::default(),
            env: EnvSection::default(),
            lighting: LightingSection::default(),
            effects: EffectsSection::default(),
            colour: ColourSection::default(),
        }
    }
}

impl Default for CameraSection {
    fn default() -> Self {
        CameraSection { heading: 0.0, pitch: 0.0, roll: 0.0, vfov: 60.0, height: 1.6 }
    }
}

impl Default for SunSection {
    fn default() -> Self {
        SunSection { direction: None, sunlight: 1.0, daylight: 1.0, latitude: None, longitude: None, time: None }
    }
}

impl Default for MaterialSection {
    fn default() -> Self {
        MaterialSection { ambient: 1.0, diffuse: 1.0, specular: 0.3, gloss: None }
    }
}

impl Default for PlacementSection {
    fn default() -> Self {
        PlacementSection { position: None, rotation: [0.0; 3], scale: None, size: 1.0, fill: 0.5 }
    }
}

impl Default for EnvSection {
    fn default() -> Self {
        EnvSection { exposure: None, heading: 0.0, captured_here: false }
    }
}

impl Default for EffectsSection {
    fn default() -> Self {
        EffectsSection { reflection: 0.8, ior: 1.5, shadow_opacity: 1.0, live_depth: 0.3 }
    }
}

/// A scene being assembled: the file's table, then overrides, then one check.
pub struct SceneBuilder {
    table: toml::Table,
    base_dir: PathBuf,
}

impl SceneBuilder {
    /// Start from defaults (paths relative to the current directory).
    pub fn new() -> Self {
        SceneBuilder { table: toml::Table::new(), base_dir: PathBuf::from(".") }
    }

    /// Start from a scene file; its relative paths are relative to its folder.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read scene file {}", path.display()))?;
        Self::from_toml(&text, path.parent().unwrap_or(Path::new("."))).with_context(|| format!("scene file {}", path.display()))
    }

    /// Start from TOML text; relative paths resolve against `base_dir`.
    pub fn from_toml(text: &str, base_dir: &Path) -> Result<Self> {
        let table: toml::Table = text.parse().context("not valid TOML")?;
        Ok(SceneBuilder { table, base_dir: base_dir.to_path_buf() })
    }

    /// Set a dotted key (e.g. `camera.heading`) to a TOML value.
    pub fn set(&mut self, key: &str, value: toml::Value) -> Result<()> {
        let parts: Vec<&str> = key.split('.').collect();
        if parts.iter().any(|p| p.is_empty()) {
            bail!("invalid key {key:?}");
        }
        let mut table = &mut self.table;
        for part in &parts[..parts.len() - 1] {
            let entry = table.entry(part.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
            table = entry.as_table_mut().ok_or_else(|| anyhow!("key {key:?}: {part:?} is not a table"))?;
        }
        table.insert(parts[parts.len() - 1].to_string(), value);
        Ok(())
    }

    /// Apply `KEY=VALUE` (the value is TOML: numbers, arrays `[1,2,3]`, booleans; anything that
    /// does not parse as TOML is taken as a string).
    pub fn set_str(&mut self, assignment: &str) -> Result<()> {
        let (key, value) = assignment.split_once('=').ok_or_else(|| anyhow!("--set {assignment:?}: expected KEY=VALUE"))?;
        let key = key.trim();
        let value = value.trim();
        let parsed = format!("v = {value}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(value.to_string()));
        self.set(key, parsed).with_context(|| format!("--set {assignment}"))
    }

    /// Check and return the scene. Relative paths are resolved against the scene file's folder.
    pub fn build(self) -> Result<Scene> {
        let output_given = self.table.contains_key("output");
        let mut scene: Scene = toml::Value::Table(self.table).try_into().map_err(|e: toml::de::Error| anyhow!("{e}"))?;
        for p in [&mut scene.model, &mut scene.environment, &mut scene.background, &mut scene.lighting.environment].into_iter().flatten() {
            if p.is_relative() {
                *p = self.base_dir.join(&*p);
            }
        }
        // An `output` the file (or --set) gives is relative to the file's folder too; the
        // default name stays in the current directory.
        if output_given && scene.output.is_relative() && !scene.output.as_os_str().is_empty() {
            scene.output = self.base_dir.join(&scene.output);
        }
        scene.validate()?;
        Ok(scene)
    }
}

impl Default for SceneBuilder {
    fn default() -> Self {
        Self::new()
    }
}

fn check(name: &str, v: f64, lo: f64, hi: f64) -> Result<()> {
    if !v.is_finite() {
        bail!("{name} must be a finite number, got {v}");
    }
    if v < lo || v > hi {
        bail!("{name} = {v} is out of range {lo}..={hi}");
    }
    Ok(())
}

impl Scene {
    /// Range and finiteness checks, naming the key at fault.
    pub fn validate(&self) -> Result<()> {
        crate::output::check_image_path(&self.output).context("output")?;
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=8192).contains(&v) {
                bail!("{name} = {v} is out of range 1..=8192");
            }
        }
        let c = &self.camera;
        check("camera.heading", c.heading, -360.0, 720.0)?;
        check("camera.pitch", c.pitch, -90.0, 90.0)?;
        check("camera.roll", c.roll, -180.0, 180.0)?;
        check("camera.vfov", c.vfov, 1.0, 179.0)?;
        check("camera.height", c.height, -1e4, 1e4)?;
        if let Some(d) = &self.sun.direction {
            for (i, v) in d.iter().enumerate() {
                check(&format!("sun.direction[{i}]"), *v, -1e6, 1e6)?;
            }
            if d.iter().map(|v| v * v).sum::<f64>() < 1e-12 {
                bail!("sun.direction must not be the zero vector");
            }
        }
        check("sun.sunlight", self.sun.sunlight, 0.0, 100.0)?;
        check("sun.daylight", self.sun.daylight, 0.0, 100.0)?;
        if let Some((lat, lon, _)) = self.sun.place_time()? {
            check("sun.latitude", lat, -90.0, 90.0)?;
            check("sun.longitude", lon, -180.0, 180.0)?;
        }
        let m = &self.material;
        check("material.ambient", m.ambient, 0.0, 100.0)?;
        check("material.diffuse", m.diffuse, 0.0, 100.0)?;
        check("material.specular", m.specular, 0.0, 100.0)?;
        if let Some(g) = m.gloss {
            check("material.gloss", g, 1.0, 10000.0)?;
        }
        let p = &self.placement;
        if let Some(pos) = p.position {
            for (i, v) in pos.iter().enumerate() {
                check(&format!("placement.position[{i}]"), *v, -1e5, 1e5)?;
            }
        }
        for (i, v) in p.rotation.iter().enumerate() {
            check(&format!("placement.rotation[{i}]"), *v, -360.0, 360.0)?;
        }
        if let Some(s) = p.scale {
            check("placement.scale", s, 1e-9, 1e9)?;
            if s <= 0.0 {
                bail!("placement.scale must be positive");
            }
        }
        check("placement.size", p.size, 1e-6, 1e6)?;
        check("placement.fill", p.fill, 0.01, 1.0)?;
        if let Some(e) = self.env.exposure {
            check("env.exposure", e, 1e-9, 1e9)?;
        }
        check("env.heading", self.env.heading, -360.0, 720.0)?;
        let l = &self.lighting;
        if l.environment.is_none() && (l.heading != 0.0 || l.exposure.is_some()) {
            bail!("lighting.heading and lighting.exposure describe lighting.environment, which is not given");
        }
        check("lighting.heading", l.heading, -360.0, 720.0)?;
        if let Some(e) = l.exposure {
            check("lighting.exposure", e, 1e-9, 1e9)?;
        }
        let e = &self.effects;
        check("effects.reflection", e.reflection, 0.0, 1.0)?;
        check("effects.ior", e.ior, 1.0, 3.0)?;
        check("effects.shadow_opacity", e.shadow_opacity, 0.0, 1.0)?;
        check("effects.live_depth", e.live_depth, 0.0, 1e4)?;
        check("colour.strength", self.colour.strength, 0.0, 1.0)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_overrides_apply() {
        let mut b = SceneBuilder::from_toml("width = 320\n[camera]\nheading = 90.0\n", Path::new("/scenes")).unwrap();
        b.set_str("camera.heading=45").unwrap();
        b.set_str("sun.direction=[1, 0, 1]").unwrap();
        b.set_str("method=cube-reflection").unwrap();
        b.set_str("model=bunny.obj").unwrap();
        let s = b.build().unwrap();
        assert_eq!(s.width, 320);
        assert_eq!(s.height, 640);
        assert_eq!(s.camera.heading, 45.0);
        assert_eq!(s.sun.direction, Some([1.0, 0.0, 1.0]));
        assert_eq!(s.method, MethodRequest::Fixed(LightingMethod::CubeReflection));
        assert_eq!(s.model.as_deref(), Some(Path::new("/scenes/bunny.obj")));
    }

    #[test]
    fn bad_values_name_the_key() {
        for (assignment, needle) in [
            ("camera.pitch=nan", "camera.pitch"),
            ("camera.vfov=0", "camera.vfov"),
            ("effects.ior=0.5", "effects.ior"),
            ("sun.direction=[0,0,0]", "sun.direction"),
            ("width=0", "width"),
            ("camera.bogus=1", "bogus"),
            ("method=phong", "method"),
            ("colour.correction=lut", "correction"),
            ("colour.strength=1.5", "colour.strength"),
            ("lighting.heading=30", "lighting.environment"),
            ("lighting.map=fold", "map"),
        ] {
            let mut b = SceneBuilder::new();
            let err = b.set_str(assignment).and_then(|()| b.build().map(|_| ())).unwrap_err();
            let msg = format!("{err:#}");
            assert!(msg.contains(needle), "{assignment}: {msg}");
        }
        assert!(SceneBuilder::new().set_str("novalue").is_err());
        assert!(SceneBuilder::from_toml("width = [", Path::new(".")).is_err());
    }

    #[test]
    fn a_lighting_environment_resolves_beside_the_scene_and_its_values_are_checked() {
        let s =
            SceneBuilder::from_toml("[lighting]\nenvironment = \"fold\"\nexposure = 1.0\n", Path::new("/export")).unwrap().build().unwrap();
        assert_eq!(s.lighting.environment.as_deref(), Some(Path::new("/export/fold")));
        assert_eq!((s.lighting.heading, s.lighting.exposure), (0.0, Some(1.0)));
        assert_eq!(SceneBuilder::new().build().unwrap().lighting, LightingSection::default());
        for (assignment, needle) in [("lighting.exposure=0", "lighting.exposure"), ("lighting.heading=nan", "lighting.heading")] {
            let mut b = SceneBuilder::new();
            b.set_str("lighting.environment=fold").unwrap();
            let err = b.set_str(assignment).and_then(|()| b.build().map(|_| ())).unwrap_err();
            assert!(format!("{err:#}").contains(needle), "{assignment}: {err:#}");
        }
    }
}
