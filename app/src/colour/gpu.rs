//! Colour correction on the GPU: a full-screen pass applying `colour_correct` to an image
//! (`shaders/colour_correct_pass.wgsl`), timed with the GPU timer.

use super::correction::{COLOUR_CORRECT_WGSL, ColourCorrection};
use crate::gpu::{Gpu, GpuTimer, Readback, build, wgsl};
use crate::scene::Rgba8Image;
use anyhow::{Result, bail};

/// The pass's own WGSL (entry points and bindings); compiled after [`COLOUR_CORRECT_WGSL`].
pub const COLOUR_CORRECT_PASS_WGSL: &str = include_str!("../../../shaders/colour_correct_pass.wgsl");

/// The WGSL of the full-screen pass: the triangle, the shared functions, the pass.
pub fn pass_source() -> String {
    wgsl::with_full_screen(&format!("{COLOUR_CORRECT_WGSL}\n{COLOUR_CORRECT_PASS_WGSL}"))
}

/// The format of the source and the corrected image: sRGB storage, linear maths.
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The full-screen colour-correction pass.
pub struct CorrectPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
}

impl CorrectPass {
    pub fn new(gpu: &Gpu) -> Result<CorrectPass> {
        gpu.checked("the colour-correction pipeline", || {
            let device = &gpu.device;
            let module = build::shader(device, "colour_correct_pass.wgsl", pass_source());
            let fs = wgpu::ShaderStages::FRAGMENT;
            let layout = build::layout(
                device,
                "colour correct",
                &[build::uniform(0, fs), build::texture_entry(1, fs, wgpu::TextureViewDimension::D2, false)],
            );
            let pipeline = build::render_pipeline(device, build::PipelineSpec::full_screen("colour correct", &module, &[&layout], FORMAT));
            let uniform = build::uniform_buffer::<ColourCorrection>(device, "colour correction");
            Ok(CorrectPass { pipeline, layout, uniform })
        })
    }

    /// Correct `image` (sRGB) with `cc` on the GPU `frames` times; returns the corrected image
    /// and, when the device has timestamp queries, the GPU time of each pass in ms.
    pub fn run(&self, gpu: &Gpu, image: &Rgba8Image, cc: &ColourCorrection, frames: u32) -> Result<(Rgba8Image, Option<Vec<f64>>)> {
        let (w, h) = (image.width, image.height);
        if w == 0 || h == 0 || image.pixels.len() != (w * h * 4) as usize {
            bail!("image has no pixels or a wrong buffer size ({w}x{h}, {} bytes)", image.pixels.len());
        }
        gpu.checked("the colour-correction pass", || {
            let device = &gpu.device;
            use wgpu::TextureUsages as U;
            let source = build::texture(device, "source", (w, h, 1), FORMAT, 1, U::TEXTURE_BINDING | U::COPY_DST);
            let target = build::texture(device, "target", (w, h, 1), FORMAT, 1, U::RENDER_ATTACHMENT | U::COPY_SRC);
            build::write_layer(&gpu.queue, &source, 0, &image.pixels);
            gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(cc));
            let source_view = source.create_view(&Default::default());
            let target_view = target.create_view(&Default::default());
            let bind = build::bind_group(
                device,
                "colour correct",
                &self.layout,
                &[self.uniform.as_entire_binding(), wgpu::BindingResource::TextureView(&source_view)],
            );
            let readback = Readback::for_texture(device, "corrected image", &target)?;
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
                    timestamp_writes: timer.as_ref().and_then(|t| t.render_pass(f, true, true)),
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
            readback.copy(&mut encoder, &target);
            gpu.queue.submit([encoder.finish()]);
            let pixels = readback.read(gpu)?;
            let times = match &timer {
                Some(t) => Some(t.read_ms(gpu, frames)?),
                None => None,
            };
            Ok((Rgba8Image { width: w, height: h, pixels }, times))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colour::stats::ColourStats;
    use crate::colour::transfer::{TransferMethod, tests::cloud};
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

    fn gpu() -> &'static Gpu {
        crate::gpu::tests::gpu()
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
        let bytes = crate::gpu::read_buffer(gpu, &readback).unwrap();
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
        for method in std::iter::once(TransferMethod::None).chain(TransferMethod::ALL) {
            for strength in [1.0, 0.4] {
                let cc = ColourCorrection::new(method, strength, &src, &tgt);
                let gpu_out = run_harness(gpu, &cc, &colours);
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
        let cc = ColourCorrection::new(TransferMethod::Reinhard, 0.8, &src, &tgt);
        let (w, h) = (37u32, 5u32);
        let pixels: Vec<u8> = (0..w * h * 4).map(|i| if i % 4 == 3 { 255 } else { ((i * 37) % 256) as u8 }).collect();
        let image = Rgba8Image { width: w, height: h, pixels };
        let (out, times) = CorrectPass::new(gpu).unwrap().run(gpu, &image, &cc, 2).unwrap();
        // One GPU time per pass wherever the device has timestamp queries (lavapipe does).
        assert_eq!(times.is_some(), gpu.timestamps);
        if let Some(t) = times {
            assert!(t.len() == 2 && t.iter().all(|ms| ms.is_finite() && *ms >= 0.0), "{t:?}");
        }
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
