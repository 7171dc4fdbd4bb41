//! The ground's sky transfer under a new placement of the model, cast on a thread of its own so
//! that turning or scaling the model in the live view does not hold a frame for its rays
//! (64² texels × 256 rays, 120–220 ms of CPU in a debug build). The model cache
//! ([`super::model_cache::PreparedModel`]) keeps drawing the previous placement's map until the
//! new transfer is ready, as the live view's fold keeps the previous environment while its
//! prefilter runs (live::LiveSession's fold).
//!
//! One job at a time: a placement asked for while another is being cast waits for that one to
//! finish (its map is then the nearer previous one) and is started on the next request.

use crate::scene::occlusion::{self, GroundTransfer, Occluders};
use glam::{Mat4, Vec3};
use std::sync::Arc;
use std::thread::JoinHandle;

/// A placement as the bits of its model matrix: equal bits, equal rays.
pub type PlacementKey = [u32; 16];

/// The key of `placement`.
pub fn placement_key(placement: Mat4) -> PlacementKey {
    placement.to_cols_array().map(f32::to_bits)
}

/// The ground's transfer under the model (`occluders`, model-space `bounds`) placed by
/// `placement`: [`occlusion::GROUND_TEXELS`]² texels of [`occlusion::GROUND_RAYS`] rays, each kept
/// with its world direction. The one cast both on the caller's thread and on the worker's, so
/// both give the same map.
pub fn cast(occluders: &Occluders, bounds: (Vec3, Vec3), placement: Mat4) -> GroundTransfer {
    occlusion::ground_transfer(occluders, bounds, placement, occlusion::GROUND_TEXELS, occlusion::GROUND_RAYS, &crate::light::sh9::basis)
}

/// The transfer being cast on its own thread, if any.
#[derive(Default)]
pub struct GroundWorker {
    job: Option<(PlacementKey, JoinHandle<GroundTransfer>)>,
}

impl GroundWorker {
    /// Start casting the transfer for `placement` unless a job is running already; whether it
    /// started.
    pub fn start(&mut self, occluders: Arc<Occluders>, bounds: (Vec3, Vec3), placement: Mat4) -> bool {
        if self.job.is_some() {
            return false;
        }
        let handle = std::thread::spawn(move || cast(&occluders, bounds, placement));
        self.job = Some((placement_key(placement), handle));
        true
    }

    /// The placement being cast, if any.
    pub fn busy(&self) -> Option<PlacementKey> {
        self.job.as_ref().map(|(key, _)| *key)
    }

    /// The finished job's placement and transfer; None while it runs (never waits) or when there
    /// is none.
    pub fn finished(&mut self) -> Option<(PlacementKey, GroundTransfer)> {
        if !self.job.as_ref().is_some_and(|(_, h)| h.is_finished()) {
            return None;
        }
        self.wait()
    }

    /// Wait for the running job, if any, and return its placement and transfer.
    pub fn wait(&mut self) -> Option<(PlacementKey, GroundTransfer)> {
        let (key, handle) = self.job.take()?;
        // The cast has no error path; a panic in it is a bug, raised again here.
        Some((key, handle.join().unwrap_or_else(|p| std::panic::resume_unwind(p))))
    }
}
