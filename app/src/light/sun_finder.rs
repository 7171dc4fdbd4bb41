//! Find the sun in a set of direction samples: a compact region far brighter than the sky
//! around it. Works on any source of [`DirSample`]s — an equirectangular HDR
//! ([`samples::from_equirect`]), a cube map ([`samples::from_cube`]) or a posed camera frame
//! ([`samples::from_camera_image`]).
//!
//! # From camera pixels and a pose
//!
//! ```no_run
//! # use previz::light::{samples, sun_finder};
//! # let (w, h, pixels, vfov_deg, camera_to_world) = (4u32, 3u32, vec![[0.0f32; 3]; 12], 60.0f32, glam::Quat::IDENTITY);
//! // `pixels`: linear RGB (sRGB-decoded for 8-bit frames), row-major, top row first.
//! // `camera_to_world`: camera frame (+x right, +y up, looking along −z) → ENU.
//! let s = samples::from_camera_image(w, h, &pixels, vfov_deg.to_radians(), camera_to_world)?;
//! // 8-bit frames saturate at 1.0 (linear): say so, and a blown-out disc counts as the sun.
//! let options = sun_finder::Options { clip_level: Some(1.0), ..Default::default() };
//! if let Some(sun) = sun_finder::find_sun(&s, &options) {
//!     let (azimuth, elevation) = sun_finder::azimuth_elevation(sun.dir); // radians, clockwise from North
//!     // heading error of the pose = SPA azimuth − measured azimuth
//! }
//! # Ok::<(), anyhow::Error>(())
//! ```
//!
//! What is measured (all in the source's linear units):
//! - the region: samples within `search_radius` of the brightest sample above the horizon whose
//!   luminance exceeds max(2·sky, sky + 10⁻³·(peak − sky)), "sky" being the median of the ring
//!   between one and two search radii around the peak (per channel, so it has a colour);
//!   on a clipped source, the saturated samples within the search radius;
//! - direction: the mean of the region's directions weighted by their excess luminance; on a
//!   clipped source, the centre of the aureole fitted to the unclipped sky around the saturated
//!   region ([`super::aureole`]), else the saturated region's centre;
//! - irradiance at normal incidence: Σ (L − L_sky) dΩ over the region, per channel;
//! - colour: that irradiance scaled to luminance 1; solid angle: Σ dΩ over the region.
//!
//! It is a sun when the peak is at least `min_contrast` times the sky's luminance, or (clipped
//! sources) when the saturated region is compact (at most `max_saturated_solid_angle`) and the
//! ring around it is not saturated itself — a blown-out overcast sky has no sun.

use super::samples::DirSample;
use crate::colour::luminance_bt709;
use glam::Vec3;

/// Tuning of [`find_sun`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Linear value at which the source saturates (1.0 for 8-bit images after sRGB decoding);
    /// None: a float source trusted as it is.
    pub clip_level: Option<f32>,
    /// Radius (rad) of the cap around the peak searched for the sun; the sky reference is the
    /// ring from one to two radii.
    pub search_radius: f32,
    /// Least ratio of the peak's luminance to the sky's around it for an unclipped sun.
    pub min_contrast: f32,
    /// Largest solid angle (sr) a saturated region may have and still be the sun.
    pub max_saturated_solid_angle: f32,
}

impl Default for Options {
    fn default() -> Self {
        Options { clip_level: None, search_radius: 6f32.to_radians(), min_contrast: 20.0, max_saturated_solid_angle: 0.05 }
    }
}

/// The sun as measured in the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Sun {
    /// Unit direction to the sun (ENU).
    pub dir: Vec3,
    /// Irradiance on a surface facing the sun, linear RGB: Σ (L − L_sky) dΩ over the region.
    /// A lower bound when `saturated`.
    pub irradiance: [f32; 3],
    /// `irradiance` scaled to luminance 1 (white when saturated: the colour is lost).
    pub colour: [f32; 3],
    /// Solid angle of the region, sr (the true disc is 6.8·10⁻⁵ sr; resampling blurs it larger).
    pub solid_angle: f32,
    /// True when the region reaches the source's clip level: its energy is missing.
    pub saturated: bool,
    /// Peak luminance over the sky's luminance around it.
    pub contrast: f32,
    /// The sky's radiance around the sun (median of the ring), linear RGB.
    pub sky_radiance: [f32; 3],
    /// Indices of the samples that make up the sun.
    pub samples: Vec<usize>,
}

