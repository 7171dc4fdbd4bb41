//! The virtual phone: renders what a phone camera sees from an environment cube map at a given
//! orientation — a pinhole camera (vertical field of view, resolution), auto-exposure, white
//! balance (auto when set, [`VirtualPhone::set_white_balance`]; lockable, [`super::controls`])
//! and a tone curve to 8-bit sRGB (see [`super::exposure`]).
//!
//! Pose: a unit quaternion rotating the camera frame to the world (ENU) frame; the camera
//! looks along its −z, +x is image right, +y image up. So the identity pose looks straight
//! down with North at the top of the image, and a +90° turn about x looks North.
//!
//! Rendering is deterministic (every pixel is computed independently; the thread count does
//! not change the result) and runs on all cores.

use super::controls::{AutoCamera, CameraSettings, Metering};
use super::exposure::{ExposureMode, ToneLut, log_average_luminance};
use super::short_exposure::{ExposureLimits, OneShot, SensorExposure, ShortFrame, plan_exposure};
use super::white_balance::{NEUTRAL, WhiteBalanceMode};
use super::{Frame, FrameSource};
use crate::scene::{CubeMap, Rgba8Image};
use anyhow::{Result, bail};
use glam::{Mat3, Quat, Vec3};
use std::sync::Arc;

/// The phone camera's settings.
#[derive(Clone, Debug)]
pub struct SimSettings {
    pub width: u32,
    pub height: u32,
    /// Vertical field of view in degrees (0 < vfov < 180).
    pub vfov_deg: f32,
    pub exposure: ExposureMode,
}

impl Default for SimSettings {
    /// A phone's main camera in landscape: 4:3, about 65° horizontal (50° vertical).
    fn default() -> Self {
        SimSettings { width: 960, height: 720, vfov_deg: 50.0, exposure: ExposureMode::default() }
    }
}

/// Metering looks at every `METER_STEP`-th pixel in each direction (as phones meter on a
/// low-resolution statistics grid).
const METER_STEP: u32 = 4;

/// A virtual phone camera looking into an environment.
pub struct VirtualPhone {
    env: Arc<CubeMap>,
    width: u32,
    height: u32,
    /// tan of half the horizontal and vertical field of view.
    tan_half: (f32, f32),
    exposure: ExposureMode,
    controls: AutoCamera,
    lut: ToneLut,
    last_t: Option<f64>,
    threads: usize,
}

/// A camera-to-world rotation from a quaternion, refusing ones that are not rotations.
pub fn pose_matrix(pose: Quat) -> Result<Mat3> {
    let len = pose.length();
    if !(pose.is_finite() && len > 1e-6) {
        bail!("camera pose {pose:?} is not a rotation (non-finite or zero quaternion)");
    }
    Ok(Mat3::from_quat(pose / len))
}

impl VirtualPhone {
    pub fn new(env: Arc<CubeMap>, settings: &SimSettings) -> Result<VirtualPhone> {
        let SimSettings { width, height, vfov_deg, exposure } = *settings;
        if width == 0 || height == 0 || width > 16384 || height > 16384 {
            bail!("virtual camera resolution {width}x{height} must be 1..=16384 in each direction");
        }
        if !(vfov_deg.is_finite() && vfov_deg > 0.0 && vfov_deg < 180.0) {
            bail!("virtual camera vertical field of view must be between 0 and 180 degrees, got {vfov_deg}");
        }
        if env.size == 0 {
            bail!("the environment cube map is empty");
        }
        let tan_v = (vfov_deg.to_radians() * 0.5).tan();
        let tan_h = tan_v * width as f32 / height as f32;
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        Ok(VirtualPhone {
            env,
            width,
            height,
            tan_half: (tan_h, tan_v),
            exposure,
            controls: AutoCamera::new(exposure, WhiteBalanceMode::Fixed(NEUTRAL))?,
            lut: ToneLut::new(),
            last_t: None,
            threads,
        })
    }

