//! Reprojection of the live view: a frame whose camera only turned since the last shaded frame
//! draws the model and its ground from that frame, warped by the turn, instead of shading them
//! again ("nothing recomputed that did not change", issue 11).
//!
//! The live camera turns about a fixed point (the phone's pose is an orientation at the scene's
//! camera position), so everything it sees moves on screen by one homography of the pixel
//! plane, `K_layer · R_layerᵀ · R_now · K_now⁻¹` ([`homography`]), whatever its depth; and what
//! the model and the ground show does not depend on the turn (the view vector from the camera to
//! a point is the same). A shaded frame draws the model (premultiplied) and the ground's matte
//! (what the ground leaves of the background per channel) into layers of the frame's size plus
//! [`margin_px`] on every side, with the same focal length ([`layer_view`]; a second compositor
//! of that size, render::compositor), then composes them with the camera image
//! (shaders/reproject.wgsl). At one sample a pixel the two share one layer in the frame's
//! colour format ([`packed_clear`]); multisampled, they are two, so that the resolve does not
//! mix them. A later frame with the same parameters but the camera's orientation composes the
//! same layers with its own camera image, each pixel reading the layer texel under it through
//! the homography (nearest texel: at most half a pixel of shift, the same bound the level of
//! detail keeps).
//!
//! A frame shades again when anything but the orientation changed (placement, light, sky,
//! method, colour, camera position or field of view; a new environment or model; a ground or
//! model sky map that arrived from the worker), when the camera turned more than
//! [`MAX_TURN_DEG`] since, or when its view would show content the layers do not hold
//! ([`view_held`]: the hull of the model's box and the ground's triangles, [`content_hull`],
//! within the view must lie inside the layers). Frames that reproject run no shadow, model or
//! ground pass: one pass over the hull of what the layers hold ([`held_part`]), the camera image
//! alone (the background pass, depth-tested) elsewhere.

use super::params::FrameParams;
use super::pipelines::{COLOR_FORMAT, depth_state};
use super::shaders::Technique;
use super::shadow_fit::{clip_convex, convex_hull, signed_area};
use crate::gpu::build;
use glam::{DMat3, DVec3, Mat4, Quat, Vec2, Vec3};
use wgpu::ShaderStages;

/// Colour format of the ground's matte layer: float, since the matte reaches 2 where the model
/// reflects light onto the ground.
pub const MATTE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The largest turn of the camera (degrees) a frame reprojects the layers over: beyond it the
/// homography magnifies parts of the layer by more than about 10 % (its scale changes by about
/// the turn times the tangent of the half field of view across the frame), so the nearest
/// texel would repeat or skip pixels of it.
pub const MAX_TURN_DEG: f64 = 10.0;

/// Pixels the hull of the layers' content is widened by (each side): a pixel just outside the
/// content reads the nearest texel, up to half a pixel inside it.
pub const HULL_MARGIN_PX: f32 = 1.5;

/// Most corners of the content's hull; a hull with more is drawn as its bounding rectangle.
pub const HULL_CORNERS: usize = 64;
/// Most vertices of the drawn fan: the hull clipped to the layers' rectangle gains at most
/// four corners.
const FAN_VERTICES: usize = 3 * (HULL_CORNERS + 4 - 2);

/// Mirrors `struct Reproject` in shaders/reproject.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ReprojectUniforms {
    /// Columns of the homography from this frame's pixels to the layers' (x right, y down, a
    /// pixel's centre at +0.5), each padded to four floats.
    pub to_layer: [[f32; 4]; 3],
    /// This frame's size in pixels (x, y) and the layers' (z, w).
    pub size: [f32; 4],
    /// x: the reciprocal of [`packed_clear`]; the rest unused.
    pub matte_scale: [f32; 4],
}

/// What the packed layer (one sample a pixel) is cleared to, linear: the matte 1 where the
/// ground leaves the background as it is. The layer is in the frame's sRGB colour format, so
/// the ground's matte (up to 2, times this) must fit under 1: about a half, exactly the value of
/// the sRGB byte 188, so that the cleared texel reads back as the same number.
pub fn packed_clear() -> f32 {
    crate::colour::srgb_to_linear(188.0 / 255.0)
}

