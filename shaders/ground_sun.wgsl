// The ground's sun visibility, drawn into a ground-space texture once per shadow map (render::
// passes::ground_sun): each texel of the rectangle baked.square (world, on the plane z =
// baked.texels.z) looks the soft shadow up as the ground pass would at that point, so that while
// the map is kept the ground pass samples the visibility once per pixel instead of looking it up
// (frame.wgsl `sun_visibility_soft`: 14 texture calls).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> light: Light;
@group(0) @binding(2) var shadow_map: texture_depth_2d;
@group(0) @binding(3) var shadow_smp: sampler_comparison;
@group(0) @binding(4) var shadow_gather_smp: sampler;
@group(0) @binding(5) var<uniform> baked: GroundSun;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    // The viewport is the texels drawn; uv 0..1 over it, row 0 at the square's min.y.
    let world = vec3<f32>(mix(baked.square.xy, baked.square.zw, in.uv), baked.texels.z);
    let visibility = sun_visibility_soft(shadow_map, shadow_smp, shadow_gather_smp, frame, world, light.sun.w);
    return vec4<f32>(visibility, 0.0, 0.0, 1.0);
}
