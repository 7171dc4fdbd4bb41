//! Shadows sized to what they cover: where the model's sun shadow can fall on the ground (the
//! receiver quad), the shadow camera fitted tightly around the model, the shadow's footprint on
//! screen and the shadow-map resolution it needs (a texel per pixel, from a few pre-allocated
//! sizes), and whether a shadow pass is needed at all. Pure functions on glam types.
//!
//! World = ENU, z up; `sun` is the unit direction towards the sun. The ground is the plane
//! z = `ground_z` (the model's base).

use glam::{Mat4, Vec2, Vec3, Vec3Swizzles, Vec4Swizzles};

/// Shadow-map sides the renderer allocates once; a frame picks one (switching allocates nothing).
pub const SHADOW_MAP_SIZES: [u32; 4] = [256, 512, 1024, 2048];

/// How far (in model bounding radii, from the model's base) the receiver may reach: the old
/// fixed ground square's half side, so a shadow at a grazing sun is cut where it was before.
pub const MAX_RECEIVER_RADII: f32 = 20.0;

/// The eight corners of the box `bounds` (model space) placed by `model`, world space.
pub fn box_corners(bounds: (Vec3, Vec3), model: Mat4) -> [Vec3; 8] {
    let (lo, hi) = bounds;
    std::array::from_fn(|i| {
        let p = Vec3::new(if i & 1 == 0 { lo.x } else { hi.x }, if i & 2 == 0 { lo.y } else { hi.y }, if i & 4 == 0 { lo.z } else { hi.z });
        model.transform_point3(p)
    })
}

/// A rectangle on the ground plane z = `z`, axis-aligned in world x/y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundRect {
    pub min: Vec2,
    pub max: Vec2,
    pub z: f32,
}

impl GroundRect {
    /// The matrix placing the unit square [-1, 1]² (z = 0) onto the rectangle: the ground
    /// pass's instance transform.
    pub fn matrix(&self) -> Mat4 {
        let c = 0.5 * (self.min + self.max);
        let h = 0.5 * (self.max - self.min);
        Mat4::from_translation(c.extend(self.z)) * Mat4::from_scale(Vec3::new(h.x, h.y, 1.0))
    }

    /// The four corners, world space.
    pub fn corners(&self) -> [Vec3; 4] {
        [(self.min.x, self.min.y), (self.max.x, self.min.y), (self.max.x, self.max.y), (self.min.x, self.max.y)]
            .map(|(x, y)| Vec3::new(x, y, self.z))
    }

    pub fn area(&self) -> f32 {
        let d = self.max - self.min;
        d.x * d.y
    }
}

/// Where a point `p` above the ground casts its shadow on z = `ground_z` (along −sun); the
/// point itself when it is on or below the ground. `sun.z` must be positive.
pub fn shadow_point(p: Vec3, sun: Vec3, ground_z: f32) -> Vec3 {
    let h = (p.z - ground_z).max(0.0);
    Vec3::new(p.x - sun.x * h / sun.z, p.y - sun.y * h / sun.z, ground_z)
}

/// The ground rectangle the shadow of the box with world `corners` can cover: the box's own
/// footprint and its corners swept along −sun onto the ground (the shadow of a box is inside
/// the convex hull of those points), clipped to [`MAX_RECEIVER_RADII`] × `radius` around
/// `base` (the model's base centre). None when the sun is on or below the horizon.
pub fn receiver(corners: &[Vec3; 8], sun: Vec3, ground_z: f32, base: Vec2, radius: f32) -> Option<GroundRect> {
    if sun.is_nan() || sun.z <= 0.0 {
        return None;
    }
    let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &c in corners {
        for q in [c, shadow_point(c, sun, ground_z)] {
            min = min.min(q.xy());
            max = max.max(q.xy());
        }
    }
    let reach = Vec2::splat(MAX_RECEIVER_RADII * radius);
    let (min, max) = (min.max(base - reach), max.min(base + reach));
    (min.cmplt(max).all()).then_some(GroundRect { min, max, z: ground_z })
}

/// The orthographic shadow camera looking along −sun, fitted around the box `corners` across
/// the sun (x/y: the box's extent in light space, no more), with depth 0..1 running over the
/// bounding sphere (centre, radius) along the sun as before, so the depth bias keeps its size
/// in metres.
pub fn light_view_proj(sun: Vec3, corners: &[Vec3; 8], centre: Vec3, radius: f32) -> Mat4 {
    let (view, lo, hi) = light_frame(sun, corners, centre, radius);
    let proj = glam::camera::rh::proj::directx::orthographic(lo.x, hi.x, lo.y, hi.y, radius, 3.0 * radius);
    proj * view
}

/// The sun camera's view (from 2 radii out along `sun`, looking at `centre`) and the rectangle
/// its map covers across the sun (view x/y, metres): the box's extent, never wider than the
/// sphere, never degenerate.
fn light_frame(sun: Vec3, corners: &[Vec3; 8], centre: Vec3, radius: f32) -> (Mat4, Vec2, Vec2) {
    let up = if sun.z.abs() > 0.99 { Vec3::Y } else { Vec3::Z };
    let eye = centre + sun * (2.0 * radius);
    let view = glam::camera::rh::view::look_at_mat4(eye, centre, up);
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &c in corners {
        let l = view.transform_point3(c).xy();
        lo = lo.min(l);
        hi = hi.max(l);
    }
    let lo = lo.max(Vec2::splat(-radius)).min(Vec2::splat(-1e-6));
    let hi = hi.min(Vec2::splat(radius)).max(Vec2::splat(1e-6));
    (view, lo, hi)
}

/// How far (metres across the sun) beyond the shadow map's rectangle the ground's soft shadow
/// lookup (shaders/frame.wgsl `sun_visibility_soft`) can still see the model, for a `size`²
/// map over `extent` metres (its rectangle's sides), a model of bounding `radius` (the map's
/// depth range is 2 radii, so no blocker is farther than that from a receiver) and a sun of
/// angular radius tan = `tan_radius`. The lookup's comparison taps reach 0.61 of the penumbra
/// (3×3 taps 0.61 penumbrae apart, the spread of the sun's disc) plus one texel of bilinear
/// footprint from the point; this allows 1.25 penumbrae plus two texels (sized when the taps
/// reached 5/6 of it, before the twelfth session; a margin, kept).
pub fn lookup_reach(size: u32, extent: Vec2, radius: f32, tan_radius: f32) -> f32 {
    let texel = extent.max_element() / size.max(1) as f32;
    let penumbra = (2.0 * radius * tan_radius.max(0.0)).max(texel);
    1.25 * penumbra + 2.0 * texel
}

