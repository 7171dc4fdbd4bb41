//! Light measured from an environment: the sun it holds (or, for a clipped map, the sun it
//! should hold), the rest of the sky as SH9 irradiance, and what the renderer needs from them by
//! default — sunlight, daylight and how dark the model's shadow makes the ground.
//!
//! Units are the environment's linear units (before exposure). Irradiance is per channel.

use super::clear_sky;
use super::ground_split::{GroundColours, GroundSplit};
use super::samples::DirSample;
use super::sh9::{Sh9, SkyRadiance};
use super::sky_model;
use super::sun_finder::{self, Sun};
use crate::colour::luminance_bt709;
use glam::Vec3;

/// Where the light's sun came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SunSource {
    /// Measured in the map: a compact region far brighter than the sky.
    Measured,
    /// The map's sun is clipped: direction from the aureole around the saturated disc
    /// ([`super::aureole`]; or the solar position), energy from the sun's share of the ground's
    /// light where the ground's colours show it ([`super::ground_split`]; colour: the beam's
    /// through the atmosphere that has the ground's direct-to-diffuse ratio, [`beam_turbidity`]),
    /// else from the clear-sky model's direct-to-diffuse ratio, times the measured sky.
    Restored,
    /// No sun: overcast, night, indoors, or below the horizon.
    None,
}

/// The light of an environment, split into a sun and the sky without it.
#[derive(Clone, Debug)]
pub struct MeasuredLight {
    /// Unit direction to the sun (ENU); None without a sun.
    pub sun_dir: Option<Vec3>,
    /// Sun irradiance on a surface facing it, linear RGB (zero without a sun); an unclipped
    /// sun's includes its aureole ([`sun_finder::aureole`]), which the sky then does not hold.
    pub sun_irradiance: [f32; 3],
    /// Angular radius of the sun as measured (rad; at least the real sun's 0.2666°); a restored
    /// sun's is the real sun's.
    pub sun_angular_radius: f32,
    /// The sky and surroundings without the sun, as SH9 radiance coefficients (the lower
    /// hemisphere bounded by [`bounded_ground`]).
    pub sky: Sh9,
    /// The sky and the ground of the world the references render (tests/reference: a
    /// Lambertian plane of the map's mean ground radiance under the map's upper hemisphere),
    /// which sh9-ggx lights the model from separately ([`SkyAndGround`]).
    pub sky_and_ground: SkyAndGround,
    pub source: SunSource,
    /// A restored sun's turbidity, read from the unclipped sky's shape (light::sky_model); None
    /// when the sun was not restored or the sky does not look like a clear sky (the restore then
    /// assumes the default clear atmosphere).
    pub turbidity: Option<f32>,
    /// A restored sun read from the ground: E_sun sin(elevation) / E_sky as the ground's colours
    /// show it ([`super::ground_split`]); None when the restore used the clear-sky model.
    pub ground_sun_over_sky: Option<f32>,
    /// A sun restored from the ground: the turbidity whose clear-sky direct-to-diffuse ratio is
    /// the ground's ([`beam_turbidity`]), which gives the sun its colour; None otherwise.
    pub beam_turbidity: Option<f32>,
    /// What the sun finder saw (None when nothing stood out).
    pub found: Option<Sun>,
}

/// The real sun's mean angular radius (rad): 959.63″ at 1 AU (IAU nominal solar radius).
pub const SUN_ANGULAR_RADIUS: f32 = 0.004_652_4;

impl MeasuredLight {
    /// Irradiance on an upward-facing ground: (from the sun, from the sky), linear RGB.
    pub fn ground_irradiance(&self) -> ([f32; 3], [f32; 3]) {
        let cos = self.sun_dir.map_or(0.0, |d| d.z.max(0.0));
        (self.sun_irradiance.map(|e| e * cos), self.sky.irradiance(Vec3::Z))
    }

    /// The sun's share of the ground's irradiance (luminance), 0..1.
    pub fn sun_share_on_ground(&self) -> f32 {
        let (sun, sky) = self.ground_irradiance();
        let (s, k) = (luminance_bt709(sun), luminance_bt709(sky));
        if s + k > 0.0 { s / (s + k) } else { 0.0 }
    }

