//! Making cube faces from shots by pose: for each face pixel, its direction (capture frame →
//! world by the reference heading), into each shot's camera by the pose estimated when the shot
//! was taken, to a frame pixel, sampled bilinearly in linear light. Not a centre crop: a shot
//! taken a little off target or rolled still lands where it belongs.

use super::Mode;
use super::projection::{Pinhole, face_pixel_dir_local, local_to_world};
use super::targets::Face;
use crate::colour::{linear_to_srgb, srgb_to_linear};
use crate::scene::Rgba8Image;
use glam::{Quat, Vec2, Vec3};
use std::sync::{Arc, OnceLock};

/// A frame taken by the assistant.
#[derive(Clone, Debug)]
pub struct Shot {
    /// Index of the target it was taken for.
    pub target: usize,
    /// Time (s) and the estimated camera pose (camera → world) when it was taken.
    pub t: f64,
    pub pose: Quat,
    pub image: Arc<Rgba8Image>,
    /// The accelerometer held before the shot (the capture's vertical, [`super::gravity`]);
    /// `None` where the readings were not logged.
    pub gravity: Option<super::gravity::HeldGravity>,
}

/// One assembled face: sRGB-encoded RGB8, `size`×`size`, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceImage {
    pub face: Face,
    pub size: u32,
    pub rgb: Vec<u8>,
    /// Fraction of the face's pixels whose true direction some shot observed (0..1).
    pub coverage: f32,
}

/// Stretch mode's magnification: the face is mapped onto the largest centred square of the
/// frame (tangent half-width = the smaller of the frame's two).
pub fn stretch_factor(camera: &Pinhole) -> f32 {
    camera.tan_half_h.min(camera.tan_half_v).min(1.0)
}

fn srgb_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// Bilinear sample (linear light) of an sRGB image at pixel position `p` (centres at +0.5),
/// clamped to the image's edge.
pub fn sample_linear(image: &Rgba8Image, p: Vec2) -> [f32; 3] {
    let lut = srgb_lut();
    bilinear(image.width as usize, image.height as usize, p, |x, y, c| lut[image.pixels[4 * (y * image.width as usize + x) + c] as usize])
}

