// Ground pass: an invisible shadow-catcher plane under the model. It darkens the background
// where the model shadows the sun or hides the sky, brightens it where the model reflects light
// onto it (differential rendering: the ground's light with the model over its light without),
// and leaves it untouched elsewhere. The output is half the factor the ground's light changes by
// per channel; the pipeline multiplies the background by twice that (render::passes::ground
// SCALE), so a shadow keeps the colour of the light left in it.
//
// SUN is a pipeline-override constant: the ground is drawn in two parts that do not overlap
// (render::frame::ground_mesh), where the sun's shadow can fall with its visibility (SUN_LOOKUP:
// looked up in the shadow map; SUN_BAKED: sampled from the ground-space texture the ground-sun
// pass drew from the same map, render::passes::ground_sun) and the rest without it (SUN_NONE:
// nothing of either compiled in; lavapipe runs every branch of a runtime test, so only leaving
// the code out saves its cost there).
// (SUN_NONE, SUN_LOOKUP, SUN_BAKED: prepended from render::passes::ground::SunOnGround.)
override SUN: u32 = SUN_LOOKUP;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> plane: Instance;
@group(0) @binding(2) var shadow_map: texture_depth_2d;
@group(0) @binding(3) var shadow_smp: sampler_comparison;
@group(0) @binding(4) var<uniform> light: Light;
// Layer 0, rgb: the share of each channel of the sky's (cosine-weighted) light the ground sees
// past the model; layer 1, rgb: the light the model reflects onto it, a gain on the ground's
// light per channel; over light.ground_square (written once per placement and light from
// scene::occlusion::GroundTransfer::map, render::passes::ground::ground_texels); layer 2, rgb:
// 1 minus the factor they give with no sun lost (render::passes::ground::sky_only_texels).
@group(0) @binding(5) var ground_sky: texture_2d_array<f32>;
@group(0) @binding(6) var ground_sky_smp: sampler;
// The shadow map's depths without comparison, nearest texel (the soft shadow's blocker search).
@group(0) @binding(7) var shadow_gather_smp: sampler;
// The sun's visibility on the ground as the ground-sun pass last drew it (SUN_BAKED), over
// ground_sun.square: texels (0, 0)..ground_sun.texels.xy of a ground_sun.texels.w² texture.
@group(0) @binding(8) var<uniform> ground_sun: GroundSun;
@group(0) @binding(9) var ground_sun_map: texture_2d<f32>;

struct GroundOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
};

@vertex
fn vs_main(@location(0) corner: vec2<f32>) -> GroundOut {
    // Triangles inside the unit square [-1, 1]^2 at z = 0 (render::frame::GroundMesh), placed by
    // plane.model on the ground quad.
    let world = plane.model * vec4<f32>(corner, 0.0, 1.0);
    var out: GroundOut;
    out.world = world.xyz;
    out.clip = frame.view_proj * world;
    return out;
}

// Seen from below (the camera under the plane) there is no ground to shadow: the factor 1.
// Chosen with select, as every choice here that depends on uniforms alone: lavapipe recompiles
// a shader that branches on them at each bind (gpu::uniform_branches).
@fragment
fn fs_main(in: GroundOut) -> @location(0) vec4<f32> {
    let below = frame.camera_pos.z <= plane.model[3].z;
    return select(ground_factor(in), vec4<f32>(0.5), below);
}

fn ground_factor(in: GroundOut) -> vec4<f32> {
    // The model hides part of the sky: the sky's share of the ground's light times the share of
    // the (cosine-weighted) sky hidden here. Outside the square the sky is whole.
    let square = light.ground_square;
    let uv = (in.world.xy - square.xy) / max(square.zw - square.xy, vec2<f32>(1e-6));
    let inside = all(uv >= vec2<f32>(0.0)) && all(uv <= vec2<f32>(1.0));
    if (SUN == SUN_NONE) {
        // Where the sun's shadow is not looked up, the map's third layer holds 1 minus the
        // factor below with no sun lost (render::passes::ground::sky_only_texels): one sample.
        var lost = vec3<f32>(0.0);
        if (inside) {
            lost = textureSampleLevel(ground_sky, ground_sky_smp, uv, 2, 0.0).rgb;
        }
        return vec4<f32>(0.5 * (1.0 - lost), 0.0);
    }
    // The sun's shadow removes the sun's share of the ground's light: shadow_opacity is that
    // share (measured from the environment by setup::light), none when there is no sunlight.
    // The pipelines that look the sun up are drawn only where the sun's shadow can fall (the
    // full-shadow reference excepted), so the lookup is made and its loss kept where it counts.
    var visibility: f32;
    if (SUN == SUN_BAKED) {
        visibility = baked_sun(in.world.xy);
    } else {
        visibility = sun_visibility_soft(shadow_map, shadow_smp, shadow_gather_smp, frame, in.world, light.sun.w);
    }
    let shadowed = (frame.sun_dir.z > 0.0) & (frame.sunlight > 0.0) & (frame.shadow_opacity > 0.0);
    let sun_lost = select(0.0, frame.shadow_opacity * (1.0 - visibility), shadowed);
    var sky_seen = vec3<f32>(1.0);
    var bounce = vec3<f32>(0.0);
    if (inside) {
        sky_seen = textureSampleLevel(ground_sky, ground_sky_smp, uv, 0, 0.0).rgb;
        bounce = textureSampleLevel(ground_sky, ground_sky_smp, uv, 1, 0.0).rgb;
    }
    let sky_lost = light.ground_sky.x * (vec3<f32>(1.0) - sky_seen);
    return vec4<f32>(0.5 * (1.0 - ground_loss(sun_lost, sky_lost) + bounce), 0.0);
}

// The baked visibility at world xy: a bilinear sample between the centres of the texels drawn
// (clamped to them: the texture beyond holds an older bake).
fn baked_sun(xy: vec2<f32>) -> f32 {
    let size = max(ground_sun.square.zw - ground_sun.square.xy, vec2<f32>(1e-6));
    let drawn = ground_sun.texels.xy;
    let t = clamp((xy - ground_sun.square.xy) / size * drawn, vec2<f32>(0.5), drawn - vec2<f32>(0.5));
    return textureSampleLevel(ground_sun_map, ground_sky_smp, t / ground_sun.texels.w, 0.0).r;
}

// What the ground loses per channel when it loses `sun_lost` of its light's luminance to the
// sun's shadow and, per channel, `sky_lost` of the sky's light in units of the sky's luminance
// share (the share times the part of that channel of the sky the model hides). The ground's
// light is the sun's, in the sun's colour (light.sun.rgb), and the sky's, in the sky's colour
// on the ground (light.ground_sky.yzw), each of luminance 1; their luminance shares are
// frame.shadow_opacity : light.ground_sky.x. Per channel each loses its own share, so a shadow
// out of a warm sun under a blue sky is blue, and one that hides the warm sky round a low sun
// is bluer still (issue 9: the shadow's colour).
fn ground_loss(sun_lost: f32, sky_lost: vec3<f32>) -> vec3<f32> {
    let sun_share = frame.shadow_opacity;
    let sky_share = light.ground_sky.x;
    let total = sun_share + sky_share;
    let sun_colour = light.sun.rgb;
    let sky_colour = light.ground_sky.yzw;
    // The ground's light per channel, luminance 1 (shares normalised); nothing lost without light.
    let light_rgb = (sun_share * sun_colour + sky_share * sky_colour) / max(total, 1e-30);
    let lost = (sun_lost * sun_colour + sky_lost * sky_colour) / max(light_rgb, vec3<f32>(1e-6));
    return select(clamp(lost, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(0.0), total <= 0.0);
}
