// Shared structs and helpers for every Previz pass. Each technique file is appended to this one
// (see render::shaders); the Rust mirrors live in app/src/render/uniforms.rs and a test checks
// their layout against naga's.
//
// Frames: world = ENU (+x East, +y North, +z Up), metres. Cube-map sampling directions are
// world directions passed through enu_to_cube (the one convention, also in scene::enu_to_cube).

struct Frame {
    // world -> clip of the camera
    view_proj: mat4x4<f32>,
    // world -> camera (view space: +x right, +y up, looking along -z)
    view: mat4x4<f32>,
    // world -> clip of the sun's orthographic shadow camera (wgpu depth 0..1)
    light_view_proj: mat4x4<f32>,
    // camera position in world space
    camera_pos: vec3<f32>,
    // daylight (ambient) intensity l_d
    daylight: f32,
    // unit direction to the sun (world)
    sun_dir: vec3<f32>,
    // sunlight intensity l_s (0 below the horizon)
    sunlight: f32,
    // upper hemisphere (sky) colour, linear
    sky: vec3<f32>,
    // hemisphere-occlusion light level
    occlusion_light: f32,
    // lower hemisphere (ground) colour, linear
    ground: vec3<f32>,
    // hemisphere-occlusion shadow level
    occlusion_shadow: f32,
    // (cos, sin) of the environment's heading rotation
    env_rotation: vec2<f32>,
    // environment exposure (linear scale)
    env_exposure: f32,
    // mix of the reflection into the model, 0..1
    reflection: f32,
    // relative refractive index (eta = n_outside / n_inside)
    eta: f32,
    // how dark the model's shadow makes the ground, 0..1
    shadow_opacity: f32,
    // live-feed refraction: how far behind the surface the refracted ray meets the scene (m)
    live_depth: f32,
    // tan(vfov / 2) and width / height of the target
    tan_half_vfov: f32,
    aspect: f32,
    // side of the square shadow map in texels
    shadow_map_size: u32,
    // the struct's size is a multiple of 16 bytes (its alignment); the Rust mirror says so too
    _padding: vec2<u32>,
};

// One model instance: model space -> world, and its normal matrix (inverse transpose, 3x3 in a 4x4).
struct Instance {
    model: mat4x4<f32>,
    normal: mat4x4<f32>,
};

// ENU -> cube sampling space, after rotating the environment by its heading about Up.
fn env_dir(frame: Frame, d: vec3<f32>) -> vec3<f32> {
    let c = frame.env_rotation.x;
    let s = frame.env_rotation.y;
    // Rotate azimuths by -heading: the world direction at the environment heading samples the
    // cube map front (+Z, North in an unrotated map).
    let r = vec3<f32>(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
    return vec3<f32>(r.x, r.z, r.y);
}

// World direction of the camera ray through a point of the target (uv (0,0) = top-left).
fn view_ray_world(frame: Frame, uv: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let d_cam = vec3<f32>(ndc.x * frame.tan_half_vfov * frame.aspect, ndc.y * frame.tan_half_vfov, -1.0);
    // view is a rigid transform: its rotation's transpose maps camera -> world.
    let r = mat3x3<f32>(frame.view[0].xyz, frame.view[1].xyz, frame.view[2].xyz);
    return normalize(transpose(r) * d_cam);
}

// Fraction of sunlight reaching world point p (1 = lit): 2x2 bilinear comparison taps half a
// texel either side of p, a filter 3 texels wide (it was 3x3 taps a texel apart, 4 wide: the
// five taps less took 0.3-1 ms off the live truck's 11-12 ms model pass on lavapipe, at a mean
// FLIP of 1e-4 between the two; docs/PERFORMANCE.md, eighth session).
// Points outside the shadow camera's footprint are lit: every occluder (the model) is inside it.
fn sun_visibility(map: texture_depth_2d, smp: sampler_comparison, frame: Frame, p: vec3<f32>) -> f32 {
    let clip = frame.light_view_proj * vec4<f32>(p, 1.0);
    let ndc = clip.xyz / clip.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    if (any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0))) {
        return 1.0;
    }
    // Receivers beyond the far plane (the ground far behind the model) compare as depth 1.
    let depth = min(ndc.z, 1.0) - 0.002;
    let texel = 1.0 / f32(frame.shadow_map_size);
    var lit = 0.0;
    for (var y = 0; y < 2; y++) {
        for (var x = 0; x < 2; x++) {
            let o = (vec2<f32>(f32(x), f32(y)) - 0.5) * texel;
            lit += textureSampleCompareLevel(map, smp, uv + o, depth);
        }
    }
    return lit / 4.0;
}

