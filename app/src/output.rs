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
