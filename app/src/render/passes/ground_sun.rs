//! The ground's sun visibility in ground space (step 2c of DESIGN.md "One frame"): where the
//! ground pass would look the soft shadow up (shaders/frame.wgsl `sun_visibility_soft`, 14
//! texture calls per pixel), a frame drawn one after another samples it once from a texture this
//! pass draws from the same shadow map, over a rectangle round the shadow's region on the ground
//! with about a texel per pixel where the ground is nearest the camera. It is drawn again only
//! when the map, the sun's size, the region or the view's need of texels changes
//! ([`keeps`]), so a kept map keeps it too; while the map moves (redrawn frame after frame) the
//! ground looks the sun up instead, as the model's sun per vertex does. One texture of
//! [`BAKE_SIDE`]² (or the device's largest 2D texture, if smaller) allocated once: a bake draws
//! into its corner.

use crate::gpu::build;
use crate::render::pipelines::{PipelineSpec, Pipelines, pipeline_into};
use crate::render::shaders::Technique;
use crate::render::shadow_fit::ShadowDrawn;
use crate::render::uniforms::GroundSunUniforms;
use glam::{Mat4, Vec2, Vec4Swizzles};
use wgpu::ShaderStages;

/// Side of the ground-sun texture (texels); a region that needs more along either axis is
/// looked up per pixel instead (a still many times the screen, a camera on the ground).
pub const BAKE_SIDE: u32 = 2048;
/// Format of the ground-sun texture: the visibility, 0..1, in half floats (11 bits: the
/// ground's loss rounds below an 8-bit level).
pub const BAKE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;
/// Texels per pixel a bake draws over what the view needs at the region's nearest point, and
/// the most a kept bake may hold before it is drawn again at the lower density: moving the
/// camera a little keeps it.
pub const BAKE_MARGIN: f32 = 1.25;
pub const BAKE_EXCESS: f32 = 2.5;
/// The rectangle a bake draws is the region's bounds widened by this share of its size on each
/// side, so that a region that moves a little (a kept map's outline against a quad that follows
/// the sun) stays inside it.
pub const BAKE_WIDEN: f32 = 0.02;

/// What the frame's ground needs of a bake: the rectangle round the region where it looks the
/// sun up (world x, y on the plane z) and the texels per metre along x and y it takes for a texel
/// per pixel where the view is densest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Need {
    pub min: Vec2,
    pub max: Vec2,
    pub z: f32,
    pub per_metre: Vec2,
}

/// What a bake holds: drawn from shadow map `map` holding `drawn`, for a sun of angular radius
/// tan = `tan_radius`, over `min`..`max` on the plane `z`, `texels` across and along.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bake {
    pub map: usize,
    pub drawn: ShadowDrawn,
    pub tan_radius: f32,
    pub min: Vec2,
    pub max: Vec2,
    pub z: f32,
    pub texels: [u32; 2],
    /// Side of the texture it is drawn into.
    pub side: u32,
}

impl Bake {
    /// Texels per metre along x and y.
    pub fn per_metre(&self) -> Vec2 {
        Vec2::new(self.texels[0] as f32, self.texels[1] as f32) / (self.max - self.min).max(Vec2::splat(1e-6))
    }

    /// The shader's `GroundSun` uniform for this bake.
    pub fn uniforms(&self) -> GroundSunUniforms {
        GroundSunUniforms {
            square: [self.min.x, self.min.y, self.max.x, self.max.y],
            texels: [self.texels[0] as f32, self.texels[1] as f32, self.z, self.side as f32],
        }
    }
}

/// Where world point `p` on the plane z = `z` lands for a camera `view_proj` rendering `size`
/// pixels: pixels from the centre of the view, or None behind the camera.
fn screen(p: Vec2, z: f32, view_proj: Mat4, (width, height): (u32, u32)) -> Option<Vec2> {
    let clip = view_proj * p.extend(z).extend(1.0);
    (clip.w > 1e-6).then(|| clip.xy() / clip.w * Vec2::new(0.5 * width as f32, 0.5 * height as f32))
}

