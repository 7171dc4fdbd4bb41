//! The colour-correction benchmark (`previz colour-transfer bench`): for every method, how close
//! the corrected image's colour distribution comes to the source's, and what the correction
//! costs per 960×640 frame in the shader (GPU timestamps) and in the CPU tool — all methods on
//! the same images in one run. Also the single-colour-texture figure for the docs.

use super::median;
use crate::colour::correction::ColourCorrection;
use crate::colour::distance::{sliced_wasserstein, subsample};
use crate::colour::gpu::CorrectPass;
use crate::colour::images::{apply, counted_linear, image_stats};
use crate::colour::lab::{LabSpace, rgb_to_lab};
use crate::colour::report::{Raster, SpeedPoint, montage, speed_accuracy_chart};
use crate::colour::stats::ColourStats;
use crate::colour::transfer::TransferMethod;
use crate::gpu::Gpu;
use crate::scene::Rgba8Image;
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The frame size costs are measured at.
pub const FRAME: (u32, u32) = (960, 640);
/// The methods measured: `none` first, the floor (a pass that only reads and writes the image).
pub const METHODS: [TransferMethod; 5] =
    [TransferMethod::None, TransferMethod::BrightnessContrast, TransferMethod::Reinhard, TransferMethod::CielabApprox, TransferMethod::Mkl];
/// Points per distribution for the sliced Wasserstein distance.
const SW_POINTS: usize = 20_000;

/// A source/target image pair.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PairSpec {
    pub name: String,
    pub source: PathBuf,
    pub target: PathBuf,
}

/// The pairs used by default: the two colour-transfer photos both ways, and two model textures
/// against a face of two real cube maps (`data` is the shared data folder).
pub fn default_pairs(data: &Path) -> Vec<PairSpec> {
    let p = |s: &str| data.join(s);
    let pair = |name: &str, s: &str, t: &str| PairSpec { name: name.into(), source: p(s), target: p(t) };
    vec![
        pair("astronaut→coffee", "photos/colour_transfer/astronaut.png", "photos/colour_transfer/coffee.png"),
        pair("coffee→astronaut", "photos/colour_transfer/coffee.png", "photos/colour_transfer/astronaut.png"),
        pair("Park2 +Z→spot texture", "cubemaps/humus_Park2/posz.jpg", "textured_models/spot/spot_texture.png"),
        pair("Bridge2 +X→milk truck", "cubemaps/humus_Bridge2/posx.jpg", "textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.png"),
    ]
}

/// Distance of a result's distribution from the source's, in log lαβ.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Accuracy {
    /// |μ_result − μ_source| per channel (l, α, β).
    pub mean_error: [f64; 3],
    /// |σ_result − σ_source| per channel.
    pub sigma_error: [f64; 3],
    /// Sliced Wasserstein-2 between the two point clouds.
    pub sliced_wasserstein: f64,
}

/// One method on one pair.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MethodRow {
    pub method: TransferMethod,
    /// Median CPU time to correct one 960×640 frame (the tool's per-pixel loop), ms.
    pub cpu_ms: f64,
    /// Median GPU time of the full-screen pass on one 960×640 frame (timestamps), ms.
    pub gpu_ms: Option<f64>,
    /// Accuracy of the CPU result.
    pub cpu: Accuracy,
    /// Accuracy of the GPU result (8-bit output of the shader).
    pub gpu: Option<Accuracy>,
    /// Fraction of pixels out of gamut after the correction (a channel below 0 or above 1).
    pub out_of_gamut_fraction: f64,
}

/// All methods on one pair.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PairRow {
    pub pair: PairSpec,
    pub uncorrected: Accuracy,
    pub methods: Vec<MethodRow>,
}

/// The whole run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchReport {
    pub device: Option<String>,
    pub frame: (u32, u32),
    pub repeats: u32,
    pub pairs: Vec<PairRow>,
}

