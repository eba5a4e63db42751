//! The wgpu instance, adapter and device, with the optional features the pipelines use.

use crate::ViewerError;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The longest the viewer waits for the GPU to finish submitted work before it reports the
/// device as hung instead of waiting for ever.
pub const GPU_WAIT_LIMIT: Duration = Duration::from_secs(120);

/// A wait for the most recent submission, bounded by `GPU_WAIT_LIMIT`.
pub fn bounded_wait() -> wgpu::PollType {
    wgpu::PollType::Wait {
        submission_index: None,
        timeout: Some(GPU_WAIT_LIMIT),
    }
}

/// Which projection path to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProjectionPath {
    /// 64-bit atomics where the adapter has them, else the 32-bit path.
    Auto,
    Int64,
    Int32,
}

/// The 64-bit atomics a device is opened with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Int64Atomics {
    /// Min and max (the projection's keys, the one-pass searches).
    min_max: bool,
    /// Add and the rest as well (the triangulation's blend sums).
    add: bool,
}

impl Int64Atomics {
    const MIN_MAX: wgpu::Features =
        wgpu::Features::SHADER_INT64.union(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX);
    const ALL_OPS: wgpu::Features = wgpu::Features::SHADER_INT64_ATOMIC_ALL_OPS;

    /// What the adapter's features allow on the path asked for; None where the 64-bit path is
    /// asked of an adapter without 64-bit min/max. Add needs min/max too: Vulkan and DX12 have
    /// both or neither, Metal min/max alone, GL neither.
    fn choose(available: wgpu::Features, path: ProjectionPath) -> Option<Int64Atomics> {
        let has = available.contains(Self::MIN_MAX);
        let min_max = match path {
            ProjectionPath::Auto => has,
            ProjectionPath::Int32 => false,
            ProjectionPath::Int64 if has => true,
            ProjectionPath::Int64 => return None,
        };
        Some(Int64Atomics {
            min_max,
            add: min_max && available.contains(Self::ALL_OPS),
        })
    }

    fn features(self) -> wgpu::Features {
        let mut f = wgpu::Features::empty();
        if self.min_max {
            f |= Self::MIN_MAX;
        }
        if self.add {
            f |= Self::ALL_OPS;
        }
        f
    }
}

pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// The device was created with 64-bit atomic min/max.
    pub int64_atomics: bool,
    /// And with the other 64-bit atomic operations (add): Vulkan and DX12 have both or
    /// neither, Metal min/max alone.
    pub int64_sums: bool,
    pub timestamps: bool,
    pub adapter_name: String,
    /// The first GPU fault no error scope caught (validation, out of memory, internal), or the
    /// loss of the device; wgpu's default would panic.
    fault: Arc<Mutex<Option<String>>>,
    /// Why the device was lost, once it was: wgpu reports no error on a lost device after the
    /// first, so every later use must ask here.
    lost: Arc<Mutex<Option<String>>>,
}

impl GpuContext {
    /// Whether the device lets `pipeline`'s largest pass bind `count` storage buffers; the
    /// error says how many it allows, before anything is compiled.
    pub fn require_storage_buffers(&self, pipeline: &str, count: u32) -> Result<(), ViewerError> {
        let have = self.device.limits().max_storage_buffers_per_shader_stage;
        if have < count {
            return Err(ViewerError::Gpu(format!(
                "the {pipeline} pipeline binds {count} storage buffers in a pass; this adapter allows {have}"
            )));
        }
        Ok(())
    }

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
        let Some(int64) = Int64Atomics::choose(available, path) else {
            return Err(ViewerError::Gpu(format!(
                "adapter {} has no 64-bit atomic min/max; use the 32-bit projection path",
                adapter.get_info().name
            )));
        };
        let timestamps = available.contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = int64.features();
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
        let fault = Arc::new(Mutex::new(None::<String>));
        let keep = |fault: &Arc<Mutex<Option<String>>>, what: String| {
            if let Ok(mut slot) = fault.lock() {
                slot.get_or_insert(what);
            }
        };
        let on_error = fault.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            keep(&on_error, describe(&e));
        }));
        let lost = Arc::new(Mutex::new(None::<String>));
        let on_lost = lost.clone();
        device.set_device_lost_callback(move |reason, message| {
            // Dropping the device at exit also calls this; only a loss is a fault.
            if reason != wgpu::DeviceLostReason::Destroyed {
                keep(&on_lost, format!("the GPU device was lost ({message})"));
            }
        });
        Ok(GpuContext {
            fault,
            lost,
            instance,
            adapter,
            device,
            queue,
            int64_atomics: int64.min_max,
            int64_sums: int64.add,
            timestamps,
            adapter_name: format!("{} ({:?})", info.name, info.backend),
        })
    }

    /// The GPU fault that happened outside any error scope since the last call, if any.
    pub fn take_fault(&self) -> Option<ViewerError> {
        if let Some(lost) = self.lost_error() {
            return Some(lost);
        }
        let fault = self.fault.lock().ok()?.take()?;
        Some(ViewerError::Gpu(fault))
    }

    /// The loss of the device, every time it is asked once it happened.
    pub fn lost_error(&self) -> Option<ViewerError> {
        let lost = self.lost.lock().ok()?.clone()?;
        Some(ViewerError::Gpu(lost))
    }

    /// Marks the device lost, as the driver's callback does (for tests of what follows).
    #[doc(hidden)]
    pub fn mark_lost(&self, why: &str) {
        if let Ok(mut slot) = self.lost.lock() {
            slot.get_or_insert_with(|| format!("the GPU device was lost ({why})"));
        }
    }

    /// Runs `f` inside validation and out-of-memory error scopes: a fault comes back as an
    /// error, with `what` saying what was being done.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T, ViewerError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let internal = self.device.push_error_scope(wgpu::ErrorFilter::Internal);
        let value = f();
        let internal = pollster::block_on(internal.pop());
        let invalid = pollster::block_on(validation.pop());
        let out_of_memory = pollster::block_on(oom.pop());
        if let Some(lost) = self.lost_error() {
            return Err(lost);
        }
        match internal.or(invalid).or(out_of_memory) {
            Some(e) => Err(ViewerError::Gpu(format!("{what}: {}", describe(&e)))),
            None => Ok(value),
        }
    }

    /// Waits for the submitted work, at most `GPU_WAIT_LIMIT`, and reports any fault.
    pub fn wait(&self) -> Result<(), ViewerError> {
        let waited = self.device.poll(bounded_wait());
        if let Some(fault) = self.take_fault() {
            return Err(fault);
        }
        waited.map(|_| ()).map_err(|e| match e {
            wgpu::PollError::Timeout => ViewerError::Gpu(format!(
                "the GPU did not finish its work within {} s; the device hangs or was lost",
                GPU_WAIT_LIMIT.as_secs()
            )),
            other => ViewerError::Gpu(format!("waiting for the GPU failed: {other}")),
        })
    }

    /// Largest storage buffer binding the device allows.
    pub fn max_binding(&self) -> u64 {
        self.device.limits().max_storage_buffer_binding_size
    }
}

