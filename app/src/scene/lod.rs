//! Level of detail: every mesh simplified once, at load, into a chain of levels, and the level
//! a frame draws chosen from the screen.
//!
//! The simplifier is a quadric-error-metric edge collapser (Garland & Heckbert 1997, "Surface
//! simplification using quadric error metrics", SIGGRAPH) in the shape of meshoptimizer's
//! `meshopt_simplify`: vertices only collapse onto a neighbour (no new vertices, so every level
//! indexes the mesh's one vertex buffer), collapses run in passes sorted by cost, and each
//! vertex is classified so that the mesh keeps its shape where it matters:
//!
//! - **border** vertices (on an edge with one triangle) only slide along the border, and border
//!   edges carry an extra quadric (a plane through the edge, perpendicular to the face) so a
//!   curved border costs error while a straight one does not;
//! - **seam** vertices (one position, two vertices with different UVs) only slide along the
//!   seam, both copies together, so texture charts stay closed;
//! - anything else irregular (non-manifold edges, seam ends, corners where borders and seams
//!   meet) is **locked**.
//!
//! A collapse is also refused when it would flip a triangle or break the link condition (the
//! two vertices share exactly the neighbours of their common triangles). The error of a level is
//! the largest collapse cost spent to reach it: the RMS distance, in model units, from the
//! kept vertex to the planes of the original triangles it now stands for.
//!
//! Normals are not a seam: vertices at one position with one UV are welded before simplifying
//! (a crease-split or computed normal would otherwise pin every split vertex, and the 100k
//! dragon stopped at 11k triangles). Each corner of a simplified triangle then takes, among the
//! mesh's vertices at its position and UV, the one whose normal is closest to the triangle's
//! face normal, so hard edges that survive keep their split normals.
//!
//! Level choice: [`select_level`] takes the coarsest level whose error, projected at the
//! model's distance, stays under half a pixel; [`finest_worth_drawing`] then draws the finest of
//! those levels whose triangles are not too small on screen to cost their setup, since larger
//! triangles than that save no time (a rasteriser pays per fragment block plus per triangle)
//! while the finer level keeps the model's shading normals as loaded.

pub mod order;

use super::{Mesh, Model};
use glam::{DVec3, Vec3};
use std::collections::HashMap;

/// One level of a mesh: a range of [`MeshLods::indices`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexRange {
    pub first: u32,
    pub count: u32,
}

/// The levels of one mesh, all in one index list (level 0 = the mesh as loaded), so a renderer
/// uploads one index buffer and switching level allocates nothing. Each level's triangles are
/// in draw order ([`order::draw_order`]: vertex reuse, then the outward-facing first).
#[derive(Clone, Debug, Default)]
pub struct MeshLods {
    pub indices: Vec<u32>,
    pub levels: Vec<IndexRange>,
    /// Per level, whether its triangles form closed surfaces ([`is_closed`]): their back faces
    /// are hidden from a camera outside them, so a renderer may cull them.
    pub closed: Vec<bool>,
}

/// The level chain of a model. Every mesh has the same number of levels; a mesh that could not
/// be simplified further repeats its last one.
#[derive(Clone, Debug, Default)]
pub struct LodChain {
    /// Per level, the simplification error in model units (level 0: 0), non-decreasing.
    pub errors: Vec<f32>,
    /// Per level, the model's triangle count.
    pub triangles: Vec<usize>,
    /// Per mesh of the model, in order.
    pub meshes: Vec<MeshLods>,
}

/// Each level aims at this fraction of the triangles of the level before.
pub const LEVEL_RATIO: f64 = 0.5;
/// No level goes below this many triangles per mesh.
pub const MIN_LEVEL_TRIANGLES: usize = 64;
/// Projected error allowed on screen, pixels (the "under half a pixel").
pub const MAX_SCREEN_ERROR_PX: f32 = 0.5;
/// The smallest projected area per triangle, px² (the model's bounding sphere's disc over the
/// level's triangle count), at which a level is drawn rather than a coarser one within
/// [`MAX_SCREEN_ERROR_PX`]: below it a frame's cost grows with the triangle count, above it
/// fewer triangles save nothing measurable (docs/PERFORMANCE.md, tenth session).
pub const MIN_TRIANGLE_AREA_PX: f32 = 2.0;
/// The same for a still image, which has no frame budget: every triangle of a pixel or more.
/// Against the path-traced references (sh9-ggx, `previz bench accuracy`, release, 2026-12-02,
/// docs/accuracy.md "Thirteenth session"): ROI FLIP mean 0.0694 at 2 px², 0.0654 at 1, 0.065
/// at 0.5 and 0.0648 at 0.25 (one 4× MSAA sample), the path tracer at equal error 28×, 27×, 25×
/// and 23× slower: below a pixel the dense scans' triangles cost lavapipe more than they show.
/// A supersampled still (render::supersample) counts its samples as pixels: 1 px² of the drawn
/// frame; counting output pixels instead cost quarry_bunny's 3 × 3 still 0.061 → 0.064 of ROI
/// FLIP (docs/accuracy.md, "Fourteenth session").
pub const STILL_MIN_TRIANGLE_AREA_PX: f32 = 1.0;

