// Environment view: what the camera sees of the environment cube map at its orientation. Used
// as the background when no photograph is given, so a composite works from an environment alone.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var env_tex: texture_cube<f32>;
@group(0) @binding(2) var env_smp: sampler;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

// Camera-space ray through a pixel (uv (0,0) = top-left), then world space.
fn view_ray_world(uv: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let d_cam = vec3<f32>(ndc.x * frame.tan_half_vfov * frame.aspect, ndc.y * frame.tan_half_vfov, -1.0);
    // view is a rigid transform: its rotation's transpose maps camera -> world.
    let r = mat3x3<f32>(frame.view[0].xyz, frame.view[1].xyz, frame.view[2].xyz);
    return normalize(transpose(r) * d_cam);
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    let d = view_ray_world(in.uv);
    let c = textureSampleLevel(env_tex, env_smp, env_dir(frame, d), 0.0).rgb * frame.env_exposure;
    return vec4<f32>(c, 1.0);
}
