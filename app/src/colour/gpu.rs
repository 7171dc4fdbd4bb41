//! Colour correction on the GPU: a full-screen pass applying `colour_correct` to an image
//! (`shaders/colour_correct_pass.wgsl`), GPU timing with timestamp queries, and buffer readback
//! helpers shared with the priors reduction.

use super::correction::{COLOUR_CORRECT_WGSL, ColourCorrection};
use crate::render::gpu::Gpu;
use crate::scene::Rgba8Image;
use anyhow::{Context, Result, anyhow, bail};

/// The pass's own WGSL (entry points and bindings); compiled after [`COLOUR_CORRECT_WGSL`].
pub const COLOUR_CORRECT_PASS_WGSL: &str = include_str!("../../../shaders/colour_correct_pass.wgsl");

/// The WGSL of the full-screen pass: the shared functions followed by the pass.
pub fn pass_source() -> String {
    format!("{COLOUR_CORRECT_WGSL}\n{COLOUR_CORRECT_PASS_WGSL}")
}

/// Read a whole `MAP_READ` buffer back to the CPU (blocks until the GPU is done).
pub fn read_buffer(gpu: &Gpu, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("waiting for the GPU failed: {e}"))?;
    rx.recv().context("the GPU dropped a buffer mapping")?.map_err(|e| anyhow!("cannot map a GPU buffer for reading: {e}"))?;
    let data = slice.get_mapped_range().map_err(|e| anyhow!("cannot read a mapped GPU buffer: {e}"))?.to_vec();
    buffer.unmap();
    Ok(data)
}

/// Pairs of GPU timestamps (begin, end) for up to `capacity` passes.
pub struct GpuTimer {
    query_set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    capacity: u32,
}

impl GpuTimer {
    /// `None` when the device has no timestamp queries.
    pub fn new(gpu: &Gpu, capacity: u32) -> Option<GpuTimer> {
        if !gpu.timestamps || capacity == 0 {
            return None;
        }
        let count = capacity * 2;
        let query_set =
            gpu.device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("timer"), ty: wgpu::QueryType::Timestamp, count });
        let size = u64::from(count) * 8;
        let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timer resolve"),
            size,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timer readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Some(GpuTimer { query_set, resolve, readback, capacity })
    }

    /// Timestamp writes for a compute pass numbered `slot`.
    pub fn compute_writes(&self, slot: u32) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        (slot < self.capacity).then(|| wgpu::ComputePassTimestampWrites {
            query_set: &self.query_set,
            beginning_of_pass_write_index: Some(slot * 2),
            end_of_pass_write_index: Some(slot * 2 + 1),
        })
    }

    /// Timestamp writes for a render pass numbered `slot`.
    pub fn render_writes(&self, slot: u32) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        (slot < self.capacity).then(|| wgpu::RenderPassTimestampWrites {
            query_set: &self.query_set,
            beginning_of_pass_write_index: Some(slot * 2),
            end_of_pass_write_index: Some(slot * 2 + 1),
        })
    }

    /// Record the resolve of the first `used` slots (call after the passes, before submit).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder, used: u32) {
        let used = used.min(self.capacity);
        if used > 0 {
            encoder.resolve_query_set(&self.query_set, 0..used * 2, &self.resolve, 0);
            encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, u64::from(used) * 16);
        }
    }

    /// Milliseconds of each of the first `used` slots (after the submission completed).
    pub fn read_ms(&self, gpu: &Gpu, used: u32) -> Result<Vec<f64>> {
        let bytes = read_buffer(gpu, &self.readback)?;
        let ticks: &[u64] = bytemuck::cast_slice(&bytes);
        let period = f64::from(gpu.queue.get_timestamp_period());
        Ok((0..used.min(self.capacity) as usize).map(|i| ticks[2 * i + 1].saturating_sub(ticks[2 * i]) as f64 * period * 1e-6).collect())
    }
}

/// The full-screen colour-correction pass.
pub struct CorrectPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
}

/// Row pitch of a texture readback (wgpu needs multiples of 256 bytes).
fn padded_row(width: u32) -> u32 {
    (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

impl CorrectPass {
    pub fn new(gpu: &Gpu) -> CorrectPass {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("colour_correct_pass.wgsl"),
            source: wgpu::ShaderSource::Wgsl(pass_source().into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("colour correct"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("colour correct"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("colour correct"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: wgpu::TextureFormat::Rgba8UnormSrgb,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("colour correction"),
            size: std::mem::size_of::<ColourCorrection>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        CorrectPass { pipeline, layout, uniform }
    }

    /// Correct `image` (sRGB) with `cc` on the GPU `frames` times; returns the corrected image
    /// and, when the device has timestamp queries, the GPU time of each pass in ms.
    pub fn run(&self, gpu: &Gpu, image: &Rgba8Image, cc: &ColourCorrection, frames: u32) -> Result<(Rgba8Image, Option<Vec<f64>>)> {
        let (w, h) = (image.width, image.height);
        if w == 0 || h == 0 || image.pixels.len() != (w * h * 4) as usize {
            bail!("image has no pixels or a wrong buffer size ({w}x{h}, {} bytes)", image.pixels.len());
        }
        let device = &gpu.device;
        let extent = wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 };
        let make = |label, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8UnormSrgb,
                usage,
                view_formats: &[],
            })
        };
        let source = make("source", wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST);
        let target = make("target", wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo { texture: &source, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            &image.pixels,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 4), rows_per_image: Some(h) },
            extent,
        );
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(cc));
        let source_view = source.create_view(&Default::default());
        let target_view = target.create_view(&Default::default());
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("colour correct"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&source_view) },
            ],
        });
        let row = padded_row(w);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("corrected image"),
            size: u64::from(row) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let frames = frames.max(1);
        let timer = GpuTimer::new(gpu, frames);
        let mut encoder = device.create_command_encoder(&Default::default());
        for f in 0..frames {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("colour correct"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: timer.as_ref().and_then(|t| t.render_writes(f)),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..3, 0..1);
        }
        if let Some(t) = &timer {
            t.resolve(&mut encoder, frames);
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo { texture: &target, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(h) },
            },
            extent,
        );
        gpu.queue.submit([encoder.finish()]);
        let bytes = read_buffer(gpu, &readback)?;
        let mut pixels = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h as usize {
            let start = y * row as usize;
            pixels.extend_from_slice(&bytes[start..start + (w * 4) as usize]);
        }
        let times = match &timer {
            Some(t) => Some(t.read_ms(gpu, frames)?),
            None => None,
        };
        Ok((Rgba8Image { width: w, height: h, pixels }, times))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colour::stats::ColourStats;
    use crate::colour::transfer::{Method, tests::cloud};
    use glam::Vec3;

    /// A compute harness: `outputs[i] = colour_correct(inputs[i], cc)`.
    const HARNESS: &str = r#"
