//! The frame maths: from the frame's parameters and what the loaded scene fixes, the uniform
//! values every pass reads. Pure functions, no GPU access.

use super::params::Lighting;
use super::params::{ColourSettings, FrameParams, HemispherePriors};
use super::shadow_fit::{self, GroundRect};
use super::uniforms::{FrameUniforms, InstanceUniforms, LightUniforms};
use super::view;
use crate::colour::correction::ColourCorrection;
use crate::colour::stats::ColourStats;
use crate::colour::transfer::TransferMethod;
use crate::scene::{lod, occlusion};
use anyhow::{Result, bail};
use glam::{Mat4, Vec2, Vec3};

/// What the frame maths needs besides the frame's parameters: fixed by the loaded model and
/// environment and by the render targets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameContext<'a> {
    /// The model's bounds in model space.
    pub bounds: (Vec3, Vec3),
    /// The environment's hemisphere priors after exposure.
    pub priors: HemispherePriors,
    /// Linear scale applied to the environment map.
    pub exposure: f32,
    /// World heading (radians, clockwise from North) of the cube map's front (+Z) face.
    pub env_heading: f32,
    /// Output size in pixels.
    pub size: (u32, u32),
    /// Sides of the square shadow maps allocated (ascending); a frame draws into the smallest
    /// with a texel per pixel of the shadow's footprint on screen (`shadow_fit::shadow_map_size`).
    pub shadow_map_sizes: &'a [u32],
}

/// The uniform values of one frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameData {
    pub frame: FrameUniforms,
    pub instance: InstanceUniforms,
    pub ground: InstanceUniforms,
    pub colour: ColourCorrection,
    /// The light measured from the environment (sh9-ggx and the soft ground shadow).
    pub light: LightUniforms,
    /// The level of detail drawn (0: the model as loaded).
    pub level: usize,
    /// Pixels per model unit at the model's nearest point (None from inside its bounds), which
    /// the meshes' longest edges are measured in for the per-vertex sun.
    pub px_per_unit: Option<f32>,
    /// Which back faces the model pass may cull: none when the model's transform mirrors it;
    /// those of closed meshes only when the camera is outside the model's bounds.
    pub cull: super::passes::model::Culling,
    /// Whether the shadow pass has anything to do: sunlight to block and the model or its
    /// shadow on screen (render::shadow_fit::shadow_needed).
    pub shadow_pass: bool,
    /// Whether the ground pass has a shadow to catch: the above, with the sun above the
    /// horizon and a shadow opacity above zero.
    pub ground_pass: bool,
    /// Side of the shadow map this frame draws into (one of `FrameContext::shadow_map_sizes`).
    pub shadow_map_size: u32,
    /// The ground quad's triangles: with the sun's shadow lookup where it can fall, without
    /// elsewhere.
    pub ground_mesh: GroundMesh,
}

/// Most vertices the ground pass draws (its vertex buffer, made once).
pub const GROUND_VERTICES: usize = 512;

/// The ground pass's triangles, in the ground quad's unit square ([-1, 1]², z = 0, placed by the
/// ground's instance matrix): first `shadowed` vertices where the sun's shadow can fall (drawn
/// with the shadow lookup), then `sky_only` vertices over the rest of the quad where the sky's
/// occlusion darkens it (drawn without). The two parts share their edges exactly and do not
/// overlap, so every ground pixel is shaded once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundMesh {
    pub vertices: [[f32; 2]; GROUND_VERTICES],
    pub shadowed: u32,
    pub sky_only: u32,
}

impl GroundMesh {
    pub const EMPTY: GroundMesh = GroundMesh { vertices: [[0.0; 2]; GROUND_VERTICES], shadowed: 0, sky_only: 0 };

    /// The mesh of `shadowed` then `sky_only` triangle lists (world x/y), in `quad`'s unit
    /// square.
    pub fn new(quad: &GroundRect, shadowed: &[Vec2], sky_only: &[Vec2]) -> GroundMesh {
        let c = 0.5 * (quad.min + quad.max);
        let h = (0.5 * (quad.max - quad.min)).max(Vec2::splat(1e-12));
        let mut mesh = GroundMesh::EMPTY;
        // split_convex gives 3 (3 n_inner + n_outer - 2) vertices: the 12-sided outline clipped
        // to the quad has at most 16, the hull of it and the 16-sided sky region clipped to the
        // quad at most 32: 234.
        let all = shadowed.iter().chain(sky_only).take(GROUND_VERTICES);
        for (v, p) in mesh.vertices.iter_mut().zip(all) {
            *v = ((*p - c) / h).to_array();
        }
        mesh.shadowed = shadowed.len().min(GROUND_VERTICES) as u32;
        mesh.sky_only = (shadowed.len() + sky_only.len()).min(GROUND_VERTICES) as u32 - mesh.shadowed;
        mesh
    }
}

