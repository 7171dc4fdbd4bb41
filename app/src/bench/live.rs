//! `previz bench live`: the live loop stage by stage — camera frame, sensors + fusion, sun,
//! compositor — on the virtual phone and phone-grade simulated sensors.

use super::{median, percentile};
use crate::gpu::Gpu;
use crate::live::{LiveConfig, LiveSession};
use crate::sensors::sim::NoiseLevel;
use crate::setup::Inputs;
use crate::setup::scene_file::Scene;
use anyhow::{Result, anyhow};
use std::sync::Arc;

/// The stages, in the order of a frame (the compositor's GPU time, then its CPU encode and the
/// wall time from submit until the pixels are in memory), then the floor: the same frame's
/// background alone (rendered after it, not part of the frame), what issue 11 compares the
/// compositor with.
pub const STAGES: [&str; 19] = [
    "camera frame (virtual phone, CPU) + upload",
    "sensors + fusion",
    "sun (SPA)",
    "compositor (GPU)",
    "compositor: CPU encode (uniforms, ground regions, passes)",
    "compositor: submit until the pixels are in memory (wall)",
    "whole frame incl. readback (wall)",
    "floor: background only (GPU)",
    "environment fold: frame's thread (fold, readback, writes; when applied)",
    "environment fold: its own thread (prefilter, priors, SH9)",
    "profile: compositor with each pass timed alone (GPU, sum)",
    "profile: shadow pass (when drawn)",
    "profile: background pass",
    "profile: model pass",
    "profile: ground pass",
    "model turning 2 deg a frame: frame's thread (uniforms, ground map, encode), rays on the worker",
    "same, the frame waiting for the ground's rays (before issue 9's worker)",
    "sky changing every frame (as a refold changes it): frame's thread (uniforms, ground map recombined, encode)",
    "compositor, every frame shading its model and ground (reprojection off; GPU)",
];
/// Index of the compositor's row in [`STAGES`], of the floor's, and of the fold's.
pub const COMPOSITOR: usize = 3;
pub const FLOOR: usize = 7;
pub const FOLD: usize = 8;
pub const FOLD_THREAD: usize = 9;
/// Index of the profile's first row: after the measured frames, as many again with each pass
/// timed alone (`Compositor::set_pass_timing`), then the passes one by one.
pub const PROFILE: usize = 10;
/// Index of the turning model's rows: after the profile, as many frames again turning the model
/// 2° each (a new placement every frame: the ground's rays cast again), timed on the frame's
/// thread with the rays on the worker, then as many waiting for them.
pub const TURN: usize = 15;
/// Index of the changing sky's row: after the turning model, as many frames again with a new
/// sky shape each (one bin of the sky's radiance 1/32 brighter, round the bins: the ground's map
/// recombined from its kept rays every frame, as each refold of the camera frame makes it).
pub const SKY: usize = 17;
/// Index of the row without reprojection: after the changing sky, as many frames again with
/// reprojection off (render::reprojection), every frame shading its model and ground: the
/// compositor row's alternative, in the same run.
pub const SHADED: usize = 18;

/// One stage's median and 95th percentile, ms.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageRow {
    pub stage: &'static str,
    pub median_ms: f64,
    pub p95_ms: f64,
}

