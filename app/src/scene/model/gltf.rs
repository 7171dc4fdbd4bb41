//! glTF 2.0 (.gltf with its buffers and images beside it, or a single .glb), through the gltf
//! crate: triangle primitives of the default scene with node transforms applied, TEXCOORD_0,
//! the metallic-roughness material's base colour (factor and texture), and whether the material
//! is double-sided.
//!
//! The document is checked before it is walked (see [`validate`]): the gltf crate's accessors
//! trust indices and sizes and panic or allocate without bound on a hostile file. Buffers and
//! images are read here, so that an error names the file at fault (a missing .bin, a truncated
//! texture), and only the base-colour images are decoded, with the limits of `scene::decode`.

use super::{LoadedModel, finish_mesh};
use crate::scene::background::rgba8_from_dynamic;
use crate::scene::{Material, Mesh, Model, Rgba8Image, Sides};
use ::gltf::json;
use ::gltf::mesh::Mode;
use anyhow::{Context, Result, anyhow, bail};
use glam::{Mat3, Mat4, Quat, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Node hierarchies deeper than this are refused.
const MAX_NODE_DEPTH: usize = 256;
/// An accessor without a bufferView is all zeros; more elements than this is refused.
const MAX_ACCESSOR_COUNT: u64 = 1 << 26;

pub(super) fn load_gltf_file(path: &Path) -> Result<LoadedModel> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read glTF {}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    import(&bytes, Some(base), &path.display().to_string())
}

/// Load a self-contained glTF held in memory (a .glb, or a .gltf with data: URIs), e.g. the
/// built-in demo model.
pub fn load_glb_bytes(bytes: &[u8]) -> Result<Model> {
    let loaded = import(bytes, None, "embedded glTF")?;
    if loaded.model.triangle_count() == 0 {
        bail!("embedded glTF contains no triangles");
    }
    Ok(loaded.model)
}

/// Parse, read the buffers, validate, and build. `base` is the folder external files are
/// relative to (None: external files are refused).
fn import(bytes: &[u8], base: Option<&Path>, what: &str) -> Result<LoadedModel> {
    let (document, mut blob) = parse_document(bytes).with_context(|| format!("cannot load glTF {what}"))?;
    let mut buffers = Vec::new();
    for (i, buffer) in document.as_json().buffers.iter().enumerate() {
        let data = match &buffer.uri {
            None => blob.take().ok_or_else(|| anyhow!("{what}: buffer {i} has no uri and there is no GLB binary chunk"))?,
            Some(uri) => read_uri(uri, base).with_context(|| format!("{what}: buffer {i}"))?,
        };
        if (data.len() as u64) < buffer.byte_length.0 {
            bail!(
                "{what}: buffer {i} ({}) holds {} bytes, the glTF says {}",
                describe_uri(buffer.uri.as_deref(), base),
                data.len(),
                buffer.byte_length.0
            );
        }
        buffers.push(data);
    }
    validate(document.as_json(), &buffers).with_context(|| format!("invalid glTF {what}"))?;
    build(&document, &buffers, base, what)
}

/// The document and the GLB binary chunk. The container is split here (glTF 2.0 §4.4) and the
/// JSON parsed without the gltf crate's checks first, because those panic on a GLB length
/// below 12 and on a POSITION accessor index out of range (found by the corpus mutation run).
fn parse_document(bytes: &[u8]) -> Result<(::gltf::Document, Option<Vec<u8>>)> {
    let (json_bytes, blob) = if bytes.starts_with(b"glTF") { split_glb(bytes)? } else { (bytes, None) };
    let root: json::Root = json::deserialize::from_slice(json_bytes).context("not valid glTF JSON")?;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(index) = prim.attributes.values().find(|i| i.value() >= root.accessors.len()) {
                bail!("mesh {m} primitive {p}: accessor {} does not exist ({} accessors)", index.value(), root.accessors.len());
            }
        }
    }
    let document = ::gltf::Document::from_json(root).map_err(|e| anyhow!("invalid glTF: {e}"))?;
    Ok((document, blob.map(<[u8]>::to_vec)))
}

