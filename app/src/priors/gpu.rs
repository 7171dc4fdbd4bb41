//! The priors on the GPU: compute-shader reductions (`shaders/priors_reduce.wgsl`) over a cube
//! map, a texture or a camera frame. Same definitions and encodings as the CPU reference
//! ([`ColourStats::from_linear`]); a test checks they agree to 1e-3.
//!
//! Input: 16 bytes per pixel for float cube maps, 4 for 8-bit images. Inputs bigger than one
//! storage binding (`max_storage_buffer_binding_size`, 128 MiB by default: a 6×2048² float cube
//! is 384 MiB) are split into chunks; the per-pixel passes run once per chunk and the finishing
//! passes combine all chunks' partial sums, so the result does not depend on the chunking.

use super::{EnvironmentPriors, ModelPriorSource, ModelPriors, TexelCounts};
use crate::colour::correction::COLOUR_CORRECT_WGSL;
use crate::colour::stats::{ColourStats, LuminanceStats, PERCENTILE_HI, PERCENTILE_LO, percentile_rank};
use crate::gpu::{Gpu, GpuTimer, build, read_buffer};
use crate::scene::{CubeMap, Model, Rgba8Image};
use anyhow::{Result, bail};

/// The reduction's own WGSL; compiled after [`COLOUR_CORRECT_WGSL`].
pub const PRIORS_REDUCE_WGSL: &str = include_str!("../../../shaders/priors_reduce.wgsl");

/// Workgroups per pass, histogram bins per level, floats per partial row, result length, as in
/// the WGSL.
const GROUPS: u64 = 256;
const BINS: u64 = 1024;
const ACC: u64 = 18;
const RESULT_LEN: u64 = 32;
const HIST_WORDS: u64 = 3 * BINS + 8;

/// Luminances below this are histogrammed as this value (log2(0) = −∞). Percentiles below it
/// come back as about this value instead of the exact one (an absolute error under 1e-6).
pub const LUM_FLOOR: f32 = 1e-6;

/// Mirror of the WGSL `struct ReduceParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ReduceParams {
    pub main_begin: u32,
    pub main_end: u32,
    pub up_begin: u32,
    pub up_end: u32,
    pub down_begin: u32,
    pub down_end: u32,
    /// 0: f32 RGB + weight per pixel; 1: RGBA8 sRGB, alpha 0 = skip.
    pub format: u32,
    pub k_lo: u32,
    pub k_hi: u32,
    pub lum_floor: f32,
    /// This chunk's first row of partial sums, and the rows of all chunks.
    pub partial_base: u32,
    pub partial_rows: u32,
}

/// Pixels packed for the GPU.
pub struct GpuInput {
    /// The storage words.
    pub words: Vec<u32>,
    /// 0 or 1, see [`ReduceParams::format`].
    pub format: u32,
    /// Pixel index ranges: main (full statistics), up, down (mean only; empty when unused).
    pub main: std::ops::Range<u32>,
    pub up: std::ops::Range<u32>,
    pub down: std::ops::Range<u32>,
    /// Used pixels in the main region (known while packing; sets the percentile ranks).
    pub main_count: u64,
}

impl GpuInput {
    /// A cube map: horizontal faces, then +Y, then −Y, as f32 with weights (non-finite pixels
    /// get weight 0, negative channels are clamped to 0 — the same as the CPU `sanitize`).
    pub fn from_cube(cube: &CubeMap) -> Result<GpuInput> {
        super::check_cube(cube)?;
        let n = cube.faces[0].len() as u32;
        let mut words = Vec::with_capacity(cube.faces.iter().map(|f| f.len() * 4).sum());
        let mut main_count = 0u64;
        let order = super::HORIZONTAL_FACES.iter().chain([super::UP_FACE, super::DOWN_FACE].iter());
        for (k, &f) in order.enumerate() {
            for p in &cube.faces[f] {
                match crate::colour::stats::sanitize(*p) {
                    Some(c) => {
                        words.extend(c.map(f32::to_bits));
                        words.push(1f32.to_bits());
                        if k < 4 {
                            main_count += 1;
                        }
                    }
                    None => words.extend([0, 0, 0, 0]),
                }
            }
        }
        Ok(GpuInput { words, format: 0, main: 0..4 * n, up: 4 * n..5 * n, down: 5 * n..6 * n, main_count })
    }

