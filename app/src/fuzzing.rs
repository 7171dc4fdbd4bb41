//! Entry points of the fuzz targets (tests/fuzz/, cargo-fuzz) and of the corpus replay test
//! (tests/fuzz_corpus.rs): one function per loader, taking arbitrary bytes. Each must return
//! without panicking whatever the bytes; an input the loader accepts must also give a result
//! that keeps the loader's promises (checked here with `assert!`, so a wrong success is a crash
//! the fuzzer reports). Returns whether the input was accepted.

use crate::scene::Model;
use std::path::Path;

/// OBJ and MTL: the bytes before the first NUL are the OBJ, the rest is the material library
/// every `mtllib` gets.
pub fn obj_mtl(data: &[u8]) -> bool {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    match crate::scene::model::load_obj_mtl_bytes(obj, mtl) {
        Ok(model) => check_model(&model),
        Err(_) => false,
    }
}

/// glTF JSON or GLB (external files refused).
pub fn gltf(data: &[u8]) -> bool {
    match crate::scene::model::load_glb_bytes(data) {
        Ok(model) => check_model(&model),
        Err(_) => false,
    }
}

/// An equirectangular environment (Radiance HDR, OpenEXR, PNG, JPEG), resampled to a small cube.
pub fn hdr_exr(data: &[u8]) -> bool {
    match crate::scene::environment::equirect_from_bytes(data) {
        Ok(e) => {
            let cube = e.to_cube(4, 0.0);
            for face in &cube.faces {
                assert!(face.iter().flatten().all(|c| c.is_finite() && *c >= 0.0), "environment radiance must be finite and ≥ 0");
            }
            true
        }
        Err(_) => false,
    }
}

/// A scene file (TOML) checked as `previz composite` checks it.
pub fn scene_toml(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else { return false };
    let Ok(builder) = crate::setup::scene_file::SceneBuilder::from_toml(text, Path::new("/nonexistent-fuzz-dir")) else { return false };
    match builder.build() {
        Ok(scene) => {
            assert!(scene.width >= 1 && scene.height >= 1);
            assert!(!scene.output.as_os_str().is_empty());
            true
        }
        Err(_) => false,
    }
}

/// A trace CSV, read as a truth trace (t,qw,qx,qy,qz,tap) and as a sensor trace.
pub fn trace_csv(data: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(data) else { return false };
    let path = Path::new("fuzz.csv");
    let truth = match crate::pose::trace::parse_truth_trace(path, text) {
        Ok(samples) => {
            let trace = crate::pose::trace::TruthTrace::new(samples).expect("a loaded trace is a valid TruthTrace");
            assert!(trace.end() - trace.start() <= crate::sensors::csv::MAX_TIME_GAP_S * trace.samples().len() as f64);
            let q = trace.orientation_at(0.5 * (trace.start() + trace.end()));
            assert!(q.is_finite() && (q.length() - 1.0).abs() < 1e-6, "orientation {q:?}");
            true
        }
        Err(_) => false,
    };
    let sensors = crate::sensors::replay::parse_sensor_trace(path, text).is_ok();
    truth || sensors
}

/// What every loaded model promises: triangles, indices in range, finite unit normals, finite
/// positions and texture coordinates, one entry of each per vertex, materials that exist.
fn check_model(model: &Model) -> bool {
    assert!(model.triangle_count() > 0);
    for mesh in &model.meshes {
        let n = mesh.positions.len();
        assert!(mesh.normals.len() == n && mesh.uvs.len() == n, "attribute counts differ");
        assert!(mesh.indices.len() % 3 == 0 && mesh.indices.iter().all(|&i| (i as usize) < n), "bad index");
        assert!(mesh.material < model.materials.len(), "missing material");
        assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()), "non-finite position");
        assert!(mesh.uvs.iter().flatten().all(|c| c.is_finite()), "non-finite uv");
        for nrm in &mesh.normals {
            let len = glam::Vec3::from_array(*nrm).length();
            assert!((len - 1.0).abs() < 1e-3, "normal {nrm:?} is not unit length");
        }
    }
    for m in &model.materials {
        assert!(m.diffuse.iter().chain(&m.specular).all(|c| c.is_finite() && *c >= 0.0), "material {m:?}");
        assert!(m.shininess.is_finite() && (0.0..=1.0).contains(&m.opacity));
    }
    true
}
