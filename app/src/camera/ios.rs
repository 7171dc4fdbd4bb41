//! iOS: the back camera through AVFoundation (`objc2-av-foundation`): an `AVCaptureSession`
//! with the back wide-angle camera as input and an `AVCaptureVideoDataOutput` delivering
//! bi-planar 4:2:0 buffers ('420f': NV12, full range) to a delegate on a serial dispatch queue.
//! Compiled for iOS only (checked by .ci/mobile-check.sh); the pure parts — the buffer's
//! Y'CbCr standard and range, the field of view — are in [`super::platform`] and tested on the
//! host.
//!
//! The delegate keeps the newest `CVPixelBuffer` (retained, no copy); the live session takes it
//! through [`FrameSource::lend_next_frame`]: the planes, locked read-only, go to the GPU
//! converter as they lie in the buffer (row strides included). The Y'CbCr matrix comes from the
//! buffer's `kCVImageBufferYCbCrMatrixKey` attachment, the range from its pixel format
//! ([`super::platform::ios_yuv_format`]). The field of view is the active format's
//! `videoFieldOfView` (horizontal, degrees), turned into the vertical one for the image's
//! aspect ([`super::platform::vfov_from_hfov_deg`]). The buffers arrive in the sensor's
//! landscape orientation, upright for the landscape-right interface the app is locked to
//! (ios/Info.plist), so no turn is needed.
//!
//! **The short exposure frame** ([`FrameSource::request_exposure_frame`], the live sun frame):
//! `setExposureModeCustomWithDuration:ISO:completionHandler:` at the device's current
//! `exposureDuration` and `ISO` × the factor ([`super::short_exposure::plan_exposure`] within
//! the active format's `minExposureDuration`..`maxExposureDuration` and `minISO`..`maxISO`).
//! While it is asked for, the delegate reads each buffer's Exif attachment (`ExposureTime`,
//! `ISOSpeedRatings`): the first buffer at the short exposure
//! ([`super::short_exposure::frame_is_short`]) is the short frame, kept aside (never lent as a
//! preview frame) and converted to RGBA on the CPU; the exposure goes back to the stream's values
//! (custom, at once), the buffers still short are hidden, and at the first one back at the
//! stream's exposure the device returns to `ContinuousAutoExposure` — or stays at those values
//! while a capture holds the lock. The request's states, timeouts and pause are
//! [`super::short_exposure::OneShot`]'s. None of this has run on a phone yet (docs/mobile.md).
//!
//! The first use of the camera shows the system's permission prompt (Info.plist's
//! `NSCameraUsageDescription`); a refusal makes [`IosCamera::open`] fail with a message saying
//! where to grant it.

use super::platform::{ios_yuv_format, vfov_from_hfov_deg};
use super::short_exposure::{Action, ExposureLimits, ExposurePlan, OneShot, SensorExposure, ShortFrame, frame_is_short, plan_exposure};
use super::yuv::{Chroma, Plane, YuvFrame, to_rgba_cpu};
use super::{Frame, FrameImage, FrameSink, FrameSource};
use anyhow::{Context, Result, bail};
use dispatch2::{DispatchQueue, DispatchRetained};
use objc2::rc::Retained;
use objc2::runtime::{AnyObject, NSObject, NSObjectProtocol, ProtocolObject};
use objc2::{AllocAnyThread, DefinedClass, define_class, msg_send};
use objc2_av_foundation::{
    AVCaptureConnection, AVCaptureDevice, AVCaptureDeviceInput, AVCaptureDevicePosition, AVCaptureDeviceTypeBuiltInWideAngleCamera,
    AVCaptureExposureMode, AVCaptureOutput, AVCaptureSession, AVCaptureSessionPreset1280x720, AVCaptureVideoDataOutput,
    AVCaptureVideoDataOutputSampleBufferDelegate, AVCaptureWhiteBalanceMode, AVMediaTypeVideo,
};
use objc2_core_media::{CMSampleBuffer, CMTime as AvTime, CMTimeFlags};
use objc2_foundation::{NSDictionary, NSNumber, NSString};
use std::ffi::c_void;
use std::sync::{Arc, Mutex};

