//! The images pay: on pre-recorded six-face hand-held paths (seed 000's procedure, 100° lens,
//! `phone` noise) into the quarry HDR, using the shots' overlaps (during the capture each shot
//! measures the drift of the guidance's gyroscope heading; at the end all shots are aligned
//! jointly) raises the faces' PSNR against the ideal faces at the front's true heading (the
//! stitch's own quality, without the compass's error in the reference heading) and lowers their
//! mean FLIP, against `--no-align` (compass-corrected poses, no image alignment).

use crate::common;

use common::data;
use glam::DQuat;
use previz::capture::Mode;
use previz::capture::align::align_turns;
use previz::capture::replay::{ReplayConfig, ReplayResult, replay, replay_guided};
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
    let mut turns = (0.0f64, 0.0f64);
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
                // The same shots with the turns about the vertical alone (no joint refinement of
                // the whole orientations), scored alike.
                let (turned, _) = align_turns(&cfg.camera().unwrap(), &r.taken_shots, 0);
                let (db, f) = stitch_scores(&env, &trace, &r, &cfg, &turned.iter().map(|s| s.pose).collect::<Vec<_>>());
                turns.0 += db / 3.0;
                turns.1 += f / 3.0;
            }
        }
    }
    let (psnr, flip) = (psnr.map(|p| p / n as f64), flip.map(|f| f / n as f64));
    eprintln!("stitch PSNR {psnr:?} dB, FLIP {flip:?}; with the turns alone {turns:?}");
    assert!(psnr[1] > psnr[0] + 2.0, "PSNR without / with alignment: {psnr:?}");
    assert!(flip[1] < flip[0], "FLIP without / with alignment: {flip:?}");
    // The joint refinement of the whole orientations (tilt included) beats the turns alone.
    assert!(psnr[1] > turns.0 + 1.0 && flip[1] < turns.1, "with the refinement {psnr:?} {flip:?}, turns alone {turns:?}");
}

/// Issue 12's quality goal at `phone` noise on the held-out six-face paths (100° lens, the
/// stability study's 320×240 frames and 128 px faces): mean FLIP ≤ 0.03 and PSNR ≥ 35 dB against
/// the ideal faces at the front's true heading. These paths overlap least, so the shots'
/// *common* tilt, which the overlaps cannot see, was what was left after the joint refinement:
/// the mean of the fusion filter's tilts, 0.1–0.45° off (the phone's own acceleration in the
/// turn before each shot). With the vertical from the accelerometer held before each shot
/// (`capture::gravity`) the same seeds measured FLIP 0.0303 → 0.0156 and PSNR 39.4 → 44.9 dB
/// (`quality_errors`, 2026-12-01).
#[test]
fn six_face_paths_meet_the_flip_goal_with_the_vertical_from_the_held_accelerometer() {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let (mut psnr, mut flip, mut n) = (0.0f64, 0.0f64, 0usize);
    for seed in 2000u64..2008 {
        let trace = TruthTrace::new(simulate_user_path(seed, &UserPathParams::default()).unwrap().samples).unwrap();
        let cfg = ReplayConfig {
            mode: Mode::Stitch,
            noise: NoiseLevel::Phone,
            seed,
            vfov_deg: WIDE_VFOV_DEG,
            width: 320,
            height: 240,
            face_size: 128,
            render_threads: 2,
            ..ReplayConfig::default()
        };
        let r = replay(&env, &trace, &cfg).unwrap();
        assert!(r.incomplete.is_none(), "seed {seed}: {:?}", r.incomplete);
        let alignment = r.capture.as_ref().unwrap().meta.alignment.unwrap();
        assert!(alignment.vertical_shots >= 5, "seed {seed}: {alignment:?}");
        for f in &r.faces {
            psnr += f.stitch_psnr_db.unwrap();
            flip += f64::from(f.stitch_flip.unwrap());
            n += 1;
        }
    }
    let (psnr, flip) = (psnr / n as f64, flip / n as f64);
    eprintln!("six-face paths, seeds 2000-2007: stitch PSNR {psnr:.2} dB, FLIP {flip:.4}");
    assert!(flip <= 0.03, "{flip}");
    assert!(psnr >= 35.0, "{psnr}");
}