// Light measured from the environment (setup::light), for the sh9-ggx method and the soft
// ground shadow. Rust mirror: render::uniforms::LightUniforms.
struct Light {
    // Sky without the sun as SH9 irradiance over pi per unit of frame.daylight (rgb;
    // coefficients already multiplied by the clamped-cosine factors A_l / pi), in the map's own
    // ENU frame (before its heading): daylight * sum_i sh[i] Y_i(n) is what a white Lambertian
    // surface facing n reflects.
    sh: array<vec4<f32>, 9>,
    // rgb: the sun's colour (luminance 1; frame.sunlight scales it); w: tangent of the sun's
    // angular radius.
    sun: vec4<f32>,
    // The ground square of the ground pass's sky-visibility map (scene::occlusion::ground_square):
    // world (min.x, min.y, max.x, max.y); texel row 0 at min.y.
    ground_square: vec4<f32>,
    // x: how dark the ground gets where the model hides all of its sky (the sky's share of its
    // light, render::Lighting::sky_occlusion); yzw: 0.
    ground_sky: vec4<f32>,
    // rgb: the ground's radiance below the horizon per unit of frame.daylight (sh9-ggx: `sh` is
    // the sky above the horizon alone, render::Lighting::ground_radiance); w: the sun's share
    // of the ground's light (render::frame::sun_share_on_ground).
    ground: vec4<f32>,
};

// The ground's sun visibility drawn in ground space (shaders/ground_sun.wgsl,
// render::passes::ground_sun): where and how densely the last bake drew it.
struct GroundSun {
    // World (min.x, min.y, max.x, max.y) of the baked rectangle; texel row 0 at min.y.
    square: vec4<f32>,
    // x, y: texels drawn across and along it (from the texture's corner); z: the ground plane's
    // height; w: the texture's side.
    texels: vec4<f32>,
};

