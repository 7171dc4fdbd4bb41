//! Work done once per model, not once per compositor: the vertices with their ambient occlusion,
//! the level-of-detail chain, and — only when a colour correction first asks — the model's colour
//! statistics; and per placement, the ground's sky transfer under the model, from which each
//! sky's visibility map is recombined without casting a ray.
//!
//! Entries are keyed by the model's content (every position, normal, uv, index, material value
//! and texel), so a second compositor, a second scene or the live view's model picker going back
//! to a model reuse the work (the 100k-triangle dragon's occlusion alone takes ~1.6 s on the
//! CPU), and any change to the model computes it again. One cache per device
//! ([`ModelCache::of`]); it keeps the [`CAPACITY`] models used last.

use super::ground_worker::{self, GroundWorker, PlacementKey, placement_key};
use super::pipelines::Vertex;
use crate::colour::stats::ColourStats;
use crate::gpu::Gpu;
use crate::light::sh9::SkyRadiance;
use crate::scene::lod::LodChain;
use crate::scene::occlusion::{self, BounceLight, BounceReach, GroundSky, GroundTransfer, ModelRays, Occluders};
use crate::scene::{Mesh, Model};
use anyhow::{Result, anyhow, bail};
use glam::{Mat4, Vec3};
use std::hash::{Hash, Hasher};
use std::sync::atomic::Ordering::{AcqRel, Acquire, Relaxed, Release};
use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

/// Models kept per device (the least recently used goes first).
pub const CAPACITY: usize = 8;

/// A model's content as a 64-bit hash (SipHash over every value that the derived data reads).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ModelKey(u64);

impl ModelKey {
    pub fn of(model: &Model) -> ModelKey {
        let mut h = std::hash::DefaultHasher::new();
        model.meshes.len().hash(&mut h);
        for m in &model.meshes {
            for bytes in [
                bytemuck::cast_slice::<_, u8>(&m.positions),
                bytemuck::cast_slice(&m.normals),
                bytemuck::cast_slice(&m.uvs),
                bytemuck::cast_slice(&m.indices),
            ] {
                bytes.len().hash(&mut h);
                h.write(bytes);
            }
            m.material.hash(&mut h);
        }
        model.materials.len().hash(&mut h);
        for m in &model.materials {
            let values = [m.diffuse.as_slice(), &m.specular, &[m.shininess, m.opacity]].concat();
            values.iter().for_each(|v| v.to_bits().hash(&mut h));
            (m.sides as u8).hash(&mut h);
            match &m.texture {
                Some(t) => (t.width, t.height, &t.pixels).hash(&mut h),
                None => 0u8.hash(&mut h),
            }
        }
        ModelKey(h.finish())
    }
}

/// The light a ground map is made for: the sky's radiance in bins (light::sh9::SkyRadiance, in
/// the environment map's frame, turned into the world by `heading`: radians, frame.wgsl
/// env_map_dir), which weights the rays the model hides, and the light the model reflects onto
/// the ground (occlusion::BounceLight, made by passes::ground::bounce_light; NONE: no bounce).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundLight {
    pub radiance: SkyRadiance,
    pub heading: f32,
    pub bounce: BounceLight,
}

impl From<SkyRadiance> for GroundLight {
    /// A sky of that radiance, the map unturned, over a model that reflects nothing.
    fn from(radiance: SkyRadiance) -> GroundLight {
        GroundLight { radiance, heading: 0.0, bounce: BounceLight::NONE }
    }
}

/// Per mesh, its vertices (shared: the model cache keeps the last, the compositor the uploaded).
pub type MeshVertices = Arc<Vec<Vec<Vertex>>>;

/// What [`PreparedModel::vertices_under`] depends on: the placement's rotation (its 3 × 3 part's
/// bits, scale included), the sky's bins and its heading.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ModelSkyKey([u32; 9], SkyRadiance, u32);

impl ModelSkyKey {
    fn of(placement: Mat4, radiance: &SkyRadiance, heading: f32) -> ModelSkyKey {
        ModelSkyKey(glam::Mat3::from_mat4(placement).to_cols_array().map(f32::to_bits), *radiance, heading.to_bits())
    }
}

/// How many lights' ground maps a placement's ground keeps: two compositors drawing the model
/// under two lights (`bench frame`'s moving sun beside its other paths, each frame) each find
/// their own instead of recombining it every frame (45 ms of the dragon's CPU frame when it
/// was found, a few ms since `GroundTransfer::under`).
const GROUND_LIGHTS_KEPT: usize = 2;

/// How far the model's light on the ground (a gain on the ground's light) may differ from a kept
/// map's before the map is made again: half an 8-bit level (a gain g brightens an sRGB value by
/// at most 255 · 1.055/2.4 · g levels, render::passes::ground::INVISIBLE_LOSS's rule). The sun
/// SPA gives for the clock moves every frame (0.25° a minute): the map follows it once its
/// light has moved that far (tens of seconds to minutes, by how much light the model sends onto
/// the ground: BounceReach) instead of being made again each frame.
pub const GROUND_BOUNCE_KEPT: f32 = 0.5 / (255.0 * 1.055 / 2.4);

/// The last placement's ground: the model matrix's bits, its transfer and the reach of its
/// bounce sums, and the lights last asked for with their maps (the latest first).
struct Ground {
    bits: PlacementKey,
    transfer: GroundTransfer,
    reach: BounceReach,
    maps: Vec<(GroundLight, Arc<GroundSky>)>,
}