@group(0) @binding(0) var<uniform> cc: ColourCorrection;
@group(0) @binding(1) var<storage, read> inputs: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> outputs: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < arrayLength(&inputs)) {
        outputs[id.x] = vec4<f32>(colour_correct(inputs[id.x].xyz, cc), 1.0);
    }
}
"#;

    fn gpu() -> Gpu {
        std::fs::create_dir_all("/tmp/xdg").ok();
        Gpu::headless().unwrap()
    }

    fn run_harness(gpu: &Gpu, cc: &ColourCorrection, colours: &[Vec3]) -> Vec<Vec3> {
        use wgpu::util::DeviceExt;
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("harness"),
            source: wgpu::ShaderSource::Wgsl(format!("{COLOUR_CORRECT_WGSL}\n{HARNESS}").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: None,
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let input: Vec<[f32; 4]> = colours.iter().map(|c| c.extend(0.0).to_array()).collect();
        let size = (input.len() * 16) as u64;
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::bytes_of(cc),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let inputs = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&input),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let outputs = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: inputs.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: outputs.as_entire_binding() },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((colours.len() as u32).div_ceil(64), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&outputs, 0, &readback, 0, size);
        gpu.queue.submit([encoder.finish()]);
        let bytes = read_buffer(gpu, &readback).unwrap();
        bytemuck::cast_slice::<u8, [f32; 4]>(&bytes).iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect()
    }

    fn test_colours() -> Vec<Vec3> {
        let mut c =
            vec![Vec3::ZERO, Vec3::ONE, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0), Vec3::splat(3.5)];
        c.extend(cloud(58, [0.5, 0.5, 0.5], [1.0, 1.0, 1.0], 0.3).into_iter().map(Vec3::from_array));
        c
    }

    #[test]
    fn wgsl_colour_correct_matches_cpu_reference() {
        let gpu = gpu();
        let src = ColourStats::from_linear(&cloud(800, [0.25, 0.3, 0.5], [0.4, 0.4, 0.5], -0.2)).unwrap();
        let tgt = ColourStats::from_linear(&cloud(800, [0.6, 0.4, 0.2], [0.5, 0.4, 0.3], 0.4)).unwrap();
        let colours = test_colours();
        for method in [Method::None, Method::BrightnessContrast, Method::Reinhard, Method::CielabApprox, Method::Mkl] {
            for strength in [1.0, 0.4] {
                let cc = ColourCorrection::new(method, strength, &src, &tgt);
                let gpu_out = run_harness(&gpu, &cc, &colours);
                for (c, g) in colours.iter().zip(gpu_out) {
                    let cpu = crate::colour::correction::correct(*c, &cc);
                    let tol = 1e-4 * cpu.max_element().max(1.0);
                    assert!((cpu - g).abs().max_element() <= tol, "{method:?} s={strength} {c}: cpu {cpu} gpu {g}");
                }
            }
        }
    }

    #[test]
    fn full_screen_pass_matches_cpu_within_8_bit_rounding() {
        let gpu = gpu();
        let src = ColourStats::from_linear(&cloud(800, [0.25, 0.3, 0.5], [0.4, 0.4, 0.5], -0.2)).unwrap();
        let tgt = ColourStats::from_linear(&cloud(800, [0.6, 0.4, 0.2], [0.5, 0.4, 0.3], 0.4)).unwrap();
        let cc = ColourCorrection::new(Method::Reinhard, 0.8, &src, &tgt);
        let (w, h) = (37u32, 5u32);
        let pixels: Vec<u8> = (0..w * h * 4).map(|i| if i % 4 == 3 { 255 } else { ((i * 37) % 256) as u8 }).collect();
        let image = Rgba8Image { width: w, height: h, pixels };
        let (out, times) = CorrectPass::new(&gpu).run(&gpu, &image, &cc, 2).unwrap();
        assert_eq!(times.map(|t| t.len()).unwrap_or(2), 2);
        let lut = crate::colour::stats::srgb8_to_linear_table();
        for (i, (a, b)) in image.pixels.chunks(4).zip(out.pixels.chunks(4)).enumerate() {
            let lin = Vec3::new(lut[a[0] as usize], lut[a[1] as usize], lut[a[2] as usize]);
            let cpu = crate::colour::correction::correct(lin, &cc);
            for ch in 0..3 {
                let expect = (crate::colour::linear_to_srgb(cpu[ch]) * 255.0).round();
                assert!((expect - b[ch] as f32).abs() <= 1.0, "pixel {i} ch {ch}: {expect} vs {}", b[ch]);
            }
            assert_eq!(b[3], 255);
        }
    }
}
