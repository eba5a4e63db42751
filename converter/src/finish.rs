//! After indexing: merge the levels above the chunks into the octree file, then write the
//! hierarchy and the metadata and rename the work directory into the dataset.

use crate::build::ConvertOptions;
use crate::error::{ConvertError, Result, io_err};
use crate::journal::{Committer, JournalEntry, record_of};
use crate::merge::TopMerge;
use crate::plan::root_spacing;
use crate::prepare::Plan;
use crate::rowfile::{Scratch, read_rows};
use crate::sampling::Sampling;
use crate::tree::FinishedNode;
use crate::workdir::WorkDir;
use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::Write;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use strata_format::{
    Bounds, BuiltHierarchy, Cube, DatasetFile, DatasetId, FileInfo, Files, HierarchyInfo, Layout,
    Metadata, NodeKey, NodeRecord, PAGE_LEVELS, RowLayout, Scanner, build_hierarchy, octree_head,
};

/// Every node of the dataset, and the octree file holding them all.
pub struct Merged {
    records: BTreeMap<NodeKey, NodeRecord>,
    octree: File,
    octree_path: PathBuf,
    octree_len: u64,
}

/// What the summary reports of the finished dataset.
pub struct Finished {
    pub points: u64,
    pub nodes: u64,
    pub depth: u32,
    pub dataset_bytes: u64,
}

/// Builds the levels above the chunks from the chunks' roots and appends them to the octree.
/// `root_of(chunk)` is where a chunk's root rows were left (`WorkDir::chunk_root`, or a task's).
pub fn merge_top(
    root_of: &dyn Fn(usize) -> PathBuf,
    plan: &Plan,
    layout: &RowLayout,
    sampling: Sampling,
    journal: &[JournalEntry],
    committer: Committer,
) -> Result<Merged> {
    let mut records: BTreeMap<NodeKey, NodeRecord> =
        journal.iter().flat_map(JournalEntry::records).collect();
    let (mut octree, octree_path, mut at) = committer.into_octree();
    let roots: Vec<(NodeKey, u8)> = journal
        .iter()
        .zip(&plan.chunks)
        .map(|(entry, chunk)| (chunk.key(), entry.root_mask))
        .collect();
    let load = |i: usize| {
        let p = root_of(journal[i].chunk);
        let mut rows = Vec::new();
        read_rows(&p, layout.stride, &mut rows, &mut Scratch::default()).map(|()| rows)
    };
    let emit = |n: FinishedNode| {
        octree
            .write_all(&n.payload)
            .map_err(io_err(&octree_path, "cannot write"))?;
        records.insert(n.key, record_of(&n, at));
        at += n.payload.len() as u64;
        Ok(())
    };
    TopMerge::new(&roots, layout, plan.cube, sampling, load, emit).run()?;
    Ok(Merged {
        records,
        octree,
        octree_path,
        octree_len: at,
    })
}

