//! Geometry shared by the assistant, face assembly and the frame fold: the phone camera as a
//! pinhole, the capture's local frame (reference heading turned to North) and the directions
//! of cube-face pixels in it.

use crate::scene::cube_to_enu;
use crate::scene::cubemap::face_uv_to_cube_dir;
use anyhow::{Result, bail};
use glam::{DQuat, Quat, Vec2, Vec3};

/// A pinhole camera: image size and field of view; +x right, +y up, looking along −z
/// (DESIGN.md). Pixel (0, 0) is the top-left corner; pixel centres are at +0.5, as in
/// [`crate::camera::sim::VirtualPhone::pixel_ray`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    pub width: u32,
    pub height: u32,
    /// tan of half the horizontal and vertical field of view.
    pub tan_half_h: f32,
    pub tan_half_v: f32,
}

impl Pinhole {
    /// From the image size and the vertical field of view in degrees (square pixels).
    pub fn from_vfov(width: u32, height: u32, vfov_deg: f32) -> Result<Pinhole> {
        if width == 0 || height == 0 {
            bail!("camera image size {width}x{height} must be at least 1x1");
        }
        if !(vfov_deg.is_finite() && vfov_deg > 0.0 && vfov_deg < 180.0) {
            bail!("vertical field of view must be between 0 and 180 degrees, got {vfov_deg}");
        }
        let tan_half_v = (0.5 * vfov_deg.to_radians()).tan();
        Ok(Pinhole { width, height, tan_half_h: tan_half_v * width as f32 / height as f32, tan_half_v })
    }

    pub fn hfov_deg(&self) -> f32 {
        2.0 * self.tan_half_h.atan().to_degrees()
    }

    pub fn vfov_deg(&self) -> f32 {
        2.0 * self.tan_half_v.atan().to_degrees()
    }

    /// Normalised image coordinates (−1..1 left→right, −1..1 bottom→top) of a camera-frame
    /// direction, or `None` when it points behind the camera.
    pub fn to_ndc(&self, dir_cam: Vec3) -> Option<Vec2> {
        if dir_cam.z >= -1e-6 || !dir_cam.is_finite() {
            return None;
        }
        let inv = -1.0 / dir_cam.z;
        Some(Vec2::new(dir_cam.x * inv / self.tan_half_h, dir_cam.y * inv / self.tan_half_v))
    }

    /// Pixel position (x right, y down; centres at +0.5) of normalised image coordinates.
    pub fn ndc_to_pixel(&self, ndc: Vec2) -> Vec2 {
        Vec2::new((ndc.x + 1.0) * 0.5 * self.width as f32, (1.0 - ndc.y) * 0.5 * self.height as f32)
    }

    /// Camera-frame direction (not normalised) through pixel position (px, py).
    pub fn pixel_to_dir(&self, px: f32, py: f32) -> Vec3 {
        let x = (2.0 * px / self.width as f32 - 1.0) * self.tan_half_h;
        let y = (1.0 - 2.0 * py / self.height as f32) * self.tan_half_v;
        Vec3::new(x, y, -1.0)
    }

    /// Pixel position of a world direction seen by a camera with `pose` (camera → world), or
    /// `None` when it is behind the camera. The position may lie outside the image.
    pub fn project(&self, pose: Quat, dir_world: Vec3) -> Option<Vec2> {
        self.to_ndc(pose.inverse() * dir_world).map(|n| self.ndc_to_pixel(n))
    }

    /// Whether a world direction falls inside the image shrunk by `inset` (in normalised
    /// units, 0 = the full frame).
    pub fn sees(&self, pose: Quat, dir_world: Vec3, inset: f32) -> bool {
        self.to_ndc(pose.inverse() * dir_world).is_some_and(|n| n.x.abs() <= 1.0 - inset && n.y.abs() <= 1.0 - inset)
    }
}

/// Rotation taking the capture's local frame (reference heading = North) to the world (ENU).
/// Headings are clockwise from North, so this is a clockwise turn by `reference_heading`
/// seen from above: Rz(−heading).
pub fn local_to_world(reference_heading_rad: f64) -> DQuat {
    DQuat::from_rotation_z(-reference_heading_rad)
}

