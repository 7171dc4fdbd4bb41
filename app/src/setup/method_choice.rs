//! `--method auto`: the lighting method a scene needs, picked from measured scene statistics
//! (the model's materials and the environment's measured light), with the reasons printed by
//! `composite --json`. One place decides; the CLI, scene files and the live view all ask here.
//!
//! The rules, cheapest first: the ray-bending methods (reflection and refraction) draw the model
//! as loaded (no level of detail, `LightingMethod::bends_rays`) and sample the environment per
//! pixel, so they are chosen only when a material needs them: refraction for a transparent
//! material (opacity below 1), reflection for a mirror-like one (specular luminance and exponent
//! both high) in an environment with something to reflect (a sun, or a sky whose irradiance
//! varies with direction). Every other scene gets sh9-ggx (the renderer's ordinary method: the most
//! accurate on the accuracy chart short of the path tracer). Under an overcast sky (no measured sun share) the sun
//! shadow costs nothing: the light terms carry sunlight 0 and the renderer skips the ground pass.

use crate::light::measure::MeasuredLight;
use crate::render::LightingMethod;
use crate::scene::Model;
use glam::Vec3;

/// What a scene asks for: a method by name, or `auto` (the default).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(try_from = "String")]
pub enum MethodRequest {
    #[default]
    Auto,
    Fixed(LightingMethod),
}

impl MethodRequest {
    /// Every request, `auto` first, then each method in [`LightingMethod::ALL`]'s order (the
    /// CLI's possible values).
    pub const ALL: [MethodRequest; LightingMethod::ALL.len() + 1] = {
        let mut all = [MethodRequest::Auto; LightingMethod::ALL.len() + 1];
        let mut i = 0;
        while i < LightingMethod::ALL.len() {
            all[i + 1] = MethodRequest::Fixed(LightingMethod::ALL[i]);
            i += 1;
        }
        all
    };

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            MethodRequest::Auto => "auto",
            MethodRequest::Fixed(m) => m.name(),
        }
    }

    /// The named method; for `auto` not yet resolved ([`resolve`]), the method `auto` picks for
    /// an ordinary scene.
    pub fn method_or_ordinary(self) -> LightingMethod {
        match self {
            MethodRequest::Auto => ORDINARY,
            MethodRequest::Fixed(m) => m,
        }
    }
}

impl TryFrom<String> for MethodRequest {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        MethodRequest::ALL.iter().copied().find(|r| r.name() == s).ok_or_else(|| {
            let names: Vec<&str> = MethodRequest::ALL.iter().map(|r| r.name()).collect();
            format!("unknown lighting method {s:?} (one of {})", names.join(", "))
        })
    }
}

impl clap::ValueEnum for MethodRequest {
    fn value_variants<'a>() -> &'a [Self] {
        &MethodRequest::ALL
    }
    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()))
    }
}

/// What `auto` picks when no material needs more.
pub const ORDINARY: LightingMethod = LightingMethod::Sh9Ggx;
/// Below this opacity a material is transparent (the refraction methods' Eq. 7 material).
pub const TRANSPARENT_BELOW: f32 = 1.0;
/// A mirror-like material: specular luminance at least this (MTL `Ks`)...
pub const MIRROR_SPECULAR: f32 = 0.5;
/// ...and a Blinn-Phong exponent at least this (MTL `Ns`; 200 is a lobe of about ±5°).
pub const MIRROR_SHININESS: f32 = 200.0;
/// A sky whose irradiance varies by at least this (max − min) / (max + min) over the six axis
/// directions has something to reflect.
pub const SKY_CONTRAST: f32 = 0.1;
/// Below this sun share of the ground's irradiance the sky counts as overcast.
pub const OVERCAST_SUN_SHARE: f32 = 0.05;

/// The scene statistics the choice reads.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneStats {
    /// The lowest material opacity and that material's name.
    pub min_opacity: (f32, String),
    /// The most mirror-like material: (specular luminance, exponent, name), by specular
    /// luminance among materials with an exponent ≥ MIRROR_SHININESS, else the highest exponent.
    pub mirror: (f32, f32, String),
    /// The sun's share of the ground's irradiance, 0..1.
    pub sun_share: f32,
    /// (max − min) / (max + min) of the sky's irradiance luminance over ±x, ±y, ±z.
    pub sky_contrast: f32,
}

