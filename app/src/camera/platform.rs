//! What the phone cameras report, converted to this crate's terms — pure functions, so they are
//! tested on the host although the backends only compile for the phones.

use super::yuv::{YuvMatrix, YuvRange};
use crate::pose::DisplayRotation;
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

/// The fields of view (horizontal, vertical; degrees) of a camera *stream* of
/// `out_w`×`out_h` pixels cropped from a sensor array of `array_w`×`array_h` (pixels or mm) by
/// a lens of focal lengths `fx`, `fy` (the same unit).
///
/// A stream whose aspect ratio differs from the array's is the largest centred region of the
/// array with the stream's aspect ratio, scaled (Android `SCALER_CROP_REGION`: "the output
/// streams use the largest centered region of the crop region with the stream's aspect
/// ratio"; the crop region is the whole active array at zoom 1). So a 16:9 stream of a 4:3
/// sensor keeps the full width and loses height: its vertical field of view is smaller than
/// the sensor's.
pub fn stream_fov_deg(fx: f64, fy: f64, (array_w, array_h): (f64, f64), (out_w, out_h): (u32, u32)) -> Result<(f64, f64)> {
    if !(array_w.is_finite() && array_w > 0.0 && array_h.is_finite() && array_h > 0.0) || out_w == 0 || out_h == 0 {
        bail!("camera stream {out_w}x{out_h} of a {array_w}x{array_h} sensor array: not a camera");
    }
    let out_aspect = f64::from(out_w) / f64::from(out_h);
    let (visible_w, visible_h) =
        if out_aspect >= array_w / array_h { (array_w, array_w / out_aspect) } else { (array_h * out_aspect, array_h) };
    Ok((vfov_from_focal_px(fx, visible_w)?, vfov_from_focal_px(fy, visible_h)?))
}

/// The clockwise quarter turns that make a back camera's image upright on the screen: the
/// sensor's orientation (Android `SENSOR_ORIENTATION`, "the clockwise angle through which the
/// output image needs to be rotated to be upright on the device screen in its native
/// orientation", 0/90/180/270) less the display's rotation (Android's documented
/// `(orientation − degrees + 360) % 360` for a back-facing camera, `Camera.setDisplayOrientation`).
pub fn back_camera_quarter_turns(sensor_orientation_deg: i32, display: DisplayRotation) -> Result<u32> {
    if sensor_orientation_deg.rem_euclid(90) != 0 {
        bail!("camera sensor orientation {sensor_orientation_deg}° is not a multiple of 90°");
    }
    Ok(((sensor_orientation_deg - display.degrees()).rem_euclid(360) / 90) as u32)
}

/// The size of an image of `(w, h)` after `quarter_turns` clockwise quarter turns.
pub fn turned_size((w, h): (u32, u32), quarter_turns: u32) -> (u32, u32) {
    if quarter_turns % 2 == 1 { (h, w) } else { (w, h) }
}

/// A phone camera's stream as the screen shows it: field of view, size and turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraInfo {
    /// The stream's (horizontal, vertical) field of view before the turn, degrees.
    stream_fov_deg: Option<(f64, f64)>,
    /// The stream's size before the turn.
    size: (u32, u32),
    /// Clockwise quarter turns that make the image upright on the screen.
    pub quarter_turns: u32,
}

impl CameraInfo {
    /// From the lens's focal lengths and the sensor array they are measured on
    /// ([`stream_fov_deg`]; None: unknown), the sensor's orientation
    /// ([`back_camera_quarter_turns`]), the stream's size and the display's rotation.
    pub fn new(
        focal: Option<(f64, f64, (f64, f64))>,
        sensor_orientation_deg: i32,
        size: (u32, u32),
        display: DisplayRotation,
    ) -> Result<CameraInfo> {
        let stream_fov_deg = match focal {
            Some((fx, fy, array)) => Some(stream_fov_deg(fx, fy, array, size)?),
            None => None,
        };
        let quarter_turns = back_camera_quarter_turns(sensor_orientation_deg, display)?;
        Ok(CameraInfo { stream_fov_deg, size, quarter_turns })
    }

    /// The (horizontal, vertical) field of view of the image as shown (after the turn), degrees
    /// (None when the camera reports neither calibration nor focal length and sensor size).
    pub fn fov_deg(&self) -> Option<(f64, f64)> {
        self.stream_fov_deg.map(|(h, v)| if self.quarter_turns % 2 == 1 { (v, h) } else { (h, v) })
    }

