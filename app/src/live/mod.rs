//! The live frame loop: what the phone runs for every camera frame. It reads any camera
//! ([`FrameSource`]) and any sensors ([`SensorSource`]); [`Sources::simulated`] plugs in the
//! virtual phone and the simulated sensors so it runs (and is tested) on any machine.
//!
//! Per camera frame (DESIGN.md "One frame"), in this order:
//! 1. the camera delivers its frame (the virtual phone renders at the *true* pose; the
//!    renderer only ever sees the *estimated* one, so sensor error shows as a model that
//!    swims against the background, exactly as on a phone);
//! 2. the sensors deliver their readings up to the frame's time, the fusion filter updates,
//!    and a GPS fix moves the place the sun is computed for;
//! 3. the sun is computed for the place and the frame's instant (NREL SPA); the model is lit
//!    by it when the environment is a capture of this place and moment (`env.captured_here`, or
//!    a capture the app just took), otherwise by the map's own sun as `composite` is (a
//!    downloaded map's sun has nothing to do with today's clock); faded through twilight;
//! 4. the compositor draws camera image, ground shadow and model at the estimated pose.
//!
//! The simulated user stands still and looks at the model, panning slowly left and right and
//! up and down with a hand-held shake ([`look_around_path`]).

#[cfg(target_os = "android")]
pub mod android;
pub mod app;
pub mod export;
#[cfg(target_os = "ios")]
pub mod ios;
pub mod phone;
pub mod sun_north;
pub mod window;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnetic_model_date_is_clamped_into_the_wmm_range() {
        let d = |y, m, day| NaiveDate::from_ymd_opt(y, m, day).unwrap();
        assert_eq!(magnetic_model_date(d(2003, 10, 17)), d(2020, 1, 1));
        assert_eq!(magnetic_model_date(d(2026, 11, 22)), d(2026, 11, 22));
        assert_eq!(magnetic_model_date(d(2041, 2, 3)), d(2029, 12, 31));
    }
}

use crate::camera::exposure::ExposureMode;
use crate::camera::sim::{SimSequence, SimSettings, VirtualPhone};
use crate::camera::yuv::YuvConverter;
use crate::camera::{FrameImage, FrameSource};
use crate::gpu::Gpu;
use crate::pose::frames::{angle_between, from_heading_pitch_roll};
use crate::pose::hand_motion::{HandShake, UserPathParams};
use crate::pose::trace::{TruthSample, TruthTrace};
use crate::pose::{DisplayRotation, FusionConfig, OrientationEstimator, OrientationFilter, Pose};
use crate::render::{Compositor, FrameParams, Layer, Rendered};
use crate::scene::{CubeMap, Model};
use crate::sensors::sim::{NoiseLevel, SimConfig, SimSensors, SimSite};
use crate::sensors::{Reading, SensorSource};
use crate::setup::scene_file::Scene;
use crate::setup::{LightTerms, camera_and_placement, environment_light, exposure, live_compositor_and_light};
use crate::sun::{Algorithm, SunInput, SunPosition, position};
use crate::ui::controls::Controls;
use anyhow::{Context, Result, bail};
use chrono::{DateTime, NaiveDate, Utc};
use glam::Vec3;
use std::sync::Arc;

/// Where, when and how the live session runs (the place is where the session starts; GPS
/// fixes move it).
#[derive(Clone, Debug, PartialEq)]
pub struct LiveConfig {
    /// Latitude and longitude of the user, degrees (the sun's position and the magnetic model).
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// The instant of the first frame.
    pub start: DateTime<Utc>,
    /// Simulation only: camera frames per second, length of the session (seconds), sensor
    /// noise and the seed of the user and the sensors.
    pub frame_hz: f64,
    pub duration_s: f64,
    pub noise: NoiseLevel,
    pub seed: u64,
}

impl LiveConfig {
    /// The phone shells' session from `start` (the phone's clock): the demo's place (Bristol)
    /// until the first GPS fix or the manual place moves it; the simulation fields are unused
    /// there (real camera and sensors).
    pub fn on_phone(start: DateTime<Utc>) -> LiveConfig {
        LiveConfig { lat_deg: 51.4545, lon_deg: -2.5879, start, frame_hz: 30.0, duration_s: 3600.0, noise: NoiseLevel::Phone, seed: 1 }
    }

    pub fn validate(&self) -> Result<()> {
        if !(self.lat_deg.is_finite() && (-90.0..=90.0).contains(&self.lat_deg)) {
            bail!("--lat must be a latitude in -90..=90 degrees, got {}", self.lat_deg);
        }
        if !(self.lon_deg.is_finite() && (-180.0..=180.0).contains(&self.lon_deg)) {
            bail!("--lon must be a longitude in -180..=180 degrees, got {}", self.lon_deg);
        }
        if !(self.frame_hz.is_finite() && (1.0..=240.0).contains(&self.frame_hz)) {
            bail!("--fps must be in 1..=240, got {}", self.frame_hz);
        }
        if !(self.duration_s.is_finite() && (1.0..=3600.0).contains(&self.duration_s)) {
            bail!("--duration must be in 1..=3600 seconds, got {}", self.duration_s);
        }
        Ok(())
    }
}