impl Ground {
    fn new(bits: PlacementKey, transfer: GroundTransfer) -> Ground {
        let reach = BounceReach::of(&transfer.texels);
        Ground { bits, transfer, reach, maps: Vec::with_capacity(GROUND_LIGHTS_KEPT) }
    }

    /// Whether the map kept for `held` serves `light`: the same sky, and the model's light on
    /// every texel within [`GROUND_BOUNCE_KEPT`] of `light`'s ([`BounceReach::bound`]).
    fn serves(&self, held: &GroundLight, light: &GroundLight) -> bool {
        held.radiance == light.radiance
            && held.heading == light.heading
            && self.reach.bound(&held.bounce, &light.bounce) <= GROUND_BOUNCE_KEPT
    }

    /// The map under `light`: a kept one that serves it ([`Ground::serves`]), else recombined
    /// from the transfer (counted in `computed`), replacing the one asked for least recently.
    fn map(&mut self, light: GroundLight, computed: &AtomicUsize) -> Arc<GroundSky> {
        let at = match self.maps.iter().position(|(held, _)| self.serves(held, &light)) {
            Some(at) => at,
            None => {
                let sky = Arc::new(self.transfer.under(&light.radiance, light.heading, &light.bounce));
                computed.fetch_add(1, Relaxed);
                self.maps.truncate(GROUND_LIGHTS_KEPT - 1);
                self.maps.push((light, sky));
                self.maps.len() - 1
            }
        };
        self.maps[..=at].rotate_right(1);
        self.maps[0].1.clone()
    }
}

/// The ground's transfers: the last placement's, and the one being cast for a newer placement.
#[derive(Default)]
struct GroundState {
    last: Option<Ground>,
    worker: GroundWorker,
}

/// What a model's upload needs, computed once per model content.
pub struct PreparedModel {
    pub key: ModelKey,
    /// Bounds in model space.
    pub bounds: (Vec3, Vec3),
    /// Per mesh, its interleaved vertices with ambient occlusion (empty for a mesh without
    /// triangles).
    pub vertices: Vec<Vec<Vertex>>,
    pub chain: LodChain,
    /// The model's mean diffuse albedo (linear RGB, occlusion::mean_albedo): what it reflects
    /// onto the ground.
    pub albedo: [f32; 3],
    model: Model,
    colour: OnceLock<std::result::Result<ColourStats, String>>,
    occluders: Arc<Occluders>,
    /// What each vertex's rays passed and met (one cast at load): its sky and bounce under any
    /// sky and placement ([`PreparedModel::vertices_under`]).
    rays: ModelRays,
    /// The vertices under the last placement and sky asked for.
    sky: Mutex<Option<(ModelSkyKey, MeshVertices)>>,
    /// Vertex sets made for a new placement or sky.
    sky_computed: AtomicUsize,
    /// A vertex set being made on a thread of its own
    /// ([`PreparedModel::vertices_under_without_waiting`]).
    sky_busy: AtomicBool,
    /// The ground under the last placement and sky asked for, and the cast of a newer one.
    ground: Mutex<GroundState>,
    /// Ground transfers cast, casts a caller waited for, and maps recombined.
    ground_cast: AtomicUsize,
    ground_waited: AtomicUsize,
    ground_computed: AtomicUsize,
}

impl PreparedModel {
    /// Check `model`, then compute its vertices with ambient occlusion and its level chain.
    pub fn new(model: &Model) -> Result<PreparedModel> {
        let bounds = model.bounds().ok_or_else(|| anyhow!("the model has no vertices"))?;
        if !(bounds.0.is_finite() && bounds.1.is_finite()) {
            bail!("the model has non-finite vertex positions");
        }
        if model.triangle_count() == 0 {
            bail!("the model has no triangles");
        }
        // Checked before simplifying: the simplifier indexes the vertices.
        let mut vertices =
            model.meshes.iter().map(|m| if m.indices.is_empty() { Ok(Vec::new()) } else { interleave(m) }).collect::<Result<Vec<_>>>()?;
        if let Some(m) = model.meshes.iter().find(|m| model.materials.get(m.material).is_none()) {
            bail!("a mesh refers to missing material {}", m.material);
        }
        // Each vertex's share of the sky and of the ground's light past the model itself
        // (occluders reflect light too: the multi-bounce fit for the mesh material's albedo),
        // and the bent normal its sky is looked up along.
        let mut occluders = Occluders::of_model(model);
        let (shares, rays) = occlusion::model_light(model, &occluders);
        // What lights each triangle, for the light the model reflects onto the ground.
        occluders.attach_light_shares(model, &shares);
        for (vertices, ao) in vertices.iter_mut().zip(shares) {
            for (v, a) in vertices.iter_mut().zip(ao) {
                v.ao = a.ao;
                // A vertex whose rays are unknown (no normal) keeps its normal.
                if a.bent != [0.0; 3] {
                    v.bent = a.bent;
                }
            }
        }
        Ok(PreparedModel {
            key: ModelKey::of(model),
            bounds,
            vertices,
            chain: LodChain::build(model),
            albedo: occlusion::mean_albedo(model),
            model: model.clone(),
            colour: OnceLock::new(),
            occluders: Arc::new(occluders),
            rays,
            sky: Mutex::default(),
            sky_computed: Default::default(),
            sky_busy: Default::default(),
            ground: Mutex::default(),
            ground_cast: Default::default(),
            ground_waited: Default::default(),
            ground_computed: Default::default(),
        })
    }

