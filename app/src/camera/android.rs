//! Android: the back camera through the NDK Camera2 API (`ACameraManager`, `ACameraDevice`, a
//! capture session repeating a preview request into an `AImageReader` of `YUV_420_888`
//! images). Compiled for Android only (checked by .ci/mobile-check.sh); the pure parts — chroma
//! layout, the stream's field of view, the image's turn — are in [`super::platform`] and tested
//! on the host.
//!
//! The live session reads frames through [`FrameSource::lend_next_frame`]: the newest image's
//! planes, as they lie in the camera's buffer (row and pixel strides), go to the GPU converter
//! ([`super::yuv::YuvConverter`]); no colour conversion happens on the CPU.
//! [`FrameSource::next_frame`] (an RGBA image on the CPU, for callers that need one) uses the
//! CPU reference conversion.
//!
//! Colour: Android's camera delivers `YUV_420_888` in the JFIF convention — BT.601 matrix, full
//! range (`ImageFormat.YUV_420_888` with the camera's default colour space; the NDK reports no
//! other for these images).
//!
//! The camera's intrinsics give the stream's field of view ([`CameraInfo::fov_deg`]):
//! `LENS_INTRINSIC_CALIBRATION` fx, fy over the active array, or else the first focal length
//! over the sensor's physical size, cropped to the stream's aspect ratio
//! ([`super::platform::stream_fov_deg`]). `SENSOR_ORIENTATION` and the display's rotation give
//! the quarter turns that make the image upright on the screen
//! ([`super::platform::back_camera_quarter_turns`]); the GPU pass turns it.
//!
//! **The short exposure frame** ([`FrameSource::request_exposure_frame`], the live sun frame):
//! the repeating request's capture results (`onCaptureCompleted`) give the stream's
//! `SENSOR_EXPOSURE_TIME` and `SENSOR_SENSITIVITY`; the short frame is one
//! `ACameraCaptureSession_capture` (a one-shot request between the repeating ones, which go on
//! by themselves) into the same reader with `CONTROL_AE_MODE` OFF and the time and sensitivity
//! of [`super::short_exposure::plan_exposure`] within the characteristics'
//! `SENSOR_INFO_EXPOSURE_TIME_RANGE` / `SENSOR_INFO_SENSITIVITY_RANGE` (cameras without
//! `MANUAL_SENSOR` take none). Its `onCaptureStarted` timestamp is its image's timestamp: the
//! frame loop reads every image in order (`AImageReader_acquireNextImage`), takes the one with
//! that timestamp aside (converted to RGBA on the CPU, turned upright, never lent as a preview
//! frame; used once its result says the exposure it really had) and lends the newest of the
//! others.
//! The request's states, timeouts and pause are [`super::short_exposure::OneShot`]'s. None of
//! this has run on a phone yet (docs/mobile.md, the manual test).

use super::platform::{CameraInfo, ChromaLayout, chroma_layout};
use super::short_exposure::{
    CAMERA2_AE_MODE_OFF, CAMERA2_CAPABILITY_MANUAL_SENSOR, ExposureLimits, OneShot, SensorExposure, ShortFrame, camera2_manual_limits,
    camera2_result_exposure, plan_exposure,
};
use super::yuv::{Chroma, Plane, YuvFrame, YuvMatrix, YuvRange, to_rgba_cpu, turn_image};
use super::{Frame, FrameImage, FrameSink, FrameSource};
use crate::pose::DisplayRotation;
use anyhow::{Context, Result, bail};
use ndk_sys as ffi;
use std::ffi::{CStr, CString, c_void};
use std::ptr::{NonNull, null_mut};
use std::sync::Mutex;
use std::sync::atomic::{AtomicI32, Ordering};

// ndk-sys declares the Camera2 and media functions but links their libraries only with features;
// name them here (android/build-apk.sh's stub libraries provide the same sonames).
#[link(name = "camera2ndk")]
unsafe extern "C" {}
#[link(name = "mediandk")]
unsafe extern "C" {}

/// Images the reader holds at most (one being read, one arriving, one spare).
const MAX_IMAGES: i32 = 3;
/// The device's state, written by its callbacks: 0 open, 1 disconnected, 2.. an error code + 2.
const OPEN: i32 = 0;
const DISCONNECTED: i32 = 1;

fn camera_ok(what: &str, s: ffi::camera_status_t) -> Result<()> {
    if s != ffi::camera_status_t::ACAMERA_OK {
        bail!("{what} failed (camera status {})", s.0);
    }
    Ok(())
}

fn media_ok(what: &str, s: ffi::media_status_t) -> Result<()> {
    if s != ffi::media_status_t::AMEDIA_OK {
        bail!("{what} failed (media status {})", s.0);
    }
    Ok(())
}

unsafe extern "C" fn on_disconnected(context: *mut c_void, _device: *mut ffi::ACameraDevice) {
    // SAFETY: the context is the Box<AtomicI32> owned by the Camera2, alive while the device is.
    unsafe { (*context.cast::<AtomicI32>()).store(DISCONNECTED, Ordering::Release) };
}

unsafe extern "C" fn on_error(context: *mut c_void, _device: *mut ffi::ACameraDevice, error: i32) {
    // SAFETY: as in on_disconnected.
    unsafe { (*context.cast::<AtomicI32>()).store(error.saturating_add(2), Ordering::Release) };
}

