//! Direction samples: one (direction, radiance, solid angle) per pixel of an environment or a
//! camera image, so the light measurements ([`super::sun_finder`], [`super::sh9`]) work the
//! same on an equirectangular map, a cube map and a posed camera frame.
//!
//! Sample `i` is pixel `i` of its source in the source's own order (equirect: row-major, top
//! row first; cube: face by face in wgpu order, each row-major), so a result that names
//! samples by index can be written back into the source ([`apply_to_cube`],
//! [`apply_to_equirect`]).

use crate::scene::environment::{Equirect, equirect_uv_to_enu, face_uv_to_cube_dir, texel_solid_angle};
use crate::scene::{CubeMap, cube_to_enu};
use anyhow::{Result, bail};
use glam::{Quat, Vec3};

/// Radiance arriving from one small patch of directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirSample {
    /// Unit direction towards the patch, world (ENU) frame.
    pub dir: Vec3,
    /// Linear RGB radiance (the source's units, before any exposure).
    pub radiance: [f32; 3],
    /// Solid angle of the patch, steradians.
    pub solid_angle: f32,
}

/// Every pixel of an equirectangular map whose centre column faces azimuth `heading` (rad).
pub fn from_equirect(map: &Equirect, heading: f32) -> Vec<DirSample> {
    let (w, h) = (map.width(), map.height());
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        let solid_angle = map.pixel_solid_angle(y);
        let v = (y as f32 + 0.5) / h as f32;
        for x in 0..w {
            let dir = equirect_uv_to_enu((x as f32 + 0.5) / w as f32, v, heading);
            out.push(DirSample { dir, radiance: map.pixels()[(y * w + x) as usize], solid_angle });
        }
    }
    out
}