fn lab_points(pixels: &[[f32; 3]]) -> Vec<DVec3> {
    subsample(pixels, SW_POINTS).iter().map(|p| rgb_to_lab(LabSpace::Log, Vec3::from_array(*p)).as_dvec3()).collect()
}

/// Accuracy of `result` (its counted pixels) against the source.
pub fn accuracy(result: &[[f32; 3]], source: &ColourStats, source_points: &[DVec3]) -> Result<Accuracy> {
    let stats = ColourStats::from_linear(result)?;
    let (sr, ss) = (stats.lab_sigma(), source.lab_sigma());
    let sw = sliced_wasserstein(&lab_points(result), source_points).context("empty point set")?;
    Ok(Accuracy {
        mean_error: [0, 1, 2].map(|i| (stats.lab_mean[i] - source.lab_mean[i]).abs()),
        sigma_error: [0, 1, 2].map(|i| (sr[i] - ss[i]).abs()),
        sliced_wasserstein: sw,
    })
}

/// `image` resized to `FRAME` (bilinear).
pub fn to_frame(image: &Rgba8Image) -> Result<Rgba8Image> {
    let img = image::RgbaImage::from_raw(image.width, image.height, image.pixels.clone()).context("image buffer has the wrong size")?;
    let r = image::imageops::resize(&img, FRAME.0, FRAME.1, image::imageops::FilterType::Triangle);
    Ok(Rgba8Image { width: FRAME.0, height: FRAME.1, pixels: r.into_raw() })
}

/// Run every method on every pair. `gpu` None: CPU only. `tick` is called after each method.
pub fn run(pairs: &[PairSpec], gpu: Option<&Gpu>, repeats: u32, mut tick: impl FnMut(&str)) -> Result<BenchReport> {
    let repeats = repeats.max(1);
    let pass = gpu.map(CorrectPass::new).transpose()?;
    let mut rows = Vec::new();
    for pair in pairs {
        let source = crate::colour::images::load_rgba8(&pair.source).with_context(|| format!("source of pair {}", pair.name))?;
        let target = to_frame(&crate::colour::images::load_rgba8(&pair.target).with_context(|| format!("target of pair {}", pair.name))?)?;
        let source_stats = image_stats(&source, false, "SOURCE")?;
        let source_points = lab_points(&counted_linear(&source, false));
        let target_stats = image_stats(&target, false, "TARGET")?;
        let uncorrected = accuracy(&counted_linear(&target, false), &source_stats, &source_points)?;
        let mut methods = Vec::new();
        for method in METHODS {
            let cc = ColourCorrection::new(method, 1.0, &source_stats, &target_stats);
            let mut times = Vec::new();
            let mut result = None;
            for _ in 0..repeats {
                let t = Instant::now();
                let r = apply(&target, &cc, false);
                times.push(t.elapsed().as_secs_f64() * 1e3);
                result = Some(r);
            }
            let Some(result) = result else { continue };
            let cpu = accuracy(&counted_linear(&result.image, false), &source_stats, &source_points)?;
            let (gpu_ms, gpu_acc) = match (gpu, &pass) {
                (Some(gpu), Some(pass)) => {
                    // One warm-up frame, then `repeats` timed frames in one submission.
                    pass.run(gpu, &target, &cc, 1)?;
                    let (image, times) = pass.run(gpu, &target, &cc, repeats)?;
                    (times.map(|t| median(&t)), Some(accuracy(&counted_linear(&image, false), &source_stats, &source_points)?))
                }
                _ => (None, None),
            };
            methods.push(MethodRow {
                method,
                cpu_ms: median(&times),
                gpu_ms,
                cpu,
                gpu: gpu_acc,
                out_of_gamut_fraction: result.out_of_gamut as f64 / (target.width * target.height) as f64,
            });
            tick(&format!("{} {}", pair.name, method.name()));
        }
        rows.push(PairRow { pair: pair.clone(), uncorrected, methods });
    }
    Ok(BenchReport { device: gpu.map(|g| g.describe()), frame: FRAME, repeats, pairs: rows })
}

