//! Where capture fails: many simulated captures per noise level and mode (`previz capture
//! stability`), plus the hard cases — reference headings next to 0/360°, up/down aimed right at
//! the poles with the phone rolled, and a magnetic disturbance during the capture with and
//! without the fusion filter's gyro-only fallback. Each run is a full replay ([`super::replay`]):
//! simulated user path → virtual phone + simulated sensors → fusion → assistant → faces, scored
//! against the ideal faces.
//!
//! Runs are independent and run in parallel (one virtual-phone thread each); the same seed gives
//! the same path and the same sensor noise in both modes, so the modes are compared pairwise.

use super::Mode;
use super::assistant::Assistant;
use super::guided_path::simulate_capture_path;
use super::replay::{ReplayConfig, ReplayResult, replay, replay_guided};
use super::targets::Face;
use crate::pose::fusion::{DisturbanceConfig, FusionConfig};
use crate::pose::hand_motion::UserPathParams;
use crate::pose::hand_motion::simulate_user_path;
use crate::pose::trace::TruthTrace;
use crate::scene::CubeMap;
use crate::sensors::sim::{Disturbance, NoiseLevel};
use anyhow::{Context, Result, bail};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The wide lens of the `random-100°` and `six-faces-100°` cases (vertical FOV, degrees).
pub const WIDE_VFOV_DEG: f32 = 100.0;

/// Passes a simulated user gets to follow the guidance ([`replay_guided`]).
pub const GUIDED_ATTEMPTS: usize = 3;

/// What a run exercises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Case {
    /// Reference heading drawn uniformly.
    Random,
    /// Reference heading within ±2° of North: the right/left/back targets and the tolerance
    /// boxes straddle 0/360.
    Wrap,
    /// Up and down aimed within 0.2° of the vertical (where heading is undefined) with the phone
    /// rolled up to ±10°.
    Pole,
    /// A 40 µT field for 8 s from 1 s after the tap; `fallback` = the filter's gyro-only mode on.
    Disturbance { fallback: bool },
    /// Random headings with a 100° lens (guided user).
    Wide,
    /// Held out: pre-recorded hand-held paths that only visit the six face centres (seed 000's
    /// procedure, [`crate::pose::hand_motion::simulate_user_path`], the pose study's user holding
    /// each 1.2–2.0 s) with a 100° lens, replayed once — nobody follows the guidance.
    SixFaces,
}

impl Case {
    pub fn name(self) -> &'static str {
        match self {
            Case::Random => "random",
            Case::Wrap => "wrap-0/360",
            Case::Pole => "pitch±90",
            Case::Disturbance { fallback: true } => "disturbed+fallback",
            Case::Disturbance { fallback: false } => "disturbed-no-fallback",
            Case::Wide => "random-100°",
            Case::SixFaces => "six-faces-100°",
        }
    }
}

/// Study settings.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    /// Random-heading runs per noise level and mode (≥ 50 for the published study).
    pub runs: usize,
    /// Runs per hard case and mode (phone noise).
    pub case_runs: usize,
    pub noise_levels: Vec<NoiseLevel>,
    pub modes: Vec<Mode>,
    /// The virtual phone and faces (smaller than the CLI's defaults to keep the study quick).
    pub width: u32,
    pub height: u32,
    pub vfov_deg: f32,
    pub face_size: u32,
    pub tolerance_deg: f64,
    pub threads: usize,
}

