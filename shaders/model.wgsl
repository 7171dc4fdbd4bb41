// Model pass: one fragment shader for every lighting method (seed 000 §5.3-5.5, Appendix D/E);
// the sh9-ggx method's shading is its own file (sh9_ggx.wgsl), appended to this one.
// All lighting happens in world space (ENU), in linear light.
//
// The METHOD_* constants are generated from render::Method (prepended by render::shaders).
// METHOD is a pipeline-override constant: each method has its own pipeline, which compiles only
// its own branches (measured faster on lavapipe than a uniform switch: docs/PERFORMANCE.md).
override METHOD: u32;
// COLOUR_CORRECTION is one too: false for frames without a correction, whose pipelines then
// hold no correction code (lavapipe runs every case of a runtime switch).
override COLOUR_CORRECTION: bool = true;
// VERTEX_SUN too: true where the sun's visibility is interpolated from the vertices
// (VertexIn.sun), whose pipelines then hold no shadow-map lookup; false where the map is looked
// up per pixel. A uniform branch on a material value instead saved nothing on lavapipe
// (docs/PERFORMANCE.md, ninth session).
override VERTEX_SUN: bool = false;
// LIGHT_KEPT too, for the light from the vertices (below): true where the vertex-light pass
// computed the light at the vertices for this frame (cs_light: a camera that only turns keeps
// it), false where the vertex stage computes it (the camera moving: the pass would run every
// frame, and costs more than the vertex stage's light; docs/PERFORMANCE.md, twenty-seventh
// session).
override LIGHT_KEPT: bool = false;
// The light from the vertices (sh9-ggx, with VERTEX_SUN; entry points vs_light and fs_light):
// the whole light is computed at the vertices and interpolated (LightOut), the fragment
// multiplying its own albedo by it, for meshes whose triangles are a few pixels on screen and
// whose normals turn little across them (render::passes::model::MAX_LIGHT_EDGE_PX,
// light_turn_limit): there a vertex is about a pixel apart, and lavapipe shades each small
// triangle's whole 4x4 blocks of pixels (docs/PERFORMANCE.md, eighth and sixteenth sessions).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> instance: Instance;
@group(0) @binding(2) var env_tex: texture_cube<f32>;
@group(0) @binding(3) var env_smp: sampler;
@group(0) @binding(4) var background_tex: texture_2d<f32>;
@group(0) @binding(5) var background_smp: sampler;
@group(0) @binding(6) var shadow_map: texture_depth_2d;
@group(0) @binding(7) var shadow_smp: sampler_comparison;
// Colour correction of the model's albedo towards the environment (colour_correct.wgsl).
@group(0) @binding(8) var<uniform> colour_cc: ColourCorrection;
// The shadow map's depths without comparison, nearest texel (the soft shadow's blocker search).
@group(0) @binding(12) var shadow_gather_smp: sampler;

struct Material {
    // rgb: diffuse colour (linear); a: 1 when the diffuse texture is used
    albedo: vec4<f32>,
    // rgb: specular colour (linear); a: gloss exponent g_f
    specular: vec4<f32>,
    // x: ambient term a_c, y: diffuse term d_c, z: specular term s_c, w: 1 for a double-sided
    // material (glTF 2.0 §3.9.5: a back face is lit with its normal reversed), else 0
    terms: vec4<f32>,
};

@group(1) @binding(0) var<uniform> material: Material;
@group(1) @binding(1) var diffuse_tex: texture_2d<f32>;
@group(1) @binding(2) var diffuse_smp: sampler;

// The model's vertex (render::pipelines::Vertex; `ao` at render::pipelines::AO_LOCATION, `bent`
// at BENT_LOCATION, `tint` at TINT_LOCATION), and `sun` from a second buffer at SUN_LOCATION.
struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    // Shares of the sky's light (x), of the ground's where the sky lights it (y) and of the
    // ground's (z) that the vertex gets past the model, and the model's own reflected light (w)
    // (1, 1, 1, 0 until the model's occlusion is computed; scene::occlusion::model_sky_ground).
    @location(3) ao: vec4<f32>,
    // The bent normal: the mean direction of the rays that pass the model, where sh9-ggx looks
    // up the sky (the normal until the occlusion is computed).
    @location(4) bent: vec3<f32>,
    // The fraction of sunlight reaching the vertex, looked up in the shadow map by the method's
    // own lookup each time the map is drawn (vertex_sun.wgsl); 1 until then.
    @location(5) sun: f32,
    // The colour of the sky's light the vertex gets through its own rays and the model's
    // bounces, per channel over its luminance (0 until computed: sh9-ggx then takes SH9's).
    @location(6) tint: vec3<f32>,
};