impl SceneStats {
    /// Measure `model`'s materials and the environment's `light`.
    pub fn measure(model: &Model, light: &MeasuredLight) -> SceneStats {
        let used = |i: usize| model.meshes.iter().any(|m| m.material == i && !m.indices.is_empty());
        let materials: Vec<_> = model.materials.iter().enumerate().filter(|(i, _)| used(*i)).map(|(_, m)| m).collect();
        let min_opacity =
            materials.iter().map(|m| (m.opacity, m.name.clone())).fold((1.0, String::new()), |a, b| if b.0 < a.0 { b } else { a });
        let lum = crate::colour::luminance_bt709;
        let key = |m: &&crate::scene::Material| if m.shininess >= MIRROR_SHININESS { (1, lum(m.specular)) } else { (0, m.shininess) };
        let mirror = materials
            .iter()
            .max_by(|a, b| key(a).partial_cmp(&key(b)).unwrap_or(std::cmp::Ordering::Equal))
            .map_or((0.0, 0.0, String::new()), |m| (lum(m.specular), m.shininess, m.name.clone()));
        let sky: Vec<f32> =
            [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z].iter().map(|&n| lum(light.sky.irradiance(n))).collect();
        let (lo, hi) = sky.iter().fold((f32::INFINITY, 0f32), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let sky_contrast = if hi + lo > 0.0 && lo.is_finite() { (hi - lo) / (hi + lo) } else { 0.0 };
        SceneStats { min_opacity, mirror, sun_share: light.sun_share_on_ground(), sky_contrast }
    }
}

/// The method picked and why (one line per rule applied).
#[derive(Clone, Debug, PartialEq)]
pub struct MethodChoice {
    pub requested: MethodRequest,
    pub method: LightingMethod,
    pub why: Vec<String>,
}

/// The method for `requested` in a scene with `stats`: the named one, or `auto`'s pick.
pub fn choose(requested: MethodRequest, stats: &SceneStats) -> MethodChoice {
    let mut why = Vec::new();
    let (opacity, transparent_name) = &stats.min_opacity;
    let (specular, shininess, mirror_name) = &stats.mirror;
    let mirror_like = *specular >= MIRROR_SPECULAR && *shininess >= MIRROR_SHININESS;
    let has_sun = stats.sun_share >= OVERCAST_SUN_SHARE;
    let something_to_reflect = has_sun || stats.sky_contrast >= SKY_CONTRAST;
    let method = match requested {
        MethodRequest::Fixed(m) => {
            why.push(format!("{} asked for by name", m.name()));
            m
        }
        MethodRequest::Auto if *opacity < TRANSPARENT_BELOW => {
            why.push(format!("material {transparent_name:?} is transparent (opacity {opacity:.2}): refraction"));
            LightingMethod::CubeRefraction
        }
        MethodRequest::Auto if mirror_like && something_to_reflect => {
            why.push(format!(
                "material {mirror_name:?} is mirror-like (specular {specular:.2}, exponent {shininess:.0}) and the environment has \
                 something to reflect (sun share {:.2}, sky contrast {:.2}): reflection",
                stats.sun_share, stats.sky_contrast
            ));
            LightingMethod::CubeReflection
        }
        MethodRequest::Auto => {
            why.push("no transparent material: no refraction".into());
            why.push(if mirror_like {
                format!(
                    "a uniform environment (no sun, sky contrast {:.2} < {SKY_CONTRAST}) has nothing to reflect: no specular environment",
                    stats.sky_contrast
                )
            } else {
                format!("no mirror-like material (most: specular {specular:.2}, exponent {shininess:.0}): no specular environment")
            });
            ORDINARY
        }
    };
    why.push(if has_sun {
        format!("sun share of the ground's light {:.2}: sun shadow drawn", stats.sun_share)
    } else {
        format!("overcast (sun share {:.2} < {OVERCAST_SUN_SHARE}): no sun shadow on the ground", stats.sun_share)
    });
    MethodChoice { requested, method, why }
}

/// [`choose`] for a scene's `model` in an environment measured as `light`.
pub fn resolve(requested: MethodRequest, model: &Model, light: &MeasuredLight) -> MethodChoice {
    choose(requested, &SceneStats::measure(model, light))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(opacity: f32, specular: f32, shininess: f32, sun_share: f32, sky_contrast: f32) -> SceneStats {
        SceneStats { min_opacity: (opacity, "glass".into()), mirror: (specular, shininess, "chrome".into()), sun_share, sky_contrast }
    }

    #[test]
    fn each_rule_picks_its_method() {
        // Matte, opaque, sunny: the ordinary method.
        let c = choose(MethodRequest::Auto, &stats(1.0, 0.1, 20.0, 0.7, 0.5));
        assert_eq!(c.method, ORDINARY, "{:?}", c.why);
        assert!(c.why.iter().any(|w| w.contains("no refraction")) && c.why.iter().any(|w| w.contains("sun shadow drawn")), "{:?}", c.why);
        // A transparent material: refraction, whatever else.
        assert_eq!(choose(MethodRequest::Auto, &stats(0.4, 0.9, 500.0, 0.7, 0.5)).method, LightingMethod::CubeRefraction);
        // Chrome under the sun, or in a sky that varies: reflection.
        assert_eq!(choose(MethodRequest::Auto, &stats(1.0, 0.9, 500.0, 0.7, 0.0)).method, LightingMethod::CubeReflection);
        assert_eq!(choose(MethodRequest::Auto, &stats(1.0, 0.9, 500.0, 0.0, 0.3)).method, LightingMethod::CubeReflection);
        // Chrome in a uniform grey world: nothing to reflect.
        let c = choose(MethodRequest::Auto, &stats(1.0, 0.9, 500.0, 0.0, 0.02));
        assert_eq!(c.method, ORDINARY);
        assert!(c.why.iter().any(|w| w.contains("overcast")), "{:?}", c.why);
        // Shiny but not a mirror (a broad lobe): no specular environment.
        assert_eq!(choose(MethodRequest::Auto, &stats(1.0, 0.9, 50.0, 0.7, 0.5)).method, ORDINARY);
        // A method by name is kept.
        let named = MethodRequest::Fixed(LightingMethod::LiveRefraction);
        assert_eq!(choose(named, &stats(1.0, 0.0, 1.0, 0.7, 0.5)).method, LightingMethod::LiveRefraction);
    }

    #[test]
    fn requests_parse_by_name() {
        for r in MethodRequest::ALL {
            assert_eq!(MethodRequest::try_from(r.name().to_string()), Ok(r));
        }
        let err = MethodRequest::try_from("phong".to_string()).unwrap_err();
        assert!(err.contains("phong") && err.contains("auto"), "{err}");
        assert_eq!(MethodRequest::default(), MethodRequest::Auto);
    }
}