/// The pinhole of a frame: focal length in pixels from the vertical field of view, the
/// principal point at the frame's centre; maps directions in the image frame (x right, y down,
/// z forward) to pixels. The same projection as `view::projection` (glam's right-handed
/// perspective), whose NDC x spans the width and y the height.
fn intrinsics(vfov: f64, (width, height): (u32, u32)) -> DMat3 {
    let f = 0.5 * f64::from(height) / (0.5 * vfov).tan();
    DMat3::from_cols(DVec3::new(f, 0.0, 0.0), DVec3::new(0.0, f, 0.0), DVec3::new(0.5 * f64::from(width), 0.5 * f64::from(height), 1.0))
}

/// A view from the camera's position: its orientation (camera → world), vertical field of view
/// (radians) and size in pixels.
pub type View = (Quat, f32, (u32, u32));

/// The homography taking a pixel of view `now` to the pixel of the same direction in view
/// `layer`, both from one point: `K_layer · F · R_layerᵀ · R_now · F · K_now⁻¹`, where F turns
/// the camera frame (x right, y up, looking along −z, `render::view`) into the image frame (x
/// right, y down, z forward).
pub fn homography((now, now_vfov, now_size): View, (layer, layer_vfov, layer_size): View) -> DMat3 {
    let flip = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let rotation = |q: Quat| DMat3::from_quat(q.as_dquat().normalize());
    let k = |vfov: f32, size| intrinsics(f64::from(vfov), size);
    k(layer_vfov, layer_size) * flip * rotation(layer).transpose() * rotation(now) * flip * k(now_vfov, now_size).inverse()
}

/// Pixels the layers reach beyond the frame on each side: the camera may turn this far (about
/// 8° at the live view's 67° field of view) towards content outside the frame before a frame
/// shades again.
pub fn margin_px(height: u32) -> u32 {
    height / 8
}

/// The layers' view for a frame of `size` with vertical field of view `vfov`: the same focal
/// length and centre, [`margin_px`] more on every side. Returns the layers' size and field of
/// view.
pub fn layer_view(vfov: f32, (width, height): (u32, u32)) -> ((u32, u32), f32) {
    let m = margin_px(height);
    let layer = (width + 2 * m, height + 2 * m);
    let half = ((0.5 * f64::from(vfov)).tan() * f64::from(layer.1) / f64::from(height)).atan();
    (layer, (2.0 * half) as f32)
}

/// `h` applied to pixel `p`; None where the direction is behind the other camera.
pub fn apply(h: &DMat3, p: Vec2) -> Option<Vec2> {
    let q = *h * DVec3::new(f64::from(p.x), f64::from(p.y), 1.0);
    (q.z > 1e-9).then(|| Vec2::new((q.x / q.z) as f32, (q.y / q.z) as f32))
}

/// The angle between two orientations, degrees.
pub fn turn_deg(a: Quat, b: Quat) -> f64 {
    let dot = a.as_dquat().normalize().dot(b.as_dquat().normalize()).abs().min(1.0);
    (2.0 * dot.acos()).to_degrees()
}

/// Whether a frame of `now` may be drawn from layers shaded with `held`: every parameter but
/// the camera's orientation the same, and the orientation within [`MAX_TURN_DEG`] of the
/// held one. (A NaN anywhere compares unequal: such a frame shades.)
pub fn reusable(held: &FrameParams, now: &FrameParams) -> bool {
    let mut same = *now;
    same.camera.pose = held.camera.pose;
    same == *held && turn_deg(held.camera.pose, now.camera.pose) <= MAX_TURN_DEG
}

/// Clip-space w (metres along the view axis) below which content is cut off before it is
/// projected: nothing that near the camera's plane is within a turn of [`MAX_TURN_DEG`] of any
/// view the layers serve (their views look at most 90° − that turn from the layers' axis).
const NEAR_W: f32 = 1e-3;

