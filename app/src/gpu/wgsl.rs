//! WGSL shared by every layer: the full-screen triangle, validation with naga, and the check
//! that a `#[repr(C)]` Rust mirror of a WGSL struct has the same size and member offsets.

use anyhow::{Result, anyhow, bail};

/// `struct FullScreen` and `fn full_screen(vertex_index)`: the one full-screen triangle.
pub const FULL_SCREEN_WGSL: &str = include_str!("../../../shaders/full_screen.wgsl");

/// `source` with the full-screen triangle in front of it.
pub fn with_full_screen(source: &str) -> String {
    format!("{FULL_SCREEN_WGSL}\n{source}")
}

/// Parse and validate a WGSL module with naga (every validation flag and capability), the error
/// rendered against the source.
pub fn validate(source: &str) -> Result<naga::Module> {
    let module = naga::front::wgsl::parse_str(source).map_err(|e| anyhow!("{}", e.emit_to_string(source)))?;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| anyhow!("{}", e.emit_to_string(source)))?;
    Ok(module)
}

/// Compare struct `name` of `module` with a Rust mirror of `size` bytes whose fields, in order,
/// are `(name, offset)`. Use it through [`assert_wgsl_layout!`](crate::assert_wgsl_layout).
pub fn check_struct_layout(module: &naga::Module, name: &str, size: usize, fields: &[(&str, usize)]) -> Result<()> {
    let Some((members, span)) = module.types.iter().find_map(|(_, ty)| match &ty.inner {
        naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(name) => Some((members, *span)),
        _ => None,
    }) else {
        bail!("the WGSL has no struct {name}");
    };
    let wgsl: Vec<(&str, usize)> = members.iter().map(|m| (m.name.as_deref().unwrap_or(""), m.offset as usize)).collect();
    if wgsl != fields || span as usize != size {
        bail!("struct {name}: WGSL is {span} bytes with {wgsl:?}, the Rust mirror {size} bytes with {fields:?}");
    }
    Ok(())
}

/// Assert that `$ty` mirrors WGSL struct `$name` in the naga module `$module`, field by field:
/// `assert_wgsl_layout!(module, FrameUniforms, "Frame", [view_proj, view, ...])`.
#[macro_export]
macro_rules! assert_wgsl_layout {
    ($module:expr, $ty:ty, $name:literal, [$($field:ident),* $(,)?]) => {
        $crate::gpu::wgsl::check_struct_layout(
            &$module,
            $name,
            ::std::mem::size_of::<$ty>(),
            &[$((stringify!($field), ::std::mem::offset_of!($ty, $field))),*],
        )
        .unwrap_or_else(|e| panic!("{e:#}"))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_screen_triangle_covers_the_viewport() {
        // Vertex i: x = (i << 1) & 2, y = i & 2 -> clip (-1, 1), (3, 1), (-1, -3), uv (0,0),
        // (2,0), (0,2): the triangle contains the square [-1, 1]², uv (0,0) at its top-left.
        let clip = |i: u32| {
            let (x, y) = (((i << 1) & 2) as f32, (i & 2) as f32);
            (x * 2.0 - 1.0, 1.0 - y * 2.0)
        };
        assert_eq!([clip(0), clip(1), clip(2)], [(-1.0, 1.0), (3.0, 1.0), (-1.0, -3.0)]);
        // The WGSL does the same arithmetic (checked textually: the two lines below are in it).
        assert!(FULL_SCREEN_WGSL.contains("let x = f32((index << 1u) & 2u);"));
        assert!(FULL_SCREEN_WGSL.contains("out.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);"));
        validate(&with_full_screen("@vertex fn vs_main(@builtin(vertex_index) i: u32) -> FullScreen { return full_screen(i); }")).unwrap();
    }

    #[allow(dead_code)] // only its layout is used
    #[repr(C)]
    struct Good {
        a: [f32; 3],
        b: f32,
        c: [f32; 4],
    }

    #[allow(dead_code)]
    #[repr(C)]
    struct Bad {
        a: [f32; 3],
        b: f32,
        c: [f32; 2],
    }

    #[test]
    fn layout_check_accepts_a_mirror_and_rejects_a_wrong_one() {
        // WGSL layout rules: vec3<f32> has size 12, so a following f32 packs at 12; vec4 at 16.
        let module = validate("struct S { a: vec3<f32>, b: f32, c: vec4<f32> }; @group(0) @binding(0) var<uniform> s: S;").unwrap();
        crate::assert_wgsl_layout!(module, Good, "S", [a, b, c]);
        let err = check_struct_layout(&module, "S", std::mem::size_of::<Bad>(), &[("a", 0), ("b", 12), ("c", 16)]).unwrap_err();
        assert!(err.to_string().contains("24 bytes"), "{err}");
        assert!(check_struct_layout(&module, "S", 32, &[("a", 0), ("c", 12), ("b", 16)]).is_err());
        assert!(check_struct_layout(&module, "T", 32, &[]).is_err());
        assert!(validate("fn broken( {").is_err());
    }
}
