//! One short exposure frame between a camera stream's frames (the live sun frame of issue 12,
//! [`crate::live::sun_north`]), the parts every camera shares, pure and tested on the host:
//!
//! - [`plan_exposure`]: the current exposure (time × sensitivity) times a factor, within the
//!   sensor's ranges — time first, then sensitivity — and the factor actually reached (the sun
//!   finder is told that one, not the one asked for);
//! - [`OneShot`]: the state of the one request (idle → in flight → the frame arrived, or it
//!   timed out or failed → the stream back at its own exposure → idle). Nothing in it waits:
//!   the frame loop asks ([`OneShot::request`]), goes on drawing the stream's frames
//!   ([`OneShot::stream_frame`]), and takes the outcome when there is one ([`OneShot::take`]);
//! - what the platforms report, parsed from plain slices ([`camera2_manual_limits`],
//!   [`camera2_result_exposure`]) and the test that tells a short frame from a stream frame by
//!   its exposure ([`nearer_short`]).
//!
//! The virtual phone ([`super::sim::SimSequence`]) and the phone backends (`camera::android`:
//! Camera2 one-shot capture request; `camera::ios`: AVFoundation custom exposure) drive it.

use super::Frame;
use anyhow::{Result, bail};

/// A frame that has not arrived this long (seconds of the stream's clock) after its request is
/// lost, and the stream goes on; the same bound for the stream's return to its own exposure.
/// A phone's capture pipeline is 3–8 frames deep (100–270 ms at 30 Hz); the live sun frame asks
/// once a second ([`crate::live::sun_north::SUN_FRAME_PERIOD_S`]).
pub const SHORT_FRAME_TIMEOUT_S: f64 = 0.5;

/// Camera2's `CONTROL_AE_MODE_OFF` and `REQUEST_AVAILABLE_CAPABILITIES_MANUAL_SENSOR`
/// (NDK `NdkCameraMetadataTags.h`; `camera::android` checks them against ndk-sys's values).
pub const CAMERA2_AE_MODE_OFF: u8 = 0;
pub const CAMERA2_CAPABILITY_MANUAL_SENSOR: u8 = 1;

/// An exposure as the sensor takes it: exposure time (seconds) and sensitivity (ISO).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorExposure {
    pub time_s: f64,
    pub iso: f64,
}

impl SensorExposure {
    /// Time × sensitivity: proportional to the image's brightness for a fixed aperture.
    pub fn product(&self) -> f64 {
        self.time_s * self.iso
    }

    fn is_valid(&self) -> bool {
        self.time_s.is_finite() && self.time_s > 0.0 && self.iso.is_finite() && self.iso > 0.0
    }
}

/// The exposure times and sensitivities a sensor takes (inclusive ranges).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureLimits {
    pub time_s: (f64, f64),
    pub iso: (f64, f64),
}

impl ExposureLimits {
    /// No limit (the virtual phone).
    pub const UNLIMITED: ExposureLimits = ExposureLimits { time_s: (f64::MIN_POSITIVE, f64::MAX), iso: (f64::MIN_POSITIVE, f64::MAX) };

    /// Ranges `(min, max)` with 0 < min ≤ max, finite.
    pub fn new(time_s: (f64, f64), iso: (f64, f64)) -> Result<ExposureLimits> {
        let ok = |(lo, hi): (f64, f64)| lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi;
        if !ok(time_s) {
            bail!("exposure time range {:?} s is not 0 < min <= max", time_s);
        }
        if !ok(iso) {
            bail!("sensitivity range {:?} is not 0 < min <= max", iso);
        }
        Ok(ExposureLimits { time_s, iso })
    }
}

/// The exposure to ask for, and what it gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposurePlan {
    /// The stream's exposure when the plan was made.
    pub stream: SensorExposure,
    /// The short frame's exposure (within the limits).
    pub exposure: SensorExposure,
    /// `exposure.product() / stream.product()`: the factor reached (the one asked for when the
    /// limits allow it).
    pub relative: f64,
}

