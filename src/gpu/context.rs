//! A headless wgpu device: a hardware adapter when there is one, else the software adapter
//! (Mesa's lavapipe, a "CPU" device), with the adapter's own limits so large problems fit.

use thiserror::Error;

/// Why the GPU path cannot run.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter at all.
    #[error("no GPU adapter found (hardware or software): {0}; on Debian, `apt-get install mesa-vulkan-drivers libvulkan1` provides the software adapter")]
    NoAdapter(String),
    /// Only the software adapter, where hardware was asked for.
    #[error("no hardware GPU (a software adapter, if installed, is taken only by --device gpu)")]
    NoHardware,
    /// The adapter would not open a device.
    #[error("the adapter {adapter} refused a device: {message}")]
    NoDevice {
        /// The adapter's name.
        adapter: String,
        /// wgpu's words.
        message: String,
    },
    /// A solver the GPU path lacks.
    #[error("the GPU path has no {0} solver yet (it has: nlgs, cpg, pcpg, jacobi, apgd)")]
    Unsupported(String),
    /// A failure while running.
    #[error("GPU: {0}")]
    Runtime(String),
    /// A stopping criterion the GPU path lacks.
    #[error("the GPU path stops on the natural-map error or a velocity test only, not on the {0} criterion")]
    Criterion(String),
}

/// Compiled pipelines of one specialisation: ((rotation, friction), kernels).
type KernelCacheEntry = ((bool, bool), std::sync::Arc<super::kernels::Kernels>);

/// A headless wgpu device and queue, with its compiled pipelines and buffer pool.
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter it runs on.
    pub info: wgpu::AdapterInfo,
    /// Compiled pipelines per specialisation (rotation, friction), built on first use.
    kernels: std::sync::Mutex<Vec<KernelCacheEntry>>,
    /// Buffers kept from one solve to the next.
    pub pool: std::sync::Arc<super::pool::BufferPool>,
}

impl GpuContext {
    /// The best adapter: hardware first, then the software fallback.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = match Self::hardware_adapter(&instance) {
            Some(a) => a,
            None => pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: true,
                compatible_surface: None,
                ..Default::default()
            }))
            .or_else(|_| pollster::block_on(instance.request_adapter(&Default::default())))
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?,
        };
        Self::on(adapter)
    }

    /// A hardware adapter only (a discrete GPU first); the software adapter is never taken.
    pub fn hardware() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = Self::hardware_adapter(&instance).ok_or(GpuError::NoHardware)?;
        Self::on(adapter)
    }

    fn hardware_adapter(instance: &wgpu::Instance) -> Option<wgpu::Adapter> {
        let rank = |t: wgpu::DeviceType| match t {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu | wgpu::DeviceType::Other => 2,
            wgpu::DeviceType::Cpu => 3,
        };
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        adapters
            .into_iter()
            .filter(|a| a.get_info().device_type != wgpu::DeviceType::Cpu)
            .min_by_key(|a| rank(a.get_info().device_type))
    }

    fn on(adapter: wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("moreau"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoDevice { adapter: info.name.clone(), message: e.to_string() })?;
        Ok(Self { device, queue, info, kernels: Default::default(), pool: Default::default() })
    }

    /// The pipelines for a problem with or without rotation and friction (compiled once).
    pub fn kernels(&self, rotation: bool, friction: bool) -> std::sync::Arc<super::kernels::Kernels> {
        let mut cache = self.kernels.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, k)) = cache.iter().find(|(key, _)| *key == (rotation, friction)) {
            return k.clone();
        }
        let k = std::sync::Arc::new(super::kernels::Kernels::new(self, rotation, friction));
        cache.push(((rotation, friction), k.clone()));
        k
    }

    /// True for a software rasteriser such as lavapipe: correct, never fast.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's name, as recorded in outputs.
    pub fn adapter_name(&self) -> String {
        self.info.name.clone()
    }

    /// One line for the user: name, backend, hardware or software.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {})",
            self.info.name,
            self.info.backend,
            if self.is_software() { "software adapter" } else { "hardware" }
        )
    }
}