/// GLB: a 12-byte header (magic, version 2, total length), a JSON chunk, an optional BIN chunk;
/// each chunk is a length, a type and the data.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    let word = |at: usize| -> Result<u32> {
        let b = bytes.get(at..at + 4).ok_or_else(|| anyhow!("GLB truncated at byte {at}"))?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (version, length) = (word(4)?, word(8)? as usize);
    if version != 2 {
        bail!("GLB version {version} (only 2 is supported)");
    }
    if length < 12 || length > bytes.len() {
        bail!("GLB header says {length} bytes, the file has {}", bytes.len());
    }
    let chunk = |at: usize, ty: &[u8; 4]| -> Result<Option<(&[u8], usize)>> {
        if at >= length {
            return Ok(None);
        }
        let len = word(at)? as usize;
        let kind = bytes.get(at + 4..at + 8).ok_or_else(|| anyhow!("GLB truncated at byte {at}"))?;
        if kind != ty {
            bail!("GLB chunk at byte {at} is {:?}, expected {:?}", String::from_utf8_lossy(kind), String::from_utf8_lossy(ty));
        }
        let end = (at + 8).checked_add(len).filter(|&e| e <= length).ok_or_else(|| anyhow!("GLB chunk at byte {at} runs past the end"))?;
        Ok(Some((&bytes[at + 8..end], end)))
    };
    let (json, next) = chunk(12, b"JSON")?.ok_or_else(|| anyhow!("GLB without a JSON chunk"))?;
    let bin = chunk(next, b"BIN\0")?.map(|(b, _)| b);
    Ok((json, bin))
}

/// The bytes a URI names: a base64 `data:` URI, or a file relative to `base`.
fn read_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or_else(|| anyhow!("data: URI is not base64"))?;
        return base64_decode(data);
    }
    let path = uri_path(uri, base)?;
    std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))
}

fn uri_path(uri: &str, base: Option<&Path>) -> Result<PathBuf> {
    if uri.contains("://") {
        bail!("URI '{uri}' is not a local file");
    }
    let base = base.ok_or_else(|| anyhow!("external file '{uri}' in an embedded glTF"))?;
    Ok(base.join(percent_decode(uri)))
}

fn describe_uri(uri: Option<&str>, base: Option<&Path>) -> String {
    match uri {
        None => "GLB binary chunk".into(),
        Some(u) if u.starts_with("data:") => "data: URI".into(),
        Some(u) => uri_path(u, base).map_or_else(|_| u.to_string(), |p| p.display().to_string()),
    }
}

/// `%20` and friends in a relative URI (RFC 3986 §2.1); malformed escapes are kept as written.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && let (Some(h), Some(l)) = (b.get(i + 1).and_then(|&c| hex(c)), b.get(i + 2).and_then(|&c| hex(c)))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Standard base64 (RFC 4648 §4), padding optional, whitespace not allowed.
fn base64_decode(s: &str) -> Result<Vec<u8>> {
    let s = s.trim_end_matches('=');
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for (i, c) in s.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => bail!("invalid base64 character at offset {i}"),
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Ok(out)
}

