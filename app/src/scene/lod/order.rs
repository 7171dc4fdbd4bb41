//! The order a level's triangles are drawn in, computed once at load, and what it costs a
//! depth-tested raster.
//!
//! Sander, Nehab & Barczak 2007, "Fast Triangle Reordering for Vertex Locality and Reduced
//! Overdraw" (ACM TOG 26(3), SIGGRAPH), in the shape of meshoptimizer's
//! `meshopt_optimizeVertexCache` + `meshopt_optimizeOverdraw`: first **Tipsify** orders the
//! triangles for a vertex cache of [`CACHE_SIZE`] (fans around one vertex at a time); then the
//! order is cut into **clusters** (where the cache starts over, and wherever a cluster's running
//! cache misses per triangle reach [`OVERDRAW_THRESHOLD`] times its own) and the clusters are
//! sorted, most outward-facing first: the key is the dot product of the cluster's mean normal with
//! the vector from the mesh's centroid to the cluster's. Whatever the view, a surface facing out
//! from the middle of the mesh tends to lie in front of one facing in, so drawn first its depth
//! rejects the fragments behind it before they are shaded. The order is view-independent.
//!
//! [`overdraw`] measures it: a software raster of a draw (meshoptimizer's
//! `meshopt_analyzeOverdraw` counts the same from six axis views), fragments that pass the
//! depth test when drawn (what a GPU with early depth rejection shades) over pixels covered.

use glam::{Mat4, Vec3, Vec4Swizzles};

/// Vertices the simulated cache holds (meshoptimizer's `kCacheSizeMax` for overdraw is 16; the
/// post-transform caches Sander et al. target hold 12-24).
pub const CACHE_SIZE: u32 = 16;
/// How much worse than its own mean a cluster's cache misses may get before it is cut, 1.05 as
/// meshoptimizer's documentation recommends (5% more vertex work for a finer sort).
pub const OVERDRAW_THRESHOLD: f32 = 1.05;

/// `indices` (triangles over `positions`) in the order that draws them fastest whatever the
/// view: [`tipsify`] then [`sort_clusters`]. The same triangles, each with its corners in the same
/// cyclic order (so the same winding).
pub fn draw_order(positions: &[[f32; 3]], indices: &[u32]) -> Vec<u32> {
    sort_clusters(positions, &tipsify(indices, positions.len(), CACHE_SIZE), OVERDRAW_THRESHOLD)
}

/// Tipsify (Sander et al. 2007, Algorithm 1): emit every live triangle around a fanning vertex,
/// then fan around the candidate (a vertex of those triangles) that stays in a cache of
/// `cache` vertices longest, or, at a dead end, the most recent vertex with live triangles,
/// or the next in index order.
pub fn tipsify(indices: &[u32], vertex_count: usize, cache: u32) -> Vec<u32> {
    let triangles = indices.len() / 3;
    // Vertex -> its triangles (CSR).
    let mut start = vec![0u32; vertex_count + 1];
    for &v in &indices[..triangles * 3] {
        start[v as usize + 1] += 1;
    }
    for v in 0..vertex_count {
        start[v + 1] += start[v];
    }
    let mut live: Vec<u32> = (0..vertex_count).map(|v| start[v + 1] - start[v]).collect();
    let mut fill = start.clone();
    let mut adjacent = vec![0u32; triangles * 3];
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        for &v in tri {
            adjacent[fill[v as usize] as usize] = t as u32;
            fill[v as usize] += 1;
        }
    }
    let mut stamp = vec![0u32; vertex_count];
    let mut emitted = vec![false; triangles];
    let mut dead_ends: Vec<u32> = Vec::new();
    let mut out = Vec::with_capacity(triangles * 3);
    let (mut time, mut cursor) = (cache + 1, 0usize);
    let mut fan = (0..vertex_count).find(|&v| live[v] > 0);
    let mut candidates: Vec<u32> = Vec::new();
    while let Some(f) = fan {
        candidates.clear();
        for &t in &adjacent[start[f] as usize..start[f + 1] as usize] {
            if std::mem::replace(&mut emitted[t as usize], true) {
                continue;
            }
            for &v in &indices[t as usize * 3..t as usize * 3 + 3] {
                out.push(v);
                dead_ends.push(v);
                candidates.push(v);
                live[v as usize] -= 1;
                if time - stamp[v as usize] > cache {
                    stamp[v as usize] = time;
                    time += 1;
                }
            }
        }
        // The candidate still in the cache after its remaining fan, longest there.
        let mut best: Option<(u32, u32)> = None;
        for &v in &candidates {
            let v = v as usize;
            if live[v] == 0 {
                continue;
            }
            let age = time - stamp[v];
            let priority = if age + 2 * live[v] <= cache { age } else { 0 };
            if best.is_none_or(|(_, p)| priority > p) {
                best = Some((v as u32, priority));
            }
        }
        fan = match best {
            Some((v, _)) => Some(v as usize),
            None => {
                let mut next = None;
                while let Some(d) = dead_ends.pop() {
                    if live[d as usize] > 0 {
                        next = Some(d as usize);
                        break;
                    }
                }
                next.or_else(|| {
                    while cursor < vertex_count && live[cursor] == 0 {
                        cursor += 1;
                    }
                    (cursor < vertex_count).then_some(cursor)
                })
            }
        };
    }
    out
}

