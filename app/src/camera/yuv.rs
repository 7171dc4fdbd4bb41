//! Camera images in YUV 4:2:0 (Android `YUV_420_888`, iOS 420v/420f): the planes go to the GPU as
//! they come from the camera — luma as an `R8Unorm` texture, chroma as one interleaved `Rg8Unorm`
//! texture (NV12, NV21) or two `R8Unorm` textures (I420) — with the camera's row strides, and
//! one pass (`shaders/yuv.wgsl`) converts them to R'G'B'. No colour conversion on the CPU.
//!
//! The Y'CbCr → R'G'B' matrix comes from the luma coefficients Kr, Kb of the camera's colour
//! standard (ITU-R BT.601-7: 0.299, 0.114; ITU-R BT.709-6: 0.2126, 0.0722) and its range:
//! *full* (JFIF: Y' = Y/255, Cb = (U − 128)/255) or *limited* ("video": Y' = (Y − 16)/219,
//! Cb = (U − 128)/224), see [`ycbcr_to_rgb`]. [`to_rgba_cpu`] is the CPU reference of the
//! shader; [`from_rgba`] makes YUV planes from an image (tests, and frames of the virtual phone
//! fed through the phone's path).
//!
//! Chroma is sampled nearest: pixel (x, y) takes the chroma sample (x/2, y/2) (odd sizes round
//! the chroma plane up, as Android and CoreVideo do).

use crate::gpu::{Gpu, Readback, build};
use crate::scene::Rgba8Image;
use anyhow::{Context, Result, bail};
use bytemuck::{Pod, Zeroable};

/// The WGSL of the conversion pass.
pub const YUV_WGSL: &str = include_str!("../../../shaders/yuv.wgsl");

/// The colour standard of the camera's Y'CbCr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum YuvMatrix {
    /// ITU-R BT.601 (SD video, JPEG/JFIF; most phone camera preview streams).
    Bt601,
    /// ITU-R BT.709 (HD video).
    Bt709,
}

impl YuvMatrix {
    /// Luma coefficients (Kr, Kb).
    pub fn kr_kb(self) -> (f64, f64) {
        match self {
            YuvMatrix::Bt601 => (0.299, 0.114),
            YuvMatrix::Bt709 => (0.2126, 0.0722),
        }
    }
}

/// The code-value range of the Y'CbCr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum YuvRange {
    /// Y 0..255, chroma 0..255 centred on 128 (JFIF; Android's camera, iOS 420f).
    Full,
    /// Y 16..235, chroma 16..240 centred on 128 (video; iOS 420v).
    Limited,
}

/// Y'CbCr → R'G'B': R'G'B' = m · ((code − offset) ⊙ scale), code values in 8-bit units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YcbcrToRgb {
    /// Rows of the matrix.
    pub m: [[f64; 3]; 3],
    pub offset: [f64; 3],
    pub scale: [f64; 3],
}

/// The conversion for a colour standard and range (ITU-R BT.601-7 §2.5 / BT.709-6 §3: E'Y =
/// Kr E'R + (1 − Kr − Kb) E'G + Kb E'B, E'Cb = (E'B − E'Y) / (2 (1 − Kb)), E'Cr = (E'R − E'Y) /
/// (2 (1 − Kr)), inverted).
pub fn ycbcr_to_rgb(matrix: YuvMatrix, range: YuvRange) -> YcbcrToRgb {
    let (kr, kb) = matrix.kr_kb();
    let kg = 1.0 - kr - kb;
    let m = [[1.0, 0.0, 2.0 * (1.0 - kr)], [1.0, -2.0 * kb * (1.0 - kb) / kg, -2.0 * kr * (1.0 - kr) / kg], [1.0, 2.0 * (1.0 - kb), 0.0]];
    let (offset, scale) = match range {
        YuvRange::Full => ([0.0, 128.0, 128.0], [1.0 / 255.0; 3]),
        YuvRange::Limited => ([16.0, 128.0, 128.0], [1.0 / 219.0, 1.0 / 224.0, 1.0 / 224.0]),
    };
    YcbcrToRgb { m, offset, scale }
}

/// The forward matrix (R'G'B' 0..1 → Y' 0..1, Cb, Cr −0.5..0.5) of the same standard.
fn rgb_to_ycbcr(matrix: YuvMatrix) -> [[f64; 3]; 3] {
    let (kr, kb) = matrix.kr_kb();
    let kg = 1.0 - kr - kb;
    let cb = 0.5 / (1.0 - kb);
    let cr = 0.5 / (1.0 - kr);
    [[kr, kg, kb], [-kr * cb, -kg * cb, (1.0 - kb) * cb], [(1.0 - kr) * cr, -kg * cr, -kb * cr]]
}

