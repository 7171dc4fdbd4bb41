//! Wavefront OBJ with MTL materials, through tobj.
//!
//! Tolerated: a missing .mtl (default material, with a note), Windows `\` separators and
//! different letter case in .mtl and texture paths, MTL texture options (`-s 1 1 1 file.jpg`),
//! polygons (fan-triangulated by tobj), missing normals (computed, see `scene::normals`).
//! Errors: unparsable OBJ or MTL, a texture the MTL names that is not there or cannot be read,
//! non-finite positions, no triangles.

use super::{LoadedModel, ModelOptions, finish_mesh};
use crate::scene::background::load_image;
use crate::scene::normals::DEFAULT_CREASE_DEG;
use crate::scene::{Material, Mesh, Model, Rgba8Image, Sides};
use anyhow::{Context, Result, anyhow, bail};
use std::cell::RefCell;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// One `mtllib` the OBJ named, in the order tobj asked for them (its material list is the
/// concatenation of the libraries' materials in this order).
struct MtlLib {
    path: PathBuf,
    /// Number of materials read from it; 0 when missing.
    count: usize,
    missing: bool,
}

/// Load an OBJ file and its materials.
pub(super) fn load_obj_file(path: &Path, options: &ModelOptions) -> Result<LoadedModel> {
    let text = std::fs::read(path).with_context(|| format!("cannot read OBJ {}", path.display()))?;
    check_obj(&text).with_context(|| format!("malformed OBJ {}", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let libs: RefCell<Vec<MtlLib>> = RefCell::new(Vec::new());
    let mtl_error: RefCell<Option<anyhow::Error>> = RefCell::new(None);
    let loader = |name: &Path| -> tobj::MTLLoadResult {
        let name = name.to_string_lossy().replace('\\', "/");
        let mtl_path = resolve_relative(dir, &name);
        // Errors are recorded and reported after parsing; tobj only gets an empty library.
        let parsed = match std::fs::File::open(&mtl_path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                libs.borrow_mut().push(MtlLib { path: mtl_path, count: 0, missing: true });
                return Ok((Vec::new(), Default::default()));
            }
            Err(e) => Err(anyhow!(e).context(format!("cannot open material library {}", mtl_path.display()))),
            Ok(mut f) => {
                let mut text = Vec::new();
                std::io::Read::read_to_end(&mut f, &mut text)
                    .map_err(|e| anyhow!(e).context(format!("cannot read material library {}", mtl_path.display())))
                    .and_then(|_| check_mtl(&text).with_context(|| format!("material library {}", mtl_path.display())))
                    .and_then(|()| {
                        tobj::load_mtl_buf(&mut std::io::Cursor::new(&text))
                            .map_err(|e| anyhow!("malformed material library {}: {e}", mtl_path.display()))
                    })
            }
        };
        match parsed {
            Ok(parsed) => {
                libs.borrow_mut().push(MtlLib { path: mtl_path, count: parsed.0.len(), missing: false });
                Ok(parsed)
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Ok((Vec::new(), Default::default()))
            }
        }
    };
    let parsed = parse(&mut std::io::Cursor::new(&text), loader).with_context(|| format!("malformed OBJ {}", path.display()))?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e.context(format!("materials of OBJ {}", path.display())));
    }
    let libs = libs.into_inner();
    let mut notes: Vec<String> = libs
        .iter()
        .filter(|l| l.missing)
        .map(|l| format!("{}: material library {} not found; using the default material", path.display(), l.path.display()))
        .collect();
    let materials = convert_materials(&parsed.1, &libs)?;
    let model = build_model(parsed.0, materials, options.crease_angle_deg, &path.display().to_string(), &mut notes)?;
    Ok(LoadedModel { model, notes })
}