/// Add the corners of triangle (a, b, c) to a FIFO cache of [`CACHE_SIZE`] vertices held as the
/// time each entered (`stamp`, the clock `time`); returns the misses.
fn cache_misses(tri: &[u32], stamp: &mut [u32], time: &mut u32) -> u32 {
    let mut misses = 0;
    for &v in tri {
        if *time - stamp[v as usize] > CACHE_SIZE {
            stamp[v as usize] = *time;
            *time += 1;
            misses += 1;
        }
    }
    misses
}

/// Cut `indices` (ordered for the cache, e.g. by [`tipsify`]) into clusters and draw the
/// clusters most outward-facing first (module docs; meshoptimizer's `meshopt_optimizeOverdraw`
/// with `threshold`). Within a cluster the order is kept.
pub fn sort_clusters(positions: &[[f32; 3]], indices: &[u32], threshold: f32) -> Vec<u32> {
    let triangles = indices.len() / 3;
    if triangles == 0 {
        return Vec::new();
    }
    let tri = |t: usize| &indices[t * 3..t * 3 + 3];
    let mut stamp = vec![0u32; positions.len()];
    // Hard boundaries: a triangle with no corner in the cache starts a new patch.
    let mut time = CACHE_SIZE + 1;
    let hard: Vec<usize> = (0..triangles).filter(|&t| cache_misses(tri(t), &mut stamp, &mut time) == 3 || t == 0).collect();
    // Soft boundaries: within a patch, cut wherever the running misses per triangle fall to the
    // patch's own mean times the threshold; the last, incomplete cluster joins the one before.
    let mut starts = Vec::new();
    for (k, &first) in hard.iter().enumerate() {
        let end = hard.get(k + 1).copied().unwrap_or(triangles);
        time += CACHE_SIZE + 1;
        let misses: u32 = (first..end).map(|t| cache_misses(tri(t), &mut stamp, &mut time)).sum();
        let limit = threshold * misses as f32 / (end - first) as f32;
        starts.push(first);
        time += CACHE_SIZE + 1;
        let (mut run_misses, mut run_tris) = (0u32, 0u32);
        for t in first..end {
            run_misses += cache_misses(tri(t), &mut stamp, &mut time);
            run_tris += 1;
            if run_misses as f32 / run_tris as f32 <= limit {
                starts.push(t + 1);
                time += CACHE_SIZE + 1;
                (run_misses, run_tris) = (0, 0);
            }
        }
        if *starts.last().unwrap() != first {
            starts.pop();
        }
    }
    // Sort key per cluster: its area-weighted centroid, from the mesh's centroid, along its
    // mean normal.
    let p = |v: u32| Vec3::from_array(positions[v as usize]);
    let centroid = indices[..triangles * 3].iter().map(|&v| p(v)).sum::<Vec3>() / (triangles * 3) as f32;
    let mut clusters: Vec<(f32, usize, usize)> = starts
        .iter()
        .enumerate()
        .map(|(k, &first)| {
            let end = starts.get(k + 1).copied().unwrap_or(triangles);
            let (mut area, mut centre, mut normal) = (0.0f32, Vec3::ZERO, Vec3::ZERO);
            for t in first..end {
                let [a, b, c] = [0, 1, 2].map(|i| p(tri(t)[i]));
                let n = (b - a).cross(c - a);
                let twice_area = n.length();
                centre += (a + b + c) * (twice_area / 3.0);
                normal += n;
                area += twice_area;
            }
            let centre = if area > 0.0 { centre / area } else { centre };
            (normal.normalize_or_zero().dot(centre - centroid), first, end)
        })
        .collect();
    clusters.sort_by(|a, b| b.0.total_cmp(&a.0));
    clusters.iter().flat_map(|&(_, first, end)| indices[first * 3..end * 3].iter().copied()).collect()
}

