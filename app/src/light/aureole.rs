//! Where a clipped sun is, read from the unclipped sky around it (issue 9, clipped maps).
//!
//! A map exposed for its sky clips the sun's disc and the bright aureole around it. The saturated
//! blob is not centred on the sun: near the horizon the sky itself brightens (the haze's
//! horizon brightening), so the blob reaches further down than up, and its centre lies below the
//! sun (quarry_01 ×0.25 clipped at 1.0: the blob's centroid 7.7° up in the equirect, 7.9°
//! through the cube map, where the sun is at 10.1°; the aureole's centre 10.0°, 0.62° from the
//! sun, tests/clipped_sun.rs). The sky outside the blob still shows the aureole's falloff around
//! the true centre.
//!
//! Model, over the unclipped sky within [`FIT_RADIUS`] of the blob: L(d) = B(elevation) +
//! A γ(d, s)^−k — a background that depends on the elevation only (the horizon brightening, and
//! whatever else varies with height: each [`ELEVATION_BIN`] of elevation gets its own level B,
//! unconstrained) plus a radially symmetric power-law aureole of amplitude A and exponent k
//! around the sun's direction s (γ: the angle from s). For a given s and k the model is linear in
//! the levels and A, solved exactly (least squares weighted by solid angle, each bin's mean
//! removed); s is searched over the saturated blob (the disc, the brightest thing in the sky,
//! is inside it) and k over [`EXPONENTS`]. Within one elevation bin the aureole's falloff
//! with azimuth gives the bin's distance from the sun (a bin through the sun peaks sharply, one
//! 5° above it is flat), so the fit pins the elevation that the blob's outline does not.

use super::samples::DirSample;
use crate::colour::luminance_bt709;
use glam::Vec3;

/// Radius (rad, 25°) of the sky around the blob's centre that the fit uses. quarry_01 clipped:
/// the fit's elevation 9.7–11.0° for radii from 12° to 35° (the sun at 10.0°; a Python probe on
/// the equirect, 2026-12-01).
pub const FIT_RADIUS: f32 = 0.436_332_3;

/// Lowest elevation (rad, 2°) of the sky samples used: below it the map holds terrain.
pub const MIN_ELEVATION: f32 = 0.034_906_59;

/// Width (rad, 0.5°) of the elevation bins that each get their own background level.
pub const ELEVATION_BIN: f32 = 0.008_726_646;

/// The aureole's power-law exponents tried (L ∝ γ^−k), refined by ±20 % around the best. A fit
/// whose exponent ends below the first ([`MIN_EXPONENT`]) has found a broad gradient of the sky,
/// not an aureole, and is not used: on the maps of ../shared/data/hdri clipped as
/// tests/clipped_sun.rs clips them, quarry_01's aureole fits with k ≈ 1 (the sun 0.62° off, the
/// blob's centroid 2.44°), while city, sunset and venice_sunset fit exponents at the search's
/// lower end (0.16 with a search from 0.25), 1.7°, 4.9° and 0.9° off where their blobs'
/// centroids are 0.15°, 4.0° and 0.5° off (2026-12-01).
pub const EXPONENTS: [f64; 7] = [0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0];
pub const MIN_EXPONENT: f64 = EXPONENTS[0];

/// Most sky samples the fit uses (every n-th beyond: a 1k map's cube holds ~10⁴ within
/// [`FIT_RADIUS`]).
pub const MAX_SKY_SAMPLES: usize = 4096;

/// Fewest usable sky samples (and elevation bins holding two or more) for a fit.
pub const MIN_SAMPLES: usize = 50;
pub const MIN_BINS: usize = 5;

/// Least share of the sky's variation within the elevation bins that the aureole must explain
/// (R²) to be used: a sky whose brightness varies with the elevation alone (no aureole) leaves
/// nothing to fit, and any direction in the blob fits that nothing as well as another.
pub const MIN_EXPLAINED: f64 = 0.5;

/// The fitted aureole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aureole {
    /// Unit direction to the sun (ENU): the aureole's centre.
    pub dir: Vec3,
    /// Exponent k and amplitude A of the falloff A γ^−k (γ in radians, the samples' units).
    pub exponent: f64,
    pub amplitude: f64,
    /// Root mean square residual (the samples' units, weighted by solid angle).
    pub rms: f64,
    /// Share of the sky's variation within the elevation bins that the aureole explains (R²).
    pub explained: f64,
}

