//! How far apart two colour distributions are: the sliced Wasserstein-2 distance (Rabin, Peyré,
//! Delon & Bernot 2011, "Wasserstein barycenter and its application to texture mixing";
//! Bonneel, Rabin, Peyré & Pfister 2015, Eq. 5):
//!
//! SW₂(A, B)² = E_θ [ W₂(θ·A, θ·B)² ],  θ uniform on the unit sphere,
//!
//! with the 1-D W₂ from quantile functions: W₂² = ∫₀¹ (F_A⁻¹(q) − F_B⁻¹(q))² dq. We use
//! [`DIRECTIONS`] Fibonacci-sphere directions (deterministic, evenly spread) and [`QUANTILES`]
//! mid-point quantiles, so the value is reproducible run to run. Units: those of the points
//! (lαβ units when the points are lαβ).

use glam::DVec3;

/// Number of projection directions.
pub const DIRECTIONS: usize = 64;
/// Number of quantiles each 1-D distribution is summarised by.
pub const QUANTILES: usize = 1024;

/// `n` directions spread evenly over the unit sphere (golden-angle spiral).
pub fn fibonacci_directions(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

fn quantiles(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (0..QUANTILES).map(|k| v[(((k as f64 + 0.5) / QUANTILES as f64) * n as f64) as usize % n.max(1)]).collect()
}

/// Sliced Wasserstein-2 distance between two point sets (empty sets → `None`).
pub fn sliced_wasserstein(a: &[DVec3], b: &[DVec3]) -> Option<f64> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let dirs = fibonacci_directions(DIRECTIONS);
    let total: f64 = dirs
        .iter()
        .map(|d| {
            let qa = quantiles(a.iter().map(|p| p.dot(*d)).collect());
            let qb = quantiles(b.iter().map(|p| p.dot(*d)).collect());
            qa.iter().zip(&qb).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / QUANTILES as f64
        })
        .sum();
    Some((total / DIRECTIONS as f64).sqrt())
}

/// Every `step`-th element, so that at most `max` remain (for big images).
pub fn subsample<T: Copy>(v: &[T], max: usize) -> Vec<T> {
    let step = v.len().div_ceil(max.max(1)).max(1);
    v.iter().step_by(step).copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(n: usize, scale: f64) -> Vec<DVec3> {
        (0..n).map(|i| DVec3::new(scale * (i as f64 + 0.5) / n as f64, 0.0, 0.0)).collect()
    }

    #[test]
    fn identical_sets_are_at_distance_zero() {
        let a = line(1000, 1.0);
        assert_eq!(sliced_wasserstein(&a, &a), Some(0.0));
        assert_eq!(sliced_wasserstein(&a, &[]), None);
    }

    #[test]
    fn translation_gives_length_over_root_three() {
        // Shifting by d shifts every projection by θ·d, so SW₂² = E[(θ·d)²] = |d|²/3.
        let a: Vec<DVec3> = fibonacci_directions(500).into_iter().map(|p| p * 0.3).collect();
        let d = DVec3::new(0.2, -0.1, 0.4);
        let b: Vec<DVec3> = a.iter().map(|p| *p + d).collect();
        let sw = sliced_wasserstein(&a, &b).unwrap();
        let expect = d.length() / 3f64.sqrt();
        assert!((sw - expect).abs() < 0.02 * expect, "{sw} vs {expect}");
    }

    #[test]
    fn uniform_segments_match_closed_form() {
        // U(0,1) vs U(0,2) on the x axis: 1-D W₂² = ∫(q − 2q)² dq = 1/3 along x; projected on θ
        // it scales by θ_x², and E[θ_x²] = 1/3, so SW₂ = 1/3.
        let sw = sliced_wasserstein(&line(3000, 1.0), &line(3000, 2.0)).unwrap();
        assert!((sw - 1.0 / 3.0).abs() < 0.01, "{sw}");
    }

    #[test]
    fn directions_are_unit_and_balanced() {
        let dirs = fibonacci_directions(DIRECTIONS);
        assert!(dirs.iter().all(|d| (d.length() - 1.0).abs() < 1e-12));
        let mean = dirs.iter().fold(DVec3::ZERO, |a, b| a + *b) / DIRECTIONS as f64;
        assert!(mean.length() < 0.05);
        assert_eq!(subsample(&[1, 2, 3, 4, 5], 2), vec![1, 4]);
    }
}