    /// How much the model's shadow darkens the ground (0 = not at all, 1 = black) where the
    /// ground keeps `sky_kept` (0..1) of its sky: see [`shadow_strength`].
    pub fn shadow_strength(&self, sky_kept: f32) -> f32 {
        shadow_strength(self.sun_share_on_ground(), sky_kept)
    }
}

/// Darkening of the ground in the model's shadow: in the shadow the ground keeps none of the
/// sun and `sky_kept` of its sky, so its irradiance falls to sky_kept·(1 − sun_share) of the
/// unshadowed value: strength = 1 − sky_kept·(1 − sun_share).
pub fn shadow_strength(sun_share: f32, sky_kept: f32) -> f32 {
    (1.0 - sky_kept.clamp(0.0, 1.0) * (1.0 - sun_share.clamp(0.0, 1.0))).clamp(0.0, 1.0)
}

/// How to measure.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeasureOptions {
    /// The sun finder's options (set `clip_level` for 8-bit maps and captures).
    pub finder: sun_finder::Options,
    /// Restore a clipped sun (8-bit maps, captures, or on request): from the ground's colours
    /// where they show the sun's share ([`super::ground_split`]), else from the clear-sky model.
    /// `solar_elevation` (rad, from SPA) is used for the model when given, else the elevation of
    /// the saturated disc.
    pub restore_clipped: bool,
    pub solar_elevation: Option<f32>,
}