    /// An sRGB image (a camera frame): every pixel with alpha > 0 is used.
    pub fn from_image(image: &Rgba8Image) -> Result<GpuInput> {
        let n = image.width as usize * image.height as usize;
        if n == 0 || image.pixels.len() != n * 4 {
            bail!("image is {}x{} with {} bytes: no pixels or wrong size", image.width, image.height, image.pixels.len());
        }
        let words: Vec<u32> = image.pixels.chunks_exact(4).map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]])).collect();
        let main_count = image.pixels.chunks_exact(4).filter(|p| p[3] > 0).count() as u64;
        Ok(GpuInput { words, format: 1, main: 0..n as u32, up: 0..0, down: 0..0, main_count })
    }

    /// A model's textures, texels outside the priors' mask given alpha 0.
    pub fn from_model(model: &Model) -> Result<(GpuInput, TexelCounts)> {
        let mut words = Vec::new();
        let mut counts = TexelCounts::default();
        for (tex, meshes) in super::model_textures(model) {
            let (used, c) = super::texture_mask(tex, &meshes)?;
            super::add_counts(&mut counts, c);
            words.extend(
                tex.pixels.chunks_exact(4).zip(&used).map(|(p, &u)| u32::from_le_bytes([p[0], p[1], p[2], if u { 255 } else { 0 }])),
            );
        }
        let n = words.len() as u32;
        Ok((GpuInput { words, format: 1, main: 0..n, up: 0..0, down: 0..0, main_count: counts.used }, counts))
    }
}

/// What one reduction returns.
pub struct GpuReduction {
    pub main: ColourStats,
    /// Mean linear RGB of the up and down regions (zeros when the region is empty).
    pub up_mean: [f64; 3],
    pub down_mean: [f64; 3],
    /// GPU time of the six passes, ms (None without timestamp queries).
    pub gpu_ms: Option<f64>,
}

/// The compute pipelines and buffers of the reduction; make once, reuse per frame.
pub struct PriorsReducer {
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
    result: wgpu::Buffer,
    hist: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Per chunk: pixel buffer (with its size) and params uniform; grown on demand.
    chunks: Vec<(wgpu::Buffer, u64, wgpu::Buffer)>,
    /// Partial sums for all chunks, with its row capacity.
    partials: Option<(wgpu::Buffer, u64)>,
    timer: Option<GpuTimer>,
    /// Largest chunk in bytes (the device's storage-binding and buffer limits).
    max_chunk_bytes: u64,
}

const ENTRY_POINTS: [&str; 6] = ["first_moments", "finish_first", "second_moments", "finish_second", "fine_histogram", "finish_fine"];

/// The full WGSL of the reduction.
pub fn reduce_source() -> String {
    format!("{COLOUR_CORRECT_WGSL}\n{PRIORS_REDUCE_WGSL}")
}

