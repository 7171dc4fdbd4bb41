//! The background pass (step 3 of DESIGN.md "One frame"): the camera image (or a photograph) fills
//! the target. Without one, the environment seen by the camera is first rendered into the
//! background texture (the environment-view pass), so every later pass reads one background.
//! An environment loaded from an equirectangular image is seen in that image, looked up
//! directly (shaders/env_view_equirect.wgsl); six cube faces are seen in the cube map.

use crate::gpu::{Gpu, build};
use crate::render::pipelines::{COLOR_FORMAT, PassPipeline, PipelineSpec, Pipelines, pipeline as make, screen_pipeline};
use crate::render::shaders::Technique;
use crate::scene::Rgba8Image;
use crate::scene::environment::Equirect;
use anyhow::{Result, anyhow, bail};
use wgpu::SamplerBindingType::Filtering;
use wgpu::ShaderStages;
use wgpu::TextureViewDimension::{Cube, D2};

/// The environment-view pipeline: a full-screen triangle sampling the cube map into the
/// single-sampled background texture.
pub fn env_view_pipeline(device: &wgpu::Device) -> PassPipeline {
    environment_view(device, "env_view", Technique::EnvView, Cube)
}

/// Lookups per pixel of the equirectangular environment view, per axis
/// (shaders/env_view_equirect.wgsl `ENV_VIEW_TAPS`): 2 × 2 spread evenly over the pixel, a box
/// filter like the path-traced references' pixels. Measured against their bare environment
/// renders (docs/accuracy.md): one lookup at the pixel's centre is a sharper image than the
/// references' (mean FLIP 0.0139 against 0.0124 on quarry_bunny), 4 × 4 gains 0.0003 more.
pub const ENV_VIEW_TAPS: u32 = 2;

/// The equirectangular environment-view pipeline: a full-screen triangle looking the map up
/// into the single-sampled background texture.
pub fn env_view_equirect_pipeline(device: &wgpu::Device) -> PassPipeline {
    environment_view(device, "env_view_equirect", Technique::EnvViewEquirect, D2)
}

/// A full-screen triangle drawing `technique`'s view of an environment texture of `dimension`
/// (frame uniform, texture, sampler) into the single-sampled background texture.
fn environment_view(device: &wgpu::Device, label: &str, technique: Technique, dimension: wgpu::TextureViewDimension) -> PassPipeline {
    let fs = ShaderStages::FRAGMENT;
    let entries = [
        build::uniform(0, ShaderStages::VERTEX | fs),
        build::texture_entry(1, fs, dimension, true),
        build::sampler_entry(2, fs, Filtering),
    ];
    let layout = build::layout(device, label, &entries);
    let spec = PipelineSpec { technique, layouts: &[&layout], vertex_buffers: &[], depth: None, samples: 1, blend: Some(None) };
    let pipeline = make(device, spec);
    PassPipeline { layout, pipeline }
}

/// The background pipeline: a full-screen triangle into the composite target (`samples` per
/// pixel), each pixel loading its texel of the background texture (the target's size: no
/// sampler).
pub fn pipeline(device: &wgpu::Device, samples: u32) -> PassPipeline {
    let layout = build::layout(device, "background", &[build::texture_entry(0, ShaderStages::FRAGMENT, D2, true)]);
    let pipeline = pipeline_for(device, &layout, COLOR_FORMAT, samples);
    PassPipeline { layout, pipeline }
}

/// The background pipeline with bind-group `layout`, drawing into `format` targets of
/// `samples` per pixel.
pub fn pipeline_for(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
    samples: u32,
) -> wgpu::RenderPipeline {
    screen_pipeline(device, (Technique::Background, layout), (format, samples), None)
}

