//! The renderer: wgpu device, pipelines and the passes of one frame.

pub mod gpu;
