//! Light from the scene's environment (issue 9): the sun and sky measured in the map
//! (`light::measure`) become the frame's sunlight, daylight and shadow strength, and — unless the
//! scene gives the sun's direction — the sun's direction. The scene's `sun.sunlight`,
//! `sun.daylight` and `effects.shadow_opacity` are multipliers on these (1 by default).
//!
//! Units: the renderer's linear light after the environment's exposure. A Lambertian surface of
//! albedo ρ under irradiance E has radiance ρ E / π, so the sunlight the model shader multiplies
//! by albedo · max(n·l, 0) is E_sun / π, and the ambient terms are scaled so that the methods'
//! ambient light equals E_sky / π (the sky without the sun, SH9) averaged over the up- and
//! down-facing normals.

use crate::light::measure::{MeasureOptions, MeasuredLight, SunSource, measure};
use crate::light::samples::from_cube;
use crate::light::sh9::COSINE_LOBE;
use crate::light::sun_finder;
use crate::render::{HemispherePriors, LightingMethod};
use crate::scene::CubeMap;
use crate::setup::scene_file::Scene;
use anyhow::{Result, bail};
use glam::Vec3;
use std::path::Path;

/// Measure the light in the scene's environment map. A clipped sun is found at the map's clip
/// level ([`clip_level`]) and its energy restored (from the ground's colours where they show the
/// sun's share, else from the clear-sky model: light::measure) at the scene's sun elevation when
/// the scene gives the sun's direction (else the saturated disc's); a float map
/// with no clip level is trusted as it is. Errors: an HDR capture's capture.json that cannot be
/// read.
pub fn measure_environment(scene: &Scene, env: &CubeMap) -> Result<MeasuredLight> {
    let samples = from_cube(env);
    let clip_level = clip_level(scene, &samples)?;
    let finder = sun_finder::Options { clip_level, ..Default::default() };
    let solar_elevation = scene.sun.direction.map(|d| sun_finder::azimuth_elevation(Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32)).1);
    Ok(measure(&samples, &MeasureOptions { finder, restore_clipped: clip_level.is_some(), solar_elevation }))
}

/// The radiance at which the environment's values clip, None when they do not: 1 for an 8-bit
/// map (every value ≤ 1: JPEG cube maps, 8-bit captures, the folded camera frame); for a float
/// map, the clip level of the HDR capture it was loaded from (the scene's environment folder's
/// capture.json, [`hdr_capture_clip`]: even the darkest bracket clips the sun's disc, which
/// then holds about a third of the sun's irradiance); None for any other float map (a
/// downloaded HDR is trusted as it is).
pub fn clip_level(scene: &Scene, samples: &[crate::light::samples::DirSample]) -> Result<Option<f32>> {
    let max = samples.iter().flat_map(|s| s.radiance).fold(0f32, f32::max);
    if max <= 1.0 {
        return Ok(Some(1.0));
    }
    match &scene.environment {
        Some(path) => hdr_capture_clip(path),
        None => Ok(None),
    }
}

/// An HDR capture folder's clip level: capture.json's `hdr.clip_radiance`, its smallest channel.
/// The sun finder takes one level and tests a texel's largest channel against it; a texel of
/// the disc clips in some channels only (quarry_01's warm sun: R and G at their clip, 110 and
/// 139, B below 139 although its clip is 148), so a texel is clipped when any channel reaches
/// the lowest clip. None for a path that is not a capture folder or a capture without float
/// faces. Errors name the metadata file.
pub fn hdr_capture_clip(path: &Path) -> Result<Option<f32>> {
    let meta = path.join(crate::capture::folder::META_FILE);
    if !path.is_dir() || !meta.is_file() {
        return Ok(None);
    }
    let Some(hdr) = crate::capture::folder::read_meta(path)?.hdr else { return Ok(None) };
    let clip = hdr.clip_radiance.into_iter().fold(f32::INFINITY, f32::min);
    if !(clip.is_finite() && clip > 0.0) {
        bail!("{}: hdr.clip_radiance {:?} is not a positive radiance", meta.display(), hdr.clip_radiance);
    }
    Ok(Some(clip))
}

