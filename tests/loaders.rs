//! Asset loaders against the real files in tests/data (tests/data/SOURCES.md gives origin and
//! licence; the counts checked are the published ones) and against bad input written to
//! temporary folders. Needs nothing outside the repository.

use glam::Vec3;
use previz::colour::luminance_bt709;
use previz::scene::background::load_image;
use previz::scene::environment::{
    EnvOptions, cube_dir_to_face_uv, face_uv_to_cube_dir, load_environment, load_environment_with, load_equirect, texel_solid_angle,
};
use previz::scene::model::{ModelOptions, load_model, load_model_with};
use previz::scene::{CubeMap, Mesh, Model, cube_to_enu, enu_to_cube};
use std::path::{Path, PathBuf};

/// The loader test data in the repository (tests/data/SOURCES.md gives origin and licence).
fn data(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data")).join(rel)
}

/// A fresh temporary folder for one test.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("previz-loaders-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn v(p: [f32; 3]) -> Vec3 {
    Vec3::from_array(p)
}

fn tri(mesh: &Mesh, t: usize) -> [usize; 3] {
    [mesh.indices[3 * t] as usize, mesh.indices[3 * t + 1] as usize, mesh.indices[3 * t + 2] as usize]
}

/// Every normal unit length; returns the fraction of triangle corners whose vertex normal
/// points to the same side as the triangle's winding normal.
fn normals_check(model: &Model) -> f64 {
    let (mut agree, mut total) = (0usize, 0usize);
    for mesh in &model.meshes {
        assert_eq!(mesh.normals.len(), mesh.positions.len());
        assert_eq!(mesh.uvs.len(), mesh.positions.len());
        for n in &mesh.normals {
            assert!((v(*n).length() - 1.0).abs() < 1e-4, "normal {n:?} not unit length");
        }
        for t in 0..mesh.indices.len() / 3 {
            let [a, b, c] = tri(mesh, t);
            let face = (v(mesh.positions[b]) - v(mesh.positions[a])).cross(v(mesh.positions[c]) - v(mesh.positions[a]));
            if face.length_squared() == 0.0 {
                continue;
            }
            for i in [a, b, c] {
                total += 1;
                agree += (v(mesh.normals[i]).dot(face) > 0.0) as usize;
            }
        }
    }
    agree as f64 / total as f64
}

/// Signed volume (divergence theorem, Σ a·(b×c)/6): positive when a closed mesh is wound with
/// outward-facing triangles.
fn signed_volume(model: &Model) -> f64 {
    let mut vol = 0.0f64;
    for mesh in &model.meshes {
        for t in 0..mesh.indices.len() / 3 {
            let [a, b, c] = tri(mesh, t).map(|i| v(mesh.positions[i]).as_dvec3());
            vol += a.dot(b.cross(c)) / 6.0;
        }
    }
    vol
}

// ---------------------------------------------------------------------------------- OBJ

#[test]
fn spider_obj_with_five_textured_materials_and_backslash_paths() {
    let loaded = load_model_with(&data("textured_models/spider/spider.obj"), &ModelOptions::default()).unwrap();
    let m = &loaded.model;
    // SOURCES.md: 1,368 triangles, 5 materials, each with a map_Kd written as `.\name.jpg`.
    assert_eq!(m.triangle_count(), 1368);
    let mut names: Vec<&str> = m.materials.iter().map(|m| m.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["Augentex", "BeinTex", "Brusttex", "HLeibTex", "Skin"]);
    let skin = m.materials.iter().find(|m| m.name == "Skin").unwrap();
    assert_eq!(skin.diffuse, [0.827451, 0.792157, 0.772549]);
    // The texture is the JPEG's pixels, decoded independently here.
    let tex = skin.texture.as_ref().unwrap();
    let direct = image::open(data("textured_models/spider/wal67ar_small.jpg")).unwrap().to_rgba8();
    assert_eq!((tex.width, tex.height), direct.dimensions());
    assert_eq!(tex.pixels, direct.into_raw());
    assert!(m.materials.iter().all(|m| m.texture.is_some()));
    // Groups of one material are merged: Skin, HLeibTex, BeinTex, Augentex are used by faces,
    // Brusttex by none (no `usemtl Brusttex` in the file).
    assert!(m.meshes.iter().all(|mesh| mesh.material < 5));
    assert_eq!(m.meshes.len(), 4);
    // The file's own normals are kept (normalised) except its one `vn 0 0 0`: every distinct
    // v/vt/vn corner using it gets the mean of its faces instead. Count those in the text.
    let text = std::fs::read_to_string(data("textured_models/spider/spider.obj")).unwrap();
    let vns: Vec<&str> = text.lines().filter(|l| l.starts_with("vn ")).collect();
    let zero = 1 + vns.iter().position(|l| l.split_whitespace().skip(1).all(|c| c.parse::<f32>().unwrap() == 0.0)).unwrap();
    let corners: std::collections::HashSet<&str> = text
        .lines()
        .filter(|l| l.starts_with("f "))
        .flat_map(|l| l.split_whitespace().skip(1))
        .filter(|c| c.rsplit('/').next() == Some(zero.to_string().as_str()))
        .collect();
    assert_eq!(loaded.notes.len(), 1, "{:?}", loaded.notes);
    assert!(loaded.notes[0].contains(&format!("{} zero or invalid normal", corners.len())), "{:?}", loaded.notes);
    assert!(normals_check(m) > 0.9);
    // UVs: OBJ's v points up the image, ours down: every loaded (u, v) is a file `vt` (u, 1 − v).
    // (The spider's UVs tile: they range over about −0.5..1.5.)
    let mut file_vt: Vec<(f32, f32)> = text
        .lines()
        .filter(|l| l.starts_with("vt "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().skip(1).map(|c| c.parse().unwrap()).collect();
            (c[0], c[1])
        })
        .collect();
    file_vt.sort_by(|a, b| a.0.total_cmp(&b.0));
    let in_file = |u: f32, v: f32| {
        let from = file_vt.partition_point(|t| t.0 < u - 1e-5);
        file_vt[from..].iter().take_while(|t| t.0 <= u + 1e-5).any(|t| (t.1 - v).abs() <= 1e-5)
    };
    assert!(m.meshes.iter().flat_map(|mesh| &mesh.uvs).all(|uv| in_file(uv[0], 1.0 - uv[1])));
}

