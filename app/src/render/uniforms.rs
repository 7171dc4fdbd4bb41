//! Uniform structs shared with the WGSL, mirrored once here. `tests::layouts_match_naga` checks
//! each struct's size and member offsets against naga's reflection of the shader source.

use bytemuck::{Pod, Zeroable};

/// Mirrors `struct Frame` in shaders/frame.wgsl (field meanings documented there).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub view_proj: [[f32; 4]; 4],
    pub view: [[f32; 4]; 4],
    pub light_view_proj: [[f32; 4]; 4],
    pub camera_pos: [f32; 4],
    pub sun: [f32; 4],
    pub up: [f32; 4],
    pub sky: [f32; 4],
    pub ground: [f32; 4],
    pub env: [f32; 4],
    pub params: [f32; 4],
    pub viewport: [f32; 4],
    pub mode: [u32; 4],
}

/// Mirrors `struct Instance` in shaders/frame.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct InstanceUniforms {
    pub model: [[f32; 4]; 4],
    pub normal: [[f32; 4]; 4],
}

/// Mirrors `struct Material` in shaders/model.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MaterialUniforms {
    pub albedo: [f32; 4],
    pub specular: [f32; 4],
    pub terms: [f32; 4],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::shaders::{Technique, source};

    #[test]
    fn layouts_match_naga() {
        let module = crate::gpu::wgsl::validate(&source(Technique::Model)).unwrap();
        crate::assert_wgsl_layout!(
            module,
            FrameUniforms,
            "Frame",
            [view_proj, view, light_view_proj, camera_pos, sun, up, sky, ground, env, params, viewport, mode]
        );
        crate::assert_wgsl_layout!(module, InstanceUniforms, "Instance", [model, normal]);
        crate::assert_wgsl_layout!(module, MaterialUniforms, "Material", [albedo, specular, terms]);
    }
}
