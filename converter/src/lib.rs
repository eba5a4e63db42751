//! Strata's converter: LAS/LAZ/PLY/E57 inputs into a layered-octree dataset, out of core.

pub mod build;
pub mod chunk_step;
pub mod copc;
pub mod copc_describe;
pub mod copc_nodes;
pub mod disk;
#[cfg(test)]
mod disk_tests;
pub mod distribute;
pub mod error;
pub mod export;
pub mod finish;
pub mod halo;
pub mod index;
pub mod input;
pub mod journal;
pub mod las_crs;
pub mod las_records;
pub mod merge;
pub mod morton;
pub mod normals;
pub mod plan;
pub mod potree2;
pub mod potree2_hierarchy;
pub mod prepare;
pub mod progress;
pub mod quantize;
pub mod replace;
pub mod row_shuffle;
pub mod rowfile;
pub mod rows;
pub mod sampling;
pub mod scan;
pub mod staging;
pub mod synth;
pub mod sys;
pub mod tasks;
pub mod tree;
pub mod uncached;
pub mod workdir;
pub mod writers;

pub use build::{ConvertOptions, ConvertSummary, convert, convert_with};
pub use chunk_step::{ChunkRows, ChunkStep, GridBox, Halo, NoStep};
pub use error::{ConvertError, Result};
pub use normals::{NormalMode, NormalOptions, NormalStep, Orient};
pub use sampling::Sampling;