/// The hull (pixels of a frame of `size` seen through `view_proj`, a convex polygon, reaching
/// beyond the frame where they do) of where the model's box `corners` and the ground's
/// `triangles` (a triangle list; world) can change the frame, widened by [`HULL_MARGIN_PX`].
/// The triangles are cut at the camera's plane ([`NEAR_W`]) before they are projected, as the
/// rasteriser clips them; None when a corner of the box is behind that plane, or for fewer than
/// three distinct pixels.
pub fn content_hull(corners: &[Vec3], triangles: &[Vec3], view_proj: Mat4, (width, height): (u32, u32)) -> Option<Vec<Vec2>> {
    let size = Vec2::new(width as f32, height as f32);
    let clip = |p: &Vec3| view_proj * p.extend(1.0);
    let mut points: Vec<glam::Vec4> = Vec::with_capacity(corners.len() + 2 * triangles.len());
    for c in corners.iter().map(clip) {
        if c.w.is_nan() || c.w <= NEAR_W {
            return None;
        }
        points.push(c);
    }
    for t in triangles.chunks_exact(3) {
        let v = [clip(&t[0]), clip(&t[1]), clip(&t[2])];
        // Sutherland-Hodgman against w >= NEAR_W.
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            if a.w >= NEAR_W {
                points.push(a);
            }
            if (a.w >= NEAR_W) != (b.w >= NEAR_W) {
                points.push(a + (b - a) * ((NEAR_W - a.w) / (b.w - a.w)));
            }
        }
    }
    let mut pixels = Vec::with_capacity(4 * points.len());
    for c in points {
        let ndc = Vec2::new(c.x, c.y) / c.w;
        let px = Vec2::new((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
        if !px.is_finite() {
            return None;
        }
        // The Minkowski sum with a square of half-side the margin (which holds its disc).
        let m = HULL_MARGIN_PX;
        pixels.extend([Vec2::new(-m, -m), Vec2::new(m, -m), Vec2::new(m, m), Vec2::new(-m, m)].map(|d| px + d));
    }
    let hull = convex_hull(&pixels);
    match hull.len() {
        0..=2 => None,
        n if n <= HULL_CORNERS => Some(hull),
        _ => {
            let (lo, hi) = hull.iter().fold((Vec2::MAX, Vec2::MIN), |(lo, hi), &p| (lo.min(p), hi.max(p)));
            Some(vec![lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)])
        }
    }
}

/// The frame of `size` as a polygon of its pixel corners, counter-clockwise (positive area).
pub fn frame_polygon((width, height): (u32, u32)) -> [Vec2; 4] {
    let (w, h) = (width as f32, height as f32);
    [Vec2::ZERO, Vec2::new(w, 0.0), Vec2::new(w, h), Vec2::new(0.0, h)]
}

/// What the layers hold of `content` (their hull, layer pixels): the part inside the layer's
/// frame of `size`; None when too little of it is there to draw.
pub fn held_part(content: &[Vec2], size: (u32, u32)) -> Option<Vec<Vec2>> {
    Some(clip_convex(content, &frame_polygon(size))).filter(|p| p.len() >= 3)
}

/// Whether a frame of `frame` pixels, which `to_layer` takes to the layers', sees only content
/// the layers hold: the part of `content` (layer pixels) inside this frame's view lies within
/// the layers' `layer` pixels (to half a pixel, which the nearest texel at its edge still
/// gives). False when a corner of this frame looks behind the layers' camera.
pub fn view_held(content: &[Vec2], to_layer: &DMat3, frame: (u32, u32), layer: (u32, u32)) -> bool {
    let corners: Option<Vec<Vec2>> = frame_polygon(frame).iter().map(|&c| apply(to_layer, c)).collect();
    let Some(mut view) = corners else { return false };
    if signed_area(&view) < 0.0 {
        view.reverse();
    }
    let (lo, hi) = (Vec2::splat(-0.5), Vec2::new(layer.0 as f32, layer.1 as f32) + 0.5);
    clip_convex(content, &view).iter().all(|p| p.cmpge(lo).all() && p.cmple(hi).all())
}