/// One line for a wgpu error: the kind and the innermost description (wgpu's own text spans
/// several lines with the whole chain).
fn describe(e: &wgpu::Error) -> String {
    let (kind, text) = match e {
        wgpu::Error::OutOfMemory { .. } => ("out of GPU memory", String::new()),
        wgpu::Error::Validation { description, .. } => ("validation error", description.clone()),
        wgpu::Error::Internal { description, .. } => ("internal GPU error", description.clone()),
    };
    let text: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    if text.is_empty() {
        kind.to_string()
    } else {
        format!("{kind} ({})", text.join(" "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_backends_64_bit_atomics_are_used_as_far_as_they_go() {
        let min_max = Int64Atomics::MIN_MAX;
        let vulkan = min_max | Int64Atomics::ALL_OPS;
        let gl = wgpu::Features::empty();
        let both = Int64Atomics {
            min_max: true,
            add: true,
        };
        let neither = Int64Atomics {
            min_max: false,
            add: false,
        };
        use ProjectionPath::*;
        assert_eq!(Int64Atomics::choose(vulkan, Auto), Some(both));
        assert_eq!(Int64Atomics::choose(vulkan, Int64), Some(both));
        assert_eq!(Int64Atomics::choose(vulkan, Int32), Some(neither));
        // Metal: min/max alone keeps the 64-bit projection and searches, and 32-bit sums.
        let metal = Some(Int64Atomics {
            min_max: true,
            add: false,
        });
        assert_eq!(Int64Atomics::choose(min_max, Auto), metal);
        assert_eq!(Int64Atomics::choose(min_max, Int64), metal);
        assert_eq!(Int64Atomics::choose(gl, Auto), Some(neither));
        assert_eq!(Int64Atomics::choose(gl, Int64), None);
        // Add without min/max is not used.
        assert_eq!(
            Int64Atomics::choose(Int64Atomics::ALL_OPS, Auto),
            Some(neither)
        );
        assert_eq!(both.features(), vulkan);
        assert_eq!(
            Int64Atomics::choose(min_max, Auto).map(|c| c.features()),
            Some(min_max)
        );
    }

    /// A buffer wgpu refuses: mappable for reading and storage at once needs a feature the
    /// device was not opened with.
    fn invalid_buffer(ctx: &GpuContext) -> wgpu::Buffer {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("invalid"),
            size: 64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    }

    #[test]
    fn a_validation_error_inside_a_scope_is_an_error_value() {
        let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
        let e = ctx
            .scoped("making a test buffer", || invalid_buffer(&ctx))
            .expect_err("the invalid buffer is refused");
        let text = e.to_string();
        assert!(
            text.contains("making a test buffer: validation error"),
            "{text}"
        );
        assert_eq!(text.lines().count(), 1, "{text}");
        assert!(ctx.take_fault().is_none(), "the scope caught it");
        ctx.wait().expect("the device still works");
    }

    #[test]
    fn a_fault_outside_any_scope_is_kept_instead_of_panicking() {
        let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
        let _ = invalid_buffer(&ctx);
        let fault = ctx.take_fault().expect("the fault was recorded");
        assert!(fault.to_string().contains("validation error"), "{fault}");
        assert!(ctx.take_fault().is_none(), "taken once");
    }
}