// A world direction in the environment map's own ENU frame (frame.wgsl env_dir before the
// cube-space swizzle).
fn env_map_dir(frame: Frame, d: vec3<f32>) -> vec3<f32> {
    let c = frame.env_rotation.x;
    let s = frame.env_rotation.y;
    return vec3<f32>(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
}

// Fraction of sunlight reaching world point p with a penumbra that follows the sun's angular
// size and the blocker's distance (percentage-closer soft shadows, Fernando 2005) in 14 texture
// calls (5 gathers, 9 comparisons; it was 50): the mean depth of the blockers around p gives the penumbra's half-width
// (receiver - blocker) * tan(angular radius); a filter with the spread of the sun's disc over
// that half-width (at least one shadow-map texel) over hardware-compared bilinear taps gives
// the visibility. The blocker search is five textureGather of 2x2 depths: around p and at the
// corners of the search square (the square the 5x5 depth loads of the 50-tap version it
// replaced covered); the filter is SOFT_TAPS x SOFT_TAPS comparison taps (cost and look against
// that version: docs/PERFORMANCE.md; until the twelfth session they covered the box its 5x5
// taps covered, 1.25 penumbrae either side). The sun camera is orthographic, so metres
// per texel and per unit depth come from the rows of its matrix. `gather` samples the nearest
// texel without comparison.
//
// The model's own surface is not a blocker of itself (docs/accuracy.md, eleventh session): the
// sun's disc, seen from p, is a cone of half-angle r (tan r = `tan_radius`) around the sun's
// direction, so a texel s metres across the sun from p can hide part of it only if it is at
// least s / tan r nearer the sun. A surface lit by the whole disc is tilted from the sun's
// direction by more than r, so its own texels around p rise towards the sun by less than that:
// where the 2x2 texels around p hold the model within SELF_TEXELS texels' worth of that slope of
// p's depth (p is on the model's surface as the sun sees it; 3 rather than the 2x2's 0.7 texel
// for the facets and biases between a vertex and its texels: at 1.5 the vertices of a faceted
// sphere near its terminator failed the test where the pixels between them passed, so the
// per-vertex lookup there was darker than the per-pixel one), a search corner counts only what
// is inside the cone. Without it a surface the sun grazes (the truck's sides, 10 degrees of sun)
// found itself at the search corners, whose mean depth gave a penumbra of several texels, and the
// filter over that width shadowed it by its own depth slope: 0.87 of the sun where the reference
// has all of it. Elsewhere (the ground, which the map does not hold, or p behind a blocker) every
// blocker counts as before: the sparse corners stand for the nearest parts of blockers the
// filter can reach, and a cone test there cut the outer half of the ground's penumbrae.
const SELF_TEXELS: f32 = 3.0;
const SOFT_TAPS: i32 = 3;
fn sun_visibility_soft(map: texture_depth_2d, smp: sampler_comparison, gather: sampler, frame: Frame, p: vec3<f32>, tan_radius: f32) -> f32 {
    let m = frame.light_view_proj;
    let clip = m * vec4<f32>(p, 1.0);
    let ndc = clip.xyz / clip.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    if (any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0))) {
        return 1.0;
    }
    let texel = 1.0 / f32(frame.shadow_map_size);
    let receiver = min(ndc.z, 1.0) - 0.002;
    // uv per metre across the sun's view, and depth units per metre along it.
    let uv_per_m = 0.5 * length(vec3<f32>(m[0].x, m[1].x, m[2].x));
    let depth_per_m = length(vec3<f32>(m[0].z, m[1].z, m[2].z));
    // Blocker search: a blocker at depth 0 (the nearest the map holds) would cast the widest
    // penumbra; search that far, between 2 and 24 texels.
    let widest = receiver / depth_per_m * tan_radius * uv_per_m;
    let search = clamp(widest, 2.0 * texel, 24.0 * texel);
    // The 2x2 texels around p (the map is cleared to depth 1 where the model is not)...
    let centre = textureGather(map, gather, uv);
    let cone = depth_per_m / (uv_per_m * max(tan_radius, 1e-4));
    let own = (abs(centre - vec4<f32>(receiver)) < vec4<f32>(SELF_TEXELS * texel * cone)) & (centre < vec4<f32>(1.0));
    // ... then four 2x2 at the corners of the search square, which on the model's own surface
    // count only blockers inside the sun's cone: depth units nearer per uv across.
    let nearer_per_uv = select(0.0, cone, any(own));
    let centre_blocks = select(vec4<f32>(0.0), vec4<f32>(1.0), centre < vec4<f32>(receiver));
    var blockers = dot(centre_blocks, vec4<f32>(1.0));
    var blocker_depth = dot(centre_blocks, centre);
    var corners = array<vec2<f32>, 4>(vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(-1.0, 1.0), vec2<f32>(1.0, 1.0));
    for (var i = 0; i < 4; i++) {
        let o = corners[i] * search;
        let d = textureGather(map, gather, uv + o);
        // Less one texel: the 2x2 texels gathered lie up to one texel nearer p than o.
        let limit = receiver - max(length(o) - texel, 0.0) * nearer_per_uv;
        let b = select(vec4<f32>(0.0), vec4<f32>(1.0), d < vec4<f32>(limit));
        blockers += dot(b, vec4<f32>(1.0));
        blocker_depth += dot(b, d);
    }
    if (blockers == 0.0) {
        return 1.0;
    }
    let distance = (receiver - blocker_depth / blockers) / depth_per_m;
    let penumbra = max(distance * tan_radius * uv_per_m, texel);
    // SOFT_TAPS taps a side, `step` apart, spread as the sun's disc spreads an edge. Seen through
    // a uniform disc of radius rho (the penumbra's half-width), a straight edge rises over 2 rho
    // with a spread (standard deviation of the rise) of rho / 2; N taps s apart spread
    // s * sqrt((N^2 - 1) / 12), so s = rho * sqrt(3 / (N^2 - 1)): 0.61 rho for 3 taps. It was
    // 2.5 rho / N (a box 1.25 rho either side, 0.83 rho for 3 taps): penumbrae 1.36x too wide
    // (tests/self_shadow.rs `a_penumbra_has_the_width_of_the_suns_disc`; docs/accuracy.md,
    // twelfth session).
    let step = penumbra * sqrt(3.0 / f32(SOFT_TAPS * SOFT_TAPS - 1));
    let first = -0.5 * f32(SOFT_TAPS - 1);
    var lit = 0.0;
    for (var y = 0; y < SOFT_TAPS; y++) {
        for (var x = 0; x < SOFT_TAPS; x++) {
            let o = (vec2<f32>(f32(x), f32(y)) + first) * step;
            lit += textureSampleCompareLevel(map, smp, uv + o, receiver);
        }
    }
    return lit / f32(SOFT_TAPS * SOFT_TAPS);
}