/// The hull `hull` (layer pixels) as a triangle fan in this frame's pixels, through `to_layer`'s
/// inverse; None when a corner is behind this frame's camera.
pub fn fan_in_frame(hull: &[Vec2], to_layer: &DMat3) -> Option<Vec<[f32; 2]>> {
    let back = to_layer.inverse();
    let corners: Option<Vec<Vec2>> = hull.iter().map(|&p| apply(&back, p)).collect();
    let corners = corners?;
    Some((1..corners.len().saturating_sub(1)).flat_map(|i| [corners[0], corners[i], corners[i + 1]]).map(|p| p.to_array()).collect())
}

/// The reprojection pass's pipeline: the hull's triangles (pixels of the frame) at depth 0.5,
/// written, so that the background drawn after them at the far plane skips their pixels.
/// One sample a pixel packs the model and the matte into one layer (shaders/reproject.wgsl
/// `PACKED`); more keep them apart, since a resolve would mix the two.
pub fn pipeline(device: &wgpu::Device, samples: u32) -> (wgpu::BindGroupLayout, wgpu::RenderPipeline) {
    use wgpu::TextureViewDimension::D2;
    let fs = ShaderStages::FRAGMENT;
    let layout = build::layout(
        device,
        "reproject",
        &[
            build::texture_entry(0, fs, D2, true),
            build::texture_entry(1, fs, D2, true),
            build::texture_entry(2, fs, D2, true),
            build::uniform(3, ShaderStages::VERTEX | fs),
        ],
    );
    const ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x2];
    let vertices = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<[f32; 2]>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    };
    let module = build::shader(device, "reproject", super::shaders::source(Technique::Reproject));
    let packed = if samples == 1 { 1.0 } else { 0.0 };
    let pipeline = build::render_pipeline(
        device,
        build::PipelineSpec {
            label: "reproject",
            module: &module,
            layouts: &[&layout],
            vertex_buffers: &[Some(vertices)],
            colour: Some(wgpu::ColorTargetState { format: COLOR_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL }),
            depth: depth_state(true, wgpu::DepthBiasState::default()),
            samples,
            constants: &[("PACKED", packed)],
        },
    );
    (layout, pipeline)
}

/// What a shaded frame's layers hold: its parameters, the hull of their content (layer
/// pixels), and the worker's maps it drew (a frame shades again when another arrives).
pub struct Held {
    pub params: FrameParams,
    /// The hull of the content, reaching beyond the layers where it does ([`content_hull`]),
    /// and the part of it they hold ([`held_part`]), which a frame draws.
    pub content: Vec<Vec2>,
    pub hull: Vec<Vec2>,
    pub ground_sky: Option<std::sync::Arc<crate::scene::occlusion::GroundSky>>,
    pub model_sky: Option<super::model_cache::MeshVertices>,
}

/// The reprojection's GPU side at one frame size: the model and matte layers, the pass's
/// pipeline and bind group, the ground's pipelines into the matte, the hull's vertices and the
/// homography's uniform; made once when the live view turns reprojection on.
pub struct Reprojection {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    vertices: wgpu::Buffer,
    /// Vertices of the hull's fan written for this frame.
    count: u32,
    /// The model layer (packed: the model and the matte, one sample a pixel).
    model_view: wgpu::TextureView,
    /// The matte layer and its multisampled target (more than one sample a pixel; None:
    /// packed into the model layer).
    matte: Option<(wgpu::TextureView, wgpu::TextureView)>,
    /// The ground's pipelines into the matte (multisampled): with the sun looked up, baked, and
    /// without it (render::passes::ground::SunOnGround).
    ground: Option<[wgpu::RenderPipeline; 3]>,
    /// The frame's size and the layers'.
    frame: (u32, u32),
    layer: (u32, u32),
    /// What the layers hold (None: nothing a frame can reuse).
    pub held: Option<Held>,
}