/// Check everything the walk below relies on, so that a hostile document is an error naming
/// what is wrong instead of a panic inside the gltf crate, a hang or a silent wrong result:
/// indices in range, sizes within their buffers, attribute types, nodes forming a forest (no
/// cycles, no node listed twice), invertible node transforms, material factors in 0..1.
pub(crate) fn validate(root: &json::Root, buffers: &[Vec<u8>]) -> Result<()> {
    use json::accessor::{ComponentType, Type};
    use json::validation::Checked::Valid;
    let n_views = root.buffer_views.len();
    for (i, v) in root.buffer_views.iter().enumerate() {
        let buffer = buffers.get(v.buffer.value()).ok_or_else(|| anyhow!("bufferView {i}: buffer {} does not exist", v.buffer.value()))?;
        let end = v.byte_offset.map_or(0, |o| o.0).checked_add(v.byte_length.0);
        if end.is_none_or(|e| e > buffer.len() as u64) {
            bail!(
                "bufferView {i}: bytes {}+{} lie outside buffer {} ({} bytes)",
                v.byte_offset.map_or(0, |o| o.0),
                v.byte_length.0,
                v.buffer.value(),
                buffer.len()
            );
        }
    }
    let view_fits = |what: &str, view: usize, offset: u64, stride: Option<u64>, count: u64, elem: u64| -> Result<()> {
        let v = root.buffer_views.get(view).ok_or_else(|| anyhow!("{what}: bufferView {view} does not exist ({n_views} views)"))?;
        let stride = stride.or(v.byte_stride.map(|s| s.0 as u64)).unwrap_or(elem).max(elem);
        let need = if count == 0 {
            Some(0)
        } else {
            (count - 1).checked_mul(stride).and_then(|x| x.checked_add(elem)).and_then(|x| x.checked_add(offset))
        };
        match need {
            Some(n) if n <= v.byte_length.0 => Ok(()),
            _ => bail!(
                "{what}: {count} elements of {elem} bytes from offset {offset} do not fit bufferView {view} ({} bytes)",
                v.byte_length.0
            ),
        }
    };
    for (i, a) in root.accessors.iter().enumerate() {
        let what = format!("accessor {i}");
        let (Valid(ty), Valid(comp)) = (&a.type_, &a.component_type) else { bail!("{what}: unknown type or componentType") };
        let elem = (comp.0.size() * ty.multiplicity()) as u64;
        if a.count.0 == 0 {
            bail!("{what}: count 0 (glTF 2.0 requires at least 1)");
        }
        let offset = a.byte_offset.map_or(0, |o| o.0);
        match a.buffer_view {
            Some(view) => view_fits(&what, view.value(), offset, None, a.count.0, elem)?,
            None if a.count.0 > MAX_ACCESSOR_COUNT => {
                bail!("{what}: {} elements without a bufferView (at most {MAX_ACCESSOR_COUNT})", a.count.0)
            }
            None => {}
        }
        if let Some(sparse) = &a.sparse {
            if sparse.count.0 > a.count.0 {
                bail!("{what}: {} sparse elements but only {} in the accessor", sparse.count.0, a.count.0);
            }
            let Valid(index_type) = &sparse.indices.component_type else { bail!("{what}: unknown sparse index type") };
            view_fits(
                &format!("{what} sparse indices"),
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                Some(index_type.0.size() as u64),
                sparse.count.0,
                index_type.0.size() as u64,
            )?;
            view_fits(
                &format!("{what} sparse values"),
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                Some(elem),
                sparse.count.0,
                elem,
            )?;
        }
    }
    let accessor = |what: &str, index: usize| {
        root.accessors.get(index).ok_or_else(|| anyhow!("{what}: accessor {index} does not exist ({} accessors)", root.accessors.len()))
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let what = format!("mesh {m} primitive {p}");
            for (semantic, index) in &prim.attributes {
                let a = accessor(&what, index.value())?;
                let (Valid(ty), Valid(comp)) = (&a.type_, &a.component_type) else {
                    bail!("{what}: accessor {} has an unknown type", index.value())
                };
                let expected = match semantic {
                    Valid(json::mesh::Semantic::Positions) => Some((Type::Vec3, "POSITION", true)),
                    Valid(json::mesh::Semantic::Normals) => Some((Type::Vec3, "NORMAL", true)),
                    Valid(json::mesh::Semantic::TexCoords(0)) => Some((Type::Vec2, "TEXCOORD_0", false)),
                    _ => None,
                };
                if let Some((want, name, float_only)) = expected {
                    // Component types glTF 2.0 §3.7.2.1 allows (and the gltf crate's readers expect).
                    let comp_ok = comp.0 == ComponentType::F32 || (!float_only && matches!(comp.0, ComponentType::U8 | ComponentType::U16));
                    if *ty != want || !comp_ok {
                        let kinds = if float_only { " of FLOAT" } else { " of FLOAT, UNSIGNED_BYTE or UNSIGNED_SHORT" };
                        bail!("{what}: {name} is {ty:?} of {:?}; glTF 2.0 requires {want:?}{kinds}", comp.0);
                    }
                }
            }
            if let Some(index) = prim.indices {
                let a = accessor(&format!("{what} indices"), index.value())?;
                let (Valid(ty), Valid(comp)) = (&a.type_, &a.component_type) else {
                    bail!("{what}: accessor {} has an unknown type", index.value())
                };
                if *ty != Type::Scalar || !matches!(comp.0, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
                    bail!("{what}: indices are {ty:?} of {:?}; glTF 2.0 requires unsigned SCALAR", comp.0);
                }
            }
            if let Some(mat) = prim.material
                && mat.value() >= root.materials.len()
            {
                bail!("{what}: material {} does not exist", mat.value());
            }
            if !matches!(prim.mode, Valid(_)) {
                bail!("{what}: unknown primitive mode");
            }
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        match (&image.buffer_view, &image.uri, &image.mime_type) {
            (Some(_), _, None) => bail!("image {i}: a bufferView without a mimeType (glTF 2.0 requires one)"),
            (Some(view), _, Some(_)) if view.value() >= n_views => bail!("image {i}: bufferView {} does not exist", view.value()),
            (None, None, _) => bail!("image {i}: neither a uri nor a bufferView"),
            _ => {}
        }
    }
    for (i, t) in root.textures.iter().enumerate() {
        if t.source.value() >= root.images.len() {
            bail!("texture {i}: image {} does not exist", t.source.value());
        }
    }
    for (i, m) in root.materials.iter().enumerate() {
        let name = m.name.clone().unwrap_or_else(|| format!("material {i}"));
        let pbr = &m.pbr_metallic_roughness;
        let factor = pbr.base_color_factor.0;
        if !factor.iter().all(|c| (0.0..=1.0).contains(c)) {
            bail!("material '{name}': baseColorFactor {factor:?} outside 0..1 (glTF 2.0 §5.22)");
        }
        for (key, v) in [("metallicFactor", pbr.metallic_factor.0), ("roughnessFactor", pbr.roughness_factor.0)] {
            if !(0.0..=1.0).contains(&v) {
                bail!("material '{name}': {key} {v} outside 0..1");
            }
        }
        if let Some(t) = &pbr.base_color_texture
            && t.index.value() >= root.textures.len()
        {
            bail!("material '{name}': texture {} does not exist", t.index.value());
        }
    }
    // Nodes: children in range, each node the child of at most one parent, no cycles; then the
    // walk from any root visits each node once.
    let n_nodes = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n_nodes];
    for (i, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten() {
            let c = c.value();
            if c >= n_nodes {
                bail!("node {i}: child {c} does not exist ({n_nodes} nodes)");
            }
            if let Some(p) = parent[c] {
                bail!("node {c} is listed as a child of node {p} and again of node {i}; glTF nodes form a forest");
            }
            parent[c] = Some(i);
        }
        if let Some(mesh) = node.mesh
            && mesh.value() >= root.meshes.len()
        {
            bail!("node {i}: mesh {} does not exist", mesh.value());
        }
        let local = local_matrix(node);
        if !local.is_finite() || local.determinant() == 0.0 || !local.determinant().is_finite() {
            bail!("node {i}: its transform is not invertible or not finite (an all-zero matrix or scale draws nothing)");
        }
    }
    for start in 0..n_nodes {
        // Following parents from any node must reach a root within n steps.
        let (mut at, mut steps) = (start, 0);
        while let Some(p) = parent[at] {
            at = p;
            steps += 1;
            if steps > n_nodes {
                bail!("node {start}: the node hierarchy has a cycle");
            }
            if steps > MAX_NODE_DEPTH {
                bail!("node {start}: the node hierarchy is deeper than {MAX_NODE_DEPTH}");
            }
        }
    }
    for (s, scene) in root.scenes.iter().enumerate() {
        let mut seen = std::collections::HashSet::new();
        for n in &scene.nodes {
            if n.value() >= n_nodes {
                bail!("scene {s}: node {} does not exist", n.value());
            }
            if parent[n.value()].is_some() || !seen.insert(n.value()) {
                bail!("scene {s}: node {} is listed twice or is another node's child", n.value());
            }
        }
    }
    Ok(())
}

