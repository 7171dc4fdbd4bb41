//! GGX specular lighting from an environment map by the split-sum approximation (Karis 2013,
//! "Real Shading in Unreal Engine 4", SIGGRAPH course notes): the specular integral is split
//! into the environment convolved with the GGX lobe (one cube-map mip level per roughness,
//! [`prefilter`], computed once per environment) times the BRDF's directional albedo for a
//! Schlick Fresnel, F0·A + B ([`split_sum`], tabulated once in [`brdf_lut`]).
//!
//! Conventions as Karis 2013: GGX (Trowbridge–Reitz) distribution with α = roughness²,
//! Smith–Schlick geometry with k = α/2 for image-based light, Schlick Fresnel.

use crate::scene::CubeMap;
use crate::scene::environment::{face_uv_to_cube_dir, texel_solid_angle};
use glam::Vec3;
use std::f32::consts::PI;

/// Mip levels of the prefiltered environment; level k holds roughness k / (LEVELS − 1).
pub const PREFILTER_LEVELS: u32 = 5;
/// Face size of the prefiltered environment's level 0 (roughness 0).
pub const PREFILTER_SIZE: u32 = 32;
/// Side of the square split-sum table (n·v along x, roughness along y).
pub const LUT_SIZE: u32 = 32;
/// Samples per table entry.
pub const LUT_SAMPLES: u32 = 256;