unsafe extern "C" fn session_state(_context: *mut c_void, _session: *mut ffi::ACameraCaptureSession) {}

// The Camera2 values the pure module declares are the NDK's.
const _: () = assert!(ffi::acamera_metadata_enum_acamera_control_ae_mode::ACAMERA_CONTROL_AE_MODE_OFF.0 == CAMERA2_AE_MODE_OFF as u32);
const _: () = assert!(
    ffi::acamera_metadata_enum_acamera_request_available_capabilities::ACAMERA_REQUEST_AVAILABLE_CAPABILITIES_MANUAL_SENSOR.0
        == CAMERA2_CAPABILITY_MANUAL_SENSOR as u32
);

/// What the capture callbacks (on the camera's threads) report to the frame loop.
#[derive(Default)]
struct CaptureReports {
    /// The stream's exposure and frame duration (ns), from the repeating request's latest result.
    stream: Option<SensorExposure>,
    frame_duration_ns: Option<i64>,
    /// The one-shot request in flight (None: nothing asked, or it was given up).
    short: Option<ShortReport>,
}

/// The one-shot request's reports.
#[derive(Clone, Copy)]
struct ShortReport {
    id: u64,
    /// `onCaptureStarted`'s timestamp: its image's.
    timestamp_ns: Option<i64>,
    /// Its result's exposure.
    exposure: Option<SensorExposure>,
    failed: bool,
}

type Reports = Mutex<CaptureReports>;

/// A metadata entry, when it is there and not empty.
///
/// # Safety
/// `meta` is a valid `ACameraMetadata`.
unsafe fn const_entry(meta: *const ffi::ACameraMetadata, tag: ffi::acamera_metadata_tag) -> Option<ffi::ACameraMetadata_const_entry> {
    // SAFETY: the caller's contract; the entry is written by the NDK before it is read.
    unsafe {
        let mut e: ffi::ACameraMetadata_const_entry = std::mem::zeroed();
        (ffi::ACameraMetadata_getConstEntry(meta, tag.0, &mut e) == ffi::camera_status_t::ACAMERA_OK && e.count > 0).then_some(e)
    }
}

/// An entry's values as a slice (empty when absent), valid while the metadata is.
///
/// # Safety
/// `meta` is a valid `ACameraMetadata` outliving the slice; `T` is the tag's declared type.
unsafe fn entry_slice<'a, T>(meta: *const ffi::ACameraMetadata, tag: ffi::acamera_metadata_tag) -> &'a [T] {
    // SAFETY: the caller's contract; every member of the data union is a pointer to `count` values.
    unsafe { const_entry(meta, tag).map_or(&[][..], |e| std::slice::from_raw_parts(e.data.u8_.cast::<T>(), e.count as usize)) }
}

/// The exposure a capture result reports.
///
/// # Safety
/// `result` is a valid capture result.
unsafe fn result_exposure(result: *const ffi::ACameraMetadata) -> Option<SensorExposure> {
    use ffi::acamera_metadata_tag as Tag;
    // SAFETY: the caller's contract; the tags' types are int64 and int32.
    unsafe {
        camera2_result_exposure(
            entry_slice(result, Tag::ACAMERA_SENSOR_EXPOSURE_TIME),
            entry_slice(result, Tag::ACAMERA_SENSOR_SENSITIVITY),
        )
    }
}

/// Run `f` on the reports behind a callback's context (a poisoned lock is taken as it is).
///
/// # Safety
/// `context` is the `Box<Reports>` owned by the Camera2, alive while its sessions are.
unsafe fn with_reports(context: *mut c_void, f: impl FnOnce(&mut CaptureReports)) {
    // SAFETY: the caller's contract.
    let reports = unsafe { &*context.cast::<Reports>() };
    f(&mut reports.lock().unwrap_or_else(|e| e.into_inner()));
}

unsafe extern "C" fn on_stream_result(
    context: *mut c_void,
    _session: *mut ffi::ACameraCaptureSession,
    _request: *mut ffi::ACaptureRequest,
    result: *const ffi::ACameraMetadata,
) {
    // SAFETY: the NDK's result is valid during the callback; the context as in with_reports.
    unsafe {
        let exposure = result_exposure(result);
        let duration = entry_slice::<i64>(result, ffi::acamera_metadata_tag::ACAMERA_SENSOR_FRAME_DURATION).first().copied();
        with_reports(context, |r| {
            if exposure.is_some() {
                r.stream = exposure;
            }
            if duration.is_some_and(|d| d > 0) {
                r.frame_duration_ns = duration;
            }
        });
    }
}

unsafe extern "C" fn on_short_started(
    context: *mut c_void,
    _session: *mut ffi::ACameraCaptureSession,
    _request: *const ffi::ACaptureRequest,
    timestamp: i64,
) {
    // SAFETY: as in with_reports.
    unsafe {
        with_reports(context, |r| {
            if let Some(s) = r.short.as_mut() {
                s.timestamp_ns = Some(timestamp);
            }
        })
    };
}

unsafe extern "C" fn on_short_result(
    context: *mut c_void,
    _session: *mut ffi::ACameraCaptureSession,
    _request: *mut ffi::ACaptureRequest,
    result: *const ffi::ACameraMetadata,
) {
    // SAFETY: as in on_stream_result.
    unsafe {
        let exposure = result_exposure(result);
        with_reports(context, |r| {
            if let Some(s) = r.short.as_mut() {
                s.exposure = exposure;
            }
        });
    }
}