/// Writes the hierarchy and the metadata, removes the work files, and renames the directory
/// into the dataset, replacing an old one.
pub fn finish(
    opts: &ConvertOptions,
    wd: &WorkDir,
    plan: &Plan,
    merged: Merged,
    record_step: &dyn Fn(&mut Metadata),
) -> Result<Finished> {
    let Merged {
        records,
        octree,
        octree_path,
        octree_len,
    } = merged;
    let built = build_hierarchy(&records, PAGE_LEVELS, Layout::V1_1);
    let id = dataset_id(&built, octree_len, plan);
    octree
        .write_all_at(&octree_head(id), 0)
        .map_err(io_err(&octree_path, "cannot write"))?;
    octree
        .sync_all()
        .map_err(io_err(&octree_path, "cannot sync"))?;
    drop(octree);
    let hier = built.file(id);
    write_synced(&wd.dataset_file(DatasetFile::Hierarchy), &hier)?;
    let points: u64 = records.values().map(|r| r.point_count as u64).sum();
    if points != plan.points {
        return Err(ConvertError::output(
            wd.root(),
            format!(
                "{} points were read but the work folder's chunks hold {points}: its work files \
                 are damaged or missing (convert again, or with --plan run its tasks again)",
                plan.points
            ),
        ));
    }
    let depth = records.keys().map(|k| k.level as u32).max().unwrap_or(0);
    let q = plan.quantization();
    let to_real = |p: [i32; 3]| plan.to_real(p.map(i64::from));
    let source_name = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let mut meta = Metadata {
        format: strata_format::FORMAT_NAME.into(),
        version: [strata_format::VERSION_MAJOR, strata_format::VERSION_MINOR],
        id: Some(id),
        points,
        nodes: records.len() as u64,
        depth,
        scale: plan.scale,
        offset: plan.offset,
        bounds: Bounds {
            min: to_real(q.quantize(&plan.min)),
            max: to_real(q.quantize(&plan.max)),
        },
        cube: plan.cube,
        spacing: root_spacing(&plan.cube, plan.scale[0]),
        sampling: opts.sampling.name().into(),
        attributes: plan.attributes.clone(),
        files: Files {
            hierarchy: FileInfo {
                name: DatasetFile::Hierarchy.name().into(),
                size: hier.len() as u64,
            },
            octree: FileInfo {
                name: DatasetFile::Octree.name().into(),
                size: octree_len,
            },
        },
        hierarchy: HierarchyInfo {
            root_page_offset: built.root_page_offset,
            root_page_size: built.root_page_size,
            page_levels: PAGE_LEVELS,
        },
        sources: opts.inputs.iter().map(|p| source_name(p)).collect(),
        generator: format!("strata {}", env!("CARGO_PKG_VERSION")),
        warnings: plan.warnings.clone(),
        classes: plan
            .classes
            .iter()
            .map(|(c, n)| (c.to_string(), *n))
            .collect(),
        normals: None,
        scanners: plan
            .scanners
            .iter()
            .zip(&plan.scanner_inputs)
            .map(|(&position, &i)| Scanner {
                position,
                source: opts
                    .inputs
                    .get(i)
                    .map(|p| source_name(p))
                    .unwrap_or_default(),
            })
            .collect(),
        crs: plan.crs.clone(),
    };
    record_step(&mut meta);
    // The inputs were checked so that this cannot happen; if it does, no dataset that fails to
    // read back may appear.
    if let Some(member) = meta.non_finite() {
        return Err(ConvertError::internal(
            "writing metadata.json",
            format!("{member} is not a finite number"),
        ));
    }
    // metadata.json makes the folder a dataset: written under another name while the work
    // (and its plan, for --resume) is still there, and given its name once nothing but renames
    // is left, so that an interruption leaves no complete dataset under the work folder's name
    // (the work and a replaced dataset can take a while to remove).
    let metadata = wd.dataset_file(DatasetFile::Metadata);
    let metadata_part = crate::writers::part_path(&metadata);
    write_synced(&metadata_part, meta.to_json().as_bytes())?;
    fs::remove_dir_all(wd.work()).map_err(io_err(wd.work(), "cannot remove work directory"))?;
    wd.forget_work_folder()?;
    fs::rename(&metadata_part, &metadata).map_err(io_err(&metadata, "cannot move into place"))?;
    let old = wd.replaced();
    let replacing = opts.output.exists();
    if replacing {
        keep_what_the_viewer_saved(&opts.output, wd.root())?;
        fs::rename(&opts.output, &old).map_err(io_err(&opts.output, "cannot replace"))?;
    }
    fs::rename(wd.root(), &opts.output).map_err(io_err(
        &opts.output,
        "cannot move the finished dataset into place",
    ))?;
    if replacing {
        fs::remove_dir_all(&old).map_err(io_err(&old, "cannot remove the replaced dataset"))?;
    }
    Ok(Finished {
        points,
        nodes: records.len() as u64,
        depth,
        dataset_bytes: octree_len + hier.len() as u64,
    })
}

/// Copies into the new dataset what the viewer saved beside the one it replaces: the user's
/// views and measurements are of the scene, not of this conversion of it (one with `--normals`
/// added, or at another scale), and `--overwrite` deleted them without a word.
fn keep_what_the_viewer_saved(replaced: &Path, new: &Path) -> Result<()> {
    for name in VIEWER_FILES {
        let from = replaced.join(name);
        if from.is_file() {
            let to = new.join(name);
            fs::copy(&from, &to).map_err(io_err(&to, "cannot keep the replaced dataset's"))?;
        }
    }
    Ok(())
}

/// What the window saves in a dataset's folder.
pub const VIEWER_FILES: [&str; 2] = ["bookmarks.json", "measurements.geojson"];

/// The dataset id: a hash of everything the files hold that decides what a reader sees (the
/// pages, which hold every payload's place, size and checksum; the octree's length; the grid;
/// the attributes), so the same conversion gives the same id and other content another.
fn dataset_id(built: &BuiltHierarchy, octree_len: u64, plan: &Plan) -> DatasetId {
    let grid: Vec<u8> = plan
        .scale
        .iter()
        .chain(&plan.offset)
        .flat_map(|v| v.to_le_bytes())
        .chain(octree_len.to_le_bytes())
        .collect();
    let Cube { min, bits } = plan.cube;
    let cube: Vec<u8> = min
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .chain(bits.to_le_bytes())
        .collect();
    let attributes = serde_json::to_vec(&plan.attributes).unwrap_or_default();
    DatasetId::of_content([&built.pages[..], &grid, &cube, &attributes])
}

fn write_synced(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = File::create(path).map_err(io_err(path, "cannot create"))?;
    f.write_all(bytes).map_err(io_err(path, "cannot write"))?;
    f.sync_all().map_err(io_err(path, "cannot sync"))
}