/// A hand-held look around a point of interest: heading `heading_deg ± 20°` and pitch
/// `pitch_deg ± 4°` as slow sinusoids (16 s and 11 s), plus the hand's tremor and sway, sampled
/// at 100 Hz for `duration_s` seconds.
pub fn look_around_path(heading_deg: f64, pitch_deg: f64, duration_s: f64, seed: u64) -> Result<TruthTrace> {
    let params = UserPathParams::default();
    let shake = HandShake::seeded(seed, &params);
    let n = (duration_s * 100.0).ceil() as usize;
    let samples = (0..=n)
        .map(|i| {
            let t = i as f64 / 100.0;
            let h = heading_deg + 20.0 * (std::f64::consts::TAU * t / 16.0).sin();
            let p = pitch_deg + 4.0 * (std::f64::consts::TAU * t / 11.0).sin();
            let q = from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.0);
            TruthSample { t, q: shake.apply(q, t), tap: false }
        })
        .collect();
    TruthTrace::new(samples)
}

/// Where the frames and readings come from.
pub struct Sources {
    pub camera: Box<dyn FrameSource>,
    pub sensors: Box<dyn SensorSource>,
    /// How the app's display is rotated from the device's natural orientation.
    pub rotation: DisplayRotation,
    /// The camera's true orientation where it is known (the simulator), for the pose error.
    pub truth: Option<TruthTrace>,
}

impl Sources {
    /// The virtual phone looking into `env` (landscape, the scene's size and field of view,
    /// exposure fixed at `exposure`), held by the simulated user ([`look_around_path`] around
    /// the scene's camera heading and pitch), with simulated sensors at `cfg`'s place and noise.
    pub fn simulated(env: Arc<CubeMap>, scene: &Scene, exposure: f32, cfg: &LiveConfig) -> Result<Sources> {
        let truth = look_around_path(scene.camera.heading, scene.camera.pitch, cfg.duration_s, cfg.seed)?;
        Sources::simulated_along(env, scene, exposure, cfg, truth)
    }

    /// [`Sources::simulated`] with the user of [`capture_then_look_around_path`]: the desktop
    /// app's capture mode on the virtual phone.
    pub fn simulated_capture(env: Arc<CubeMap>, scene: &Scene, exposure: f32, cfg: &LiveConfig) -> Result<Sources> {
        let camera = crate::capture::projection::Pinhole::from_vfov(scene.width, scene.height, scene.camera.vfov as f32)?;
        let truth = capture_then_look_around_path(&camera, scene.camera.heading, scene.camera.pitch, cfg.duration_s, cfg.seed)?;
        Sources::simulated_along(env, scene, exposure, cfg, truth)
    }

    /// The virtual phone and simulated sensors held along `truth`.
    pub fn simulated_along(env: Arc<CubeMap>, scene: &Scene, exposure: f32, cfg: &LiveConfig, truth: TruthTrace) -> Result<Sources> {
        cfg.validate()?;
        let settings = SimSettings {
            width: scene.width,
            height: scene.height,
            vfov_deg: scene.camera.vfov as f32,
            exposure: ExposureMode::Fixed(exposure),
        };
        let phone = VirtualPhone::new(env, &settings)?;
        let frames = (truth.end() * cfg.frame_hz).floor() as usize;
        let poses = (0..=frames)
            .map(|k| {
                let t = k as f64 / cfg.frame_hz;
                (t, truth.orientation_at(t).as_quat())
            })
            .collect();
        let mut sim = SimConfig::new(cfg.noise, cfg.seed);
        sim.site = SimSite { lat_deg: cfg.lat_deg, lon_deg: cfg.lon_deg, alt_m: 0.0, date: magnetic_model_date(cfg.start.date_naive()) };
        let rotation = sim.rotation;
        let sensors = SimSensors::with_config(truth.clone(), sim)?;
        Ok(Sources { camera: Box::new(SimSequence::new(phone, poses)?), sensors: Box::new(sensors), rotation, truth: Some(truth) })
    }
}

/// A simulated user who first follows the capture assistant (aims at the front and taps, then
/// turns to each face in turn and holds it, [`crate::capture::guided_path`]) and then looks
/// around the point of interest ([`look_around_path`]) for the rest of `duration_s`. The
/// capture's front is the scene camera's heading. Taps are marked in the samples.
pub fn capture_then_look_around_path(
    camera: &crate::capture::projection::Pinhole,
    heading_deg: f64,
    pitch_deg: f64,
    duration_s: f64,
    seed: u64,
) -> Result<TruthTrace> {
    use crate::capture::{Mode, guided_path, targets};
    let plan =
        targets::plan_targets(Mode::Stitch, camera, crate::capture::assistant::AssistantConfig::new(Mode::Stitch, *camera).tolerance_deg);
    // Holds long enough for the assistant's dwell and a settling filter at every face.
    let params = UserPathParams { reference_heading_deg: Some(heading_deg), hold_s: (1.5, 2.0), ..UserPathParams::default() };
    let capture = guided_path::simulate_capture_path(seed, &plan, &params)?;
    // The user first holds the phone where the path starts while the fusion filter settles on
    // a first attitude (the assistant needs a pose for the tap).
    const SETTLE_S: f64 = 2.5;
    let first = capture.samples.first().map(|s| s.q).unwrap_or_default();
    let mut samples: Vec<TruthSample> =
        (0..(SETTLE_S * 100.0) as usize).map(|i| TruthSample { t: i as f64 / 100.0, q: first, tap: false }).collect();
    samples.extend(capture.samples.iter().map(|s| TruthSample { t: s.t + SETTLE_S, ..*s }));
    let end = samples.last().map_or(0.0, |s| s.t);
    let rest = look_around_path(heading_deg, pitch_deg, (duration_s - end).max(1.0), seed)?;
    // Turn from where the capture ended to the look-around's first aim in half a second.
    let (from, to) = (samples.last().map_or(rest.samples()[0].q, |s| s.q), rest.samples()[0].q);
    for i in 1..=50 {
        let f = i as f64 / 50.0;
        samples.push(TruthSample { t: end + 0.5 * f, q: from.slerp(to, f * f * (3.0 - 2.0 * f)), tap: false });
    }
    samples.extend(rest.samples().iter().skip(1).map(|s| TruthSample { t: s.t + end + 0.5, ..*s }));
    TruthTrace::new(samples)
}