unsafe extern "C" fn on_short_failed(
    context: *mut c_void,
    _session: *mut ffi::ACameraCaptureSession,
    _request: *mut ffi::ACaptureRequest,
    _failure: *mut ffi::ACameraCaptureFailure,
) {
    // SAFETY: as in with_reports.
    unsafe {
        with_reports(context, |r| {
            if let Some(s) = r.short.as_mut() {
                s.failed = true;
            }
        })
    };
}

/// Capture callbacks reporting into `reports`: the stream's results, or the one-shot request's
/// start, result and failure.
fn capture_callbacks(reports: &Reports, short: bool) -> Box<ffi::ACameraCaptureSession_captureCallbacks> {
    let context = (reports as *const Reports).cast_mut().cast();
    Box::new(ffi::ACameraCaptureSession_captureCallbacks {
        context,
        onCaptureStarted: if short { Some(on_short_started) } else { None },
        onCaptureProgressed: None,
        onCaptureCompleted: Some(if short { on_short_result } else { on_stream_result }),
        onCaptureFailed: if short { Some(on_short_failed) } else { None },
        onCaptureSequenceCompleted: None,
        onCaptureSequenceAborted: None,
        onCaptureBufferLost: None,
    })
}

/// The open device, its capture session and request (closed on pause, made again on resume).
/// Dropping it releases whatever exists, session before device (the NDK's order), so a start
/// that fails half-way leaks nothing.
struct Streaming {
    device: NonNull<ffi::ACameraDevice>,
    container: Option<NonNull<ffi::ACaptureSessionOutputContainer>>,
    output: Option<NonNull<ffi::ACaptureSessionOutput>>,
    target: Option<NonNull<ffi::ACameraOutputTarget>>,
    request: Option<NonNull<ffi::ACaptureRequest>>,
    /// The one-shot short exposure request (same target, `CONTROL_AE_MODE` OFF).
    short_request: Option<NonNull<ffi::ACaptureRequest>>,
    session: Option<NonNull<ffi::ACameraCaptureSession>>,
}

impl Drop for Streaming {
    fn drop(&mut self) {
        // SAFETY: every pointer was made by `Camera2::start` and is released exactly once here.
        unsafe {
            if let Some(s) = self.session {
                ffi::ACameraCaptureSession_stopRepeating(s.as_ptr());
                ffi::ACameraCaptureSession_close(s.as_ptr());
            }
            for r in [self.request, self.short_request].into_iter().flatten() {
                ffi::ACaptureRequest_free(r.as_ptr());
            }
            if let Some(t) = self.target {
                ffi::ACameraOutputTarget_free(t.as_ptr());
            }
            if let Some(c) = self.container {
                ffi::ACaptureSessionOutputContainer_free(c.as_ptr());
            }
            if let Some(o) = self.output {
                ffi::ACaptureSessionOutput_free(o.as_ptr());
            }
            ffi::ACameraDevice_close(self.device.as_ptr());
        }
    }
}

/// The back camera streaming YUV_420_888 images of a fixed size.
pub struct Camera2 {
    manager: NonNull<ffi::ACameraManager>,
    id: CString,
    reader: NonNull<ffi::AImageReader>,
    window: NonNull<ffi::ANativeWindow>,
    streaming: Option<Streaming>,
    state: Box<AtomicI32>,
    device_callbacks: Box<ffi::ACameraDevice_StateCallbacks>,
    session_callbacks: Box<ffi::ACameraCaptureSession_stateCallbacks>,
    info: CameraInfo,
    t0_ns: Option<i64>,
    /// Auto-exposure and auto white balance locked ([`FrameSource::lock_exposure`]); applied
    /// again when the camera restarts after a pause.
    locked: bool,
    /// The manual exposure's ranges; None: the camera cannot take a short exposure frame.
    manual: Option<ExposureLimits>,
    /// The capture callbacks' reports, and the callbacks of the repeating and one-shot requests.
    reports: Box<Reports>,
    stream_callbacks: Box<ffi::ACameraCaptureSession_captureCallbacks>,
    short_callbacks: Box<ffi::ACameraCaptureSession_captureCallbacks>,
    /// The short exposure frame's request state.
    shot: OneShot,
}