/// One plane of 8-bit samples.
#[derive(Clone, Copy, Debug)]
pub struct Plane<'a> {
    pub data: &'a [u8],
    /// Bytes from one row to the next (≥ the row's bytes).
    pub row_stride: usize,
}

/// The chroma of a 4:2:0 image.
#[derive(Clone, Copy, Debug)]
pub enum Chroma<'a> {
    /// One plane of (Cb, Cr) pairs — NV12 (`cb_first`) — or (Cr, Cb) pairs — NV21. Android's
    /// `YUV_420_888` with a chroma pixel stride of 2.
    Interleaved { plane: Plane<'a>, cb_first: bool },
    /// Separate Cb and Cr planes (I420; pixel stride 1).
    Planar { cb: Plane<'a>, cr: Plane<'a> },
}

/// A borrowed YUV 4:2:0 frame, as a camera delivers it.
#[derive(Clone, Copy, Debug)]
pub struct YuvFrame<'a> {
    pub width: u32,
    pub height: u32,
    pub luma: Plane<'a>,
    pub chroma: Chroma<'a>,
    pub matrix: YuvMatrix,
    pub range: YuvRange,
}

impl YuvFrame<'_> {
    /// Size of the chroma planes: half the image, rounded up.
    pub fn chroma_size(&self) -> (u32, u32) {
        (self.width.div_ceil(2), self.height.div_ceil(2))
    }

    /// Check sizes, strides and plane lengths (a short plane names itself and its sizes).
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            bail!("YUV frame is {}x{}: empty", self.width, self.height);
        }
        let check = |name: &str, p: &Plane, row_bytes: usize, rows: usize| -> Result<()> {
            if p.row_stride < row_bytes {
                bail!("YUV {name} plane: row stride {} is less than the row's {row_bytes} bytes", p.row_stride);
            }
            let need = p.row_stride * (rows - 1) + row_bytes;
            if p.data.len() < need {
                bail!("YUV {name} plane: {} bytes, {rows} rows of {row_bytes} bytes at stride {} need {need}", p.data.len(), p.row_stride);
            }
            Ok(())
        };
        check("luma", &self.luma, self.width as usize, self.height as usize)?;
        let (cw, ch) = self.chroma_size();
        let (cw, ch) = (cw as usize, ch as usize);
        match &self.chroma {
            Chroma::Interleaved { plane, .. } => check("chroma", plane, 2 * cw, ch),
            Chroma::Planar { cb, cr } => {
                check("Cb", cb, cw, ch)?;
                check("Cr", cr, cw, ch)
            }
        }
    }

    /// The code values (Y, Cb, Cr) at a pixel.
    fn sample(&self, x: usize, y: usize) -> [u8; 3] {
        let l = self.luma.data[y * self.luma.row_stride + x];
        let (cx, cy) = (x / 2, y / 2);
        let (cb, cr) = match &self.chroma {
            Chroma::Interleaved { plane, cb_first } => {
                let i = cy * plane.row_stride + 2 * cx;
                let (a, b) = (plane.data[i], plane.data[i + 1]);
                if *cb_first { (a, b) } else { (b, a) }
            }
            Chroma::Planar { cb, cr } => (cb.data[cy * cb.row_stride + cx], cr.data[cy * cr.row_stride + cx]),
        };
        [l, cb, cr]
    }
}

/// The CPU reference of `shaders/yuv.wgsl`: R'G'B' bytes (rounded, clamped), alpha 255.
pub fn to_rgba_cpu(frame: &YuvFrame) -> Result<Rgba8Image> {
    frame.validate()?;
    let c = ycbcr_to_rgb(frame.matrix, frame.range);
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut pixels = Vec::with_capacity(w * h * 4);
    for y in 0..h {
        for x in 0..w {
            let code = frame.sample(x, y);
            let v: [f64; 3] = std::array::from_fn(|i| (f64::from(code[i]) - c.offset[i]) * c.scale[i]);
            for row in &c.m {
                let value = row[0] * v[0] + row[1] * v[1] + row[2] * v[2];
                pixels.push((value.clamp(0.0, 1.0) * 255.0).round() as u8);
            }
            pixels.push(255);
        }
    }
    Ok(Rgba8Image { width: frame.width, height: frame.height, pixels })
}

