//! The one cube-map face/uv convention, and sampling a [`CubeMap`] by world (ENU) direction.
//!
//! Face selection and face coordinates follow the Vulkan specification, §16.5.4 "Cube Map Face
//! Selection" (Table "Cube map face and coordinate selection"), which wgpu, D3D, Metal and GL
//! share: the major axis picks the face, then
//!
//! | face | sc  | tc  | ma |
//! |------|-----|-----|----|
//! | +X   | −rz | −ry | rx |
//! | −X   | +rz | −ry | rx |
//! | +Y   | +rx | +rz | ry |
//! | −Y   | +rx | −rz | ry |
//! | +Z   | +rx | −ry | rz |
//! | −Z   | −rx | −ry | rz |
//!
//! and u = (sc/|ma| + 1)/2, v = (tc/|ma| + 1)/2, with v = 0 the top row of the face image.
//! World directions become cube directions through [`enu_to_cube`] only.

use super::{CubeMap, cube_to_enu, enu_to_cube};
use glam::Vec3;

/// Face index (wgpu order +X, −X, +Y, −Y, +Z, −Z) and face coordinates (u, v) in [0, 1] of a
/// cube-space direction (need not be unit length).
///
/// Ties between axes go to x, then y (as most GPUs do; the spec leaves ties open). A zero or
/// non-finite direction gives face 0 at its centre.
pub fn cube_dir_to_face_uv(d: Vec3) -> (usize, f32, f32) {
    if !d.is_finite() || d == Vec3::ZERO {
        return (0, 0.5, 0.5);
    }
    let a = d.abs();
    let (face, sc, tc, ma) = if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 { (0, -d.z, -d.y, a.x) } else { (1, d.z, -d.y, a.x) }
    } else if a.y >= a.z {
        if d.y >= 0.0 { (2, d.x, d.z, a.y) } else { (3, d.x, -d.z, a.y) }
    } else if d.z >= 0.0 {
        (4, d.x, -d.y, a.z)
    } else {
        (5, -d.x, -d.y, a.z)
    };
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}

/// Unit cube-space direction through face coordinates (u, v) of `face`: the inverse of
/// [`cube_dir_to_face_uv`]. A face index above 5 gives the zero vector.
pub fn face_uv_to_cube_dir(face: usize, u: f32, v: f32) -> Vec3 {
    let (sc, tc) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    let d = match face {
        0 => Vec3::new(1.0, -tc, -sc),
        1 => Vec3::new(-1.0, -tc, sc),
        2 => Vec3::new(sc, 1.0, tc),
        3 => Vec3::new(sc, -1.0, -tc),
        4 => Vec3::new(sc, -tc, 1.0),
        5 => Vec3::new(-sc, -tc, -1.0),
        _ => return Vec3::ZERO,
    };
    d.normalize()
}

/// Solid angle (steradians) of texel (x, y) of a `size`×`size` cube face: the area of its
/// projection onto the unit sphere, Ω = A(x0,y0) − A(x0,y1) − A(x1,y0) + A(x1,y1) with
/// A(x, y) = atan2(xy, √(x² + y² + 1)) over the texel's corners in [−1, 1] face coordinates
/// (the closed form used by AMD CubeMapGen, derived by M. Öhrström; the faces sum to 4π).
pub fn texel_solid_angle(size: u32, x: u32, y: u32) -> f32 {
    let s = size as f64;
    let corner = |i: u32| 2.0 * i as f64 / s - 1.0;
    let area = |a: f64, b: f64| (a * b).atan2((a * a + b * b + 1.0).sqrt());
    let (x0, x1, y0, y1) = (corner(x), corner(x + 1), corner(y), corner(y + 1));
    (area(x0, y0) - area(x0, y1) - area(x1, y0) + area(x1, y1)) as f32
}

impl CubeMap {
    /// A cube map whose texel centres take `f(direction in ENU, unit length)`.
    pub fn from_fn(size: u32, f: impl Fn(Vec3) -> [f32; 3]) -> CubeMap {
        let faces = std::array::from_fn(|face| {
            let mut texels = Vec::with_capacity((size * size) as usize);
            for y in 0..size {
                for x in 0..size {
                    let (u, v) = ((x as f32 + 0.5) / size as f32, (y as f32 + 0.5) / size as f32);
                    texels.push(f(cube_to_enu(face_uv_to_cube_dir(face, u, v))));
                }
            }
            texels
        });
        CubeMap { size, faces }
    }