impl Camera2 {
    /// Open the first back-facing camera and stream `width`×`height` images (the size must be
    /// one the camera offers for YUV_420_888; 1280×720 and 640×480 exist on every camera), for
    /// a screen rotated by `display` (the app is landscape-only, so it does not change while
    /// the camera is open). Needs the CAMERA permission ([`crate::sensors::permissions`]).
    pub fn open(width: u32, height: u32, display: DisplayRotation) -> Result<Camera2> {
        // SAFETY: plain NDK calls; every returned pointer is checked before use and released in
        // Drop (or here on the error paths, through the partially built Camera2's Drop).
        unsafe {
            let manager = NonNull::new(ffi::ACameraManager_create()).context("ACameraManager_create returned null")?;
            let (id, optics) = match back_camera(manager) {
                Ok(v) => v,
                Err(e) => {
                    ffi::ACameraManager_delete(manager.as_ptr());
                    return Err(e);
                }
            };
            let info = match CameraInfo::new(optics.focal, optics.sensor_orientation_deg, (width, height), display) {
                Ok(v) => v,
                Err(e) => {
                    ffi::ACameraManager_delete(manager.as_ptr());
                    return Err(e);
                }
            };
            let mut reader = null_mut();
            let status = ffi::AImageReader_new(
                width as i32,
                height as i32,
                ffi::AIMAGE_FORMATS::AIMAGE_FORMAT_YUV_420_888.0 as i32,
                MAX_IMAGES,
                &mut reader,
            );
            if let Err(e) = media_ok("AImageReader_new", status) {
                ffi::ACameraManager_delete(manager.as_ptr());
                return Err(e);
            }
            let reader = NonNull::new(reader).context("AImageReader_new returned null")?;
            let mut window = null_mut();
            let status = ffi::AImageReader_getWindow(reader.as_ptr(), &mut window);
            let window = match (media_ok("AImageReader_getWindow", status), NonNull::new(window)) {
                (Ok(()), Some(w)) => w,
                (r, _) => {
                    ffi::AImageReader_delete(reader.as_ptr());
                    ffi::ACameraManager_delete(manager.as_ptr());
                    r?;
                    bail!("AImageReader_getWindow returned null");
                }
            };
            let mut state = Box::new(AtomicI32::new(OPEN));
            let context: *mut c_void = (&mut *state as *mut AtomicI32).cast();
            let device_callbacks =
                Box::new(ffi::ACameraDevice_StateCallbacks { context, onDisconnected: Some(on_disconnected), onError: Some(on_error) });
            let session_callbacks = Box::new(ffi::ACameraCaptureSession_stateCallbacks {
                context: null_mut(),
                onClosed: Some(session_state),
                onReady: Some(session_state),
                onActive: Some(session_state),
            });
            let reports: Box<Reports> = Box::default();
            let (stream_callbacks, short_callbacks) = (capture_callbacks(&reports, false), capture_callbacks(&reports, true));
            let mut camera = Camera2 {
                manager,
                id,
                reader,
                window,
                streaming: None,
                state,
                device_callbacks,
                session_callbacks,
                info,
                t0_ns: None,
                locked: false,
                manual: optics.manual,
                reports,
                stream_callbacks,
                short_callbacks,
                shot: OneShot::new(),
            };
            camera.start()?;
            Ok(camera)
        }
    }

    /// The camera's field of view, image size and turn.
    pub fn info(&self) -> CameraInfo {
        self.info
    }

    /// Open the device and start the repeating preview request into the reader.
    fn start(&mut self) -> Result<()> {
        if self.streaming.is_some() {
            return Ok(());
        }
        self.state.store(OPEN, Ordering::Release);
        // SAFETY: the manager, reader window and callback boxes live as long as self; every
        // object made here is owned by `Streaming`, whose Drop releases it.
        unsafe {
            let mut device = null_mut();
            camera_ok(
                "ACameraManager_openCamera",
                ffi::ACameraManager_openCamera(self.manager.as_ptr(), self.id.as_ptr(), &mut *self.device_callbacks, &mut device),
            )?;
            let device = NonNull::new(device).context("ACameraManager_openCamera returned null")?;
            let mut s =
                Streaming { device, container: None, output: None, target: None, request: None, short_request: None, session: None };
            let mut container = null_mut();
            camera_ok("ACaptureSessionOutputContainer_create", ffi::ACaptureSessionOutputContainer_create(&mut container))?;
            let container = *s.container.insert(NonNull::new(container).context("null output container")?);
            let mut output = null_mut();
            camera_ok("ACaptureSessionOutput_create", ffi::ACaptureSessionOutput_create(self.window.as_ptr(), &mut output))?;
            let output = *s.output.insert(NonNull::new(output).context("null session output")?);
            camera_ok("ACaptureSessionOutputContainer_add", ffi::ACaptureSessionOutputContainer_add(container.as_ptr(), output.as_ptr()))?;
            let mut target = null_mut();
            camera_ok("ACameraOutputTarget_create", ffi::ACameraOutputTarget_create(self.window.as_ptr(), &mut target))?;
            let target = *s.target.insert(NonNull::new(target).context("null output target")?);
            let mut request = null_mut();
            camera_ok(
                "ACameraDevice_createCaptureRequest",
                ffi::ACameraDevice_createCaptureRequest(
                    device.as_ptr(),
                    ffi::ACameraDevice_request_template::TEMPLATE_PREVIEW,
                    &mut request,
                ),
            )?;
            let request = *s.request.insert(NonNull::new(request).context("null capture request")?);
            camera_ok("ACaptureRequest_addTarget", ffi::ACaptureRequest_addTarget(request.as_ptr(), target.as_ptr()))?;
            set_controls_lock(request, self.locked)?;
            if self.manual.is_some() {
                let mut short = null_mut();
                camera_ok(
                    "ACameraDevice_createCaptureRequest (short exposure)",
                    ffi::ACameraDevice_createCaptureRequest(
                        device.as_ptr(),
                        ffi::ACameraDevice_request_template::TEMPLATE_PREVIEW,
                        &mut short,
                    ),
                )?;
                let short = *s.short_request.insert(NonNull::new(short).context("null short exposure request")?);
                camera_ok("ACaptureRequest_addTarget (short exposure)", ffi::ACaptureRequest_addTarget(short.as_ptr(), target.as_ptr()))?;
                let off = [CAMERA2_AE_MODE_OFF];
                camera_ok(
                    "ACaptureRequest_setEntry_u8(CONTROL_AE_MODE)",
                    ffi::ACaptureRequest_setEntry_u8(short.as_ptr(), ffi::acamera_metadata_tag::ACAMERA_CONTROL_AE_MODE.0, 1, off.as_ptr()),
                )?;
            }
            let mut session = null_mut();
            camera_ok(
                "ACameraDevice_createCaptureSession",
                ffi::ACameraDevice_createCaptureSession(device.as_ptr(), container.as_ptr(), &*self.session_callbacks, &mut session),
            )?;
            let session = *s.session.insert(NonNull::new(session).context("null capture session")?);
            let mut requests = [request.as_ptr()];
            camera_ok(
                "ACameraCaptureSession_setRepeatingRequest",
                ffi::ACameraCaptureSession_setRepeatingRequest(
                    session.as_ptr(),
                    &mut *self.stream_callbacks,
                    1,
                    requests.as_mut_ptr(),
                    null_mut(),
                ),
            )?;
            self.streaming = Some(s);
        }
        Ok(())
    }

