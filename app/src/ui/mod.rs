//! egui panels and overlays, and a headless egui renderer for tests and screenshots.
//!
//! - [`capture_overlay`]: the capture assistant's guidance over the camera view.
//! - [`controls`]: the composite mode's control panel (seed 000 Fig. 23) and touch gestures.
//! - [`layout`]: where the composite mode's panels go at any screen size, none over another.
//! - [`headless`]: draw any egui UI over an image offscreen (egui-wgpu), read the pixels back.
//! - [`paint`]: one egui pass painted into a texture view (headless and the live window).

pub mod capture_overlay;
pub mod controls;
pub mod headless;
pub mod layout;
pub mod paint;