/// A node's local transform: its matrix, or T·R·S (glTF 2.0 §5.25).
fn local_matrix(node: &json::scene::Node) -> Mat4 {
    if let Some(m) = node.matrix {
        return Mat4::from_cols_array(&m);
    }
    let t = node.translation.map_or(Vec3::ZERO, Vec3::from_array);
    let r = node.rotation.map_or(Quat::IDENTITY, |q| Quat::from_array(q.0));
    let s = node.scale.map_or(Vec3::ONE, Vec3::from_array);
    Mat4::from_scale_rotation_translation(s, r, t)
}

fn build(doc: &::gltf::Document, buffers: &[Vec<u8>], base: Option<&Path>, what: &str) -> Result<LoadedModel> {
    let what = what.to_string();
    let mut out = Builder {
        what: &what,
        root: doc.as_json(),
        buffers,
        base,
        notes: Vec::new(),
        materials: Vec::new(),
        by_gltf: HashMap::new(),
        meshes: Vec::new(),
    };

    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            // No scene: draw every node that is nobody's child.
            let children: std::collections::HashSet<usize> = doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
            out.notes.push(format!("{what}: no scene defined; using all root nodes"));
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    let mut stack: Vec<(::gltf::Node, Mat4, usize)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                out.add_primitive(&mesh, &prim, world)?;
            }
        }
        stack.extend(node.children().collect::<Vec<_>>().into_iter().rev().map(|c| (c, world, depth + 1)));
    }
    let Builder { notes, materials, meshes, .. } = out;
    Ok(LoadedModel { model: Model { meshes, materials }, notes })
}