    /// Lock or release auto-exposure and auto white balance: `CONTROL_AE_LOCK` and
    /// `CONTROL_AWB_LOCK` on the preview request, which is then repeated anew.
    fn set_locked(&mut self, lock: bool) -> Result<()> {
        self.locked = lock;
        let Some(s) = &self.streaming else { return Ok(()) };
        let (Some(request), Some(session)) = (s.request, s.session) else { return Ok(()) };
        // SAFETY: the request and session are alive while `streaming` holds them.
        unsafe {
            set_controls_lock(request, lock)?;
            let mut requests = [request.as_ptr()];
            camera_ok(
                "ACameraCaptureSession_setRepeatingRequest",
                ffi::ACameraCaptureSession_setRepeatingRequest(
                    session.as_ptr(),
                    &mut *self.stream_callbacks,
                    1,
                    requests.as_mut_ptr(),
                    null_mut(),
                ),
            )
        }
    }

    /// Stop the repeating request and close the session and the device (the camera is then
    /// free for other apps and draws no power). A short exposure frame in flight is lost.
    fn stop(&mut self) {
        self.streaming = None;
        self.shot.cancel();
        self.reports().short = None;
    }

    fn reports(&self) -> std::sync::MutexGuard<'_, CaptureReports> {
        self.reports.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Submit the one-shot short exposure request at `relative_exposure` × the stream's last
    /// reported exposure; false when the camera has no manual exposure, is paused, has reported
    /// no exposure yet, or a request is not finished.
    fn request_short(&mut self, relative_exposure: f32) -> Result<bool> {
        let Some(limits) = self.manual else { return Ok(false) };
        let Some((Some(session), Some(request))) = self.streaming.as_ref().map(|s| (s.session, s.short_request)) else { return Ok(false) };
        let (stream, frame_duration_ns) = {
            let r = self.reports();
            (r.stream, r.frame_duration_ns)
        };
        let Some(stream) = stream else { return Ok(false) };
        let plan = plan_exposure(stream, f64::from(relative_exposure), &limits)?;
        let Some(id) = self.shot.request(plan) else { return Ok(false) };
        self.reports().short = Some(ShortReport { id, timestamp_ns: None, exposure: None, failed: false });
        let time_ns = [(plan.exposure.time_s * 1e9).round() as i64];
        let iso = [plan.exposure.iso.round() as i32];
        // SAFETY: the request and session are alive while `streaming` holds them; the entries
        // are the tags' declared types and counts; the NDK copies the request at submission.
        let submitted = unsafe {
            use ffi::acamera_metadata_tag as Tag;
            let r = request.as_ptr();
            camera_ok(
                "ACaptureRequest_setEntry_i64(SENSOR_EXPOSURE_TIME)",
                ffi::ACaptureRequest_setEntry_i64(r, Tag::ACAMERA_SENSOR_EXPOSURE_TIME.0, 1, time_ns.as_ptr()),
            )
            .and_then(|()| {
                camera_ok(
                    "ACaptureRequest_setEntry_i32(SENSOR_SENSITIVITY)",
                    ffi::ACaptureRequest_setEntry_i32(r, Tag::ACAMERA_SENSOR_SENSITIVITY.0, 1, iso.as_ptr()),
                )
            })
            .and_then(|()| match frame_duration_ns {
                // The stream's frame duration, so the short frame keeps its pace.
                Some(d) => camera_ok(
                    "ACaptureRequest_setEntry_i64(SENSOR_FRAME_DURATION)",
                    ffi::ACaptureRequest_setEntry_i64(r, Tag::ACAMERA_SENSOR_FRAME_DURATION.0, 1, [d].as_ptr()),
                ),
                None => Ok(()),
            })
            .and_then(|()| {
                let mut requests = [r];
                camera_ok(
                    "ACameraCaptureSession_capture",
                    ffi::ACameraCaptureSession_capture(session.as_ptr(), &mut *self.short_callbacks, 1, requests.as_mut_ptr(), null_mut()),
                )
            })
        };
        if let Err(e) = submitted {
            self.shot.failed(id);
            self.reports().short = None;
            return Err(e.context("the short exposure frame for the sun"));
        }
        Ok(true)
    }

