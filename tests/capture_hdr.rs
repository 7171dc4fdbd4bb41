//! Exposure in captures (issue 12): a phone left to auto-expose and auto-white-balance between
//! shots records seams; locking both at the tap (the default) or estimating each shot's gain
//! from the overlaps removes them. Exposure brackets merged into HDR faces measure the sky and
//! the sun's surroundings: the assembled luminance against the source's. Virtual phone in the
//! quarry HDR.

use crate::common;

use common::data;
use previz::capture::guided_path::simulate_capture_path;
use previz::capture::projection::{face_pixel_dir_local, local_to_world};
use previz::capture::replay::{ReplayConfig, ReplayResult, replay};
use previz::capture::{Assistant, Face, Mode};
use previz::colour::luminance_bt709;
use previz::pose::hand_motion::{UserPathParams, simulate_user_path};
use previz::pose::trace::TruthTrace;
use previz::scene::CubeMap;
use previz::scene::environment::load_environment;
use previz::sensors::sim::NoiseLevel;
use std::sync::Arc;

fn quarry() -> Arc<CubeMap> {
    Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap())
}

fn config(vfov_deg: f32, seed: u64, size: (u32, u32), face_size: u32) -> ReplayConfig {
    ReplayConfig {
        mode: Mode::Stitch,
        noise: NoiseLevel::Phone,
        seed,
        vfov_deg,
        width: size.0,
        height: size.1,
        face_size,
        render_threads: 2,
        ..ReplayConfig::default()
    }
}

fn trace(cfg: &ReplayConfig, seed: u64) -> TruthTrace {
    let targets: Vec<_> = Assistant::new(cfg.assistant().unwrap()).unwrap().targets().into_iter().cloned().collect();
    TruthTrace::new(simulate_capture_path(seed, &targets, &UserPathParams::default()).unwrap().samples).unwrap()
}

/// Mean stitch PSNR (dB) and FLIP over the faces.
fn scores(r: &ReplayResult) -> (f64, f64) {
    let n = r.faces.len() as f64;
    (
        r.faces.iter().map(|f| f.stitch_psnr_db.unwrap()).sum::<f64>() / n,
        r.faces.iter().map(|f| f64::from(f.stitch_flip.unwrap())).sum::<f64>() / n,
    )
}

/// Spread of the shots' exposures (stops, max/min) and of their red/blue white balance ratio.
fn spread(r: &ReplayResult) -> (f64, f64) {
    let shots = &r.capture.as_ref().unwrap().meta.shots;
    let e: Vec<f64> = shots.iter().map(|s| f64::from(s.exposure.unwrap()).log2()).collect();
    let wb: Vec<f64> = shots.iter().map(|s| s.white_balance.unwrap()).map(|w| f64::from(w[0] / w[2]).log2()).collect();
    let range = |v: &[f64]| v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min);
    (range(&e), range(&wb))
}

/// (lock, gain compensation) cases, in the order the study prints them.
const CASES: [(bool, bool); 4] = [(true, true), (true, false), (false, false), (false, true)];

fn run_cases(env: &Arc<CubeMap>, vfov: f32, seed: u64, size: (u32, u32), face: u32) -> Vec<ReplayResult> {
    let t = trace(&config(vfov, seed, size, face), seed);
    CASES
        .iter()
        .map(|&(lock, gain)| {
            let cfg = ReplayConfig { lock_exposure: lock, gain_compensation: Some(gain), ..config(vfov, seed, size, face) };
            let r = replay(env, &t, &cfg).unwrap();
            assert!(r.incomplete.is_none(), "seed {seed} lock {lock} gain {gain}: {:?}", r.incomplete);
            r
        })
        .collect()
}

#[test]
fn unlocked_exposure_leaves_seams_that_the_lock_or_the_gains_remove() {
    let env = quarry();
    let r = run_cases(&env, 100.0, 1, (160, 120), 32);
    let s: Vec<(f64, f64)> = r.iter().map(scores).collect();
    let (ev, wb) = spread(&r[2]);
    eprintln!(
        "locked+gain {:?}, locked {:?}, unlocked {:?}, unlocked+gain {:?}; unlocked spread {ev:.2} EV, R/B {wb:.2} stops",
        s[0], s[1], s[2], s[3]
    );
    // Unlocked, the shots' exposures differ (the view turns from sky to rock) ...
    assert!(ev > 0.5, "exposure spread {ev} EV");
    // ... the faces are worse than locked ones, and the gains from the overlaps bring them back.
    assert!(s[2].0 < s[1].0 - 3.0, "unlocked {:?} vs locked {:?}", s[2], s[1]);
    assert!(s[3].0 > s[2].0 + 3.0, "unlocked with gains {:?} vs without {:?}", s[3], s[2]);
    // Locked, the estimated gains are 1 within a few percent; estimating them anyway costs a
    // little (the pose's residual error against the sky's gradient reads as a 1 % gain), so a
    // locked capture does not (ReplayConfig::gain_compensation None).
    for g in r[0].capture.as_ref().unwrap().meta.shots.iter().map(|s| s.gain.unwrap()) {
        assert!(g.iter().all(|v| (v - 1.0).abs() < 0.05), "{g:?}");
    }
    assert!(s[0].0 > s[1].0 - 1.5, "locked with / without gains {:?} {:?}", s[0], s[1]);
    assert!(r[1].capture.as_ref().unwrap().meta.shots.iter().all(|s| s.gain.is_none()));
}

