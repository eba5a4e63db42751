//! The datasets under the served directory and the files each may serve: `metadata.json` and
//! the files its `files` section names, nothing else. Each `metadata.json` is parsed once per
//! version (device, inode, mtime, size) and kept. Blocking: call only on the blocking pool.

use crate::files::confined;
use serde::Serialize;
use std::collections::HashMap;
use std::io::Write;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use strata_format::{DatasetFile, Metadata, plain_file_name};

/// `metadata.json` larger than this is not a dataset's (a real one is a few KiB).
const METADATA_MAX: u64 = strata_format::METADATA_MAX_BYTES;

#[derive(Debug, Clone, Serialize)]
pub struct DatasetEntry {
    pub name: String,
    /// The format version, `"1.1"`.
    pub version: String,
    /// The dataset id (format 1.1), as in `metadata.json`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub id: Option<strata_format::DatasetId>,
    pub points: u64,
    pub nodes: u64,
    pub depth: u32,
    pub bounds: strata_format::Bounds,
    pub bytes: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Version {
    dev: u64,
    ino: u64,
    mtime_ns: i128,
    size: u64,
}

impl Version {
    fn of(m: &std::fs::Metadata) -> Version {
        Version {
            dev: m.dev(),
            ino: m.ino(),
            mtime_ns: m.mtime() as i128 * 1_000_000_000 + m.mtime_nsec() as i128,
            size: m.len(),
        }
    }
}

#[derive(Debug, Clone)]
struct Known {
    version: Version,
    entry: DatasetEntry,
    /// The names this dataset serves besides `metadata.json`.
    files: Vec<String>,
}

#[derive(Debug)]
pub struct Catalog {
    root: PathBuf,
    /// Datasets whose `metadata.json` was reported as not served, with the version reported:
    /// each broken version is reported once, not at every request.
    reported: Mutex<HashMap<String, Version>>,
    /// By dataset name.
    known: Mutex<HashMap<String, Known>>,
}

/// The files of a Potree 2.0 dataset besides `metadata.json`.
const POTREE2_FILES: [&str; 2] = ["hierarchy.bin", "octree.bin"];

/// A Potree 2.0 dataset's entry, from its `metadata.json`: version "2.0" and the fields a
/// Potree loader starts from; its two files are those beside it.
fn potree2(name: &str, json: &[u8], dir: &Path, version: Version) -> Option<Known> {
    let v: serde_json::Value = serde_json::from_slice(json).ok()?;
    if v.get("version")?.as_str()? != "2.0" || v.get("hierarchy")?.get("firstChunkSize").is_none() {
        return None;
    }
    let corner = |which: &str| -> Option<[f64; 3]> {
        let a = v.get("boundingBox")?.get(which)?.as_array()?;
        let c = |k: usize| a.get(k)?.as_f64();
        Some([c(0)?, c(1)?, c(2)?])
    };
    let files_bytes: u64 = POTREE2_FILES
        .iter()
        .filter_map(|f| std::fs::metadata(dir.join(f)).ok())
        .map(|m| m.len())
        .sum();
    Some(Known {
        version,
        entry: DatasetEntry {
            name: name.to_string(),
            version: "potree 2.0".into(),
            id: None,
            points: v.get("points")?.as_u64()?,
            nodes: 0,
            depth: v.get("hierarchy")?.get("depth")?.as_u64()? as u32,
            bounds: strata_format::Bounds {
                min: corner("min")?,
                max: corner("max")?,
            },
            bytes: json.len() as u64 + files_bytes,
        },
        files: POTREE2_FILES.iter().map(|f| f.to_string()).collect(),
    })
}

impl Catalog {
    /// `root` must be canonical.
    pub fn new(root: PathBuf) -> Catalog {
        Catalog {
            root,
            known: Mutex::new(HashMap::new()),
            reported: Mutex::new(HashMap::new()),
        }
    }

    /// The dataset directory `name` (one segment, already checked), if it lies inside the root.
    fn dataset_dir(&self, name: &str) -> Option<PathBuf> {
        let (dir, meta) = confined(&self.root, &self.root.join(name))?;
        meta.is_dir().then_some(dir)
    }