fn mat(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

/// Uniforms of a frame: camera, model/ground transforms, sun shadow camera, lights, priors.
/// Returns the `Frame` uniform, the model's instance and the ground plane's instance.
pub fn frame_uniforms(p: &FrameParams, c: &FrameContext) -> (FrameUniforms, InstanceUniforms, InstanceUniforms) {
    let (width, height) = c.size;
    let aspect = width as f32 / height as f32;
    let bounds = c.bounds;
    let model = view::model_matrix(bounds, &p.placement);
    // World bounding sphere of the placed model.
    let centre_model = 0.5 * (bounds.0 + bounds.1);
    let centre = model.transform_point3(centre_model);
    let radius = (0.5 * (bounds.1 - bounds.0).length() * p.placement.scale).max(1e-4);
    let distance = (centre - p.camera.position).length();
    let near = (distance - 4.0 * radius).max(distance * 1e-3).max(1e-3);
    let far = (distance + 50.0 * radius).max(near * 2.0);
    let proj = view::projection(p.camera.vfov, aspect, near, far);
    let view_m = view::view_matrix(p.camera.pose, p.camera.position);
    let sun = p.lighting.sun_dir.normalize_or(Vec3::Z);
    let shadow = fit_shadow(p, c);
    let light = shadow.light_view_proj;
    // The ground plane: where the sun's shadow can fall and the sky's occlusion darkens it
    // (nothing when neither does).
    let ground =
        ground_rect(p, bounds, &shadow).map_or(Mat4::from_translation(p.placement.position) * Mat4::from_scale(Vec3::ZERO), |r| r.matrix());
    let (hs, hc) = c.env_heading.sin_cos();
    let priors = &c.priors;
    let frame = FrameUniforms {
        view_proj: mat(proj * view_m),
        view: mat(view_m),
        light_view_proj: mat(light),
        camera_pos: p.camera.position.to_array(),
        daylight: p.lighting.daylight,
        sun_dir: sun.to_array(),
        sunlight: p.lighting.sunlight,
        sky: priors.sky,
        occlusion_light: priors.light,
        ground: priors.ground,
        occlusion_shadow: priors.shadow,
        env_rotation: [hc, hs],
        env_exposure: c.exposure,
        reflection: p.lighting.reflection,
        eta: 1.0 / p.lighting.ior,
        shadow_opacity: p.lighting.shadow_opacity,
        live_depth: p.lighting.live_depth,
        tan_half_vfov: (0.5 * p.camera.vfov).tan(),
        aspect,
        shadow_map_size: shadow.map_size,
        _padding: [0; 2],
    };
    let instance = InstanceUniforms { model: mat(model), normal: mat(view::normal_matrix(&model)) };
    let ground = InstanceUniforms { model: mat(ground), normal: mat(Mat4::IDENTITY) };
    (frame, instance, ground)
}

/// The `Light` uniform of a frame's lighting: the sky's SH9 coefficients and the sun's colour
/// (alpha 0 and 1), tan of the sun's angular radius, the ground square of the sky-visibility
/// map under the model (world min, max), how dark the sky's occlusion makes the ground and the
/// colour of the sky's light on the ground (luminance 1), which the ground pass's coloured
/// shadow needs.
pub fn light_uniforms(l: &Lighting, (min, max): (Vec2, Vec2)) -> LightUniforms {
    let [r, g, b] = l.sun_colour;
    LightUniforms {
        sh: l.sky_sh.map(|[r, g, b]| [r, g, b, 0.0]),
        sun: [r, g, b, l.sun_angular_radius.tan()],
        ground_square: [min.x, min.y, max.x, max.y],
        ground_sky: {
            let [r, g, b] = crate::light::sh9::irradiance_colour(&l.sky_sh, Vec3::Z);
            [l.sky_occlusion, r, g, b]
        },
        ground: {
            let [r, g, b] = l.ground_radiance;
            [r, g, b, sun_share_on_ground(l)]
        },
    }
}

/// The sun's share of the light a horizontal ground gets in `l` (luminance): the sun's
/// E/π = sunlight · max(sun.z, 0) against the sky's daylight · Σ sky_sh_i Y_i(up); 0 without light.
pub fn sun_share_on_ground(l: &Lighting) -> f32 {
    let up = crate::light::sh9::basis(Vec3::Z);
    let sky: [f32; 3] = std::array::from_fn(|k| l.sky_sh.iter().zip(up).map(|(c, y)| c[k] * y).sum::<f32>().max(0.0));
    let sky = l.daylight * crate::colour::luminance_bt709(sky);
    let sun = l.sunlight * l.sun_dir.normalize_or_zero().z.max(0.0);
    if sun + sky > 0.0 { (sun / (sun + sky)).clamp(0.0, 1.0) } else { 0.0 }
}

/// The ground square whose sky visibility the ground pass samples, for a model with model-space
/// `bounds` placed by `placement` (scene::occlusion::ground_square): world min, max and height.
pub fn sky_square(bounds: (Vec3, Vec3), placement: &view::Placement) -> GroundRect {
    let (min, max, z) = occlusion::ground_square(bounds, view::model_matrix(bounds, placement));
    GroundRect { min, max, z }
}

/// The ground quad of a frame: the sun's receiver and, when the sky's occlusion is on, the
/// sky's square.
fn ground_rect(p: &FrameParams, bounds: (Vec3, Vec3), shadow: &shadow_fit::ShadowFit) -> Option<GroundRect> {
    let sky = (p.lighting.sky_occlusion > 0.0).then(|| sky_square(bounds, &p.placement));
    ground_quad(shadow.receiver, sky)
}

/// Where the ground pass's two parts can darken anything, as convex polygons (world x/y,
/// counter-clockwise): the sun's shadow (`shadow_fit::silhouette_outline`: the lookup can find
/// the sun blocked only inside) and the sky's occlusion (`shadow_fit::sky_region`: visible
/// only inside; None: anywhere on the quad).
#[derive(Clone, Copy, Debug, Default)]
pub struct GroundRegions<'a> {
    pub outline: &'a [Vec2],
    pub sky: Option<&'a [Vec2]>,
}

