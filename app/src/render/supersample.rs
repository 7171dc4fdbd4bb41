//! Supersampling of a still: the frame drawn at k× the output's width and height, each output
//! pixel the box-filtered mean of its k × k samples in linear light — the pixel's integral that
//! the path-traced references take (tests/reference: a box reconstruction filter), which one
//! shading sample per pixel misses where the shading varies within a pixel (a scan's bumps, a
//! texture's detail, a self-shadow's edge). Multisampling only antialiases coverage; this
//! integrates the shading too.
//!
//! The factor is chosen on the accuracy-versus-cost chart of `previz bench accuracy`
//! (docs/accuracy.md, "Fourteenth session"): [`STILL_FACTOR`], fewer where the output is so
//! large that the samples would pass [`SAMPLE_BUDGET`] or the device's texture limit.

use super::antialiasing::Antialiasing;
use super::layers::{LayerImages, compose};
use crate::colour::{linear_to_srgb, srgb_to_linear};

/// Samples per side of each output pixel of a still (`setup::prepare`).
pub const STILL_FACTOR: u32 = 3;

/// Most pixels a supersampled still is drawn at (8 Mi: a 960×640 still keeps 3×, a 1920×1080
/// one gets 2×): the targets of the frame and of its float layers grow with it.
pub const SAMPLE_BUDGET: u64 = 1 << 23;

/// The antialiasing of a still drawn at `k` × `k` samples a pixel: none beyond them when there
/// are several (measured with `previz bench accuracy`, 2026-12-02 on lavapipe: 3 × 3 samples of
/// one sample each against 3 × 3 of 4× MSAA, ROI FLIP the same to three decimals on three
/// reference scenes and 0.001 lower on two, quarry_bunny and quarry_truck, at 39–61 % less GPU
/// time), else [`Antialiasing::STILL`].
pub fn antialiasing(k: u32) -> Antialiasing {
    if k > 1 { Antialiasing::Msaa(1) } else { Antialiasing::STILL }
}

/// The factor for a `width` × `height` still: the largest k ≤ `wanted` whose k·width × k·height
/// samples stay within [`SAMPLE_BUDGET`] and `max_side` per side; at least 1.
pub fn factor_for(width: u32, height: u32, wanted: u32, max_side: u32) -> u32 {
    let pixels = u64::from(width) * u64::from(height);
    (1..=wanted.max(1))
        .rev()
        .find(|&k| {
            let k64 = u64::from(k);
            pixels * k64 * k64 <= SAMPLE_BUDGET
                && u64::from(width) * k64 <= u64::from(max_side)
                && u64::from(height) * k64 <= u64::from(max_side)
        })
        .unwrap_or(1)
}

/// The mean of each `k` × `k` block of a `width` × `height` (the samples') row-major image of
/// `N` channels: the (width / k) × (height / k) image.
pub fn box_mean<const N: usize>(samples: &[[f32; N]], (width, height): (u32, u32), k: u32) -> Vec<[f32; N]> {
    let k = k.max(1) as usize;
    let (w, h) = (width as usize / k, height as usize / k);
    let scale = 1.0 / (k * k) as f32;
    let mut out = vec![[0f32; N]; w * h];
    for (y, row) in out.chunks_exact_mut(w.max(1)).enumerate().take(h) {
        for (x, px) in row.iter_mut().enumerate() {
            let mut sum = [0f32; N];
            for dy in 0..k {
                let line = (y * k + dy) * width as usize + x * k;
                for s in &samples[line..line + k] {
                    sum.iter_mut().zip(s).for_each(|(a, b)| *a += b);
                }
            }
            *px = sum.map(|v| v * scale);
        }
    }
    out
}

/// [`box_mean`] of an sRGB-encoded RGBA8 image: colour averaged in linear light and encoded
/// again, alpha averaged as it is.
pub fn box_mean_srgb8(rgba: &[u8], size: (u32, u32), k: u32) -> Vec<u8> {
    let linear: Vec<[f32; 4]> = rgba
        .chunks_exact(4)
        .map(|p| {
            [
                srgb_to_linear(f32::from(p[0]) / 255.0),
                srgb_to_linear(f32::from(p[1]) / 255.0),
                srgb_to_linear(f32::from(p[2]) / 255.0),
                f32::from(p[3]) / 255.0,
            ]
        })
        .collect();
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    box_mean(&linear, size, k)
        .iter()
        .flat_map(|p| [byte(linear_to_srgb(p[0])), byte(linear_to_srgb(p[1])), byte(linear_to_srgb(p[2])), byte(p[3])])
        .collect()
}

