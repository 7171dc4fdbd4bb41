//! What a frame is made of, as the caller sets it: camera, lighting, placement, colour
//! correction and the method. Plain data; the frame maths is in [`super::frame`].

use super::LightingMethod;
use super::view::Placement;
use crate::colour::transfer::TransferMethod;
use crate::priors::EnvironmentPriors;
use glam::{Quat, Vec3};

/// What the hemisphere methods need from the environment (seed 000 §5.4), in linear light after
/// exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemispherePriors {
    /// Mean colour of the up (+Y, sky) face.
    pub sky: [f32; 3],
    /// Mean colour of the down (−Y, ground) face.
    pub ground: [f32; 3],
    /// Hemisphere-occlusion light level: the bright end of the horizontal faces' luminance.
    pub light: f32,
    /// Hemisphere-occlusion shadow level: the dark end of the horizontal faces' luminance.
    pub shadow: f32,
}

impl HemispherePriors {
    /// From the environment priors (after exposure): sky/ground = mean colour of the +Y/−Y faces;
    /// occlusion light/shadow = 99th/1st percentile of BT.709 luminance over the four horizontal
    /// faces (robust against one bright pixel, unlike the seed's single-pixel max/min).
    pub fn from_environment(p: &EnvironmentPriors) -> HemispherePriors {
        let rgb = |v: [f64; 3]| v.map(|c| c as f32);
        HemispherePriors {
            sky: rgb(p.up_mean),
            ground: rgb(p.down_mean),
            light: p.horizontal.luminance.p_hi as f32,
            shadow: p.horizontal.luminance.p_lo as f32,
        }
    }
}

/// Colour correction of the model towards the environment (seed §5.6): which method, how much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourSettings {
    pub method: TransferMethod,
    /// 0..1 (the seed's CC slider).
    pub strength: f32,
}

impl ColourSettings {
    pub const NONE: ColourSettings = ColourSettings { method: TransferMethod::None, strength: 0.0 };
}

/// The Blinn-Phong material terms of Eq. 3 (scalars; colour comes from the material/texture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialTerms {
    /// a_c
    pub ambient: f32,
    /// d_c
    pub diffuse: f32,
    /// s_c
    pub specular: f32,
    /// g_f; `None` keeps each material's own exponent (MTL `Ns`).
    pub gloss: Option<f32>,
}

/// The lights and effect strengths of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Unit direction to the sun, world (ENU).
    pub sun_dir: Vec3,
    /// Sunlight intensity l_s (already faded through twilight by the caller).
    pub sunlight: f32,
    /// Daylight (ambient) intensity l_d.
    pub daylight: f32,
    pub material: MaterialTerms,
    /// Mix of the reflection into the model, 0..1 (reflection methods).
    pub reflection: f32,
    /// Refractive index of the model's material (refraction methods); eta = 1 / ior.
    pub ior: f32,
    /// How dark the model's shadow makes the ground, 0..1: the sun's share of the ground's light.
    pub shadow_opacity: f32,
    /// How dark the model's occlusion of the sky makes the ground where it hides all of it, 0..1:
    /// the sky's share of the ground's light (the contact shadow, the only one under overcast).
    pub sky_occlusion: f32,
    /// Live-feed refraction: how far behind the surface (metres) the refracted ray meets the scene.
    pub live_depth: f32,
    /// The sky without the sun (sh9-ggx): SH9 coefficients of irradiance / π in linear RGB, in
    /// the environment map's own ENU frame (before its heading), per unit of `daylight`:
    /// daylight · Σ c_i Y_i(n) is what a white Lambertian surface facing n reflects.
    pub sky_sh: [[f32; 3]; 9],
    /// The same sky's radiance in bins (relative, the map's own frame): what weights the rays of
    /// the ground's sky visibility under the model (render::model_cache).
    pub sky_radiance: crate::light::sh9::SkyRadiance,
    /// The ground's radiance per unit of `daylight` (sh9-ggx, linear RGB): `sky_sh` is the sky
    /// above the horizon, below it a uniform ground of this radiance lights the model, as far as
    /// each vertex sees it past the model and its shadow (scene::occlusion::model_sky_ground).
    pub ground_radiance: [f32; 3],
    /// The sun's colour (sh9-ggx): linear RGB of BT.709 luminance 1, scaled by `sunlight`.
    pub sun_colour: [f32; 3],
    /// Angular radius of the sun, radians: the width of the soft shadows' penumbra.
    pub sun_angular_radius: f32,
}

/// The camera of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Orientation, camera → world.
    pub pose: Quat,
    /// Position in world (ENU), metres.
    pub position: Vec3,
    /// Vertical field of view, radians.
    pub vfov: f32,
}

/// Everything that may change from frame to frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameParams {
    pub camera: Camera,
    pub method: LightingMethod,
    pub lighting: Lighting,
    pub placement: Placement,
    pub colour: ColourSettings,
}

/// Which image a render produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// Background, ground shadow and model.
    Composite,
    /// The model alone over transparent black: premultiplied RGBA, alpha = coverage.
    Model,
    /// The background alone.
    Background,
}

#[cfg(test)]
impl FrameParams {
    /// A plain frame for tests: camera at the origin looking along its identity pose, Blinn-Phong,
    /// the sun overhead.
    pub fn example() -> FrameParams {
        use super::{MaterialTerms, Placement};
        FrameParams {
            camera: Camera { pose: Quat::IDENTITY, position: Vec3::ZERO, vfov: 1.0 },
            method: LightingMethod::BlinnPhong,
            lighting: Lighting {
                sun_dir: Vec3::Z,
                sunlight: 1.0,
                daylight: 0.5,
                material: MaterialTerms { ambient: 1.0, diffuse: 1.0, specular: 0.5, gloss: None },
                reflection: 0.0,
                ior: 1.5,
                shadow_opacity: 0.6,
                sky_occlusion: 0.0,
                live_depth: 1.0,
                sky_sh: [[0.0; 3]; 9],
                sky_radiance: crate::light::sh9::SkyRadiance::UNIFORM,
                ground_radiance: [0.0; 3],
                sun_colour: [1.0; 3],
                sun_angular_radius: 0.0047,
            },
            placement: Placement { position: Vec3::ZERO, rotation: Vec3::ZERO, scale: 1.0 },
            colour: ColourSettings::NONE,
        }
    }
}
