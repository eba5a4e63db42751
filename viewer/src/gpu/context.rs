//! The wgpu instance, adapter and device, with the optional features the pipelines use.

use crate::ViewerError;

/// Which projection path to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProjectionPath {
    /// 64-bit atomics where the adapter has them, else the 32-bit path.
    Auto,
    Int64,
    Int32,
}

pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// The device was created with 64-bit atomic min/max.
    pub int64_atomics: bool,
    pub timestamps: bool,
    pub adapter_name: String,
}

impl GpuContext {
    /// Picks an adapter (WGPU_BACKEND and WGPU_ADAPTER_NAME are honoured) and opens a device
    /// with the features the chosen projection path needs.
    pub fn new(path: ProjectionPath) -> Result<GpuContext, ViewerError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        ))
        .map_err(|e| ViewerError::NoAdapter(e.to_string()))?;
        GpuContext::with_adapter(instance, adapter, path)
    }

    pub fn with_adapter(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        path: ProjectionPath,
    ) -> Result<GpuContext, ViewerError> {
        let available = adapter.features();
        let int64 = wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
        let has_int64 = available.contains(int64);
        let int64_atomics = match path {
            ProjectionPath::Auto => has_int64,
            ProjectionPath::Int32 => false,
            ProjectionPath::Int64 if has_int64 => true,
            ProjectionPath::Int64 => {
                return Err(ViewerError::Gpu(format!(
                    "adapter {} has no 64-bit atomic min/max; use the 32-bit projection path",
                    adapter.get_info().name
                )));
            }
        };
        let timestamps = available.contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = wgpu::Features::empty();
        if int64_atomics {
            features |= int64;
        }
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("strata"),
            required_features: features,
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| ViewerError::Gpu(format!("cannot open a device: {e}")))?;
        let info = adapter.get_info();
        Ok(GpuContext {
            instance,
            adapter,
            device,
            queue,
            int64_atomics,
            timestamps,
            adapter_name: format!("{} ({:?})", info.name, info.backend),
        })
    }

    /// Largest storage buffer binding the device allows.
    pub fn max_binding(&self) -> u64 {
        self.device.limits().max_storage_buffer_binding_size
    }
}
