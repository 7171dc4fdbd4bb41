// Background pass: the camera image (or the environment seen by the camera) fills the target.

@group(0) @binding(0) var background_tex: texture_2d<f32>;
@group(0) @binding(1) var background_smp: sampler;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    // At the far plane: drawn after the opaque model (render::compositor), the depth test keeps
    // it off the pixels the model covers.
    var out = full_screen(index);
    out.clip.z = 1.0;
    return out;
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    // The texture is sRGB-encoded; sampling an *Srgb view returns linear light.
    return vec4<f32>(textureSample(background_tex, background_smp, in.uv).rgb, 1.0);
}