/// `current` × `factor` within `limits`: the exposure time first (`factor` × the current time,
/// clamped to its range), then the sensitivity for what the time could not reach (clamped to
/// its range). Keeping the sensitivity and shortening the time is what a −4 EV bracket does on
/// a phone; the sensitivity only falls when the time is at its end (bright daylight already
/// runs near the shortest times). Errors name a current exposure or factor that is not a
/// positive number.
pub fn plan_exposure(current: SensorExposure, factor: f64, limits: &ExposureLimits) -> Result<ExposurePlan> {
    if !current.is_valid() {
        bail!("the camera's current exposure ({} s, ISO {}) is not positive", current.time_s, current.iso);
    }
    if !(factor.is_finite() && factor > 0.0) {
        bail!("relative exposure {factor} is not a positive number");
    }
    let target = current.product() * factor;
    let iso = current.iso.clamp(limits.iso.0, limits.iso.1);
    let time_s = (target / iso).clamp(limits.time_s.0, limits.time_s.1);
    let iso = (target / time_s).clamp(limits.iso.0, limits.iso.1);
    let exposure = SensorExposure { time_s, iso };
    Ok(ExposurePlan { stream: current, exposure, relative: exposure.product() / current.product() })
}

/// Whether a frame exposed at `measured` (time × sensitivity) is nearer, in stops, the short
/// frame's `planned` exposure than the stream's `stream` one. A platform that only says a frame's
/// exposure (iOS: the buffer's Exif `ExposureTime` and `ISOSpeedRatings`) tells the short frame,
/// and the frames still dark after it, from the stream's frames this way; the midpoint in stops
/// leaves room for the sensor's rounding of the time to whole lines.
pub fn nearer_short(measured: f64, planned: f64, stream: f64) -> bool {
    measured > 0.0 && (measured / planned).ln().abs() < (measured / stream).ln().abs()
}

/// Whether a frame whose metadata reports `time_s` and, when it says, `iso` (iOS: the sample
/// buffer's Exif `ExposureTime` and `ISOSpeedRatings`) is at `plan`'s short exposure rather than
/// the stream's ([`nearer_short`] on time × sensitivity; on the time alone without a sensitivity).
pub fn frame_is_short(time_s: f64, iso: Option<f64>, plan: &ExposurePlan) -> bool {
    match iso {
        Some(iso) => nearer_short(time_s * iso, plan.exposure.product(), plan.stream.product()),
        None => nearer_short(time_s, plan.exposure.time_s, plan.stream.time_s),
    }
}

/// Camera2 characteristics → the limits of a manual exposure, or None when the camera cannot take
/// one: `CONTROL_AE_AVAILABLE_MODES` must list OFF and `REQUEST_AVAILABLE_CAPABILITIES`
/// `MANUAL_SENSOR` (the LIMITED devices without it ignore `SENSOR_EXPOSURE_TIME`);
/// `SENSOR_INFO_EXPOSURE_TIME_RANGE` (ns, `[min, max]`) and `SENSOR_INFO_SENSITIVITY_RANGE`
/// (ISO, `[min, max]`) give the ranges.
pub fn camera2_manual_limits(ae_modes: &[u8], capabilities: &[u8], time_range_ns: &[i64], iso_range: &[i32]) -> Option<ExposureLimits> {
    if !ae_modes.contains(&CAMERA2_AE_MODE_OFF) || !capabilities.contains(&CAMERA2_CAPABILITY_MANUAL_SENSOR) {
        return None;
    }
    let (&[t0, t1, ..], &[s0, s1, ..]) = (time_range_ns, iso_range) else { return None };
    ExposureLimits::new((t0 as f64 * 1e-9, t1 as f64 * 1e-9), (f64::from(s0), f64::from(s1))).ok()
}

/// A Camera2 capture result's `SENSOR_EXPOSURE_TIME` (ns) and `SENSOR_SENSITIVITY` (ISO) as a
/// [`SensorExposure`]; None when either is missing or not positive.
pub fn camera2_result_exposure(time_ns: &[i64], iso: &[i32]) -> Option<SensorExposure> {
    let (&[t, ..], &[s, ..]) = (time_ns, iso) else { return None };
    let e = SensorExposure { time_s: t as f64 * 1e-9, iso: f64::from(s) };
    e.is_valid().then_some(e)
}

/// A short exposure frame and the exposure it really had, relative to the stream's.
#[derive(Clone, Debug)]
pub struct ExposureFrame {
    pub frame: Frame,
    pub relative_exposure: f64,
}