/// How many directions across the sun the shadow's outline takes the model's support along
/// ([`silhouette_outline`]): a 12-gon hugging the model's silhouette seen from the sun.
pub const OUTLINE_DIRECTIONS: usize = 12;

/// The `n` unit directions at equal angles from +x, counter-clockwise.
pub fn directions(n: usize) -> Vec<Vec2> {
    (0..n).map(|i| Vec2::from_angle(std::f32::consts::TAU * i as f32 / n as f32)).collect()
}

/// The convex polygon { x : x · dirs[i] <= heights[i] for every i } for `dirs` at equal angles
/// counter-clockwise ([`directions`]) and `heights` the support of some set along them (so that
/// every side touches it): vertex i is where sides i and i + 1 meet; counter-clockwise.
pub fn polygon_from_supports(dirs: &[Vec2], heights: &[f32]) -> Vec<Vec2> {
    let n = dirs.len();
    (0..n)
        .map(|i| {
            let (u, v, hu, hv) = (dirs[i], dirs[(i + 1) % n], heights[i], heights[(i + 1) % n]);
            let det = u.perp_dot(v);
            Vec2::new(hu * v.y - hv * u.y, hv * u.x - hu * v.x) / det
        })
        .collect()
}

/// The support of `points` along each of `dirs` (the largest `p · dir`); −∞ without points.
pub fn supports(points: impl IntoIterator<Item = Vec2>, dirs: &[Vec2]) -> Vec<f32> {
    let mut h = vec![f32::NEG_INFINITY; dirs.len()];
    for p in points {
        for (h, d) in h.iter_mut().zip(dirs) {
            *h = h.max(p.dot(*d));
        }
    }
    h
}

/// Where on the ground z = `ground_z` the ground's sun-shadow lookup can find the sun blocked
/// in a `size`² shadow map drawn through `light_view_proj` ([`light_view_proj`]; the frame's,
/// or the held one when the map is kept) of the model `vertices` (model space; every level of
/// detail indexes them, scene::lod) placed by `model`: the vertices' support in the map along
/// [`OUTLINE_DIRECTIONS`] directions (a polygon around the model's silhouette seen from the
/// sun: every triangle's projection lies inside it), widened on every side by what the lookup
/// reaches ([`lookup_reach`], a sun of angular radius tan = `tan_radius`, a model of bounding
/// `radius`), swept along the sun onto the ground — counter-clockwise seen from above. Outside
/// it every comparison tap reads a texel the model does not cover, so the lookup returns
/// "lit": the ground pass skips it there. Empty without vertices or with the sun on the
/// horizon.
pub fn silhouette_outline(
    light_view_proj: Mat4,
    (model, vertices): (Mat4, impl IntoIterator<Item = Vec3>),
    ground_z: f32,
    (size, tan_radius, radius): (u32, f32, f32),
) -> Vec<Vec2> {
    let to_map = light_view_proj * model;
    let dirs = directions(OUTLINE_DIRECTIONS);
    let heights = supports(vertices.into_iter().map(|v| to_map.transform_point3(v).xy()), &dirs);
    if heights.iter().any(|h| !h.is_finite()) {
        return Vec::new();
    }
    // Metres per map unit: the map's x and y (NDC, 2 across) over its extent across the sun.
    let m = light_view_proj;
    let per_unit =
        Vec2::new(Vec3::new(m.x_axis.x, m.y_axis.x, m.z_axis.x).length(), Vec3::new(m.x_axis.y, m.y_axis.y, m.z_axis.y).length());
    let extent = 2.0 / per_unit.max(Vec2::splat(1e-12));
    let reach = lookup_reach(size, extent, radius, tan_radius) * per_unit;
    // A side along u pushed out by the reach (an ellipse in map units) holds every point within
    // the reach of the polygon.
    let grown: Vec<f32> = dirs.iter().zip(&heights).map(|(u, h)| h + (reach * *u).length()).collect();
    let to_world = m.inverse();
    let outline: Vec<Vec2> = polygon_from_supports(&dirs, &grown)
        .into_iter()
        .map(|q| {
            // Along the sun through this point of the map, down (or up) to the ground.
            let a = to_world.project_point3(q.extend(0.0));
            let d = to_world.project_point3(q.extend(1.0)) - a;
            (a + d * ((ground_z - a.z) / d.z)).xy()
        })
        .collect();
    if outline.iter().any(|p| !p.is_finite()) {
        return Vec::new();
    }
    if signed_area(&outline) < 0.0 { outline.into_iter().rev().collect() } else { outline }
}

/// Twice the signed area of a polygon (positive: counter-clockwise).
pub fn signed_area(poly: &[Vec2]) -> f32 {
    (0..poly.len()).map(|i| poly[i].perp_dot(poly[(i + 1) % poly.len()])).sum()
}

/// The convex polygon `poly` (counter-clockwise) clipped to the convex polygon `to`
/// (counter-clockwise; Sutherland-Hodgman); empty when they do not overlap.
pub fn clip_convex(poly: &[Vec2], to: &[Vec2]) -> Vec<Vec2> {
    let mut out = poly.to_vec();
    for (i, &a) in to.iter().enumerate() {
        let b = to[(i + 1) % to.len()];
        // Inside: on the left of the edge a -> b.
        let side = |p: Vec2| (b - a).perp_dot(p - a);
        let input = std::mem::take(&mut out);
        for (k, &p) in input.iter().enumerate() {
            let q = input[(k + 1) % input.len()];
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                out.push(p + (q - p) * (sp / (sp - sq)));
            }
        }
    }
    out
}

/// The convex hull of `points`, counter-clockwise, without collinear points (Andrew's monotone
/// chain).
pub fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let mut hull: Vec<Vec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        for &q in p.iter() {
            while hull.len() >= start + 2 && (hull[hull.len() - 1] - hull[hull.len() - 2]).perp_dot(q - hull[hull.len() - 2]) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
        if pass == 0 {
            p.reverse();
        }
    }
    hull
}

/// The rectangle `min`..`max` as a counter-clockwise polygon.
pub fn rect_polygon(min: Vec2, max: Vec2) -> [Vec2; 4] {
    [min, Vec2::new(max.x, min.y), max, Vec2::new(min.x, max.y)]
}