/// Where in its pixel [`overdraw`] samples: the centre moved by different small fractions along
/// x and y.
const SAMPLE_OFFSET: [f32; 2] = [0.5 + 1.0 / 512.0, 0.5 + 1.0 / 384.0];

/// What a depth-tested draw of triangles costs in fragments ([`overdraw`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Overdraw {
    /// Pixels covered by at least one triangle.
    pub covered: u64,
    /// Fragments that passed the depth test when drawn: what is shaded.
    pub shaded: u64,
    /// Every fragment rasterised, the depth pre-pass's too.
    pub rasterised: u64,
    /// 2×2-pixel quads shaded: per triangle, the quads holding at least one of its shaded
    /// fragments. A GPU shades whole quads (the helper lanes give derivatives), so a triangle a
    /// few pixels across costs several quads' lanes.
    pub quads: u64,
    /// The same for 4×4-pixel blocks: lavapipe (llvmpipe) runs the fragment shader on a 4×4
    /// block at a time, masked.
    pub blocks: u64,
}

impl Overdraw {
    /// Fragments shaded per covered pixel (1: no hidden fragment shaded).
    pub fn ratio(&self) -> f64 {
        self.shaded as f64 / self.covered.max(1) as f64
    }
}

/// One mesh of a draw for [`overdraw`]: positions, triangles (drawn in this order), whether
/// back faces (clockwise on screen) are culled and whether its depth is drawn first, in a
/// pre-pass.
pub struct Draw<'a> {
    pub positions: &'a [[f32; 3]],
    pub indices: &'a [u32],
    pub cull: bool,
    pub prepass: bool,
}

