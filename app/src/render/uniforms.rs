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

    /// (name, size, offsets) of a struct in a naga module.
    fn naga_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        for (handle, ty) in module.types.iter() {
            if ty.name.as_deref() == Some(name)
                && let naga::TypeInner::Struct { members, span } = &ty.inner
            {
                let _ = handle;
                let offsets = members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect();
                return (*span, offsets);
            }
        }
        panic!("struct {name} not found");
    }

    fn rust_offsets<T>(fields: &[(&str, usize)]) -> (u32, Vec<(String, u32)>) {
        (std::mem::size_of::<T>() as u32, fields.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect())
    }

    #[test]
    fn layouts_match_naga() {
        let module = naga::front::wgsl::parse_str(&source(Technique::Model)).unwrap();
        use std::mem::offset_of;
        assert_eq!(
            naga_layout(&module, "Frame"),
            rust_offsets::<FrameUniforms>(&[
                ("view_proj", offset_of!(FrameUniforms, view_proj)),
                ("view", offset_of!(FrameUniforms, view)),
                ("light_view_proj", offset_of!(FrameUniforms, light_view_proj)),
                ("camera_pos", offset_of!(FrameUniforms, camera_pos)),
                ("sun", offset_of!(FrameUniforms, sun)),
                ("up", offset_of!(FrameUniforms, up)),
                ("sky", offset_of!(FrameUniforms, sky)),
                ("ground", offset_of!(FrameUniforms, ground)),
                ("env", offset_of!(FrameUniforms, env)),
                ("params", offset_of!(FrameUniforms, params)),
                ("viewport", offset_of!(FrameUniforms, viewport)),
                ("mode", offset_of!(FrameUniforms, mode)),
            ])
        );
        assert_eq!(
            naga_layout(&module, "Instance"),
            rust_offsets::<InstanceUniforms>(&[
                ("model", offset_of!(InstanceUniforms, model)),
                ("normal", offset_of!(InstanceUniforms, normal)),
            ])
        );
        assert_eq!(
            naga_layout(&module, "Material"),
            rust_offsets::<MaterialUniforms>(&[
                ("albedo", offset_of!(MaterialUniforms, albedo)),
                ("specular", offset_of!(MaterialUniforms, specular)),
                ("terms", offset_of!(MaterialUniforms, terms)),
            ])
        );
    }
}