impl Default for StudyConfig {
    fn default() -> Self {
        StudyConfig {
            runs: 50,
            case_runs: 25,
            noise_levels: vec![NoiseLevel::None, NoiseLevel::Phone, NoiseLevel::Bad],
            modes: vec![Mode::Stretch, Mode::Stitch],
            width: 320,
            height: 240,
            vfov_deg: 50.0,
            face_size: 128,
            tolerance_deg: 2.0,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

/// One run.
#[derive(Clone, Copy, Debug)]
pub struct Job {
    pub case: Case,
    pub noise: NoiseLevel,
    pub mode: Mode,
    pub seed: u64,
}

/// The result of one run.
#[derive(Clone, Debug)]
pub struct RunRow {
    pub job: Job,
    pub reference_heading_deg: f64,
    pub completed: bool,
    pub time_to_complete_s: Option<f64>,
    pub shots: usize,
    pub targets: usize,
    pub mean_error_deg: Option<f64>,
    pub max_error_deg: Option<f64>,
    /// PSNR per face in [`Face::ALL`] order (dB; None when incomplete or identical).
    pub face_psnr: [Option<f64>; 6],
    pub mean_flip: Option<f64>,
    /// Mean PSNR and FLIP of the faces against the ideal faces at the front's true heading
    /// ([`super::replay::FaceReport::stitch_psnr_db`]).
    pub stitch_psnr_db: Option<f64>,
    pub stitch_flip: Option<f64>,
    /// The reference heading's error (degrees).
    pub reference_heading_error_deg: Option<f64>,
    pub min_coverage: Option<f64>,
    pub gyro_only_fraction: f64,
    pub assembly_ms: f64,
    /// Missing faces (incomplete runs).
    pub missing: String,
    /// Why, in the assistant's words: per missing face, what is unseen and why each of its
    /// targets was not taken (incomplete runs).
    pub why: String,
    /// Shots whose image match corrected the guidance's heading drift.
    pub drift_fixes: usize,
    /// Passes the guided user needed (see [`replay_guided`]).
    pub attempts: usize,
}

impl RunRow {
    pub fn mean_psnr(&self) -> Option<f64> {
        let v: Vec<f64> = self.face_psnr.iter().flatten().copied().collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    }
}

/// The job list: random headings for every noise level and mode, then the hard cases at
/// `phone` noise for every mode.
pub fn jobs(cfg: &StudyConfig) -> Vec<Job> {
    let mut v = Vec::new();
    for &noise in &cfg.noise_levels {
        for &mode in &cfg.modes {
            v.extend((0..cfg.runs as u64).map(|seed| Job { case: Case::Random, noise, mode, seed }));
        }
    }
    for &noise in &cfg.noise_levels {
        for case in [Case::Wide, Case::SixFaces] {
            for &mode in &cfg.modes {
                v.extend((0..cfg.case_runs as u64).map(|seed| Job { case, noise, mode, seed: 2000 + seed }));
            }
        }
    }
    for case in [Case::Wrap, Case::Pole, Case::Disturbance { fallback: true }, Case::Disturbance { fallback: false }] {
        for &mode in &cfg.modes {
            v.extend((0..cfg.case_runs as u64).map(|seed| Job { case, noise: NoiseLevel::Phone, mode, seed: 1000 + seed }));
        }
    }
    v
}

/// Run one job.
pub fn run_job(env: &Arc<CubeMap>, cfg: &StudyConfig, job: Job) -> Result<RunRow> {
    let mut replay_cfg = ReplayConfig {
        mode: job.mode,
        width: cfg.width,
        height: cfg.height,
        vfov_deg: cfg.vfov_deg,
        noise: job.noise,
        seed: job.seed,
        tolerance_deg: cfg.tolerance_deg,
        face_size: cfg.face_size,
        render_threads: 1,
        ..ReplayConfig::default()
    };
    if matches!(job.case, Case::Wide | Case::SixFaces) {
        replay_cfg.vfov_deg = WIDE_VFOV_DEG;
    }
    if job.case == Case::SixFaces {
        let path = simulate_user_path(job.seed, &UserPathParams::default())?;
        let result = replay(env, &TruthTrace::new(path.samples)?, &replay_cfg)?;
        return Ok(row(job, path.reference_heading_deg, &result));
    }
    let targets: Vec<_> = Assistant::new(replay_cfg.assistant()?)?.targets().into_iter().cloned().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(job.seed ^ 0x5eed);
    let mut params = UserPathParams::default();
    match job.case {
        Case::Wrap => params.reference_heading_deg = Some((358.0 + rng.random_range(0.0..4.0)) % 360.0),
        Case::Pole => {
            params.aim_error_deg = 0.2;
            params.roll_deg = 10.0;
        }
        _ => {}
    }
    if let Case::Disturbance { fallback } = job.case {
        // Starts 1 s after the tap of the undisturbed path (the user's timing barely changes
        // between guided passes).
        let tap = simulate_capture_path(job.seed, &targets, &params)?.samples.iter().find(|s| s.tap).map_or(0.0, |s| s.t);
        let dir = DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.0).normalize_or(DVec3::X);
        replay_cfg.disturbances = vec![Disturbance { start: tap + 1.0, duration: 8.0, field_enu_ut: dir * 40.0 }];
        replay_cfg.fusion = FusionConfig {
            disturbance: DisturbanceConfig { enabled: fallback, ..DisturbanceConfig::default() },
            ..FusionConfig::default()
        };
    }
    let run = replay_guided(env, &replay_cfg, job.seed, &params, GUIDED_ATTEMPTS)?;
    let mut row = row(job, run.path.reference_heading_deg, &run.result);
    row.attempts = run.attempts;
    Ok(row)
}

fn row(job: Job, href: f64, r: &ReplayResult) -> RunRow {
    let errors: Vec<f64> = r.faces.iter().map(|f| f.max_shot_error_deg.max(f.orientation_error_deg)).collect();
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let face_psnr = Face::ALL.map(|face| r.faces.iter().find(|f| f.face == face).and_then(|f| f.psnr_db));
    let flips: Vec<f64> = r.faces.iter().filter_map(|f| f.mean_flip.map(f64::from)).collect();
    RunRow {
        job,
        reference_heading_deg: r.capture.as_ref().map_or(href, |c| c.meta.reference_heading_deg),
        completed: r.capture.is_some(),
        time_to_complete_s: r.time_to_complete(),
        shots: r.shots,
        targets: r.targets,
        mean_error_deg: mean(&errors),
        max_error_deg: errors.iter().copied().reduce(f64::max),
        face_psnr,
        mean_flip: mean(&flips),
        stitch_psnr_db: mean(&r.faces.iter().filter_map(|f| f.stitch_psnr_db).collect::<Vec<_>>()),
        stitch_flip: mean(&r.faces.iter().filter_map(|f| f.stitch_flip.map(f64::from)).collect::<Vec<_>>()),
        reference_heading_error_deg: r.reference_heading_error_deg,
        min_coverage: r.faces.iter().map(|f| f64::from(f.coverage)).reduce(f64::min),
        gyro_only_fraction: r.gyro_only_fraction,
        assembly_ms: r.assembly_ms,
        why: r.incomplete.as_deref().map(|s| s.lines().skip(1).map(str::trim).collect::<Vec<_>>().join(" | ")).unwrap_or_default(),
        drift_fixes: r.drift_fixes,
        missing: r
            .incomplete
            .as_deref()
            .map(|s| s.lines().skip(1).map(|l| l.trim().split(':').next().unwrap_or("").to_string()).collect::<Vec<_>>().join(" "))
            .unwrap_or_default(),
        attempts: 1,
    }
}

/// Run every job on `cfg.threads` threads; `tick` is called after each.
pub fn run_study(env: &Arc<CubeMap>, cfg: &StudyConfig, jobs: &[Job], tick: impl Fn() + Sync) -> Result<Vec<RunRow>> {
    if jobs.is_empty() {
        bail!("the study has no runs");
    }
    let next = AtomicUsize::new(0);
    let rows = Mutex::new(Vec::with_capacity(jobs.len()));
    let first_error = Mutex::new(None);
    std::thread::scope(|s| {
        for _ in 0..cfg.threads.max(1) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(job) = jobs.get(i) else { break };
                    match run_job(env, cfg, *job) {
                        Ok(r) => rows.lock().unwrap_or_else(|e| e.into_inner()).push((i, r)),
                        Err(e) => {
                            first_error.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(e.context(format!(
                                "{} {} {} seed {}",
                                job.case.name(),
                                job.noise.name(),
                                job.mode.name(),
                                job.seed
                            )));
                            next.store(jobs.len(), Ordering::Relaxed);
                        }
                    }
                    tick();
                }
            });
        }
    });
    if let Some(e) = first_error.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(e);
    }
    let mut rows = rows.into_inner().unwrap_or_else(|e| e.into_inner());
    rows.sort_by_key(|(i, _)| *i);
    Ok(rows.into_iter().map(|(_, r)| r).collect())
}