    /// Per mesh, its vertices under a sky of radiance `radiance` turned by `heading` (as
    /// [`GroundLight`]'s), the model placed by `placement` (model space → world; its translation
    /// is not used): each vertex's bent normal scaled to the length of its normal times the sky's
    /// light it gets (occlusion::ModelRays::sky: through its own open rays, plus what the model's
    /// own surfaces reflect of it; irradiance over π relative to the sky's mean radiance), which
    /// shaders/sh9_ggx.wgsl reads as the bent normal's length over the normal's. Made from the
    /// rays kept at load (no ray is cast); the same `Arc` comes back while the placement's
    /// rotation and the sky stay (counted in [`PreparedModel::sky_computed`] when made).
    pub fn vertices_under(&self, placement: Mat4, radiance: &SkyRadiance, heading: f32) -> MeshVertices {
        let key = ModelSkyKey::of(placement, radiance, heading);
        if let Some(v) = self.held_vertices(key).and_then(|(same, v)| same.then_some(v)) {
            return v;
        }
        // Made without the lock held, so that a caller that does not wait
        // (vertices_under_without_waiting) gets the last set meanwhile.
        let frame = glam::Mat3::from_mat4(placement);
        // The sky's luminance (what the vertex's share of it is: the bent normal's length) and
        // its colour channels (the tint), through each vertex's rays in one walk.
        let sky = self.rays.sky_channels(&self.model, &|d| radiance.towards((frame * d).normalize_or_zero(), heading), occlusion::BOUNCES);
        let vertices: Vec<Vec<Vertex>> = self
            .vertices
            .iter()
            .zip(sky)
            .map(|(vs, s)| {
                vs.iter()
                    .zip(s)
                    .map(|(v, [s, r, g, b])| {
                        let n = Vec3::from(v.normal);
                        let bent = Vec3::from(v.bent).normalize_or(n.normalize_or_zero()) * s.max(1e-4) * n.length();
                        let rgb = [r, g, b];
                        let l = crate::colour::luminance_bt709(rgb);
                        let tint = if l > 1e-6 { rgb.map(|c| c / l) } else { [0.0; 3] };
                        Vertex { bent: bent.to_array(), tint, ..*v }
                    })
                    .collect()
            })
            .collect();
        let vertices = Arc::new(vertices);
        self.sky_computed.fetch_add(1, Relaxed);
        *self.sky.lock().unwrap_or_else(|p| p.into_inner()) = Some((key, vertices.clone()));
        vertices
    }

    /// The vertices made last, and whether they were made for `key`.
    fn held_vertices(&self, key: ModelSkyKey) -> Option<(bool, MeshVertices)> {
        self.sky.lock().unwrap_or_else(|p| p.into_inner()).as_ref().map(|(k, v)| (*k == key, v.clone()))
    }

    /// [`PreparedModel::vertices_under`] for the live view: the vertices of a new turn or sky
    /// are made on a thread of their own while the set made last is returned, so that turning
    /// the model never holds a frame (54–63 ms for the dragon, release, on a 2-core machine: the
    /// ground's map does the same on its worker). The first set, with none made before, is made
    /// here. While a set is being made, newer turns start nothing; the next call after it is
    /// done starts the latest.
    pub fn vertices_under_without_waiting(self: &Arc<Self>, placement: Mat4, radiance: &SkyRadiance, heading: f32) -> MeshVertices {
        let last = match self.held_vertices(ModelSkyKey::of(placement, radiance, heading)) {
            Some((true, v)) => return v,
            Some((false, v)) => v,
            None => return self.vertices_under(placement, radiance, heading),
        };
        if !self.sky_busy.swap(true, AcqRel) {
            let (me, radiance) = (Arc::clone(self), *radiance);
            let made = std::thread::Builder::new().name("previz-model-sky".into()).spawn(move || {
                me.vertices_under(placement, &radiance, heading);
                me.sky_busy.store(false, Release);
            });
            if made.is_err() {
                // No thread to be had: make it here, as a composite does.
                self.sky_busy.store(false, Release);
                return self.vertices_under(placement, &radiance, heading);
            }
        }
        last
    }

    /// Whether a vertex set is being made on its own thread.
    pub fn sky_pending(&self) -> bool {
        self.sky_busy.load(Acquire)
    }

    /// How many vertex sets [`PreparedModel::vertices_under`] made (for a new placement or sky).
    pub fn sky_computed(&self) -> usize {
        self.sky_computed.load(Relaxed)
    }

    /// Bytes the model keeps per vertex for [`PreparedModel::vertices_under`] (its rays; inner
    /// samples counted with their triangles' vertices).
    pub fn ray_bytes(&self) -> usize {
        self.rays.bytes()
    }

    /// Colour statistics of the model's texture (or diffuse colours), the colour correction's
    /// target, or the reason there are none (every texel masked out): computed on the first call.
    pub fn colour(&self) -> &std::result::Result<ColourStats, String> {
        self.colour.get_or_init(|| crate::priors::model_priors(&self.model).map(|p| p.stats).map_err(|e| format!("{e:#}")))
    }

    /// Whether [`PreparedModel::colour`] has been computed.
    pub fn colour_computed(&self) -> bool {
        self.colour.get().is_some()
    }