/// The date the simulated magnetometer (and the filter's magnetic reference) uses: the
/// session's date, clamped into the World Magnetic Model's validity (2020-01-01..=2029-12-31).
/// The sun always uses the requested instant.
pub fn magnetic_model_date(date: NaiveDate) -> NaiveDate {
    match (NaiveDate::from_ymd_opt(2020, 1, 1), NaiveDate::from_ymd_opt(2029, 12, 31)) {
        (Some(first), Some(last)) => date.clamp(first, last),
        _ => date,
    }
}

/// What one live frame used, for the overlay and the tests.
#[derive(Clone, Copy, Debug)]
pub struct LiveFrame {
    /// Seconds since the session started.
    pub t: f64,
    /// The estimated camera pose the model was drawn with (None until the filter has settled
    /// on a first attitude: the frame shows the camera image only).
    pub pose: Option<Pose>,
    /// Angle between the estimated and the true camera orientation, degrees.
    pub pose_error_deg: Option<f64>,
    /// NREL SPA's sun for the place and the frame's instant (the model is lit with it only when
    /// the environment is a capture of this place and moment, `env.captured_here`).
    pub sun: SunPosition,
    /// Sunlight intensity after the twilight fade.
    pub sunlight: f32,
    /// CPU milliseconds of this frame's stages: the camera frame (delivered and uploaded),
    /// sensors and fusion, the sun.
    pub camera_ms: f64,
    pub pose_ms: f64,
    pub sun_ms: f64,
    /// The simulated user tapped the screen since the previous frame (never on a phone: there
    /// the taps are real touch events).
    pub user_tapped: bool,
}

/// The live loop's state: compositor, camera, sensors, filter and the frame parameters.
pub struct LiveSession {
    compositor: Compositor,
    sources: Sources,
    filter: OrientationFilter,
    params: FrameParams,
    layer: Layer,
    full_sunlight: f32,
    cfg: LiveConfig,
    /// Latitude and longitude the sun is computed for: the start, then the latest GPS fix.
    location: (f64, f64),
    readings: Vec<Reading>,
    /// The control panel's values, applied to every frame once set.
    controls: Option<Controls>,
    /// The sun's intensity of the current frame before SL (place, time, twilight).
    sun_intensity: f32,
    /// Light with SPA's sun for the place and the clock (the environment is a capture of this
    /// place and moment); false: with the map's sun (or the scene's), as `composite` does.
    sun_from_clock: bool,
    /// The sun direction measured in the map (or set by the scene) the frames use when not
    /// `sun_from_clock`.
    map_sun_dir: Vec3,
    /// With `sun_from_clock`, the sun the frames light with: SPA's for the clock, taken again
    /// once SPA's has turned away from it by more than [`crate::setup::light::sun_step`] allows
    /// (the shadow moved half a pixel, or the light a fraction of a level), so that frames in
    /// between have the same parameters (kept maps, reprojected turns).
    clock_sun: Option<Vec3>,
    /// The current camera image (the background of the frame) when it came as an image; a YUV
    /// frame stays on the GPU, in `yuv`'s target.
    camera_image: Option<crate::scene::Rgba8Image>,
    /// The GPU YUV → R'G'B' conversion of phone camera frames (made at the first YUV frame).
    yuv: Option<YuvConverter>,
    /// The light measured in the environment with the scene's multipliers at 1 (unfaded): the
    /// export writes the frame's light as multipliers of it.
    unit_light: LightTerms,
    /// The scene the session was made from (model, environment, size), for the export.
    scene: Scene,
    /// Camera and sensors stopped ([`LiveSession::suspend`]).
    suspended: bool,
    /// Draw the model (false: the camera image only, as capture mode shows it).
    show_model: bool,
    /// The time of the previous frame (the simulated user's taps between two frames).
    last_t: Option<f64>,
    /// The camera frame folded into the environment, until a capture replaces it (None: the
    /// scene's map lights the model).
    fold: Option<FoldedEnvironment>,
    /// The model is still where the scene's camera heading and pitch put it, to be placed in
    /// front of where the phone points at its first pose (the scene gives no position).
    place_at_first_pose: bool,
    /// True north from the sun in the camera frame (short exposure frames, fused into `filter`).
    sun_north: sun_north::SunNorth,
}

/// Face size (texels) of the environment folded from the camera frame.
pub const FOLD_SIZE: u32 = 64;
/// The folded environment is refreshed when the camera has turned this far since the last fold
/// (degrees)...
pub const FOLD_REFRESH_DEG: f64 = 10.0;
/// ... or this long after it (seconds): the scene in front of the camera changes too.
pub const FOLD_REFRESH_S: f64 = 2.0;