    /// Every face one colour (linear RGB), in wgpu face order: the test pattern that shows
    /// which way each face points.
    pub fn solid_faces(size: u32, colours: [[f32; 3]; 6]) -> CubeMap {
        CubeMap { size, faces: colours.map(|c| vec![c; (size * size) as usize]) }
    }

    /// Radiance (linear RGB) seen along world direction `dir` (ENU, any length), bilinear
    /// within the face (clamped at its edges). Zero or non-finite directions give black.
    pub fn sample_enu(&self, dir: Vec3) -> [f32; 3] {
        if !dir.is_finite() || dir == Vec3::ZERO || self.size == 0 {
            return [0.0; 3];
        }
        let (face, u, v) = cube_dir_to_face_uv(enu_to_cube(dir));
        let texels = &self.faces[face];
        let n = self.size as usize;
        if texels.len() < n * n {
            return [0.0; 3]; // a malformed map (fields are public); no panic
        }
        let max = (n - 1) as f32;
        let x = (u * n as f32 - 0.5).clamp(0.0, max);
        let y = (v * n as f32 - 0.5).clamp(0.0, max);
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let (a, b, c, d) = (texels[y0 * n + x0], texels[y0 * n + x1], texels[y1 * n + x0], texels[y1 * n + x1]);
        std::array::from_fn(|i| {
            let top = a[i] + (b[i] - a[i]) * fx;
            let bottom = c[i] + (d[i] - c[i]) * fx;
            top + (bottom - top) * fy
        })
    }