/// How a request ended.
#[derive(Clone, Debug)]
pub enum ShortFrame {
    Arrived(ExposureFrame),
    /// Timed out ([`SHORT_FRAME_TIMEOUT_S`]), failed on the platform, or the camera was paused.
    Lost,
}

/// What the backend must do after a step of [`OneShot`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    None,
    /// Put the stream's exposure back (AVFoundation: the custom exposure at the stream's values;
    /// Camera2 goes back by itself: the repeating request never changed).
    Restore,
    /// The stream is at its own exposure again (AVFoundation: continuous auto-exposure again,
    /// unless a capture holds the lock).
    Resumed,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Idle,
    /// Asked for; `since` is the first stream frame's time after the request.
    InFlight {
        id: u64,
        plan: ExposurePlan,
        since: Option<f64>,
    },
    /// The short frame came (or was given up); waiting for a frame at the stream's exposure.
    Resuming {
        since: Option<f64>,
    },
}

/// One short exposure frame at a time, driven by the frame loop (module docs).
#[derive(Clone, Debug)]
pub struct OneShot {
    phase: Phase,
    outcome: Option<ShortFrame>,
    next_id: u64,
    /// The request in flight's frame and its reported exposure, whichever came first (Camera2
    /// reports the exposure in a capture result that may come before or after the image).
    frame: Option<Frame>,
    exposure: Option<SensorExposure>,
}

impl Default for OneShot {
    fn default() -> Self {
        OneShot { phase: Phase::Idle, outcome: None, next_id: 1, frame: None, exposure: None }
    }
}

impl OneShot {
    pub fn new() -> OneShot {
        OneShot::default()
    }

    /// Start a request for `plan`: its id, or None while an earlier one is not finished (in
    /// flight, the stream not back yet, or its outcome not taken).
    pub fn request(&mut self, plan: ExposurePlan) -> Option<u64> {
        if self.phase != Phase::Idle || self.outcome.is_some() {
            return None;
        }
        let id = self.next_id;
        self.next_id += 1;
        self.phase = Phase::InFlight { id, plan, since: None };
        (self.frame, self.exposure) = (None, None);
        Some(id)
    }

    /// The request in flight: its id and plan.
    pub fn in_flight(&self) -> Option<(u64, ExposurePlan)> {
        match self.phase {
            Phase::InFlight { id, plan, .. } => Some((id, plan)),
            _ => None,
        }
    }

    /// The short frame of request `id` arrived, exposed at `exposure` as the platform reports
    /// it: [`OneShot::frame_arrived`] and [`OneShot::exposure_reported`] at once.
    pub fn arrived(&mut self, id: u64, frame: Frame, exposure: SensorExposure) -> Action {
        self.frame_arrived(id, frame);
        self.exposure_reported(id, exposure)
    }

    /// The short frame of request `id` arrived; it is taken once its exposure is reported too
    /// ([`Action::Restore`] then). A frame of a request that timed out, was cancelled or is not
    /// the one in flight is dropped ([`Action::None`]).
    pub fn frame_arrived(&mut self, id: u64, frame: Frame) -> Action {
        if !self.is_in_flight(id) {
            return Action::None;
        }
        self.frame = Some(frame);
        self.complete()
    }

    /// The platform reports the exposure request `id`'s frame really had (a positive time and
    /// sensitivity; anything else is ignored, and the request times out without it).
    pub fn exposure_reported(&mut self, id: u64, exposure: SensorExposure) -> Action {
        if !self.is_in_flight(id) || !exposure.is_valid() {
            return Action::None;
        }
        self.exposure = Some(exposure);
        self.complete()
    }

    fn is_in_flight(&self, id: u64) -> bool {
        matches!(self.phase, Phase::InFlight { id: current, .. } if current == id)
    }

    /// The frame and its exposure both there: the outcome, the stream's exposure to restore.
    fn complete(&mut self) -> Action {
        let Phase::InFlight { plan, .. } = self.phase else { return Action::None };
        let Some(exposure) = self.exposure else { return Action::None };
        let Some(frame) = self.frame.take() else { return Action::None };
        let relative_exposure = exposure.product() / plan.stream.product();
        self.outcome = Some(ShortFrame::Arrived(ExposureFrame { frame, relative_exposure }));
        self.exposure = None;
        self.phase = Phase::Resuming { since: None };
        Action::Restore
    }