/// The ground pass's triangles for a frame whose shadow is `shadow` ([`fit_shadow`]): inside
/// the shadow's outline (within the ground quad) with the sun's shadow lookup; around it,
/// where the sky's occlusion is visible, without it (the convex hull of the two within the
/// quad, less the outline); nothing elsewhere, and no sky part when the sky's occlusion is off.
/// Only the sky's part, without the lookup, when the ground has no sun shadow (sun down, no
/// sunlight, no shadow opacity). `everywhere`: all of the quad with the lookup (the
/// full-shadow reference; the shader then skips the lookup itself where the ground has no sun
/// shadow, as it did before the split).
pub fn ground_mesh(
    p: &FrameParams,
    c: &FrameContext,
    shadow: &shadow_fit::ShadowFit,
    regions: GroundRegions,
    everywhere: bool,
) -> GroundMesh {
    use shadow_fit::{clip_convex, convex_hull, rect_polygon, split_convex};
    let Some(quad) = ground_rect(p, c.bounds, shadow) else {
        return GroundMesh::EMPTY;
    };
    let rect = rect_polygon(quad.min, quad.max);
    if everywhere {
        return GroundMesh::new(&quad, &split_convex(&[], &rect).1, &[]);
    }
    let sky = match regions.sky {
        _ if p.lighting.sky_occlusion <= 0.0 => Vec::new(),
        Some(r) if r.len() >= 3 => clip_convex(r, &rect),
        Some(_) => Vec::new(),
        None => rect.to_vec(),
    };
    let outline = regions.outline;
    if !(shadow.needed && p.lighting.shadow_opacity > 0.0) || outline.len() < 3 {
        return GroundMesh::new(&quad, &[], &split_convex(&[], &sky).1);
    }
    if sky.len() < 3 {
        return GroundMesh::new(&quad, &split_convex(outline, &rect).0, &[]);
    }
    let outer = clip_convex(&convex_hull(&[outline, &sky].concat()), &rect);
    let (shadowed, rest) = split_convex(outline, &outer);
    GroundMesh::new(&quad, &shadowed, &rest)
}

/// The ground quad the ground pass draws: where the sun's shadow can fall (`receiver`) and,
/// when the sky's occlusion darkens the ground, the sky-visibility square around the model.
pub fn ground_quad(receiver: Option<GroundRect>, sky: Option<GroundRect>) -> Option<GroundRect> {
    match (receiver, sky) {
        (Some(r), Some(s)) => Some(GroundRect { min: r.min.min(s.min), max: r.max.max(s.max), z: r.z }),
        (r, s) => r.or(s),
    }
}

/// The frame's shadow: the shadow camera fitted to the model, the ground quad where its shadow
/// can fall, its footprint on screen, and whether the shadow and ground passes have anything
/// to do (see `render::shadow_fit`).
pub fn fit_shadow(p: &FrameParams, c: &FrameContext) -> shadow_fit::ShadowFit {
    let (width, height) = c.size;
    let bounds = c.bounds;
    let model = view::model_matrix(bounds, &p.placement);
    let centre = model.transform_point3(0.5 * (bounds.0 + bounds.1));
    let radius = (0.5 * (bounds.1 - bounds.0).length() * p.placement.scale).max(1e-4);
    let distance = (centre - p.camera.position).length();
    let near = (distance - 4.0 * radius).max(distance * 1e-3).max(1e-3);
    let far = (distance + 50.0 * radius).max(near * 2.0);
    let view_proj =
        view::projection(p.camera.vfov, width as f32 / height as f32, near, far) * view::view_matrix(p.camera.pose, p.camera.position);
    let sun = p.lighting.sun_dir.normalize_or(Vec3::Z);
    shadow_fit::fit(
        bounds,
        model,
        (p.placement.position, centre, radius),
        (sun, p.lighting.sunlight),
        (view_proj, c.size),
        c.shadow_map_sizes,
    )
}

/// Which level of the model's level-of-detail chain a compositor draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Detail {
    /// Frames drawn one after another (the live view, `bench frame`): [`lod_level`] with triangles
    /// of at least `lod::MIN_TRIANGLE_AREA_PX`, where a frame's cost stops following the count.
    Frame,
    /// A still image (`previz composite`, the goldens, `bench accuracy`): [`lod_level`] with
    /// triangles down to `lod::STILL_MIN_TRIANGLE_AREA_PX` (one pixel of the frame drawn: one
    /// sample of a supersampled still, render::supersample). The frame's 2 px² keeps
    /// the whole frame within FLIP 0.01 of level 0 (tests/lod.rs) but shows on the models' own
    /// pixels against the path-traced references (docs/accuracy.md, thirteenth session).
    Still,
    /// Level 0 whatever the screen allows (the full-detail references).
    Full,
}

