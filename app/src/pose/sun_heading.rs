//! True north from the sun: the sun seen in a camera frame (or in a capture's cube map), put
//! into the world with the estimated pose, compared with where the sun really is (NREL SPA for
//! the GPS fix and the clock). The difference of the two azimuths is the estimate's heading
//! error — measured to a fraction of a degree, where the compass's steady error is degrees.
//!
//! 1. [`sight_sun`]: in an 8-bit frame the sun is a saturated, compact, round blob. The light
//!    module's sun finder ([`crate::light::sun_finder`], the same one that finds the sun in
//!    environment maps) centres on the saturated samples (their solid-angle-weighted mean
//!    direction: sub-pixel) and rejects a blown-out sky. Here the blob must also be small
//!    (angular radius ≤ [`MAX_RADIUS_DEG`]: a bright cloud edge is larger), round (second
//!    moment of the blob about its centre within [`MAX_ROUNDNESS`] of a disc's: a glint along
//!    a car roof or a window edge is elongated), clear of the image border (a cut disc has a
//!    biased centre), and the sky around it unsaturated (a contrast).
//! 2. [`heading_measurement`]: azimuth difference measured − SPA, accepted when the elevations
//!    agree (a reflection or a street light is somewhere else); its 1σ from the blob's
//!    centring (a fraction of a pixel, plus the asymmetry of a clipped aureole) and the pose's
//!    tilt error, which shifts the azimuth of a sun at elevation e by tilt·tan e.
//! 3. The fusion filter takes it as a measurement of its heading
//!    ([`super::fusion::OrientationFilter::sun_heading`]): a Kalman update on yaw.
//!
//! Sign: an estimate whose heading is `e` too large (clockwise) sees every direction, the sun
//! included, `e` too far clockwise, so `error = azimuth_measured − azimuth_SPA = e`, and the
//! correction turns the estimate by −e.

use crate::colour::luminance_bt709;
use crate::light::samples::{DirSample, from_camera_image, from_cube};
use crate::light::sun_finder::{self, Options, azimuth_elevation};
use crate::scene::{CubeMap, Rgba8Image};
use anyhow::Result;
use glam::{Quat, Vec2, Vec3};

/// Largest angular radius (degrees) of a saturated blob that is taken for the sun. The disc is
/// 0.27°; a clipped aureole around a low, hazy sun reaches a degree or two.
pub const MAX_RADIUS_DEG: f32 = 3.0;
/// Largest ratio of the blob's mean squared angular distance from its centre to a disc's of the
/// same area (1 for a disc, 4/3 for a 2:1 ellipse... a 3:1 streak is 1.67).
pub const MAX_ROUNDNESS: f32 = 1.5;
/// The blob must keep this many pixels from the image border.
pub const BORDER_PX: f32 = 3.0;
/// Largest disagreement between the measured and the SPA elevation (degrees) beyond the tilt
/// error: larger, and the blob is not the sun.
pub const ELEVATION_GATE_DEG: f64 = 2.0;
/// Centring error of the blob, as a fraction of its angular radius (the clipped aureole of a
/// low sun is lopsided towards the haze; measured on quarry_01 frames, see docs/pose.md).
const CENTRE_SIGMA_OF_RADIUS: f64 = 0.05;

/// The sun as seen in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunSighting {
    /// Unit direction (ENU) through the pose the frame was taken with.
    pub dir_world: Vec3,
    /// Unit direction in the camera frame (+x right, +y up, looking along −z).
    pub dir_camera: Vec3,
    /// Sub-pixel position in the image ((0, 0) the top-left corner, pixel centres at +0.5).
    pub pixel: Vec2,
    /// Angular radius of a disc with the blob's solid angle (degrees).
    pub radius_deg: f32,
    /// Blob's second moment over a disc's (1 = round).
    pub roundness: f32,
    /// Angular size of a pixel at the image centre (degrees).
    pub pixel_deg: f32,
    /// 0..1: 1 for a small round blob well inside the frame, falling towards the limits.
    pub confidence: f32,
}

