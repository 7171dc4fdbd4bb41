//! The lighting method: a run-time choice, so new methods slot in and the benchmark iterates
//! over all of them. The numbers are the `frame.mode.x` values the model shader switches on.

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
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
}

impl Method {
    pub const ALL: [Method; 7] = [
        Method::BlinnPhong,
        Method::Hemisphere,
        Method::HemisphereOcclusion,
        Method::CubeReflection,
        Method::CubeRefraction,
        Method::LiveReflection,
        Method::LiveRefraction,
    ];

    /// The value of `frame.mode.x` in shaders/model.wgsl.
    pub fn shader_id(self) -> u32 {
        self as u32
    }

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Method::BlinnPhong => "blinn-phong",
            Method::Hemisphere => "hemisphere",
            Method::HemisphereOcclusion => "hemisphere-occlusion",
            Method::CubeReflection => "cube-reflection",
            Method::CubeRefraction => "cube-refraction",
            Method::LiveReflection => "live-reflection",
            Method::LiveRefraction => "live-refraction",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shader_ids_match_the_model_shader_table() {
        // The table at the top of shaders/model.wgsl lists "<id> <name>" for every method.
        let wgsl = include_str!("../../../shaders/model.wgsl");
        for m in Method::ALL {
            let row = format!("//   {} {}", m.shader_id(), m.name());
            assert!(wgsl.contains(&row), "model.wgsl does not document {row:?}");
            let parsed: Method = clap::ValueEnum::from_str(m.name(), false).unwrap();
            assert_eq!(parsed, m);
        }
    }
}