/// A direction in the map's own frame (ENU of the unrotated cube map) as a world direction, for
/// an environment turned by `heading` (rad): shaders/frame.wgsl `env_dir` samples the map at
/// Rz(heading)·d, so d = Rz(−heading)·m.
pub fn map_to_world(m: Vec3, heading: f32) -> Vec3 {
    let (s, c) = heading.sin_cos();
    Vec3::new(c * m.x + s * m.y, -s * m.x + c * m.y, m.z)
}

/// The light measured in a scene's environment, kept with the compositor it was set up for: what
/// the map holds, and the frame's light terms with the scene's multipliers at 1
/// ([`light_terms`]) — what the live view's sliders and its export scale.
#[derive(Clone, Debug)]
pub struct SceneLight {
    pub measured: MeasuredLight,
    pub unit: LightTerms,
}

/// The light terms of a scene's environment with every multiplier (sun.sunlight, sun.daylight,
/// effects.shadow_opacity) at 1; [`super::frame_params`] applies the multipliers and the twilight
/// fade once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightTerms {
    /// Unit direction to the sun, world (ENU): the scene's when it gives one, else the map's
    /// (straight up when the map has no sun; the sunlight is then 0).
    pub sun_dir: Vec3,
    /// The map's sun in the world (None: no sun found).
    pub map_sun_dir: Option<Vec3>,
    /// l_s = E_sun / π (luminance, after exposure), before the twilight fade.
    pub sunlight: f32,
    /// l_d: the factor that makes the method's ambient term E_sky / π.
    pub daylight: f32,
    /// The sun's share of the ground's irradiance (what the ground loses in the model's shadow,
    /// sky kept), twilight fade included.
    pub shadow_opacity: f32,
    /// Irradiance (luminance, after exposure) the sun gives the ground, before the fade, and the
    /// sky gives it: the shadow's share is computed from these with the multipliers.
    pub ground_sun: f32,
    pub ground_sky: f32,
    /// The sun's colour: linear RGB with BT.709 luminance 1 (white without a sun).
    pub sun_colour: [f32; 3],
    /// The sky without the sun as SH9 coefficients of irradiance / π over `daylight` (linear RGB,
    /// the map's own ENU frame): l_d · Σ c_i Y_i(n) is the light a white Lambertian surface
    /// facing n reflects (sh9-ggx).
    pub sky_sh: [[f32; 3]; 9],
    /// The same sky's radiance in bins (relative, the map's own frame; light::sh9::SkyRadiance).
    pub sky_radiance: crate::light::sh9::SkyRadiance,
    /// The ground's radiance below the horizon per unit of `daylight` (linear RGB, sh9-ggx): the
    /// map's upper hemisphere is the sky of `sky_sh`, its lower one a uniform ground of this
    /// radiance (light::measure::SkyAndGround), which the model shadows where it stands.
    pub ground_radiance: [f32; 3],
    /// Angular radius of the sun (rad).
    pub sun_angular_radius: f32,
}