/// Rasterise `draws` as the model pass does through `clip` (model to clip space, wgpu
/// conventions: depth 0..1, counter-clockwise fronts) at `width`×`height` pixels, one sample per
/// pixel, depth test less-or-equal: first the depth of the draws with a pre-pass, then every
/// draw in order, counting fragments. The sample sits a hair off the pixel's centre
/// ([`SAMPLE_OFFSET`]) so that it never lies on an edge of axis-aligned or diagonal test shapes
/// (no tie rule needed: a shared edge gives its pixels to one side). Triangles with a corner
/// behind the eye are skipped (a measurement of models in front of the camera).
pub fn overdraw(draws: &[Draw<'_>], clip: Mat4, (width, height): (u32, u32)) -> Overdraw {
    let (w, h) = (width as usize, height as usize);
    let mut depth = vec![f32::INFINITY; w * h];
    let mut out = Overdraw::default();
    // Screen positions (pixels, y down) and depth per vertex.
    let screen = |positions: &[[f32; 3]]| -> Vec<Option<Vec3>> {
        positions
            .iter()
            .map(|p| {
                let c = clip * Vec3::from_array(*p).extend(1.0);
                (c.w > 1e-6).then(|| {
                    let n = c.xyz() / c.w;
                    Vec3::new((n.x * 0.5 + 0.5) * width as f32, (0.5 - n.y * 0.5) * height as f32, n.z)
                })
            })
            .collect()
    };
    let projected: Vec<Vec<Option<Vec3>>> = draws.iter().map(|d| screen(d.positions)).collect();
    // Per quad and per block, the last triangle that shaded a fragment in it.
    let (qw, bw) = (w.div_ceil(2), w.div_ceil(4));
    let mut quad_seen = vec![usize::MAX; qw * h.div_ceil(2)];
    let mut block_seen = vec![usize::MAX; bw * h.div_ceil(4)];
    let mut first_triangle = 0;
    let prepass = draws.iter().zip(&projected).filter(|(d, _)| d.prepass);
    for (shading, (d, s)) in prepass.map(|x| (false, x)).chain(draws.iter().zip(&projected).map(|x| (true, x))) {
        raster(d, s, (w, h), |t, at, z| {
            out.rasterised += 1;
            let stored = &mut depth[at];
            if z <= *stored {
                *stored = z;
                if shading {
                    out.shaded += 1;
                    let (x, y) = (at % w, at / w);
                    let t = first_triangle + t;
                    for (seen, count, side, row) in [(&mut quad_seen, &mut out.quads, 2, qw), (&mut block_seen, &mut out.blocks, 4, bw)] {
                        let cell = &mut seen[y / side * row + x / side];
                        if *cell != t {
                            *cell = t;
                            *count += 1;
                        }
                    }
                }
            }
        });
        first_triangle += d.indices.len() / 3;
    }
    out.covered = depth.iter().filter(|z| z.is_finite()).count() as u64;
    out
}

/// Call `fragment(triangle, pixel index, depth)` for every fragment of `draw`'s triangles, whose
/// vertices are at `screen` (pixels, depth; None: behind the eye), on a `w`×`h` screen.
fn raster(draw: &Draw<'_>, screen: &[Option<Vec3>], (w, h): (usize, usize), mut fragment: impl FnMut(usize, usize, f32)) {
    for (k, t) in draw.indices.chunks_exact(3).enumerate() {
        let (Some(a), Some(b), Some(c)) = (screen[t[0] as usize], screen[t[1] as usize], screen[t[2] as usize]) else { continue };
        // Twice the signed area with y down: negative for counter-clockwise in NDC.
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area == 0.0 || (draw.cull && area > 0.0) {
            continue;
        }
        let x0 = (a.x.min(b.x).min(c.x) - 0.5).floor().max(0.0) as usize;
        let y0 = (a.y.min(b.y).min(c.y) - 0.5).floor().max(0.0) as usize;
        let x1 = ((a.x.max(b.x).max(c.x) - 0.5).ceil() as isize).min(w as isize - 1);
        let y1 = ((a.y.max(b.y).max(c.y) - 0.5).ceil() as isize).min(h as isize - 1);
        if x1 < x0 as isize || y1 < y0 as isize {
            continue;
        }
        let edge = |p: Vec3, q: Vec3, x: f32, y: f32| (q.x - p.x) * (y - p.y) - (q.y - p.y) * (x - p.x);
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let (px, py) = (x as f32 + SAMPLE_OFFSET[0], y as f32 + SAMPLE_OFFSET[1]);
                let (w0, w1, w2) = (edge(b, c, px, py) / area, edge(c, a, px, py) / area, edge(a, b, px, py) / area);
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                if (0.0..=1.0).contains(&z) {
                    fragment(k, y * w + x, z);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::lod::tests::icosphere;

    /// The triangles of `indices` as sets of corners in cyclic order (rotated to start at the
    /// smallest index), so a reorder that keeps every triangle and its winding compares equal.
    fn triangle_set(indices: &[u32]) -> Vec<[u32; 3]> {
        let mut v: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| {
                let k = (0..3).min_by_key(|&k| t[k]).unwrap();
                [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
            })
            .collect();
        v.sort();
        v
    }

    /// Average cache misses per triangle (ACMR) of `indices` in a FIFO cache of `CACHE_SIZE`.
    fn acmr(indices: &[u32], vertices: usize) -> f64 {
        let (mut stamp, mut time) = (vec![0u32; vertices], CACHE_SIZE + 1);
        let misses: u32 = indices.chunks_exact(3).map(|t| cache_misses(t, &mut stamp, &mut time)).sum();
        misses as f64 / (indices.len() / 3) as f64
    }

    /// A pseudo-random permutation of the triangles (a fixed LCG, no dependency).
    fn shuffled(indices: &[u32]) -> Vec<u32> {
        let mut tris: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let mut state = 0x2545_f491_u64;
        for i in (1..tris.len()).rev() {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            tris.swap(i, (state >> 33) as usize % (i + 1));
        }
        tris.concat()
    }

    #[test]
    fn tipsify_keeps_every_triangle_and_reaches_the_published_vertex_reuse() {
        // A regular grid's triangles in random order: every vertex but the border ones is shared
        // by six triangles, so the best any order can do is 0.5 misses per triangle (each vertex
        // loaded once, two triangles per vertex). Sander et al. 2007 (Table 1) report Tipsify
        // within ~0.65-0.75 ACMR on regular meshes for caches of 12-24 entries.
        let n = 64u32;
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let grid: Vec<u32> = (0..n)
            .flat_map(|j| (0..n).flat_map(move |i| [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)]))
            .collect();
        let vertices = ((n + 1) * (n + 1)) as usize;
        let random = shuffled(&grid);
        let ordered = tipsify(&random, vertices, CACHE_SIZE);
        assert_eq!(triangle_set(&ordered), triangle_set(&grid));
        let (before, after) = (acmr(&random, vertices), acmr(&ordered, vertices));
        assert!(before > 2.0, "a random order misses nearly every corner: {before}");
        assert!(after < 0.8, "Tipsify's ACMR on a grid: {after} (random {before})");
    }

    #[test]
    fn the_draw_order_keeps_every_triangle_and_its_winding() {
        let sphere = icosphere(3);
        let order = draw_order(&sphere.positions, &shuffled(&sphere.indices));
        assert_eq!(order.len(), sphere.indices.len());
        assert_eq!(triangle_set(&order), triangle_set(&sphere.indices));
        assert!(draw_order(&sphere.positions, &[]).is_empty());
    }

    #[test]
    fn overdraw_counts_hidden_fragments_by_hand() {
        // Two squares facing the camera, the near one (depth 0.25) covering the far one (0.75)'s
        // left half, on a 16×16 screen (identity clip: the square x, y in [-0.5, 0.5] covers
        // pixels 4..12, 8×8 = 64 of them; the near one 4×8 = 32).
        let sq = |x0: f32, x1: f32, z: f32| [[x0, -0.5, z], [x1, -0.5, z], [x1, 0.5, z], [x0, 0.5, z]];
        let positions: Vec<[f32; 3]> = [sq(-0.5, 0.5, 0.75), sq(-0.5, 0.0, 0.25)].concat();
        let far: Vec<u32> = vec![0, 1, 2, 0, 2, 3];
        let near: Vec<u32> = vec![4, 5, 6, 4, 6, 7];
        let draw = |first: &[u32], second: &[u32], cull: bool, prepass: bool| {
            let d = |indices| Draw { positions: &positions, indices, cull, prepass };
            overdraw(&[d(first), d(second)], Mat4::IDENTITY, (16, 16))
        };
        // Back to front: the overlap (32 pixels) is shaded twice; front to back, once; after a
        // pre-pass, once, for twice the fragments rasterised.
        let fragments = |o: Overdraw| (o.covered, o.shaded, o.rasterised);
        let back_to_front = draw(&far, &near, true, false);
        assert_eq!(fragments(back_to_front), (64, 96, 96));
        assert_eq!(back_to_front.ratio(), 1.5);
        assert_eq!(fragments(draw(&near, &far, true, false)), (64, 64, 96));
        assert_eq!(fragments(draw(&far, &near, true, true)), (64, 64, 192));
        // Quads and blocks: the far square alone covers 4×4 quads and 2×2 blocks. Its diagonal
        // (x + y = 16 in pixels, corner to corner) splits the quads whose samples' sums
        // straddle 16, those with qx + qy = 7 (four), and the blocks with bx + by = 3 (two):
        // each of those is shaded for both triangles.
        let alone = overdraw(&[Draw { positions: &positions, indices: &far, cull: true, prepass: false }], Mat4::IDENTITY, (16, 16));
        assert_eq!((alone.shaded, alone.quads, alone.blocks), (64, 16 + 4, 4 + 2));
        // Wound the other way, both squares are back faces: culled, nothing is drawn; not
        // culled, the same fragments as before.
        let reversed = |t: &[u32]| t.chunks_exact(3).flat_map(|t| [t[0], t[2], t[1]]).collect::<Vec<u32>>();
        assert_eq!(draw(&reversed(&far), &reversed(&near), true, false), Overdraw::default());
        assert_eq!(draw(&reversed(&far), &reversed(&near), false, false), back_to_front);
    }

    #[test]
    fn the_draw_order_draws_the_outer_of_two_nested_spheres_first() {
        // A sphere of radius 0.5 inside one of radius 1, one mesh, back faces culled, the inner
        // one's triangles first (as loaded). Seen from 4 units away the inner sphere is wholly
        // hidden, yet drawn first every one of its front fragments is shaded: the ratio is
        // 1 + its disc over the outer's, (tan asin(0.5/d) / tan asin(1/d))² = 0.238 at
        // d = 4.03. Reordered, the outer sphere's clusters face out from the centre farther
        // (their key is ~1 against ~0.5) and come first: nothing hidden is shaded.
        let (outer, inner) = (icosphere(3), icosphere(3));
        let n = inner.positions.len() as u32;
        let positions: Vec<[f32; 3]> = inner.positions.iter().map(|p| p.map(|c| 0.5 * c)).chain(outer.positions.iter().copied()).collect();
        let indices: Vec<u32> = inner.indices.iter().copied().chain(outer.indices.iter().map(|i| i + n)).collect();
        let eye = Vec3::new(0.3, 0.4, 4.0);
        let view = glam::camera::rh::view::look_at_mat4(eye, Vec3::ZERO, Vec3::Y);
        let proj = glam::camera::rh::proj::directx::perspective(0.8, 1.0, 0.1, 10.0);
        let measure =
            |indices: &[u32]| overdraw(&[Draw { positions: &positions, indices, cull: true, prepass: false }], proj * view, (256, 256));
        let (before, after) = (measure(&indices), measure(&draw_order(&positions, &indices)));
        assert_eq!((before.covered, before.rasterised), (after.covered, after.rasterised), "the same fragments in any order");
        let d = eye.length();
        let expected = 1.0 + ((0.5 / d).asin().tan() / (1.0 / d).asin().tan()).powi(2) as f64;
        // The polygonal spheres (1280 triangles) and the pixel grid: within 2%.
        assert!((before.ratio() - expected).abs() < 0.02, "as loaded {before:?}: ratio {} vs {expected}", before.ratio());
        assert_eq!(after.shaded, after.covered, "reordered {after:?}");
    }
}
