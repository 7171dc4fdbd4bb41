//! Vertex normals for meshes that come without them: smooth across soft edges, split across
//! creases.
//!
//! Method: an edge is hard when the normals of the two faces meeting there differ by more than
//! the crease angle (the "auto smooth by angle" rule of Blender and 3ds Max). Around each vertex
//! position the triangles joined by soft edges form smoothing groups; each group's normal is the
//! corner-angle-weighted mean of its face normals (Thürmer & Wüthrich 1998, "Computing vertex
//! normals from polygonal facets", J. Graphics Tools 3(1)), and a vertex is split where groups
//! differ. Vertices are welded by position value (not by index), so UV seams and unwelded patch
//! seams (a tessellated teapot) are smoothed across like any other edge. (three.js'
//! `toCreasedNormals` compares every pair of faces around a vertex instead of edge neighbours;
//! on noisy scans that splits far more vertices than the creases warrant.)

use super::Mesh;
use anyhow::{Result, bail};
use glam::Vec3;
use std::collections::HashMap;

/// The default crease angle in degrees: edges sharper than this stay hard.
pub const DEFAULT_CREASE_DEG: f32 = 60.0;

/// Unit normal of triangle (a, b, c) following the right-hand rule of its winding
/// (counter-clockwise seen from the front, as OBJ and glTF specify); zero for a degenerate one.
pub fn face_normal(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    (b - a).cross(c - a).normalize_or_zero()
}

/// Interior angles of triangle (a, b, c) at a, b and c in radians; zeros for a degenerate one.
pub fn corner_angles(a: Vec3, b: Vec3, c: Vec3) -> [f32; 3] {
    let angle = |p: Vec3, q: Vec3, r: Vec3| {
        let (u, v) = ((q - p).normalize_or_zero(), (r - p).normalize_or_zero());
        if u == Vec3::ZERO || v == Vec3::ZERO { 0.0 } else { u.dot(v).clamp(-1.0, 1.0).acos() }
    };
    [angle(a, b, c), angle(b, c, a), angle(c, a, b)]
}

/// A hashable key for a position: its bit pattern, with −0.0 folded onto +0.0.
fn position_key(p: [f32; 3]) -> [u32; 3] {
    p.map(|c| if c == 0.0 { 0 } else { c.to_bits() })
}

