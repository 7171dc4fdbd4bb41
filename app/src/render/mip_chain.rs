//! A model texture's mip chain: every level down to 1×1, built once on the CPU when the model is
//! uploaded and sampled trilinearly (the material sampler's mipmap filter is linear), so a
//! minified texture reads the average of the texels under a pixel instead of four of them at
//! random (texture aliasing). shaders/model.wgsl samples it at a bias toward finer levels
//! (`DIFFUSE_LOD_BIAS`: accuracy against the path-traced references; docs/PERFORMANCE.md, twelfth
//! session).
//!
//! Each level is the area-weighted box filter of the level above **in linear light** (an sRGB
//! texel is decoded before averaging and the average encoded again, as GPUs' sRGB formats
//! filter), computed from the level above's unrounded linear values; alpha is averaged as it
//! is. Where a size halves exactly this is the mean of each 2×2 block, and level k the mean of
//! each 2^k × 2^k block of the texture; a texel of a level halved from an odd size n covers
//! n / ⌊n/2⌋ texels of the level above (2.5 for 5 → 2), its end texels with fractional weights,
//! so every texel above counts equally and none is dropped.

use crate::scene::Rgba8Image;
use anyhow::{Result, bail};

/// The number of levels of a `width` × `height` texture's full chain (down to 1×1).
pub fn level_count(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

/// The size of `level` of a `width` × `height` texture (each level halves, rounding down, to 1).
pub fn level_size((width, height): (u32, u32), level: u32) -> (u32, u32) {
    ((width >> level).max(1), (height >> level).max(1))
}

/// Levels 1.. of `image`'s chain, sRGB-encoded like it (level 0 is `image` itself). Errors on
/// an empty image or one whose pixel count does not match its size.
pub fn levels(image: &Rgba8Image) -> Result<Vec<Rgba8Image>> {
    let (w, h) = (image.width, image.height);
    if w == 0 || h == 0 {
        bail!("a texture of {w}×{h} texels has no mip chain");
    }
    if image.pixels.len() != 4 * w as usize * h as usize {
        bail!("a {w}×{h} texture holds {} bytes, not {}", image.pixels.len(), 4 * w as usize * h as usize);
    }
    let decode = decode_table();
    let texel = |i: usize| {
        let p = &image.pixels[4 * i..][..4];
        [decode[p[0] as usize], decode[p[1] as usize], decode[p[2] as usize], f32::from(p[3]) / 255.0]
    };
    let encoder = Encoder::new();
    let mut size = (w, h);
    // The level above in linear light; level 0 is read from the image's codes as it is needed.
    let mut linear: Option<Vec<[f32; 4]>> = None;
    let mut out = Vec::new();
    for level in 1..level_count(w, h) {
        let next = level_size((w, h), level);
        let halves = size.0 == 2 * next.0 && size.1 == 2 * next.1;
        let filtered = match (&linear, halves) {
            (None, true) => halve(size, texel),
            (Some(above), true) => halve(size, |i| above[i]),
            (None, false) => box_filter(&(0..(w * h) as usize).map(texel).collect::<Vec<_>>(), size, next),
            (Some(above), false) => box_filter(above, size, next),
        };
        size = next;
        let pixels = filtered
            .iter()
            .flat_map(|t| [encoder.code(t[0]), encoder.code(t[1]), encoder.code(t[2]), (t[3] * 255.0).round() as u8])
            .collect();
        out.push(Rgba8Image { width: size.0, height: size.1, pixels });
        linear = Some(filtered);
    }
    Ok(out)
}

/// A sampled `Rgba8UnormSrgb` texture holding `image` and its whole chain ([`levels`]), as a
/// view of every level.
pub fn upload(device: &wgpu::Device, queue: &wgpu::Queue, label: &str, image: &Rgba8Image) -> Result<wgpu::TextureView> {
    let chain = levels(image)?;
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: image.width, height: image.height, depth_or_array_layers: 1 },
        mip_level_count: level_count(image.width, image.height),
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, l) in std::iter::once(image).chain(&chain).enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: level as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &l.pixels,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * l.width), rows_per_image: None },
            wgpu::Extent3d { width: l.width, height: l.height, depth_or_array_layers: 1 },
        );
    }
    Ok(texture.create_view(&Default::default()))
}