pub struct BackgroundPass {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    env_view_pipeline: wgpu::RenderPipeline,
    /// The environment-view bind group, once there is an environment.
    env_view_bind_group: Option<wgpu::BindGroup>,
    env_view_equirect_pipeline: wgpu::RenderPipeline,
    /// The equirectangular map the environment was loaded from (Rgba16Float, linear light before
    /// exposure) and its environment-view bind group; kept while a map of the same size follows.
    equirect: Option<(wgpu::Texture, wgpu::BindGroup)>,
    /// True: the environment view looks `equirect` up; false: the cube map.
    equirect_on: bool,
    /// True: the background is the environment seen by the camera; false: an uploaded image.
    from_env: bool,
    /// Samples per side of each output pixel (render::supersample): the texture is this many
    /// times the output's size, an image of the output's size is set with each pixel repeated.
    supersample: u32,
}

impl BackgroundPass {
    /// The background of a `width`×`height` output drawn at `supersample` × its size (its
    /// texture that size), drawn from the environment until an image is set.
    pub fn new(device: &wgpu::Device, pipelines: &Pipelines, (width, height): (u32, u32), supersample: u32) -> BackgroundPass {
        let supersample = supersample.max(1);
        let (width, height) = (width * supersample, height * supersample);
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let texture = build::texture(device, "background", (width, height, 1), COLOR_FORMAT, 1, usage);
        let view = texture.create_view(&Default::default());
        let bind_group =
            build::bind_group(device, "background", &pipelines.background.layout, &[wgpu::BindingResource::TextureView(&view)]);
        BackgroundPass {
            pipeline: pipelines.background.pipeline.clone(),
            bind_group,
            texture,
            view,
            env_view_pipeline: pipelines.env_view.pipeline.clone(),
            env_view_bind_group: None,
            env_view_equirect_pipeline: pipelines.env_view_equirect.pipeline.clone(),
            equirect: None,
            equirect_on: false,
            from_env: true,
            supersample,
        }
    }

    /// The background texture (the model pass samples it for the live methods).
    pub fn view(&self) -> &wgpu::TextureView {
        &self.view
    }

    /// The environment-view bind group for a new environment cube map (`frame`: the Frame
    /// uniform buffer).
    pub fn env_view_bind_group(
        device: &wgpu::Device,
        pipelines: &Pipelines,
        frame: &wgpu::Buffer,
        cube: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        build::bind_group(
            device,
            "env view",
            &pipelines.env_view.layout,
            &[
                frame.as_entire_binding(),
                wgpu::BindingResource::TextureView(cube),
                wgpu::BindingResource::Sampler(&pipelines.linear_sampler),
            ],
        )
    }

    pub fn set_env_view_bind_group(&mut self, bind_group: wgpu::BindGroup) {
        self.env_view_bind_group = Some(bind_group);
    }

    /// See the environment in the cube map (a new cube map was set: an equirectangular map set
    /// before may not be its source).
    pub fn use_cube(&mut self) {
        self.equirect_on = false;
    }

