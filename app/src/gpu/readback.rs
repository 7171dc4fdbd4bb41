//! Reading GPU memory back: whole buffers, and textures through a buffer whose rows are padded
//! to wgpu's copy alignment ([`padded_row_bytes`]) and unpadded on the way out.

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