struct VertexOut {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) ao: vec4<f32>,
    @location(4) bent: vec3<f32>,
    // The sun's visibility from the vertices (VERTEX_SUN), weighted by how much each vertex faces
    // the sun: x interpolates visibility * max(n.l, 0), y interpolates n.l (n: the vertex's
    // world normal as `normal` carries it, l: the sun). vertex_sun() divides them.
    @location(5) sun: vec2<f32>,
    @location(6) tint: vec3<f32>,
};

// What the light from the vertices interpolates: the texture coordinates, the light at the
// vertex that the albedo multiplies and the light it adds (sh9_ggx.wgsl Sh9Light). Only what its
// fragment reads: lavapipe sets up and interpolates every varying of a triangle, and 8 floats
// instead of VertexOut's 26 took 0.8 ms off the dragon's model pass (docs/PERFORMANCE.md,
// seventeenth session).
struct LightOut {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) lit: vec3<f32>,
    @location(2) specular: vec3<f32>,
};

// What an untextured mesh's light from the vertices interpolates: its whole colour, the
// material's albedo (constant over the mesh) times the light plus the reflection, which is what
// the two interpolated apart give (the product is linear in the light). 3 floats instead of 8,
// and a fragment that only writes them (docs/PERFORMANCE.md, twenty-seventh session).
struct ColourOut {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) colour: vec3<f32>,
};

// The light at a vertex as the vertex-light pass computed it (cs_light; read where LIGHT_KEPT):
// two more attributes of the light-from-the-vertices pipelines, from the mesh's light buffer
// (at render::pipelines::LIGHT_LOCATION and LIGHT_SPECULAR_LOCATION).
struct LightIn {
    @location(7) lit: vec4<f32>,
    @location(8) specular: vec4<f32>,
};

@vertex
fn vs_main(vertex: VertexIn) -> VertexOut {
    return vertex_out(vertex);
}

// The clip-space position of a model-space point (vertex_out's, @invariant: the same depth).
fn clip_position(position: vec3<f32>) -> vec4<f32> {
    return frame.view_proj * (instance.model * vec4<f32>(position, 1.0));
}

// sh9-ggx's light at a vertex from its sun's visibility: as the vertex-light pass computed it
// (LIGHT_KEPT), or computed here.
fn light_at_vertex(vertex: VertexIn, light_in: LightIn) -> Sh9Light {
    if (LIGHT_KEPT) {
        return Sh9Light(light_in.lit.rgb, light_in.specular.rgb);
    }
    let v = vertex_out(vertex);
    return sh9_ggx_light(v.world, v.normal, v.ao, v.bent, v.tint, vertex.sun);
}

// The light from the vertices.
@vertex
fn vs_light(vertex: VertexIn, light_in: LightIn) -> LightOut {
    let shaded = light_at_vertex(vertex, light_in);
    return LightOut(clip_position(vertex.position), vertex.uv, shaded.lit, shaded.specular);
}

@fragment
fn fs_light(in: LightOut) -> @location(0) vec4<f32> {
    return vec4<f32>(surface_albedo(in.uv) * in.lit + in.specular, 1.0);
}

// The light from the vertices of an untextured material: the whole colour at the vertex.
@vertex
fn vs_colour(vertex: VertexIn, light_in: LightIn) -> ColourOut {
    let shaded = light_at_vertex(vertex, light_in);
    let albedo = min(corrected_colour(material.albedo.rgb), vec3<f32>(1.0));
    return ColourOut(clip_position(vertex.position), albedo * shaded.lit + shaded.specular);
}

@fragment
fn fs_colour(in: ColourOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.colour, 1.0);
}

// The vertex-light pass (render::passes::model::ModelPass::encode_vertex_light): sh9-ggx's light at each vertex
// of a mesh's drawn level (`level_vertices`, each once), from the mesh's vertices
// (render::pipelines::Vertex, VERTEX_FLOATS floats each) and its sun per vertex (vertex_sun.wgsl),
// written to `vertex_light` (two vec4 per vertex: what the albedo multiplies, what is added) for
// vs_light and vs_colour. It reads the frame's camera position but not its view: a camera that
// only turns keeps the buffer (render::passes::model::LightKey; that module's tests check which
// fields of Frame it reads).
@group(2) @binding(0) var<storage, read> mesh_vertices: array<f32>;
@group(2) @binding(1) var<storage, read> level_vertices: array<u32>;
@group(2) @binding(2) var<storage, read> vertex_sun_values: array<f32>;
@group(2) @binding(3) var<storage, read_write> vertex_light: array<vec4<f32>>;

fn vertex_vec3(v: u32, offset: u32) -> vec3<f32> {
    let k = v * VERTEX_FLOATS + offset;
    return vec3<f32>(mesh_vertices[k], mesh_vertices[k + 1u], mesh_vertices[k + 2u]);
}

