//! The Strata viewer: streams a dataset under a per-frame point budget and renders it with
//! compute-shader projection, in a window (egui) or headless (PNG).

pub mod app;
pub mod bookmarks;
pub mod camera;
pub mod dataset;
mod error;
mod flight;
pub mod gpu;
pub mod headless;
mod http_source;
pub mod loader;
pub mod lod;
pub mod marks;
pub mod measure;
pub mod overlay;
pub mod pick;
pub mod pipelines;
pub mod polygon;
pub mod profile;
pub mod renderer;
pub mod settings;
mod source;
mod streams;

pub use camera::Camera;
pub use dataset::StreamDataset;
pub use error::ViewerError;
pub use http_source::{HttpOptions, HttpSource};
pub use pipelines::{PipelineInfo, REGISTRY};
pub use renderer::{FrameStats, Renderer};
pub use settings::{ColourMode, PointFilter, Settings};
pub use source::{LocalSource, Source};