/// The table in docs/capture.md: `cargo test --test integration capture_hdr::exposure_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn exposure_study() {
    let env = quarry();
    println!(
        "| lens | lock | gains | seeds | stitch PSNR (dB) | stitch FLIP | shots' exposure spread (EV) | R/B white balance spread (stops) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for vfov in [50.0f32, 100.0] {
        let seeds = [0u64, 1, 2, 3];
        let mut acc = vec![(0.0, 0.0, 0.0, 0.0); CASES.len()];
        for &seed in &seeds {
            let r = run_cases(&env, vfov, seed, (320, 240), 64);
            for (k, r) in r.iter().enumerate() {
                let (p, f) = scores(r);
                let (e, w) = spread(r);
                acc[k].0 += p / seeds.len() as f64;
                acc[k].1 += f / seeds.len() as f64;
                acc[k].2 += e / seeds.len() as f64;
                acc[k].3 += w / seeds.len() as f64;
            }
        }
        for (k, (lock, gain)) in CASES.iter().enumerate() {
            let (p, f, e, w) = acc[k];
            println!(
                "| {vfov}° | {} | {} | {} | {p:.1} | {f:.3} | {e:.2} | {w:.2} |",
                if *lock { "yes" } else { "no" },
                if *gain { "yes" } else { "no" },
                seeds.len()
            );
        }
    }
}

/// Share of the HDR faces' texels whose luminance is within 10 % of the source's, the source
/// clipped per channel where even the darkest bracket clipped (the capture's `clip_radiance`),
/// compared at the front shot's true heading (the stitch's own frame, as `stitch_psnr_db`).
fn hdr_within_10_percent(env: &CubeMap, r: &ReplayResult, true_front_deg: f64) -> (f64, f64) {
    let cap = r.capture.as_ref().unwrap();
    let hdr = cap.hdr.as_ref().expect("an HDR capture");
    let clip = cap.meta.hdr.as_ref().unwrap().clip_radiance;
    let size = cap.meta.face_size;
    let to_world = local_to_world(true_front_deg.to_radians()).as_quat();
    let (mut within, mut n, mut max_ratio) = (0usize, 0usize, 0f64);
    for face in Face::ALL {
        for (i, got) in hdr[face.layer()].iter().enumerate() {
            let d = to_world * face_pixel_dir_local(face.layer(), i as u32 % size, i as u32 / size, size, 1.0);
            let src = env.sample_enu(d);
            let want = luminance_bt709([0, 1, 2].map(|c| src[c].min(clip[c])));
            let ratio = f64::from(luminance_bt709(*got) / want.max(1e-12));
            max_ratio = max_ratio.max(ratio.max(1.0 / ratio));
            within += usize::from((ratio - 1.0).abs() <= 0.10);
            n += 1;
        }
    }
    (within as f64 / n as f64, max_ratio)
}

fn front_true_heading(trace: &TruthTrace, r: &ReplayResult) -> f64 {
    previz::pose::frames::heading_pitch_roll(trace.orientation_at(r.tap_t.unwrap())).heading.to_degrees()
}

#[test]
fn an_hdr_capture_measures_the_sky_within_ten_percent() {
    let env = quarry();
    let mut cfg = ReplayConfig { hdr: true, noise: NoiseLevel::None, ..config(100.0, 2, (640, 480), 64) };
    cfg.score = false;
    let t = trace(&cfg, 2);
    let r = replay(&env, &t, &cfg).unwrap();
    let (share, worst) = hdr_within_10_percent(&env, &r, front_true_heading(&t, &r));
    let cap = r.capture.as_ref().unwrap();
    let clip = cap.meta.hdr.as_ref().unwrap().clip_radiance;
    let max = cap.hdr.as_ref().unwrap().iter().flatten().map(|p| luminance_bt709(*p)).fold(0.0, f32::max);
    eprintln!("within 10 %: {:.2} % of texels (worst ratio {worst:.2}); brightest texel {max:.1}, clip {clip:?}", 100.0 * share);
    // The 8-bit faces clip at radiance ~5 / exposure (the tone curve's code 255); the HDR
    // faces measure up to 16 times that (the −4 EV bracket); around the quarry's sun they
    // hold several times it.
    let clip_8bit = f64::from(previz::camera::exposure::saturation_exposed() / cap.meta.exposure.unwrap());
    assert!(f64::from(max) > 4.0 * clip_8bit, "{max} vs 8-bit clip {clip_8bit}");
    assert!(share >= 0.99, "{share}");
}