// One invocation per vertex of the level: in world space as vertex_out places it.
@compute @workgroup_size(64)
fn cs_light(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= arrayLength(&level_vertices)) {
        return;
    }
    let v = level_vertices[id.x];
    let world = (instance.model * vec4<f32>(vertex_vec3(v, VERTEX_POSITION), 1.0)).xyz;
    let normal = (instance.normal * vec4<f32>(vertex_vec3(v, VERTEX_NORMAL), 0.0)).xyz;
    let bent = (instance.normal * vec4<f32>(vertex_vec3(v, VERTEX_BENT), 0.0)).xyz;
    let k = v * VERTEX_FLOATS + VERTEX_AO;
    let ao = vec4<f32>(mesh_vertices[k], mesh_vertices[k + 1u], mesh_vertices[k + 2u], mesh_vertices[k + 3u]);
    let shaded = sh9_ggx_light(world, normal, ao, bent, vertex_vec3(v, VERTEX_TINT), vertex_sun_values[v]);
    vertex_light[2u * v] = vec4<f32>(shaded.lit, 0.0);
    vertex_light[2u * v + 1u] = vec4<f32>(shaded.specular, 0.0);
}

fn vertex_out(vertex: VertexIn) -> VertexOut {
    var out: VertexOut;
    let world = instance.model * vec4<f32>(vertex.position, 1.0);
    out.world = world.xyz;
    out.normal = (instance.normal * vec4<f32>(vertex.normal, 0.0)).xyz;
    out.uv = vertex.uv;
    out.ao = vertex.ao;
    out.tint = vertex.tint;
    out.bent = (instance.normal * vec4<f32>(vertex.bent, 0.0)).xyz;
    let n_dot_l = dot(out.normal, frame.sun_dir);
    out.sun = vec2<f32>(vertex.sun * max(n_dot_l, 0.0), n_dot_l);
    out.clip = frame.view_proj * world;
    return out;
}

// The sun's visibility at a fragment from its triangle's vertices (VERTEX_SUN): each vertex's
// looked-up visibility weighted by its n.l, so a vertex facing away from the sun (weight 0; its
// lookup is the model's own shadow) does not darken the sunlit part of a triangle across the
// terminator, which takes the visibility of its sunlit vertices; where every vertex faces the
// sun it is their visibility interpolated with weights n.l. 0 where the fragment faces away
// (its n.l, the sign of in.sun.y, makes its sun term 0 anyway).
fn vertex_sun(in: VertexOut) -> f32 {
    return select(0.0, clamp(in.sun.x / in.sun.y, 0.0, 1.0), in.sun.y > 0.0);
}

// The diffuse texture's level-of-detail bias (mip levels; negative reads finer levels than
// the sampler's own choice). The texture has its whole mip chain (render/mip_chain.rs); the
// sampler picks the level from the larger of the pixel's two footprint axes and blends two
// levels of bilinear texels, a kernel wider than the pixel, so at bias 0 the truck was blurrier
// than the path-traced references (64 samples a pixel, box filter) and its sh9-ggx ROI FLIP
// rose 0.0701 -> 0.0743; -1, -1.5, -2 gave 0.0708, 0.0699, 0.0698 (docs/PERFORMANCE.md,
// twelfth session): -1.5 is the smallest of those no less accurate than level 0 alone (0.0701).
const DIFFUSE_LOD_BIAS: f32 = -1.5;

// The surface's diffuse reflectance after colour correction (seed §5.6), which acts on what the
// model priors were measured on: the diffuse texture's linear colour when there is one, else
// the material's diffuse colour. A corrected reflectance is kept at or below 1.
// Chosen with select, not branched on: lavapipe recompiles a shader that branches on uniform
// values alone at each bind (gpu::uniform_branches); an untextured material's texture is 1×1.
fn surface_albedo(uv: vec2<f32>) -> vec3<f32> {
    let albedo = material.albedo.rgb;
    let texel = textureSampleBias(diffuse_tex, diffuse_smp, uv, DIFFUSE_LOD_BIAS).rgb;
    let source = select(albedo, texel, material.albedo.a > 0.5);
    let corrected = min(corrected_colour(source), vec3<f32>(1.0));
    return select(corrected, albedo * corrected, material.albedo.a > 0.5);
}

// The colour correction of a reflectance, or the reflectance itself in the pipelines without
// correction (what the identity correction gives: strength 0).
fn corrected_colour(rgb: vec3<f32>) -> vec3<f32> {
    if (COLOUR_CORRECTION) {
        return colour_correct(rgb, colour_cc);
    }
    return rgb;
}

