//! `previz capture` end to end: a simulated capture with --json, and bad input — each a clear
//! error, a non-zero exit, no panic, nothing written.

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use common::data;

/// A small environment: the Pisa cube faces (256 px PNG).
fn env_dir() -> String {
    data("cubemaps/humus_Park2_512").to_string_lossy().into_owned()
}

#[test]
fn simulated_capture_writes_a_loadable_folder_and_json() {
    let dir = tempdir("capture-cli", "sim");
    let out = previz(
        &dir,
        &[
            "capture",
            "--env",
            &env_dir(),
            "--simulate",
            "--seed",
            "2",
            "--noise",
            "none",
            "--mode",
            "stretch",
            "--face-size",
            "64",
            "-o",
            "cap",
            "--json",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let faces = json["faces"].as_array().unwrap();
    assert_eq!(faces.len(), 6);
    for f in faces {
        // Noise-free sensors: the shots' orientation error is the filter's residual only.
        assert!(f["orientation_error_deg"].as_f64().unwrap() < 1.0, "{f}");
        assert!(f["capture_t"].as_f64().unwrap() >= json["tap_t"].as_f64().unwrap());
        // Stretch mode: a 50° lens observes under a third of each face.
        let c = f["coverage"].as_f64().unwrap();
        assert!(c > 0.2 && c < 0.4, "{f}");
        assert!(f["psnr_db"].as_f64().unwrap() > 5.0 && f["mean_flip"].as_f64().unwrap() > 0.0, "{f}");
    }
    let cap = previz::capture::load_capture(&dir.join("cap")).unwrap();
    assert_eq!(cap.meta.face_size, 64);
    assert_eq!(cap.meta.faces.len(), 6);
    assert!(cap.meta.location.is_some() && cap.meta.time_utc.is_some() && cap.meta.exposure.is_some());
    assert!((cap.meta.reference_heading_deg - json["reference_heading_deg"].as_f64().unwrap()).abs() < 1e-9);
    // A capture folder with a face missing: loading it (as a capture or as --env) fails clearly.
    std::fs::remove_file(dir.join("cap/negy.png")).unwrap();
    let e = format!("{:#}", previz::capture::load_capture(&dir.join("cap")).unwrap_err());
    assert!(e.contains("negy.png (down)"), "{e}");
    let before = files(&dir);
    let out = previz(&dir, &["capture", "--env", "cap", "--simulate", "-o", "cap2"]);
    assert_clean_failure(&out, &dir, &before, &["cap", "negy"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_traces_and_inputs_fail_cleanly() {
    let dir = tempdir("capture-cli", "bad");
    let good_rows = "0,1,0,0,0,0\n0.1,1,0,0,0,1\n";
    let traces = [
        ("nan.csv", format!("t,qw,qx,qy,qz,tap\n{good_rows}0.2,NaN,0,0,0,0\n"), vec!["nan.csv"]),
        ("nonunit.csv", format!("t,qw,qx,qy,qz,tap\n{good_rows}0.2,1,1,0,0,0\n"), vec!["nonunit.csv", "unit"]),
        ("back.csv", format!("t,qw,qx,qy,qz,tap\n{good_rows}0.05,1,0,0,0,0\n"), vec!["back.csv", "backwards"]),
        ("missing.csv", "t,qw,qx,qy,tap\n0,1,0,0,0\n".to_string(), vec!["missing.csv", "qz"]),
        ("empty.csv", String::new(), vec!["empty.csv"]),
    ];
    for (name, text, _) in &traces {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let before = files(&dir);
    let env = env_dir();
    for (name, _, needles) in &traces {
        let out = previz(&dir, &["capture", "--env", &env, "--trace", name, "-o", "out"]);
        assert_clean_failure(&out, &dir, &before, needles);
    }
    // A valid trace where the user taps and never turns: incomplete, naming the faces and why.
    let still: String = std::iter::once("t,qw,qx,qy,qz,tap\n".to_string())
        .chain((0..300).map(|i| format!("{},0.7071068,0.7071068,0,0,{}\n", i as f64 * 0.01, u8::from(i == 150))))
        .collect();
    std::fs::write(dir.join("still.csv"), still).unwrap();
    let before = files(&dir);
    let out = previz(&dir, &["capture", "--env", &env, "--trace", "still.csv", "--noise", "none", "--mode", "stretch", "-o", "out"]);
    assert_clean_failure(
        &out,
        &dir,
        &before,
        // The tolerance is 2° widened by twice the pose's own uncertainty (so not a fixed ±2°).
        &["capture incomplete", "5 face(s) missing", "up: never within ±", "° (closest 90.0° off", "left:"],
    );
    // Stitch mode (the default) also misses the rest of the front, says how much of it is
    // unseen, and how many shots are not taken.
    let out = previz(&dir, &["capture", "--env", &env, "--trace", "still.csv", "--noise", "none", "-o", "out"]);
    assert_clean_failure(&out, &dir, &before, &["6 face(s) missing", "front: ", "% of the face unseen", "more shot(s) not taken"]);
    // An environment that fails to load, a bad face size, no trace.
    let out = previz(&dir, &["capture", "--env", "nope.hdr", "--trace", "still.csv", "-o", "out"]);
    assert_clean_failure(&out, &dir, &before, &["nope.hdr"]);
    let out = previz(&dir, &["capture", "--env", &env, "--trace", "still.csv", "--face-size", "100", "-o", "out"]);
    assert_clean_failure(&out, &dir, &before, &["--face-size", "power of two"]);
    let out = previz(&dir, &["capture", "--env", &env, "-o", "out"]);
    assert_clean_failure(&out, &dir, &before, &["--trace", "--simulate"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 12: the default command (`previz capture --env ENV --simulate -o DIR`, stitch mode,
/// phone-grade noise, 50° lens) failed for seeds 0–3 in the quarry HDR with "5 face(s)
/// missing". Every one of them must complete now (faces at 64 px to keep the test cheap; the
/// face size does not change what is taken).
#[test]
fn default_command_completes_for_the_seeds_that_failed() {
    let dir = tempdir("capture-cli", "seeds");
    let env = data("hdri/polyhaven_1k/quarry_01_1k.hdr").to_string_lossy().into_owned();
    for seed in ["0", "1", "2", "3"] {
        let out_dir = format!("cap{seed}");
        let mut args = vec!["capture", "--env", &env, "--simulate", "--seed", seed, "--face-size", "64", "-o", &out_dir, "--json"];
        if seed == "0" {
            args.push("--hdr");
        }
        let out = previz(&dir, &args);
        assert!(out.status.success(), "seed {seed}: {}", String::from_utf8_lossy(&out.stderr));
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        // The simulated world puts the map's sun where SPA has it: north from the sun.
        assert_eq!(json["heading"]["source"], "sun", "seed {seed}: {}", json["heading"]);
        if seed == "0" {
            // HDR: float faces beside the PNGs, and they are what an environment load reads.
            let cap = dir.join(&out_dir);
            assert!(json["hdr"]["clip_radiance"].is_array(), "{}", json["hdr"]);
            let env = previz::scene::environment::load_environment(&cap).unwrap();
            let max = env.faces.iter().flatten().flatten().fold(0f32, |m, v| m.max(*v));
            assert!(max > 1.0, "float radiance, brightest {max}");
        }
        for f in json["faces"].as_array().unwrap() {
            // Complete means every face seen but for a sliver (assistant::MAX_UNSEEN = 2 %).
            assert!(f["coverage"].as_f64().unwrap() >= 0.98, "seed {seed}: {f}");
        }
        assert!(previz::capture::load_capture(&dir.join(&out_dir)).is_ok());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
