//! Ambient occlusion computed once per model: the fraction of the cosine-weighted hemisphere
//! above each vertex that sees past the model itself ("visibility", 1 = open sky, 0 = enclosed).
//!
//! Visibility does not depend on the view, so it is computed at load by casting deterministic
//! cosine-distributed rays (a Hammersley set, shifted per vertex so that neighbours do not share
//! one pattern) against a bounding-volume hierarchy of the model's triangles. The same
//! [`Occluders`] answer the ground's question: how much of the sky a point under the model sees
//! ([`sky_visibility`]), and under any sky at once through the rays kept with their directions,
//! which each sky's radiance weights ([`ground_transfer`]). A compact BVH is written here rather than taken from
//! a crate: the job is any-hit queries on a static triangle list (~150 lines), and
//! `bvh`/`parry3d` would bring nalgebra and a second maths library next to glam.

use super::{Mesh, Model};
use crate::light::sh9::{SKY_BINS, SKY_COLUMNS, SKY_ROWS, SkyRadiance};
use glam::{Mat4, Vec2, Vec3};
use std::f32::consts::TAU;

/// Rays cast for a whole model at most (when that leaves each vertex at least [`MIN_RAYS`]): the
/// load-time cost is bounded by the model's size, ~0.7 µs a ray on one core of the development
/// machine (the 100k-triangle dragon: 50k vertices, 40 rays each).
pub const RAY_BUDGET: u32 = 2_000_000;
/// Rays per vertex for small models.
pub const MAX_RAYS: u32 = 64;
/// Rays per vertex for the largest models.
pub const MIN_RAYS: u32 = 8;

/// Rays per vertex for a model of `vertices` vertices under [`RAY_BUDGET`].
pub fn rays_per_vertex(vertices: usize) -> u32 {
    (RAY_BUDGET as usize / vertices.max(1)).clamp(MIN_RAYS as usize, MAX_RAYS as usize) as u32
}

/// Triangles per BVH leaf at most.
const LEAF_SIZE: usize = 4;
/// Deepest node: a traversal holds at most one pending sibling per level.
const MAX_DEPTH: usize = 62;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first triangle; inner node: index of the left child (the right one follows it).
    first: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// The triangles that can block a ray, in a bounding-volume hierarchy (binned surface-area
/// heuristic, Wald 2007).
#[derive(Clone, Debug)]
pub struct Occluders {
    nodes: Vec<Node>,
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle (in `triangles`' order), the model's light on it as shares of an open
    /// surface's ([`model_sky_ground`]'s four, the mean of its vertices'), then its albedo's
    /// luminance over the model's mean ([`mean_albedo`]); empty: every triangle open and of the
    /// mean albedo ([`OPEN_SURFACE`]). Set by [`Occluders::attach_light_shares`].
    shares: Vec<[f32; 5]>,
    /// Ray offset from the surface: a small fraction of the model's size.
    epsilon: f32,
}

/// The light shares of a surface nothing occludes ([`model_sky_ground`]'s order: sky, ground lit
/// by the sky, ground, the model's own bounce), of the model's mean albedo (1).
pub const OPEN_SURFACE: [f32; 5] = [1.0, 1.0, 1.0, 0.0, 1.0];

impl Occluders {
    /// Every triangle of `model`, in model space.
    pub fn of_model(model: &Model) -> Occluders {
        Occluders::new(model.meshes.iter().flat_map(mesh_triangles).collect())
    }

    /// A hierarchy over `triangles` (degenerate ones are kept: they are never hit).
    pub fn new(mut triangles: Vec<[Vec3; 3]>) -> Occluders {
        let (lo, hi) = bounds(&triangles);
        let diagonal = if triangles.is_empty() { 0.0 } else { (hi - lo).length() };
        let mut nodes = vec![Node { lo, hi, first: 0, count: triangles.len() as u32 }];
        // Split nodes breadth-first; each split appends the two children together.
        let mut todo = vec![(0usize, 0usize)];
        while let Some((i, depth)) = todo.pop() {
            let Node { first, count, .. } = nodes[i];
            let (first, count) = (first as usize, count as usize);
            // The depth bound keeps every traversal inside `blocked`'s fixed stack.
            if count <= LEAF_SIZE || depth >= MAX_DEPTH {
                continue;
            }
            let Some(half) = sah_split(&mut triangles[first..first + count]) else { continue };
            let left = nodes.len();
            for (start, n) in [(first, half), (first + half, count - half)] {
                let (lo, hi) = bounds(&triangles[start..start + n]);
                nodes.push(Node { lo, hi, first: start as u32, count: n as u32 });
            }
            nodes[i].first = left as u32;
            nodes[i].count = 0;
            todo.extend([(left, depth + 1), (left + 1, depth + 1)]);
        }
        Occluders { nodes, triangles, shares: Vec::new(), epsilon: 1e-5 * diagonal.max(f32::MIN_POSITIVE) }
    }

    /// Give each triangle of `model` (the one these occluders were made of) the mean of its
    /// vertices' light shares (`per_vertex`, per mesh: [`model_sky_ground`]) and its albedo (the
    /// material's colour times its texture at the triangle's mean uv, nearest texel) over the
    /// model's mean, so that what a ray hits says how much light that surface gets and reflects
    /// ([`Occluders::transfer`]'s bounce: a truck's dark chassis reflects less than its white
    /// body). Triangles are matched by their corners (the hierarchy reorders them); one not
    /// found stays open.
    pub fn attach_light_shares(&mut self, model: &Model, per_vertex: &[Vec<VertexLight>]) {
        let key = |t: [Vec3; 3]| t.map(|p| p.to_array().map(f32::to_bits));
        let lum = crate::colour::luminance_bt709;
        let mean = lum(mean_albedo(model)).max(1e-6);
        let mut by_corners = std::collections::HashMap::new();
        for (mesh, shares) in model.meshes.iter().zip(per_vertex) {
            let Some(material) = model.materials.get(mesh.material) else { continue };
            for t in mesh.indices.chunks_exact(3) {
                let corner = |i: u32| {
                    let uv = mesh.uvs.get(i as usize).copied().unwrap_or([0.0; 2]);
                    Some((Vec3::from_array(*mesh.positions.get(i as usize)?), shares.get(i as usize)?.ao, glam::Vec2::from(uv)))
                };
                let (Some(a), Some(b), Some(c)) = (corner(t[0]), corner(t[1]), corner(t[2])) else { continue };
                let texel = material.texture.as_ref().map_or([1.0; 3], |tex| texel_at(tex, (a.2 + b.2 + c.2) / 3.0));
                let albedo = lum(std::array::from_fn(|k| material.diffuse[k] * texel[k]));
                let mut v = [0.0; 5];
                (0..4).for_each(|k| v[k] = (a.1[k] + b.1[k] + c.1[k]) / 3.0);
                v[4] = albedo / mean;
                by_corners.insert(key([a.0, b.0, c.0]), v);
            }
        }
        self.shares = self.triangles.iter().map(|t| by_corners.get(&key(*t)).copied().unwrap_or(OPEN_SURFACE)).collect();
    }

    /// Whether the ray `origin + t·dir`, 0 < t < `t_max`, hits any triangle (either side).
    pub fn blocked(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let inv = dir.recip();
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !slab_hit(node.lo, node.hi, origin, inv, t_max) {
                continue;
            }
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                if self.triangles[range].iter().any(|t| triangle_hit(t, origin, dir, t_max)) {
                    return true;
                }
            } else {
                stack[top] = node.first;
                stack[top + 1] = node.first + 1;
                top += 2;
            }
        }
        false
    }

    /// The nearest triangle the ray `origin + t·dir`, t > 0, hits (either side): its distance t
    /// along the ray (in units of `dir`'s length), its (unnormalised) face normal, turned to face
    /// the ray's origin, and its light shares and albedo ([`Occluders::attach_light_shares`]).
    /// None when it hits nothing: a ray [`Occluders::blocked`] lets through (the same tests).
    pub fn nearest_hit(&self, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3, [f32; 5])> {
        let (t, i) = self.nearest_triangle(origin, dir)?;
        let [a, b, c] = self.triangles[i];
        let n = (b - a).cross(c - a);
        Some((t, if n.dot(dir) > 0.0 { -n } else { n }, self.shares.get(i).copied().unwrap_or(OPEN_SURFACE)))
    }

    /// The nearest triangle the ray `origin + t·dir`, t > 0, hits (either side): its distance t
    /// and its index in the hierarchy's order ([`Occluders::triangle`]); of hits at the same
    /// distance, the lowest index.
    pub fn nearest_triangle(&self, origin: Vec3, dir: Vec3) -> Option<(f32, usize)> {
        let inv = dir.recip();
        let entry = |i: u32, t_max: f32| {
            let node = &self.nodes[i as usize];
            slab_entry(node.lo, node.hi, origin, inv, t_max).map(|t| (i, t))
        };
        // Nodes still to visit with the distance at which the ray enters them, the nearer child
        // on top: a near hit found first leaves the far side's boxes out (Wald 2007 §4 visits
        // children front to back the same way).
        let mut stack = [(0u32, 0f32); 64];
        let mut top = 0;
        if !self.triangles.is_empty()
            && let Some(root) = entry(0, f32::INFINITY)
        {
            stack[0] = root;
            top = 1;
        }
        let mut nearest: Option<(f32, usize)> = None;
        while top > 0 {
            top -= 1;
            let (i, enters) = stack[top];
            let t_max = nearest.map_or(f32::INFINITY, |(t, _)| t);
            // A hit inside the box is no nearer than where the ray enters it.
            if enters > t_max {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                for i in node.first as usize..(node.first + node.count) as usize {
                    // Of two hits at the same distance (a ray along an edge two triangles share)
                    // the first in the hierarchy's order, whatever order the boxes are visited in.
                    let (t_max, first) = nearest.unwrap_or((f32::INFINITY, usize::MAX));
                    if let Some(t) = triangle_distance(&self.triangles[i], origin, dir, t_max.next_up())
                        && (t < t_max || i < first)
                    {
                        nearest = Some((t, i));
                    }
                }
            } else {
                match (entry(node.first, t_max), entry(node.first + 1, t_max)) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a.1 <= b.1 { (a, b) } else { (b, a) };
                        stack[top] = far;
                        stack[top + 1] = near;
                        top += 2;
                    }
                    (Some(one), None) | (None, Some(one)) => {
                        stack[top] = one;
                        top += 1;
                    }
                    (None, None) => {}
                }
            }
        }
        nearest
    }

    /// The corners of triangle `i` in the hierarchy's order ([`Occluders::nearest_triangle`]).
    pub fn triangle(&self, i: usize) -> Option<[Vec3; 3]> {
        self.triangles.get(i).copied()
    }

    /// How many triangles the hierarchy holds.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The cosine-weighted visibility of the hemisphere around unit `normal` at `point`, from
    /// `rays` rays whose pattern is shifted by `seed` (deterministic).
    pub fn visibility(&self, point: Vec3, normal: Vec3, rays: u32, seed: u32) -> f32 {
        self.weighted_visibility(point, normal, rays, seed, |_| 1.0)
    }

    /// [`Occluders::visibility`] with each direction `d` (unit, the occluders' space) weighted by
    /// `radiance(d)` ≥ 0: the share of the cosine-weighted light from a sky of that radiance that
    /// reaches `point`, Σ V(d) L(d) / Σ L(d) over the same rays. A weight of 1 everywhere is
    /// the plain visibility; a sky that gives no light along the rays leaves it plain too.
    pub fn weighted_visibility(&self, point: Vec3, normal: Vec3, rays: u32, seed: u32, radiance: impl Fn(Vec3) -> f32) -> f32 {
        let Some(n) = normal.try_normalize() else { return 1.0 };
        let (mut open, mut total, mut open_n) = (0f32, 0f32, 0u32);
        self.cast(point, n, rays, seed, |dir, hit| {
            let w = radiance(dir).max(0.0);
            total += w;
            if !hit {
                open += w;
                open_n += 1;
            }
        });
        if total > 0.0 { open / total } else { open_n as f32 / rays.max(1) as f32 }
    }

    /// The rays of a ground point (`point`, `normal`: the world's up in the occluders' space) for
    /// a sky of any radiance ([`Transfer`]): each ray's world direction and whether it passes the
    /// occluders, so that a sky's map weights them by its own radiance
    /// ([`Transfer::weighted_visibility`]). `placement` turns the occluders' space into the
    /// world's (a rotation and a uniform scale; its translation is not used). The rays are
    /// [`sky_rays`]: the same number in each of the sky's rows, spread over its columns, so that
    /// every bin of a sky's radiance (light::sh9::SkyRadiance) is met by a ray at 256 rays.
    ///
    /// The rays the occluders block also say what the point sees of them ([`Bounce`]): sums over
    /// each blocked ray's nearest hit (face normal n facing the point, light shares a of the
    /// triangle), each ray counted by its share of the cosine-weighted hemisphere. A Lambertian
    /// occluder of albedo ρ whose surface facing n receives irradiance E(n) sends the point
    /// ρ π · Σ_hits s_i E(n_i)/π: the rays estimate ∫ L cos θ dω as π Σ s_i L_i (configuration
    /// factors, e.g. Modest, Radiative Heat Transfer, §4.3), and each hit's radiance is
    /// ρ E(n_i)/π. E is the light previz's own model shading gives that surface
    /// (shaders/sh9_ggx.wgsl `sky_and_ground`, plus the sun unshadowed), split so any light
    /// recombines it: its sky part by `basis` of the hit's world normal (light::sh9::basis).
    pub fn transfer(
        &self,
        (point, normal): (Vec3, Vec3),
        rays: u32,
        seed: u32,
        placement: Mat4,
        basis: impl Fn(Vec3) -> [f32; TERMS],
    ) -> Transfer {
        let Some(n) = normal.try_normalize() else {
            return Transfer { plain: 1.0, ..Transfer::default() };
        };
        let frame = placement_rotation(placement);
        let mut t = Transfer { rays: Vec::with_capacity(rays as usize), ..Transfer::default() };
        let origin = point + n * self.epsilon;
        for (world, share) in sky_rays(rays, seed) {
            let dir = frame.transpose() * world;
            let Some((_, face, a)) = self.nearest_hit(origin, dir) else {
                t.rays.push(SkyRay::new(world, true));
                t.plain += share;
                continue;
            };
            t.rays.push(SkyRay::new(world, false));
            let Some(f) = face.try_normalize() else { continue };
            let w = (frame * f).normalize_or_zero();
            let y = basis(w);
            let b = &mut t.bounce;
            let albedo = a[4] * share;
            b.sky.iter_mut().zip(y).for_each(|(s, y)| *s += albedo * (a[0] + a[3]) * y);
            b.sun.push([w.x, w.y, w.z, albedo]);
            // The ground below: E/π = L (1 − f_z)/2, up being the point's normal (a ground
            // point's: the world's up).
            let down = 0.5 * (1.0 - f.dot(n));
            b.ground[0] += albedo * down * (a[1] + a[3]);
            b.ground[1] += albedo * down * (a[2] + a[3]);
        }
        t
    }

    /// Cast `rays` cosine-distributed rays about unit `n` from `point` (a Hammersley set shifted
    /// by `seed`): `each(direction, blocked)` for each.
    fn cast(&self, point: Vec3, n: Vec3, rays: u32, seed: u32, mut each: impl FnMut(Vec3, bool)) {
        let origin = point + n * self.epsilon;
        for dir in ray_directions(n, rays, seed) {
            each(dir, self.blocked(origin, dir, f32::INFINITY));
        }
    }
}

/// The directions [`Occluders::cast`] casts: `rays` (at least one) cosine-distributed about unit
/// `n`, a Hammersley set shifted by `seed`. The same directions every time, so a ray's direction
/// need not be kept ([`SampleRays`]).
pub fn ray_directions(n: Vec3, rays: u32, seed: u32) -> impl Iterator<Item = Vec3> {
    let (t, b) = orthonormal_basis(n);
    let shift = (unit_hash(seed), unit_hash(seed.wrapping_mul(0x9E37_79B9) ^ 0x5bd1_e995));
    let rays = rays.max(1);
    (0..rays).map(move |i| {
        let (u1, u2) = hammersley(i, rays);
        let d = cosine_direction((u1 + shift.0).fract(), (u2 + shift.1).fract());
        t * d.x + b * d.y + n * d.z
    })
}

/// The rotation of `placement` (a rotation and a uniform scale): model directions → world.
fn placement_rotation(placement: Mat4) -> glam::Mat3 {
    let scale = placement.transform_vector3(Vec3::X).length();
    glam::Mat3::from_mat4(placement) * if scale > 0.0 { 1.0 / scale } else { 1.0 }
}

