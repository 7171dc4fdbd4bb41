//! Every image decode in the program goes through here, so that every one has the same limits:
//! a file whose header claims a huge size is an error naming the file, not a 30 GB allocation.
//!
//! Limits: at most [`MAX_SIDE`] pixels a side and [`MAX_DECODED_BYTES`] for the decoder's
//! output buffer (a 16384×16384 RGBA8 image fits; a 100000×100000 claim does not). OpenEXR
//! needs more: the image decoder checks the display window, but the exr crate decodes the data
//! window, zero-filling line buffers for all of it before it finds the data missing (a 760-byte
//! file whose data window claimed 167 772 168×4 pixels spent 8 s in page faults). So each EXR
//! part's data window is held to the same side limit, and its pixel bytes to what a file of its
//! size can hold (see [`MAX_EXR_EXPANSION`]), before anything is decoded.

use anyhow::{Context, Result, anyhow};
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};
use std::io::{BufRead, Seek};
use std::path::Path;

/// The largest width or height any decoded image may have.
pub const MAX_SIDE: u32 = 16384;
/// The largest buffer (bytes) a decoder may fill: 16384² RGBA8.
pub const MAX_DECODED_BYTES: u64 = 1 << 30;

/// The most uncompressed pixel bytes an OpenEXR file may claim per byte of file. No valid file
/// comes near: deflate (ZIP, ZIPS, and PXR24 after its 24-to-32-bit widening, ×4/3) compresses
/// at most 1032:1 (zlib's technical notes), RLE at most 64:1, PIZ's Huffman run code about
/// 450:1, B44/B44A about 11:1. So 1032 × 4/3 ≈ 1376, rounded up to a power of two.
pub const MAX_EXR_EXPANSION: u64 = 2048;

/// The limits every decode uses.
pub fn limits() -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_DECODED_BYTES);
    limits
}

/// A decoded image and the EXIF orientation its file asked for (not yet applied).
pub struct Decoded {
    pub image: DynamicImage,
    pub orientation: image::metadata::Orientation,
    pub format: ImageFormat,
}

/// Decode an image file (format from the content) within the limits. `allowed` (if not empty)
/// lists the formats accepted; anything else is an error naming the file.
pub fn decode_file(path: &Path, allowed: &[ImageFormat]) -> Result<Decoded> {
    let reader = ImageReader::open(path).with_context(|| format!("cannot open image {}", path.display()))?;
    let len = std::fs::metadata(path).with_context(|| format!("cannot open image {}", path.display()))?.len();
    decode_reader(reader, len, allowed).with_context(|| format!("image {}", path.display()))
}

/// Decode an in-memory image (format from the content) within the limits.
pub fn decode_bytes(bytes: &[u8], allowed: &[ImageFormat]) -> Result<Decoded> {
    decode_reader(ImageReader::new(std::io::Cursor::new(bytes)), bytes.len() as u64, allowed)
}

/// Decode `len` bytes of image data from `reader`.
fn decode_reader<R: BufRead + Seek>(reader: ImageReader<R>, len: u64, allowed: &[ImageFormat]) -> Result<Decoded> {
    let mut reader = reader.with_guessed_format().context("cannot read")?;
    let format = reader.format().ok_or_else(|| anyhow!("unrecognised content (not an image?)"))?;
    if format == ImageFormat::OpenExr {
        let mut inner = reader.into_inner();
        let start = inner.stream_position().context("cannot read")?;
        check_exr_claims(&mut inner, len)?;
        inner.seek(std::io::SeekFrom::Start(start)).context("cannot read")?;
        reader = ImageReader::with_format(inner, format);
    }
    if !allowed.is_empty() && !allowed.contains(&format) {
        let names: Vec<String> = allowed.iter().map(|f| format!("{f:?}")).collect();
        return Err(anyhow!("{format:?} images are not supported here ({} expected)", names.join(" or ")));
    }
    reader.limits(limits());
    let mut decoder = reader.into_decoder().map_err(|e| anyhow!(e)).context("cannot decode")?;
    let (w, h) = decoder.dimensions();
    // `into_decoder` checks the sides but not the buffer size; check it before allocating.
    let mut budget = limits();
    budget.reserve(decoder.total_bytes()).map_err(|_| {
        anyhow!("{w}x{h} {:?} needs {} bytes, more than the {MAX_DECODED_BYTES}-byte limit", decoder.color_type(), decoder.total_bytes())
    })?;
    if w == 0 || h == 0 {
        return Err(anyhow!("the image is empty ({w}x{h})"));
    }
    let orientation = decoder.orientation().context("cannot read its EXIF orientation")?;
    let image = DynamicImage::from_decoder(decoder).context("cannot decode")?;
    Ok(Decoded { image, orientation, format })
}