/// The environment folded from the live camera frame before any capture exists (seed 004,
/// `capture::frame_fold`): the fold runs on the GPU from the compositor's background (the camera
/// image, whether it came as an image or as YUV converted on the GPU) into a cube texture made
/// once; the 64-texel map is read back, its GGX-prefiltered levels, priors and the sky's SH9 are
/// computed on a thread of their own, and a later frame writes them into the compositor's
/// environment textures in place (`Compositor::set_prepared_environment` at the same face size
/// allocates nothing).
struct FoldedEnvironment {
    fold: Option<crate::capture::frame_fold::FrameFold>,
    /// Estimated camera orientation and time of the last fold.
    last: Option<(glam::Quat, f64)>,
    /// Folds applied so far.
    refreshes: usize,
    /// Milliseconds the last refresh took on the frame's thread (fold and readback, then the
    /// texture writes) and on its own thread (prefilter, priors, light).
    frame_ms: f64,
    cpu_ms: f64,
    /// The CPU half of the latest fold, running.
    pending: Option<std::thread::JoinHandle<Result<PreparedFold>>>,
    /// The folded map that lights the model now (the export writes it).
    applied: Option<CubeMap>,
}

/// A folded map with what the frame needs from it, computed off the frame's thread.
struct PreparedFold {
    cube: CubeMap,
    prepared: crate::render::environment::Prepared,
    sky_sh: [[f32; 3]; 9],
    sky_radiance: crate::light::sh9::SkyRadiance,
    ground_radiance: [f32; 3],
    cpu_ms: f64,
    /// Milliseconds the fold and its readback took on the frame's thread.
    fold_ms: f64,
}

impl LiveSession {
    /// A session looking at `model` placed as the scene says (auto-placed in front of the
    /// scene's camera heading and pitch) in `env` (lighting, reflections, colour priors), at
    /// the scene's output size. `sources` deliver the camera frames (of the output size) and
    /// the sensor readings; [`LiveSession::simulated`] makes the simulated ones.
    pub fn new(gpu: &Gpu, env: &CubeMap, model: &Model, scene: &Scene, cfg: LiveConfig, sources: Sources) -> Result<LiveSession> {
        cfg.validate()?;
        let (compositor, params, light) = live_compositor_and_light(gpu, scene, env, model)?;
        let unit_light = light.unit;
        let map_sun_dir = params.lighting.sun_dir;
        // True north from the first GPS fix and the World Magnetic Model for the date.
        let mut filter = OrientationFilter::new(FusionConfig::default());
        filter.set_date(magnetic_model_date(cfg.start.date_naive()));
        Ok(LiveSession {
            compositor,
            sources,
            filter,
            params,
            layer: Layer::Composite,
            full_sunlight: scene.sun.sunlight as f32 * unit_light.sunlight,
            location: (cfg.lat_deg, cfg.lon_deg),
            cfg,
            readings: Vec::new(),
            controls: None,
            sun_intensity: scene.sun.sunlight as f32 * unit_light.sunlight,
            sun_from_clock: scene.env.captured_here,
            map_sun_dir,
            clock_sun: None,
            camera_image: None,
            yuv: None,
            unit_light,
            scene: scene.clone(),
            suspended: false,
            show_model: true,
            last_t: None,
            fold: None,
            place_at_first_pose: scene.placement.position.is_none(),
            sun_north: sun_north::SunNorth::new(),
        })
    }

    /// A session on the virtual phone and the simulated sensors ([`Sources::simulated`]); the
    /// camera sees the environment at the exposure the model is lit with, as a phone that
    /// locked its exposure would.
    pub fn simulated(gpu: &Gpu, env: Arc<CubeMap>, model: &Model, scene: &Scene, cfg: LiveConfig) -> Result<LiveSession> {
        let sources = Sources::simulated(env.clone(), scene, exposure(scene, &env), &cfg)?;
        LiveSession::new(gpu, &env, model, scene, cfg, sources)
    }

