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
    pub camera_pos: [f32; 3],
    pub daylight: f32,
    pub sun_dir: [f32; 3],
    pub sunlight: f32,
    pub sky: [f32; 3],
    pub occlusion_light: f32,
    pub ground: [f32; 3],
    pub occlusion_shadow: f32,
    pub env_rotation: [f32; 2],
    pub env_exposure: f32,
    pub reflection: f32,
    pub eta: f32,
    pub shadow_opacity: f32,
    pub live_depth: f32,
    pub tan_half_vfov: f32,
    pub aspect: f32,
    pub shadow_map_size: u32,
    pub _padding: [u32; 2],
}

/// Mirrors `struct Instance` in shaders/frame.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct InstanceUniforms {
    pub model: [[f32; 4]; 4],
    pub normal: [[f32; 4]; 4],
}

/// Mirrors `struct Light` in shaders/frame.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LightUniforms {
    pub sh: [[f32; 4]; 9],
    pub sun: [f32; 4],
    pub ground_square: [f32; 4],
    pub ground_sky: [f32; 4],
    pub ground: [f32; 4],
}

/// Mirrors `struct GroundSun` in shaders/frame.wgsl: the rectangle and texels of the ground's
/// sun visibility as last drawn (render::passes::ground_sun).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GroundSunUniforms {
    pub square: [f32; 4],
    pub texels: [f32; 4],
}

/// Mirrors `struct Material` in shaders/model.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MaterialUniforms {
    pub albedo: [f32; 4],
    pub specular: [f32; 4],
    pub terms: [f32; 4],
}

/// Mirrors `struct SplitLevel` in shaders/vertex_sun.wgsl: where a level's triangles are in a
/// mesh's index buffer, and where the second list of the split starts.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SplitLevelUniforms {
    pub first: u32,
    pub count: u32,
    pub second: u32,
    pub unused: u32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::shaders::{Technique, source};

    #[test]
    fn the_vertex_ao_bent_sun_and_light_attributes_are_at_their_named_locations() {
        let module = crate::gpu::wgsl::validate(&source(Technique::Model)).unwrap();
        let ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("VertexIn")).expect("struct VertexIn").1;
        let naga::TypeInner::Struct { members, .. } = &ty.inner else { panic!("VertexIn is not a struct") };
        use crate::render::pipelines::{AO_LOCATION, BENT_LOCATION, SUN_LOCATION, TINT_LOCATION};
        for (name, at) in [("ao", AO_LOCATION), ("bent", BENT_LOCATION), ("sun", SUN_LOCATION), ("tint", TINT_LOCATION)] {
            let m = members.iter().find(|m| m.name.as_deref() == Some(name)).expect(name);
            assert!(matches!(m.binding, Some(naga::Binding::Location { location, .. }) if location == at), "{name}: {:?}", m.binding);
        }
        let ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("LightIn")).expect("struct LightIn").1;
        let naga::TypeInner::Struct { members, .. } = &ty.inner else { panic!("LightIn is not a struct") };
        use crate::render::pipelines::{LIGHT_LOCATION, LIGHT_SPECULAR_LOCATION};
        for (name, at) in [("lit", LIGHT_LOCATION), ("specular", LIGHT_SPECULAR_LOCATION)] {
            let m = members.iter().find(|m| m.name.as_deref() == Some(name)).expect(name);
            assert!(matches!(m.binding, Some(naga::Binding::Location { location, .. }) if location == at), "{name}: {:?}", m.binding);
        }
    }

    #[test]
    fn layouts_match_naga() {
        let module = crate::gpu::wgsl::validate(&source(Technique::Model)).unwrap();
        crate::assert_wgsl_layout!(
            module,
            FrameUniforms,
            "Frame",
            [
                view_proj,
                view,
                light_view_proj,
                camera_pos,
                daylight,
                sun_dir,
                sunlight,
                sky,
                occlusion_light,
                ground,
                occlusion_shadow,
                env_rotation,
                env_exposure,
                reflection,
                eta,
                shadow_opacity,
                live_depth,
                tan_half_vfov,
                aspect,
                shadow_map_size,
                _padding
            ]
        );
        crate::assert_wgsl_layout!(module, InstanceUniforms, "Instance", [model, normal]);
        crate::assert_wgsl_layout!(module, LightUniforms, "Light", [sh, sun, ground_square, ground_sky, ground]);
        crate::assert_wgsl_layout!(module, MaterialUniforms, "Material", [albedo, specular, terms]);
        let module = crate::gpu::wgsl::validate(&source(Technique::GroundSun)).unwrap();
        crate::assert_wgsl_layout!(module, GroundSunUniforms, "GroundSun", [square, texels]);
        let module = crate::gpu::wgsl::validate(&source(Technique::VertexSun)).unwrap();
        crate::assert_wgsl_layout!(module, SplitLevelUniforms, "SplitLevel", [first, count, second, unused]);
        let module = crate::gpu::wgsl::validate(&source(Technique::Reproject)).unwrap();
        crate::assert_wgsl_layout!(module, crate::render::reprojection::ReprojectUniforms, "Reproject", [to_layer, size, matte_scale]);
    }
}
