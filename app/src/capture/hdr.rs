//! HDR capture: a short exposure bracket per view (−4, 0, +4 EV: [`BRACKET_EV`]) merged into
//! scene radiance, and the merged views stitched by pose into float cube faces — the sky and the
//! sun's surroundings measured, not clipped.
//!
//! Merge: P. E. Debevec and J. Malik 1997, "Recovering High Dynamic Range Radiance Maps from
//! Photographs", SIGGRAPH 97, eq. 6: per pixel and channel,
//! ln E = Σ_j w(Z_j) (g(Z_j) − ln Δt_j) / Σ_j w(Z_j), with the hat weight w(z) = z for
//! z ≤ 127, 255 − z above (§2.1), and g the camera's response. The response here is known —
//! the virtual phone's tone curve, inverted ([`crate::camera::exposure::srgb8_to_exposed`]) —
//! instead of recovered from the images (D&M §2.1's least squares), and "Δt" is each frame's
//! whole gain on radiance: exposure × white balance ([`CameraSettings::gains`]), which the
//! camera reports per frame (Camera2's capture result, AVFoundation's sample metadata). So
//! E is in the environment's own radiance units, and a capture that did not lock exposure still
//! merges consistently. A pixel clipped in every bracket (the sun's disc, brighter than even
//! the −4 EV frame records) gets the darkest bracket's saturation level: a lower bound,
//! recorded as the capture's `clip_radiance`.

use super::projection::Pinhole;
use super::reproject::{bilinear, stitch_face};
use super::targets::Face;
use crate::camera::controls::CameraSettings;
use crate::camera::exposure::{exposed_lut, saturation_exposed};
use crate::scene::Rgba8Image;
use anyhow::{Result, bail};
use glam::{Quat, Vec2};

/// The bracket taken per view (stops relative to the capture's exposure); 0 EV is the shot the
/// assistant and the 8-bit faces use.
pub const BRACKET_EV: [f32; 3] = [-4.0, 0.0, 4.0];

/// A linear float RGB image (radiance), top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct FloatImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
}

impl FloatImage {
    /// Bilinear sample at pixel position `p` (centres at +0.5), clamped to the edge.
    pub fn sample(&self, p: Vec2) -> [f32; 3] {
        let w = self.width as usize;
        bilinear(w, self.height as usize, p, |x, y, c| self.rgb[y * w + x][c])
    }
}

/// Debevec & Malik's hat weight of an 8-bit code.
pub fn hat_weight(code: u8) -> f32 {
    f32::from(if code <= 127 { code } else { 255 - code })
}

/// The radiance above which every bracket of frames with these settings is clipped, per channel.
pub fn clip_radiance(brackets: &[CameraSettings]) -> [f32; 3] {
    let mut gains = [f32::INFINITY; 3];
    for s in brackets {
        for (g, b) in gains.iter_mut().zip(s.gains()) {
            *g = g.min(b);
        }
    }
    gains.map(|g| saturation_exposed() / g)
}

/// Merge frames of one view taken with different settings into radiance (Debevec & Malik 1997
/// eq. 6 with the known response). Frames must share their size.
pub fn merge_brackets(frames: &[(&Rgba8Image, CameraSettings)]) -> Result<FloatImage> {
    let Some((first, _)) = frames.first() else { bail!("no frames to merge") };
    let (w, h) = (first.width, first.height);
    if frames.iter().any(|(f, _)| f.width != w || f.height != h || f.pixels.len() != (w * h * 4) as usize) {
        bail!("the bracket's frames differ in size");
    }
    for (_, s) in frames {
        s.validate()?;
    }
    let ln_g: [f32; 256] = exposed_lut().map(|e| if e > 0.0 { e.ln() } else { f32::NEG_INFINITY });
    let ln_gain: Vec<[f32; 3]> = frames.iter().map(|(_, s)| s.gains().map(f32::ln)).collect();
    let clip = clip_radiance(&frames.iter().map(|(_, s)| *s).collect::<Vec<_>>());
    // The brightest bracket (largest gain) tells black: a code 0 there is below everything.
    let mut rgb = Vec::with_capacity((w * h) as usize);
    for i in 0..(w * h) as usize {
        let px: [f32; 3] = std::array::from_fn(|c| {
            let (mut num, mut den) = (0.0f32, 0.0f32);
            let mut all_white = true;
            for ((f, _), lg) in frames.iter().zip(&ln_gain) {
                let z = f.pixels[4 * i + c];
                all_white &= z == 255;
                let wt = hat_weight(z);
                if wt > 0.0 {
                    num += wt * (ln_g[z as usize] - lg[c]);
                    den += wt;
                }
            }
            if den > 0.0 {
                (num / den).exp()
            } else if all_white {
                clip[c]
            } else {
                0.0
            }
        });
        rgb.push(px);
    }
    Ok(FloatImage { width: w, height: h, rgb })
}