/// Load an OBJ held in memory (the built-in demo scene); `mtllib` lines are ignored and every
/// mesh gets the default material. Normals are computed where absent (60° crease).
pub fn load_obj_bytes(obj: &[u8]) -> Result<Model> {
    check_obj(obj).context("malformed embedded OBJ")?;
    let no_materials = |_: &Path| -> tobj::MTLLoadResult { Ok((Vec::new(), Default::default())) };
    let (meshes, _) = parse(&mut std::io::Cursor::new(obj), no_materials).context("malformed embedded OBJ")?;
    let model = build_model(meshes, Vec::new(), DEFAULT_CREASE_DEG, "embedded OBJ", &mut Vec::new())?;
    if model.triangle_count() == 0 {
        bail!("embedded OBJ contains no triangles");
    }
    Ok(model)
}

/// Lines of an OBJ that tobj would silently drop, misread or panic on: a face (`f`) with fewer
/// than three vertices (a truncated line); a face or line (`l`) index that is 0, points before
/// the first element (a relative `-12` with fewer than 12 defined) or past the last one (tobj
/// overflows on such indices; found by the corpus mutation run). Errors name the line.
fn check_obj(text: &[u8]) -> Result<()> {
    let lines = || text.split(|&b| b == b'\n').map(String::from_utf8_lossy);
    let kind = |key: &str| ["v", "vt", "vn"].iter().position(|k| *k == key);
    let mut total = [0usize; 3];
    for line in lines() {
        if let Some(k) = line.split_whitespace().next().and_then(kind) {
            total[k] += 1;
        }
    }
    let mut seen = [0usize; 3];
    for (n, line) in lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        if let Some(k) = key.and_then(kind) {
            seen[k] += 1;
            continue;
        }
        if !matches!(key, Some("f" | "l")) {
            continue;
        }
        let refs: Vec<&str> = words.collect();
        if key == Some("f") && refs.len() < 3 {
            bail!("line {}: a face with {} vertices (at least 3; a truncated line?)", n + 1, refs.len());
        }
        for r in refs {
            for (k, part) in r.split('/').enumerate().filter(|(_, p)| !p.is_empty()) {
                let Ok(i) = part.parse::<i64>() else { continue };
                let ok = match k {
                    0..=2 if i > 0 => i as u64 <= total[k] as u64,
                    0..=2 if i < 0 => i.unsigned_abs() <= seen[k] as u64,
                    _ => false,
                };
                if !ok {
                    let name = ["vertex", "texture coordinate", "normal"].get(k).copied().unwrap_or("index");
                    bail!("line {}: {name} index {i} in '{r}' does not exist ({} defined)", n + 1, total.get(k).copied().unwrap_or(0));
                }
            }
        }
    }
    Ok(())
}

/// Colour and number statements of an MTL, checked before tobj reads them (it would panic on
/// `Kd 0.5` and silently replace NaN, 1e39 or −1 by a default): `Ka/Kd/Ks` three numbers in
/// 0..=1, `Ke` three finite numbers ≥ 0, `Ns` finite ≥ 0, `d` and `Tr` in 0..=1, `Ni` finite.
/// Errors name the line.
fn check_mtl(text: &[u8]) -> Result<()> {
    for (n, line) in text.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let (count, lo, hi) = match key {
            "Ka" | "Kd" | "Ks" => (3, 0.0, 1.0),
            "Ke" => (3, 0.0, f32::MAX),
            "Ns" => (1, 0.0, f32::MAX),
            "d" | "Tr" => (1, 0.0, 1.0),
            "Ni" => (1, f32::MIN, f32::MAX),
            _ => continue,
        };
        let values: Vec<&str> = words.take(count).collect();
        if values.len() < count {
            bail!("line {}: {key} needs {count} number(s), got {:?}", n + 1, values.join(" "));
        }
        for v in values {
            // tobj reads the first `count` words (other forms, such as `Kd spectral file`, are
            // its parse errors).
            let Ok(x) = v.parse::<f32>() else { continue };
            if !(x.is_finite() && (lo..=hi).contains(&x)) {
                let range = if hi == f32::MAX { format!("finite and at least {lo}") } else { format!("in {lo}..={hi}") };
                bail!("line {}: {key} value {v} must be {range}", n + 1);
            }
        }
    }
    Ok(())
}

