//! Camera frames: the [`FrameSource`] trait and its backends.
//!
//! - [`sim`]: the virtual phone, rendering what a phone camera sees from an environment.
//! - [`file`]: a still image or a folder of numbered images.
//! - [`yuv`]: camera YUV 4:2:0 planes converted to R'G'B' on the GPU (the phone cameras' format).
//!
//! - `android`: the back camera through the NDK Camera2 API (Android only).
//! - [`platform`]: the phone cameras' chroma layout and field of view (pure, host-tested).
//!
//! Phone backends implement the same trait.

#[cfg(target_os = "android")]
pub mod android;
pub mod exposure;
pub mod file;
pub mod platform;
pub mod sim;
pub mod yuv;

use crate::scene::Rgba8Image;
use anyhow::Result;

/// One camera frame: an sRGB-encoded 8-bit image and the time it was taken.
#[derive(Clone, Debug)]
pub struct Frame {
    pub image: Rgba8Image,
    /// Seconds since the start of the stream.
    pub t: f64,
}

/// Anything that produces camera frames.
pub trait FrameSource {
    /// The next frame; `Ok(None)` at the end of the stream. Errors name what failed (the file,
    /// the invalid pose, ...).
    fn next_frame(&mut self) -> Result<Option<Frame>>;

    /// Stop the camera (the app went to the background): no frame is captured or queued until
    /// [`FrameSource::resume`]. Files and the simulator have nothing to stop.
    fn pause(&mut self) -> Result<()> {
        Ok(())
    }

    /// Start the camera again after [`FrameSource::pause`].
    fn resume(&mut self) -> Result<()> {
        Ok(())
    }
}