    /// Arithmetic mean of a face's texels (linear RGB, not weighted by solid angle).
    /// A face index above 5 or an empty map gives black.
    pub fn face_mean(&self, face: usize) -> [f32; 3] {
        let Some(texels) = self.faces.get(face).filter(|t| !t.is_empty()) else {
            return [0.0; 3];
        };
        let sum = texels.iter().fold([0.0f64; 3], |s, t| [s[0] + t[0] as f64, s[1] + t[1] as f64, s[2] + t[2] as f64]);
        sum.map(|s| (s / texels.len() as f64) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vulkan_table_major_axes_and_corners() {
        // Face centres (Vulkan table: each axis direction maps to its own face, u = v = 0.5).
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        for (f, a) in axes.iter().enumerate() {
            assert_eq!(cube_dir_to_face_uv(*a), (f, 0.5, 0.5));
        }
        // +X face: sc = −rz, tc = −ry. Direction (1, 0.5, −0.5): sc = 0.5, tc = −0.5 →
        // u = 0.75, v = 0.25 (towards −z is right, +y is up).
        assert_eq!(cube_dir_to_face_uv(Vec3::new(1.0, 0.5, -0.5)), (0, 0.75, 0.25));
        // +Y face: sc = +rx, tc = +rz. (0.5, 1, 0.5) → u = 0.75, v = 0.75.
        assert_eq!(cube_dir_to_face_uv(Vec3::new(0.5, 1.0, 0.5)), (2, 0.75, 0.75));
        // −Y face: sc = +rx, tc = −rz. (0.5, −1, 0.5) → u = 0.75, v = 0.25.
        assert_eq!(cube_dir_to_face_uv(Vec3::new(0.5, -1.0, 0.5)), (3, 0.75, 0.25));
        // −Z face: sc = −rx, tc = −ry. (0.5, 0.5, −1) → u = 0.25, v = 0.25.
        assert_eq!(cube_dir_to_face_uv(Vec3::new(0.5, 0.5, -1.0)), (5, 0.25, 0.25));
        // −X face: sc = +rz, tc = −ry. (−1, −0.5, 0.5) → u = 0.75, v = 0.75.
        assert_eq!(cube_dir_to_face_uv(Vec3::new(-1.0, -0.5, 0.5)), (1, 0.75, 0.75));
        // Length does not matter.
        assert_eq!(cube_dir_to_face_uv(Vec3::new(4.0, 2.0, -2.0)), (0, 0.75, 0.25));
    }

    #[test]
    fn face_uv_round_trip_including_edges_and_corners() {
        for face in 0..6 {
            for &(u, v) in &[(0.5, 0.5), (0.1, 0.9), (0.99, 0.01), (0.3, 0.6)] {
                let d = face_uv_to_cube_dir(face, u, v);
                assert!((d.length() - 1.0).abs() < 1e-6);
                let (f2, u2, v2) = cube_dir_to_face_uv(d);
                assert_eq!(f2, face);
                assert!((u2 - u).abs() < 1e-5 && (v2 - v).abs() < 1e-5, "face {face} ({u},{v}) -> ({u2},{v2})");
            }
            // Exact corners land on a valid face with coordinates in [0, 1].
            for &(u, v) in &[(0.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                let (f2, u2, v2) = cube_dir_to_face_uv(face_uv_to_cube_dir(face, u, v));
                assert!(f2 < 6 && (0.0..=1.0).contains(&u2) && (0.0..=1.0).contains(&v2));
            }
        }
        assert_eq!(face_uv_to_cube_dir(6, 0.5, 0.5), Vec3::ZERO);
        assert_eq!(cube_dir_to_face_uv(Vec3::ZERO), (0, 0.5, 0.5));
        assert_eq!(cube_dir_to_face_uv(Vec3::new(f32::NAN, 0.0, 1.0)), (0, 0.5, 0.5));
    }

    #[test]
    fn side_faces_are_unmirrored_from_inside() {
        // Standing inside and facing a side face with the sky up, image-right (u growing) must be
        // the direction to our right: for ENU facing North, East; facing East, South; etc.
        let right_of = |forward: Vec3| forward.cross(Vec3::Z); // right-handed ENU, z up
        for forward in [Vec3::Y, Vec3::X, -Vec3::Y, -Vec3::X] {
            let (f0, u0, v0) = cube_dir_to_face_uv(enu_to_cube(forward));
            let (f1, u1, v1) = cube_dir_to_face_uv(enu_to_cube(forward + 0.2 * right_of(forward)));
            let (f2, _, v2) = cube_dir_to_face_uv(enu_to_cube(forward + 0.2 * Vec3::Z));
            assert_eq!((f0, f1, f2), (f0, f0, f0));
            assert!(u1 > u0 && (v1 - v0).abs() < 1e-6, "facing {forward}: right is +u");
            assert!(v2 < v0, "facing {forward}: up is −v (towards the top row)");
        }
    }

    #[test]
    fn solid_angles_sum_to_four_pi() {
        for size in [1u32, 2, 7, 64] {
            let total: f64 = (0..size).flat_map(|y| (0..size).map(move |x| texel_solid_angle(size, x, y) as f64)).sum::<f64>() * 6.0;
            assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-4, "size {size}: {total}");
        }
        // A whole face is 4π/6 (one sixth of the sphere, by symmetry).
        assert!((texel_solid_angle(1, 0, 0) - 4.0 * std::f32::consts::PI / 6.0).abs() < 1e-6);
        // Centre texels subtend more than corner texels.
        assert!(texel_solid_angle(8, 3, 4) > texel_solid_angle(8, 0, 0));
    }

    #[test]
    fn solid_faces_sampled_along_enu_axes() {
        let colours = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]];
        let cube = CubeMap::solid_faces(4, colours);
        // enu_to_cube: +X = East, +Y = Up, +Z = North.
        assert_eq!(cube.sample_enu(Vec3::X), colours[0]);
        assert_eq!(cube.sample_enu(-Vec3::X), colours[1]);
        assert_eq!(cube.sample_enu(Vec3::Z), colours[2]);
        assert_eq!(cube.sample_enu(-Vec3::Z), colours[3]);
        assert_eq!(cube.sample_enu(Vec3::Y * 3.0), colours[4]);
        assert_eq!(cube.sample_enu(-Vec3::Y), colours[5]);
        assert_eq!(cube.sample_enu(Vec3::ZERO), [0.0; 3]);
        assert_eq!(cube.sample_enu(Vec3::splat(f32::NAN)), [0.0; 3]);
        assert_eq!(cube.face_mean(4), colours[4]);
        assert_eq!(cube.face_mean(9), [0.0; 3]);
        let broken = CubeMap { size: 4, faces: Default::default() };
        assert_eq!(broken.sample_enu(Vec3::X), [0.0; 3]);
    }

    #[test]
    fn from_fn_and_bilinear_reproduce_a_linear_field() {
        // f(d) = d.x + 2 d.y is linear in the direction; at texel centres from_fn stores it
        // exactly, and bilinear sampling between centres of one face stays close (the map from
        // face coordinates to unit directions is smooth).
        let cube = CubeMap::from_fn(64, |d| [d.x + 2.0 * d.y, 0.0, 0.0]);
        for d in [Vec3::new(0.3, 0.9, 0.2), Vec3::new(-0.5, 0.1, 0.8), Vec3::new(0.2, -0.3, -0.9)] {
            let d = d.normalize();
            let got = cube.sample_enu(d)[0];
            assert!((got - (d.x + 2.0 * d.y)).abs() < 2e-3, "{d}: {got}");
        }
    }
}