/// Run `warmup` + `frames` frames of a simulated session (Bristol, 2026-06-21 15:00 +01:00,
/// 30 frames per second) and time each stage of the measured ones. The session folds the camera
/// frame into its environment as the app does before a capture; the fold's row is over the
/// frames that refreshed it (`live::FOLD_REFRESH_DEG`, `live::FOLD_REFRESH_S`).
pub fn run(gpu: &Gpu, scene: &Scene, inputs: Inputs, frames: usize, warmup: usize, progress: &indicatif::ProgressBar) -> Result<LiveBench> {
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T15:00:00+01:00")?.with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: ((6 * frames + warmup) as f64 / 30.0).ceil() + 1.0,
        noise: NoiseLevel::Phone,
        seed: 1,
    };
    let mut session = LiveSession::simulated(gpu, Arc::new(inputs.env), &inputs.model, scene, cfg)?;
    session.fold_camera_into_environment();
    progress.set_length((frames + warmup) as u64);
    let mut samples: [Vec<f64>; STAGES.len()] = Default::default();
    let mut reprojected = 0;
    for i in 0..frames + warmup {
        let t = std::time::Instant::now();
        let folds = session.fold_refreshes().map_or(0, |r| r.0);
        let f = session.advance(gpu)?.ok_or_else(|| anyhow!("the simulated session ended early"))?;
        let fold = session.fold_refreshes().filter(|r| r.0 > folds);
        let r = session.render(gpu)?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let floor = session.render_layer(gpu, crate::render::Layer::Background)?;
        if i >= warmup {
            reprojected += usize::from(r.timings.reprojected);
            let gpu_ms = |r: &crate::render::Rendered| r.timings.gpu_ms.unwrap_or(f64::NAN);
            let (encode, submitted) = (r.timings.encode_ms, r.timings.readback_ms);
            for (v, x) in samples.iter_mut().zip([f.camera_ms, f.pose_ms, f.sun_ms, gpu_ms(&r), encode, submitted, wall, gpu_ms(&floor)]) {
                v.push(x);
            }
            if let Some((_, frame_ms, cpu_ms)) = fold {
                samples[FOLD].push(frame_ms);
                samples[FOLD_THREAD].push(cpu_ms);
            }
        }
        progress.inc(1);
    }
    // The profile: the same session going on, each pass timed alone.
    session.set_pass_timing(true);
    progress.set_length((2 * frames + warmup) as u64);
    let mut counts = Vec::new();
    for _ in 0..frames {
        session.advance(gpu)?.ok_or_else(|| anyhow!("the simulated session ended early"))?;
        let r = session.render(gpu)?;
        counts.extend(r.timings.counts);
        if let Some(p) = r.timings.passes {
            for (v, x) in samples[PROFILE..].iter_mut().zip([Some(p.total()), p.shadow, p.background, p.model, p.ground]) {
                v.extend(x);
            }
        }
        progress.inc(1);
    }
    session.set_pass_timing(false);
    // The model turning: each frame a new placement. With the rays on the worker the frame keeps
    // the last map that arrived; waiting, it casts them itself.
    progress.set_length((4 * frames + warmup) as u64);
    for (row, background) in [(TURN, true), (TURN + 1, false)] {
        session.set_ground_in_background(background);
        for _ in 0..frames {
            session.advance(gpu)?.ok_or_else(|| anyhow!("the simulated session ended early"))?;
            session.params_mut().placement.rotation.z += 2f32.to_radians();
            let r = session.render(gpu)?;
            samples[row].push(r.timings.encode_ms);
            progress.inc(1);
        }
    }
    session.set_ground_in_background(true);
    // The sky changing: each frame a sky shape no kept map was made for.
    progress.set_length((5 * frames + warmup) as u64);
    for i in 0..frames {
        session.advance(gpu)?.ok_or_else(|| anyhow!("the simulated session ended early"))?;
        let bins = &mut session.params_mut().lighting.sky_radiance.bins;
        bins[i % bins.len()] += 1.0 / 32.0;
        let r = session.render(gpu)?;
        samples[SKY].push(r.timings.encode_ms);
        progress.inc(1);
    }
    // Every frame shaded: the compositor's alternative without reprojection.
    session.shade_every_frame(gpu)?;
    progress.set_length((6 * frames + warmup) as u64);
    for _ in 0..frames {
        session.advance(gpu)?.ok_or_else(|| anyhow!("the simulated session ended early"))?;
        let r = session.render(gpu)?;
        samples[SHADED].push(r.timings.gpu_ms.unwrap_or(f64::NAN));
        progress.inc(1);
    }
    // The profile's frame whose model pass drew the median count of fragments.
    counts.sort_by_key(|c: &crate::render::PassCounts| c.model.map(|m| m.fragments));
    let counts = counts.get(counts.len() / 2).copied();
    let stages =
        STAGES.iter().zip(&samples).map(|(stage, v)| StageRow { stage, median_ms: median(v), p95_ms: percentile(v, 0.95) }).collect();
    Ok(LiveBench { stages, counts, reprojected: (reprojected, frames) })
}