/// Per method, averaged over the pairs: (method, cpu ms, gpu ms, SW, mean |Δμ|, mean |Δσ|).
/// `none` is the floor: decoding, encoding and (GPU) the pass itself, no correction.
pub fn summary(report: &BenchReport) -> Vec<(TransferMethod, f64, Option<f64>, f64, f64, f64)> {
    METHODS
        .iter()
        .map(|&m| {
            let rows: Vec<&MethodRow> = report.pairs.iter().flat_map(|p| p.methods.iter().filter(move |r| r.method == m)).collect();
            let n = rows.len().max(1) as f64;
            let avg = |f: &dyn Fn(&MethodRow) -> f64| rows.iter().map(|r| f(r)).sum::<f64>() / n;
            let gpu =
                if rows.iter().all(|r| r.gpu_ms.is_some()) && !rows.is_empty() { Some(avg(&|r| r.gpu_ms.unwrap_or(0.0))) } else { None };
            (
                m,
                avg(&|r| r.cpu_ms),
                gpu,
                avg(&|r| r.cpu.sliced_wasserstein),
                avg(&|r| r.cpu.mean_error.iter().sum::<f64>() / 3.0),
                avg(&|r| r.cpu.sigma_error.iter().sum::<f64>() / 3.0),
            )
        })
        .collect()
}

fn uncorrected_mean(report: &BenchReport) -> f64 {
    report.pairs.iter().map(|p| p.uncorrected.sliced_wasserstein).sum::<f64>() / report.pairs.len().max(1) as f64
}

/// The report as markdown tables.
pub fn markdown(report: &BenchReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Frame {}×{}, median of {} runs; device: {}.\n",
        report.frame.0,
        report.frame.1,
        report.repeats,
        report.device.as_deref().unwrap_or("none (CPU only)")
    );
    let _ = writeln!(
        s,
        "Averaged over {} image pairs (accuracy in log lαβ; SW = sliced Wasserstein-2 to the source; uncorrected SW = {:.4}):\n",
        report.pairs.len(),
        uncorrected_mean(report)
    );
    let rows = summary(report);
    let floor = rows.iter().find(|r| r.0 == TransferMethod::None).map(|r| (r.1, r.2));
    let _ = writeln!(
        s,
        "| method | GPU ms/frame | GPU ms above `none` | CPU ms/frame | CPU ms above `none` | CPU/GPU | SW to source | mean abs Δμ | mean abs Δσ |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &(m, cpu, gpu, sw, dm, ds) in &rows {
        let (g, g_above, ratio) = match gpu {
            Some(g) => {
                let above = floor.and_then(|f| f.1).map(|f| format!("{:.2}", g - f)).unwrap_or_else(|| "–".into());
                (format!("{g:.2}"), above, format!("{:.1}×", cpu / g))
            }
            None => ("–".into(), "–".into(), "–".into()),
        };
        let c_above = floor.map(|f| format!("{:.1}", cpu - f.0)).unwrap_or_else(|| "–".into());
        let _ = writeln!(s, "| {} | {g} | {g_above} | {cpu:.1} | {c_above} | {ratio} | {sw:.4} | {dm:.4} | {ds:.4} |", m.name());
    }
    let _ = writeln!(s, "\nPer pair (CPU result; GPU result SW in brackets):\n");
    let _ = writeln!(s, "| pair | uncorrected SW | {} |", METHODS.map(|m| m.name()).join(" | "));
    let _ = writeln!(s, "|---|---:|{}", "---:|".repeat(METHODS.len()));
    for p in &report.pairs {
        let cells: Vec<String> = p
            .methods
            .iter()
            .map(|r| match &r.gpu {
                Some(g) => format!("{:.4} [{:.4}]", r.cpu.sliced_wasserstein, g.sliced_wasserstein),
                None => format!("{:.4}", r.cpu.sliced_wasserstein),
            })
            .collect();
        let _ = writeln!(s, "| {} | {:.4} | {} |", p.pair.name, p.uncorrected.sliced_wasserstein, cells.join(" | "));
    }
    s
}