/// A heading measurement from the sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingMeasurement {
    /// Heading error of the pose the sighting was made with (radians, positive = estimate too
    /// far clockwise): measured azimuth − SPA azimuth, wrapped to (−π, π].
    pub error: f64,
    /// Its 1σ (radians).
    pub sigma: f64,
    /// Measured − SPA elevation (radians), for the record.
    pub elevation_difference: f64,
}

fn linear_pixels(image: &Rgba8Image) -> Vec<[f32; 3]> {
    let lut: [f32; 256] = std::array::from_fn(|i| crate::colour::srgb_to_linear(i as f32 / 255.0));
    image.pixels.chunks_exact(4).map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]).collect()
}

/// The sun finder's options for a source that clips at `clip_level` (8-bit sources: 1.0 after
/// sRGB decoding), the search cap a little larger than the biggest blob accepted.
fn clipped_options(clip_level: f32) -> Options {
    Options { clip_level: Some(clip_level), search_radius: (2.0 * MAX_RADIUS_DEG).to_radians(), ..Default::default() }
}

/// Shape of the sun finder's region: (angular radius in rad, roundness) about `centre`.
fn blob_shape(samples: &[DirSample], region: &[usize], centre: Vec3) -> (f32, f32) {
    let area: f32 = region.iter().map(|&i| samples[i].solid_angle).sum();
    let second: f32 =
        region.iter().map(|&i| samples[i].dir.dot(centre).clamp(-1.0, 1.0).acos().powi(2) * samples[i].solid_angle).sum::<f32>()
            / area.max(1e-12);
    // A disc of area A = π r² has mean squared distance r²/2 = A/(2π) about its centre; a
    // region of a few pixels is never below a square pixel's A/6.
    let disc = area / (2.0 * std::f32::consts::PI);
    ((area / std::f32::consts::PI).sqrt(), (second / disc.max(1e-12)).max(1.0 / 3.0))
}

/// Sub-pixel centre of a clipped sun: the mean direction of the samples within `radius` + two
/// pixels of the finder's centre, each weighted by its luminance (at most `white`, a clipped
/// sample's) above the sky's.
/// Saturated samples weigh alike; the partly covered ones at the rim, brighter than the sky but
/// not saturated, weigh by how much of the sun they caught, which places the centre between
/// pixels.
fn refined_centre(samples: &[DirSample], centre: Vec3, radius: f32, pixel: f32, sky_lum: f32, white: f32) -> Vec3 {
    let cos_cap = (radius + 2.0 * pixel).cos();
    let sum: Vec3 = samples
        .iter()
        .filter(|s| s.dir.dot(centre) >= cos_cap)
        .map(|s| s.dir * ((luminance_bt709(s.radiance).min(white) - sky_lum).max(0.0) * s.solid_angle))
        .sum();
    sum.normalize_or(centre)
}

/// Find the sun in an 8-bit sRGB camera frame with vertical field of view `vfov_deg` taken
/// with `pose` (camera → ENU). None when no sun is seen, or a blob is there but fails the
/// size, shape, border or contrast tests (clouds, reflections, a sun cut by the frame).
pub fn sight_sun(image: &Rgba8Image, vfov_deg: f32, pose: Quat) -> Result<Option<SunSighting>> {
    let samples = from_camera_image(image.width, image.height, &linear_pixels(image), vfov_deg.to_radians(), pose)?;
    let Some(sun) = sun_finder::find_sun(&samples, &clipped_options(1.0)) else { return Ok(None) };
    let (radius, roundness) = blob_shape(&samples, &sun.samples, sun.dir);
    let radius_deg = radius.to_degrees();
    let tan_v = (0.5 * vfov_deg.to_radians()).tan();
    let pixel_plane = 2.0 * tan_v / image.height as f32;
    let dir_world = refined_centre(&samples, sun.dir, radius, pixel_plane, luminance_bt709(sun.sky_radiance), 1.0);
    let dir_camera = (pose.inverse() * dir_world).normalize();
    if dir_camera.z >= -1e-3 {
        return Ok(None);
    }
    let (w, h) = (image.width as f32, image.height as f32);
    let px = Vec2::new(w * 0.5 + (dir_camera.x / -dir_camera.z) / pixel_plane, h * 0.5 - (dir_camera.y / -dir_camera.z) / pixel_plane);
    // Border: every pixel of the region away from the edges.
    let near_border = sun.samples.iter().any(|&i| {
        let (x, y) = ((i as u32 % image.width) as f32 + 0.5, (i as u32 / image.width) as f32 + 0.5);
        x < BORDER_PX || y < BORDER_PX || x > w - BORDER_PX || y > h - BORDER_PX
    });
    if radius_deg > MAX_RADIUS_DEG || roundness > MAX_ROUNDNESS || near_border {
        return Ok(None);
    }
    let margin = |v: f32, limit: f32| (1.0 - v / limit).clamp(0.0, 1.0);
    let confidence = (margin(radius_deg, MAX_RADIUS_DEG).sqrt() * margin(roundness - 1.0, MAX_ROUNDNESS - 1.0).sqrt()).clamp(0.0, 1.0);
    Ok(Some(SunSighting {
        dir_world,
        dir_camera,
        pixel: px,
        radius_deg,
        roundness,
        pixel_deg: pixel_plane.atan().to_degrees(),
        confidence,
    }))
}