/// Aggregate of the runs of one (case, noise, mode).
#[derive(Clone, Debug)]
pub struct Summary {
    pub case: Case,
    pub noise: NoiseLevel,
    pub mode: Mode,
    pub runs: usize,
    pub completed: usize,
    pub median_time_s: Option<f64>,
    pub mean_error_deg: Option<f64>,
    pub p95_error_deg: Option<f64>,
    pub mean_psnr_db: Option<f64>,
    pub face_psnr_db: [Option<f64>; 6],
    pub mean_flip: Option<f64>,
    pub stitch_psnr_db: Option<f64>,
    pub stitch_flip: Option<f64>,
    /// RMS of the reference heading's error over the completed runs (degrees).
    pub rms_reference_error_deg: Option<f64>,
    pub mean_min_coverage: Option<f64>,
    pub mean_shots: f64,
    pub mean_assembly_ms: f64,
    pub mean_gyro_only: f64,
    /// Mean guided passes per run.
    pub mean_attempts: f64,
}

impl Summary {
    pub fn completion(&self) -> f64 {
        self.completed as f64 / self.runs.max(1) as f64
    }

    pub fn label(&self) -> String {
        format!("{} {} {}", self.case.name(), self.noise.name(), self.mode.name())
    }
}

/// The q-quantile (0..1) by linear interpolation between order statistics (Hyndman & Fan 1996,
/// definition 7, the default of R and NumPy).
pub fn quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let h = (v.len() - 1) as f64 * q.clamp(0.0, 1.0);
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    Some(v[lo] + (v[hi] - v[lo]) * (h - lo as f64))
}