/// `rays` unit world directions over the upper hemisphere for a ground point, each with its share
/// of the cosine-weighted hemisphere (the shares sum to 1), shifted by `seed`: [`SKY_ROWS`] rows
/// of equal z steps (light::sh9::SkyRadiance's rows), the same number of rays in each (`rays` /
/// [`SKY_ROWS`], at least one), each ray in its own equal slice of azimuth (clockwise from North)
/// and within it at a jittered point, cosine-distributed within its row (z² uniform). At 256
/// rays, one in each of the sky's 8 × 32 bins: a bright bin near the horizon, which 256
/// cosine-distributed rays met about once in eight texels, is met in every texel (docs/accuracy.md
/// "Tenth session").
pub fn sky_rays(rays: u32, seed: u32) -> impl Iterator<Item = (Vec3, f32)> {
    let rows = SKY_ROWS as u32;
    let per_row = (rays / rows).max(1);
    (0..per_row * rows).map(move |k| {
        let (i, j) = (k / per_row, k % per_row);
        let key = seed.wrapping_mul(per_row * rows).wrapping_add(k);
        let (u1, u2) = (unit_hash(key ^ 0x5bd1_e995), unit_hash(key.wrapping_mul(0x9E37_79B9) ^ 0x27d4_eb2f));
        let (z0, z1) = (i as f32 / rows as f32, (i + 1) as f32 / rows as f32);
        let z = (z0 * z0 + (z1 * z1 - z0 * z0) * u1).sqrt();
        let phi = TAU * (j as f32 + u2) / per_row as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        (Vec3::new(r * phi.sin(), r * phi.cos(), z), (z1 * z1 - z0 * z0) / per_row as f32)
    })
}

/// A ray's share of the cosine-weighted hemisphere relative to the others' at height `z`
/// ([`sky_rays`]: 2i + 1 in row i).
fn row_weight(z: f32) -> f32 {
    let i = (z * SKY_ROWS as f32).floor().clamp(0.0, SKY_ROWS as f32 - 1.0);
    2.0 * i + 1.0
}

/// Terms of a [`Bounce`]'s sky part: the nine real spherical harmonics up to l = 2
/// (light::sh9::basis) of the surface's normal, as the model's own sky light is.
pub const TERMS: usize = 9;

/// One ground point's rays ([`Occluders::transfer`]): the visibility under any sky
/// ([`Transfer::weighted_visibility`]) and the occluders' bounce under any light.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Transfer {
    /// The cosine-weighted share of the sky the point sees past the occluders: the visibility
    /// under a uniform sky.
    pub plain: f32,
    /// What the point sees of the occluders' surface ([`Occluders::transfer`]).
    pub bounce: Bounce,
    /// Each ray's world direction and whether it sees the sky ([`sky_rays`]).
    pub rays: Vec<SkyRay>,
}

/// One ray of a [`Transfer`] in 4 bytes (a ground map holds 64² × [`GROUND_RAYS`] of them): its
/// world direction's azimuth, clockwise from North, in 1/65536 turns, its height z in 1/32768,
/// and in the top bit whether it passes the occluders. Both are cut (not rounded) to their
/// steps and read back at the step's middle, so a ray stays in its row of the sky
/// ([`SKY_ROWS`]: edges at multiples of 1/8 in z) and, for a map without heading, its column
/// (1/32 turn).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyRay {
    azimuth: u16,
    z_open: u16,
}

impl SkyRay {
    /// The ray along unit world direction `d`.
    pub fn new(d: Vec3, open: bool) -> SkyRay {
        let turns = d.x.atan2(d.y).rem_euclid(TAU) / TAU;
        let azimuth = ((turns * 65536.0) as u32).min(65535) as u16;
        let z = ((d.z.clamp(0.0, 1.0) * 32768.0) as u16).min(32767);
        SkyRay { azimuth, z_open: z | (u16::from(open) << 15) }
    }

    /// Azimuth (rad, clockwise from North, 0..2π) and z of the direction.
    pub fn direction(self) -> (f32, f32) {
        ((f32::from(self.azimuth) + 0.5) / 65536.0 * TAU, (f32::from(self.z_open & 0x7fff) + 0.5) / 32768.0)
    }

    /// Whether the ray passes the occluders.
    pub fn open(self) -> bool {
        self.z_open & 0x8000 != 0
    }
}

/// Sums over the rays that hit the occluders, each over the number of rays, of what lights the
/// surface hit (world normal n, light shares a = [`model_sky_ground`]'s four, albedo ρ over the
/// model's mean): recombined with a [`BounceLight`] by [`Transfer::reflected`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bounce {
    /// Σ ρ (a_sky + a_bounce) basis_k(n): the sky's share of its light.
    pub sky: [f32; TERMS],
    /// Per hit (n, ρ / rays): the sun's, max(n·s, 0) exactly for any sun s (the nine harmonics
    /// of a clamped cosine are 0.06–0.09 of its peak where it is 0, which a low sun, bright
    /// against the ground's light, turns into a bounce from the model's shaded side); the
    /// model's own shadow on that surface is not known here: unshadowed.
    pub sun: Vec<[f32; 4]>,
    /// Σ ρ (1 − n_z)/2 (a_ground lit by the sky + a_bounce) and Σ ρ (1 − n_z)/2 (a_ground +
    /// a_bounce): the ground's, lit by the sky and by the sun.
    pub ground: [f32; 2],
}

/// The light on the model's surface that [`Bounce`] recombines, per channel, as the model's mean
/// albedo × irradiance / π in units of the ground's own irradiance / π (so the result is a gain
/// on the ground's light): a surface facing n reflects Σ_k sky_k a_sky Y_k(n) +
/// sun max(n·sun_dir, 0) + (1 − n_z)/2 (ground_0 a_ground lit by the sky + ground_1 a_ground).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BounceLight {
    pub sky: [[f32; 3]; TERMS],
    pub sun: [f32; 3],
    /// Unit direction to the sun, world.
    pub sun_dir: [f32; 3],
    pub ground: [[f32; 3]; 2],
}

impl BounceLight {
    /// A model that reflects nothing.
    pub const NONE: BounceLight = BounceLight { sky: [[0.0; 3]; TERMS], sun: [0.0; 3], sun_dir: [0.0, 0.0, 1.0], ground: [[0.0; 3]; 2] };
}

/// The largest magnitude, over a ground map's texels, of each sum [`Transfer::reflected`]
/// recombines ([`Bounce`]): what bounds how far two [`BounceLight`]s' maps can differ
/// ([`BounceReach::bound`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BounceReach {
    /// max |Σ ρ (a_sky + a_bounce) basis_k(n)| per term k.
    pub sky: [f32; TERMS],
    /// max Σ |ρ / rays| over the hits (the sun's weights).
    pub sun: f32,
    /// max |Bounce::ground[j]|.
    pub ground: [f32; 2],
}

impl BounceReach {
    /// The reach of `texels`' bounces.
    pub fn of(texels: &[Transfer]) -> BounceReach {
        let mut r = BounceReach::default();
        for b in texels.iter().map(|t| &t.bounce) {
            for (m, v) in r.sky.iter_mut().zip(b.sky) {
                *m = m.max(v.abs());
            }
            r.sun = r.sun.max(b.sun.iter().map(|h| h[3].abs()).sum());
            for (m, v) in r.ground.iter_mut().zip(b.ground) {
                *m = m.max(v.abs());
            }
        }
        r
    }

    /// A bound on |reflected(a) − reflected(b)| ([`Transfer::reflected`]) over every texel and
    /// channel: reflected is a clamp at 0 (1-Lipschitz) of sums linear in the light's sky and
    /// ground terms, and of the sun's Σ w max(n·s, 0) L over unit normals n, which moves by at
    /// most Σ|w| (|ΔL| + |L| |Δs|) (max(n·s, 0) moves by at most |n·Δs| ≤ |Δs|).
    pub fn bound(&self, a: &BounceLight, b: &BounceLight) -> f32 {
        let ds = (Vec3::from(a.sun_dir) - Vec3::from(b.sun_dir)).length();
        (0..3)
            .map(|c| {
                let sky: f32 = self.sky.iter().zip(a.sky.iter().zip(&b.sky)).map(|(m, (x, y))| m * (x[c] - y[c]).abs()).sum();
                let ground: f32 = self.ground.iter().zip(a.ground.iter().zip(&b.ground)).map(|(m, (x, y))| m * (x[c] - y[c]).abs()).sum();
                let sun = self.sun * ((a.sun[c] - b.sun[c]).abs() + a.sun[c].abs().min(b.sun[c].abs()) * ds);
                sky + ground + sun
            })
            .fold(0.0, f32::max)
    }
}

impl Transfer {
    /// The visibility under a sky of radiance `radiance(azimuth, z)` ≥ 0 (a world direction's,
    /// [`SkyRay::direction`]): Σ V(d) L(d) s(d) / Σ L(d) s(d) over the rays, s being each ray's
    /// share of the cosine-weighted hemisphere ([`sky_rays`]); the plain visibility when that
    /// sky gives no light along them.
    pub fn weighted_visibility(&self, radiance: &dyn Fn(f32, f32) -> f32) -> f32 {
        let (mut open, mut total) = (0f32, 0f32);
        for r in &self.rays {
            let (azimuth, z) = r.direction();
            let w = radiance(azimuth, z).max(0.0) * row_weight(z);
            total += w;
            if r.open() {
                open += w;
            }
        }
        if total > 0.0 { (open / total).clamp(0.0, 1.0) } else { self.plain }
    }

    /// [`Transfer::weighted_visibility`] per colour channel, each ray weighted by that channel
    /// of `radiance(azimuth, z)`: the share of each channel's light the point still sees (the
    /// plain share for a channel without light).
    pub fn weighted_visibility_rgb(&self, radiance: &dyn Fn(f32, f32) -> [f32; 3]) -> [f32; 3] {
        let (mut open, mut total) = ([0f32; 3], [0f32; 3]);
        for r in &self.rays {
            let (azimuth, z) = r.direction();
            let l = radiance(azimuth, z);
            let w = row_weight(z);
            for c in 0..3 {
                let wc = l[c].max(0.0) * w;
                total[c] += wc;
                if r.open() {
                    open[c] += wc;
                }
            }
        }
        std::array::from_fn(|c| if total[c] > 0.0 { (open[c] / total[c]).clamp(0.0, 1.0) } else { self.plain })
    }

    /// The occluders' light at the point per channel, a gain on the point's own light, under
    /// `light` ([`BounceLight`]); clamped at 0 (the nine harmonics of a clamped cosine ring a
    /// little below it).
    pub fn reflected(&self, light: &BounceLight) -> [f32; 3] {
        let b = &self.bounce;
        let s = Vec3::from(light.sun_dir);
        let sun: f32 =
            if light.sun == [0.0; 3] { 0.0 } else { b.sun.iter().map(|h| h[3] * Vec3::new(h[0], h[1], h[2]).dot(s).max(0.0)).sum() };
        std::array::from_fn(|c| {
            let dot = |sums: &[f32], l: &[[f32; 3]]| sums.iter().zip(l).map(|(s, l)| s * l[c]).sum::<f32>();
            (dot(&b.sky, &light.sky) + sun * light.sun[c] + dot(&b.ground, &light.ground)).max(0.0)
        })
    }
}

/// Per-vertex visibility of `mesh` against `occluders` (1 = unoccluded), `rays` rays each; the
/// work is split over the machine's cores. Vertices with a zero normal get 1.
pub fn vertex_ao(mesh: &Mesh, occluders: &Occluders, rays: u32) -> Vec<f32> {
    per_vertex(mesh, 1.0, |start, normal, seed| occluders.visibility(start, normal, rays, seed))
}

/// `f(start, normal, seed)` for each vertex of `mesh` over the machine's cores (`empty` for a
/// vertex without a normal entry gets a zero normal): `start` is the vertex moved a little
/// inside its own triangles, `seed` its index.
fn per_vertex<T: Send + Clone>(mesh: &Mesh, empty: T, f: impl Fn(Vec3, Vec3, u32) -> T + Sync) -> Vec<T> {
    let n = mesh.positions.len();
    // Each ray starts a little inside the vertex's own triangles (towards their mean centroid):
    // a vertex on a concave hard edge (the corner of a room) would otherwise sit exactly in the
    // plane of the neighbouring wall and see through it.
    let mut towards = vec![(Vec3::ZERO, 0u32); n];
    for t in mesh.indices.chunks_exact(3) {
        let Some(tri) =
            [t[0], t[1], t[2]].iter().map(|&i| mesh.positions.get(i as usize).map(|p| Vec3::from_array(*p))).collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        let c = (tri[0] + tri[1] + tri[2]) / 3.0;
        for &i in t {
            let e = &mut towards[i as usize];
            *e = (e.0 + c, e.1 + 1);
        }
    }
    let indices: Vec<usize> = (0..n).collect();
    parallel_map(&indices, empty, |i, _| {
        let normal = mesh.normals.get(i).map_or(Vec3::ZERO, |v| Vec3::from_array(*v));
        let p = Vec3::from_array(mesh.positions[i]);
        let (sum, count) = towards[i];
        let start = if count > 0 { p + (sum / count as f32 - p) * 1e-3 } else { p };
        f(start, normal, i as u32)
    })
}

/// `f(index, item)` for each of `items` over the machine's cores, in order.
fn parallel_map<I: Sync, T: Send + Clone>(items: &[I], empty: T, f: impl Fn(usize, &I) -> T + Sync) -> Vec<T> {
    let n = items.len();
    let f = &f;
    let mut out = vec![empty; n];
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get()).min(n.max(1));
    let chunk = n.div_ceil(threads.max(1)).max(1);
    std::thread::scope(|s| {
        for (c, part) in out.chunks_mut(chunk).enumerate() {
            s.spawn(move || {
                for (k, v) in part.iter_mut().enumerate() {
                    let i = c * chunk + k;
                    *v = f(i, &items[i]);
                }
            });
        }
    });
    out
}

/// Per vertex of every mesh of `model`, the light it gets from the sky and from the ground it
/// stands on, each as a share of what an open vertex would get (sh9-ggx, shaders/sh9_ggx.wgsl,
/// the vertex attribute `ao`): `[sky, ground lit by the sky, ground, bounce]`. Sloan, Kautz &
/// Snyder 2002's transfer split at the horizon, computed once per model: a point's
/// cosine-distributed rays that go up and pass the model see the sky; those that go down and
/// pass the model meet the ground plane under it, whose sky the model hides in part
/// ([`standing_ground`]): the ground's light the model gets is darkened by the model's own
/// contact shadow (one bounce).
/// - sky = open up-rays / up-rays;
/// - ground lit by the sky = Σ (the ground's sky visibility at the hit) over the open down-rays
///   / down-rays;
/// - ground = open down-rays / down-rays (the sun's part of the ground's light, whose shadow
///   depends on the sun, is taken as unshadowed: the shader mixes the two by the sun's share of
///   the ground's light);
/// - bounce = the light the model's own surfaces reflect onto the point, as a share of an open
///   point's whole light: the multi-bounce fit for the mesh's albedo over all the rays' open
///   share A, [`multi_bounce`](A) − A (the fit assumes the occluders lit as the point is);
/// - and [`VertexLight::bent`], the mean direction of the open rays (`light_at`), along which
///   the shader looks the sky up.
///
/// A half without rays (a normal straight up or down) takes the open share of all rays.
///
/// Where a mesh's triangles are small (every edge under [`SAMPLE_SPACING`] of the model's
/// diagonal) the values are sampled at the vertices and each is averaged once over the vertex's
/// neighbours ([`smooth_over_neighbours`]: the vertices it shares a triangle with, which
/// multiplies the rays behind each value about sevenfold at the cost of a one-edge blur). A
/// large triangle (the truck's 2.4 m body side between two columns of vertices) is sampled
/// inside too ([`triangle_samples`]: a grid of that spacing), and a vertex of one takes the
/// lumped L² projection of the sampled values onto the mesh's linear interpolation: each
/// value weighted by the vertex's barycentric coordinate (its hat function) and the area the
/// sample stands for, ∫ φ_i f dA / ∫ φ_i dA (a vertex whose triangles are all small gets its own
/// value, as before): what the shader's interpolation across the triangle then averages to is the
/// light the triangle's surface receives, not the light at its corners.
///
/// Every sample casts [`rays_per_vertex`] rays (of the vertices and inner samples together)
/// against `occluders` (the model's triangles, which the renderer keeps for the ground's
/// [`ground_transfer`]). The model stands upright on its bounding box's base (model space y up,
/// render::view::model_matrix without a tilt).
pub fn model_sky_ground(model: &Model, occluders: &Occluders) -> Vec<Vec<VertexLight>> {
    model_light(model, occluders).0
}

/// [`model_sky_ground`] and, from the same rays (one cast), what each sample's rays passed and
/// met ([`ModelRays`]): the sky and the bounce it sees under any sky.
pub fn model_light(model: &Model, occluders: &Occluders) -> (Vec<Vec<VertexLight>>, ModelRays) {
    let Some(bounds) = model.bounds() else {
        let open = model.meshes.iter().map(|m| vec![VertexLight::from(OPEN); m.positions.len()]).collect();
        return (open, ModelRays::default());
    };
    let ground = standing_ground(occluders, bounds, GROUND_TEXELS, GROUND_RAYS);
    let spacing = SAMPLE_SPACING * (bounds.1 - bounds.0).length();
    let inner: Vec<Vec<SurfaceSample>> = model.meshes.iter().map(|m| triangle_samples(m, spacing)).collect();
    let samples = model.meshes.iter().map(|m| m.positions.len()).sum::<usize>() + inner.iter().map(Vec::len).sum::<usize>();
    let rays = rays_per_vertex(samples);
    let none = (OPEN, SampleRays::default());
    let mut kept = Vec::with_capacity(model.meshes.len());
    let lights = model
        .meshes
        .iter()
        .zip(inner)
        .map(|(mesh, inner)| {
            let albedo = model.materials.get(mesh.material).map_or(0.8, |m| crate::colour::luminance_bt709(m.diffuse));
            let light =
                |start: Vec3, normal: Vec3, seed: u32| light_at(occluders, &ground, bounds.0.y, (start, normal), rays, seed, albedo);
            let (values, at_vertices): (Vec<Values>, Vec<SampleRays>) = per_vertex(mesh, none.clone(), light).into_iter().unzip();
            let mut out = smooth_over_neighbours(mesh, &values);
            let mut inner_rays = Vec::new();
            if !inner.is_empty() {
                let first = mesh.positions.len() as u32;
                let sampled: Vec<Values>;
                (sampled, inner_rays) =
                    parallel_map(&inner, none.clone(), |k, s| light(s.point, s.normal, first + k as u32)).into_iter().unzip();
                let projected = lumped_projection(mesh, spacing, &values, &inner, &sampled);
                for (o, p) in out.iter_mut().zip(projected) {
                    if let Some(p) = p {
                        *o = p;
                    }
                }
            }
            kept.push(MeshRays { at_vertices, inner, inner_rays });
            out.into_iter().map(VertexLight::from).collect()
        })
        .collect();
    (lights, ModelRays { meshes: kept, rays, spacing, triangles: hit_triangles(model, occluders) })
}

