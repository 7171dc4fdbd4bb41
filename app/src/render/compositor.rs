//! The compositor: GPU resources for one output size and the passes of one frame.
//!
//! Everything is created once (`Compositor::new`, `set_environment`, `set_model`,
//! `set_background`); a frame only writes uniforms (and the camera image) and encodes passes,
//! so per-frame work allocates no GPU resources.

use super::Method;
use super::pipelines::{COLOR_FORMAT, DEPTH_FORMAT, Pipelines, SAMPLES, SHADOW_MAP_SIZE, Vertex};
use super::uniforms::{FrameUniforms, InstanceUniforms, MaterialUniforms};
use super::view::{self, Placement};
use crate::colour::correction::ColourCorrection;
use crate::colour::stats::ColourStats;
use crate::colour::transfer::Method as ColourMethod;
use crate::gpu::{Gpu, GpuTimer, Readback, build};
use crate::priors::{self, EnvironmentPriors};
use crate::scene::{CubeMap, Model, Rgba8Image};
use anyhow::{Context, Result, anyhow, bail};
use glam::{Mat4, Quat, Vec3};
use std::time::Instant;

/// What the hemisphere methods need from the environment (seed 000 §5.4), in linear light after
/// exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemispherePriors {
    /// Mean colour of the up (+Y, sky) face.
    pub sky: [f32; 3],
    /// Mean colour of the down (−Y, ground) face.
    pub ground: [f32; 3],
    /// Hemisphere-occlusion light level: the bright end of the horizontal faces' luminance.
    pub light: f32,
    /// Hemisphere-occlusion shadow level: the dark end of the horizontal faces' luminance.
    pub shadow: f32,
}

impl HemispherePriors {
    /// From the environment priors (after exposure): sky/ground = mean colour of the +Y/−Y faces;
    /// occlusion light/shadow = 99th/1st percentile of BT.709 luminance over the four horizontal
    /// faces (robust against one bright pixel, unlike the seed's single-pixel max/min).
    pub fn from_environment(p: &EnvironmentPriors) -> HemispherePriors {
        let rgb = |v: [f64; 3]| v.map(|c| c as f32);
        HemispherePriors {
            sky: rgb(p.up_mean),
            ground: rgb(p.down_mean),
            light: p.horizontal.luminance.p_hi as f32,
            shadow: p.horizontal.luminance.p_lo as f32,
        }
    }
}

/// Colour correction of the model towards the environment (seed §5.6): which method, how much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourSettings {
    pub method: ColourMethod,
    /// 0..1 (the seed's CC slider).
    pub strength: f32,
}

impl ColourSettings {
    pub const NONE: ColourSettings = ColourSettings { method: ColourMethod::None, strength: 0.0 };
}

/// The Blinn-Phong material terms of Eq. 3 (scalars; colour comes from the material/texture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialTerms {
    /// a_c
    pub ambient: f32,
    /// d_c
    pub diffuse: f32,
    /// s_c
    pub specular: f32,
    /// g_f; `None` keeps each material's own exponent (MTL `Ns`).
    pub gloss: Option<f32>,
}

/// The lights and effect strengths of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Unit direction to the sun, world (ENU).
    pub sun_dir: Vec3,
    /// Sunlight intensity l_s (already faded through twilight by the caller).
    pub sunlight: f32,
    /// Daylight (ambient) intensity l_d.
    pub daylight: f32,
    pub material: MaterialTerms,
    /// Mix of the reflection into the model, 0..1 (reflection methods).
    pub reflection: f32,
    /// Refractive index of the model's material (refraction methods); eta = 1 / ior.
    pub ior: f32,
    /// How dark the model's shadow makes the ground, 0..1.
    pub shadow_opacity: f32,
    /// Live-feed refraction: how far behind the surface (metres) the refracted ray meets the scene.
    pub live_depth: f32,
}

/// The camera of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Orientation, camera → world.
    pub pose: Quat,
    /// Position in world (ENU), metres.
    pub position: Vec3,
    /// Vertical field of view, radians.
    pub vfov: f32,
}

/// Everything that may change from frame to frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameParams {
    pub camera: Camera,
    pub method: Method,
    pub lighting: Lighting,
    pub placement: Placement,
    pub colour: ColourSettings,
}

/// The uniform values of one frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameData {
    pub frame: FrameUniforms,
    pub instance: InstanceUniforms,
    pub ground: InstanceUniforms,
    pub colour: ColourCorrection,
}