/// The six float faces (cube-layer order) stitched from merged views taken with `poses`
/// (camera → world), at the capture's reference heading, `size` texels a side.
pub fn hdr_faces(views: &[(Quat, FloatImage)], camera: &Pinhole, reference_heading_deg: f64, size: u32) -> Vec<Vec<[f32; 3]>> {
    let poses: Vec<Quat> = views.iter().map(|v| v.0).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = Face::ALL
            .iter()
            .map(|&face| {
                let poses = &poses;
                (face, scope.spawn(move || stitch_face(face, poses, camera, reference_heading_deg, size, |k, p| views[k].1.sample(p)).0))
            })
            .collect();
        let mut faces = vec![Vec::new(); 6];
        for (face, h) in handles {
            faces[face.layer()] = h.join().unwrap_or_default();
        }
        faces
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::exposure::ExposureMode;
    use crate::camera::sim::{SimSettings, VirtualPhone};
    use crate::scene::CubeMap;
    use std::sync::Arc;

    #[test]
    fn the_brackets_merge_into_the_radiance_they_saw() {
        // A view North across a world whose radiance doubles every 6° to the East: the frame
        // spans 11.5 stops (2^-4.8 to 2^6.8); each bracket alone clips or crushes part of it;
        // merged, every pixel's radiance is back within 8-bit steps.
        let env = Arc::new(CubeMap::from_fn(64, |d| {
            let l = 2f32.powf(-8.0 + 18.0 * (0.5 + 0.5 * d.x));
            [l, 0.5 * l, 0.25 * l]
        }));
        let phone =
            VirtualPhone::new(env.clone(), &SimSettings { width: 96, height: 72, vfov_deg: 60.0, exposure: ExposureMode::Fixed(1.0) })
                .unwrap();
        let pose = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        let base = CameraSettings { exposure: 0.3, white_balance: [0.8, 1.0, 1.6] };
        let frames: Vec<(Rgba8Image, CameraSettings)> =
            BRACKET_EV.iter().map(|ev| (phone.render_with(pose, base.with_ev(*ev)).unwrap(), base.with_ev(*ev))).collect();
        let merged = merge_brackets(&frames.iter().map(|(f, s)| (f, *s)).collect::<Vec<_>>()).unwrap();
        let cam = Pinhole::from_vfov(96, 72, 60.0).unwrap();
        let clip = clip_radiance(&frames.iter().map(|f| f.1).collect::<Vec<_>>());
        let (mut worst, mut n) = (0f32, 0);
        for y in 0..72 {
            for x in 0..96 {
                let d = pose * cam.pixel_to_dir(x as f32 + 0.5, y as f32 + 0.5);
                let truth = env.sample_enu(d);
                let got = merged.rgb[y * 96 + x];
                for c in 0..3 {
                    let t = truth[c].min(clip[c]);
                    worst = worst.max((got[c] / t - 1.0).abs());
                    n += 1;
                }
            }
        }
        eprintln!("worst relative error {:.2} % over {n} values", 100.0 * worst);
        assert!(worst < 0.03, "{worst}");
        // The 0 EV frame alone clips the bright end: the merge keeps its range.
        let max = merged.rgb.iter().map(|p| p[0]).fold(0.0, f32::max);
        assert!(max > 8.0, "{max}");
        assert!(merge_brackets(&[]).is_err());
        let small = Rgba8Image { width: 1, height: 1, pixels: vec![0; 4] };
        assert!(merge_brackets(&[(&frames[0].0, base), (&small, base)]).is_err());
    }

    #[test]
    fn hat_weights_and_clipped_pixels() {
        assert_eq!((hat_weight(0), hat_weight(127), hat_weight(128), hat_weight(255)), (0.0, 127.0, 127.0, 0.0));
        // Clipped in every frame: the darkest frame's saturation radiance.
        let white = Rgba8Image { width: 1, height: 1, pixels: vec![255; 4] };
        let s = CameraSettings::exposure(1.0);
        let m = merge_brackets(&[(&white, s.with_ev(-4.0)), (&white, s)]).unwrap();
        assert!((m.rgb[0][0] - saturation_exposed() * 16.0).abs() < 1e-3, "{:?}", m.rgb[0]);
        let black = Rgba8Image { width: 1, height: 1, pixels: vec![0, 0, 0, 255] };
        assert_eq!(merge_brackets(&[(&black, s)]).unwrap().rgb[0], [0.0; 3]);
    }
}