/// Bilinear interpolation of a `w`×`h` RGB image whose texel (x, y) channel c is `px(x, y, c)`,
/// at pixel position `p` (centres at +0.5), clamped to the edge; black for an empty image or a
/// non-finite position.
pub fn bilinear(w: usize, h: usize, p: Vec2, px: impl Fn(usize, usize, usize) -> f32) -> [f32; 3] {
    if w == 0 || h == 0 || !p.is_finite() {
        return [0.0; 3];
    }
    let x = (p.x - 0.5).clamp(0.0, (w - 1) as f32);
    let y = (p.y - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    std::array::from_fn(|c| {
        let top = px(x0, y0, c) + (px(x1, y0, c) - px(x0, y0, c)) * fx;
        let bottom = px(x0, y1, c) + (px(x1, y1, c) - px(x0, y1, c)) * fx;
        top + (bottom - top) * fy
    })
}

/// Blend weight of a shot at normalised image position `n`: 1 inside, falling smoothly to a
/// small floor over the outer `FEATHER` of the frame (so overlapping shots cross-fade instead
/// of leaving a seam), 0 outside.
fn feather_weight(n: Vec2) -> f32 {
    const FEATHER: f32 = 0.15;
    let m = (1.0 - n.x.abs()).min(1.0 - n.y.abs());
    if m < 0.0 {
        return 0.0;
    }
    let s = (m / FEATHER).min(1.0);
    (s * s * (3.0 - 2.0 * s)).max(1e-3)
}

fn encode(c: [f32; 3], out: &mut Vec<u8>) {
    for v in c {
        out.push((linear_to_srgb(v) * 255.0 + 0.5) as u8);
    }
}

/// Assemble one face. Stretch mode uses the face's own shot only (`primary`); stitch mode
/// blends every shot that sees each pixel ([`stitch_face`]). Pixels no shot sees take the
/// nearest shot's clamped edge colour (and count against coverage).
pub fn assemble_face(
    face: Face,
    mode: Mode,
    primary: &Shot,
    shots: &[Shot],
    camera: &Pinhole,
    reference_heading_deg: f64,
    size: u32,
) -> FaceImage {
    let mut rgb = Vec::with_capacity((size * size * 3) as usize);
    let coverage = match mode {
        Mode::Stretch => {
            let to_world = local_to_world(reference_heading_deg.to_radians()).as_quat();
            let stretch = stretch_factor(camera);
            let mut seen = 0u64;
            for y in 0..size {
                for x in 0..size {
                    if camera.sees(primary.pose, to_world * face_pixel_dir_local(face.layer(), x, y, size, 1.0), 0.0) {
                        seen += 1;
                    }
                    let d = to_world * face_pixel_dir_local(face.layer(), x, y, size, stretch);
                    let p = camera.project(primary.pose, d).unwrap_or(Vec2::new(camera.width as f32, camera.height as f32) * 0.5);
                    encode(sample_linear(&primary.image, p), &mut rgb);
                }
            }
            seen as f32 / (size * size) as f32
        }
        Mode::Stitch => {
            let poses: Vec<Quat> = shots.iter().map(|s| s.pose).collect();
            let (colours, coverage) =
                stitch_face(face, &poses, camera, reference_heading_deg, size, |k, p| sample_linear(&shots[k].image, p));
            for c in colours {
                encode(c, &mut rgb);
            }
            coverage
        }
    };
    FaceImage { face, size, rgb, coverage }
}

/// Stitch one face from shots taken with `poses` (camera → world): per face pixel, every shot
/// that sees its direction, sampled by `sample(shot, pixel position)` (linear light, any
/// scale: display-linear 8-bit frames, or merged radiance) and blended with feathered edges.
/// Pixels no shot sees take the nearest shot's clamped edge sample. Returns the face's
/// colours (top row first) and its coverage.
pub fn stitch_face(
    face: Face,
    poses: &[Quat],
    camera: &Pinhole,
    reference_heading_deg: f64,
    size: u32,
    sample: impl Fn(usize, Vec2) -> [f32; 3],
) -> (Vec<[f32; 3]>, f32) {
    let to_world = local_to_world(reference_heading_deg.to_radians()).as_quat();
    let inverse: Vec<Quat> = poses.iter().map(|q| q.inverse()).collect();
    let mut out = Vec::with_capacity((size * size) as usize);
    let mut seen = 0u64;
    for y in 0..size {
        for x in 0..size {
            let true_dir = to_world * face_pixel_dir_local(face.layer(), x, y, size, 1.0);
            let (mut sum, mut wsum) = ([0.0f32; 3], 0.0f32);
            for (k, inv) in inverse.iter().enumerate() {
                let Some(n) = camera.to_ndc(*inv * true_dir) else { continue };
                let w = feather_weight(n);
                if w > 0.0 {
                    let c = sample(k, camera.ndc_to_pixel(n));
                    for i in 0..3 {
                        sum[i] += w * c[i];
                    }
                    wsum += w;
                }
            }
            if wsum > 0.0 {
                seen += 1;
                out.push(sum.map(|s| s / wsum));
            } else {
                out.push(nearest_edge(&inverse, camera, true_dir, &sample));
            }
        }
    }
    (out, seen as f32 / (size * size) as f32)
}

/// Colour for a direction no shot sees: the shot whose view axis is closest to it, sampled at
/// its clamped edge.
fn nearest_edge(inverse: &[Quat], camera: &Pinhole, dir: Vec3, sample: &impl Fn(usize, Vec2) -> [f32; 3]) -> [f32; 3] {
    let best = inverse.iter().enumerate().max_by(|a, b| (*a.1 * dir).z.total_cmp(&(*b.1 * dir).z).reverse());
    let Some((k, inv)) = best else { return [0.0; 3] };
    let c = *inv * dir;
    // Push directions behind the camera to the frame's edge in the same image direction.
    let n = if c.z < -1e-3 {
        Vec2::new(c.x / -c.z / camera.tan_half_h, c.y / -c.z / camera.tan_half_v)
    } else {
        Vec2::new(c.x, c.y).normalize_or_zero() * 1e3
    };
    let n = n.clamp(Vec2::splat(-1.0), Vec2::splat(1.0));
    sample(k, camera.ndc_to_pixel(n))
}

/// A synthetic "frame" for the capture tests: what a camera at `pose` sees of a world whose
/// colour is a function of direction, rendered exactly (no environment needed).
#[cfg(test)]
pub(super) fn render_synthetic(camera: &Pinhole, pose: Quat, f: &impl Fn(Vec3) -> [u8; 3]) -> Rgba8Image {
    let mut pixels = Vec::with_capacity((camera.width * camera.height * 4) as usize);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let c = f((pose * camera.pixel_to_dir(x as f32 + 0.5, y as f32 + 0.5)).normalize());
            pixels.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }
    Rgba8Image { width: camera.width, height: camera.height, pixels }
}

#[cfg(test)]
mod tests {
    use super::render_synthetic as render;
    use super::*;
    use crate::capture::targets::Target;
    use crate::pose::frames::from_heading_pitch_roll;

    /// Colour encodes the direction: an ideal face can be computed per pixel.
    fn world(d: Vec3) -> [u8; 3] {
        [((d.x * 0.5 + 0.5) * 255.0) as u8, ((d.y * 0.5 + 0.5) * 255.0) as u8, ((d.z * 0.5 + 0.5) * 255.0) as u8]
    }

