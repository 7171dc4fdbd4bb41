//! The environment on the GPU: the cube map as half floats (linear light after exposure) and
//! what the frame maths needs from it (hemisphere priors, colour statistics, heading). The CPU
//! work on the map's content (the GGX-prefiltered levels, the colour priors at an exposure) is
//! done once per content and device ([`EnvironmentCache`]), not once per compositor.

use super::params::HemispherePriors;
use crate::colour::stats::ColourStats;
use crate::gpu::{Gpu, build};
use crate::light::ggx;
use crate::priors;
use crate::scene::{CubeMap, FACE_NAMES};
use anyhow::{Context, Result, bail};
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex};

/// Environments whose derived data a device keeps (the least recently used goes first).
pub const ENV_CAPACITY: usize = 4;

/// A cube map's content as a 64-bit hash (SipHash over its size and every texel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EnvKey(u64);

impl EnvKey {
    pub fn of(cube: &CubeMap) -> EnvKey {
        let mut h = std::hash::DefaultHasher::new();
        cube.size.hash(&mut h);
        for face in &cube.faces {
            face.len().hash(&mut h);
            h.write(bytemuck::cast_slice(face));
        }
        EnvKey(h.finish())
    }
}

/// How often the cache computed each kind of work (the rest of the asks were reused).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EnvCounts {
    pub prefiltered: usize,
    pub priors: usize,
    pub reused: usize,
}

/// The GGX-prefiltered levels per environment content and the colour priors per content and
/// exposure, for the [`ENV_CAPACITY`] used last, shared by every compositor on a device
/// ([`EnvironmentCache::of`]). Only CPU results are kept; each compositor uploads its own
/// textures.
#[derive(Default)]
pub struct EnvironmentCache {
    state: Mutex<EnvState>,
}

type PriorsKey = (EnvKey, u32);

#[derive(Default)]
struct EnvState {
    prefiltered: Vec<(EnvKey, Arc<Vec<CubeMap>>)>,
    priors: Vec<(PriorsKey, priors::EnvironmentPriors)>,
    counts: EnvCounts,
}

/// Look `key` up in `list` (most recent last), moving a hit to the end.
fn recent<K: PartialEq, V: Clone>(list: &mut Vec<(K, V)>, key: &K) -> Option<V> {
    let i = list.iter().position(|(k, _)| k == key)?;
    let hit = list.remove(i);
    let v = hit.1.clone();
    list.push(hit);
    Some(v)
}

/// Keep `value` under `key` as the most recent, the oldest going past [`ENV_CAPACITY`].
fn keep<K, V>(list: &mut Vec<(K, V)>, key: K, value: V) {
    if list.len() >= ENV_CAPACITY {
        list.remove(0);
    }
    list.push((key, value));
}

impl EnvironmentCache {
    /// The cache of `gpu`'s device.
    pub fn of(gpu: &Gpu) -> Result<Arc<EnvironmentCache>> {
        gpu.shared("the environment cache", |_| Ok(EnvironmentCache::default()))
    }

    /// `cube`'s GGX-prefiltered levels (light::ggx::prefilter), computed on the first ask for
    /// its content (outside the lock).
    pub fn prefiltered(&self, key: EnvKey, cube: &CubeMap) -> Arc<Vec<CubeMap>> {
        let computed = self.cached(
            |s| &mut s.prefiltered,
            |c| &mut c.prefiltered,
            key,
            || Ok::<_, std::convert::Infallible>(Arc::new(ggx::prefilter(cube))),
        );
        let Ok(levels) = computed;
        levels
    }

    /// `cube`'s colour priors after `exposure` (priors::environment_priors_scaled), computed on
    /// the first ask for its content at that exposure. Errors are not kept.
    pub fn priors(&self, key: EnvKey, cube: &CubeMap, exposure: f32) -> Result<priors::EnvironmentPriors> {
        self.cached(|s| &mut s.priors, |c| &mut c.priors, (key, exposure.to_bits()), || priors::environment_priors_scaled(cube, exposure))
    }

    /// The value under `key` in the list `list` picks out, or `compute`'s (run outside the lock,
    /// counted in the count `computed` picks out, kept only when it succeeds).
    fn cached<K: PartialEq + Copy, V: Clone, E>(
        &self,
        list: fn(&mut EnvState) -> &mut Vec<(K, V)>,
        computed: fn(&mut EnvCounts) -> &mut usize,
        key: K,
        compute: impl FnOnce() -> std::result::Result<V, E>,
    ) -> std::result::Result<V, E> {
        {
            let mut state = self.lock();
            if let Some(hit) = recent(list(&mut state), &key) {
                state.counts.reused += 1;
                return Ok(hit);
            }
        }
        let value = compute()?;
        let mut state = self.lock();
        let kept = list(&mut state);
        kept.retain(|(k, _)| *k != key);
        keep(kept, key, value.clone());
        *computed(&mut state.counts) += 1;
        Ok(value)
    }