/// The image size asked of the camera (`AVCaptureSessionPreset1280x720`).
pub const SIZE: (u32, u32) = (1280, 720);

// CoreFoundation / CoreMedia / CoreVideo C functions (stable C API, declared here with raw
// pointers rather than through more objc2 framework crates).
#[repr(C)]
#[derive(Clone, Copy)]
struct CMTime {
    value: i64,
    timescale: i32,
    flags: u32,
    epoch: i64,
}

#[link(name = "CoreFoundation", kind = "framework")]
unsafe extern "C" {
    fn CFRetain(cf: *const c_void) -> *const c_void;
    fn CFRelease(cf: *const c_void);
    fn CFDictionaryGetValue(dict: *const c_void, key: *const c_void) -> *const c_void;
    fn CFArrayGetCount(array: *const c_void) -> isize;
    fn CFArrayGetValueAtIndex(array: *const c_void, index: isize) -> *const c_void;
    fn CFNumberGetValue(number: *const c_void, number_type: isize, value: *mut c_void) -> bool;
    fn CFGetTypeID(cf: *const c_void) -> usize;
    fn CFNumberGetTypeID() -> usize;
    fn CFArrayGetTypeID() -> usize;
}

/// `kCFNumberFloat64Type`.
const CF_NUMBER_FLOAT64: isize = 6;

#[link(name = "CoreMedia", kind = "framework")]
unsafe extern "C" {
    fn CMSampleBufferGetImageBuffer(sbuf: *const c_void) -> *mut c_void;
    fn CMSampleBufferGetPresentationTimeStamp(sbuf: *const c_void) -> CMTime;
    fn CMGetAttachment(target: *const c_void, key: *const c_void, mode: *mut u32) -> *const c_void;
}

#[link(name = "CoreVideo", kind = "framework")]
unsafe extern "C" {
    static kCVPixelBufferPixelFormatTypeKey: *const c_void;
    static kCVImageBufferYCbCrMatrixKey: *const c_void;
    fn CVPixelBufferLockBaseAddress(buffer: *mut c_void, flags: u64) -> i32;
    fn CVPixelBufferUnlockBaseAddress(buffer: *mut c_void, flags: u64) -> i32;
    fn CVPixelBufferGetPixelFormatType(buffer: *mut c_void) -> u32;
    fn CVPixelBufferGetWidth(buffer: *mut c_void) -> usize;
    fn CVPixelBufferGetHeight(buffer: *mut c_void) -> usize;
    fn CVPixelBufferGetPlaneCount(buffer: *mut c_void) -> usize;
    fn CVPixelBufferGetBaseAddressOfPlane(buffer: *mut c_void, plane: usize) -> *mut c_void;
    fn CVPixelBufferGetBytesPerRowOfPlane(buffer: *mut c_void, plane: usize) -> usize;
    fn CVPixelBufferGetHeightOfPlane(buffer: *mut c_void, plane: usize) -> usize;
    fn CVBufferGetAttachment(buffer: *mut c_void, key: *const c_void, mode: *mut u32) -> *const c_void;
}

const LOCK_READ_ONLY: u64 = 1;

/// A retained `CVPixelBuffer` and its presentation time (seconds).
struct PixelBuffer {
    ptr: *mut c_void,
    t: f64,
    /// At a short exposure asked for (hidden from the preview).
    short: bool,
}

// SAFETY: a CVPixelBuffer is a reference-counted CoreFoundation object, safe to retain, release
// and read (locked) from any thread.
unsafe impl Send for PixelBuffer {}

impl Drop for PixelBuffer {
    fn drop(&mut self) {
        // SAFETY: retained once in the delegate, released once here.
        unsafe { CFRelease(self.ptr) };
    }
}

