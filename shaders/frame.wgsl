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

// Fraction of sunlight reaching world point p (1 = lit), 3x3 PCF over the sun's depth map.
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
    for (var y = -1; y <= 1; y++) {
        for (var x = -1; x <= 1; x++) {
            let o = vec2<f32>(f32(x), f32(y)) * texel;
            lit += textureSampleCompareLevel(map, smp, uv + o, depth);
        }
    }
    return lit / 9.0;
}
