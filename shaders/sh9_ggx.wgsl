// The sh9-ggx lighting method (issue 9), appended to model.wgsl's module: light measured from
// the environment, in colour.
//   diffuse  = albedo * ((the sky above the horizon without the sun through the vertex's own
//                         open rays, weighted by its binned radiance, plus the model's own
//                         surfaces' reflection of it, in the colour of SH9 along the bent normal
//                         + a uniform ground's irradiance * mix(ao.y, ao.z, sun's share)) / pi * a_c
//                        + the sun's irradiance / pi * max(n.l, 0) * soft shadow * d_c)
//   specular = the environment prefiltered for the GGX lobe at the surface's roughness, times the
//              split-sum BRDF terms F0 * A + B (Karis 2013), times (ao.x + ao.w) * s_c
// ao: the vertex's shares of the sky's light, of the ground's where the sky lights it (past the
// model's contact shadow on the ground), of the ground's past the model alone, and the model's
// own reflected light by the multi-bounce fit (scene::occlusion::model_sky_ground; ao.x and ao.w
// now weight the specular alone); the ground's sunlit part is taken as unshadowed. The sky's
// colour is looked up along the bent normal (the mean direction of the vertex's rays that pass
// the model): a surface in a crevice gets the light of the sky it sees.
// The sky's and sun's levels are frame.daylight and frame.sunlight, so the DL/SL multipliers
// and the live view's sliders act on them; a_c, d_c, s_c (the scene's material terms, seed
// Eq. 3) scale the sky, sun and specular terms: s_c = 0 gives a Lambertian surface, the
// references' material for a model without one (tests/reference).
// Two-sided, like the references (tests/reference): the normal faces the viewer.
// F0 = the material's specular colour (MTL Ks; glTF: mix(0.04, base colour, metallic)); GGX
// roughness from its Blinn-Phong exponent (light::ggx::roughness_from_exponent, Walter 2007).

@group(0) @binding(9) var<uniform> light: Light;
@group(0) @binding(10) var specular_env: texture_cube<f32>;
@group(0) @binding(11) var brdf_lut: texture_2d<f32>;

// PREFILTER_LEVELS (mip levels of specular_env; level k holds roughness k / (n - 1)) is
// generated from light::ggx::PREFILTER_LEVELS by render::shaders.

// Sum of the SH9 coefficients weighted by the real SH basis at unit direction d (light::sh9::basis).
fn sh9_eval(d: vec3<f32>) -> vec3<f32> {
    let x = d.x;
    let y = d.y;
    let z = d.z;
    var e = light.sh[0].rgb * 0.282095;
    e += light.sh[1].rgb * (0.488603 * y);
    e += light.sh[2].rgb * (0.488603 * z);
    e += light.sh[3].rgb * (0.488603 * x);
    e += light.sh[4].rgb * (1.092548 * x * y);
    e += light.sh[5].rgb * (1.092548 * y * z);
    e += light.sh[6].rgb * (0.315392 * (3.0 * z * z - 1.0));
    e += light.sh[7].rgb * (1.092548 * x * z);
    e += light.sh[8].rgb * (0.546274 * (x * x - y * y));
    return max(e, vec3<f32>(0.0));
}

// The light of the sky (above the horizon) and of the ground the model stands on, on a surface
// facing world normal n, as irradiance / pi per unit of frame.daylight; ao: the vertex's shares
// (VertexIn.ao); bent: the unit world direction of the vertex's open rays (VertexIn.bent); seen:
// the sky's light the vertex gets, through its own open rays and reflected by the model's own
// surfaces, as irradiance / pi relative to the sky's mean radiance (render::model_cache::
// PreparedModel::vertices_under, carried in the bent normal's length), given the colour of the
// SH9 irradiance along the bent normal. A uniform ground of radiance L below the horizon gives
// E / pi = L (1 - n.z) / 2; the ground's light is the sky's (shadowed by the model: ao.y) and the
// sun's (light.ground.w of it, unshadowed here: ao.z). The ground's light the model's own surfaces
// reflect is not added: previz's ground term alone is 0.965 of the path tracer's whole ground-lit
// light on the courtyard dragon, its interreflection included (docs/accuracy.md, "Twelfth session
// — the model's sky and bounce from its own rays").
fn sky_and_ground(n: vec3<f32>, ao: vec4<f32>, bent: vec3<f32>, seen: f32, tint: vec3<f32>) -> vec3<f32> {
    let sky = sh9_eval(env_map_dir(frame, bent));
    let lum = vec3<f32>(0.2126, 0.7152, 0.0722);
    let l = dot(sky, lum);
    // The upper hemisphere's mean radiance: L00 Y00 / (2 pi Y00^2) = L00 * 2 Y00.
    let mean = light.sh[0].rgb * 0.5641896;
    let mean_l = dot(mean, lum);
    // Where SH9 gives a direction little of the sky's light (a bent normal turned down with a
    // back face seen, at a silhouette where the interpolated normal faces away), its value is
    // the band limit's ringing and its colour noise: one channel clamped at 0 made pure red
    // samples on the full-detail bunny's edge. Below a tenth of the mean the colour fades to the
    // mean sky's.
    let trust = smoothstep(0.0, 0.1 * mean_l, l);
    let colour = select(mix(mean / max(mean_l, 1e-8), sky / max(l, 1e-8), trust), tint, dot(tint, lum) > 0.0);
    let visible = colour * (seen * mean_l);
    let ground = light.ground.rgb * (0.5 * (1.0 - n.z));
    return visible + ground * mix(ao.y, ao.z, light.ground.w);
}