    /// The ground's sky visibility under the model placed by `placement` (model space → world)
    /// under a sky of radiance `light.radiance` turned by `light.heading`, with the light the
    /// model reflects onto it (`light.bounce`, [`GroundLight`]), over
    /// [`occlusion::GROUND_TEXELS`]² texels. The rays ([`occlusion::GROUND_RAYS`] a texel) are
    /// cast once per placement into a transfer ([`ground_worker::cast`]: each ray kept with its
    /// world direction); a new light only recombines it: each ray weighted by the sky's binned
    /// radiance, and the bounce's sums (no ray). The same `Arc` comes back while the placement
    /// and the light stay, so `Arc::ptr_eq` with the one uploaded says whether to upload. Waits
    /// for the rays of a new placement, cast here (after any cast still running on the worker):
    /// what a single composite needs.
    pub fn ground_sky(&self, placement: Mat4, light: impl Into<GroundLight>) -> Arc<GroundSky> {
        let light = light.into();
        let mut state = self.lock_ground();
        self.adopt_finished(&mut state);
        // A cast still running first: this placement's is the one wanted, and another's would
        // replace this one's as the last placement's when it finished.
        if let Some((bits, transfer)) = state.worker.wait() {
            self.ground_waited.fetch_add(1, Relaxed);
            self.keep(&mut state, bits, transfer);
        }
        let key = placement_key(placement);
        if state.last.as_ref().is_none_or(|g| g.bits != key) {
            let transfer = ground_worker::cast(&self.occluders, self.bounds, placement);
            self.ground_waited.fetch_add(1, Relaxed);
            self.keep(&mut state, key, transfer);
        }
        state.last.as_mut().expect("the placement's ground, just made").map(light, &self.ground_computed)
    }

    /// [`PreparedModel::ground_sky`] without waiting for rays (the live view: a turn or a scale
    /// of the model must not hold the frame): for a new placement the transfer is cast on the
    /// [`GroundWorker`]'s thread and the previous placement's map (under `light`) comes back
    /// until it is ready; a later call finds it. Only the very first placement, with no map to
    /// keep, waits.
    pub fn ground_sky_without_waiting(&self, placement: Mat4, light: impl Into<GroundLight>) -> Arc<GroundSky> {
        let light = light.into();
        let mut state = self.lock_ground();
        self.adopt_finished(&mut state);
        let key = placement_key(placement);
        match state.last.as_ref().map(|g| g.bits == key) {
            None => {
                drop(state);
                return self.ground_sky(placement, light);
            }
            // Not started when the worker is casting another placement: that one first (then
            // kept as the nearer previous map), this one on a later call.
            Some(false) => {
                state.worker.start(self.occluders.clone(), self.bounds, placement);
            }
            Some(true) => {}
        }
        state.last.as_mut().expect("a placement's ground is kept").map(light, &self.ground_computed)
    }

    /// Whether a ground transfer is being cast on the worker's thread.
    pub fn ground_pending(&self) -> bool {
        self.lock_ground().worker.busy().is_some()
    }

    /// Wait for the worker's transfer, if one is being cast, and keep it as the last placement's
    /// (tests and benchmarks that want it before the next frame; the live view lets it finish).
    pub fn finish_ground(&self) {
        let mut state = self.lock_ground();
        if let Some((bits, transfer)) = state.worker.wait() {
            self.keep(&mut state, bits, transfer);
        }
    }

    /// A finished worker's transfer becomes the last placement's (newer than the one kept).
    fn adopt_finished(&self, state: &mut GroundState) {
        if let Some((bits, transfer)) = state.worker.finished() {
            self.keep(state, bits, transfer);
        }
    }

    /// Keep a newly cast transfer as the last placement's.
    fn keep(&self, state: &mut GroundState, bits: PlacementKey, transfer: GroundTransfer) {
        self.ground_cast.fetch_add(1, Relaxed);
        state.last = Some(Ground::new(bits, transfer));
    }

    fn lock_ground(&self) -> MutexGuard<'_, GroundState> {
        self.ground.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// How many times [`PreparedModel::ground_sky`] made a map (for a new placement or sky).
    pub fn ground_sky_computed(&self) -> usize {
        self.ground_computed.load(Relaxed)
    }

    /// How many ground transfers have been cast and kept (one per new placement), on the
    /// caller's thread or the worker's.
    pub fn ground_rays_cast(&self) -> usize {
        self.ground_cast.load(Relaxed)
    }

    /// How many times a call for the ground's map waited for rays (cast them, or waited for the
    /// worker casting them): [`PreparedModel::ground_sky`] on each new placement,
    /// [`PreparedModel::ground_sky_without_waiting`] only on the first.
    pub fn ground_waits(&self) -> usize {
        self.ground_waited.load(Relaxed)
    }
}

/// A mesh's vertices interleaved for the vertex buffer (ambient occlusion 1, the bent normal the
/// normal), after checking that
/// its attribute arrays agree and its indices stay inside them (missing uvs become (0, 0)).
pub fn interleave(mesh: &Mesh) -> Result<Vec<Vertex>> {
    let n = mesh.positions.len();
    if mesh.normals.len() != n || (!mesh.uvs.is_empty() && mesh.uvs.len() != n) {
        bail!("a mesh has {n} positions but {} normals and {} uvs", mesh.normals.len(), mesh.uvs.len());
    }
    if let Some(&bad) = mesh.indices.iter().find(|&&i| i as usize >= n) {
        bail!("a mesh index ({bad}) points past its {n} vertices");
    }
    Ok((0..n)
        .map(|i| Vertex {
            position: mesh.positions[i],
            normal: mesh.normals[i],
            uv: mesh.uvs.get(i).copied().unwrap_or([0.0, 0.0]),
            ao: [1.0, 1.0, 1.0, 0.0],
            bent: mesh.normals[i],
            tint: [0.0; 3],
        })
        .collect())
}