/// Which image a render produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// Background, ground shadow and model.
    Composite,
    /// The model alone over transparent black: premultiplied RGBA, alpha = coverage.
    Model,
    /// The background alone.
    Background,
}

/// Milliseconds spent in each stage of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// CPU: writing uniforms and encoding the passes.
    pub encode_ms: f64,
    /// GPU: first pass start to last pass end (timestamp queries); None if unsupported.
    pub gpu_ms: Option<f64>,
    /// CPU wall time from submit until the pixels are in memory.
    pub readback_ms: f64,
}

/// A rendered RGBA8 image (sRGB-encoded; the model layer is premultiplied in linear light).
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    pub timings: Timings,
}

struct MeshGpu {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    material: wgpu::BindGroup,
}

struct ModelGpu {
    meshes: Vec<MeshGpu>,
    bounds: (Vec3, Vec3),
    /// Per-material gloss exponents, in mesh order, for `MaterialTerms::gloss == None`.
    materials: Vec<(wgpu::Buffer, MaterialUniforms)>,
    /// Colour statistics of the model's texture (or diffuse colours), the correction's target;
    /// the reason when there are none (every texel masked out).
    colour: std::result::Result<ColourStats, String>,
}

struct EnvGpu {
    priors: HemispherePriors,
    /// Colour statistics of the horizontal faces after exposure, the correction's source.
    colour: ColourStats,
    exposure: f32,
    /// World heading (radians, clockwise from North) of the cube map's front (+Z) face.
    heading: f32,
}

/// GPU state for compositing at one output size.
pub struct Compositor {
    pipelines: std::sync::Arc<Pipelines>,
    width: u32,
    height: u32,
    frame_buf: wgpu::Buffer,
    instance_buf: wgpu::Buffer,
    ground_buf: wgpu::Buffer,
    colour_buf: wgpu::Buffer,
    shadow_view: wgpu::TextureView,
    shadow_size: u32,
    msaa_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    resolve: wgpu::Texture,
    resolve_view: wgpu::TextureView,
    encoded_view: wgpu::TextureView,
    readback: Readback,
    background: wgpu::Texture,
    background_view: wgpu::TextureView,
    background_from_env: bool,
    white: wgpu::TextureView,
    env: Option<EnvGpu>,
    model: Option<ModelGpu>,
    env_view_bg: Option<wgpu::BindGroup>,
    background_bg: wgpu::BindGroup,
    shadow_bg: wgpu::BindGroup,
    ground_bg: wgpu::BindGroup,
    model_bg: Option<wgpu::BindGroup>,
    /// Slot 0: from the first pass's start to the composite pass's end.
    timer: Option<GpuTimer>,
}

/// Upload an sRGB RGBA8 image as a sampled texture.
fn upload_rgba8(gpu: &Gpu, label: &str, image: &Rgba8Image) -> wgpu::TextureView {
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
    let texture = build::texture(&gpu.device, label, (image.width, image.height, 1), COLOR_FORMAT, 1, usage);
    build::write_layer(&gpu.queue, &texture, 0, &image.pixels);
    texture.create_view(&Default::default())
}

impl Compositor {
    /// Pipelines and targets for `width`×`height` output.
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Result<Compositor> {
        gpu.check_size("output", width, height)?;
        gpu.checked("the compositor's render targets", || Self::create(gpu, width, height))
    }