    /// The frame loop's side of the one-shot request after the reader was drained: the failure
    /// or the exposure its result reported (the frame is taken once both it and its exposure are
    /// in, [`OneShot::frame_arrived`]).
    fn settle_short(&mut self) {
        let report = self.reports().short;
        let Some(report) = report else { return };
        if report.failed {
            self.shot.failed(report.id);
        }
        if let Some(exposure) = report.exposure {
            self.shot.exposure_reported(report.id, exposure);
        }
        if self.shot.in_flight().is_none() {
            self.reports().short = None;
        }
    }

    /// Call `f` with the newest image (seconds since the first image, planes) and release it;
    /// `Ok(None)` when no new image has arrived.
    pub fn latest<T>(&mut self, f: impl FnOnce(f64, &YuvFrame) -> Result<T>) -> Result<Option<T>> {
        match self.state.load(Ordering::Acquire) {
            OPEN => {}
            DISCONNECTED => bail!("the camera was disconnected (another app took it?)"),
            e => bail!("the camera device failed (ACameraDevice error {})", e - 2),
        }
        if self.streaming.is_none() {
            bail!("the camera is paused");
        }
        // SAFETY: the reader lives as long as self; every image acquired is deleted on every path
        // below, and the plane slices do not outlive it (they are only lent to `f`).
        unsafe {
            // Every image that came, in order: the short exposure frame is kept aside, the
            // newest of the others is lent.
            let mut newest: Option<NonNull<ffi::AImage>> = None;
            let drained = loop {
                let mut image = null_mut();
                let status = ffi::AImageReader_acquireNextImage(self.reader.as_ptr(), &mut image);
                if status == ffi::media_status_t::AMEDIA_IMGREADER_NO_BUFFER_AVAILABLE {
                    break Ok(());
                }
                if let Err(e) = media_ok("AImageReader_acquireNextImage", status) {
                    break Err(e);
                }
                let Some(image) = NonNull::new(image) else { break Err(anyhow::anyhow!("AImageReader_acquireNextImage returned null")) };
                let mut ts = 0;
                let ts = (ffi::AImage_getTimestamp(image.as_ptr(), &mut ts) == ffi::media_status_t::AMEDIA_OK).then_some(ts);
                // The one-shot request's image: its `onCaptureStarted` timestamp (reported at the
                // start of its exposure, before its image can be read out).
                let short = self.reports().short.and_then(|s| s.timestamp_ns.map(|t| (s.id, t)));
                match short {
                    Some((id, short_ts)) if ts == Some(short_ts) => {
                        let turns = self.info.quarter_turns;
                        let frame =
                            read_image(image, &mut self.t0_ns, |t, yuv| Ok(Frame { image: turn_image(&to_rgba_cpu(yuv)?, turns), t }));
                        ffi::AImage_delete(image.as_ptr());
                        match frame {
                            Ok(frame) => {
                                self.shot.frame_arrived(id, frame);
                            }
                            Err(_) => {
                                self.shot.failed(id);
                            }
                        }
                    }
                    _ => {
                        if let Some(old) = newest.replace(image) {
                            ffi::AImage_delete(old.as_ptr());
                        }
                    }
                }
            };
            self.settle_short();
            if let Err(e) = drained {
                if let Some(image) = newest {
                    ffi::AImage_delete(image.as_ptr());
                }
                return Err(e);
            }
            let Some(image) = newest else { return Ok(None) };
            let mut frame_t = None;
            let result = read_image(image, &mut self.t0_ns, |t, frame| {
                frame_t = Some(t);
                f(t, frame)
            });
            ffi::AImage_delete(image.as_ptr());
            if let Some(t) = frame_t {
                self.shot.stream_frame(t, true);
                self.settle_short();
            }
            result.map(Some)
        }
    }
}

/// Lend one image's planes to `f`.
///
/// # Safety
/// `image` is a valid, acquired `AImage` of format YUV_420_888.
unsafe fn read_image<T>(image: NonNull<ffi::AImage>, t0_ns: &mut Option<i64>, f: impl FnOnce(f64, &YuvFrame) -> Result<T>) -> Result<T> {
    // SAFETY: the caller's contract; the slices are valid until the image is deleted.
    unsafe {
        let img = image.as_ptr();
        let (mut w, mut h, mut ts) = (0, 0, 0);
        media_ok("AImage_getWidth", ffi::AImage_getWidth(img, &mut w))?;
        media_ok("AImage_getHeight", ffi::AImage_getHeight(img, &mut h))?;
        media_ok("AImage_getTimestamp", ffi::AImage_getTimestamp(img, &mut ts))?;
        let plane = |i: i32| -> Result<(*mut u8, usize, usize, i32)> {
            let (mut data, mut len, mut row, mut px) = (null_mut(), 0, 0, 0);
            media_ok("AImage_getPlaneData", ffi::AImage_getPlaneData(img, i, &mut data, &mut len))?;
            media_ok("AImage_getPlaneRowStride", ffi::AImage_getPlaneRowStride(img, i, &mut row))?;
            media_ok("AImage_getPlanePixelStride", ffi::AImage_getPlanePixelStride(img, i, &mut px))?;
            if data.is_null() || len <= 0 || row <= 0 {
                bail!("YUV_420_888 plane {i} is empty");
            }
            Ok((data, len as usize, row as usize, px))
        };
        let (y, y_len, y_row, _) = plane(0)?;
        let (u, u_len, u_row, px) = plane(1)?;
        let (v, v_len, v_row, _) = plane(2)?;
        let luma = Plane { data: std::slice::from_raw_parts(y, y_len), row_stride: y_row };
        let chroma = match chroma_layout(u as usize, v as usize, px)? {
            ChromaLayout::Planar => Chroma::Planar {
                cb: Plane { data: std::slice::from_raw_parts(u, u_len), row_stride: u_row },
                cr: Plane { data: std::slice::from_raw_parts(v, v_len), row_stride: v_row },
            },
            // The interleaved plane starts at the first of the two and covers both.
            ChromaLayout::Nv12 => {
                Chroma::Interleaved { plane: Plane { data: std::slice::from_raw_parts(u, v_len + 1), row_stride: u_row }, cb_first: true }
            }
            ChromaLayout::Nv21 => {
                Chroma::Interleaved { plane: Plane { data: std::slice::from_raw_parts(v, u_len + 1), row_stride: v_row }, cb_first: false }
            }
        };
        // Camera YUV_420_888 is JFIF: BT.601 matrix, full range.
        let frame = YuvFrame { width: w as u32, height: h as u32, luma, chroma, matrix: YuvMatrix::Bt601, range: YuvRange::Full };
        let t0 = *t0_ns.get_or_insert(ts);
        f((ts - t0) as f64 * 1e-9, &frame)
    }
}

