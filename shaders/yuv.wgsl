// Camera YUV 4:2:0 -> R'G'B' (gamma-encoded, as the camera's sRGB-like transfer leaves it) in one
// pass: the luma plane and the chroma plane(s) arrive as textures straight from the camera
// buffers (camera::yuv); the matrix and offsets for BT.601/BT.709, full/limited range, come in
// the uniform (camera::yuv::YuvUniforms, built by camera::yuv::ycbcr_to_rgb). The full-screen
// triangle (FullScreen, full_screen) comes from full_screen.wgsl (gpu::wgsl::with_full_screen).

struct YuvUniforms {
    // Rows of the Y'CbCr -> R'G'B' matrix (xyz), applied to (code values - offset) * scale.
    row_r: vec4<f32>,
    row_g: vec4<f32>,
    row_b: vec4<f32>,
    // Code-value offsets (Y, Cb, Cr) and scales, 8-bit units.
    offset: vec4<f32>,
    scale: vec4<f32>,
    // Channel of the chroma texture holding Cb and Cr (0 = r, 1 = g), the image size.
    cb_channel: u32,
    cr_channel: u32,
    width: u32,
    height: u32,
    // Clockwise quarter turns of the image (a camera mounted at an angle to the screen); the
    // target is the turned size. Padding to 16 bytes.
    quarter_turns: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> u: YuvUniforms;
@group(0) @binding(1) var luma: texture_2d<f32>;
@group(0) @binding(2) var chroma_cb: texture_2d<f32>;
@group(0) @binding(3) var chroma_cr: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> FullScreen {
    return full_screen(i);
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    // The source pixel of this target pixel (camera::yuv::turn_image is the CPU reference).
    let w = u.width;
    let h = u.height;
    let o = vec2<u32>(pos.xy);
    var s = o;
    switch u.quarter_turns {
        case 1u: { s = vec2<u32>(o.y, h - 1u - min(o.x, h - 1u)); }
        case 2u: { s = vec2<u32>(w - 1u - min(o.x, w - 1u), h - 1u - min(o.y, h - 1u)); }
        case 3u: { s = vec2<u32>(w - 1u - min(o.y, w - 1u), o.x); }
        default: {}
    }
    // Nearest chroma sample: pixel (x, y) uses chroma (x / 2, y / 2), as the CPU reference does.
    let xy = min(s, vec2<u32>(w - 1u, h - 1u));
    let c = xy / 2u;
    let y = textureLoad(luma, xy, 0).r;
    let cb = textureLoad(chroma_cb, c, 0)[u.cb_channel];
    let cr = textureLoad(chroma_cr, c, 0)[u.cr_channel];
    let ycc = (vec3<f32>(y, cb, cr) * 255.0 - u.offset.xyz) * u.scale.xyz;
    let rgb = vec3<f32>(dot(u.row_r.xyz, ycc), dot(u.row_g.xyz, ycc), dot(u.row_b.xyz, ycc));
    return vec4<f32>(clamp(rgb, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
}