/// One usable sky sample: direction, luminance, solid angle, elevation bin.
struct Sky {
    dir: Vec3,
    lum: f64,
    w: f64,
    bin: usize,
}

/// Fit the aureole around the saturated `blob` (indices into `samples`) whose centre is `start`,
/// using the samples `usable` keeps (unclipped, finite) within [`FIT_RADIUS`] of `start` and above
/// [`MIN_ELEVATION`]. None where too little sky is seen, or no direction in the blob gives a
/// brightening aureole (A > 0) that explains [`MIN_EXPLAINED`] of the sky's variation with an
/// exponent of [`MIN_EXPONENT`] or more.
pub fn fit(samples: &[DirSample], blob: &[usize], start: Vec3, usable: impl Fn(usize) -> bool) -> Option<Aureole> {
    let cos_r = FIT_RADIUS.cos();
    let in_blob = super::samples::mask(samples.len(), blob);
    let mut sky: Vec<Sky> = samples
        .iter()
        .enumerate()
        .filter(|&(i, s)| !in_blob[i] && s.dir.dot(start) >= cos_r && s.dir.z >= MIN_ELEVATION.sin() && usable(i))
        .filter_map(|(_, s)| {
            let lum = f64::from(luminance_bt709(s.radiance));
            let el = s.dir.z.clamp(-1.0, 1.0).asin();
            (lum.is_finite() && s.solid_angle > 0.0).then(|| Sky {
                dir: s.dir,
                lum,
                w: f64::from(s.solid_angle),
                bin: (el / ELEVATION_BIN) as usize,
            })
        })
        .collect();
    // At most MAX_SKY_SAMPLES, evenly taken (the fit's cost is samples × candidates).
    let stride = sky.len().div_ceil(MAX_SKY_SAMPLES).max(1);
    if stride > 1 {
        sky = sky.into_iter().step_by(stride).collect();
    }
    // Keep the bins that hold two samples or more (a lone sample's level is its own value).
    let bins = sky.iter().map(|s| s.bin).max()? + 1;
    let mut count = vec![0usize; bins];
    for s in &sky {
        count[s.bin] += 1;
    }
    sky.retain(|s| count[s.bin] >= 2);
    if sky.len() < MIN_SAMPLES || count.iter().filter(|&&c| c >= 2).count() < MIN_BINS {
        return None;
    }
    // The sky's luminance with each bin's weighted mean removed (what the levels B leave).
    let (mut wsum, mut lsum) = (vec![0f64; bins], vec![0f64; bins]);
    for s in &sky {
        wsum[s.bin] += s.w;
        lsum[s.bin] += s.w * s.lum;
    }
    let centred: Vec<f64> = sky.iter().map(|s| s.lum - lsum[s.bin] / wsum[s.bin]).collect();
    let lcl: f64 = sky.iter().zip(&centred).map(|(s, l)| s.w * l * l).sum();
    let total_w: f64 = sky.iter().map(|s| s.w).sum();

    // Residual sum of squares of the best A with exponent k, for the sun at the direction whose
    // angles to the samples have logarithms `log_gamma`.
    let (mut fsum, mut f) = (vec![0f64; bins], vec![0f64; sky.len()]);
    let mut residual = |log_gamma: &[f64], k: f64| -> Option<(f64, f64)> {
        fsum.iter_mut().for_each(|v| *v = 0.0);
        for ((v, s), lg) in f.iter_mut().zip(&sky).zip(log_gamma) {
            *v = (-k * lg).exp();
            fsum[s.bin] += s.w * *v;
        }
        let (mut ff, mut fl) = (0f64, 0f64);
        for ((s, v), l) in sky.iter().zip(&f).zip(&centred) {
            let fc = v - fsum[s.bin] / wsum[s.bin];
            ff += s.w * fc * fc;
            fl += s.w * fc * l;
        }
        (ff > 0.0 && fl > 0.0).then(|| {
            let a = fl / ff;
            ((lcl - a * fl).max(0.0), a)
        })
    };

    // Candidates: a tangent-plane grid around `start`, kept where a blob sample is within its
    // texel's width (the disc is inside the blob), coarse to fine.
    let (e1, e2) = {
        let east = Vec3::Z.cross(start).try_normalize().unwrap_or(Vec3::X);
        (east, start.cross(east))
    };
    let blob_dirs: Vec<(Vec3, f32)> =
        blob.iter().filter_map(|&i| samples.get(i)).map(|s| (s.dir, s.solid_angle.sqrt().max(1e-4).cos())).collect();
    let inside = |d: Vec3| blob_dirs.iter().any(|&(b, cos_w)| b.dot(d) >= cos_w);
    let mut best: Option<(f64, Vec3, f64, f64)> = None;
    let (mut centre, mut exponents): (Vec3, Vec<f64>) = (start, EXPONENTS.to_vec());
    for (half, step) in [(10f32, 1.0f32), (1.5, 0.25), (0.3, 0.05)] {
        let n = (half / step).round() as i32;
        let mut round: Option<(f64, Vec3, f64, f64)> = None;
        for i in -n..=n {
            for j in -n..=n {
                let (x, y) = ((i as f32 * step).to_radians(), (j as f32 * step).to_radians());
                let d = (centre + e1 * x + e2 * y).normalize();
                if !inside(d) {
                    continue;
                }
                let log_gamma: Vec<f64> = sky.iter().map(|s| f64::from(s.dir.dot(d).clamp(-1.0, 1.0).acos()).max(1e-4).ln()).collect();
                for &k in &exponents {
                    if let Some((ss, a)) = residual(&log_gamma, k)
                        && round.is_none_or(|r| ss < r.0)
                    {
                        round = Some((ss, d, k, a));
                    }
                }
            }
        }
        let Some(r) = round else { break };
        centre = r.1;
        exponents = (-2..=2).map(|m| r.2 * (1.0 + 0.1 * f64::from(m))).collect();
        best = Some(r);
    }
    let (ss, dir, exponent, amplitude) = best?;
    let explained = if lcl > 0.0 { 1.0 - ss / lcl } else { 0.0 };
    (explained >= MIN_EXPLAINED && exponent >= MIN_EXPONENT).then_some(Aureole {
        dir,
        exponent,
        amplitude,
        rms: (ss / total_w).sqrt(),
        explained,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::samples::from_equirect;
    use crate::scene::environment::{Equirect, equirect_uv_to_enu};

    fn dir_from(az_deg: f32, el_deg: f32) -> Vec3 {
        let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
        Vec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
    }

    #[test]
    fn a_lopsided_clipped_blob_gives_the_aureoles_centre() {
        // A sky whose background brightens steeply towards the horizon (0.2 + 0.6 e^{−el/4°})
        // plus an aureole 0.02 γ^−1.5 around a sun at azimuth 40°, elevation 9°; clipped at 1.0
        // the blob reaches the horizon, its centre far below the sun. The fit finds the sun.
        let sun = dir_from(40.0, 9.0);
        let (w, h) = (1024u32, 512u32);
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let d = equirect_uv_to_enu(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32, 0.0);
                if d.z < 0.0 {
                    return [0.1; 3];
                }
                let el = d.z.asin().to_degrees();
                let gamma = d.dot(sun).clamp(-1.0, 1.0).acos().max(1e-3);
                let l = (0.2 + 0.6 * (-el / 4.0).exp() + 0.02 * gamma.powf(-1.5)).min(1.0);
                [l; 3]
            })
            .collect();
        let samples = from_equirect(&Equirect::new(w, h, pixels).unwrap(), 0.0);
        let blob: Vec<usize> = (0..samples.len()).filter(|&i| samples[i].radiance[0] >= 0.99 && samples[i].dir.z > -0.03).collect();
        let centroid = blob.iter().map(|&i| samples[i].dir * samples[i].solid_angle).sum::<Vec3>().normalize();
        let off = |d: Vec3| d.angle_between(sun).to_degrees();
        assert!(off(centroid) > 1.5, "the blob's centre is {} deg off: not lopsided enough to test", off(centroid));
        let a = fit(&samples, &blob, centroid, |i| samples[i].radiance[0] < 0.99).expect("a fit");
        assert!(off(a.dir) < 0.3, "aureole centre {} deg off (blob's {} deg)", off(a.dir), off(centroid));
        assert!((a.exponent - 1.5).abs() < 0.2 && (a.amplitude / 0.02 - 1.0).abs() < 0.2, "{a:?}");
        // No sky around the blob (all of it unusable): nothing to fit.
        assert_eq!(fit(&samples, &blob, centroid, |_| false), None);
    }
}