/// Load an OBJ and one material library held in memory (the fuzz targets): every `mtllib` gets
/// `mtl`, whose texture statements are ignored (no files are read). Same checks as a file.
pub fn load_obj_mtl_bytes(obj: &[u8], mtl: &[u8]) -> Result<Model> {
    check_obj(obj).context("malformed OBJ")?;
    check_mtl(mtl).context("malformed MTL")?;
    let library = tobj::load_mtl_buf(&mut std::io::Cursor::new(mtl)).map_err(|e| anyhow!("malformed MTL: {e}"))?;
    let loader = |_: &Path| -> tobj::MTLLoadResult { Ok(library.clone()) };
    let (meshes, mut materials) = parse(&mut std::io::Cursor::new(obj), loader).context("malformed OBJ")?;
    materials.iter_mut().for_each(|m| m.diffuse_texture = None);
    let converted = convert_materials(&materials, &[])?;
    let model = build_model(meshes, converted, DEFAULT_CREASE_DEG, "OBJ", &mut Vec::new())?;
    if model.triangle_count() == 0 {
        bail!("OBJ contains no triangles");
    }
    Ok(model)
}

fn parse<B: BufRead>(reader: &mut B, loader: impl Fn(&Path) -> tobj::MTLLoadResult) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>)> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let (models, materials) = tobj::load_obj_buf(reader, &options, loader).map_err(|e| match e {
        tobj::LoadError::ReadError => anyhow!("{e} (not a text file?)"),
        _ => anyhow!("{e}"),
    })?;
    // The loader never fails (it records errors itself), so this is always Ok.
    Ok((models, materials.unwrap_or_default()))
}

/// `dir/rel`, or if that does not exist, the entry of `dir` (and of each sub-folder in `rel`)
/// whose name matches ignoring ASCII case: models made on Windows often differ in case.
fn resolve_relative(dir: &Path, rel: &str) -> PathBuf {
    let exact = dir.join(rel);
    if exact.exists() {
        return exact;
    }
    let mut current = dir.to_path_buf();
    for part in rel.split('/').filter(|p| !p.is_empty() && *p != ".") {
        let found = std::fs::read_dir(&current).ok().and_then(|entries| {
            entries.filter_map(|e| e.ok()).map(|e| e.file_name()).find(|n| n.to_string_lossy().eq_ignore_ascii_case(part))
        });
        match found {
            Some(name) => current.push(name),
            None => return exact,
        }
    }
    current
}

/// The file name in an MTL texture statement, without the options that may precede it
/// (MTL spec: `map_Kd -options args filename`; `-o/-s/-t` take 1–3 numbers, `-mm` two).
pub(crate) fn texture_file_name(statement: &str) -> String {
    let mut words = statement.split_whitespace().peekable();
    while let Some(w) = words.peek().copied() {
        let max_args = match w {
            "-blendu" | "-blendv" | "-cc" | "-clamp" | "-imfchan" | "-texres" | "-bm" | "-boost" | "-type" => 1,
            "-mm" => 2,
            "-o" | "-s" | "-t" => 3,
            _ => break,
        };
        words.next();
        let numeric_only = matches!(w, "-o" | "-s" | "-t" | "-mm" | "-bm" | "-boost" | "-texres");
        for _ in 0..max_args {
            match words.peek() {
                Some(a) if !numeric_only || a.parse::<f32>().is_ok() => {
                    words.next();
                }
                _ => break,
            }
        }
    }
    words.collect::<Vec<_>>().join(" ").replace('\\', "/")
}

fn finite_or<const N: usize>(v: Option<[f32; N]>, default: [f32; N]) -> [f32; N] {
    v.filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or(default)
}

