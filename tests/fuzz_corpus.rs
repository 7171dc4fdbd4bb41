//! Replays every file of the fuzz corpora (tests/fuzz/corpus/TARGET/) through the loader its
//! target feeds, as an ordinary test: none may panic (the entry points also assert what an
//! accepted input promises). The corpora are the hand-written seeds plus the libFuzzer runs'
//! corpora reduced to a set cover of their edges; the runs are recorded in docs/robustness.md.

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

/// A mutation smoke run on stable Rust (no coverage guidance; cargo-fuzz is the real fuzzer):
/// `PREVIZ_MUTATIONS=N cargo test --test integration fuzz_corpus:: -- --ignored` feeds N mutants of
/// the corpus files (bit flips, interesting bytes, deleted, duplicated and spliced chunks) to
/// each target; none may panic. Prints executions and the slowest input per target.
#[test]
#[ignore = "long: a mutation run, see docs/robustness.md"]
fn corpus_mutants_load_or_fail_cleanly() {
    use rand::{Rng, SeedableRng};
    let runs: usize = std::env::var("PREVIZ_MUTATIONS").ok().and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/corpus");
    let out = std::env::temp_dir().join("previz-mutants");
    std::fs::create_dir_all(&out).unwrap();
    let mut failures = Vec::new();
    for (name, target) in TARGETS {
        let corpus: Vec<Vec<u8>> = std::fs::read_dir(root.join(name)).unwrap().map(|e| std::fs::read(e.unwrap().path()).unwrap()).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let (mut accepted, mut slowest) = (0usize, (std::time::Duration::ZERO, 0usize));
        let start = std::time::Instant::now();
        for run in 0..runs {
            let mut d = corpus[rng.random_range(0..corpus.len())].clone();
            for _ in 0..rng.random_range(1..=8) {
                let len = d.len();
                match rng.random_range(0..6) {
                    0 if len > 0 => {
                        let i = rng.random_range(0..len);
                        d[i] ^= 1 << rng.random_range(0..8);
                    }
                    1 if len > 0 => {
                        let i = rng.random_range(0..len);
                        d[i] = [0u8, 0xFF, 0x7F, 0x80, b'0', b'9', b'-', b'\n', b',', b'e'][rng.random_range(0..10)];
                    }
                    2 if len > 0 => {
                        let (a, n) = (rng.random_range(0..len), rng.random_range(1..=64));
                        d.drain(a..(a + n).min(len));
                    }
                    3 if len > 0 => {
                        let (a, n) = (rng.random_range(0..len), rng.random_range(1..=64));
                        let chunk = d[a..(a + n).min(len)].to_vec();
                        let at = rng.random_range(0..=len);
                        for _ in 0..rng.random_range(1..=4) {
                            d.splice(at..at, chunk.iter().copied());
                        }
                    }
                    4 => {
                        let other = &corpus[rng.random_range(0..corpus.len())];
                        let cut = rng.random_range(0..=d.len());
                        let from = rng.random_range(0..=other.len());
                        d.truncate(cut);
                        d.extend_from_slice(&other[from..]);
                    }
                    _ => {
                        let at = rng.random_range(0..=len);
                        let digits = format!("{}", [1e39, -1.0, 65536.0, 4294967296.0, 1e300, f64::NAN][rng.random_range(0..6)]);
                        d.splice(at..at, digits.bytes());
                    }
                }
            }
            let t = std::time::Instant::now();
            match std::panic::catch_unwind(|| target(&d)) {
                Ok(ok) => accepted += usize::from(ok),
                Err(_) => {
                    let path = out.join(format!("{name}-{run}"));
                    std::fs::write(&path, &d).unwrap();
                    failures.push(path.display().to_string());
                }
            }
            let took = t.elapsed();
            if took.as_secs_f64() > 1.0 {
                // Not an assertion (the suite has no timed ones): saved for a look.
                let path = out.join(format!("{name}-{run}-slow"));
                std::fs::write(&path, &d).unwrap();
                println!("{name}: run {run} took {:.1} s, saved as {}", took.as_secs_f64(), path.display());
            }
            slowest = slowest.max((took, run));
        }
        println!(
            "{name}: {runs} mutants, {accepted} accepted, {:.1} s, slowest {:.1} ms (run {})",
            start.elapsed().as_secs_f64(),
            slowest.0.as_secs_f64() * 1e3,
            slowest.1
        );
    }
    assert!(failures.is_empty(), "panicking inputs saved: {failures:?}");
}
