//! The model pass's raster side: which faces a material shows (glTF `doubleSided`) and the
//! triangle order each level of detail is drawn in.

use crate::common;

use common::{gpu, inputs, scene};
use previz::render::Layer;
use previz::scene::{Model, Sides};
use previz::setup::{Inputs, prepare};

/// A GLB (glTF 2.0 §4.4: header, JSON chunk, BIN chunk) of two upright 1.8-unit squares side by
/// side, one material (grey, 0.25): the left one (x < 0) wound counter-clockwise seen from +z, the right one
/// seen from −z; no normals, so the loader computes them from the winding. `double_sided`: the
/// material's `doubleSided` (None: left out, which glTF reads as false).
fn two_squares_glb(double_sided: Option<bool>) -> Vec<u8> {
    let positions: [[f32; 3]; 8] = [
        [-2.0, 0.0, 0.0],
        [-0.2, 0.0, 0.0],
        [-0.2, 1.8, 0.0],
        [-2.0, 1.8, 0.0],
        [0.2, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 1.8, 0.0],
        [0.2, 1.8, 0.0],
    ];
    // Left: (0,1,2), (0,2,3) counter-clockwise from +z; right: the same corners reversed.
    let indices: [u16; 12] = [0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6];
    let mut bin: Vec<u8> = positions.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let sided = double_sided.map_or(String::new(), |d| format!(", \"doubleSided\": {d}"));
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
"meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
"materials": [{{"name": "grey paper", "pbrMetallicRoughness": {{"baseColorFactor": [0.25, 0.25, 0.25, 1.0]}}{sided}}}],
"buffers": [{{"byteLength": {n}}}],
"bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 96}}, {{"buffer": 0, "byteOffset": 96, "byteLength": 24}}],
"accessors": [{{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-2.0, 0.0, 0.0], "max": [2.0, 1.8, 0.0]}},
{{"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}}]}}"#,
        n = bin.len()
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(bin);
    glb
}

/// glTF 2.0 §3.9.5: a material without `doubleSided` (or with it false) shows front faces only,
/// one with `doubleSided: true` both. Seen from +z (the camera stands south of the model, whose
/// +z turns to the camera), the left square faces the camera and the right one faces away: a
/// single-sided material shows the left one only; a double-sided one both, the left one
/// unchanged to the byte; a material that does not say (an OBJ's) both, as before.
#[test]
fn a_single_sided_material_hides_its_back_faces() {
    let s = scene("width = 160\nheight = 96\nenvironment = \"cubemaps/humus_Park2_512\"\n[placement]\nfill = 0.9\n");
    let env = inputs(&s).env;
    let load = |d| previz::scene::model::load_glb_bytes(&two_squares_glb(d)).unwrap();
    let (absent, single, double) = (load(None), load(Some(false)), load(Some(true)));
    assert_eq!(
        [absent.materials[0].sides, single.materials[0].sides, double.materials[0].sides],
        [Sides::Front, Sides::Front, Sides::Both]
    );
    let mut unspecified = single.clone();
    unspecified.materials[0].sides = Sides::Unspecified;
    // The model layer: premultiplied RGBA over transparent black, alpha = coverage.
    let render = |model: &Model| {
        let i = Inputs { model: model.clone(), env: env.clone(), env_equirect: None, background: None };
        let (mut c, p) = prepare(gpu(), &s, &i).unwrap();
        c.render(gpu(), &p, Layer::Model).unwrap()
    };
    let covered = |r: &previz::render::Rendered, left: bool| {
        let half = r.width / 2;
        (0..r.height)
            .flat_map(|y| (0..half).map(move |x| (x, y)))
            .filter(|&(x, y)| common::pixel(r, if left { x } else { half + x }, y)[3] > 0)
            .count()
    };
    let [absent, single, double, unspecified] = [&absent, &single, &double, &unspecified].map(render);
    let (w, h) = (single.width as usize, single.height as usize);
    let front = covered(&single, true);
    // The 4.4-unit bounding sphere spans 90% of the view's 96 rows, so each 1.8-unit square is
    // about 35 pixels on a side (~1 200 pixels).
    assert!(front > w * h / 20, "the square facing the camera covers {front} pixels");
    assert_eq!(covered(&single, false), 0, "the single-sided square seen from behind is drawn");
    assert_eq!(absent.rgba, single.rgba, "doubleSided left out is doubleSided false");
    for (name, r) in [("double-sided", &double), ("unspecified", &unspecified)] {
        let back = covered(r, false);
        assert_eq!(covered(r, true), front, "{name}: the front-facing square");
        // Mirror images of each other: the same coverage within the raster's rounding.
        assert!(back.abs_diff(front) <= front / 50, "{name}: the square seen from behind covers {back} pixels vs {front}");
        let left = |r: &previz::render::Rendered| -> Vec<u8> {
            r.rgba.chunks_exact(r.width as usize * 4).flat_map(|row| row[..row.len() / 2].to_vec()).collect()
        };
        assert_eq!(left(r), left(&single), "{name}: the front-facing square is drawn differently");
    }
}

/// The float layers (`--layers`, render/layers.rs) cull as the composite does: the single-sided
/// square seen from behind covers nothing in the model layer and has no depth; a double-sided
/// material shows both squares, the front one exactly as the single-sided material does.
#[test]
fn the_layers_hide_a_single_sided_back_face_as_the_composite_does() {
    let s = scene("width = 160\nheight = 96\nenvironment = \"cubemaps/humus_Park2_512\"\n[placement]\nfill = 0.9\n");
    let env = inputs(&s).env;
    let load = |d| previz::scene::model::load_glb_bytes(&two_squares_glb(Some(d))).unwrap();
    let layers = |model: Model| {
        let i = Inputs { model, env: env.clone(), env_equirect: None, background: None };
        let (mut c, p) = prepare(gpu(), &s, &i).unwrap();
        c.render_layers(gpu(), &p).unwrap()
    };
    // Pixels of each half the layer covers (alpha > 0.5) and that have a finite depth.
    let halves = |l: &previz::render::layers::LayerImages| {
        let (w, half) = (l.width as usize, l.width as usize / 2);
        [0, half].map(|x0| {
            let px = (0..l.height as usize).flat_map(|y| (x0..x0 + half).map(move |x| y * w + x));
            let px: Vec<usize> = px.collect();
            (px.iter().filter(|&&i| l.model[i][3] > 0.5).count(), px.iter().filter(|&&i| l.depth[i].is_finite()).count())
        })
    };
    let (single, double) = (layers(load(false)), layers(load(true)));
    let [(front, front_depth), (back, back_depth)] = halves(&single);
    // About 35 pixels on a side (a_single_sided_material_hides_its_back_faces).
    assert!(front > 1000, "front-facing square: {front} layer pixels");
    assert!(front_depth.abs_diff(front) <= front / 20, "front-facing square: {front_depth} pixels with depth, {front} covered");
    assert_eq!((back, back_depth), (0, 0), "the single-sided square seen from behind is in the layers");
    let [(d_front, _), (d_back, d_back_depth)] = halves(&double);
    assert_eq!(d_front, front, "double-sided: the front-facing square");
    assert!(
        d_back.abs_diff(front) <= front / 50 && d_back_depth > front / 2,
        "double-sided back square: {d_back} covered, {d_back_depth} with depth"
    );
}

/// A texture seen from far away renders as its mean, not as a few of its texels (aliasing):
/// the model's textures carry their mip chain (render/mip_chain.rs) and the material sampler
/// filters between levels. A 2×2-unit square, 256×256 black-and-white texels of one texel
/// each, lit by the sun alone from straight above (a pixel is the texel's linear value × a
/// constant), is drawn 30 px wide: 8.6 texels a pixel, level 3.1, 1.6 after model.wgsl's bias
/// of -1.5, so every level the sampler blends is 1 or coarser, and each of those is uniform:
/// 188, the linear mean 0.5 encoded. The same square with a uniform 188 texture is its
/// reference, so the bound is the 8-bit rounding of the same value: one level. Without the
/// chain each pixel reads 4 of the 0/255 texels of level 0 and lands anywhere between black
/// and white. Near (0.46 texels a pixel) the checks show, which proves the texture is what is
/// drawn.
#[test]
fn a_far_checkerboard_renders_its_mean() {
    use glam::Vec3;
    let n = 256u32;
    let texture = |code: &dyn Fn(u32, u32) -> u8| previz::scene::Rgba8Image {
        width: n,
        height: n,
        pixels: (0..n * n)
            .flat_map(|i| {
                let v = code(i % n, i / n);
                [v, v, v, 255]
            })
            .collect(),
    };
    let square = |tex: previz::scene::Rgba8Image| {
        let mut grid = common::flat_grid(1);
        grid.uvs = grid.positions.iter().map(|p| [(p[0] + 1.0) / 2.0, (p[2] + 1.0) / 2.0]).collect();
        let material = previz::scene::Material {
            diffuse: [1.0; 3],
            specular: [0.0; 3],
            sides: Sides::Front,
            texture: Some(tex),
            ..previz::scene::Material::default()
        };
        Model { meshes: vec![grid], materials: vec![material] }
    };
    // The square's pixels at height `z` (the camera looks straight down at it), 2 px inside its
    // edges (vfov 60°, 240 px: half-width 120 / (z tan 30°) px; at most 100 px).
    let draw = |tex: previz::scene::Rgba8Image, z: f32| -> Vec<[u8; 4]> {
        let (mut c, mut p) = common::sun_alone_from_above(square(tex), previz::render::LightingMethod::Hemisphere, 1.0);
        p.lighting.sun_dir = Vec3::Z;
        p.lighting.sunlight = 1.0;
        p.camera.position = Vec3::new(0.0, 0.0, z);
        let r = c.render(gpu(), &p, Layer::Composite).unwrap();
        let half = (120.0 / (z * 30f32.to_radians().tan())).min(100.0) as u32 - 2;
        (120 - half..120 + half).flat_map(|y| (160 - half..160 + half).map(move |x| (x, y))).map(|(x, y)| common::pixel(&r, x, y)).collect()
    };
    let checks = || texture(&|x, y| if (x + y) % 2 == 0 { 0 } else { 255 });
    let far = draw(checks(), 14.0);
    let mean = draw(texture(&|_, _| 188), 14.0);
    assert!(far.len() > 500, "{} pixels", far.len());
    assert!(mean.iter().all(|p| p[1] > 60), "the uniform square is lit: {:?}", mean[0]);
    let worst = far.iter().zip(&mean).flat_map(|(a, b)| (0..3).map(|c| a[c].abs_diff(b[c]))).max().unwrap();
    assert!(worst <= 1, "far away the checks differ from their mean by up to {worst} levels (aliasing)");
    let near = draw(checks(), 0.75);
    let (lo, hi) = near.iter().fold((255, 0), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
    assert!(hi - lo > 150, "near, the checks show: {lo}..{hi}");
}

/// glTF 2.0 §3.9.5: a double-sided material's back face has "its normals reversed before the
/// lighting equation is evaluated". The sun stands south of the squares, behind the camera, so
/// the front-facing square's normal (south) faces it. Reversed, the back-facing square's normal
/// faces it too, and the two are lit alike; not reversed (a material that does not say, as
/// before), its normal points north, away from the sun, and it gets no direct light. The
/// hemisphere method (sh9-ggx turns every normal to the viewer already).
#[test]
fn a_double_sided_back_face_is_lit_with_its_normal_reversed() {
    let s = scene(
        "width = 160\nheight = 96\nmethod = \"hemisphere\"\nenvironment = \"cubemaps/humus_Park2_512\"\n[sun]\ndirection = [0.0, -1.0, 1.0]\n[placement]\nfill = 0.9\n",
    );
    let env = inputs(&s).env;
    let double = previz::scene::model::load_glb_bytes(&two_squares_glb(Some(true))).unwrap();
    let mut unspecified = double.clone();
    unspecified.materials[0].sides = Sides::Unspecified;
    // Mean RGB of each half's fully covered pixels.
    let halves = |model: &Model| {
        let i = Inputs { model: model.clone(), env: env.clone(), env_equirect: None, background: None };
        let (mut c, p) = prepare(gpu(), &s, &i).unwrap();
        let r = c.render(gpu(), &p, Layer::Model).unwrap();
        let half = r.width / 2;
        [0, half].map(|x0| {
            let px: Vec<[u8; 4]> = (0..r.height)
                .flat_map(|y| (x0..x0 + half).map(move |x| (x, y)))
                .map(|(x, y)| common::pixel(&r, x, y))
                .filter(|p| p[3] == 255)
                .collect();
            assert!(px.len() > 100, "{} fully covered pixels", px.len());
            [0, 1, 2].map(|k| px.iter().map(|p| f64::from(p[k])).sum::<f64>() / px.len() as f64)
        })
    };
    let luma = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let [front, back] = halves(&double);
    eprintln!("double-sided: front {front:?}, back {back:?}");
    assert!((luma(front) - luma(back)).abs() < 0.03 * luma(front), "double-sided: front {front:?} vs back {back:?}");
    let [front_u, back_u] = halves(&unspecified);
    eprintln!("unspecified: front {front_u:?}, back {back_u:?}");
    assert_eq!(front_u, front, "the front-facing square does not depend on the material's sides");
    assert!(luma(back_u) < 0.8 * luma(front_u), "not reversed, the back face is lit from behind: {back_u:?} vs {front_u:?}");
}

/// What the model pass rasterises for the benchmarks' two scenes, `bench live`'s truck (the
/// demo scene) and `bench frame`'s dragon (960×640, pisa, coffee.png): per draw order and face
/// culling, fragments shaded per covered pixel from a software raster of the level drawn
/// (`scene::lod::order::overdraw`, the camera's own view; also the lanes of the 2×2 quads and
/// 4×4 blocks those fragments fall in, per triangle), and the model pass's GPU time (each
/// pass timed alone, medians) culling as the frame may against every triangle after a depth
/// pre-pass (what main drew for an open mesh). Run:
/// `cargo test --release --test integration raster:: -- --ignored --nocapture bench_model_raster`.
#[test]
#[ignore = "a benchmark; run it in release with --ignored --nocapture"]
fn bench_model_raster() {
    use previz::scene::lod::order::{Draw, overdraw};
    use previz::setup::scene_file::SceneBuilder;
    let shared = |rel: &str| format!("{}/../shared/data/{rel}", env!("CARGO_MANIFEST_DIR"));
    let demo = SceneBuilder::from_toml(previz::scene::demo::SCENE_TOML, std::path::Path::new(".")).unwrap().build().unwrap();
    let dragon = scene(&format!(
        "model = \"{}\"\nenvironment = \"{}\"\nbackground = \"{}\"\n",
        shared("meshes/stanford-dragon-100k.obj"),
        shared("cubemaps/pisa_ldr_png"),
        shared("photos/colour_transfer/coffee.png")
    ));
    let frames = 15;
    for (name, s, demo_inputs) in [("truck (demo scene)", &demo, true), ("dragon 100k (bench frame)", &dragon, false)] {
        let i = previz::setup::load_inputs(s, demo_inputs).unwrap();
        let aa = previz::render::Antialiasing::for_adapter(&gpu().adapter.get_info());
        let (mut c, p) = previz::setup::prepare_antialiased(gpu(), s, &i, aa).unwrap();
        c.render(gpu(), &p, Layer::Composite).unwrap();
        let level = c.lod_level();
        let fd = c.frame_uniforms(&p).unwrap();
        let clip = glam::Mat4::from_cols_array_2d(&fd.frame.view_proj) * glam::Mat4::from_cols_array_2d(&fd.instance.model);
        let prepared = c.prepared_model().unwrap().clone();
        let meshes: Vec<&previz::scene::Mesh> = i.model.meshes.iter().filter(|m| !m.indices.is_empty()).collect();
        let simplified: Vec<Vec<u32>> = meshes
            .iter()
            .map(|m| {
                let chain = previz::scene::lod::simplify_chain(m);
                chain[level.min(chain.len() - 1)].0.clone()
            })
            .collect();
        let ordered: Vec<Vec<u32>> = prepared
            .chain
            .meshes
            .iter()
            .filter(|l| !l.indices.is_empty())
            .map(|l| {
                let r = l.levels[level.min(l.levels.len() - 1)];
                l.indices[r.first as usize..(r.first + r.count) as usize].to_vec()
            })
            .collect();
        let closed: Vec<bool> = prepared.chain.meshes.iter().filter(|l| !l.indices.is_empty()).map(|l| l.closed[level]).collect();
        let sides: Vec<Sides> = meshes.iter().map(|m| i.model.materials[m.material].sides).collect();
        println!(
            "\n{name}: {}x{}, level {level} ({} triangles), materials {:?}, closed {:?}",
            s.width, s.height, prepared.chain.triangles[level], sides, closed
        );
        println!(
            "| order | faces | fragments shaded / covered | rasterised / covered | 2x2 quad lanes / covered | 4x4 block lanes / covered | covered px |\n|---|---|---:|---:|---:|---:|---:|"
        );
        for (order, indices) in [("as simplified", &simplified), ("draw order", &ordered)] {
            // Main culled closed meshes only; now single-sided materials too. Each mesh drawn
            // without culling has a depth pre-pass.
            for (faces, culled) in [
                ("every triangle, pre-pass", vec![false; meshes.len()]),
                ("closed culled (main)", closed.clone()),
                (
                    "closed and single-sided culled",
                    closed.iter().zip(&sides).map(|(&c, &s)| s == Sides::Front || (s == Sides::Unspecified && c)).collect(),
                ),
            ] {
                let draws: Vec<Draw<'_>> = meshes
                    .iter()
                    .zip(indices)
                    .zip(&culled)
                    .map(|((m, ix), &cull)| Draw { positions: &m.positions, indices: ix, cull, prepass: !cull })
                    .collect();
                let o = overdraw(&draws, clip, (s.width, s.height));
                let per = |n: u64| n as f64 / o.covered as f64;
                println!(
                    "| {order} | {faces} | {:.3} | {:.3} | {:.2} | {:.2} | {} |",
                    per(o.shaded),
                    per(o.rasterised),
                    per(4 * o.quads),
                    per(16 * o.blocks),
                    o.covered
                );
            }
        }
        // The pixels: culling as the frame may against every triangle (main's pixels for an open
        // mesh), written for looking at.
        let mut image = |cull: bool| {
            c.set_culling(cull);
            let r = c.render(gpu(), &p, Layer::Composite).unwrap();
            let rgb: Vec<u8> = r.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
            let path = std::env::temp_dir().join(format!(
                "raster-{}-{}.png",
                name.split(' ').next().unwrap(),
                if cull { "culled" } else { "every" }
            ));
            image::save_buffer(&path, &rgb, r.width, r.height, image::ExtendedColorType::Rgb8).unwrap();
            rgb
        };
        let (culled, every) = (image(true), image(false));
        let differing = culled.iter().zip(&every).filter(|(a, b)| a != b).count();
        let flip = previz::capture::replay::mean_flip(&every, &culled, s.width, s.height).unwrap();
        println!("composite, culled vs every triangle: mean FLIP {flip:.5}, {differing} of {} bytes differ", culled.len());
        // GPU: the model pass alone, interleaving the two ways frame by frame.
        c.set_pass_timing(true);
        let mut ms = [Vec::new(), Vec::new()];
        for k in 0..2 * (frames + 2) {
            c.set_culling(k % 2 == 0);
            let mut q = p;
            q.camera.pose *= glam::Quat::from_rotation_y(1e-4 * k as f32);
            let r = c.render(gpu(), &q, Layer::Composite).unwrap();
            if k >= 4 {
                ms[k % 2].push(r.timings.passes.and_then(|t| t.model).unwrap());
            }
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (culled, every) = (median(&mut ms[0]), median(&mut ms[1]));
        println!(
            "model pass (GPU, median of {frames}): culling as the frame may {culled:.2} ms, every triangle after a pre-pass {every:.2} ms ({:.2}x)",
            culled / every
        );
    }
}