/// What [`run`] measured: each stage, and what the profile's passes drew (its frame with the
/// median count of the model's fragments; None without pipeline-statistics queries).
#[derive(Clone, Debug)]
pub struct LiveBench {
    pub stages: Vec<StageRow>,
    pub counts: Option<crate::render::PassCounts>,
    /// Of the measured frames, how many reprojected the last shaded frame's layers
    /// (render::reprojection), and how many there were.
    pub reprojected: (usize, usize),
}

/// The compositor's median GPU time over the floor's (issue 11's goal: at most 1.5).
pub fn floor_ratio(rows: &[StageRow]) -> f64 {
    rows[COMPOSITOR].median_ms / rows[FLOOR].median_ms
}

/// The rows as JSON (`previz bench live --json`): the stages, the compositor's ratio to the
/// floor, and the profile's passes by name (GPU medians, ms; null: the pass did not run), with
/// what they drew (`counts`: each pass's `triangles` and `fragments`, gpu::PassCounter).
pub fn json(bench: &LiveBench) -> serde_json::Value {
    let rows = &bench.stages;
    let ms = |k: usize| rows.get(k).map(|r| r.median_ms).filter(|v| v.is_finite());
    serde_json::json!({
        "stages": rows,
        "compositor_over_floor": floor_ratio(rows),
        "shaded_over_floor": rows[SHADED].median_ms / rows[FLOOR].median_ms,
        "frames_reprojected": bench.reprojected.0,
        "frames_measured": bench.reprojected.1,
        "profile": {
            "total_ms": ms(PROFILE),
            "shadow_ms": ms(PROFILE + 1),
            "background_ms": ms(PROFILE + 2),
            "model_ms": ms(PROFILE + 3),
            "ground_ms": ms(PROFILE + 4),
            "counts": bench.counts,
        },
    })
}

/// The rows as a markdown table, then the compositor's ratio to the floor and what the
/// profile's passes drew.
pub fn markdown(bench: &LiveBench) -> String {
    let mut s = String::from("| stage | median ms | p95 ms |\n|---|---:|---:|\n");
    for r in &bench.stages {
        s += &format!("| {} | {:.3} | {:.3} |\n", r.stage, r.median_ms, r.p95_ms);
    }
    let (rows, ratio) = (&bench.stages, floor_ratio(&bench.stages));
    s += &format!("\ncompositor / floor (GPU medians): {ratio:.2}x (goal <= 1.5x: {})\n", if ratio <= 1.5 { "met" } else { "not met" });
    let (reprojected, measured) = bench.reprojected;
    s += &format!(
        "of the {measured} measured frames, {reprojected} composed the last shaded frame's model and ground through the camera's turn (reprojected), {} shaded them; every frame shaded (reprojection off): {:.2}x the floor\n",
        measured - reprojected,
        rows[SHADED].median_ms / rows[FLOOR].median_ms
    );
    if let Some(c) = bench.counts {
        let pass = |p: Option<crate::gpu::PassCount>| {
            p.map_or("–".to_string(), |p| format!("{} triangles, {} fragments", p.triangles, p.fragments))
        };
        s += &format!(
            "the profile's passes drew (fragment-shader invocations as the driver counts them; lavapipe: 16 for each 4×4 block a triangle covers part of): background {}; model {}; ground {}\n",
            pass(c.background),
            pass(c.model),
            pass(c.ground)
        );
    }
    s
}