/// Measure the light in `samples` (an environment's every pixel).
pub fn measure(samples: &[DirSample], options: &MeasureOptions) -> MeasuredLight {
    let found = sun_finder::find_sun(samples, &options.finder);
    let Some(sun) = found.clone() else {
        let ground = bounded_ground(samples.to_vec(), [0.0; 3]);
        return MeasuredLight {
            sun_dir: None,
            sun_irradiance: [0.0; 3],
            sun_angular_radius: SUN_ANGULAR_RADIUS,
            sky: Sh9::project(&ground),
            sky_and_ground: SkyAndGround::of(&ground),
            source: SunSource::None,
            turbidity: None,
            ground_sun_over_sky: None,
            beam_turbidity: None,
            found,
        };
    };
    // An unclipped sun's aureole lights and is shadowed as the sun (none for a clipped one).
    let (ring, aureole) = sun_finder::aureole(samples, &sun, &options.finder);
    let sky_samples = sun_finder::without_sun_and_aureole(samples, &sun, &ring);
    let radius = sun.angular_radius().max(SUN_ANGULAR_RADIUS);
    // An unclipped sun is measured; a clipped one, unless asked to restore it, is taken as it
    // is: what energy the map holds, white.
    if !sun.saturated || !options.restore_clipped {
        let irradiance: [f32; 3] = std::array::from_fn(|k| sun.irradiance[k] + aureole[k]);
        let on_ground = irradiance.map(|e| e * sun.dir.z.max(0.0));
        let ground = bounded_ground(sky_samples, on_ground);
        return MeasuredLight {
            sun_dir: Some(sun.dir),
            sun_irradiance: irradiance,
            sun_angular_radius: radius,
            sky: Sh9::project(&ground),
            sky_and_ground: SkyAndGround::of(&ground),
            source: SunSource::Measured,
            turbidity: None,
            ground_sun_over_sky: None,
            beam_turbidity: None,
            found,
        };
    }
    let sky = Sh9::project(&sky_samples);
    let elevation = options.solar_elevation.unwrap_or_else(|| sun_finder::azimuth_elevation(sun.dir).1);
    // How hazy the day is, from the shape of the sky the map kept: not the sun's region, nothing
    // saturated.
    let clip = options.finder.clip_level.unwrap_or(f32::INFINITY);
    let in_sun = super::samples::mask(samples.len(), &sun.samples);
    // A sky the Perez model does not explain (trees, buildings, clouds) says nothing about the
    // haze: the default clear atmosphere then.
    let fit = sky_model::fit_turbidity(samples, sun.dir, |i| !in_sun[i] && samples[i].radiance.iter().all(|&c| c < 0.99 * clip))
        .filter(|(_, rms)| *rms <= sky_model::MAX_FIT_RMS);
    let atmosphere = fit.map_or_else(clear_sky::Atmosphere::default, |(t, _)| sky_model::atmosphere_for_turbidity(t));
    // The sun's share of the ground's light where the ground's colours show it, in the colour of
    // the beam through the atmosphere whose direct-to-diffuse ratio is the ground's (else the
    // sky shape's); else the clear-sky model's direct-to-diffuse ratio.
    let clear = restore_sun(&sky, elevation, &atmosphere);
    let sky_irradiance = sky.irradiance(Vec3::Z);
    let colours = (luminance_bt709(clear) > 0.0 && elevation > 0.0).then(|| GroundColours::of(samples, clip)).flatten();
    let beam = colours.and_then(|g| beam_turbidity(&g, sky_irradiance, elevation));
    let zenith = 90.0 - f64::from(elevation.to_degrees());
    let (ground_split, colour) = match beam {
        Some((t, g)) => (Some(g), clear_sky::beam_colour(zenith, &sky_model::atmosphere_for_turbidity(t))),
        None => (colours.and_then(|g| g.split(clear, sky_irradiance)), Some(clear.map(|c| c / luminance_bt709(clear)))),
    };
    let restored = match (ground_split, colour) {
        (Some(g), Some(colour)) => {
            let e = g.sun_over_sky as f32 * luminance_bt709(sky_irradiance) / elevation.sin();
            colour.map(|c| c * e)
        }
        _ => clear,
    };
    // The clipped disc's own energy is a lower bound (an HDR capture's disc still holds about a
    // third of the sun).
    let sun_irradiance = if luminance_bt709(restored) > 0.0 && luminance_bt709(sun.irradiance) > luminance_bt709(restored) {
        sun.irradiance
    } else {
        restored
    };
    let source = if luminance_bt709(sun_irradiance) > 0.0 { SunSource::Restored } else { SunSource::None };
    let on_ground = sun_irradiance.map(|e| e * sun.dir.z.max(0.0));
    let ground = bounded_ground(sky_samples, on_ground);
    MeasuredLight {
        sun_dir: (source == SunSource::Restored).then_some(sun.dir),
        sun_irradiance,
        // The saturated blob is the clipped aureole (6° across on quarry_01 ×0.25), not the
        // disc: its penumbra would blur the model's shadow away (docs/accuracy.md, "Tenth
        // session — clipped maps"). The restored energy is the disc's.
        sun_angular_radius: SUN_ANGULAR_RADIUS,
        sky: Sh9::project(&ground),
        sky_and_ground: SkyAndGround::of(&ground),
        source,
        turbidity: fit.map(|(t, _)| t as f32),
        ground_sun_over_sky: ground_split.map(|g| g.sun_over_sky as f32),
        beam_turbidity: beam.map(|(t, _)| t as f32),
        found,
    }
}

/// A sky over a uniform ground: what tests/reference/render_reference.py renders from a map (its
/// upper hemisphere as the sky, below it a Lambertian plane whose unshadowed radiance is the
/// mean radiance of the map's lower hemisphere), so that the model's light from below can be
/// shadowed by the model on that plane (scene::occlusion::model_sky_ground) instead of coming
/// from the map's own lower hemisphere (a sunlit patch of floor, courtyard.exr).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SkyAndGround {
    /// The upper hemisphere's radiance as SH9 coefficients (the lower hemisphere black).
    pub sky: Sh9,
    /// The ground's radiance, linear RGB: the solid-angle mean of the lower hemisphere.
    pub ground: [f32; 3],
    /// The upper hemisphere's radiance in bins (the ground's shadow weights its rays by it).
    pub radiance: SkyRadiance,
}