    /// Advance to the next camera frame: camera image (uploaded), sensors, pose, sun. `None`
    /// when the camera stream ends.
    /// An error while suspended: the camera and the sensors are stopped.
    pub fn advance(&mut self, gpu: &Gpu) -> Result<Option<LiveFrame>> {
        if self.suspended {
            bail!("the live session is suspended (camera and sensors stopped); resume it first");
        }
        let t0 = std::time::Instant::now();
        // 1. The camera image: an image is one write_texture; YUV planes go to the GPU as they
        // are and are converted there (no CPU colour conversion), then copied into the background.
        let mut t = 0.0;
        let (compositor, camera_image, yuv) = (&mut self.compositor, &mut self.camera_image, &mut self.yuv);
        let delivered = self.sources.camera.lend_next_frame(&mut |frame_t, image| {
            t = frame_t;
            match image {
                FrameImage::Rgba(image) => {
                    compositor.set_background(gpu, Some(&image))?;
                    *camera_image = Some(image);
                }
                FrameImage::Yuv { frame, quarter_turns } => {
                    let converter = yuv.get_or_insert_with(|| YuvConverter::new(gpu));
                    converter.convert_turned(gpu, &frame, quarter_turns)?;
                    compositor.set_background_texture(gpu, converter.target().context("the YUV conversion made no image")?)?;
                    *camera_image = None;
                }
            }
            Ok(())
        })?;
        if !delivered {
            return Ok(None);
        }
        let previous = self.last_t.replace(t);
        if let Some(rotation) = self.sources.sensors.display_rotation() {
            self.sources.rotation = rotation;
        }
        let t1 = std::time::Instant::now();
        self.readings.clear();
        self.sources.sensors.poll(t, &mut self.readings)?;
        for r in &self.readings {
            self.filter.update(r)?;
            if let Reading::Gps(fix) = r {
                self.location = (fix.lat_deg, fix.lon_deg);
            }
        }
        let pose = self.filter.pose(self.sources.rotation);
        let t2 = std::time::Instant::now();
        let instant = self.cfg.start + chrono::Duration::microseconds((t * 1e6).round() as i64);
        let sun = position(&SunInput::new(instant, self.location.0, self.location.1), Algorithm::Spa)?;
        // True north from the sun in the camera frame. The virtual phone's world is the map,
        // whose sun is the map's, not where SPA has it for the clock.
        let sky_sun = if self.sources.truth.is_some() { self.map_sun_dir } else { sun.direction_enu() };
        let (size, vfov) = ((self.scene.width, self.scene.height), self.scene.camera.vfov as f32);
        self.sun_north.frame(t, pose.as_ref(), sky_sun, size, vfov, &mut *self.sources.camera, &mut self.filter)?;
        let t3 = std::time::Instant::now();
        // SPA's sun for a capture of this place and moment; otherwise the map's own sun (the
        // demo's picture, a downloaded HDR), whatever the clock says.
        let sun_dir = if self.sun_from_clock { self.clock_sun(sun.direction_enu()) } else { self.map_sun_dir };
        let sunlight = self.full_sunlight * crate::sun::twilight::sunlight_factor_toward(sun_dir);
        if let Some(p) = pose {
            self.params.camera.pose = p.q;
            if std::mem::take(&mut self.place_at_first_pose) {
                self.place_in_front(p.q)?;
            }
        }
        self.params.lighting.sun_dir = sun_dir;
        self.params.lighting.sunlight = sunlight;
        self.sun_intensity = sunlight;
        if let Some(c) = &self.controls {
            c.apply(&mut self.params, sunlight);
        }
        // The ground's shadows follow the sun as it moves (setup::lighting for the same light).
        let l = &mut self.params.lighting;
        let unit = &self.unit_light;
        let daylight = if unit.daylight > 0.0 { l.daylight / unit.daylight } else { 1.0 };
        let multiplier = self.scene.effects.shadow_opacity as f32;
        (l.shadow_opacity, l.sky_occlusion) =
            crate::setup::light::ground_strengths(l.sunlight, l.sun_dir, daylight * unit.ground_sky, multiplier);
        self.layer = if pose.is_some() && self.show_model { Layer::Composite } else { Layer::Background };
        if pose.is_some() {
            self.refresh_fold(gpu, t)?;
        }
        let user_tapped = match &self.sources.truth {
            Some(truth) => truth.samples().iter().any(|s| s.tap && s.t <= t && previous.is_none_or(|p| s.t > p)),
            None => false,
        };
        let pose_error_deg = match (pose, &self.sources.truth) {
            (Some(p), Some(truth)) => Some(angle_between(p.q.as_dquat(), truth.orientation_at(t)).to_degrees()),
            _ => None,
        };
        let ms = |a: std::time::Instant, b: std::time::Instant| (b - a).as_secs_f64() * 1e3;
        Ok(Some(LiveFrame {
            t,
            pose,
            pose_error_deg,
            sun,
            sunlight,
            camera_ms: ms(t0, t1),
            pose_ms: ms(t1, t2),
            sun_ms: ms(t2, t3),
            user_tapped,
        }))
    }

    /// The sun a frame lights with when it follows the clock: the held one while SPA's sun `now`
    /// is within a step of it (`setup::light::sun_step` for the model where it stands, half a
    /// pixel), else `now`, held from then on.
    fn clock_sun(&mut self, now: Vec3) -> Vec3 {
        let bounds = self.compositor.model_bounds();
        let p = &self.params;
        let step = |held: Vec3| match bounds {
            Some(b) => {
                let corners = crate::render::shadow_fit::box_corners(b, crate::render::view::model_matrix(b, &p.placement));
                let view = (p.camera.vfov, (self.scene.width, self.scene.height));
                crate::setup::light::sun_step(&corners, p.placement.position.z, p.camera.position, view, held, 0.5)
            }
            None => 0.0,
        };
        match self.clock_sun {
            Some(held) if crate::setup::light::sun_turn(held, now) <= f64::from(step(held)) => held,
            _ => *self.clock_sun.insert(now),
        }
    }

    /// The app went to the background (another app, the screen locked): stop the camera and the
    /// sensors. Everything else is kept (scene, placement, controls, the filter's attitude) and
    /// [`LiveSession::resume`] carries on from it. Suspending twice is the same as once.
    pub fn suspend(&mut self) -> Result<()> {
        if self.suspended {
            return Ok(());
        }
        self.sources.camera.pause()?;
        self.sources.sensors.pause()?;
        self.suspended = true;
        Ok(())
    }

    /// Start the camera and the sensors again after [`LiveSession::suspend`].
    pub fn resume(&mut self) -> Result<()> {
        if !self.suspended {
            return Ok(());
        }
        self.sources.sensors.resume()?;
        self.sources.camera.resume()?;
        self.suspended = false;
        Ok(())
    }

    pub fn is_suspended(&self) -> bool {
        self.suspended
    }

    /// True north from the sun in the camera frame: short frames taken, measurements, the last.
    pub fn sun_north(&self) -> &sun_north::SunNorth {
        &self.sun_north
    }

    /// Draw the current frame into [`Compositor::target_view`] (no readback). Returns the CPU
    /// encode time, ms.
    pub fn draw(&mut self, gpu: &Gpu) -> Result<f64> {
        self.compositor.draw(gpu, &self.params, self.layer)
    }

