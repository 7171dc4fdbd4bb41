// A full-screen triangle: vertex index 0..3 -> clip position, uv with (0,0) top-left. One
// triangle with vertices (-1,1), (3,1), (-1,-3) in clip space covers the viewport; draw 0..3.
// Prepended by gpu::wgsl::with_full_screen to every pass that fills its target.

struct FullScreen {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

fn full_screen(index: u32) -> FullScreen {
    var out: FullScreen;
    let x = f32((index << 1u) & 2u);
    let y = f32(index & 2u);
    out.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    out.uv = vec2<f32>(x, y);
    return out;
}
