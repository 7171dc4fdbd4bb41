//! Camera frames: the [`FrameSource`] trait and its backends.
//!
//! - [`sim`]: the virtual phone, rendering what a phone camera sees from an environment.
//! - [`file`]: a still image or a folder of numbered images.
//! - [`yuv`]: camera YUV 4:2:0 planes converted to R'G'B' on the GPU (the phone cameras' format).
//!
//! Phone backends (Android, iOS) implement the same trait.

pub mod exposure;
pub mod file;
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
}