/// What [`model_sky_ground`] gives one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexLight {
    /// `[sky, ground lit by the sky, ground, bounce]` (render::pipelines::Vertex::ao).
    pub ao: [f32; 4],
    /// The bent normal (model space, unit; zero when unknown: use the vertex normal): the mean
    /// direction of the rays that pass the model, where the sky's light is looked up
    /// (render::pipelines::Vertex::bent).
    pub bent: [f32; 3],
}

/// The values [`model_sky_ground`] samples and averages: the four shares, then the bent normal.
const VALUES: usize = 7;
type Values = [f32; VALUES];

impl From<Values> for VertexLight {
    fn from(v: Values) -> VertexLight {
        let bent = Vec3::new(v[4], v[5], v[6]).normalize_or_zero();
        VertexLight { ao: [v[0], v[1], v[2], v[3]], bent: bent.to_array() }
    }
}

/// The values of an open point: all of the sky and of the ground, no bounce, no bent normal.
const OPEN: Values = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0];

/// The light of one point of the model (model space, y up; `start` on the surface, `normal` its
/// normal) from `rays` cosine-distributed rays shifted by `seed` against `occluders`, over the
/// ground plane at height `floor` whose own sky visibility is `ground`, for a mesh of `albedo`:
/// `[sky, ground lit by the sky, ground, bounce, bent normal x, y, z]` ([`model_sky_ground`]).
/// The bent normal is the mean direction of the open rays, normalised (the normal when every ray
/// is blocked): a surface in a crevice sees the sky through the crevice's mouth, and the sky's
/// light is looked up there (Landis 2002, "Production-ready global illumination": ambient
/// occlusion with bent normals).
fn light_at(
    occluders: &Occluders,
    ground: &GroundSky,
    floor: f32,
    (start, normal): (Vec3, Vec3),
    rays: u32,
    seed: u32,
    albedo: f32,
) -> (Values, SampleRays) {
    let Some(n) = normal.try_normalize() else { return (OPEN, SampleRays::default()) };
    // (rays, open rays) going up; (rays, open rays, Σ ground visibility) going down.
    let (mut up, mut up_open, mut down, mut down_open, mut lit) = (0u32, 0u32, 0u32, 0u32, 0f32);
    let mut bent = Vec3::ZERO;
    let mut kept = SampleRays { normal: n, open_up: 0, hits: Vec::new() };
    let origin = start + n * occluders.epsilon;
    for (i, d) in ray_directions(n, rays, seed).enumerate() {
        let nearest = occluders.nearest_triangle(origin, d);
        let hit = nearest.is_some();
        if let Some((_, t)) = nearest {
            kept.hits.push(t as u32);
        }
        if !hit {
            bent += d;
        }
        if d.y > 0.0 {
            up += 1;
            up_open += u32::from(!hit);
            if !hit && i < 64 {
                kept.open_up |= 1 << i;
            }
        } else {
            down += 1;
            if !hit {
                down_open += 1;
                let t = if d.y < 0.0 { ((floor - start.y) / d.y).max(0.0) } else { 0.0 };
                let g = start + d * t;
                lit += ground.at(Vec2::new(g.x, -g.z));
            }
        }
    }
    let open = (up_open + down_open) as f32 / rays.max(1) as f32;
    let share = |k: u32, n: u32| if n > 0 { k as f32 / n as f32 } else { open };
    let lit = if down > 0 { lit / down as f32 } else { open };
    let b = bent.try_normalize().unwrap_or(n);
    ([share(up_open, up), lit, share(down_open, down), multi_bounce(open, albedo) - open, b.x, b.y, b.z], kept)
}

/// What one sample's rays ([`ray_directions`] about `normal`, [`model_light`]'s count and seed)
/// passed and met.
#[derive(Clone, Debug, Default)]
pub struct SampleRays {
    /// The unit normal the rays were cast about (zero: none were).
    normal: Vec3,
    /// Bit i: ray i goes up (model space y) and passes the model.
    open_up: u64,
    /// Per ray that meets the model, the nearest triangle's index in the occluders' order.
    hits: Vec<u32>,
}

/// One mesh's [`SampleRays`]: at its vertices, and at its large triangles' inner samples.
#[derive(Clone, Debug, Default)]
struct MeshRays {
    at_vertices: Vec<SampleRays>,
    inner: Vec<SurfaceSample>,
    inner_rays: Vec<SampleRays>,
}

/// Each sample's rays of [`model_light`] (one cast at load), kept so that any sky gives each
/// vertex the light it sees through its own rays and the light of that sky the model's own
/// surfaces reflect onto it ([`ModelRays::sky`]).
#[derive(Clone, Debug, Default)]
pub struct ModelRays {
    meshes: Vec<MeshRays>,
    /// Rays cast per sample (open or not, up or down).
    rays: u32,
    spacing: f32,
    /// Per triangle of the occluders (their order): its corners as indices into every mesh's
    /// vertices in turn and its albedo's luminance (the mesh material's diffuse colour times its
    /// texture at the triangle's centre); None: not a model triangle.
    triangles: Vec<Option<HitTriangle>>,
}

#[derive(Clone, Copy, Debug)]
struct HitTriangle {
    corners: [u32; 3],
    albedo: f32,
}

/// Bounces of the model's own light that [`ModelRays`] follows: the second lets each surface the
/// rays meet carry the first's.
pub const BOUNCES: usize = 2;

/// [`ModelRays::triangles`] of `model`'s triangles in `occluders` ([`Occluders::of_model`]).
fn hit_triangles(model: &Model, occluders: &Occluders) -> Vec<Option<HitTriangle>> {
    let key = |t: [Vec3; 3]| t.map(|p| p.to_array().map(f32::to_bits));
    let mut by_corners = std::collections::HashMap::new();
    let mut first = 0u32;
    for mesh in &model.meshes {
        if let Some(material) = model.materials.get(mesh.material) {
            for t in mesh.indices.chunks_exact(3) {
                let Some((corners, p, _)) = triangle_of(mesh, t) else { continue };
                let uv = |i: u32| glam::Vec2::from(mesh.uvs.get(i as usize).copied().unwrap_or([0.0; 2]));
                let centre = (uv(corners[0]) + uv(corners[1]) + uv(corners[2])) / 3.0;
                let texel = material.texture.as_ref().map_or([1.0; 3], |tex| texel_at(tex, centre));
                let albedo = crate::colour::luminance_bt709(std::array::from_fn(|k| material.diffuse[k] * texel[k]));
                by_corners.insert(key(p), HitTriangle { corners: corners.map(|c| c + first), albedo });
            }
        }
        first += mesh.positions.len() as u32;
    }
    occluders.triangles.iter().map(|t| by_corners.get(&key(*t)).copied()).collect()
}

impl ModelRays {
    /// Per mesh of `model` (the one the rays were cast for), per vertex: `value` of each sample
    /// averaged over the vertex's neighbours and projected from a large triangle's inner samples
    /// as [`model_sky_ground`]'s values are, each of its `N` channels alone (one walk of the
    /// samples and one projection for all of them). `value(mesh, sample, rays)`: a mesh's
    /// samples are its vertices, then its inner samples (the index is the rays' seed).
    fn per_vertex<const N: usize>(
        &self,
        model: &Model,
        value: &(dyn Fn(usize, usize, &SampleRays) -> [f32; N] + Sync),
    ) -> Vec<Vec<[f32; N]>> {
        const { assert!(N <= VALUES, "the projection carries at most VALUES channels") };
        let pack = |v: &[f32; N]| -> Values { std::array::from_fn(|k| v.get(k).copied().unwrap_or(0.0)) };
        model
            .meshes
            .iter()
            .zip(&self.meshes)
            .enumerate()
            .map(|(j, (mesh, rays))| {
                let values = parallel_map(&rays.at_vertices, [0.0; N], |i, r| value(j, i, r));
                let mut out = smooth_over_neighbours(mesh, &values);
                if !rays.inner.is_empty() {
                    let first = rays.at_vertices.len();
                    let inner = parallel_map(&rays.inner_rays, pack(&[0.0; N]), |k, r| pack(&value(j, first + k, r)));
                    let at: Vec<Values> = values.iter().map(pack).collect();
                    for (o, p) in out.iter_mut().zip(lumped_projection(mesh, self.spacing, &at, &rays.inner, &inner)) {
                        if let Some(p) = p {
                            *o = std::array::from_fn(|c| p[c]);
                        }
                    }
                }
                out
            })
            .collect()
    }

    /// The light the surfaces a sample's rays meet reflect onto it, per channel, (1/N) Σ over
    /// those rays of the surface's albedo times `light(triangle)` (its irradiance over π), N the
    /// rays cast (cosine-distributed: the mean of the radiance they meet is the irradiance over
    /// π).
    fn reflected<const C: usize>(&self, r: &SampleRays, light: &dyn Fn(&HitTriangle) -> [f32; C]) -> [f32; C] {
        let mut sum = [0.0f32; C];
        for t in r.hits.iter().filter_map(|&h| self.triangles.get(h as usize)?.as_ref()) {
            sum.iter_mut().zip(light(t)).for_each(|(s, l)| *s += t.albedo * l);
        }
        sum.map(|s| s / self.rays.max(1) as f32)
    }

    /// The mean of `values` (every mesh's vertices in turn) over a triangle's corners, per
    /// channel.
    fn corner_mean<const C: usize>(values: &[[f32; C]], t: &HitTriangle) -> [f32; C] {
        std::array::from_fn(|c| t.corners.iter().map(|&k| values.get(k as usize).map_or(0.0, |v| v[c])).sum::<f32>() / 3.0)
    }

    /// Per mesh, per vertex: the sky's light as irradiance over π, relative to the sky's mean
    /// radiance, for a sky of radiance `radiance(d)` (d: unit, model space, y up) — the light
    /// through the vertex's own open up-going rays, (1/N) Σ L(d) over them (N the rays cast,
    /// cosine-distributed: a lone plane tilted θ under a uniform sky of 1 gets (1 + cos θ) / 2),
    /// plus the sky's light the model's own surfaces reflect onto it ([`BOUNCES`] bounces): each
    /// surface its rays meet, of albedo ρ, sends ρ times its own sky light (the mean of its
    /// corners' values).
    pub fn sky(&self, model: &Model, radiance: &(dyn Fn(Vec3) -> f32 + Sync)) -> Vec<Vec<f32>> {
        self.sky_with(model, radiance, BOUNCES)
    }

    /// [`ModelRays::sky`] with `bounces` bounces (0: the sky the vertices see through their own
    /// rays alone).
    pub fn sky_with(&self, model: &Model, radiance: &(dyn Fn(Vec3) -> f32 + Sync), bounces: usize) -> Vec<Vec<f32>> {
        let per_vertex = self.sky_channels(model, &|d| [radiance(d)], bounces);
        per_vertex.into_iter().map(|m| m.into_iter().map(|[v]| v).collect()).collect()
    }

    /// [`ModelRays::sky`] for `N` skies at once, `radiance(d)` giving each one's radiance (the
    /// sky's luminance and its colour channels): the rays are walked once, and each sky's
    /// bounces (a grey surface reflects each channel alike) follow its own light.
    pub fn sky_channels<const N: usize>(
        &self,
        model: &Model,
        radiance: &(dyn Fn(Vec3) -> [f32; N] + Sync),
        bounces: usize,
    ) -> Vec<Vec<[f32; N]>> {
        let n = self.rays.max(1);
        let seen_at = |r: &SampleRays, seed: u32| -> [f32; N] {
            let mut sum = [0f32; N];
            if r.open_up == 0 {
                return sum;
            }
            for (_, d) in ray_directions(r.normal, n, seed).enumerate().filter(|(i, _)| *i < 64 && r.open_up & (1 << i) != 0) {
                sum.iter_mut().zip(radiance(d)).for_each(|(s, l)| *s += l.max(0.0));
            }
            sum.map(|s| s / n as f32)
        };
        // Each sample's own sky, kept for the bounces (per mesh: vertices, then inner samples).
        let seen: Vec<Vec<[f32; N]>> = self
            .meshes
            .iter()
            .map(|m| {
                let samples: Vec<&SampleRays> = m.at_vertices.iter().chain(&m.inner_rays).collect();
                parallel_map(&samples, [0.0; N], |i, r| seen_at(r, i as u32))
            })
            .collect();
        let mut out = self.per_vertex(model, &|j, i, _| seen[j][i]);
        for _ in 0..bounces {
            let all = out.concat();
            out = self.per_vertex(model, &|j, i, r| {
                let bounced = self.reflected(r, &|t| Self::corner_mean(&all, t));
                std::array::from_fn(|c| seen[j][i][c] + bounced[c])
            });
        }
        out
    }

    /// Bytes held (the rays' masks and hits, the samples and the triangles' table).
    pub fn bytes(&self) -> usize {
        let rays = |r: &[SampleRays]| r.iter().map(|s| std::mem::size_of::<SampleRays>() + 4 * s.hits.capacity()).sum::<usize>();
        self.meshes
            .iter()
            .map(|m| rays(&m.at_vertices) + rays(&m.inner_rays) + m.inner.len() * std::mem::size_of::<SurfaceSample>())
            .sum::<usize>()
            + self.triangles.len() * std::mem::size_of::<Option<HitTriangle>>()
    }
}

/// Largest distance between the points where [`model_sky_ground`] samples the light, as a share
/// of the model's bounding-box diagonal (the truck's: 0.19 m). Measured on the quarry_truck
/// reference scene (ROI FLIP): 1/8 and 1/16 0.131, 1/32 and 1/64 0.128 (vertices only: 0.137).
pub const SAMPLE_SPACING: f32 = 1.0 / 32.0;

/// A point inside a large triangle where [`model_sky_ground`] samples the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    pub point: Vec3,
    /// The interpolated vertex normal (not normalised).
    pub normal: Vec3,
    /// The triangle's vertices and what this sample adds to each one's projection: the sample's
    /// quadrature weight (area) times the vertex's barycentric coordinate there.
    pub corners: [u32; 3],
    pub weights: [f32; 3],
}

/// Subdivisions of each side of a triangle whose longest edge is `longest` for samples at most
/// `spacing` apart (1: only its corners), at most 64.
fn subdivisions(longest: f32, spacing: f32) -> u32 {
    if spacing > 0.0 && longest.is_finite() { (longest / spacing).ceil().clamp(1.0, 64.0) as u32 } else { 1 }
}

/// The corners and area of triangle `t` of `mesh` (None when an index is out of range).
fn triangle_of(mesh: &Mesh, t: &[u32]) -> Option<([u32; 3], [Vec3; 3], f32)> {
    let corners = [t[0], t[1], t[2]];
    let p = corners.map(|i| mesh.positions.get(i as usize).map(|p| Vec3::from_array(*p)));
    let p = [p[0]?, p[1]?, p[2]?];
    Some((corners, p, 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()))
}

/// The inner samples of `mesh`'s large triangles: a triangle whose longest edge needs m > 1
/// subdivisions at `spacing` ([`subdivisions`]) is cut into m² similar triangles, whose corners
/// other than the triangle's own are the samples (barycentric (i, j, m − i − j) / m). Each
/// sample's quadrature weight is the trapezoid rule of the m² small triangles (a third of each
/// small triangle's area to each of its corners: 2A/m² inside, A/m² on an edge, A/(3m²) at a
/// corner, the corners' share going to the vertices' own values in [`lumped_projection`]).
pub fn triangle_samples(mesh: &Mesh, spacing: f32) -> Vec<SurfaceSample> {
    let mut out = Vec::new();
    for t in mesh.indices.chunks_exact(3) {
        let Some((corners, p, area)) = triangle_of(mesh, t) else { continue };
        let longest = [(0, 1), (1, 2), (2, 0)].iter().map(|&(a, b)| p[a].distance(p[b])).fold(0.0, f32::max);
        let m = subdivisions(longest, spacing);
        if m == 1 {
            continue;
        }
        let normal = |i: u32| mesh.normals.get(i as usize).map_or(Vec3::ZERO, |n| Vec3::from_array(*n));
        let n = corners.map(normal);
        let small = area / (m * m) as f32;
        for i in 0..=m {
            for j in 0..=m - i {
                let k = m - i - j;
                let on_edges = [i, j, k].iter().filter(|&&c| c == 0).count();
                if on_edges == 2 {
                    continue; // a corner: the vertex's own value
                }
                let b = [i, j, k].map(|c| c as f32 / m as f32);
                let weight = if on_edges == 1 { small } else { 2.0 * small };
                out.push(SurfaceSample {
                    point: p[0] * b[0] + p[1] * b[1] + p[2] * b[2],
                    normal: n[0] * b[0] + n[1] * b[1] + n[2] * b[2],
                    corners,
                    weights: b.map(|b| b * weight),
                });
            }
        }
    }
    out
}

