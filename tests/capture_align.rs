//! The images pay: on pre-recorded six-face hand-held paths (seed 000's procedure, 100° lens,
//! `phone` noise) into the quarry HDR, using the shots' overlaps (during the capture each shot
//! measures the drift of the guidance's gyroscope heading; at the end all shots are aligned
//! jointly) raises the faces' PSNR against the ideal faces at the front's true heading (the
//! stitch's own quality, without the compass's error in the reference heading) and lowers their
//! mean FLIP, against `--no-align` (compass-corrected poses, no image alignment).

mod common;

use common::data;
use glam::DQuat;
use previz::capture::Mode;
use previz::capture::replay::{ReplayConfig, replay, replay_guided};
use previz::capture::stability::{Case, GUIDED_ATTEMPTS, Job, StudyConfig, WIDE_VFOV_DEG, run_job};
use previz::pose::hand_motion::{UserPathParams, simulate_user_path};
use previz::pose::trace::TruthTrace;
use previz::scene::CubeMap;
use previz::scene::environment::load_environment;
use previz::sensors::sim::NoiseLevel;
use std::sync::Arc;

#[test]
fn aligning_the_shots_raises_the_stitch_psnr_on_hand_held_paths() {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let (mut psnr, mut flip) = ([0.0f64; 2], [0.0f64; 2]);
    let mut n = 0usize;
    for seed in [2000u64, 2001, 2003] {
        let path = simulate_user_path(seed, &UserPathParams::default()).unwrap();
        let trace = TruthTrace::new(path.samples).unwrap();
        for (k, align) in [false, true].into_iter().enumerate() {
            let cfg = ReplayConfig {
                mode: Mode::Stitch,
                noise: NoiseLevel::Phone,
                seed,
                vfov_deg: 100.0,
                width: 160,
                height: 120,
                face_size: 32,
                render_threads: 2,
                align,
                ..ReplayConfig::default()
            };
            let r = replay(&env, &trace, &cfg).unwrap();
            assert!(r.incomplete.is_none(), "seed {seed}: {:?}", r.incomplete);
            for f in &r.faces {
                psnr[k] += f.stitch_psnr_db.unwrap();
                flip[k] += f64::from(f.stitch_flip.unwrap());
            }
            if align {
                n += r.faces.len();
            }
        }
    }
    let (psnr, flip) = (psnr.map(|p| p / n as f64), flip.map(|f| f / n as f64));
    eprintln!("stitch PSNR {psnr:?} dB, FLIP {flip:?}");
    assert!(psnr[1] > psnr[0] + 2.0, "PSNR without / with alignment: {psnr:?}");
    assert!(flip[1] < flip[0], "FLIP without / with alignment: {flip:?}");
}

/// `bad` noise, 50° lens, stitch mode, the guided user: seeds 9 and 12 of the stability study
/// failed with the tour that was short in the angle between aims (the fifth session's study:
/// "never held steady" on right+2, the held heading 30–60° off by then). It ran the −45° ring
/// first and came back to the neighbouring horizon views 20 s later, when the held heading had
/// drifted by 15–30° relative to them; the tour short in the phone's rotation sweeps sector by
/// sector, so neighbouring shots are taken seconds apart and agree in the guidance's heading.
#[test]
fn bad_noise_stitch_captures_that_failed_complete_with_the_rotation_tour() {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let cfg = StudyConfig { face_size: 32, threads: 1, ..StudyConfig::default() };
    for seed in [9u64, 12] {
        let row = run_job(&env, &cfg, Job { case: Case::Random, noise: NoiseLevel::Bad, mode: Mode::Stitch, seed }).unwrap();
        assert!(row.completed, "seed {seed}: {}", row.why);
    }
}

fn env_or(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.to_string())
}

/// Yaw (degrees) of the world-frame error rotation est · truth⁻¹.
fn yaw_error_deg(est: DQuat, truth: DQuat) -> f64 {
    let e = est * truth.inverse();
    let e = if e.w < 0.0 { -e } else { e };
    (2.0 * e.z.atan2(e.w)).to_degrees()
}