/// How [`from_rgba`] lays out the planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    Nv12,
    Nv21,
    I420,
}

/// Owned YUV planes (made by [`from_rgba`]); [`OwnedYuv::frame`] borrows them as a camera frame.
#[derive(Clone, Debug)]
pub struct OwnedYuv {
    pub width: u32,
    pub height: u32,
    pub layout: Layout,
    pub matrix: YuvMatrix,
    pub range: YuvRange,
    pub luma: Vec<u8>,
    pub luma_stride: usize,
    /// The interleaved plane (NV12/NV21) or Cb then Cr (I420).
    pub chroma: Vec<Vec<u8>>,
    pub chroma_stride: usize,
}

impl OwnedYuv {
    pub fn frame(&self) -> YuvFrame<'_> {
        let chroma = match self.layout {
            Layout::Nv12 | Layout::Nv21 => Chroma::Interleaved {
                plane: Plane { data: &self.chroma[0], row_stride: self.chroma_stride },
                cb_first: self.layout == Layout::Nv12,
            },
            Layout::I420 => Chroma::Planar {
                cb: Plane { data: &self.chroma[0], row_stride: self.chroma_stride },
                cr: Plane { data: &self.chroma[1], row_stride: self.chroma_stride },
            },
        };
        YuvFrame {
            width: self.width,
            height: self.height,
            luma: Plane { data: &self.luma, row_stride: self.luma_stride },
            chroma,
            matrix: self.matrix,
            range: self.range,
        }
    }
}

/// Convert an R'G'B' image to YUV 4:2:0 planes (chroma: the mean of each 2×2 block, of the
/// pixels that exist at odd edges), rows padded by `padding` bytes (filled with 0xAB, so a reader
/// that ignores the stride sees garbage). The padding of the last row is left off, as Android's
/// buffers do.
pub fn from_rgba(img: &Rgba8Image, layout: Layout, matrix: YuvMatrix, range: YuvRange, padding: usize) -> Result<OwnedYuv> {
    let (w, h) = (img.width as usize, img.height as usize);
    if w == 0 || h == 0 || img.pixels.len() != w * h * 4 {
        bail!("from_rgba: {}x{} image with {} bytes is not RGBA8", img.width, img.height, img.pixels.len());
    }
    let fwd = rgb_to_ycbcr(matrix);
    let (y_scale, y_off, c_scale) = match range {
        YuvRange::Full => (255.0, 0.0, 255.0),
        YuvRange::Limited => (219.0, 16.0, 224.0),
    };
    let ycc = |x: usize, y: usize| -> [f64; 3] {
        let p = &img.pixels[4 * (y * w + x)..];
        let rgb = [f64::from(p[0]) / 255.0, f64::from(p[1]) / 255.0, f64::from(p[2]) / 255.0];
        std::array::from_fn(|i| fwd[i][0] * rgb[0] + fwd[i][1] * rgb[1] + fwd[i][2] * rgb[2])
    };
    let code = |v: f64| v.round().clamp(0.0, 255.0) as u8;
    let luma_stride = w + padding;
    let mut luma = vec![0xAB; luma_stride * (h - 1) + w];
    for y in 0..h {
        for x in 0..w {
            luma[y * luma_stride + x] = code(y_off + y_scale * ycc(x, y)[0]);
        }
    }
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut cb = vec![0u8; cw * ch];
    let mut cr = vec![0u8; cw * ch];
    for cy in 0..ch {
        for cx in 0..cw {
            let (mut s, mut n) = ([0.0; 2], 0.0);
            for (x, y) in [(2 * cx, 2 * cy), (2 * cx + 1, 2 * cy), (2 * cx, 2 * cy + 1), (2 * cx + 1, 2 * cy + 1)] {
                if x < w && y < h {
                    let v = ycc(x, y);
                    s[0] += v[1];
                    s[1] += v[2];
                    n += 1.0;
                }
            }
            cb[cy * cw + cx] = code(128.0 + c_scale * s[0] / n);
            cr[cy * cw + cx] = code(128.0 + c_scale * s[1] / n);
        }
    }
    let (chroma, chroma_stride) = match layout {
        Layout::Nv12 | Layout::Nv21 => {
            let stride = 2 * cw + padding;
            let mut plane = vec![0xAB; stride * (ch - 1) + 2 * cw];
            for cy in 0..ch {
                for cx in 0..cw {
                    let (a, b) =
                        if layout == Layout::Nv12 { (cb[cy * cw + cx], cr[cy * cw + cx]) } else { (cr[cy * cw + cx], cb[cy * cw + cx]) };
                    plane[cy * stride + 2 * cx] = a;
                    plane[cy * stride + 2 * cx + 1] = b;
                }
            }
            (vec![plane], stride)
        }
        Layout::I420 => {
            let stride = cw + padding;
            let pad = |p: &[u8]| {
                let mut out = vec![0xAB; stride * (ch - 1) + cw];
                for cy in 0..ch {
                    out[cy * stride..cy * stride + cw].copy_from_slice(&p[cy * cw..(cy + 1) * cw]);
                }
                out
            };
            (vec![pad(&cb), pad(&cr)], stride)
        }
    };
    Ok(OwnedYuv { width: img.width, height: img.height, layout, matrix, range, luma, luma_stride, chroma, chroma_stride })
}

