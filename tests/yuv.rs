//! Camera YUV 4:2:0 → R'G'B' on the GPU (`camera::yuv`, `shaders/yuv.wgsl`) against the CPU
//! reference, for every layout the phone cameras deliver (NV12, NV21, I420), both colour
//! standards and both ranges, at odd sizes with padded rows; and back to the image it came from.

use crate::common;

use common::{data, gpu};
use previz::camera::yuv::{Layout, YuvConverter, YuvMatrix, YuvRange, from_rgba, to_rgba_cpu};
use previz::scene::Rgba8Image;

const LAYOUTS: [Layout; 3] = [Layout::Nv12, Layout::Nv21, Layout::I420];
const STANDARDS: [(YuvMatrix, YuvRange); 4] = [
    (YuvMatrix::Bt601, YuvRange::Full),
    (YuvMatrix::Bt601, YuvRange::Limited),
    (YuvMatrix::Bt709, YuvRange::Full),
    (YuvMatrix::Bt709, YuvRange::Limited),
];

fn max_diff(a: &Rgba8Image, b: &Rgba8Image) -> i32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.pixels.iter().zip(&b.pixels).map(|(x, y)| (i32::from(*x) - i32::from(*y)).abs()).max().unwrap_or(0)
}

/// A deterministic image with gradients, hard edges and per-pixel noise (a hash), so a wrong
/// stride, a swapped chroma pair or a chroma offset by one sample shows.
fn synthetic(w: u32, h: u32) -> Rgba8Image {
    let mut pixels = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let hash = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 61;
            let r = (x * 255 / w.max(2).saturating_sub(1)).min(255);
            let g = if (x / 3 + y / 2) % 2 == 0 { 200 } else { 40 };
            let b = (y * 255 / h.max(2).saturating_sub(1)).min(255);
            pixels.extend([(r + hash).min(255) as u8, (g + hash) as u8, (255 - b).saturating_sub(hash) as u8, 255]);
        }
    }
    Rgba8Image { width: w, height: h, pixels }
}

fn crop(img: &Rgba8Image, w: u32, h: u32) -> Rgba8Image {
    let mut pixels = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        let start = (4 * y * img.width) as usize;
        pixels.extend_from_slice(&img.pixels[start..start + 4 * w as usize]);
    }
    Rgba8Image { width: w, height: h, pixels }
}

#[test]
fn gpu_conversion_matches_the_cpu_reference_for_every_layout_standard_and_range() {
    let photo = image::open(data("photos/colour_transfer/coffee.png")).unwrap().to_rgba8();
    let photo = Rgba8Image { width: photo.width(), height: photo.height(), pixels: photo.into_raw() };
    // Odd sizes (the chroma plane rounds up) and row paddings that are not multiples of 4.
    let images = [(synthetic(37, 23), 5), (synthetic(1, 1), 3), (synthetic(64, 2), 0), (crop(&photo, 301, 199), 13)];
    let mut converter = YuvConverter::new(gpu());
    for (img, padding) in &images {
        for layout in LAYOUTS {
            for (matrix, range) in STANDARDS {
                let yuv = from_rgba(img, layout, matrix, range, *padding).unwrap();
                let frame = yuv.frame();
                converter.convert(gpu(), &frame).unwrap();
                let gpu_rgb = converter.read_back(gpu()).unwrap();
                let cpu_rgb = to_rgba_cpu(&frame).unwrap();
                // f32 on the GPU against f64 on the CPU: a value on a rounding boundary may land
                // one code away.
                let d = max_diff(&gpu_rgb, &cpu_rgb);
                assert!(
                    d <= 1,
                    "{}x{} {layout:?} {matrix:?} {range:?} padding {padding}: GPU differs from CPU by {d}",
                    img.width,
                    img.height
                );
            }
        }
    }
}

#[test]
fn images_of_two_by_two_blocks_come_back_within_quantisation() {
    // Constant 2×2 blocks lose nothing to 4:2:0 subsampling, so RGB → YUV → RGB differs from
    // the original only by rounding the code values: Y, Cb and Cr are each off by at most half a
    // code. The largest output coefficient is Cb → B (2 (1 − Kb) = 1.8556 for BT.709), so B is off
    // by at most 0.5 · 255/219 + 0.5 · 1.8556 · 255/224 + 0.5 (the final rounding) < 2.2 codes in
    // limited range and 0.5 + 0.5 · 1.8556 + 0.5 < 1.93 in full range: at most 2 and 1 codes.
    // Components stay in 16..=239 so no code value clips.
    let (w, h) = (24u32, 10u32);
    let mut pixels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (bx, by) = (x / 2, y / 2);
            pixels.extend([(16 + bx * 19 % 224) as u8, (16 + (bx * 7 + by * 53) % 224) as u8, (16 + by * 47 % 224) as u8, 255]);
        }
    }
    let img = Rgba8Image { width: w, height: h, pixels };
    let mut converter = YuvConverter::new(gpu());
    for layout in LAYOUTS {
        for (matrix, range) in STANDARDS {
            let yuv = from_rgba(&img, layout, matrix, range, 7).unwrap();
            converter.convert(gpu(), &yuv.frame()).unwrap();
            let back = converter.read_back(gpu()).unwrap();
            let bound = if range == YuvRange::Full { 1 } else { 2 };
            let d = max_diff(&back, &img);
            assert!(d <= bound, "{layout:?} {matrix:?} {range:?}: {d} codes from the original (bound {bound})");
        }
    }
}

#[test]
fn bad_frames_are_clear_errors_not_panics() {
    let img = synthetic(8, 6);
    let yuv = from_rgba(&img, Layout::Nv12, YuvMatrix::Bt601, YuvRange::Full, 0).unwrap();
    let mut frame = yuv.frame();
    frame.luma.data = &yuv.luma[..40];
    let mut converter = YuvConverter::new(gpu());
    let e = converter.convert(gpu(), &frame).unwrap_err().to_string();
    assert!(e.contains("luma plane") && e.contains("need 48"), "{e}");
    assert!(converter.read_back(gpu()).unwrap_err().to_string().contains("no YUV frame"));
}