impl PriorsReducer {
    pub fn new(gpu: &Gpu) -> Result<PriorsReducer> {
        gpu.checked("the priors reduction pipelines", || {
            let device = &gpu.device;
            let module = build::shader(device, "priors_reduce.wgsl", reduce_source());
            let cs = wgpu::ShaderStages::COMPUTE;
            let entries = [
                build::uniform(0, cs),
                build::storage(1, cs, true),
                build::storage(2, cs, false),
                build::storage(3, cs, false),
                build::storage(4, cs, false),
            ];
            let layout = build::layout(device, "priors reduce", &entries);
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("priors reduce"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipelines = ENTRY_POINTS
                .iter()
                .map(|e| {
                    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(e),
                        layout: Some(&pipeline_layout),
                        module: &module,
                        entry_point: Some(e),
                        compilation_options: Default::default(),
                        cache: None,
                    })
                })
                .collect();
            use wgpu::BufferUsages as U;
            let limits = device.limits();
            Ok(PriorsReducer {
                layout,
                pipelines,
                result: build::buffer(device, "reduce result", RESULT_LEN * 4, U::STORAGE | U::COPY_SRC),
                hist: build::buffer(device, "reduce histogram", HIST_WORDS * 4, U::STORAGE | U::COPY_DST | U::COPY_SRC),
                readback: build::buffer(device, "reduce readback", (RESULT_LEN + HIST_WORDS) * 4, U::MAP_READ | U::COPY_DST),
                chunks: Vec::new(),
                partials: None,
                timer: GpuTimer::new(gpu, 1),
                max_chunk_bytes: limits.max_storage_buffer_binding_size.min(limits.max_buffer_size) & !15,
            })
        })
    }

    /// Limit the chunk size (bytes, at least one pixel); for tests of the chunked path.
    pub fn set_max_chunk_bytes(&mut self, bytes: u64) {
        self.max_chunk_bytes = bytes.clamp(16, self.max_chunk_bytes) & !15;
    }

    /// Run the reduction over `input`.
    pub fn reduce(&mut self, gpu: &Gpu, input: &GpuInput) -> Result<GpuReduction> {
        if input.main_count == 0 {
            bail!("no pixels to take statistics of");
        }
        gpu.checked("the priors reduction", || self.reduce_unchecked(gpu, input))
    }

    fn reduce_unchecked(&mut self, gpu: &Gpu, input: &GpuInput) -> Result<GpuReduction> {
        let device = &gpu.device;
        let words_per_pixel: usize = if input.format == 0 { 4 } else { 1 };
        let pixels = input.words.len() / words_per_pixel;
        let chunk_pixels = ((self.max_chunk_bytes / 4) as usize / words_per_pixel).max(1);
        let n_chunks = pixels.div_ceil(chunk_pixels).max(1);
        let rows = GROUPS * n_chunks as u64;
        if self.partials.as_ref().is_none_or(|(_, r)| *r < rows) {
            let buf = build::buffer(device, "reduce partials", rows * ACC * 4, wgpu::BufferUsages::STORAGE);
            self.partials = Some((buf, rows));
        }
        let mut binds = Vec::with_capacity(n_chunks);
        for c in 0..n_chunks {
            let (p0, p1) = (c * chunk_pixels, ((c + 1) * chunk_pixels).min(pixels));
            let words = &input.words[p0 * words_per_pixel..p1 * words_per_pixel];
            let bytes = (words.len() as u64 * 4).max(16);
            if self.chunks.len() <= c {
                let params = build::uniform_buffer::<ReduceParams>(device, "reduce params");
                self.chunks.push((pixel_buffer(device, bytes), bytes, params));
            } else if self.chunks[c].1 < bytes {
                self.chunks[c].0 = pixel_buffer(device, bytes);
                self.chunks[c].1 = bytes;
            }
            let (pixel_buf, _, params_buf) = &self.chunks[c];
            gpu.queue.write_buffer(pixel_buf, 0, bytemuck::cast_slice(words));
            // The regions' ranges relative to this chunk (empty where they do not meet it).
            let local = |r: &std::ops::Range<u32>| {
                let (a, b) = ((r.start as usize).max(p0), (r.end as usize).min(p1));
                if a < b { ((a - p0) as u32, (b - p0) as u32) } else { (0, 0) }
            };
            let ((main_begin, main_end), (up_begin, up_end), (down_begin, down_end)) =
                (local(&input.main), local(&input.up), local(&input.down));
            let params = ReduceParams {
                main_begin,
                main_end,
                up_begin,
                up_end,
                down_begin,
                down_end,
                format: input.format,
                k_lo: percentile_rank(PERCENTILE_LO, input.main_count) as u32,
                k_hi: percentile_rank(PERCENTILE_HI, input.main_count) as u32,
                lum_floor: LUM_FLOOR,
                partial_base: (c as u64 * GROUPS) as u32,
                partial_rows: rows as u32,
            };
            gpu.queue.write_buffer(params_buf, 0, bytemuck::bytes_of(&params));
        }
        let Some((partials, _)) = &self.partials else { bail!("internal: no partials buffer") };
        for (pixel_buf, _, params_buf) in &self.chunks[..n_chunks] {
            // Only the rows this input uses: the buffer may have grown for a larger input.
            let used_partials = wgpu::BufferBinding { buffer: partials, offset: 0, size: wgpu::BufferSize::new(rows * ACC * 4) };
            let resources = [
                params_buf.as_entire_binding(),
                pixel_buf.as_entire_binding(),
                wgpu::BindingResource::Buffer(used_partials),
                self.result.as_entire_binding(),
                self.hist.as_entire_binding(),
            ];
            binds.push(build::bind_group(device, "priors reduce", &self.layout, &resources));
        }
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.hist, 0, None);
        let last = self.pipelines.len() - 1;
        for (i, pipeline) in self.pipelines.iter().enumerate() {
            // One GPU time for the whole reduction: begin of the first pass, end of the last.
            let timestamp_writes = self.timer.as_ref().and_then(|t| t.compute_pass(0, i == 0, i == last));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(ENTRY_POINTS[i]), timestamp_writes });
            pass.set_pipeline(pipeline);
            if i % 2 == 0 {
                // Per-pixel passes: once per chunk.
                for bind in &binds {
                    pass.set_bind_group(0, bind, &[]);
                    pass.dispatch_workgroups(GROUPS as u32, 1, 1);
                }
            } else {
                pass.set_bind_group(0, &binds[0], &[]);
                pass.dispatch_workgroups(1, 1, 1);
            }
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut encoder, 1);
        }
        encoder.copy_buffer_to_buffer(&self.result, 0, &self.readback, 0, RESULT_LEN * 4);
        encoder.copy_buffer_to_buffer(&self.hist, 0, &self.readback, RESULT_LEN * 4, HIST_WORDS * 4);
        gpu.queue.submit([encoder.finish()]);
        let raw = read_buffer(gpu, &self.readback)?;
        let r: &[f32] = bytemuck::cast_slice(&raw[..(RESULT_LEN * 4) as usize]);
        let h: &[u32] = bytemuck::cast_slice(&raw[(RESULT_LEN * 4) as usize..]);
        let histogram_count = u64::from(h[(3 * BINS + 4) as usize]);
        if histogram_count != input.main_count {
            bail!("GPU reduction counted {histogram_count} pixels, expected {}", input.main_count);
        }
        let gpu_ms = match &self.timer {
            Some(t) => t.read_ms(gpu, 1)?.first().copied(),
            None => None,
        };
        Ok(GpuReduction { main: stats_from_result(r, input.main_count), up_mean: triple(r, 11), down_mean: triple(r, 15), gpu_ms })
    }

    /// Environment priors on the GPU.
    pub fn environment(&mut self, gpu: &Gpu, cube: &CubeMap) -> Result<EnvironmentPriors> {
        let input = GpuInput::from_cube(cube)?;
        for (range, name) in [(&input.up, "+Y (up)"), (&input.down, "-Y (down)")] {
            let n = range.len();
            let dead = input.words[range.start as usize * 4..range.end as usize * 4].chunks(4).filter(|p| p[3] == 0).count();
            if dead == n {
                bail!("the {name} face of the cube map has no finite pixels");
            }
        }
        if input.main_count == 0 {
            bail!("the horizontal faces of the cube map have no finite pixels");
        }
        let r = self.reduce(gpu, &input)?;
        Ok(EnvironmentPriors { up_mean: r.up_mean, down_mean: r.down_mean, horizontal: r.main })
    }

    /// Model priors on the GPU (the diffuse-colour fallback of untextured models is computed on
    /// the CPU: a handful of values).
    pub fn model(&mut self, gpu: &Gpu, model: &Model) -> Result<ModelPriors> {
        if model.triangle_count() == 0 || super::model_textures(model).is_empty() {
            return super::model_priors(model);
        }
        let (input, counts) = GpuInput::from_model(model)?;
        if counts.used == 0 {
            return Err(super::no_texels_error(counts));
        }
        let r = self.reduce(gpu, &input)?;
        Ok(ModelPriors { source: ModelPriorSource::Textures, texels: counts, stats: r.main })
    }

    /// Statistics of a camera frame (sRGB; alpha 0 pixels skipped) on the GPU.
    pub fn frame(&mut self, gpu: &Gpu, frame: &Rgba8Image) -> Result<GpuReduction> {
        self.reduce(gpu, &GpuInput::from_image(frame)?)
    }
}