    /// The dataset in `dir`, from the cache while its `metadata.json` is unchanged.
    fn dataset(&self, name: &str, dir: &Path) -> Option<Known> {
        let meta_path = dir.join(DatasetFile::Metadata.name());
        let (meta_path, stat) = confined(&self.root, &meta_path)?;
        if !stat.is_file() {
            return None;
        }
        let version = Version::of(&stat);
        if let Some(k) = self.known.lock().ok()?.get(name)
            && k.version == version
        {
            return Some(k.clone());
        }
        let (file, stat) = crate::files::open_regular(&meta_path)?;
        if stat.len() > METADATA_MAX {
            self.report(
                name,
                version,
                &meta_path,
                &format!(
                    "{} bytes, more than a dataset's metadata holds ({METADATA_MAX})",
                    stat.len()
                ),
            );
            return None;
        }
        let bytes = crate::files::read_range(&file, 0, stat.len() as usize).ok()?;
        let version = Version::of(&stat);
        // Any minor version: the server hands out the files without reading them. A Potree
        // 2.0 dataset (`strata export --format potree2`, PotreeConverter 2) is served too.
        let known = match Metadata::from_json_any_minor(&bytes, &meta_path) {
            Ok(m) => Known {
                version,
                entry: DatasetEntry {
                    name: name.to_string(),
                    version: format!("{}.{}", m.version[0], m.version[1]),
                    id: m.id,
                    points: m.points,
                    nodes: m.nodes,
                    depth: m.depth,
                    bounds: m.bounds,
                    bytes: bytes.len() as u64 + m.files.hierarchy.size + m.files.octree.size,
                },
                files: [&m.files.hierarchy.name, &m.files.octree.name]
                    .into_iter()
                    .filter(|n| plain_file_name(n))
                    .cloned()
                    .collect(),
            },
            Err(e) => match potree2(name, &bytes, dir, version) {
                Some(k) => k,
                None => {
                    self.report(name, version, &meta_path, &e.to_string());
                    return None;
                }
            },
        };
        if let Ok(mut cache) = self.known.lock() {
            cache.insert(name.to_string(), known.clone());
        }
        Some(known)
    }

    /// Says on stderr, once per version of its `metadata.json`, why dataset `name` is not
    /// served: a client sees only a 404, and the listing leaves it out.
    fn report(&self, name: &str, version: Version, path: &Path, fault: &str) {
        let first = match self.reported.lock() {
            Ok(mut reported) => reported.insert(name.to_string(), version) != Some(version),
            Err(_) => false,
        };
        if first {
            // The fault names the file where it comes from the parser; else name it here.
            let fault = match fault.contains(&*path.to_string_lossy()) {
                true => fault.to_string(),
                false => format!("{}: {fault}", path.display()),
            };
            // Outside the lock, and never a panic: stderr may be a closed pipe.
            let _ = writeln!(
                std::io::stderr(),
                "warning: {fault}; dataset {name:?} is not served"
            );
        }
    }

    /// The path of `file` in dataset `dataset` if the dataset's metadata names it, inside the
    /// root; `None` for everything else, whether or not it exists.
    pub fn file(&self, dataset: &str, file: &str) -> Option<PathBuf> {
        let dir = self.dataset_dir(dataset)?;
        let known = self.dataset(dataset, &dir)?;
        if file != DatasetFile::Metadata.name() && !known.files.iter().any(|f| f == file) {
            return None;
        }
        let (path, stat) = confined(&self.root, &dir.join(file))?;
        stat.is_file().then_some(path)
    }

    /// Every dataset directly under the root, by name; `None` where the root cannot be read
    /// (gone since the start, say), which is no empty list.
    pub fn list(&self) -> Option<Vec<DatasetEntry>> {
        let dir = std::fs::read_dir(&self.root).ok()?;
        let mut out: Vec<DatasetEntry> = dir
            .filter_map(Result::ok)
            .filter_map(|e| {
                let name = e.file_name().to_str()?.to_string();
                // Hidden, or a name no request can give (`path::segments` refuses it).
                if name.starts_with('.') || name.contains([':', '\\']) {
                    return None;
                }
                let dir = self.dataset_dir(&name)?;
                Some(self.dataset(&name, &dir)?.entry)
            })
            .collect();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        // Datasets removed since: forget them, so the cache holds what the root holds.
        if let Ok(mut cache) = self.known.lock() {
            cache.retain(|name, _| out.iter().any(|e| &e.name == name));
        }
        Some(out)
    }
}