impl LodChain {
    /// Simplify every mesh of `model` into levels of halving triangle count, down to
    /// [`MIN_LEVEL_TRIANGLES`] or until a mesh stops shrinking.
    pub fn build(model: &Model) -> LodChain {
        let per_mesh: Vec<Vec<(Vec<u32>, f32)>> = model.meshes.iter().map(simplify_chain).collect();
        let levels = per_mesh.iter().map(Vec::len).max().unwrap_or(1);
        let mut chain = LodChain { errors: vec![0.0; levels], triangles: vec![0; levels], meshes: Vec::new() };
        for (mesh, chain_of_mesh) in model.meshes.iter().zip(&per_mesh) {
            let mut lods = MeshLods::default();
            let welded = position_ids(&mesh.positions);
            let ordered: Vec<Vec<u32>> = chain_of_mesh.iter().map(|(indices, _)| order::draw_order(&mesh.positions, indices)).collect();
            for (level, err) in chain.errors.iter_mut().enumerate() {
                let at = level.min(chain_of_mesh.len() - 1);
                *err = err.max(chain_of_mesh[at].1);
                let indices = &ordered[at];
                lods.levels.push(IndexRange { first: lods.indices.len() as u32, count: indices.len() as u32 });
                lods.indices.extend_from_slice(indices);
                lods.closed.push(is_closed(&welded, indices));
            }
            for (t, r) in chain.triangles.iter_mut().zip(&lods.levels) {
                *t += r.count as usize / 3;
            }
            chain.meshes.push(lods);
        }
        chain
    }

    /// The number of levels (1 when nothing could be simplified).
    pub fn len(&self) -> usize {
        self.errors.len()
    }

    /// True for the chain of a model without meshes.
    pub fn is_empty(&self) -> bool {
        self.meshes.is_empty()
    }
}

/// The pinhole focal length in pixels for a vertical field of view over `height_px` rows.
pub fn focal_px(fov_y_rad: f32, height_px: u32) -> f32 {
    height_px as f32 / (2.0 * (0.5 * fov_y_rad).tan())
}

/// The coarsest level whose error, seen from `distance` (world units) with a focal length of
/// `focal_px` pixels, projects to less than `max_px` pixels. `errors` are in world units and
/// non-decreasing (level 0 first). A distance that is not positive (the camera inside the
/// model's bounds) selects level 0.
pub fn select_level(errors: &[f32], distance: f32, focal_px: f32, max_px: f32) -> usize {
    if distance.is_nan() || distance <= 0.0 {
        return 0;
    }
    errors.iter().rposition(|&e| e * focal_px / distance < max_px).unwrap_or(0)
}

/// The area in pixels of the disc that a sphere of `radius` whose centre is `distance` away
/// projects to through a pinhole of focal length `focal_px` (tangent cone of half-angle θ,
/// sin θ = r / d, disc radius f·tan θ). Infinite when the camera is inside the sphere.
pub fn sphere_area_px(radius: f32, distance: f32, focal_px: f32) -> f32 {
    let slant = distance * distance - radius * radius;
    if distance.is_nan() || slant <= 0.0 {
        return f32::INFINITY;
    }
    let r = focal_px * radius / slant.sqrt();
    std::f32::consts::PI * r * r
}

/// Among levels `0..=coarsest` (those within the error allowed, [`select_level`]), the finest
/// whose triangles cover at least `min_area_px` each of the model's projected `area_px`, or
/// `coarsest` when none does. `triangles` per level, non-increasing (level 0 first).
pub fn finest_worth_drawing(triangles: &[usize], coarsest: usize, area_px: f32, min_area_px: f32) -> usize {
    let within = triangles.iter().take(coarsest.saturating_add(1));
    within.clone().position(|&t| area_px >= t as f32 * min_area_px).unwrap_or(within.count().saturating_sub(1))
}

/// Per vertex, an id shared by the vertices at the same position (bit for bit).
pub fn position_ids(positions: &[[f32; 3]]) -> Vec<u32> {
    let mut ids = std::collections::HashMap::new();
    positions
        .iter()
        .map(|p| {
            let next = ids.len() as u32;
            *ids.entry(p.map(f32::to_bits)).or_insert(next)
        })
        .collect()
}

/// Whether `indices` (triangles over vertices with position ids `welded`, [`position_ids`])
/// form closed surfaces wound one way: every edge between two positions is used exactly once in
/// each direction (triangles with two corners at one position have no area and are left out).
/// Seen from outside such a surface, every back face lies behind a front face, so culling the
/// back faces changes no pixel.
pub fn is_closed(welded: &[u32], indices: &[u32]) -> bool {
    let mut edges = std::collections::HashMap::new();
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| welded[t[k] as usize]);
        if a == b || b == c || c == a {
            continue;
        }
        for edge in [(a, b), (b, c), (c, a)] {
            *edges.entry(edge).or_insert(0u32) += 1;
        }
    }
    !edges.is_empty() && edges.iter().all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}

/// The distance from `point` to the nearest point of the axis-aligned box `(min, max)`; 0 when
/// the point is inside it. Every vertex of a model lies in its bounding box, so no vertex is
/// nearer than this to a camera at `point` (the box is nearer the surface than the bounding
/// sphere, whose nearest point the rule used before: a tighter bound, still never too coarse).
pub fn box_distance(point: Vec3, (lo, hi): (Vec3, Vec3)) -> f32 {
    (lo - point).max(point - hi).max(Vec3::ZERO).length()
}

/// Simplify `mesh` into a chain: level 0 is the mesh as it is, each next level aims at
/// [`LEVEL_RATIO`] of the one before; returns (indices, error) per level.
pub fn simplify_chain(mesh: &Mesh) -> Vec<(Vec<u32>, f32)> {
    let mut out = vec![(mesh.indices.clone(), 0.0)];
    let mut s = Simplifier::new(mesh);
    loop {
        let have = s.indices.len() / 3;
        let target = ((have as f64 * LEVEL_RATIO) as usize).max(MIN_LEVEL_TRIANGLES);
        if have <= MIN_LEVEL_TRIANGLES {
            break;
        }
        s.run(target, f32::INFINITY);
        // A level that saved less than a fifth of the triangles is not worth a switch.
        if s.indices.len() / 3 > have * 4 / 5 {
            break;
        }
        out.push((s.output(), s.error()));
    }
    out
}

