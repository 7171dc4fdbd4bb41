// Reprojection pass (render::reprojection): a live frame whose camera only turned since the last
// shaded frame composes that frame's model and ground layers with its own camera image. Drawn
// over the hull of what the layers hold (pixels of this frame, through the homography's
// inverse) at depth 0.5; the background pass after it fills the rest at the far plane.
//
// Each pixel reads the layer texel under it (the homography takes this frame's pixel to the
// layers' pixel plane; nearest texel, at most half a pixel away) and composes as the frame
// does: the model premultiplied over the background darkened by the ground.
//
// PACKED (one sample a pixel): one layer holds both, in the frame's colour format: where the
// model covers the pixel its colour with alpha 1, elsewhere the ground's matte times the
// layer's clear value (warp.matte_scale.x is its reciprocal) with alpha 0. Otherwise (multisampled) the model layer holds the model premultiplied, alpha its
// coverage, and the matte layer, per channel, what the ground leaves of the background where
// the model does not cover the sample and 1 where it does, resolved: less the coverage it is
// the matte over the uncovered samples alone.
override PACKED: bool = false;

struct Reproject {
    to_layer: mat3x3<f32>,
    // This frame's size in pixels (x, y), the layers' (z, w).
    size: vec4<f32>,
    // x: the reciprocal of the packed layer's clear value (the matte 1); yzw unused.
    matte_scale: vec4<f32>,
};

@group(0) @binding(0) var background_tex: texture_2d<f32>;
@group(0) @binding(1) var model_layer: texture_2d<f32>;
@group(0) @binding(2) var matte_layer: texture_2d<f32>;
@group(0) @binding(3) var<uniform> warp: Reproject;

struct Warped {
    @builtin(position) clip: vec4<f32>,
    // The layers' homogeneous pixel: the homography is linear in this frame's pixel, so it is
    // interpolated in screen space (no perspective), exactly.
    @location(0) @interpolate(linear) layer: vec3<f32>,
};

@vertex
fn vs_main(@location(0) pixel: vec2<f32>) -> Warped {
    var out: Warped;
    out.clip = vec4<f32>(pixel.x / warp.size.x * 2.0 - 1.0, 1.0 - pixel.y / warp.size.y * 2.0, 0.5, 1.0);
    out.layer = warp.to_layer * vec3<f32>(pixel, 1.0);
    return out;
}

@fragment
fn fs_main(in: Warped) -> @location(0) vec4<f32> {
    // The camera image is the target's size: each pixel its own texel (background.wgsl).
    let background = textureLoad(background_tex, vec2<i32>(in.clip.xy), 0).rgb;
    let last = vec2<i32>(warp.size.zw) - vec2<i32>(1);
    let texel = clamp(vec2<i32>(floor(in.layer.xy / max(in.layer.z, 1e-6))), vec2<i32>(0), last);
    let model = textureLoad(model_layer, texel, 0);
    if (PACKED) {
        return vec4<f32>(mix(background * model.rgb * warp.matte_scale.x, model.rgb, model.a), 1.0);
    }
    let matte = textureLoad(matte_layer, texel, 0).rgb;
    return vec4<f32>(model.rgb + background * max(matte - vec3<f32>(model.a), vec3<f32>(0.0)), 1.0);
}