impl Reprojection {
    /// Layers of `layer` pixels at `samples` a pixel (the frame's), composed into frames of
    /// `frame` pixels with `background` (the compositor's camera image, the frame's size).
    pub fn new(
        device: &wgpu::Device,
        pipelines: &super::pipelines::Pipelines,
        background: &wgpu::TextureView,
        (frame, layer): ((u32, u32), (u32, u32)),
        samples: u32,
    ) -> Reprojection {
        use super::passes::ground::{self, SunOnGround};
        let (layout, pipeline) = self::pipeline(device, samples);
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let sampled = attach | wgpu::TextureUsages::TEXTURE_BINDING;
        let extent = (layer.0, layer.1, 1);
        let view = |t: wgpu::Texture| t.create_view(&Default::default());
        let model_view = view(build::texture(device, "model layer (reprojection)", extent, COLOR_FORMAT, 1, sampled));
        let matte = (samples > 1).then(|| {
            let resolved = view(build::texture(device, "matte layer (reprojection)", extent, MATTE_FORMAT, 1, sampled));
            (resolved, view(build::texture(device, "matte msaa (reprojection)", extent, MATTE_FORMAT, samples, attach)))
        });
        let uniform = build::uniform_buffer::<ReprojectUniforms>(device, "reproject");
        let bytes = (FAN_VERTICES * std::mem::size_of::<[f32; 2]>()) as u64;
        let vertices = build::buffer(device, "reprojection hull", bytes, wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST);
        let bind_group = build::bind_group(
            device,
            "reproject",
            &layout,
            &[
                wgpu::BindingResource::TextureView(background),
                wgpu::BindingResource::TextureView(&model_view),
                // Packed: not read (the binding takes the model layer).
                wgpu::BindingResource::TextureView(matte.as_ref().map_or(&model_view, |m| &m.0)),
                uniform.as_entire_binding(),
            ],
        );
        let ground = matte.is_some().then(|| {
            let module = ground::shader(device);
            [SunOnGround::Lookup, SunOnGround::Baked, SunOnGround::SkyOnly]
                .map(|sun| ground::pipeline_for(device, (&pipelines.ground.layout, &module), (MATTE_FORMAT, samples), sun))
        });
        Reprojection { pipeline, bind_group, uniform, vertices, count: 0, model_view, matte, ground, frame, layer, held: None }
    }

    /// The model layer (the frame's colour format, single-sampled): what the model pass
    /// resolves into on a shaded frame (packed: the ground's too, drawn after it in its pass).
    pub fn model_view(&self) -> &wgpu::TextureView {
        &self.model_view
    }

    /// Whether the model layer holds the matte too (one sample a pixel).
    pub fn packed(&self) -> bool {
        self.matte.is_none()
    }

    /// The ground's pipelines into the matte: looked up, baked, sky only (None: packed).
    pub fn ground_pipelines(&self) -> Option<[&wgpu::RenderPipeline; 3]> {
        self.ground.as_ref().map(|[a, b, c]| [a, b, c])
    }