/// What the delegate received, shared with the frame loop.
#[derive(Default)]
struct Delivered {
    /// The newest buffer.
    latest: Option<PixelBuffer>,
    /// While a short exposure frame is asked for or the stream is coming back from it: the
    /// request's id and plan, and whether its frame was found.
    watch: Option<(u64, ExposurePlan, bool)>,
    /// The short frame: the request's id, the buffer, its exposure from the Exif attachment.
    short: Option<(u64, PixelBuffer, SensorExposure)>,
}

type Latest = Arc<Mutex<Delivered>>;

struct DelegateIvars {
    latest: Latest,
}

/// A sample buffer's exposure from its Exif attachment (`{Exif}` → `ExposureTime` in seconds,
/// `ISOSpeedRatings`'s first value): the time, and the sensitivity when it says.
///
/// # Safety
/// `sbuf` is a valid `CMSampleBuffer`.
unsafe fn exif_exposure(sbuf: *const c_void) -> Option<(f64, Option<f64>)> {
    // The ImageIO keys' values (kCGImagePropertyExifDictionary, ...ExifExposureTime,
    // ...ExifISOSpeedRatings); an NSString is a CFString.
    let key = |k: &str| NSString::from_str(k);
    let (exif_key, time_key, iso_key) = (key("{Exif}"), key("ExposureTime"), key("ISOSpeedRatings"));
    let ptr = |k: &Retained<NSString>| Retained::as_ptr(k).cast::<c_void>();
    // SAFETY: the caller's contract; every object is checked for null and its type before use,
    // and follows the Get rule (not owned, valid while the buffer is).
    unsafe {
        let number = |n: *const c_void| {
            let mut v = 0f64;
            (!n.is_null() && CFGetTypeID(n) == CFNumberGetTypeID() && CFNumberGetValue(n, CF_NUMBER_FLOAT64, (&mut v as *mut f64).cast()))
                .then_some(v)
        };
        let exif = CMGetAttachment(sbuf, ptr(&exif_key), std::ptr::null_mut());
        if exif.is_null() {
            return None;
        }
        let time = number(CFDictionaryGetValue(exif, ptr(&time_key)))?;
        let isos = CFDictionaryGetValue(exif, ptr(&iso_key));
        let iso = (!isos.is_null() && CFGetTypeID(isos) == CFArrayGetTypeID() && CFArrayGetCount(isos) > 0)
            .then(|| number(CFArrayGetValueAtIndex(isos, 0)))
            .flatten();
        Some((time, iso))
    }
}

define_class!(
    // SAFETY: NSObject has no subclassing requirements; the delegate has no Drop of its own.
    #[unsafe(super(NSObject))]
    #[name = "PrevizCameraDelegate"]
    #[ivars = DelegateIvars]
    struct Delegate;

    unsafe impl NSObjectProtocol for Delegate {}

    unsafe impl AVCaptureVideoDataOutputSampleBufferDelegate for Delegate {
        #[unsafe(method(captureOutput:didOutputSampleBuffer:fromConnection:))]
        fn capture_output(&self, _output: &AVCaptureOutput, sample: &CMSampleBuffer, _connection: &AVCaptureConnection) {
            let sbuf = (sample as *const CMSampleBuffer).cast::<c_void>();
            // SAFETY: the sample buffer is valid during the callback; its image buffer follows
            // the Get rule (not owned), so it is retained before it is kept.
            unsafe {
                let image = CMSampleBufferGetImageBuffer(sbuf);
                if image.is_null() {
                    return;
                }
                let time = CMSampleBufferGetPresentationTimeStamp(sbuf);
                let t = if time.timescale > 0 { time.value as f64 / f64::from(time.timescale) } else { 0.0 };
                let Ok(mut d) = self.ivars().latest.lock() else { return };
                // While a short frame is asked for: this buffer's exposure says whether it is one.
                let short = d.watch.and_then(|(id, plan, found)| {
                    let (time, iso) = exif_exposure(sbuf)?;
                    frame_is_short(time, iso, &plan).then_some((
                        id,
                        found,
                        SensorExposure { time_s: time, iso: iso.unwrap_or(plan.exposure.iso) },
                    ))
                });
                CFRetain(image);
                match short {
                    Some((id, false, exposure)) => {
                        d.short = Some((id, PixelBuffer { ptr: image, t, short: true }, exposure));
                        if let Some(w) = d.watch.as_mut() {
                            w.2 = true;
                        }
                    }
                    _ => d.latest = Some(PixelBuffer { ptr: image, t, short: short.is_some() }),
                }
            }
        }
    }
);