/// The conversion pass's uniforms (mirrors `YuvUniforms` in `shaders/yuv.wgsl`; a test checks
/// the layout against naga).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct YuvUniforms {
    pub row_r: [f32; 4],
    pub row_g: [f32; 4],
    pub row_b: [f32; 4],
    pub offset: [f32; 4],
    pub scale: [f32; 4],
    pub cb_channel: u32,
    pub cr_channel: u32,
    pub width: u32,
    pub height: u32,
    /// Clockwise quarter turns applied to the image (0..=3).
    pub quarter_turns: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl YuvUniforms {
    pub fn new(frame: &YuvFrame, quarter_turns: u32) -> YuvUniforms {
        let c = ycbcr_to_rgb(frame.matrix, frame.range);
        let v4 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0];
        let (cb_channel, cr_channel) = match frame.chroma {
            Chroma::Interleaved { cb_first: true, .. } => (0, 1),
            Chroma::Interleaved { cb_first: false, .. } => (1, 0),
            Chroma::Planar { .. } => (0, 0),
        };
        YuvUniforms {
            row_r: v4(c.m[0]),
            row_g: v4(c.m[1]),
            row_b: v4(c.m[2]),
            offset: v4(c.offset),
            scale: v4(c.scale),
            cb_channel,
            cr_channel,
            width: frame.width,
            height: frame.height,
            quarter_turns: quarter_turns % 4,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }
}

/// `img` turned clockwise by `quarter_turns` quarter turns (the CPU reference of the
/// conversion pass's turn): output pixel (x', y') of a turned image comes from source pixel
/// (y', h−1−x') for one turn, (w−1−x', h−1−y') for two, (w−1−y', x') for three.
pub fn turn_image(img: &Rgba8Image, quarter_turns: u32) -> Rgba8Image {
    let (w, h) = (img.width as usize, img.height as usize);
    let q = quarter_turns % 4;
    let (ow, oh) = if q % 2 == 1 { (h, w) } else { (w, h) };
    let mut pixels = Vec::with_capacity(img.pixels.len());
    for y in 0..oh {
        for x in 0..ow {
            let (sx, sy) = match q {
                0 => (x, y),
                1 => (y, h - 1 - x),
                2 => (w - 1 - x, h - 1 - y),
                _ => (w - 1 - y, x),
            };
            pixels.extend_from_slice(&img.pixels[4 * (sy * w + sx)..4 * (sy * w + sx) + 4]);
        }
    }
    Rgba8Image { width: ow as u32, height: oh as u32, pixels }
}

/// The plane textures of one frame shape (size and chroma layout).
struct Planes {
    /// Width, height, interleaved chroma, target turned a quarter (width and height swapped).
    key: (u32, u32, bool, bool),
    luma: wgpu::Texture,
    chroma: Vec<wgpu::Texture>,
    target: wgpu::Texture,
    target_view: wgpu::TextureView,
    bind: wgpu::BindGroup,
}

/// The GPU conversion: upload the planes (one `write_texture` each), convert in one pass into an
/// `Rgba8Unorm` texture holding the R'G'B' bytes.
pub struct YuvConverter {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
    planes: Option<Planes>,
}

/// The converted image's format: R'G'B' bytes, like an sRGB-encoded image's.
pub const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