    fn create(gpu: &Gpu, width: u32, height: u32) -> Result<Compositor> {
        let device = &gpu.device;
        let pipelines = Pipelines::shared(gpu)?;
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        // The shadow map's side: SHADOW_MAP_SIZE where the device allows it.
        let shadow_size = SHADOW_MAP_SIZE.min(device.limits().max_texture_dimension_2d);
        let shadow = build::texture(
            device,
            "shadow map",
            (shadow_size, shadow_size, 1),
            DEPTH_FORMAT,
            1,
            attach | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let msaa = build::texture(device, "msaa colour", (width, height, 1), COLOR_FORMAT, SAMPLES, attach);
        let depth = build::texture(device, "depth", (width, height, 1), DEPTH_FORMAT, SAMPLES, attach);
        // The resolved frame: read back (headless) or sampled by the window's UI pass (live),
        // which blends in gamma space and so samples the sRGB-encoded bytes as they are.
        let resolve = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("resolve"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            usage: attach | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[COLOR_FORMAT.remove_srgb_suffix()],
        });
        let background = build::texture(
            device,
            "background",
            (width, height, 1),
            COLOR_FORMAT,
            1,
            attach | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        let readback = Readback::for_texture(device, "readback", &resolve)?;
        let frame_buf = build::uniform_buffer::<FrameUniforms>(device, "frame");
        let instance_buf = build::uniform_buffer::<InstanceUniforms>(device, "instance");
        let ground_buf = build::uniform_buffer::<InstanceUniforms>(device, "ground plane");
        let colour_buf = build::uniform_buffer::<ColourCorrection>(device, "colour correction");
        let shadow_view = shadow.create_view(&Default::default());
        let background_view = background.create_view(&Default::default());
        let white = upload_rgba8(gpu, "white", &Rgba8Image { width: 1, height: 1, pixels: vec![255; 4] });
        let background_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("background"),
            layout: &pipelines.background_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&background_view) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&pipelines.linear_sampler) },
            ],
        });
        let shadow_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow"),
            layout: &pipelines.shadow_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: instance_buf.as_entire_binding() },
            ],
        });
        let ground_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ground"),
            layout: &pipelines.ground_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: ground_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&shadow_view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&pipelines.shadow_sampler) },
            ],
        });
        let timer = GpuTimer::new(gpu, 1);
        Ok(Compositor {
            pipelines,
            width,
            height,
            frame_buf,
            instance_buf,
            ground_buf,
            colour_buf,
            shadow_view,
            shadow_size,
            msaa_view: msaa.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            resolve_view: resolve.create_view(&Default::default()),
            encoded_view: resolve
                .create_view(&wgpu::TextureViewDescriptor { format: Some(COLOR_FORMAT.remove_srgb_suffix()), ..Default::default() }),
            resolve,
            readback,
            background,
            background_view,
            background_from_env: true,
            white,
            env: None,
            model: None,
            env_view_bg: None,
            background_bg,
            shadow_bg,
            ground_bg,
            model_bg: None,
            timer,
        })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Upload the environment cube map, scaled by `exposure` (linear light), and its priors.
    /// `heading` (radians, clockwise from North) is the world direction of the map's front (+Z)
    /// face: 0 for maps already aligned with North, a capture's reference heading otherwise.
    pub fn set_environment(&mut self, gpu: &Gpu, cube: &CubeMap, exposure: f32, heading: f32) -> Result<()> {
        gpu.checked("the environment cube map", || self.set_environment_unchecked(gpu, cube, exposure, heading))
    }

    fn set_environment_unchecked(&mut self, gpu: &Gpu, cube: &CubeMap, exposure: f32, heading: f32) -> Result<()> {
        if !(exposure.is_finite() && exposure > 0.0) {
            bail!("environment exposure must be a positive number, got {exposure}");
        }
        if !heading.is_finite() {
            bail!("environment heading must be a finite angle");
        }
        let size = cube.size;
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let texture = build::texture(&gpu.device, "environment", (size, size, 6), wgpu::TextureFormat::Rgba16Float, 1, usage);
        for (layer, face) in cube.faces.iter().enumerate() {
            if face.len() != (size * size) as usize {
                bail!("cube-map face {} has {} pixels, expected {size}x{size}", crate::scene::FACE_NAMES[layer], face.len());
            }
            let halfs: Vec<half::f16> =
                face.iter().flat_map(|p| [p[0], p[1], p[2], 1.0]).map(|v| half::f16::from_f32(v.max(0.0))).collect();
            build::write_layer(&gpu.queue, &texture, layer as u32, bytemuck::cast_slice(&halfs));
        }
        let view = build::cube_view(&texture);
        let env_priors = priors::environment_priors_scaled(cube, exposure).context("environment colour priors")?;
        self.env_view_bg = Some(gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("env view"),
            layout: &self.pipelines.env_view_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.frame_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&self.pipelines.linear_sampler) },
            ],
        }));
        self.model_bg = Some(gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("model"),
            layout: &self.pipelines.model_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.frame_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.instance_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&self.pipelines.linear_sampler) },
                wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&self.background_view) },
                wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::Sampler(&self.pipelines.linear_sampler) },
                wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::TextureView(&self.shadow_view) },
                wgpu::BindGroupEntry { binding: 7, resource: wgpu::BindingResource::Sampler(&self.pipelines.shadow_sampler) },
                wgpu::BindGroupEntry { binding: 8, resource: self.colour_buf.as_entire_binding() },
            ],
        }));
        self.env =
            Some(EnvGpu { priors: HemispherePriors::from_environment(&env_priors), colour: env_priors.horizontal, exposure, heading });
        Ok(())
    }

    /// The environment's hemisphere priors after exposure (None before `set_environment`).
    pub fn priors(&self) -> Option<HemispherePriors> {
        self.env.as_ref().map(|e| e.priors)
    }

    /// Upload a model: one vertex/index buffer and material bind group per mesh.
    pub fn set_model(&mut self, gpu: &Gpu, model: &Model) -> Result<()> {
        gpu.checked("the model's buffers and textures", || self.set_model_unchecked(gpu, model))
    }

    fn set_model_unchecked(&mut self, gpu: &Gpu, model: &Model) -> Result<()> {
        let bounds = model.bounds().ok_or_else(|| anyhow!("the model has no vertices"))?;
        if !(bounds.0.is_finite() && bounds.1.is_finite()) {
            bail!("the model has non-finite vertex positions");
        }
        use wgpu::util::DeviceExt;
        let device = &gpu.device;
        let mut textures = Vec::with_capacity(model.materials.len());
        for m in &model.materials {
            textures.push(m.texture.as_ref().map(|t| upload_rgba8(gpu, &m.name, t)));
        }
        let mut meshes = Vec::new();
        let mut materials = Vec::new();
        for mesh in &model.meshes {
            if mesh.indices.is_empty() {
                continue;
            }
            let n = mesh.positions.len();
            if mesh.normals.len() != n || (!mesh.uvs.is_empty() && mesh.uvs.len() != n) {
                bail!("a mesh has {n} positions but {} normals and {} uvs", mesh.normals.len(), mesh.uvs.len());
            }
            if let Some(&bad) = mesh.indices.iter().find(|&&i| i as usize >= n) {
                bail!("a mesh index ({bad}) points past its {n} vertices");
            }
            let vertices: Vec<Vertex> = (0..n)
                .map(|i| Vertex {
                    position: mesh.positions[i],
                    normal: mesh.normals[i],
                    uv: mesh.uvs.get(i).copied().unwrap_or([0.0, 0.0]),
                })
                .collect();
            let material =
                model.materials.get(mesh.material).ok_or_else(|| anyhow!("a mesh refers to missing material {}", mesh.material))?;
            let uniforms = MaterialUniforms {
                albedo: [material.diffuse[0], material.diffuse[1], material.diffuse[2], if material.texture.is_some() { 1.0 } else { 0.0 }],
                specular: [material.specular[0], material.specular[1], material.specular[2], material.shininess],
                terms: [1.0, 1.0, 1.0, 0.0],
            };
            let material_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("material"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
            let texture = textures[mesh.material].as_ref().unwrap_or(&self.white);
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("material"),
                layout: &self.pipelines.material_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: material_buf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(texture) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&self.pipelines.repeat_sampler) },
                ],
            });
            meshes.push(MeshGpu {
                vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("vertices"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
                indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("indices"),
                    contents: bytemuck::cast_slice(&mesh.indices),
                    usage: wgpu::BufferUsages::INDEX,
                }),
                index_count: mesh.indices.len() as u32,
                material: bind,
            });
            materials.push((material_buf, uniforms));
        }
        if meshes.is_empty() {
            bail!("the model has no triangles");
        }
        let colour = priors::model_priors(model).map(|p| p.stats).map_err(|e| format!("{e:#}"));
        self.model = Some(ModelGpu { meshes, bounds, materials, colour });
        Ok(())
    }

    /// The loaded model's bounds in model space.
    pub fn model_bounds(&self) -> Option<(Vec3, Vec3)> {
        self.model.as_ref().map(|m| m.bounds)
    }

    /// Use a photograph (or a camera frame) as the background, or `None` for the environment
    /// seen by the camera. The image must already be the output size (see
    /// `scene::background::fit`); a camera frame of the same size is re-uploaded with this call
    /// each frame (one `write_texture`).
    pub fn set_background(&mut self, gpu: &Gpu, image: Option<&Rgba8Image>) -> Result<()> {
        match image {
            None => self.background_from_env = true,
            Some(img) => {
                if (img.width, img.height) != (self.width, self.height) {
                    bail!("background is {}x{}, the output is {}x{}", img.width, img.height, self.width, self.height);
                }
                if img.pixels.len() != (4 * img.width * img.height) as usize {
                    bail!("background pixel buffer has the wrong length");
                }
                gpu.checked("the background image", || {
                    build::write_layer(&gpu.queue, &self.background, 0, &img.pixels);
                    Ok(())
                })?;
                self.background_from_env = false;
            }
        }
        Ok(())
    }

    /// The uniform values for a frame (pure: no GPU access). A colour correction needs the
    /// model's colour priors; a model without any (every texel masked out) is an error then.
    pub fn frame_uniforms(&self, p: &FrameParams) -> Result<FrameData> {
        let env = self.env.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let (frame, instance, ground) =
            frame_uniforms(p, model.bounds, &env.priors, env.exposure, env.heading, (self.width, self.height), self.shadow_size);
        let colour = match (p.colour.method, &model.colour) {
            (ColourMethod::None, _) => ColourCorrection::identity(),
            (m, Ok(target)) => ColourCorrection::new(m, p.colour.strength, &env.colour, target),
            (m, Err(why)) => bail!("colour correction {} needs the model's colour statistics: {why}", m.name()),
        };
        Ok(FrameData { frame, instance, ground, colour })
    }

    /// Render one image of `layer` and read it back.
    pub fn render(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<Rendered> {
        gpu.checked("the frame", || self.render_unchecked(gpu, p, layer))
    }

    /// Render one image of `layer` into [`Compositor::target_view`] without reading it back:
    /// the live view samples it in its UI pass. Returns the CPU encode time in ms.
    pub fn draw(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<f64> {
        gpu.checked("the frame", || {
            let t0 = Instant::now();
            let encoder = self.prepare_frame(gpu, p, layer)?;
            let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
            gpu.queue.submit([encoder.finish()]);
            Ok(encode_ms)
        })
    }

    /// The rendered frame (the output size) as an `Rgba8Unorm` view of its sRGB-encoded bytes:
    /// sampling returns the encoded values, which is what egui-wgpu's gamma-space pass wants.
    pub fn target_view(&self) -> &wgpu::TextureView {
        &self.encoded_view
    }

    fn render_unchecked(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<Rendered> {
        let t0 = Instant::now();
        let mut encoder = self.prepare_frame(gpu, p, layer)?;
        self.readback.copy(&mut encoder, &self.resolve);
        if let Some(timer) = &self.timer {
            timer.resolve(&mut encoder, 1);
        }
        let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t1 = Instant::now();
        gpu.queue.submit([encoder.finish()]);
        let rgba = self.readback.read(gpu)?;
        let gpu_ms = match &self.timer {
            Some(timer) => timer.read_ms(gpu, 1)?.first().copied(),
            None => None,
        };
        let readback_ms = t1.elapsed().as_secs_f64() * 1e3;
        Ok(Rendered { width: self.width, height: self.height, rgba, timings: Timings { encode_ms, gpu_ms, readback_ms } })
    }

    /// Write the frame's uniforms and encode its passes.
    fn prepare_frame(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<wgpu::CommandEncoder> {
        let data = self.frame_uniforms(p)?;
        gpu.queue.write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&data.frame));
        gpu.queue.write_buffer(&self.instance_buf, 0, bytemuck::bytes_of(&data.instance));
        gpu.queue.write_buffer(&self.ground_buf, 0, bytemuck::bytes_of(&data.ground));
        gpu.queue.write_buffer(&self.colour_buf, 0, bytemuck::bytes_of(&data.colour));
        if let Some(model) = &self.model {
            for (buf, base) in &model.materials {
                let mut m = *base;
                let t = p.lighting.material;
                m.terms = [t.ambient, t.diffuse, t.specular, 0.0];
                if let Some(g) = t.gloss {
                    m.specular[3] = g;
                }
                gpu.queue.write_buffer(buf, 0, bytemuck::bytes_of(&m));
            }
        }
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        self.encode_frame(&mut encoder, layer)?;
        Ok(encoder)
    }

    /// The passes of one frame, top-down (DESIGN.md "One frame"). The camera image was uploaded
    /// by `set_background`; nothing here allocates GPU resources.
    fn encode_frame(&self, encoder: &mut wgpu::CommandEncoder, layer: Layer) -> Result<()> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let model_bg = self.model_bg.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        let env_view_bg = self.env_view_bg.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        // The first pass recorded writes the start timestamp, the composite pass the end.
        let shadows = layer != Layer::Background;
        let stamp = |begin: bool, end: bool| self.timer.as_ref().and_then(|t| t.render_pass(0, begin, end));

        // 2. Shadow pass: the model's depth seen from the sun (not needed for the background alone).
        if shadows {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shadow"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.shadow_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: stamp(true, false),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines.shadow);
            pass.set_bind_group(0, &self.shadow_bg, &[]);
            for mesh in &model.meshes {
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.index_count, 0, 0..1);
            }
        }

        // 3a. The environment seen by the camera becomes the background when there is no photo.
        if self.background_from_env {
            let mut pass = build::clear_pass(encoder, "environment view", &self.background_view, stamp(!shadows, false));
            pass.set_pipeline(&self.pipelines.env_view);
            pass.set_bind_group(0, env_view_bg, &[]);
            pass.draw(0..3, 0..1);
        }

        // 3b-5. Background, ground shadow, model into the multisampled target.
        let clear = if layer == Layer::Model { wgpu::Color::TRANSPARENT } else { wgpu::Color::BLACK };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.msaa_view,
                depth_slice: None,
                resolve_target: Some(&self.resolve_view),
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Discard },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            timestamp_writes: stamp(!shadows && !self.background_from_env, true),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if layer != Layer::Model {
            // 3b. Background pass: the camera image fills the target.
            pass.set_pipeline(&self.pipelines.background);
            pass.set_bind_group(0, &self.background_bg, &[]);
            pass.draw(0..3, 0..1);
        }
        if layer == Layer::Composite {
            // 4. Ground pass: the shadow catcher darkens the background under the model.
            pass.set_pipeline(&self.pipelines.ground);
            pass.set_bind_group(0, &self.ground_bg, &[]);
            pass.draw(0..6, 0..1);
        }
        if layer != Layer::Background {
            // 5. Model pass: shading, reflection/refraction, one fragment shader.
            pass.set_pipeline(&self.pipelines.model);
            pass.set_bind_group(0, model_bg, &[]);
            for mesh in &model.meshes {
                pass.set_bind_group(1, &mesh.material, &[]);
                pass.set_vertex_buffer(0, mesh.vertices.slice(..));
                pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.index_count, 0, 0..1);
            }
        }
        Ok(())
    }
}

