//! How much the sun improves the heading: the virtual phone held by a simulated hand in a real
//! HDR environment, its sensors simulated (hard-iron offset, disturbances, noise:
//! [`crate::sensors::sim`]) into the fusion filter, twice — once with the compass alone and
//! once taking a sun heading measurement ([`super::sun_heading`]) from a frame every
//! [`FRAME_PERIOD_S`] — and the heading error of each against the truth.
//!
//! The simulated world: the environment map's own sun (found unclipped in the HDR) must be where
//! SPA puts the sun for the place and the clock. [`sun_world`] picks the afternoon time at the
//! simulated site when SPA's apparent elevation equals the map's sun elevation, and turns the
//! map so that its sun lies at SPA's azimuth. The world's sun does not move during a run (the
//! map is static), so SPA is evaluated at that one time.

use super::frames::{angle_difference, from_heading_pitch_roll, heading_pitch_roll};
use super::fusion::{FusionConfig, OrientationFilter};
use super::hand_motion::{HandShake, UserPathParams};
use super::sun_heading::{heading_measurement, sight_sun};
use super::trace::{TruthSample, TruthTrace};
use super::{HeadingSource, OrientationEstimator};
use crate::camera::exposure::ExposureMode;
use crate::camera::sim::{SimSettings, VirtualPhone};
use crate::light::samples::from_equirect;
use crate::light::sun_finder::{self, azimuth_elevation};
use crate::scene::CubeMap;
use crate::scene::environment::Equirect;
use crate::sensors::SensorSource;
use crate::sensors::sim::{NoiseLevel, SimConfig, SimSensors, SimSite};
use crate::sun::{Algorithm, SunInput};
use anyhow::{Context, Result, bail};
use chrono::{DateTime, TimeZone, Utc};
use glam::Vec3;
use std::sync::Arc;

/// A frame is examined for the sun this often (s).
pub const FRAME_PERIOD_S: f64 = 0.5;
/// The first sun measurement is taken after the filter's start-up (s).
pub const FIRST_SUN_S: f64 = 5.0;
/// Heading errors are scored from this time on (s): 5 s after the first sun measurement.
pub const SCORE_FROM_S: f64 = 10.0;

/// The simulated world: an environment whose sun is where SPA puts it.
pub struct SunWorld {
    /// The environment in ENU (the map turned by `map_heading_deg`).
    pub env: Arc<CubeMap>,
    /// SPA's apparent sun direction (ENU) at `time` and `site`.
    pub sun_enu: Vec3,
    pub time: DateTime<Utc>,
    pub site: SimSite,
    /// Azimuth the map's centre column faces (degrees).
    pub map_heading_deg: f64,
    /// SPA azimuth and apparent elevation (degrees).
    pub sun_azimuth_deg: f64,
    pub sun_elevation_deg: f64,
}

fn spa(site: &SimSite, time: DateTime<Utc>) -> Result<crate::sun::SunPosition> {
    let mut input = SunInput::new(time, site.lat_deg, site.lon_deg);
    input.site.elevation_m = site.alt_m;
    crate::sun::position(&input, Algorithm::Spa)
}

/// The world for `map` at `site` (on its date): the afternoon time when SPA's apparent sun
/// elevation equals the map's sun elevation (bisection to 10⁻⁴°), the map turned so that its
/// sun lies at SPA's azimuth, as a cube of `cube_size`.
pub fn sun_world(map: &Equirect, site: SimSite, cube_size: u32) -> Result<SunWorld> {
    let found =
        sun_finder::find_sun(&from_equirect(map, 0.0), &sun_finder::Options::default()).context("the environment map has no sun")?;
    let (az_map, el_map) = azimuth_elevation(found.dir);
    let (az_map, el_map) = (f64::from(az_map).to_degrees(), f64::from(el_map).to_degrees());
    let day = Utc.from_utc_datetime(&site.date.and_hms_opt(0, 0, 0).context("bad date")?);
    // Solar noon near 12:00 − longitude/15 h; the elevation falls from there to sunset.
    let noon = day + chrono::Duration::seconds(((12.0 - site.lon_deg / 15.0) * 3600.0) as i64);
    let (mut lo, mut hi) = (noon, noon + chrono::Duration::hours(8));
    let el = |t: DateTime<Utc>| spa(&site, t).map(|p| p.apparent_elevation_deg());
    if el(lo)? < el_map || el(hi)? > el_map {
        bail!(
            "the map's sun elevation {el_map:.2}° is not reached in the afternoon at {:.3}, {:.3} on {}",
            site.lat_deg,
            site.lon_deg,
            site.date
        );
    }
    while hi - lo > chrono::Duration::milliseconds(50) {
        let mid = lo + (hi - lo) / 2;
        if el(mid)? > el_map {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let sun = spa(&site, lo)?;
    let heading = (sun.azimuth_deg - az_map).rem_euclid(360.0);
    Ok(SunWorld {
        env: Arc::new(map.to_cube(cube_size, heading.to_radians() as f32)),
        sun_enu: sun.direction_enu(),
        time: lo,
        site,
        map_heading_deg: heading,
        sun_azimuth_deg: sun.azimuth_deg,
        sun_elevation_deg: sun.apparent_elevation_deg(),
    })
}

/// Where the simulated user looks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SunCase {
    /// 10° left of the sun and 5° up: the sun is in the frame, right of centre.
    InView,
    /// 150° away from the sun: never in the frame (as under clouds).
    Hidden,
}

impl SunCase {
    pub fn name(self) -> &'static str {
        match self {
            SunCase::InView => "sun in view",
            SunCase::Hidden => "sun hidden",
        }
    }
}