/// Pixels per metre along world x and y on the plane z = `z` at `p` for a camera `view_proj`
/// rendering `size` pixels (the derivative of the projection), or None behind the camera.
pub fn pixels_per_metre(p: Vec2, z: f32, view_proj: Mat4, size: (u32, u32)) -> Option<Vec2> {
    let screen = |q: Vec2| screen(q, z, view_proj, size);
    // Central differences a millimetre apart: exact to rounding for the projection's curvature
    // at any distance a frame shows.
    let h = 1e-3;
    let along = |d: Vec2| Some((screen(p + d * h)? - screen(p - d * h)?).length() / (2.0 * h));
    Some(Vec2::new(along(Vec2::X)?, along(Vec2::Y)?))
}

/// The part of the rectangle `min`..`max` on the plane z = `z` that a camera `view_proj` shows
/// (clipped to the view's four side planes in clip space, Sutherland–Hodgman), as world x, y.
pub fn on_screen(min: Vec2, max: Vec2, z: f32, view_proj: Mat4) -> Vec<Vec2> {
    let corners = [min, Vec2::new(max.x, min.y), max, Vec2::new(min.x, max.y)];
    let mut polygon: Vec<(Vec2, glam::Vec4)> = corners.iter().map(|&p| (p, view_proj * p.extend(z).extend(1.0))).collect();
    // Inside: w ± x ≥ 0 and w ± y ≥ 0.
    let planes = [
        glam::Vec4::new(1.0, 0.0, 0.0, 1.0),
        glam::Vec4::new(-1.0, 0.0, 0.0, 1.0),
        glam::Vec4::new(0.0, 1.0, 0.0, 1.0),
        glam::Vec4::new(0.0, -1.0, 0.0, 1.0),
    ];
    for plane in planes {
        let mut clipped = Vec::with_capacity(polygon.len() + 1);
        for (k, &(p, c)) in polygon.iter().enumerate() {
            let (q, d) = polygon[(k + 1) % polygon.len()];
            let (a, b) = (plane.dot(c), plane.dot(d));
            if a >= 0.0 {
                clipped.push((p, c));
            }
            if (a >= 0.0) != (b >= 0.0) {
                let t = a / (a - b);
                clipped.push((p.lerp(q, t), c.lerp(d, t)));
            }
        }
        polygon = clipped;
        if polygon.is_empty() {
            break;
        }
    }
    polygon.into_iter().filter(|(_, c)| c.w > 1e-6).map(|(p, _)| p).collect()
}

/// What the ground needs of a bake to cover `points` (world x, y on the plane z = `z`: the
/// region where it looks the sun up) seen through `view_proj` at `size` pixels: their bounds
/// widened by [`BAKE_WIDEN`], and the largest pixels per metre along each axis over the corners
/// of the part of that rectangle on screen ([`on_screen`]: the density grows towards the camera,
/// and a region reaching below the frame would otherwise ask for texels no pixel samples). None
/// for no region, or none of it on screen.
pub fn need(points: &[Vec2], z: f32, view_proj: Mat4, size: (u32, u32)) -> Option<Need> {
    let first = *points.first()?;
    let (lo, hi) = points.iter().fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let widen = (hi - lo) * BAKE_WIDEN;
    let (min, max) = (lo - widen, hi + widen);
    let shown = on_screen(min, max, z, view_proj);
    let per_metre = shown.iter().filter_map(|&p| pixels_per_metre(p, z, view_proj, size)).reduce(Vec2::max)?;
    per_metre.is_finite().then_some(Need { min, max, z, per_metre })
}

/// Whether `held` serves a frame that needs `need` from shadow map `map` holding `drawn` with a
/// sun of angular radius tan = `tan_radius`: the same map, contents and sun, a rectangle that
/// contains the region's, and between the texels per metre it needs and [`BAKE_EXCESS`] times
/// that along each axis.
pub fn keeps(held: &Bake, need: &Need, (map, drawn, tan_radius): (usize, &ShadowDrawn, f32)) -> bool {
    let density = held.per_metre();
    held.map == map
        && held.drawn == *drawn
        && held.tan_radius == tan_radius
        && held.z == need.z
        && held.min.cmple(need.min).all()
        && held.max.cmpge(need.max).all()
        && density.cmpge(need.per_metre).all()
        && density.cmple(need.per_metre * BAKE_EXCESS).all()
}

