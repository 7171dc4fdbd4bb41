//! What the phone cameras report, converted to this crate's terms — pure functions, so they are
//! tested on the host although the backends only compile for the phones.

use anyhow::{Result, bail};

/// How Android `YUV_420_888` chroma planes lie in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChromaLayout {
    /// Pixel stride 1: separate Cb (plane 1) and Cr (plane 2) planes (I420).
    Planar,
    /// Pixel stride 2 with Cr one byte after Cb: one interleaved plane starting at Cb (NV12).
    Nv12,
    /// Pixel stride 2 with Cb one byte after Cr: one interleaved plane starting at Cr (NV21,
    /// what most Android cameras deliver).
    Nv21,
}

/// The chroma layout from the addresses of planes 1 (U = Cb) and 2 (V = Cr) and their pixel
/// stride (`AImage_getPlanePixelStride`; Android guarantees both chroma planes share it).
/// `YUV_420_888` allows only pixel strides 1 and 2; with 2 the planes must overlap by one byte.
pub fn chroma_layout(u_addr: usize, v_addr: usize, pixel_stride: i32) -> Result<ChromaLayout> {
    match pixel_stride {
        1 => Ok(ChromaLayout::Planar),
        2 if v_addr == u_addr + 1 => Ok(ChromaLayout::Nv12),
        2 if u_addr == v_addr + 1 => Ok(ChromaLayout::Nv21),
        2 => bail!("YUV_420_888 chroma planes with pixel stride 2 are not interleaved (U at {u_addr:#x}, V at {v_addr:#x})"),
        s => bail!("YUV_420_888 chroma pixel stride {s} (only 1 and 2 exist)"),
    }
}

/// Vertical field of view (degrees) of a pinhole camera whose image is `height_px` pixels high
/// with a focal length of `fy_px` pixels (Android `LENS_INTRINSIC_CALIBRATION` [fx, fy, cx, cy, s]
/// over `SENSOR_INFO_ACTIVE_ARRAY_SIZE`): 2·atan(h / 2f).
pub fn vfov_from_focal_px(fy_px: f64, height_px: f64) -> Result<f64> {
    if !(fy_px.is_finite() && fy_px > 0.0 && height_px.is_finite() && height_px > 0.0) {
        bail!("camera intrinsics: focal length {fy_px} px over {height_px} px is not a camera");
    }
    Ok((2.0 * (height_px / (2.0 * fy_px)).atan()).to_degrees())
}

/// The same from the lens focal length and the sensor's physical height, both in mm (Android
/// `LENS_INFO_AVAILABLE_FOCAL_LENGTHS[0]` and `SENSOR_INFO_PHYSICAL_SIZE`, the fallback when the
/// calibration is missing).
pub fn vfov_from_focal_mm(focal_mm: f64, sensor_height_mm: f64) -> Result<f64> {
    vfov_from_focal_px(focal_mm, sensor_height_mm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chroma_layouts_of_yuv_420_888() {
        assert_eq!(chroma_layout(1000, 2000, 1).unwrap(), ChromaLayout::Planar);
        assert_eq!(chroma_layout(1000, 1001, 2).unwrap(), ChromaLayout::Nv12);
        assert_eq!(chroma_layout(1001, 1000, 2).unwrap(), ChromaLayout::Nv21);
        assert!(chroma_layout(1000, 5000, 2).is_err());
        assert!(chroma_layout(1000, 1001, 3).is_err());
    }

    #[test]
    fn field_of_view_from_focal_length() {
        // A focal length equal to half the image height sees ±45°: 90°; equal to the height,
        // 2·atan(1/2) = 53.1301°.
        assert!((vfov_from_focal_px(500.0, 1000.0).unwrap() - 90.0).abs() < 1e-9);
        assert!((vfov_from_focal_mm(4.0, 4.0).unwrap() - 53.130_102_354).abs() < 1e-6);
        assert!(vfov_from_focal_px(0.0, 1000.0).is_err());
        assert!(vfov_from_focal_mm(f64::NAN, 3.0).is_err());
    }
}