fn pixel_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    build::buffer(device, "reduce pixels", bytes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST)
}

/// Environment priors on the GPU, convenience for one-off use (makes the pipelines each call).
pub fn environment_priors(gpu: &Gpu, cube: &CubeMap) -> Result<EnvironmentPriors> {
    PriorsReducer::new(gpu)?.environment(gpu, cube)
}

fn triple(r: &[f32], at: usize) -> [f64; 3] {
    [f64::from(r[at]), f64::from(r[at + 1]), f64::from(r[at + 2])]
}

fn sym(r: &[f32], at: usize) -> [[f64; 3]; 3] {
    let v = |k: usize| f64::from(r[at + k]);
    [[v(0), v(1), v(2)], [v(1), v(3), v(4)], [v(2), v(4), v(5)]]
}

fn stats_from_result(r: &[f32], count: u64) -> ColourStats {
    ColourStats {
        count,
        rgb_mean: triple(r, 1),
        rgb_cov: sym(r, 18),
        lab_mean: triple(r, 4),
        lab_cov: sym(r, 24),
        luminance: LuminanceStats {
            min: f64::from(r[8]),
            mean: f64::from(r[7]),
            max: f64::from(r[9]),
            p_lo: f64::from(r[30]),
            p_hi: f64::from(r[31]),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priors::tests::{half_quad_model, solid_cube};

    fn gpu() -> &'static Gpu {
        crate::gpu::tests::gpu()
    }

    #[test]
    fn wgsl_validates_and_params_layout_matches_naga() {
        let module = crate::gpu::wgsl::validate(&reduce_source()).unwrap();
        crate::assert_wgsl_layout!(
            module,
            ReduceParams,
            "ReduceParams",
            [main_begin, main_end, up_begin, up_end, down_begin, down_end, format, k_lo, k_hi, lum_floor, partial_base, partial_rows]
        );
    }

    /// |a − b| ≤ 1e-3 · max(1, |b|).
    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-3 * b.abs().max(1.0)
    }

    fn assert_stats_agree(g: &ColourStats, c: &ColourStats) {
        assert_eq!(g.count, c.count);
        for i in 0..3 {
            assert!(close(g.rgb_mean[i], c.rgb_mean[i]), "rgb mean {i}: {} vs {}", g.rgb_mean[i], c.rgb_mean[i]);
            assert!(close(g.lab_mean[i], c.lab_mean[i]), "lab mean {i}: {} vs {}", g.lab_mean[i], c.lab_mean[i]);
            for j in 0..3 {
                assert!(close(g.rgb_cov[i][j], c.rgb_cov[i][j]), "rgb cov {i}{j}: {} vs {}", g.rgb_cov[i][j], c.rgb_cov[i][j]);
                assert!(close(g.lab_cov[i][j], c.lab_cov[i][j]), "lab cov {i}{j}: {} vs {}", g.lab_cov[i][j], c.lab_cov[i][j]);
            }
        }
        let (gl, cl) = (g.luminance, c.luminance);
        for (name, a, b) in [
            ("min", gl.min, cl.min),
            ("mean", gl.mean, cl.mean),
            ("max", gl.max, cl.max),
            ("p_lo", gl.p_lo, cl.p_lo),
            ("p_hi", gl.p_hi, cl.p_hi),
        ] {
            assert!(close(a, b), "luminance {name}: gpu {a} cpu {b}");
        }
    }

    /// A synthetic HDR-ish environment: gradients, a bright "sun" spot, a few black and NaN
    /// pixels, so that min, max and percentiles all differ.
    fn synthetic_cube(size: u32) -> CubeMap {
        let mut cube = solid_cube(size, [[0.0; 3]; 6]);
        for (f, face) in cube.faces.iter_mut().enumerate() {
            for (i, p) in face.iter_mut().enumerate() {
                let (x, y) = ((i as u32 % size) as f32 / size as f32, (i as u32 / size) as f32 / size as f32);
                *p = [0.05 + 0.6 * x * (f as f32 + 1.0) / 6.0, 0.1 + 0.5 * y, 0.2 + 0.3 * ((x * 7.0 + y * 3.0).sin() * 0.5 + 0.5)];
            }
        }
        cube.faces[0][5] = [5000.0, 4800.0, 4000.0];
        cube.faces[1][3] = [0.0; 3];
        cube.faces[4][7] = [f32::NAN, 0.0, 0.0];
        cube.faces[5][9] = [-1.0, 0.5, 0.5];
        cube
    }

    #[test]
    fn gpu_environment_priors_agree_with_cpu() {
        let gpu = gpu();
        let cube = synthetic_cube(48);
        let cpu = crate::priors::environment_priors(&cube).unwrap();
        let g = environment_priors(gpu, &cube).unwrap();
        assert_stats_agree(&g.horizontal, &cpu.horizontal);
        for i in 0..3 {
            assert!(close(g.up_mean[i], cpu.up_mean[i]) && close(g.down_mean[i], cpu.down_mean[i]));
        }
        // The same input split into 19984-byte chunks (1249 pixels: not aligned with the faces).
        let mut chunked = PriorsReducer::new(gpu).unwrap();
        chunked.set_max_chunk_bytes(20_000);
        let c = chunked.environment(gpu, &cube).unwrap();
        assert_stats_agree(&c.horizontal, &cpu.horizontal);
        for i in 0..3 {
            assert!(close(c.up_mean[i], cpu.up_mean[i]) && close(c.down_mean[i], cpu.down_mean[i]));
        }
    }

    #[test]
    fn gpu_model_and_frame_priors_agree_with_cpu() {
        let gpu = gpu();
        let mut reducer = PriorsReducer::new(gpu).unwrap();
        let (w, h) = (40u32, 30u32);
        let pixels: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                if x == 3 && y == 4 {
                    [0, 255, 0, 255]
                } else {
                    [(x * 6) as u8, (y * 8) as u8, ((x * y) % 256) as u8, if x == 5 { 0 } else { 255 }]
                }
            })
            .collect();
        let tex = Rgba8Image { width: w, height: h, pixels };
        let model = half_quad_model(tex.clone());
        let cpu = crate::priors::model_priors(&model).unwrap();
        let g = reducer.model(gpu, &model).unwrap();
        assert_eq!(g.texels, cpu.texels);
        assert_stats_agree(&g.stats, &cpu.stats);
        // A frame: all pixels with alpha > 0, green included.
        let lut = crate::colour::stats::srgb8_to_linear_table();
        let lin: Vec<[f32; 3]> =
            tex.pixels.chunks(4).filter(|p| p[3] > 0).map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]).collect();
        let cpu = ColourStats::from_linear(&lin).unwrap();
        let g = reducer.frame(gpu, &tex).unwrap();
        assert_stats_agree(&g.main, &cpu);
        // Chunked: 1000 pixels of 1200 per chunk.
        reducer.set_max_chunk_bytes(4000);
        let g = reducer.frame(gpu, &tex).unwrap();
        assert_stats_agree(&g.main, &cpu);
    }

    #[test]
    fn gpu_flat_input_and_errors() {
        let gpu = gpu();
        let cube = solid_cube(8, [[0.3, 0.3, 0.3]; 6]);
        let g = environment_priors(gpu, &cube).unwrap();
        let cpu = crate::priors::environment_priors(&cube).unwrap();
        assert_stats_agree(&g.horizontal, &cpu.horizontal);
        let mut reducer = PriorsReducer::new(gpu).unwrap();
        let transparent = Rgba8Image { width: 2, height: 2, pixels: vec![0; 16] };
        assert!(reducer.frame(gpu, &transparent).is_err());
        let empty = Rgba8Image { width: 0, height: 0, pixels: vec![] };
        assert!(reducer.frame(gpu, &empty).is_err());
    }

    #[test]
    fn gpu_priors_of_a_real_model_and_cube_map_agree_with_cpu() {
        let gpu = gpu();
        let mut reducer = PriorsReducer::new(gpu).unwrap();
        let spot = crate::priors::tests::spot();
        let (g, c) = (reducer.model(gpu, &spot).unwrap(), crate::priors::model_priors(&spot).unwrap());
        assert_eq!(g.texels, c.texels);
        assert_stats_agree(&g.stats, &c.stats);
        let env = crate::scene::environment::load_environment(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/cubemaps/humus_Park2_512"
        )))
        .unwrap();
        let (g, c) = (reducer.environment(gpu, &env).unwrap(), crate::priors::environment_priors(&env).unwrap());
        assert_stats_agree(&g.horizontal, &c.horizontal);
        for i in 0..3 {
            assert!(close(g.up_mean[i], c.up_mean[i]) && close(g.down_mean[i], c.down_mean[i]));
        }
    }
}