#[test]
fn spot_without_mtl_or_normals_gets_computed_normals_and_a_given_texture() {
    let path = data("textured_models/spot/spot_triangulated.obj");
    let options = ModelOptions { texture: Some(data("textured_models/spot/spot_texture.png")), ..Default::default() };
    let loaded = load_model_with(&path, &options).unwrap();
    let m = &loaded.model;
    assert_eq!(m.triangle_count(), 5856);
    assert!(loaded.notes.iter().any(|n| n.contains("computed smooth normals")), "{:?}", loaded.notes);
    let tex = m.materials[0].texture.as_ref().unwrap();
    assert_eq!((tex.width, tex.height), (1024, 1024));
    // Computed normals: unit length and on the front side of every corner's own face.
    assert_eq!(normals_check(m), 1.0);
    // Closed, outward-wound genus-0 mesh (SOURCES.md): positive volume.
    assert!(signed_volume(m) > 0.0);
    // The UV seams did not become normal seams (vertices are welded by position).
    assert!(seams_smoothed(&m.meshes[0], 60.0) > 100, "spot has UV seams");
}

/// Where several vertices share a position (UV or patch seams) and every face around that
/// position lies within the crease angle of every other, the crease rule gives them all the
/// same normal. Checks that and returns how many such seam positions there were.
fn seams_smoothed(mesh: &Mesh, crease_deg: f32) -> usize {
    let mut faces_at: std::collections::HashMap<[u32; 3], Vec<Vec3>> = Default::default();
    let mut normals_at: std::collections::HashMap<[u32; 3], Vec<Vec3>> = Default::default();
    for t in 0..mesh.indices.len() / 3 {
        let [a, b, c] = tri(mesh, t);
        let n = (v(mesh.positions[b]) - v(mesh.positions[a])).cross(v(mesh.positions[c]) - v(mesh.positions[a])).normalize_or_zero();
        for i in [a, b, c] {
            faces_at.entry(mesh.positions[i].map(f32::to_bits)).or_default().push(n);
            normals_at.entry(mesh.positions[i].map(f32::to_bits)).or_default().push(v(mesh.normals[i]));
        }
    }
    let cos = crease_deg.to_radians().cos() + 1e-3;
    let mut checked = 0;
    for (key, faces) in &faces_at {
        let mut vertices: Vec<u32> =
            (0..mesh.positions.len()).filter(|&i| mesh.positions[i].map(f32::to_bits) == *key).map(|i| i as u32).collect();
        vertices.dedup();
        let smooth = faces.iter().all(|f| faces.iter().all(|g| f.dot(*g) >= cos));
        if vertices.len() < 2 || !smooth {
            continue;
        }
        let ns = &normals_at[key];
        assert!(ns.iter().all(|n| n.dot(ns[0]) > 1.0 - 1e-6), "split normals at a smooth seam {key:?}");
        checked += 1;
    }
    checked
}

#[test]
fn missing_mtllib_is_tolerated_with_a_note() {
    for (file, tris) in [("meshes/bunny-crane-with-normals.obj", 28_576), ("meshes/stanford-dragon-100k.obj", 100_000)] {
        let loaded = load_model_with(&data(file), &ModelOptions::default()).unwrap();
        let m = &loaded.model;
        assert_eq!(m.triangle_count(), tris, "{file}");
        assert!(loaded.notes.iter().any(|n| n.contains(".mtl") && n.contains("not found")), "{file}: {:?}", loaded.notes);
        assert_eq!(m.materials.len(), 1);
        assert_eq!(m.materials[0].name, "default");
        // Both are closed and outward-wound (SOURCES.md); normals face out.
        assert!(signed_volume(m) > 0.0, "{file}");
        assert!(normals_check(m) > 0.99, "{file}");
    }
}

#[test]
fn dragon_bounds_and_computed_normals() {
    let loaded = load_model_with(&data("meshes/stanford-dragon-100k.obj"), &ModelOptions::default()).unwrap();
    let (lo, hi) = loaded.model.bounds().unwrap();
    // SOURCES.md: bbox x ±7.05, y 0..9.94, z ±3.15.
    assert!((lo.x + 7.05).abs() < 0.01 && (hi.x - 7.05).abs() < 0.01, "{lo} {hi}");
    assert!(lo.y.abs() < 0.01 && (hi.y - 9.94).abs() < 0.01, "{lo} {hi}");
    assert!((lo.z + 3.15).abs() < 0.01 && (hi.z - 3.15).abs() < 0.01, "{lo} {hi}");
    assert!(loaded.notes.iter().any(|n| n.contains("no normals")));
    assert_eq!(normals_check(&loaded.model), 1.0);
}

#[test]
fn suzanne_quads_are_triangulated() {
    let m = load_model(&data("meshes/suzanne.obj")).unwrap();
    // 500 faces, 468 of them quads: 468 * 2 + 32 = 968 triangles.
    assert_eq!(m.triangle_count(), 968);
    assert!(normals_check(&m) > 0.95);
    let (lo, hi) = m.bounds().unwrap();
    assert!((lo.x + 3.86).abs() < 0.01 && (hi.x + 1.13).abs() < 0.01, "{lo} {hi}");
}