/// Each 8-bit sRGB code's linear value.
fn decode_table() -> [f32; 256] {
    std::array::from_fn(|c| crate::colour::srgb_to_linear(c as f32 / 255.0))
}

/// The linear values half-way (in sRGB) between consecutive codes: a linear value encodes to
/// the number of thresholds at or below it, which is `round(255 · linear_to_srgb(v))`.
fn encode_thresholds() -> [f32; 255] {
    std::array::from_fn(|k| crate::colour::srgb_to_linear((k as f32 + 0.5) / 255.0))
}

/// Linear values to 8-bit sRGB codes, rounded as `round(255 · linear_to_srgb(v))`: the code is
/// the number of [`encode_thresholds`] at or below `v`, found from a 4096-bucket table of the
/// code at each bucket's start and at most one step on (consecutive thresholds are at least
/// 1 / (255 · 12.92) > 1/4096 apart).
struct Encoder {
    thresholds: [f32; 255],
    start: Vec<u8>,
}

const BUCKETS: usize = 4096;

impl Encoder {
    fn new() -> Encoder {
        let thresholds = encode_thresholds();
        let start = (0..=BUCKETS).map(|b| thresholds.partition_point(|&t| t <= b as f32 / BUCKETS as f32) as u8).collect();
        Encoder { thresholds, start }
    }

    fn code(&self, v: f32) -> u8 {
        let mut code = self.start[(v.clamp(0.0, 1.0) * BUCKETS as f32) as usize];
        while code < 255 && self.thresholds[code as usize] <= v {
            code += 1;
        }
        code
    }
}

/// The 1-D box filter from `n` texels to `m` (m ≤ n): per output texel, the source texels it
/// covers and the share of its width each covers (they sum to 1).
fn taps(n: u32, m: u32) -> Vec<Vec<(usize, f32)>> {
    let scale = f64::from(n) / f64::from(m);
    (0..m)
        .map(|i| {
            let (a, b) = (f64::from(i) * scale, f64::from(i + 1) * scale);
            (a.floor() as usize..(b.ceil() as usize).min(n as usize))
                .map(|j| (j, ((b.min(j as f64 + 1.0) - a.max(j as f64)) / scale) as f32))
                .filter(|&(_, w)| w > 0.0)
                .collect()
        })
        .collect()
}

/// The level below a `from`-sized level whose sides both halve exactly: the mean of each 2×2
/// block (the general [`box_filter`]'s result, without its per-texel weights: the 2048² truck
/// texture's first level is most of the chain's work).
/// Rows are shared out among the CPU's threads.
fn halve(from: (u32, u32), texel: impl Fn(usize) -> [f32; 4] + Sync) -> Vec<[f32; 4]> {
    let (fw, tw, th) = (from.0 as usize, from.0 as usize / 2, from.1 as usize / 2);
    let mut out = vec![[0.0f32; 4]; tw * th];
    // Threads only where a level is large enough to pay for them.
    let threads = if tw * th < 1 << 16 { 1 } else { std::thread::available_parallelism().map_or(1, |n| n.get()).min(th) };
    let rows = th.div_ceil(threads);
    let texel = &texel;
    std::thread::scope(|scope| {
        for (chunk, part) in out.chunks_mut(rows * tw).enumerate() {
            scope.spawn(move || {
                for (r, row) in part.chunks_exact_mut(tw).enumerate() {
                    let y = chunk * rows + r;
                    let (top, bottom) = (2 * y * fw, (2 * y + 1) * fw);
                    for (x, t) in row.iter_mut().enumerate() {
                        let [a, b, c, d] = [texel(top + 2 * x), texel(top + 2 * x + 1), texel(bottom + 2 * x), texel(bottom + 2 * x + 1)];
                        *t = std::array::from_fn(|k| 0.25 * (a[k] + b[k] + c[k] + d[k]));
                    }
                }
            });
        }
    });
    out
}