/// Why captures fail, run by hand (not in CI): per run, completion, time, shots, guided passes,
/// the share of gyro-only frames, the stitch scores, and with `DETAIL=1` the drift of the
/// guidance's heading relative to the tap (yaw of est·truth⁻¹, every 2 s) and the assistant's
/// reasons. `CASE=random|wide|six|wrap|pole|dist|distnf NOISE=none|phone|bad
/// MODE=stretch|stitch SEEDS=0-11 [SIZE=160] cargo test --test capture_align diagnose --
/// --ignored --nocapture`.
#[test]
#[ignore]
fn diagnose() {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let case = match env_or("CASE", "random").as_str() {
        "random" => Case::Random,
        "wide" => Case::Wide,
        "six" => Case::SixFaces,
        "wrap" => Case::Wrap,
        "pole" => Case::Pole,
        "dist" => Case::Disturbance { fallback: true },
        "distnf" => Case::Disturbance { fallback: false },
        c => panic!("case {c}"),
    };
    let noise = match env_or("NOISE", "bad").as_str() {
        "none" => NoiseLevel::None,
        "phone" => NoiseLevel::Phone,
        _ => NoiseLevel::Bad,
    };
    let mode = if env_or("MODE", "stitch") == "stretch" { Mode::Stretch } else { Mode::Stitch };
    let seeds = env_or("SEEDS", "0-3");
    let (a, b) = seeds.split_once('-').unwrap_or((&seeds, &seeds));
    let (a, b): (u64, u64) = (a.parse().unwrap(), b.parse().unwrap());
    let base = if matches!(case, Case::Wide | Case::SixFaces) {
        2000
    } else if case == Case::Random {
        0
    } else {
        1000
    };
    let size: u32 = env_or("SIZE", "160").parse().unwrap();
    let cfg = StudyConfig { width: size, height: size * 3 / 4, face_size: 32, threads: 2, ..StudyConfig::default() };
    let jobs: Vec<Job> = (a..=b).map(|s| Job { case, noise, mode, seed: base + s }).collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let rows = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..cfg.threads {
            s.spawn(|| {
                loop {
                    let i = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(job) = jobs.get(i) else { break };
                    let row = run_job(&env, &cfg, *job).unwrap();
                    let detail = if matches!(job.case, Case::Random | Case::Wide | Case::SixFaces) && std::env::var("DETAIL").is_ok() {
                        detail(&env, &cfg, *job)
                    } else {
                        row.missing.clone()
                    };
                    rows.lock().unwrap().push((row, detail));
                }
            });
        }
    });
    let mut rows = rows.into_inner().unwrap();
    rows.sort_by_key(|r| r.0.job.seed);
    let mut ok = 0;
    for (r, d) in &rows {
        ok += usize::from(r.completed);
        println!(
            "seed {:>4} {} t={:>5.1} shots {:>2}/{:>2} passes {} gyro-only {:>3.0}% stitchPSNR {:?} FLIP {:?} {d}",
            r.job.seed,
            if r.completed { "OK  " } else { "FAIL" },
            r.time_to_complete_s.unwrap_or(f64::NAN),
            r.shots,
            r.targets,
            r.attempts,
            100.0 * r.gyro_only_fraction,
            r.stitch_psnr_db.map(|p| (p * 10.0).round() / 10.0),
            r.stitch_flip.map(|p| (p * 1000.0).round() / 1000.0),
        );
    }
    println!("{} {} {}: {ok}/{} complete", case.name(), noise.name(), mode.name(), rows.len());
}

/// The last pass again, with the guidance pose's heading drift (yaw error relative to the one
/// at the tap) and the reasons of an incomplete capture.
fn detail(env: &Arc<CubeMap>, cfg: &StudyConfig, job: Job) -> String {
    let mut rc = ReplayConfig {
        mode: job.mode,
        width: cfg.width,
        height: cfg.height,
        vfov_deg: cfg.vfov_deg,
        noise: job.noise,
        seed: job.seed,
        face_size: cfg.face_size,
        render_threads: 1,
        score: false,
        ..ReplayConfig::default()
    };
    if matches!(job.case, Case::Wide | Case::SixFaces) {
        rc.vfov_deg = WIDE_VFOV_DEG;
    }
    let r = match job.case {
        Case::SixFaces => {
            let path = simulate_user_path(job.seed, &UserPathParams::default()).unwrap();
            replay(env, &TruthTrace::new(path.samples).unwrap(), &rc).unwrap()
        }
        Case::Random | Case::Wide => replay_guided(env, &rc, job.seed, &UserPathParams::default(), GUIDED_ATTEMPTS).unwrap().result,
        _ => return String::new(),
    };
    let tap = r.tap_t.unwrap_or(0.0);
    let at_tap = r.track.iter().find(|(t, _, _)| *t >= tap).map_or(0.0, |(_, e, q)| yaw_error_deg(e.as_dquat(), *q));
    let mut worst = (0.0f64, 0.0f64);
    let mut series = String::new();
    for (t, e, q) in r.track.iter().filter(|(t, _, _)| *t >= tap) {
        let d = yaw_error_deg(e.as_dquat(), *q) - at_tap;
        if d.abs() > worst.0.abs() {
            worst = (d, *t - tap);
        }
        if ((t - tap) * 30.0).round() as i64 % 60 == 0 {
            series += &format!(" {d:.1}");
        }
    }
    format!(
        "fixes {}/{} drift max {:.1} at {:.1}s [{}] end {}",
        r.drift_fixes,
        r.shots,
        worst.0,
        worst.1,
        series.trim(),
        r.incomplete.map(|s| s.replace('\n', " | ")).unwrap_or_default()
    )
}