impl Delegate {
    fn new(latest: Latest) -> Retained<Self> {
        let this = Self::alloc().set_ivars(DelegateIvars { latest });
        // SAFETY: NSObject's init.
        unsafe { msg_send![super(this), init] }
    }
}

/// The back camera streaming 1280×720 '420f' buffers.
pub struct IosCamera {
    session: Retained<AVCaptureSession>,
    device: Retained<AVCaptureDevice>,
    _output: Retained<AVCaptureVideoDataOutput>,
    _delegate: Retained<Delegate>,
    _queue: DispatchRetained<DispatchQueue>,
    latest: Latest,
    vfov_deg: Option<f64>,
    t0: Option<f64>,
    last_t: Option<f64>,
    /// Exposure and white balance locked by a capture ([`FrameSource::lock_exposure`]).
    locked: bool,
    paused: bool,
    /// The short exposure frame's request state.
    shot: OneShot,
}

/// Seconds of a `CMTime` (None when it is not a valid, finite time).
fn seconds(t: AvTime) -> Option<f64> {
    let (value, timescale, flags) = (t.value, t.timescale, t.flags);
    (flags.contains(CMTimeFlags::Valid) && timescale > 0).then(|| value as f64 / f64::from(timescale))
}

/// A `CMTime` of `s` seconds in nanoseconds, within `[min, max]` (the format's own times at the
/// ends, so the device never sees a value outside them: it would raise NSRangeException).
fn cm_time(s: f64, min: AvTime, max: AvTime) -> AvTime {
    let t = AvTime { value: (s * 1e9).round() as i64, timescale: 1_000_000_000, flags: CMTimeFlags::Valid, epoch: 0 };
    match (seconds(min), seconds(max)) {
        (Some(lo), _) if s <= lo => min,
        (_, Some(hi)) if s >= hi => max,
        _ => t,
    }
}

impl IosCamera {
    /// Open the back wide-angle camera and start the session (the first call shows the camera
    /// permission prompt). Create it on the main thread.
    pub fn open() -> Result<IosCamera> {
        // SAFETY: AVFoundation calls on objects created here, with valid arguments; the
        // statics are AVFoundation's and CoreVideo's constants.
        unsafe {
            let media = AVMediaTypeVideo.context("AVMediaTypeVideo is missing")?;
            let device = AVCaptureDevice::defaultDeviceWithDeviceType_mediaType_position(
                AVCaptureDeviceTypeBuiltInWideAngleCamera,
                Some(media),
                AVCaptureDevicePosition::Back,
            )
            .context("this device has no back wide-angle camera")?;
            let input = AVCaptureDeviceInput::deviceInputWithDevice_error(&device).map_err(|e| {
                anyhow::anyhow!(
                    "cannot use the camera ({}); if access was refused, allow it in Settings > Privacy & Security > Camera > Previz",
                    e.localizedDescription()
                )
            })?;
            let session = AVCaptureSession::new();
            session.beginConfiguration();
            let preset = AVCaptureSessionPreset1280x720;
            if session.canSetSessionPreset(preset) {
                session.setSessionPreset(preset);
            }
            if !session.canAddInput(&input) {
                session.commitConfiguration();
                bail!("the capture session does not accept the camera as input");
            }
            session.addInput(&input);
            let output = AVCaptureVideoDataOutput::new();
            output.setAlwaysDiscardsLateVideoFrames(true);
            // The buffer format: '420f' (NV12, full range).
            let key: &NSString = &*kCVPixelBufferPixelFormatTypeKey.cast::<NSString>();
            let format = NSNumber::new_u32(super::platform::CV_420F);
            let settings = NSDictionary::<NSString, AnyObject>::from_slices(&[key], &[format.as_ref()]);
            output.setVideoSettings(Some(&settings));
            let latest: Latest = Arc::default();
            let delegate = Delegate::new(latest.clone());
            let queue = DispatchQueue::new("org.previz.camera", None);
            output.setSampleBufferDelegate_queue(Some(ProtocolObject::from_ref(&*delegate)), Some(&queue));
            if !session.canAddOutput(&output) {
                session.commitConfiguration();
                bail!("the capture session does not accept a video data output");
            }
            session.addOutput(&output);
            session.commitConfiguration();
            let hfov = f64::from(device.activeFormat().videoFieldOfView());
            let vfov_deg = vfov_from_hfov_deg(hfov, SIZE).ok();
            session.startRunning();
            Ok(IosCamera {
                session,
                device,
                _output: output,
                _delegate: delegate,
                _queue: queue,
                latest,
                vfov_deg,
                t0: None,
                last_t: None,
                locked: false,
                paused: false,
                shot: OneShot::new(),
            })
        }
    }

