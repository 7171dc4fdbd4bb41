//! The renderer: pipelines and the passes of one frame (the device is `crate::gpu`).

pub mod compositor;
pub mod method;
pub mod pipelines;
pub mod shaders;
pub mod shadow_fit;
pub mod uniforms;
pub mod view;

pub use compositor::{
    Camera, ColourSettings, Compositor, FrameData, FrameParams, HemispherePriors, Layer, Lighting, MaterialTerms, Rendered, Timings,
};
pub use method::Method;
pub use view::Placement;
