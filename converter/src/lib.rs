//! Strata's converter: LAS/LAZ/PLY inputs into a layered-octree dataset, out of core.

pub mod build;
pub mod distribute;
pub mod error;
pub mod export;
pub mod input;
pub mod merge;
pub mod morton;
pub mod plan;
pub mod progress;
pub mod quantize;
pub mod rows;
pub mod sampling;
pub mod scan;
pub mod staging;
pub mod synth;
pub mod sys;
pub mod tree;
pub mod writers;

pub use build::{ConvertOptions, ConvertSummary, convert};
pub use error::{ConvertError, Result};
pub use sampling::Sampling;