/// The convex polygon `outer` (counter-clockwise) split into the part inside the convex polygon
/// `inner` (counter-clockwise) and the rest, as triangle lists (three points each, counter-clockwise).
/// Both share every edge exactly (no T-junctions), so together they cover `outer` once: the inner
/// part as a fan from its first vertex, and the ring around it cut along the rays from the
/// inner part's centroid through its vertices, one convex piece per inner edge (that edge, the
/// outer boundary between the two rays) drawn as a fan from the edge's first vertex. With no
/// inner part, the outer polygon as a fan. Few, wide triangles: a software rasteriser shades the
/// 4×4 blocks along every edge once per triangle that crosses them, so thin slivers cost it
/// pixels it does not draw.
pub fn split_convex(inner: &[Vec2], outer: &[Vec2]) -> (Vec<Vec2>, Vec<Vec2>) {
    let area = signed_area(outer).abs();
    let inner = if inner.len() >= 3 { clip_convex(inner, outer) } else { Vec::new() };
    if inner.len() < 3 || signed_area(&inner) <= 1e-9 * area {
        return (Vec::new(), fan(outer));
    }
    let c = inner.iter().copied().sum::<Vec2>() / inner.len() as f32;
    let exits: Vec<Vec2> = inner.iter().map(|&p| ray_exit_convex(c, p - c, outer)).collect();
    let mut ring = Vec::with_capacity(3 * (outer.len() + 2 * inner.len()));
    for i in 0..inner.len() {
        let j = (i + 1) % inner.len();
        let (a, b) = (inner[i] - c, inner[j] - c);
        // The outer vertices strictly inside the sector from ray i to ray j, in angle order.
        let mut between: Vec<(f32, Vec2)> = outer
            .iter()
            .filter(|&&o| a.perp_dot(o - c) > 0.0 && (o - c).perp_dot(b) > 0.0)
            .map(|&o| (a.perp_dot(o - c).atan2(a.dot(o - c)), o))
            .collect();
        between.sort_by(|x, y| x.0.total_cmp(&y.0));
        let boundary: Vec<Vec2> =
            std::iter::once(exits[i]).chain(between.into_iter().map(|(_, o)| o)).chain([exits[j], inner[j]]).collect();
        ring.extend(boundary.windows(2).flat_map(|w| [inner[i], w[0], w[1]]));
    }
    (fan(&inner), ring)
}

/// The convex polygon `poly` as a fan of triangles from its first vertex.
fn fan(poly: &[Vec2]) -> Vec<Vec2> {
    (1..poly.len().saturating_sub(1)).flat_map(|i| [poly[0], poly[i], poly[i + 1]]).collect()
}

/// Where the ray from `c` along `d` leaves the convex polygon `poly` (counter-clockwise, `c`
/// inside).
fn ray_exit_convex(c: Vec2, d: Vec2, poly: &[Vec2]) -> Vec2 {
    let mut t = f32::INFINITY;
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        // Outward normal of a counter-clockwise edge.
        let n = Vec2::new(b.y - a.y, a.x - b.x);
        let along = n.dot(d);
        if along > 0.0 {
            t = t.min(n.dot(a - c) / along);
        }
    }
    if t.is_finite() { c + d * t } else { c }
}

/// How many directions the sky-occlusion region takes the occluded texels' support along
/// ([`sky_region`]).
pub const SKY_REGION_DIRECTIONS: usize = 16;

/// Where on the ground the sky's occlusion under the model reaches `min_occlusion` (the share
/// of the sky hidden) or the model's light on it reaches `min_bounce` in some channel (the gain
/// on the ground's light, `GroundSky::bounce`): a convex polygon (counter-clockwise) around
/// every texel of `sky` (its visibility as the ground pass holds it: in 255ths per channel,
/// passes::ground::sky_texels, the channel losing most) hiding or gaining at least that much, widened by
/// a texel on every side (the bilinear lookup's reach), from their support along
/// [`SKY_REGION_DIRECTIONS`] directions; in the map's square as the ground pass places it (0..1
/// from its min to its max corner: the map moves with the model). Outside it every lookup
/// blends texels that hide and gain less, so the sky's occlusion there is below
/// `min_occlusion` and the bounce below `min_bounce`. Empty when no texel reaches either.
pub fn sky_region(sky: &crate::scene::occlusion::GroundSky, min_occlusion: f32, min_bounce: f32) -> Vec<Vec2> {
    let n = sky.size.max(1) as usize;
    let texel = 1.0 / n as f32;
    let corners = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 1.0), Vec2::new(-1.0, 1.0)];
    let texels = crate::render::passes::ground::sky_texels(sky);
    let gains = |i: usize| sky.bounce.get(i).map_or(0.0, |b| b.iter().copied().fold(0.0, f32::max));
    let points = (texels.iter().enumerate())
        // In whole 255ths, as the texture holds them.
        .filter(|(i, v)| f32::from(255 - v.iter().min().copied().unwrap_or(255)) >= min_occlusion * 255.0 - 1e-3 || gains(*i) >= min_bounce)
        .flat_map(|(i, _)| {
            let centre = (Vec2::new((i % n) as f32, (i / n) as f32) + 0.5) * texel;
            corners.map(|c| centre + c * texel)
        });
    let dirs = directions(SKY_REGION_DIRECTIONS);
    let heights = supports(points, &dirs);
    if heights.iter().any(|h| !h.is_finite()) {
        return Vec::new();
    }
    polygon_from_supports(&dirs, &heights)
}

/// The pixel rectangle (min, max) that the convex hull of `points` covers on a `size` image
/// seen through `view_proj`, clipped to the image; None when the hull lies wholly outside the
/// view (all points beyond one frustum side, or all behind the camera). Where the points
/// straddle the camera plane the answer is the whole image (conservative).
pub fn screen_rect(points: &[Vec3], view_proj: Mat4, (width, height): (u32, u32)) -> Option<(Vec2, Vec2)> {
    let size = Vec2::new(width as f32, height as f32);
    let clip: Vec<glam::Vec4> = points.iter().map(|p| view_proj * p.extend(1.0)).collect();
    let outside = |f: fn(&glam::Vec4) -> bool| clip.iter().all(f);
    if clip.is_empty()
        || outside(|c| c.w <= 1e-6)
        || outside(|c| c.x > c.w)
        || outside(|c| c.x < -c.w)
        || outside(|c| c.y > c.w)
        || outside(|c| c.y < -c.w)
    {
        return None;
    }
    if clip.iter().any(|c| c.w.is_nan() || c.w <= 1e-6) {
        return Some((Vec2::ZERO, size));
    }
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for c in &clip {
        // NDC y up, pixel rows down.
        let ndc = c.xy() / c.w;
        let px = Vec2::new((ndc.x * 0.5 + 0.5) * size.x, (0.5 - ndc.y * 0.5) * size.y);
        lo = lo.min(px);
        hi = hi.max(px);
    }
    let (lo, hi) = (lo.max(Vec2::ZERO), hi.min(size));
    (lo.cmplt(hi).all()).then_some((lo, hi))
}