/// The light terms for `scene` from the measured light of its environment, at `exposure`, with
/// the environment turned by `heading` (rad); `priors` are the hemisphere methods' ambient
/// colours (after exposure) that the daylight factor scales. The scene's light multipliers are
/// not applied (see [`LightTerms`]).
pub fn light_terms(scene: &Scene, light: &MeasuredLight, priors: &HemispherePriors, exposure: f32, heading: f32) -> LightTerms {
    let lum = crate::colour::luminance_bt709;
    let pi = std::f32::consts::PI;
    let map_sun_dir = light.sun_dir.map(|d| map_to_world(d, heading).normalize());
    let sun_dir = match scene.sun.direction {
        Some(d) => Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32).normalize(),
        None => map_sun_dir.unwrap_or(Vec3::Z),
    };
    let has_sun = light.source != SunSource::None && map_sun_dir.is_some();
    let sun_luminance = lum(light.sun_irradiance);
    let sun = if has_sun { sun_luminance * exposure / pi } else { 0.0 };
    let sun_colour = if has_sun && sun_luminance > 0.0 { light.sun_irradiance.map(|c| c / sun_luminance) } else { [1.0; 3] };
    // The sky's ambient radiance E/π, averaged over up and down normals (the hemisphere
    // methods blend between these two).
    let up = lum(light.sky.irradiance(Vec3::Z)) * exposure / pi;
    let down = lum(light.sky.irradiance(-Vec3::Z)) * exposure / pi;
    let reference = match scene.method.method_or_ordinary() {
        LightingMethod::BlinnPhong | LightingMethod::Sh9Ggx => 1.0,
        LightingMethod::HemisphereOcclusion => 0.5 * (priors.light + priors.shadow),
        _ => 0.5 * (lum(priors.sky) + lum(priors.ground)),
    };
    let daylight = if reference > 0.0 { 0.5 * (up + down) / reference } else { 0.0 };
    // sh9-ggx's sky: irradiance / π per unit of its daylight (reference 1: daylight = 0.5 (up + down)).
    let sky_daylight = 0.5 * (up + down);
    let per_daylight = if sky_daylight > 0.0 { exposure / sky_daylight } else { 0.0 };
    let sky_sh = std::array::from_fn(|i| light.sky_and_ground.sky.coeffs[i].map(|c| c * COSINE_LOBE[i] / pi * per_daylight));
    let ground_radiance = light.sky_and_ground.ground.map(|c| c * per_daylight);
    // The sun's share of the ground's irradiance with the direction used (the scene's sun is
    // given the map's energy).
    let ground_sun = sun * pi * sun_dir.z.max(0.0);
    let ground_sky = up * pi;
    let shadow_opacity = shadow_opacity(ground_sun * crate::sun::twilight::sunlight_factor_toward(sun_dir), ground_sky);
    LightTerms {
        sun_dir,
        map_sun_dir,
        sunlight: sun,
        daylight,
        shadow_opacity,
        ground_sun,
        ground_sky,
        sun_colour,
        sky_sh,
        sky_radiance: light.sky_and_ground.radiance,
        ground_radiance,
        sun_angular_radius: light.sun_angular_radius,
    }
}

/// How dark the model's shadow makes the ground: the sun's share of the ground's irradiance
/// (what the shadow removes, the sky kept), from the sun's and the sky's irradiance there.
pub fn shadow_opacity(ground_sun: f32, ground_sky: f32) -> f32 {
    let share = if ground_sun + ground_sky > 0.0 { ground_sun / (ground_sun + ground_sky) } else { 0.0 };
    crate::light::measure::shadow_strength(share, 1.0)
}

/// The ground pass's two strengths, `(shadow_opacity, sky_occlusion)`, for a frame whose sun
/// (unit direction `sun_dir`) gives `sunlight` = E_sun/π (faded, multipliers applied) and whose
/// sky gives the ground `ground_sky` (multipliers applied), each times the scene's
/// `effects.shadow_opacity` `multiplier` and clamped to 0..1: what setup::lighting computes for a
/// scene, and the live view for its moving sun.
pub fn ground_strengths(sunlight: f32, sun_dir: Vec3, ground_sky: f32, multiplier: f32) -> (f32, f32) {
    let ground_sun = sunlight * std::f32::consts::PI * sun_dir.normalize_or_zero().z.max(0.0);
    let scaled = |v: f32| (multiplier * v).clamp(0.0, 1.0);
    (scaled(shadow_opacity(ground_sun, ground_sky)), scaled(sky_occlusion(ground_sun, ground_sky)))
}

/// How dark the ground gets where the model hides all of its sky (the sun kept): the sky's share
/// of the ground's irradiance. The ground pass scales it by the share of the cosine-weighted sky
/// the model hides there (scene::occlusion::ground_sky), so the sun's and the sky's shadows add
/// up to what the ground loses.
pub fn sky_occlusion(ground_sun: f32, ground_sky: f32) -> f32 {
    if ground_sun + ground_sky > 0.0 { (ground_sky / (ground_sun + ground_sky)).clamp(0.0, 1.0) } else { 0.0 }
}