/// Mean PSNR (dB) and FLIP over the six faces assembled from `r`'s shots as taken, placed at
/// `poses` (same order), against the ideal faces at the front shot's true heading (the stitch
/// scores of the replay, for another set of poses).
fn stitch_scores(env: &CubeMap, trace: &TruthTrace, r: &ReplayResult, cfg: &ReplayConfig, poses: &[glam::Quat]) -> (f64, f64) {
    use previz::camera::controls::CameraSettings;
    use previz::capture::Face;
    use previz::capture::replay::{ideal_face, mean_flip, psnr};
    use previz::capture::reproject::{Shot, assemble_face};
    let meta = &r.capture.as_ref().expect("a complete capture").meta;
    let settings = CameraSettings { exposure: meta.exposure.unwrap(), white_balance: meta.white_balance.unwrap() };
    let true_front = previz::pose::frames::heading_pitch_roll(trace.orientation_at(r.taken_shots[0].t)).heading.to_degrees();
    let posed: Vec<Shot> = r.taken_shots.iter().zip(poses).map(|(s, p)| Shot { pose: *p, ..s.clone() }).collect();
    let camera = cfg.camera().unwrap();
    let (mut db, mut flip) = (0.0, 0.0);
    for face in Face::ALL {
        let f = assemble_face(face, Mode::Stitch, &posed[0], &posed, &camera, meta.reference_heading_deg, cfg.face_size);
        let ideal = ideal_face(env, true_front, face, cfg.face_size, settings);
        db += psnr(&ideal, &f.rgb).unwrap_or(99.0) / 6.0;
        flip += f64::from(mean_flip(&ideal, &f.rgb, cfg.face_size, cfg.face_size).unwrap()) / 6.0;
    }
    (db, flip)
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

/// `bad` noise, 50° lens, stitch mode, the guided user at the study's frame size: seeds 22, 28
/// and 39 failed in the sixth session's study (the back face: the held heading drifted 23–48°
/// over the capture). The guidance's held pose was tilted by 1–4° at `bad` noise, so a new
/// shot's turn searched alone against an earlier shot's often found a wrong minimum (up to 7°
/// off), which the heading fix then took as drift; the match now searches the relative tilt
/// too, and the matched turns between views near the horizon teach the held filter the
/// gyroscope's bias. Measured (320×240 frames): all three complete in the first pass, the held
/// heading's drift since the tap at the end 0.38°, 0.17° and 4.23° (before, in the last of three
/// passes: 20.6°, 17.0° and 43.6°).
#[test]
fn bad_noise_captures_that_drifted_complete_and_the_held_heading_stays_within_five_degrees() {
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    for seed in [22u64, 28, 39] {
        let cfg = ReplayConfig {
            mode: Mode::Stitch,
            noise: NoiseLevel::Bad,
            seed,
            width: 320,
            height: 240,
            face_size: 32,
            render_threads: 2,
            score: false,
            ..ReplayConfig::default()
        };
        let run = replay_guided(&env, &cfg, seed, &UserPathParams::default(), GUIDED_ATTEMPTS).unwrap();
        let r = &run.result;
        assert!(r.incomplete.is_none(), "seed {seed}: {:?}", r.incomplete);
        let tap = r.tap_t.unwrap();
        let yaw = |(_, e, q): &(f64, glam::Quat, DQuat)| yaw_error_deg(e.as_dquat(), *q);
        let at_tap = yaw(r.track.iter().find(|(t, _, _)| *t >= tap).unwrap());
        let drift = yaw(r.track.last().unwrap()) - at_tap;
        eprintln!("seed {seed}: complete in {} pass(es), held heading's drift since the tap at the end {drift:.2} deg", run.attempts);
        assert!(drift.abs() < 5.0, "seed {seed}: the held heading drifted {drift:.2} deg");
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
/// MODE=stretch|stitch SEEDS=0-11 [SIZE=160] cargo test --test integration capture_align::diagnose --
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
    // Per image match: when, against which shot, the measured turn, the true one (the drift of
    // the guidance's heading since the earlier shot's placed pose), and whether the bias
    // learnt from it.
    let psi = |t: f64| r.track.iter().find(|(tt, _, _)| *tt >= t - 1e-9).map_or(f64::NAN, |(_, e, q)| yaw_error_deg(e.as_dquat(), *q));
    let turn_at = |t: f64| r.matches.iter().find(|m| m.t == t).map_or(0.0, |m| m.turn_deg);
    // The error rotation est · truth⁻¹ and the true camera's elevation at a frame.
    let at = |t: f64| {
        r.track.iter().find(|(tt, _, _)| *tt >= t - 1e-9).map(|(_, e, q)| {
            let err = e.as_dquat() * q.inverse();
            let axis = *q * glam::DVec3::NEG_Z;
            (err, axis.z.asin().to_degrees())
        })
    };
    // Tilt (degrees) of a rotation: the angle between where it takes the vertical and the vertical.
    let tilt = |q: DQuat| (q * glam::DVec3::Z).angle_between(glam::DVec3::Z).to_degrees();
    let mut matches = String::new();
    for m in &r.matches {
        let truth = -(psi(m.t) - psi(m.against_t) - turn_at(m.against_t));
        let ((ei, eli), (ej, elj)) = (at(m.t).unwrap(), at(m.against_t).unwrap());
        matches += &format!(
            "\n    {:5.1}s vs {:5.1}s turn {:6.2} true {:6.2}{} elev {:4.0} {:4.0} tilt err {:.1} {:.1} rel {:.1}",
            m.t - tap,
            m.against_t - tap,
            m.turn_deg,
            truth,
            if m.bias_learnt { " bias" } else { "     " },
            eli,
            elj,
            tilt(ei),
            tilt(ej),
            tilt(ei * ej.inverse()),
        );
    }
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
        "fixes {}/{} (bias {}) drift max {:.1} at {:.1}s [{}] end {}{}",
        r.drift_fixes,
        r.shots,
        r.matches.iter().filter(|m| m.bias_learnt).count(),
        worst.0,
        worst.1,
        series.trim(),
        r.incomplete.map(|s| s.replace('\n', " | ")).unwrap_or_default(),
        matches
    )
}

/// Where the stitch's error comes from, and what each alignment step does, run by hand (not
/// in CI). Per run, the shots as taken are aligned offline twice on the same images: turns
/// about the vertical only (`align_turns`, the fifth session's alignment) and then every
/// shot's whole orientation refined jointly (`refine_shots`, `align_shots`'s second step).
/// Each pose set is scored by the faces' mean stitch FLIP and PSNR against the ideal faces at
/// the front's true heading, with the shots' residual yaw and tilt against the truth (in the
/// front's true frame), and the turns-only poses also with their residual yaw alone, their
/// tilt alone and none (the true poses: what blending and resampling alone cost). With `HDR=1`
/// each shot's bracket is rendered at its true pose and the HDR faces' share of texels within
/// 10 % of the source luminance is scored too. The last two rows: the refined poses with the
/// capture's common tilt taken off with the truth (the best a vertical can do), and levelled by
/// the accelerometer held at the shots (`capture::gravity`, what `align_shots` does).
/// `CASE=random50|random100|six SEEDS=0-3 [SIZE=320] [FACE=128] [HDR=1] [NOISE=phone|bad]
/// [MAPS=dir: per run, ideal | refined | ×4 difference | levelled | ×4 difference, a face per row]
/// [DETAIL=1] cargo test --test integration capture_align::quality_errors -- --ignored --nocapture`.
#[test]
#[ignore]
fn quality_errors() {
    use glam::{DVec2, Quat};
    use previz::camera::controls::CameraSettings;
    use previz::camera::exposure::ExposureMode;
    use previz::camera::sim::{SimSettings, VirtualPhone};
    use previz::capture::align::refine_shots;
    use previz::capture::guided_path::simulate_capture_path;
    use previz::capture::hdr::{BRACKET_EV, clip_radiance, hdr_faces, merge_brackets};
    use previz::capture::projection::{face_pixel_dir_local, local_to_world};
    use previz::capture::replay::ideal_face;
    use previz::capture::reproject::{Shot, assemble_face};
    use previz::capture::{Assistant, Face};
    use previz::colour::luminance_bt709;
    let env = Arc::new(load_environment(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
    let case = env_or("CASE", "random50");
    let seeds = env_or("SEEDS", "0-3");
    let (a, b) = seeds.split_once('-').unwrap_or((&seeds, &seeds));
    let (a, b): (u64, u64) = (a.parse().unwrap(), b.parse().unwrap());
    let width: u32 = env_or("SIZE", "320").parse().unwrap();
    let face_size: u32 = env_or("FACE", "128").parse().unwrap();
    let hdr = std::env::var("HDR").is_ok();
    let vfov = if case == "random50" { 50.0 } else { 100.0 };
    let noise = if env_or("NOISE", "phone") == "bad" { NoiseLevel::Bad } else { NoiseLevel::Phone };
    const NAMES: [&str; 7] = [
        "turns",
        "turns+refine",
        "turns, yaw error only",
        "turns, tilt error only",
        "true poses",
        "refined, common tilt off",
        "refined + levelled (product)",
    ];
    let mut totals = [[0.0f64; 3]; 7];
    let mut runs = 0;
    for seed in a..=b {
        let seed = if case == "six" { 2000 + seed } else { seed };
        let cfg = ReplayConfig {
            mode: Mode::Stitch,
            noise,
            seed,
            vfov_deg: vfov,
            width,
            height: width * 3 / 4,
            face_size,
            render_threads: 2,
            score: false,
            ..ReplayConfig::default()
        };
        let trace = if case == "six" {
            TruthTrace::new(simulate_user_path(seed, &UserPathParams::default()).unwrap().samples).unwrap()
        } else {
            let targets: Vec<_> = Assistant::new(cfg.assistant().unwrap()).unwrap().targets().into_iter().cloned().collect();
            TruthTrace::new(simulate_capture_path(seed, &targets, &UserPathParams::default()).unwrap().samples).unwrap()
        };
        let r = replay(&env, &trace, &cfg).unwrap();
        let Some(cap) = r.capture.as_ref() else {
            println!("seed {seed}: incomplete");
            continue;
        };
        let meta = &cap.meta;
        let settings = CameraSettings { exposure: meta.exposure.unwrap(), white_balance: meta.white_balance.unwrap() };
        let href = meta.reference_heading_deg;
        let taken = &r.taken_shots;
        let tf = previz::pose::frames::heading_pitch_roll(trace.orientation_at(taken[0].t)).heading.to_degrees();
        let camera = cfg.camera().unwrap();
        let (w_href, w_tf) = (local_to_world(href.to_radians()), local_to_world(tf.to_radians()));
        let started = std::time::Instant::now();
        let (turned, _) = align_turns(&camera, taken, 0);
        let t_turns = started.elapsed().as_secs_f64();
        let (refined, refinement) = refine_shots(&camera, &turned, 0);
        let t_refine = started.elapsed().as_secs_f64() - t_turns;
        // A pose's error in the front's true frame, split into yaw (twist about the vertical)
        // and tilt (the swing left).
        let split = |pose: Quat, t: f64| {
            let a_local = w_href.inverse() * pose.as_dquat();
            let b_local = w_tf.inverse() * trace.orientation_at(t);
            let err = (a_local * b_local.inverse()).normalize();
            let err = if err.w < 0.0 { -err } else { err };
            let twist = DQuat::from_xyzw(0.0, 0.0, err.z, err.w).normalize();
            (err, twist, err * twist.inverse(), b_local)
        };
        let stats = |shots: &[Shot]| {
            let (mut yaw, mut tilt, mut mean) = (0.0, 0.0, DVec2::ZERO);
            for s in shots {
                let (_, twist, swing, _) = split(s.pose, s.t);
                yaw += (2.0 * twist.z.atan2(twist.w)).to_degrees().powi(2);
                tilt += (2.0 * swing.xyz().length().atan2(swing.w)).to_degrees().powi(2);
                mean += DVec2::new(swing.x, swing.y) * 2.0f64.to_degrees();
            }
            let n = shots.len() as f64;
            ((yaw / n).sqrt(), (tilt / n).sqrt(), mean / n)
        };
        if std::env::var("DETAIL").is_ok() {
            for (k, (t, f)) in turned.iter().zip(&refined).enumerate() {
                let e = |s: &Shot| {
                    let (_, twist, swing, _) = split(s.pose, s.t);
                    ((2.0 * twist.z.atan2(twist.w)).to_degrees(), (2.0 * swing.xyz().length().atan2(swing.w)).to_degrees())
                };
                let axis = t.pose * glam::Vec3::NEG_Z;
                println!("  shot {k} (elevation {:.0}°): turns {:?} refined {:?}", axis.z.asin().to_degrees(), e(t), e(f));
            }
        }
        let mut variants: Vec<Vec<Quat>> = vec![turned.iter().map(|s| s.pose).collect(), refined.iter().map(|s| s.pose).collect()];
        for pick in 0..3 {
            variants.push(
                turned
                    .iter()
                    .map(|s| {
                        let (_, twist, swing, b_local) = split(s.pose, s.t);
                        let e = [twist, swing, DQuat::IDENTITY][pick];
                        (w_href * e * b_local).normalize().as_quat()
                    })
                    .collect(),
            );
        }
        // The refined poses with the capture's common tilt (the mean over the shots of their
        // tilt error: the refinement's gauge) taken off: what a better vertical would give.
        let common = refined.iter().fold(glam::DVec3::ZERO, |acc, s| {
            let (err, _, _, _) = split(s.pose, s.t);
            let v = err.to_scaled_axis();
            acc + glam::DVec3::new(v.x, v.y, 0.0)
        }) / refined.len() as f64;
        variants.push(
            refined
                .iter()
                .map(|s| (w_href * DQuat::from_scaled_axis(-common) * w_href.inverse() * s.pose.as_dquat()).normalize().as_quat())
                .collect(),
        );
        // The product's vertical: the refined poses levelled by the accelerometer held at the
        // shots (`align_shots` does this after the refinement).
        let leveling = previz::capture::gravity::level(
            &refined.iter().map(|s| s.pose).collect::<Vec<_>>(),
            &refined.iter().map(|s| s.gravity).collect::<Vec<_>>(),
        );
        if std::env::var("DETAIL").is_ok() {
            println!("  leveling {leveling:?}");
        }
        let correction = leveling.map_or(Quat::IDENTITY, |l| l.correction);
        variants.push(refined.iter().map(|s| (correction * s.pose).normalize()).collect());
        let ideal: Vec<Vec<u8>> = Face::ALL.iter().map(|&f| ideal_face(&env, tf, f, face_size, settings)).collect();
        // HDR: every shot's bracket at its true pose, merged.
        let merged: Vec<_> = if hdr {
            let phone = VirtualPhone::new(
                env.clone(),
                &SimSettings { width: cfg.width, height: cfg.height, vfov_deg: vfov, exposure: ExposureMode::Fixed(1.0) },
            )
            .unwrap();
            taken
                .iter()
                .map(|s| {
                    let truth = trace.orientation_at(s.t).as_quat();
                    let frames: Vec<_> = BRACKET_EV
                        .iter()
                        .map(|&ev| (phone.render_with(truth, settings.with_ev(ev)).unwrap(), settings.with_ev(ev)))
                        .collect();
                    merge_brackets(&frames.iter().map(|(f, s)| (f, *s)).collect::<Vec<_>>()).unwrap()
                })
                .collect()
        } else {
            Vec::new()
        };
        let clip = clip_radiance(&BRACKET_EV.map(|ev| settings.with_ev(ev)));
        let mut line =
            format!("seed {seed}: {} shots, turns {t_turns:.2} s, refine {t_refine:.2} s ({} pairs) |", taken.len(), refinement.pairs);
        let mut maps = Vec::new();
        for (vi, poses) in variants.iter().enumerate() {
            let (db, flip) = stitch_scores(&env, &trace, &r, &cfg, poses);
            if (vi == 1 || vi == NAMES.len() - 1) && std::env::var("MAPS").is_ok() {
                let posed: Vec<Shot> = taken.iter().zip(poses).map(|(s, p)| Shot { pose: *p, ..s.clone() }).collect();
                maps.push(Face::ALL.map(|face| assemble_face(face, Mode::Stitch, &posed[0], &posed, &camera, href, face_size).rgb));
            }
            let mut within = f64::NAN;
            if hdr {
                let views: Vec<(Quat, _)> = poses.iter().copied().zip(merged.iter().cloned()).collect();
                let faces = hdr_faces(&views, &camera, href, face_size);
                let (mut ok, mut n) = (0usize, 0usize);
                for face in Face::ALL {
                    for (i, got) in faces[face.layer()].iter().enumerate() {
                        let d =
                            w_tf.as_quat() * face_pixel_dir_local(face.layer(), i as u32 % face_size, i as u32 / face_size, face_size, 1.0);
                        let src = env.sample_enu(d);
                        let want = luminance_bt709([0, 1, 2].map(|c| src[c].min(clip[c])));
                        ok += usize::from((luminance_bt709(*got) / want.max(1e-12) - 1.0).abs() <= 0.10);
                        n += 1;
                    }
                }
                within = ok as f64 / n as f64;
            }
            let shots: Vec<Shot> = taken.iter().zip(poses).map(|(s, p)| Shot { pose: *p, ..s.clone() }).collect();
            let (yaw, tilt, mean) = stats(&shots);
            line += &format!(
                " {}: FLIP {flip:.4} PSNR {db:.2} HDR {:.2}% yaw {yaw:.3}° tilt {tilt:.3}° (mean {:.2},{:.2}) |",
                NAMES[vi],
                100.0 * within,
                mean.x,
                mean.y
            );
            totals[vi][0] += flip;
            totals[vi][1] += db;
            totals[vi][2] += within;
        }
        println!("{line}");
        runs += 1;
        if let Ok(dir) = std::env::var("MAPS") {
            // Per face (rows): ideal | refined | |difference| x4 | levelled | |difference| x4.
            let s = face_size as usize;
            let mut img = image::RgbImage::new(5 * face_size, 6 * face_size);
            for row in 0..6 {
                let want = &ideal[row];
                for i in 0..s * s {
                    let (x, y) = ((i % s) as u32, (row * s + i / s) as u32);
                    let p = |v: &[u8]| image::Rgb([v[3 * i], v[3 * i + 1], v[3 * i + 2]]);
                    img.put_pixel(x, y, p(want));
                    for (k, got) in maps.iter().map(|m| &m[row]).enumerate() {
                        let d: [u8; 3] =
                            std::array::from_fn(|c| ((i32::from(want[3 * i + c]) - i32::from(got[3 * i + c])).abs() * 4).min(255) as u8);
                        img.put_pixel(x + (1 + 2 * k as u32) * face_size, y, p(got));
                        img.put_pixel(x + (2 + 2 * k as u32) * face_size, y, image::Rgb(d));
                    }
                }
            }
            img.save(format!("{dir}/{case}_{seed}.png")).unwrap();
        }
    }
    for (vi, t) in totals.iter().enumerate() {
        println!(
            "{case} {}: mean FLIP {:.4}, PSNR {:.2} dB, HDR within 10 % {:.2} % ({runs} runs)",
            NAMES[vi],
            t[0] / runs as f64,
            t[1] / runs as f64,
            100.0 * t[2] / runs as f64
        );
    }
}