    fn ideal(face: Face, href: f64, size: u32) -> Vec<u8> {
        let to_world = local_to_world(href.to_radians()).as_quat();
        (0..size * size).flat_map(|i| world(to_world * face_pixel_dir_local(face.layer(), i % size, i / size, size, 1.0))).collect()
    }

    fn mean_abs_diff(a: &[u8], b: &[u8]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs()).sum::<f64>() / a.len() as f64
    }

    #[test]
    fn a_rolled_off_target_shot_reprojects_into_place() {
        // Wide lens so one shot covers the whole face; the shot is 1.5° off in heading and
        // pitch and rolled 8°: the face must still match the ideal (no seam, no tilt).
        let cam = Pinhole::from_vfov(400, 300, 120.0).unwrap();
        let href = 359.0;
        let pose = from_heading_pitch_roll((href + 90.0 + 1.5f64).to_radians(), 1.5f64.to_radians(), 8f64.to_radians()).as_quat();
        let shot = Shot { target: 0, t: 0.0, pose, image: Arc::new(render(&cam, pose, &world)), gravity: None };
        let face = assemble_face(Face::Right, Mode::Stitch, &shot, std::slice::from_ref(&shot), &cam, href, 32);
        assert_eq!(face.coverage, 1.0);
        let err = mean_abs_diff(&face.rgb, &ideal(Face::Right, href, 32));
        assert!(err < 2.0, "mean abs error {err}");
        // A centre crop (ignoring the pose) would be tilted by the roll: clearly worse.
        let level = from_heading_pitch_roll((href + 90.0f64).to_radians(), 0.0, 0.0).as_quat();
        let wrong = Shot { pose: level, ..shot.clone() };
        let cropped = assemble_face(Face::Right, Mode::Stitch, &wrong, std::slice::from_ref(&wrong), &cam, href, 32);
        assert!(mean_abs_diff(&cropped.rgb, &ideal(Face::Right, href, 32)) > 4.0 * err.max(0.5));
    }

    #[test]
    fn stretch_covers_less_than_the_face_and_stitch_covers_it() {
        let cam = Pinhole::from_vfov(160, 120, 50.0).unwrap();
        let href = 10.0;
        let targets = super::super::targets::plan_targets(Mode::Stitch, &cam, 2.0);
        let shots: Vec<Shot> = targets
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let pose = t.pose(href).as_quat();
                Shot { target: i, t: i as f64, pose, image: Arc::new(render(&cam, pose, &world)), gravity: None }
            })
            .collect();
        let front = &shots[0];
        assert_eq!(targets[0], Target::for_face(Face::Front));
        let stretched = assemble_face(Face::Front, Mode::Stretch, front, &shots, &cam, href, 32);
        // Exactly aimed, a 50°x63.7° frame sees tan25°·tan31.87° of the face's 1x1 tangent
        // square (both half-widths in tangent units): 0.4663 · 0.6217 = 0.290.
        assert!((stretched.coverage - 0.290).abs() < 0.02, "{}", stretched.coverage);
        let stitched = assemble_face(Face::Front, Mode::Stitch, front, &shots, &cam, href, 32);
        assert_eq!(stitched.coverage, 1.0);
        let ideal = ideal(Face::Front, href, 32);
        let (es, et) = (mean_abs_diff(&stretched.rgb, &ideal), mean_abs_diff(&stitched.rgb, &ideal));
        assert!(et < 2.0 && es > 5.0 * et, "stitch {et} stretch {es}");
        for face in [Face::Up, Face::Down, Face::Back] {
            let f = assemble_face(face, Mode::Stitch, front, &shots, &cam, href, 32);
            assert_eq!(f.coverage, 1.0, "{face:?}");
            assert!(mean_abs_diff(&f.rgb, &super::tests::ideal(face, href, 32)) < 2.0, "{face:?}");
        }
    }

    #[test]
    fn bilinear_sampling_in_linear_light() {
        // Half black, half white: the midpoint is 0.5 linear, i.e. sRGB 188, not 128.
        let img = Rgba8Image { width: 2, height: 1, pixels: vec![0, 0, 0, 255, 255, 255, 255, 255] };
        let c = sample_linear(&img, Vec2::new(1.0, 0.5));
        assert!((c[0] - 0.5).abs() < 1e-6);
        assert_eq!((linear_to_srgb(c[0]) * 255.0 + 0.5) as u8, 188);
        // Clamped at the edges, black for NaN positions.
        assert_eq!(sample_linear(&img, Vec2::new(-5.0, 9.0))[0], 0.0);
        assert_eq!(sample_linear(&img, Vec2::new(f32::NAN, 0.0)), [0.0; 3]);
        assert_eq!(feather_weight(Vec2::new(1.1, 0.0)), 0.0);
        assert_eq!(feather_weight(Vec2::ZERO), 1.0);
    }
}