/// The first back camera's stream as the screen shows it ([`CameraInfo`]), read from its
/// characteristics (no CAMERA permission needed, but Android 10+ may hide
/// `LENS_INTRINSIC_CALIBRATION` until it is granted: the focal length and sensor size are used
/// then) for a stream of `size` on a screen rotated by `display`.
pub fn query_back_camera(size: (u32, u32), display: DisplayRotation) -> Result<CameraInfo> {
    // SAFETY: the manager is checked for null and deleted before returning.
    unsafe {
        let manager = NonNull::new(ffi::ACameraManager_create()).context("ACameraManager_create returned null")?;
        let optics = back_camera(manager);
        ffi::ACameraManager_delete(manager.as_ptr());
        let optics = optics?.1;
        CameraInfo::new(optics.focal, optics.sensor_orientation_deg, size, display)
    }
}

/// What the camera's characteristics say about its optics.
struct Optics {
    /// Focal lengths fx, fy and the sensor array (width, height) in the same unit (pixels of the
    /// active array, or mm of the physical sensor).
    focal: Option<(f64, f64, (f64, f64))>,
    /// `SENSOR_ORIENTATION`, degrees clockwise.
    sensor_orientation_deg: i32,
    /// The manual exposure's ranges, when the camera takes a manual exposure.
    manual: Option<ExposureLimits>,
}

/// The first back-facing camera's id and optics.
///
/// # Safety
/// `manager` is a valid `ACameraManager`.
unsafe fn back_camera(manager: NonNull<ffi::ACameraManager>) -> Result<(CString, Optics)> {
    // SAFETY: the caller's contract; the id list and metadata are freed before returning.
    unsafe {
        let mut list = null_mut();
        camera_ok("ACameraManager_getCameraIdList", ffi::ACameraManager_getCameraIdList(manager.as_ptr(), &mut list))?;
        let list = NonNull::new(list).context("ACameraManager_getCameraIdList returned null")?;
        let l = list.as_ref();
        let ids: Vec<CString> = (0..l.numCameras.max(0) as usize).map(|i| CStr::from_ptr(*l.cameraIds.add(i)).to_owned()).collect();
        ffi::ACameraManager_deleteCameraIdList(list.as_ptr());
        for id in ids {
            let mut meta = null_mut();
            if ffi::ACameraManager_getCameraCharacteristics(manager.as_ptr(), id.as_ptr(), &mut meta) != ffi::camera_status_t::ACAMERA_OK
                || meta.is_null()
            {
                continue;
            }
            let entry = |tag: ffi::acamera_metadata_tag| const_entry(meta, tag);
            let back = entry(ffi::acamera_metadata_tag::ACAMERA_LENS_FACING)
                .is_some_and(|e| u32::from(*e.data.u8_) == ffi::acamera_metadata_enum_acamera_lens_facing::ACAMERA_LENS_FACING_BACK.0);
            if !back {
                ffi::ACameraMetadata_free(meta);
                continue;
            }
            let calibrated = match (
                entry(ffi::acamera_metadata_tag::ACAMERA_LENS_INTRINSIC_CALIBRATION),
                entry(ffi::acamera_metadata_tag::ACAMERA_SENSOR_INFO_ACTIVE_ARRAY_SIZE),
            ) {
                // [fx, fy, cx, cy, s] over the active array [left, top, right, bottom].
                (Some(cal), Some(active)) if cal.count >= 5 && active.count >= 4 => {
                    let (fx, fy) = (f64::from(*cal.data.f), f64::from(*cal.data.f.add(1)));
                    let width = f64::from(*active.data.i32_.add(2) - *active.data.i32_);
                    let height = f64::from(*active.data.i32_.add(3) - *active.data.i32_.add(1));
                    (fx > 0.0 && fy > 0.0).then_some((fx, fy, (width, height)))
                }
                _ => None,
            };
            let focal = calibrated.or_else(|| {
                match (
                    entry(ffi::acamera_metadata_tag::ACAMERA_LENS_INFO_AVAILABLE_FOCAL_LENGTHS),
                    entry(ffi::acamera_metadata_tag::ACAMERA_SENSOR_INFO_PHYSICAL_SIZE),
                ) {
                    (Some(f), Some(size)) if size.count >= 2 => {
                        let f = f64::from(*f.data.f);
                        Some((f, f, (f64::from(*size.data.f), f64::from(*size.data.f.add(1)))))
                    }
                    _ => None,
                }
            });
            // Back cameras are mostly mounted at 90°; 0 when the camera does not say.
            let sensor_orientation_deg = entry(ffi::acamera_metadata_tag::ACAMERA_SENSOR_ORIENTATION).map_or(0, |e| *e.data.i32_);
            let manual = {
                use ffi::acamera_metadata_tag as Tag;
                camera2_manual_limits(
                    entry_slice(meta, Tag::ACAMERA_CONTROL_AE_AVAILABLE_MODES),
                    entry_slice(meta, Tag::ACAMERA_REQUEST_AVAILABLE_CAPABILITIES),
                    entry_slice(meta, Tag::ACAMERA_SENSOR_INFO_EXPOSURE_TIME_RANGE),
                    entry_slice(meta, Tag::ACAMERA_SENSOR_INFO_SENSITIVITY_RANGE),
                )
            };
            ffi::ACameraMetadata_free(meta);
            return Ok((id, Optics { focal, sensor_orientation_deg, manual }));
        }
        bail!("this device has no back-facing camera")
    }
}