impl Detail {
    /// The smallest projected area per triangle (px²) a level is drawn for; 0 for level 0, whose
    /// triangles then always cover enough ([`lod_level`]).
    pub fn min_triangle_area_px(self) -> f32 {
        match self {
            Detail::Frame => lod::MIN_TRIANGLE_AREA_PX,
            Detail::Still => lod::STILL_MIN_TRIANGLE_AREA_PX,
            Detail::Full => 0.0,
        }
    }
}

/// The level of detail drawn for a model with model-space `bounds` and a chain with `errors`
/// (model units) and `triangles` per level, placed and seen as in `p`, rendered `height_px` rows
/// high: among the levels whose error projects under half a pixel (`scene::lod::select_level`),
/// the finest whose triangles cover at least `min_area_px` each of the model's projected
/// bounding sphere (`scene::lod::finest_worth_drawing`; [`Detail::min_triangle_area_px`]). Also
/// the distance to the model's bounding box (world units: no vertex is nearer) and the focal
/// length in pixels.
pub fn lod_level(
    errors: &[f32],
    triangles: &[usize],
    bounds: (Vec3, Vec3),
    p: &FrameParams,
    height_px: u32,
    min_area_px: f32,
) -> (usize, f32, f32) {
    // The camera in model space: the model matrix turns, scales uniformly and moves.
    let camera = view::model_matrix(bounds, &p.placement).inverse().transform_point3(p.camera.position);
    let scale = p.placement.scale.abs();
    let distance = lod::box_distance(camera, bounds) * scale;
    let focal = lod::focal_px(p.camera.vfov, height_px);
    let world: Vec<f32> = errors.iter().map(|e| e * scale).collect();
    let coarsest = lod::select_level(&world, distance, focal, lod::MAX_SCREEN_ERROR_PX);
    let area = model_area_px(bounds, p, height_px);
    (lod::finest_worth_drawing(triangles, coarsest, area, min_area_px), distance, focal)
}

/// The projected area in pixels of the bounding sphere of a model with model-space `bounds`
/// (centre the box's, radius half its diagonal), placed and seen as in `p`, rendered `height_px`
/// rows high (`scene::lod::sphere_area_px`).
pub fn model_area_px((lo, hi): (Vec3, Vec3), p: &FrameParams, height_px: u32) -> f32 {
    let camera = view::model_matrix((lo, hi), &p.placement).inverse().transform_point3(p.camera.position);
    let scale = p.placement.scale.abs();
    let focal = lod::focal_px(p.camera.vfov, height_px);
    lod::sphere_area_px(0.5 * (hi - lo).length() * scale, camera.distance(0.5 * (lo + hi)) * scale, focal)
}