    /// Request `id` failed on the platform (the submission, or Camera2's `onCaptureFailed`): it
    /// is lost.
    pub fn failed(&mut self, id: u64) -> Action {
        match self.phase {
            Phase::InFlight { id: current, .. } if current == id => self.lose(),
            _ => Action::None,
        }
    }

    fn lose(&mut self) -> Action {
        (self.frame, self.exposure) = (None, None);
        self.outcome = Some(ShortFrame::Lost);
        self.phase = Phase::Resuming { since: None };
        Action::Restore
    }

    /// A frame of the stream (not the short one) at time `t` (seconds, the stream's clock);
    /// `at_stream_exposure`: false for a frame still at the short exposure (the backend hides
    /// it from the preview). A request in flight longer than [`SHORT_FRAME_TIMEOUT_S`] is lost;
    /// after the short frame, the first frame at the stream's exposure — or the timeout — ends
    /// the request.
    pub fn stream_frame(&mut self, t: f64, at_stream_exposure: bool) -> Action {
        match &mut self.phase {
            Phase::Idle => Action::None,
            Phase::InFlight { since, .. } => {
                let since = *since.get_or_insert(t);
                if t - since > SHORT_FRAME_TIMEOUT_S { self.lose() } else { Action::None }
            }
            Phase::Resuming { since } => {
                let since = *since.get_or_insert(t);
                if at_stream_exposure || t - since > SHORT_FRAME_TIMEOUT_S {
                    self.phase = Phase::Idle;
                    Action::Resumed
                } else {
                    Action::None
                }
            }
        }
    }

    /// The camera stops (pause): a request in flight is lost and any frame of it dropped; the
    /// backend puts the stream's exposure back if anything was asked ([`Action::Restore`]).
    pub fn cancel(&mut self) -> Action {
        let was = self.phase;
        self.phase = Phase::Idle;
        (self.frame, self.exposure) = (None, None);
        match was {
            Phase::Idle => Action::None,
            Phase::InFlight { .. } => {
                self.outcome = Some(ShortFrame::Lost);
                Action::Restore
            }
            Phase::Resuming { .. } => Action::Restore,
        }
    }

    /// How the last request ended, once (None while it is in flight or nothing was asked).
    pub fn take(&mut self) -> Option<ShortFrame> {
        self.outcome.take()
    }