/// The shadow-map side for a shadow whose on-screen footprint spans `footprint_px` pixels along
/// its longer side: the smallest of `sizes` (ascending) with a texel per pixel, else the
/// largest. A non-finite footprint takes the largest.
pub fn shadow_map_size(footprint_px: f32, sizes: &[u32]) -> u32 {
    let largest = *sizes.last().expect("at least one shadow-map size");
    if !footprint_px.is_finite() {
        return largest;
    }
    sizes.iter().copied().find(|&s| s as f32 >= footprint_px).unwrap_or(largest)
}

/// Whether the frame needs a shadow pass: the sun is above the horizon, there is sunlight to
/// block (a measured sun share above zero), and the shadow — the model (self-shadowing) or its
/// ground footprint — is on screen.
pub fn shadow_needed(sun: Vec3, sunlight: f32, footprint_on_screen: bool) -> bool {
    sun.z > 0.0 && sunlight > 0.0 && footprint_on_screen
}

/// What a shadow map holds: the sun camera, the model's transform and the level of detail it
/// was drawn with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowDrawn {
    pub light_view_proj: Mat4,
    pub model: Mat4,
    pub level: usize,
}

/// How far (shadow-map texels across the sun) the model's box may have moved in the map since
/// it was drawn for the map to be kept: an eighth of a texel, below what the bilinear
/// comparison taps resolve.
pub const REUSE_TEXELS: f32 = 0.125;
/// The same along the sun, in depth units (0..1 over the shadow camera's depth range): an eighth
/// of the receivers' depth bias (frame.wgsl compares at depth − 0.002).
pub const REUSE_DEPTH: f32 = 0.002 / 8.0;

/// Whether a `size`² map drawn as `held` still serves a frame that would draw it as `now`: the
/// same model transform and level of detail, and no corner of the model's box (`corners`,
/// world) lands more than [`REUSE_TEXELS`] across or [`REUSE_DEPTH`] along the sun from where
/// the held sun camera put it. A frame that keeps the map also keeps the held sun camera, so
/// its lookups match the map exactly; the sun's slow motion (0.004° a second) redraws it every
/// few minutes instead of every frame.
pub fn map_still_valid(held: &ShadowDrawn, now: &ShadowDrawn, corners: &[Vec3; 8], size: u32) -> bool {
    if held.model != now.model || held.level != now.level {
        return false;
    }
    // NDC x and y span 2 across the map.
    let texels = 0.5 * size as f32;
    corners.iter().all(|&c| {
        let (a, b) = (held.light_view_proj.project_point3(c), now.light_view_proj.project_point3(c));
        let d = (a - b).abs();
        d.x * texels <= REUSE_TEXELS && d.y * texels <= REUSE_TEXELS && d.z <= REUSE_DEPTH
    })
}

/// Everything a frame needs to know about its shadow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowFit {
    /// The ground pass's quad (None: no shadow can fall, nothing to draw).
    pub receiver: Option<GroundRect>,
    pub light_view_proj: Mat4,
    /// The caster and its ground shadow on screen, pixels (None: off-screen).
    pub footprint: Option<(Vec2, Vec2)>,
    pub map_size: u32,
    pub needed: bool,
}