/// The farthest (radians) a sun that follows the clock turns before the frame's light follows it
/// at any geometry: the twilight fade moves by at most 0.25 %/0.01° (`sun::twilight`'s steepest
/// slope, 1.5/6 per degree) and a surface's cosine to the sun by at most 1.7·10⁻⁴, both under half
/// an 8-bit level of the light they scale. The sun crosses it in 2.4 s at its fastest
/// (15°/h).
pub const MAX_SUN_STEP_RAD: f32 = 0.01 * std::f32::consts::PI / 180.0;

/// The angle (radians) between two sun directions (any non-zero lengths), from their chord: acos
/// of an f32 dot product cannot tell turns under ~0.02° from none.
pub fn sun_turn(a: Vec3, b: Vec3) -> f64 {
    2.0 * (0.5 * (a.as_dvec3().normalize() - b.as_dvec3().normalize()).length()).asin()
}

/// How far a sun that follows the clock may turn (radians) before the frame must light with it:
/// the turn that moves the model's shadow by at most `px` pixels on screen, at most
/// [`MAX_SUN_STEP_RAD`]. The shadow of a point `h` above the ground lies `h·cot e` from its foot
/// (e the sun's elevation); a turn of the sun by Δ moves it by at most `h·Δ/sin²e` (a change
/// Δe of the elevation moves it `h·Δe/sin²e` away from the foot, a change Δa of the azimuth
/// `h·cot e·Δa` = `h·(cos e·Δa)/sin e` across, and Δ² = Δe² + (cos e·Δa)²). That
/// displacement is seen from no nearer than the nearest point the shadow can reach: the model's
/// box `corners` (world) and its shadow, no nearer than the camera's height above the ground
/// plane `ground_z`; and the projection magnifies an angle by at most `1 + tan²φ` at the frame's
/// corner φ off axis (vertical field `vfov`, radians; `size` in pixels). A sun below the horizon
/// casts no shadow: only the light's bound holds then. `sun` is a unit direction.
pub fn sun_step(corners: &[Vec3; 8], ground_z: f32, camera: Vec3, (vfov, size): (f32, (u32, u32)), sun: Vec3, px: f32) -> f32 {
    let height = corners.iter().map(|c| c.z - ground_z).fold(0.0f32, f32::max);
    let sin_e = sun.z;
    if !(height > 0.0 && sin_e > 0.0) {
        return MAX_SUN_STEP_RAD;
    }
    let foot = corners.iter().fold(Vec3::ZERO, |a, &c| a + c) / 8.0;
    let reach = corners.iter().map(|c| (c.truncate() - foot.truncate()).length()).fold(0.0f32, f32::max);
    let shadow_len = height * (1.0 - sin_e * sin_e).max(0.0).sqrt() / sin_e;
    let lift = (camera.z - ground_z).abs();
    let across = ((camera.truncate() - foot.truncate()).length() - reach - shadow_len).max(0.0);
    let nearest = (across * across + lift * lift).sqrt();
    let half_v = 0.5 * vfov;
    let focal = 0.5 * size.1 as f32 / half_v.tan();
    let aspect = size.0 as f32 / size.1.max(1) as f32;
    let tan_corner_sq = half_v.tan().powi(2) * (1.0 + aspect * aspect);
    let px_per_rad_at_nearest = focal * (1.0 + tan_corner_sq) / nearest.max(1e-6);
    let step = px * sin_e * sin_e / (height * px_per_rad_at_nearest);
    if step.is_nan() { 0.0 } else { step.min(MAX_SUN_STEP_RAD) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_to_world_turns_north_to_the_heading() {
        // Heading 90°: the map's North is seen looking East (frame.wgsl env_dir).
        let d = map_to_world(Vec3::Y, 90f32.to_radians());
        assert!((d - Vec3::X).length() < 1e-6, "{d}");
        // Inverse of env_dir's rotation: map_to_world then the shader's Rz(heading) is identity.
        let h = 0.7f32;
        let m = Vec3::new(0.3, -0.5, 0.8);
        let d = map_to_world(m, h);
        let (s, c) = h.sin_cos();
        let back = Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
        assert!((back - m).length() < 1e-6);
    }

    #[test]
    fn an_hdr_captures_clip_level_is_read_from_its_metadata() {
        let dir = std::env::temp_dir().join(format!("previz-setup-light-clip-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // A folder of faces without capture.json, and a file, are not captures.
        assert_eq!(hdr_capture_clip(&dir).unwrap(), None);
        assert_eq!(hdr_capture_clip(&dir.join("missing.hdr")).unwrap(), None);
        // Unreadable metadata is an error naming the file, not a map trusted as it is.
        std::fs::write(dir.join("capture.json"), "{").unwrap();
        let e = format!("{:#}", hdr_capture_clip(&dir).unwrap_err());
        assert!(e.contains("capture.json") && e.contains("not valid capture metadata"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_shadow_removes_the_suns_share_of_the_grounds_light() {
        // Sun 3, sky 1 on the ground: the shadow keeps the sky's quarter.
        assert!((shadow_opacity(3.0, 1.0) - 0.75).abs() < 1e-6);
        assert_eq!(shadow_opacity(0.0, 1.0), 0.0);
        assert_eq!(shadow_opacity(0.0, 0.0), 0.0);
    }

    #[test]
    fn the_sun_and_sky_shares_make_up_the_grounds_light() {
        // Sun 3, sky 1: the sky is a quarter of the ground's light; overcast (no sun): all of it.
        assert!((sky_occlusion(3.0, 1.0) - 0.25).abs() < 1e-6);
        assert_eq!(sky_occlusion(0.0, 2.0), 1.0);
        assert_eq!(sky_occlusion(0.0, 0.0), 0.0);
        // E_sun/π = 1/π from straight up gives the ground 1, as much as the sky's 1: half each;
        // the scene's multiplier scales both; a sun below the horizon leaves the sky's alone.
        let pi = std::f32::consts::PI;
        let (a, b) = ground_strengths(1.0 / pi, Vec3::Z, 1.0, 1.0);
        assert!((a - 0.5).abs() < 1e-6 && (b - 0.5).abs() < 1e-6, "{a} {b}");
        let (a, b) = ground_strengths(1.0 / pi, Vec3::Z * 3.0, 1.0, 0.5);
        assert!((a - 0.25).abs() < 1e-6 && (b - 0.25).abs() < 1e-6, "{a} {b}");
        // 30° up: the ground gets sin 30° = 1/2 of the sun's normal irradiance.
        let (a, _) = ground_strengths(2.0 / pi, Vec3::new(0.0, 3f32.sqrt(), 1.0), 1.0, 1.0);
        assert!((a - 0.5).abs() < 1e-6, "{a}");
        assert_eq!(ground_strengths(1.0, Vec3::new(0.0, 1.0, -0.1), 1.0, 1.0), (0.0, 1.0));
        for (sun, sky) in [(3.0, 1.0), (0.2, 5.0), (1.0, 0.0)] {
            assert!((shadow_opacity(sun, sky) + sky_occlusion(sun, sky) - 1.0).abs() < 1e-6);
        }
    }

    /// Where the shadows of the box's top corners fall on the ground, in pixels of the camera
    /// (None for one behind the camera or off the frame: nothing on screen moves there).
    fn shadow_tips_px(corners: &[Vec3; 8], sun: Vec3, view_proj: glam::Mat4, (w, h): (u32, u32)) -> Vec<Option<glam::Vec2>> {
        corners
            .iter()
            .filter(|c| c.z > 1e-6)
            .map(|&c| {
                let clip = view_proj * (c - sun * (c.z / sun.z)).extend(1.0);
                let px = glam::Vec2::new((clip.x / clip.w + 1.0) * 0.5 * w as f32, (1.0 - clip.y / clip.w) * 0.5 * h as f32);
                (clip.w > 0.0 && px.x >= 0.0 && px.y >= 0.0 && px.x <= w as f32 && px.y <= h as f32).then_some(px)
            })
            .collect()
    }

    fn sun_at(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
        crate::sun::direction_enu(f64::from(90.0 - elevation_deg).to_radians(), f64::from(azimuth_deg).to_radians())
    }

    #[test]
    fn the_turn_between_suns_holds_for_a_hundred_thousandth_of_a_degree() {
        // About 0.00001° apart, far below what acos of an f32 dot resolves: against the angle of
        // the same two vectors from atan2(|a×b|, a·b) in f64.
        let (a, b) = (sun_at(30.0, 10.0), sun_at(30.00001, 10.0));
        let (da, db) = (a.as_dvec3(), b.as_dvec3());
        let truth = da.cross(db).length().atan2(da.dot(db));
        assert!(truth > 1e-7 && truth < 3e-7, "{truth}");
        assert!((sun_turn(a, b) - truth).abs() < 1e-12, "{} {truth}", sun_turn(a, b));
        assert!((f64::from(a.angle_between(b)) - truth).abs() > 0.5 * truth, "f32 acos resolves it after all");
        assert!((sun_turn(Vec3::X, Vec3::Y * 2.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((sun_turn(Vec3::X, -Vec3::X) - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn a_sun_step_moves_the_shadow_by_at_most_half_a_pixel() {
        use crate::render::view::{Placement, camera_pose, model_matrix, projection, view_matrix};
        let size = (960, 640);
        let vfov = 60f32.to_radians();
        let camera = Vec3::new(0.0, 0.0, 1.5);
        // A truck-sized box 8 m ahead, turned; the camera looks at it 10° down.
        let bounds = (Vec3::new(-2.0, 0.0, -1.0), Vec3::new(2.0, 1.6, 1.0));
        let placement = Placement { position: Vec3::new(1.0, 8.0, 0.0), rotation: Vec3::new(0.0, 0.0, 0.5), scale: 1.0 };
        let corners = crate::render::shadow_fit::box_corners(bounds, model_matrix(bounds, &placement));
        let view_proj = projection(vfov, 1.5, 0.05, 100.0) * view_matrix(camera_pose(0.0, -10f32.to_radians(), 0.0), camera);
        let mut tightest = 0.0f32;
        for elevation in [3.0, 8.0, 20.0, 45.0, 80.0] {
            for azimuth in [0.0, 70.0, 160.0, 250.0] {
                let sun = sun_at(elevation, azimuth);
                let step = sun_step(&corners, 0.0, camera, (vfov, size), sun, 0.5);
                assert!(step > 0.0 && step <= MAX_SUN_STEP_RAD, "{elevation} {azimuth}: {step}");
                let before = shadow_tips_px(&corners, sun, view_proj, size);
                // The turn by the step in eight directions: up, down, along the horizon, between.
                for k in 0..8 {
                    let t = k as f32 * std::f32::consts::FRAC_PI_4;
                    let turned = sun_at(
                        elevation + (step * t.cos()).to_degrees(),
                        azimuth + (step * t.sin() / elevation.to_radians().cos()).to_degrees(),
                    );
                    let moved = before
                        .iter()
                        .zip(shadow_tips_px(&corners, turned, view_proj, size))
                        .filter_map(|(a, b)| Some(a.as_ref()?.distance(b?)))
                        .fold(0.0f32, f32::max);
                    assert!(moved <= 0.5, "{elevation}° {azimuth}° turned {:.5}° towards {k}: {moved} px", step.to_degrees());
                    if step < MAX_SUN_STEP_RAD {
                        tightest = tightest.max(moved);
                    }
                }
            }
        }
        // The bound is not vacuous: somewhere it is within a factor of 10 of the half pixel.
        assert!(tightest > 0.05, "largest move {tightest} px");
        // A low sun steps in smaller turns than a high one; below the horizon, or for a flat
        // model, only the light's bound is left.
        let low = sun_step(&corners, 0.0, camera, (vfov, size), sun_at(5.0, 0.0), 0.5);
        let high = sun_step(&corners, 0.0, camera, (vfov, size), sun_at(40.0, 0.0), 0.5);
        assert!(low < high, "{low} {high}");
        assert_eq!(sun_step(&corners, 0.0, camera, (vfov, size), sun_at(-2.0, 0.0), 0.5), MAX_SUN_STEP_RAD);
        assert_eq!(sun_step(&corners, 5.0, camera, (vfov, size), sun_at(30.0, 0.0), 0.5), MAX_SUN_STEP_RAD);
    }
}
