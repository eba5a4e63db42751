//! The quality-versus-speed harness (`--bin quality`): ground-truth meshes, point sets sampled
//! from them, the reference renderer, the metrics and the report.

pub mod cli;
pub mod configs;
pub mod mesh;
pub mod metrics;
pub mod reference;
pub mod report;
pub mod sample;
pub mod scenes;
pub mod shadows;
pub mod shapes;
pub mod silhouette;
pub mod temporal;
pub mod triangulate_targets;
