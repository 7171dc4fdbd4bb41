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
//! The first use of the camera shows the system's permission prompt (Info.plist's
//! `NSCameraUsageDescription`); a refusal makes [`IosCamera::open`] fail with a message saying
//! where to grant it.

use super::platform::{ios_yuv_format, vfov_from_hfov_deg};
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
use objc2_core_media::CMSampleBuffer;
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
}

#[link(name = "CoreMedia", kind = "framework")]
unsafe extern "C" {
    fn CMSampleBufferGetImageBuffer(sbuf: *const c_void) -> *mut c_void;
    fn CMSampleBufferGetPresentationTimeStamp(sbuf: *const c_void) -> CMTime;
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

/// The newest buffer the delegate received, shared with the frame loop.
type Latest = Arc<Mutex<Option<PixelBuffer>>>;

struct DelegateIvars {
    latest: Latest,
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
                CFRetain(image);
                let buffer = PixelBuffer { ptr: image, t };
                if let Ok(mut latest) = self.ivars().latest.lock() {
                    *latest = Some(buffer);
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
            Ok(IosCamera { session, device, _output: output, _delegate: delegate, _queue: queue, latest, vfov_deg, t0: None, last_t: None })
        }
    }

    /// The vertical field of view of the images, degrees (from the active format's
    /// `videoFieldOfView`).
    pub fn vfov_deg(&self) -> Option<f64> {
        self.vfov_deg
    }

    /// Wait (polling every millisecond; an error after 2 s) for a buffer newer than the last one
    /// and lend its planes to `f`.
    fn wait_for_image<T>(&mut self, mut f: impl FnMut(f64, &YuvFrame) -> Result<T>) -> Result<T> {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(2);
        loop {
            let buffer = self.latest.lock().map_err(|_| anyhow::anyhow!("the camera delegate panicked"))?.take();
            if let Some(buffer) = buffer.filter(|b| self.last_t.is_none_or(|t| b.t > t)) {
                self.last_t = Some(buffer.t);
                let t = buffer.t - *self.t0.get_or_insert(buffer.t);
                // SAFETY: the buffer is retained by `buffer` for the whole call.
                return unsafe { lend_planes(&buffer, |frame| f(t, frame)) };
            }
            if std::time::Instant::now() > deadline {
                bail!("no camera image for 2 s");
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
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
        if let Ok(mut latest) = self.latest.lock() {
            *latest = None;
        }
        Ok(())
    }

    fn resume(&mut self) -> Result<()> {
        // SAFETY: as in pause.
        unsafe { self.session.startRunning() };
        Ok(())
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
