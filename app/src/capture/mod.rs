//! The cube-map capture assistant (seed 000 §4.2, Fig. 12a/12b) and face assembly.
//!
//! The user taps on the front view: its heading becomes the capture's *reference heading*.
//! Up, down, right, back and left follow in any order; each is taken automatically when the
//! estimated camera pose is on that target — judged with the pose's own uncertainty — and held
//! steady ([`assistant`]). Faces are re-projected from the frames by pose ([`reproject`]): per face
//! pixel, direction → camera → frame pixel. Two modes:
//!
//! - [`Mode::Stretch`]: the seed's cheapest — one shot per face, its centred square stretched
//!   over the whole 90° face (the lens sees less than 90°, so the face is magnified);
//! - [`Mode::Stitch`]: the fewest views that cover the sphere for the lens's field of view
//!   ([`targets::plan_targets`]), stitched by pose; complete when every face has been seen,
//!   whichever shots saw it. [`align`] can correct the shots' headings from their overlaps.
//!
//! A capture saves and loads as a folder of six PNG faces and a metadata JSON ([`folder`]).
//! Without a capture, [`frame_fold`] folds the live frame into an approximate cube map (seed
//! 004, after Ropinski et al. 2004). [`replay`] drives the assistant from a truth trace through
//! the virtual phone and simulated sensors (`previz capture`); [`stability`] measures where
//! it fails (`previz capture stability`).
//!
//! Cube convention: the project's ([`crate::scene::enu_to_cube`]) applied to the capture's
//! local frame, which is ENU turned so that the reference heading points North. So +Z (posz)
//! is the front, +X (posx) the right (reference + 90°), −Z back, −X left, +Y up, −Y down.

pub mod aim_heading;
pub mod align;
pub mod assistant;
pub mod dense_solve;
pub mod folder;
pub mod frame_fold;
pub mod gain;
pub mod gravity;
pub mod guided_path;
pub mod hdr;
pub mod projection;
pub mod replay;
pub mod reproject;
pub mod stability;
pub mod targets;

pub use assistant::{Assistant, AssistantConfig, Guidance, Phase};
pub use folder::{CaptureMeta, CubeCapture, load_capture, save_capture};
pub use projection::Pinhole;
pub use targets::{Face, Target};

/// How faces are made from the shots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// One shot per face, its centred square stretched over the face (seed 000).
    Stretch,
    /// The views the lens needs, stitched by pose: every face observed.
    Stitch,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Stretch => "stretch",
            Mode::Stitch => "stitch",
        }
    }
}
