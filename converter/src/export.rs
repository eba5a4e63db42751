//! `strata export`: every point of a dataset back out as LAS, LAZ or PLY.

use crate::error::Result;
use crate::writers::open_writer;
use std::path::Path;
use strata_format::LocalDataset;

/// Writes all points of `dataset` to `output`; returns the number written.
pub fn export(dataset: &Path, output: &Path, overwrite: bool) -> Result<u64> {
    let ds = LocalDataset::open(dataset)?;
    let meta = ds.metadata();
    let layout = ds.layout().clone();
    let mut writer = open_writer(
        output,
        &layout,
        meta.scale,
        meta.offset,
        meta.points,
        overwrite,
    )?;
    let mut written = 0u64;
    for node in ds.all_nodes()? {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node)?;
        writer.write_rows(&cols.to_rows(&layout))?;
        written += node.point_count as u64;
    }
    writer.finish()?;
    Ok(written)
}