/// The bake to draw for `need` from map `map` holding `drawn` into a `side`² texture:
/// [`BAKE_MARGIN`] times the texels per metre it needs, or just what it needs where that would
/// pass `side`; None where even that would (the ground then looks the sun up per pixel).
pub fn plan(need: &Need, (map, drawn, tan_radius): (usize, &ShadowDrawn, f32), side: u32) -> Option<Bake> {
    let extent = need.max - need.min;
    let texels = |scale: f32| {
        let t = (extent * need.per_metre * scale).ceil().max(Vec2::ONE);
        (t.max_element() <= side as f32).then_some([t.x as u32, t.y as u32])
    };
    let texels = texels(BAKE_MARGIN).or_else(|| texels(1.0))?;
    Some(Bake { map, drawn: *drawn, tan_radius, min: need.min, max: need.max, z: need.z, texels, side })
}

/// The ground-sun pipeline and the layout of its bind group: frame, light, a shadow map with its
/// comparison and gather samplers, the `GroundSun` uniform.
pub fn pipeline(device: &wgpu::Device) -> crate::render::pipelines::PassPipeline {
    let fs = ShaderStages::FRAGMENT;
    let layout = build::layout(
        device,
        "ground sun",
        &[
            build::uniform(0, fs),
            build::uniform(1, fs),
            build::depth_texture_entry(2, fs),
            build::sampler_entry(3, fs, wgpu::SamplerBindingType::Comparison),
            build::sampler_entry(4, fs, wgpu::SamplerBindingType::NonFiltering),
            build::uniform(5, fs),
        ],
    );
    let spec = PipelineSpec {
        technique: Technique::GroundSun,
        layouts: &[&layout],
        vertex_buffers: &[],
        depth: None,
        samples: 1,
        blend: Some(None),
    };
    let pipeline = pipeline_into(device, spec, BAKE_FORMAT);
    crate::render::pipelines::PassPipeline { layout, pipeline }
}

pub struct GroundSunPass {
    pipeline: wgpu::RenderPipeline,
    /// One per shadow map (in the order of `ShadowPass::maps`).
    bind_groups: Vec<wgpu::BindGroup>,
    /// The visibility, `side`², [`BAKE_FORMAT`].
    view: wgpu::TextureView,
    /// [`BAKE_SIDE`], or the device's largest 2D texture if smaller.
    side: u32,
    /// The `GroundSun` uniform: the held bake's rectangle and texels (read by the ground pass).
    uniform: wgpu::Buffer,
    /// What the texture holds (None: nothing yet, or not known after a failed frame).
    held: Option<Bake>,
    /// The bake the next encoded frame draws.
    pending: Option<Bake>,
    /// How many bakes were planned, each drawn by its frame (the tests count them).
    pub bakes: usize,
}

impl GroundSunPass {
    /// Reads the Frame and Light uniform buffers and one of the sun's `shadow_maps` per frame.
    pub fn new(
        device: &wgpu::Device,
        pipelines: &Pipelines,
        (frame, light): (&wgpu::Buffer, &wgpu::Buffer),
        shadow_maps: &[wgpu::TextureView],
    ) -> Self {
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let side = BAKE_SIDE.min(device.limits().max_texture_dimension_2d);
        let texture = build::texture(device, "ground sun", (side, side, 1), BAKE_FORMAT, 1, usage);
        let view = texture.create_view(&Default::default());
        let uniform = build::uniform_buffer::<GroundSunUniforms>(device, "ground sun");
        let bind_groups = shadow_maps
            .iter()
            .map(|map| {
                build::bind_group(
                    device,
                    "ground sun",
                    &pipelines.ground_sun.layout,
                    &[
                        frame.as_entire_binding(),
                        light.as_entire_binding(),
                        wgpu::BindingResource::TextureView(map),
                        wgpu::BindingResource::Sampler(&pipelines.shadow_sampler),
                        wgpu::BindingResource::Sampler(&pipelines.shadow_gather_sampler),
                        uniform.as_entire_binding(),
                    ],
                )
            })
            .collect();
        GroundSunPass {
            pipeline: pipelines.ground_sun.pipeline.clone(),
            bind_groups,
            view,
            side,
            uniform,
            held: None,
            pending: None,
            bakes: 0,
        }
    }

    /// The texture the ground pass samples.
    pub fn view(&self) -> &wgpu::TextureView {
        &self.view
    }

    /// The `GroundSun` uniform buffer the ground pass reads.
    pub fn uniform(&self) -> &wgpu::Buffer {
        &self.uniform
    }