/// Simplify `mesh` to at most `target_triangles` triangles, spending no collapse whose error
/// exceeds `max_error` (model units). Returns the new indices (into the mesh's vertices) and
/// the error reached.
pub fn simplify(mesh: &Mesh, target_triangles: usize, max_error: f32) -> (Vec<u32>, f32) {
    let mut s = Simplifier::new(mesh);
    s.run(target_triangles, max_error);
    (s.output(), s.error())
}

/// A plane quadric: error(x) = xᵀAx + 2bᵀx + c, weighted (w = total weight).
#[derive(Clone, Copy, Debug, Default)]
struct Quadric {
    a: [f64; 6], // a00 a01 a02 a11 a12 a22
    b: [f64; 3],
    c: f64,
    w: f64,
}

impl Quadric {
    /// The plane n·x + d = 0 (n unit) with weight w.
    fn plane(n: DVec3, d: f64, w: f64) -> Quadric {
        Quadric {
            a: [n.x * n.x * w, n.x * n.y * w, n.x * n.z * w, n.y * n.y * w, n.y * n.z * w, n.z * n.z * w],
            b: [n.x * d * w, n.y * d * w, n.z * d * w],
            c: d * d * w,
            w,
        }
    }

    fn add(&mut self, o: &Quadric) {
        for i in 0..6 {
            self.a[i] += o.a[i];
        }
        for i in 0..3 {
            self.b[i] += o.b[i];
        }
        self.c += o.c;
        self.w += o.w;
    }

    /// Weighted mean squared distance of `p` to the quadric's planes.
    fn error(&self, p: DVec3) -> f64 {
        if self.w <= 0.0 {
            return 0.0;
        }
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let ax = DVec3::new(a00 * p.x + a01 * p.y + a02 * p.z, a01 * p.x + a11 * p.y + a12 * p.z, a02 * p.x + a12 * p.y + a22 * p.z);
        let r = p.dot(ax) + 2.0 * DVec3::from_array(self.b).dot(p) + self.c;
        r.max(0.0) / self.w
    }
}

/// Border edges weigh this much more than faces (meshoptimizer's kEdgeWeight is 10 too).
const EDGE_WEIGHT: f64 = 10.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Manifold,
    Border,
    Seam,
    Locked,
}

struct Simplifier {
    /// Position of each vertex.
    pos: Vec<DVec3>,
    /// Normal of each vertex (zero when the mesh has none).
    normals: Vec<Vec3>,
    /// Welded vertex (position and UV) -> the mesh's vertices there, in CSR form: the vertices
    /// of `w` are `weld_verts[weld_start[w]..weld_start[w + 1]]`; `weld_of` maps back.
    weld_start: Vec<u32>,
    weld_verts: Vec<u32>,
    weld_of: Vec<u32>,
    /// Vertex -> position id (vertices at the same position share one).
    pos_id: Vec<u32>,
    /// Current triangles (vertex indices).
    indices: Vec<u32>,
    /// Position of each position id (collapses only move onto existing positions).
    id_pos: Vec<DVec3>,
    /// Accumulated quadric per position id.
    quadrics: Vec<Quadric>,
    /// Largest squared error spent so far.
    max_cost: f64,
}

/// Per pass: what each undirected position edge looks like.
#[derive(Clone, Copy, Debug)]
struct EdgeInfo {
    /// Triangles using the edge (in either direction).
    count: u32,
    /// The (vertex at lower pos id, vertex at higher pos id) pair of the first triangle.
    verts: (u32, u32),
    /// Set when another triangle uses the edge with a different vertex pair.
    seam: bool,
}

