//! Loading 8-bit images (backgrounds, model textures): JPEG or PNG, sRGB-encoded, turned upright
//! according to the EXIF orientation tag the way a photo viewer shows them.

use super::Rgba8Image;
use anyhow::Result;
use image::{DynamicImage, ImageFormat};
use std::path::Path;

/// Load a JPEG or PNG as 8-bit sRGB RGBA, top row first.
///
/// The format is recognised from the file's content (a `.jpg` that is really a PNG loads);
/// anything other than JPEG or PNG is an error naming the file. A JPEG's EXIF orientation is
/// applied. 16-bit PNGs are rounded to 8 bits; grey images are expanded to RGB.
pub fn load_image(path: &Path) -> Result<Rgba8Image> {
    let decoded = super::decode::decode_file(path, &[ImageFormat::Jpeg, ImageFormat::Png])?;
    let mut image = decoded.image;
    image.apply_orientation(decoded.orientation);
    Ok(rgba8_from_dynamic(&image))
}

/// Any decoded image as 8-bit RGBA (no transfer-function change: 8-bit sources are assumed
/// sRGB-encoded, as JPEG and PNG files are).
pub fn rgba8_from_dynamic(image: &DynamicImage) -> Rgba8Image {
    let rgba = image.to_rgba8();
    Rgba8Image { width: rgba.width(), height: rgba.height(), pixels: rgba.into_raw() }
}

/// Scale and centre-crop `img` to exactly `width`×`height` (aspect fill, like a camera preview),
/// filtering in linear light is not needed for a photo background: sRGB values are resampled
/// with a Catmull-Rom filter. (Written by the renderer's author; kept here beside the loader.)
pub fn fit(img: &Rgba8Image, width: u32, height: u32) -> Rgba8Image {
    if (img.width, img.height) == (width, height) {
        return img.clone();
    }
    if img.width == 0 || img.height == 0 {
        return Rgba8Image { width, height, pixels: [0, 0, 0, 255].repeat((width * height) as usize) };
    }
    let scale = (width as f64 / img.width as f64).max(height as f64 / img.height as f64);
    let crop_w = ((width as f64 / scale).round() as u32).clamp(1, img.width);
    let crop_h = ((height as f64 / scale).round() as u32).clamp(1, img.height);
    let x = (img.width - crop_w) / 2;
    let y = (img.height - crop_h) / 2;
    let Some(buffer) = image::RgbaImage::from_raw(img.width, img.height, img.pixels.clone()) else {
        // A malformed buffer cannot come from the loaders; fall back to a black frame.
        return Rgba8Image { width, height, pixels: [0, 0, 0, 255].repeat((width * height) as usize) };
    };
    let cropped = image::imageops::crop_imm(&buffer, x, y, crop_w, crop_h).to_image();
    let resized = image::imageops::resize(&cropped, width, height, image::imageops::FilterType::CatmullRom);
    Rgba8Image { width, height, pixels: resized.into_raw() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageEncoder, RgbImage};

    fn temp_dir(tag: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("previz-bg-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A minimal little-endian EXIF (TIFF) block with one IFD entry: Orientation (0x0112,
    /// SHORT) = `value` (TIFF 6.0 §2 header and IFD layout; EXIF 2.32 tag 274).
    fn exif_orientation(value: u16) -> Vec<u8> {
        let mut b = b"II*\0".to_vec();
        b.extend_from_slice(&8u32.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&0x0112u16.to_le_bytes());
        b.extend_from_slice(&3u16.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
        b.extend_from_slice(&[0, 0]);
        b.extend_from_slice(&0u32.to_le_bytes());
        b
    }

    #[test]
    fn exif_rotation_is_applied() {
        // 32x16, left half red, right half blue; orientation 6 = "rotate 90° clockwise to
        // display", so the upright image is 16x32 with red on top.
        let img = RgbImage::from_fn(32, 16, |x, _| if x < 16 { image::Rgb([255, 0, 0]) } else { image::Rgb([0, 0, 255]) });
        let mut jpeg = Vec::new();
        let mut enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95);
        enc.set_exif_metadata(exif_orientation(6)).unwrap();
        enc.write_image(img.as_raw(), 32, 16, image::ExtendedColorType::Rgb8).unwrap();
        let dir = temp_dir("exif");
        let path = dir.join("rotated.jpg");
        std::fs::write(&path, &jpeg).unwrap();
        let loaded = load_image(&path).unwrap();
        assert_eq!((loaded.width, loaded.height), (16, 32));
        let top = &loaded.pixels[(4 * 16 + 8) * 4..][..3];
        let bottom = &loaded.pixels[(28 * 16 + 8) * 4..][..3];
        assert!(top[0] > 200 && top[2] < 60, "top {top:?}");
        assert!(bottom[2] > 200 && bottom[0] < 60, "bottom {bottom:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn fit_fills_and_centre_crops() {
        // 8x4, left quarter red, the rest blue, fitted into 4x4: the scale is 1 (height fits),
        // the centre 4 columns are kept, all blue.
        let mut pixels = Vec::new();
        for _y in 0..4 {
            for x in 0..8 {
                pixels.extend_from_slice(if x < 2 { &[255, 0, 0, 255] } else { &[0, 0, 255, 255] });
            }
        }
        let img = Rgba8Image { width: 8, height: 4, pixels };
        let out = fit(&img, 4, 4);
        assert_eq!((out.width, out.height), (4, 4));
        assert!(out.pixels.chunks(4).all(|p| p == [0, 0, 255, 255]));
        // Same size: unchanged.
        assert_eq!(fit(&img, 8, 4).pixels, img.pixels);
    }

    #[test]
    fn unsupported_and_garbage_files_are_errors() {
        let dir = temp_dir("bad");
        let txt = dir.join("notes.png");
        std::fs::write(&txt, b"this is not an image").unwrap();
        let err = format!("{:#}", load_image(&txt).unwrap_err());
        assert!(err.contains("notes.png"), "{err}");
        let hdr = dir.join("x.hdr");
        let mut bytes = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut bytes).encode(&[image::Rgb([1.0f32, 1.0, 1.0])], 1, 1).unwrap();
        std::fs::write(&hdr, &bytes).unwrap();
        let err = format!("{:#}", load_image(&hdr).unwrap_err());
        assert!(err.contains("x.hdr") && err.contains("Jpeg or Png"), "{err}");
        let err = format!("{:#}", load_image(&dir.join("missing.jpg")).unwrap_err());
        assert!(err.contains("missing.jpg"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