    /// The vertical field of view of the images, degrees (from the active format's
    /// `videoFieldOfView`).
    pub fn vfov_deg(&self) -> Option<f64> {
        self.vfov_deg
    }

    fn delivered(&self) -> Result<std::sync::MutexGuard<'_, Delivered>> {
        self.latest.lock().map_err(|_| anyhow::anyhow!("the camera delegate panicked"))
    }

    /// Wait (polling every millisecond; an error after 2 s without a buffer) for a buffer newer
    /// than the last one and lend its planes to `f`. A short exposure frame the delegate found is
    /// taken on the way; buffers still at the short exposure are not lent.
    fn wait_for_image<T>(&mut self, mut f: impl FnMut(f64, &YuvFrame) -> Result<T>) -> Result<T> {
        let mut deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
        loop {
            let (buffer, short) = {
                let mut d = self.delivered()?;
                (d.latest.take(), d.short.take())
            };
            if let Some((id, buffer, exposure)) = short {
                let t = buffer.t - *self.t0.get_or_insert(buffer.t);
                // SAFETY: the buffer is retained by `buffer` for the whole call.
                let frame = unsafe { lend_planes(&buffer, |yuv| Ok(Frame { image: to_rgba_cpu(yuv)?, t })) };
                let action = match frame {
                    Ok(frame) => self.shot.arrived(id, frame, exposure),
                    Err(_) => self.shot.failed(id),
                };
                self.act(action)?;
            }
            if let Some(buffer) = buffer.filter(|b| self.last_t.is_none_or(|t| b.t > t)) {
                self.last_t = Some(buffer.t);
                let t = buffer.t - *self.t0.get_or_insert(buffer.t);
                let action = self.shot.stream_frame(t, !buffer.short);
                self.act(action)?;
                if !buffer.short {
                    // SAFETY: the buffer is retained by `buffer` for the whole call.
                    return unsafe { lend_planes(&buffer, |frame| f(t, frame)) };
                }
                deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
            }
            if std::time::Instant::now() > deadline {
                bail!("no camera image for 2 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }

    /// Set the exposure mode under the configuration lock: `Some(exposure)` custom at that
    /// duration and ISO, None continuous auto-exposure (or locked at the current values while a
    /// capture holds the lock).
    fn set_exposure(&self, custom: Option<SensorExposure>) -> Result<()> {
        // SAFETY: AVFoundation calls on the device this camera owns, under its configuration
        // lock; the custom values are within the active format's ranges (cm_time, the plan).
        unsafe {
            self.device.lockForConfiguration().map_err(|e| anyhow::anyhow!("cannot configure the camera: {}", e.localizedDescription()))?;
            match custom {
                Some(e) => {
                    let format = self.device.activeFormat();
                    let duration = cm_time(e.time_s, format.minExposureDuration(), format.maxExposureDuration());
                    let iso = (e.iso as f32).max(format.minISO()).min(format.maxISO());
                    self.device.setExposureModeCustomWithDuration_ISO_completionHandler(duration, iso, None);
                }
                None => {
                    let mode = if self.locked { AVCaptureExposureMode::Locked } else { AVCaptureExposureMode::ContinuousAutoExposure };
                    if self.device.isExposureModeSupported(mode) {
                        self.device.setExposureMode(mode);
                    }
                }
            }
            self.device.unlockForConfiguration();
        }
        Ok(())
    }

    /// What [`OneShot`] asks: the stream's exposure back (custom at its values, at once), and
    /// once the stream is back, the automatic (or locked) mode and no more watching.
    fn act(&mut self, action: Action) -> Result<()> {
        match action {
            Action::None => Ok(()),
            Action::Restore => {
                let stream = self.delivered()?.watch.map(|(_, plan, _)| plan.stream);
                stream.map_or(Ok(()), |s| self.set_exposure(Some(s)))
            }
            Action::Resumed => {
                self.delivered()?.watch = None;
                self.set_exposure(None)
            }
        }
    }

    /// Ask for the short exposure frame (module docs); false while paused, without custom
    /// exposure, or while a request is not finished.
    fn request_short(&mut self, relative_exposure: f32) -> Result<bool> {
        // SAFETY: plain property reads on the device this camera owns.
        let (current, limits) = unsafe {
            if self.paused || !self.device.isExposureModeSupported(AVCaptureExposureMode::Custom) {
                return Ok(false);
            }
            let format = self.device.activeFormat();
            let current = seconds(self.device.exposureDuration()).map(|t| SensorExposure { time_s: t, iso: f64::from(self.device.ISO()) });
            let times = (seconds(format.minExposureDuration()), seconds(format.maxExposureDuration()));
            let Some(((min_t, max_t), current)) = times.0.zip(times.1).zip(current) else { return Ok(false) };
            (current, ExposureLimits::new((min_t, max_t), (f64::from(format.minISO()), f64::from(format.maxISO())))?)
        };
        let plan = plan_exposure(current, f64::from(relative_exposure), &limits)?;
        let Some(id) = self.shot.request(plan) else { return Ok(false) };
        self.delivered()?.watch = Some((id, plan, false));
        if let Err(e) = self.set_exposure(Some(plan.exposure)) {
            let action = self.shot.failed(id);
            self.act(action)?;
            return Err(e.context("the short exposure frame for the sun"));
        }
        Ok(true)
    }
}

/// Lock a bi-planar buffer read-only and lend its planes.
///
/// # Safety
/// `buffer.ptr` is a valid, retained `CVPixelBuffer`.
unsafe fn lend_planes<T>(buffer: &PixelBuffer, f: impl FnOnce(&YuvFrame) -> Result<T>) -> Result<T> {
    let b = buffer.ptr;
    // SAFETY: the caller's contract; the plane slices live only while the buffer is locked.
    unsafe {
        if CVPixelBufferLockBaseAddress(b, LOCK_READ_ONLY) != 0 {
            bail!("CVPixelBufferLockBaseAddress failed");
        }
        let result = (|| {
            let matrix = {
                let m = CVBufferGetAttachment(b, kCVImageBufferYCbCrMatrixKey, std::ptr::null_mut());
                (!m.is_null()).then(|| (*m.cast::<NSString>()).to_string())
            };
            let (matrix, range) = ios_yuv_format(CVPixelBufferGetPixelFormatType(b), matrix.as_deref())?;
            if CVPixelBufferGetPlaneCount(b) != 2 {
                bail!("the camera buffer is not bi-planar");
            }
            let plane = |i: usize| -> Result<Plane<'_>> {
                let data = CVPixelBufferGetBaseAddressOfPlane(b, i).cast::<u8>();
                let row_stride = CVPixelBufferGetBytesPerRowOfPlane(b, i);
                let rows = CVPixelBufferGetHeightOfPlane(b, i);
                if data.is_null() || row_stride == 0 || rows == 0 {
                    bail!("camera buffer plane {i} is empty");
                }
                Ok(Plane { data: std::slice::from_raw_parts(data, row_stride * rows), row_stride })
            };
            let frame = YuvFrame {
                width: CVPixelBufferGetWidth(b) as u32,
                height: CVPixelBufferGetHeight(b) as u32,
                luma: plane(0)?,
                chroma: Chroma::Interleaved { plane: plane(1)?, cb_first: true },
                matrix,
                range,
            };
            f(&frame)
        })();
        CVPixelBufferUnlockBaseAddress(b, LOCK_READ_ONLY);
        result
    }
}

impl FrameSource for IosCamera {
    /// The newest image as RGBA on the CPU (the reference conversion); the live session uses
    /// [`FrameSource::lend_next_frame`] instead.
    fn next_frame(&mut self) -> Result<Option<Frame>> {
        self.wait_for_image(|t, yuv| Ok(Frame { image: to_rgba_cpu(yuv)?, t })).map(Some)
    }

    /// The newest buffer's planes, lent as they lie in the buffer.
    fn lend_next_frame(&mut self, sink: &mut FrameSink<'_>) -> Result<bool> {
        self.wait_for_image(|t, frame| sink(t, FrameImage::Yuv { frame: *frame, quarter_turns: 0 }))?;
        Ok(true)
    }

    fn pause(&mut self) -> Result<()> {
        // SAFETY: a plain call on the session this camera owns.
        unsafe { self.session.stopRunning() };
        self.paused = true;
        // A short frame asked for is lost; the exposure goes back to the stream's and its mode.
        let restore = self.shot.cancel() == Action::Restore;
        let stream = {
            let mut d = self.delivered()?;
            d.latest = None;
            d.short = None;
            d.watch.take().map(|(_, plan, _)| plan.stream)
        };
        if restore {
            if let Some(s) = stream {
                self.set_exposure(Some(s))?;
            }
            self.set_exposure(None)?;
        }
        Ok(())
    }

    fn resume(&mut self) -> Result<()> {
        // SAFETY: as in pause.
        unsafe { self.session.startRunning() };
        self.paused = false;
        Ok(())
    }

    /// `setExposureModeCustomWithDuration:ISO:completionHandler:` (module docs).
    fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
        self.request_short(relative_exposure)
    }

    fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
        Ok(self.shot.take())
    }

    /// `AVCaptureExposureModeLocked` + `AVCaptureWhiteBalanceModeLocked` (each where the device
    /// supports it), or back to the continuous automatic modes; false when the device cannot
    /// lock both.
    fn lock_exposure(&mut self, lock: bool) -> Result<bool> {
        let (exposure, white) = if lock {
            (AVCaptureExposureMode::Locked, AVCaptureWhiteBalanceMode::Locked)
        } else {
            (AVCaptureExposureMode::ContinuousAutoExposure, AVCaptureWhiteBalanceMode::ContinuousAutoWhiteBalance)
        };
        // SAFETY: AVFoundation calls on the device this camera owns; the modes are set only
        // when supported and while the configuration lock is held, as AVCaptureDevice requires.
        unsafe {
            self.device.lockForConfiguration().map_err(|e| anyhow::anyhow!("cannot configure the camera: {}", e.localizedDescription()))?;
            let exposure_ok = self.device.isExposureModeSupported(exposure);
            if exposure_ok {
                self.device.setExposureMode(exposure);
            }
            let white_ok = self.device.isWhiteBalanceModeSupported(white);
            if white_ok {
                self.device.setWhiteBalanceMode(white);
            }
            self.device.unlockForConfiguration();
            self.locked = lock && exposure_ok;
            Ok(lock && exposure_ok && white_ok)
        }
    }
}

impl Drop for IosCamera {
    fn drop(&mut self) {
        // SAFETY: as in pause.
        unsafe { self.session.stopRunning() };
    }
}