impl Camera2 {
    /// Wait for an image newer than the last one (polling the reader every millisecond; an
    /// error after 2 s without one) and lend it to `f`.
    fn wait_for_image<T>(&mut self, mut f: impl FnMut(f64, &YuvFrame) -> Result<T>) -> Result<T> {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
        loop {
            if let Some(v) = self.latest(&mut f)? {
                return Ok(v);
            }
            if std::time::Instant::now() > deadline {
                bail!("no camera image for 2 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }
}

impl FrameSource for Camera2 {
    /// The newest image as RGBA on the CPU (the reference conversion, turned upright); the live
    /// session uses [`FrameSource::lend_next_frame`] instead.
    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let turns = self.info.quarter_turns;
        self.wait_for_image(|t, yuv| Ok(Frame { image: turn_image(&to_rgba_cpu(yuv)?, turns), t })).map(Some)
    }

    /// The newest image's planes, lent as they lie in the camera's buffer, with the turn that
    /// makes them upright.
    fn lend_next_frame(&mut self, sink: &mut FrameSink<'_>) -> Result<bool> {
        let quarter_turns = self.info.quarter_turns;
        self.wait_for_image(|t, frame| sink(t, FrameImage::Yuv { frame: *frame, quarter_turns }))?;
        Ok(true)
    }

    fn pause(&mut self) -> Result<()> {
        self.stop();
        Ok(())
    }

    fn resume(&mut self) -> Result<()> {
        self.start()
    }

    fn lock_exposure(&mut self, lock: bool) -> Result<bool> {
        self.set_locked(lock)?;
        Ok(lock)
    }

    /// One `ACameraCaptureSession_capture` with `CONTROL_AE_MODE` OFF (module docs).
    fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
        self.request_short(relative_exposure)
    }

    fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
        Ok(self.shot.take())
    }
}

/// Set `CONTROL_AE_LOCK` and `CONTROL_AWB_LOCK` on a capture request (ON locks both at their
/// current values; the camera keeps adapting with OFF).
///
/// # Safety
/// `request` must be a live capture request.
unsafe fn set_controls_lock(request: NonNull<ffi::ACaptureRequest>, lock: bool) -> Result<()> {
    use ffi::acamera_metadata_enum_acamera_control_ae_lock as Ae;
    use ffi::acamera_metadata_enum_acamera_control_awb_lock as Awb;
    let ae = [(if lock { Ae::ACAMERA_CONTROL_AE_LOCK_ON } else { Ae::ACAMERA_CONTROL_AE_LOCK_OFF }).0 as u8];
    let awb = [(if lock { Awb::ACAMERA_CONTROL_AWB_LOCK_ON } else { Awb::ACAMERA_CONTROL_AWB_LOCK_OFF }).0 as u8];
    // SAFETY: the caller's contract; one u8 entry each, as the tags are declared.
    unsafe {
        camera_ok(
            "ACaptureRequest_setEntry_u8(CONTROL_AE_LOCK)",
            ffi::ACaptureRequest_setEntry_u8(request.as_ptr(), ffi::acamera_metadata_tag::ACAMERA_CONTROL_AE_LOCK.0, 1, ae.as_ptr()),
        )?;
        camera_ok(
            "ACaptureRequest_setEntry_u8(CONTROL_AWB_LOCK)",
            ffi::ACaptureRequest_setEntry_u8(request.as_ptr(), ffi::acamera_metadata_tag::ACAMERA_CONTROL_AWB_LOCK.0, 1, awb.as_ptr()),
        )
    }
}

impl Drop for Camera2 {
    fn drop(&mut self) {
        self.stop();
        // SAFETY: made in `open`, released once here (the reader owns its window).
        unsafe {
            ffi::AImageReader_delete(self.reader.as_ptr());
            ffi::ACameraManager_delete(self.manager.as_ptr());
        }
    }
}