    /// Render the current frame and read it back.
    pub fn render(&mut self, gpu: &Gpu) -> Result<Rendered> {
        self.compositor.render(gpu, &self.params, self.layer)
    }

    /// Render the current frame as a still: as [`LiveSession::render`], but the ground's map and
    /// the model's sky of a new turn are waited for instead of drawn from the previous turn while
    /// their threads make them (which frame shows them depends on timing), as the shutter's
    /// export does ([`LiveSession::render_layer`]). Goldens of the app's screens use it.
    pub fn render_still(&mut self, gpu: &Gpu) -> Result<Rendered> {
        self.render_layer(gpu, self.layer)
    }

    /// Whether a turn or scale of the model casts the ground's rays on a worker (the default)
    /// or the frame waits for them, as a composite does (`bench live` compares the two).
    pub fn set_ground_in_background(&mut self, on: bool) {
        self.compositor.set_ground_in_background(on);
    }

    /// Render one layer of the current frame (the model alone, say) and read it back: a still
    /// (the shutter's export), so the ground's map is the model's current placement's, waiting
    /// for its rays if a turn's are still being cast.
    pub fn render_layer(&mut self, gpu: &Gpu, layer: Layer) -> Result<Rendered> {
        self.compositor.set_ground_in_background(false);
        let rendered = self.compositor.render(gpu, &self.params, layer);
        self.compositor.set_ground_in_background(true);
        rendered
    }

    /// The current frame's float layers (render/layers.rs), for the shutter's `layers.exr` (a
    /// still, as [`LiveSession::render_layer`]).
    pub fn render_float_layers(&mut self, gpu: &Gpu) -> Result<crate::render::layers::LayerImages> {
        self.compositor.set_ground_in_background(false);
        let layers = self.compositor.render_layers(gpu, &self.params);
        self.compositor.set_ground_in_background(true);
        layers
    }

    pub fn compositor(&self) -> &Compositor {
        &self.compositor
    }

    /// Turn off the reprojection of frames that only turn the camera (render::reprojection; on
    /// from the start): every frame shades its model and ground, as `bench live` measures it
    /// side by side. It cannot be turned on again in the session.
    pub fn shade_every_frame(&mut self, gpu: &Gpu) -> Result<()> {
        self.compositor.set_reprojection(gpu, false)?;
        Ok(())
    }

    /// Time each pass of the following frames alone (`Compositor::set_pass_timing`: a profile
    /// for `previz bench live`).
    pub fn set_pass_timing(&mut self, on: bool) {
        self.compositor.set_pass_timing(on);
    }

    /// The parameters the current frame is drawn with.
    pub fn params(&self) -> &FrameParams {
        &self.params
    }

    /// The parameters, for gestures that move the model (the control panel goes through
    /// [`LiveSession::set_controls`]).
    pub fn params_mut(&mut self) -> &mut FrameParams {
        &mut self.params
    }

    /// Apply the control panel's values from now on (SL scales the sun's intensity for the place
    /// and time); applied at once to the current frame too.
    pub fn set_controls(&mut self, c: Controls) {
        c.apply(&mut self.params, self.sun_intensity);
        self.controls = Some(c);
    }

    /// The light measured in the environment with the scene's multipliers at 1 (unfaded).
    pub fn unit_light(&self) -> &LightTerms {
        &self.unit_light
    }

    /// The scene the session was made from.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The camera image of the current frame when the camera delivered an image (None before
    /// the first frame, and for YUV frames, which stay on the GPU: [`LiveSession::camera_frame`]).
    pub fn camera_image(&self) -> Option<&crate::scene::Rgba8Image> {
        self.camera_image.as_ref()
    }

    /// The camera image of the current frame as R'G'B' bytes, read back from the GPU when the
    /// camera delivered YUV. An error before the first frame.
    pub fn camera_frame(&self, gpu: &Gpu) -> Result<crate::scene::Rgba8Image> {
        match (&self.camera_image, &self.yuv) {
            (Some(image), _) => Ok(image.clone()),
            (None, Some(yuv)) => yuv.read_back(gpu),
            (None, None) => bail!("no camera frame yet"),
        }
    }

    pub fn controls(&self) -> Option<&Controls> {
        self.controls.as_ref()
    }

    pub fn config(&self) -> &LiveConfig {
        &self.cfg
    }

    /// Draw the model over the camera image (true) or the camera image alone (capture mode),
    /// from the next frame on.
    pub fn set_show_model(&mut self, on: bool) {
        self.show_model = on;
        if !on {
            self.layer = Layer::Background;
        }
    }