fn mean_of(v: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = v.filter(|x| x.is_finite()).collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Group runs by (case, noise, mode), in first-seen order.
pub fn summarise(rows: &[RunRow]) -> Vec<Summary> {
    let mut keys: Vec<(Case, NoiseLevel, Mode)> = Vec::new();
    for r in rows {
        let k = (r.job.case, r.job.noise, r.job.mode);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    keys.into_iter()
        .map(|(case, noise, mode)| {
            let g: Vec<&RunRow> = rows.iter().filter(|r| (r.job.case, r.job.noise, r.job.mode) == (case, noise, mode)).collect();
            let done: Vec<&&RunRow> = g.iter().filter(|r| r.completed).collect();
            let times: Vec<f64> = done.iter().filter_map(|r| r.time_to_complete_s).collect();
            let errs: Vec<f64> = done.iter().filter_map(|r| r.mean_error_deg).collect();
            let max_errs: Vec<f64> = done.iter().filter_map(|r| r.max_error_deg).collect();
            Summary {
                case,
                noise,
                mode,
                runs: g.len(),
                completed: done.len(),
                median_time_s: quantile(&times, 0.5),
                mean_error_deg: mean_of(errs.iter().copied()),
                p95_error_deg: quantile(&max_errs, 0.95),
                mean_psnr_db: mean_of(done.iter().filter_map(|r| r.mean_psnr())),
                face_psnr_db: std::array::from_fn(|i| mean_of(done.iter().filter_map(|r| r.face_psnr[i]))),
                mean_flip: mean_of(done.iter().filter_map(|r| r.mean_flip)),
                stitch_psnr_db: mean_of(done.iter().filter_map(|r| r.stitch_psnr_db)),
                stitch_flip: mean_of(done.iter().filter_map(|r| r.stitch_flip)),
                rms_reference_error_deg: mean_of(done.iter().filter_map(|r| r.reference_heading_error_deg.map(|e| e * e))).map(f64::sqrt),
                mean_min_coverage: mean_of(done.iter().filter_map(|r| r.min_coverage)),
                mean_shots: g.iter().map(|r| r.shots as f64).sum::<f64>() / g.len().max(1) as f64,
                mean_assembly_ms: mean_of(done.iter().map(|r| r.assembly_ms)).unwrap_or(0.0),
                mean_gyro_only: g.iter().map(|r| r.gyro_only_fraction).sum::<f64>() / g.len().max(1) as f64,
                mean_attempts: g.iter().map(|r| r.attempts as f64).sum::<f64>() / g.len().max(1) as f64,
            }
        })
        .collect()
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(String::new, |x| format!("{x:.digits$}"))
}

/// One CSV row per run (header included).
pub fn rows_csv(rows: &[RunRow]) -> String {
    let mut s = String::from(
        "case,noise,mode,seed,reference_heading_deg,completed,time_to_complete_s,shots,targets,mean_orientation_error_deg,\
max_orientation_error_deg,psnr_front_db,psnr_up_db,psnr_down_db,psnr_right_db,psnr_back_db,psnr_left_db,mean_psnr_db,mean_flip,\
stitch_psnr_db,stitch_flip,reference_heading_error_deg,min_coverage,gyro_only_fraction,assembly_ms,guided_passes,drift_fixes,missing,why\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{:.3},{},{},{},{},{},{},{},{},{},{}",
            r.job.case.name(),
            r.job.noise.name(),
            r.job.mode.name(),
            r.job.seed,
            r.reference_heading_deg,
            u8::from(r.completed),
            opt(r.time_to_complete_s, 3),
            r.shots,
            r.targets,
            opt(r.mean_error_deg, 4),
            opt(r.max_error_deg, 4),
            r.face_psnr.iter().map(|p| opt(*p, 3)).collect::<Vec<_>>().join(","),
            opt(r.mean_psnr(), 3),
            opt(r.mean_flip, 5),
            format_args!(
                "{},{},{},{},{:.4},{:.2},{},{},{},\"{}\"",
                opt(r.stitch_psnr_db, 3),
                opt(r.stitch_flip, 5),
                opt(r.reference_heading_error_deg, 3),
                opt(r.min_coverage, 4),
                r.gyro_only_fraction,
                r.assembly_ms,
                r.attempts,
                r.drift_fixes,
                r.missing,
                r.why.replace('"', "\"\"")
            ),
        );
    }
    s
}

/// The summary as a markdown table.
pub fn summary_markdown(summaries: &[Summary]) -> String {
    let mut s = String::from(
        "| case | noise | mode | runs | complete | median time (s) | mean orient. err (°) | p95 max err (°) | mean PSNR (dB) | mean FLIP | stitch PSNR (dB) | stitch FLIP | RMS ref. heading err (°) | min coverage | shots | passes | assembly (ms) | gyro-only frames |\n\
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for m in summaries {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.0}% | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.1} | {:.2} | {:.1} | {:.0}% |",
            m.case.name(),
            m.noise.name(),
            m.mode.name(),
            m.runs,
            100.0 * m.completion(),
            opt(m.median_time_s, 1),
            opt(m.mean_error_deg, 2),
            opt(m.p95_error_deg, 2),
            opt(m.mean_psnr_db, 1),
            opt(m.mean_flip, 3),
            opt(m.stitch_psnr_db, 1),
            opt(m.stitch_flip, 3),
            opt(m.rms_reference_error_deg, 2),
            opt(m.mean_min_coverage, 3),
            m.mean_shots,
            m.mean_attempts,
            m.mean_assembly_ms,
            100.0 * m.mean_gyro_only,
        );
    }
    s
}