/// Every texel of a cube map (directions already in ENU, see `scene::enu_to_cube`).
pub fn from_cube(cube: &CubeMap) -> Vec<DirSample> {
    let n = cube.size;
    let mut out = Vec::with_capacity(6 * (n * n) as usize);
    for (face, texels) in cube.faces.iter().enumerate() {
        for y in 0..n {
            for x in 0..n {
                let (u, v) = ((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                let dir = cube_to_enu(face_uv_to_cube_dir(face, u, v));
                out.push(DirSample { dir, radiance: texels[(y * n + x) as usize], solid_angle: texel_solid_angle(n, x, y) });
            }
        }
    }
    out
}

/// Every pixel of a pinhole camera image (`width`×`height`, linear RGB, row-major, top row
/// first) with vertical field of view `vfov` (rad), posed by `camera_to_world` (camera frame:
/// +x right, +y up, looking along −z; world ENU). A pixel's solid angle is its area on the
/// image plane at distance 1 times cos³ of its angle off the optical axis.
pub fn from_camera_image(width: u32, height: u32, pixels: &[[f32; 3]], vfov: f32, camera_to_world: Quat) -> Result<Vec<DirSample>> {
    if width == 0 || height == 0 || pixels.len() != (width as usize) * (height as usize) {
        bail!("camera image {width}x{height} with {} pixels is not a usable image", pixels.len());
    }
    if !(vfov.is_finite() && vfov > 0.0 && vfov < std::f32::consts::PI) {
        bail!("camera vertical field of view must be between 0 and 180 degrees, got {} degrees", vfov.to_degrees());
    }
    let half_h = (0.5 * vfov).tan();
    let pixel = 2.0 * half_h / height as f32; // pixel side on the plane z = −1
    let half_w = pixel * width as f32 * 0.5;
    let mut out = Vec::with_capacity(pixels.len());
    for y in 0..height {
        for x in 0..width {
            let cam = Vec3::new(-half_w + (x as f32 + 0.5) * pixel, half_h - (y as f32 + 0.5) * pixel, -1.0);
            let cos = 1.0 / cam.length();
            out.push(DirSample {
                dir: camera_to_world * (cam * cos),
                radiance: pixels[(y * width + x) as usize],
                solid_angle: pixel * pixel * cos * cos * cos,
            });
        }
    }
    Ok(out)
}

/// Which of `len` samples `indices` names (indices past `len` are ignored): a region's mask.
pub fn mask(len: usize, indices: &[usize]) -> Vec<bool> {
    let mut m = vec![false; len];
    for &i in indices {
        if let Some(b) = m.get_mut(i) {
            *b = true;
        }
    }
    m
}

/// Write new radiances (sample index, radiance) into the cube map the samples came from.
pub fn apply_to_cube(cube: &mut CubeMap, changes: &[(usize, [f32; 3])]) {
    let per_face = (cube.size * cube.size) as usize;
    for &(i, rgb) in changes {
        if let Some(t) = cube.faces.get_mut(i / per_face).and_then(|f| f.get_mut(i % per_face)) {
            *t = rgb;
        }
    }
}

/// Write new radiances (sample index, radiance) into equirect pixels (row-major) the samples
/// came from.
pub fn apply_to_equirect(pixels: &mut [[f32; 3]], changes: &[(usize, [f32; 3])]) {
    for &(i, rgb) in changes {
        if let Some(p) = pixels.get_mut(i) {
            *p = rgb;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn a_mask_marks_the_named_samples_and_ignores_the_rest() {
        assert_eq!(mask(5, &[3, 0, 3, 9]), vec![true, false, false, true, false]);
        assert_eq!(mask(0, &[1]), Vec::<bool>::new());
    }

    #[test]
    fn solid_angles_cover_the_sphere() {
        let e = Equirect::new(64, 32, vec![[1.0; 3]; 64 * 32]).unwrap();
        let total: f32 = from_equirect(&e, 0.3).iter().map(|s| s.solid_angle).sum();
        assert!((total - 4.0 * PI).abs() < 1e-3, "{total}");
        let cube = CubeMap::solid_faces(16, [[1.0; 3]; 6]);
        let total: f32 = from_cube(&cube).iter().map(|s| s.solid_angle).sum();
        assert!((total - 4.0 * PI).abs() < 1e-3, "{total}");
    }

    #[test]
    fn camera_pixels_point_where_the_camera_looks() {
        // A 90 deg x 90 deg square camera covers exactly one cube face: 4π/6 sr.
        let (w, h) = (64, 64);
        let s = from_camera_image(w, h, &vec![[0.0; 3]; 64 * 64], 90f32.to_radians(), Quat::IDENTITY).unwrap();
        let total: f32 = s.iter().map(|s| s.solid_angle).sum();
        assert!((total - 4.0 * PI / 6.0).abs() < 1e-3, "{total}");
        // The identity pose looks down (−z) with image up = North, right = East: the top-left
        // pixel looks down towards the North-West.
        assert!(s[0].dir.x < 0.0 && s[0].dir.y > 0.0 && s[0].dir.z < 0.0);
        // The identity pose looks down (−z); turned 180 deg about +x it looks up along +z.
        let up = from_camera_image(2, 2, &[[0.0; 3]; 4], 1.0, Quat::from_rotation_x(PI)).unwrap();
        let mean = up.iter().map(|s| s.dir).sum::<Vec3>().normalize();
        assert!((mean - Vec3::Z).length() < 1e-5, "{mean}");
        assert!(from_camera_image(2, 2, &[[0.0; 3]; 3], 1.0, Quat::IDENTITY).is_err());
        assert!(from_camera_image(2, 2, &[[0.0; 3]; 4], 0.0, Quat::IDENTITY).is_err());
    }

    #[test]
    fn sample_index_is_pixel_index() {
        let mut cube = CubeMap::solid_faces(4, [[0.0; 3]; 6]);
        let s = from_cube(&cube);
        // Sample 16*4 + 5 is face 4 (+Z cube = North), texel (1, 1).
        assert!(s[16 * 4 + 5].dir.y > 0.5);
        apply_to_cube(&mut cube, &[(16 * 4 + 5, [7.0; 3])]);
        assert_eq!(cube.faces[4][5], [7.0; 3]);
        assert!((cube.sample_enu(s[16 * 4 + 5].dir)[0] - 7.0).abs() < 1e-3);
    }
}