    pub fn counts(&self) -> EnvCounts {
        self.lock().counts
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, EnvState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// What the frame needs from the environment besides its texture.
#[derive(Clone)]
pub struct Environment {
    pub priors: HemispherePriors,
    /// Colour statistics of the horizontal faces after exposure, the correction's source.
    pub colour: ColourStats,
    pub exposure: f32,
    /// World heading (radians, clockwise from North) of the cube map's front (+Z) face.
    pub heading: f32,
}

/// One face's (or an equirectangular map's) RGB texels as RGBA16F (alpha 1). The map is
/// radiance: a negative value (which a loader should already have repaired) is clamped to 0, and
/// one above the largest half float (65504; quarry_01's sun reaches 86528) to that, not to
/// infinity, which the sampler's filter would turn into NaN beside it (0 × ∞).
pub fn rgba16f_texels(face: &[[f32; 3]]) -> Vec<half::f16> {
    let max = half::f16::MAX.to_f32();
    face.iter().flat_map(|p| [p[0], p[1], p[2], 1.0]).map(|v| half::f16::from_f32(v.clamp(0.0, max))).collect()
}

/// The environment's views on the GPU.
pub struct EnvironmentViews {
    /// The map as given.
    pub cube: wgpu::TextureView,
    /// The map convolved with the GGX lobe, one mip level per roughness (light::ggx::prefilter).
    pub specular: wgpu::TextureView,
}

/// The environment's textures, made once per face size: the map and its GGX-prefiltered levels.
/// [`EnvironmentTextures::write`] refreshes them in place (write_texture only), so a new map of
/// the same size — a refreshed fold of the camera frame, a capture — allocates nothing and keeps
/// every bind group that holds the views.
pub struct EnvironmentTextures {
    cube: wgpu::Texture,
    specular: wgpu::Texture,
    pub views: EnvironmentViews,
}

impl EnvironmentTextures {
    /// Textures for maps of `size`×`size` faces.
    pub fn new(gpu: &Gpu, size: u32) -> EnvironmentTextures {
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let cube = build::texture(&gpu.device, "environment", (size, size, 6), wgpu::TextureFormat::Rgba16Float, 1, usage);
        let specular = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("prefiltered environment"),
            size: wgpu::Extent3d { width: ggx::PREFILTER_SIZE, height: ggx::PREFILTER_SIZE, depth_or_array_layers: 6 },
            mip_level_count: ggx::PREFILTER_LEVELS,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage,
            view_formats: &[],
        });
        let views = EnvironmentViews { cube: build::cube_view(&cube), specular: build::cube_view(&specular) };
        EnvironmentTextures { cube, specular, views }
    }

    /// Face size of the map these textures hold.
    pub fn size(&self) -> u32 {
        self.cube.width()
    }

    /// Write `cube` (of this size) and its GGX-prefiltered `levels` ([`prepare`]) into the
    /// textures.
    pub fn write(&self, gpu: &Gpu, cube: &CubeMap, levels: &[CubeMap]) -> Result<()> {
        if cube.size != self.size() {
            bail!("environment of {}-texel faces written into textures of {}", cube.size, self.size());
        }
        for (layer, face) in cube.faces.iter().enumerate() {
            build::write_layer(&gpu.queue, &self.cube, layer as u32, bytemuck::cast_slice(&rgba16f_texels(face)));
        }
        if levels.len() != ggx::PREFILTER_LEVELS as usize {
            bail!("{} prefiltered environment levels, expected {}", levels.len(), ggx::PREFILTER_LEVELS);
        }
        for (mip, level) in levels.iter().enumerate() {
            for (layer, face) in level.faces.iter().enumerate() {
                gpu.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.specular,
                        mip_level: mip as u32,
                        origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytemuck::cast_slice(&rgba16f_texels(face)),
                    wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(8 * level.size), rows_per_image: None },
                    wgpu::Extent3d { width: level.size, height: level.size, depth_or_array_layers: 1 },
                );
            }
        }
        Ok(())
    }
}

/// What the GPU and the frame need from a map besides its texels, computed on the CPU (on any
/// thread: the live view prepares its folded camera frame off the frame's thread).
#[derive(Clone)]
pub struct Prepared {
    /// The map convolved with the GGX lobe, one level per roughness (light::ggx::prefilter).
    pub levels: Arc<Vec<CubeMap>>,
    pub env: Environment,
}

/// Check `cube`, `exposure` and `heading`; prefilter the map and compute its priors. For a map
/// that changes every time (the folded camera frame); [`prepare_cached`] for maps that return.
pub fn prepare(cube: &CubeMap, exposure: f32, heading: f32) -> Result<Prepared> {
    check(cube, exposure, heading)?;
    let env_priors = priors::environment_priors_scaled(cube, exposure).context("environment colour priors")?;
    Ok(Prepared { levels: Arc::new(ggx::prefilter(cube)), env: environment(&env_priors, exposure, heading) })
}