    /// Light the model with a new environment (a capture folder the app just saved, say): `env`
    /// loaded from `path`, its front face towards `heading_deg`. The light is measured in it
    /// again (sunlight, daylight, shadow strength; the panel's multipliers stay); the scene
    /// the export writes names the new environment. On an error nothing changes.
    pub fn set_environment(&mut self, gpu: &Gpu, env: &CubeMap, path: &std::path::Path, heading_deg: f64) -> Result<()> {
        let mut scene = self.scene.clone();
        scene.environment = Some(path.to_path_buf());
        scene.env.heading = heading_deg;
        scene.env.exposure = None;
        let exposure = exposure(&scene, env);
        self.compositor.set_environment(gpu, env, exposure, (heading_deg as f32).to_radians())?;
        // The capture replaces the environment folded from the camera frame for good.
        self.fold = None;
        let priors = self.compositor.priors().context("environment priors")?;
        let (unit, scene_light) = environment_light(&scene, env, &priors, exposure, (heading_deg as f32).to_radians())?;
        let light = crate::setup::lighting(&scene, &unit);
        self.unit_light = scene_light.unit;
        self.full_sunlight = scene.sun.sunlight as f32 * self.unit_light.sunlight;
        // A capture just taken here: from now on the sun is SPA's for the place and the clock.
        scene.env.captured_here = true;
        self.sun_from_clock = true;
        self.clock_sun = None;
        self.params.lighting.daylight = light.daylight;
        self.params.lighting.shadow_opacity = light.shadow_opacity;
        self.params.lighting.sky_occlusion = light.sky_occlusion;
        self.params.lighting.sky_sh = light.sky_sh;
        self.params.lighting.sky_radiance = light.sky_radiance;
        self.params.lighting.ground_radiance = light.ground_radiance;
        self.params.lighting.sun_colour = light.sun_colour;
        self.params.lighting.sun_angular_radius = light.sun_angular_radius;
        if let Some(c) = &mut self.controls {
            c.daylight = light.daylight;
        }
        self.scene = scene;
        Ok(())
    }

    /// Place the model as the scene's automatic placement does (`placement.size`, `.fill`), in
    /// front of a camera with orientation `q` (camera → world) instead of the scene's camera
    /// heading and pitch: where the phone points when the session starts. Turn and scale stay.
    fn place_in_front(&mut self, q: glam::Quat) -> Result<()> {
        let bounds = self.compositor.model_bounds().context("model bounds")?;
        let (c, p) = (&self.params.camera, &self.scene.placement);
        let auto = crate::render::view::auto_placement(bounds, q, c.position, c.vfov, p.size as f32, p.fill as f32);
        self.params.placement.position = auto.position;
        Ok(())
    }

    /// Whether the model has been placed in front of the first pose (or the scene placed it):
    /// from then on its placement is the user's to change.
    pub fn placed(&self) -> bool {
        !self.place_at_first_pose
    }

    /// Light the model with the live camera frame folded into a cube map (reflections, the sky's
    /// SH9 ambient, priors) until a capture is set ([`LiveSession::set_environment`]): folded at
    /// the next frame with a pose, then again whenever the camera has turned
    /// [`FOLD_REFRESH_DEG`] or [`FOLD_REFRESH_S`] has passed. The sun (direction, intensity,
    /// colour, shadows) and the ambient level (DL) stay the ones measured in the scene's map: a
    /// camera frame rarely holds the sun, and then clipped. The fold pass is made at the first
    /// fold, once. Nothing changes when the scene's environment is already a capture of here
    /// and now (`env.captured_here`).
    pub fn fold_camera_into_environment(&mut self) {
        if self.fold.is_none() && !self.scene.env.captured_here {
            self.fold =
                Some(FoldedEnvironment { fold: None, last: None, refreshes: 0, frame_ms: 0.0, cpu_ms: 0.0, pending: None, applied: None });
        }
    }

    /// How many folds of the camera frame have been applied to the environment, and the
    /// milliseconds the last one took on the frame's thread (fold, readback, texture writes) and
    /// on its own (prefilter, priors, light). None when the fold is off: before
    /// [`LiveSession::fold_camera_into_environment`] or after a capture replaced it.
    pub fn fold_refreshes(&self) -> Option<(usize, f64, f64)> {
        self.fold.as_ref().map(|f| (f.refreshes, f.frame_ms, f.cpu_ms))
    }

    /// Wait for a fold whose CPU half is still running and apply it now (tests and benchmarks
    /// that want each due fold applied before the next frame; the app lets it finish on its own).
    pub fn finish_fold(&mut self, gpu: &Gpu) -> Result<()> {
        self.apply_fold(gpu, true)
    }

    /// Apply the pending fold if its CPU half is done (`wait`: wait for it).
    fn apply_fold(&mut self, gpu: &Gpu, wait: bool) -> Result<()> {
        let Some(state) = &mut self.fold else { return Ok(()) };
        if !state.pending.as_ref().is_some_and(|h| wait || h.is_finished()) {
            return Ok(());
        }
        let Some(handle) = state.pending.take() else { return Ok(()) };
        let done = handle.join().map_err(|_| anyhow::anyhow!("the folded environment's thread panicked"))??;
        let started = std::time::Instant::now();
        self.compositor.set_prepared_environment(gpu, &done.cube, done.prepared)?;
        // The ambient's colour and direction from the fold; its level (DL) stays the map's.
        self.params.lighting.sky_sh = done.sky_sh;
        self.unit_light.sky_sh = done.sky_sh;
        self.params.lighting.sky_radiance = done.sky_radiance;
        self.unit_light.sky_radiance = done.sky_radiance;
        self.params.lighting.ground_radiance = done.ground_radiance;
        self.unit_light.ground_radiance = done.ground_radiance;
        state.refreshes += 1;
        state.frame_ms = done.fold_ms + started.elapsed().as_secs_f64() * 1e3;
        state.cpu_ms = done.cpu_ms;
        state.applied = Some(done.cube);
        Ok(())
    }

    /// The camera frame folded into a cube map that lights the model now (world directions,
    /// the renderer's linear light: exposure 1, heading 0); None before the first fold is
    /// applied and once a capture replaced it.
    pub fn folded_environment(&self) -> Option<&CubeMap> {
        self.fold.as_ref().and_then(|f| f.applied.as_ref())
    }