    /// Decide this frame's ground sun for a ground that needs `need` (None: it looks the sun up
    /// per pixel, or draws no sun) from shadow map `map` holding `drawn`: keep the held bake,
    /// plan a new one (drawn by [`GroundSunPass::encode`]) or none. Returns whether the ground
    /// samples the texture this frame.
    pub fn prepare(&mut self, queue: &wgpu::Queue, need: Option<&Need>, source: (usize, &ShadowDrawn, f32)) -> bool {
        self.pending = None;
        let Some(need) = need else { return false };
        if self.held.as_ref().is_some_and(|held| keeps(held, need, source)) {
            return true;
        }
        let Some(bake) = plan(need, source, self.side) else { return false };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&bake.uniforms()));
        self.pending = Some(bake);
        self.held = Some(bake);
        self.bakes += 1;
        true
    }

    /// Whether the next encoded frame draws a bake.
    pub fn pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Forget what the texture holds (after a failed frame, or new shadow maps' contents).
    pub fn forget(&mut self) {
        self.held = None;
        self.pending = None;
    }

    /// Draw the bake [`GroundSunPass::prepare`] planned for this frame, if any, into the
    /// texture's corner.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>) {
        let Some(bake) = self.pending else { return };
        let mut pass = build::clear_pass(encoder, "ground sun", &self.view, timestamps);
        pass.set_viewport(0.0, 0.0, bake.texels[0] as f32, bake.texels[1] as f32, 0.0, 1.0);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_groups[bake.map], &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn drawn() -> ShadowDrawn {
        ShadowDrawn { light_view_proj: Mat4::IDENTITY, model: Mat4::IDENTITY, level: 0 }
    }

    /// A camera at `eye` looking at `at` (z up), 60° vertical field of view, 960×640.
    fn camera(eye: Vec3, at: Vec3) -> Mat4 {
        crate::render::view::projection(60f32.to_radians(), 1.5, 0.1, 100.0) * glam::camera::rh::view::look_at_mat4(eye, at, Vec3::Z)
    }

    #[test]
    fn the_density_is_the_focal_length_over_the_distance_face_on() {
        // Looking straight down from 5 m: a metre on the ground at the centre spans f / 5 pixels,
        // f = 320 / tan 30° = 554.26 px (640 rows, 60°), along either axis.
        let vp = crate::render::view::projection(60f32.to_radians(), 1.5, 0.1, 100.0)
            * glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y);
        let d = pixels_per_metre(Vec2::ZERO, 0.0, vp, (960, 640)).unwrap();
        let f = 320.0 / 30f32.to_radians().tan();
        assert!((d.x - f / 5.0).abs() < 0.01 && (d.y - f / 5.0).abs() < 0.01, "{d} vs {}", f / 5.0);
        // Seen at 30° from the horizon from 10 m away: across the view f / 10, along it
        // foreshortened by sin 30° (to first order): f / 10 · 0.5.
        let eye = Vec3::new(0.0, -10.0 * 30f32.to_radians().cos(), 10.0 * 30f32.to_radians().sin());
        let d = pixels_per_metre(Vec2::ZERO, 0.0, camera(eye, Vec3::ZERO), (960, 640)).unwrap();
        assert!((d.x - f / 10.0).abs() < 0.01, "{d}");
        assert!((d.y - 0.5 * f / 10.0).abs() < 0.01, "{d}");
        // Behind the camera: none.
        assert!(pixels_per_metre(Vec2::new(0.0, -20.0), 0.0, camera(eye, Vec3::ZERO), (960, 640)).is_none());
    }

    #[test]
    fn a_need_covers_the_region_at_its_densest() {
        let eye = Vec3::new(0.0, -6.0, 2.0);
        let vp = camera(eye, Vec3::ZERO);
        let region = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -0.5), Vec2::new(0.5, 2.0)];
        let n = need(&region, 0.0, vp, (960, 640)).unwrap();
        // Bounds (-1, -1)..(1, 2) widened by 2 % of (2, 3) on each side.
        assert!((n.min - Vec2::new(-1.04, -1.06)).length() < 1e-5 && (n.max - Vec2::new(1.04, 2.06)).length() < 1e-5, "{n:?}");
        // All of it on screen: the nearest corners (y = -1.06) are the densest, and no point of
        // the rectangle needs more.
        let densest = |n: &Need| {
            let mut most = Vec2::ZERO;
            for i in 0..=200 {
                for j in 0..=200 {
                    let p = n.min + (n.max - n.min) * Vec2::new(i as f32, j as f32) / 200.0;
                    if screen(p, 0.0, vp, (960, 640)).unwrap().abs().cmple(Vec2::new(480.0, 320.0)).all() {
                        most = most.max(pixels_per_metre(p, 0.0, vp, (960, 640)).unwrap());
                    }
                }
            }
            most
        };
        // (Not exactly at a corner: the derivative's numerator varies too; 0.01 % here.)
        assert!((densest(&n) - n.per_metre).abs().max_element() < 1e-3 * n.per_metre.max_element(), "{} vs {n:?}", densest(&n));
        // A region reaching below the frame, towards the camera: the densest point the frame
        // shows of it sets the density (a fine grid of its points on screen reaches within 5 %),
        // much less than its nearest corner would ask.
        let long = need(&[Vec2::new(-1.0, -5.5), Vec2::new(1.0, 2.0)], 0.0, vp, (960, 640)).unwrap();
        let (near, shown) = (pixels_per_metre(long.min, 0.0, vp, (960, 640)).unwrap(), densest(&long));
        assert!(long.per_metre.cmpge(shown).all() && long.per_metre.cmple(shown * 1.05).all(), "{long:?} vs {shown}");
        assert!(near.y > 2.0 * long.per_metre.y, "{near} vs {long:?}");
        // A region reaching behind the camera needs what the frame shows of it; none, or one
        // off screen, needs no bake.
        let behind = need(&[Vec2::new(-1.0, -7.0), Vec2::new(1.0, 2.0)], 0.0, vp, (960, 640)).unwrap();
        assert!((behind.per_metre - long.per_metre).abs().max_element() < 1e-2 * long.per_metre.max_element(), "{behind:?}");
        assert!(need(&[], 0.0, vp, (960, 640)).is_none());
        assert!(need(&[Vec2::new(20.0, 0.0), Vec2::new(21.0, 1.0)], 0.0, vp, (960, 640)).is_none());
    }

    #[test]
    fn a_bake_is_kept_while_it_holds_the_region_densely_enough() {
        let need = Need { min: Vec2::ZERO, max: Vec2::new(2.0, 1.0), z: 0.0, per_metre: Vec2::new(100.0, 50.0) };
        let source = (1, &drawn(), 0.005);
        let bake = plan(&need, source, BAKE_SIDE).unwrap();
        // 1.25 × (200, 50) texels.
        assert_eq!(bake.texels, [250, 63]);
        assert!(keeps(&bake, &need, source));
        // The camera a little nearer (10 % more density) or farther keeps it; twice as near, or
        // three times as far, draws it again.
        let scaled = |s: f32| Need { per_metre: need.per_metre * s, ..need };
        assert!(keeps(&bake, &scaled(1.1), source) && keeps(&bake, &scaled(0.6), source));
        assert!(!keeps(&bake, &scaled(2.0), source) && !keeps(&bake, &scaled(0.4), source));
        // A region that grows past the rectangle, another map, its contents moved, a larger sun.
        assert!(!keeps(&bake, &Need { max: Vec2::new(2.01, 1.0), ..need }, source));
        assert!(!keeps(&bake, &need, (0, &drawn(), 0.005)));
        let moved = ShadowDrawn { level: 1, ..drawn() };
        assert!(!keeps(&bake, &need, (1, &moved, 0.005)));
        assert!(!keeps(&bake, &need, (1, &drawn(), 0.006)));
        // Past the texture's side at 1.25 × the density but not at 1×: just the need.
        let tight = Need { per_metre: Vec2::new(1000.0, 50.0), ..need };
        assert_eq!(plan(&tight, source, BAKE_SIDE).unwrap().texels, [2000, 50]);
        // A device whose textures stop at 1024 texels: that region is looked up.
        assert!(plan(&tight, source, 1024).is_none());
        // Past it even at 1×: no bake (the ground looks the sun up).
        assert!(plan(&Need { per_metre: Vec2::new(1100.0, 50.0), ..need }, source, BAKE_SIDE).is_none());
    }
}