    /// The size of the image as shown (after the turn).
    pub fn image_size(&self) -> (u32, u32) {
        turned_size(self.size, self.quarter_turns)
    }
}

/// CoreVideo's `kCVPixelFormatType_420YpCbCr8BiPlanarFullRange` ('420f'): NV12, full range.
pub const CV_420F: u32 = u32::from_be_bytes(*b"420f");
/// CoreVideo's `kCVPixelFormatType_420YpCbCr8BiPlanarVideoRange` ('420v'): NV12, video range.
pub const CV_420V: u32 = u32::from_be_bytes(*b"420v");

/// The Y'CbCr standard and range of an iOS camera buffer from its pixel format ('420f' full,
/// '420v' video range) and its `kCVImageBufferYCbCrMatrixKey` attachment
/// (`kCVImageBufferYCbCrMatrix_ITU_R_709_2` = "ITU_R_709_2", `…_ITU_R_601_4` = "ITU_R_601_4";
/// none: BT.601, what the camera's SD and photo-preset buffers use).
pub fn ios_yuv_format(pixel_format: u32, matrix: Option<&str>) -> Result<(YuvMatrix, YuvRange)> {
    let range = match pixel_format {
        CV_420F => YuvRange::Full,
        CV_420V => YuvRange::Limited,
        other => bail!("camera pixel format {:?} is not 420f or 420v", String::from_utf8_lossy(&other.to_be_bytes())),
    };
    let matrix = match matrix {
        None | Some("ITU_R_601_4") => YuvMatrix::Bt601,
        Some("ITU_R_709_2") => YuvMatrix::Bt709,
        Some(other) => bail!("camera Y'CbCr matrix {other} is neither BT.601 nor BT.709"),
    };
    Ok((matrix, range))
}