impl Simplifier {
    fn new(mesh: &Mesh) -> Simplifier {
        let pos: Vec<DVec3> = mesh.positions.iter().map(|p| Vec3::from_array(*p).as_dvec3()).collect();
        let mut ids: HashMap<[u32; 3], u32> = HashMap::with_capacity(pos.len());
        // +0.0 and -0.0 are one value.
        let bits = |c: f32| if c == 0.0 { 0 } else { c.to_bits() };
        let pos_id: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let next = ids.len() as u32;
                *ids.entry(p.map(bits)).or_insert(next)
            })
            .collect();
        // Weld by position and UV: the first vertex of each (position, UV) stands for all.
        let mut reps: HashMap<(u32, [u32; 2]), u32> = HashMap::with_capacity(pos.len());
        let rep: Vec<u32> = (0..pos.len())
            .map(|v| {
                let uv = mesh.uvs.get(v).copied().unwrap_or_default().map(bits);
                *reps.entry((pos_id[v], uv)).or_insert(v as u32)
            })
            .collect();
        let mut weld_id = vec![u32::MAX; pos.len()];
        let mut nweld = 0u32;
        let weld_of: Vec<u32> = rep
            .iter()
            .map(|&r| {
                if weld_id[r as usize] == u32::MAX {
                    weld_id[r as usize] = nweld;
                    nweld += 1;
                }
                weld_id[r as usize]
            })
            .collect();
        let mut weld_start = vec![0u32; nweld as usize + 1];
        for &w in &weld_of {
            weld_start[w as usize + 1] += 1;
        }
        for i in 0..nweld as usize {
            weld_start[i + 1] += weld_start[i];
        }
        let mut fill = weld_start.clone();
        let mut weld_verts = vec![0u32; pos.len()];
        for (v, &w) in weld_of.iter().enumerate() {
            weld_verts[fill[w as usize] as usize] = v as u32;
            fill[w as usize] += 1;
        }
        let normals: Vec<Vec3> = (0..pos.len()).map(|v| mesh.normals.get(v).map_or(Vec3::ZERO, |n| Vec3::from_array(*n))).collect();
        let mut quadrics = vec![Quadric::default(); ids.len()];
        let mut id_pos = vec![DVec3::ZERO; ids.len()];
        for (v, &p) in pos_id.iter().enumerate() {
            id_pos[p as usize] = pos[v];
        }
        let indices: Vec<u32> = mesh
            .indices
            .chunks_exact(3)
            .filter(|t| distinct(pos_id[t[0] as usize], pos_id[t[1] as usize], pos_id[t[2] as usize]))
            .flatten()
            .map(|&v| rep[v as usize])
            .collect();
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| pos[i as usize]);
            let n = (b - a).cross(c - a);
            let area2 = n.length();
            if area2 > 0.0 {
                let n = n / area2;
                let q = Quadric::plane(n, -n.dot(a), 0.5 * area2);
                for &v in t {
                    quadrics[pos_id[v as usize] as usize].add(&q);
                }
            }
        }
        let mut s = Simplifier { pos, normals, weld_start, weld_verts, weld_of, pos_id, indices, id_pos, quadrics, max_cost: 0.0 };
        s.add_edge_quadrics();
        s
    }

    /// The current triangles in the mesh's vertices: each corner the vertex at its position and
    /// UV whose normal is closest to the triangle's face normal.
    fn output(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.indices.len());
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|v| self.pos[v as usize]);
            let n = (b - a).cross(c - a).as_vec3().normalize_or_zero();
            out.extend(t.iter().map(|&v| {
                let w = self.weld_of[v as usize] as usize;
                let verts = &self.weld_verts[self.weld_start[w] as usize..self.weld_start[w + 1] as usize];
                // Ties (one vertex, or no normals) keep the first, which is the weld's own.
                verts
                    .iter()
                    .copied()
                    .fold((v, f32::NEG_INFINITY), |best, u| {
                        let d = self.normals[u as usize].dot(n);
                        if d > best.1 { (u, d) } else { best }
                    })
                    .0
            }));
        }
        out
    }

    fn error(&self) -> f32 {
        self.max_cost.sqrt() as f32
    }

    fn p(&self, v: u32) -> u32 {
        self.pos_id[v as usize]
    }

    fn edges(&self) -> HashMap<(u32, u32), EdgeInfo> {
        let mut edges: HashMap<(u32, u32), EdgeInfo> = HashMap::with_capacity(self.indices.len());
        for t in self.indices.chunks_exact(3) {
            for k in 0..3 {
                let (va, vb) = (t[k], t[(k + 1) % 3]);
                let (pa, pb) = (self.p(va), self.p(vb));
                let (key, verts) = if pa < pb { ((pa, pb), (va, vb)) } else { ((pb, pa), (vb, va)) };
                edges
                    .entry(key)
                    .and_modify(|e| {
                        e.count += 1;
                        e.seam |= e.verts != verts;
                    })
                    .or_insert(EdgeInfo { count: 1, verts, seam: false });
            }
        }
        edges
    }

    /// Border and seam edges get a plane through the edge, perpendicular to their triangle.
    fn add_edge_quadrics(&mut self) {
        let edges = self.edges();
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| self.pos[i as usize]);
            let Some(n) = (b - a).cross(c - a).try_normalize() else { continue };
            for k in 0..3 {
                let (va, vb) = (t[k], t[(k + 1) % 3]);
                let (pa, pb) = (self.pos_id[va as usize], self.pos_id[vb as usize]);
                let e = edges[&(pa.min(pb), pa.max(pb))];
                if e.count == 1 || e.seam {
                    let (p0, p1) = (self.pos[va as usize], self.pos[vb as usize]);
                    let d = p1 - p0;
                    let Some(en) = d.cross(n).try_normalize() else { continue };
                    let q = Quadric::plane(en, -en.dot(p0), EDGE_WEIGHT * d.length_squared());
                    self.quadrics[pa as usize].add(&q);
                    self.quadrics[pb as usize].add(&q);
                }
            }
        }
    }

    /// Collapse passes until at most `target` triangles remain, the next collapse would cost
    /// more than `max_error`, or nothing can collapse.
    fn run(&mut self, target: usize, max_error: f32) {
        let max_cost = if max_error.is_finite() { (max_error as f64).powi(2) } else { f64::INFINITY };
        while self.indices.len() / 3 > target {
            if !self.pass(target, max_cost) {
                break;
            }
        }
    }

    /// One pass of collapses; false when none was made.
    fn pass(&mut self, target: usize, max_cost: f64) -> bool {
        let npos = self.quadrics.len();
        let edges = self.edges();
        let tri_count = self.indices.len() / 3;
        // Position -> triangles (CSR).
        let mut start = vec![0u32; npos + 1];
        for &v in &self.indices {
            start[self.p(v) as usize + 1] += 1;
        }
        for i in 0..npos {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut tris = vec![0u32; self.indices.len()];
        for (t, tri) in self.indices.chunks_exact(3).enumerate() {
            for &v in tri {
                let p = self.p(v) as usize;
                tris[fill[p] as usize] = t as u32;
                fill[p] += 1;
            }
        }
        let tris_of = |p: u32| &tris[start[p as usize] as usize..start[p as usize + 1] as usize];

        // Classify positions.
        let mut border = vec![0u8; npos];
        let mut seam = vec![0u8; npos];
        let mut locked = vec![false; npos];
        for (&(a, b), e) in &edges {
            if e.count > 2 {
                locked[a as usize] = true;
                locked[b as usize] = true;
            } else if e.count == 1 {
                border[a as usize] = border[a as usize].saturating_add(1);
                border[b as usize] = border[b as usize].saturating_add(1);
            } else if e.seam {
                seam[a as usize] = seam[a as usize].saturating_add(1);
                seam[b as usize] = seam[b as usize].saturating_add(1);
            }
        }
        let mut verts_at: Vec<[u32; 3]> = vec![[u32::MAX; 3]; npos];
        let mut nverts = vec![0u8; npos];
        for &v in &self.indices {
            let p = self.p(v) as usize;
            let n = nverts[p] as usize;
            if !verts_at[p][..n.min(3)].contains(&v) {
                if n < 3 {
                    verts_at[p][n] = v;
                }
                nverts[p] = nverts[p].saturating_add(1);
            }
        }
        let kind: Vec<Kind> = (0..npos)
            .map(|p| match (locked[p], border[p], seam[p], nverts[p]) {
                (true, ..) => Kind::Locked,
                (false, 0, 0, 1) => Kind::Manifold,
                (false, 2, 0, 1) => Kind::Border,
                (false, 0, 2, 2) => Kind::Seam,
                _ => Kind::Locked,
            })
            .collect();

        // Candidate collapses: (cost, from, to), the cheaper allowed direction of each edge.
        let mut cands: Vec<(f64, u32, u32)> = Vec::with_capacity(edges.len());
        for (&(a, b), e) in &edges {
            let allowed = |from: u32| match kind[from as usize] {
                Kind::Manifold => true,
                Kind::Border => e.count == 1,
                Kind::Seam => e.seam,
                Kind::Locked => false,
            };
            let cost = |from: u32, to: u32| self.quadrics[from as usize].error(self.pos_of(to));
            let ab = allowed(a).then(|| cost(a, b));
            let ba = allowed(b).then(|| cost(b, a));
            match (ab, ba) {
                (Some(x), Some(y)) if y < x => cands.push((y, b, a)),
                (Some(x), _) => cands.push((x, a, b)),
                (None, Some(y)) => cands.push((y, b, a)),
                (None, None) => {}
            }
        }
        // Ties broken by vertex ids: the edge map's iteration order differs from run to run, the
        // result must not.
        cands.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let goal = (tri_count - target).div_ceil(2);
        let pass_limit = if goal < cands.len() { 1.5 * cands[goal].0 } else { f64::INFINITY };

        let mut busy = vec![false; npos];
        let mut remap: Vec<u32> = (0..self.pos.len() as u32).collect();
        let mut removed = 0usize;
        let mut collapsed = false;
        for &(cost, from, to) in &cands {
            if cost > max_cost || cost > pass_limit || tri_count - removed <= target {
                break;
            }
            if busy[from as usize] || busy[to as usize] {
                continue;
            }
            // Link condition: the common neighbours are exactly the far corners of the shared triangles.
            let shared = tris_of(from).iter().filter(|t| self.tri_has(**t, to)).count();
            let nbrs = |p: u32| {
                let mut n: Vec<u32> = tris_of(p).iter().flat_map(|&t| self.tri_pos(t)).filter(|&q| q != p).collect();
                n.sort_unstable();
                n.dedup();
                n
            };
            let (nf, nt) = (nbrs(from), nbrs(to));
            let common = nf.iter().filter(|q| nt.binary_search(q).is_ok()).count();
            if common != shared || self.flips(tris_of(from), from, to) {
                continue;
            }
            // Vertex mapping: each vertex at `from` goes to the vertex at `to` it shares a triangle with.
            let mut map: [(u32, u32); 2] = [(u32::MAX, u32::MAX); 2];
            let n_from = nverts[from as usize] as usize;
            let mut ok = true;
            for &t in tris_of(from) {
                if !self.tri_has(t, to) {
                    continue;
                }
                let tri = &self.indices[3 * t as usize..3 * t as usize + 3];
                let vf = *tri.iter().find(|&&v| self.p(v) == from).unwrap();
                let vt = *tri.iter().find(|&&v| self.p(v) == to).unwrap();
                let slot = verts_at[from as usize][..n_from].iter().position(|&v| v == vf).unwrap();
                if map[slot].0 == u32::MAX {
                    map[slot] = (vf, vt);
                } else if map[slot].1 != vt {
                    ok = false;
                }
            }
            if !ok || map[..n_from].iter().any(|m| m.0 == u32::MAX) || (n_from == 2 && map[0].1 == map[1].1) {
                continue;
            }
            for &(vf, vt) in &map[..n_from] {
                remap[vf as usize] = vt;
            }
            let q = self.quadrics[from as usize];
            self.quadrics[to as usize].add(&q);
            self.max_cost = self.max_cost.max(cost);
            removed += shared;
            collapsed = true;
            busy[from as usize] = true;
            busy[to as usize] = true;
            for n in nf {
                busy[n as usize] = true;
            }
        }
        if collapsed {
            let mut out = Vec::with_capacity(self.indices.len());
            for t in self.indices.chunks_exact(3) {
                let r = [t[0], t[1], t[2]].map(|v| remap[v as usize]);
                if distinct(self.p(r[0]), self.p(r[1]), self.p(r[2])) {
                    out.extend_from_slice(&r);
                }
            }
            self.indices = out;
        }
        collapsed
    }

    /// The position of position id `p`.
    fn pos_of(&self, p: u32) -> DVec3 {
        self.id_pos[p as usize]
    }

    fn tri_pos(&self, t: u32) -> [u32; 3] {
        let i = 3 * t as usize;
        [self.p(self.indices[i]), self.p(self.indices[i + 1]), self.p(self.indices[i + 2])]
    }

    fn tri_has(&self, t: u32, p: u32) -> bool {
        self.tri_pos(t).contains(&p)
    }

    /// Would moving `from` onto `to` flip (or nearly flip) one of `from`'s surviving triangles?
    fn flips(&self, tris: &[u32], from: u32, to: u32) -> bool {
        let target = self.pos_of(to);
        tris.iter().any(|&t| {
            let ps = self.tri_pos(t);
            if ps.contains(&to) {
                return false;
            }
            let before = ps.map(|p| self.pos_of(p));
            let after = ps.map(|p| if p == from { target } else { self.pos_of(p) });
            let n0 = (before[1] - before[0]).cross(before[2] - before[0]);
            let n1 = (after[1] - after[0]).cross(after[2] - after[0]);
            n0.dot(n1) < 0.25 * n0.length() * n1.length()
        })
    }
}

