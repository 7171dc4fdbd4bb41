//! Camera, model placement and the sun's shadow camera: small pure functions on glam types.
//!
//! World = ENU (+x East, +y North, +z Up). Camera frame: +x right, +y up, looking along −z.
//! A camera pose is a unit quaternion rotating camera → world.

use glam::{Mat3, Mat4, Quat, Vec3};

/// Camera orientation from heading (clockwise from true north), pitch (up positive) and roll
/// (positive = the camera turns clockwise about its view direction, so the image content turns
/// counter-clockwise), all in radians. Heading 0, pitch 0, roll 0 looks North, level.
pub fn camera_pose(heading: f32, pitch: f32, roll: f32) -> Quat {
    // Level, looking North: camera x -> East, y -> Up, z -> South.
    let level_north = Quat::from_mat3(&Mat3::from_cols(Vec3::X, Vec3::Z, -Vec3::Y));
    let yaw = Quat::from_axis_angle(Vec3::Z, -heading);
    let pitch = Quat::from_axis_angle(Vec3::X, pitch);
    let roll = Quat::from_axis_angle(-Vec3::Z, roll);
    (yaw * level_north * pitch * roll).normalize()
}

/// World → camera matrix for a camera at `position` with orientation `pose` (camera → world).
pub fn view_matrix(pose: Quat, position: Vec3) -> Mat4 {
    Mat4::from_rotation_translation(pose, position).inverse()
}

/// Perspective projection to wgpu clip space (depth 0..1) from a vertical field of view.
pub fn projection(vfov: f32, aspect: f32, near: f32, far: f32) -> Mat4 {
    glam::camera::rh::proj::directx::perspective(vfov, aspect, near, far)
}

/// Model files are y-up; world is z-up. Model (x, y, z) → world (x, −z, y): the model's +y
/// becomes Up and its front (+z) faces South, towards a camera looking North.
pub fn model_to_world_axes() -> Mat4 {
    Mat4::from_cols(
        glam::Vec4::new(1.0, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, 1.0, 0.0),
        glam::Vec4::new(0.0, -1.0, 0.0, 0.0),
        glam::Vec4::W,
    )
}

/// Where and how large the model stands in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// World position of the model's base centre (bottom of its bounding box), metres.
    pub position: Vec3,
    /// Rotation about the model's own axes after the y-up → z-up turn: Euler X, Y, Z in radians
    /// applied as Z·Y·X (seed 000's X/Y/Z controls), about world East, North, Up.
    pub rotation: Vec3,
    /// Uniform scale (model units → metres).
    pub scale: f32,
}

/// Model matrix: centre the model's bounding box base on the origin, y-up → z-up, scale, rotate,
/// then move to the placement position.
pub fn model_matrix(bounds: (Vec3, Vec3), p: &Placement) -> Mat4 {
    let (lo, hi) = bounds;
    let base = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
    let rot = Mat4::from_rotation_z(p.rotation.z) * Mat4::from_rotation_y(p.rotation.y) * Mat4::from_rotation_x(p.rotation.x);
    Mat4::from_translation(p.position)
        * rot
        * Mat4::from_scale(Vec3::splat(p.scale))
        * model_to_world_axes()
        * Mat4::from_translation(-base)
}

/// Inverse transpose of the upper 3×3 of `m` (seed Eq. 4), as a 4×4 for the uniform.
pub fn normal_matrix(m: &Mat4) -> Mat4 {
    Mat4::from_mat3(Mat3::from_mat4(*m).inverse().transpose())
}

/// Default placement: the model, scaled so its largest dimension is `size` metres, stands with
/// its bounding sphere centred on the camera's forward ray, at the distance where that sphere
/// spans `fill` of the vertical field of view. The ground is then the model's base.
pub fn auto_placement(bounds: (Vec3, Vec3), pose: Quat, camera: Vec3, vfov: f32, size: f32, fill: f32) -> Placement {
    let extent = bounds.1 - bounds.0;
    let largest = extent.max_element().max(f32::MIN_POSITIVE);
    let scale = size / largest;
    let radius = 0.5 * extent.length() * scale;
    let distance = radius / (fill * vfov * 0.5).tan();
    let forward = pose * -Vec3::Z;
    let centre = camera + forward * distance;
    // The box's base centre sits half its (world) height below the centre.
    let height = extent.y * scale;
    Placement { position: centre - Vec3::Z * (0.5 * height), rotation: Vec3::ZERO, scale }
}

