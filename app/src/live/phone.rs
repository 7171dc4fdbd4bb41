//! What the Android and iOS shells share, written without platform calls so it runs (and is
//! tested) on the host: the camera that opens once the user allows it ([`OpeningCamera`]) and
//! iOS's authorisation values as the app's answers ([`ios_authorization_answer`]). The answers
//! the app reads while it runs come from the shells' [`super::app::PermissionSource`].

use crate::camera::short_exposure::ShortFrame;
use crate::camera::{Frame, FrameImage, FrameSink, FrameSource};
use crate::scene::Rgba8Image;
use crate::sensors::permissions::Answer;
use anyhow::Result;
use std::time::{Duration, Instant};

/// How often a camera that would not open is tried again.
pub const REOPEN_EVERY: Duration = Duration::from_millis(500);
/// The grey of the frames shown while there is no camera (sRGB code).
pub const NO_CAMERA_GREY: u8 = 96;

/// Opens the platform's camera (Camera2, AVFoundation); fails while the permission is missing.
pub type OpenCamera = Box<dyn FnMut() -> Result<Box<dyn FrameSource>>>;

/// The phone's camera, opened at the first frame and, while that fails (the permission dialog
/// is still up, the user refused and may change their mind in the settings), tried again every
/// [`REOPEN_EVERY`]; meanwhile grey frames of the camera image's size at 30 Hz, so the app keeps
/// drawing (and granting the permission starts the picture without a restart). Pausing a camera
/// that is not open yet stops the tries until it is resumed.
pub struct OpeningCamera {
    open: OpenCamera,
    size: (u32, u32),
    camera: Option<Box<dyn FrameSource>>,
    start: Instant,
    next_try: Instant,
    paused: bool,
    last_error: Option<String>,
    log: fn(&str),
}

impl OpeningCamera {
    /// `size`: the upright image the opened camera delivers (the grey frames have it too).
    /// `log` receives each failed attempt's error.
    pub fn new(size: (u32, u32), open: OpenCamera, log: fn(&str)) -> OpeningCamera {
        let now = Instant::now();
        OpeningCamera { open, size, camera: None, start: now, next_try: now, paused: false, last_error: None, log }
    }

    pub fn is_open(&self) -> bool {
        self.camera.is_some()
    }

    /// Why the last attempt to open the camera failed.
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// Open the camera when it is time to try again.
    fn try_open(&mut self) {
        if self.camera.is_some() || self.paused || Instant::now() < self.next_try {
            return;
        }
        self.next_try = Instant::now() + REOPEN_EVERY;
        match (self.open)() {
            Ok(c) => {
                self.camera = Some(c);
                self.last_error = None;
            }
            Err(e) => {
                let msg = format!("camera not open yet: {e:#}");
                (self.log)(&msg);
                self.last_error = Some(msg);
            }
        }
    }

    /// A grey frame while there is no camera, paced at 30 Hz (the display loop asks as fast as
    /// it can draw).
    fn grey(&self) -> Frame {
        std::thread::sleep(Duration::from_millis(33));
        let (w, h) = self.size;
        Frame {
            image: Rgba8Image { width: w, height: h, pixels: vec![NO_CAMERA_GREY; (4 * w * h) as usize] },
            t: self.start.elapsed().as_secs_f64(),
        }
    }
}

impl FrameSource for OpeningCamera {
    fn next_frame(&mut self) -> Result<Option<Frame>> {
        self.try_open();
        match &mut self.camera {
            Some(c) => c.next_frame(),
            None => Ok(Some(self.grey())),
        }
    }

    fn lend_next_frame(&mut self, sink: &mut FrameSink<'_>) -> Result<bool> {
        self.try_open();
        match &mut self.camera {
            Some(c) => c.lend_next_frame(sink),
            None => {
                let frame = self.grey();
                sink(frame.t, FrameImage::Rgba(frame.image))?;
                Ok(true)
            }
        }
    }

    fn pause(&mut self) -> Result<()> {
        self.paused = true;
        self.camera.as_mut().map_or(Ok(()), |c| c.pause())
    }

    fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
        self.camera.as_mut().map_or(Ok(false), |c| c.request_exposure_frame(relative_exposure))
    }

    fn take_exposure_frame(&mut self) -> Result<Option<ShortFrame>> {
        self.camera.as_mut().map_or(Ok(None), |c| c.take_exposure_frame())
    }

    fn resume(&mut self) -> Result<()> {
        self.paused = false;
        // A camera refused before the pause is tried again at once (the user may have allowed
        // it in the settings meanwhile).
        self.next_try = Instant::now();
        self.camera.as_mut().map_or(Ok(()), |c| c.resume())
    }
}

