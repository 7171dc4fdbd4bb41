//! Colour correction of whole 8-bit sRGB images on the CPU (the `colour-transfer` tool and the
//! benchmark): loading, choosing the pixels that count, applying a [`ColourCorrection`].
//!
//! Which pixels count for statistics: alpha > 0 (fully transparent pixels are invisible) and,
//! with the green-screen option, not pure (0,255,0). Pixels that do not count are copied to the
//! output unchanged.

use super::correction::{ColourCorrection, correct_unclipped, finish};
use super::stats::{ColourStats, srgb8_to_linear_table};
use crate::priors::mask::is_green_screen;
use crate::scene::Rgba8Image;
use anyhow::{Result, bail};
use std::path::Path;

/// Read an image file as 8-bit sRGB RGBA (16-bit files are reduced to 8 bits; grey and RGB
/// files get opaque alpha).
pub fn load_rgba8(path: &Path) -> Result<Rgba8Image> {
    let img = crate::scene::decode::decode_file(path, &[])?.image.to_rgba8();
    let (width, height) = img.dimensions();
    if width == 0 || height == 0 {
        bail!("{} is empty ({width}x{height})", path.display());
    }
    Ok(Rgba8Image { width, height, pixels: img.into_raw() })
}

/// Whether pixel `p` (RGBA) counts for statistics.
pub fn counts(p: &[u8], green_screen: bool) -> bool {
    p[3] > 0 && !(green_screen && is_green_screen([p[0], p[1], p[2]]))
}

/// Linear RGB of the pixels that count.
pub fn counted_linear(image: &Rgba8Image, green_screen: bool) -> Vec<[f32; 3]> {
    let lut = srgb8_to_linear_table();
    image
        .pixels
        .chunks_exact(4)
        .filter(|p| counts(p, green_screen))
        .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
        .collect()
}

/// Statistics of the pixels that count; errors name `what` and say why none are left.
pub fn image_stats(image: &Rgba8Image, green_screen: bool, what: &str) -> Result<ColourStats> {
    let px = counted_linear(image, green_screen);
    if px.is_empty() {
        let transparent = image.pixels.chunks_exact(4).filter(|p| p[3] == 0).count();
        let reason = if transparent == image.pixels.len() / 4 {
            "it is fully transparent (alpha 0 everywhere)".to_string()
        } else {
            format!("all its visible pixels are green screen (0,255,0) ({transparent} transparent)")
        };
        bail!("{what} has no pixels to take statistics of: {reason}");
    }
    ColourStats::from_linear(&px)
}

/// The result of correcting an image.
pub struct Corrected {
    pub image: Rgba8Image,
    /// Pixels out of gamut after the correction: a channel below 0 (clamped to 0 by the
    /// correction itself) or, after the strength mix, above 1 (clipped when encoding).
    pub out_of_gamut: u64,
}

/// Apply `cc` to every counted pixel of `image` (linear light), clip per channel to 0..1 and
/// encode back to sRGB; other pixels are copied. Alpha is kept. Same maths as the shader's
/// `colour_correct` (negatives clamped inside the correction, then the strength mix).
pub fn apply(image: &Rgba8Image, cc: &ColourCorrection, green_screen: bool) -> Corrected {
    let lut = srgb8_to_linear_table();
    let mut out = image.pixels.clone();
    let mut out_of_gamut = 0u64;
    for p in out.chunks_exact_mut(4) {
        if !counts(p, green_screen) {
            continue;
        }
        let c = glam::Vec3::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]);
        let raw = correct_unclipped(c, cc);
        let r = finish(c, raw, cc);
        if (cc.strength > 0.0 && raw.min_element() < 0.0) || r.max_element() > 1.0 {
            out_of_gamut += 1;
        }
        for ch in 0..3 {
            p[ch] = (super::linear_to_srgb(r[ch]) * 255.0).round() as u8;
        }
    }
    Corrected { image: Rgba8Image { width: image.width, height: image.height, pixels: out }, out_of_gamut }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colour::transfer::TransferMethod;

    fn img(pixels: Vec<[u8; 4]>) -> Rgba8Image {
        Rgba8Image { width: pixels.len() as u32, height: 1, pixels: pixels.concat() }
    }

    #[test]
    fn transparent_and_green_pixels() {
        let t = img(vec![[1, 2, 3, 0]; 4]);
        let e = image_stats(&t, false, "TARGET").unwrap_err().to_string();
        assert!(e.contains("TARGET") && e.contains("transparent"), "{e}");
        let g = img(vec![[0, 255, 0, 255], [0, 255, 0, 255], [5, 5, 5, 0]]);
        let e = image_stats(&g, true, "TARGET").unwrap_err().to_string();
        assert!(e.contains("green"), "{e}");
        assert_eq!(image_stats(&g, false, "TARGET").unwrap().count, 2);
    }

    #[test]
    fn apply_keeps_uncounted_pixels_and_alpha() {
        let src = img(vec![[200, 50, 50, 255], [150, 30, 20, 255], [250, 90, 70, 255]]);
        let tgt = img(vec![[20, 60, 200, 255], [0, 255, 0, 255], [40, 80, 160, 7], [9, 9, 9, 0]]);
        let cc = ColourCorrection::new(
            TransferMethod::Reinhard,
            1.0,
            &image_stats(&src, false, "s").unwrap(),
            &image_stats(&tgt, true, "t").unwrap(),
        );
        let out = apply(&tgt, &cc, true);
        let px: Vec<&[u8]> = out.image.pixels.chunks(4).collect();
        assert_eq!(px[1], &[0, 255, 0, 255]);
        assert_eq!(px[3], &[9, 9, 9, 0]);
        assert_eq!(px[2][3], 7);
        // Blue pixels became reddish (the source is red).
        assert!(px[0][0] > px[0][2], "{:?}", px[0]);
    }

    #[test]
    fn unreadable_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("previz-colour-img-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let bad = dir.join("bad.png");
        std::fs::write(&bad, b"not a png").unwrap();
        assert!(load_rgba8(&bad).is_err());
        assert!(load_rgba8(&dir.join("missing.png")).unwrap_err().to_string().contains("missing.png"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