    /// How the white balance is chosen from now on (neutral fixed gains by default; auto follows
    /// the view, [`super::white_balance`]). Starts the controls afresh (unlocked).
    pub fn set_white_balance(&mut self, mode: WhiteBalanceMode) -> Result<()> {
        self.controls = AutoCamera::new(self.exposure, mode)?;
        Ok(())
    }

    /// Lock (true) or release (false) exposure and white balance at the last frame's values.
    pub fn lock_controls(&mut self, lock: bool) {
        if lock {
            self.controls.lock();
        } else {
            self.controls.unlock();
        }
    }

    /// Use `n` threads (at least 1) for rendering; the default is one per core.
    pub fn set_threads(&mut self, n: usize) {
        self.threads = n.max(1);
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The environment being looked at.
    pub fn environment(&self) -> &Arc<CubeMap> {
        &self.env
    }

    /// Horizontal field of view in degrees (from the vertical one and the aspect ratio).
    pub fn hfov_deg(&self) -> f32 {
        2.0 * self.tan_half.0.atan().to_degrees()
    }

    /// World (ENU) direction, not normalised, through image position (px, py) in pixels
    /// ((0, 0) is the top-left corner of the image, pixel centres are at +0.5).
    pub fn pixel_ray(&self, rot: &Mat3, px: f32, py: f32) -> Vec3 {
        let x = (2.0 * px / self.width as f32 - 1.0) * self.tan_half.0;
        let y = (1.0 - 2.0 * py / self.height as f32) * self.tan_half.1;
        rot.x_axis * x + rot.y_axis * y - rot.z_axis
    }

    /// What the metering grid sees of the view at `pose` (linear light): the log-average
    /// luminance and the per-channel geometric means.
    pub fn meter(&self, pose: Quat) -> Result<Metering> {
        let rot = pose_matrix(pose)?;
        let (gw, gh) = (self.width.div_ceil(METER_STEP), self.height.div_ceil(METER_STEP));
        let (sx, sy) = (self.width as f32 / gw as f32, self.height as f32 / gh as f32);
        let samples: Vec<[f32; 3]> = (0..gh)
            .flat_map(|j| (0..gw).map(move |i| ((i as f32 + 0.5) * sx, (j as f32 + 0.5) * sy)))
            .map(|(x, y)| self.env.sample_enu(self.pixel_ray(&rot, x, y)))
            .collect();
        let channel = |c: usize| log_average_luminance(samples.iter().map(|s| [s[c]; 3]));
        Ok(Metering {
            log_average_luminance: log_average_luminance(samples.iter().copied()),
            log_average_rgb: [channel(0), channel(1), channel(2)],
        })
    }

    /// The next frame of a stream at time `t` seconds: meters (auto mode), adapts the exposure
    /// by the time since the previous frame, renders.
    pub fn render(&mut self, pose: Quat, t: f64) -> Result<Frame> {
        let rot = pose_matrix(pose)?;
        let metered = if self.controls.needs_metering() {
            self.meter(pose)?
        } else {
            Metering { log_average_luminance: 0.0, log_average_rgb: [0.0; 3] }
        };
        let dt = self.last_t.map_or(0.0, |last| t - last);
        self.last_t = Some(t);
        let settings = self.controls.update(metered, dt);
        Ok(Frame { image: self.draw(&rot, settings.gains()), t })
    }

    /// One image at a given exposure (neutral white balance), outside any stream (no metering,
    /// no adaptation): e.g. the ideal view to compare a capture against.
    pub fn render_with_exposure(&self, pose: Quat, exposure: f32) -> Result<Rgba8Image> {
        if !(exposure.is_finite() && exposure > 0.0) {
            bail!("exposure must be a positive number, got {exposure}");
        }
        self.render_with(pose, CameraSettings::exposure(exposure))
    }

    /// One image with given exposure and white balance, outside any stream.
    pub fn render_with(&self, pose: Quat, settings: CameraSettings) -> Result<Rgba8Image> {
        settings.validate()?;
        Ok(self.draw(&pose_matrix(pose)?, settings.gains()))
    }

    /// The exposure (multiplier on scene radiance) of the last frame.
    pub fn exposure(&self) -> Option<f32> {
        self.controls.current().map(|s| s.exposure)
    }

    /// The exposure and white balance of the last frame.
    pub fn settings(&self) -> Option<CameraSettings> {
        self.controls.current()
    }

    /// The exposure mode (auto or fixed).
    pub fn exposure_mode(&self) -> ExposureMode {
        self.exposure
    }

    fn draw(&self, rot: &Mat3, gains: [f32; 3]) -> Rgba8Image {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut pixels = vec![0u8; w * h * 4];
        let xs: Vec<f32> = (0..w).map(|x| (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * self.tan_half.0).collect();
        let (env, lut) = (&*self.env, &self.lut);
        let tan_v = self.tan_half.1;
        let (right, up, back) = (rot.x_axis, rot.y_axis, rot.z_axis);
        let draw_rows = |first_row: usize, band: &mut [u8]| {
            for (r, row) in band.chunks_exact_mut(w * 4).enumerate() {
                let y = (1.0 - 2.0 * ((first_row + r) as f32 + 0.5) / h as f32) * tan_v;
                let base = up * y - back;
                for (px, &x) in row.chunks_exact_mut(4).zip(&xs) {
                    let c = env.sample_enu(base + right * x);
                    px[0] = lut.map(c[0] * gains[0]);
                    px[1] = lut.map(c[1] * gains[1]);
                    px[2] = lut.map(c[2] * gains[2]);
                    px[3] = 255;
                }
            }
        };
        let threads = self.threads.min(h).max(1);
        if threads == 1 {
            draw_rows(0, &mut pixels);
        } else {
            let rows_per_band = h.div_ceil(threads);
            std::thread::scope(|s| {
                for (i, band) in pixels.chunks_mut(rows_per_band * w * 4).enumerate() {
                    let draw_rows = &draw_rows;
                    s.spawn(move || draw_rows(i * rows_per_band, band));
                }
            });
        }
        Rgba8Image { width: self.width, height: self.height, pixels }
    }
}

/// A [`FrameSource`] that renders the virtual phone along a list of timed poses (one frame
/// per pose), adapting exposure from frame to frame.
///
/// A short exposure frame ([`FrameSource::request_exposure_frame`]) goes through the phones'
/// request states ([`super::short_exposure::OneShot`]): it is rendered at the next pose and time,
/// as a phone's one-shot request lands on a later frame of its stream, at the last frame's
/// exposure × the factor (the exposure multiplier taken as the time, no sensor limits) and white
/// balance; that pose's stream frame is rendered too (the virtual phone hides none).
pub struct SimSequence {
    phone: VirtualPhone,
    poses: std::vec::IntoIter<(f64, Quat)>,
    shot: OneShot,
}

impl SimSequence {
    /// `poses`: (time in seconds, camera → ENU rotation), times finite and not decreasing.
    pub fn new(phone: VirtualPhone, poses: Vec<(f64, Quat)>) -> Result<SimSequence> {
        for (i, (t, q)) in poses.iter().enumerate() {
            if !t.is_finite() {
                bail!("pose {i}: time {t} is not a finite number of seconds");
            }
            if i > 0 && *t < poses[i - 1].0 {
                bail!("pose {i}: time goes backwards ({} s after {} s)", t, poses[i - 1].0);
            }
            pose_matrix(*q).map_err(|e| e.context(format!("pose {i} at {t} s")))?;
        }
        Ok(SimSequence { phone, poses: poses.into_iter(), shot: OneShot::new() })
    }

    pub fn phone(&self) -> &VirtualPhone {
        &self.phone
    }
}

impl FrameSource for SimSequence {
    fn next_frame(&mut self) -> Result<Option<Frame>> {
        match self.poses.next() {
            None => Ok(None),
            Some((t, pose)) => {
                if let (Some((id, plan)), Some(s)) = (self.shot.in_flight(), self.phone.settings()) {
                    let settings = CameraSettings { exposure: plan.exposure.product() as f32, ..s };
                    self.shot.arrived(id, Frame { image: self.phone.render_with(pose, settings)?, t }, plan.exposure);
                }
                let frame = self.phone.render(pose, t)?;
                self.shot.stream_frame(t, true);
                Ok(Some(frame))
            }
        }
    }

    /// Asked after a frame (the exposure to shorten is that frame's).
    fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
        let Some(s) = self.phone.settings() else { return Ok(false) };
        let current = SensorExposure { time_s: f64::from(s.exposure), iso: 1.0 };
        let plan = plan_exposure(current, f64::from(relative_exposure), &ExposureLimits::UNLIMITED)?;
        Ok(self.shot.request(plan).is_some())
    }

    fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
        Ok(self.shot.take())
    }