/// The app's answer for an iOS authorisation status: `AVAuthorizationStatus` (camera) and
/// `CLAuthorizationStatus` (location) share 0 not determined, 1 restricted, 2 denied, 3
/// authorised (location: always), and location adds 4 when in use. iOS asks once: restricted
/// (parental controls, device management) and denied can only change in the Settings app.
pub fn ios_authorization_answer(status: i64) -> Answer {
    match status {
        3 | 4 => Answer::Granted,
        1 | 2 => Answer::DeniedForever,
        _ => Answer::Pending,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    type Log = Arc<Mutex<Vec<String>>>;

    /// A camera double: frames of one white pixel row, logging pause/resume.
    struct White {
        log: Log,
        k: u32,
    }

    impl FrameSource for White {
        fn next_frame(&mut self) -> Result<Option<Frame>> {
            self.k += 1;
            Ok(Some(Frame { image: Rgba8Image { width: 4, height: 2, pixels: vec![255; 32] }, t: f64::from(self.k) }))
        }
        fn pause(&mut self) -> Result<()> {
            self.log.lock().unwrap().push("pause".into());
            Ok(())
        }
        fn resume(&mut self) -> Result<()> {
            self.log.lock().unwrap().push("resume".into());
            Ok(())
        }
    }

    /// An opener that fails (permission missing) while `allowed` is false.
    fn opener(allowed: Arc<Mutex<bool>>, log: Log) -> OpenCamera {
        Box::new(move || {
            log.lock().unwrap().push("open".into());
            anyhow::ensure!(*allowed.lock().unwrap(), "CAMERA permission not granted");
            Ok(Box::new(White { log: log.clone(), k: 0 }) as Box<dyn FrameSource>)
        })
    }

    fn opens(log: &Log) -> usize {
        log.lock().unwrap().iter().filter(|s| *s == "open").count()
    }

    #[test]
    fn grey_frames_until_the_camera_opens_then_its_frames() {
        let (allowed, log): (Arc<Mutex<bool>>, Log) = Default::default();
        let mut cam = OpeningCamera::new((4, 2), opener(allowed.clone(), log.clone()), |_| {});
        let f = cam.next_frame().unwrap().unwrap();
        assert_eq!((f.image.width, f.image.height), (4, 2));
        assert!(f.image.pixels.iter().all(|&p| p == NO_CAMERA_GREY));
        assert!(!cam.is_open() && cam.last_error().is_some_and(|e| e.contains("CAMERA permission")));
        // Not tried again before REOPEN_EVERY has passed.
        cam.next_frame().unwrap();
        assert_eq!(opens(&log), 1);
        // The user allows it; the next try (made due by a pause/resume) opens it.
        *allowed.lock().unwrap() = true;
        cam.pause().unwrap();
        cam.next_frame().unwrap();
        assert_eq!(opens(&log), 1, "no try while paused");
        cam.resume().unwrap();
        let f = cam.next_frame().unwrap().unwrap();
        assert!(cam.is_open() && cam.last_error().is_none());
        assert!(f.image.pixels.iter().all(|&p| p == 255), "the camera's own frame");
        // Pause and resume reach the opened camera.
        cam.pause().unwrap();
        cam.resume().unwrap();
        let calls = log.lock().unwrap().clone();
        assert_eq!(calls, ["open", "open", "pause", "resume"]);
    }

    #[test]
    fn a_refused_camera_is_tried_again_after_the_interval() {
        let (allowed, log): (Arc<Mutex<bool>>, Log) = Default::default();
        let mut cam = OpeningCamera::new((4, 2), opener(allowed, log.clone()), |_| {});
        cam.next_frame().unwrap();
        // Wait for the condition (the interval passed), not a fixed time.
        while Instant::now() < cam.next_try {
            std::thread::yield_now();
        }
        cam.next_frame().unwrap();
        assert_eq!(opens(&log), 2);
    }

    #[test]
    fn ios_authorisation_values_map_to_answers() {
        // Values from Apple's headers (AVCaptureDevice.h AVAuthorizationStatus, CLLocationManager.h
        // CLAuthorizationStatus).
        assert_eq!(ios_authorization_answer(0), Answer::Pending);
        assert_eq!(ios_authorization_answer(1), Answer::DeniedForever);
        assert_eq!(ios_authorization_answer(2), Answer::DeniedForever);
        assert_eq!(ios_authorization_answer(3), Answer::Granted);
        assert_eq!(ios_authorization_answer(4), Answer::Granted);
        assert_eq!(ios_authorization_answer(7), Answer::Pending);
    }
}