impl SkyAndGround {
    /// Split `samples` (a whole sphere) at the horizon.
    pub fn of(samples: &[DirSample]) -> SkyAndGround {
        let upper: Vec<DirSample> = samples.iter().filter(|s| s.dir.z > 0.0).copied().collect();
        let (mut sum, mut weight) = ([0f64; 3], 0f64);
        for s in samples.iter().filter(|s| s.dir.z <= 0.0) {
            weight += f64::from(s.solid_angle);
            for (a, r) in sum.iter_mut().zip(s.radiance) {
                *a += f64::from(r) * f64::from(s.solid_angle);
            }
        }
        let ground = if weight > 0.0 { sum.map(|a| (a / weight) as f32) } else { [0.0; 3] };
        SkyAndGround { sky: Sh9::project(&upper), ground, radiance: SkyRadiance::of(&upper) }
    }
}

/// The highest albedo a natural ground has: fresh snow reflects 0.8–0.95 of the light (the same
/// bound tests/reference/render_reference.py puts on its ground plane).
pub const MAX_GROUND_ALBEDO: f32 = 0.95;

/// The sky samples with the lower hemisphere bounded by energy: the ground a model stands on
/// reflects at most [`MAX_GROUND_ALBEDO`] of the light it receives, so the mean radiance below
/// the horizon is at most MAX_GROUND_ALBEDO · E_up / π per channel, E_up being the irradiance
/// the upper hemisphere (these samples' sky plus `sun_on_ground`, the sun's irradiance on a
/// horizontal surface) gives the ground. A lower hemisphere brighter than that (a sunlit patch
/// of floor under a sky whose sun the map does not hold, courtyard.exr: red 1.27 × what its sky
/// can light) is scaled down to it; a darker one is kept as it is.
pub fn bounded_ground(mut samples: Vec<DirSample>, sun_on_ground: [f32; 3]) -> Vec<DirSample> {
    let mut e_up = sun_on_ground.map(f64::from);
    let (mut l_down, mut w_down) = ([0f64; 3], 0f64);
    for s in &samples {
        let w = f64::from(s.solid_angle);
        if s.dir.z > 0.0 {
            for (e, r) in e_up.iter_mut().zip(s.radiance) {
                *e += f64::from(r) * f64::from(s.dir.z) * w;
            }
        } else {
            w_down += w;
            for (l, r) in l_down.iter_mut().zip(s.radiance) {
                *l += f64::from(r) * w;
            }
        }
    }
    if w_down <= 0.0 {
        return samples;
    }
    let scale: [f32; 3] = std::array::from_fn(|c| {
        let mean = l_down[c] / w_down;
        let most = f64::from(MAX_GROUND_ALBEDO) * e_up[c] / std::f64::consts::PI;
        if mean > most { (most / mean) as f32 } else { 1.0 }
    });
    if scale != [1.0; 3] {
        for s in samples.iter_mut().filter(|s| s.dir.z <= 0.0) {
            for (r, k) in s.radiance.iter_mut().zip(scale) {
                *r *= k;
            }
        }
    }
    samples
}