/// Find the sun in a capture's cube map (8-bit faces decoded to linear, the capture's local
/// frame: front = +Z = North) placed in the world with `reference_heading` (radians, clockwise
/// from North). Same tests as [`sight_sun`] except the border (a cube has none).
///
/// `clip`: the radiance (R, G, B) at which the faces clip: `[1.0; 3]` for 8-bit faces (sRGB
/// decoded), an HDR capture's `clip_radiance` for its float faces (the sun's disc clips even in
/// the darkest bracket; [`crate::capture::hdr`]).
pub fn sight_sun_in_capture(cube: &CubeMap, reference_heading: f64, clip: [f32; 3]) -> Option<SunSighting> {
    let turn = Quat::from_rotation_z(-reference_heading as f32);
    let mut samples = from_cube(cube);
    for s in &mut samples {
        s.dir = turn * s.dir;
    }
    // A texel whose largest channel reaches the largest channel's clip is clipped.
    let sun = sun_finder::find_sun(&samples, &clipped_options(clip.into_iter().fold(0.0, f32::max)))?;
    let (radius, roundness) = blob_shape(&samples, &sun.samples, sun.dir);
    let radius_deg = radius.to_degrees();
    if radius_deg > MAX_RADIUS_DEG || roundness > MAX_ROUNDNESS {
        return None;
    }
    let texel = (2.0 / cube.size as f32).atan();
    let dir_world = refined_centre(&samples, sun.dir, radius, texel, luminance_bt709(sun.sky_radiance), luminance_bt709(clip));
    let margin = |v: f32, limit: f32| (1.0 - v / limit).clamp(0.0, 1.0);
    Some(SunSighting {
        dir_world,
        dir_camera: dir_world,
        pixel: Vec2::ZERO,
        radius_deg,
        roundness,
        pixel_deg: (90.0 / cube.size as f32),
        confidence: (margin(radius_deg, MAX_RADIUS_DEG).sqrt() * margin(roundness - 1.0, MAX_ROUNDNESS - 1.0).sqrt()).clamp(0.0, 1.0),
    })
}

/// Exposure of the frame taken to measure the sun, relative to the scene's exposure (−4 EV,
/// a phone's usual bracket step): at a scene exposure the whole sky around a low sun clips
/// into a blob degrees wide and lopsided towards the haze (quarry_01 at the capture's locked
/// exposure: 0.02 sr, ring contrast 1.1), at −4 EV only the disc and the inner aureole do.
pub const SUN_FRAME_EXPOSURE: f32 = 1.0 / 16.0;