/// Unit direction in the capture's local frame (ENU turned so that the reference heading is
/// North) through the centre of pixel (x, y) of cube layer `layer` (wgpu order) of a
/// `size`×`size` face, optionally magnified by `stretch` (1 = the true 90° face; k < 1 maps
/// the face onto the central k-fraction of its tangent plane).
pub fn face_pixel_dir_local(layer: usize, x: u32, y: u32, size: u32, stretch: f32) -> Vec3 {
    let s = size as f32;
    let u = 0.5 + ((x as f32 + 0.5) / s - 0.5) * stretch;
    let v = 0.5 + ((y as f32 + 0.5) / s - 0.5) * stretch;
    cube_to_enu(face_uv_to_cube_dir(layer, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::from_heading_pitch_roll;
    use crate::scene::cubemap::cube_dir_to_face_uv;
    use crate::scene::enu_to_cube;

    #[test]
    fn projection_inverts_pixel_rays() {
        let cam = Pinhole::from_vfov(640, 480, 50.0).unwrap();
        // 4:3 at 50° vertical: hfov = 2·atan(4/3·tan 25°) = 2·atan(0.621744) = 63.742°.
        assert!((cam.hfov_deg() - 63.742).abs() < 0.001, "{}", cam.hfov_deg());
        let pose = from_heading_pitch_roll(0.7, -0.3, 0.1).as_quat();
        for (px, py) in [(0.5, 0.5), (320.0, 240.0), (639.5, 10.25), (100.0, 479.5)] {
            let world = pose * cam.pixel_to_dir(px, py);
            let back = cam.project(pose, world).unwrap();
            assert!((back - Vec2::new(px, py)).length() < 1e-3, "{px},{py} -> {back}");
        }
        // The optical axis lands on the image centre; behind the camera is None.
        assert!((cam.project(pose, pose * Vec3::NEG_Z).unwrap() - Vec2::new(320.0, 240.0)).length() < 1e-3);
        assert!(cam.project(pose, pose * Vec3::Z).is_none());
        // A direction 25° above the axis is exactly on the top edge.
        let up25 = Vec3::new(0.0, 25f32.to_radians().sin(), -25f32.to_radians().cos());
        assert!((cam.project(Quat::IDENTITY, up25).unwrap().y).abs() < 1e-3);
        assert!(Pinhole::from_vfov(0, 10, 50.0).is_err() && Pinhole::from_vfov(10, 10, 180.0).is_err());
    }

    #[test]
    fn face_pixels_point_where_the_cube_convention_says() {
        // Centre pixels: +Z layer (4) is the front = local North, +X (0) right = East, +Y up.
        let c = |layer| face_pixel_dir_local(layer, 1, 1, 2, 0.0);
        assert!((c(4) - Vec3::Y).length() < 1e-6);
        assert!((c(0) - Vec3::X).length() < 1e-6);
        assert!((c(2) - Vec3::Z).length() < 1e-6);
        assert!((c(5) + Vec3::Y).length() < 1e-6);
        // Every pixel direction maps back to its own face and pixel.
        for layer in 0..6 {
            for (x, y) in [(0, 0), (5, 2), (7, 7)] {
                let d = face_pixel_dir_local(layer, x, y, 8, 1.0);
                let (f, u, v) = cube_dir_to_face_uv(enu_to_cube(d));
                assert_eq!(f, layer);
                assert_eq!(((u * 8.0) as u32, (v * 8.0) as u32), (x, y));
            }
        }
        // The front face's top-left pixel looks up and to the left (unmirrored photo).
        let tl = face_pixel_dir_local(4, 0, 0, 8, 1.0);
        assert!(tl.x < 0.0 && tl.z > 0.0 && tl.y > 0.0);
        // Local → world: reference heading 90° turns local North to East.
        let w = local_to_world(90f64.to_radians()) * glam::DVec3::Y;
        assert!((w - glam::DVec3::X).length() < 1e-12);
    }
}