fn distinct(a: u32, b: u32, c: u32) -> bool {
    a != b && b != c && a != c
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    /// An n×n-quad grid over [x0, x0 + w] × [0, 1] in the z = 0 plane, UVs from `uv0`.
    fn grid(n: usize, x0: f32, w: f32, uv0: f32) -> Mesh {
        let mut m = Mesh::default();
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                m.positions.push([x0 + w * u, v, 0.0]);
                m.normals.push([0.0, 0.0, 1.0]);
                m.uvs.push([uv0 + 0.5 * u, v]);
            }
        }
        let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        for j in 0..n {
            for i in 0..n {
                m.indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        m
    }

    fn append(a: &mut Mesh, b: &Mesh) {
        let base = a.positions.len() as u32;
        a.positions.extend(&b.positions);
        a.normals.extend(&b.normals);
        a.uvs.extend(&b.uvs);
        a.indices.extend(b.indices.iter().map(|i| i + base));
    }

    /// The undirected edges used by exactly one triangle, as position pairs.
    fn border_edges(positions: &[[f32; 3]], indices: &[u32]) -> HashSet<[[u32; 3]; 2]> {
        let mut count: HashMap<[[u32; 3]; 2], u32> = HashMap::new();
        for t in indices.chunks_exact(3) {
            for k in 0..3 {
                let [a, b] = [t[k], t[(k + 1) % 3]].map(|i| positions[i as usize].map(f32::to_bits));
                *count.entry(if a < b { [a, b] } else { [b, a] }).or_default() += 1;
            }
        }
        count.into_iter().filter(|(_, c)| *c == 1).map(|(e, _)| e).collect()
    }

    #[test]
    fn a_subdivided_plane_collapses_to_two_triangles_with_zero_error() {
        let m = grid(8, 0.0, 1.0, 0.0);
        let (indices, err) = simplify(&m, 1, 1e-6);
        assert_eq!(indices.len(), 6, "{indices:?}");
        assert_eq!(err, 0.0);
        let corners: HashSet<[u32; 3]> = indices.iter().map(|&i| m.positions[i as usize].map(f32::to_bits)).collect();
        let expect: HashSet<[u32; 3]> =
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]].map(|p: [f32; 3]| p.map(f32::to_bits)).into();
        assert_eq!(corners, expect);
    }

    #[test]
    fn a_uv_seam_stays_closed_and_each_triangle_keeps_its_chart() {
        // Two charts meet along x = 1: the seam's vertices are duplicated with different UVs
        // (u = 0.5 on chart 0's side, 0.6 on chart 1's).
        let mut m = grid(6, 0.0, 1.0, 0.0);
        append(&mut m, &grid(6, 1.0, 1.0, 0.6));
        let (indices, err) = simplify(&m, 1, 1e-6);
        assert_eq!(err, 0.0);
        // Zero-error limit: each chart is a rectangle, two triangles each.
        assert_eq!(indices.len() / 3, 4);
        for t in indices.chunks_exact(3) {
            // Chart 0 has u in [0, 0.5] and x in [0, 1]; chart 1 u in [0.6, 1.1], x in [1, 2].
            let chart: HashSet<bool> = t.iter().map(|&i| (i as usize) >= 49).collect();
            assert_eq!(chart.len(), 1, "a triangle mixes vertices of both charts: {t:?}");
        }
        // The seam (1,0)-(1,1) is an edge of both charts, so it is no border: the border is the
        // 2×1 rectangle's outline, two edges along each long side and one at each end.
        assert_eq!(border_edges(&m.positions, &indices).len(), 6, "the seam opened or moved");
    }

    #[test]
    fn a_curved_border_is_kept_while_the_flat_interior_collapses() {
        // A flat disc: 4 rings of 32 vertices around a centre. The interior is coplanar (free to
        // collapse); the outer ring is a circle (moving a border vertex costs error).
        let (rings, seg) = (4, 32);
        let mut m = Mesh::default();
        m.positions.push([0.0; 3]);
        for r in 1..=rings {
            for s in 0..seg {
                let a = std::f32::consts::TAU * s as f32 / seg as f32;
                let rad = r as f32 / rings as f32;
                m.positions.push([rad * a.cos(), rad * a.sin(), 0.0]);
            }
        }
        let at = |r: usize, s: usize| if r == 0 { 0 } else { (1 + (r - 1) * seg + s % seg) as u32 };
        for s in 0..seg {
            m.indices.extend([at(0, 0), at(1, s), at(1, s + 1)]);
            for r in 1..rings {
                m.indices.extend([at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
            }
        }
        m.normals = vec![[0.0, 0.0, 1.0]; m.positions.len()];
        m.uvs = vec![[0.0; 2]; m.positions.len()];
        let before = border_edges(&m.positions, &m.indices);
        assert_eq!(before.len(), seg);
        let (indices, err) = simplify(&m, 1, 1e-4);
        assert!(err < 1e-6, "only zero-error collapses fit under the limit, got {err}");
        assert_eq!(border_edges(&m.positions, &indices), before, "the circular border changed");
        // A 32-gon triangulated with no interior vertex has 30 triangles.
        assert_eq!(indices.len() / 3, seg - 2);
    }

    /// A unit icosphere: the icosahedron with each triangle split in four `levels` times.
    pub(crate) fn icosphere(levels: u32) -> Mesh {
        let t = (1.0 + 5f32.sqrt()) / 2.0;
        let mut pos: Vec<Vec3> = [[-1.0, t, 0.0], [1.0, t, 0.0], [-1.0, -t, 0.0], [1.0, -t, 0.0], [0.0, -1.0, t], [0.0, 1.0, t]]
            .into_iter()
            .chain([[0.0, -1.0, -t], [0.0, 1.0, -t], [t, 0.0, -1.0], [t, 0.0, 1.0], [-t, 0.0, -1.0], [-t, 0.0, 1.0]])
            .map(|p| Vec3::from_array(p).normalize())
            .collect();
        let mut tris: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut split = |a: u32, b: u32, pos: &mut Vec<Vec3>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    pos.push((pos[a as usize] + pos[b as usize]).normalize());
                    pos.len() as u32 - 1
                })
            };
            tris = tris
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (split(a, b, &mut pos), split(b, c, &mut pos), split(c, a, &mut pos));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        let positions: Vec<[f32; 3]> = pos.iter().map(|p| p.to_array()).collect();
        Mesh { normals: positions.clone(), uvs: vec![[0.0; 2]; positions.len()], positions, indices: tris.concat(), material: 0 }
    }

    #[test]
    fn closed_surfaces_are_found_by_their_edges() {
        // An icosphere is closed; one triangle fewer leaves a hole; one triangle turned over is
        // wound against its neighbours; a flat grid has a border.
        let sphere = icosphere(2);
        let welded = position_ids(&sphere.positions);
        assert!(is_closed(&welded, &sphere.indices));
        assert!(!is_closed(&welded, &sphere.indices[3..]));
        let mut turned = sphere.indices.clone();
        turned.swap(0, 1);
        assert!(!is_closed(&welded, &turned));
        let grid = grid(4, 0.0, 1.0, 0.0);
        assert!(!is_closed(&position_ids(&grid.positions), &grid.indices));
        // Split vertices (a flat-shaded cube: 24 vertices, 8 positions) are welded by position.
        let corners: Vec<[f32; 3]> = (0..8).map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let positions: Vec<[f32; 3]> = quads.iter().flat_map(|q| q.map(|c| corners[c])).collect();
        let indices: Vec<u32> = (0..6u32).flat_map(|f| [0, 1, 2, 0, 2, 3].map(|k| 4 * f + k)).collect();
        assert!(is_closed(&position_ids(&positions), &indices));
        // The chain notes it per level: the sphere's levels stay closed.
        let chain = LodChain::build(&Model { meshes: vec![icosphere(4)], materials: vec![Default::default()] });
        assert!(chain.meshes[0].closed.iter().all(|&c| c), "{:?}", chain.meshes[0].closed);
    }

    #[test]
    fn box_distance_is_to_the_nearest_face_edge_or_corner() {
        let unit = (Vec3::ZERO, Vec3::ONE);
        // By hand: beyond a face, an edge and a corner; inside and on the surface, 0.
        assert_eq!(box_distance(Vec3::new(0.5, 0.5, 3.0), unit), 2.0);
        assert_eq!(box_distance(Vec3::new(2.0, 3.0, 0.5), unit), 5f32.sqrt());
        assert_eq!(box_distance(Vec3::new(-1.0, -2.0, 3.0), unit), 3.0);
        assert_eq!(box_distance(Vec3::splat(0.5), unit), 0.0);
        assert_eq!(box_distance(Vec3::new(1.0, 0.5, 0.0), unit), 0.0);
    }

    #[test]
    fn sphere_error_bounds_the_distance_to_the_analytic_sphere() {
        let m = icosphere(4);
        assert_eq!(m.indices.len() / 3, 5120);
        for target in [1280, 320, 80] {
            let (indices, err) = simplify(&m, target, f32::INFINITY);
            let n = indices.len() / 3;
            assert!(n <= target && n >= target * 3 / 4, "{n} triangles for a target of {target}");
            // Every kept vertex lies on the sphere; the worst deviation is inside the triangles.
            // Sample each triangle's centroid and edge midpoints against the unit radius.
            let p = |i: u32| Vec3::from_array(m.positions[i as usize]);
            let deviation = indices
                .chunks_exact(3)
                .flat_map(|t| {
                    let [a, b, c] = [p(t[0]), p(t[1]), p(t[2])];
                    [(a + b + c) / 3.0, (a + b) / 2.0, (b + c) / 2.0, (c + a) / 2.0]
                })
                .map(|q| 1.0 - q.length())
                .fold(0.0f32, f32::max);
            // The reported error is an RMS distance to the original planes: the worst sampled
            // deviation lies between it and twice it (measured 1.33-1.53x at these targets).
            assert!(err > 0.0 && deviation >= err && deviation <= 2.0 * err, "{n} triangles: error {err}, deviation {deviation}");
            // Against the best case, N equilateral triangles of equal area on the unit sphere:
            // side s = sqrt(16π / (√3 N)), circumradius s/√3, centroid depth 1 - sqrt(1 - s²/3)
            // (measured 2.2-2.9x it).
            let s2 = 16.0 * std::f32::consts::PI / (3f32.sqrt() * n as f32);
            let ideal = 1.0 - (1.0 - s2 / 3.0).sqrt();
            assert!(deviation <= 4.0 * ideal, "{n} triangles: deviation {deviation} vs ideal {ideal} (measured 2.2-2.9x)");
        }
    }

    #[test]
    fn the_chain_halves_the_triangles_and_its_error_grows() {
        let model = Model { meshes: vec![icosphere(4), grid(8, 0.0, 1.0, 0.0)], materials: vec![Default::default()] };
        let chain = LodChain::build(&model);
        assert_eq!(chain.triangles[0], 5120 + 128);
        assert!(chain.len() >= 5, "{:?}", chain.triangles);
        for w in chain.errors.windows(2) {
            assert!(w[1] >= w[0], "errors must not decrease: {:?}", chain.errors);
        }
        for (lods, mesh) in chain.meshes.iter().zip(&model.meshes) {
            assert_eq!(lods.levels.len(), chain.len());
            let sorted = |indices: &[u32]| {
                let mut t: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
                t.sort();
                t
            };
            // In draw order ([`order::draw_order`]), each triangle with its corners as loaded.
            assert_eq!(sorted(&lods.indices[..mesh.indices.len()]), sorted(&mesh.indices), "level 0 is the mesh as loaded");
            for r in &lods.levels {
                assert!((r.first + r.count) as usize <= lods.indices.len());
                assert!(lods.indices[r.first as usize..][..r.count as usize].iter().all(|&i| (i as usize) < mesh.positions.len()));
            }
        }
        // The sphere halves level by level (within the pass granularity).
        let sphere = &chain.meshes[0].levels;
        for w in sphere.windows(2).take(3) {
            let ratio = w[1].count as f64 / w[0].count as f64;
            assert!((0.35..=0.55).contains(&ratio), "level ratio {ratio}");
        }
    }

    #[test]
    fn split_normals_do_not_pin_vertices_and_corners_keep_their_face_normal() {
        // A flat-shaded sphere: every triangle has its own three vertices with its face normal
        // (each position split five or six ways). Welded by position it simplifies like the
        // smooth sphere; unwelded, every vertex would be a locked seam and nothing would move.
        let smooth = icosphere(3);
        let mut flat = smooth.clone();
        crate::scene::normals::compute_crease_normals(&mut flat, 0.0).unwrap();
        assert_eq!(flat.positions.len(), 3 * 1280);
        let (indices, _) = simplify(&flat, 160, f32::INFINITY);
        let n = indices.len() / 3;
        assert!((120..=160).contains(&n), "{n} triangles for a target of 160");
        // Each corner takes the split vertex whose normal is nearest the new face's normal:
        // on average within the angle between neighbouring faces of the original (~10°).
        let p = |i: u32| Vec3::from_array(flat.positions[i as usize]);
        // Without a choice, a corner would keep the first vertex at its position.
        let mut first: HashMap<[u32; 3], u32> = HashMap::new();
        for (i, q) in flat.positions.iter().enumerate() {
            first.entry(q.map(f32::to_bits)).or_insert(i as u32);
        }
        let (mut chosen, mut unchosen) = (Vec::new(), Vec::new());
        for t in indices.chunks_exact(3) {
            let f = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).normalize();
            let deg = |i: u32| Vec3::from_array(flat.normals[i as usize]).dot(f).clamp(-1.0, 1.0).acos().to_degrees();
            for &i in t {
                chosen.push(deg(i));
                unchosen.push(deg(first[&flat.positions[i as usize].map(f32::to_bits)]));
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let (c, u) = (mean(&chosen), mean(&unchosen));
        // A face of the 160-triangle sphere spans ~20°, so even its corners' nearest original
        // faces lie degrees off it; the first vertex at a position is any of five or six faces
        // (measured 11.5° chosen vs 16.4° first).
        assert!(c < 0.8 * u, "mean corner normal off its face: chosen {c}° vs first vertex {u}°");
    }

    #[test]
    fn the_level_is_the_coarsest_under_half_a_pixel() {
        // fov_y = 2 atan(1/2): tan(fov/2) = 1/2, so a 640-row image has a 640 px focal length.
        let f = focal_px(2.0 * 0.5f32.atan(), 640);
        assert!((f - 640.0).abs() < 1e-3, "{f}");
        let errors = [0.0, 0.001, 0.004, 0.02];
        // 2 m: level 1 projects to 0.001 * 640 / 2 = 0.32 px, level 2 to 1.28 px.
        assert_eq!(select_level(&errors, 2.0, f, 0.5), 1);
        // 10 m: level 2 is 0.256 px, level 3 is 1.28 px.
        assert_eq!(select_level(&errors, 10.0, f, 0.5), 2);
        // 30 m: level 3 is 0.43 px.
        assert_eq!(select_level(&errors, 30.0, f, 0.5), 3);
        // 1 m: level 1 is 0.64 px, so only the full mesh.
        assert_eq!(select_level(&errors, 1.0, f, 0.5), 0);
        // Inside the bounds, or nonsense: full detail.
        assert_eq!(select_level(&errors, 0.0, f, 0.5), 0);
        assert_eq!(select_level(&errors, f32::NAN, f, 0.5), 0);
    }

    #[test]
    fn the_finest_level_whose_triangles_cover_the_minimum() {
        // A 1 m sphere 2 m away seen with a 100 px focal length: sin θ = 1/2, tan θ = 1/√3, a
        // disc of radius 100/√3 px, area π·10000/3 = 10 472 px².
        let area = sphere_area_px(1.0, 2.0, 100.0);
        assert!((area - std::f32::consts::PI * 10000.0 / 3.0).abs() < 0.1, "{area}");
        assert_eq!(sphere_area_px(1.0, 0.5, 100.0), f32::INFINITY);
        assert_eq!(sphere_area_px(1.0, f32::NAN, 100.0), f32::INFINITY);
        let triangles = [8000, 4000, 2000, 1000];
        // 2 px² each: 10 472 / 2 = 5 236 triangles at most, level 1 (4 000), if the error allows it.
        assert_eq!(finest_worth_drawing(&triangles, 3, area, 2.0), 1);
        assert_eq!(finest_worth_drawing(&triangles, 1, area, 2.0), 1);
        // 1 px²: level 0's 8 000 fit.
        assert_eq!(finest_worth_drawing(&triangles, 3, area, 1.0), 0);
        // 6 px² (1 745 at most): level 3; with the error allowing only level 2, level 2.
        assert_eq!(finest_worth_drawing(&triangles, 3, area, 6.0), 3);
        assert_eq!(finest_worth_drawing(&triangles, 2, area, 6.0), 2);
        // Inside the sphere: level 0. A coarsest past the chain: the chain's last level; an
        // empty chain: 0.
        assert_eq!(finest_worth_drawing(&triangles, 3, f32::INFINITY, 2.0), 0);
        assert_eq!(finest_worth_drawing(&triangles, 9, 0.0, 2.0), 3);
        assert_eq!(finest_worth_drawing(&triangles, usize::MAX, 0.0, 2.0), 3);
        assert_eq!(finest_worth_drawing(&[], 2, area, 2.0), 0);
    }
}
