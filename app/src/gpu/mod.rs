//! The bottom layer: the wgpu device, validation-error scopes, buffer readback, the timestamp
//! timer, the passes' pipeline-statistics counter and small builders, in the spirit of
//! `wgpu::util::DeviceExt`. Nothing here knows about passes or scenes; `render`, `colour`,
//! `priors`, `capture` and `ui` build on it.

pub mod build;
pub mod counter;
pub mod readback;
pub mod timer;
pub mod uniform_branches;
pub mod wgsl;

pub use counter::{PassCount, PassCounter};
pub use readback::{Readback, padded_row_bytes, read_buffer};
pub use timer::GpuTimer;

use anyhow::{Context, Result, anyhow, bail};
use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// How to get a Vulkan driver on a machine without a GPU.
pub const NO_ADAPTER_HELP: &str = "no GPU adapter found. On a machine without a GPU install the \
software Vulkan driver lavapipe: `sudo apt-get install mesa-vulkan-drivers libvulkan1` \
(Debian/Ubuntu), then run again";

/// A device and queue, with what the adapter supports that we care about.
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Whether GPU timestamp queries are available (timings in `--json` and `previz bench`).
    pub timestamps: bool,
    /// Whether pipeline-statistics queries are available (the passes' counts in `previz bench`).
    pub pipeline_statistics: bool,
    /// Per-device state built once and shared (pipelines), by type; see [`Gpu::shared`].
    shared: Mutex<HashMap<TypeId, Arc<dyn Any + Send + Sync>>>,
    /// GPU errors that escaped every [`Gpu::checked`] scope (printed to stderr).
    uncaptured: Arc<AtomicUsize>,
}

impl Gpu {
    /// A device without a window. Honours `WGPU_BACKEND` / `WGPU_ADAPTER_NAME` from the environment.
    pub fn headless() -> Result<Gpu> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL | wgpu::Backends::METAL;
        }
        let instance = wgpu::Instance::new(desc);
        Self::with_instance(instance, None)
    }

    /// A headless device with `limits` instead of the defaults: lower ones show what happens
    /// to input beyond a device's limits (the tests of every GPU entry point's errors).
    pub fn headless_with_limits(limits: wgpu::Limits) -> Result<Gpu> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL | wgpu::Backends::METAL;
        }
        Self::create(wgpu::Instance::new(desc), None, Some(limits))
    }

    /// A device able to present to `surface` (or any device when `None`).
    pub fn with_instance(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>) -> Result<Gpu> {
        Self::create(instance, surface, None)
    }

    fn create(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>, limits: Option<wgpu::Limits>) -> Result<Gpu> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            apply_limit_buckets: false,
        }))
        .map_err(|e| anyhow!("{NO_ADAPTER_HELP} ({e})"))?;
        let required_features = adapter.features() & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::PIPELINE_STATISTICS_QUERY);
        let timestamps = required_features.contains(wgpu::Features::TIMESTAMP_QUERY);
        let pipeline_statistics = required_features.contains(wgpu::Features::PIPELINE_STATISTICS_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("previz"),
            required_features,
            required_limits: limits.unwrap_or_else(|| wgpu::Limits::default().using_resolution(adapter.limits())),
            ..Default::default()
        }))
        .context("the GPU adapter refused to create a device")?;
        // Every entry point runs its GPU work inside `checked`; anything that still escapes is
        // reported rather than aborting the process (wgpu's default handler panics).
        let uncaptured = Arc::new(AtomicUsize::new(0));
        let count = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            count.fetch_add(1, Ordering::Relaxed);
            eprintln!("GPU error: {e}");
        }));
        Ok(Gpu { instance, adapter, device, queue, timestamps, pipeline_statistics, shared: Mutex::new(HashMap::new()), uncaptured })
    }

    /// How many GPU errors escaped every [`Gpu::checked`] scope so far (each was printed to
    /// stderr instead of being returned): 0 when every entry point reports its errors.
    pub fn uncaptured_errors(&self) -> usize {
        self.uncaptured.load(Ordering::Relaxed)
    }

    /// The adapter's name and backend, for reports.
    pub fn describe(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?}, driver {})", info.name, info.backend, info.driver_info)
    }

    /// Run `f` inside validation and out-of-memory error scopes: work the GPU rejects is an
    /// error naming `what`, not a panic or a line on stderr. Scopes are per thread.
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = f();
        let oom = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(validation.pop());
        if let Some(e) = invalid.or(oom) {
            bail!("the GPU rejected {what}: {e}");
        }
        result
    }

    /// State built once per device and shared by everyone who asks for the same type (the
    /// compositor's pipelines): the first call runs `make` inside [`Gpu::checked`], later calls
    /// return the same value. A failed `make` is not cached.
    pub fn shared<T: Any + Send + Sync>(&self, what: &str, make: impl FnOnce(&Gpu) -> Result<T>) -> Result<Arc<T>> {
        let key = TypeId::of::<T>();
        let cached = |map: &HashMap<TypeId, Arc<dyn Any + Send + Sync>>| map.get(&key).cloned().and_then(|a| a.downcast::<T>().ok());
        if let Some(v) = cached(&self.lock_shared()) {
            return Ok(v);
        }
        // Built without the lock held, so `make` may ask for other shared state.
        let made: Arc<T> = Arc::new(self.checked(what, || make(self))?);
        let mut map = self.lock_shared();
        if let Some(v) = cached(&map) {
            return Ok(v);
        }
        map.insert(key, made.clone());
        Ok(made)
    }

    /// [`Gpu::shared`] once per `key` of the same type (the pipelines of each sample count): the
    /// first call for a key runs `make` inside [`Gpu::checked`], later calls for it return the
    /// same value. A failed `make` is not cached.
    pub fn shared_per<T: Any + Send + Sync>(&self, what: &str, key: u32, make: impl FnOnce(&Gpu) -> Result<T>) -> Result<Arc<T>> {
        let sets = self.shared(what, |_| Ok(PerKey::<T>(Mutex::new(Vec::new()))))?;
        let find =
            |sets: &PerKey<T>| sets.0.lock().unwrap_or_else(|p| p.into_inner()).iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone());
        if let Some(v) = find(&sets) {
            return Ok(v);
        }
        // Built without the lock held, as in `shared`.
        let made = Arc::new(self.checked(what, || make(self))?);
        let mut list = sets.0.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, v)) = list.iter().find(|(k, _)| *k == key) {
            return Ok(v.clone());
        }
        list.push((key, made.clone()));
        Ok(made)
    }

    fn lock_shared(&self) -> std::sync::MutexGuard<'_, HashMap<TypeId, Arc<dyn Any + Send + Sync>>> {
        self.shared.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Whether a `width`×`height` 2D texture fits this device (an error naming `what` if not).
    pub fn check_size(&self, what: &str, width: u32, height: u32) -> Result<()> {
        let max = self.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            bail!("{what} size {width}x{height} is outside 1..={max} pixels per side (this GPU's limit)");
        }
        Ok(())
    }
}

