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

/// Least-squares sphere through points; `None` when the points do not determine one (too few,
/// or all near a plane or a line).
pub fn fit_sphere(points: &[DVec3]) -> Option<HardIronFit> {
    if points.len() < 4 {
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
    fn degenerate_points_give_no_fit() {
        // All readings in one plane (the phone only turned about one axis): no unique sphere.
        let flat: Vec<DVec3> = (0..20).map(|i| DVec3::new((i as f64).cos(), (i as f64).sin(), 0.0) * 40.0).collect();
        assert!(fit_sphere(&flat).is_none());
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
