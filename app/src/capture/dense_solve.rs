//! Small dense linear systems `a x = b` (a few dozen unknowns: the shots of one capture), by
//! Gaussian elimination with partial pivoting. Used by the shots' alignment (capture::align) and
//! the per-shot gains (capture::gain).

/// Pivots smaller than this count as zero.
const SINGULAR: f64 = 1e-12;

/// Solve `a x = b`. A column without a usable pivot is skipped and its unknown set to 0; the
/// flag says whether every column had one (false: the system is singular).
pub fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> (Vec<f64>, bool) {
    let n = b.len();
    let mut full_rank = true;
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs())).unwrap_or(c);
        a.swap(c, p);
        b.swap(c, p);
        let d = a[c][c];
        if d.abs() < SINGULAR {
            full_rank = false;
            continue;
        }
        let (pivot_rows, rest) = a.split_at_mut(c + 1);
        let pivot = &pivot_rows[c];
        for (k, row) in rest.iter_mut().enumerate() {
            let f = row[c] / d;
            if f != 0.0 {
                for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                    *x -= f * p;
                }
                b[c + 1 + k] -= f * b[c];
            }
        }
    }
    let mut x = vec![0.0; n];
    for c in (0..n).rev() {
        let s: f64 = (c + 1..n).map(|k| a[c][k] * x[k]).sum();
        x[c] = if a[c][c].abs() < SINGULAR { 0.0 } else { (b[c] - s) / a[c][c] };
    }
    (x, full_rank)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_system_that_needs_pivoting_and_flags_a_singular_one() {
        // 2y + z = 7, x + y + z = 6, 3x + z = 6 (zero first pivot): x = 1, y = 2, z = 3.
        let (x, full) = solve_dense(vec![vec![0.0, 2.0, 1.0], vec![1.0, 1.0, 1.0], vec![3.0, 0.0, 1.0]], vec![7.0, 6.0, 6.0]);
        assert!(full);
        for (got, want) in x.iter().zip([1.0, 2.0, 3.0]) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        // The second row is twice the first: singular, and the lost unknown is 0.
        let (x, full) = solve_dense(vec![vec![1.0, 2.0], vec![2.0, 4.0]], vec![3.0, 6.0]);
        assert!(!full);
        assert_eq!(x[1], 0.0);
        assert!((x[0] - 3.0).abs() < 1e-12, "{x:?}");
    }
}