impl YuvConverter {
    pub fn new(gpu: &Gpu) -> YuvConverter {
        let device = &gpu.device;
        let module = build::shader(device, "yuv", crate::gpu::wgsl::with_full_screen(YUV_WGSL));
        let fs = wgpu::ShaderStages::FRAGMENT;
        let texture = |binding| build::texture_entry(binding, fs, wgpu::TextureViewDimension::D2, false);
        let layout = build::layout(device, "yuv", &[build::uniform(0, fs), texture(1), texture(2), texture(3)]);
        let pipeline = build::render_pipeline(device, build::PipelineSpec::full_screen("yuv", &module, &[&layout], TARGET_FORMAT));
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("yuv uniforms"),
            size: std::mem::size_of::<YuvUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        YuvConverter { pipeline, layout, uniforms, planes: None }
    }

    /// The converted image of the last [`YuvConverter::convert`] (None before the first).
    pub fn target(&self) -> Option<&wgpu::Texture> {
        self.planes.as_ref().map(|p| &p.target)
    }

    pub fn target_view(&self) -> Option<&wgpu::TextureView> {
        self.planes.as_ref().map(|p| &p.target_view)
    }

    /// Upload `frame`'s planes and convert them on the GPU. Textures are made again only when
    /// the frame's size or chroma layout changes.
    pub fn convert(&mut self, gpu: &Gpu, frame: &YuvFrame) -> Result<()> {
        self.convert_turned(gpu, frame, 0)
    }