/// Issue 12's HDR goal at `phone` noise: the assembled luminance within 10 % of the source over
/// 99 % of texels (100° lens, the study's 640×480 frames and 128 px faces). The shots' poses
/// after the joint refinement err only by the capture's common tilt, which moves every
/// high-contrast edge; with the vertical from the accelerometer held before each shot
/// (`capture::gravity`) seeds 0 and 1 went from 96.30 % and 97.71 % (the tilt from the mean of the
/// fusion filter's tilts, 0.15–0.3° off) to over 99.8 % (`hdr_study`, 2026-12-01).
#[test]
fn an_hdr_capture_at_phone_noise_measures_the_sky_within_ten_percent() {
    let env = quarry();
    for seed in [0u64, 1] {
        let mut cfg = ReplayConfig { hdr: true, ..config(100.0, seed, (640, 480), 128) };
        cfg.score = false;
        let t = trace(&cfg, seed);
        let r = replay(&env, &t, &cfg).unwrap();
        assert!(r.incomplete.is_none(), "seed {seed}: {:?}", r.incomplete);
        let (share, _) = hdr_within_10_percent(&env, &r, front_true_heading(&t, &r));
        let alignment = r.capture.as_ref().unwrap().meta.alignment.unwrap();
        eprintln!("seed {seed}: within 10 %: {:.2} % of texels; {alignment:?}", 100.0 * share);
        assert!(alignment.vertical_shots >= 5, "seed {seed}: {alignment:?}");
        assert!(share >= 0.99, "seed {seed}: {share}");
    }
}

/// Irradiance (luminance) on a plane facing `s`, from every texel of a cube in its own frame.
fn facing_irradiance(cube: &CubeMap, s: glam::Vec3, clip: Option<[f32; 3]>) -> f64 {
    previz::light::samples::from_cube(cube)
        .iter()
        .map(|t| {
            let l = clip.map_or(t.radiance, |c| [0, 1, 2].map(|k| t.radiance[k].min(c[k])));
            f64::from(luminance_bt709(l) * t.dir.dot(s).max(0.0) * t.solid_angle)
        })
        .sum()
}

/// The HDR rows of docs/capture.md: `cargo test --test integration capture_hdr::hdr_study -- --ignored --nocapture`.
#[test]
#[ignore]
fn hdr_study() {
    let env = quarry();
    let sun = previz::light::sun_finder::find_sun(&previz::light::samples::from_cube(&env), &Default::default()).unwrap().dir;
    println!(
        "| noise | lens | seeds | texels within 10 % (mean, worst seed) | sun-facing irradiance, capture / source | same, source clipped where the brackets clip |"
    );
    println!("|---|---|---|---|---|---|");
    for noise in [NoiseLevel::None, NoiseLevel::Phone] {
        // The guided user with each lens, and the held-out six-face paths (seeds 2000–2003).
        for (vfov, six) in [(100.0f32, false), (50.0, false), (100.0, true)] {
            let seeds = [0u64, 1, 2, 3];
            let (mut share, mut worst, mut ratio, mut ratio_clipped) = (0.0, 1f64, 0.0, 0.0);
            for &seed in &seeds {
                let seed = if six { 2000 + seed } else { seed };
                let mut cfg = ReplayConfig { hdr: true, noise, ..config(vfov, seed, (640, 480), 128) };
                cfg.score = false;
                let t = if six {
                    TruthTrace::new(simulate_user_path(seed, &UserPathParams::default()).unwrap().samples).unwrap()
                } else {
                    trace(&cfg, seed)
                };
                let r = replay(&env, &t, &cfg).unwrap();
                assert!(r.incomplete.is_none(), "{:?}", r.incomplete);
                let front = front_true_heading(&t, &r);
                let (s, _) = hdr_within_10_percent(&env, &r, front);
                let cap = r.capture.as_ref().unwrap();
                let clip = cap.meta.hdr.as_ref().unwrap().clip_radiance;
                let s_local = previz::capture::targets::world_to_local(front).as_quat() * sun;
                let e_cap = facing_irradiance(&cap.to_cube_map(), s_local, None);
                share += s / seeds.len() as f64;
                worst = worst.min(s);
                ratio += e_cap / facing_irradiance(&env, sun, None) / seeds.len() as f64;
                ratio_clipped += e_cap / facing_irradiance(&env, sun, Some(clip)) / seeds.len() as f64;
            }
            println!(
                "| {} | {vfov}°{} | {} | {:.2} % ({:.2} %) | {ratio:.3} | {ratio_clipped:.3} |",
                noise.name(),
                if six { " six-face paths" } else { "" },
                seeds.len(),
                100.0 * share,
                100.0 * worst
            );
        }
    }
}