/// `src` (`from`, row-major) box-filtered to `to`: rows first, then columns.
fn box_filter(src: &[[f32; 4]], from: (u32, u32), to: (u32, u32)) -> Vec<[f32; 4]> {
    let (columns, rows) = (taps(from.0, to.0), taps(from.1, to.1));
    let (fw, tw) = (from.0 as usize, to.0 as usize);
    let mut across = vec![[0.0f32; 4]; tw * from.1 as usize];
    for (y, row) in src.chunks_exact(fw).enumerate() {
        for (x, taps) in columns.iter().enumerate() {
            across[y * tw + x] = weighted(taps.iter().map(|&(j, w)| (row[j], w)));
        }
    }
    let mut out = vec![[0.0f32; 4]; tw * to.1 as usize];
    for (y, taps) in rows.iter().enumerate() {
        for x in 0..tw {
            out[y * tw + x] = weighted(taps.iter().map(|&(j, w)| (across[j * tw + x], w)));
        }
    }
    out
}

fn weighted(texels: impl Iterator<Item = ([f32; 4], f32)>) -> [f32; 4] {
    let mut sum = [0.0f32; 4];
    for (t, w) in texels {
        sum.iter_mut().zip(t).for_each(|(s, v)| *s += w * v);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_counts_and_sizes() {
        // 2048² → 12 levels (2048 ... 1); 1×1 has one; a 5×3 texture halves to 2×1 then 1×1.
        assert_eq!(level_count(2048, 2048), 12);
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(5, 3), 3);
        assert_eq!(level_size((5, 3), 1), (2, 1));
        assert_eq!(level_size((5, 3), 2), (1, 1));
        assert_eq!(level_size((2048, 512), 11), (1, 1));
    }

    #[test]
    fn odd_sizes_weigh_every_source_texel_equally() {
        // 5 texels to 2: each output covers 2.5 source texels, the middle one split in half.
        let t = taps(5, 2);
        assert_eq!(t[0], vec![(0, 0.4), (1, 0.4), (2, 0.2)]);
        assert_eq!(t[1], vec![(2, 0.2), (3, 0.4), (4, 0.4)]);
        // Every source texel's total weight is m / n of the total.
        for (n, m) in [(5, 2), (7, 3), (3, 1), (640, 320), (1000, 1)] {
            let mut per = vec![0.0f32; n as usize];
            taps(n, m).iter().flatten().for_each(|&(j, w)| per[j] += w);
            per.iter().for_each(|&w| assert!((w - m as f32 / n as f32).abs() < 1e-5, "{n}→{m}: {per:?}"));
        }
    }

    #[test]
    fn encoding_rounds_like_the_formula() {
        let (dec, encoder) = (decode_table(), Encoder::new());
        for c in 0..=255u8 {
            assert_eq!(encoder.code(dec[c as usize]), c);
        }
        let thresholds = encode_thresholds();
        for i in 0..=100_000 {
            let v = i as f32 / 100_000.0;
            // The table's answer is the search's, and the formula's away from a tie.
            assert_eq!(encoder.code(v), thresholds.partition_point(|&t| t <= v) as u8, "{v}");
            let exact = 255.0 * crate::colour::linear_to_srgb(v);
            if (exact - exact.floor() - 0.5).abs() > 1e-3 {
                assert_eq!(encoder.code(v), exact.round() as u8, "{v}");
            }
        }
    }

    /// sRGB decode in f64, written out here rather than taken from `crate::colour`.
    fn decode64(code: u8) -> f64 {
        let c = f64::from(code) / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    }

    fn encode64(v: f64) -> f64 {
        255.0 * if v <= 0.0031308 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
    }

    /// A `w`×`h` image of pseudo-random bytes (a fixed linear congruential sequence).
    fn noise(w: u32, h: u32, seed: u64) -> Rgba8Image {
        let mut x = seed;
        let pixels = (0..4 * w * h)
            .map(|_| {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (x >> 56) as u8
            })
            .collect();
        Rgba8Image { width: w, height: h, pixels }
    }

    #[test]
    fn each_level_is_the_linear_mean_of_its_block_of_the_texture() {
        // A power-of-two texture: level k's texel (x, y) is the mean, in linear light, of the
        // 2^k × 2^k block of level 0 at (2^k x, 2^k y), computed here directly from level 0 in
        // f64 (not level by level), encoded and compared with the stored code: within the
        // rounding to 8 bits (half a code) and f32 arithmetic.
        let image = noise(64, 16, 7);
        let chain = levels(&image).unwrap();
        assert_eq!(chain.len(), 6);
        let mut worst = 0.0f64;
        for (k, level) in chain.iter().enumerate() {
            let block = 1usize << (k + 1);
            assert_eq!((level.width, level.height), level_size((64, 16), k as u32 + 1));
            for y in 0..level.height as usize {
                for x in 0..level.width as usize {
                    let mut sum = [0.0f64; 4];
                    let (bx, by) = (block.min(64), block.min(16));
                    for v in y * by..(y + 1) * by {
                        for u in x * bx..(x + 1) * bx {
                            let p = &image.pixels[4 * (v * 64 + u)..][..4];
                            for (c, (s, &code)) in sum.iter_mut().zip(p).enumerate() {
                                *s += if c < 3 { decode64(code) } else { f64::from(code) / 255.0 };
                            }
                        }
                    }
                    let n = (bx * by) as f64;
                    let stored = &level.pixels[4 * (y * level.width as usize + x)..][..4];
                    for (c, (s, &code)) in sum.iter().zip(stored).enumerate() {
                        let want = if c < 3 { encode64(s / n) } else { 255.0 * s / n };
                        worst = worst.max((f64::from(code) - want).abs());
                    }
                }
            }
        }
        assert!(worst <= 0.501, "a level is {worst} codes from its block's linear mean");
        // Averaging the codes instead (in sRGB) would be visibly darker: the mean of 0 and 255
        // is 188 in linear light, 128 in sRGB.
        let checker = Rgba8Image { width: 2, height: 1, pixels: vec![0, 0, 0, 255, 255, 255, 255, 255] };
        assert_eq!(levels(&checker).unwrap()[0].pixels, vec![188, 188, 188, 255]);
    }

    #[test]
    fn the_last_level_of_an_odd_texture_is_its_mean() {
        // Box filters with weights summing to one keep the mean; every texel of 7×5 and 5×3
        // counts equally, so the 1×1 level is the whole texture's linear mean.
        for (w, h, seed) in [(7, 5, 1), (5, 3, 2), (3, 1, 3), (1, 6, 4)] {
            let image = noise(w, h, seed);
            let last = levels(&image).unwrap().pop().unwrap();
            assert_eq!((last.width, last.height), (1, 1));
            let n = f64::from(w * h);
            for c in 0..4 {
                let mean =
                    image.pixels.chunks_exact(4).map(|p| if c < 3 { decode64(p[c]) } else { f64::from(p[c]) / 255.0 }).sum::<f64>() / n;
                let want = if c < 3 { encode64(mean) } else { 255.0 * mean };
                assert!((f64::from(last.pixels[c]) - want).abs() <= 0.501, "{w}×{h} channel {c}: {} for {want}", last.pixels[c]);
            }
        }
    }

    #[test]
    fn bad_images_are_errors() {
        assert!(levels(&Rgba8Image { width: 0, height: 4, pixels: vec![] }).is_err());
        assert!(levels(&Rgba8Image { width: 2, height: 2, pixels: vec![0; 12] }).is_err());
        assert!(levels(&Rgba8Image { width: 1, height: 1, pixels: vec![0; 4] }).unwrap().is_empty());
    }
}
