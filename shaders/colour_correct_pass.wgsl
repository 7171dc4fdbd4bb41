// A full-screen pass that applies colour_correct to an image: the cost of the correction per
// frame, measured by `previz colour-transfer bench`, and the GPU path of the same maths the
// model shader runs. Concatenated after colour_correct.wgsl.
//
// The source is an Rgba8UnormSrgb texture (sampling decodes to linear light); the target is
// Rgba8UnormSrgb (the store encodes back to sRGB, clamping to 0..1).

@group(0) @binding(0) var<uniform> cc: ColourCorrection;
@group(0) @binding(1) var source_image: texture_2d<f32>;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
}

// One triangle that covers the viewport: vertices (-1,-1), (3,-1), (-1,3).
@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> VertexOut {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return VertexOut(vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0));
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    let texel = textureLoad(source_image, vec2<i32>(v.position.xy), 0);
    return vec4<f32>(colour_correct(texel.rgb, cc), texel.a);
}
