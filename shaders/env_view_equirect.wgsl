// Environment view of an equirectangular map: what the camera sees of the environment, looked
// up in the image it was loaded from, not through the cube map (a second resampling that blurs
// it). The background when no photograph is given.
//
// The lookup is scene::environment's convention (Equirect::sample_uv, enu_to_equirect_uv): the
// centre column faces the environment's heading, azimuth grows to the right, the top row is the
// zenith; texel (i, j) is centred on u = (i + ½)/W, v = (j + ½)/H, bilinear, wrapping around in
// u and clamped at the poles (the sampler's address modes). Each pixel averages
// ENV_VIEW_TAPS × ENV_VIEW_TAPS lookups spread evenly over its area (a box filter, as the
// path-traced references' pixels are); the constant is declared in render::passes::background.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var env_tex: texture_2d<f32>;
@group(0) @binding(2) var env_smp: sampler;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

// Equirectangular (u, v) of a world direction, the map's centre column at the environment's
// heading: u = 0.5 + (azimuth - heading)/2pi, v = 0.5 - elevation/pi.
fn equirect_uv(d: vec3<f32>) -> vec2<f32> {
    // env_dir turns azimuths by -heading and swaps to cube space (x, z, y).
    let c = env_dir(frame, d);
    let azimuth = atan2(c.x, c.z);
    let elevation = atan2(c.y, length(c.xz));
    return vec2<f32>(0.5 + azimuth / 6.283185307179586, 0.5 - elevation / 3.141592653589793);
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    // One pixel's extent in uv: the full-screen triangle's uv is linear in the pixel position.
    let step_x = dpdx(in.uv);
    let step_y = dpdy(in.uv);
    var sum = vec3<f32>(0.0);
    for (var j = 0u; j < ENV_VIEW_TAPS; j++) {
        for (var i = 0u; i < ENV_VIEW_TAPS; i++) {
            let offset = (vec2<f32>(f32(i), f32(j)) + 0.5) / f32(ENV_VIEW_TAPS) - 0.5;
            let uv = in.uv + offset.x * step_x + offset.y * step_y;
            sum += textureSampleLevel(env_tex, env_smp, equirect_uv(view_ray_world(frame, uv)), 0.0).rgb;
        }
    }
    let n = f32(ENV_VIEW_TAPS * ENV_VIEW_TAPS);
    return vec4<f32>(sum / n * frame.env_exposure, 1.0);
}