/// Orthographic camera looking along −sun that just encloses a sphere (centre, radius), for the
/// shadow map. Depth runs 0..1 from the sphere's sun-facing side to its far side.
pub fn sun_view_proj(sun: Vec3, centre: Vec3, radius: f32) -> Mat4 {
    let up = if sun.z.abs() > 0.99 { Vec3::Y } else { Vec3::Z };
    let eye = centre + sun * (2.0 * radius);
    let view = glam::camera::rh::view::look_at_mat4(eye, centre, up);
    let proj = glam::camera::rh::proj::directx::orthographic(-radius, radius, -radius, radius, radius, 3.0 * radius);
    proj * view
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_2;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn camera_pose_conventions() {
        // Hand-checkable: level heading 0 looks North with image-up = Up and image-right = East.
        let q = camera_pose(0.0, 0.0, 0.0);
        assert!(close(q * -Vec3::Z, Vec3::Y));
        assert!(close(q * Vec3::Y, Vec3::Z));
        assert!(close(q * Vec3::X, Vec3::X));
        // Heading 90° (clockwise from North) looks East; right is then South.
        let q = camera_pose(FRAC_PI_2, 0.0, 0.0);
        assert!(close(q * -Vec3::Z, Vec3::X));
        assert!(close(q * Vec3::X, -Vec3::Y));
        // Pitch +90° looks straight up, image-up points North (the top of the view is ahead).
        let q = camera_pose(0.0, FRAC_PI_2, 0.0);
        assert!(close(q * -Vec3::Z, Vec3::Z));
        assert!(close(q * Vec3::Y, -Vec3::Y));
        // Roll +90° (clockwise): image-right now points Down, image-up points East.
        let q = camera_pose(0.0, 0.0, FRAC_PI_2);
        assert!(close(q * Vec3::X, -Vec3::Z));
        assert!(close(q * Vec3::Y, Vec3::X));
        // Heading wraps: 360° equals 0°.
        assert!(camera_pose(2.0 * std::f32::consts::PI, 0.3, 0.1).angle_between(camera_pose(0.0, 0.3, 0.1)) < 1e-3);
    }

    #[test]
    fn projection_maps_forward_to_centre_and_depth_range() {
        let p = projection(60f32.to_radians(), 1.5, 0.1, 100.0);
        let near = p.project_point3(Vec3::new(0.0, 0.0, -0.1));
        let far = p.project_point3(Vec3::new(0.0, 0.0, -100.0));
        assert!(near.z.abs() < 1e-5 && (far.z - 1.0).abs() < 1e-5);
        // A point at the top edge of the field of view lands on ndc y = 1.
        let top = p.project_point3(Vec3::new(0.0, (30f32).to_radians().tan(), -1.0));
        assert!((top.y - 1.0).abs() < 1e-5);
    }

    #[test]
    fn model_axes_and_normal_matrix() {
        // Model +y is world Up, model +z (its front) faces South.
        let m = model_to_world_axes();
        assert!(close(m.transform_vector3(Vec3::Y), Vec3::Z));
        assert!(close(m.transform_vector3(Vec3::Z), -Vec3::Y));
        // Under a non-uniform scale the normal matrix keeps normals perpendicular to surfaces.
        let m = Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0));
        let tangent = m.transform_vector3(Vec3::new(1.0, -1.0, 0.0));
        let normal = normal_matrix(&m).transform_vector3(Vec3::new(1.0, 1.0, 0.0));
        assert!(tangent.dot(normal).abs() < 1e-6);
    }

    #[test]
    fn auto_placement_centres_the_model_on_the_view_ray() {
        let bounds = (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 4.0, 1.0));
        let pose = camera_pose(0.7, -0.2, 0.0);
        let vfov = 50f32.to_radians();
        let p = auto_placement(bounds, pose, Vec3::new(0.0, 0.0, 1.6), vfov, 1.0, 0.5);
        assert!((p.scale - 0.25).abs() < 1e-6);
        let m = model_matrix(bounds, &p);
        let centre = m.transform_point3(Vec3::new(0.0, 2.0, 0.0));
        let dir = (centre - Vec3::new(0.0, 0.0, 1.6)).normalize();
        assert!(close(dir, pose * -Vec3::Z));
        // The bounding sphere subtends half the vertical field of view.
        let radius = 0.5 * (bounds.1 - bounds.0).length() * p.scale;
        let distance = (centre - Vec3::new(0.0, 0.0, 1.6)).length();
        assert!(((radius / distance).atan() * 2.0 - 0.5 * vfov).abs() < 1e-4);
        // Base on the placement position, height 1 m after scaling.
        assert!(close(m.transform_point3(Vec3::ZERO), p.position));
        assert!(close(m.transform_point3(Vec3::new(0.0, 4.0, 0.0)), p.position + Vec3::Z));
    }

    #[test]
    fn shadow_camera_encloses_the_sphere() {
        let sun = Vec3::new(0.3, -0.5, 0.8).normalize();
        let centre = Vec3::new(1.0, 5.0, 0.5);
        let m = sun_view_proj(sun, centre, 2.0);
        // The sphere's sun-facing point is at depth 0, the far point at depth 1, the centre 0.5.
        assert!(m.project_point3(centre + sun * 2.0).z.abs() < 1e-5);
        assert!((m.project_point3(centre - sun * 2.0).z - 1.0).abs() < 1e-5);
        let c = m.project_point3(centre);
        assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5 && (c.z - 0.5).abs() < 1e-5);
        // Straight-down sun works too (degenerate up vector avoided).
        let m = sun_view_proj(Vec3::Z, centre, 1.0);
        assert!(m.is_finite());
    }
}