impl Sun {
    /// Angular radius (rad) of a disc with the region's solid angle.
    pub fn angular_radius(&self) -> f32 {
        (self.solid_angle / (2.0 * std::f32::consts::PI)).mul_add(-1.0, 1.0).clamp(-1.0, 1.0).acos()
    }

    /// The changes that remove the sun: each of its samples becomes the sky around it. Apply
    /// with [`super::samples::apply_to_cube`] / [`super::samples::apply_to_equirect`].
    pub fn removal(&self) -> Vec<(usize, [f32; 3])> {
        self.samples.iter().map(|&i| (i, self.sky_radiance)).collect()
    }
}

/// The aureole around an unclipped `sun` found with `options`: the samples of its search cap
/// above the horizon brighter than the sky around it (`sun.sky_radiance`, the ring's median)
/// that are not the disc's region, and their irradiance at normal incidence Σ (L − L_sky) dΩ,
/// linear RGB. The model hides the aureole from the ground as it hides the disc; left in the sky
/// it reaches the sun's shadow through the ground's coarse sky occlusion (docs/accuracy.md,
/// thirteenth session: 7 % of quarry_01's sun). None for a clipped sun, whose aureole is what
/// the restore reads.
pub fn aureole(samples: &[DirSample], sun: &Sun, options: &Options) -> (Vec<usize>, [f32; 3]) {
    if sun.saturated {
        return (Vec::new(), [0.0; 3]);
    }
    let in_disc = super::samples::mask(samples.len(), &sun.samples);
    let (cos_r, sky_lum) = (options.search_radius.cos(), luminance_bt709(sun.sky_radiance));
    let ring: Vec<usize> = (0..samples.len())
        .filter(|&i| {
            let s = &samples[i];
            !in_disc[i] && s.dir.z >= 0.0 && s.dir.dot(sun.dir) >= cos_r && luminance_bt709(s.radiance) > sky_lum
        })
        .collect();
    let mut irradiance = [0.0f32; 3];
    for &i in &ring {
        for (k, e) in irradiance.iter_mut().enumerate() {
            *e += (samples[i].radiance[k] - sun.sky_radiance[k]).max(0.0) * samples[i].solid_angle;
        }
    }
    (ring, irradiance)
}

/// The samples with the sun replaced by the sky around it.
pub fn without_sun(samples: &[DirSample], sun: &Sun) -> Vec<DirSample> {
    without_sun_and_aureole(samples, sun, &[])
}

/// The samples with the sun and the `aureole` samples ([`aureole`]) replaced by the sky around
/// it.
pub fn without_sun_and_aureole(samples: &[DirSample], sun: &Sun, aureole: &[usize]) -> Vec<DirSample> {
    let mut out = samples.to_vec();
    for &i in sun.samples.iter().chain(aureole) {
        if let Some(s) = out.get_mut(i) {
            s.radiance = sun.sky_radiance;
        }
    }
    out
}

/// Azimuth (rad, clockwise from North, 0..2π) and elevation (rad) of an ENU direction.
pub fn azimuth_elevation(d: Vec3) -> (f32, f32) {
    (d.x.atan2(d.y).rem_euclid(std::f32::consts::TAU), d.z.atan2(d.x.hypot(d.y)))
}

/// Lowest direction z searched for the peak (sin of −2°: a sun on the horizon, with some
/// slack for a tilted capture).
const HORIZON_Z: f32 = -0.035;