/// [`Gpu::shared_per`]'s values of one type, by key.
struct PerKey<T>(Mutex<Vec<(u32, Arc<T>)>>);

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::sync::OnceLock;

    /// One device for the library's unit tests (lavapipe in CI).
    pub(crate) fn gpu() -> &'static Gpu {
        static GPU: OnceLock<Gpu> = OnceLock::new();
        GPU.get_or_init(|| Gpu::headless().unwrap_or_else(|e| panic!("{e:#}")))
    }

    #[test]
    fn checked_turns_a_rejected_texture_into_an_error() {
        let gpu = gpu();
        let too_wide = gpu.device.limits().max_texture_dimension_2d + 1;
        let err = gpu
            .checked("a test texture", || {
                Ok(build::texture(
                    &gpu.device,
                    "too wide",
                    (too_wide, 4, 1),
                    wgpu::TextureFormat::Rgba8Unorm,
                    1,
                    wgpu::TextureUsages::COPY_DST,
                ))
            })
            .expect_err("an oversized texture must be rejected");
        assert!(format!("{err:#}").contains("the GPU rejected a test texture"), "{err:#}");
        // A shader that does not compile is caught the same way (pipeline creation).
        let bad = gpu.checked("a broken shader", || Ok(build::shader(&gpu.device, "broken", "fn broken( {".into())));
        assert!(format!("{:#}", bad.expect_err("a broken shader must be rejected")).contains("a broken shader"));
        // Valid work passes through with its value.
        let ok = gpu.checked("a small texture", || {
            Ok(build::texture(&gpu.device, "small", (4, 4, 1), wgpu::TextureFormat::Rgba8Unorm, 1, wgpu::TextureUsages::COPY_DST).width())
        });
        assert_eq!(ok.unwrap(), 4);
        assert!(gpu.check_size("output", 0, 4).is_err() && gpu.check_size("output", too_wide, 4).is_err());
    }

    #[test]
    fn shared_per_key_is_built_once_per_key() {
        struct Key(u32);
        let gpu = Gpu::headless().unwrap();
        let one = gpu.shared_per("keyed", 1, |_| Ok(Key(1))).unwrap();
        let four = gpu.shared_per("keyed", 4, |_| Ok(Key(4))).unwrap();
        let again = gpu.shared_per("keyed", 1, |_: &Gpu| -> Result<Key> { panic!("built twice") }).unwrap();
        assert!(Arc::ptr_eq(&one, &again) && one.0 == 1 && four.0 == 4);
        // A failed build is not kept: the next call builds it.
        assert!(gpu.shared_per("keyed", 2, |_: &Gpu| -> Result<Key> { bail!("no") }).is_err());
        assert_eq!(gpu.shared_per("keyed", 2, |_| Ok(Key(2))).unwrap().0, 2);
    }

    #[test]
    fn shared_state_is_built_once_per_type() {
        struct Counter(u32);
        let gpu = Gpu::headless().unwrap();
        let calls = std::cell::Cell::new(0);
        let make = |_: &Gpu| {
            calls.set(calls.get() + 1);
            Ok(Counter(7))
        };
        let a = gpu.shared("a counter", make).unwrap();
        let b = gpu.shared("a counter", |_: &Gpu| -> Result<Counter> { panic!("built twice") }).unwrap();
        assert!(Arc::ptr_eq(&a, &b) && a.0 == 7 && calls.get() == 1);
        // A failed build is reported and not cached.
        struct Other;
        assert!(gpu.shared("other", |_: &Gpu| -> Result<Other> { bail!("no") }).is_err());
        assert!(gpu.shared("other", |_: &Gpu| Ok(Other)).is_ok());
    }
}
