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
                "{FRAME_WGSL}\n{}{}const PREFILTER_LEVELS: f32 = {}.0;\n{}\n{}\n{SH9_GGX_WGSL}",
                vertex_consts(),
                super::LightingMethod::wgsl_consts(),
                crate::light::ggx::PREFILTER_LEVELS,
                crate::colour::correction::COLOUR_CORRECT_WGSL,
                t.file()
            )
        }
        Technique::VertexSun => format!(
            "{FRAME_WGSL}\n{}const SPLIT_CULL_MARGIN: f32 = {:?};\n{}",
            vertex_consts(),
            super::passes::vertex_sun::SPLIT_CULL_MARGIN,
            t.file()
        ),
        Technique::Ground => format!("{FRAME_WGSL}\n{}{}", super::passes::ground::SunOnGround::wgsl_consts(), t.file()),
        Technique::EnvViewEquirect => {
            format!("{FRAME_WGSL}\nconst ENV_VIEW_TAPS: u32 = {}u;\n{}", super::passes::background::ENV_VIEW_TAPS, t.file())
        }
        _ => format!("{FRAME_WGSL}\n{}", t.file()),
    };
    crate::gpu::wgsl::with_full_screen(&own)
}

/// The model's vertex (render::pipelines::Vertex) for compute shaders that read it as floats:
/// VERTEX_FLOATS floats each, and where its fields start (VERTEX_POSITION, VERTEX_NORMAL,
/// VERTEX_AO, VERTEX_BENT, VERTEX_TINT).
fn vertex_consts() -> String {
    use super::pipelines::Vertex;
    use std::mem::{offset_of, size_of};
    let floats = |bytes: usize| bytes / size_of::<f32>();
    [
        ("FLOATS", floats(size_of::<Vertex>())),
        ("POSITION", floats(offset_of!(Vertex, position))),
        ("NORMAL", floats(offset_of!(Vertex, normal))),
        ("AO", floats(offset_of!(Vertex, ao))),
        ("BENT", floats(offset_of!(Vertex, bent))),
        ("TINT", floats(offset_of!(Vertex, tint))),
    ]
    .iter()
    .map(|(name, value)| format!("const VERTEX_{name}: u32 = {value}u;\n"))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pipeline a frame binds, with the override constants it is made with, branches on
    /// nothing that lavapipe would inline and recompile at each bind (gpu::uniform_branches:
    /// several milliseconds a frame for each such pipeline, whatever it draws;
    /// docs/PERFORMANCE.md, twenty-sixth session).
    #[test]
    fn no_pipeline_branches_on_uniform_values_alone() {
        use crate::gpu::uniform_branches::uniform_branches;
        // The technique, its vertex (or compute) and fragment (or second) entry points and its
        // override constants.
        type Pipeline<'a> = (Technique, [&'a str; 2], Vec<(&'a str, f64)>);
        let mut pipelines: Vec<Pipeline> = Vec::new();
        for method in crate::render::LightingMethod::ALL {
            for corrected in [0.0, 1.0] {
                let m = f64::from(method.shader_id());
                let kinds = [
                    (["vs_main", "fs_main"], 0.0, 0.0),
                    (["vs_main", "fs_main"], 1.0, 0.0),
                    (["vs_light", "fs_light"], 1.0, 0.0),
                    (["vs_light", "fs_light"], 1.0, 1.0),
                    (["vs_colour", "fs_colour"], 1.0, 0.0),
                    (["vs_colour", "fs_colour"], 1.0, 1.0),
                ];
                for (entries, vertex_sun, kept) in kinds {
                    pipelines.push((
                        Technique::Model,
                        entries,
                        vec![("METHOD", m), ("COLOUR_CORRECTION", corrected), ("VERTEX_SUN", vertex_sun), ("LIGHT_KEPT", kept)],
                    ));
                }
            }
        }
        pipelines.push((Technique::Model, ["vs_main", "fs_depth"], vec![("METHOD", 0.0), ("COLOUR_CORRECTION", 0.0)]));
        let sh9 = f64::from(crate::render::LightingMethod::Sh9Ggx.shader_id());
        pipelines.push((Technique::Model, ["cs_light", "cs_light"], vec![("METHOD", sh9)]));
        for sun in [0.0, 1.0, 2.0] {
            pipelines.push((Technique::Ground, ["vs_main", "fs_main"], vec![("SUN", sun)]));
        }
        for soft in [0.0, 1.0] {
            pipelines.push((Technique::VertexSun, ["main", "split"], vec![("SOFT", soft)]));
        }
        for packed in [0.0, 1.0] {
            pipelines.push((Technique::Reproject, ["vs_main", "fs_main"], vec![("PACKED", packed)]));
        }
        for t in [Technique::Background, Technique::EnvView, Technique::EnvViewEquirect, Technique::GroundSun, Technique::Fxaa] {
            pipelines.push((t, ["vs_main", "fs_main"], Vec::new()));
        }
        pipelines.push((Technique::Shadow, ["vs_main", "vs_main"], Vec::new()));
        let mut checked = 0;
        for (t, entries, constants) in &pipelines {
            let module = crate::gpu::wgsl::validate(&source(*t)).unwrap();
            for entry in entries {
                assert!(module.entry_points.iter().any(|e| e.name == *entry), "{t:?} has no entry point {entry}");
                let found = uniform_branches(&module, entry, constants);
                assert!(
                    found.is_empty(),
                    "{t:?} {entry} with {constants:?}: {}",
                    found.iter().map(|b| b.to_string()).collect::<Vec<_>>().join(", ")
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 2 * pipelines.len());
    }

    #[test]
    fn every_shader_parses_and_validates() {
        for t in Technique::ALL {
            crate::gpu::wgsl::validate(&source(t)).unwrap_or_else(|e| panic!("{t:?}: {e}"));
        }
    }
}