// Eq. 6: blend factor of the upper hemisphere for a normal (1 = facing straight up; world up
// is +z).
fn hemisphere_blend(n: vec3<f32>) -> f32 {
    return 0.5 + 0.5 * n.z;
}

// The ambient light colour reaching a surface with normal n, per method.
fn ambient_light(n: vec3<f32>, method: u32) -> vec3<f32> {
    let a = hemisphere_blend(n);
    if (method == METHOD_BLINN_PHONG) {
        return vec3<f32>(1.0);
    }
    if (method == METHOD_HEMISPHERE_OCCLUSION) {
        // Hemisphere occlusion: greyscale light level above, shadow level below (§5.4.2).
        return vec3<f32>(mix(frame.occlusion_shadow, frame.occlusion_light, a));
    }
    return mix(frame.ground, frame.sky, a);
}

// Screen uv (0,0 top-left) of a world point.
fn screen_uv(p: vec3<f32>) -> vec2<f32> {
    let clip = frame.view_proj * vec4<f32>(p, 1.0);
    let ndc = clip.xy / clip.w;
    return vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
}

// Blinn-Phong specular factor (Eq. 3).
fn specular_factor(n: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> f32 {
    let h = normalize(l + e);
    return pow(max(dot(n, h), 0.0), max(material.specular.a, 1.0));
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let method = METHOD;
    if (method == METHOD_SH9_GGX) {
        // Turns every normal to the viewer, a double-sided material's back faces' too.
        return shade_sh9_ggx(in);
    }
    var n = normalize(in.normal);
    if (!front && material.terms.w > 0.5) {
        n = -n;
    }
    let e = normalize(frame.camera_pos - in.world); // towards the camera
    let l = frame.sun_dir;                               // towards the sun
    let l_s = frame.sunlight;
    let l_d = frame.daylight;

    if (method == METHOD_CUBE_REFRACTION || method == METHOD_LIVE_REFRACTION) {
        // Transparent material, Eq. 7: C = r_c + s_f. Two-sided: the normal is turned to face
        // the viewer (by geometry, so it does not depend on the mesh's winding).
        if (dot(n, e) < 0.0) {
            n = -n;
        }
        let sf = specular_factor(n, l, e) * l_s * material.terms.z;
        let t = refract(-e, n, frame.eta);
        var rc: vec3<f32>;
        if (method == METHOD_CUBE_REFRACTION) {
            rc = textureSampleLevel(env_tex, env_smp, env_dir(frame, t), 0.0).rgb * frame.env_exposure;
        } else {
            // Where the refracted ray lands a little way behind the surface, seen by the camera.
            let uv = screen_uv(in.world + t * frame.live_depth);
            rc = textureSampleLevel(background_tex, background_smp, clamp(uv, vec2<f32>(0.0), vec2<f32>(1.0)), 0.0).rgb;
        }
        return vec4<f32>(rc + vec3<f32>(sf), 1.0);
    }

    // Opaque, one-sided lighting (Eq. 3): factors are clamped at zero, so a surface facing away
    // from the sun gets only ambient light.
    let albedo = surface_albedo(in.uv);
    var visibility = vertex_sun(in);
    if (!VERTEX_SUN) {
        visibility = sun_visibility(shadow_map, shadow_smp, frame, in.world + n * 0.002);
    }
    let df = max(dot(n, l), 0.0) * visibility;
    let sf = specular_factor(n, l, e) * visibility * select(0.0, 1.0, dot(n, l) > 0.0);
    let ambient = ambient_light(n, method) * material.terms.x * l_d;
    let direct = material.terms.y * df * l_s;
    var colour = albedo * (ambient + vec3<f32>(direct)) + material.specular.rgb * material.terms.z * sf * l_s;

    if (method == METHOD_CUBE_REFLECTION) {
        let r = reflect(-e, n);
        let env = textureSampleLevel(env_tex, env_smp, env_dir(frame, r), 0.0).rgb * frame.env_exposure;
        colour = mix(colour, env, frame.reflection);
    } else if (method == METHOD_LIVE_REFLECTION) {
        // Seed §5.5.3: the reflection vector in camera space indexes the camera image.
        let r_view = (frame.view * vec4<f32>(reflect(-e, n), 0.0)).xyz;
        let uv = vec2<f32>(r_view.x * 0.5 + 0.5, 0.5 - r_view.y * 0.5);
        let live = textureSampleLevel(background_tex, background_smp, uv, 0.0).rgb;
        colour = mix(colour, live, frame.reflection);
    }
    return vec4<f32>(colour, 1.0);
}

// The depth pre-pass: the model's depth alone (colour writes masked), so the shading pass then
// shades each pixel once.
@fragment
fn fs_depth() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0);
}