/// Replace `mesh.normals` by computed ones, duplicating vertices where a crease splits them.
///
/// `crease_deg` is the largest angle between two faces' normals that is still smoothed over
/// (0 gives flat shading, 180 smooths everything). Triangles keep their winding; every normal
/// is unit length. Corners of degenerate (zero-area) triangles take the normal of a
/// neighbouring group, else the mean of all faces around their position, else model up (+y).
/// An index outside the vertex list is an error (the mesh is left unchanged).
pub fn compute_crease_normals(mesh: &mut Mesh, crease_deg: f32) -> Result<()> {
    if let Some(&i) = mesh.indices.iter().find(|&&i| i as usize >= mesh.positions.len()) {
        bail!("index {i} out of range ({} vertices)", mesh.positions.len());
    }
    let pos: Vec<Vec3> = mesh.positions.iter().map(|p| Vec3::from_array(*p)).collect();
    let tris: Vec<[usize; 3]> = mesh.indices.chunks_exact(3).map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect();
    let face_n: Vec<Vec3> = tris.iter().map(|&[a, b, c]| face_normal(pos[a], pos[b], pos[c])).collect();
    let angles: Vec<[f32; 3]> = tris.iter().map(|&[a, b, c]| corner_angles(pos[a], pos[b], pos[c])).collect();

    // Weld vertices by position value.
    let mut weld: HashMap<[u32; 3], u32> = HashMap::with_capacity(pos.len());
    let pos_id: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let next = weld.len() as u32;
            *weld.entry(position_key(*p)).or_insert(next)
        })
        .collect();

    // Corners (triangle * 3 + k) around each welded position, in CSR form.
    let mut start = vec![0usize; weld.len() + 1];
    for t in &tris {
        for &v in t {
            start[pos_id[v] as usize + 1] += 1;
        }
    }
    for i in 0..weld.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut corners = vec![0u32; tris.len() * 3];
    for (ti, t) in tris.iter().enumerate() {
        for (k, &v) in t.iter().enumerate() {
            let slot = &mut fill[pos_id[v] as usize];
            corners[*slot] = (ti * 3 + k) as u32;
            *slot += 1;
        }
    }

    let cos_crease = crease_deg.clamp(0.0, 180.0).to_radians().cos();
    // Tolerance so that exactly coplanar faces count as within a 0° crease despite rounding.
    let cos_limit = cos_crease - 1e-5;
    let mut corner_n = vec![Vec3::ZERO; tris.len() * 3];
    let mut parent: Vec<usize> = Vec::new();
    let mut edges: Vec<(u32, usize)> = Vec::new();
    for p in 0..weld.len() {
        let around = &corners[start[p]..start[p + 1]];
        // Union the corners whose faces share an edge from this position and meet at no more
        // than the crease angle (degenerate faces join any neighbour).
        parent.clear();
        parent.extend(0..around.len());
        let others = |c: u32| {
            let (t, k) = (c as usize / 3, c as usize % 3);
            [pos_id[tris[t][(k + 1) % 3]], pos_id[tris[t][(k + 2) % 3]]]
        };
        // Corners grouped by the edge (p, o) they share: linear in the corners around p, where
        // comparing every pair was quadratic (a 30 000-gon fan, one vertex of 100 000 triangles).
        edges.clear();
        for (i, &c) in around.iter().enumerate() {
            for o in others(c) {
                if o != p as u32 {
                    edges.push((o, i));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        for bucket in edges.chunk_by(|a, b| a.0 == b.0) {
            let members: Vec<usize> = bucket.iter().map(|&(_, i)| i).collect();
            let normal = |i: usize| face_n[around[i] as usize / 3];
            join_smooth(&mut parent, &members, normal, cos_limit);
        }
        // Each group's normal: corner-angle-weighted sum of its faces' normals.
        let roots: Vec<usize> = (0..around.len()).map(|i| find(&mut parent, i)).collect();
        let weighted = |c: u32| face_n[c as usize / 3] * angles[c as usize / 3][c as usize % 3];
        let mut sums = vec![Vec3::ZERO; around.len()];
        for (i, &c) in around.iter().enumerate() {
            sums[roots[i]] += weighted(c);
        }
        let all = sums.iter().copied().sum::<Vec3>();
        let mut group_sizes = vec![0usize; around.len()];
        for &r in &roots {
            group_sizes[r] += 1;
        }
        for (i, &c) in around.iter().enumerate() {
            let root = roots[i];
            let own = face_n[c as usize / 3];
            let mut group = sums[root].normalize_or_zero();
            if own != Vec3::ZERO && group.dot(own) < cos_limit && group_sizes[root] <= MAX_DRIFT_GROUP {
                // A long, gently bending group can drift more than the crease angle away from
                // this face (rare, on noisy scans): average only the group's faces within the
                // crease of this one, which keeps the normal on the face's front side.
                group = around
                    .iter()
                    .enumerate()
                    .filter(|&(j, &c2)| roots[j] == root && face_n[c2 as usize / 3].dot(own) >= cos_limit)
                    .map(|(_, &c2)| weighted(c2))
                    .sum::<Vec3>()
                    .normalize_or_zero();
            }
            let n = [group, all.normalize_or_zero(), own].into_iter().find(|n| *n != Vec3::ZERO);
            corner_n[c as usize] = n.unwrap_or(Vec3::Y);
        }
    }

    // New vertices: one per distinct (position, uv, normal); old vertices that differed only
    // in the normals being replaced merge.
    let mut remap: HashMap<(u32, [u32; 2], [u32; 3]), u32> = HashMap::with_capacity(pos.len());
    let (mut positions, mut uvs, mut normals) = (Vec::new(), Vec::new(), Vec::new());
    let mut indices = Vec::with_capacity(mesh.indices.len());
    let has_uv = mesh.uvs.len() == mesh.positions.len();
    for (ti, t) in tris.iter().enumerate() {
        for (k, &v) in t.iter().enumerate() {
            let n = corner_n[ti * 3 + k];
            let uv = if has_uv { mesh.uvs[v] } else { [0.0, 0.0] };
            let key = (pos_id[v], uv.map(f32::to_bits), position_key(n.to_array()));
            let next = positions.len() as u32;
            let idx = *remap.entry(key).or_insert_with(|| {
                positions.push(mesh.positions[v]);
                uvs.push(uv);
                normals.push(n.to_array());
                next
            });
            indices.push(idx);
        }
    }
    mesh.positions = positions;
    mesh.uvs = uvs;
    mesh.normals = normals;
    mesh.indices = indices;
    Ok(())
}

/// Edges shared by more faces than this (non-manifold fans, repeated triangles) compare only
/// faces with equal normals and neighbours in normal order, not every pair.
const MAX_PAIRWISE: usize = 16;
/// Smoothing groups larger than this skip the drift correction (it is quadratic in the group).
const MAX_DRIFT_GROUP: usize = 1024;

/// Union the faces (`members`, indices into `parent`) meeting along one edge whose normals are
/// within the crease (`cos_limit`); a degenerate face (zero normal) joins all of them. Pairwise
/// up to [`MAX_PAIRWISE`] faces; beyond that equal normals join and the distinct ones are
/// compared with their neighbour in sorted order, so a hostile edge stays linear.
fn join_smooth(parent: &mut [usize], members: &[usize], normal: impl Fn(usize) -> Vec3, cos_limit: f32) {
    let mut union = |a: usize, b: usize| {
        let (ra, rb) = (find(parent, a), find(parent, b));
        parent[ra.max(rb)] = ra.min(rb);
    };
    let smooth = |a: Vec3, b: Vec3| a == Vec3::ZERO || b == Vec3::ZERO || a.dot(b) >= cos_limit;
    if members.len() <= MAX_PAIRWISE {
        for (k, &i) in members.iter().enumerate() {
            for &j in &members[k + 1..] {
                if smooth(normal(i), normal(j)) {
                    union(i, j);
                }
            }
        }
        return;
    }
    if members.iter().any(|&i| normal(i) == Vec3::ZERO) {
        for &j in &members[1..] {
            union(members[0], j);
        }
        return;
    }
    let mut sorted: Vec<(u32, u32, u32, usize)> = members
        .iter()
        .map(|&i| {
            let [x, y, z] = normal(i).to_array().map(f32::to_bits);
            (x, y, z, i)
        })
        .collect();
    sorted.sort_unstable();
    for w in sorted.windows(2) {
        let (a, b) = (w[0].3, w[1].3);
        if (w[0].0, w[0].1, w[0].2) == (w[1].0, w[1].1, w[1].2) || smooth(normal(a), normal(b)) {
            union(a, b);
        }
    }
}

/// Union-find root with path halving.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube [0,1]^3 as 8 shared vertices and 12 outward-wound triangles.
    fn cube() -> Mesh {
        let mut positions = Vec::new();
        for i in 0..8u32 {
            positions.push([(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]);
        }
        // Quads (counter-clockwise seen from outside), split into two triangles each.
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let indices = quads.iter().flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]]).collect();
        Mesh { positions, indices, ..Default::default() }
    }

    #[test]
    fn right_hand_rule_and_angles() {
        // Counter-clockwise in the xy plane seen from +z has normal +z (right-hand rule).
        let n = face_normal(Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(n, Vec3::Z);
        let a = corner_angles(Vec3::ZERO, Vec3::X, Vec3::Y);
        let q = std::f32::consts::FRAC_PI_4;
        assert!((a[0] - 2.0 * q).abs() < 1e-6 && (a[1] - q).abs() < 1e-6 && (a[2] - q).abs() < 1e-6);
        // Degenerate: collinear points.
        assert_eq!(face_normal(Vec3::ZERO, Vec3::X, 2.0 * Vec3::X), Vec3::ZERO);
        assert_eq!(corner_angles(Vec3::ZERO, Vec3::ZERO, Vec3::X), [0.0; 3]);
    }

    #[test]
    fn cube_is_split_into_flat_faces_at_default_crease() {
        let mut m = cube();
        compute_crease_normals(&mut m, DEFAULT_CREASE_DEG).unwrap();
        // 6 faces x 4 corners, each normal axis-aligned and pointing away from the centre.
        assert_eq!(m.positions.len(), 24);
        assert_eq!(m.indices.len(), 36);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            let n = Vec3::from_array(*n);
            assert!((n.length() - 1.0).abs() < 1e-6);
            assert_eq!(n.abs().max_element(), 1.0, "axis aligned: {n}");
            assert!((Vec3::from_array(*p) - Vec3::splat(0.5)).dot(n) > 0.0);
        }
    }

    #[test]
    fn cube_fully_smoothed_at_180_gives_diagonal_corners() {
        // Each cube corner touches three faces with a total angle of 90 deg each, so the angle-
        // weighted mean is the diagonal (+-1,+-1,+-1)/sqrt(3) by symmetry.
        let mut m = cube();
        compute_crease_normals(&mut m, 180.0).unwrap();
        assert_eq!(m.positions.len(), 8);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            let expect = (Vec3::from_array(*p) - Vec3::splat(0.5)).normalize();
            assert!(Vec3::from_array(*n).dot(expect) > 1.0 - 1e-6, "{n:?} vs {expect}");
        }
    }

    #[test]
    fn gently_curving_fan_is_one_smoothing_group() {
        // Four faces of a tall cone around its apex, 40° apart in azimuth: neighbours meet at
        // about 40° (soft at a 60° crease) although the first and last differ by about 120°.
        // Edges decide, so the apex stays one vertex with one normal.
        let mut positions = vec![[0.0, 0.0, 0.0]];
        for i in 0..5 {
            let phi = (i as f32 * 40.0).to_radians();
            positions.push([phi.cos(), phi.sin(), -10.0]);
        }
        let indices = (1..5u32).flat_map(|i| [0, i, i + 1]).collect();
        let mut m = Mesh { positions, indices, ..Default::default() };
        let face = |i: usize| face_normal(Vec3::ZERO, Vec3::from_array(m.positions[i]), Vec3::from_array(m.positions[i + 1]));
        assert!(face(1).dot(face(2)) > 60f32.to_radians().cos() && face(1).dot(face(4)) < 60f32.to_radians().cos());
        compute_crease_normals(&mut m, 60.0).unwrap();
        let apex: Vec<u32> = (0..4).map(|t| m.indices[3 * t]).collect();
        assert!(apex.iter().all(|&i| i == apex[0]), "apex split: {apex:?}");
    }

    #[test]
    fn uv_seam_is_smoothed_across() {
        // Two triangles of a bent strip sharing an edge whose vertices are duplicated (a UV seam).
        let positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.3]];
        let uvs = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.0, 0.5], [1.0, 1.0]];
        let mut m = Mesh { positions, uvs, indices: vec![0, 1, 2, 3, 5, 4], ..Default::default() };
        compute_crease_normals(&mut m, 60.0).unwrap();
        // Vertices 1 and 3 share a position: their normals must agree although indices differ.
        let n1 = Vec3::from_array(m.normals[m.indices[1] as usize]);
        let n3 = Vec3::from_array(m.normals[m.indices[3] as usize]);
        assert!((n1 - n3).length() < 1e-6);
        // ... and UVs stay with their vertex.
        assert_eq!(m.uvs[m.indices[3] as usize], [0.5, 0.0]);
    }

    #[test]
    fn degenerate_triangles_get_unit_normals() {
        let positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // One sliver (collinear) triangle sharing positions with a proper one, one lone sliver.
        let mut m = Mesh { positions, indices: vec![0, 1, 4, 0, 1, 2, 3, 3, 3], ..Default::default() };
        compute_crease_normals(&mut m, 60.0).unwrap();
        for n in &m.normals {
            assert!((Vec3::from_array(*n).length() - 1.0).abs() < 1e-6);
        }
        // The sliver's corner at the origin borrows the proper face's normal (+z).
        assert!(Vec3::from_array(m.normals[m.indices[3] as usize]).dot(Vec3::Z) > 0.999);
        // Out-of-range index: error, mesh untouched.
        let mut bad = Mesh { positions: vec![[0.0; 3]; 3], indices: vec![0, 1, 3], ..Default::default() };
        assert!(compute_crease_normals(&mut bad, 60.0).is_err());
        assert!(bad.normals.is_empty() && bad.indices == [0, 1, 3]);
    }
}