/// Per-face PSNR of the random-heading groups, as a markdown table.
pub fn face_psnr_markdown(summaries: &[Summary]) -> String {
    let mut s = String::from("| noise | mode | front | up | down | right | back | left |\n|---|---|---|---|---|---|---|---|\n");
    for m in summaries.iter().filter(|m| m.case == Case::Random) {
        let cells: Vec<String> = m.face_psnr_db.iter().map(|p| opt(*p, 1)).collect();
        let _ = writeln!(s, "| {} | {} | {} |", m.noise.name(), m.mode.name(), cells.join(" | "));
    }
    s
}

/// Bar labels read downwards from each bar's foot (plotters' rotated axis labels are anchored
/// as if unrotated and run up into the plot).
fn bar_labels(
    area: &plotters::prelude::DrawingArea<plotters::prelude::BitMapBackend<'_>, plotters::coord::Shift>,
    feet: impl Iterator<Item = (i32, i32)>,
    labels: &[String],
) -> Result<()> {
    use plotters::prelude::*;
    let style = ("sans-serif", 12).into_font().transform(FontTransform::Rotate90).color(&BLACK);
    for ((x, y), label) in feet.zip(labels) {
        area.draw(&Text::new(label.clone(), (x + 6, y + 6), style.clone())).context("chart")?;
    }
    Ok(())
}

