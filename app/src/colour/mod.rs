//! Colour spaces and colour correction: sRGB transfer, luminance, Reinhard lαβ, brightness /
//! contrast and statistical colour transfer. The CPU reference of what
//! `shaders/colour_correct.wgsl` does (tests compare the two); see docs/colour.md.
//!
//! Encoding: every function here takes and returns linear-light RGB unless its name says sRGB.

pub mod correction;
pub mod distance;
pub mod gpu;
pub mod images;
pub mod intensity;
pub mod lab;
pub mod linalg;
pub mod report;
pub mod stats;
pub mod transfer;

/// sRGB-encoded value (0..1) to linear light (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear light (0..1) to sRGB-encoded value (IEC 61966-2-1).
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.0031308 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// Relative luminance of linear BT.709 RGB (ITU-R BT.709-6 item 3.3).
pub fn luminance_bt709(rgb: [f32; 3]) -> f32 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_reference_values() {
        // sRGB 0.5 -> 0.21404 linear (IEC 61966-2-1 formula); 0.04045 is the knee.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        assert!((srgb_to_linear(0.04045) - 0.003_130_8).abs() < 1e-6);
        for i in 0..=255 {
            let c = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
        assert!((luminance_bt709([1.0, 1.0, 1.0]) - 1.0).abs() < 1e-6);
    }
}