/// Fit the shadow of a model with (model-space) `bounds` placed by `model` (base centre `base`,
/// bounding sphere `centre`/`radius`), a sun direction and share, for a camera `view_proj`
/// rendering `size` pixels.
pub fn fit(
    bounds: (Vec3, Vec3),
    model: Mat4,
    (base, centre, radius): (Vec3, Vec3, f32),
    (sun, sunlight): (Vec3, f32),
    (view_proj, size): (Mat4, (u32, u32)),
    sizes: &[u32],
) -> ShadowFit {
    let corners = box_corners(bounds, model);
    let receiver = receiver(&corners, sun, base.z, base.xy(), radius);
    let mut points: Vec<Vec3> = corners.to_vec();
    if let Some(r) = &receiver {
        points.extend(r.corners());
    }
    let footprint = screen_rect(&points, view_proj, size);
    let px = footprint.map_or(0.0, |(lo, hi)| (hi - lo).max_element());
    let needed = receiver.is_some() && shadow_needed(sun, sunlight, footprint.is_some());
    ShadowFit {
        receiver,
        light_view_proj: light_view_proj(sun, &corners, centre, radius),
        footprint,
        map_size: shadow_map_size(px, sizes),
        needed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube standing on the origin: x, y in [-0.5, 0.5], z in [0, 1].
    fn cube() -> [Vec3; 8] {
        box_corners((Vec3::new(-0.5, -0.5, 0.0), Vec3::new(0.5, 0.5, 1.0)), Mat4::IDENTITY)
    }

    fn close2(a: Vec2, b: Vec2) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn the_receiver_is_the_cube_and_its_shadow() {
        // Sun due south at 45° elevation: a 1 m tall cube's shadow reaches 1 m north of it.
        let sun = Vec3::new(0.0, -1.0, 1.0).normalize();
        let r = receiver(&cube(), sun, 0.0, Vec2::ZERO, 0.87).unwrap();
        assert!(close2(r.min, Vec2::new(-0.5, -0.5)) && close2(r.max, Vec2::new(0.5, 1.5)), "{r:?}");
        // Sun overhead: only the cube's own footprint.
        let r = receiver(&cube(), Vec3::Z, 0.0, Vec2::ZERO, 0.87).unwrap();
        assert!(close2(r.min, Vec2::splat(-0.5)) && close2(r.max, Vec2::splat(0.5)), "{r:?}");
        // Sun at 30° elevation towards the east-north-east (azimuth 60°): the shadow points to
        // azimuth 240°, length 1 / tan 30° = √3 m.
        let (el, az) = (30f32.to_radians(), 60f32.to_radians());
        let sun = Vec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
        let r = receiver(&cube(), sun, 0.0, Vec2::ZERO, 0.87).unwrap();
        let l = 3f32.sqrt();
        let tip = Vec2::new(-l * az.sin(), -l * az.cos());
        assert!(close2(r.min, Vec2::splat(-0.5) + tip) && close2(r.max, Vec2::splat(0.5)), "{r:?} tip {tip}");
        // The quad's matrix maps the unit square's corners onto the rectangle.
        let m = r.matrix();
        assert!((m.transform_point3(Vec3::new(-1.0, -1.0, 0.0)) - r.corners()[0]).length() < 1e-5);
        assert!((m.transform_point3(Vec3::new(1.0, 1.0, 0.0)) - r.corners()[2]).length() < 1e-5);
    }

    #[test]
    fn a_grazing_sun_is_clipped_and_a_set_sun_casts_nothing() {
        // 1° elevation: the shadow would be 57 m long; it is cut at 20 radii from the base.
        let sun = Vec3::new(0.0, -1f32.to_radians().cos(), 1f32.to_radians().sin());
        let r = receiver(&cube(), sun, 0.0, Vec2::ZERO, 0.87).unwrap();
        assert!((r.max.y - 20.0 * 0.87).abs() < 1e-4 && (r.min.y + 0.5).abs() < 1e-5, "{r:?}");
        // Still far smaller than the fixed 40-radius square the ground pass used to draw.
        assert!(r.area() < 0.05 * (40.0 * 0.87f32).powi(2), "{}", r.area());
        assert_eq!(receiver(&cube(), Vec3::new(0.0, 1.0, 0.0), 0.0, Vec2::ZERO, 0.87), None);
        assert_eq!(receiver(&cube(), Vec3::new(0.0, 0.9, -0.1).normalize(), 0.0, Vec2::ZERO, 0.87), None);
    }

    #[test]
    fn the_shadow_camera_touches_the_box_on_every_side() {
        let corners = box_corners((Vec3::new(-1.0, 0.0, -0.3), Vec3::new(1.0, 0.5, 0.3)), Mat4::from_rotation_z(0.4));
        let centre = corners.iter().copied().sum::<Vec3>() / 8.0;
        let radius = corners.iter().map(|c| (*c - centre).length()).fold(0.0, f32::max);
        for sun in [Vec3::new(0.3, -0.5, 0.8), Vec3::Z, Vec3::new(-0.9, 0.1, 0.2)] {
            let m = light_view_proj(sun.normalize(), &corners, centre, radius);
            let ndc: Vec<Vec3> = corners.iter().map(|&c| m.project_point3(c)).collect();
            let (lo, hi) = ndc.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
            // Tight across the sun: the box's extreme corners land on the map's edges.
            assert!(close2(lo.xy(), Vec2::splat(-1.0)) && close2(hi.xy(), Vec2::splat(1.0)), "{sun}: {lo} {hi}");
            // Depth inside 0..1 (the sphere's range along the sun).
            assert!(lo.z >= -1e-5 && hi.z <= 1.0 + 1e-5, "{sun}: {lo} {hi}");
        }
    }

    #[test]
    fn the_screen_rect_is_clipped_and_empty_off_screen() {
        // A 90° square camera at the origin looking down −z: (x, y, −1) with |x|, |y| <= 1 is in view.
        let vp = glam::camera::rh::proj::directx::perspective(90f32.to_radians(), 1.0, 0.1, 100.0);
        let (lo, hi) = screen_rect(&[Vec3::new(-0.5, -0.5, -1.0), Vec3::new(0.5, 0.5, -1.0)], vp, (200, 100)).unwrap();
        // x: ±0.5 -> 50..150 px of 200; y: ±0.5 -> 25..75 px of 100 (rows down).
        assert!(close2(lo, Vec2::new(50.0, 25.0)) && close2(hi, Vec2::new(150.0, 75.0)), "{lo} {hi}");
        // Half off the right edge: clipped.
        let (lo, hi) = screen_rect(&[Vec3::new(0.5, 0.0, -1.0), Vec3::new(3.0, 0.5, -1.0)], vp, (200, 100)).unwrap();
        assert!(close2(lo, Vec2::new(150.0, 25.0)) && close2(hi, Vec2::new(200.0, 50.0)), "{lo} {hi}");
        // Wholly to the right: off-screen.
        assert_eq!(screen_rect(&[Vec3::new(2.0, 0.0, -1.0), Vec3::new(3.0, 0.5, -1.0)], vp, (200, 100)), None);
        // Wholly behind the camera: off-screen; straddling it: conservatively the whole image.
        assert_eq!(screen_rect(&[Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 2.0)], vp, (200, 100)), None);
        let whole = Some((Vec2::ZERO, Vec2::new(200.0, 100.0)));
        assert_eq!(screen_rect(&[Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -2.0)], vp, (200, 100)), whole);
    }

    #[test]
    fn a_texel_per_pixel_from_the_preallocated_sizes() {
        assert_eq!(shadow_map_size(0.0, &SHADOW_MAP_SIZES), 256);
        assert_eq!(shadow_map_size(256.0, &SHADOW_MAP_SIZES), 256);
        assert_eq!(shadow_map_size(300.0, &SHADOW_MAP_SIZES), 512);
        assert_eq!(shadow_map_size(960.0, &SHADOW_MAP_SIZES), 1024);
        assert_eq!(shadow_map_size(5000.0, &SHADOW_MAP_SIZES), 2048);
        assert_eq!(shadow_map_size(f32::NAN, &SHADOW_MAP_SIZES), 2048);
    }

    #[test]
    fn a_held_map_serves_until_the_box_moves_an_eighth_of_a_texel() {
        // The unit cube under a sun 40° up in the south-east, into a 1024² map.
        let corners = cube();
        let centre = Vec3::new(0.0, 0.0, 0.5);
        let radius = 0.75f32.sqrt();
        let sun = |az: f32| {
            let (el, az) = (40f32.to_radians(), az.to_radians());
            Vec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin())
        };
        let drawn = |az: f32, model: Mat4, level: usize| ShadowDrawn {
            light_view_proj: light_view_proj(sun(az), &corners, centre, radius),
            model,
            level,
        };
        let held = drawn(135.0, Mat4::IDENTITY, 2);
        assert!(map_still_valid(&held, &held, &corners, 1024));
        // The map spans the cube across the sun (about 1.4 m), so a texel of 1024 is ~1.4 mm
        // and an eighth of it ~0.17 mm; a corner ~0.7 m from the turning axis moves ~12 µm per
        // 1/1000° of azimuth (4 minutes of the sun's motion: kept) and ~0.6 mm per 1/20° (drawn
        // again).
        assert!(map_still_valid(&held, &drawn(135.001, Mat4::IDENTITY, 2), &corners, 1024));
        assert!(!map_still_valid(&held, &drawn(135.05, Mat4::IDENTITY, 2), &corners, 1024));
        // A quarter of the resolution tolerates four times the motion: 1/30° (~0.37 mm) keeps a
        // 256² map (an eighth of its texel ~0.7 mm) but not a 1024² one.
        assert!(map_still_valid(&held, &drawn(135.03, Mat4::IDENTITY, 2), &corners, 256));
        assert!(!map_still_valid(&held, &drawn(135.03, Mat4::IDENTITY, 2), &corners, 1024));
        // Another level of detail or a moved model always draws again.
        assert!(!map_still_valid(&held, &drawn(135.0, Mat4::IDENTITY, 3), &corners, 1024));
        assert!(!map_still_valid(&held, &drawn(135.0, Mat4::from_translation(Vec3::X * 1e-3), 2), &corners, 1024));
    }

    /// Area of a triangle list (three points each), by the shoelace formula.
    fn triangles_area(t: &[Vec2]) -> f32 {
        t.chunks_exact(3).map(|t| 0.5 * (t[1] - t[0]).perp_dot(t[2] - t[0]).abs()).sum()
    }

    /// Whether `q` lies strictly inside triangle `t` (not on an edge).
    fn strictly_inside(t: &[Vec2], q: Vec2) -> bool {
        let s: Vec<f32> = (0..3).map(|i| (t[(i + 1) % 3] - t[i]).perp_dot(q - t[i])).collect();
        (s.iter().all(|&v| v > 1e-6)) || (s.iter().all(|&v| v < -1e-6))
    }

    #[test]
    fn the_lookups_reach_is_its_penumbra_and_two_texels() {
        // A 512² map over 1 x 2 m: a texel is 2/512 = 3.906 mm. A model of radius 1 m under the
        // sun (angular radius 0.2665°, tan 0.004651): the widest penumbra, a blocker 2 m away, is
        // 9.30 mm; reach = 1.25 * 9.30 + 2 * 3.906 = 19.44 mm.
        let tan_sun = 0.2665f32.to_radians().tan();
        let r = lookup_reach(512, Vec2::new(1.0, 2.0), 1.0, tan_sun);
        assert!((r - (1.25 * 2.0 * tan_sun + 2.0 * 2.0 / 512.0)).abs() < 1e-6 && (r - 0.019_44).abs() < 1e-4, "{r}");
        // A point sun: the penumbra is at least a texel.
        assert!((lookup_reach(512, Vec2::new(1.0, 2.0), 1.0, 0.0) - 3.25 * 2.0 / 512.0).abs() < 1e-7);
    }

    /// The bounding box of a polygon.
    fn bbox(o: &[Vec2]) -> (Vec2, Vec2) {
        o.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
    }

    #[test]
    fn the_outline_is_the_silhouette_widened_and_swept_onto_the_ground() {
        let corners = cube();
        let sphere = (Vec3::new(0.0, 0.0, 0.5), 0.75f32.sqrt());
        let outline = |sun: Vec3, vertices: &[Vec3], size: u32, tan: f32| {
            let lvp = light_view_proj(sun, &corners, sphere.0, sphere.1);
            silhouette_outline(lvp, (Mat4::IDENTITY, vertices.iter().copied()), 0.0, (size, tan, sphere.1))
        };
        // The sun overhead: the cube's silhouette is its 1 x 1 m footprint, and the outline is
        // that square widened by the reach (the 12 directions include the map's axes).
        let reach = lookup_reach(1024, Vec2::ONE, sphere.1, 0.01);
        let o = outline(Vec3::Z, &corners, 1024, 0.01);
        let (lo, hi) = bbox(&o);
        assert!(close2(lo, Vec2::splat(-0.5 - reach)) && close2(hi, Vec2::splat(0.5 + reach)), "{o:?} reach {reach}");
        assert!(o.len() == OUTLINE_DIRECTIONS && signed_area(&o) > 0.0, "counter-clockwise: {o:?}");
        // The sun 45° up in the south: the cube and its shadow cover x in [-0.5, 0.5], y in
        // [-0.5, 1.5]. The cube seen from the sun is a 1 x √2 m rectangle (map x: world x; map
        // y: (0, 1, 1)/√2); a reach r across the sun is r·√2 along the ground northwards.
        let sun = Vec3::new(0.0, -1.0, 1.0).normalize();
        let (lo, hi) = bbox(&outline(sun, &corners, 1024, 0.0));
        let reach = lookup_reach(1024, Vec2::new(1.0, 2f32.sqrt()), sphere.1, 0.0);
        let want_lo = Vec2::new(-0.5 - reach, -0.5 - reach * 2f32.sqrt());
        let want_hi = Vec2::new(0.5 + reach, 1.5 + reach * 2f32.sqrt());
        assert!((lo - want_lo).abs().max_element() < 1e-4 && (hi - want_hi).abs().max_element() < 1e-4, "{lo} {hi} vs {want_lo} {want_hi}");
        // A model whose silhouette is not its box: the octahedron in the cube, seen from above,
        // is the diamond |x| + |y| <= 0.5 (area 0.5), half of its box. Its support along the 12
        // directions is 0.5 on the axes and 0.5 cos 30° at ±30° from them; sides 30° and 60°
        // meet at (a, a), a = (√3/4) / ((1 + √3)/2), so the polygon's area is 8 · ½ · 0.5 · a
        // = √3 / (1 + √3) = 0.634, where the map's rectangle gave 1; plus the reach (a point
        // sun, 3.25 texels of 2048) around its perimeter (< 3.5).
        let octahedron = [(0.5, 0.0, 0.5), (-0.5, 0.0, 0.5), (0.0, 0.5, 0.5), (0.0, -0.5, 0.5), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
            .map(|(x, y, z)| Vec3::new(x, y, z));
        let o = outline(Vec3::Z, &octahedron, 2048, 0.0);
        let area = 0.5 * signed_area(&o);
        let (want, reach) = (3f32.sqrt() / (1.0 + 3f32.sqrt()), lookup_reach(2048, Vec2::ONE, sphere.1, 0.0));
        assert!(area > want && area < want + 3.5 * reach, "{area} vs {want} + reach {reach}");
        assert!(octahedron.iter().all(|p| clip_convex(&[p.truncate()], &o).len() == 1), "{o:?}");
        // No vertices: no outline.
        assert!(outline(Vec3::Z, &[], 1024, 0.0).is_empty());
    }

    #[test]
    fn support_polygons_and_hulls() {
        // The unit square's corners along 4 and 8 directions: the square itself (the diagonal
        // sides touch it at the corners, zero length).
        let square = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 1.0), Vec2::new(-1.0, 1.0)];
        for n in [4, 8] {
            let dirs = directions(n);
            let p = polygon_from_supports(&dirs, &supports(square, &dirs));
            assert!((0.5 * signed_area(&p) - 4.0).abs() < 1e-5, "{n}: {p:?}");
        }
        // A point along 4 directions: a square of side 0 at the point.
        let dirs = directions(4);
        let p = polygon_from_supports(&dirs, &supports([Vec2::new(2.0, 3.0)], &dirs));
        assert!(p.iter().all(|q| close2(*q, Vec2::new(2.0, 3.0))), "{p:?}");
        // The hull of the square's corners, its centre, an edge's midpoint and a repeat:
        // the four corners, counter-clockwise.
        let mut points = square.to_vec();
        points.extend([Vec2::ZERO, Vec2::new(1.0, 0.0), square[2]]);
        let h = convex_hull(&points);
        assert!(h.len() == 4 && (0.5 * signed_area(&h) - 4.0).abs() < 1e-6, "{h:?}");
    }

    #[test]
    fn the_sky_region_holds_every_texel_hiding_enough() {
        // A 4 x 4 map (texels a quarter of the square); texel (1, 2) hides 10/255 of the sky,
        // (3, 3) 2/255, the rest nothing.
        let mut visibility = vec![1.0; 16];
        visibility[2 * 4 + 1] = 245.0 / 255.0;
        visibility[3 * 4 + 3] = 253.0 / 255.0;
        let mut sky = crate::scene::occlusion::GroundSky {
            min: Vec2::splat(7.0),
            max: Vec2::splat(11.0),
            z: 0.0,
            size: 4,
            visibility,
            visibility_rgb: Vec::new(),
            bounce: Vec::new(),
        };
        // At 10/255: texel (1, 2), centre (1.5, 2.5)/4, widened by a texel: [0.5, 2.5] x [1.5,
        // 3.5] quarters (the map's own placement does not matter: the ground square places it).
        let r = sky_region(&sky, 10.0 / 255.0, 1.0);
        let (lo, hi) = bbox(&r);
        assert!(close2(lo * 4.0, Vec2::new(0.5, 1.5)) && close2(hi * 4.0, Vec2::new(2.5, 3.5)), "{r:?}");
        assert!((0.5 * signed_area(&r) - 0.25).abs() < 1e-5, "{r:?}");
        // At 2/255 both: [0.5, 4.5] x [1.5, 4.5]; above 10/255 none.
        let (lo, hi) = bbox(&sky_region(&sky, 2.0 / 255.0, 1.0));
        assert!(close2(lo * 4.0, Vec2::new(0.5, 1.5)) && close2(hi * 4.0, Vec2::new(4.5, 4.5)), "{lo} {hi}");
        assert!(sky_region(&sky, 11.0 / 255.0, 1.0).is_empty());
        // The model's light on texel (0, 0), 0.02 in green, brings it in at a bounce threshold of
        // 0.01, not at 0.03: [-0.5, 1.5] x [-0.5, 1.5] quarters joined to texel (1, 2)'s box.
        sky.bounce = vec![[0.0; 3]; 16];
        sky.bounce[0] = [0.0, 0.02, 0.0];
        let (lo, hi) = bbox(&sky_region(&sky, 10.0 / 255.0, 0.01));
        assert!(close2(lo * 4.0, Vec2::new(-0.5, -0.5)) && close2(hi * 4.0, Vec2::new(2.5, 3.5)), "{lo} {hi}");
        let (lo, _) = bbox(&sky_region(&sky, 10.0 / 255.0, 0.03));
        assert!(close2(lo * 4.0, Vec2::new(0.5, 1.5)), "{lo}");
        // A texel whose blue alone loses 12/255 (a model hiding the blue overhead) comes in at
        // 10/255 whatever its luminance's share: texel (3, 0) widens the box to x = 4.5 quarters.
        sky.bounce.clear();
        sky.visibility_rgb = (0..16).map(|i| [sky.visibility[i]; 3]).collect();
        sky.visibility_rgb[3] = [1.0, 1.0, 243.0 / 255.0];
        let (lo, hi) = bbox(&sky_region(&sky, 10.0 / 255.0, 1.0));
        assert!(close2(lo * 4.0, Vec2::new(0.5, -0.5)) && close2(hi * 4.0, Vec2::new(4.5, 3.5)), "{lo} {hi}");
    }

    #[test]
    fn clipping_a_polygon_to_a_convex_polygon() {
        // A diamond of half-diagonal 2 clipped to the unit square [-1, 1]²: all of the square
        // (the diamond contains it): area 4.
        let square = rect_polygon(Vec2::splat(-1.0), Vec2::splat(1.0));
        let diamond = [Vec2::new(2.0, 0.0), Vec2::new(0.0, 2.0), Vec2::new(-2.0, 0.0), Vec2::new(0.0, -2.0)];
        let c = clip_convex(&diamond, &square);
        assert!((0.5 * signed_area(&c) - 4.0).abs() < 1e-5, "{c:?}");
        // Shifted right by 2: the triangle x + |y| <= 2 ... inside the square: x from 0 to 1,
        // |y| <= x: area 1.
        let shifted = diamond.map(|p| p + Vec2::new(2.0, 0.0));
        let c = clip_convex(&shifted, &square);
        assert!((0.5 * signed_area(&c) - 1.0).abs() < 1e-5, "{c:?}");
        // The square clipped to the unshifted diamond |x| + |y| <= 2: all of it; to the diamond
        // of half-diagonal 1: that diamond (area 2).
        assert!((0.5 * signed_area(&clip_convex(&square, &diamond)) - 4.0).abs() < 1e-5);
        let small = diamond.map(|p| p * 0.5);
        assert!((0.5 * signed_area(&clip_convex(&square, &small)) - 2.0).abs() < 1e-5);
        // Apart: nothing.
        let far = diamond.map(|p| p + Vec2::new(10.0, 0.0));
        assert!(clip_convex(&far, &square).is_empty());
    }

    #[test]
    fn the_split_covers_the_outer_polygon_once() {
        let (min, max) = (Vec2::new(-1.0, -2.0), Vec2::new(3.0, 1.0));
        let rect = rect_polygon(min, max);
        // A square inside, one across the edge, a parallelogram across a corner, one apart.
        let inside = [Vec2::new(0.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
        let across = inside.map(|p| p + Vec2::new(2.5, 0.0));
        let corner = [Vec2::new(2.0, 0.0), Vec2::new(4.0, 0.5), Vec2::new(4.5, 2.0), Vec2::new(2.5, 1.5)];
        let apart = inside.map(|p| p + Vec2::new(10.0, 0.0));
        // The inner parts' areas by hand: 1; 0.5 x 1 (x from 2.5 to 3); the corner parallelogram
        // within x <= 3, y <= 1: its edge from (2, 0) to (4, 0.5) and from (2, 0) to (2.5,
        // 1.5) bound it: the part is the quadrilateral (2, 0), (3, 0.25), (3, 1), (2.333, 1)
        // (shoelace: 0.7917); none.
        let corner_area = {
            let q = [Vec2::new(2.0, 0.0), Vec2::new(3.0, 0.25), Vec2::new(3.0, 1.0), Vec2::new(2.0 + 1.0 / 3.0, 1.0)];
            0.5 * signed_area(&q)
        };
        // The rectangle with its corners cut at 45° (1 m legs): area 12 - 4 x 0.5 = 10; the
        // inside square lies in it, so its part is still 1.
        let cut = [(0.0, -2.0), (2.0, -2.0), (3.0, -1.0), (3.0, 0.0), (2.0, 1.0), (0.0, 1.0), (-1.0, 0.0), (-1.0, -1.0)]
            .map(|(x, y)| Vec2::new(x, y));
        let cases = [
            (&inside[..], &rect[..], 1.0, 12.0),
            (&across[..], &rect[..], 0.5, 12.0),
            (&corner[..], &rect[..], corner_area, 12.0),
            (&apart[..], &rect[..], 0.0, 12.0),
            (&[][..], &rect[..], 0.0, 12.0),
            (&inside[..], &cut[..], 1.0, 10.0),
        ];
        for (poly, outer, area, total) in cases {
            let (fan, ring) = split_convex(poly, outer);
            assert!((triangles_area(&fan) - area).abs() < 1e-4, "{poly:?}: fan {}", triangles_area(&fan));
            assert!((triangles_area(&fan) + triangles_area(&ring) - total).abs() < 1e-4, "{poly:?}: ring {}", triangles_area(&ring));
            // Counter-clockwise (or degenerate, where the inner part touches the outer boundary).
            let ccw = |t: &[Vec2]| (t[1] - t[0]).perp_dot(t[2] - t[0]) >= -1e-6;
            assert!(fan.chunks_exact(3).chain(ring.chunks_exact(3)).all(ccw), "{poly:?}: a clockwise triangle");
            let inner_max = poly.len() + outer.len();
            assert!(fan.len() + ring.len() <= 3 * (3 * inner_max + outer.len()), "{}", fan.len() + ring.len());
            // Every point of a grid (none on an edge by construction of the odd offsets) lies
            // in exactly one triangle of the two lists, or in none outside the outer polygon.
            for i in 0..40 {
                for j in 0..30 {
                    let q = min + Vec2::new((i as f32 + 0.437) * 0.1, (j as f32 + 0.291) * 0.1);
                    let hits = fan.chunks_exact(3).chain(ring.chunks_exact(3)).filter(|t| strictly_inside(t, q)).count();
                    let on_edge = fan
                        .chunks_exact(3)
                        .chain(ring.chunks_exact(3))
                        .any(|t| (0..3).any(|k| (t[(k + 1) % 3] - t[k]).perp_dot(q - t[k]).abs() <= 1e-6));
                    let want = usize::from(clip_convex(&[q], outer).len() == 1);
                    assert!(hits == want || on_edge, "{poly:?}: {q} in {hits} triangles");
                }
            }
        }
    }

    #[test]
    fn no_shadow_pass_without_sun_or_on_screen_footprint() {
        let up = Vec3::new(0.0, -0.6, 0.8);
        assert!(shadow_needed(up, 1.0, true));
        assert!(!shadow_needed(Vec3::new(0.0, -0.8, -0.6), 1.0, true), "sun below the horizon");
        assert!(!shadow_needed(up, 0.0, true), "overcast: no measured sun");
        assert!(!shadow_needed(up, 1.0, false), "footprint off-screen");
        // Through `fit`: a cube 5 m ahead of a camera looking north needs a shadow; turned
        // around (looking south), neither the cube nor its shadow is in view.
        let bounds = (Vec3::new(-0.5, -0.5, 0.0), Vec3::new(0.5, 0.5, 1.0));
        let model = Mat4::from_translation(Vec3::new(0.0, 5.0, 0.0));
        let sphere = (Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, 5.0, 0.5), 0.87);
        let proj = crate::render::view::projection(60f32.to_radians(), 1.5, 0.1, 100.0);
        let cam = Vec3::new(0.0, 0.0, 1.6);
        let look = |heading: f32| proj * crate::render::view::view_matrix(crate::render::view::camera_pose(heading, -0.2, 0.0), cam);
        let f = fit(bounds, model, sphere, (up.normalize(), 1.0), (look(0.0), (960, 640)), &SHADOW_MAP_SIZES);
        assert!(f.needed && f.footprint.is_some() && f.receiver.is_some(), "{f:?}");
        // The cube and its shadow span some hundred pixels: a 256-512 map suffices, not 2048.
        let (lo, hi) = f.footprint.unwrap();
        assert!(f.map_size < 2048 && f.map_size as f32 >= (hi - lo).max_element(), "{f:?}");
        let f = fit(bounds, model, sphere, (up.normalize(), 1.0), (look(std::f32::consts::PI), (960, 640)), &SHADOW_MAP_SIZES);
        assert!(!f.needed && f.footprint.is_none(), "{f:?}");
    }
}