/// The GGX normal distribution D(h) = α² / (π ((n·h)² (α² − 1) + 1)²) (Walter et al. 2007,
/// "Microfacet Models for Refraction through Rough Surfaces", eq. 33; Karis 2013 eq. 3).
pub fn ggx_d(n_dot_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith's geometry term with Schlick's G1 = (n·x) / ((n·x)(1 − k) + k), k = α/2 for
/// image-based light (Karis 2013 eq. 4 and the remark after it).
pub fn smith_g(n_dot_v: f32, n_dot_l: f32, roughness: f32) -> f32 {
    let k = roughness * roughness / 2.0;
    let g1 = |x: f32| x / (x * (1.0 - k) + k);
    g1(n_dot_v) * g1(n_dot_l)
}

/// The i-th of n points of the Hammersley set on [0, 1)²: (i/n, radical inverse of i in base 2).
pub fn hammersley(i: u32, n: u32) -> (f32, f32) {
    (i as f32 / n as f32, i.reverse_bits() as f32 * 2.328_306_4e-10)
}

/// A half vector around +z distributed as D(h)(n·h) (Karis 2013, ImportanceSampleGGX).
fn sample_half_vector((u, w): (f32, f32), alpha: f32) -> Vec3 {
    let phi = 2.0 * PI * u;
    let cos_t = ((1.0 - w) / (1.0 + (alpha * alpha - 1.0) * w)).sqrt();
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// The split-sum BRDF terms (A, B) at `n_dot_v` and `roughness`: the directional albedo of the
/// GGX microfacet BRDF with Schlick's Fresnel is F0·A + B (Karis 2013, IntegrateBRDF), by
/// importance sampling `samples` half vectors.
pub fn split_sum(n_dot_v: f32, roughness: f32, samples: u32) -> [f32; 2] {
    let n_dot_v = n_dot_v.clamp(1e-4, 1.0);
    let alpha = (roughness * roughness).max(1e-4);
    let v = Vec3::new((1.0 - n_dot_v * n_dot_v).sqrt(), 0.0, n_dot_v);
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for i in 0..samples {
        let h = sample_half_vector(hammersley(i, samples), alpha);
        let v_dot_h = v.dot(h);
        let l = 2.0 * v_dot_h * h - v;
        if l.z <= 0.0 {
            continue;
        }
        // f·(n·l)/pdf with pdf = D (n·h) / (4 v·h): D cancels.
        let g_vis = smith_g(n_dot_v, l.z, roughness) * v_dot_h.max(0.0) / (h.z * n_dot_v);
        let fc = (1.0 - v_dot_h.max(0.0)).powi(5);
        a += f64::from((1.0 - fc) * g_vis);
        b += f64::from(fc * g_vis);
    }
    [(a / f64::from(samples)) as f32, (b / f64::from(samples)) as f32]
}

/// The split-sum table: entry (x, y) of a `size`×`size` grid holds [`split_sum`] at texel
/// centres n·v = (x + ½)/size, roughness = (y + ½)/size (row-major, y = 0 first).
pub fn brdf_lut(size: u32, samples: u32) -> Vec<[f32; 2]> {
    let centre = |i: u32| (i as f32 + 0.5) / size as f32;
    (0..size).flat_map(|y| (0..size).map(move |x| split_sum(centre(x), centre(y), samples))).collect()
}

/// GGX roughness (perceptual, α = roughness²) for a Blinn-Phong exponent (MTL `Ns`): the
/// Beckmann α of a Phong exponent is √(2 / (Ns + 2)) (Walter et al. 2007 §5.2), used as GGX α
/// (the inverse of scene::model's glTF-roughness → exponent mapping).
pub fn roughness_from_exponent(exponent: f32) -> f32 {
    (2.0 / (exponent.max(0.0) + 2.0)).sqrt().sqrt()
}

/// Roughness of prefiltered level `level`.
pub fn level_roughness(level: u32) -> f32 {
    level as f32 / (PREFILTER_LEVELS - 1) as f32
}

/// `cube` averaged down (or sampled up) to `size`×`size` faces: each output texel is the mean of
/// the source texels whose centres fall inside it (the nearest one when none does).
pub fn resample(cube: &CubeMap, size: u32) -> CubeMap {
    let n = cube.size as usize;
    let s = size as usize;
    let faces = std::array::from_fn(|f| {
        let face = &cube.faces[f];
        let mut sum = vec![[0.0f32; 3]; s * s];
        let mut count = vec![0u32; s * s];
        for y in 0..n {
            for x in 0..n {
                let i = (y * s / n) * s + x * s / n;
                let p = face[y * n + x];
                for k in 0..3 {
                    sum[i][k] += p[k];
                }
                count[i] += 1;
            }
        }
        (0..s * s)
            .map(|i| {
                if count[i] > 0 {
                    sum[i].map(|v| v / count[i] as f32)
                } else {
                    let (x, y) = (i % s, i / s);
                    face[(y * n / s) * n + x * n / s]
                }
            })
            .collect()
    });
    CubeMap { size, faces }
}

/// The environment convolved with the GGX lobe for each roughness level (Karis 2013's
/// prefiltered environment, with his n = v = r assumption): level k (faces of
/// PREFILTER_SIZE >> k texels) at direction r is Σ L(l) D(r·h) (r·l) dω / Σ D(r·h) (r·l) dω over
/// the source texels l with r·l > 0, h = normalize(r + l). Level 0 is the map averaged down;
/// the source of level 1 is level 0, of the rougher levels the map at half that size. Directions
/// are cube-sampling directions, so the result is sampled exactly as the map is.
pub fn prefilter(cube: &CubeMap) -> Vec<CubeMap> {
    let base = resample(cube, PREFILTER_SIZE);
    let coarse = resample(&base, PREFILTER_SIZE / 2);
    let texels = |c: &CubeMap| -> Vec<(Vec3, [f32; 3], f32)> {
        let s = c.size;
        (0..6usize)
            .flat_map(|f| (0..s * s).map(move |i| (f, i % s, i / s)))
            .map(|(f, x, y)| {
                let d = face_uv_to_cube_dir(f, (x as f32 + 0.5) / s as f32, (y as f32 + 0.5) / s as f32);
                (d, c.faces[f][(y * s + x) as usize], texel_solid_angle(s, x, y))
            })
            .collect()
    };
    let fine = texels(&base);
    let rough = texels(&coarse);
    let mut levels = vec![base.clone()];
    for level in 1..PREFILTER_LEVELS {
        let alpha = level_roughness(level).powi(2);
        let size = (PREFILTER_SIZE >> level).max(1);
        let source = if level == 1 { &fine } else { &rough };
        let faces = std::array::from_fn(|f| {
            (0..size * size)
                .map(|i| {
                    let (x, y) = (i % size, i / size);
                    let r = face_uv_to_cube_dir(f, (x as f32 + 0.5) / size as f32, (y as f32 + 0.5) / size as f32);
                    let (mut acc, mut wsum) = ([0.0f32; 3], 0.0f32);
                    for &(l, radiance, omega) in source {
                        let r_dot_l = r.dot(l);
                        if r_dot_l <= 0.0 {
                            continue;
                        }
                        let h = (r + l).normalize();
                        let w = ggx_d(r.dot(h), alpha) * r_dot_l * omega;
                        for k in 0..3 {
                            acc[k] += w * radiance[k];
                        }
                        wsum += w;
                    }
                    acc.map(|v| if wsum > 0.0 { v / wsum } else { 0.0 })
                })
                .collect()
        });
        levels.push(CubeMap { size, faces });
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The directional albedo ∫ f (n·l) dω of the GGX BRDF with Schlick Fresnel of F0, by a
    /// midpoint rule over (θ_l, φ_l) on the hemisphere: an integration independent of the
    /// importance sampling in `split_sum`.
    fn albedo_brute_force(n_dot_v: f32, roughness: f32, f0: f32) -> f32 {
        let alpha = roughness * roughness;
        let v = Vec3::new((1.0 - n_dot_v * n_dot_v).sqrt(), 0.0, n_dot_v);
        let (nt, np) = (1200, 600);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let t = (i as f32 + 0.5) / nt as f32 * PI / 2.0;
            for j in 0..np {
                let p = (j as f32 + 0.5) / np as f32 * 2.0 * PI;
                let l = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                let h = (v + l).normalize();
                let f = f0 + (1.0 - f0) * (1.0 - v.dot(h)).powi(5);
                let brdf = ggx_d(h.z, alpha) * smith_g(n_dot_v, l.z, roughness) * f / (4.0 * l.z * n_dot_v);
                let d_omega = t.sin() * (PI / 2.0 / nt as f32) * (2.0 * PI / np as f32);
                sum += f64::from(brdf * l.z * d_omega);
            }
        }
        sum as f32
    }

    #[test]
    fn split_sum_matches_a_brute_force_integration_of_the_brdf() {
        for (n_dot_v, roughness) in [(0.5, 0.5), (0.9, 0.3), (0.2, 0.8), (0.7, 1.0)] {
            let [a, b] = split_sum(n_dot_v, roughness, 4096);
            let white = albedo_brute_force(n_dot_v, roughness, 1.0);
            let black = albedo_brute_force(n_dot_v, roughness, 0.0);
            assert!((a + b - white).abs() < 0.01, "n.v {n_dot_v} r {roughness}: A+B {} vs {white}", a + b);
            assert!((b - black).abs() < 0.005, "n.v {n_dot_v} r {roughness}: B {b} vs {black}");
        }
    }

    #[test]
    fn split_sum_of_a_smooth_mirror_seen_head_on_is_the_fresnel_f0() {
        // A near-mirror at normal incidence reflects F0: A → 1, B → 0 (Karis 2013 Fig. 3's
        // corner at n·v = 1, roughness 0).
        let [a, b] = split_sum(1.0, 0.02, 256);
        assert!((a - 1.0).abs() < 0.01 && b < 0.01, "A {a} B {b}");
        // Rough surfaces lose energy to single scattering: A + B < 1 at roughness 1.
        let [a, b] = split_sum(0.5, 1.0, 1024);
        assert!(a + b < 0.9 && a + b > 0.3, "A+B {}", a + b);
    }

    #[test]
    fn the_table_holds_split_sum_at_texel_centres() {
        let lut = brdf_lut(4, 64);
        assert_eq!(lut.len(), 16);
        // Entry (x = 1, y = 2): n·v = 0.375, roughness = 0.625.
        assert_eq!(lut[2 * 4 + 1], split_sum(0.375, 0.625, 64));
    }

    #[test]
    fn phong_exponent_maps_to_walters_beckmann_alpha() {
        // Walter et al. 2007: α = √(2 / (Ns + 2)); Ns 32 → α = √(2/34) = 0.24254.
        let r = roughness_from_exponent(32.0);
        assert!((r * r - 0.242_536).abs() < 1e-5, "{r}");
        // Ns 0 (no highlight) is the roughest surface.
        assert!((roughness_from_exponent(0.0) - 1.0).abs() < 1e-6);
        assert!(roughness_from_exponent(1000.0) < 0.25);
    }

    #[test]
    fn ggx_d_integrates_to_one_over_projected_area() {
        // ∫ D(h) (n·h) dω_h = 1 (Walter et al. 2007 eq. 4), by a midpoint rule in θ.
        for alpha in [0.1f32, 0.5, 1.0] {
            let n = 20000;
            let sum: f32 = (0..n)
                .map(|i| {
                    let t = (i as f32 + 0.5) / n as f32 * PI / 2.0;
                    ggx_d(t.cos(), alpha) * t.cos() * t.sin() * 2.0 * PI * (PI / 2.0 / n as f32)
                })
                .sum();
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
        }
    }

    #[test]
    fn prefiltering_keeps_a_constant_map_and_blurs_a_bright_spot() {
        let flat = CubeMap::solid_faces(8, [[0.3, 0.5, 0.7]; 6]);
        let levels = prefilter(&flat);
        assert_eq!(levels.len(), PREFILTER_LEVELS as usize);
        for (k, level) in levels.iter().enumerate() {
            assert_eq!(level.size, PREFILTER_SIZE >> k);
            for p in level.faces.iter().flatten() {
                assert!((p[0] - 0.3).abs() < 1e-4 && (p[2] - 0.7).abs() < 1e-4, "level {k}: {p:?}");
            }
        }
        // A bright patch on +Z spreads wider at each rougher level: the value 30° away from
        // it grows with roughness while the peak falls.
        let spot = CubeMap::from_fn(32, |d| if d.z > 0.99 { [100.0; 3] } else { [0.0; 3] });
        let levels = prefilter(&spot);
        let peak: Vec<f32> = levels.iter().map(|c| c.sample_enu(Vec3::Z)[0]).collect();
        assert!(peak.windows(2).all(|w| w[1] < w[0]), "peaks {peak:?}");
        let side = Vec3::new(0.5, 0.0, 0.866);
        let off: Vec<f32> = levels.iter().map(|c| c.sample_enu(side)[0]).collect();
        assert!(off[4] > off[1] && off[1] < 1.0, "30 degrees off the spot: {off:?}");
    }
}
