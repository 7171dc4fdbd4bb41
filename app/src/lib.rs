//! Previz: composite a 3D model into a photograph or a live camera view, lit by the real sun,
//! reflecting and colour-matched to the real surroundings.
//!
//! Conventions (see `../shared/DESIGN.md`): world frame ENU (+x East, +y North, +z Up), camera
//! frame +x right, +y up, looking along −z; a pose rotates camera → world. Angles are degrees at
//! the edges (CLI, files) and radians inside. Images are sRGB-encoded; shading is linear.

pub mod bench;
pub mod camera;
pub mod capture;
pub mod chart;
pub mod cli;
pub mod colour;
#[doc(hidden)]
pub mod fuzzing;
pub mod gpu;
pub mod light;
pub mod live;
pub mod output;
pub mod pose;
pub mod priors;
pub mod render;
pub mod scene;
pub mod sensors;
pub mod setup;
pub mod sun;
pub mod ui;