/// Collects primitives into one mesh per material.
struct Builder<'a> {
    what: &'a str,
    root: &'a json::Root,
    buffers: &'a [Vec<u8>],
    base: Option<&'a Path>,
    notes: Vec<String>,
    materials: Vec<Material>,
    /// glTF material index (None: primitive without material) to index in `materials`.
    by_gltf: HashMap<Option<usize>, usize>,
    meshes: Vec<Mesh>,
}

impl Builder<'_> {
    fn add_primitive(&mut self, mesh: &::gltf::Mesh, prim: &::gltf::Primitive, world: Mat4) -> Result<()> {
        let label = format!("{}: mesh '{}' primitive {}", self.what, mesh.name().unwrap_or("?"), prim.index());
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.notes.push(format!("{label}: {mode:?} primitive skipped (only triangles are drawn)"));
            return Ok(());
        }
        let buffers = self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
        let positions: Vec<[f32; 3]> = reader.read_positions().ok_or_else(|| anyhow!("{label}: no POSITION attribute"))?.collect();
        let normals: Vec<[f32; 3]> = reader.read_normals().map(|n| n.collect()).unwrap_or_default();
        if let Some(i) = normals.iter().position(|n| !n.iter().all(|c| c.is_finite())) {
            bail!("{label}: NORMAL {i} is not finite ({:?})", normals[i]);
        }
        let uvs: Vec<[f32; 2]> = reader.read_tex_coords(0).map(|t| t.into_f32().collect()).unwrap_or_default();
        let raw: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let mut indices = match mode {
            Mode::TriangleStrip => strip_to_list(&raw),
            Mode::TriangleFan => fan_to_list(&raw),
            _ => raw,
        };
        indices.truncate(indices.len() / 3 * 3);

        // Node transform: points by the matrix, normals by its inverse transpose; a mirroring
        // transform (negative determinant) flips the winding, so swap two corners back.
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        let positions = positions.iter().map(|p| world.transform_point3(Vec3::from_array(*p)).to_array()).collect();
        let normals = normals.iter().map(|n| (normal_matrix * Vec3::from_array(*n)).normalize_or_zero().to_array()).collect();
        if world.determinant() < 0.0 {
            for t in indices.chunks_exact_mut(3) {
                t.swap(1, 2);
            }
        }
        let mut part = Mesh { positions, normals, uvs, indices, material: 0 };
        // glTF 2.0 spec §3.7.2.1: without normals, clients must compute flat normals.
        self.notes.extend(finish_mesh(&mut part, 0.0, &label)?);

        let material = self.material(prim.material())?;
        let target = match self.meshes.iter().position(|m| m.material == material) {
            Some(i) => i,
            None => {
                self.meshes.push(Mesh { material, ..Default::default() });
                self.meshes.len() - 1
            }
        };
        let dst = &mut self.meshes[target];
        let base = dst.positions.len() as u32;
        dst.positions.extend(part.positions);
        dst.normals.extend(part.normals);
        dst.uvs.extend(part.uvs);
        dst.indices.extend(part.indices.iter().map(|i| i + base));
        Ok(())
    }

    /// Our material for a glTF material, converted once.
    fn material(&mut self, mat: ::gltf::Material) -> Result<usize> {
        if let Some(&i) = self.by_gltf.get(&mat.index()) {
            return Ok(i);
        }
        let converted = match mat.index() {
            // No material on the primitive: our default colours (the spec's default is a white
            // metal, which looks wrong under a Blinn-Phong model), single-sided as the spec's
            // default material is (glTF 2.0 §3.9.6).
            None => Material { sides: Sides::Front, ..Material::default() },
            Some(index) => self.convert_material(&mat, index)?,
        };
        self.materials.push(converted);
        self.by_gltf.insert(mat.index(), self.materials.len() - 1);
        Ok(self.materials.len() - 1)
    }

    /// Decode image `index` (validated) with the limits of `scene::decode`; errors name the file.
    fn image(&self, index: usize) -> Result<Rgba8Image> {
        use image::ImageFormat::{Jpeg, Png};
        let image = &self.root.images[index];
        let decoded = match (&image.buffer_view, &image.uri) {
            (Some(view), _) => {
                let v = &self.root.buffer_views[view.value()];
                let start = v.byte_offset.map_or(0, |o| o.0) as usize;
                let bytes = &self.buffers[v.buffer.value()][start..start + v.byte_length.0 as usize];
                crate::scene::decode::decode_bytes(bytes, &[Png, Jpeg])?
            }
            (None, Some(uri)) if uri.starts_with("data:") => crate::scene::decode::decode_bytes(&read_uri(uri, self.base)?, &[Png, Jpeg])?,
            (None, Some(uri)) => crate::scene::decode::decode_file(&uri_path(uri, self.base)?, &[Png, Jpeg])?,
            (None, None) => bail!("image {index} has neither a uri nor a bufferView"),
        };
        Ok(rgba8_from_dynamic(&decoded.image))
    }

    fn convert_material(&mut self, mat: &::gltf::Material, index: usize) -> Result<Material> {
        let name = mat.name().map_or_else(|| format!("material {index}"), str::to_string);
        let pbr = mat.pbr_metallic_roughness();
        let base = pbr.base_color_factor();
        let texture = match pbr.base_color_texture() {
            None => None,
            Some(info) => {
                if info.tex_coord() != 0 {
                    self.notes.push(format!(
                        "{}: material '{name}' uses TEXCOORD_{} for its base colour; only TEXCOORD_0 is read",
                        self.what,
                        info.tex_coord()
                    ));
                }
                let image_index = info.texture().source().index();
                Some(
                    self.image(image_index)
                        .with_context(|| format!("{}: base-colour image {image_index} of material '{name}'", self.what))?,
                )
            }
        };
        let metallic = pbr.metallic_factor().clamp(0.0, 1.0);
        // glTF 2.0 spec, Appendix B: the specular reflectance at normal incidence is
        // F0 = mix(0.04, baseColor, metallic).
        let specular = [0, 1, 2].map(|i| 0.04 + (base[i] - 0.04) * metallic);
        Ok(Material {
            name,
            diffuse: [base[0], base[1], base[2]],
            texture,
            specular,
            shininess: blinn_phong_exponent(pbr.roughness_factor()),
            opacity: match mat.alpha_mode() {
                ::gltf::material::AlphaMode::Blend => base[3].clamp(0.0, 1.0),
                _ => 1.0,
            },
            // glTF 2.0 §3.9.5: `doubleSided` false (the default) culls back faces.
            sides: if mat.double_sided() { Sides::Both } else { Sides::Front },
        })
    }
}