/// The speed-vs-accuracy chart of a run.
pub fn chart(report: &BenchReport) -> Result<Raster> {
    let mut points = Vec::new();
    for (m, cpu, gpu, sw, _, _) in summary(report) {
        let label_above = matches!(m, TransferMethod::None | TransferMethod::Reinhard);
        points.push(SpeedPoint { label: m.name().to_string(), ms: cpu, distance: sw, gpu: false, label_above });
        if let Some(g) = gpu {
            points.push(SpeedPoint { label: m.name().to_string(), ms: g, distance: sw, gpu: true, label_above });
        }
    }
    let device = report.device.as_deref().map(|d| d.split(" (").next().unwrap_or(d).to_string()).unwrap_or_else(|| "CPU only".into());
    speed_accuracy_chart(&points, uncorrected_mean(report), &format!("{} pairs, {device}", report.pairs.len()))
}

/// A Lambert-shaded sphere of one sRGB colour on a transparent background: what a model with a
/// single-colour texture looks like when rendered.
pub fn shaded_sphere(size: u32, srgb: [u8; 3]) -> Rgba8Image {
    let lut = crate::colour::stats::srgb8_to_linear_table();
    let albedo = Vec3::new(lut[srgb[0] as usize], lut[srgb[1] as usize], lut[srgb[2] as usize]);
    let light = Vec3::new(-0.4, 0.5, 0.77).normalize();
    let r = size as f32 * 0.45;
    let c = size as f32 * 0.5;
    let mut pixels = Vec::with_capacity((size * size * 4) as usize);
    for y in 0..size {
        for x in 0..size {
            let (dx, dy) = ((x as f32 + 0.5 - c) / r, (c - y as f32 - 0.5) / r);
            let d2 = dx * dx + dy * dy;
            if d2 > 1.0 {
                pixels.extend([0, 0, 0, 0]);
                continue;
            }
            let n = Vec3::new(dx, dy, (1.0 - d2).sqrt());
            let lit = albedo * (0.12 + 0.88 * n.dot(light).max(0.0));
            pixels.extend([0, 1, 2].map(|i| (crate::colour::linear_to_srgb(lit[i]) * 255.0).round() as u8));
            pixels.push(255);
        }
    }
    Rgba8Image { width: size, height: size, pixels }
}

/// The seed's published colour transfer (Eq. 11a space, Eq. 11b gains σ_t/σ_s as printed), for
/// comparison only.
pub fn seed_eq11b(source: &ColourStats, target: &ColourStats) -> ColourCorrection {
    manual_diagonal(LabSpace::Linear, source, target, |s, t| if s > 0.0 { t / s } else { 0.0 })
}

/// Reinhard 2001 without our guards: gains σ_s / max(σ_t, 1e-6), for comparison only.
pub fn unguarded_reinhard(source: &ColourStats, target: &ColourStats) -> ColourCorrection {
    manual_diagonal(LabSpace::Log, source, target, |s, t| s / t.max(1e-6))
}

fn manual_diagonal(space: LabSpace, source: &ColourStats, target: &ColourStats, gain: impl Fn(f64, f64) -> f64) -> ColourCorrection {
    let (cs, ct) = (source.cov_in(space), target.cov_in(space));
    let g = DVec3::from_array([0, 1, 2].map(|i| gain(cs.col(i)[i].max(0.0).sqrt(), ct.col(i)[i].max(0.0).sqrt())));
    let offset = source.mean_in(space) - g * target.mean_in(space);
    let mut cc = ColourCorrection::identity();
    cc.method = if space == LabSpace::Log { TransferMethod::Reinhard.shader_id() } else { TransferMethod::CielabApprox.shader_id() };
    cc.strength = 1.0;
    cc.transfer = [[g.x as f32, 0.0, 0.0, 0.0], [0.0, g.y as f32, 0.0, 0.0], [0.0, 0.0, g.z as f32, 0.0]];
    cc.offset = offset.as_vec3().to_array();
    cc
}