/// tobj materials to ours, loading each diffuse texture once.
fn convert_materials(mats: &[tobj::Material], libs: &[MtlLib]) -> Result<Vec<Material>> {
    let mut owner = Vec::with_capacity(mats.len());
    for lib in libs {
        owner.extend(std::iter::repeat_n(lib.path.as_path(), lib.count));
    }
    let mut cache: HashMap<PathBuf, Rgba8Image> = HashMap::new();
    let defaults = Material::default();
    let mut out = Vec::with_capacity(mats.len());
    for (i, m) in mats.iter().enumerate() {
        let mtl = owner.get(i).copied().unwrap_or(Path::new("?"));
        let texture = match &m.diffuse_texture {
            None => None,
            Some(statement) => {
                let name = texture_file_name(statement);
                let mtl_dir = mtl.parent().unwrap_or(Path::new("."));
                let file = resolve_relative(mtl_dir, &name);
                if !file.is_file() {
                    bail!(
                        "material '{}' in {} uses texture '{}', which does not exist (looked for {})",
                        m.name,
                        mtl.display(),
                        statement,
                        file.display()
                    );
                }
                if !cache.contains_key(&file) {
                    let image = load_image(&file).with_context(|| format!("texture of material '{}' in {}", m.name, mtl.display()))?;
                    cache.insert(file.clone(), image);
                }
                cache.get(&file).cloned()
            }
        };
        let opacity = m
            .dissolve
            .or_else(|| m.unknown_param.get("Tr").and_then(|t| t.trim().parse::<f32>().ok()).map(|tr| 1.0 - tr))
            .filter(|d| d.is_finite())
            .map_or(1.0, |d| d.clamp(0.0, 1.0));
        out.push(Material {
            name: m.name.clone(),
            diffuse: finite_or(m.diffuse, defaults.diffuse),
            texture,
            specular: finite_or(m.specular, defaults.specular),
            // An exponent below 1 makes the highlight cover the whole hemisphere; MTL files
            // often write Ns 0 meaning "no highlight" (together with Ks 0).
            shininess: finite_or(m.shininess.map(|s| [s]), [defaults.shininess])[0].max(1.0),
            opacity,
            // MTL has no such flag.
            sides: Sides::Unspecified,
        });
    }
    Ok(out)
}

