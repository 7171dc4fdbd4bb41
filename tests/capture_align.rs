//! The image alignment pays: on pre-recorded six-face hand-held paths (seed 000's procedure,
//! 100° lens, `phone` noise) into the quarry HDR, aligning the shots from their overlaps raises
//! the faces' PSNR against the ideal faces at the front's true heading (the stitch's own
//! quality, without the compass's error in the reference heading) and lowers their mean FLIP.

mod common;

use common::data;
use previz::capture::Mode;
use previz::capture::replay::{ReplayConfig, replay};
use previz::pose::hand_motion::{UserPathParams, simulate_user_path};
use previz::pose::trace::TruthTrace;
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