/// The single-colour-texture case (seed Fig. 33): a sphere whose texture is one colour (σ = 0),
/// corrected towards an environment by the seed's formula, by unguarded Reinhard and by ours.
pub fn single_colour_figure(environment: &Rgba8Image, environment_stats: &ColourStats, albedo_srgb: [u8; 3]) -> Result<Raster> {
    let size = 200;
    let sphere = shaded_sphere(size, albedo_srgb);
    let lut = crate::colour::stats::srgb8_to_linear_table();
    let texture_stats = ColourStats::from_linear(&[albedo_srgb.map(|c| lut[c as usize])])?;
    let env_tile = {
        let img = image::RgbaImage::from_raw(environment.width, environment.height, environment.pixels.clone())
            .context("environment image has the wrong size")?;
        let r = image::imageops::resize(&img, size, size, image::imageops::FilterType::Triangle);
        Rgba8Image { width: size, height: size, pixels: r.into_raw() }
    };
    let fix = |cc: ColourCorrection| apply(&sphere, &cc, false).image;
    let ours_at = |m: TransferMethod, strength: f32| fix(ColourCorrection::new(m, strength, environment_stats, &texture_stats));
    let ours = |m: TransferMethod| ours_at(m, 1.0);
    let tiles = [
        ("environment (one face)", env_tile),
        ("model, uncorrected", sphere.clone()),
        ("seed Eq. 11b", fix(seed_eq11b(environment_stats, &texture_stats))),
        ("Reinhard, unguarded", fix(unguarded_reinhard(environment_stats, &texture_stats))),
        ("reinhard (ours)", ours(TransferMethod::Reinhard)),
        ("reinhard, strength 0.5", ours_at(TransferMethod::Reinhard, 0.5)),
        ("cielab-approx (ours)", ours(TransferMethod::CielabApprox)),
        ("mkl (ours)", ours(TransferMethod::Mkl)),
        ("brightness-contrast", ours(TransferMethod::BrightnessContrast)),
    ];
    let refs: Vec<(&str, &Rgba8Image)> = tiles.iter().map(|(l, t)| (*l, t)).collect();
    montage(&refs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_is_single_albedo_with_shading() {
        let s = shaded_sphere(32, [200, 40, 30]);
        let visible: Vec<&[u8]> = s.pixels.chunks(4).filter(|p| p[3] == 255).collect();
        assert!(visible.len() > 400 && visible.len() < 32 * 32);
        // Lit side brighter than the shadow side; hue stays red.
        assert!(visible.iter().all(|p| p[0] >= p[1] && p[0] >= p[2]));
        assert!(visible.iter().map(|p| p[0]).max() > visible.iter().map(|p| p[0]).min());
    }

    #[test]
    fn guarded_methods_keep_single_colour_shading_unlike_the_seed() {
        // Source: a varied image; target prior: one colour. Ours keeps the sphere's shading
        // (several distinct output values); the seed's σ_t/σ_s = 0 flattens it to one colour.
        let env: Vec<[f32; 3]> = crate::colour::transfer::tests::cloud(500, [0.3, 0.35, 0.4], [0.4, 0.4, 0.4], 0.1);
        let env_stats = ColourStats::from_linear(&env).unwrap();
        let sphere = shaded_sphere(24, [200, 40, 30]);
        let tex = ColourStats::from_linear(&[[0.58, 0.02, 0.013]]).unwrap();
        let distinct = |img: &Rgba8Image| {
            let mut v: Vec<[u8; 3]> = img.pixels.chunks(4).filter(|p| p[3] > 0).map(|p| [p[0], p[1], p[2]]).collect();
            v.sort();
            v.dedup();
            v.len()
        };
        assert_eq!(distinct(&apply(&sphere, &seed_eq11b(&env_stats, &tex), false).image), 1);
        let ours = apply(&sphere, &ColourCorrection::new(TransferMethod::Reinhard, 1.0, &env_stats, &tex), false).image;
        assert!(distinct(&ours) > 20, "{}", distinct(&ours));
    }
}
