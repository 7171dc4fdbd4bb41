//! Small builders for the wgpu descriptors every pass writes: textures, buffers, bind-group
//! layout entries, bind groups and render pipelines (full-screen ones included).

use wgpu::{BindingType, ShaderStages};

/// A 2D texture (or array of `layers`) with one mip level.
pub fn texture(
    device: &wgpu::Device,
    label: &str,
    (width, height, layers): (u32, u32, u32),
    format: wgpu::TextureFormat,
    samples: u32,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: samples,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// Write tightly packed texels into array layer `layer` (mip 0, the whole layer) of `texture`.
pub fn write_layer(queue: &wgpu::Queue, texture: &wgpu::Texture, layer: u32, texels: &[u8]) {
    let bytes_per_texel = texture.format().block_copy_size(None).unwrap_or(4);
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d { x: 0, y: 0, z: layer },
            aspect: wgpu::TextureAspect::All,
        },
        texels,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(bytes_per_texel * texture.width()), rows_per_image: None },
        wgpu::Extent3d { width: texture.width(), height: texture.height(), depth_or_array_layers: 1 },
    );
}

/// A sampled 2D texture holding `texels` (tightly packed, `format`), as a view.
pub fn sampled_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    texels: &[u8],
) -> wgpu::TextureView {
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
    let texture = texture(device, label, (width, height, 1), format, 1, usage);
    write_layer(queue, &texture, 0, texels);
    texture.create_view(&Default::default())
}

/// A view of a six-layer texture as a cube map.
pub fn cube_view(texture: &wgpu::Texture) -> wgpu::TextureView {
    texture.create_view(&wgpu::TextureViewDescriptor { dimension: Some(wgpu::TextureViewDimension::Cube), ..Default::default() })
}

/// A buffer of `size` bytes.
pub fn buffer(device: &wgpu::Device, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
}

/// A uniform buffer the size of `T`, written with `queue.write_buffer`.
pub fn uniform_buffer<T: bytemuck::Pod>(device: &wgpu::Device, label: &str) -> wgpu::Buffer {
    buffer(device, label, std::mem::size_of::<T>() as u64, wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST)
}

/// A uniform buffer binding.
pub fn uniform(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
    let ty = BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None };
    wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
}

/// A storage buffer binding.
pub fn storage(binding: u32, visibility: ShaderStages, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    let ty = BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None };
    wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
}

/// A sampled float texture binding (filterable or not).
pub fn texture_entry(
    binding: u32,
    visibility: ShaderStages,
    view_dimension: wgpu::TextureViewDimension,
    filterable: bool,
) -> wgpu::BindGroupLayoutEntry {
    let ty = BindingType::Texture { sample_type: wgpu::TextureSampleType::Float { filterable }, view_dimension, multisampled: false };
    wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
}

/// A 2D depth texture binding (for comparison sampling).
pub fn depth_texture_entry(binding: u32, visibility: ShaderStages) -> wgpu::BindGroupLayoutEntry {
    let ty = BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Depth,
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None }
}

/// A sampler binding.
pub fn sampler_entry(binding: u32, visibility: ShaderStages, ty: wgpu::SamplerBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility, ty: BindingType::Sampler(ty), count: None }
}

/// A bind-group layout.
pub fn layout(device: &wgpu::Device, label: &str, entries: &[wgpu::BindGroupLayoutEntry]) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
}

/// A bind group whose resources are bindings 0, 1, 2… in order.
pub fn bind_group(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[wgpu::BindingResource<'_>],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> =
        resources.iter().enumerate().map(|(i, r)| wgpu::BindGroupEntry { binding: i as u32, resource: r.clone() }).collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}

/// A WGSL shader module.
pub fn shader(device: &wgpu::Device, label: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) })
}

/// What a render pipeline needs; entry points are `vs_main` and `fs_main`.
pub struct PipelineSpec<'a> {
    pub label: &'a str,
    pub module: &'a wgpu::ShaderModule,
    pub layouts: &'a [&'a wgpu::BindGroupLayout],
    pub vertex_buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    /// `None`: a depth-only pipeline (no fragment stage).
    pub colour: Option<wgpu::ColorTargetState>,
    pub depth: Option<wgpu::DepthStencilState>,
    pub samples: u32,
    /// Override constants of the module, by name.
    pub constants: &'a [(&'a str, f64)],
}

impl<'a> PipelineSpec<'a> {
    /// A full-screen pass (the triangle of `shaders/full_screen.wgsl`, drawn with `draw(0..3)`):
    /// no vertex buffers, no depth, one sample, colour written without blending.
    pub fn full_screen(
        label: &'a str,
        module: &'a wgpu::ShaderModule,
        layouts: &'a [&'a wgpu::BindGroupLayout],
        format: wgpu::TextureFormat,
    ) -> Self {
        PipelineSpec {
            label,
            module,
            layouts,
            vertex_buffers: &[],
            colour: Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL }),
            depth: None,
            samples: 1,
            constants: &[],
        }
    }
}

/// A render pipeline (no culling: the model's winding is not trusted).
pub fn render_pipeline(device: &wgpu::Device, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = spec.layouts.iter().map(|l| Some(*l)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(spec.label),
        bind_group_layouts: &layouts,
        immediate_size: 0,
    });
    let options = wgpu::PipelineCompilationOptions { constants: spec.constants, ..Default::default() };
    let targets = spec.colour.map(|c| [Some(c)]);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: spec.module,
            entry_point: Some("vs_main"),
            compilation_options: options.clone(),
            buffers: spec.vertex_buffers,
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: spec.depth,
        multisample: wgpu::MultisampleState { count: spec.samples, ..Default::default() },
        fragment: targets.as_ref().map(|targets| wgpu::FragmentState {
            module: spec.module,
            entry_point: Some("fs_main"),
            compilation_options: options.clone(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A linear-filtering sampler with one address mode on every axis.
pub fn linear_sampler(device: &wgpu::Device, label: &str, address: wgpu::AddressMode) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some(label),
        address_mode_u: address,
        address_mode_v: address,
        address_mode_w: address,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    })
}

/// A render pass that clears one colour target to black and stores it: the shape of the
/// full-screen passes (camera YUV conversion, frame-fold faces, the environment view).
pub fn clear_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: None,
        timestamp_writes,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
