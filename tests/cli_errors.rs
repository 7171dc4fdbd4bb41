//! Hostile-but-realistic command lines (issue 8, "Robustness"): each gives a clear error naming
//! the flag or key, a non-zero exit, no panic and no output file; or, where the issue asks for
//! it, does the sensible thing (a JPEG for `-o out.jpg`, a created `--layers` folder, a quiet
//! exit when the reader of stdout goes away).

use crate::common;

use common::cli::{assert_clean_failure, files, previz, tempdir};
use std::process::Command;

#[test]
fn flag_values_out_of_range_name_the_flag_and_the_range() {
    let dir = tempdir("cli-errors", "ranges");
    let before = files(&dir);
    let sun = ["sun", "--lat", "51.5", "--lon", "-0.1", "--time", "2024-06-21T12:00:00Z"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> { sun.iter().chain(extra).copied().collect() };
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["composite", "--width", "-1"], vec!["--width", "-1", "1..=8192"]),
        (vec!["composite", "--height", "100000"], vec!["--height", "1..=8192"]),
        (vec!["composite", "-o", ""], vec!["--output"]),
        (vec!["composite", "--set", "output="], vec!["output", "empty"]),
        (vec!["composite", "-o", "out.tiff"], vec!["output", "out.tiff", ".png, .jpg or .jpeg"]),
        (with(&["--slope", "1000", "--surface-azimuth", "0"]), vec!["--slope 1000", "0..=180"]),
        (with(&["--slope", "-5", "--surface-azimuth", "0"]), vec!["--slope -5"]),
        (with(&["--slope", "30", "--surface-azimuth", "-720"]), vec!["--surface-azimuth -720"]),
        (vec!["capture", "--env", "env.hdr", "--simulate", "-o", "cap", "--vfov", "1e-9"], vec!["--vfov", "20..=120"]),
        (vec!["live", "--frames", "1000000000", "-o", "frames"], vec!["--frames 1000000000", "1..=1800"]),
        (vec!["live", "--fps", "-5", "--frames", "1", "-o", "frames"], vec!["--fps", "1..=240"]),
    ];
    for (args, needles) in cases {
        let out = previz(&dir, &args);
        assert_clean_failure(&out, &dir, &before, &needles);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn scene_file_output_is_checked_and_relative_to_the_scene_folder() {
    let dir = tempdir("cli-errors", "scene-output");
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::write(dir.join("scenes/empty.toml"), "output = \"\"\n").unwrap();
    let before = files(&dir);
    let out = previz(&dir, &["composite", "scenes/empty.toml"]);
    assert_clean_failure(&out, &dir, &before, &["scenes/empty.toml", "output", "empty"]);
    // Relative to the scene's folder, as the help says (checked with the parsed scene: a
    // render is not needed to see where the path points).
    std::fs::write(dir.join("scenes/s.toml"), "output = \"out/c.png\"\n").unwrap();
    let scene = previz::setup::scene_file::SceneBuilder::from_file(&dir.join("scenes/s.toml")).unwrap().build().unwrap();
    assert_eq!(scene.output, dir.join("scenes/out/c.png"));
    // Without the key the default stays in the current directory.
    std::fs::write(dir.join("scenes/d.toml"), "width = 64\n").unwrap();
    let scene = previz::setup::scene_file::SceneBuilder::from_file(&dir.join("scenes/d.toml")).unwrap().build().unwrap();
    assert_eq!(scene.output, std::path::Path::new("composite.png"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn jpg_output_is_jpeg_and_layers_dir_is_created() {
    let dir = tempdir("cli-errors", "jpeg");
    let out = previz(&dir, &["composite", "--width", "96", "--height", "64", "-o", "c.jpg", "--layers", "new/layers"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(dir.join("c.jpg")).unwrap();
    assert_eq!(&bytes[..3], &[0xFF, 0xD8, 0xFF], "JPEG SOI marker");
    assert_eq!(image::load_from_memory(&bytes).unwrap().width(), 96);
    assert!(dir.join("new/layers/composite.png").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn closed_stdout_is_a_quiet_success() {
    // The reader end is closed before the program starts, so its first print meets EPIPE
    // (`previz sun ... | true` where `true` has already exited).
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(env!("CARGO_BIN_EXE_previz"))
        .args(["sun", "--lat", "51.5", "--lon", "-0.1", "--time", "2024-06-21T12:00:00Z", "--json"])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "status {:?}: {stderr}", out.status);
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");
}