/// Per vertex of `mesh`, the lumped L² projection ∫ φ_i f dA / ∫ φ_i dA of the values sampled at
/// the vertices (`at_vertices`) and at the large triangles' inner samples (`samples` with their
/// `values`, [`triangle_samples`] at `spacing`); None for a vertex whose triangles are all
/// small (its own value is the projection then).
fn lumped_projection(
    mesh: &Mesh,
    spacing: f32,
    at_vertices: &[Values],
    samples: &[SurfaceSample],
    values: &[Values],
) -> Vec<Option<Values>> {
    let mut sum = vec![([0.0f32; VALUES], 0.0f32, false); at_vertices.len()];
    let add = |sum: &mut [(Values, f32, bool)], i: u32, w: f32, v: &Values| {
        let e = &mut sum[i as usize];
        e.0.iter_mut().zip(v).for_each(|(a, v)| *a += w * v);
        e.1 += w;
    };
    for t in mesh.indices.chunks_exact(3) {
        let Some((corners, p, area)) = triangle_of(mesh, t) else { continue };
        let longest = [(0, 1), (1, 2), (2, 0)].iter().map(|&(a, b)| p[a].distance(p[b])).fold(0.0, f32::max);
        let m = subdivisions(longest, spacing);
        for c in corners {
            add(&mut sum, c, area / (3 * m * m) as f32, &at_vertices[c as usize]);
            sum[c as usize].2 |= m > 1;
        }
    }
    for (s, v) in samples.iter().zip(values) {
        for (c, w) in s.corners.iter().zip(s.weights) {
            add(&mut sum, *c, w, v);
        }
    }
    sum.into_iter().map(|(s, w, large)| (large && w > 0.0).then(|| s.map(|s| s / w))).collect()
}

/// The sky visibility of the ground plane under a model standing upright on its bounding box's
/// base (model space, y up), [`ground_square`] of that stance, `size`² texels of `rays` rays: a
/// [`GroundSky`] over model (x, −z), the world's (East, North) of an unturned placement.
pub fn standing_ground(occluders: &Occluders, bounds: (Vec3, Vec3), size: u32, rays: u32) -> GroundSky {
    // Model (x, y, z) → (x, −z, y): y up becomes z up (render::view::model_to_world_axes).
    let stance = Mat4::from_cols(glam::Vec4::X, glam::Vec4::Z, -glam::Vec4::Y, glam::Vec4::W);
    let (min, max, z, visibility) = over_ground(bounds, stance, size, |point, up, seed| occluders.visibility(point, up, rays, seed));
    GroundSky { min, max, z, size: size.max(1), visibility, visibility_rgb: Vec::new(), bounce: Vec::new() }
}

/// Each vertex's value averaged with those of the vertices it shares a triangle with (each
/// neighbour counted once per shared triangle edge, itself once per triangle), each of its `N`
/// channels alone, in one walk of the triangles.
pub fn smooth_over_neighbours<const N: usize>(mesh: &Mesh, values: &[[f32; N]]) -> Vec<[f32; N]> {
    let mut sum = vec![([0.0f32; N], 0u32); values.len()];
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        if a.max(b).max(c) >= values.len() {
            continue;
        }
        for (i, j, k) in [(a, b, c), (b, c, a), (c, a, b)] {
            let (s, n) = &mut sum[i];
            for ch in 0..N {
                s[ch] = s[ch] + values[i][ch] + 0.5 * (values[j][ch] + values[k][ch]);
            }
            *n += 2;
        }
    }
    values.iter().zip(&sum).map(|(&v, &(s, n))| if n == 0 { v } else { s.map(|s| s / n as f32) }).collect()
}

/// The cosine-weighted fraction of the upper hemisphere (+`up`) that `point` sees past the
/// occluders: the sky a ground point under the model still receives.
pub fn sky_visibility(occluders: &Occluders, point: Vec3, up: Vec3, rays: u32, seed: u32) -> f32 {
    occluders.visibility(point, up, rays, seed)
}

/// Visibility including the light the occluders themselves reflect: Jimenez et al. 2016,
/// "Practical real-time strategies for accurate indirect occlusion" (GTAO), Eq. 10, a cubic fit
/// of multi-bounce ambient occlusion against path-traced ground truth for a surface of diffuse
/// `albedo` surrounded by the same albedo. Never below `ao`; 1 stays 1.
pub fn multi_bounce(ao: f32, albedo: f32) -> f32 {
    let a = 2.0404 * albedo - 0.3324;
    let b = -4.7951 * albedo + 0.6417;
    let c = 2.7552 * albedo + 0.6903;
    ao.max(((ao * a + b) * ao + c) * ao)
}

/// The model's mean diffuse albedo, linear RGB: each mesh's material colour times its texture's
/// mean (sRGB-decoded; 1 without a texture), weighted by the mesh's surface area. What the model
/// reflects onto the ground ([`Transfer::reflected`]); a model without area gives its first
/// material's colour (the default material's 0.8 grey without one).
pub fn mean_albedo(model: &Model) -> [f32; 3] {
    let mut sum = [0f64; 3];
    let mut area = 0f64;
    for mesh in &model.meshes {
        let Some(material) = model.materials.get(mesh.material) else { continue };
        let a: f64 = mesh_triangles(mesh).map(|[p, q, r]| f64::from((q - p).cross(r - p).length() * 0.5)).sum();
        let texture = material.texture.as_ref().map_or([1.0; 3], |t| {
            let mut m = [0f64; 3];
            let texels = t.pixels.chunks_exact(4);
            let n = texels.len().max(1) as f64;
            for px in texels {
                m.iter_mut().zip(px).for_each(|(m, &v)| *m += f64::from(crate::colour::srgb_to_linear(f32::from(v) / 255.0)));
            }
            m.map(|v| v / n)
        });
        for c in 0..3 {
            sum[c] += a * f64::from(material.diffuse[c]) * texture[c];
        }
        area += a;
    }
    if area > 0.0 {
        sum.map(|v| (v / area) as f32)
    } else {
        model.materials.first().map_or(crate::scene::Material::default().diffuse, |m| m.diffuse)
    }
}

/// The linear colour of `texture` at `uv` (0,0 = top-left), nearest texel, wrapping.
fn texel_at(texture: &crate::scene::Rgba8Image, uv: glam::Vec2) -> [f32; 3] {
    let (w, h) = (texture.width.max(1), texture.height.max(1));
    let x = ((uv.x.rem_euclid(1.0) * w as f32) as u32).min(w - 1);
    let y = ((uv.y.rem_euclid(1.0) * h as f32) as u32).min(h - 1);
    let i = 4 * (y * w + x) as usize;
    std::array::from_fn(|k| texture.pixels.get(i + k).map_or(1.0, |&v| crate::colour::srgb_to_linear(f32::from(v) / 255.0)))
}

/// Texels per side of the ground's sky-visibility map.
pub const GROUND_TEXELS: u32 = 64;
/// Rays per texel of the ground map ([`sky_rays`]: one in each bin of the sky's radiance) and of
/// the ground [`model_sky_ground`] stands on (cosine-distributed, unweighted). Measured on the
/// reference scenes (ROI FLIP of blouberg_teapot, city_spot, courtyard_dragon, quarry_bunny,
/// quarry_truck; docs/accuracy.md "Tenth session"): one ray a bin 0.0560, 0.0806, 0.0924, 0.0868,
/// 0.1087; half a ray a bin (128) 0.0558, 0.0802, 0.0968, 0.0886, 0.1089; 256 cosine-distributed
/// rays (ninth session) 0.0572, 0.0803, 0.0934, 0.0878, 0.1090.
pub const GROUND_RAYS: u32 = 256;

/// The sky a horizontal ground square under a placed model still sees: the contact shadow an
/// overcast sky (or the sky part of any light) leaves under the model.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundSky {
    /// World corners of the square (x, y) at height `z`.
    pub min: Vec2,
    pub max: Vec2,
    pub z: f32,
    /// Texels per side; `visibility` is row-major from `min` (row 0 at min.y), cosine-weighted
    /// sky visibility in 0..=1 at each texel's centre.
    pub size: u32,
    pub visibility: Vec<f32>,
    /// The same per colour channel (linear RGB), each channel's rays weighted by that channel of
    /// the sky ([`Transfer::weighted_visibility_rgb`]): a model that hides the warm sky round a
    /// low sun leaves the ground bluer, not greyer. Row-major as `visibility`; empty: the
    /// `visibility` in every channel.
    pub visibility_rgb: Vec<[f32; 3]>,
    /// The model's light reflected onto each texel as a gain on the ground's own light, per
    /// channel (linear RGB; [`Transfer::reflected`]), row-major as `visibility`; empty: none.
    pub bounce: Vec<[f32; 3]>,
}

impl GroundSky {
    /// Texel `i`'s visibility per channel ([`GroundSky::visibility_rgb`]).
    pub fn channels(&self, i: usize) -> [f32; 3] {
        self.visibility_rgb.get(i).copied().unwrap_or_else(|| [self.visibility.get(i).copied().unwrap_or(1.0); 3])
    }

    /// The visibility at world (x, y) by bilinear interpolation between texel centres (1 outside
    /// the square: far from the model the sky is whole).
    pub fn at(&self, p: Vec2) -> f32 {
        let uv = (p - self.min) / (self.max - self.min);
        if !(0.0..=1.0).contains(&uv.x) || !(0.0..=1.0).contains(&uv.y) {
            return 1.0;
        }
        let n = self.size as usize;
        let f = (uv * self.size as f32 - 0.5).clamp(Vec2::ZERO, Vec2::splat(self.size as f32 - 1.0));
        let (x0, y0) = (f.x as usize, f.y as usize);
        let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
        let (tx, ty) = (f.x - x0 as f32, f.y - y0 as f32);
        let v = |x: usize, y: usize| self.visibility[y * n + x];
        let top = v(x0, y0) * (1.0 - tx) + v(x1, y0) * tx;
        let bottom = v(x0, y1) * (1.0 - tx) + v(x1, y1) * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

/// The ground square that holds the model's contact shadow: the footprint of the placed model's
/// box (model-space `bounds`, placement `model`, world z up) widened by twice its height on
/// every side, at the box's lowest point. Past that margin a wall as tall as the box hides less
/// than (1 − cos atan ½)/2 ≈ 5 % of the cosine-weighted sky.
pub fn ground_square(bounds: (Vec3, Vec3), model: Mat4) -> (Vec2, Vec2, f32) {
    let (lo, hi) = bounds;
    let corners = (0..8).map(|i| model.transform_point3(Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][i >> 2])));
    let (wlo, whi) = corners.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), c| (a.min(c), b.max(c)));
    let margin = 2.0 * (whi.z - wlo.z);
    let centre = 0.5 * (wlo.truncate() + whi.truncate());
    let half = 0.5 * (whi.truncate() - wlo.truncate()).max_element() + margin;
    (centre - Vec2::splat(half), centre + Vec2::splat(half), wlo.z)
}

/// The ground's sky transfer around a model placed by `model` (model space → world, a
/// rotation, uniform scale and translation): `occluders` are the model's triangles in model
/// space; `size`² texels over [`ground_square`], `rays` rays each ([`Occluders::transfer`]; the
/// bounce's sky by `basis` of the world normal, light::sh9::basis). Cast once per placement;
/// each sky then makes its map without a ray ([`GroundTransfer::map`]): the model hides a
/// directional sky (a courtyard lit from one side, the glow over a sunrise horizon) by how much
/// light the hidden part gives, not by its solid angle alone.
pub fn ground_transfer(
    occluders: &Occluders,
    bounds: (Vec3, Vec3),
    model: Mat4,
    size: u32,
    rays: u32,
    basis: &(dyn Fn(Vec3) -> [f32; TERMS] + Sync),
) -> GroundTransfer {
    let (min, max, z, texels) =
        over_ground(bounds, model, size, |point, up, seed| occluders.transfer((point, up), rays, seed, model, basis));
    GroundTransfer { min, max, z, size: size.max(1), texels }
}

/// The rays of a ground map: [`ground_transfer`].
#[derive(Clone, Debug, PartialEq)]
pub struct GroundTransfer {
    pub min: Vec2,
    pub max: Vec2,
    pub z: f32,
    pub size: u32,
    /// Row-major from `min`, as [`GroundSky::visibility`].
    pub texels: Vec<Transfer>,
}

impl GroundTransfer {
    /// The ground's sky visibility under a sky of linear RGB radiance `radiance(azimuth, z)` (a
    /// world direction's, [`SkyRay::direction`]): each texel's rays weighted by its BT.709
    /// luminance ([`Transfer::weighted_visibility`]) and, per channel, by each channel
    /// ([`Transfer::weighted_visibility_rgb`]); no ray is cast.
    ///
    /// With it, the model's light on each texel ([`Transfer::reflected`]) under `bounce`
    /// ([`BounceLight::NONE`]: none, an empty `GroundSky::bounce`).
    pub fn map(&self, radiance: &dyn Fn(f32, f32) -> [f32; 3], bounce: &BounceLight) -> GroundSky {
        let luminance = |azimuth, z| crate::colour::luminance_bt709(radiance(azimuth, z));
        let visibility = self.texels.iter().map(|t| t.weighted_visibility(&luminance)).collect();
        let visibility_rgb = self.texels.iter().map(|t| t.weighted_visibility_rgb(radiance)).collect();
        let bounce = if *bounce == BounceLight::NONE { Vec::new() } else { self.texels.iter().map(|t| t.reflected(bounce)).collect() };
        GroundSky { min: self.min, max: self.max, z: self.z, size: self.size, visibility, visibility_rgb, bounce }
    }

    /// [`GroundTransfer::map`] under the binned sky `sky` turned by `heading` (rad:
    /// [`SkyRadiance::at_rgb`]), as the model cache makes each new light's map: the same
    /// products summed in the same order, so the same map to the bit, but each ray's bin read
    /// from a table of its quantised azimuth and z instead of the sky asked twice a ray, and
    /// the texels shared among the machine's cores (the demo truck's new sky on the frame's
    /// thread 38 → 3–4 ms in `previz bench live`; docs/PERFORMANCE.md, twenty-first session).
    pub fn under(&self, sky: &SkyRadiance, heading: f32, bounce: &BounceLight) -> GroundSky {
        // Each quantised azimuth's column for this heading (SkyRay::direction's step middle).
        let columns: Vec<u8> = (0..=u16::MAX)
            .map(|a| SkyRadiance::bin_at(SkyRay { azimuth: a, z_open: 0 }.direction().0 - heading, 0.5 / 32768.0) as u8)
            .collect();
        // Each bin's luminance and colour weights: at_rgb's radiance (not below 0) times the
        // ray's share of its row (row_weight).
        let weights: Vec<[f32; 4]> = (0..SKY_BINS)
            .map(|b| {
                let rgb = sky.tint[b].map(|t| t * sky.bins[b]);
                let row = (2 * (b / SKY_COLUMNS) + 1) as f32;
                let [r, g, b] = rgb.map(|c| c.max(0.0) * row);
                [crate::colour::luminance_bt709(rgb).max(0.0) * row, r, g, b]
            })
            .collect();
        let reflects = *bounce != BounceLight::NONE;
        let texel = |t: &Transfer| -> ([f32; 4], [f32; 3]) {
            let (mut open, mut total) = ([0f32; 4], [0f32; 4]);
            for r in &t.rays {
                // SkyRay::direction's z at its step's middle, ((z + ½) / 32768 · SKY_ROWS) cut:
                // the top three of its 15 bits.
                let row = usize::from((r.z_open & 0x7fff) >> 12);
                let w = &weights[row * SKY_COLUMNS + usize::from(columns[usize::from(r.azimuth)])];
                for c in 0..4 {
                    total[c] += w[c];
                    if r.open() {
                        open[c] += w[c];
                    }
                }
            }
            let shares = std::array::from_fn(|c| if total[c] > 0.0 { (open[c] / total[c]).clamp(0.0, 1.0) } else { t.plain });
            (shares, if reflects { t.reflected(bounce) } else { [0.0; 3] })
        };
        let texels = parallel_map(&self.texels, ([0.0; 4], [0.0; 3]), |_, t| texel(t));
        let visibility = texels.iter().map(|(s, _)| s[0]).collect();
        let visibility_rgb = texels.iter().map(|(s, _)| [s[1], s[2], s[3]]).collect();
        let bounce = if reflects { texels.iter().map(|&(_, b)| b).collect() } else { Vec::new() };
        GroundSky { min: self.min, max: self.max, z: self.z, size: self.size, visibility, visibility_rgb, bounce }
    }
}

