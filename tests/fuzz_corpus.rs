//! Replays every file of the fuzz corpora (tests/fuzz/corpus/TARGET/) through the loader its
//! target feeds, as an ordinary test: none may panic (the entry points also assert what an
//! accepted input promises). The corpora were minimised with `cargo fuzz cmin`; the runs that
//! grew them are recorded in docs/robustness.md.

use std::path::Path;

type Target = fn(&[u8]) -> bool;

const TARGETS: [(&str, Target); 5] = [
    ("obj_mtl", previz::fuzzing::obj_mtl),
    ("gltf", previz::fuzzing::gltf),
    ("hdr_exr", previz::fuzzing::hdr_exr),
    ("scene_toml", previz::fuzzing::scene_toml),
    ("trace_csv", previz::fuzzing::trace_csv),
];

#[test]
fn every_corpus_file_loads_or_fails_cleanly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/corpus");
    for (name, target) in TARGETS {
        let dir = root.join(name);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("corpus {}: {e}", dir.display()))
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        let mut accepted = 0;
        for f in &files {
            let bytes = std::fs::read(f).unwrap();
            let ok = std::panic::catch_unwind(|| target(&bytes)).unwrap_or_else(|_| panic!("{name}: {} panicked", f.display()));
            accepted += usize::from(ok);
        }
        // A corpus that no input passes would test only the error paths.
        assert!(files.len() >= 2 && accepted >= 1, "{name}: {} files, {accepted} accepted", files.len());
        println!("{name}: {} corpus files, {accepted} accepted", files.len());
    }
}
