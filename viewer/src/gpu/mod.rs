//! The GPU's shared parts: device, node cache, readbacks and pass timing (the passes
//! themselves live with their pipelines, under `pipelines`).

pub mod async_readback;
pub mod cache;
pub mod context;
pub mod readback;
pub mod timing;

pub use cache::NodeCache;
pub use context::{GpuContext, ProjectionPath};