// GGX roughness of a Blinn-Phong exponent (light::ggx::roughness_from_exponent).
fn roughness_from_exponent(exponent: f32) -> f32 {
    return sqrt(sqrt(2.0 / (max(exponent, 0.0) + 2.0)));
}

// The light at a surface point: `lit` is what its albedo multiplies (the sky, the ground and
// the sun), `specular` what is added (the environment's reflection).
struct Sh9Light {
    lit: vec3<f32>,
    specular: vec3<f32>,
};

// The light at world point `p` of a surface with world normal `normal` (interpolated, not
// normalised: its length divides the bent normal's), shares `ao`, bent normal `bent`, sky colour
// `tint` (VertexIn) and the sun's visibility `visibility` there: at a vertex (model.wgsl
// vs_light) or a pixel.
fn sh9_ggx_light(p: vec3<f32>, normal: vec3<f32>, ao: vec4<f32>, bent: vec3<f32>, tint: vec3<f32>, visibility: f32) -> Sh9Light {
    let n = facing(p, normal);
    let v = normalize(frame.camera_pos - p);
    // The bent normal turns with the normal when the back face is seen.
    let b = normalize(bent) * select(1.0, -1.0, dot(normal, n) < 0.0);
    let seen = length(bent) / max(length(normal), 1e-8);
    let sky = sky_and_ground(n, ao, b, seen, tint) * (frame.daylight * material.terms.x);
    let n_dot_l = max(dot(n, frame.sun_dir), 0.0);
    let sun = light.sun.rgb * (frame.sunlight * n_dot_l * visibility * material.terms.y);
    // The reflection is computed for every material (zero without a specular term): a branch on
    // the material alone is one lavapipe recompiles the shader for at each bind
    // (gpu::uniform_branches).
    let f0 = material.specular.rgb;
    let roughness = roughness_from_exponent(material.specular.a);
    let n_dot_v = clamp(dot(n, v), 1e-3, 1.0);
    let r = reflect(-v, n);
    let prefiltered = textureSampleLevel(specular_env, env_smp, env_dir(frame, r), roughness * (PREFILTER_LEVELS - 1.0)).rgb;
    let ab = textureSampleLevel(brdf_lut, background_smp, vec2<f32>(n_dot_v, roughness), 0.0).xy;
    let strength = select(0.0, material.terms.z, max(f0.r, max(f0.g, f0.b)) * material.terms.z > 0.0);
    let specular = prefiltered * frame.env_exposure * (f0 * ab.x + ab.y) * ((ao.x + ao.w) * strength);
    return Sh9Light(sky + sun, specular);
}

// The unit normal at `p` turned to the viewer (a double-sided material's back faces' too).
fn facing(p: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let n = normalize(normal);
    return select(n, -n, dot(n, frame.camera_pos - p) < 0.0);
}

fn shade_sh9_ggx(in: VertexOut) -> vec4<f32> {
    // Interpolated from the vertices (VERTEX_SUN, model.wgsl), or looked up per pixel.
    var visibility = vertex_sun(in);
    if (!VERTEX_SUN) {
        visibility = 0.0;
        let n = facing(in.world, in.normal);
        if (dot(n, frame.sun_dir) > 0.0) {
            visibility = sun_visibility_soft(shadow_map, shadow_smp, shadow_gather_smp, frame, in.world + n * 0.002, light.sun.w);
        }
    }
    let shaded = sh9_ggx_light(in.world, in.normal, in.ao, in.bent, in.tint, visibility);
    return vec4<f32>(surface_albedo(in.uv) * shaded.lit + shaded.specular, 1.0);
}
