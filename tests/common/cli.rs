//! Running the `previz` binary in a test folder and checking clean failures.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run `previz ARGS` in `dir`.
pub fn previz(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_previz")).current_dir(dir).args(args).output().unwrap()
}

/// A fresh, empty folder for one test: `previz-{suite}-{name}-{pid}` in the temp folder.
pub fn tempdir(suite: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("previz-{suite}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The folder's entries, sorted.
pub fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    v.sort();
    v
}

/// A failed run: non-zero exit, the message mentions every needle, no panic, and the folder
/// holds nothing but what was there before (`before`, as [`files`] returned it).
pub fn assert_clean_failure(out: &Output, dir: &Path, before: &[PathBuf], needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "stderr should mention {n:?}: {stderr}");
    }
    let mut before = before.to_vec();
    before.sort();
    assert_eq!(files(dir), before, "files left behind");
}