/// The turbidity at which the clear-sky model agrees with the ground, and the ground's split in
/// that atmosphere's beam colour: Bird's DNI/DHI at `elevation` (rad) times sin(elevation) equals
/// the ground's E_sun sin(elevation) / E_sky ([`GroundColours::split`] with the sky's irradiance
/// colour `sky` and the beam's colour, [`clear_sky::beam_colour`]). The sky's shape
/// (light::sky_model) says how hazy the sky looks, but the clear-sky model's ratio at that
/// turbidity is twice the map's own on quarry_01 (7.7 against 4.2: docs/accuracy.md, "Clipped
/// maps: where the 1.8× comes from"); the ground measures the ratio itself, and the atmosphere
/// that has it reddens the beam as the map's sun is reddened (quarry_01 clipped: T 2.7–2.8, beam
/// RGB/luminance 1.32, 0.96, 0.44; from the sky's shape, T 2.05: 1.27, 0.97, 0.49; the unclipped
/// sun measures 1.37, 0.95, 0.37). Bird's ratio falls with T and the split barely moves with the
/// beam's colour (0.842–0.857 over T 1.7–4 on quarry), so the root is found by bisection over
/// [`sky_model::TURBIDITY_RANGE`], clamped to its ends. None with the sun below the horizon or
/// where the split fails at a turbidity tried.
pub fn beam_turbidity(ground: &GroundColours, sky: [f32; 3], elevation: f32) -> Option<(f64, GroundSplit)> {
    let zenith = 90.0 - f64::from(elevation.to_degrees());
    let at = |t: f64| -> Option<(f64, GroundSplit)> {
        let atmosphere = sky_model::atmosphere_for_turbidity(t);
        let (c, colour) = (clear_sky::bird(zenith, &atmosphere)?, clear_sky::beam_colour(zenith, &atmosphere)?);
        let g = ground.split(colour, sky)?;
        (c.diffuse_horizontal > 0.0).then(|| (g.sun_over_sky - c.direct_normal / c.diffuse_horizontal * f64::from(elevation.sin()), g))
    };
    let (mut lo, mut hi) = sky_model::TURBIDITY_RANGE;
    let (f_lo, g_lo) = at(lo)?;
    let (f_hi, g_hi) = at(hi)?;
    // Below the clearest sky's ratio, or above the haziest's: the nearest end.
    if f_lo >= 0.0 {
        return Some((lo, g_lo));
    }
    if f_hi <= 0.0 {
        return Some((hi, g_hi));
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if at(mid)?.0 < 0.0 { lo = mid } else { hi = mid }
    }
    let t = 0.5 * (lo + hi);
    Some((t, at(t)?.1))
}