#[test]
fn icosphere_normals_from_the_crease_rule_are_radial() {
    // The icosphere ships flat per-face normals; recomputed smooth normals of a unit sphere
    // must point along the position vector.
    let mut m = load_model(&data("meshes/icosphere-320.obj")).unwrap();
    assert_eq!(m.triangle_count(), 320);
    for mesh in &mut m.meshes {
        previz::scene::normals::compute_crease_normals(mesh, 60.0).unwrap();
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let angle = v(*p).normalize().dot(v(*n)).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(angle < 1.0, "normal {angle} deg off radial at {p:?}");
        }
        // Smooth: one normal per position (162 vertices, SOURCES.md).
        assert_eq!(mesh.positions.len(), 162);
    }
}

#[test]
fn teapot_unwelded_patch_seams_are_smoothed_across() {
    let m = load_model(&data("meshes/teapot.obj")).unwrap();
    assert_eq!(m.triangle_count(), 6320);
    assert_eq!(normals_check(&m), 1.0);
    // The file's patch seams are unwelded: 1,036 boundary edges (SOURCES.md). Normals are
    // computed on positions, so seam vertices with equal position and normal merge and the
    // loaded mesh is welded except at real creases and the real openings.
    let mesh = &m.meshes[0];
    let mut edges: std::collections::HashMap<(u32, u32), u32> = Default::default();
    for t in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let boundary = edges.values().filter(|n| **n == 1).count();
    assert!(boundary < 1036 / 4, "{boundary} boundary edges");
    // Any position still carrying several vertices is at a crease, not a smooth seam.
    assert_eq!(seams_smoothed(mesh, 60.0), 0);
}

// --------------------------------------------------------------------------------- glTF

#[test]
fn milk_truck_gltf_and_glb_agree() {
    let a = load_model(&data("textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.gltf")).unwrap();
    let b = load_model(&data("textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.glb")).unwrap();
    for m in [&a, &b] {
        // Truck mesh: 5232 + 168 + 864 indices; wheel mesh 2304 indices, instanced by two nodes.
        assert_eq!(m.triangle_count(), (5232 + 168 + 864) / 3 + 2 * 2304 / 3);
        let names: Vec<&str> = m.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names.len(), 4);
        for n in ["truck", "glass", "window_trim", "wheels"] {
            assert!(names.contains(&n), "{names:?}");
        }
        let glass = m.materials.iter().find(|m| m.name == "glass").unwrap();
        assert_eq!(glass.diffuse, [0.0, 0.040_506_3, 0.021_240_7]);
        assert!(glass.texture.is_none());
        let truck = m.materials.iter().find(|m| m.name == "truck").unwrap();
        let tex = truck.texture.as_ref().unwrap();
        assert_eq!((tex.width, tex.height), (2048, 2048));
        assert_eq!(normals_check(m), 1.0);
    }
    assert_eq!(a.bounds().unwrap(), b.bounds().unwrap());
    // The same .glb from memory (the embedded demo model path).
    let bytes = std::fs::read(data("textured_models/cesium_milk_truck_gltf/CesiumMilkTruck.glb")).unwrap();
    let c = previz::scene::model::load_glb_bytes(&bytes).unwrap();
    assert_eq!((c.triangle_count(), c.bounds()), (b.triangle_count(), b.bounds()));
    assert!(previz::scene::model::load_glb_bytes(&bytes[..bytes.len() / 3]).is_err());
    let tex_a = &a.materials.iter().find(|m| m.name == "truck").unwrap().texture.as_ref().unwrap().pixels;
    let tex_b = &b.materials.iter().find(|m| m.name == "truck").unwrap().texture.as_ref().unwrap().pixels;
    assert!(tex_a == tex_b, "the .gltf's PNG and the .glb's embedded PNG decode alike");
    // Node transforms: the wheel mesh is placed by two nodes at x = −1.352 and x = +1.433.
    let wheels_index = a.materials.iter().position(|m| m.name == "wheels").unwrap();
    let wheels = a.meshes.iter().find(|m| m.material == wheels_index).unwrap();
    let (left, right): (Vec<f32>, Vec<f32>) = wheels.positions.iter().map(|p| p[0]).partition(|x| *x < 0.0);
    assert_eq!(left.len(), right.len());
    let mean = |xs: &[f32]| xs.iter().sum::<f32>() / xs.len() as f32;
    assert!((mean(&left) + 1.352).abs() < 0.05 && (mean(&right) - 1.433).abs() < 0.05, "{} {}", mean(&left), mean(&right));
}

// ------------------------------------------------------------------------- environments

/// Mean absolute difference between texels that touch across face edges, and between texels
/// one step apart inside faces. A wrong face orientation makes the first much larger.
fn seam_vs_interior(cube: &CubeMap) -> (f32, f32) {
    let n = cube.size as usize;
    let texel = |f: usize, x: usize, y: usize| cube.faces[f][y * n + x];
    let diff = |a: [f32; 3], b: [f32; 3]| (0..3).map(|i| (a[i] - b[i]).abs()).sum::<f32>() / 3.0;
    let (mut seam, mut inner, mut count) = (0.0, 0.0, 0usize);
    for face in 0..6 {
        for i in 0..n {
            let along = (i as f32 + 0.5) / n as f32;
            let half = 0.5 / n as f32;
            // (edge texel, just outside the edge, one texel inside)
            for (x, y, out_u, out_v, in_x, in_y) in [
                (0, i, -half, along, 1, i),
                (n - 1, i, 1.0 + half, along, n - 2, i),
                (i, 0, along, -half, i, 1),
                (i, n - 1, along, 1.0 + half, i, n - 2),
            ] {
                let (f2, u2, v2) = cube_dir_to_face_uv(face_uv_to_cube_dir(face, out_u, out_v));
                assert_ne!(f2, face);
                let (x2, y2) = (((u2 * n as f32) as usize).min(n - 1), ((v2 * n as f32) as usize).min(n - 1));
                seam += diff(texel(face, x, y), texel(f2, x2, y2));
                inner += diff(texel(face, x, y), texel(face, in_x, in_y));
                count += 1;
            }
        }
    }
    (seam / count as f32, inner / count as f32)
}

