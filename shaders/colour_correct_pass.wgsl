// A full-screen pass that applies colour_correct to an image: the cost of the correction per
// frame, measured by `previz colour-transfer bench`, and the GPU path of the same maths the
// model shader runs. Concatenated after full_screen.wgsl and colour_correct.wgsl.
//
// The source is an Rgba8UnormSrgb texture (sampling decodes to linear light); the target is
// Rgba8UnormSrgb (the store encodes back to sRGB, clamping to 0..1).

@group(0) @binding(0) var<uniform> cc: ColourCorrection;
@group(0) @binding(1) var source_image: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

@fragment
fn fs_main(v: FullScreen) -> @location(0) vec4<f32> {
    let texel = textureLoad(source_image, vec2<i32>(v.clip.xy), 0);
    return vec4<f32>(colour_correct(texel.rgb, cc), texel.a);
}