    /// The same, turning the image clockwise by `quarter_turns` quarter turns on the way (a
    /// camera mounted at an angle to the screen: `camera::platform::back_camera_quarter_turns`);
    /// the target is the turned size.
    pub fn convert_turned(&mut self, gpu: &Gpu, frame: &YuvFrame, quarter_turns: u32) -> Result<()> {
        frame.validate()?;
        let max = gpu.device.limits().max_texture_dimension_2d;
        if frame.width > max || frame.height > max {
            bail!("YUV frame {}x{} is larger than the GPU's {max}-texel textures", frame.width, frame.height);
        }
        let interleaved = matches!(frame.chroma, Chroma::Interleaved { .. });
        let key = (frame.width, frame.height, interleaved, quarter_turns % 2 == 1);
        if self.planes.as_ref().is_none_or(|p| p.key != key) {
            self.planes = Some(self.make_planes(gpu, key));
        }
        let planes = self.planes.as_ref().context("YUV plane textures missing")?;
        let (cw, ch) = frame.chroma_size();
        let upload = |texture: &wgpu::Texture, p: &Plane, w: u32, h: u32| {
            gpu.queue.write_texture(
                texture.as_image_copy(),
                p.data,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(p.row_stride as u32), rows_per_image: None },
                wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            );
        };
        upload(&planes.luma, &frame.luma, frame.width, frame.height);
        match &frame.chroma {
            Chroma::Interleaved { plane, .. } => upload(&planes.chroma[0], plane, cw, ch),
            Chroma::Planar { cb, cr } => {
                upload(&planes.chroma[0], cb, cw, ch);
                upload(&planes.chroma[1], cr, cw, ch);
            }
        }
        gpu.queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&YuvUniforms::new(frame, quarter_turns)));
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("yuv") });
        {
            let mut pass = build::clear_pass(&mut encoder, "yuv", &planes.target_view, None);
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &planes.bind, &[]);
            pass.draw(0..3, 0..1);
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(())
    }

    fn make_planes(&self, gpu: &Gpu, key: (u32, u32, bool, bool)) -> Planes {
        let (w, h, interleaved, swapped) = key;
        let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
        let texture = |label, w, h, format, usage| {
            gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let upload = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let luma = texture("yuv luma", w, h, wgpu::TextureFormat::R8Unorm, upload);
        let chroma = if interleaved {
            vec![texture("yuv chroma", cw, ch, wgpu::TextureFormat::Rg8Unorm, upload)]
        } else {
            vec![
                texture("yuv cb", cw, ch, wgpu::TextureFormat::R8Unorm, upload),
                texture("yuv cr", cw, ch, wgpu::TextureFormat::R8Unorm, upload),
            ]
        };
        let target_usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC;
        let (tw, th) = if swapped { (h, w) } else { (w, h) };
        let target = texture("yuv rgb", tw, th, TARGET_FORMAT, target_usage);
        let target_view = target.create_view(&Default::default());
        let luma_view = luma.create_view(&Default::default());
        let cb_view = chroma[0].create_view(&Default::default());
        let cr_view = chroma[chroma.len() - 1].create_view(&Default::default());
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("yuv"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.uniforms.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&luma_view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&cb_view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&cr_view) },
            ],
        });
        Planes { key, luma, chroma, target, target_view, bind }
    }

    /// Read the converted image back (tests; the app samples [`YuvConverter::target_view`]).
    pub fn read_back(&self, gpu: &Gpu) -> Result<Rgba8Image> {
        let planes = self.planes.as_ref().context("no YUV frame converted yet")?;
        let (w, h) = (planes.target.width(), planes.target.height());
        let pixels = gpu.checked("the YUV readback", || {
            let readback = Readback::for_texture(&gpu.device, "yuv readback", &planes.target)?;
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("yuv readback") });
            readback.copy(&mut encoder, &planes.target);
            gpu.queue.submit([encoder.finish()]);
            readback.read(gpu)
        })?;
        Ok(Rgba8Image { width: w, height: h, pixels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn bt601_full_range_is_the_jfif_matrix() {
        // JFIF 1.02 (ITU-T T.871 §7): R = Y + 1.402 (Cr − 128), G = Y − 0.344136 (Cb − 128)
        // − 0.714136 (Cr − 128), B = Y + 1.772 (Cb − 128).
        let c = ycbcr_to_rgb(YuvMatrix::Bt601, YuvRange::Full);
        let want = [[1.0, 0.0, 1.402], [1.0, -0.344136, -0.714136], [1.0, 1.772, 0.0]];
        for (row, want) in c.m.iter().zip(want) {
            for (a, b) in row.iter().zip(want) {
                assert!(close(*a, b, 5e-6), "{:?}", c.m);
            }
        }
        assert_eq!(c.offset, [0.0, 128.0, 128.0]);
    }

    #[test]
    fn bt709_limited_range_is_the_published_video_matrix() {
        // The widely published 8-bit BT.709 video-range inverse (e.g. Poynton, "Digital Video
        // and HD", 2nd ed., Eq. 30.x): R = 1.164384 (Y − 16) + 1.792741 (Cr − 128),
        // G = 1.164384 (Y − 16) − 0.213249 (Cb − 128) − 0.532909 (Cr − 128),
        // B = 1.164384 (Y − 16) + 2.112402 (Cb − 128) (all × 1/255).
        let c = ycbcr_to_rgb(YuvMatrix::Bt709, YuvRange::Limited);
        let per_code = |row: usize, col: usize| c.m[row][col] * c.scale[col] * 255.0;
        let want = [[1.164384, 0.0, 1.792741], [1.164384, -0.213249, -0.532909], [1.164384, 2.112402, 0.0]];
        for (r, want) in want.iter().enumerate() {
            for (col, b) in want.iter().enumerate() {
                assert!(close(per_code(r, col), *b, 5e-6), "row {r} col {col}: {} vs {b}", per_code(r, col));
            }
        }
        // BT.601 limited: 1.596027 for Cr in R (the same book's Eq. for SD).
        let sd = ycbcr_to_rgb(YuvMatrix::Bt601, YuvRange::Limited);
        assert!(close(sd.m[0][2] * sd.scale[2] * 255.0, 1.596027, 5e-6));
    }

    #[test]
    fn forward_and_inverse_matrices_are_inverses() {
        for matrix in [YuvMatrix::Bt601, YuvMatrix::Bt709] {
            let rows = |m: [[f64; 3]; 3]| glam::DMat3::from_cols_array_2d(&m).transpose();
            let product = rows(ycbcr_to_rgb(matrix, YuvRange::Full).m) * rows(rgb_to_ycbcr(matrix));
            assert!(product.abs_diff_eq(glam::DMat3::IDENTITY, 1e-12), "{matrix:?}: {product}");
        }
    }

    #[test]
    fn uniform_layout_matches_the_wgsl() {
        let module = naga::front::wgsl::parse_str(&crate::gpu::wgsl::with_full_screen(YUV_WGSL)).unwrap();
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all()).validate(&module).unwrap();
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (_, ty) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("YuvUniforms")).unwrap();
        let naga::TypeInner::Struct { members, span } = &ty.inner else { panic!("YuvUniforms is not a struct") };
        assert_eq!(*span as usize, std::mem::size_of::<YuvUniforms>());
        let offsets: Vec<(String, u32)> = members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect();
        use std::mem::offset_of;
        let rust: Vec<(String, u32)> = [
            ("row_r", offset_of!(YuvUniforms, row_r)),
            ("row_g", offset_of!(YuvUniforms, row_g)),
            ("row_b", offset_of!(YuvUniforms, row_b)),
            ("offset", offset_of!(YuvUniforms, offset)),
            ("scale", offset_of!(YuvUniforms, scale)),
            ("cb_channel", offset_of!(YuvUniforms, cb_channel)),
            ("cr_channel", offset_of!(YuvUniforms, cr_channel)),
            ("width", offset_of!(YuvUniforms, width)),
            ("height", offset_of!(YuvUniforms, height)),
            ("quarter_turns", offset_of!(YuvUniforms, quarter_turns)),
            ("_pad0", offset_of!(YuvUniforms, _pad0)),
            ("_pad1", offset_of!(YuvUniforms, _pad1)),
            ("_pad2", offset_of!(YuvUniforms, _pad2)),
        ]
        .iter()
        .map(|(n, o)| (n.to_string(), *o as u32))
        .collect();
        assert_eq!(offsets, rust);
    }

    #[test]
    fn short_planes_and_strides_are_named() {
        let y = [0u8; 20];
        let c = [0u8; 8];
        let frame = YuvFrame {
            width: 5,
            height: 4,
            luma: Plane { data: &y, row_stride: 5 },
            chroma: Chroma::Interleaved { plane: Plane { data: &c, row_stride: 6 }, cb_first: true },
            matrix: YuvMatrix::Bt601,
            range: YuvRange::Full,
        };
        // Chroma 3x2 pairs: 6 + 6 bytes needed, 8 given.
        let e = frame.validate().unwrap_err().to_string();
        assert!(e.contains("chroma plane") && e.contains("need 12"), "{e}");
        let bad_stride = YuvFrame { luma: Plane { data: &y, row_stride: 4 }, ..frame };
        assert!(bad_stride.validate().unwrap_err().to_string().contains("row stride 4"));
        let empty = YuvFrame { width: 0, ..frame };
        assert!(empty.validate().is_err());
    }

    #[test]
    fn a_grey_and_a_saturated_colour_round_trip() {
        // Mid grey is (128, 128, 128) in full range; pure red in BT.601 full range is
        // Y = 0.299·255 = 76.245 → 76, Cr = 128 + 0.5·255 = 255.5 → 255 (JFIF).
        let img = Rgba8Image { width: 2, height: 2, pixels: [[128, 128, 128, 255], [255, 0, 0, 255]].repeat(2).concat() };
        let yuv = from_rgba(&img, Layout::I420, YuvMatrix::Bt601, YuvRange::Full, 3).unwrap();
        assert_eq!(&yuv.luma[..2], &[128, 76]);
        let solid = Rgba8Image { width: 1, height: 1, pixels: vec![255, 0, 0, 255] };
        let red = from_rgba(&solid, Layout::Nv21, YuvMatrix::Bt601, YuvRange::Full, 0).unwrap();
        assert_eq!(red.luma, [76]);
        assert_eq!(red.chroma[0], [255, 85]); // Cr then Cb: 128 − 0.5·0.299/0.886·255 = 84.97
        let back = to_rgba_cpu(&red.frame()).unwrap();
        for (a, b) in back.pixels.iter().zip([255u8, 0, 0, 255]) {
            assert!((i32::from(*a) - i32::from(b)).abs() <= 2, "{:?}", back.pixels);
        }
    }

    #[test]
    fn turning_a_three_by_two_image() {
        // Pixels numbered row by row:   a b c      one turn clockwise:  d a
        //                               d e f                           e b
        //                                                               f c
        let px = |v: u8| [v, v, v, 255];
        let img = Rgba8Image { width: 3, height: 2, pixels: (1..=6).flat_map(px).collect() };
        let values = |i: &Rgba8Image| i.pixels.chunks(4).map(|p| p[0]).collect::<Vec<_>>();
        let one = turn_image(&img, 1);
        assert_eq!((one.width, one.height), (2, 3));
        assert_eq!(values(&one), [4, 1, 5, 2, 6, 3]);
        assert_eq!(values(&turn_image(&img, 2)), [6, 5, 4, 3, 2, 1]);
        assert_eq!(values(&turn_image(&img, 3)), [3, 6, 2, 5, 1, 4]);
        assert_eq!(values(&turn_image(&img, 4)), values(&img));
    }
}