/// Blinn-Phong exponent matching a glTF roughness: glTF's microfacet α is roughness²
/// (spec Appendix B), and a Beckmann α corresponds to the Phong exponent 2/α² − 2 (Walter et al.
/// 2007, "Microfacet Models for Refraction through Rough Surfaces", §5.2). Clamped to [1, 8192];
/// a non-finite roughness counts as the spec's default, 1.
pub(crate) fn blinn_phong_exponent(roughness: f32) -> f32 {
    let roughness = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
    let alpha = (roughness * roughness).max(1e-3);
    (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 8192.0)
}

/// glTF spec §3.7.2.1: strip triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}).
fn strip_to_list(v: &[u32]) -> Vec<u32> {
    (0..v.len().saturating_sub(2)).flat_map(|i| [v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]]).collect()
}

/// glTF spec §3.7.2.1: fan triangle i is (v_{i+1}, v_{i+2}, v_0).
fn fan_to_list(v: &[u32]) -> Vec<u32> {
    (0..v.len().saturating_sub(2)).flat_map(|i| [v[i + 1], v[i + 2], v[0]]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_follow_the_spec() {
        // Strip 0,1,2,3,4: (0,1,2), (1,3,2), (2,3,4) — consistent counter-clockwise winding.
        assert_eq!(strip_to_list(&[0, 1, 2, 3, 4]), vec![0, 1, 2, 1, 3, 2, 2, 3, 4]);
        assert_eq!(fan_to_list(&[0, 1, 2, 3]), vec![1, 2, 0, 2, 3, 0]);
        assert!(strip_to_list(&[0, 1]).is_empty());
    }

    #[test]
    fn roughness_to_exponent() {
        // roughness 0.5: α = 0.25, 2/α² − 2 = 30 (Walter et al. 2007 eq. for the Phong exponent).
        assert!((blinn_phong_exponent(0.5) - 30.0).abs() < 1e-4);
        assert_eq!(blinn_phong_exponent(1.0), 1.0);
        assert_eq!(blinn_phong_exponent(0.0), 8192.0);
        assert_eq!(blinn_phong_exponent(f32::NAN), 1.0);
    }

    #[test]
    fn base64_and_percent_decoding_follow_the_rfcs() {
        // RFC 4648 §10 test vectors.
        for (enc, dec) in
            [("", ""), ("Zg==", "f"), ("Zm8=", "fo"), ("Zm9v", "foo"), ("Zm9vYg==", "foob"), ("Zm9vYmE=", "fooba"), ("Zm9vYmFy", "foobar")]
        {
            assert_eq!(base64_decode(enc).unwrap(), dec.as_bytes());
        }
        assert!(base64_decode("Zm9v!").is_err());
        // RFC 3986 §2.1: "%20" is a space; a malformed escape stays as written.
        assert_eq!(percent_decode("my%20tex.png"), "my tex.png");
        assert_eq!(percent_decode("100%.png"), "100%.png");
    }
}