/// A `width` × `height` RGBA8 image at `k`× its size, each pixel repeated over its k × k block:
/// what [`box_mean_srgb8`] takes back to the same bytes.
pub fn repeat_pixels(rgba: &[u8], (width, height): (u32, u32), k: u32) -> Vec<u8> {
    let (w, k) = (width as usize, k.max(1) as usize);
    let mut out = Vec::with_capacity(rgba.len() * k * k);
    for row in rgba.chunks_exact(4 * w.max(1)).take(height as usize) {
        let line: Vec<u8> = row.chunks_exact(4).flat_map(|p| std::iter::repeat_n(p, k).flatten().copied()).collect();
        for _ in 0..k {
            out.extend_from_slice(&line);
        }
    }
    out
}

/// The shadow matte of a pixel from the means of its samples: what its uncovered background
/// (`(1 − α)·background`) must be multiplied by for the model over it to give the mean `beauty`,
/// so that the layers still compose to the beauty ([`compose`]); where nothing of the
/// background shows, or the quotient leaves the matte's range 0..=2
/// (render::passes::ground::SCALE), the samples' mean matte.
fn pixel_matte(beauty: [f32; 4], model: [f32; 4], background: [f32; 4], mean_matte: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|c| {
        let under = (1.0 - model[3]) * background[c];
        let m = (beauty[c] - model[c]) / under;
        if under > 1e-6 && (0.0..=2.0).contains(&m) { m } else { mean_matte[c] }
    })
}