/// The colour correction of a frame: from the environment's statistics (`source`) towards the
/// model's (`target`, or why it has none — every texel masked out, an error then). `target` is
/// asked only when a correction is on: the model's statistics are computed on demand.
pub fn colour_correction<'a>(
    settings: ColourSettings,
    source: &ColourStats,
    target: impl FnOnce() -> &'a std::result::Result<ColourStats, String>,
) -> Result<ColourCorrection> {
    if settings.method == TransferMethod::None {
        return Ok(ColourCorrection::identity());
    }
    match target() {
        Ok(target) => Ok(ColourCorrection::new(settings.method, settings.strength, source, target)),
        Err(why) => bail!("colour correction {} needs the model's colour statistics: {why}", settings.method.name()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::params::{Camera, Lighting, MaterialTerms};
    use crate::render::{LightingMethod, Placement};
    use glam::{Quat, Vec4};
    use std::f32::consts::{FRAC_PI_2, PI};

    /// A 2×2×2 cube whose base stands at (0, 0, −10), seen from the origin by a camera looking
    /// straight down (identity pose: camera −z = world −z) with a 90° vertical field of view
    /// into a 200×100 target. By hand: the box's centre is at (0, 0, −9), the bounding sphere's
    /// radius is √3 (half the 2×2×2 diagonal), so near = 9 − 4√3 and far = 9 + 50√3.
    fn scene(scale: f32) -> (FrameParams, FrameContext<'static>) {
        let p = FrameParams {
            camera: Camera { pose: Quat::IDENTITY, position: Vec3::ZERO, vfov: FRAC_PI_2 },
            method: LightingMethod::CubeRefraction,
            lighting: Lighting {
                sun_dir: Vec3::new(0.0, 0.0, 2.0),
                sunlight: 0.7,
                daylight: 0.3,
                material: MaterialTerms { ambient: 1.0, diffuse: 1.0, specular: 1.0, gloss: None },
                reflection: 0.25,
                ior: 1.5,
                shadow_opacity: 0.6,
                sky_occlusion: 0.0,
                live_depth: 2.0,
                sky_sh: std::array::from_fn(|i| [i as f32, 0.5, 0.25]),
                sky_radiance: crate::light::sh9::SkyRadiance::UNIFORM,
                ground_radiance: [0.2, 0.3, 0.4],
                sun_colour: [1.2, 0.9, 0.7],
                sun_angular_radius: 0.01,
            },
            placement: Placement { position: Vec3::new(0.0, 0.0, -10.0), rotation: Vec3::ZERO, scale },
            colour: ColourSettings::NONE,
        };
        let c = FrameContext {
            bounds: (Vec3::splat(-1.0), Vec3::splat(1.0)),
            priors: HemispherePriors { sky: [0.1, 0.2, 0.3], ground: [0.4, 0.5, 0.6], light: 0.9, shadow: 0.05 },
            exposure: 2.0,
            env_heading: FRAC_PI_2,
            size: (200, 100),
            shadow_map_sizes: &[1024],
        };
        (p, c)
    }

    fn clip(m: [[f32; 4]; 4], world: Vec3) -> Vec3 {
        let v = Mat4::from_cols_array_2d(&m) * Vec4::new(world.x, world.y, world.z, 1.0);
        v.truncate() / v.w
    }

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() < tol
    }

    #[test]
    fn camera_projection_against_hand_computed_points() {
        let (p, c) = scene(1.0);
        let (f, _, _) = frame_uniforms(&p, &c);
        let r = 3f32.sqrt();
        let (near, far) = (9.0 - 4.0 * r, 9.0 + 50.0 * r);
        // On the view axis: the near and far distances land on depth 0 and 1.
        assert!(close(clip(f.view_proj, Vec3::new(0.0, 0.0, -near)), Vec3::ZERO, 1e-5));
        assert!(close(clip(f.view_proj, Vec3::new(0.0, 0.0, -far)), Vec3::new(0.0, 0.0, 1.0), 1e-5));
        // tan(45°) = 1: at 9 m the half-height is 9 m and the half-width (aspect 2) is 18 m.
        // Camera +x is world +x and camera +y is world +y for the identity pose.
        assert!(close(clip(f.view_proj, Vec3::new(18.0, 0.0, -9.0)).truncate().extend(0.0), Vec3::X, 1e-5));
        assert!(close(clip(f.view_proj, Vec3::new(0.0, 9.0, -9.0)).truncate().extend(0.0), Vec3::Y, 1e-5));
        assert!((f.tan_half_vfov - 1.0).abs() < 1e-6);
        assert_eq!(f.aspect, 2.0);
        assert_eq!(f.camera_pos, [0.0; 3]);
        assert_eq!(f.view, Mat4::IDENTITY.to_cols_array_2d());
    }

    #[test]
    fn sun_camera_encloses_the_model_sphere() {
        let (p, c) = scene(1.0);
        let (f, _, _) = frame_uniforms(&p, &c);
        // The sun direction (0, 0, 2) is normalised.
        assert_eq!(f.sun_dir, [0.0, 0.0, 1.0]);
        // Orthographic from 2r above the centre (0, 0, −9), depth r..3r: the centre is at depth
        // 0.5, the sphere's top at 0 and its bottom at 1. Across the sun the map fits the box,
        // not the sphere: the box's side 1 m to the East is the right edge, 1 m North the top
        // (looking down with North up).
        let r = 3f32.sqrt();
        let centre = Vec3::new(0.0, 0.0, -9.0);
        assert!(close(clip(f.light_view_proj, centre), Vec3::new(0.0, 0.0, 0.5), 1e-5));
        assert!(close(clip(f.light_view_proj, centre + Vec3::Z * r), Vec3::ZERO, 1e-5));
        assert!(close(clip(f.light_view_proj, centre - Vec3::Z * r), Vec3::Z, 1e-5));
        assert!(close(clip(f.light_view_proj, centre + Vec3::X), Vec3::new(1.0, 0.0, 0.5), 1e-5));
        assert!(close(clip(f.light_view_proj, centre + Vec3::Y), Vec3::new(0.0, 1.0, 0.5), 1e-5));
        // No sun direction at all falls back to straight overhead.
        let mut p0 = p;
        p0.lighting.sun_dir = Vec3::ZERO;
        assert_eq!(frame_uniforms(&p0, &c).0.sun_dir, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn scalars_pass_through_or_follow_their_formula() {
        let (p, c) = scene(1.0);
        let (f, _, _) = frame_uniforms(&p, &c);
        // Heading 90°: (cos, sin) = (0, 1).
        assert!(f.env_rotation[0].abs() < 1e-6 && (f.env_rotation[1] - 1.0).abs() < 1e-6);
        // eta = 1 / ior = 1 / 1.5.
        assert!((f.eta - 2.0 / 3.0).abs() < 1e-6);
        assert_eq!((f.shadow_map_size, f.env_exposure), (1024, 2.0));
        assert_eq!((f.sunlight, f.daylight, f.reflection, f.shadow_opacity, f.live_depth), (0.7, 0.3, 0.25, 0.6, 2.0));
        assert_eq!((f.sky, f.ground, f.occlusion_light, f.occlusion_shadow), ([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], 0.9, 0.05));
        // Heading 180°: (−1, 0).
        let c = FrameContext { env_heading: PI, ..c };
        let rot = frame_uniforms(&p, &c).0.env_rotation;
        assert!((rot[0] + 1.0).abs() < 1e-6 && rot[1].abs() < 1e-6);
    }

    #[test]
    fn the_light_uniform_carries_the_sky_and_the_suns_colour_and_size() {
        let (p, _) = scene(1.0);
        let mut lighting = p.lighting;
        lighting.sky_occlusion = 0.4;
        let l = light_uniforms(&lighting, (Vec2::new(-1.0, -2.0), Vec2::new(3.0, 4.0)));
        assert_eq!(l.ground_square, [-1.0, -2.0, 3.0, 4.0]);
        assert_eq!(l.ground_sky[0], 0.4);
        // The sky's colour on the ground: the SH9 sum facing up (sh[0], sh[2], sh[6] only).
        let up = crate::light::sh9::basis(Vec3::Z);
        let e: [f32; 3] = std::array::from_fn(|k| [0, 2, 6].iter().map(|&i| lighting.sky_sh[i][k] * up[i]).sum::<f32>().max(0.0));
        let lum = crate::colour::luminance_bt709(e);
        for (got, ek) in l.ground_sky[1..].iter().zip(e) {
            let want = if lum > 0.0 { ek / lum } else { 1.0 };
            assert!((got - want).abs() < 1e-5, "{:?}", l.ground_sky);
        }
        assert_eq!(l.sh[3], [3.0, 0.5, 0.25, 0.0]);
        assert_eq!(&l.ground[..3], &[0.2, 0.3, 0.4]);
        // The sun's share on the ground: sun E/π 0.7 from straight up (sun_dir (0, 0, 2)) against
        // the sky's 0.3 · luminance of Σ sh_i Y_i(up) (the same sum as above, unnormalised).
        let sky = 0.3 * lum;
        assert!((l.ground[3] - 0.7 / (0.7 + sky)).abs() < 1e-5, "{} vs {}", l.ground[3], 0.7 / (0.7 + sky));
        // tan(0.01) = 0.010000333 (series x + x³/3).
        assert_eq!(&l.sun[..3], &[1.2, 0.9, 0.7]);
        assert!((l.sun[3] - 0.010_000_333).abs() < 1e-8);
    }

    #[test]
    fn model_and_ground_transforms() {
        // Scale 2: the box is 4 m high, its base centre at (0, 0, −10); the model's +y (up)
        // becomes world +z, its +z (front) world −y (South).
        let (p, c) = scene(2.0);
        let (_, instance, ground) = frame_uniforms(&p, &c);
        let m = Mat4::from_cols_array_2d(&instance.model);
        assert!(close(m.transform_point3(Vec3::new(0.0, -1.0, 0.0)), Vec3::new(0.0, 0.0, -10.0), 1e-5));
        assert!(close(m.transform_point3(Vec3::new(1.0, 1.0, 1.0)), Vec3::new(2.0, -2.0, -6.0), 1e-5));
        // Normal matrix = inverse transpose: a uniform scale of 2 halves normals.
        let n = Mat4::from_cols_array_2d(&instance.normal);
        assert!(close(n.transform_vector3(Vec3::Y), Vec3::new(0.0, 0.0, 0.5), 1e-6));
        // The ground: with the sun overhead the shadow falls on the box's own 4×4 m footprint,
        // in the plane of the model's base.
        let g = Mat4::from_cols_array_2d(&ground.model);
        assert!(close(g.transform_point3(Vec3::new(1.0, 1.0, 0.0)), Vec3::new(2.0, 2.0, -10.0), 1e-5));
        assert!(close(g.transform_point3(Vec3::new(-1.0, -1.0, 0.0)), Vec3::new(-2.0, -2.0, -10.0), 1e-5));
        // A sun 45° up in the South (direction (0, −1, 1)/√2): the 4 m tall box's shadow reaches
        // 4 m further North.
        let mut south = p;
        south.lighting.sun_dir = Vec3::new(0.0, -1.0, 1.0);
        let g = Mat4::from_cols_array_2d(&frame_uniforms(&south, &c).2.model);
        assert!(close(g.transform_point3(Vec3::new(1.0, 1.0, 0.0)), Vec3::new(2.0, 6.0, -10.0), 1e-4));
        assert!(close(g.transform_point3(Vec3::new(-1.0, -1.0, 0.0)), Vec3::new(-2.0, -2.0, -10.0), 1e-4));
        assert_eq!(ground.normal, Mat4::IDENTITY.to_cols_array_2d());
    }

    #[test]
    fn the_ground_quad_holds_the_suns_shadow_and_the_skys_square() {
        // The 2×2×2 cube scaled by 2 (4 m high) stands at (0, 0, −10): its sky square is its
        // 4×4 m footprint widened by twice its height (8 m) on every side.
        let (mut p, c) = scene(2.0);
        let sky = sky_square(c.bounds, &p.placement);
        assert!(sky.min.abs_diff_eq(Vec2::splat(-10.0), 1e-4) && sky.max.abs_diff_eq(Vec2::splat(10.0), 1e-4), "{sky:?}");
        assert!((sky.z + 10.0).abs() < 1e-5);
        // With the sky's occlusion on, the ground quad is that square even with the sun
        // overhead (its receiver, the footprint, lies inside it) ...
        p.lighting.sky_occlusion = 0.5;
        let g = Mat4::from_cols_array_2d(&frame_uniforms(&p, &c).2.model);
        assert!(close(g.transform_point3(Vec3::new(1.0, 1.0, 0.0)), Vec3::new(10.0, 10.0, -10.0), 1e-4));
        assert!(close(g.transform_point3(Vec3::new(-1.0, -1.0, 0.0)), Vec3::new(-10.0, -10.0, -10.0), 1e-4));
        // ... and a long shadow reaching past it widens it (a sun 10° up in the South: the
        // shadow of the 4 m box reaches 4 / tan 10° = 22.7 m North of the box's far side).
        let el = 10f32.to_radians();
        p.lighting.sun_dir = Vec3::new(0.0, -el.cos(), el.sin());
        let r = ground_quad(fit_shadow(&p, &c).receiver, Some(sky)).unwrap();
        assert!((r.max.y - (2.0 + 4.0 / el.tan())).abs() < 1e-3 && r.min == sky.min && r.max.x == sky.max.x, "{r:?}");
        // The sun below the horizon: the sky's square alone; neither: nothing.
        assert_eq!(ground_quad(None, Some(sky)), Some(sky));
        assert_eq!(ground_quad(None, None), None);
    }

    #[test]
    fn the_ground_mesh_looks_up_the_shadow_only_where_it_can_fall() {
        // The 4 m cube under a sun 30° up in the South-East, the sky's occlusion on: the quad
        // (the unit square, area 4) is split into the shadow's outline and the rest.
        let (mut p, c) = scene(2.0);
        p.camera.position = Vec3::new(0.0, -30.0, 10.0);
        p.camera.pose = view::camera_pose(0.0, -0.3, 0.0);
        let (el, az) = (30f32.to_radians(), 135f32.to_radians());
        p.lighting.sun_dir = Vec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
        p.lighting.sky_occlusion = 0.5;
        let shadow = fit_shadow(&p, &c);
        assert!(shadow.needed, "{shadow:?}");
        let area = |v: &[[f32; 2]]| -> f32 {
            v.chunks_exact(3).map(|t| 0.5 * (Vec2::from(t[1]) - Vec2::from(t[0])).perp_dot(Vec2::from(t[2]) - Vec2::from(t[0])).abs()).sum()
        };
        // The cube's corners as its vertices, in the frame's own shadow map.
        let outline_of = |p: &FrameParams| {
            let (f, instance, _) = frame_uniforms(p, &c);
            let lvp = Mat4::from_cols_array_2d(&f.light_view_proj);
            let model = Mat4::from_cols_array_2d(&instance.model);
            let corners = shadow_fit::box_corners(c.bounds, Mat4::IDENTITY);
            shadow_fit::silhouette_outline(lvp, (model, corners), p.placement.position.z, (1024, 0.01, 2.0 * 3f32.sqrt()))
        };
        let outline = outline_of(&p);
        let regions = GroundRegions { outline: &outline, sky: None };
        let m = ground_mesh(&p, &c, &shadow, regions, false);
        let (lit, rest) = (m.shadowed as usize, (m.shadowed + m.sky_only) as usize);
        let (a_lit, a_rest) = (area(&m.vertices[..lit]), area(&m.vertices[lit..rest]));
        assert!((a_lit + a_rest - 4.0).abs() < 1e-3, "{a_lit} + {a_rest}");
        // The sky's square is the cube's footprint widened by 8 m on every side (20 m wide); the
        // shadow (the cube and 4 m / tan 30° = 6.9 m of shadow to the North-West) is a small
        // part of it.
        assert!(a_lit > 0.05 && a_lit < 1.0, "{a_lit}");
        // The sky's occlusion visible only in a square of 4 x 4 m around the cube (0.16 of the
        // unit square's 4): the rest is the hull of it and the outline, less the outline.
        let near = shadow_fit::rect_polygon(Vec2::new(-2.0, -2.0), Vec2::new(2.0, 2.0));
        let m = ground_mesh(&p, &c, &shadow, GroundRegions { outline: &outline, sky: Some(&near) }, false);
        let (lit2, all) = (m.shadowed as usize, (m.shadowed + m.sky_only) as usize);
        assert!((area(&m.vertices[..lit2]) - a_lit).abs() < 1e-4, "{}", area(&m.vertices[..lit2]));
        let quad = ground_rect(&p, c.bounds, &shadow).unwrap();
        let h = 0.5 * (quad.max - quad.min);
        let to_unit = |q: Vec2| (q - 0.5 * (quad.min + quad.max)) / h;
        let hull = shadow_fit::convex_hull(&[outline.clone(), near.to_vec()].concat());
        let hull_unit: Vec<Vec2> = hull.iter().map(|&q| to_unit(q)).collect();
        let hull_area = 0.5 * (0..hull_unit.len()).map(|i| hull_unit[i].perp_dot(hull_unit[(i + 1) % hull_unit.len()])).sum::<f32>();
        assert!((area(&m.vertices[..all]) - hull_area).abs() < 1e-3 && hull_area < 1.0, "{} vs {hull_area}", area(&m.vertices[..all]));
        // Nowhere visible: only the outline.
        let m = ground_mesh(&p, &c, &shadow, GroundRegions { outline: &outline, sky: Some(&[]) }, false);
        assert!(m.sky_only == 0 && (area(&m.vertices[..m.shadowed as usize]) - a_lit).abs() < 1e-4);
        // Without the sky's occlusion only the outline is drawn; the sun down: only the rest;
        // the reference: all of it with the lookup.
        p.lighting.sky_occlusion = 0.0;
        let m = ground_mesh(&p, &c, &fit_shadow(&p, &c), regions, false);
        assert!(m.shadowed > 0 && m.sky_only == 0, "{} {}", m.shadowed, m.sky_only);
        p.lighting.sky_occlusion = 0.5;
        let all = ground_mesh(&p, &c, &shadow, regions, true);
        assert!(all.sky_only == 0 && (area(&all.vertices[..all.shadowed as usize]) - 4.0).abs() < 1e-4);
        p.lighting.sun_dir = Vec3::new(0.0, 0.9, -0.1);
        let m = ground_mesh(&p, &c, &fit_shadow(&p, &c), GroundRegions { outline: &[], sky: None }, false);
        assert!(m.shadowed == 0 && (area(&m.vertices[..m.sky_only as usize]) - 4.0).abs() < 1e-4);
    }

    #[test]
    fn the_level_follows_the_distance_and_the_scale() {
        // Camera at the origin, 90° vertical field of view, 200 rows: focal = 100 px. The 2 m
        // cube stands on z = −10 below the camera: its top face, the nearest point, is 8 m away
        // at scale 1 (its bounding sphere's would be 9 − √3 = 7.27 m).
        let (p, c) = scene(1.0);
        let errors = [0.0, 0.01, 0.036, 0.1];
        // Triangles far under a pixel each at every level: the error alone decides.
        let dense = [1 << 30, 1 << 29, 1 << 28, 1 << 27];
        let lod_level = |e: &[f32], b, p: &FrameParams, h| lod_level(e, &dense, b, p, h, lod::MIN_TRIANGLE_AREA_PX);
        let (level, distance, focal) = lod_level(&errors, c.bounds, &p, 200);
        assert!((focal - 100.0).abs() < 1e-3 && (distance - 8.0).abs() < 1e-4, "{focal} {distance}");
        // 0.036 * 100 / 8 = 0.45 px < 0.5 (at the sphere's 7.27 m: 0.50, too coarse); 0.1 →
        // 1.25 px.
        assert_eq!(level, 2);
        // Scale 2: the errors double (0.072 m → 0.2 m) and the top face is nearer (the base stays
        // on z = −10, the top at −6): 0.02 * 100 / 6 = 0.33 px, 0.072 → 1.2 px.
        assert_eq!(lod_level(&errors, c.bounds, &scene(2.0).0, 200).0, 1);
        // Twice the rows: twice the focal length, one level finer (0.036 → 0.9 px).
        assert_eq!(lod_level(&errors, c.bounds, &p, 400).0, 1);
        // A camera inside the box draws level 0.
        let mut inside = p;
        inside.camera.position = inside.placement.position + Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(lod_level(&errors, c.bounds, &inside, 200).0, 0);
    }

    #[test]
    fn the_level_keeps_triangles_that_cover_pixels() {
        // The cube of `scene(1.0)`: bounding sphere radius √3 about (0, 0, −9), 9 m from the
        // camera, focal 100 px: its disc's radius is 100·√3 / √(81 − 3) px, area
        // π·30000/78 = 1208.3 px². Level 2 is the coarsest within half a pixel
        // (the_level_follows_the_distance_and_the_scale).
        let (p, c) = scene(1.0);
        let errors = [0.0, 0.01, 0.036, 0.1];
        let area = PI * 30000.0 / 78.0;
        let fits = (area / lod::MIN_TRIANGLE_AREA_PX).floor() as usize;
        // Level 1's triangles cover the minimum each, level 0's a quarter of it: level 1.
        assert_eq!(lod_level(&errors, &[4 * fits, fits, fits / 2, fits / 4], c.bounds, &p, 200, lod::MIN_TRIANGLE_AREA_PX).0, 1);
        // Every level's triangles large enough: level 0, whatever the error allows.
        assert_eq!(lod_level(&errors, &[fits, fits / 2, fits / 4, fits / 8], c.bounds, &p, 200, lod::MIN_TRIANGLE_AREA_PX).0, 0);
        // None large enough: the coarsest within the error, level 2 (not 3).
        assert_eq!(lod_level(&errors, &[8 * fits, 4 * fits, 2 * fits, fits], c.bounds, &p, 200, lod::MIN_TRIANGLE_AREA_PX).0, 2);
    }

    #[test]
    fn colour_correction_needs_the_model_statistics_only_when_on() {
        let stats = ColourStats::from_linear(&[[0.2, 0.3, 0.4], [0.5, 0.5, 0.5]]).unwrap();
        let none = colour_correction(ColourSettings::NONE, &stats, || panic!("no correction needs no statistics")).unwrap();
        assert_eq!(bytemuck::bytes_of(&none), bytemuck::bytes_of(&ColourCorrection::identity()));
        let on = ColourSettings { method: TransferMethod::ALL[1], strength: 1.0 };
        let masked = Err("all masked".to_string());
        let err = colour_correction(on, &stats, || &masked).unwrap_err();
        assert!(format!("{err:#}").contains("all masked"), "{err:#}");
    }
}