    /// Nothing asked and nothing to take.
    pub fn is_idle(&self) -> bool {
        self.phase == Phase::Idle && self.outcome.is_none()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Rgba8Image;

    fn frame(t: f64) -> Frame {
        Frame { image: Rgba8Image { width: 1, height: 1, pixels: vec![0; 4] }, t }
    }

    /// A phone in daylight: 1/500 s at ISO 100; a sensor taking 1/100 000 .. 1/10 s and ISO
    /// 50 .. 3200 (a typical Camera2 `SENSOR_INFO_EXPOSURE_TIME_RANGE`, `SENSITIVITY_RANGE`).
    const DAYLIGHT: SensorExposure = SensorExposure { time_s: 1.0 / 500.0, iso: 100.0 };
    fn limits() -> ExposureLimits {
        ExposureLimits::new((1e-5, 0.1), (50.0, 3200.0)).unwrap()
    }

    #[test]
    fn a_reachable_factor_shortens_the_time_and_keeps_the_sensitivity() {
        // −4 EV: 1/500 s / 16 = 1/8000 s = 125 µs, ISO 100 kept.
        let p = plan_exposure(DAYLIGHT, 1.0 / 16.0, &limits()).unwrap();
        assert!((p.exposure.time_s - 125e-6).abs() < 1e-12, "{p:?}");
        assert_eq!(p.exposure.iso, 100.0);
        assert!((p.relative - 1.0 / 16.0).abs() < 1e-12);
        assert_eq!(p.stream, DAYLIGHT);
    }

    #[test]
    fn a_factor_beyond_the_shortest_time_lowers_the_sensitivity_then_stops_at_its_end() {
        // Bright sun: 1/20 000 s at ISO 100. −4 EV wants 3.125 µs; the sensor stops at 10 µs
        // (×0.2 of the current 50 µs), so ISO 100 → 100 × (3.125/10) = 31.25 → clamped at 50:
        // reached 10 µs × 50 / (50 µs × 100) = 0.1 (−3.32 EV), not 1/16.
        let bright = SensorExposure { time_s: 50e-6, iso: 100.0 };
        let p = plan_exposure(bright, 1.0 / 16.0, &limits()).unwrap();
        assert_eq!(p.exposure, SensorExposure { time_s: 1e-5, iso: 50.0 });
        assert!((p.relative - 0.1).abs() < 1e-12, "{p:?}");
        // −2 EV from the same time at ISO 200: 12.5 µs is within the range, so ISO 200 is kept.
        let p = plan_exposure(SensorExposure { time_s: 50e-6, iso: 200.0 }, 0.25, &limits()).unwrap();
        assert!((p.exposure.time_s - 12.5e-6).abs() < 1e-15 && p.exposure.iso == 200.0, "{p:?}");
        // −4 EV from 1/20 000 s at ISO 400: time 10 µs (reached ×0.2), ISO 400 × 0.3125 = 125.
        let p = plan_exposure(SensorExposure { time_s: 50e-6, iso: 400.0 }, 1.0 / 16.0, &limits()).unwrap();
        assert!((p.exposure.time_s - 1e-5).abs() < 1e-15 && (p.exposure.iso - 125.0).abs() < 1e-9, "{p:?}");
        assert!((p.relative - 1.0 / 16.0).abs() < 1e-12);
    }

    #[test]
    fn a_longer_exposure_lengthens_the_time_then_raises_the_sensitivity() {
        // +4 EV from 1/100 s at ISO 100: 0.16 s > 0.1 s, so 0.1 s and ISO 160.
        let p = plan_exposure(SensorExposure { time_s: 0.01, iso: 100.0 }, 16.0, &limits()).unwrap();
        assert!((p.exposure.time_s - 0.1).abs() < 1e-15 && (p.exposure.iso - 160.0).abs() < 1e-9, "{p:?}");
        assert!((p.relative - 16.0).abs() < 1e-9);
        // A current sensitivity outside the range (reported ISO 40) is brought into it first.
        let p = plan_exposure(SensorExposure { time_s: 0.001, iso: 40.0 }, 1.0, &limits()).unwrap();
        assert_eq!(p.exposure.iso, 50.0);
        assert!((p.exposure.time_s - 0.0008).abs() < 1e-15 && (p.relative - 1.0).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn bad_exposures_factors_and_ranges_are_errors_naming_them() {
        let e = plan_exposure(SensorExposure { time_s: 0.0, iso: 100.0 }, 0.5, &limits()).unwrap_err().to_string();
        assert!(e.contains("current exposure"), "{e}");
        let e = plan_exposure(DAYLIGHT, f64::NAN, &limits()).unwrap_err().to_string();
        assert!(e.contains("relative exposure NaN"), "{e}");
        assert!(plan_exposure(DAYLIGHT, -1.0, &limits()).is_err());
        assert!(ExposureLimits::new((0.0, 1.0), (50.0, 100.0)).unwrap_err().to_string().contains("exposure time range"));
        assert!(ExposureLimits::new((1e-5, 1.0), (100.0, 50.0)).unwrap_err().to_string().contains("sensitivity range"));
    }

    #[test]
    fn camera2_metadata_gives_limits_only_for_a_manual_sensor() {
        // AE modes OFF, ON, ON_AUTO_FLASH; capabilities BACKWARD_COMPATIBLE, MANUAL_SENSOR.
        let l = camera2_manual_limits(&[0, 1, 2], &[0, 1], &[10_000, 100_000_000], &[50, 3200]).unwrap();
        assert_eq!(l, limits());
        // No OFF mode, or no MANUAL_SENSOR (a LIMITED camera), or a missing range: none.
        assert_eq!(camera2_manual_limits(&[1, 2], &[0, 1], &[10_000, 100_000_000], &[50, 3200]), None);
        assert_eq!(camera2_manual_limits(&[0, 1], &[0, 6], &[10_000, 100_000_000], &[50, 3200]), None);
        assert_eq!(camera2_manual_limits(&[0, 1], &[0, 1], &[10_000], &[50, 3200]), None);
        assert_eq!(camera2_manual_limits(&[0, 1], &[0, 1], &[10_000, 100_000_000], &[3200, 50]), None);
        // A result: 1/500 s = 2 000 000 ns at ISO 100.
        assert_eq!(camera2_result_exposure(&[2_000_000], &[100]), Some(DAYLIGHT));
        assert_eq!(camera2_result_exposure(&[], &[100]), None);
        assert_eq!(camera2_result_exposure(&[2_000_000], &[0]), None);
    }

    #[test]
    fn a_frame_is_short_when_nearer_the_plan_in_stops() {
        let (stream, planned) = (DAYLIGHT.product(), DAYLIGHT.product() / 16.0);
        // The short frame, its time rounded up to a whole line (+3 %).
        assert!(nearer_short(planned * 1.03, planned, stream));
        // The stream's own frames and a frame halfway back at −1 EV are not.
        assert!(!nearer_short(stream, planned, stream));
        assert!(!nearer_short(stream * 0.5, planned, stream));
        // −3 EV is nearer −4 EV than 0 EV; −2 EV is the midpoint and not short.
        assert!(nearer_short(stream / 8.0, planned, stream));
        assert!(!nearer_short(stream / 4.0, planned, stream));
        assert!(!nearer_short(0.0, planned, stream));
    }

    #[test]
    fn exif_exposure_tells_the_short_frame_with_or_without_its_sensitivity() {
        // Bright sun: 1/20 000 s at ISO 400, −4 EV planned as 10 µs at ISO 125 (the test above).
        let plan = plan_exposure(SensorExposure { time_s: 50e-6, iso: 400.0 }, 1.0 / 16.0, &limits()).unwrap();
        assert!(frame_is_short(1e-5, Some(125.0), &plan));
        assert!(!frame_is_short(50e-6, Some(400.0), &plan));
        // The time alone: 10 µs against 50 µs (−2.3 EV of the 4 by time; ISO not said).
        assert!(frame_is_short(1e-5, None, &plan));
        assert!(!frame_is_short(40e-6, None, &plan));
        // A frame at the shortest time but still at ISO 400 is −2.3 EV: 1.7 stops from the plan,
        // 2.3 from the stream, so short.
        assert!(frame_is_short(1e-5, Some(400.0), &plan));
    }

    fn plan() -> ExposurePlan {
        plan_exposure(DAYLIGHT, 1.0 / 16.0, &limits()).unwrap()
    }

    #[test]
    fn a_request_goes_in_flight_arrives_and_ends_when_the_stream_is_back() {
        let mut s = OneShot::new();
        assert!(s.is_idle());
        let id = s.request(plan()).unwrap();
        assert_eq!(s.in_flight().map(|(i, _)| i), Some(id));
        assert_eq!(s.request(plan()), None, "one at a time");
        // Stream frames go on while it is in flight; nothing to take yet.
        assert_eq!(s.stream_frame(10.0, true), Action::None);
        assert!(s.take().is_none());
        // The short frame arrives, exposed 3 % longer than planned (a whole line): the real
        // factor is 1.03/16.
        let real = SensorExposure { time_s: 125e-6 * 1.03, iso: 100.0 };
        assert_eq!(s.arrived(id, frame(10.1), real), Action::Restore);
        // A frame still dark keeps it resuming; the first at the stream's exposure ends it.
        assert_eq!(s.stream_frame(10.13, false), Action::None);
        assert_eq!(s.request(plan()), None, "not before the stream is back and the frame taken");
        assert_eq!(s.stream_frame(10.16, true), Action::Resumed);
        match s.take() {
            Some(ShortFrame::Arrived(f)) => {
                assert_eq!(f.frame.t, 10.1);
                assert!((f.relative_exposure - 1.03 / 16.0).abs() < 1e-12, "{}", f.relative_exposure);
            }
            other => panic!("expected the frame, got {other:?}"),
        }
        assert!(s.is_idle());
        assert!(s.take().is_none(), "taken once");
        // The next request gets a new id; a late frame of the old one is dropped.
        let next = s.request(plan()).unwrap();
        assert_ne!(next, id);
        assert_eq!(s.arrived(id, frame(11.0), real), Action::None);
        assert_eq!(s.in_flight().map(|(i, _)| i), Some(next));
        // The frame first, its exposure later (Camera2's capture result): taken when both are in.
        assert_eq!(s.frame_arrived(next, frame(11.1)), Action::None);
        assert!(s.take().is_none());
        assert_eq!(s.exposure_reported(next, SensorExposure { time_s: 0.0, iso: 100.0 }), Action::None, "not an exposure");
        assert_eq!(s.exposure_reported(next, plan().exposure), Action::Restore);
        let Some(ShortFrame::Arrived(f)) = s.take() else { panic!("no frame") };
        assert_eq!(f.frame.t, 11.1);
        assert!((f.relative_exposure - 1.0 / 16.0).abs() < 1e-12);
        // The exposure first, then the frame.
        assert_eq!(s.stream_frame(11.2, true), Action::Resumed);
        let id = s.request(plan()).unwrap();
        assert_eq!(s.exposure_reported(id, real), Action::None);
        assert_eq!(s.frame_arrived(id, frame(12.0)), Action::Restore);
        let Some(ShortFrame::Arrived(f)) = s.take() else { panic!("no frame") };
        assert!((f.relative_exposure - 1.03 / 16.0).abs() < 1e-12);
    }

    #[test]
    fn a_lost_frame_times_out_and_the_stream_goes_on() {
        let mut s = OneShot::new();
        let id = s.request(plan()).unwrap();
        // The timeout counts from the first stream frame after the request, on the stream's clock.
        assert_eq!(s.stream_frame(3.0, true), Action::None);
        assert_eq!(s.stream_frame(3.0 + SHORT_FRAME_TIMEOUT_S, true), Action::None);
        assert_eq!(s.stream_frame(3.0 + SHORT_FRAME_TIMEOUT_S + 0.04, true), Action::Restore);
        assert!(matches!(s.take(), Some(ShortFrame::Lost)));
        // Its frame arriving now is dropped; the next stream frame ends the request.
        assert_eq!(s.arrived(id, frame(3.6), plan().exposure), Action::None);
        assert_eq!(s.stream_frame(3.6, true), Action::Resumed);
        assert!(s.is_idle());
        // A frame whose exposure is never reported is lost at the timeout too.
        let id = s.request(plan()).unwrap();
        assert_eq!(s.frame_arrived(id, frame(4.0)), Action::None);
        assert_eq!(s.stream_frame(4.0, true), Action::None);
        assert_eq!(s.stream_frame(4.0 + SHORT_FRAME_TIMEOUT_S + 0.04, true), Action::Restore);
        assert!(matches!(s.take(), Some(ShortFrame::Lost)));
        assert_eq!(s.exposure_reported(id, plan().exposure), Action::None, "too late");
        assert_eq!(s.stream_frame(4.6, true), Action::Resumed);
        // A failure reported by the platform loses it at once.
        let id = s.request(plan()).unwrap();
        assert_eq!(s.failed(id + 1), Action::None, "another request's failure");
        assert_eq!(s.failed(id), Action::Restore);
        assert!(matches!(s.take(), Some(ShortFrame::Lost)));
        // A stream that never comes back to its exposure is given up after the timeout too.
        assert_eq!(s.stream_frame(5.0, false), Action::None);
        assert_eq!(s.stream_frame(5.0 + SHORT_FRAME_TIMEOUT_S + 0.01, false), Action::Resumed);
        assert!(s.is_idle());
    }

    #[test]
    fn pausing_during_a_request_loses_it_and_restores_the_exposure() {
        let mut s = OneShot::new();
        assert_eq!(s.cancel(), Action::None, "nothing asked");
        let id = s.request(plan()).unwrap();
        assert_eq!(s.cancel(), Action::Restore);
        assert!(matches!(s.take(), Some(ShortFrame::Lost)));
        assert!(s.is_idle());
        // The paused camera's late frame is dropped.
        assert_eq!(s.arrived(id, frame(1.0), plan().exposure), Action::None);
        // Paused while resuming after the frame: the frame is kept, the exposure restored.
        let id = s.request(plan()).unwrap();
        assert_eq!(s.arrived(id, frame(2.0), plan().exposure), Action::Restore);
        assert_eq!(s.cancel(), Action::Restore);
        assert!(matches!(s.take(), Some(ShortFrame::Arrived(_))));
        assert!(s.is_idle());
    }
}
