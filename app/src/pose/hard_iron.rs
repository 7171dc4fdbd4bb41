//! Online hard-iron calibration: the magnetometer's constant offset (magnetised parts of the
//! phone) estimated from readings taken at many orientations. Without interference the readings
//! lie on a sphere of radius F (the local field) centred on the offset; the centre is found by
//! linear least squares on |m|² = 2 m·c + (R² − |c|²) (the algebraic sphere fit, e.g. NXP
//! application note AN4246 "Calibrating an eCompass in the Presence of Hard- and Soft-Iron
//! Interference", eq. 24–27), refitted without outliers (readings taken during a disturbance).

use glam::DVec3;

/// Readings kept for the fit.
const CAPACITY: usize = 48;
/// A reading is kept only if its direction differs this much (radians) from every kept one.
const MIN_SEPARATION: f64 = 0.2;
/// At least this many readings before a fit is tried.
const MIN_SAMPLES: usize = 12;

/// The result of a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HardIronFit {
    pub offset: DVec3,
    pub radius: f64,
    /// RMS distance of the inliers from the sphere (µT).
    pub residual: f64,
    pub inliers: usize,
}

/// Smallest over largest eigenvalue of the points' covariance: near 0 when they lie near a
/// plane or a line (the phone turned about one axis only), 1 for an even spread.
pub fn spread_ratio(points: &[DVec3]) -> f64 {
    if points.len() < 2 {
        return 0.0;
    }
    let mean = points.iter().sum::<DVec3>() / points.len() as f64;
    let mut c = glam::DMat3::ZERO;
    for p in points {
        let d = *p - mean;
        c += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let e = symmetric_eigenvalues(c);
    if e[2] <= 0.0 { 0.0 } else { (e[0] / e[2]).max(0.0) }
}

/// Eigenvalues (ascending) of a symmetric 3×3 matrix, closed form (Smith 1961, "Eigenvalues of
/// a symmetric 3 × 3 matrix", Communications of the ACM 4(4):168).
pub fn symmetric_eigenvalues(a: glam::DMat3) -> [f64; 3] {
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    if p1 == 0.0 {
        let mut e = [a00, a11, a22];
        e.sort_by(f64::total_cmp);
        return e;
    }
    let q = (a00 + a11 + a22) / 3.0;
    let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (a - glam::DMat3::from_diagonal(glam::DVec3::splat(q))) * (1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let e1 = q + 2.0 * p * phi.cos();
    let e3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    let e2 = 3.0 * q - e1 - e3;
    [e3, e2, e1]
}

/// Readings must spread at least this much (see [`spread_ratio`]) for a fit: a sphere through
/// readings near one plane is not determined by them, and noise would pick it.
pub const MIN_SPREAD: f64 = 0.1;

/// Least-squares sphere through points; `None` when the points do not determine one (too few,
/// or too close to a plane or a line, see [`MIN_SPREAD`]).
pub fn fit_sphere(points: &[DVec3]) -> Option<HardIronFit> {
    if points.len() < 4 || spread_ratio(points) < MIN_SPREAD {
        return None;
    }
    // Normal equations of [2x 2y 2z 1]·[cx cy cz k]ᵀ = x² + y² + z², centred on the mean for
    // conditioning.
    let mean = points.iter().sum::<DVec3>() / points.len() as f64;
    let mut a = [[0.0f64; 5]; 4];
    for p in points {
        let d = *p - mean;
        let row = [2.0 * d.x, 2.0 * d.y, 2.0 * d.z, 1.0];
        let rhs = d.length_squared();
        for i in 0..4 {
            for j in 0..4 {
                a[i][j] += row[i] * row[j];
            }
            a[i][4] += row[i] * rhs;
        }
    }
    let x = solve4(a)?;
    let c = DVec3::new(x[0], x[1], x[2]);
    let r2 = x[3] + c.length_squared();
    // Also rejects NaN.
    if r2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let radius = r2.sqrt();
    let offset = c + mean;
    let residual = (points.iter().map(|p| ((*p - offset).length() - radius).powi(2)).sum::<f64>() / points.len() as f64).sqrt();
    Some(HardIronFit { offset, radius, residual, inliers: points.len() })
}

/// Gaussian elimination with partial pivoting on an augmented 4×5 matrix.
fn solve4(mut a: [[f64; 5]; 4]) -> Option<[f64; 4]> {
    let scale = a.iter().flat_map(|r| r[..4].iter()).fold(0.0f64, |m, v| m.max(v.abs()));
    for col in 0..4 {
        let pivot = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-9 * scale {
            return None;
        }
        a.swap(col, pivot);
        let pivot_row = a[col];
        for (row, r) in a.iter_mut().enumerate() {
            if row != col {
                let f = r[col] / pivot_row[col];
                for (x, p) in r.iter_mut().zip(pivot_row.iter()).skip(col) {
                    *x -= f * p;
                }
            }
        }
    }
    Some(std::array::from_fn(|i| a[i][4] / a[i][i]))
}

/// Collects well-spread readings and keeps the current offset estimate.
#[derive(Clone, Debug, Default)]
pub struct HardIronCalibrator {
    samples: Vec<DVec3>,
    next: usize,
    fit: Option<HardIronFit>,
    since_fit: usize,
}

impl HardIronCalibrator {
    /// The accepted fit, if any.
    pub fn fit(&self) -> Option<HardIronFit> {
        self.fit
    }

    /// The offset to subtract from readings (zero until a fit is accepted).
    pub fn offset(&self) -> DVec3 {
        self.fit.map_or(DVec3::ZERO, |f| f.offset)
    }

    /// Offer a reading (µT, device frame). `expected_total` is the model's field intensity when
    /// known: a fit is accepted only if its radius is within 15 % of it and its residual under
    /// 5 % of the radius.
    pub fn add(&mut self, m: DVec3, expected_total: Option<f64>) {
        let centre = self.offset();
        let dir = (m - centre).normalize_or_zero();
        if dir == DVec3::ZERO || self.samples.iter().any(|s| (*s - centre).normalize_or_zero().angle_between(dir) < MIN_SEPARATION) {
            return;
        }
        if self.samples.len() < CAPACITY {
            self.samples.push(m);
        } else {
            self.samples[self.next] = m;
            self.next = (self.next + 1) % CAPACITY;
        }
        self.since_fit += 1;
        if self.samples.len() >= MIN_SAMPLES && self.since_fit >= 4 {
            self.since_fit = 0;
            self.refit(expected_total);
        }
    }

    fn refit(&mut self, expected_total: Option<f64>) {
        let Some(first) = fit_sphere(&self.samples) else { return };
        // Drop readings far off the first sphere (taken during a disturbance) and refit.
        let mut dist: Vec<f64> = self.samples.iter().map(|p| ((*p - first.offset).length() - first.radius).abs()).collect();
        let mut sorted = dist.clone();
        sorted.sort_by(f64::total_cmp);
        let cut = (3.0 * sorted[sorted.len() / 2]).max(0.02 * first.radius);
        let inliers: Vec<DVec3> = self.samples.iter().zip(dist.drain(..)).filter(|(_, d)| *d <= cut).map(|(p, _)| *p).collect();
        if inliers.len() < MIN_SAMPLES {
            return;
        }
        let Some(fit) = fit_sphere(&inliers) else { return };
        let radius_ok = expected_total.is_none_or(|f| (fit.radius - f).abs() <= 0.15 * f);
        if radius_ok && fit.residual <= 0.05 * fit.radius {
            self.fit = Some(fit);
            // Keep only the inliers so old disturbed readings do not return.
            self.samples = inliers;
            self.next = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_points(centre: DVec3, r: f64, n: usize) -> Vec<DVec3> {
        // Fibonacci sphere: well spread directions.
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                let s = (1.0 - z * z).sqrt();
                centre + DVec3::new(s * phi.cos(), s * phi.sin(), z) * r
            })
            .collect()
    }

    #[test]
    fn exact_sphere_is_recovered() {
        let c = DVec3::new(6.0, -4.0, 2.5);
        let fit = fit_sphere(&sphere_points(c, 48.0, 30)).unwrap();
        assert!((fit.offset - c).length() < 1e-9 && (fit.radius - 48.0).abs() < 1e-9 && fit.residual < 1e-9);
    }

    #[test]
    fn eigenvalues_of_known_matrices() {
        // diag(1, 2, 3) rotated: eigenvalues unchanged.
        let r = glam::DMat3::from_quat(glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.8, 1.2));
        let a = r * glam::DMat3::from_diagonal(DVec3::new(1.0, 2.0, 3.0)) * r.transpose();
        let e = symmetric_eigenvalues(a);
        assert!((e[0] - 1.0).abs() < 1e-12 && (e[1] - 2.0).abs() < 1e-12 && (e[2] - 3.0).abs() < 1e-12, "{e:?}");
        // [[2,1,0],[1,2,0],[0,0,5]]: 1, 3, 5.
        let b = glam::DMat3::from_cols(DVec3::new(2.0, 1.0, 0.0), DVec3::new(1.0, 2.0, 0.0), DVec3::new(0.0, 0.0, 5.0));
        let e = symmetric_eigenvalues(b);
        assert!((e[0] - 1.0).abs() < 1e-12 && (e[1] - 3.0).abs() < 1e-12 && (e[2] - 5.0).abs() < 1e-12, "{e:?}");
        // Points on a circle have no spread across its plane; on a sphere, an even spread.
        let circle: Vec<DVec3> = (0..36).map(|i| DVec3::new((i as f64 * 0.17).cos(), (i as f64 * 0.17).sin(), 0.0)).collect();
        assert!(spread_ratio(&circle) < 1e-12);
        assert!(spread_ratio(&sphere_points(DVec3::ZERO, 1.0, 200)) > 0.9);
    }

    #[test]
    fn degenerate_points_give_no_fit() {
        // All readings in one plane (the phone only turned about one axis): no unique sphere.
        let flat: Vec<DVec3> = (0..20).map(|i| DVec3::new((i as f64).cos(), (i as f64).sin(), 0.0) * 40.0).collect();
        assert!(fit_sphere(&flat).is_none());
        // Nearly flat (a turn about the vertical with a little wobble) is refused too.
        let wobbly: Vec<DVec3> =
            (0..20).map(|i| DVec3::new((i as f64).cos() * 40.0, (i as f64).sin() * 40.0, 2.0 * (i as f64 * 0.7).sin())).collect();
        assert!(fit_sphere(&wobbly).is_none());
        assert!(fit_sphere(&[DVec3::X; 3]).is_none());
    }

    #[test]
    fn calibrator_finds_the_offset_despite_disturbed_readings() {
        let c = DVec3::new(-5.0, 3.0, 7.0);
        let mut cal = HardIronCalibrator::default();
        for (i, p) in sphere_points(c, 48.0, 40).into_iter().enumerate() {
            // Every fifth reading taken next to a steel post: 20 µT extra.
            let m = if i % 5 == 0 { p + DVec3::new(20.0, 0.0, 0.0) } else { p };
            cal.add(m, Some(48.0));
        }
        let fit = cal.fit().expect("a fit");
        assert!((fit.offset - c).length() < 0.5, "{fit:?}");
        // A wrong expected intensity is refused.
        let mut cal = HardIronCalibrator::default();
        for p in sphere_points(c, 48.0, 40) {
            cal.add(p, Some(30.0));
        }
        assert!(cal.fit().is_none());
    }
}
