//! Camera frames: the [`FrameSource`] trait and its backends.
//!
//! - [`sim`]: the virtual phone, rendering what a phone camera sees from an environment.
//! - [`file`]: a still image or a folder of numbered images.
//! - [`yuv`]: camera YUV 4:2:0 planes converted to R'G'B' on the GPU (the phone cameras' format).
//!
//! - `android`: the back camera through the NDK Camera2 API (Android only).
//! - `ios`: the back camera through AVFoundation (iOS only).
//! - [`platform`]: the phone cameras' chroma layout and field of view (pure, host-tested).
//! - [`short_exposure`]: one short exposure frame between the stream's frames (the live sun
//!   frame): the exposure arithmetic and the request's states (pure, host-tested).
//!
//! Phone backends implement the same trait.

#[cfg(target_os = "android")]
pub mod android;
pub mod controls;
pub mod exposure;
pub mod file;
#[cfg(target_os = "ios")]
pub mod ios;
pub mod platform;
pub mod short_exposure;
pub mod sim;
pub mod white_balance;
pub mod yuv;

use crate::scene::Rgba8Image;
use anyhow::Result;
use yuv::YuvFrame;

/// One camera frame: an sRGB-encoded 8-bit image and the time it was taken.
#[derive(Clone, Debug)]
pub struct Frame {
    pub image: Rgba8Image,
    /// Seconds since the start of the stream.
    pub t: f64,
}

/// A frame's pixels as the camera delivers them, lent to [`FrameSource::lend_next_frame`]'s
/// callback.
pub enum FrameImage<'a> {
    /// An sRGB-encoded 8-bit image (the virtual phone, image files).
    Rgba(Rgba8Image),
    /// YUV 4:2:0 planes still in the camera's buffer (the phones), converted on the GPU
    /// ([`yuv::YuvConverter::convert_turned`]) after `quarter_turns` clockwise quarter turns
    /// that make them upright on the screen.
    Yuv { frame: YuvFrame<'a>, quarter_turns: u32 },
}

/// The callback [`FrameSource::lend_next_frame`] lends a frame to: the frame's time (seconds
/// since the start of the stream) and its pixels.
pub type FrameSink<'s> = dyn FnMut(f64, FrameImage<'_>) -> Result<()> + 's;

/// Anything that produces camera frames.
pub trait FrameSource {
    /// The next frame as an image on the CPU; `Ok(None)` at the end of the stream. Errors name
    /// what failed (the file, the invalid pose, ...).
    fn next_frame(&mut self) -> Result<Option<Frame>>;

    /// The next frame lent to `sink` as the camera delivers it (a phone camera's YUV planes are
    /// only valid during the call); false at the end of the stream. The live session reads its
    /// frames through this, so YUV goes to the GPU without a CPU conversion. By default the
    /// image of [`FrameSource::next_frame`].
    fn lend_next_frame(&mut self, sink: &mut FrameSink<'_>) -> Result<bool> {
        let Some(frame) = self.next_frame()? else { return Ok(false) };
        sink(frame.t, FrameImage::Rgba(frame.image))?;
        Ok(true)
    }

    /// Stop the camera (the app went to the background): no frame is captured or queued until
    /// [`FrameSource::resume`]. Files and the simulator have nothing to stop.
    fn pause(&mut self) -> Result<()> {
        Ok(())
    }

    /// Start the camera again after [`FrameSource::pause`].
    fn resume(&mut self) -> Result<()> {
        Ok(())
    }

    /// Lock (true) auto-exposure and auto white balance at their current values, or let them
    /// follow the view again (false): a capture locks them at the tap, so every shot shares one
    /// exposure and colour ([`controls`]). Returns whether they are locked now: false from a
    /// source that cannot lock them (files; a camera without the lock), whose captures then
    /// estimate each shot's gain from the overlaps ([`crate::capture::gain`]).
    fn lock_exposure(&mut self, lock: bool) -> Result<bool> {
        let _ = lock;
        Ok(false)
    }

    /// Ask for one frame between the stream's frames at `relative_exposure` times the current
    /// exposure (same white balance): the short exposure in which only the sun's disc clips
    /// ([`crate::pose::sun_heading::SUN_FRAME_EXPOSURE`], for true north from the sun,
    /// [`crate::live::sun_north`]). Never waits: the frame comes with a later stream frame and
    /// is taken with [`FrameSource::take_exposure_frame`]; the stream's frames go on meanwhile
    /// and the short frame is never lent as one of them. False when the source cannot take one
    /// (files; a phone camera without manual exposure) or a request is not finished yet. The
    /// request's states and the exposure arithmetic are [`short_exposure`]'s.
    fn request_exposure_frame(&mut self, relative_exposure: f32) -> Result<bool> {
        let _ = relative_exposure;
        Ok(false)
    }

    /// How the last [`FrameSource::request_exposure_frame`] ended, once it has (polled after each
    /// stream frame): the frame with the relative exposure it really had (the sensor's limits may
    /// not reach the one asked for), or lost (timed out, failed, the camera paused). None while
    /// it is in flight or when nothing was asked.
    fn take_exposure_frame(&mut self) -> Result<Option<short_exposure::ShortFrame>> {
        Ok(None)
    }
}