fn mat(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

/// Uniforms of a frame: camera, model/ground transforms, sun shadow camera, lights, priors.
pub fn frame_uniforms(
    p: &FrameParams,
    bounds: (Vec3, Vec3),
    priors: &HemispherePriors,
    exposure: f32,
    env_heading: f32,
    (width, height): (u32, u32),
    shadow_size: u32,
) -> (FrameUniforms, InstanceUniforms, InstanceUniforms) {
    let aspect = width as f32 / height as f32;
    let model = view::model_matrix(bounds, &p.placement);
    // World bounding sphere of the placed model.
    let centre_model = 0.5 * (bounds.0 + bounds.1);
    let centre = model.transform_point3(centre_model);
    let radius = (0.5 * (bounds.1 - bounds.0).length() * p.placement.scale).max(1e-4);
    let distance = (centre - p.camera.position).length();
    let near = (distance - 4.0 * radius).max(distance * 1e-3).max(1e-3);
    let far = (distance + 50.0 * radius).max(near * 2.0);
    let proj = view::projection(p.camera.vfov, aspect, near, far);
    let view_m = view::view_matrix(p.camera.pose, p.camera.position);
    let sun = p.lighting.sun_dir.normalize_or(Vec3::Z);
    let light = view::sun_view_proj(sun, centre, radius);
    // The ground plane: a square under the model, large enough for long low-sun shadows.
    let ground = Mat4::from_translation(p.placement.position) * Mat4::from_scale(Vec3::new(40.0 * radius, 40.0 * radius, 1.0));
    let (hs, hc) = env_heading.sin_cos();
    let frame = FrameUniforms {
        view_proj: mat(proj * view_m),
        view: mat(view_m),
        light_view_proj: mat(light),
        camera_pos: p.camera.position.to_array(),
        daylight: p.lighting.daylight,
        sun_dir: sun.to_array(),
        sunlight: p.lighting.sunlight,
        sky: priors.sky,
        occlusion_light: priors.light,
        ground: priors.ground,
        occlusion_shadow: priors.shadow,
        env_rotation: [hc, hs],
        env_exposure: exposure,
        reflection: p.lighting.reflection,
        eta: 1.0 / p.lighting.ior,
        shadow_opacity: p.lighting.shadow_opacity,
        live_depth: p.lighting.live_depth,
        tan_half_vfov: (0.5 * p.camera.vfov).tan(),
        aspect,
        method: p.method.shader_id(),
        shadow_map_size: shadow_size,
        _padding: 0,
    };
    let instance = InstanceUniforms { model: mat(model), normal: mat(view::normal_matrix(&model)) };
    let ground = InstanceUniforms { model: mat(ground), normal: mat(Mat4::IDENTITY) };
    (frame, instance, ground)
}