/// Merge tobj's per-group meshes into one mesh per (material, has normals), fix up UVs
/// (OBJ's v points up; ours points down the image) and fill in normals.
fn build_model(
    parts: Vec<tobj::Model>,
    mut materials: Vec<Material>,
    crease_deg: f32,
    what: &str,
    notes: &mut Vec<String>,
) -> Result<Model> {
    let mut default_material: Option<usize> = None;
    let mut keys: Vec<(usize, bool)> = Vec::new();
    let mut meshes: Vec<Mesh> = Vec::new();
    for part in parts {
        let m = part.mesh;
        if m.indices.is_empty() {
            continue;
        }
        let material = match m.material_id.filter(|&id| id < materials.len()) {
            Some(id) => id,
            None => *default_material.get_or_insert_with(|| {
                materials.push(Material::default());
                materials.len() - 1
            }),
        };
        let n_vert = m.positions.len() / 3;
        let has_normals = m.normals.len() == m.positions.len();
        let key = (material, has_normals);
        let slot = match keys.iter().position(|k| *k == key) {
            Some(s) => s,
            None => {
                keys.push(key);
                meshes.push(Mesh { material, ..Default::default() });
                meshes.len() - 1
            }
        };
        let mesh = &mut meshes[slot];
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        if has_normals {
            mesh.normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        }
        if m.texcoords.len() == n_vert * 2 {
            mesh.uvs.extend(m.texcoords.chunks_exact(2).map(|t| [t[0], 1.0 - t[1]]));
        } else {
            mesh.uvs.extend(std::iter::repeat_n([0.0, 0.0], n_vert));
        }
        mesh.indices.extend(m.indices.iter().map(|i| i + base));
    }
    for mesh in &mut meshes {
        let label = format!("{what}: material '{}'", materials[mesh.material].name);
        notes.extend(finish_mesh(mesh, crease_deg, &label)?);
    }
    Ok(Model { meshes, materials })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_statement_options_are_skipped() {
        // Examples of the option syntax from the MTL spec (Wavefront, "Texture map statements").
        assert_eq!(texture_file_name(".\\wal67ar_small.jpg"), "./wal67ar_small.jpg");
        assert_eq!(texture_file_name("-s 1 1 1 -o 0.5 0 tex.png"), "tex.png");
        assert_eq!(texture_file_name("-blendu off -mm 0 1 dir\\my tex.jpg"), "dir/my tex.jpg");
        assert_eq!(texture_file_name("-s 2 wood.jpg"), "wood.jpg");
        assert_eq!(texture_file_name("plain.png"), "plain.png");
    }

    #[test]
    fn embedded_quad_is_triangulated_with_flipped_v() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
        let m = load_obj_bytes(obj).unwrap();
        assert_eq!(m.triangle_count(), 2);
        let mesh = &m.meshes[0];
        // OBJ vt (0,0) is the image's bottom-left, i.e. (0,1) with v pointing down.
        let i0 = mesh.positions.iter().position(|p| *p == [0.0, 0.0, 0.0]).unwrap();
        assert_eq!(mesh.uvs[i0], [0.0, 1.0]);
        // Counter-clockwise seen from +z: normals +z.
        for n in &mesh.normals {
            assert!((n[2] - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn embedded_garbage_is_an_error() {
        assert!(load_obj_bytes(b"v 1 2\nf 1 2 3\n").is_err());
        assert!(load_obj_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").is_err());
        assert!(load_obj_bytes(b"# nothing\n").is_err());
        assert!(load_obj_bytes(b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").is_err());
    }

    #[test]
    fn bad_obj_and_mtl_lines_are_errors_naming_the_line() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        let cases: [(String, &str); 9] = [
            (format!("{tri}f 1 2\n"), "line 4"),
            (format!("{tri}f\n"), "line 4"),
            (format!("{tri}vt 0 0\nf 1/1 2/-12 3/1\n"), "texture coordinate index -12"),
            (format!("{tri}f 1 2 0\n"), "vertex index 0"),
            (format!("{tri}f 1 2 9223372036854775807\n"), "vertex index 9223372036854775807"),
            (format!("{tri}vn 0 0 1\nf 1//1 2//1 3//2\n"), "normal index 2"),
            (format!("{tri}vn nan 0 1\nf 1//1 2//1 3//1\n"), "non-finite normal"),
            (format!("{tri}vt inf 0\nf 1/1 2/1 3/1\n"), "non-finite texture coordinate"),
            (format!("{tri}vn 1e39 0 0\nf 1//1 2//1 3//1\n"), "non-finite normal"),
        ];
        for (obj, needle) in cases {
            let err = format!("{:#}", load_obj_bytes(obj.as_bytes()).unwrap_err());
            assert!(err.contains(needle), "{obj:?}: {err}");
        }
        for (mtl, needle) in [
            ("newmtl a\nKd nan 0 0\n", "line 2: Kd value nan"),
            ("newmtl a\nKd 1e39 0 0\n", "line 2: Kd value 1e39"),
            ("newmtl a\n\nKd -1 0.5 0.5\n", "line 3: Kd value -1"),
            ("newmtl a\nKd 0.5\n", "line 2: Kd needs 3"),
            ("newmtl a\nd 2\n", "line 2: d value 2"),
            ("newmtl a\nNs -4\n", "line 2: Ns value -4"),
        ] {
            let err = format!("{:#}", check_mtl(mtl.as_bytes()).unwrap_err());
            assert!(err.contains(needle), "{mtl:?}: {err}");
        }
        check_mtl(b"newmtl a\nKd 0.8 0.8 0.8\nKs 0 0 0\nNs 32\nd 1\nmap_Kd tex.png\n").unwrap();
    }
}