    /// The matte's pass: cleared to white (nothing darkened), against the model's depth as its
    /// pass left it in `depth` (the ground is not shaded where the model covers a sample).
    /// None when packed.
    pub fn begin_matte<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        depth: &wgpu::TextureView,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> Option<wgpu::RenderPass<'e>> {
        let (resolved, msaa) = self.matte.as_ref()?;
        let (view, resolve_target, store) = (msaa, Some(resolved), wgpu::StoreOp::Discard);
        Some(encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("matte layer (reprojection)"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::WHITE), store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        }))
    }

    /// Write this frame's homography (this frame's pixels to the layers') and the held hull's
    /// fan in this frame's pixels. False (nothing written) when the hull does not map onto this
    /// frame (a corner behind its camera) or there is nothing held.
    pub fn prepare(&mut self, queue: &wgpu::Queue, to_layer: &DMat3) -> bool {
        let Some(held) = &self.held else { return false };
        if !view_held(&held.content, to_layer, self.frame, self.layer) {
            return false;
        }
        let Some(fan) = fan_in_frame(&held.hull, to_layer).filter(|f| f.len() <= FAN_VERTICES) else { return false };
        let h = to_layer.as_mat3();
        let column = |c: glam::Vec3| [c.x, c.y, c.z, 0.0];
        let size = |(w, h): (u32, u32)| [w as f32, h as f32];
        let ([fw, fh], [lw, lh]) = (size(self.frame), size(self.layer));
        let uniforms = ReprojectUniforms {
            to_layer: [column(h.x_axis), column(h.y_axis), column(h.z_axis)],
            size: [fw, fh, lw, lh],
            matte_scale: [1.0 / packed_clear(), 0.0, 0.0, 0.0],
        };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniforms));
        queue.write_buffer(&self.vertices, 0, bytemuck::cast_slice(&fan));
        self.count = fan.len() as u32;
        true
    }

    /// Draw the hull, composing the layers with the camera image (the background pass fills
    /// the rest of the frame after it).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.draw(0..self.count, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::view::{camera_pose, projection, view_matrix};

    const SIZE: (u32, u32) = (960, 640);

    fn pixel(view_proj: Mat4, p: Vec3) -> Vec2 {
        let c = view_proj * p.extend(1.0);
        Vec2::new((c.x / c.w + 1.0) * 0.5 * SIZE.0 as f32, (1.0 - c.y / c.w) * 0.5 * SIZE.1 as f32)
    }

    #[test]
    fn the_same_orientation_is_the_identity() {
        let q = camera_pose(0.7, 0.2, -0.1);
        let h = homography((q, 0.8, SIZE), (q, 0.8, SIZE));
        assert!((h - DMat3::IDENTITY).to_cols_array().iter().all(|v| v.abs() < 1e-9), "{h:?}");
    }

    #[test]
    fn a_turn_moves_the_centre_by_the_focal_length_times_its_tangent() {
        // Pinhole geometry: a camera turned right by θ sees the old centre f·tan θ left of its
        // own centre, f = (h/2) / tan(vfov/2).
        let (vfov, turn) = (50f32.to_radians(), 4f32.to_radians());
        let f = 0.5 * SIZE.1 as f64 / (0.5 * f64::from(vfov)).tan();
        let (layer, now) = (camera_pose(0.3, 0.0, 0.0), camera_pose(0.3 + turn, 0.0, 0.0));
        let h = homography((now, vfov, SIZE), (layer, vfov, SIZE));
        let centre = Vec2::new(480.0, 320.0);
        let seen_at = Vec2::new((480.0 - f * f64::from(turn).tan()) as f32, 320.0);
        let to = apply(&h, seen_at).unwrap();
        assert!((to - centre).length() < 1e-3, "{to} vs {centre}");
    }

    #[test]
    fn it_agrees_with_the_renderers_projection_of_world_points() {
        // Independently: project world points with view::projection · view::view_matrix from
        // both orientations; the homography takes one pixel to the other.
        let (vfov, camera) = (0.9f32, Vec3::new(3.0, -2.0, 1.6));
        let (now, layer) = (camera_pose(0.4, -0.15, 0.05), camera_pose(0.47, -0.1, 0.0));
        let vp = |q: Quat| projection(vfov, SIZE.0 as f32 / SIZE.1 as f32, 0.01, 1e4) * view_matrix(q, camera);
        let h = homography((now, vfov, SIZE), (layer, vfov, SIZE));
        for p in [Vec3::new(5.0, 12.0, 0.0), Vec3::new(1.0, 8.0, 2.5), Vec3::new(7.0, 20.0, -1.0)] {
            let (a, b) = (pixel(vp(now), p), pixel(vp(layer), p));
            let mapped = apply(&h, a).unwrap();
            assert!((mapped - b).length() < 2e-2, "{p}: {mapped} vs {b}");
        }
    }

    #[test]
    fn only_the_orientation_may_change() {
        let mut held = FrameParams::example();
        held.camera.pose = camera_pose(0.0, 0.0, 0.0);
        let mut now = held;
        now.camera.pose = camera_pose(5f32.to_radians(), 0.0, 0.0);
        assert!(reusable(&held, &now));
        now.camera.pose = camera_pose(11f32.to_radians(), 0.0, 0.0);
        assert!(!reusable(&held, &now), "beyond the turn limit");
        now.camera.pose = held.camera.pose;
        now.camera.position.x += 0.01;
        assert!(!reusable(&held, &now), "the camera moved");
        now = held;
        now.lighting.sun_dir = Vec3::new(0.0, 0.6, 0.8);
        assert!(!reusable(&held, &now), "the sun moved");
        now = held;
        now.placement.rotation.z += 0.01;
        assert!(!reusable(&held, &now), "the model turned");
        now = held;
        now.lighting.sunlight = f32::NAN;
        assert!(!reusable(&held, &now), "NaN");
    }

    #[test]
    fn the_hull_holds_every_point_widened_and_cuts_the_ground_at_the_camera_plane() {
        let vp = projection(0.9, 1.5, 0.1, 100.0) * view_matrix(camera_pose(0.0, 0.0, 0.0), Vec3::ZERO);
        let points = [Vec3::new(-1.0, 10.0, -1.0), Vec3::new(1.0, 10.0, -1.0), Vec3::new(0.0, 10.0, 1.0), Vec3::new(0.2, 9.0, 0.1)];
        let hull = content_hull(&points[3..], &points[..3], vp, SIZE).unwrap();
        for p in points {
            let px = pixel(vp, p);
            // Every point is at least the margin inside every edge.
            for i in 0..hull.len() {
                let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
                let inside = (b - a).perp_dot(px - a) / (b - a).length();
                assert!(inside >= HULL_MARGIN_PX - 1e-3, "{p}: {inside}");
            }
        }
        // A corner of the box behind the camera: no hull.
        assert!(content_hull(&[points[0], Vec3::new(0.0, -5.0, 0.0)], &[], vp, SIZE).is_none());
        // A ground triangle reaching behind the camera is cut at its plane: the hull holds what
        // is in front, every pixel of which lies below the camera's horizon, and reaches as
        // far down as the cut does (beyond the frame).
        let ground = [Vec3::new(-2.0, 10.0, -1.0), Vec3::new(2.0, 10.0, -1.0), Vec3::new(0.0, -10.0, -1.0)];
        let hull = content_hull(&[], &ground, vp, SIZE).unwrap();
        assert!(hull.iter().all(|p| p.y > 320.0 - HULL_MARGIN_PX - 1e-3), "{hull:?}");
        assert!(hull.iter().any(|p| p.y > 1e4), "{hull:?}");
    }

    #[test]
    fn a_view_is_held_while_the_content_it_sees_was_in_the_layers() {
        let (vfov, layer) = (0.9f32, camera_pose(0.0, 0.0, 0.0));
        // Content from x = 300 to 1400 px: its right part beyond the layers' 960.
        let content = vec![Vec2::new(300.0, 200.0), Vec2::new(1400.0, 200.0), Vec2::new(1400.0, 400.0), Vec2::new(300.0, 400.0)];
        assert_eq!(held_part(&content, SIZE).unwrap().iter().map(|p| p.x).fold(0f32, f32::max), 960.0);
        let turned = |deg: f32| homography((camera_pose(deg.to_radians(), 0.0, 0.0), vfov, SIZE), (layer, vfov, SIZE));
        assert!(view_held(&content, &turned(0.0), SIZE, SIZE), "the same view");
        // Turned left (heading down): the right edge of the view moves into the layers.
        assert!(view_held(&content, &turned(-3.0), SIZE, SIZE), "turned away from the missing part");
        // Turned right: the view sees content beyond the layers' right edge.
        assert!(!view_held(&content, &turned(3.0), SIZE, SIZE), "turned towards the missing part");
        // Content wholly inside the layers: any turn is held.
        let inside = vec![Vec2::new(300.0, 200.0), Vec2::new(600.0, 200.0), Vec2::new(600.0, 400.0)];
        assert!(view_held(&inside, &turned(6.0), SIZE, SIZE) && view_held(&inside, &turned(-6.0), SIZE, SIZE));
    }

    #[test]
    fn the_fan_maps_back_onto_the_frame() {
        let (vfov, q0) = (0.9f32, camera_pose(0.2, 0.0, 0.0));
        let q1 = camera_pose(0.25, 0.02, 0.0);
        let h = homography((q1, vfov, SIZE), (q0, vfov, SIZE));
        let hull = vec![Vec2::new(100.0, 100.0), Vec2::new(300.0, 120.0), Vec2::new(200.0, 400.0)];
        let fan = fan_in_frame(&hull, &h).unwrap();
        assert_eq!(fan.len(), 3);
        for (corner, p) in hull.iter().zip(&fan) {
            let back = apply(&h, Vec2::from_array(*p)).unwrap();
            assert!((back - *corner).length() < 1e-2, "{back} vs {corner}");
        }
    }
}