fn median(mut v: Vec<f32>) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// Find the sun; None when nothing compact stands out from the sky (overcast, night, indoors
/// without a window light, or no samples above the horizon).
pub fn find_sun(samples: &[DirSample], options: &Options) -> Option<Sun> {
    let lum: Vec<f32> = samples.iter().map(|s| luminance_bt709(s.radiance)).collect();
    let peak = (0..samples.len())
        .filter(|&i| samples[i].dir.z >= HORIZON_Z && lum[i].is_finite() && samples[i].solid_angle > 0.0)
        .max_by(|&a, &b| lum[a].total_cmp(&lum[b]))?;
    let peak_lum = lum[peak];
    if peak_lum <= 0.0 {
        return None;
    }
    let max_channel = |s: &DirSample| s.radiance.into_iter().fold(0.0f32, f32::max);
    let clip = options.clip_level.filter(|c| *c > 0.0 && max_channel(&samples[peak]) >= 0.99 * c);
    let saturated_at = |i: usize| clip.is_some_and(|c| max_channel(&samples[i]) >= 0.99 * c);
    let cos_r = options.search_radius.cos();
    // Where the source clips, every saturated sample is a "peak": centre the cap on the
    // saturated blob instead (a few mean-shift steps), so the direction is the blob's centre.
    let mut centre = samples[peak].dir;
    if clip.is_some() {
        for _ in 0..5 {
            let sum: Vec3 = (0..samples.len())
                .filter(|&i| samples[i].dir.dot(centre) >= cos_r && saturated_at(i))
                .map(|i| samples[i].dir * samples[i].solid_angle)
                .sum();
            centre = sum.normalize_or(centre);
        }
    }
    let cos_2r = (2.0 * options.search_radius).cos();
    let mut ring: [Vec<f32>; 3] = Default::default();
    let mut ring_lum = Vec::new();
    let mut cap = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        let c = s.dir.dot(centre);
        if c >= cos_r {
            cap.push(i);
        } else if c >= cos_2r {
            ring_lum.push(lum[i]);
            for (k, r) in ring.iter_mut().enumerate() {
                r.push(s.radiance[k]);
            }
        }
    }
    let sky_lum = median(ring_lum.clone());
    let sky_radiance = ring.map(median);
    let contrast = if sky_lum > 0.0 { peak_lum / sky_lum } else { f32::INFINITY };

    let (region, saturated) = if let Some(clip) = clip {
        let region: Vec<usize> = cap.iter().copied().filter(|&i| saturated_at(i)).collect();
        let area: f32 = region.iter().map(|&i| samples[i].solid_angle).sum();
        let ring_saturated = ring_lum.iter().filter(|&&l| l >= 0.99 * clip).count() * 2 > ring_lum.len();
        if area > options.max_saturated_solid_angle || ring_saturated {
            return None;
        }
        (region, true)
    } else {
        if contrast < options.min_contrast {
            return None;
        }
        let threshold = (2.0 * sky_lum).max(sky_lum + 1e-3 * (peak_lum - sky_lum));
        (cap.iter().copied().filter(|&i| lum[i] > threshold).collect(), false)
    };
    if region.is_empty() {
        return None;
    }

    let mut irradiance = [0.0f32; 3];
    let mut weighted = Vec3::ZERO;
    let mut solid_angle = 0.0;
    for &i in &region {
        let s = &samples[i];
        for (k, e) in irradiance.iter_mut().enumerate() {
            *e += (s.radiance[k] - sky_radiance[k]).max(0.0) * s.solid_angle;
        }
        weighted += s.dir * ((lum[i] - sky_lum).max(0.0) * s.solid_angle).max(1e-12);
        solid_angle += s.solid_angle;
    }
    let y = luminance_bt709(irradiance);
    let colour = if saturated || y <= 0.0 { [1.0; 3] } else { irradiance.map(|e| e / y) };
    // A clipped sun is where the aureole around the blob is centred (the blob reaches further
    // towards the bright horizon than away from it), when the sky around it can be fitted.
    let dir = if saturated {
        let unclipped = |i: usize| samples[i].radiance.iter().all(|&c| c.is_finite() && c < 0.99 * clip.unwrap_or(f32::INFINITY));
        super::aureole::fit(samples, &region, centre, unclipped).map_or(centre, |a| a.dir)
    } else {
        weighted.normalize_or(centre)
    };
    Some(Sun { dir, irradiance, colour, solid_angle, saturated, contrast, sky_radiance, samples: region })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::samples::{from_camera_image, from_cube, from_equirect};
    use crate::scene::environment::{Equirect, equirect_uv_to_enu, load_equirect};
    use glam::Quat;
    use std::f32::consts::PI;
    use std::path::Path;

    const SUN_RADIUS_DEG: f32 = 0.5;

    fn dir_from(az_deg: f32, el_deg: f32) -> Vec3 {
        let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
        Vec3::new(e.cos() * a.sin(), e.cos() * a.cos(), e.sin())
    }

    /// A blue sky brightening towards the horizon, a grey ground, and a sun disc of radius
    /// 0.5 deg and radiance `sun` at `sun_dir`; 4x4 supersampled so partly covered pixels get
    /// their share. Returns the map and the disc's exact irradiance (sun · 2π(1 − cos r)).
    fn synthetic_sky(w: u32, sun_dir: Vec3, sun: [f32; 3]) -> (Equirect, [f32; 3]) {
        let h = w / 2;
        let cos_r = SUN_RADIUS_DEG.to_radians().cos();
        let mut pixels = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0.0f32; 3];
                for sy in 0..4 {
                    for sx in 0..4 {
                        let u = (x as f32 + (sx as f32 + 0.5) / 4.0) / w as f32;
                        let v = (y as f32 + (sy as f32 + 0.5) / 4.0) / h as f32;
                        let d = equirect_uv_to_enu(u, v, 0.0);
                        let base = if d.z > 0.0 { [0.4 + 0.4 * (1.0 - d.z), 0.6 + 0.3 * (1.0 - d.z), 1.0] } else { [0.2, 0.2, 0.2] };
                        let l = if d.dot(sun_dir) > cos_r { [base[0] + sun[0], base[1] + sun[1], base[2] + sun[2]] } else { base };
                        acc = std::array::from_fn(|k| acc[k] + l[k] / 16.0);
                    }
                }
                pixels.push(acc);
            }
        }
        let omega = 2.0 * PI * (1.0 - f64::from(cos_r)) as f32;
        (Equirect::new(w, h, pixels).unwrap(), sun.map(|s| s * omega))
    }

    fn angle_deg(a: Vec3, b: Vec3) -> f32 {
        a.dot(b).clamp(-1.0, 1.0).acos().to_degrees()
    }

    fn rel(a: f32, b: f32) -> f32 {
        (a - b).abs() / b.abs()
    }

    #[test]
    fn finds_a_synthetic_sun_in_an_equirect_a_cube_and_a_camera_frame() {
        let sun_dir = dir_from(123.0, 27.0);
        let sun_rgb = [60_000.0, 50_000.0, 40_000.0];
        let (map, exact) = synthetic_sky(1024, sun_dir, sun_rgb);

        let s = find_sun(&from_equirect(&map, 0.0), &Options::default()).expect("sun in equirect");
        assert!(angle_deg(s.dir, sun_dir) < 0.1, "equirect direction off by {} deg", angle_deg(s.dir, sun_dir));
        for k in 0..3 {
            assert!(rel(s.irradiance[k], exact[k]) < 0.02, "equirect irradiance {:?} vs {exact:?}", s.irradiance);
        }
        // Colour: irradiance at luminance 1 keeps the sun's chromaticity.
        let y = luminance_bt709(sun_rgb);
        assert!((s.colour[0] - sun_rgb[0] / y).abs() < 0.02 && (s.colour[2] - sun_rgb[2] / y).abs() < 0.02, "{:?}", s.colour);
        assert!(!s.saturated && s.contrast > 1000.0);
        // Sky around the sun: the synthetic sky at 27 deg is (0.4 + 0.4(1 − sin 27°), 0.6 +
        // 0.3(1 − sin 27°), 1) = (0.618, 0.764, 1.0), give or take the gradient inside the ring.
        assert!((s.sky_radiance[2] - 1.0).abs() < 1e-3 && (s.sky_radiance[0] - 0.618).abs() < 0.01, "{:?}", s.sky_radiance);

        // The same map as a cube (the 2x2-averaging resampler keeps the energy only roughly).
        let cube = map.to_cube(256, 0.0);
        let c = find_sun(&from_cube(&cube), &Options::default()).expect("sun in cube");
        assert!(angle_deg(c.dir, sun_dir) < 0.3, "cube direction off by {} deg", angle_deg(c.dir, sun_dir));
        assert!(rel(c.irradiance[1], exact[1]) < 0.10, "cube irradiance {:?} vs {exact:?}", c.irradiance);

        // A camera looking at the sun, 10 deg field of view, slightly off centre.
        let look = dir_from(120.0, 25.0);
        let to_world = Quat::from_rotation_arc(-Vec3::Z, look);
        let (w, h) = (200u32, 160u32);
        let dirs = from_camera_image(w, h, &vec![[0.0; 3]; (w * h) as usize], 10f32.to_radians(), to_world).unwrap();
        let cos_r = SUN_RADIUS_DEG.to_radians().cos();
        let pixels: Vec<[f32; 3]> =
            dirs.iter().map(|d| if d.dir.dot(sun_dir) > cos_r { [60_001.0, 50_001.0, 40_001.0] } else { [1.0; 3] }).collect();
        let frame = from_camera_image(w, h, &pixels, 10f32.to_radians(), to_world).unwrap();
        let options = Options { search_radius: 2f32.to_radians(), ..Default::default() };
        let f = find_sun(&frame, &options).expect("sun in camera frame");
        assert!(angle_deg(f.dir, sun_dir) < 0.05, "camera direction off by {} deg", angle_deg(f.dir, sun_dir));
        assert!(rel(f.irradiance[1], exact[1]) < 0.05, "camera irradiance {:?} vs {exact:?}", f.irradiance);
    }

    #[test]
    fn clipped_sun_is_found_as_saturated_and_removed() {
        let sun_dir = dir_from(200.0, 40.0);
        let (map, _) = synthetic_sky(512, sun_dir, [5000.0; 3]);
        // An 8-bit capture: everything above 1.0 clips (the sky peaks at 1.0 blue too, so
        // expose it down first as a camera would).
        let clipped: Vec<[f32; 3]> = map.pixels().iter().map(|p| p.map(|c| (c * 0.8).min(1.0))).collect();
        let clipped = Equirect::new(512, 256, clipped).unwrap();
        let samples = from_equirect(&clipped, 0.0);
        // Trusted as a float map, the 1.0 disc is not far brighter than a 0.8 sky.
        assert!(find_sun(&samples, &Options::default()).is_none());
        let options = Options { clip_level: Some(1.0), ..Default::default() };
        let s = find_sun(&samples, &options).expect("saturated sun");
        assert!(s.saturated && s.colour == [1.0; 3]);
        assert!(angle_deg(s.dir, sun_dir) < 0.5, "{} deg", angle_deg(s.dir, sun_dir));
        let removed = without_sun(&samples, &s);
        let peak = removed.iter().map(|d| luminance_bt709(d.radiance)).fold(0.0, f32::max);
        assert!(peak < 0.99, "sun left in the map: peak {peak}");
    }

    #[test]
    fn overcast_and_blown_out_skies_have_no_sun() {
        // A smooth overcast sky, three times brighter at the zenith than at the horizon
        // (the CIE overcast sky is 1 + 2 sin(elevation)).
        let (w, h) = (256u32, 128u32);
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let d = equirect_uv_to_enu(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32, 0.0);
                [1.0 + 2.0 * d.z.max(0.0); 3]
            })
            .collect();
        let map = Equirect::new(w, h, pixels).unwrap();
        assert!(find_sun(&from_equirect(&map, 0.0), &Options::default()).is_none());
        // A white, blown-out sky in an 8-bit capture is no sun either.
        let blown: Vec<[f32; 3]> = map.pixels().iter().map(|p| p.map(|c| c.min(1.0))).collect();
        let blown = Equirect::new(w, h, blown).unwrap();
        assert!(find_sun(&from_equirect(&blown, 0.0), &Options { clip_level: Some(1.0), ..Default::default() }).is_none());
        // Nothing at all.
        assert!(find_sun(&[], &Options::default()).is_none());
        let black = Equirect::new(w, h, vec![[0.0; 3]; (w * h) as usize]).unwrap();
        assert!(find_sun(&from_equirect(&black, 0.0), &Options::default()).is_none());
    }

    fn data(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
    }

    #[test]
    fn finds_the_sun_in_real_hdrs() {
        // quarry_01: clear sky, unclipped sun. Its brightest pixel (hdri_peak_stats_DERIVED.csv,
        // numpy) is row 227, column 614 of 1024x512: elevation 10.02 deg, u 0.6001 (azimuth
        // 36.0 deg with the centre column North).
        let quarry = load_equirect(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
        let samples = from_equirect(&quarry, 0.0);
        let s = find_sun(&samples, &Options::default()).expect("quarry sun");
        let (az, el) = azimuth_elevation(s.dir);
        assert!(
            (el.to_degrees() - 10.02).abs() < 0.4 && (az.to_degrees() - 36.04).abs() < 0.4,
            "az {} el {}",
            az.to_degrees(),
            el.to_degrees()
        );
        assert!(!s.saturated && s.contrast > 1000.0, "{s:?}");
        // Late-afternoon sun light is warm: red above blue.
        assert!(s.colour[0] > s.colour[2], "{:?}", s.colour);
        // The csv says the top 0.1 % of pixels hold 47 % of the map's energy; the sun is most
        // of that. Sun irradiance vs the whole map's 4π-integral of luminance:
        let total: f32 = samples.iter().map(|d| luminance_bt709(d.radiance) * d.solid_angle).sum();
        let share = luminance_bt709(s.irradiance) / total;
        assert!((0.35..0.5).contains(&share), "sun share {share}");
        // Its aureole (the cap's samples above the horizon brighter than the ring, outside the
        // disc's region): numpy over the same equirect (cos-latitude pixel solid angles, the
        // brightest pixel's 6° cap, the 6–12° ring's median luminance subtracted) gives the disc's
        // region 0.4941 of the map's 4π luminance and the whole cap 0.5290: the aureole 0.0349.
        let (ring, aureole) = aureole(&samples, &s, &Options::default());
        let aureole_share = luminance_bt709(aureole) / total;
        assert!((aureole_share - 0.0349).abs() < 0.002, "aureole share {aureole_share}");
        assert!((share - 0.4941).abs() < 0.005, "sun share {share}");
        assert!(ring.iter().all(|i| !s.samples.contains(i) && samples[*i].dir.z >= 0.0));
        // Removing it leaves no pixel within 10x of the old peak.
        let rest = without_sun(&samples, &s);
        let peak = rest.iter().map(|d| luminance_bt709(d.radiance)).fold(0.0, f32::max);
        assert!(peak < 6374.0, "{peak}");

        // venice_sunset: sun re-saved much reduced (peak 44) but still a compact bright spot at
        // row 246, column 614 (elevation 3.34 deg, u 0.6001).
        let venice = load_equirect(&data("hdri/polyhaven_1k/venice_sunset_1k.hdr")).unwrap();
        if let Some(v) = find_sun(&from_equirect(&venice, 0.0), &Options::default()) {
            let (az, el) = azimuth_elevation(v.dir);
            assert!(
                (el.to_degrees() - 3.34).abs() < 1.0 && (az.to_degrees() - 36.04).abs() < 1.0,
                "az {} el {}",
                az.to_degrees(),
                el.to_degrees()
            );
        }
    }

    #[test]
    fn quarry_clipped_at_one_finds_the_same_direction() {
        // Expose quarry_01 as a camera might, clip at 1.0, and find the saturated disc. With
        // the exposure low enough that only the disc clips, it lands on the unclipped sun; at 5x
        // and 25x that, the aureole of the 10°-high sun clips too, lopsided (a blob ~9° across,
        // reaching down into the horizon's haze): its centroid is 2.75° off, the aureole fitted
        // around it (light::aureole) 0.60° (2026-12-01: 0.20°, 0.35°, 0.60° at the three
        // exposures, the blob's centroid 0.20°, 0.49°, 2.75°; before the aureole fit the bounds
        // were 0.5°, 1°, 3°).
        let quarry = load_equirect(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
        let full = find_sun(&from_equirect(&quarry, 0.0), &Options::default()).unwrap();
        for (exposure, bound_deg) in [(0.01, 0.35), (0.05, 0.5), (0.25, 0.75)] {
            let clipped: Vec<[f32; 3]> = quarry.pixels().iter().map(|p| p.map(|c| (c * exposure).min(1.0))).collect();
            let clipped = Equirect::new(quarry.width(), quarry.height(), clipped).unwrap();
            let samples = from_equirect(&clipped, 0.0);
            let s = find_sun(&samples, &Options { clip_level: Some(1.0), ..Default::default() }).expect("clipped sun");
            assert!(s.saturated);
            let off = angle_deg(s.dir, full.dir);
            let centroid = s.samples.iter().map(|&i| samples[i].dir * samples[i].solid_angle).sum::<Vec3>().normalize();
            let centroid_off = angle_deg(centroid, full.dir);
            eprintln!(
                "quarry x{exposure} clipped at 1.0: direction {off:.2} deg off (the blob's centroid {centroid_off:.2}), {:.4} sr saturated",
                s.solid_angle
            );
            assert!(off < bound_deg, "exposure {exposure}: {off} deg");
            if exposure == 0.25 {
                assert!(off < 0.5 * centroid_off, "the aureole's centre {off} deg off, the blob's {centroid_off} deg");
            }
        }
    }
}