/// How often the cache computed and reused a model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CacheCounts {
    pub computed: usize,
    pub reused: usize,
}

/// The prepared models of one device: the [`CAPACITY`] used last (most recent last), and every
/// one still held by someone (a compositor drawing it is never made to prepare it again).
#[derive(Default)]
pub struct ModelCache {
    state: Mutex<CacheState>,
}

#[derive(Default)]
struct CacheState {
    recent: Vec<Arc<PreparedModel>>,
    held: Vec<std::sync::Weak<PreparedModel>>,
    counts: CacheCounts,
}

impl CacheState {
    fn find(&mut self, key: ModelKey) -> Option<Arc<PreparedModel>> {
        if let Some(i) = self.recent.iter().position(|p| p.key == key) {
            let hit = self.recent.remove(i);
            self.recent.push(hit.clone());
            return Some(hit);
        }
        let hit = self.held.iter().filter_map(std::sync::Weak::upgrade).find(|p| p.key == key)?;
        self.keep(hit.clone());
        Some(hit)
    }

    /// Make `p` the most recently used (the oldest goes past [`CAPACITY`]).
    fn keep(&mut self, p: Arc<PreparedModel>) {
        if self.recent.len() >= CAPACITY {
            self.recent.remove(0);
        }
        self.recent.push(p);
    }
}

impl ModelCache {
    /// The cache of `gpu`'s device.
    pub fn of(gpu: &Gpu) -> Result<Arc<ModelCache>> {
        gpu.shared("the model cache", |_| Ok(ModelCache::default()))
    }

    /// The prepared `model`: the cached one when a model of the same content was prepared
    /// before, else computed now (outside the lock: two threads may prepare different models
    /// at once). A model that fails its checks is not cached.
    pub fn prepare(&self, model: &Model) -> Result<Arc<PreparedModel>> {
        let key = ModelKey::of(model);
        {
            let mut state = self.lock();
            if let Some(hit) = state.find(key) {
                state.counts.reused += 1;
                return Ok(hit);
            }
        }
        let prepared = Arc::new(PreparedModel::new(model)?);
        let mut state = self.lock();
        state.recent.retain(|p| p.key != key);
        state.held.retain(|w| w.strong_count() > 0);
        state.held.push(Arc::downgrade(&prepared));
        state.keep(prepared.clone());
        state.counts.computed += 1;
        Ok(prepared)
    }

    pub fn counts(&self) -> CacheCounts {
        self.lock().counts
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, CacheState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Material;

    /// A closed tetrahedron (4 triangles) with one material.
    fn tetrahedron() -> Model {
        let positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let normals = positions.iter().map(|p: &[f32; 3]| Vec3::from(*p).normalize_or(Vec3::NEG_ONE.normalize()).to_array()).collect();
        let mesh = Mesh { positions, normals, uvs: vec![], indices: vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3], material: 0 };
        Model { meshes: vec![mesh], materials: vec![Material::default()] }
    }