/// Draw the study chart: completion, orientation error, per-face PSNR and cost vs quality.
pub fn draw_chart(path: &std::path::Path, summaries: &[Summary]) -> Result<()> {
    use plotters::prelude::*;
    crate::chart::register_font();
    let (w, h) = (1600u32, 1100u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).context("chart")?;
        let full = root.clone();
        let root = root.titled("Capture stability: where methods fail (simulated captures)", ("sans-serif", 28)).context("chart")?;
        let panels = root.split_evenly((2, 2));
        let n = summaries.len();
        let colour = |m: &Summary| match m.mode {
            Mode::Stretch => RGBColor(230, 120, 40),
            Mode::Stitch => RGBColor(40, 110, 200),
        };
        let labels: Vec<String> = summaries.iter().map(|m| format!("{} {}", m.case.name(), m.noise.name())).collect();
        // (a) completion rate.
        {
            let mut c = ChartBuilder::on(&panels[0])
                .caption("Completion rate (orange: stretch, blue: stitch)", ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(120)
                .y_label_area_size(50)
                .build_cartesian_2d(-0.6f64..(n as f64 - 0.4), 0f64..105.0)
                .context("chart")?;
            c.configure_mesh().x_labels(0).y_desc("% of runs complete").draw().context("chart")?;
            c.draw_series(
                summaries
                    .iter()
                    .enumerate()
                    .map(|(i, m)| Rectangle::new([(i as f64 - 0.35, 0.0), (i as f64 + 0.35, 100.0 * m.completion())], colour(m).filled())),
            )
            .context("chart")?;
            bar_labels(&full, (0..n).map(|i| c.backend_coord(&(i as f64, 0.0))), &labels)?;
        }
        // (b) orientation error: mean (bar) and p95 of the per-run maximum (marker).
        {
            let top = summaries.iter().filter_map(|m| m.p95_error_deg.or(m.mean_error_deg)).fold(1.0f64, f64::max) * 1.15;
            let mut c = ChartBuilder::on(&panels[1])
                .caption("Orientation error of the shots (bar: mean, dot: p95 of run max)", ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(120)
                .y_label_area_size(50)
                .build_cartesian_2d(-0.6f64..(n as f64 - 0.4), 0f64..top)
                .context("chart")?;
            c.configure_mesh().x_labels(0).y_desc("degrees (estimated vs true)").draw().context("chart")?;
            c.draw_series(summaries.iter().enumerate().filter_map(|(i, m)| {
                Some(Rectangle::new([(i as f64 - 0.35, 0.0), (i as f64 + 0.35, m.mean_error_deg?)], colour(m).filled()))
            }))
            .context("chart")?;
            c.draw_series(
                summaries.iter().enumerate().filter_map(|(i, m)| Some(Circle::new((i as f64, m.p95_error_deg?), 5, BLACK.filled()))),
            )
            .context("chart")?;
            bar_labels(&full, (0..n).map(|i| c.backend_coord(&(i as f64, 0.0))), &labels)?;
        }
        // (c) per-face PSNR, random headings.
        {
            let random: Vec<&Summary> = summaries.iter().filter(|m| m.case == Case::Random).collect();
            let top = random.iter().flat_map(|m| m.face_psnr_db.iter().flatten()).fold(10.0f64, |a, b| a.max(*b)) * 1.1;
            let mut c = ChartBuilder::on(&panels[2])
                .caption("PSNR per face vs the ideal face (random headings)", ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(50)
                .build_cartesian_2d(-0.6f64..5.6, 0f64..top)
                .context("chart")?;
            c.configure_mesh()
                .x_labels(6)
                .x_label_formatter(&|x: &f64| {
                    let i = x.round();
                    if (x - i).abs() < 1e-6 && (0.0..6.0).contains(&i) { Face::ALL[i as usize].name().to_string() } else { String::new() }
                })
                .y_desc("PSNR (dB)")
                .draw()
                .context("chart")?;
            let k = random.len().max(1) as f64;
            for (j, m) in random.iter().enumerate() {
                let shade = match m.noise {
                    NoiseLevel::None => 1.0,
                    NoiseLevel::Phone => 0.75,
                    NoiseLevel::Bad => 0.5,
                };
                let RGBColor(r, g, b) = colour(m);
                let col = RGBColor((f64::from(r) * shade) as u8, (f64::from(g) * shade) as u8, (f64::from(b) * shade) as u8);
                let width = 0.8 / k;
                c.draw_series(m.face_psnr_db.iter().enumerate().filter_map(|(i, p)| {
                    let x0 = i as f64 - 0.4 + j as f64 * width;
                    Some(Rectangle::new([(x0, 0.0), (x0 + width * 0.9, (*p)?)], col.filled()))
                }))
                .context("chart")?
                .label(format!("{} {}", m.mode.name(), m.noise.name()))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], col.filled()));
            }
            c.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().context("chart")?;
        }
        // (d) cost vs quality.
        {
            let max_shots = summaries.iter().map(|m| m.mean_shots).fold(1.0f64, f64::max) * 1.15;
            let psnr: Vec<f64> = summaries.iter().filter_map(|m| m.mean_psnr_db).collect();
            let (lo, hi) = (psnr.iter().copied().fold(f64::INFINITY, f64::min), psnr.iter().copied().fold(f64::NEG_INFINITY, f64::max));
            let (lo, hi) = if lo.is_finite() { (lo - 2.0, hi + 2.0) } else { (0.0, 40.0) };
            let mut c = ChartBuilder::on(&panels[3])
                .caption("Cost vs quality (label: median seconds to complete)", ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..max_shots, lo..hi)
                .context("chart")?;
            c.configure_mesh().x_desc("shots per capture").y_desc("mean PSNR (dB)").draw().context("chart")?;
            for m in summaries.iter().filter(|m| m.mean_psnr_db.is_some()) {
                let p = (m.mean_shots, m.mean_psnr_db.unwrap_or(0.0));
                let text = format!("{} {} ({}s)", m.case.name(), m.noise.name(), opt(m.median_time_s, 0));
                c.draw_series(std::iter::once(Circle::new(p, 6, colour(m).filled()))).context("chart")?;
                c.draw_series(std::iter::once(Text::new(text, (p.0, p.1), ("sans-serif", 12)))).context("chart")?;
            }
        }
        root.present().context("chart")?;
    }
    crate::output::write_png_rgb8(path, w, h, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_matches_numpy_default() {
        // numpy.quantile([1, 2, 3, 4], 0.95) = 3.85 (linear, Hyndman-Fan type 7).
        assert!((quantile(&[4.0, 1.0, 3.0, 2.0], 0.95).unwrap() - 3.85).abs() < 1e-12);
        assert_eq!(quantile(&[2.0], 0.5), Some(2.0));
        assert_eq!(quantile(&[f64::NAN], 0.5), None);
        assert_eq!(quantile(&[], 0.5), None);
    }

    #[test]
    fn a_few_runs_per_case_summarise_and_chart() {
        // A handful of tiny runs: the pipeline works end to end and the hard cases behave.
        let env = Arc::new(CubeMap::from_fn(16, |d| [0.3 + 0.2 * d.x, 0.3 + 0.2 * d.y, 0.3 + 0.2 * d.z]));
        let cfg = StudyConfig {
            runs: 1,
            case_runs: 1,
            noise_levels: vec![NoiseLevel::None],
            modes: vec![Mode::Stretch],
            width: 96,
            height: 72,
            face_size: 16,
            ..StudyConfig::default()
        };
        let jobs = jobs(&cfg);
        assert_eq!(jobs.len(), 7);
        let ticks = AtomicUsize::new(0);
        let rows = run_study(&env, &cfg, &jobs, || {
            ticks.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
        assert_eq!(ticks.load(Ordering::Relaxed), 7);
        let by = |c: Case| rows.iter().find(|r| r.job.case == c).unwrap();
        assert!(by(Case::Random).completed, "{:?}", by(Case::Random).missing);
        // The user aimed within 2° of North (± the 0.8° aim error); the estimated reference adds
        // the phone-noise heading error (a few degrees at most over a capture).
        let wrap = by(Case::Wrap);
        let off_north = crate::pose::frames::heading_difference_deg(wrap.reference_heading_deg, 0.0).abs();
        assert!(wrap.completed && off_north < 2.8 + 3.0, "{wrap:?}");
        assert!(by(Case::Pole).completed, "{:?}", by(Case::Pole).missing);
        // The held-out six-face path with the 100° lens completes without guidance.
        assert!(by(Case::SixFaces).completed, "{:?}", by(Case::SixFaces).missing);
        assert!(by(Case::Wide).completed, "{:?}", by(Case::Wide).missing);
        // The disturbance drives the filter into gyro-only mode only when the fallback is on.
        assert!(by(Case::Disturbance { fallback: true }).gyro_only_fraction > 0.0);
        assert_eq!(by(Case::Disturbance { fallback: false }).gyro_only_fraction, 0.0);
        let s = summarise(&rows);
        assert_eq!(s.len(), 7);
        let csv = rows_csv(&rows);
        assert_eq!(csv.lines().count(), 8);
        // Every row has the header's fields, read back as CSV (a case name with a comma once
        // shifted its rows' columns).
        let mut reader = csv::Reader::from_reader(csv.as_bytes());
        let fields = reader.headers().unwrap().len();
        let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
        assert_eq!(records.len(), 7);
        assert!(records.iter().all(|r| r.len() == fields), "{records:?}");
        assert!(summary_markdown(&s).contains("| random | none | stretch | 1 |"));
        let png = std::env::temp_dir().join(format!("previz-capture-stability-{}.png", std::process::id()));
        draw_chart(&png, &s).unwrap();
        assert!(image::open(&png).unwrap().width() == 1600);
        std::fs::remove_file(&png).unwrap();
    }
}
