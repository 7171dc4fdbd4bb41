//! The wgpu device: headless (lavapipe in CI) or for a window surface.

use super::pipelines::Pipelines;
use anyhow::{Context, Result, anyhow};
use std::sync::{Arc, OnceLock};

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
    /// The render pipelines, built on first use and shared by every compositor on this device.
    pipelines: OnceLock<Arc<Pipelines>>,
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

    /// A device able to present to `surface` (or any device when `None`).
    pub fn with_instance(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>) -> Result<Gpu> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            apply_limit_buckets: false,
        }))
        .map_err(|e| anyhow!("{NO_ADAPTER_HELP} ({e})"))?;
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features = if timestamps { wgpu::Features::TIMESTAMP_QUERY } else { wgpu::Features::empty() };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("previz"),
            required_features,
            required_limits: wgpu::Limits::default().using_resolution(adapter.limits()),
            ..Default::default()
        }))
        .context("the GPU adapter refused to create a device")?;
        // Errors are caught with error scopes where work is submitted; anything that escapes
        // them is reported rather than aborting the process (wgpu's default handler panics).
        device.on_uncaptured_error(std::sync::Arc::new(|e: wgpu::Error| eprintln!("GPU error: {e}")));
        Ok(Gpu { instance, adapter, device, queue, timestamps, pipelines: OnceLock::new() })
    }

    /// The pipelines, bind-group layouts and samplers of the compositor: built once per device,
    /// so a second composite in the same process compiles no shaders.
    pub fn pipelines(&self) -> Arc<Pipelines> {
        self.pipelines.get_or_init(|| Arc::new(Pipelines::new(&self.device))).clone()
    }

    /// The adapter's name and backend, for reports.
    pub fn describe(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?}, driver {})", info.name, info.backend, info.driver_info)
    }
}
