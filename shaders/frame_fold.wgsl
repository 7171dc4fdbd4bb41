// Fold the live camera frame into an approximate cube map around the model (seed 004, after
// Ropinski, Wachenfeld & Hinrichs 2004, "Virtual Reflections for Augmented Reality
// Environments"). One draw per cube layer; every texel finds its source in the frame:
//
//   world direction (cube convention) -> camera frame -> the fold's face in camera axes:
//   - away from the camera (behind the model): the model's screen-space bounding box;
//   - right / left / up / down: the four quads between that box and the rectangle through the
//     midpoints of box corner -> image corner (bilinear, so no triangle seam);
//   - towards the camera: the image border outside the midpoint rectangle, folded inwards so
//     that the image edge closes in the middle of the face.
//
// The CPU reference is `fold_uv` in app/src/capture/frame_fold.rs; keep the two in step.

struct FoldUniforms {
    // World (ENU) -> camera rotation (columns).
    world_to_camera: mat3x3<f32>,
    // Corrected bounding box and midpoint rectangle in image uv: (u0, v0, u1, v1), v0 = top.
    inner: vec4<f32>,
    outer: vec4<f32>,
    // x = cube face size in texels.
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: FoldUniforms;
@group(0) @binding(1) var frame_tex: texture_2d<f32>;
@group(0) @binding(2) var frame_sampler: sampler;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) @interpolate(flat) layer: u32,
};

// The full-screen triangle (full_screen.wgsl, prepended); the instance index is the cube layer.
@vertex
fn vs_main(@builtin(vertex_index) vi: u32, @builtin(instance_index) layer: u32) -> VsOut {
    return VsOut(full_screen(vi).clip, layer);
}

// Vulkan cube-face table (app/src/scene/cubemap.rs face_uv_to_cube_dir).
fn face_uv_to_cube_dir(face: u32, uv: vec2<f32>) -> vec3<f32> {
    let sc = 2.0 * uv.x - 1.0;
    let tc = 2.0 * uv.y - 1.0;
    var d: vec3<f32>;
    switch face {
        case 0u: { d = vec3<f32>(1.0, -tc, -sc); }
        case 1u: { d = vec3<f32>(-1.0, -tc, sc); }
        case 2u: { d = vec3<f32>(sc, 1.0, tc); }
        case 3u: { d = vec3<f32>(sc, -1.0, -tc); }
        case 4u: { d = vec3<f32>(sc, -tc, 1.0); }
        default: { d = vec3<f32>(-sc, -tc, -1.0); }
    }
    return normalize(d);
}

// Cube space -> ENU (app/src/scene/mod.rs cube_to_enu: the y/z swap).
fn cube_to_enu(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(c.x, c.z, c.y);
}

// A point of box b at s (−1 left .. 1 right) and t (−1 bottom .. 1 top).
fn box_point(b: vec4<f32>, s: f32, t: f32) -> vec2<f32> {
    return vec2<f32>(mix(b.x, b.z, 0.5 * (s + 1.0)), mix(b.w, b.y, 0.5 * (t + 1.0)));
}

fn fold_uv(c: vec3<f32>) -> vec2<f32> {
    let x = c.x;
    let y = c.y;
    let f = -c.z;
    let a = abs(vec3<f32>(x, y, f));
    if (f >= a.x && f >= a.y) {
        return box_point(u.inner, x / f, y / f);
    }
    if (-f >= a.x && -f >= a.y) {
        let p = vec2<f32>(x, y) / a.z;
        let r = max(abs(p.x), abs(p.y));
        // Straight at the camera the whole border meets; pick its top.
        let b = select(p / max(r, 1e-6), vec2<f32>(0.0, 1.0), r < 1e-6);
        let border = box_point(vec4<f32>(0.0, 0.0, 1.0, 1.0), b.x, b.y);
        let mid = box_point(u.outer, b.x, b.y);
        return mix(border, mid, r);
    }
    if (a.x >= a.y) {
        let side = sign(x);
        let t = y / a.x;
        let w = f / a.x;
        return mix(box_point(u.inner, side, t), box_point(u.outer, side, t), 0.5 * (1.0 - w));
    }
    let side = sign(y);
    let s = x / a.y;
    let w = f / a.y;
    return mix(box_point(u.inner, s, side), box_point(u.outer, s, side), 0.5 * (1.0 - w));
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let uv_face = in.pos.xy / u.params.x;
    let d = cube_to_enu(face_uv_to_cube_dir(in.layer, uv_face));
    let uv = fold_uv(u.world_to_camera * d);
    // The frame texture is sRGB: sampling returns linear light.
    let c = textureSampleLevel(frame_tex, frame_sampler, uv, 0.0);
    return vec4<f32>(c.rgb, 1.0);
}