/// The vertical field of view (degrees) of a pinhole image of `(w, h)` pixels whose horizontal
/// field of view is `hfov_deg` (iOS `AVCaptureDeviceFormat.videoFieldOfView`, the format's
/// horizontal field of view): 2·atan(tan(hfov/2)·h/w).
pub fn vfov_from_hfov_deg(hfov_deg: f64, (w, h): (u32, u32)) -> Result<f64> {
    if !(hfov_deg.is_finite() && hfov_deg > 0.0 && hfov_deg < 180.0) || w == 0 || h == 0 {
        bail!("camera field of view {hfov_deg}° across {w}x{h} pixels: not a camera");
    }
    Ok((2.0 * ((hfov_deg.to_radians() / 2.0).tan() * f64::from(h) / f64::from(w)).atan()).to_degrees())
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

    #[test]
    fn a_wide_stream_of_a_four_by_three_sensor_loses_height() {
        // A 4000×3000 array with fx = fy = 3000 px: the full array sees 2·atan(4000/6000) =
        // 67.380° across and 2·atan(3000/6000) = 53.130° up. A 1280×720 (16:9) stream keeps the
        // width (67.380°) and sees 4000·9/16 = 2250 px up: 2·atan(2250/6000) = 41.112°.
        let (h, v) = stream_fov_deg(3000.0, 3000.0, (4000.0, 3000.0), (1280, 720)).unwrap();
        assert!((h - 67.380_135).abs() < 1e-5 && (v - 41.112_090).abs() < 1e-5, "{h} {v}");
        // A 4:3 stream sees the whole array; a 1:1 stream keeps the height (3000 px both ways).
        let (h, v) = stream_fov_deg(3000.0, 3000.0, (4000.0, 3000.0), (640, 480)).unwrap();
        assert!((h - 67.380_135).abs() < 1e-5 && (v - 53.130_102).abs() < 1e-5, "{h} {v}");
        let (h, v) = stream_fov_deg(3000.0, 3000.0, (4000.0, 3000.0), (720, 720)).unwrap();
        assert!((h - 53.130_102).abs() < 1e-5 && (v - 53.130_102).abs() < 1e-5, "{h} {v}");
        // Millimetres work the same: a 4.38 mm lens on a 5.64×4.23 mm sensor (4:3).
        let (_, v) = stream_fov_deg(4.38, 4.38, (5.64, 4.23), (1280, 720)).unwrap();
        assert!((v - (2.0 * (5.64 * 9.0 / 16.0 / 8.76f64).atan()).to_degrees()).abs() < 1e-9);
        assert!(stream_fov_deg(3000.0, 3000.0, (0.0, 3000.0), (1280, 720)).is_err());
        assert!(stream_fov_deg(3000.0, 3000.0, (4000.0, 3000.0), (0, 720)).is_err());
        assert!(stream_fov_deg(-1.0, 3000.0, (4000.0, 3000.0), (1280, 720)).is_err());
    }

    #[test]
    fn back_camera_turns_follow_androids_formula() {
        // Most phones: sensor at 90°, app in landscape (ROTATION_90): upright as delivered.
        assert_eq!(back_camera_quarter_turns(90, DisplayRotation::R90).unwrap(), 0);
        // A sensor mounted at 270° (the Nexus 5X) in the same landscape: upside down.
        assert_eq!(back_camera_quarter_turns(270, DisplayRotation::R90).unwrap(), 2);
        // Portrait (ROTATION_0) with a 90° sensor: a quarter turn clockwise; reverse landscape:
        // (90 − 270 + 360) % 360 = 180.
        assert_eq!(back_camera_quarter_turns(90, DisplayRotation::R0).unwrap(), 1);
        assert_eq!(back_camera_quarter_turns(90, DisplayRotation::R270).unwrap(), 2);
        // A landscape tablet: sensor 0°, display 0°.
        assert_eq!(back_camera_quarter_turns(0, DisplayRotation::R0).unwrap(), 0);
        assert!(back_camera_quarter_turns(45, DisplayRotation::R0).is_err());
        assert_eq!(turned_size((1280, 720), 1), (720, 1280));
        assert_eq!(turned_size((1280, 720), 2), (1280, 720));
    }

    #[test]
    fn a_portrait_screen_shows_the_streams_height_across() {
        // The 4000×3000-px sensor of the test above, fx = fy = 3000 px, mounted at 90°, a
        // 1280×720 stream: in landscape (ROTATION_90) the image is as delivered; in portrait it
        // is turned a quarter, 720×1280, and its vertical field of view is the stream's
        // horizontal one (67.380°).
        let focal = Some((3000.0, 3000.0, (4000.0, 3000.0)));
        let landscape = CameraInfo::new(focal, 90, (1280, 720), DisplayRotation::R90).unwrap();
        assert_eq!(landscape.image_size(), (1280, 720));
        let (_, v) = landscape.fov_deg().unwrap();
        assert!((v - 41.112_090).abs() < 1e-5, "{v}");
        let portrait = CameraInfo::new(focal, 90, (1280, 720), DisplayRotation::R0).unwrap();
        assert_eq!(portrait.image_size(), (720, 1280));
        let (h, v) = portrait.fov_deg().unwrap();
        assert!((v - 67.380_135).abs() < 1e-5 && (h - 41.112_090).abs() < 1e-5, "{h} {v}");
        assert_eq!(CameraInfo::new(None, 90, (1280, 720), DisplayRotation::R90).unwrap().fov_deg(), None);
        assert!(CameraInfo::new(focal, 33, (1280, 720), DisplayRotation::R90).is_err());
    }

    #[test]
    fn ios_buffer_formats_and_field_of_view() {
        // The four-character codes as CoreVideo defines them: '420f' = 0x34323066.
        assert_eq!(CV_420F, 0x3432_3066);
        assert_eq!(CV_420V, 0x3432_3076);
        assert_eq!(ios_yuv_format(CV_420F, None).unwrap(), (YuvMatrix::Bt601, YuvRange::Full));
        assert_eq!(ios_yuv_format(CV_420V, Some("ITU_R_709_2")).unwrap(), (YuvMatrix::Bt709, YuvRange::Limited));
        assert_eq!(ios_yuv_format(CV_420F, Some("ITU_R_601_4")).unwrap(), (YuvMatrix::Bt601, YuvRange::Full));
        let bgra = u32::from_be_bytes(*b"BGRA");
        assert!(ios_yuv_format(bgra, None).unwrap_err().to_string().contains("BGRA"));
        assert!(ios_yuv_format(CV_420F, Some("ITU_R_2020")).is_err());
        // A 90° horizontal view of a square image is 90° up; of a 16:9 image 2·atan(9/16) =
        // 58.7155°.
        assert!((vfov_from_hfov_deg(90.0, (720, 720)).unwrap() - 90.0).abs() < 1e-9);
        assert!((vfov_from_hfov_deg(90.0, (1280, 720)).unwrap() - 58.715_507).abs() < 1e-5);
        assert!(vfov_from_hfov_deg(0.0, (1280, 720)).is_err());
        assert!(vfov_from_hfov_deg(60.0, (0, 720)).is_err());
    }
}