    /// Apply a finished fold; fold the current camera frame when one is due (see
    /// [`LiveSession::fold_camera_into_environment`]) and none is running.
    fn refresh_fold(&mut self, gpu: &Gpu, t: f64) -> Result<()> {
        self.apply_fold(gpu, false)?;
        let Some(state) = &mut self.fold else { return Ok(()) };
        let pose = self.params.camera.pose;
        let due = state.last.is_none_or(|(q, t0)| {
            crate::pose::frames::angle_between_f32(q, pose).to_degrees() >= FOLD_REFRESH_DEG || t - t0 >= FOLD_REFRESH_S
        });
        if !due || state.pending.is_some() {
            return Ok(());
        }
        let started = std::time::Instant::now();
        let bounds = self.compositor.model_bounds().context("model bounds")?;
        let (w, h) = self.compositor.size();
        let c = &self.params.camera;
        let view_proj = crate::render::view::projection(c.vfov, w as f32 / h as f32, 0.01, 1e4)
            * crate::render::view::view_matrix(c.pose, c.position)
            * crate::render::view::model_matrix(bounds, &self.params.placement);
        let bbox = crate::capture::frame_fold::screen_bbox(view_proj, bounds);
        let fold = match &mut state.fold {
            Some(fold) => fold,
            None => state.fold.insert(crate::capture::frame_fold::FrameFold::new(gpu, FOLD_SIZE)?),
        };
        fold.render_view(gpu, self.compositor.background_view(), pose, bbox)?;
        let cube = fold.read_back(gpu)?;
        let fold_ms = started.elapsed().as_secs_f64() * 1e3;
        state.last = Some((pose, t));
        // The folded frame is in the renderer's linear light already (the camera image is the
        // background the model is drawn over): exposure 1, indexed by world directions. It is
        // measured with the frame's sun, as `previz composite` measures an export's lighting
        // environment with the exported `sun.direction` (a clipped sun's restored energy depends
        // on its elevation).
        let mut scene = self.scene.clone();
        let d = self.params.lighting.sun_dir;
        scene.sun.direction = Some([f64::from(d.x), f64::from(d.y), f64::from(d.z)]);
        state.pending = Some(std::thread::spawn(move || {
            let started = std::time::Instant::now();
            let prepared = crate::render::environment::prepare(&cube, 1.0, 0.0)?;
            let (unit, _) = environment_light(&scene, &cube, &prepared.env.priors, 1.0, 0.0)?;
            Ok(PreparedFold {
                cube,
                prepared,
                sky_sh: unit.sky_sh,
                sky_radiance: unit.sky_radiance,
                ground_radiance: unit.ground_radiance,
                cpu_ms: started.elapsed().as_secs_f64() * 1e3,
                fold_ms,
            })
        }));
        Ok(())
    }

    /// Replace the model (a bundled one or a file the user opened), scaled as the scene scales a
    /// model of its size, standing where the current one stands (once placed: before the first
    /// pose it is placed then) with its turn. On an error the current model stays.
    pub fn set_model(&mut self, gpu: &Gpu, model: &Model, path: Option<&std::path::Path>) -> Result<()> {
        self.compositor.set_model(gpu, model)?;
        let bounds = self.compositor.model_bounds().context("model bounds")?;
        self.scene.model = path.map(std::path::Path::to_path_buf);
        let mut placement = camera_and_placement(&self.scene, bounds).1;
        placement.rotation = self.params.placement.rotation;
        if self.placed() {
            placement.position = self.params.placement.position;
        }
        self.params.placement = placement;
        Ok(())
    }

    /// The place and the instant of the session's first frame the sun is computed for: what the
    /// user sets by hand when location is not allowed. Later GPS fixes still move the place.
    pub fn set_place(&mut self, lat_deg: f64, lon_deg: f64, start: DateTime<Utc>) -> Result<()> {
        let cfg = LiveConfig { lat_deg, lon_deg, start, ..self.cfg.clone() };
        cfg.validate()?;
        self.cfg = cfg;
        self.location = (lat_deg, lon_deg);
        Ok(())
    }

    /// The instant of the latest frame (the session's start before the first): the phone's clock
    /// live, the simulated clock in a scripted session, so names made from it repeat with it.
    pub fn now(&self) -> DateTime<Utc> {
        self.cfg.start + chrono::Duration::microseconds((self.last_t.unwrap_or(0.0) * 1e6).round() as i64)
    }

    /// Lock (true) or release the camera's auto-exposure and auto white balance
    /// ([`FrameSource::lock_exposure`]); whether they are locked now.
    pub fn lock_camera_exposure(&mut self, lock: bool) -> Result<bool> {
        self.sources.camera.lock_exposure(lock)
    }

    /// Latitude and longitude the sun is computed for now.
    pub fn location(&self) -> (f64, f64) {
        self.location
    }

    /// The sensor readings the latest frame delivered, in the order the fusion filter took them.
    pub fn readings(&self) -> &[Reading] {
        &self.readings
    }

    /// The fusion filter, as the latest frame's readings left it.
    pub fn orientation_filter(&self) -> &OrientationFilter {
        &self.filter
    }

    /// How the app's display is rotated from the device's natural orientation now.
    pub fn display_rotation(&self) -> DisplayRotation {
        self.sources.rotation
    }

    /// A description of the sensor source, for the overlay.
    pub fn sensors(&self) -> String {
        self.sources.sensors.describe()
    }
}
