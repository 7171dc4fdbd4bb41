//! Which texels of a model's texture count for its colour priors: the seed's "green screen"
//! rule (pure (0,255,0) texels are background, seed 000 §5.1.1) and, better, the texels that some
//! UV triangle of the mesh actually covers, so no hand-edited texture is needed.

use crate::scene::Mesh;

/// The seed's green-screen colour, sRGB 8-bit.
pub const GREEN_SCREEN: [u8; 3] = [0, 255, 0];

/// Whether an sRGB 8-bit pixel is the pure green-screen colour.
pub fn is_green_screen(rgb: [u8; 3]) -> bool {
    rgb == GREEN_SCREEN
}

/// Above this many texels of bounding box per triangle (in multiples of the texture's area) a
/// triangle tiles the texture many times and is taken to cover all of it.
const TILING_LIMIT: f64 = 16.0;

/// Mark every texel of a `width`×`height` texture that a UV triangle of `mesh` touches
/// (conservative rasterisation: any overlap of triangle and texel square with positive area
/// counts — touching at an edge or corner does not — so sliver and sub-texel triangles still
/// mark the texels they sample). UVs wrap (repeat addressing);
/// v = 0 is the top row (`Mesh::uvs` convention). Returns whether the mesh has usable UVs
/// (false when all UVs are zero or the UV array does not match the positions).
pub fn mark_uv_coverage(mesh: &Mesh, width: u32, height: u32, covered: &mut [bool]) -> bool {
    let (w, h) = (width as i64, height as i64);
    if w == 0 || h == 0 || covered.len() != (w * h) as usize {
        return false;
    }
    if mesh.uvs.len() != mesh.positions.len() || mesh.uvs.iter().all(|uv| uv[0] == 0.0 && uv[1] == 0.0) {
        return false;
    }
    let mut any = false;
    for tri in mesh.indices.chunks_exact(3) {
        let Some(p) = tri
            .iter()
            .map(|&i| mesh.uvs.get(i as usize).map(|uv| [uv[0] as f64 * w as f64, uv[1] as f64 * h as f64]))
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        if p.iter().any(|q| !q[0].is_finite() || !q[1].is_finite()) {
            continue;
        }
        any = true;
        let (x0, x1) = (p.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min), p.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max));
        let (y0, y1) = (p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min), p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max));
        // Texels whose square meets the bounding box with positive area (touching its edge
        // does not count; a zero-width box still gets its one texel).
        let span = |a: f64, b: f64| (a.floor() as i64, ((b.ceil() as i64) - 1).max(a.floor() as i64));
        let ((tx0, tx1), (ty0, ty1)) = (span(x0, x1), span(y0, y1));
        let area = ((tx1 - tx0 + 1) as f64) * ((ty1 - ty0 + 1) as f64);
        if area > TILING_LIMIT * (w * h) as f64 {
            covered.iter_mut().for_each(|c| *c = true);
            return true;
        }
        // Separating axes: the two texel axes (the bounding box loop) and the three edge normals.
        let normals: Vec<[f64; 2]> = (0..3).map(|i| [p[(i + 1) % 3][1] - p[i][1], p[i][0] - p[(i + 1) % 3][0]]).collect();
        let ranges: Vec<(f64, f64)> = normals
            .iter()
            .map(|n| {
                let d: Vec<f64> = p.iter().map(|q| n[0] * q[0] + n[1] * q[1]).collect();
                (d.iter().copied().fold(f64::INFINITY, f64::min), d.iter().copied().fold(f64::NEG_INFINITY, f64::max))
            })
            .collect();
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let (cx, cy) = (tx as f64 + 0.5, ty as f64 + 0.5);
                let overlaps = normals.iter().zip(&ranges).all(|(n, (lo, hi))| {
                    let c = n[0] * cx + n[1] * cy;
                    let r = 0.5 * (n[0].abs() + n[1].abs());
                    c + r > *lo && c - r < *hi
                });
                if overlaps {
                    covered[(ty.rem_euclid(h) * w + tx.rem_euclid(w)) as usize] = true;
                }
            }
        }
    }
    any
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(uvs: Vec<[f32; 2]>, indices: Vec<u32>) -> Mesh {
        Mesh { positions: vec![[0.0; 3]; uvs.len()], normals: vec![], uvs, indices, material: 0 }
    }

    fn count(c: &[bool]) -> usize {
        c.iter().filter(|&&b| b).count()
    }

    #[test]
    fn half_texture_triangle() {
        // The triangle (0,0),(1,0),(0,1) on an 8×8 texture covers, by hand, the texels with
        // tx + ty ≤ 7: 8 + 7 + … + 1 = 36 (those with tx + ty = 8 only touch the diagonal at a
        // corner); the texel (7,7) in the opposite corner is not touched.
        let m = mesh(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], vec![0, 1, 2]);
        let mut c = vec![false; 64];
        assert!(mark_uv_coverage(&m, 8, 8, &mut c));
        assert_eq!(count(&c), 36);
        assert!(c[0] && !c[63] && c[7] && c[56]);
    }

    #[test]
    fn sub_texel_and_sliver_triangles_mark_what_they_touch() {
        // A triangle inside texel (2,1) of a 4×4 texture.
        let m = mesh(vec![[0.55, 0.30], [0.60, 0.30], [0.55, 0.32]], vec![0, 1, 2]);
        let mut c = vec![false; 16];
        mark_uv_coverage(&m, 4, 4, &mut c);
        assert_eq!(count(&c), 1);
        assert!(c[4 + 2]);
        // A degenerate (zero-area) horizontal sliver along v = 0.6 from u = 0.1 to 0.9 touches
        // row 2 texels 0..=3.
        let m = mesh(vec![[0.1, 0.6], [0.9, 0.6], [0.5, 0.6]], vec![0, 1, 2]);
        let mut c = vec![false; 16];
        mark_uv_coverage(&m, 4, 4, &mut c);
        assert_eq!(count(&c), 4);
        assert!((0..4).all(|x| c[2 * 4 + x]));
    }

    #[test]
    fn wrapping_and_missing_uvs() {
        // u in 1.0..1.25 wraps onto the first column of a 4×4 texture (v 0..0.25: first row).
        let m = mesh(vec![[1.01, 0.01], [1.2, 0.01], [1.01, 0.2]], vec![0, 1, 2]);
        let mut c = vec![false; 16];
        mark_uv_coverage(&m, 4, 4, &mut c);
        assert_eq!(count(&c), 1);
        assert!(c[0]);
        // No UVs: reported, nothing marked.
        let m = mesh(vec![[0.0, 0.0]; 3], vec![0, 1, 2]);
        let mut c = vec![false; 16];
        assert!(!mark_uv_coverage(&m, 4, 4, &mut c));
        assert_eq!(count(&c), 0);
        // Out-of-range indices are skipped, not a panic.
        let m = mesh(vec![[0.1, 0.1], [0.2, 0.1], [0.1, 0.2]], vec![0, 1, 9]);
        assert!(!mark_uv_coverage(&m, 4, 4, &mut [false; 16]));
    }

    #[test]
    fn green_screen() {
        assert!(is_green_screen([0, 255, 0]));
        assert!(!is_green_screen([0, 254, 0]));
        assert!(!is_green_screen([1, 255, 0]));
    }
}