/// `f(point, up, seed)` at the centre of each of the `size`² texels of the [`ground_square`]
/// under the model placed by `model`, in model space (`up`: the world's +z there; `seed`: the
/// texel's row-major index), over the machine's cores: the square and the row-major values.
fn over_ground<T: Send + Clone + Default>(
    bounds: (Vec3, Vec3),
    model: Mat4,
    size: u32,
    f: impl Fn(Vec3, Vec3, u32) -> T + Sync,
) -> (Vec2, Vec2, f32, Vec<T>) {
    let (min, max, z) = ground_square(bounds, model);
    let to_model = model.inverse();
    let up = to_model.transform_vector3(Vec3::Z).normalize_or_zero();
    let n = size.max(1) as usize;
    let values = parallel_map(&vec![(); n * n], T::default(), |k, _| {
        let (x, y) = (k % n, k / n);
        let uv = (Vec2::new(x as f32, y as f32) + 0.5) / n as f32;
        let world = (min + (max - min) * uv).extend(z);
        f(to_model.transform_point3(world), up, k as u32)
    });
    (min, max, z, values)
}

/// The ground map computed directly, one radiance `sky(d)` (world direction) weighting the same
/// rays as [`ground_transfer`] as they are cast (Σ V L s / Σ L s, [`sky_rays`], the radiance
/// clamped at 0): what the transfer's maps are tested against, casting every ray again for each
/// sky.
#[cfg(test)]
pub(crate) fn ground_sky_direct(
    occluders: &Occluders,
    bounds: (Vec3, Vec3),
    model: Mat4,
    size: u32,
    rays: u32,
    sky: &(dyn Fn(Vec3) -> f32 + Sync),
) -> GroundSky {
    let frame = placement_rotation(model);
    let (min, max, z, visibility) = over_ground(bounds, model, size, |point, up, seed| {
        let origin = point + up * occluders.epsilon;
        let (mut open, mut total, mut plain) = (0f32, 0f32, 0f32);
        for (world, share) in sky_rays(rays, seed) {
            let w = sky(world).max(0.0) * share;
            total += w;
            if !occluders.blocked(origin, frame.transpose() * world, f32::INFINITY) {
                open += w;
                plain += share;
            }
        }
        if total > 0.0 { (open / total).clamp(0.0, 1.0) } else { plain }
    });
    GroundSky { min, max, z, size: size.max(1), visibility, visibility_rgb: Vec::new(), bounce: Vec::new() }
}

fn mesh_triangles(mesh: &Mesh) -> impl Iterator<Item = [Vec3; 3]> + '_ {
    mesh.indices.chunks_exact(3).filter_map(|t| {
        let p = |i: u32| mesh.positions.get(i as usize).map(|p| Vec3::from_array(*p));
        Some([p(t[0])?, p(t[1])?, p(t[2])?])
    })
}

/// Reorder `tris` so that the split that minimises the surface-area heuristic comes first and
/// return where it falls; None when keeping them in one leaf is cheaper.
fn sah_split(tris: &mut [[Vec3; 3]]) -> Option<usize> {
    const BINS: usize = 16;
    let (clo, chi) = tris.iter().map(centroid).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), c| (a.min(c), b.max(c)));
    let extent = chi - clo;
    let area = |lo: Vec3, hi: Vec3| {
        let d = (hi - lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    };
    let mut best: Option<(f32, usize, f32)> = None; // (cost, axis, split position)
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let bin_of = |t: &[Vec3; 3]| (((centroid(t)[axis] - clo[axis]) / extent[axis] * BINS as f32) as usize).min(BINS - 1);
        let mut bins = [(Vec3::INFINITY, Vec3::NEG_INFINITY, 0u32); BINS];
        for t in tris.iter() {
            let b = &mut bins[bin_of(t)];
            for p in t {
                b.0 = b.0.min(*p);
                b.1 = b.1.max(*p);
            }
            b.2 += 1;
        }
        // Sweep from the right to know each right side's area and count.
        let mut right = [(0.0f32, 0u32); BINS];
        let (mut lo, mut hi, mut n) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0);
        for i in (1..BINS).rev() {
            (lo, hi, n) = (lo.min(bins[i].0), hi.max(bins[i].1), n + bins[i].2);
            right[i] = (area(lo, hi), n);
        }
        let (mut lo, mut hi, mut n) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0);
        for i in 0..BINS - 1 {
            (lo, hi, n) = (lo.min(bins[i].0), hi.max(bins[i].1), n + bins[i].2);
            let (ra, rn) = right[i + 1];
            if n == 0 || rn == 0 {
                continue;
            }
            let cost = area(lo, hi) * n as f32 + ra * rn as f32;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, clo[axis] + extent[axis] * (i + 1) as f32 / BINS as f32));
            }
        }
    }
    let (lo, hi) = bounds(tris);
    let leaf_cost = area(lo, hi) * tris.len() as f32;
    match best {
        // Splitting costs one more box test per ray, about one triangle test.
        Some((cost, axis, at)) if cost + area(lo, hi) < leaf_cost || tris.len() > 4 * LEAF_SIZE => {
            let mut i = 0;
            for j in 0..tris.len() {
                if centroid(&tris[j])[axis] < at {
                    tris.swap(i, j);
                    i += 1;
                }
            }
            (i > 0 && i < tris.len()).then_some(i)
        }
        // All centroids in one point (or one bin): split in the middle of the list.
        None if tris.len() > 4 * LEAF_SIZE => Some(tris.len() / 2),
        _ => None,
    }
}

fn centroid(t: &[Vec3; 3]) -> Vec3 {
    (t[0] + t[1] + t[2]) / 3.0
}

fn bounds(tris: &[[Vec3; 3]]) -> (Vec3, Vec3) {
    tris.iter().flatten().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
}

/// Ray against an axis-aligned box (slab test), for 0 <= t <= t_max.
fn slab_hit(lo: Vec3, hi: Vec3, origin: Vec3, inv: Vec3, t_max: f32) -> bool {
    slab_entry(lo, hi, origin, inv, t_max).is_some()
}

/// Where the ray `origin + t·dir` (`inv` = 1/dir) enters the box `lo`..`hi` (0 from inside),
/// if it meets it before `t_max`.
fn slab_entry(lo: Vec3, hi: Vec3, origin: Vec3, inv: Vec3, t_max: f32) -> Option<f32> {
    let a = (lo - origin) * inv;
    let b = (hi - origin) * inv;
    // NaN (0 · inf, a ray in a box's plane) must not reject the box: min/max ignore NaN.
    let near = a.min(b).max_element().max(0.0);
    let far = a.max(b).min_element().min(t_max);
    (near <= far).then_some(near)
}

/// Möller–Trumbore ray/triangle test, both sides, hits with 0 < t < t_max.
fn triangle_hit(t: &[Vec3; 3], origin: Vec3, dir: Vec3, t_max: f32) -> bool {
    triangle_distance(t, origin, dir, t_max).is_some()
}

/// [`triangle_hit`]'s distance t along the ray (in units of `dir`'s length).
fn triangle_distance(t: &[Vec3; 3], origin: Vec3, dir: Vec3, t_max: f32) -> Option<f32> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - t[0];
    let u = s.dot(p) * inv;
    if !(-1e-6..=1.0 + 1e-6).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -1e-6 || u + v > 1.0 + 1e-6 {
        return None;
    }
    let dist = e2.dot(q) * inv;
    (dist > 0.0 && dist < t_max).then_some(dist)
}

/// The i-th of n points of the Hammersley set in [0, 1)^2 (i/n, base-2 radical inverse of i).
pub fn hammersley(i: u32, n: u32) -> (f32, f32) {
    ((i as f32 + 0.5) / n as f32, i.reverse_bits() as f32 * (1.0 / 4_294_967_296.0))
}