    /// See the environment in `map`, the equirectangular image the cube map was made from
    /// (`frame`: the Frame uniform buffer, whose heading and exposure apply), or in the cube map
    /// for `None`. A map of the size already held is written into its texture (nothing
    /// allocated); a map wider or taller than the device's 2D textures keeps the cube map.
    pub fn set_equirect(&mut self, gpu: &Gpu, pipelines: &Pipelines, frame: &wgpu::Buffer, map: Option<&Equirect>) -> Result<()> {
        let Some(map) = map else {
            self.equirect_on = false;
            return Ok(());
        };
        let max = gpu.device.limits().max_texture_dimension_2d;
        if map.width() > max || map.height() > max {
            self.equirect_on = false;
            return Ok(());
        }
        let texels = crate::render::environment::rgba16f_texels(map.pixels());
        gpu.checked("the equirectangular environment", || {
            let reuse = self.equirect.as_ref().is_some_and(|(t, _)| (t.width(), t.height()) == (map.width(), map.height()));
            if !reuse {
                let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
                let size = (map.width(), map.height(), 1);
                let texture = build::texture(&gpu.device, "equirect environment", size, wgpu::TextureFormat::Rgba16Float, 1, usage);
                let view = texture.create_view(&Default::default());
                let bind_group = build::bind_group(
                    &gpu.device,
                    "env view equirect",
                    &pipelines.env_view_equirect.layout,
                    &[
                        frame.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&view),
                        wgpu::BindingResource::Sampler(&pipelines.equirect_sampler),
                    ],
                );
                self.equirect = Some((texture, bind_group));
            }
            if let Some((texture, _)) = &self.equirect {
                build::write_layer(&gpu.queue, texture, 0, bytemuck::cast_slice(&texels));
            }
            Ok(())
        })?;
        self.equirect_on = true;
        Ok(())
    }

    /// Whether the environment view looks an equirectangular map up (rather than the cube map).
    pub fn sees_equirect(&self) -> bool {
        self.equirect_on
    }

    /// Use `image` (already the output's size) as the background, or `None` for the
    /// environment seen by the camera. An image is one `write_texture` (each pixel repeated
    /// over its samples when the output is supersampled: they average back to it).
    pub fn set_image(&mut self, gpu: &Gpu, image: Option<&Rgba8Image>) -> Result<()> {
        let Some(img) = image else {
            self.from_env = true;
            return Ok(());
        };
        let k = self.supersample;
        let (width, height) = (self.texture.width() / k, self.texture.height() / k);
        if (img.width, img.height) != (width, height) {
            bail!("background is {}x{}, the output is {width}x{height}", img.width, img.height);
        }
        if img.pixels.len() != (4 * img.width * img.height) as usize {
            bail!("background pixel buffer has the wrong length");
        }
        let repeated;
        let pixels = match k {
            1 => &img.pixels,
            _ => {
                repeated = crate::render::supersample::repeat_pixels(&img.pixels, (img.width, img.height), k);
                &repeated
            }
        };
        gpu.checked("the background image", || {
            build::write_layer(&gpu.queue, &self.texture, 0, pixels);
            Ok(())
        })?;
        self.from_env = false;
        Ok(())
    }

    /// Use the image in `source` (already the background's size, `Rgba8Unorm` or
    /// `Rgba8UnormSrgb` holding sRGB-encoded bytes, e.g. the camera's YUV converted on the GPU)
    /// as the background: one texture-to-texture copy on the GPU.
    pub fn copy_image(&mut self, gpu: &Gpu, source: &wgpu::Texture) -> Result<()> {
        let (width, height) = (self.texture.width(), self.texture.height());
        if (source.width(), source.height()) != (width, height) {
            bail!("background is {}x{}, the output is {width}x{height}", source.width(), source.height());
        }
        if source.format().remove_srgb_suffix() != self.texture.format().remove_srgb_suffix() {
            bail!("background texture is {:?}, expected {:?} bytes", source.format(), self.texture.format());
        }
        gpu.checked("the background copy", || {
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("background copy") });
            encoder.copy_texture_to_texture(source.as_image_copy(), self.texture.as_image_copy(), source.size());
            gpu.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        self.from_env = false;
        Ok(())
    }

    /// Whether the background is the environment seen by the camera (drawn by the
    /// environment-view pass each frame) rather than an uploaded image.
    pub fn from_env(&self) -> bool {
        self.from_env
    }

    /// Begin the environment-view pass into the background texture.
    pub fn begin_env_view<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> wgpu::RenderPass<'e> {
        build::clear_pass(encoder, "environment view", &self.view, timestamps)
    }

    /// 3a. The environment seen by the camera.
    pub fn draw_env_view(&self, pass: &mut wgpu::RenderPass<'_>) -> Result<()> {
        let (pipeline, bind_group) = match &self.equirect {
            Some((_, bind_group)) if self.equirect_on => (&self.env_view_equirect_pipeline, bind_group),
            _ => (&self.env_view_pipeline, self.env_view_bind_group.as_ref().ok_or_else(|| anyhow!("no environment set"))?),
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..3, 0..1);
        Ok(())
    }

    /// 3b. The background fills the composite target.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.draw_with(pass, &self.pipeline);
    }

    /// Draw with `pipeline`: this pass's, or its float twin (render/layers.rs).
    pub fn draw_with(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