    fn pause(&mut self) -> Result<()> {
        self.shot.cancel();
        Ok(())
    }

    fn lock_exposure(&mut self, lock: bool) -> Result<bool> {
        self.phone.lock_controls(lock);
        Ok(lock)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::exposure::{MIDDLE_GREY, tone_to_srgb8};
    use std::f32::consts::{FRAC_PI_2, PI};

    /// Wgpu face order +X (East), −X, +Y (up), −Y, +Z (North), −Z.
    const COLOURS: [[f32; 3]; 6] = [[0.8, 0.1, 0.1], [0.1, 0.8, 0.1], [0.1, 0.1, 0.8], [0.8, 0.8, 0.1], [0.1, 0.8, 0.8], [0.8, 0.1, 0.8]];

    fn phone(w: u32, h: u32, vfov: f32) -> VirtualPhone {
        let env = Arc::new(CubeMap::solid_faces(8, COLOURS));
        VirtualPhone::new(env, &SimSettings { width: w, height: h, vfov_deg: vfov, exposure: ExposureMode::Fixed(1.0) }).unwrap()
    }

    fn pixel(img: &Rgba8Image, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * img.width + x) * 4) as usize;
        [img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]]
    }

    fn expect(face: usize) -> [u8; 3] {
        COLOURS[face].map(tone_to_srgb8)
    }

    fn close(a: [u8; 3], b: [u8; 3]) -> bool {
        a.iter().zip(&b).all(|(x, y)| (*x as i32 - *y as i32).abs() <= 1)
    }

    /// Level camera looking at true azimuth `az` (radians, clockwise from North).
    fn level(az: f32) -> Quat {
        Quat::from_rotation_z(-az) * Quat::from_rotation_x(FRAC_PI_2)
    }

    #[test]
    fn looking_along_the_compass_sees_the_matching_faces() {
        let cam = phone(64, 48, 60.0);
        let centre = |q: Quat| pixel(&cam.render_with_exposure(q, 1.0).unwrap(), 32, 24);
        assert!(close(centre(level(0.0)), expect(4)), "North sees +Z");
        assert!(close(centre(level(FRAC_PI_2)), expect(0)), "East sees +X");
        assert!(close(centre(level(PI)), expect(5)), "South sees -Z");
        assert!(close(centre(level(-FRAC_PI_2)), expect(1)), "West sees -X");
    }

    #[test]
    fn pitch_plus_minus_90_and_image_orientation() {
        // Wide view (vfov 120°): the top edge is 60° from the centre.
        let cam = phone(64, 64, 120.0);
        // Pitch +90 from level-North: looking up, image top towards South (the camera's +y is
        // the old −z... i.e. what was "behind" tilts to the top).
        let up = Quat::from_rotation_x(PI);
        let img = cam.render_with_exposure(up, 1.0).unwrap();
        assert!(close(pixel(&img, 32, 32), expect(2)), "looking up sees +Y");
        assert!(close(pixel(&img, 32, 1), expect(5)), "top of an upward view (image up = South)");
        assert!(close(pixel(&img, 62, 32), expect(0)), "right of an upward view is East");
        // Identity: looking down, North at the top of the image, East on the right.
        let img = cam.render_with_exposure(Quat::IDENTITY, 1.0).unwrap();
        assert!(close(pixel(&img, 32, 32), expect(3)), "looking down sees -Y");
        assert!(close(pixel(&img, 32, 1), expect(4)), "top of a downward view is North");
        assert!(close(pixel(&img, 62, 32), expect(0)), "right of a downward view is East");
        // Level North, wide: top of the image is sky, bottom ground, right East.
        let img = cam.render_with_exposure(level(0.0), 1.0).unwrap();
        assert!(close(pixel(&img, 32, 1), expect(2)) && close(pixel(&img, 32, 62), expect(3)));
        assert!(close(pixel(&img, 63, 32), expect(0)) && close(pixel(&img, 0, 32), expect(1)));
        // Through pitch 90 there is no flip: 89.9° and 90.1° (heading North) look almost alike.
        let a = cam.render_with_exposure(Quat::from_rotation_x(FRAC_PI_2 + 89.9f32.to_radians()), 1.0).unwrap();
        let b = cam.render_with_exposure(Quat::from_rotation_x(FRAC_PI_2 + 90.1f32.to_radians()), 1.0).unwrap();
        let differing = a.pixels.iter().zip(&b.pixels).filter(|(x, y)| x != y).count();
        assert!(differing < a.pixels.len() / 50, "{differing} bytes differ");
    }

    #[test]
    fn auto_exposure_maps_a_uniform_scene_to_middle_grey_at_any_brightness() {
        // (δ = 1e-4 in the log average shifts the exposure by δ/L: 0.1% at L = 0.1.)
        for radiance in [0.1f32, 1.0, 300.0] {
            let env = Arc::new(CubeMap::solid_faces(4, [[radiance; 3]; 6]));
            let mut cam =
                VirtualPhone::new(env, &SimSettings { width: 16, height: 12, vfov_deg: 60.0, exposure: ExposureMode::default() }).unwrap();
            let frame = cam.render(level(0.3), 0.0).unwrap();
            let grey = tone_to_srgb8(MIDDLE_GREY);
            assert!(frame.image.pixels.chunks(4).all(|p| (p[0] as i32 - grey as i32).abs() <= 1), "radiance {radiance}");
            let e = cam.exposure().unwrap();
            assert!((e * radiance / MIDDLE_GREY - 1.0).abs() < 1.5e-3, "exposure {e}");
        }
    }

    #[test]
    fn exposure_adapts_over_frames_when_the_scene_darkens() {
        // Bright sky above, dark ground below: turning from up to down, the first downward
        // frame is dark (exposure still set for the sky) and brightens as the camera adapts.
        let mut colours = [[0.05f32; 3]; 6];
        colours[2] = [5.0; 3];
        let env = Arc::new(CubeMap::solid_faces(4, colours));
        let settings = SimSettings { width: 16, height: 16, vfov_deg: 40.0, exposure: ExposureMode::Auto { key: 0.18, adaptation_s: 0.5 } };
        let mut cam = VirtualPhone::new(env, &settings).unwrap();
        let mut seq = SimSequence::new(
            VirtualPhone::new(cam.env.clone(), &settings).unwrap(),
            vec![(0.0, Quat::from_rotation_x(PI)), (0.1, Quat::IDENTITY), (0.6, Quat::IDENTITY), (5.0, Quat::IDENTITY)],
        )
        .unwrap();
        let means: Vec<f32> = std::iter::from_fn(|| seq.next_frame().unwrap())
            .map(|f| f.image.pixels.chunks(4).map(|p| p[0] as f32).sum::<f32>() / (f.image.pixels.len() / 4) as f32)
            .collect();
        assert_eq!(means.len(), 4);
        let grey = tone_to_srgb8(MIDDLE_GREY) as f32;
        assert!((means[0] - grey).abs() <= 1.0, "first frame converged: {means:?}");
        assert!(means[1] < means[2] && means[2] < means[3], "brightening: {means:?}");
        assert!(means[1] < grey - 50.0, "first dark frame underexposed: {means:?}");
        assert!((means[3] - grey).abs() <= 1.0, "converged after 5 s: {means:?}");
        // The same phone driven directly gives the same frames (deterministic).
        let a = cam.render(Quat::from_rotation_x(PI), 0.0).unwrap();
        let b = cam.render(Quat::IDENTITY, 0.1).unwrap();
        assert_eq!(a.t, 0.0);
        assert!((b.image.pixels.chunks(4).map(|p| p[0] as f32).sum::<f32>() / 256.0 - means[1]).abs() < 1e-3);
    }

    #[test]
    fn auto_white_balance_drifts_with_the_view_unless_locked() {
        // Blue sky above, brown ground below. Unlocked, the grey world balances each view to
        // grey: the sky turns grey, and so does the ground; locked at the sky, the ground keeps
        // its colour relative to the sky.
        let mut colours = [[0.4f32, 0.25, 0.15]; 6];
        colours[2] = [0.2, 0.3, 0.6];
        let env = Arc::new(CubeMap::solid_faces(4, colours));
        let settings = SimSettings { width: 16, height: 16, vfov_deg: 40.0, exposure: ExposureMode::Auto { key: 0.18, adaptation_s: 0.0 } };
        let frames = |lock: bool| {
            let mut phone = VirtualPhone::new(env.clone(), &settings).unwrap();
            phone.set_white_balance(WhiteBalanceMode::Auto { adaptation_s: 0.0 }).unwrap();
            let mut seq = SimSequence::new(phone, vec![(0.0, Quat::from_rotation_x(PI)), (1.0, Quat::IDENTITY)]).unwrap();
            let sky = seq.next_frame().unwrap().unwrap();
            assert_eq!(seq.lock_exposure(lock).unwrap(), lock);
            let ground = seq.next_frame().unwrap().unwrap();
            (pixel(&sky.image, 8, 8), pixel(&ground.image, 8, 8), seq.phone().settings().unwrap())
        };
        let (sky, ground, s) = frames(false);
        let grey = |p: [u8; 3]| p.iter().all(|c| (*c as i32 - p[1] as i32).abs() <= 1);
        assert!(grey(sky) && grey(ground), "unlocked: sky {sky:?} ground {ground:?}");
        let near = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x / y - 1.0).abs() < 1e-3);
        assert!(near(s.white_balance, [0.25 / 0.4, 1.0, 0.25 / 0.15]), "{:?}", s.white_balance);
        let (sky_locked, ground_locked, s) = frames(true);
        assert_eq!(sky_locked, sky);
        // Locked at the sky's gains (1.5, 1, 0.5) and exposure (0.18 / its luminance).
        assert!(near(s.white_balance, [1.5, 1.0, 0.5]), "{:?}", s.white_balance);
        let expect = [0.4 * s.white_balance[0], 0.25, 0.15 * s.white_balance[2]].map(|c| tone_to_srgb8(c * s.exposure));
        assert!(close(ground_locked, expect), "{ground_locked:?} vs {expect:?}");
        assert!(ground_locked[0] > ground_locked[2] + 40, "the ground stays brown: {ground_locked:?}");
    }

    #[test]
    fn a_short_exposure_frame_comes_with_the_next_frame_at_its_pose() {
        let poses = vec![(0.0, level(0.0)), (0.1, level(FRAC_PI_2)), (0.2, level(PI)), (0.3, level(PI))];
        let mut seq = SimSequence::new(phone(16, 12, 60.0), poses).unwrap();
        assert!(!seq.request_exposure_frame(0.25).unwrap(), "no exposure to shorten before a frame");
        seq.next_frame().unwrap().unwrap();
        assert!(seq.request_exposure_frame(0.25).unwrap());
        assert!(!seq.request_exposure_frame(0.25).unwrap(), "one at a time");
        assert!(seq.take_exposure_frame().unwrap().is_none(), "in flight");
        // The next frame (East): the stream's frame at the full exposure, and the short frame
        // at the same pose and time at a quarter of it.
        let stream = seq.next_frame().unwrap().unwrap();
        assert!(close(pixel(&stream.image, 8, 6), expect(0)));
        let Some(ShortFrame::Arrived(short)) = seq.take_exposure_frame().unwrap() else { panic!("no short frame") };
        assert_eq!(short.frame.t, 0.1);
        assert_eq!(short.relative_exposure, 0.25);
        assert!(close(pixel(&short.frame.image, 8, 6), COLOURS[0].map(|c| tone_to_srgb8(c * 0.25))));
        assert!(seq.take_exposure_frame().unwrap().is_none(), "taken once");
        // Paused while one is in flight: lost, and the next frame brings none.
        assert!(seq.request_exposure_frame(0.25).unwrap());
        seq.pause().unwrap();
        assert!(matches!(seq.take_exposure_frame().unwrap(), Some(ShortFrame::Lost)));
        seq.next_frame().unwrap().unwrap();
        assert!(seq.take_exposure_frame().unwrap().is_none());
        assert!(seq.request_exposure_frame(0.25).unwrap(), "asked again");
    }

    #[test]
    fn threads_do_not_change_the_image() {
        let mut cam = phone(37, 23, 75.0);
        let q = Quat::from_euler(glam::EulerRot::ZXY, 0.3, 1.1, -0.4);
        cam.set_threads(1);
        let one = cam.render_with_exposure(q, 1.3).unwrap();
        cam.set_threads(5);
        let five = cam.render_with_exposure(q, 1.3).unwrap();
        assert_eq!(one.pixels, five.pixels);
    }

    #[test]
    fn bad_settings_and_poses_are_errors() {
        let env = Arc::new(CubeMap::solid_faces(2, COLOURS));
        let bad = |s: SimSettings| VirtualPhone::new(env.clone(), &s).is_err();
        assert!(bad(SimSettings { width: 0, ..Default::default() }));
        assert!(bad(SimSettings { vfov_deg: 180.0, ..Default::default() }));
        assert!(bad(SimSettings { vfov_deg: f32::NAN, ..Default::default() }));
        assert!(bad(SimSettings { exposure: ExposureMode::Fixed(-1.0), ..Default::default() }));
        let mut cam = phone(8, 8, 60.0);
        assert!(cam.render(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), 0.0).is_err());
        assert!(cam.render(Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0), 0.0).is_err());
        assert!(cam.render_with_exposure(Quat::IDENTITY, 0.0).is_err());
        // A non-unit quaternion is normalised, not refused.
        assert!(cam.render(Quat::from_xyzw(0.0, 0.0, 0.0, 2.0), 0.0).is_ok());
        let p = || phone(4, 4, 60.0);
        assert!(SimSequence::new(p(), vec![(1.0, Quat::IDENTITY), (0.5, Quat::IDENTITY)]).is_err());
        assert!(SimSequence::new(p(), vec![(f64::NAN, Quat::IDENTITY)]).is_err());
        assert!(SimSequence::new(p(), vec![(0.0, Quat::from_xyzw(0.0, 0.0, 0.0, 0.0))]).is_err());
    }
}
