//! The lighting method: a run-time choice, so new methods slot in and the benchmark iterates
//! over all of them. The numbers are the values of the model shader's `METHOD` override constant
//! (one model pipeline per method); the shader knows them by name through [`LightingMethod::wgsl_consts`].

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightingMethod {
    /// Modified Blinn-Phong (seed 000 Eq. 3) with a constant ambient (daylight) term.
    BlinnPhong,
    /// Blinn-Phong with hemisphere lighting (Eq. 6) as the ambient term: sky and ground colours
    /// are the mean colours of the environment's up and down faces.
    Hemisphere,
    /// Blinn-Phong with hemisphere occlusion as the ambient term (§5.4.2): light and shadow
    /// levels from the horizontal faces' luminance.
    HemisphereOcclusion,
    /// Hemisphere-lit model mixed with the environment cube map seen in reflection (§5.5.1).
    CubeReflection,
    /// Transparent material (Eq. 7) refracting the environment cube map.
    CubeRefraction,
    /// Hemisphere-lit model mixed with the camera image used as a mirror ball (§5.5.3).
    LiveReflection,
    /// Transparent material (Eq. 7) refracting the camera image behind it (§5.5.3).
    LiveRefraction,
    /// Light measured from the environment, in colour (issue 9; shaders/sh9_ggx.wgsl): the sky
    /// without the sun through each vertex's own open rays (weighted by its binned radiance,
    /// plus its bounce off the model) in SH9's colour, the sun with soft (PCSS) shadows, GGX
    /// specular from the prefiltered environment (split-sum, Karis 2013).
    Sh9Ggx,
}

impl LightingMethod {
    pub const ALL: [LightingMethod; 8] = [
        LightingMethod::BlinnPhong,
        LightingMethod::Hemisphere,
        LightingMethod::HemisphereOcclusion,
        LightingMethod::CubeReflection,
        LightingMethod::CubeRefraction,
        LightingMethod::LiveReflection,
        LightingMethod::LiveRefraction,
        LightingMethod::Sh9Ggx,
    ];

    /// Whether the method reflects or refracts the view ray off the surface: its image follows
    /// the surface normal, which the half-pixel bound on the simplified surface's position does
    /// not bound (measured: the bunny goldens' cube and live reflection at their chosen level,
    /// p99 FLIP 0.31 vs the full mesh, over the goldens' 0.3), so these methods draw the model
    /// as loaded.
    pub fn bends_rays(self) -> bool {
        matches!(
            self,
            LightingMethod::CubeReflection
                | LightingMethod::CubeRefraction
                | LightingMethod::LiveReflection
                | LightingMethod::LiveRefraction
        )
    }

    /// The value of the `METHOD` override constant in shaders/model.wgsl.
    pub fn shader_id(self) -> u32 {
        self as u32
    }

    /// The name of the method's WGSL constant, e.g. `METHOD_CUBE_REFLECTION`.
    pub fn wgsl_const(self) -> String {
        format!("METHOD_{}", self.name().replace('-', "_").to_ascii_uppercase())
    }

    /// `const METHOD_…: u32 = id;` for every method: the WGSL side of the ids, generated here
    /// so that they are declared once.
    pub fn wgsl_consts() -> String {
        LightingMethod::ALL.iter().map(|m| format!("const {}: u32 = {}u;\n", m.wgsl_const(), m.shader_id())).collect()
    }

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            LightingMethod::BlinnPhong => "blinn-phong",
            LightingMethod::Hemisphere => "hemisphere",
            LightingMethod::HemisphereOcclusion => "hemisphere-occlusion",
            LightingMethod::CubeReflection => "cube-reflection",
            LightingMethod::CubeRefraction => "cube-refraction",
            LightingMethod::LiveReflection => "live-reflection",
            LightingMethod::LiveRefraction => "live-refraction",
            LightingMethod::Sh9Ggx => "sh9-ggx",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_shader_names_every_method_and_no_id() {
        let wgsl = include_str!("../../../shaders/model.wgsl");
        assert!(LightingMethod::wgsl_consts().contains("const METHOD_HEMISPHERE_OCCLUSION: u32 = 2u;\n"));
        for m in LightingMethod::ALL {
            // Every method but the default Blinn-Phong path is branched on by name...
            assert!(wgsl.contains(&m.wgsl_const()), "model.wgsl never uses {}", m.wgsl_const());
            let parsed: LightingMethod = clap::ValueEnum::from_str(m.name(), false).unwrap();
            assert_eq!(parsed, m);
        }
        // ...and never by number.
        for id in 0..LightingMethod::ALL.len() {
            assert!(!wgsl.contains(&format!("method == {id}u")), "model.wgsl compares the method with the literal {id}u");
        }
    }
}