/// Whether the direction `sun` (ENU) falls inside a `width`×`height` frame with vertical field
/// of view `vfov_deg` at `pose`, at least `margin_deg` from its edges.
pub fn sun_in_view(pose: Quat, sun: Vec3, vfov_deg: f32, width: u32, height: u32, margin_deg: f32) -> bool {
    let c = pose.inverse() * sun;
    if c.z >= 0.0 {
        return false;
    }
    let tan_v = (0.5 * vfov_deg.to_radians()).tan();
    let tan_h = tan_v * width as f32 / height as f32;
    let (x, y) = ((c.x / -c.z).atan(), (c.y / -c.z).atan());
    let m = margin_deg.to_radians();
    x.abs() <= tan_h.atan() - m && y.abs() <= tan_v.atan() - m
}

/// Wrap an angle to (−π, π].
fn wrap_pi(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI { w - std::f64::consts::TAU } else { w }
}

/// Compare a sighting with the sun's true direction (`sun_enu`, e.g. SPA's
/// [`crate::sun::SunPosition::direction_enu`]); `tilt_sigma` is the pose's tilt 1σ (radians).
/// None when the sun is below the horizon or too near the zenith for an azimuth (above 80°), or
/// when the elevations disagree by more than [`ELEVATION_GATE_DEG`] + 3·tilt.
pub fn heading_measurement(sighting: &SunSighting, sun_enu: Vec3, tilt_sigma: f64) -> Option<HeadingMeasurement> {
    let (az_m, el_m) = azimuth_elevation(sighting.dir_world);
    let (az_s, el_s) = azimuth_elevation(sun_enu.normalize_or_zero());
    let (el_m, el_s) = (f64::from(el_m), f64::from(el_s));
    if !(-1f64.to_radians()..=80f64.to_radians()).contains(&el_s) {
        return None;
    }
    let elevation_difference = el_m - el_s;
    if elevation_difference.abs() > ELEVATION_GATE_DEG.to_radians() + 3.0 * tilt_sigma {
        return None;
    }
    let error = wrap_pi(f64::from(az_m) - f64::from(az_s));
    // Centring: a quarter pixel plus a share of the blob's radius; an angle off the line of
    // sight becomes 1/cos(e) of azimuth. Tilt: tan(e) of azimuth.
    let centre = (0.25 * f64::from(sighting.pixel_deg)).hypot(CENTRE_SIGMA_OF_RADIUS * f64::from(sighting.radius_deg)).to_radians();
    let sigma = (centre / el_s.cos()).hypot(tilt_sigma * el_s.tan().abs());
    Some(HeadingMeasurement { error, sigma, elevation_difference })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::exposure::ExposureMode;
    use crate::camera::sim::{SimSettings, VirtualPhone};
    use crate::pose::frames::from_heading_pitch_roll;
    use std::sync::Arc;

    fn dir(az_deg: f32, el_deg: f32) -> Vec3 {
        let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
        Vec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
    }

    /// A cube map: blue sky brightening to the horizon, grey ground, a 0.27° sun disc of
    /// radiance 5·10⁴ at `sun` (4×4 supersampled), and optionally a bright streak.
    fn sky(size: u32, sun: Option<Vec3>, streak: Option<(Vec3, Vec3)>) -> CubeMap {
        let cos_r = 0.27f32.to_radians().cos();
        let faces = std::array::from_fn(|face| {
            let mut texels = Vec::with_capacity((size * size) as usize);
            for y in 0..size {
                for x in 0..size {
                    let mut acc = [0.0f32; 3];
                    for k in 0..16 {
                        let (u, v) = (
                            (x as f32 + (k % 4) as f32 * 0.25 + 0.125) / size as f32,
                            (y as f32 + (k / 4) as f32 * 0.25 + 0.125) / size as f32,
                        );
                        let d = crate::scene::cube_to_enu(crate::scene::environment::face_uv_to_cube_dir(face, u, v)).normalize();
                        let mut l = if d.z > 0.0 { [0.5 + 0.5 * (1.0 - d.z), 0.7 + 0.3 * (1.0 - d.z), 1.2] } else { [0.15; 3] };
                        if sun.is_some_and(|s| d.dot(s) > cos_r) {
                            l = l.map(|c| c + 5.0e4);
                        }
                        // A thin glint: within 0.3° of the great circle through a and b, between them.
                        if let Some((a, b)) = streak {
                            let n = a.cross(b).normalize();
                            if d.dot(n).abs() < 0.3f32.to_radians().sin() && d.dot(a) > a.dot(b) && d.dot(b) > a.dot(b) {
                                l = l.map(|c| c + 2.0e3);
                            }
                        }
                        acc = std::array::from_fn(|i| acc[i] + l[i] / 16.0);
                    }
                    texels.push(acc);
                }
            }
            texels
        });
        CubeMap { size, faces }
    }

    fn phone(cube: CubeMap) -> VirtualPhone {
        let mut p =
            VirtualPhone::new(Arc::new(cube), &SimSettings { width: 320, height: 240, vfov_deg: 50.0, exposure: ExposureMode::default() })
                .unwrap();
        p.set_threads(1);
        p
    }

    #[test]
    fn a_rendered_sun_gives_the_heading_error_of_the_pose() {
        // Sun at azimuth 215°, elevation 12°; the camera looks at heading 205°, pitch 5°, so the
        // sun is right of centre. The estimated pose is 2.5° too far clockwise.
        let sun = dir(215.0, 12.0);
        let mut p = phone(sky(512, Some(sun), None));
        let truth = from_heading_pitch_roll(205f64.to_radians(), 5f64.to_radians(), 0.0).as_quat();
        let frame = p.render(truth, 0.0).unwrap().image;
        let est = Quat::from_rotation_z(-2.5f32.to_radians()) * truth;
        let s = sight_sun(&frame, 50.0, est).unwrap().expect("sun in view");
        // Where the true ray hits the image: heading 10° right of centre, 7° up.
        let c = truth.inverse() * sun;
        let f = 120.0 / 25f32.to_radians().tan();
        let expected = Vec2::new(160.0 + f * c.x / -c.z, 120.0 - f * c.y / -c.z);
        // Any cube texel the disc touches saturates (5·10⁴ against a sky of ~1), so the blob's
        // outline is quantised to the map's 0.18° texels: within half a texel (0.09°, 0.45 px).
        assert!((s.pixel - expected).length() < 0.45, "pixel {:?} vs {expected:?}", s.pixel);
        assert!(s.radius_deg < 1.0 && s.roundness < 1.3 && s.confidence > 0.5, "{s:?}");
        let m = heading_measurement(&s, sun, 0.5f64.to_radians()).expect("measurement");
        eprintln!("pixel {:?} vs {expected:?}; error {}°, σ {}°", s.pixel, m.error.to_degrees(), m.sigma.to_degrees());
        assert!((m.error.to_degrees() - 2.5).abs() < 0.09, "error {}°", m.error.to_degrees());
        assert!(m.elevation_difference.to_degrees().abs() < 0.09, "{}", m.elevation_difference.to_degrees());
        // 1σ: centring (¼ of a 0.2° pixel) and 0.5° tilt × tan 12° = 0.11°.
        assert!((0.1..0.2).contains(&m.sigma.to_degrees()), "sigma {}°", m.sigma.to_degrees());
        // The exact pose measures no error.
        let s0 = sight_sun(&frame, 50.0, truth).unwrap().unwrap();
        let m0 = heading_measurement(&s0, sun, 0.0).unwrap();
        assert!(m0.error.to_degrees().abs() < 0.09, "{}", m0.error.to_degrees());
    }

    #[test]
    fn no_sun_when_hidden_cut_by_the_border_or_not_compact() {
        let sun = dir(215.0, 12.0);
        let mut p = phone(sky(256, Some(sun), None));
        // Looking away from the sun.
        let away = from_heading_pitch_roll(30f64.to_radians(), 5f64.to_radians(), 0.0).as_quat();
        let frame = p.render(away, 0.0).unwrap().image;
        assert_eq!(sight_sun(&frame, 50.0, away).unwrap(), None);
        // The sun on the image's left edge (horizontal half-field 31.8°).
        let edge = from_heading_pitch_roll((215.0f64 + 31.8).to_radians(), 12f64.to_radians(), 0.0).as_quat();
        let frame = p.render(edge, 0.0).unwrap().image;
        assert_eq!(sight_sun(&frame, 50.0, edge).unwrap(), None);
        // Overcast: no disc, a bright but smooth sky.
        let mut p = phone(sky(256, None, None));
        let towards = from_heading_pitch_roll(215f64.to_radians(), 12f64.to_radians(), 0.0).as_quat();
        assert_eq!(sight_sun(&p.render(towards, 0.0).unwrap().image, 50.0, towards).unwrap(), None);
        // A glint 10° long and 0.6° wide (a reflection along an edge): saturated but a streak.
        let mut p = phone(sky(512, None, Some((dir(205.0, 8.0), dir(215.0, 9.0)))));
        let frame = p.render(towards, 0.0).unwrap().image;
        assert_eq!(sight_sun(&frame, 50.0, towards).unwrap(), None);
    }

    #[test]
    fn a_sun_in_the_wrong_place_is_not_used() {
        // A sighting 6° below where SPA puts the sun (a reflection in a window): rejected; at
        // the zenith or below the horizon there is no azimuth to compare.
        let s = SunSighting {
            dir_world: dir(180.0, 10.0),
            dir_camera: -Vec3::Z,
            pixel: Vec2::ZERO,
            radius_deg: 0.5,
            roundness: 1.0,
            pixel_deg: 0.2,
            confidence: 1.0,
        };
        assert!(heading_measurement(&s, dir(181.0, 16.0), 0.5f64.to_radians()).is_none());
        assert!(heading_measurement(&s, dir(181.0, 85.0), 0.5f64.to_radians()).is_none());
        assert!(heading_measurement(&s, dir(181.0, -5.0), 0.5f64.to_radians()).is_none());
        // Across north: measured 359°, SPA 1° → −2°.
        let n = SunSighting { dir_world: dir(359.0, 10.0), ..s };
        let m = heading_measurement(&n, dir(1.0, 10.0), 0.0).unwrap();
        assert!((m.error.to_degrees() + 2.0).abs() < 1e-3, "{}", m.error.to_degrees());
    }

    #[test]
    fn the_sun_is_in_view_inside_the_frame_and_its_margin() {
        // Heading 200°, the frame 50° high and 66.7° wide (4:3): a sun 30° right is in view,
        // 35° right is not, and 30° right with a 3° margin is not either (half width 33.4°).
        let pose = from_heading_pitch_roll(200f64.to_radians(), 0.0, 0.0).as_quat();
        assert!(sun_in_view(pose, dir(230.0, 0.0), 50.0, 320, 240, 0.0));
        assert!(!sun_in_view(pose, dir(235.0, 0.0), 50.0, 320, 240, 0.0));
        assert!(!sun_in_view(pose, dir(230.0, 0.0), 50.0, 320, 240, 3.5));
        assert!(!sun_in_view(pose, dir(20.0, 0.0), 50.0, 320, 240, 0.0));
    }

    #[test]
    fn the_sun_in_a_capture_cube_gives_its_heading() {
        // A capture's cube in its local frame (front = North) whose front faced true heading
        // 200°: the sun at true azimuth 215° sits 15° right of the front. Placed with a
        // reference heading 3° too large, the sun is measured 3° clockwise.
        let local_sun = dir(15.0, 12.0);
        let cube = sky(256, Some(local_sun), None);
        // 8-bit like a capture: expose, clip at 1, quantise.
        let q = |c: f32| crate::colour::srgb_to_linear((crate::colour::linear_to_srgb((c * 0.5).min(1.0)) * 255.0).round() / 255.0);
        let cube = CubeMap { size: cube.size, faces: cube.faces.map(|f| f.into_iter().map(|p| p.map(q)).collect()) };
        let s = sight_sun_in_capture(&cube, 203f64.to_radians(), [1.0; 3]).expect("sun in the capture");
        let m = heading_measurement(&s, dir(215.0, 12.0), 0.0).unwrap();
        // Within half of the capture's 0.35° texel (the disc saturates every texel it touches).
        assert!((m.error.to_degrees() - 3.0).abs() < 0.18, "{}", m.error.to_degrees());
    }
}