/// A cosine-distributed direction about +z from a point of the unit square (Malley's method:
/// uniform on the disc, lifted to the hemisphere).
pub fn cosine_direction(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = TAU * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Two unit vectors completing unit `n` to a right-handed orthonormal basis (Duff et al. 2017,
/// "Building an orthonormal basis, revisited").
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// A hash of `x` mapped to [0, 1) (the lowbias32 integer hash).
fn unit_hash(mut x: u32) -> f32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_point_loses_the_colour_of_the_sky_it_no_longer_sees() {
        // Two rays in the same row: the one North sees a warm sky (R 2, G 1, B 0.5) and is
        // blocked, the one South a blue one (0.5, 1, 2) and passes. Red keeps 0.5/2.5 of its
        // light, green half, blue 2/2.5: a shadow that hides the warm part of a sky turns blue.
        let up = std::f32::consts::FRAC_1_SQRT_2;
        let t = Transfer {
            plain: 0.5,
            bounce: Bounce::default(),
            rays: vec![SkyRay::new(Vec3::new(0.0, up, up), false), SkyRay::new(Vec3::new(0.0, -up, up), true)],
        };
        let sky = |azimuth: f32, _z: f32| if azimuth.cos() > 0.0 { [2.0, 1.0, 0.5] } else { [0.5, 1.0, 2.0] };
        let v = t.weighted_visibility_rgb(&sky);
        for (got, want) in v.iter().zip([0.2, 0.5, 0.8]) {
            assert!((got - want).abs() < 1e-6, "{v:?}");
        }
        // A channel without light takes the plain share.
        assert_eq!(t.weighted_visibility_rgb(&|_, _| [0.0, 1.0, 1.0])[0], 0.5);
    }
    use super::*;

    /// Two triangles spanning the rectangle [x0, x1] x [y0, y1] at height z.
    fn quad(x0: f32, x1: f32, y0: f32, y1: f32, z: f32) -> [[Vec3; 3]; 2] {
        let p = |x, y| Vec3::new(x, y, z);
        [[p(x0, y0), p(x1, y0), p(x1, y1)], [p(x0, y0), p(x1, y1), p(x0, y1)]]
    }

    #[test]
    fn an_open_vertex_sees_the_tilted_planes_share_of_the_sky_through_its_own_rays() {
        // A lone quad whose normal leans θ from the model's up (y): under a sky of radiance 1 above
        // the horizon, E / π = (1 + cos θ) / 2, the tilted plane's view factor to the sky; a
        // level quad under a sky of 2 towards +x and 1 towards −x: E / π = (2 + 1) / 2. Nothing
        // is met, so nothing is reflected.
        for theta in [0.0f32, 30.0, 60.0, 90.0, 120.0] {
            let t = theta.to_radians();
            let n = Vec3::new(t.sin(), t.cos(), 0.0);
            let (u, v) = (Vec3::Z, n.cross(Vec3::Z));
            let positions = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(a, b)| (u * a + v * b).to_array()).to_vec();
            let mesh = Mesh { positions, normals: vec![n.to_array(); 4], uvs: vec![], indices: vec![0, 1, 2, 0, 2, 3], material: 0 };
            let model = Model { meshes: vec![mesh], materials: vec![crate::scene::Material::default()] };
            let (_, rays) = model_light(&model, &Occluders::of_model(&model));
            let sky = rays.sky(&model, &|d| if d.y > 0.0 { 1.0 } else { 0.0 });
            let mean = sky[0].iter().sum::<f32>() / 4.0;
            let want = (1.0 + t.cos()) / 2.0;
            assert!((mean - want).abs() < 0.03, "θ {theta}: {mean} against {want}");
            if theta == 0.0 {
                let sky = rays.sky(&model, &|d| if d.x > 0.0 { 2.0 } else { 1.0 });
                let mean = sky[0].iter().sum::<f32>() / 4.0;
                assert!((mean - 1.5).abs() < 0.05, "{mean}");
            }
        }
    }

    #[test]
    fn each_colour_channel_of_the_sky_goes_through_the_same_rays() {
        // A level quad (facing the model's up, y) under a sky warm towards +x, R, G, B (2, 1,
        // 0.5), and blue towards −x, (0.5, 1, 2): each channel's E / π is the mean of its two
        // halves, (2 + 0.5) / 2 = 1.25 in red and blue, 1 in green, and each is what that
        // channel's sky alone gives (ModelRays::sky_with, walked once per sky).
        let mesh = level_quad(1.0, 0);
        let model = Model { meshes: vec![mesh], materials: vec![crate::scene::Material::default()] };
        let (_, rays) = model_light(&model, &Occluders::of_model(&model));
        let sky = |d: Vec3| {
            if d.y <= 0.0 {
                [0.0; 3]
            } else if d.x > 0.0 {
                [2.0, 1.0, 0.5]
            } else {
                [0.5, 1.0, 2.0]
            }
        };
        let rgb = rays.sky_channels(&model, &sky, BOUNCES);
        for c in 0..3 {
            let alone = rays.sky(&model, &|d| sky(d)[c]);
            let got: Vec<f32> = rgb[0].iter().map(|v| v[c]).collect();
            assert_eq!(got, alone[0], "channel {c}");
            let mean = got.iter().sum::<f32>() / 4.0;
            let want = [1.25, 1.0, 1.25][c];
            assert!((mean - want).abs() < 0.05, "channel {c}: {mean} against {want}");
        }
    }

    #[test]
    fn the_skys_channels_walked_together_are_each_channel_walked_alone() {
        // A ball resting on a floor 4 wide (its triangles larger than the sample spacing, so
        // inner samples are projected), grey 0.6: the floor's rays meet the ball and the ball's
        // the floor, so the bounces carry light. Under a sky whose three channels differ by
        // direction (model space, y up), sky_channels walks the samples once for all three; each
        // channel is what that channel's sky alone gives, to the bit, with and without bounces.
        let mut ball = sphere(0.5, 12, 24);
        ball.positions.iter_mut().for_each(|p| p[1] += 0.5);
        let floor = level_quad(2.0, 0);
        let grey = crate::scene::Material { diffuse: [0.6; 3], ..Default::default() };
        let model = Model { meshes: vec![ball, floor], materials: vec![grey] };
        let (_, rays) = model_light(&model, &Occluders::of_model(&model));
        let sky = |d: Vec3| [1.0 + d.x.max(0.0), 1.0, 0.5 + 2.0 * d.z.abs()];
        for bounces in [0, BOUNCES] {
            let together = rays.sky_channels(&model, &sky, bounces);
            for c in 0..3 {
                let alone = rays.sky_with(&model, &|d| sky(d)[c], bounces);
                for (m, mesh) in together.iter().enumerate() {
                    let got: Vec<f32> = mesh.iter().map(|v| v[c]).collect();
                    assert_eq!(got, alone[m], "mesh {m}, channel {c}, {bounces} bounces");
                }
            }
        }
        // The bounces carry light: the floor's vertices gain the ball's (through the inner
        // samples under it, projected onto the corners).
        let (direct, bounced) = (rays.sky_with(&model, &|_| 1.0, 0), rays.sky(&model, &|_| 1.0));
        let gained = direct[1].iter().zip(&bounced[1]).map(|(a, b)| b - a).fold(0.0f32, f32::max);
        assert!(gained > 0.01, "{gained}");
    }

    #[test]
    fn a_vertex_in_a_closed_box_gets_only_the_light_its_walls_reflect() {
        // A closed cube of albedo 0.5 (normals inwards) with a small level quad of albedo 0.8
        // floating inside, facing up: no ray of the quad passes, so it sees no sky, and the
        // quad gets only what its walls reflect. Walls lit by E / π = 3: every ray of the quad
        // meets a wall, so its vertices get 0.5 × 3, the walls' albedo times their light.
        let mut walls = Mesh::default();
        for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                let mut n = Vec3::ZERO;
                n[axis] = -side;
                let (u, v) = orthonormal_basis(n);
                let first = walls.positions.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    walls.positions.push((-n + u * a + v * b).to_array());
                    walls.normals.push(n.to_array());
                }
                // Wound so that (b − a) × (c − a) is the inward normal.
                walls.indices.extend([0, 1, 2, 0, 2, 3].map(|i| first + i));
            }
        }
        let quad = level_quad(0.1, 1);
        let grey = |g: f32| crate::scene::Material { diffuse: [g; 3], ..Default::default() };
        let model = Model { meshes: vec![walls, quad], materials: vec![grey(0.5), grey(0.8)] };
        let (shares, rays) = model_light(&model, &Occluders::of_model(&model));
        // The quad sees no sky; what it gets is its walls' light (the walls' own vertices, at the
        // cube's corners and edges, let a few grazing rays out between faces) times their albedo.
        let seen = rays.sky_with(&model, &|_| 1.0, 0);
        assert!(seen[1].iter().all(|&v| v == 0.0), "{:?}", seen[1]);
        let sky = rays.sky(&model, &|_| 1.0);
        let brightest_wall = sky[0].iter().copied().fold(0.0, f32::max);
        assert!(sky[1].iter().all(|&v| v > 0.0 && v <= 0.5 * brightest_wall + 1e-6), "{sky:?}");
        let lit = rays.per_vertex(&model, &|_, _, r| rays.reflected(r, &|_| [3.0]));
        for [v] in &lit[1] {
            assert!((v - 1.5).abs() < 1e-4, "{:?}", lit[1]);
        }
        // The vertices' own shares agree: no ray of the quad passes the box.
        assert!(shares[1].iter().all(|v| v.ao[0] == 0.0 && v.ao[2] == 0.0), "{:?}", shares[1]);
    }

    /// A level square 2 `half` wide at the model's floor (y = 0, facing up: the model's up is
    /// y), two triangles, drawn with `material`.
    fn level_quad(half: f32, material: usize) -> Mesh {
        Mesh {
            positions: vec![[-half, 0.0, -half], [-half, 0.0, half], [half, 0.0, half], [half, 0.0, -half]],
            normals: vec![[0.0, 1.0, 0.0]; 4],
            uvs: vec![],
            indices: vec![0, 1, 2, 0, 2, 3],
            material,
        }
    }

    /// A UV sphere of radius r at the origin with outward unit normals.
    fn sphere(r: f32, rings: u32, segments: u32) -> Mesh {
        let mut mesh = Mesh::default();
        for i in 0..=rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..=segments {
                let phi = TAU * j as f32 / segments as f32;
                let n = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                mesh.positions.push((n * r).to_array());
                mesh.normals.push(n.to_array());
            }
        }
        let w = segments + 1;
        for i in 0..rings {
            for j in 0..segments {
                let (a, b, c, d) = (i * w + j, i * w + j + 1, (i + 1) * w + j, (i + 1) * w + j + 1);
                mesh.indices.extend([a, c, b, b, c, d]);
            }
        }
        mesh
    }

    /// The monomials up to degree 2 (the same space as the nine SH, light::sh9::basis).
    fn polynomials(d: Vec3) -> [f32; TERMS] {
        [1.0, d.x, d.y, d.z, d.x * d.y, d.y * d.z, d.z * d.z, d.x * d.z, d.x * d.x - d.y * d.y]
    }
    /// A uniform sky in [`polynomials`].
    const UNIFORM: [f32; TERMS] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

    /// Σ c_k polynomials_k(d).
    fn radiance(c: &[f32; TERMS], d: Vec3) -> f32 {
        polynomials(d).iter().zip(c).map(|(y, c)| y * c).sum()
    }

    /// The unit world direction at `azimuth` (clockwise from North) and height `z`.
    fn world_direction(azimuth: f32, z: f32) -> Vec3 {
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(azimuth.sin() * r, azimuth.cos() * r, z)
    }

    #[test]
    fn hammersley_directions_are_cosine_distributed() {
        // E[cos θ] under a cosine-weighted density is 2/3; E[d.x] = E[d.y] = 0.
        let n = 4096;
        let mean = (0..n).map(|i| hammersley(i, n)).map(|(a, b)| cosine_direction(a, b)).fold(Vec3::ZERO, |s, d| s + d) / n as f32;
        assert!((mean.z - 2.0 / 3.0).abs() < 1e-3, "{mean}");
        assert!(mean.x.abs() < 1e-3 && mean.y.abs() < 1e-3, "{mean}");
    }

    #[test]
    fn the_basis_is_orthonormal_for_every_normal() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, 0.8).normalize(), Vec3::new(1e-7, 0.0, -1.0).normalize()] {
            let (t, b) = orthonormal_basis(n);
            for (x, y) in [(t, b), (t, n), (b, n)] {
                assert!(x.dot(y).abs() < 1e-5, "{n}");
            }
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!((t.cross(b) - n).length() < 1e-5, "right-handed for {n}");
        }
    }

    #[test]
    fn a_plane_with_a_hole_above_lets_through_the_cone_it_frames() {
        // A point on the floor under a ceiling at height d with a round hole of radius r straight
        // above sees the cone of half-angle atan(r/d); its cosine-weighted share is sin² of that
        // angle = r²/(r²+d²). The ceiling is an annulus of triangles out to 100 d
        // (which lets through another 1/(1 + 100²) = 1e-4).
        let (d, r) = (1.0f32, 1.0f32);
        let segments = 256;
        let mut tris = Vec::new();
        for j in 0..segments {
            let a0 = TAU * j as f32 / segments as f32;
            let a1 = TAU * (j + 1) as f32 / segments as f32;
            let at = |rad: f32, a: f32| Vec3::new(rad * a.cos(), rad * a.sin(), d);
            let (outer, inner) = (100.0 * d, r / (std::f32::consts::PI / segments as f32).cos());
            tris.push([at(inner, a0), at(outer, a0), at(outer, a1)]);
            tris.push([at(inner, a0), at(outer, a1), at(inner, a1)]);
        }
        let occ = Occluders::new(tris);
        let expected = r * r / (r * r + d * d);
        let mean = (0..16).map(|s| occ.visibility(Vec3::ZERO, Vec3::Z, 512, s)).sum::<f32>() / 16.0;
        assert!((mean - expected).abs() < 0.01, "visibility {mean}, expected {expected}");
    }

    #[test]
    fn the_inside_of_a_closed_box_sees_nothing() {
        // A unit cube with inward normals at its vertices: every ray hits a wall.
        let mut mesh = Mesh::default();
        let faces: [(Vec3, Vec3, Vec3); 6] = [
            (Vec3::X, Vec3::Y, Vec3::Z),
            (Vec3::NEG_X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::Z, Vec3::X),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::Y, Vec3::X),
        ];
        for (outward, u, v) in faces {
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push((outward + u * a + v * b).to_array());
                mesh.normals.push((-outward).to_array());
            }
            mesh.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        let ao = vertex_ao(&mesh, &Occluders::new(mesh_triangles(&mesh).collect()), 256);
        assert!(ao.iter().all(|&v| v == 0.0), "{ao:?}");
        // And from the middle of the box, every direction.
        let occ = Occluders::new(mesh_triangles(&mesh).collect());
        assert_eq!(occ.visibility(Vec3::new(0.2, -0.3, 0.1), Vec3::new(1.0, 2.0, 3.0), 512, 7), 0.0);
    }

    #[test]
    fn a_lone_convex_shape_is_unoccluded() {
        // A sphere standing on the ground: every vertex sees all the sky above it and all the
        // ground below it past the sphere, and the sphere reflects nothing onto itself.
        let mesh = sphere(2.0, 24, 48);
        let model = Model { meshes: vec![mesh], materials: vec![Default::default()] };
        let ao = model_sky_ground(&model, &Occluders::of_model(&model));
        assert_eq!(ao[0].len(), model.meshes[0].positions.len());
        assert!(
            ao[0].iter().all(|v| v.ao[0] == 1.0 && v.ao[2] == 1.0 && v.ao[3].abs() < 1e-6),
            "{:?}",
            ao[0].iter().find(|v| v.ao[0] < 1.0 || v.ao[2] < 1.0)
        );
    }

    #[test]
    fn the_foot_of_a_wall_sees_half_the_cosine_weighted_sky() {
        // Floor z = 0 and wall x = 0 (towards +x), both 1000 wide; a point on the floor at the
        // foot of the wall sees the half hemisphere x < 0: by symmetry, half the cosine weight.
        let mut tris = quad(-1000.0, 1000.0, -1000.0, 1000.0, 0.0).to_vec();
        for t in quad(-1000.0, 1000.0, 0.0, 1000.0, 0.0) {
            tris.push(t.map(|p| Vec3::new(0.0, p.x, p.y))); // the wall: x = 0, |y| < 1000, 0 < z < 1000
        }
        let occ = Occluders::new(tris);
        let mean = (0..16).map(|s| occ.visibility(Vec3::new(-1e-3, 0.0, 0.0), Vec3::Z, 512, s)).sum::<f32>() / 16.0;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }

    #[test]
    fn sky_over_the_ground_under_a_sphere_matches_the_spherical_cap() {
        // A sphere of radius R centred at height h over the ground: from the point right under
        // it, the sphere hides the cone of half-angle asin(R/h) about the zenith, whose
        // cosine-weighted share is sin² = (R/h)²; the sky visibility is 1 − (R/h)².
        let (r, h) = (1.0f32, 2.0f32);
        let mut mesh = sphere(r, 48, 96);
        for p in &mut mesh.positions {
            p[2] += h;
        }
        let occ = Occluders::new(mesh_triangles(&mesh).collect());
        let under = (0..16).map(|s| sky_visibility(&occ, Vec3::ZERO, Vec3::Z, 512, s)).sum::<f32>() / 16.0;
        let expected = 1.0 - (r / h).powi(2);
        assert!((under - expected).abs() < 0.01, "under the sphere {under}, expected {expected}");
        // Far away the sphere covers almost nothing: at distance 100 its cone is ~1e-4 sr.
        let far = sky_visibility(&occ, Vec3::new(100.0, 0.0, 0.0), Vec3::Z, 512, 3);
        assert!(far > 0.99, "{far}");
    }

    #[test]
    fn smoothing_keeps_a_constant_and_spreads_a_spike_over_its_ring() {
        // A fan of 6 triangles around vertex 0 (a hexagon): the centre is in all six, each rim
        // vertex in two (with the centre and one rim neighbour on each side).
        let mut mesh = Mesh::default();
        mesh.positions.push([0.0; 3]);
        for k in 0..6 {
            let a = TAU * k as f32 / 6.0;
            mesh.positions.push([a.cos(), a.sin(), 0.0]);
        }
        for k in 0..6u32 {
            mesh.indices.extend([0, 1 + k, 1 + (k + 1) % 6]);
        }
        assert!(smooth_over_neighbours(&mesh, &[[0.4]; 7]).iter().all(|&[v]| (v - 0.4).abs() < 1e-6));
        // A spike at the centre in the first channel, at a rim vertex in the second: each
        // channel is smoothed alone.
        let mut spike = [[0.0; 2]; 7];
        (spike[0][0], spike[1][1]) = (1.0, 1.0);
        let s = smooth_over_neighbours(&mesh, &spike);
        // Centre: itself in 6 triangles (weight 6 of 12); a rim vertex: the centre at weight 1/2
        // in each of its 2 triangles (1 of 4).
        assert!((s[0][0] - 0.5).abs() < 1e-6, "{s:?}");
        assert!(s[1..].iter().all(|&[v, _]| (v - 0.25).abs() < 1e-6), "{s:?}");
        // Rim vertex 1 in the second: itself once in each of its 2 triangles (2 of 4); the
        // centre sees it at 1/2 in two of its 6 triangles (1 of 12), its rim neighbours at 1/2 in
        // one of their 2 (1/2 of 4), the rest not at all.
        assert!((s[1][1] - 0.5).abs() < 1e-6 && (s[0][1] - 1.0 / 12.0).abs() < 1e-6, "{s:?}");
        assert!((s[2][1] - 0.125).abs() < 1e-6 && (s[6][1] - 0.125).abs() < 1e-6 && s[4][1] == 0.0, "{s:?}");
    }

    #[test]
    fn under_a_floating_sphere_the_ground_it_shadows_lights_it_less() {
        // A sphere of radius R centred h above the ground (model space, y up; a degenerate
        // triangle at the origin puts the bounding box's base, the ground, at y = 0). A ground
        // point at distance ρ from the point under the centre sees the sphere at distance
        // D = √(ρ² + h²) and zenith angle β = atan(ρ/h), wholly above its horizon: the sphere's
        // configuration factor from that differential area is (R/D)² cos β (Howell's catalog of
        // radiation configuration factors: a sphere wholly above a tilted differential area), so
        // the ground's sky visibility is V(ρ) = 1 − (R/D)² cos β.
        // The sphere's lowest vertex (normal straight down, height d = h − R) sees the ground
        // at ρ = d tan θ along a ray θ from straight down; its share of the ground's light is the
        // cosine-weighted mean 2 ∫ V(d tan θ) cos θ sin θ dθ over 0..π/2.
        let (r, h) = (1.0f32, 2.0f32);
        let mut ball = sphere(r, 48, 96);
        for p in &mut ball.positions {
            p[1] += h;
        }
        let base = Mesh { positions: vec![[0.0; 3]; 3], normals: vec![[0.0, 1.0, 0.0]; 3], indices: vec![0, 1, 2], ..Default::default() };
        let model = Model { meshes: vec![ball, base], materials: vec![Default::default()] };
        let values = model_sky_ground(&model, &Occluders::of_model(&model));
        let steps = 4000;
        let expected = (0..steps)
            .map(|i| {
                let theta = (i as f64 + 0.5) / steps as f64 * std::f64::consts::FRAC_PI_2;
                let rho = f64::from(h - r) * theta.tan();
                let d2 = rho * rho + f64::from(h * h);
                let v = 1.0 - f64::from(r * r) / d2 * f64::from(h) / d2.sqrt();
                2.0 * v * theta.cos() * theta.sin() * std::f64::consts::FRAC_PI_2 / steps as f64
            })
            .sum::<f64>() as f32;
        // The lowest vertex: ring 24 (θ = π/2 about the sphere's z), segment 72 (φ = 3π/2: −y).
        let bottom = values[0][24 * 97 + 72].ao;
        assert!((bottom[1] - expected).abs() < 0.02, "ground share {} vs {expected}", bottom[1]);
        // Nothing of the sphere is below its lowest vertex: all of the ground, and no bounce from a
        // convex shape (the fit keeps 1 at 1).
        assert!((bottom[2] - 1.0).abs() < 1e-6 && bottom[3].abs() < 1e-6, "{bottom:?}");
        assert!(expected < 0.9, "the sphere's shadow darkens the ground it sees: {expected}");
        // The top vertex sees the whole sky; nothing of the ground.
        let top = values[0][24 * 97 + 24].ao;
        assert!((top[0] - 1.0).abs() < 1e-6, "{top:?}");
        // Far from a small model the ground is whole: a ball of radius 0.01 at the same height.
        let mut tiny = model.clone();
        tiny.meshes[0].positions.iter_mut().for_each(|p| *p = [p[0] * 0.01, (p[1] - h) * 0.01 + h, p[2] * 0.01]);
        let values = model_sky_ground(&tiny, &Occluders::of_model(&tiny));
        assert!(values[0][24 * 97 + 72].ao[1] > 0.99, "{:?}", values[0][24 * 97 + 72]);
    }

    #[test]
    fn a_large_triangle_takes_the_light_its_surface_receives() {
        // A floor square of side 2a (two triangles, vertices only at its corners, normal up:
        // model space y) under a sphere of radius R centred h above its middle. A floor point at
        // distance ρ from under the centre sees the sphere at D = √(ρ² + h²) and zenith angle β,
        // cos β = h/D: its sky share is V(ρ) = 1 − (R/D)² cos β (the configuration factor of the
        // floating-sphere test above). Point-sampled, a corner vertex (ρ = a√2) would take
        // V(a√2) = 0.98 for the whole of its triangles; the shares the shader interpolates should
        // be the hat-weighted means ∫ φ_i V dA / ∫ φ_i dA over the square, computed here by a
        // midpoint rule on a fine grid with the triangles' barycentric coordinates.
        let (a, r, h) = (4.0f32, 1.5f32, 2.0f32);
        let mut ball = sphere(r, 24, 48);
        for p in &mut ball.positions {
            p[1] += h;
        }
        let floor = Mesh {
            positions: vec![[-a, 0.0, -a], [a, 0.0, -a], [a, 0.0, a], [-a, 0.0, a]],
            normals: vec![[0.0, 1.0, 0.0]; 4],
            indices: vec![0, 2, 1, 0, 3, 2],
            ..Default::default()
        };
        let model = Model { meshes: vec![floor, ball], materials: vec![Default::default()] };
        let values = model_sky_ground(&model, &Occluders::of_model(&model));
        let n = 800;
        let (mut sum, mut weight) = ([0.0f64; 4], [0.0f64; 4]);
        for iz in 0..n {
            for ix in 0..n {
                let u = (ix as f64 + 0.5) / n as f64;
                let v = (iz as f64 + 0.5) / n as f64;
                let (x, z) = (f64::from(a) * (2.0 * u - 1.0), f64::from(a) * (2.0 * v - 1.0));
                let d2 = x * x + z * z + f64::from(h * h);
                let sky = 1.0 - f64::from(r * r) / d2 * f64::from(h) / d2.sqrt();
                // Triangle (0, 2, 1) where u ≥ v, (0, 3, 2) where v > u.
                let hat = if u >= v { [1.0 - u, u - v, v, 0.0] } else { [1.0 - v, 0.0, u, v - u] };
                for k in 0..4 {
                    sum[k] += hat[k] * sky;
                    weight[k] += hat[k];
                }
            }
        }
        let d2 = 2.0 * a * a + h * h;
        let at_corner = 1.0 - r * r / d2 * h / d2.sqrt();
        for k in 0..4 {
            let expected = (sum[k] / weight[k]) as f32;
            assert!((values[0][k].ao[0] - expected).abs() < 0.01, "vertex {k}: sky {} vs {expected}", values[0][k].ao[0]);
            assert!(at_corner - expected > 0.05, "the mean differs from the corner's own light: {at_corner} vs {expected}");
        }
    }

    #[test]
    fn the_bent_normal_at_the_foot_of_a_wall_leans_away_from_it() {
        // Floor y = 0 (model space, y up) and a wall filling x > 0, both 1000 wide; a point on
        // the floor at the wall's foot sees the half hemisphere x < 0. The mean of the
        // cosine-distributed directions over that half: E[x] = −∫ sin²θ cosθ |cos φ| / π =
        // −4/(3π), E[y] = 2/3 (the whole hemisphere's), so the bent normal leans
        // atan((4/(3π)) / (2/3)) = atan(2/π) = 32.5° from the normal, away from the wall. Half
        // the rays see the sky; an open point's bent normal is its normal.
        let mut tris: Vec<[Vec3; 3]> =
            quad(-1000.0, 1000.0, -1000.0, 1000.0, 0.0).iter().map(|t| t.map(|p| Vec3::new(p.x, 0.0, p.y))).collect();
        for t in quad(-1000.0, 1000.0, 0.0, 1000.0, 0.0) {
            tris.push(t.map(|p| Vec3::new(0.0, p.y, p.x))); // the wall: x = 0, 0 < y < 1000
        }
        let occ = Occluders::new(tris);
        let ground = GroundSky {
            min: Vec2::ZERO,
            max: Vec2::ONE,
            z: 0.0,
            size: 1,
            visibility: vec![1.0],
            visibility_rgb: Vec::new(),
            bounce: Vec::new(),
        };
        let (v, _) = light_at(&occ, &ground, 0.0, (Vec3::new(-1e-3, 0.0, 0.0), Vec3::Y), 4096, 1, 0.0);
        let bent = Vec3::new(v[4], v[5], v[6]);
        let lean = bent.angle_between(Vec3::Y).to_degrees();
        let want = (2.0 / std::f32::consts::PI).atan().to_degrees();
        assert!((lean - want).abs() < 1.0, "{lean}° vs {want}°");
        assert!(bent.x < -0.5 && bent.z.abs() < 0.02, "{bent}");
        assert!((v[0] - 0.5).abs() < 0.01, "{v:?}");
        let (open, _) = light_at(&Occluders::new(Vec::new()), &ground, 0.0, (Vec3::new(0.0, 5.0, 0.0), Vec3::Y), 256, 1, 0.0);
        assert!(Vec3::new(open[4], open[5], open[6]).angle_between(Vec3::Y) < 0.02, "{open:?}");
    }

    #[test]
    fn the_ray_count_follows_the_budget() {
        assert_eq!(rays_per_vertex(100), MAX_RAYS);
        assert_eq!(rays_per_vertex(50_000), 40);
        assert_eq!(rays_per_vertex(10_000_000), MIN_RAYS);
    }

    #[test]
    fn the_ground_under_a_placed_sphere_is_darkest_below_it_and_whole_far_away() {
        // A model-space (y-up) unit sphere centred 2 above its origin, placed by a scale of 1.5,
        // a turn of 0.7 rad about world z and a move to (3, -1, 0.5): in the world a sphere of
        // radius 1.5 centred at (3, -1, 3.5), resting on the ground square at z = 2.
        let mut mesh = sphere(1.0, 48, 96);
        for p in &mut mesh.positions {
            p[1] += 2.0;
        }
        let y_up = Mat4::from_cols_array(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        let model =
            Mat4::from_translation(Vec3::new(3.0, -1.0, 0.5)) * Mat4::from_rotation_z(0.7) * Mat4::from_scale(Vec3::splat(1.5)) * y_up;
        let bounds = (Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, 3.0, 1.0));
        let occ = Occluders::new(mesh_triangles(&mesh).collect());
        let sky = ground_transfer(&occ, bounds, model, 33, 256, &polynomials).map(&|_, _| [1.0; 3], &BounceLight::NONE);
        assert!((sky.z - 2.0).abs() < 1e-4, "{}", sky.z);
        let centre = Vec2::new(3.0, -1.0);
        assert!(((sky.min + sky.max) * 0.5 - centre).length() < 1e-4);
        // The side: the turned box's footprint, 3 (cos 0.7 + sin 0.7), plus twice its height (3)
        // on both sides.
        let side = 3.0 * (0.7f32.cos() + 0.7f32.sin()) + 12.0;
        assert!(((sky.max - sky.min) - Vec2::splat(side)).length() < 1e-3, "{:?} vs {side}", sky.max - sky.min);
        // Darkest at the texel under the contact point (the middle of a 33-texel map).
        let darkest = sky.visibility.iter().copied().enumerate().fold((0, 2.0), |b, (i, v)| if v < b.1 { (i, v) } else { b });
        assert_eq!(darkest.0, 16 * 33 + 16);
        // Under a sphere of radius R whose centre is h above the ground: 1 − (R/h)²; this one
        // touches the ground (R = h), and the middle texel lies right under the contact point.
        assert!(darkest.1 < 0.02, "{}", darkest.1);
        // The map's corner, 8.1·√2 = 11.5 from the centre: the sphere hides less than
        // (1.5/11.5)² = 1.7 % of the cosine-weighted sky there.
        assert!(sky.visibility[0] > 0.98, "{}", sky.visibility[0]);
        assert!(sky.at(centre + Vec2::splat(100.0)) == 1.0);
    }

    #[test]
    fn the_ground_map_under_a_floating_sphere_matches_the_cap() {
        // A sphere of radius 1 floating with its centre 2 above z = 0, under a square whose
        // z is forced to the ground: 1 − (R/h)² = 0.75 right under it.
        let mut mesh = sphere(1.0, 48, 96);
        for p in &mut mesh.positions {
            p[2] += 2.0;
        }
        let occ = Occluders::new(mesh_triangles(&mesh).collect());
        // Bounds that reach down to the ground (a model whose box includes a pedestal).
        let sky = ground_transfer(&occ, (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 3.0)), Mat4::IDENTITY, 25, 1024, &polynomials)
            .map(&|_, _| [1.0; 3], &BounceLight::NONE);
        let under = sky.at(Vec2::ZERO);
        assert!((under - 0.75).abs() < 0.01, "{under}");
    }

    /// A unit sphere resting on the ground beside a wall, its occluders, bounds and a model matrix
    /// that turns and scales it (so that the rays' world directions differ from the model's).
    fn sphere_beside_a_wall() -> (Occluders, (Vec3, Vec3), Mat4) {
        let mut mesh = sphere(1.0, 24, 48);
        for p in &mut mesh.positions {
            p[2] += 1.0;
        }
        let mut tris: Vec<[Vec3; 3]> = mesh_triangles(&mesh).collect();
        tris.extend(quad(-2.0, 2.0, 0.0, 2.0, 0.0).map(|t| t.map(|p| Vec3::new(1.5, p.x, p.y))));
        let bounds = (Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.5, 2.0, 2.0));
        let model = Mat4::from_rotation_z(0.7) * Mat4::from_scale(Vec3::splat(1.5));
        (Occluders::new(tris), bounds, model)
    }

    #[test]
    fn the_transfer_recombines_the_map_each_sky_would_cast() {
        // A sphere resting on the ground beside a wall, turned and scaled (so that the rays'
        // world directions differ from the model's), with the product's texels and rays: the map
        // each sky makes from the kept rays against the map cast again under that sky
        // (ground_sky_direct, the same rays weighted by the same radiance).
        let (occ, bounds, model) = sphere_beside_a_wall();
        let transfer = ground_transfer(&occ, bounds, model, GROUND_TEXELS, GROUND_RAYS, &polynomials);
        let max_diff = |c: &[f32; TERMS]| {
            let direct = ground_sky_direct(&occ, bounds, model, GROUND_TEXELS, GROUND_RAYS, &|d| radiance(c, d));
            let map = transfer.map(&|azimuth, z| [radiance(c, world_direction(azimuth, z)); 3], &BounceLight::NONE);
            assert_eq!((map.min, map.max, map.z, map.size), (direct.min, direct.max, direct.z, direct.size));
            map.visibility.iter().zip(&direct.visibility).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max)
        };
        // Skies ≥ 0.2 over the whole hemisphere: the same sums, each ray's direction kept to
        // 1/65536 turn and 1/32767 of z; the uniform sky exactly.
        let positive = [[1.0, 0.6, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.4, 0.0, 0.0, 0.0, 0.3, 0.0, 0.4]];
        for c in &positive {
            let d = max_diff(c);
            assert!(d < 1e-5, "{c:?}: {d}");
        }
        assert_eq!(max_diff(&UNIFORM), 0.0);
        // The map is not trivial: the sky is hidden under the sphere and at the foot of the wall.
        let plain = transfer.map(&|_, _| [1.0; 3], &BounceLight::NONE).visibility;
        assert!(plain.iter().copied().fold(1.0, f32::min) < 0.1);
        assert!(transfer.texels.iter().zip(&plain).all(|(t, v)| (t.plain - v).abs() < 1e-5));
    }

    #[test]
    fn a_floating_sphere_reflects_its_configuration_factor_onto_the_ground() {
        // A sphere of radius R = 1 with its centre h = 2 above z = 0, lit so that every surface
        // element reflects the ground's own light (a uniform light, albedo 1, the gain 1 in
        // polynomials' constant term), sends a ground point the configuration factor of a
        // horizontal element to a sphere wholly above its plane, F = (R/D)² cos β with D the
        // distance to the centre and β the angle from the element's normal (Howell's catalog of
        // radiation configuration factors: a sphere wholly above a tilted differential area).
        let mut mesh = sphere(1.0, 48, 96);
        for p in &mut mesh.positions {
            p[2] += 2.0;
        }
        let mut occ = Occluders::new(mesh_triangles(&mesh).collect());
        let mut constant = [[0.0; 3]; TERMS];
        constant[0] = [1.0; 3];
        let sky = BounceLight { sky: constant, ..BounceLight::NONE };
        // A sun straight above, as strong on a surface facing it as on the ground.
        let sun = BounceLight { sun: [1.0; 3], sun_dir: [0.0, 0.0, 1.0], ..BounceLight::NONE };
        let factor = |x: f32| {
            let d2 = x * x + 4.0;
            (1.0 / d2) * (2.0 / d2.sqrt())
        };
        for x in [0.0f32, 1.0, 2.0, 3.5] {
            let t = occ.transfer((Vec3::new(x, 0.0, 0.0), Vec3::Z), 4096, 7, Mat4::IDENTITY, polynomials);
            let f = factor(x);
            // Open surfaces (no shares attached).
            let got = t.reflected(&sky);
            assert!(got.iter().all(|g| (g - f).abs() < 0.004 + 0.02 * f), "x = {x}: {got:?} against F = {f}");
            // The sphere hides exactly what it reflects here: the blocked share is F too.
            assert!((1.0 - t.plain - f).abs() < 0.004 + 0.02 * f, "{} {f}", t.plain);
        }
        // Lit by a sun straight above (a surface facing n reflects max(n_z, 0)): the cap a point
        // under the sphere sees faces down, so no sunlight comes back, exactly. A sun in the
        // East lights the sphere's eastern half: per unit of F, a point 3 East of the centre's
        // foot sees 0.71 of it lit, the point under it 0.13 (a numpy Monte-Carlo of the same
        // sphere, 400k rays each: 0.712 and 0.132).
        let under = occ.transfer((Vec3::ZERO, Vec3::Z), 1024, 7, Mat4::IDENTITY, polynomials);
        assert_eq!(under.reflected(&sun), [0.0; 3]);
        let east = BounceLight { sun: [1.0; 3], sun_dir: [1.0, 0.0, 0.0], ..BounceLight::NONE };
        let beside = occ.transfer((Vec3::new(3.0, 0.0, 0.0), Vec3::Z), 1024, 7, Mat4::IDENTITY, polynomials);
        let (beside, under_east) = (beside.reflected(&east)[0] / factor(3.0), under.reflected(&east)[0] / factor(0.0));
        assert!((beside - 0.712).abs() < 0.03 && (under_east - 0.132).abs() < 0.02, "{beside} {under_east}");
        // The same cap lit by the ground below (E/π = (1 − n_z)/2, between 1/2 and 1 on a cap
        // facing down) reflects between F/2 and F.
        let ground = BounceLight { ground: [[0.0; 3], [1.0; 3]], ..BounceLight::NONE };
        let g = under.reflected(&ground)[0];
        assert!(g > 0.5 * factor(0.0) && g <= factor(0.0) * 1.02, "{g}");
        // Surfaces that get a share of the light: the sky's part scales by sky + bounce shares
        // (0.5 + 0.1), the ground's by its own (0.75 + 0.1); the sun's stays (the default
        // material: the mean albedo, a ratio of 1).
        let shares = vec![VertexLight { ao: [0.5, 0.25, 0.75, 0.1], bent: [0.0; 3] }; mesh.positions.len()];
        let model = Model { meshes: vec![mesh], materials: vec![crate::scene::Material::default()] };
        occ.attach_light_shares(&model, &[shares]);
        let shared = occ.transfer((Vec3::ZERO, Vec3::Z), 1024, 7, Mat4::IDENTITY, polynomials);
        let scaled = |a: [f32; 3], b: [f32; 3], k: f32| a.iter().zip(b).all(|(a, b)| (a - k * b).abs() < 1e-5);
        assert!(scaled(shared.reflected(&sky), under.reflected(&sky), 0.6), "{:?} {:?}", shared.reflected(&sky), under.reflected(&sky));
        assert!(scaled(shared.reflected(&ground), under.reflected(&ground), 0.85));
        assert!(scaled(shared.reflected(&east), under.reflected(&east), 1.0));
        // The ground map carries it per texel in colour (under the sphere: the sky's part, 0.6 of
        // F = 0.25 with the shares attached above), and none when the model reflects nothing.
        let bounds = (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 3.0));
        let transfer = ground_transfer(&occ, bounds, Mat4::IDENTITY, 9, 1024, &polynomials);
        let mut tinted = BounceLight::NONE;
        tinted.sky[0] = [0.5, 1.0, 0.25];
        let map = transfer.map(&|_, _| [1.0; 3], &tinted);
        let centre = map.bounce[4 * 9 + 4];
        assert!((centre[1] - 0.15).abs() < 0.006 && (centre[0] - 0.5 * centre[1]).abs() < 1e-6, "{centre:?}");
        assert!(transfer.map(&|_, _| [1.0; 3], &BounceLight::NONE).bounce.is_empty());
    }

    #[test]
    fn the_mean_albedo_weighs_each_material_by_its_area() {
        use crate::scene::{Material, Rgba8Image};
        // Mesh 0: a 1×1 quad of diffuse 0.8 grey; mesh 1: a 3×1 quad (three times the area) of
        // white under a texture whose texels are sRGB 255 and 0 in red (mean linear 0.5), 188
        // in green (sRGB 188 = linear 0.5029, IEC 61966-2-1) and 0 in blue.
        let quad_mesh = |w: f32, material: usize| Mesh {
            positions: vec![[0.0, 0.0, 0.0], [w, 0.0, 0.0], [w, 1.0, 0.0], [0.0, 1.0, 0.0]],
            indices: vec![0, 1, 2, 0, 2, 3],
            material,
            ..Default::default()
        };
        let texture = Rgba8Image { width: 2, height: 1, pixels: vec![255, 188, 0, 255, 0, 188, 0, 255] };
        let white = Material { diffuse: [1.0; 3], texture: Some(texture), ..Default::default() };
        let model = Model { meshes: vec![quad_mesh(1.0, 0), quad_mesh(3.0, 1)], materials: vec![Material::default(), white] };
        let a = mean_albedo(&model);
        let want = [(0.8 + 3.0 * 0.5) / 4.0, (0.8 + 3.0 * 0.502_886) / 4.0, 0.8 / 4.0];
        assert!(a.iter().zip(want).all(|(a, w)| (a - w).abs() < 1e-4), "{a:?} {want:?}");
    }

    #[test]
    fn multi_bounce_adds_the_light_the_occluders_reflect() {
        for i in 0..=20 {
            let ao = i as f32 / 20.0;
            // Black occluders reflect nothing: plain AO (the fit stays below it at albedo 0).
            assert_eq!(multi_bounce(ao, 0.0), ao);
            // An open point stays open whatever the albedo (the fit's a + b + c = 1 ± 0.001).
            assert!((multi_bounce(1.0, ao) - 1.0).abs() < 1e-3);
            // Brighter surroundings give back more light.
            assert!(multi_bounce(ao, 0.8) >= multi_bounce(ao, 0.4) && multi_bounce(ao, 0.4) >= ao);
        }
    }

    #[test]
    fn a_wall_hides_the_light_of_the_sky_behind_it() {
        // A wall 0.01 East of the origin, 200 wide and 100 tall, hides every direction with
        // x > 0 (up to 0.006° from the zenith): half of the cosine-weighted sky. A sky that
        // shines only from the East is hidden whole, one that shines only from the West not at
        // all. A sky of radiance 1 + x (x = sinθ cosφ) keeps, by hand,
        // ∫ (1 + x) cosθ dω over x < 0 / ∫ over the hemisphere = (π/2 − 2/3) / π = 0.288.
        let (x, lo, hi) = (0.01, -100.0, 100.0);
        let a = Vec3::new(x, lo, 0.0);
        let b = Vec3::new(x, hi, 0.0);
        let c = Vec3::new(x, hi, 100.0);
        let d = Vec3::new(x, lo, 100.0);
        let occ = Occluders::new(vec![[a, b, c], [a, c, d]]);
        let rays = 4096;
        let uniform = occ.visibility(Vec3::ZERO, Vec3::Z, rays, 3);
        assert!((uniform - 0.5).abs() < 0.01, "{uniform}");
        assert_eq!(occ.weighted_visibility(Vec3::ZERO, Vec3::Z, rays, 3, |_| 1.0), uniform);
        let east = occ.weighted_visibility(Vec3::ZERO, Vec3::Z, rays, 3, |d| d.x.max(0.0));
        let west = occ.weighted_visibility(Vec3::ZERO, Vec3::Z, rays, 3, |d| (-d.x).max(0.0));
        assert!(east < 0.005 && west > 0.995, "{east} {west}");
        let tilted = occ.weighted_visibility(Vec3::ZERO, Vec3::Z, rays, 3, |d| 1.0 + d.x);
        let want = (std::f32::consts::FRAC_PI_2 - 2.0 / 3.0) / std::f32::consts::PI;
        assert!((tilted - want).abs() < 0.01, "{tilted} vs {want}");
        // No light along any ray: the plain visibility.
        assert_eq!(occ.weighted_visibility(Vec3::ZERO, Vec3::Z, rays, 3, |_| 0.0), uniform);
    }

    #[test]
    fn nine_harmonics_smear_the_light_a_wall_hides_and_the_rays_keep_it() {
        // The wall of a_wall_hides_the_light_of_the_sky_behind_it hides every direction with
        // x > 0. Under a sky of radiance 0.1 with a glow of 1 low in the East (x > 0, z < 0.2: a
        // sunrise), the origin keeps, by hand, the West's ∫ L cos θ dω = 0.1 π/2 of the
        // hemisphere's 0.1 π/2 + (π/2 − π/50) 0.1 + π/50 (the East's band: ∫ z dω over half the
        // azimuths and 0 < z < 0.2 is π · 0.2² / 2) = 0.424. The rays weighted by that radiance
        // say so; its nine-harmonic projection (what weighted the ground's rays before) spreads
        // the glow over the hemisphere, rings, and is off by a tenth: measured 0.315.
        let (x, lo, hi) = (0.01, -100.0, 100.0);
        let (a, b, c, d) = (Vec3::new(x, lo, 0.0), Vec3::new(x, hi, 0.0), Vec3::new(x, hi, 100.0), Vec3::new(x, lo, 100.0));
        let occ = Occluders::new(vec![[a, b, c], [a, c, d]]);
        let glow = |d: Vec3| {
            if d.z <= 0.0 {
                0.0
            } else if d.x > 0.0 && d.z < 0.2 {
                1.0
            } else {
                0.1
            }
        };
        let t = occ.transfer((Vec3::ZERO, Vec3::Z), 1024, 3, Mat4::IDENTITY, crate::light::sh9::basis);
        let weighted = t.weighted_visibility(&|azimuth, z| glow(Vec3::new(azimuth.sin() * (1.0 - z * z).sqrt(), 0.0, z)));
        let pi = std::f32::consts::PI;
        let want = 0.1 * pi / 2.0 / (0.1 * pi / 2.0 + 0.1 * (pi / 2.0 - pi / 50.0) + pi / 50.0);
        assert!((weighted - want).abs() < 0.01, "{weighted} vs {want}");
        // The glow's SH9 coefficients over the upper hemisphere (a midpoint rule in z and azimuth).
        let mut coeffs = [0.0f32; TERMS];
        let (nz, na) = (200, 400);
        for i in 0..nz {
            for j in 0..na {
                let z = (i as f32 + 0.5) / nz as f32;
                let phi = TAU * (j as f32 + 0.5) / na as f32;
                let r = (1.0 - z * z).sqrt();
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let w = glow(d) * TAU / (nz * na) as f32;
                coeffs.iter_mut().zip(crate::light::sh9::basis(d)).for_each(|(c, y)| *c += w * y);
            }
        }
        // The same rays weighted by that projection (clamped at 0 where it rings below).
        let sh = |d: Vec3| crate::light::sh9::basis(d).iter().zip(coeffs).map(|(y, c)| y * c).sum::<f32>();
        let smeared = occ.weighted_visibility(Vec3::ZERO, Vec3::Z, 1024, 3, sh);
        assert!((smeared - want).abs() > 0.05, "{smeared} vs {want}");
        // The same rays weighted by a sky without light: the plain visibility (half).
        assert_eq!(t.weighted_visibility(&|_, _| 0.0), t.plain);
        assert!((t.plain - 0.5).abs() < 0.01, "{}", t.plain);
    }

    #[test]
    fn a_wall_that_hides_a_warm_glow_leaves_each_channel_its_own_share() {
        // The wall of nine_harmonics_smear_the_light_a_wall_hides_and_the_rays_keep_it hides
        // x > 0, where a warm glow g = (1, 0.5, 0.25) lies low (0 < z < 0.2) in a blue sky
        // b = (0.05, 0.1, 0.2). By hand each channel keeps the West's b π/2 of
        // b π/2 + b (π/2 − π/50) + g π/50: red 0.05 / 0.138 = 0.362, green 0.1 / 0.216 = 0.463,
        // blue 0.2 / 0.402 = 0.498, where the luminance alone would give every channel one share.
        let (x, lo, hi) = (0.01, -100.0, 100.0);
        let (a, b, c, d) = (Vec3::new(x, lo, 0.0), Vec3::new(x, hi, 0.0), Vec3::new(x, hi, 100.0), Vec3::new(x, lo, 100.0));
        let occ = Occluders::new(vec![[a, b, c], [a, c, d]]);
        let (glow, blue) = ([1.0f32, 0.5, 0.25], [0.05f32, 0.1, 0.2]);
        let sky = |azimuth: f32, z: f32| {
            if z <= 0.0 {
                [0.0; 3]
            } else if azimuth.sin() > 0.0 && z < 0.2 {
                glow
            } else {
                blue
            }
        };
        let t = occ.transfer((Vec3::ZERO, Vec3::Z), 1024, 3, Mat4::IDENTITY, crate::light::sh9::basis);
        let got = t.weighted_visibility_rgb(&sky);
        let pi = std::f32::consts::PI;
        for c in 0..3 {
            let want = blue[c] * pi / 2.0 / (blue[c] * pi / 2.0 + blue[c] * (pi / 2.0 - pi / 50.0) + glow[c] * pi / 50.0);
            assert!((got[c] - want).abs() < 0.01, "channel {c}: {got:?} vs {want}");
        }
        // The ground map made from it holds the same per texel, and the luminance-weighted share
        // between red's and blue's.
        let transfer = GroundTransfer { min: Vec2::ZERO, max: Vec2::ONE, z: 0.0, size: 1, texels: vec![t] };
        let map = transfer.map(&sky, &BounceLight::NONE);
        assert_eq!(map.channels(0), got);
        assert!(got[0] < map.visibility[0] && map.visibility[0] < got[2], "{got:?} {:?}", map.visibility);
    }

    /// BounceReach::bound bounds the largest change of the model's light on any texel and channel
    /// (Transfer::reflected, computed for both lights) when the sun turns, brightens or goes,
    /// and when the sky's or the ground's terms change; nothing changed, it is 0.
    #[test]
    fn the_bounce_reach_bounds_how_far_two_lights_maps_differ() {
        let (occ, bounds, model) = sphere_beside_a_wall();
        let transfer = ground_transfer(&occ, bounds, model, 17, 64, &polynomials);
        let reach = BounceReach::of(&transfer.texels);
        assert!(reach.sun > 0.0 && reach.sky.iter().all(|&m| m > 0.0) && reach.ground.iter().all(|&m| m > 0.0), "{reach:?}");
        let s = Vec3::new(0.5, -0.3, 0.8).normalize();
        let base = BounceLight {
            sky: std::array::from_fn(|k| [0.3, 0.25, 0.2].map(|v| v / (k + 1) as f32)),
            sun: [1.1, 1.0, 0.8],
            sun_dir: s.to_array(),
            ground: [[0.2, 0.2, 0.25], [0.1, 0.12, 0.1]],
        };
        let turned = |a: f32| {
            let mut l = base;
            l.sun_dir = (glam::Quat::from_rotation_z(a) * s).to_array();
            l
        };
        let changes = [
            turned(1e-4),
            turned(0.05),
            turned(1.5),
            BounceLight { sun: [1.3, 1.0, 0.6], ..base },
            BounceLight { sky: std::array::from_fn(|k| [0.3, 0.2, 0.1].map(|v| v / (k + 2) as f32)), ..base },
            BounceLight { ground: [[0.25, 0.2, 0.2], [0.0, 0.12, 0.3]], ..base },
            BounceLight::NONE,
        ];
        for other in changes {
            let moved = transfer
                .texels
                .iter()
                .flat_map(|t| {
                    let (x, y) = (t.reflected(&base), t.reflected(&other));
                    (0..3).map(move |c| (x[c] - y[c]).abs())
                })
                .fold(0.0f32, f32::max);
            let bound = reach.bound(&base, &other);
            assert!(moved > 0.0 && moved <= bound * (1.0 + 1e-5), "{other:?}: moved {moved}, bound {bound}");
        }
        assert_eq!(reach.bound(&base, &base), 0.0);
        // A turn of 1e-4 rad (the sun's motion over 24 s) moves it by at most the sun's weights
        // times its brightest channel times the turn.
        let tiny = reach.bound(&base, &turned(1e-4));
        assert!(tiny <= reach.sun * 1.1 * 1e-4 * 1.001, "{tiny} {reach:?}");
    }

    #[test]
    fn the_nearest_hit_is_the_one_every_triangle_tried_in_turn_gives() {
        // The sphere beside a wall (2,306 triangles): from 20,000 points in and around its
        // bounds in pseudo-random directions, the hierarchy's nearest hit (its boxes visited
        // nearer first) against trying every triangle (the nearest, of equal ones the lowest
        // index).
        let (occ, (lo, hi), _) = sphere_beside_a_wall();
        let brute = |o: Vec3, d: Vec3| {
            let mut best: Option<(f32, usize)> = None;
            for i in 0..occ.triangle_count() {
                let t = triangle_distance(&occ.triangle(i).unwrap(), o, d, f32::INFINITY);
                if let Some(t) = t.filter(|&t| best.is_none_or(|(b, _)| t < b)) {
                    best = Some((t, i));
                }
            }
            best
        };
        let (lo, hi) = (lo - Vec3::ONE, hi + Vec3::ONE);
        let mut hits = 0;
        for k in 0..20_000u32 {
            let o = lo + (hi - lo) * Vec3::new(unit_hash(3 * k), unit_hash(3 * k + 1), unit_hash(3 * k + 2));
            let d = Vec3::new(unit_hash(k ^ 0xabcdef), unit_hash(k ^ 0x123457), unit_hash(k ^ 0x777777)) - 0.5;
            let want = brute(o, d);
            assert_eq!(occ.nearest_triangle(o, d), want, "from {o} along {d}");
            hits += usize::from(want.is_some());
        }
        assert!(hits > 2_000, "{hits}");
        // A ray down the edge two triangles share meets both at the same distance: the lower
        // index, from either side of the hierarchy.
        let square = Occluders::new(quad(-1.0, 1.0, -1.0, 1.0, 0.5).to_vec());
        let (o, d) = (Vec3::new(0.0, 0.0, 2.0), -Vec3::Z);
        let both: Vec<f32> = (0..2).filter_map(|i| triangle_distance(&square.triangle(i).unwrap(), o, d, f32::INFINITY)).collect();
        assert_eq!(both, [1.5, 1.5]);
        assert_eq!(square.nearest_triangle(o, d), Some((1.5, 0)));
    }

    #[test]
    fn a_binned_skys_map_is_the_one_its_radiance_function_gives_to_the_bit() {
        // The sphere beside a wall, turned and scaled, with the product's texels and rays: the
        // map `under` a binned sky (bins and tints varying from bin to bin, one row dark) at
        // several headings, against `map` asking the sky's at_rgb for every ray; and a sky with
        // no light anywhere, whose texels keep their plain visibility.
        let (occ, bounds, model) = sphere_beside_a_wall();
        let transfer = ground_transfer(&occ, bounds, model, GROUND_TEXELS, GROUND_RAYS, &polynomials);
        let mut sky = SkyRadiance::UNIFORM;
        for b in 0..SKY_BINS {
            sky.bins[b] = if b / SKY_COLUMNS == 3 { 0.0 } else { (4.0 * unit_hash(b as u32) * 32.0).round() / 32.0 };
            sky.tint[b] = [0.6 + unit_hash(3 * b as u32 + 1), 1.0, 1.4 - unit_hash(3 * b as u32 + 2)].map(|c| (c * 32.0).round() / 32.0);
        }
        let bounce = BounceLight { sky: [[0.3, 0.2, 0.1]; TERMS], sun: [2.0, 1.8, 1.5], sun_dir: [0.6, 0.0, 0.8], ground: [[0.1; 3]; 2] };
        let dark = SkyRadiance { bins: [0.0; SKY_BINS], ..SkyRadiance::UNIFORM };
        for (sky, heading, bounce) in [
            (sky, 0.0, BounceLight::NONE),
            (sky, 1.234, bounce),
            (sky, -2.5, bounce),
            (sky, TAU + 0.3, BounceLight::NONE),
            (SkyRadiance::UNIFORM, 0.7, bounce),
            (dark, 0.0, BounceLight::NONE),
        ] {
            let fast = transfer.under(&sky, heading, &bounce);
            let each_ray = transfer.map(&|azimuth, z| sky.at_rgb(azimuth, z, heading), &bounce);
            assert_eq!(fast, each_ray, "heading {heading}");
        }
        // Not trivially equal: the sky's shape and its heading move texels.
        let moved =
            |a: &GroundSky, b: &GroundSky| a.visibility.iter().zip(&b.visibility).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
        let (north, turned, uniform) = (
            transfer.under(&sky, 0.0, &BounceLight::NONE),
            transfer.under(&sky, 2.0, &BounceLight::NONE),
            transfer.under(&SkyRadiance::UNIFORM, 0.0, &BounceLight::NONE),
        );
        assert!(moved(&north, &turned) > 0.05 && moved(&north, &uniform) > 0.05, "{} {}", moved(&north, &turned), moved(&north, &uniform));
        let plain: Vec<f32> = transfer.texels.iter().map(|t| t.plain).collect();
        assert_eq!(transfer.under(&dark, 0.0, &BounceLight::NONE).visibility, plain);
    }

    #[test]
    fn a_transfer_weighs_its_rays_by_any_sky_as_casting_them_again_would() {
        // The sphere beside a wall of the_transfer_recombines_the_map_each_sky_would_cast, turned
        // and scaled, under a sky no nine harmonics hold (a lobe exp(20 (d·g − 1)), ~18° wide,
        // round g 10° above the East-North-East horizon, over a dim uniform sky): the map from the
        // kept rays against the map cast again with the same radiance (ground_sky_direct). The
        // rays keep their directions to 1/65536 turn and 1/32768 of z.
        let (occ, bounds, model) = sphere_beside_a_wall();
        let transfer = ground_transfer(&occ, bounds, model, GROUND_TEXELS, 64, &polynomials);
        let g = Vec3::new(
            70f32.to_radians().sin() * 10f32.to_radians().cos(),
            70f32.to_radians().cos() * 10f32.to_radians().cos(),
            10f32.to_radians().sin(),
        );
        let lobe = |d: Vec3| 0.1 + 20.0 * (20.0 * (d.dot(g) - 1.0)).exp();
        let glow = |azimuth: f32, z: f32| lobe(Vec3::new(azimuth.sin() * (1.0 - z * z).sqrt(), azimuth.cos() * (1.0 - z * z).sqrt(), z));
        let map = transfer.map(&|azimuth, z| [glow(azimuth, z); 3], &BounceLight::NONE);
        let direct = ground_sky_direct(&occ, bounds, model, GROUND_TEXELS, 64, &lobe);
        assert_eq!((map.min, map.max, map.z, map.size), (direct.min, direct.max, direct.z, direct.size));
        let diff = map.visibility.iter().zip(&direct.visibility).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        // Measured: 7.0e-5.
        assert!(diff < 2e-4, "{diff}");
        // The sky matters: against the uniform sky's map, texels move by more than 0.1.
        let plain = transfer.map(&|_, _| [1.0; 3], &BounceLight::NONE);
        let moved = map.visibility.iter().zip(&plain.visibility).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(moved > 0.1, "{moved}");
        // A ray keeps its direction to within its quantisation: 1/65536 turn and 1/32768 of z,
        // read at the step's middle; at the zenith z = 1 − 1/65536, √(2/65536) = 0.0055 rad off.
        for (d, bound) in
            [(Vec3::new(0.3, -0.5, 0.81), 1e-3), (Vec3::new(-0.9, 0.1, 0.42), 1e-3), (Vec3::new(0.0, -1.0, 0.0), 1e-3), (Vec3::Z, 0.0056)]
        {
            let d = d.normalize();
            let r = SkyRay::new(d, true);
            let (azimuth, z) = r.direction();
            let back = Vec3::new(azimuth.sin() * (1.0 - z * z).sqrt(), azimuth.cos() * (1.0 - z * z).sqrt(), z);
            assert!((back - d).length() < bound && r.open() && !SkyRay::new(d, false).open(), "{d} → {back}");
        }
        // A ray stays in its row of the sky, and in its column at a heading of 0, at the edges.
        for k in 1..SKY_ROWS {
            let z = k as f32 / SKY_ROWS as f32;
            for (dz, row) in [(-1e-6, k - 1), (0.0, k), (1e-6, k)] {
                let r = SkyRay::new(Vec3::new(0.0, (1.0 - (z + dz).powi(2)).sqrt(), z + dz), true);
                assert_eq!((r.direction().1 * SKY_ROWS as f32) as usize, row, "z {}", z + dz);
            }
        }
    }

    #[test]
    fn an_empty_occluder_set_blocks_nothing() {
        let occ = Occluders::new(Vec::new());
        assert_eq!(occ.visibility(Vec3::ZERO, Vec3::Z, 16, 0), 1.0);
        assert!(!occ.blocked(Vec3::ZERO, Vec3::X, f32::INFINITY));
    }
}
