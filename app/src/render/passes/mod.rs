//! One file per pass of a frame (DESIGN.md "One frame"): each pass builds its pipeline, owns its
//! bind groups, uniform buffers and targets, and encodes itself. `Compositor::encode_frame`
//! calls them in order.

pub mod background;
pub mod ground;
pub mod ground_sun;
pub mod model;
pub mod shadow;
pub mod vertex_sun;
