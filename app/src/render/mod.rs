//! The renderer: pipelines and the passes of one frame (the device is `crate::gpu`).

pub mod antialiasing;
pub mod compositor;
pub mod environment;
pub mod frame;
pub mod ground_worker;
pub mod layers;
pub mod method;
pub mod mip_chain;
pub mod model_cache;
pub mod params;
pub mod passes;
pub mod pipelines;
pub mod reprojection;
pub mod shaders;
pub mod shadow_fit;
pub mod supersample;
pub mod targets;
pub mod uniforms;
pub mod view;

pub use antialiasing::Antialiasing;
pub use compositor::{Compositor, PassCounts, PassTimes, PassesRun, Rendered, Timings};
pub use frame::{Detail, FrameData};
pub use method::LightingMethod;
pub use params::{Camera, ColourSettings, FrameParams, HemispherePriors, Layer, Lighting, MaterialTerms};
pub use view::Placement;