    fn triangle() -> Mesh {
        Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            uvs: vec![],
            indices: vec![0, 1, 2],
            material: 0,
        }
    }

    #[test]
    fn interleave_checks_the_mesh() {
        let v = interleave(&triangle()).unwrap();
        assert_eq!(v.len(), 3);
        assert_eq!((v[1].position, v[1].normal, v[1].uv), ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0]));
        let mut m = triangle();
        m.indices[2] = 3;
        assert!(format!("{:#}", interleave(&m).unwrap_err()).contains("index (3) points past its 3 vertices"));
        let mut m = triangle();
        m.normals.pop();
        assert!(format!("{:#}", interleave(&m).unwrap_err()).contains("3 positions but 2 normals"));
        let mut m = triangle();
        m.uvs = vec![[0.5, 0.5]];
        assert!(interleave(&m).is_err());
    }

    #[test]
    fn the_same_content_is_prepared_once_and_any_change_prepares_again() {
        let cache = ModelCache::default();
        let model = tetrahedron();
        let a = cache.prepare(&model).unwrap();
        // A copy of the model (another load of the same file) is the same content.
        let b = cache.prepare(&model.clone()).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(cache.counts(), CacheCounts { computed: 1, reused: 1 });
        // A moved vertex, a new colour and a new texel each make a new entry.
        let mut moved = model.clone();
        moved.meshes[0].positions[3][2] = 1.5;
        let mut recoloured = model.clone();
        recoloured.materials[0].diffuse[1] = 0.1;
        let mut textured = model.clone();
        textured.materials[0].texture = Some(crate::scene::Rgba8Image { width: 1, height: 1, pixels: vec![9, 9, 9, 255] });
        for changed in [&moved, &recoloured, &textured] {
            let c = cache.prepare(changed).unwrap();
            assert!(!Arc::ptr_eq(&a, &c));
        }
        assert_eq!(cache.counts(), CacheCounts { computed: 4, reused: 1 });
        // The moved vertex is in the new entry's vertices and bounds.
        assert_eq!(cache.prepare(&moved).unwrap().bounds.1.z, 1.5);
        // The original is still cached (capacity 8).
        assert!(Arc::ptr_eq(&a, &cache.prepare(&model).unwrap()));
        assert_eq!(cache.counts(), CacheCounts { computed: 4, reused: 3 });
    }

    #[test]
    fn the_least_recently_used_model_goes_first() {
        let cache = ModelCache::default();
        let models: Vec<Model> = (0..=CAPACITY)
            .map(|i| {
                let mut m = tetrahedron();
                m.meshes[0].positions[3][2] = 1.0 + i as f32;
                m
            })
            .collect();
        let first = cache.prepare(&models[0]).unwrap();
        for m in &models[1..CAPACITY] {
            cache.prepare(m).unwrap();
        }
        // Using the first again makes the second the oldest; one more model evicts the second
        // (nobody holds it any more).
        cache.prepare(&models[0]).unwrap();
        cache.prepare(&models[CAPACITY]).unwrap();
        assert_eq!(cache.counts(), CacheCounts { computed: CAPACITY + 1, reused: 1 });
        assert!(Arc::ptr_eq(&first, &cache.prepare(&models[0]).unwrap()));
        cache.prepare(&models[1]).unwrap();
        assert_eq!(cache.counts(), CacheCounts { computed: CAPACITY + 2, reused: 2 });
        // A model still held (a compositor drawing it) is found even after leaving the recent
        // ones: `first` is pushed out by CAPACITY others, then asked for again.
        for m in &models[2..] {
            cache.prepare(m).unwrap();
        }
        let mut other = tetrahedron();
        other.meshes[0].positions[3][2] = -1.0;
        cache.prepare(&other).unwrap();
        let before = cache.counts();
        assert!(Arc::ptr_eq(&first, &cache.prepare(&models[0]).unwrap()));
        assert_eq!(cache.counts(), CacheCounts { computed: before.computed, reused: before.reused + 1 });
    }

    #[test]
    fn a_bad_model_is_an_error_and_not_cached() {
        let cache = ModelCache::default();
        let mut bad = tetrahedron();
        bad.meshes[0].indices[5] = 9;
        let err = cache.prepare(&bad).err().unwrap();
        assert!(format!("{err:#}").contains("index (9) points past its 4 vertices"), "{err:#}");
        let mut no_material = tetrahedron();
        no_material.meshes[0].material = 3;
        assert!(format!("{:#}", cache.prepare(&no_material).err().unwrap()).contains("missing material 3"));
        assert_eq!(cache.counts(), CacheCounts::default());
    }

    #[test]
    fn colour_statistics_wait_for_the_first_request() {
        let prepared = PreparedModel::new(&tetrahedron()).unwrap();
        assert!(!prepared.colour_computed());
        // Untextured: the statistics of the diffuse colour (0.8 grey, linear).
        let stats = prepared.colour().as_ref().unwrap();
        assert!(prepared.colour_computed());
        assert!(std::ptr::eq(stats, prepared.colour().as_ref().unwrap()));
    }

    /// A sky of radiance 1.5 over the map's eastern half (azimuths 0–180°) and 0.5 over its
    /// western, with `bright` in one bin low in the North-East (row 0, 45°–56.25°).
    fn east_sky(bright: f32) -> SkyRadiance {
        let mut bins = [0.5; crate::light::sh9::SKY_BINS];
        for (i, b) in bins.iter_mut().enumerate() {
            if i % crate::light::sh9::SKY_COLUMNS < crate::light::sh9::SKY_COLUMNS / 2 {
                *b = 1.5;
            }
        }
        bins[4] = bright;
        SkyRadiance { bins, ..SkyRadiance::UNIFORM }
    }

    #[test]
    fn the_models_sky_is_made_once_per_turn_and_sky() {
        let prepared = PreparedModel::new(&tetrahedron()).unwrap();
        let sky = east_sky(4.0);
        let here = Mat4::from_translation(Vec3::new(1.0, 2.0, 0.0));
        let a = prepared.vertices_under(here, &sky, 0.0);
        // Moved, not turned: the same vertices.
        assert!(Arc::ptr_eq(&a, &prepared.vertices_under(Mat4::from_translation(Vec3::X), &sky, 0.0)));
        assert_eq!(prepared.sky_computed(), 1);
        // The sky turned by the map's heading, or the model turned: made again, and different
        // (the sky's bright side is elsewhere); the bent normals keep their directions.
        let b = prepared.vertices_under(here, &sky, 2.0);
        let c = prepared.vertices_under(Mat4::from_rotation_z(2.0) * here, &sky, 0.0);
        assert_eq!(prepared.sky_computed(), 3);
        let length = |v: &Vertex| Vec3::from(v.bent).length() / Vec3::from(v.normal).length();
        let lengths = |vs: &Arc<Vec<Vec<Vertex>>>| vs[0].iter().map(length).collect::<Vec<_>>();
        assert_ne!(lengths(&a), lengths(&b));
        assert_ne!(lengths(&a), lengths(&c));
        for (v, w) in a[0].iter().zip(&b[0]) {
            assert!(Vec3::from(v.bent).normalize().distance(Vec3::from(w.bent).normalize()) < 1e-5);
        }
        // Nothing hides a tetrahedron's outward faces from the sky but its own base: each vertex
        // gets some of it.
        assert!(lengths(&a).iter().all(|&l| l > 0.0 && l.is_finite()), "{:?}", lengths(&a));
    }

    #[test]
    fn a_turn_keeps_the_previous_sky_while_its_vertices_are_made_on_their_thread() {
        let model = tetrahedron();
        let prepared = Arc::new(PreparedModel::new(&model).unwrap());
        let sky = east_sky(4.0);
        let here = Mat4::from_scale(Vec3::splat(2.0));
        let turned = Mat4::from_rotation_z(0.7) * here;
        let bytes = |v: &MeshVertices| v.iter().map(|m| bytemuck::cast_slice::<Vertex, u8>(m).to_vec()).collect::<Vec<_>>();
        // The set each turn gets when the caller waits (a fresh cache).
        let waited = |placement: Mat4| bytes(&PreparedModel::new(&model).unwrap().vertices_under(placement, &sky, 0.0));
        // The first turn has no set to keep: made here.
        let first = prepared.vertices_under_without_waiting(here, &sky, 0.0);
        assert_eq!(prepared.sky_computed(), 1);
        assert_eq!(bytes(&first), waited(here));
        // A turn: the previous set comes back and the turn's is made on its own thread.
        let during = prepared.vertices_under_without_waiting(turned, &sky, 0.0);
        assert!(Arc::ptr_eq(&during, &first));
        // Wait for the condition (the thread done), not for a time.
        let start = std::time::Instant::now();
        while prepared.sky_pending() {
            assert!(start.elapsed() < std::time::Duration::from_secs(60), "the turn's vertices never arrived");
            std::thread::yield_now();
        }
        assert_eq!(prepared.sky_computed(), 2);
        let arrived = prepared.vertices_under_without_waiting(turned, &sky, 0.0);
        assert_eq!(bytes(&arrived), waited(turned));
        assert!(!Arc::ptr_eq(&arrived, &first));
        // Kept while the turn stays: nothing more made.
        assert!(Arc::ptr_eq(&arrived, &prepared.vertices_under_without_waiting(turned, &sky, 0.0)));
        assert_eq!((prepared.sky_computed(), prepared.sky_pending()), (2, false));
    }

    #[test]
    fn the_ground_map_is_computed_once_per_placement() {
        let prepared = PreparedModel::new(&tetrahedron()).unwrap();
        let uniform = GroundLight::from(SkyRadiance::UNIFORM);
        let here = Mat4::from_translation(Vec3::new(1.0, 2.0, 0.0));
        let a = prepared.ground_sky(here, uniform);
        let b = prepared.ground_sky(here, uniform);
        assert!(Arc::ptr_eq(&a, &b) && prepared.ground_sky_computed() == 1);
        // Moved: computed again, and the square follows the model.
        let there = Mat4::from_translation(Vec3::new(3.0, 2.0, 0.0));
        let c = prepared.ground_sky(there, uniform);
        assert_eq!(prepared.ground_sky_computed(), 2);
        assert!(((c.min + c.max) * 0.5 - (a.min + a.max) * 0.5 - glam::Vec2::new(2.0, 0.0)).length() < 1e-5);
        // Back to the first placement: the map is computed again (only the last is kept), equal.
        let d = prepared.ground_sky(here, uniform);
        assert_eq!(prepared.ground_sky_computed(), 3);
        assert_eq!(*d, *a);
        // A sky brighter in the East weights the rays differently: computed again; the same sky
        // again keeps it.
        let east = GroundLight::from(east_sky(1.5));
        let e = prepared.ground_sky(here, east);
        assert!(Arc::ptr_eq(&e, &prepared.ground_sky(here, east)) && prepared.ground_sky_computed() == 4);
        // Each placement cast its rays once; the sky's change recombined them without a ray.
        assert_eq!(prepared.ground_rays_cast(), 3);
        assert_ne!(e.visibility, d.visibility);
        // The same sky turned, and the first one again (two lights are kept: the uniform sky's
        // map went when the turned sky's came): two more maps, no more rays.
        let turned = GroundLight { heading: 1.0, ..east };
        let f = prepared.ground_sky(here, turned);
        assert_ne!(f.visibility, e.visibility);
        assert_eq!(*prepared.ground_sky(here, uniform), *a);
        assert_eq!((prepared.ground_sky_computed(), prepared.ground_rays_cast()), (6, 3));
        // The turned sky is kept beside the uniform one: two lights alternating frame by frame
        // (two compositors of one model) make nothing more; the East sky went, so it is made again.
        for _ in 0..3 {
            assert!(Arc::ptr_eq(&prepared.ground_sky(here, turned), &f));
            assert_eq!(*prepared.ground_sky(here, uniform), *a);
        }
        assert_eq!(prepared.ground_sky_computed(), 6);
        assert_eq!(*prepared.ground_sky(here, east), *e);
        assert_eq!(prepared.ground_sky_computed(), 7);
    }

    /// The sun SPA gives for the clock moves a little every frame: the map made for it is kept
    /// while the model's light on the ground stays within GROUND_BOUNCE_KEPT of it, and made
    /// again once the sun has moved so far that some texel's light moved by more.
    #[test]
    fn the_ground_map_follows_a_moving_sun_only_when_its_light_moves_visibly() {
        let prepared = PreparedModel::new(&tetrahedron()).unwrap();
        let here = Mat4::from_scale(Vec3::splat(2.0));
        let s = Vec3::new(0.6, 0.0, 0.8);
        let sunlit = |a: f32| GroundLight {
            bounce: BounceLight { sun: [2.0; 3], sun_dir: (glam::Quat::from_rotation_z(a) * s).to_array(), ..BounceLight::NONE },
            ..GroundLight::from(SkyRadiance::UNIFORM)
        };
        let first = prepared.ground_sky(here, sunlit(0.0));
        // 30 frames at 30 a second of the sun's 0.25° a minute: 2.2e-5 rad.
        for frame in 1..=30 {
            let sky = prepared.ground_sky(here, sunlit(frame as f32 * 7.3e-7));
            assert!(Arc::ptr_eq(&sky, &first), "frame {frame}");
        }
        assert_eq!(prepared.ground_sky_computed(), 1);
        // A quarter turn round the vertical: made again, and some texel's light moved by more
        // than the map may be off.
        let moved = prepared.ground_sky(here, sunlit(std::f32::consts::FRAC_PI_2));
        assert_eq!(prepared.ground_sky_computed(), 2);
        let most =
            moved.bounce.iter().zip(&first.bounce).flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs())).fold(0.0f32, f32::max);
        assert!(most > GROUND_BOUNCE_KEPT, "{most}");
    }

    #[test]
    fn a_turn_keeps_the_previous_map_while_its_rays_are_cast_on_the_worker() {
        let model = tetrahedron();
        let prepared = PreparedModel::new(&model).unwrap();
        let shape = GroundLight::from(east_sky(4.0));
        let here = Mat4::from_scale(Vec3::splat(2.0));
        let turned = Mat4::from_rotation_z(0.7) * here;
        let scaled = Mat4::from_scale(Vec3::splat(3.0));
        // The map each placement gets when the caller waits for its rays (a fresh cache).
        let waited = |placement: Mat4| PreparedModel::new(&model).unwrap().ground_sky(placement, shape);
        // The first placement has no map to keep: it waits.
        let first = prepared.ground_sky_without_waiting(here, shape);
        assert_eq!((prepared.ground_waits(), prepared.ground_rays_cast()), (1, 1));
        assert_eq!(*first, *waited(here));
        // A turn: the call comes back with the previous placement's map, its own rays left to the
        // worker; a scale asked for before they are in starts nothing more.
        let during = prepared.ground_sky_without_waiting(turned, shape);
        assert!(Arc::ptr_eq(&during, &first));
        assert!(Arc::ptr_eq(&prepared.ground_sky_without_waiting(scaled, shape), &first));
        assert_eq!((prepared.ground_waits(), prepared.ground_rays_cast()), (1, 1));
        // The turn's transfer arrives (kept as the nearer previous map, under any sky) and the
        // scale's is started from it; then the scale's arrives: each the map of a waiting caller.
        prepared.finish_ground();
        assert!(!prepared.ground_pending());
        let nearer = prepared.ground_sky_without_waiting(scaled, shape);
        assert_eq!(*nearer, *waited(turned));
        assert_ne!(nearer.visibility, first.visibility);
        assert!(prepared.ground_pending());
        prepared.finish_ground();
        let arrived = prepared.ground_sky_without_waiting(scaled, shape);
        assert_eq!(*arrived, *waited(scaled));
        assert!(Arc::ptr_eq(&arrived, &prepared.ground_sky_without_waiting(scaled, shape)));
        // No call after the first waited for a ray; three placements, three casts.
        assert_eq!((prepared.ground_waits(), prepared.ground_rays_cast()), (1, 3));
        // A caller that waits, asking while the worker casts its placement (or once it is done),
        // takes that cast instead of casting again.
        prepared.ground_sky_without_waiting(here, shape);
        assert_eq!(*prepared.ground_sky(here, shape), *first);
        assert_eq!(prepared.ground_rays_cast(), 4);
    }

    #[test]
    fn the_recombined_ground_map_is_the_one_each_sky_would_cast() {
        // A sky brighter in the East with one bin 20× the West's low in the North-East, at two
        // headings, under a turned and scaled tetrahedron: the map made from the transfer against
        // the map cast directly with the sky's radiance (scene::occlusion::ground_sky_direct),
        // every texel.
        let model = tetrahedron();
        let prepared = PreparedModel::new(&model).unwrap();
        let occluders = Occluders::of_model(&model);
        let placement = Mat4::from_rotation_z(0.5) * Mat4::from_scale(Vec3::splat(2.0));
        let sky = east_sky(10.0);
        let mut maps = Vec::new();
        for heading in [0.0, 2.0] {
            let map = prepared.ground_sky(placement, GroundLight { heading, ..GroundLight::from(sky) });
            let direct = occlusion::ground_sky_direct(
                &occluders,
                prepared.bounds,
                placement,
                occlusion::GROUND_TEXELS,
                occlusion::GROUND_RAYS,
                &|d| sky.towards(d, heading)[0],
            );
            let diffs: Vec<f32> = map.visibility.iter().zip(&direct.visibility).map(|(a, b)| (a - b).abs()).collect();
            let (max, mean) = (diffs.iter().copied().fold(0.0f32, f32::max), diffs.iter().sum::<f32>() / diffs.len() as f32);
            // A ray's azimuth is kept to 1/65536 turn: at a heading that puts a bin's edge inside
            // a step, a ray there may change bins. Measured: 0 at heading 0; largest 1.3e-4, mean
            // 2.0e-7 at heading 2.
            assert!(max < 5e-4 && mean < 1e-6, "heading {heading}: largest {max}, mean {mean}");
            assert!(map.visibility.iter().copied().fold(1.0, f32::min) < 0.5, "the tetrahedron hides the sky near it");
            maps.push(map);
        }
        assert_eq!(prepared.ground_rays_cast(), 1);
        // The heading matters: the sky's bright side moved.
        let moved = maps[0].visibility.iter().zip(&maps[1].visibility).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(moved > 0.01, "{moved}");
    }
}
