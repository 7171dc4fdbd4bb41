//! The renderer: wgpu device, pipelines and the passes of one frame.

pub mod compositor;
pub mod gpu;
pub mod method;
pub mod pipelines;
pub mod shaders;
pub mod uniforms;
pub mod view;

pub use compositor::{
    Camera, ColourSettings, Compositor, FrameData, FrameParams, HemispherePriors, Layer, Lighting, MaterialTerms, Rendered, Timings,
};
pub use method::Method;
pub use view::Placement;