#[test]
fn humus_face_folders_with_both_namings_join_without_seams() {
    for (dir, size) in [("cubemaps/humus_Bridge2", 1024), ("cubemaps/humus_SwedishRoyalCastle", 512)] {
        let cube = load_environment(&data(dir)).unwrap();
        assert_eq!(cube.size, size, "{dir}");
        // 8-bit faces converted to linear: within [0, 1].
        assert!(cube.faces.iter().flatten().flatten().all(|c| (0.0..=1.0).contains(c)));
        let (seam, inner) = seam_vs_interior(&cube);
        assert!(seam < 2.0 * inner + 0.01, "{dir}: seam {seam} vs interior {inner}");
    }
}

#[test]
fn bridge2_daylight_sky_is_brighter_than_ground() {
    let cube = load_environment(&data("cubemaps/humus_Bridge2")).unwrap();
    let lum = |f| luminance_bt709(cube.face_mean(f));
    // +Y (sky) above −Y (ground) on a sunny outdoor map.
    assert!(lum(2) > 2.0 * lum(3), "{} vs {}", lum(2), lum(3));
    // Blue sky: the up face is bluer than it is red.
    let up = cube.face_mean(2);
    assert!(up[2] > up[0], "{up:?}");
}

#[test]
fn hdr_face_folders_stay_linear_float() {
    // Six Radiance .hdr faces made from the CC0 quarry panorama (its sun peaks near 64 000):
    // loaded back as a face folder, the values above 1 survive and each face matches the cube it
    // was written from, texel by texel, within RGBE's 8-bit mantissa (≤ 1/128 relative), and
    // matches no other face.
    let cube = load_equirect(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap().to_cube(64, 0.0);
    let dir = temp_dir("hdr-faces");
    for (f, name) in ["px", "nx", "py", "ny", "pz", "nz"].iter().enumerate() {
        let pixels: Vec<image::Rgb<f32>> = cube.faces[f].iter().map(|p| image::Rgb(*p)).collect();
        let file = std::io::BufWriter::new(std::fs::File::create(dir.join(format!("{name}.hdr"))).unwrap());
        image::codecs::hdr::HdrEncoder::new(file).encode(&pixels, 64, 64).unwrap();
    }
    let hdr = load_environment(&dir).unwrap();
    assert_eq!(hdr.size, 64);
    let max = hdr.faces.iter().flatten().flatten().fold(0.0f32, |m, c| m.max(*c));
    let max_in = cube.faces.iter().flatten().flatten().fold(0.0f32, |m, c| m.max(*c));
    assert!(max > 100.0 && (max / max_in - 1.0).abs() < 1.0 / 128.0, "max {max} vs {max_in}");
    for f in 0..6 {
        for g in 0..6 {
            let rel = |a: &[[f32; 3]], b: &[[f32; 3]]| {
                a.iter()
                    .zip(b)
                    .map(|(x, y)| (luminance_bt709(*x) - luminance_bt709(*y)).abs() / luminance_bt709(*y).max(1e-3))
                    .fold(0.0f32, f32::max)
            };
            let worst = rel(&hdr.faces[f], &cube.faces[g]);
            if f == g {
                assert!(worst < 1.0 / 64.0, "face {f}: worst relative difference {worst}");
            } else {
                assert!(worst > 0.1, "face {f} matches face {g}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Direction of the brightest texel of a cube map, in ENU.
fn brightest_direction(cube: &CubeMap) -> Vec3 {
    let n = cube.size as usize;
    let (mut best, mut dir) = (f32::MIN, Vec3::ZERO);
    for (f, texels) in cube.faces.iter().enumerate() {
        for (i, t) in texels.iter().enumerate() {
            let l = luminance_bt709(*t);
            if l > best {
                best = l;
                dir = cube_to_enu(face_uv_to_cube_dir(f, ((i % n) as f32 + 0.5) / n as f32, ((i / n) as f32 + 0.5) / n as f32));
            }
        }
    }
    dir
}

/// ∫ luminance dω over the sphere for a cube map.
fn cube_integral(cube: &CubeMap) -> f64 {
    let n = cube.size;
    cube.faces
        .iter()
        .flat_map(|f| f.iter().enumerate())
        .map(|(i, t)| luminance_bt709(*t) as f64 * texel_solid_angle(n, i as u32 % n, i as u32 / n) as f64)
        .sum()
}

#[test]
fn quarry_equirect_hdr_sun_position_and_energy() {
    let path = data("hdri/polyhaven_1k/quarry_01_1k.hdr");
    let eq = load_equirect(&path).unwrap();
    assert_eq!((eq.width(), eq.height()), (1024, 512));
    // hdri_peak_stats_DERIVED.csv (numpy): mean luminance 0.48687, peak 63,745.9 at row 227,
    // column 614.
    let lum: Vec<f32> = eq.pixels().iter().map(|p| luminance_bt709(*p)).collect();
    let mean = lum.iter().map(|l| *l as f64).sum::<f64>() / lum.len() as f64;
    assert!((mean / 0.48687 - 1.0).abs() < 1e-3, "mean {mean}");
    let (peak_i, peak) = lum.iter().enumerate().fold((0, 0.0f32), |b, (i, l)| if *l > b.1 { (i, *l) } else { b });
    assert!((peak / 63_745.9 - 1.0).abs() < 1e-3, "peak {peak}");
    assert_eq!((peak_i / 1024, peak_i % 1024), (227, 614));

    // The cube map has the sun where the equirect convention puts it: column 614 of 1024 is
    // azimuth (614.5/1024 − 0.5)·360° = 36.0°, row 227 elevation 90° − 227.5/512·180° = 10.0°.
    let cube = load_environment(&path).unwrap();
    assert_eq!(cube.size, 256);
    let (az, el) = (36.035f32.to_radians(), 10.02f32.to_radians());
    let expected = Vec3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin());
    let got = brightest_direction(&cube);
    let err = got.dot(expected).clamp(-1.0, 1.0).acos().to_degrees();
    assert!(err < 0.6, "sun {err} deg from where it belongs");

    // Energy: ∫ L dω over the sphere is the same from the equirect and the cube (1%).
    let eq_integral: f64 =
        (0..512u32).map(|y| (0..1024).map(|x| lum[(y * 1024 + x) as usize] as f64).sum::<f64>() * eq.pixel_solid_angle(y) as f64).sum();
    let cube_int = cube_integral(&cube);
    assert!((cube_int / eq_integral - 1.0).abs() < 0.01, "cube {cube_int} vs equirect {eq_integral}");

    // A heading turns the whole map: with the panorama's front at azimuth 90°, the sun is at
    // 126°.
    let turned = load_environment_with(&path, &EnvOptions { heading_deg: 90.0, face_size: Some(128) }).unwrap();
    assert_eq!(turned.size, 128);
    let az2 = 126.035f32.to_radians();
    let expected2 = Vec3::new(el.cos() * az2.sin(), el.cos() * az2.cos(), el.sin());
    assert!(brightest_direction(&turned).dot(expected2) > 1.5f32.to_radians().cos());
}

#[test]
fn zip_exr_equirect_loads_with_negatives_clamped() {
    let path = data("hdri/blender_studiolights_world_zip/city.exr");
    let eq = load_equirect(&path).unwrap();
    assert_eq!((eq.width(), eq.height()), (1024, 512));
    // hdri_peak_stats_DERIVED.csv: the file has 299 negative pixels (min −0.0016) — gone.
    assert!(eq.pixels().iter().flatten().all(|c| *c >= 0.0));
    // Mean luminance 1.05452 and peak 31,749.4 at row 120, column 614 (numpy, same values).
    let lum: Vec<f32> = eq.pixels().iter().map(|p| luminance_bt709(*p)).collect();
    let mean = lum.iter().map(|l| *l as f64).sum::<f64>() / lum.len() as f64;
    assert!((mean / 1.05452 - 1.0).abs() < 1e-3, "mean {mean}");
    let (peak_i, peak) = lum.iter().enumerate().fold((0, 0.0f32), |b, (i, l)| if *l > b.1 { (i, *l) } else { b });
    assert!((peak / 31_749.4 - 1.0).abs() < 1e-3, "peak {peak}");
    assert_eq!((peak_i / 1024, peak_i % 1024), (120, 614));
    let cube = load_environment_with(&path, &EnvOptions { face_size: Some(64), ..Default::default() }).unwrap();
    assert_eq!(cube.size, 64);
}

#[test]
fn dwab_exr_decodes_like_its_zip_copy() {
    // SOURCES.md made the ZIP copies because older `exr` releases could not read DWAB; the exr
    // 1.74 decoder in our lock file does, bit-identically to OpenEXR (which wrote the ZIP copy).
    let dwab = load_equirect(&data("hdri/blender_studiolights_world/city.exr")).unwrap();
    let zip = load_equirect(&data("hdri/blender_studiolights_world_zip/city.exr")).unwrap();
    assert!(dwab.pixels() == zip.pixels());
    // A damaged DWAB file: the error names it and its compression and suggests ZIP.
    let dir = temp_dir("dwab");
    let bytes = std::fs::read(data("hdri/blender_studiolights_world/city.exr")).unwrap();
    let cut = dir.join("cut.exr");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let err = err_text(load_environment(&cut));
    assert!(err.contains("cut.exr") && err.contains("dwab") && err.contains("ZIP"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------- backgrounds

#[test]
fn background_photos() {
    let a = load_image(&data("cubemaps/humus_SwedishRoyalCastle/px.jpg")).unwrap();
    assert_eq!((a.width, a.height), (512, 512));
    assert_eq!(a.pixels.len(), 512 * 512 * 4);
    let b = load_image(&data("photos/exif_gps/87_OSError.jpg")).unwrap();
    assert_eq!((b.width, b.height), (1488, 2240));
    let c = load_image(&data("textured_models/spot/spot_texture.png")).unwrap();
    assert_eq!((c.width, c.height), (1024, 1024));
    assert!(c.pixels.chunks(4).all(|p| p[3] == 255));
}

// ------------------------------------------------------------------------------ bad input

fn err_text<T: std::fmt::Debug>(r: anyhow::Result<T>) -> String {
    format!("{:#}", r.unwrap_err())
}

#[test]
fn malformed_obj_names_the_file() {
    let dir = temp_dir("badobj");
    for (name, body) in [
        ("short_vertex.obj", "v 1 2\nf 1 2 3\n"),
        ("bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"),
        ("no_faces.obj", "v 0 0 0\nv 1 0 0\n"),
        ("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, body).unwrap();
        let err = err_text(load_model(&path));
        assert!(err.contains(name), "{name}: {err}");
    }
    let binary = dir.join("binary.obj");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x80, 0x81]).unwrap();
    assert!(err_text(load_model(&binary)).contains("binary.obj"));
    let err = err_text(load_model(&dir.join("absent.obj")));
    assert!(err.contains("absent.obj"), "{err}");
    let err = err_text(load_model(&dir.join("model.fbx")));
    assert!(err.contains("model.fbx") && err.contains(".obj"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_texture_names_texture_and_mtl() {
    let dir = temp_dir("notex");
    std::fs::write(dir.join("m.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n")
        .unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 1 0 0\nmap_Kd textures\\gone.jpg\n").unwrap();
    let err = err_text(load_model(&dir.join("m.obj")));
    assert!(err.contains("gone.jpg") && err.contains("m.mtl"), "{err}");
    // A texture that exists but is not an image: error names it.
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    std::fs::write(dir.join("textures/gone.jpg"), b"not a jpeg").unwrap();
    let err = err_text(load_model(&dir.join("m.obj")));
    assert!(err.contains("gone.jpg"), "{err}");
    // Case differs from the file on disk (a Windows-made model): found anyway.
    image::RgbImage::from_pixel(2, 2, image::Rgb([9, 9, 9])).save(dir.join("textures/GONE.png")).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 1 0 0\nmap_Kd Textures\\gone.PNG\n").unwrap();
    let m = load_model(&dir.join("m.obj")).unwrap();
    assert_eq!(m.materials[0].texture.as_ref().unwrap().pixels[0], 9);
    // Malformed MTL: error names it.
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd x y z\n").unwrap();
    let err = err_text(load_model(&dir.join("m.obj")));
    assert!(err.contains("m.mtl"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn write_faces(dir: &Path, names: [&str; 6], size: impl Fn(usize) -> (u32, u32)) {
    for (i, n) in names.iter().enumerate() {
        let (w, h) = size(i);
        image::RgbImage::from_pixel(w, h, image::Rgb([40 * i as u8, 100, 200])).save(dir.join(n)).unwrap();
    }
}

#[test]
fn bad_cube_folders_are_clear_errors() {
    let long = ["posx.png", "negx.png", "posy.png", "negy.png", "posz.png", "negz.png"];
    let short = ["px.png", "nx.png", "py.png", "ny.png", "pz.png", "nz.png"];
    let dir = temp_dir("faces");

    // Good: solid faces land in wgpu order with the convention of enu_to_cube.
    write_faces(&dir, short, |_| (4, 4));
    let cube = load_environment(&dir).unwrap();
    let srgb = previz::colour::srgb_to_linear;
    for f in 0..6 {
        assert!((cube.face_mean(f)[0] - srgb(40.0 * f as f32 / 255.0)).abs() < 1e-5);
    }
    // North (ENU +y) is the +Z face, pz.png.
    assert_eq!(cube_dir_to_face_uv(enu_to_cube(Vec3::Y)).0, 4);
    assert!((cube.sample_enu(Vec3::Y)[0] - srgb(160.0 / 255.0)).abs() < 1e-5);

    // Mismatched size: names the odd file.
    write_faces(&dir, short, |i| if i == 2 { (8, 8) } else { (4, 4) });
    let err = err_text(load_environment(&dir));
    assert!(err.contains("py.png") && err.contains("same size"), "{err}");
    // Non-square.
    write_faces(&dir, short, |i| if i == 4 { (4, 3) } else { (4, 4) });
    let err = err_text(load_environment(&dir));
    assert!(err.contains("pz.png") && err.contains("square"), "{err}");
    // Unreadable image.
    write_faces(&dir, short, |_| (4, 4));
    std::fs::write(dir.join("nx.png"), b"garbage").unwrap();
    let err = err_text(load_environment(&dir));
    assert!(err.contains("nx.png"), "{err}");
    // Ambiguous: two files for one face.
    write_faces(&dir, short, |_| (4, 4));
    write_faces(&dir, long, |_| (4, 4));
    let err = err_text(load_environment(&dir));
    assert!(err.contains("ambiguous"), "{err}");
    // Missing face.
    for n in short {
        std::fs::remove_file(dir.join(n)).unwrap();
    }
    std::fs::remove_file(dir.join("negz.png")).unwrap();
    let err = err_text(load_environment(&dir));
    assert!(err.contains("-Z") && err.contains("negz"), "{err}");
    // Not an environment at all.
    let err = err_text(load_environment(&dir.join("posx.txt")));
    assert!(err.contains("posx.txt"), "{err}");
    // Equirect of the wrong shape.
    image::RgbImage::new(30, 20).save(dir.join("pano.png")).unwrap();
    let err = err_text(load_environment(&dir.join("pano.png")));
    assert!(err.contains("pano.png") && err.contains("2:1"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ------------------------------------------------------------------------ hostile input
// Cases from issue 8 ("651 malformed inputs"): each is a clear error naming the file or the
// element at fault, or a bounded load.

/// A PNG that is only a header (signature + IHDR with its CRC, RFC 2083) claiming `w`×`h` RGB8.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut crc = !0u32;
    for &b in &ihdr {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend_from_slice(&13u32.to_be_bytes());
    out.extend_from_slice(&ihdr);
    out.extend_from_slice(&(!crc).to_be_bytes());
    out
}

#[test]
fn every_image_path_refuses_a_huge_header_naming_the_file() {
    let dir = temp_dir("huge");
    let huge = png_header_only(100_000, 100_000);
    std::fs::write(dir.join("huge.png"), &huge).unwrap();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
    std::fs::write(dir.join("m.obj"), format!("mtllib m.mtl\n{tri}usemtl a\nf 1/1 2/2 3/3\n")).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 1 1 1\nmap_Kd huge.png\n").unwrap();
    std::fs::write(dir.join("plain.obj"), format!("{tri}f 1/1 2/2 3/3\n")).unwrap();
    let faces = dir.join("faces");
    std::fs::create_dir_all(&faces).unwrap();
    for n in ["px", "nx", "py", "ny", "pz", "nz"] {
        image::RgbImage::new(4, 4).save(faces.join(format!("{n}.png"))).unwrap();
    }
    std::fs::write(faces.join("ny.png"), &huge).unwrap();
    let gltf = r#"{"asset":{"version":"2.0"},"images":[{"uri":"huge.png"}],"textures":[{"source":0}],
        "materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
        "buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
        "bufferViews":[{"buffer":0,"byteLength":36}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#;
    std::fs::write(dir.join("t.gltf"), gltf).unwrap();
    let texture = ModelOptions { texture: Some(dir.join("huge.png")), ..Default::default() };
    let results: Vec<(&str, String)> = vec![
        ("background", err_text(load_image(&dir.join("huge.png")))),
        ("MTL texture", err_text(load_model(&dir.join("m.obj")))),
        ("--texture", err_text(load_model_with(&dir.join("plain.obj"), &texture))),
        ("cube face", err_text(load_environment(&faces))),
        ("equirect", err_text(load_environment(&dir.join("huge.png")))),
        ("glTF image", err_text(load_model(&dir.join("t.gltf")))),
        ("colour image", err_text(previz::colour::images::load_rgba8(&dir.join("huge.png")))),
    ];
    for (path, err) in results {
        assert!(err.contains("huge.png") || err.contains("ny.png"), "{path}: {err}");
        assert!(err.contains("limit"), "{path}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A one-triangle glTF (positions, normals, indices, one material) as JSON, to be broken.
fn gltf_triangle() -> serde_json::Value {
    let mut buf = Vec::new();
    for f in [0.0f32, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 1., 0., 0., 1.] {
        buf.extend_from_slice(&f.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}],
        "buffers": [{"byteLength": buf.len(), "uri": format!("data:application/octet-stream;base64,{}", base64(&buf))}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 72, "byteLength": 6}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
                      {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    })
}

/// Standard base64 with padding (RFC 4648 §4).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            s.push(if k <= c.len() { A[(n >> (18 - 6 * k)) as usize & 63] as char } else { '=' });
        }
    }
    s
}

#[test]
fn hostile_gltf_documents_are_errors_naming_what_is_wrong() {
    let ok = gltf_triangle();
    let loaded = previz::scene::model::load_glb_bytes(ok.to_string().as_bytes()).unwrap();
    assert_eq!(loaded.triangle_count(), 1);
    type Break = fn(&mut serde_json::Value);
    let cases: Vec<(&str, Break, &str)> = vec![
        ("attribute accessor out of range", |d| d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 99.into(), "accessor 99"),
        ("image bufferView without mimeType", |d| d["images"] = serde_json::json!([{"bufferView": 0}]), "mimeType"),
        ("index count 2^40", |d| d["accessors"][2]["count"] = (1u64 << 40).into(), "do not fit"),
        (
            "same child 200 000 times",
            |d| {
                d["nodes"] = serde_json::json!([{"children": vec![1; 200_000]}, {"mesh": 0}]);
            },
            "again",
        ),
        (
            "node with two parents",
            |d| d["nodes"] = serde_json::json!([{"children": [1]}, {"children": [2], "mesh": 0}, {"children": [1]}]),
            "node 1",
        ),
        ("node cycle", |d| d["nodes"] = serde_json::json!([{"children": [1], "mesh": 0}, {"children": [0]}]), "cycle"),
        ("all-zero matrix", |d| d["nodes"][0]["matrix"] = serde_json::Value::from(vec![0.0; 16]), "not invertible"),
        ("zero scale", |d| d["nodes"][0]["scale"] = serde_json::json!([0.0, 1.0, 1.0]), "not invertible"),
        ("POSITION typed SCALAR", |d| d["accessors"][0]["type"] = "SCALAR".into(), "POSITION"),
        ("signed indices", |d| d["accessors"][2]["componentType"] = 5122.into(), "indices are Scalar of I16"),
        (
            "negative baseColorFactor",
            |d| d["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([-1.0, 0.5, 0.5, 1.0]),
            "baseColorFactor",
        ),
        (
            "1e30 baseColorFactor",
            |d| d["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([1e30, 0.5, 0.5, 1.0]),
            "paint",
        ),
        ("bufferView past its buffer", |d| d["bufferViews"][0]["byteLength"] = 4000.into(), "bufferView 0"),
        ("buffer shorter than byteLength", |d| d["buffers"][0]["byteLength"] = 4000.into(), "holds 80 bytes"),
        ("material out of range", |d| d["meshes"][0]["primitives"][0]["material"] = 5.into(), "primitives[0].material"),
    ];
    let extra: Vec<(&str, Break, &str)> = vec![
        ("POSITION accessor out of range", |d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 7.into(), "accessor 7"),
        ("accessor count 0", |d| d["accessors"][0]["count"] = 0.into(), "count 0"),
        (
            "TEXCOORD_0 of SHORT",
            |d| {
                d["accessors"]
                    .as_array_mut()
                    .unwrap()
                    .push(serde_json::json!({"bufferView": 0, "componentType": 5122, "count": 3, "type": "VEC2"}));
                d["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 3.into();
            },
            "TEXCOORD_0 is Vec2 of I16",
        ),
    ];
    let cases: Vec<(&str, Break, &str)> = cases.into_iter().chain(extra).collect();
    let mut wrong = Vec::new();
    for (what, break_it, needle) in cases {
        let mut doc = ok.clone();
        break_it(&mut doc);
        let err = err_text(previz::scene::model::load_glb_bytes(doc.to_string().as_bytes()));
        if !err.contains(needle) {
            wrong.push(format!("{what}: {err}"));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    // GLB containers the gltf crate panicked on (found by the corpus mutation run).
    let err = err_text(previz::scene::model::load_glb_bytes(b"glTF\x02\0\0\0\x04\0\0\0"));
    assert!(err.contains("GLB header says 4 bytes"), "{err}");
    // NaN and infinite normals in the binary data.
    for bad in [f32::NAN, f32::INFINITY] {
        let mut doc = ok.clone();
        let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_string();
        let (head, data) = uri.split_once("base64,").unwrap();
        let mut bytes = decode_base64(data);
        bytes[36..40].copy_from_slice(&bad.to_le_bytes());
        doc["buffers"][0]["uri"] = format!("{head}base64,{}", base64(&bytes)).into();
        let err = err_text(previz::scene::model::load_glb_bytes(doc.to_string().as_bytes()));
        assert!(err.contains("NORMAL 0 is not finite"), "{bad}: {err}");
    }
}

fn decode_base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        _ => 63,
    };
    let s = s.trim_end_matches('=').as_bytes();
    let (mut acc, mut bits, mut out) = (0u32, 0, Vec::new());
    for &c in s {
        acc = (acc << 6) | u32::from(val(c));
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

#[test]
fn gltf_missing_or_truncated_files_are_named() {
    let dir = temp_dir("gltf-files");
    let mut doc = gltf_triangle();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_string();
    std::fs::write(dir.join("tri.bin"), decode_base64(uri.split_once("base64,").unwrap().1)).unwrap();
    doc["buffers"][0]["uri"] = "tri%20data.bin".into();
    std::fs::write(dir.join("a.gltf"), doc.to_string()).unwrap();
    let err = err_text(load_model(&dir.join("a.gltf")));
    assert!(err.contains("tri data.bin") && err.contains("a.gltf"), "{err}");
    std::fs::rename(dir.join("tri.bin"), dir.join("tri data.bin")).unwrap();
    assert_eq!(load_model(&dir.join("a.gltf")).unwrap().triangle_count(), 1);
    // A base-colour image that is missing, then truncated.
    doc["images"] = serde_json::json!([{"uri": "paint.png"}]);
    doc["textures"] = serde_json::json!([{"source": 0}]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = serde_json::json!({"index": 0});
    std::fs::write(dir.join("a.gltf"), doc.to_string()).unwrap();
    let err = err_text(load_model(&dir.join("a.gltf")));
    assert!(err.contains("paint.png") && err.contains("paint"), "{err}");
    let mut png = Vec::new();
    image::RgbImage::from_fn(64, 64, |x, y| image::Rgb([(x * 4) as u8, (y * 4) as u8, 7]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.join("paint.png"), &png[..png.len() / 2]).unwrap();
    let err = err_text(load_model(&dir.join("a.gltf")));
    assert!(err.contains("paint.png"), "{err}");
    std::fs::write(dir.join("paint.png"), &png).unwrap();
    let m = load_model(&dir.join("a.gltf")).unwrap();
    assert_eq!(m.materials[0].texture.as_ref().unwrap().width, 64);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn obj_loading_stays_linear_on_huge_faces_shared_vertices_and_repeats() {
    // One face with 30 000 corners (a circle), one vertex shared by 100 000 triangles (a cone
    // fan), 10 000 copies of one triangle: each loads, with the expected triangle count. These
    // took minutes when computing normals compared every pair of corners around a vertex.
    let n = 30_000;
    let mut big_face = String::new();
    for i in 0..n {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        big_face += &format!("v {} {} 0\n", a.cos(), a.sin());
    }
    big_face += "f";
    for i in 1..=n {
        big_face += &format!(" {i}");
    }
    big_face += "\n";
    let m = previz::scene::model::load_obj_bytes(big_face.as_bytes()).unwrap();
    assert_eq!(m.triangle_count(), n - 2);

    let k = 100_000;
    let mut fan = String::from("v 0 0 1\n");
    for i in 0..k {
        let a = i as f32 / k as f32 * std::f32::consts::TAU;
        fan += &format!("v {} {} {}\n", a.cos(), a.sin(), 0.1 * (7.0 * a).sin());
    }
    for i in 0..k {
        fan += &format!("f 1 {} {}\n", i + 2, (i + 1) % k + 2);
    }
    let m = previz::scene::model::load_obj_bytes(fan.as_bytes()).unwrap();
    assert_eq!(m.triangle_count(), k);
    assert!(normals_check(&m) > 0.99);

    let mut repeats = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    repeats += &"f 1 2 3\n".repeat(10_000);
    let m = previz::scene::model::load_obj_bytes(repeats.as_bytes()).unwrap();
    assert_eq!(m.triangle_count(), 10_000);
    assert!(m.meshes[0].normals.iter().all(|n| (n[2] - 1.0).abs() < 1e-6));
}

#[test]
fn mtl_values_out_of_range_name_the_file_and_line() {
    let dir = temp_dir("mtl-values");
    std::fs::write(dir.join("m.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    for (kd, needle) in [("nan 0 0", "nan"), ("1e39 0 0", "1e39"), ("-1 0.5 0.5", "-1")] {
        std::fs::write(dir.join("m.mtl"), format!("newmtl a\n# diffuse\nKd {kd}\n")).unwrap();
        let err = err_text(load_model(&dir.join("m.obj")));
        assert!(err.contains("m.mtl") && err.contains("line 3") && err.contains(needle), "{kd}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_with_nan_infinite_or_absurd_pixels_is_an_error_naming_the_file() {
    let dir = temp_dir("exr-nan");
    for (name, bad) in [("nan.exr", f32::NAN), ("inf.exr", f32::INFINITY), ("huge.exr", 1e30)] {
        let img = image::Rgb32FImage::from_fn(16, 8, |x, y| image::Rgb(if (x, y) == (5, 2) { [bad, 0.5, 0.5] } else { [0.5, 0.5, 0.5] }));
        image::DynamicImage::ImageRgb32F(img).save(dir.join(name)).unwrap();
        let err = err_text(load_environment(&dir.join(name)));
        assert!(err.contains(name) && err.contains("x=5, y=2"), "{err}");
    }
    // Negative values are the documented repair: set to 0.
    let img = image::Rgb32FImage::from_fn(16, 8, |x, _| image::Rgb(if x == 3 { [-0.004, 0.5, 0.5] } else { [0.5, 0.5, 0.5] }));
    image::DynamicImage::ImageRgb32F(img).save(dir.join("neg.exr")).unwrap();
    let e = load_equirect(&dir.join("neg.exr")).unwrap();
    assert!(e.pixels().iter().flatten().all(|c| *c >= 0.0));
    assert_eq!(e.pixels()[3][0], 0.0);
    std::fs::remove_dir_all(&dir).unwrap();
}