/// [`prepare`] through the device's [`EnvironmentCache`]: a content seen before (at the same
/// exposure) is not prefiltered or measured again.
pub fn prepare_cached(gpu: &Gpu, cube: &CubeMap, exposure: f32, heading: f32) -> Result<Prepared> {
    check(cube, exposure, heading)?;
    let cache = EnvironmentCache::of(gpu)?;
    let key = EnvKey::of(cube);
    let env_priors = cache.priors(key, cube, exposure).context("environment colour priors")?;
    Ok(Prepared { levels: cache.prefiltered(key, cube), env: environment(&env_priors, exposure, heading) })
}

fn environment(env_priors: &priors::EnvironmentPriors, exposure: f32, heading: f32) -> Environment {
    Environment { priors: HemispherePriors::from_environment(env_priors), colour: env_priors.horizontal, exposure, heading }
}

/// Reject a non-positive exposure, a non-finite heading and faces of the wrong size.
fn check(cube: &CubeMap, exposure: f32, heading: f32) -> Result<()> {
    if !(exposure.is_finite() && exposure > 0.0) {
        bail!("environment exposure must be a positive number, got {exposure}");
    }
    if !heading.is_finite() {
        bail!("environment heading must be a finite angle");
    }
    let size = cube.size;
    if let Some(layer) = cube.faces.iter().position(|face| face.len() != (size * size) as usize) {
        bail!("cube-map face {} has {} pixels, expected {size}x{size}", FACE_NAMES[layer], cube.faces[layer].len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4-texel cube whose faces are grey levels 0.1 .. 0.6.
    fn cube(bright: f32) -> CubeMap {
        CubeMap { size: 4, faces: std::array::from_fn(|i| vec![[bright * (i + 1) as f32 / 10.0; 3]; 16]) }
    }

    #[test]
    fn environment_work_is_done_once_per_content_and_exposure() {
        let cache = EnvironmentCache::default();
        let (a, b) = (cube(1.0), cube(2.0));
        let (ka, kb) = (EnvKey::of(&a), EnvKey::of(&b));
        assert_ne!(ka, kb);
        assert_eq!(ka, EnvKey::of(&a.clone()), "the key is the content, not the value's address");
        let first = cache.prefiltered(ka, &a);
        assert!(Arc::ptr_eq(&first, &cache.prefiltered(ka, &a)));
        assert_eq!(cache.counts(), EnvCounts { prefiltered: 1, priors: 0, reused: 1 });
        // The cached levels are what the prefilter computes.
        let direct = ggx::prefilter(&a);
        assert_eq!(first.len(), direct.len());
        assert!(first.iter().zip(&direct).all(|(x, y)| x.faces == y.faces));
        cache.prefiltered(kb, &b);
        assert_eq!(cache.counts().prefiltered, 2);
        // Priors per exposure: the up face (+Y, level 0.3) scaled by 2 is 0.6.
        let p1 = cache.priors(ka, &a, 1.0).unwrap();
        let p2 = cache.priors(ka, &a, 2.0).unwrap();
        assert_eq!(cache.priors(ka, &a, 1.0).unwrap(), p1);
        assert!((p2.up_mean[0] - 2.0 * p1.up_mean[0]).abs() < 1e-6 && (p1.up_mean[0] - 0.3).abs() < 1e-6, "{p1:?} {p2:?}");
        assert_eq!(cache.counts(), EnvCounts { prefiltered: 2, priors: 2, reused: 2 });
        // A bad exposure is an error, and nothing is kept for it.
        assert!(cache.priors(ka, &a, -1.0).is_err());
        assert_eq!(cache.counts().priors, 2);
        // Past the capacity the oldest content is computed again.
        for k in 0..ENV_CAPACITY {
            let c = cube(3.0 + k as f32);
            cache.prefiltered(EnvKey::of(&c), &c);
        }
        cache.prefiltered(ka, &a);
        assert_eq!(cache.counts().prefiltered, 3 + ENV_CAPACITY);
    }

    #[test]
    fn texels_are_rgba_halves_clamped_to_zero_and_the_largest_half() {
        let t = rgba16f_texels(&[[0.5, -2.0, 1000.0], [0.0, 0.25, 65504.0], [86528.0, 1e30, 2.0]]);
        let f: Vec<f32> = t.iter().map(|h| h.to_f32()).collect();
        // 0.5, 0.25, 1000 and 65504 (the largest finite half) are exact in f16; above it, 65504.
        assert_eq!(f, [0.5, 0.0, 1000.0, 1.0, 0.0, 0.25, 65504.0, 1.0, 65504.0, 65504.0, 2.0, 1.0]);
    }
}
