//! The library reads as layers, lowest first, and nothing imports upward (DESIGN.md):
//! `gpu` (with the file/chart writers) → `render` and the CPU science and data modules → scene
//! set-up → the app and the CLI. Every top-level module of app/src is placed in one tier; a
//! reference `crate::m` (or `previz::m` from main.rs) from a lower tier to a higher one fails.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

/// The tiers, lowest first. A module not listed here fails the test: place it when you add it.
const TIERS: &[&[&str]] = &[
    // Foundations: the GPU layer and the writers every layer uses.
    &["gpu", "output", "chart"],
    // Render (passes, pipelines) and the science and data modules it stands beside.
    &["render", "sun", "pose", "sensors", "camera", "colour", "priors", "capture", "scene", "light"],
    // Scene set-up: the scene file, inputs, exposure, light from the environment, frame parameters.
    &["setup"],
    // The app (modes, UI, frame loop), measurements and the CLI.
    &["live", "ui", "bench", "cli", "fuzzing", "main"],
];

fn tier_of(module: &str) -> Option<usize> {
    TIERS.iter().position(|tier| tier.contains(&module))
}

/// Drops comments: whole-line `//`, `///`, `//!` and trailing `// …` (doc links are not imports).
fn code_only(line: &str) -> &str {
    match line.find("//") {
        Some(i) => &line[..i],
        None => line,
    }
}

/// The top-level modules a source text refers to through `crate::` (or `previz::`), with the
/// line each appears on; macros (`crate::name!`) are not modules.
fn referenced_modules(source: &str, root: &str) -> Vec<(String, usize)> {
    let prefix = format!("{root}::");
    let mut found = Vec::new();
    for (n, line) in source.lines().enumerate() {
        let code = code_only(line);
        let mut rest = code;
        while let Some(i) = rest.find(&prefix) {
            let preceded_by_ident = rest[..i].chars().next_back().is_some_and(|c| c.is_alphanumeric() || c == '_');
            rest = &rest[i + prefix.len()..];
            if preceded_by_ident {
                continue;
            }
            if let Some(group) = rest.strip_prefix('{') {
                // `crate::{a::X, b}`: the first segment of each item in the group.
                let inner = &group[..group.find('}').unwrap_or(group.len())];
                for item in inner.split(',') {
                    let name: String = item.trim().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                    if !name.is_empty() {
                        found.push((name, n + 1));
                    }
                }
                continue;
            }
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if !name.is_empty() && !rest[name.len()..].starts_with('!') {
                found.push((name, n + 1));
            }
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level module a file under app/src belongs to (`lib` for lib.rs).
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel.components().next().unwrap().as_os_str().to_string_lossy().into_owned();
    first.strip_suffix(".rs").map(str::to_owned).unwrap_or(first)
}

/// Upward references as "file:line: from → to" lines.
fn upward_references(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    let mut bad = Vec::new();
    for file in &files {
        let from = module_of(src, file);
        if from == "lib" {
            continue;
        }
        let from_tier = tier_of(&from).unwrap_or_else(|| panic!("{}: module `{from}` is in no tier of tests/layers.rs", file.display()));
        let root = if from == "main" { "previz" } else { "crate" };
        for (to, line) in referenced_modules(&fs::read_to_string(file).unwrap(), root) {
            let to_tier = tier_of(&to).unwrap_or_else(|| panic!("{}:{line}: `{to}` is in no tier of tests/layers.rs", file.display()));
            if to_tier > from_tier {
                bad.push(format!("{}:{line}: {from} (tier {from_tier}) → {to} (tier {to_tier})", file.display()));
            }
        }
    }
    bad
}

#[test]
fn nothing_imports_upward() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("app/src");
    let bad = upward_references(&src);
    assert!(bad.is_empty(), "upward imports:\n{}", bad.join("\n"));
}

#[test]
fn every_module_of_the_library_has_a_tier() {
    let lib = fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("app/src/lib.rs")).unwrap();
    let modules: Vec<&str> = lib.lines().filter_map(|l| l.trim().strip_prefix("pub mod ")?.strip_suffix(';')).collect();
    assert!(modules.len() >= 10, "parsed only {modules:?} from lib.rs");
    let placed: BTreeMap<&str, Option<usize>> = modules.iter().map(|m| (*m, tier_of(m))).collect();
    let unplaced: Vec<_> = placed.iter().filter(|(_, t)| t.is_none()).map(|(m, _)| *m).collect();
    assert!(unplaced.is_empty(), "modules in no tier: {unplaced:?}");
}

#[test]
fn the_scanner_sees_paths_groups_and_skips_comments_and_macros() {
    let text = "use crate::render::Compositor;\n\
                use crate::{setup::light, gpu};\n\
                // see crate::live::App\n\
                let x = crate::bench::median(&v); // crate::cli\n\
                crate::assert_wgsl_layout!(T);\n\
                let y = notcrate::live::f();\n";
    let found: Vec<(String, usize)> = referenced_modules(text, "crate");
    let names: Vec<(&str, usize)> = found.iter().map(|(m, l)| (m.as_str(), *l)).collect();
    assert_eq!(names, [("render", 1), ("setup", 2), ("gpu", 2), ("bench", 4)]);
    // And a tier-1 file that refers to the app would be reported.
    let dir = std::env::temp_dir().join(format!("previz-layers-{}", std::process::id()));
    fs::create_dir_all(dir.join("render")).unwrap();
    fs::write(dir.join("render/bad.rs"), "use crate::live::LiveSession;\n").unwrap();
    fs::write(dir.join("lib.rs"), "pub mod render;\n").unwrap();
    let bad = upward_references(&dir);
    fs::remove_dir_all(&dir).unwrap();
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(bad[0].ends_with("render (tier 1) → live (tier 3)"), "{bad:?}");
}

/// Cargo builds only the test targets Cargo.toml lists (`autotests = false`, tests/integration.rs
/// says why): every file directly in tests/ is either one of them or a module of the shared
/// binary, and every module declared there exists, so a new test file cannot silently not run.
#[test]
fn every_test_file_is_built() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let targets: Vec<&str> =
        manifest.lines().filter_map(|l| l.trim().strip_prefix("path = \"tests/").and_then(|p| p.strip_suffix(".rs\""))).collect();
    assert!(targets.contains(&"integration"), "Cargo.toml lists no tests/integration.rs target");
    let shared = fs::read_to_string(root.join("tests/integration.rs")).unwrap();
    let modules: Vec<&str> =
        shared.lines().filter_map(|l| l.strip_prefix("mod ").and_then(|m| m.strip_suffix(';'))).filter(|m| *m != "common").collect();
    let mut files: Vec<String> = fs::read_dir(root.join("tests"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert!(files.len() > 10, "tests/ read as {files:?}");
    let unbuilt: Vec<&String> = files.iter().filter(|f| !targets.contains(&f.as_str()) && !modules.contains(&f.as_str())).collect();
    assert!(
        unbuilt.is_empty(),
        "tests/NAME.rs for NAME in {unbuilt:?}: neither a [[test]] in Cargo.toml nor a `mod` of tests/integration.rs"
    );
    let twice: Vec<&&str> = modules.iter().filter(|m| targets.contains(m)).collect();
    assert!(twice.is_empty(), "{twice:?}: both a [[test]] of their own and a module of tests/integration.rs");
    let missing: Vec<&&str> = modules.iter().chain(&targets).filter(|m| !files.iter().any(|f| f == *m)).collect();
    assert!(missing.is_empty(), "declared but no tests/NAME.rs: {missing:?}");
}
