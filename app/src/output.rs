//! Writing output files so that a failure never leaves a partial file behind: everything is
//! written to a temporary file beside the target and renamed into place only when complete.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Write `bytes` to `path` atomically (temporary sibling + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = temp_sibling(path);
    let result =
        std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path)).with_context(|| format!("cannot write {}", path.display()));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Image files we write, by extension (lower case).
pub const IMAGE_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

/// Check that `path` names an image file we can write: not empty, an extension from
/// [`IMAGE_EXTENSIONS`], not a directory. The error says what is wrong; callers add the flag or
/// key.
pub fn check_image_path(path: &Path) -> Result<()> {
    if path.as_os_str().is_empty() {
        anyhow::bail!("the output path is empty");
    }
    if path.is_dir() {
        anyhow::bail!("{} is a directory, not an image file", path.display());
    }
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if !IMAGE_EXTENSIONS.contains(&ext.as_str()) {
        anyhow::bail!("{}: unsupported image extension {ext:?} (expected .png, .jpg or .jpeg)", path.display());
    }
    Ok(())
}

/// Write an opaque-or-not 8-bit RGBA image as PNG, or as JPEG (quality 92, alpha dropped) when
/// the extension is .jpg/.jpeg; any other extension is an error naming the file.
pub fn write_image_rgba8(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    check_image_path(path)?;
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if ext == "png" {
        return write_png_rgba8(path, width, height, rgba);
    }
    use image::ImageEncoder;
    let rgb: Vec<u8> = rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, 92)
        .write_image(&rgb, width, height, image::ExtendedColorType::Rgb8)
        .context("JPEG encoding failed")?;
    write_atomic(path, &buf)
}

/// Encode an 8-bit RGBA image as PNG in memory and write it atomically.
pub fn write_png_rgba8(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    write_atomic(path, &encode_png(width, height, rgba, image::ExtendedColorType::Rgba8)?)
}

/// Encode an 8-bit RGB image as PNG in memory and write it atomically.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    write_atomic(path, &encode_png(width, height, rgb, image::ExtendedColorType::Rgb8)?)
}

fn encode_png(width: u32, height: u32, data: &[u8], ty: image::ExtendedColorType) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf).write_image(data, width, height, ty).context("PNG encoding failed")?;
    Ok(buf)
}

/// Write a `width`×`height` OpenEXR of 32-bit float channels, one part, scan lines with ZIP
/// compression (lossless; every OpenEXR reader decodes it). `channels`: (name, plane row-major
/// from the top-left pixel); the file lists them sorted by name, as the format requires.
pub fn write_exr_f32(path: &Path, width: u32, height: u32, channels: Vec<(&str, Vec<f32>)>) -> Result<()> {
    use exr::prelude::*;
    let pixels = width as usize * height as usize;
    if pixels == 0 || channels.is_empty() {
        anyhow::bail!("{}: an EXR needs at least one pixel and one channel", path.display());
    }
    if let Some((name, plane)) = channels.iter().find(|(_, plane)| plane.len() != pixels) {
        anyhow::bail!("{}: channel {name} has {} samples for {width}x{height} pixels", path.display(), plane.len());
    }
    let list = channels.into_iter().map(|(name, plane)| AnyChannel::new(name, FlatSamples::F32(plane))).collect();
    let layer =
        Layer::new((width as usize, height as usize), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
    let mut buf = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut buf).with_context(|| format!("{}: EXR encoding failed", path.display()))?;
    write_atomic(path, buf.get_ref())
}

fn temp_sibling(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("previz-out-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("no/such/dir/out.png");
        assert!(write_atomic(&missing, b"x").is_err());
        let ok = dir.join("ok.bin");
        write_atomic(&ok, b"abc").unwrap();
        assert_eq!(std::fs::read(&ok).unwrap(), b"abc");
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
            .collect();
        assert!(leftovers.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exr_channels_round_trip_as_f32() {
        let dir = std::env::temp_dir().join(format!("previz-out-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("layers.exr");
        // Values f16 cannot hold (1e-7, 70000, 1 + 2^-20) and infinity must come back bit-exact.
        let z = vec![1e-7, 70000.0, 1.0 + 2f32.powi(-20), f32::INFINITY, 0.5, 2.0];
        let r = vec![0.25, 0.5, 0.75, 1.0, 1.25, 1.5];
        write_exr_f32(&path, 3, 2, vec![("depth.Z", z.clone()), ("R", r.clone())]).unwrap();
        let image = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        let channels = &image.layer_data.channel_data.list;
        let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
        assert_eq!(names, ["R", "depth.Z"]);
        assert_eq!(channels[0].sample_data.values_as_f32().collect::<Vec<_>>(), r);
        assert_eq!(channels[1].sample_data.values_as_f32().collect::<Vec<_>>(), z);
        let err = format!("{:#}", write_exr_f32(&path, 3, 3, vec![("R", r)]).unwrap_err());
        assert!(err.contains("channel R has 6 samples for 3x3 pixels") && err.contains("layers.exr"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn extension_chooses_the_format() {
        let dir = std::env::temp_dir().join(format!("previz-out-ext-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rgba = [200u8, 100, 50, 255].repeat(16);
        for (name, magic) in [("a.png", &b"\x89PNG"[..]), ("b.jpg", &[0xFF, 0xD8, 0xFF][..]), ("c.JPEG", &[0xFF, 0xD8, 0xFF][..])] {
            write_image_rgba8(&dir.join(name), 4, 4, &rgba).unwrap();
            assert!(std::fs::read(dir.join(name)).unwrap().starts_with(magic), "{name}");
        }
        for (name, needle) in [("d.tiff", "unsupported"), ("noext", "unsupported"), ("", "directory")] {
            let err = format!("{:#}", write_image_rgba8(&dir.join(name), 4, 4, &rgba).unwrap_err());
            assert!(err.contains(needle), "{name}: {err}");
        }
        assert!(format!("{:#}", check_image_path(Path::new("")).unwrap_err()).contains("empty"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
