//! Reading GPU memory back: whole buffers, query results, and textures through a buffer whose
//! rows are padded to wgpu's copy alignment ([`padded_row_bytes`]) and unpadded on the way out.

use super::Gpu;
use anyhow::{Context, Result, bail};

/// Bytes per row of a texture-to-buffer copy: `width × bytes_per_texel` rounded up to
/// `wgpu::COPY_BYTES_PER_ROW_ALIGNMENT` (256, WebGPU §"GPUImageCopyBuffer": bytesPerRow must be
/// a multiple of 256).
pub fn padded_row_bytes(width: u32, bytes_per_texel: u32) -> u32 {
    (width * bytes_per_texel).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// Map a whole `MAP_READ` buffer, copy it out and unmap it (blocks until the GPU is done).
pub fn read_buffer(gpu: &Gpu, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).context("waiting for the GPU failed")?;
    rx.recv().context("the GPU dropped a buffer mapping")?.context("cannot map a GPU buffer for reading")?;
    let data = slice.get_mapped_range().context("cannot read a mapped GPU buffer")?.to_vec();
    buffer.unmap();
    Ok(data)
}

/// A query set with the buffer its results are resolved into and the one they are read back
/// from (the timestamp timer's and the pass counter's).
pub struct QueryResults {
    pub query_set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
}

impl QueryResults {
    /// `count` queries of type `ty`, their results `bytes` long once resolved.
    pub fn new(gpu: &Gpu, label: &str, ty: wgpu::QueryType, count: u32, bytes: u64) -> QueryResults {
        let query_set = gpu.device.create_query_set(&wgpu::QuerySetDescriptor { label: Some(label), ty, count });
        use wgpu::BufferUsages as U;
        let resolve = super::build::buffer(&gpu.device, &format!("{label} resolve"), bytes, U::QUERY_RESOLVE | U::COPY_SRC);
        let readback = super::build::buffer(&gpu.device, &format!("{label} readback"), bytes, U::MAP_READ | U::COPY_DST);
        QueryResults { query_set, resolve, readback }
    }

    /// Record the resolve of `queries` to `offset` of the resolve buffer.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder, queries: std::ops::Range<u32>, offset: u64) {
        encoder.resolve_query_set(&self.query_set, queries, &self.resolve, offset);
    }

    /// Record the copy of the resolve buffer's first `bytes` to the readback buffer (after the
    /// resolves).
    pub fn copy_out(&self, encoder: &mut wgpu::CommandEncoder, bytes: u64) {
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, bytes);
    }

    /// The readback buffer's results as 64-bit values (after the submission completed).
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<u64>> {
        Ok(bytemuck::cast_slice(&read_buffer(gpu, &self.readback)?).to_vec())
    }
}

/// A buffer that receives every array layer of a texture's first mip level and returns its
/// texels tightly packed, layer after layer. Made once per texture size, reused every frame.
pub struct Readback {
    buffer: wgpu::Buffer,
    width: u32,
    height: u32,
    layers: u32,
    bytes_per_texel: u32,
    padded_row: u32,
}

impl Readback {
    /// For textures of `texture`'s size, layer count and format.
    pub fn for_texture(device: &wgpu::Device, label: &str, texture: &wgpu::Texture) -> Result<Readback> {
        let Some(bytes_per_texel) = texture.format().block_copy_size(None) else {
            bail!("{label}: texture format {:?} cannot be copied whole", texture.format());
        };
        let (width, height, layers) = (texture.width(), texture.height(), texture.depth_or_array_layers());
        let padded_row = padded_row_bytes(width, bytes_per_texel);
        let size = u64::from(padded_row) * u64::from(height) * u64::from(layers);
        let buffer = super::build::buffer(device, label, size, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        Ok(Readback { buffer, width, height, layers, bytes_per_texel, padded_row })
    }

    /// Record the copy of `texture` (the size this readback was made for) into the buffer.
    pub fn copy(&self, encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) {
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(self.padded_row), rows_per_image: Some(self.height) },
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: self.layers },
        );
    }

    /// The texels of the last copy (after its submission), rows unpadded.
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<u8>> {
        let padded = read_buffer(gpu, &self.buffer)?;
        let row = (self.width * self.bytes_per_texel) as usize;
        let mut out = Vec::with_capacity(row * (self.height * self.layers) as usize);
        for chunk in padded.chunks_exact(self.padded_row as usize) {
            out.extend_from_slice(&chunk[..row]);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_up_to_256_bytes() {
        // 1 and 64 RGBA8 texels fit one 256-byte row; 65 need two; 32 RGBA16F texels are 256.
        assert_eq!(padded_row_bytes(1, 4), 256);
        assert_eq!(padded_row_bytes(64, 4), 256);
        assert_eq!(padded_row_bytes(65, 4), 512);
        assert_eq!(padded_row_bytes(32, 8), 256);
        assert_eq!(padded_row_bytes(960, 4), 3840);
    }

    #[test]
    fn texture_round_trip_unpads_rows_of_every_layer() {
        let gpu = super::super::tests::gpu();
        // 70 texels per row (280 bytes, padded to 512) and two layers: every byte distinct-ish.
        let (w, h, layers) = (70u32, 3u32, 2u32);
        let usage = wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST;
        let texture = super::super::build::texture(&gpu.device, "round trip", (w, h, layers), wgpu::TextureFormat::Rgba8Unorm, 1, usage);
        let texels: Vec<u8> = (0..w * h * 4 * layers).map(|i| (i * 7 % 251) as u8).collect();
        let per_layer = (w * h * 4) as usize;
        for l in 0..layers {
            super::super::build::write_layer(&gpu.queue, &texture, l, &texels[l as usize * per_layer..(l as usize + 1) * per_layer]);
        }
        let readback = Readback::for_texture(&gpu.device, "round trip", &texture).unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        readback.copy(&mut encoder, &texture);
        gpu.queue.submit([encoder.finish()]);
        assert_eq!(readback.read(gpu).unwrap(), texels);
    }
}
