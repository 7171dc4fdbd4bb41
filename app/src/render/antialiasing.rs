//! Antialiasing of the composite: multisampling resolved in the pass, or one sample and a
//! post-process pass (shaders/fxaa.wgsl) — and which one each kind of GPU gets
//! ([`Antialiasing::for_adapter`], the one place that decides).

use super::pipelines::{COLOR_FORMAT, PassPipeline, Pipelines};
use super::shaders::{Technique, source};
use crate::gpu::build;
use wgpu::ShaderStages;

/// How the composite's edges are antialiased.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Antialiasing {
    /// Multisampling with this many samples per pixel (1: none), resolved in the pass.
    Msaa(u32),
    /// One sample per pixel, then the post-process pass of shaders/fxaa.wgsl.
    Fxaa,
}

impl Antialiasing {
    /// Every choice, for the study in `previz bench frame`.
    pub const ALL: [Antialiasing; 4] = [Antialiasing::Msaa(1), Antialiasing::Msaa(2), Antialiasing::Msaa(4), Antialiasing::Fxaa];

    /// A still image (`previz composite`, its layers) drawn one sample a pixel (an output too
    /// large to supersample, render::supersample): 4× MSAA on every adapter — one frame has no
    /// frame budget, and exported layers need the coverage in their alpha. A supersampled still
    /// needs none (render::supersample::antialiasing).
    pub const STILL: Antialiasing = Antialiasing::Msaa(4);

    /// Samples per pixel of the composite's colour and depth targets.
    pub fn samples(self) -> u32 {
        match self {
            Antialiasing::Msaa(n) => n,
            Antialiasing::Fxaa => 1,
        }
    }

    /// Whether `gpu`'s device can draw it: WebGPU guarantees 1 and 4 samples for the colour
    /// format; other counts need the adapter-specific format features (lavapipe has only 1 and
    /// 4 even then).
    pub fn supported(self, gpu: &crate::gpu::Gpu) -> bool {
        let n = self.samples();
        let adapter_specific = gpu.device.features().contains(wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES);
        n == 1 || n == 4 || adapter_specific && gpu.adapter.get_texture_format_features(COLOR_FORMAT).flags.sample_count_supported(n)
    }

    pub fn name(self) -> String {
        match self {
            Antialiasing::Msaa(n) => format!("{n}x MSAA"),
            Antialiasing::Fxaa => "FXAA".into(),
        }
    }

    /// The antialiasing of frames drawn one after another (the live view, the benchmarks) on an
    /// adapter. Tile-based GPUs (the phones': ARM Mali, Qualcomm Adreno, Imagination PowerVR,
    /// Apple) keep the samples in tile memory and resolve them on the way out, so 4× MSAA costs
    /// little there, and desktop GPUs have the bandwidth for it. Software rasterisers
    /// (lavapipe/llvmpipe, SwiftShader, WARP: device type CPU) shade and store every sample:
    /// measured on lavapipe (docs/PERFORMANCE.md, "Antialiasing"), the dragon's frame cost
    /// 10.8× the background-only floor single-sampled, 16.2× with FXAA and 24.3× with 4× MSAA,
    /// for a silhouette FLIP against a 16-sample render of 0.135, 0.126 and 0.113; they draw
    /// one sample. A still image has no frame budget: [`Antialiasing::STILL`].
    pub fn for_adapter(info: &wgpu::AdapterInfo) -> Antialiasing {
        match info.device_type {
            wgpu::DeviceType::Cpu => Antialiasing::Msaa(1),
            _ => Antialiasing::Msaa(4),
        }
    }
}

/// The post-process pipeline: a full-screen triangle sampling the single-sampled frame.
pub fn fxaa_pipeline(device: &wgpu::Device) -> PassPipeline {
    let fs = ShaderStages::FRAGMENT;
    let layout = build::layout(
        device,
        "fxaa",
        &[
            build::texture_entry(0, fs, wgpu::TextureViewDimension::D2, true),
            build::sampler_entry(1, fs, wgpu::SamplerBindingType::Filtering),
        ],
    );
    let module = build::shader(device, "fxaa", source(Technique::Fxaa));
    let pipeline = build::render_pipeline(device, build::PipelineSpec::full_screen("fxaa", &module, &[&layout], COLOR_FORMAT));
    PassPipeline { layout, pipeline }
}

/// The post-process pass of one compositor: its pipeline and the bind group of its input.
pub struct FxaaPass {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
}

impl FxaaPass {
    /// Reads `input`, the single-sampled frame (`Targets::aa_input`).
    pub fn new(device: &wgpu::Device, pipelines: &Pipelines, input: &wgpu::TextureView) -> FxaaPass {
        use wgpu::BindingResource::{Sampler, TextureView};
        let bind_group =
            build::bind_group(device, "fxaa", &pipelines.fxaa.layout, &[TextureView(input), Sampler(&pipelines.linear_sampler)]);
        FxaaPass { pipeline: pipelines.fxaa.pipeline.clone(), bind_group }
    }

    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adapter(device_type: wgpu::DeviceType, vendor: u32, name: &str) -> wgpu::AdapterInfo {
        wgpu::AdapterInfo { name: name.into(), vendor, ..wgpu::AdapterInfo::new(device_type, wgpu::Backend::Vulkan) }
    }

    #[test]
    fn software_rasterisers_draw_one_sample_and_gpus_four() {
        let lavapipe = adapter(wgpu::DeviceType::Cpu, 0x10005, "llvmpipe (LLVM 15.0.6, 256 bits)");
        assert_eq!(Antialiasing::for_adapter(&lavapipe), Antialiasing::Msaa(1));
        let mali = adapter(wgpu::DeviceType::IntegratedGpu, 0x13B5, "Mali-G78");
        assert_eq!(Antialiasing::for_adapter(&mali), Antialiasing::Msaa(4));
        let desktop = adapter(wgpu::DeviceType::DiscreteGpu, 0x10DE, "NVIDIA GeForce");
        assert_eq!(Antialiasing::for_adapter(&desktop), Antialiasing::Msaa(4));
        assert_eq!(Antialiasing::ALL.map(Antialiasing::samples), [1, 2, 4, 1]);
    }
}
