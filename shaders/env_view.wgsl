// Environment view: what the camera sees of the environment cube map at its orientation. Used
// as the background when no photograph is given, so a composite works from an environment alone.
// An environment loaded from an equirectangular image is seen through env_view_equirect.wgsl.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var env_tex: texture_cube<f32>;
@group(0) @binding(2) var env_smp: sampler;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    let d = view_ray_world(frame, in.uv);
    let c = textureSampleLevel(env_tex, env_smp, env_dir(frame, d), 0.0).rgb * frame.env_exposure;
    return vec4<f32>(c, 1.0);
}