/// Refuse an OpenEXR file (`len` bytes) any of whose parts claims a data window over
/// [`MAX_SIDE`] a side, deep data, or more pixel bytes than [`MAX_EXR_EXPANSION`] × `len`.
fn check_exr_claims(reader: &mut impl std::io::Read, len: u64) -> Result<()> {
    let meta = exr::meta::MetaData::read_from_buffered(reader, false).map_err(|e| anyhow!("cannot decode OpenEXR header: {e}"))?;
    // `read_from_buffered` does not validate (a channel sampling of 0 would divide by zero in
    // the exr crate's own size arithmetic); the decoder validates the same way.
    exr::meta::MetaData::validate(&meta.headers, false).map_err(|e| anyhow!("invalid OpenEXR header: {e}"))?;
    for (i, header) in meta.headers.iter().enumerate() {
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        if w > MAX_SIDE as usize || h > MAX_SIDE as usize {
            return Err(anyhow!("OpenEXR part {i}: data window {w}x{h} is over the limit of {MAX_SIDE} pixels a side"));
        }
        if header.deep {
            return Err(anyhow!("OpenEXR part {i}: deep data is not supported"));
        }
        // Every channel at full resolution, one level: no subsampling or mip arithmetic.
        let bytes = (w as u64).saturating_mul(h as u64).saturating_mul(header.channels.bytes_per_pixel as u64);
        if bytes > len.saturating_mul(MAX_EXR_EXPANSION) {
            return Err(anyhow!(
                "OpenEXR part {i}: data window {w}x{h} holds {bytes} pixel bytes, more than a {len}-byte file can hold (at most {MAX_EXR_EXPANSION} per byte of file); the file is truncated or damaged"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PNG header (signature + IHDR, CRC per RFC 2083 §3.4) claiming `w`×`h` with the given
    /// bit depth and colour type (2 = RGB, 6 = RGBA), with an empty image-data chunk.
    fn png_header(w: u32, h: u32, depth: u8, colour: u8) -> Vec<u8> {
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend_from_slice(&w.to_be_bytes());
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[depth, colour, 0, 0, 0]);
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        out.extend_from_slice(&13u32.to_be_bytes());
        out.extend_from_slice(&ihdr);
        out.extend_from_slice(&crc32(&ihdr).to_be_bytes());
        // An empty IDAT chunk, so that the header is read completely.
        out.extend_from_slice(&0u32.to_be_bytes());
        out.extend_from_slice(b"IDAT");
        out.extend_from_slice(&crc32(b"IDAT").to_be_bytes());
        out
    }

    fn crc32(data: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in data {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
            }
        }
        !crc
    }

    #[test]
    fn crc_matches_the_standard_check_value() {
        // CRC-32/ISO-HDLC check value of "123456789" (the catalogue of parametrised CRCs).
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn huge_claims_are_refused_before_allocating() {
        // Sides over the limit, and 16384² RGBA16 (2 GiB) over the byte limit.
        for (w, h, depth, colour) in
            [(100_000, 100_000, 8, 2), (MAX_SIDE + 1, 4, 8, 2), (4, MAX_SIDE + 1, 8, 6), (MAX_SIDE, MAX_SIDE, 16, 6)]
        {
            let err = format!("{:#}", decode_bytes(&png_header(w, h, depth, colour), &[]).err().expect("refused"));
            assert!(err.contains("limit"), "{w}x{h}: {err}");
        }
        // Within the limits the same header fails only because the data is missing.
        let err = format!("{:#}", decode_bytes(&png_header(64, 64, 8, 2), &[]).err().expect("truncated"));
        assert!(!err.contains("limit"), "{err}");
    }

    /// The fuzz corpus's 8×4 RGB float OpenEXR (scan lines, no compression, no chunkCount
    /// attribute) with its data window widened to `w`×`h` (box2i xMin yMin xMax yMax, per the
    /// OpenEXR file layout), without adding pixel data.
    fn exr_claiming(w: i32, h: i32) -> Vec<u8> {
        let mut bytes = include_bytes!("../../../tests/fuzz/corpus/hdr_exr/tiny.exr").to_vec();
        let key = b"dataWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|k| k == key).unwrap() + key.len() + 4;
        bytes[at + 8..at + 12].copy_from_slice(&(w - 1).to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&(h - 1).to_le_bytes());
        bytes
    }

    #[test]
    fn exr_claiming_more_than_its_size_can_hold_is_refused_before_allocating() {
        assert_eq!(decode_bytes(&exr_claiming(8, 4), &[]).unwrap().image.width(), 8);
        // 16384×4096 RGB f32 (768 MiB) is within the side limit, not within a few hundred bytes
        // of file; a data window wider than the side limit (as a fuzzer found: 167 772 168×4)
        // is refused whatever the file's size.
        let err = format!("{:#}", decode_bytes(&exr_claiming(16384, 4096), &[]).err().expect("refused"));
        assert!(err.contains("file can hold"), "{err}");
        let err = format!("{:#}", decode_bytes(&exr_claiming(167_772_168, 4), &[]).err().expect("refused"));
        assert!(err.contains("over the limit"), "{err}");
        // A claim the file's size allows fails only on the missing data.
        let err = format!("{:#}", decode_bytes(&exr_claiming(64, 64), &[]).err().expect("truncated"));
        assert!(!err.contains("can hold") && !err.contains("limit"), "{err}");
    }

    #[test]
    fn formats_outside_the_list_are_named() {
        let mut png = Vec::new();
        image::RgbImage::new(2, 2).write_to(&mut std::io::Cursor::new(&mut png), ImageFormat::Png).unwrap();
        assert_eq!(decode_bytes(&png, &[ImageFormat::Png]).unwrap().image.width(), 2);
        let err = format!("{:#}", decode_bytes(&png, &[ImageFormat::Jpeg]).err().unwrap());
        assert!(err.contains("Png") && err.contains("Jpeg"), "{err}");
        assert!(decode_bytes(b"not an image", &[]).is_err());
    }
}
