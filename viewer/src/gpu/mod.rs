//! Everything on the GPU: device, node cache, compute passes and pass timing.

pub mod async_readback;
pub mod cache;
pub mod context;
pub mod passes;
pub mod pyramid;
pub mod readback;
pub mod timing;

pub use cache::NodeCache;
pub use context::{GpuContext, ProjectionPath};
