// Background pass: the camera image (or the environment seen by the camera) fills the target.
// The background texture is the target's size (render::passes::background), so each pixel reads
// its own texel with textureLoad: the value a filtered sample at the texel's centre gives (the
// same bytes), without the filter's four reads and weights: 21-24 % off the background-only
// frame on lavapipe (docs/PERFORMANCE.md, eleventh session).

@group(0) @binding(0) var background_tex: texture_2d<f32>;

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
    // The texture is sRGB-encoded; loading from an *Srgb view returns linear light. The
    // fragment's position is the pixel's centre, whose integer part is the texel.
    return vec4<f32>(textureLoad(background_tex, vec2<i32>(in.clip.xy), 0).rgb, 1.0);
}