/// One run's result.
#[derive(Clone, Debug, PartialEq)]
pub struct SunRun {
    pub case: SunCase,
    pub noise: NoiseLevel,
    pub seed: u64,
    /// RMS heading error (degrees) from [`SCORE_FROM_S`] on: compass only, and with the sun.
    pub rms_before_deg: f64,
    pub rms_after_deg: f64,
    /// Frames examined, and those in which the sun was measured.
    pub frames: usize,
    pub measurements: usize,
    /// At the end of the run (with the sun): heading source and 1σ (degrees).
    pub source: HeadingSource,
    pub accuracy_deg: f32,
    /// Per examined frame: time (s), heading error compass only and with the sun (degrees),
    /// the sun measurement taken then (degrees), whether the magnetometer read disturbed.
    pub series: Vec<(f64, f64, f64, Option<f64>, bool)>,
}

/// Run one case: `secs` seconds of the phone held by hand, a frame examined every
/// [`FRAME_PERIOD_S`].
pub fn run_case(world: &SunWorld, case: SunCase, noise: NoiseLevel, seed: u64, secs: f64) -> Result<SunRun> {
    run_case_every(world, case, noise, seed, secs, FRAME_PERIOD_S)
}

/// [`run_case`] with a frame examined every `period_s` (a multiple of the sensors' 0.01 s).
pub fn run_case_every(world: &SunWorld, case: SunCase, noise: NoiseLevel, seed: u64, secs: f64, period_s: f64) -> Result<SunRun> {
    let look = match case {
        SunCase::InView => world.sun_azimuth_deg - 10.0,
        SunCase::Hidden => world.sun_azimuth_deg + 150.0,
    };
    let pitch = (world.sun_elevation_deg - 5.0).to_radians();
    let hand = HandShake::seeded(seed, &UserPathParams::default());
    let n = (secs * 100.0).round() as usize;
    let base = from_heading_pitch_roll(look.to_radians(), pitch, 0.0);
    let truth = TruthTrace::new((0..=n).map(|i| i as f64 * 0.01).map(|t| TruthSample { t, q: hand.apply(base, t), tap: false }).collect())?;
    let mut cfg = SimConfig::new(noise, seed);
    cfg.site = world.site;
    let rotation = cfg.rotation;
    let mut sensors = SimSensors::with_config(truth.clone(), cfg)?;
    let mut compass = OrientationFilter::new(FusionConfig::default());
    compass.set_reference(sensors.magnetic_reference());
    let mut with_sun = compass.clone();
    let vfov = 50.0;
    let mut phone =
        VirtualPhone::new(world.env.clone(), &SimSettings { width: 320, height: 240, vfov_deg: vfov, exposure: ExposureMode::default() })?;
    phone.set_threads(1);
    let (mut sq_before, mut sq_after, mut count) = (0.0, 0.0, 0usize);
    let (mut frames, mut measurements) = (0usize, 0usize);
    let mut readings = Vec::new();
    let mut series = Vec::new();
    let steps = (secs / 0.01).round() as usize;
    let frame_every = ((period_s / 0.01).round() as usize).max(1);
    for k in 1..=steps {
        let t = k as f64 * 0.01;
        readings.clear();
        sensors.poll(t, &mut readings)?;
        for r in &readings {
            compass.update(r)?;
            with_sun.update(r)?;
        }
        let (Some(pc), Some(ps)) = (compass.pose(rotation), with_sun.pose(rotation)) else { continue };
        let true_q = truth.orientation_at(t);
        let true_heading = heading_pitch_roll(true_q).heading;
        let e = |q: glam::Quat| angle_difference(heading_pitch_roll(q.as_dquat()).heading, true_heading);
        if k % frame_every == 0 {
            // The phone renders every frame (auto-exposure adapts); the sun finder looks at
            // the frames from FIRST_SUN_S on.
            let frame = phone.render(true_q.as_quat(), t)?;
            let mut measured = None;
            if t >= FIRST_SUN_S {
                frames += 1;
                if let Some(s) = sight_sun(&frame.image, vfov, ps.q)?
                    && let Some(m) = heading_measurement(&s, world.sun_enu, f64::from(ps.tilt_accuracy_deg).to_radians())
                    && with_sun.sun_heading(t, m.error, m.sigma).is_some()
                {
                    measurements += 1;
                    measured = Some(m.error.to_degrees());
                }
            }
            series.push((t, e(pc.q).to_degrees(), e(ps.q).to_degrees(), measured, ps.magnetic_disturbance));
        }
        if t >= SCORE_FROM_S {
            sq_before += e(pc.q).powi(2);
            sq_after += e(ps.q).powi(2);
            count += 1;
        }
    }
    let end = with_sun.pose(rotation).context("the filter never started")?;
    let rms = |s: f64| (s / count.max(1) as f64).sqrt().to_degrees();
    Ok(SunRun {
        case,
        noise,
        seed,
        rms_before_deg: rms(sq_before),
        rms_after_deg: rms(sq_after),
        frames,
        measurements,
        source: end.heading_source,
        accuracy_deg: end.heading_accuracy_deg,
        series,
    })
}

/// RMS over runs of their RMS errors (degrees): (before, after).
pub fn pooled_rms(runs: &[SunRun]) -> (f64, f64) {
    let n = runs.len().max(1) as f64;
    let p = |f: fn(&SunRun) -> f64| (runs.iter().map(|r| f(r).powi(2)).sum::<f64>() / n).sqrt();
    (p(|r| r.rms_before_deg), p(|r| r.rms_after_deg))
}
