//! Symmetric 3×3 eigen-decomposition and the matrix functions built on it (square root,
//! inverse square root), in f64. Used to fit the Monge–Kantorovich colour map.

use glam::{DMat3, DVec3};

/// Eigen-decomposition of a symmetric matrix: `a = vectors · diag(values) · vectorsᵀ`, the
/// columns of `vectors` orthonormal, values in descending order.
///
/// Cyclic Jacobi rotations (Golub & Van Loan, "Matrix Computations", 4th ed., Alg. 8.5.3),
/// which are accurate for small symmetric matrices and need no special cases for repeated
/// eigenvalues. Only the upper triangle of `a` is read. Non-finite input gives non-finite
/// output; callers check with [`DMat3::is_finite`].
pub fn sym_eigen(a: DMat3) -> (DVec3, DMat3) {
    // Work on a row-major array copy: m[i][j] = a(i, j).
    let mut m = [[0.0f64; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (r, c) = if i <= j { (i, j) } else { (j, i) };
            *v = a.col(c)[r];
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0f64]];
    for _sweep in 0..50 {
        let off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        let scale = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2] + off;
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            if m[p][q] == 0.0 {
                continue;
            }
            // Symmetric Schur decomposition of the (p, q) 2×2 block (G&VL Alg. 8.5.1).
            let tau = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
            let t = if tau == 0.0 { 1.0 } else { t };
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = t * c;
            // m ← Jᵀ m J with J the rotation in the (p, q) plane.
            for row in m.iter_mut() {
                let (mkp, mkq) = (row[p], row[q]);
                row[p] = c * mkp - s * mkq;
                row[q] = s * mkp + c * mkq;
            }
            let (row_p, row_q) = (m[p], m[q]);
            m[p] = std::array::from_fn(|k| c * row_p[k] - s * row_q[k]);
            m[q] = std::array::from_fn(|k| s * row_p[k] + c * row_q[k]);
            for row in v.iter_mut() {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| m[j][j].total_cmp(&m[i][i]));
    let values = DVec3::new(m[order[0]][order[0]], m[order[1]][order[1]], m[order[2]][order[2]]);
    let col = |k: usize| DVec3::new(v[0][k], v[1][k], v[2][k]);
    (values, DMat3::from_cols(col(order[0]), col(order[1]), col(order[2])))
}

/// `vectors · diag(f(values)) · vectorsᵀ`.
pub fn sym_apply(values: DVec3, vectors: DMat3, f: impl Fn(f64) -> f64) -> DMat3 {
    vectors * DMat3::from_diagonal(DVec3::new(f(values.x), f(values.y), f(values.z))) * vectors.transpose()
}

/// Principal square root of a symmetric positive semi-definite matrix (negative eigenvalues,
/// which only rounding produces, are treated as 0).
pub fn sym_sqrt(a: DMat3) -> DMat3 {
    let (values, vectors) = sym_eigen(a);
    sym_apply(values, vectors, |x| x.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DMat3, b: DMat3, tol: f64) -> bool {
        (0..3).all(|c| (a.col(c) - b.col(c)).abs().max_element() <= tol)
    }

    #[test]
    fn known_eigenvalues() {
        // [[2,1,0],[1,2,0],[0,0,3]] has eigenvalues 3, 3, 1 (by hand: the 2×2 block has 2 ± 1).
        let a = DMat3::from_cols(DVec3::new(2.0, 1.0, 0.0), DVec3::new(1.0, 2.0, 0.0), DVec3::new(0.0, 0.0, 3.0));
        let (values, vectors) = sym_eigen(a);
        assert!((values - DVec3::new(3.0, 3.0, 1.0)).abs().max_element() < 1e-12);
        assert!(close(vectors.transpose() * vectors, DMat3::IDENTITY, 1e-12));
        assert!(close(sym_apply(values, vectors, |x| x), a, 1e-12));
        // Eigenvector of 1 is (1, −1, 0)/√2 up to sign.
        assert!((vectors.col(2).x.abs() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        assert!(vectors.col(2).z.abs() < 1e-12);
    }

    #[test]
    fn general_and_degenerate_matrices() {
        // The 3×3 second-difference matrix [[2,−1,0],[−1,2,−1],[0,−1,2]] has eigenvalues
        // 2 − 2cos(kπ/4), k = 1..3 (closed form for tridiagonal Toeplitz matrices).
        let a = DMat3::from_cols(DVec3::new(2.0, -1.0, 0.0), DVec3::new(-1.0, 2.0, -1.0), DVec3::new(0.0, -1.0, 2.0));
        let (values, _) = sym_eigen(a);
        let expect = |k: f64| 2.0 - 2.0 * (k * std::f64::consts::PI / 4.0).cos();
        assert!((values - DVec3::new(expect(3.0), expect(2.0), expect(1.0))).abs().max_element() < 1e-12);
        // Zero matrix and a rank-1 matrix.
        let (z, _) = sym_eigen(DMat3::ZERO);
        assert_eq!(z, DVec3::ZERO);
        let u = DVec3::new(1.0, 2.0, 2.0);
        let r1 = DMat3::from_cols(u * u.x, u * u.y, u * u.z);
        let (values, _) = sym_eigen(r1);
        assert!((values - DVec3::new(9.0, 0.0, 0.0)).abs().max_element() < 1e-12);
    }

    #[test]
    fn square_root_squares_back() {
        let a = DMat3::from_cols(DVec3::new(4.0, 1.0, 0.5), DVec3::new(1.0, 3.0, 0.2), DVec3::new(0.5, 0.2, 1.0));
        let s = sym_sqrt(a);
        assert!(close(s * s, a, 1e-11));
        // diag(4, 9, 0) → diag(2, 3, 0).
        let d = sym_sqrt(DMat3::from_diagonal(DVec3::new(4.0, 9.0, 0.0)));
        assert!(close(d, DMat3::from_diagonal(DVec3::new(2.0, 3.0, 0.0)), 1e-12));
    }
}
