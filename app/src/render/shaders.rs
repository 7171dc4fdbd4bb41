//! The WGSL sources, one file per technique, each appended to the full-screen triangle and the
//! shared `frame.wgsl`.

/// A render technique with its own shader file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Technique {
    Background,
    EnvView,
    EnvViewEquirect,
    Shadow,
    Ground,
    /// The ground's sun visibility in ground space (render::passes::ground_sun).
    GroundSun,
    Model,
    /// The model's sun per vertex (a compute shader).
    VertexSun,
    Fxaa,
    /// The live view's layers composed through a turn of the camera (render::reprojection).
    Reproject,
}

impl Technique {
    pub const ALL: [Technique; 10] = [
        Technique::Background,
        Technique::EnvView,
        Technique::EnvViewEquirect,
        Technique::Shadow,
        Technique::Ground,
        Technique::GroundSun,
        Technique::Model,
        Technique::VertexSun,
        Technique::Fxaa,
        Technique::Reproject,
    ];

    fn file(self) -> &'static str {
        match self {
            Technique::Background => include_str!("../../../shaders/background.wgsl"),
            Technique::EnvView => include_str!("../../../shaders/env_view.wgsl"),
            Technique::EnvViewEquirect => include_str!("../../../shaders/env_view_equirect.wgsl"),
            Technique::Shadow => include_str!("../../../shaders/shadow.wgsl"),
            Technique::Ground => include_str!("../../../shaders/ground.wgsl"),
            Technique::GroundSun => include_str!("../../../shaders/ground_sun.wgsl"),
            Technique::Model => include_str!("../../../shaders/model.wgsl"),
            Technique::VertexSun => include_str!("../../../shaders/vertex_sun.wgsl"),
            Technique::Fxaa => include_str!("../../../shaders/fxaa.wgsl"),
            Technique::Reproject => include_str!("../../../shaders/reproject.wgsl"),
        }
    }
}

/// The sh9-ggx lighting method's shading, appended to the model shader (which calls it).
pub const SH9_GGX_WGSL: &str = include_str!("../../../shaders/sh9_ggx.wgsl");

/// Shared structs and helpers, prepended to every technique.
pub const FRAME_WGSL: &str = include_str!("../../../shaders/frame.wgsl");

/// The complete WGSL module for a technique. The model shader also gets the colour-correction
/// functions (`colour_correct.wgsl`, shared with the priors compute shader).
pub fn source(t: Technique) -> String {
    let own = match t {
        Technique::Model => {
            format!(
                "{FRAME_WGSL}\n{}const PREFILTER_LEVELS: f32 = {}.0;\n{}\n{}\n{SH9_GGX_WGSL}",
                super::LightingMethod::wgsl_consts(),
                crate::light::ggx::PREFILTER_LEVELS,
                crate::colour::correction::COLOUR_CORRECT_WGSL,
                t.file()
            )
        }
        Technique::VertexSun => {
            use super::pipelines::Vertex;
            let floats = |bytes: usize| bytes / std::mem::size_of::<f32>();
            format!(
                "{FRAME_WGSL}\nconst VERTEX_FLOATS: u32 = {}u;\nconst VERTEX_POSITION: u32 = {}u;\nconst VERTEX_NORMAL: u32 = {}u;\nconst SPLIT_CULL_MARGIN: f32 = {:?};\n{}",
                floats(std::mem::size_of::<Vertex>()),
                floats(std::mem::offset_of!(Vertex, position)),
                floats(std::mem::offset_of!(Vertex, normal)),
                super::passes::vertex_sun::SPLIT_CULL_MARGIN,
                t.file()
            )
        }
        Technique::Ground => format!("{FRAME_WGSL}\n{}{}", super::passes::ground::SunOnGround::wgsl_consts(), t.file()),
        Technique::EnvViewEquirect => {
            format!("{FRAME_WGSL}\nconst ENV_VIEW_TAPS: u32 = {}u;\n{}", super::passes::background::ENV_VIEW_TAPS, t.file())
        }
        _ => format!("{FRAME_WGSL}\n{}", t.file()),
    };
    crate::gpu::wgsl::with_full_screen(&own)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_parses_and_validates() {
        for t in Technique::ALL {
            crate::gpu::wgsl::validate(&source(t)).unwrap_or_else(|e| panic!("{t:?}: {e}"));
        }
    }
}