/// The sun a clipped map should hold: the clear-sky model's direct-normal to diffuse-horizontal
/// ratio at `elevation` (rad) in `atmosphere` (its aerosol from the turbidity the unclipped sky
/// shows, light::sky_model) times the diffuse horizontal irradiance the map's unclipped sky
/// gives, in the colour of the direct beam through that atmosphere ([`clear_sky::beam_colour`]:
/// a clipped disc has lost its own colour); zero below the horizon.
pub fn restore_sun(sky: &Sh9, elevation: f32, atmosphere: &clear_sky::Atmosphere) -> [f32; 3] {
    let zenith = 90.0 - f64::from(elevation.to_degrees());
    let (Some(c), Some(colour)) = (clear_sky::bird(zenith, atmosphere), clear_sky::beam_colour(zenith, atmosphere)) else {
        return [0.0; 3];
    };
    if c.diffuse_horizontal <= 0.0 {
        return [0.0; 3];
    }
    let ratio = (c.direct_normal / c.diffuse_horizontal) as f32;
    let dhi = luminance_bt709(sky.irradiance(Vec3::Z));
    colour.map(|k| k * ratio * dhi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::samples::from_equirect;
    use crate::light::sh9::brute_force_irradiance;
    use crate::scene::environment::{Equirect, load_equirect};
    use std::path::Path;

    fn data(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
    }

    #[test]
    fn a_ground_brighter_than_its_sky_can_light_is_bounded() {
        // A uniform sky of radiance 1 gives a horizontal ground E_up = π; a ground of radiance 2
        // would need albedo 2: it is bounded to 0.95 · π / π = 0.95. A sun of irradiance 1 on the
        // ground adds 0.95/π. A dark ground (0.3) is kept.
        let (w, h) = (64u32, 32u32);
        let map = |ground: f32| {
            let pixels: Vec<[f32; 3]> = (0..w * h).map(|i| if (i / w) < h / 2 { [1.0; 3] } else { [ground, 0.3, ground] }).collect();
            from_equirect(&Equirect::new(w, h, pixels).unwrap(), 0.0)
        };
        let mean_down = |s: &[DirSample]| {
            let (sum, n) = s
                .iter()
                .filter(|s| s.dir.z <= 0.0)
                .fold(([0f32; 3], 0f32), |(a, n), s| (std::array::from_fn(|c| a[c] + s.radiance[c] * s.solid_angle), n + s.solid_angle));
            sum.map(|v| v / n)
        };
        let bounded = mean_down(&bounded_ground(map(2.0), [0.0; 3]));
        assert!((bounded[0] - 0.95).abs() < 0.01 && (bounded[1] - 0.3).abs() < 1e-5, "{bounded:?}");
        let with_sun = mean_down(&bounded_ground(map(2.0), [1.0; 3]));
        let want = 0.95 * (std::f32::consts::PI + 1.0) / std::f32::consts::PI;
        assert!((with_sun[0] - want).abs() < 0.01, "{with_sun:?} vs {want}");
        assert_eq!(mean_down(&bounded_ground(map(0.3), [0.0; 3])), mean_down(&map(0.3)));
    }

    #[test]
    fn a_map_splits_into_the_sky_above_and_a_uniform_ground() {
        // Sky radiance 1 above the horizon, a ground of 0.3 (R), 0.5 (G), 0.1 (B) half of it and
        // twice that the other half below: the ground is the mean (0.45, 0.75, 0.15). A uniform
        // upper hemisphere projects onto bands 0 and 1 only (∫ over it of Y20 ∝ 3z² − 1 is 0), so
        // its SH9 irradiance is exact: E(n) = π (1 + n.z) / 2 (the sky's view factor from a
        // tilted surface): π facing up, π/2 facing the horizon, 0 facing down.
        let (w, h) = (128u32, 64u32);
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let k = if i % w < w / 2 { 1.0 } else { 2.0 };
                if (i / w) < h / 2 { [1.0; 3] } else { [0.3 * k, 0.5 * k, 0.1 * k] }
            })
            .collect();
        let split = SkyAndGround::of(&from_equirect(&Equirect::new(w, h, pixels).unwrap(), 0.0));
        for (got, want) in split.ground.iter().zip([0.45, 0.75, 0.15]) {
            assert!((got - want).abs() < 1e-4, "{:?}", split.ground);
        }
        let pi = std::f32::consts::PI;
        for (n, want) in [(Vec3::Z, pi), (Vec3::X, pi / 2.0), (Vec3::new(0.0, 0.6, -0.8), pi * 0.1), (-Vec3::Z, 0.0)] {
            let e = split.sky.irradiance(n);
            assert!(e.iter().all(|&c| (c - want).abs() < 0.01), "{n}: {e:?} vs {want}");
        }
    }

    #[test]
    fn the_beam_turbidity_is_the_one_whose_ratio_the_ground_shows() {
        // A sandy ground under a sky of irradiance colour k and a sun whose colour and strength
        // are the clear-sky model's at T = 3.2, 12° up: E_sun / E_sky = Bird's DNI/DHI there.
        // Texels in shade (x 0) and sunlit (x 2 sin el: the mean share is sin el), brightness
        // 0.6..1.2. The turbidity whose ratio the ground shows is 3.2, and the split is that
        // ratio times sin(el).
        let (t, el) = (3.2f64, 12f32.to_radians());
        let zenith = 90.0 - f64::from(el.to_degrees());
        let atmosphere = sky_model::atmosphere_for_turbidity(t);
        let bird = clear_sky::bird(zenith, &atmosphere).unwrap();
        let ratio = (bird.direct_normal / bird.diffuse_horizontal) as f32;
        let sun = clear_sky::beam_colour(zenith, &atmosphere).unwrap();
        let (sky, albedo) = ([0.8f32, 0.95, 1.3], [0.45f32, 0.35, 0.25]);
        let y = luminance_bt709(sky);
        let ground_of = |ratio: f32| -> Vec<DirSample> {
            (0..4000)
                .map(|i| {
                    let e = -(6.0 + 53.0 * i as f32 / 4000.0f32).to_radians();
                    let (a, x) = ([0.6f32, 1.2, 0.9][i % 3], [0.0, 2.0 * el.sin()][(i / 3) % 2]);
                    let radiance = std::array::from_fn(|c| a * albedo[c] * (x * ratio * sun[c] + sky[c] / y));
                    DirSample { dir: Vec3::new(e.cos(), 0.0, e.sin()), radiance, solid_angle: 1e-3 }
                })
                .collect()
        };
        let ground = GroundColours::of(&ground_of(ratio), f32::INFINITY).expect("one albedo under two lights");
        let (got, g) = beam_turbidity(&ground, sky, el).expect("a turbidity");
        assert!((got - t).abs() < 0.01, "turbidity {got}, want {t}");
        let want = f64::from(ratio * el.sin());
        assert!((g.sun_over_sky / want - 1.0).abs() < 1e-3, "split {} vs {want}", g.sun_over_sky);
        // A ground that shows a stronger sun than the clearest sky's (Bird's ratio at T 1.7 and
        // 12° is below 3 × that at 3.2): the clearest sky.
        let clearest = clear_sky::bird(zenith, &sky_model::atmosphere_for_turbidity(sky_model::TURBIDITY_RANGE.0)).unwrap();
        assert!(clearest.direct_normal / clearest.diffuse_horizontal < 3.0 * f64::from(ratio));
        let strong = GroundColours::of(&ground_of(3.0 * ratio), f32::INFINITY).unwrap();
        assert_eq!(beam_turbidity(&strong, sky, el).map(|(t, _)| t), Some(sky_model::TURBIDITY_RANGE.0));
    }

    #[test]
    fn shadow_strength_by_hand() {
        // All the ground's light from the sun, sky kept: black shadow. No sun: no shadow.
        assert_eq!(shadow_strength(1.0, 1.0), 1.0);
        assert_eq!(shadow_strength(0.0, 1.0), 0.0);
        // Sun 75 % of the ground's light: the shadow keeps 25 %; with 80 % of the sky, 20 %.
        assert!((shadow_strength(0.75, 1.0) - 0.75).abs() < 1e-6);
        assert!((shadow_strength(0.75, 0.8) - 0.8).abs() < 1e-6);
        // Overcast: only the sky's occlusion darkens (contact shadow).
        assert!((shadow_strength(0.0, 0.6) - 0.4).abs() < 1e-6);
    }

    #[test]
    fn quarry_sun_share_matches_brute_force() {
        // The sun's share of the ground's irradiance from the measurement (sun irradiance ×
        // cos + SH9 sky) against brute force over every pixel (with and without the sun).
        let quarry = load_equirect(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
        let samples = from_equirect(&quarry, 0.0);
        let light = measure(&samples, &MeasureOptions::default());
        assert_eq!(light.source, SunSource::Measured);
        let sun = light.found.as_ref().unwrap();
        let total = luminance_bt709(brute_force_irradiance(&samples, Vec3::Z));
        // The sun is the disc and its aureole (sun_finder::aureole), both out of the sky.
        let ring = sun_finder::aureole(&samples, sun, &Default::default()).0;
        let sky = luminance_bt709(brute_force_irradiance(&sun_finder::without_sun_and_aureole(&samples, sun, &ring), Vec3::Z));
        let brute_share = 1.0 - sky / total;
        let share = light.sun_share_on_ground();
        assert!((share - brute_share).abs() < 0.02, "share {share} vs brute force {brute_share}");
        // A low (10 deg) clear sun still gives the ground most of its light.
        assert!(share > 0.3, "{share}");
    }

    #[test]
    fn overcast_sky_has_no_sun_and_a_weak_sun_has_a_small_share() {
        // CIE standard overcast sky, L ∝ 1 + 2 sin(elevation), over a grey ground: no sun, so
        // the shadow is the sky's occlusion only.
        let (w, h) = (256u32, 128u32);
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let v = ((i / w) as f32 + 0.5) / h as f32;
                let el = (0.5 - v) * std::f32::consts::PI;
                if el > 0.0 { [1.0 + 2.0 * el.sin(); 3] } else { [0.3; 3] }
            })
            .collect();
        let overcast = Equirect::new(w, h, pixels).unwrap();
        let light = measure(&from_equirect(&overcast, 0.0), &MeasureOptions::default());
        assert_eq!(light.source, SunSource::None);
        assert!((light.shadow_strength(0.7) - 0.3).abs() < 1e-6);
        // courtyard.exr: soft light with a small bright spot (peak 53, the top 0.1 % of pixels
        // hold 3.7 % of the energy, hdri_peak_stats_DERIVED.csv): found as a sun, but its share of
        // the ground's light is small and agrees with brute force.
        let courtyard = load_equirect(&data("hdri/blender_studiolights_world_zip/courtyard.exr")).unwrap();
        let samples = from_equirect(&courtyard, 0.0);
        let light = measure(&samples, &MeasureOptions::default());
        let share = light.sun_share_on_ground();
        if let Some(sun) = &light.found {
            let total = luminance_bt709(brute_force_irradiance(&samples, Vec3::Z));
            let sky = luminance_bt709(brute_force_irradiance(&sun_finder::without_sun(&samples, sun), Vec3::Z));
            assert!((share - (1.0 - sky / total)).abs() < 0.02, "share {share} vs brute force {}", 1.0 - sky / total);
        }
        assert!(share < 0.2, "courtyard sun share {share}");
    }

    #[test]
    fn clipped_quarry_restores_a_sun_near_the_real_one() {
        // quarry_01 exposed so the sky is in range and clipped at 1.0, as an 8-bit capture.
        let quarry = load_equirect(&data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap();
        let scale = 0.25;
        let full = measure(&from_equirect(&quarry, 0.0), &MeasureOptions::default());
        let clipped: Vec<[f32; 3]> = quarry.pixels().iter().map(|p| p.map(|c| (c * scale).min(1.0))).collect();
        let clipped = Equirect::new(quarry.width(), quarry.height(), clipped).unwrap();
        let samples = from_equirect(&clipped, 0.0);
        let finder = sun_finder::Options { clip_level: Some(1.0), ..Default::default() };
        let kept = measure(&samples, &MeasureOptions { finder, restore_clipped: false, solar_elevation: None });
        let restored = measure(&samples, &MeasureOptions { finder, restore_clipped: true, solar_elevation: None });
        assert_eq!(restored.source, SunSource::Restored);
        let truth = luminance_bt709(full.sun_irradiance) * scale;
        let (k, r) = (luminance_bt709(kept.sun_irradiance), luminance_bt709(restored.sun_irradiance));
        // The clipped map keeps a small part of the sun. Restored with the default (AOD 0.1)
        // atmosphere it was 2.1x the true sun (2026-11-30); with the turbidity read from the
        // unclipped sky (light::sky_model: T = 2.05, a very clear sky, AOD500 0.12) 1.85x
        // (2026-12-01): Bird's direct/diffuse ratio at 10° for so clear a sky is 8.0, the map's
        // own 4.7. Since the ninth session the sand's colours give the sun's share of the
        // ground's light (light::ground_split) and the clear-sky model is not used: 1.34x with the
        // saturated blob's elevation (2026-12-01; 1.13x at the true sun's, tests/clipped_sun.rs).
        // Since the tenth session the elevation is the aureole's centre around the blob
        // (light::aureole: 10.1°, the blob's centroid 9.2°): 1.12x (2026-12-01; the bounds were
        // 1.2x..1.5x).
        assert!(k < 0.2 * truth, "clipped keeps {k} of {truth}");
        assert!(restored.ground_sun_over_sky.is_some(), "the ground shows the sun's share");
        assert!(r > 1.0 * truth && r < 1.2 * truth, "restored {r} vs true {truth}");
        let t = restored.turbidity.expect("a turbidity for the restored sun");
        assert!((1.7..2.5).contains(&t), "turbidity {t}: quarry_01 is a clear day");
        // The restored sun has the beam's colour at 10° (clear_sky::beam_colour: RGB/luminance
        // 1.27, 0.97, 0.49), nearer the measured sun's (1.37, 0.95, 0.37) than white is.
        let colour = |e: [f32; 3]| e.map(|c| c / luminance_bt709(e));
        let distance = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f32>().sqrt();
        let (got, want) = (colour(restored.sun_irradiance), colour(full.sun_irradiance));
        assert!(distance(got, want) < 0.5 * distance([1.0; 3], want), "restored colour {got:?}, measured {want:?}");
        eprintln!(
            "quarry clipped at 1.0: true sun {truth:.3}, kept {k:.4}, restored {r:.3} ({:.2}x), turbidity {:?}",
            r / truth,
            restored.turbidity
        );
    }
}