/// The layers of a still drawn at `k`× ([`LayerImages`] at the samples' size) at the output's
/// size: model, background and beauty are box means; the matte is [`pixel_matte`] and the
/// beauty is then recomposed from the layers, so they still compose to it exactly; the depth is
/// the nearest of the samples nearest the pixel's centre (the centre sample for an odd `k`, the
/// middle four for an even one), so it stays the distance at the pixel's centre.
pub fn layers_mean(fine: LayerImages, k: u32) -> LayerImages {
    let k = k.max(1);
    if k == 1 {
        return fine;
    }
    let size = (fine.width, fine.height);
    let (width, height) = (fine.width / k, fine.height / k);
    let model = box_mean(&fine.model, size, k);
    let background = box_mean(&fine.background, size, k);
    let beauty_mean = box_mean(&fine.beauty, size, k);
    let mean_matte = box_mean(&fine.matte, size, k);
    let matte: Vec<[f32; 3]> = (0..model.len()).map(|i| pixel_matte(beauty_mean[i], model[i], background[i], mean_matte[i])).collect();
    let beauty = model.iter().zip(&background).zip(&matte).map(|((&m, &b), &s)| compose(m, b, s)).collect();
    let middle: Vec<u32> = if k % 2 == 1 { vec![k / 2] } else { vec![k / 2 - 1, k / 2] };
    let depth = (0..(width * height) as usize)
        .map(|i| {
            let (x, y) = (i as u32 % width, i as u32 / width);
            let at = |dx: u32, dy: u32| fine.depth[((y * k + dy) * fine.width + x * k + dx) as usize];
            middle.iter().flat_map(|&dy| middle.iter().map(move |&dx| (dx, dy))).map(|(dx, dy)| at(dx, dy)).fold(f32::INFINITY, f32::min)
        })
        .collect();
    LayerImages { width, height, beauty, model, matte, background, depth }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_black_and_white_checkerboard_averages_to_half_its_light() {
        // Each output pixel covers 2 × 2 samples, two black and two white: linear 0.5, which
        // sRGB encodes as 0.7354 (IEC 61966-2-1: 1.055 · 0.5^(1/2.4) − 0.055) → 188 of 255, not
        // the 128 that averaging the encoded bytes would give.
        let (w, h) = (4u32, 2u32);
        let rgba: Vec<u8> =
            (0..w * h).flat_map(|i| if ((i % w) + (i / w)) % 2 == 0 { [255, 255, 255, 255] } else { [0, 0, 0, 255] }).collect();
        let out = box_mean_srgb8(&rgba, (w, h), 2);
        assert_eq!(out, vec![188, 188, 188, 255, 188, 188, 188, 255]);
    }

    #[test]
    fn a_repeated_image_averages_back_to_its_bytes() {
        // Every byte value in a 16 × 16 image: decoding, averaging 9 equal samples and encoding
        // again returns each byte exactly.
        let rgba: Vec<u8> = (0..=255u8).flat_map(|v| [v, 255 - v, v / 2, 255]).collect();
        let up = repeat_pixels(&rgba, (16, 16), 3);
        assert_eq!(up.len(), rgba.len() * 9);
        assert_eq!(&up[..12], &[0, 255, 0, 255, 0, 255, 0, 255, 0, 255, 0, 255]);
        assert_eq!(box_mean_srgb8(&up, (48, 48), 3), rgba);
    }

    #[test]
    fn box_mean_takes_each_block_and_nothing_else() {
        // A 6 × 3 ramp (value = index) at k = 3: the blocks' means are 7 and 10.
        let samples: Vec<[f32; 1]> = (0..18).map(|i| [i as f32]).collect();
        assert_eq!(box_mean(&samples, (6, 3), 3), vec![[7.0], [10.0]]);
        assert_eq!(box_mean(&samples, (6, 3), 1), samples);
    }

    #[test]
    fn the_factor_keeps_within_the_budget_and_the_device() {
        assert_eq!(factor_for(320, 240, 3, 8192), 3);
        assert_eq!(factor_for(960, 640, 3, 8192), 3);
        // 1920 × 1080 × 9 = 18.7 M samples is over 8 Mi; × 4 = 8.3 M is under.
        assert_eq!(factor_for(1920, 1080, 3, 8192), 2);
        assert_eq!(factor_for(4000, 3000, 3, 8192), 1);
        // A 3000-wide still on a device of 8192 per side: 2 × 3000 fits, 3 × 3000 does not.
        assert_eq!(factor_for(3000, 10, 3, 8192), 2);
        assert_eq!(factor_for(320, 240, 0, 8192), 1);
    }

    fn layers(width: u32, height: u32, f: impl Fn(u32, u32) -> ([f32; 4], [f32; 4], [f32; 3], f32)) -> LayerImages {
        let mut l = LayerImages { width, height, beauty: vec![], model: vec![], matte: vec![], background: vec![], depth: vec![] };
        for y in 0..height {
            for x in 0..width {
                let (m, b, s, d) = f(x, y);
                l.model.push(m);
                l.background.push(b);
                l.matte.push(s);
                l.beauty.push(compose(m, b, s));
                l.depth.push(d);
            }
        }
        l
    }

    #[test]
    fn supersampled_layers_still_compose_to_the_mean_beauty() {
        // 3 × 3 samples: the model (linear 0.9 grey, opaque) covers the left column, the ground's
        // shadow (matte 0.2) lies under the middle one, the background is 0.5 everywhere. The
        // pixel's mean beauty is (3 · 0.9 + 3 · 0.1 + 3 · 0.5) / 9 = 0.5; its model is 0.3 with α
        // 1/3, so the uncovered background (2/3 · 0.5) must keep (0.5 − 0.3)/(1/3) = 0.6 of its
        // light: the mean of the uncovered columns' mattes (0.2 and 1), not the mean of all
        // three (0.733), which would make the layers compose to 0.544.
        let fine = layers(3, 3, |x, y| match x {
            0 => ([0.9, 0.9, 0.9, 1.0], [0.5; 4], [1.0; 3], 2.0 + y as f32),
            1 => ([0.0; 4], [0.5; 4], [0.2; 3], f32::INFINITY),
            _ => ([0.0; 4], [0.5; 4], [1.0; 3], f32::INFINITY),
        });
        let px = layers_mean(fine, 3);
        assert_eq!((px.width, px.height), (1, 1));
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        assert!(close(px.model[0][3], 1.0 / 3.0) && close(px.model[0][0], 0.3), "{:?}", px.model);
        assert!(close(px.matte[0][0], 0.6), "{:?}", px.matte);
        assert!(close(px.beauty[0][0], 0.5), "{:?}", px.beauty);
        assert_eq!(px.beauty[0], compose(px.model[0], px.background[0], px.matte[0]));
        // The centre sample (x 1) sees no model: the pixel's centre has no depth.
        assert_eq!(px.depth[0], f32::INFINITY);
        // Shift the model under the centre: the centre sample's distance.
        let fine = layers(3, 3, |x, y| {
            if x == 1 { ([0.9, 0.9, 0.9, 1.0], [0.5; 4], [1.0; 3], 2.0 + y as f32) } else { ([0.0; 4], [0.5; 4], [1.0; 3], f32::INFINITY) }
        });
        assert_eq!(layers_mean(fine, 3).depth[0], 3.0);
    }

    #[test]
    fn a_pixel_the_model_covers_keeps_the_mean_matte() {
        // Fully covered: no background shows, so the matte is the samples' mean.
        let fine = layers(2, 2, |x, _| ([0.4, 0.4, 0.4, 1.0], [0.5; 4], [if x == 0 { 0.2 } else { 1.0 }; 3], 1.0));
        let px = layers_mean(fine, 2);
        assert!((px.matte[0][1] - 0.6).abs() < 1e-6, "{:?}", px.matte);
        assert_eq!(px.beauty[0], compose(px.model[0], px.background[0], px.matte[0]));
        assert_eq!(px.depth[0], 1.0);
    }
}
