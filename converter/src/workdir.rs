//! Where a conversion keeps its files: `OUTPUT.strata-tmp/`, which becomes the dataset by a
//! rename once complete. Its `work/` folder holds what only the conversion reads (staging
//! files, chunk parts, the plan and the journal for `--resume`) and is removed before the rename;
//! with `--temp-dir DIR` that folder is `DIR/OUTPUT.strata-work` instead, on another disk.

use crate::distribute::chunk_path;
use crate::error::{ConvertError, Result, io_err};
use std::fs;
use std::path::{Path, PathBuf};
use strata_format::DatasetFile;

/// An exclusive lock on folder `dir`, held while the file lives; `None` where another process
/// holds it. A file system that cannot lock a folder (NFS emulates flock with locks that need
/// a file open for writing) gives the file unlocked: unguarded rather than refusing all work.
pub fn lock_folder(dir: &Path) -> Result<Option<fs::File>> {
    let folder = fs::File::open(dir).map_err(io_err(dir, "cannot open"))?;
    match folder.try_lock() {
        Ok(()) | Err(fs::TryLockError::Error(_)) => Ok(Some(folder)),
        Err(fs::TryLockError::WouldBlock) => Ok(None),
    }
}

/// The lock `WorkDir::lock` takes, held while the value lives.
#[derive(Debug)]
pub struct OutputLock {
    _folder: fs::File,
    /// The folder to remove (if empty) on release.
    remove: Option<PathBuf>,
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        if let Some(folder) = &self.remove {
            let _ = fs::remove_dir(folder);
        }
    }
}

#[derive(Debug, Clone)]
pub struct WorkDir {
    root: PathBuf,
    work: PathBuf,
    /// Where the chunk files are when a plan's shares wrote them, not this conversion.
    shared: Option<SharedChunks>,
}

/// The chunk files a plan's distribution shares wrote, each share into its own folder, read
/// by every task: a task reads them but never removes them.
#[derive(Debug, Clone)]
pub struct SharedChunks {
    /// Share s's files are in `dir/s`.
    pub dir: PathBuf,
    pub shares: usize,
}

impl WorkDir {
    /// The work directory of a conversion into `output`: a sibling, so the final rename stays
    /// on one file system.
    pub fn for_output(output: &Path) -> Self {
        Self::new(output, None)
    }

    /// As `for_output`, with the work folder under `temp` when given.
    pub fn new(output: &Path, temp: Option<&Path>) -> Self {
        let base = output.file_name().unwrap_or_default().to_os_string();
        let mut name = base.clone();
        name.push(".strata-tmp");
        let root = output.with_file_name(name);
        let work = match temp {
            Some(t) => {
                let mut name = base;
                name.push(".strata-work");
                t.join(name)
            }
            None => root.join("work"),
        };
        WorkDir {
            root,
            work,
            shared: None,
        }
    }

    /// A conversion's files in `root`, its work files in `work`: a plan's folder, a task's.
    pub fn at(root: PathBuf, work: PathBuf) -> Self {
        WorkDir {
            root,
            work,
            shared: None,
        }
    }

    /// As `at`, reading the chunk files a plan's shares wrote.
    pub fn with_shared_chunks(self, shared: SharedChunks) -> Self {
        WorkDir {
            shared: Some(shared),
            ..self
        }
    }

    /// Whether the chunk files are this conversion's own, to remove once consumed.
    pub fn owns_chunks(&self) -> bool {
        self.shared.is_none()
    }

    /// Whether the work folder lies outside the folder that becomes the dataset.
    pub fn separate(&self) -> bool {
        !self.work.starts_with(&self.root)
    }

    /// Removes everything of the conversion: the folder and a separate work folder.
    pub fn remove_all(&self) {
        let _ = fs::remove_dir_all(&self.root);
        if self.separate() {
            let _ = fs::remove_dir_all(&self.work);
        }
    }

    /// The folder that becomes the dataset.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The folder of files that never reach the dataset.
    pub fn work(&self) -> &Path {
        &self.work
    }

    /// Whether `path` is one of the conversion's own files (a staging file), not an input.
    pub fn holds(&self, path: &Path) -> bool {
        path.starts_with(&self.work)
    }

    pub fn chunks(&self) -> PathBuf {
        self.work.join("chunks")
    }

    /// Part `part` of chunk `chunk`, as the distribute phase (or a plan's share) wrote it.
    pub fn chunk_part(&self, chunk: usize, part: usize) -> PathBuf {
        match &self.shared {
            // `Share::file_part`: part = worker x shares + share.
            Some(s) => chunk_path(
                &s.dir.join((part % s.shares.max(1)).to_string()),
                chunk,
                part,
            ),
            None => chunk_path(&self.chunks(), chunk, part),
        }
    }

    /// Where each committed chunk keeps its root node's rows for the top-level merge.
    pub fn roots(&self) -> PathBuf {
        self.work.join("roots")
    }

    pub fn chunk_root(&self, chunk: usize) -> PathBuf {
        self.roots().join(format!("c{chunk}.bin"))
    }

    /// The rows of each chunk within its neighbours' reach, which they see as their halo, a
    /// file for each neighbour.
    pub fn bands(&self) -> PathBuf {
        self.work.join("bands")
    }

    /// The rows of chunk `chunk` that lie in chunk `reader`'s halo.
    pub fn chunk_band(&self, chunk: usize, reader: usize) -> PathBuf {
        self.bands().join(format!("c{chunk}-for-c{reader}.bin"))
    }

    /// Its presence marks a work directory that `--resume` can continue.
    pub fn plan(&self) -> PathBuf {
        self.work.join("plan.json")
    }

    /// Written first and renamed, so a plan file is always whole.
    pub fn plan_part(&self) -> PathBuf {
        self.work.join("plan.json.part")
    }

    pub fn journal(&self) -> PathBuf {
        self.work.join("journal.jsonl")
    }

    /// Rows decoded from compressed input `input`.
    pub fn decoded_rows(&self, input: usize) -> PathBuf {
        self.work.join(format!("rows{input}.bin"))
    }

    /// Every input's points as f64 positions, before the scale is known.
    pub fn measured_staging(&self) -> PathBuf {
        self.work.join("staging.bin")
    }

    /// The measured staging file quantized into rows.
    pub fn measured_rows(&self) -> PathBuf {
        self.work.join("rows.bin")
    }

    /// A file of the dataset, as it will be named once the folder is renamed.
    pub fn dataset_file(&self, file: DatasetFile) -> PathBuf {
        self.root.join(file.name())
    }

    /// Where a dataset being replaced (`--overwrite`) goes just before it is removed.
    pub fn replaced(&self) -> PathBuf {
        self.root.with_extension("old")
    }

    /// Takes the folder that becomes the dataset for this process, creating it where it is
    /// missing: two conversions into one output would each clear and fill what the other
    /// writes. The second is refused while the first runs (its lock goes with the process, a
    /// crash included), before it touches anything. `output` names the fault.
    pub fn lock(&self, output: &Path) -> Result<OutputLock> {
        fs::create_dir_all(&self.root)
            .map_err(io_err(&self.root, "cannot create work directory"))?;
        match lock_folder(&self.root)? {
            Some(folder) => Ok(OutputLock {
                _folder: folder,
                remove: None,
            }),
            None => Err(ConvertError::output(
                output,
                format!(
                    "is being written by another conversion (it holds {}); wait for it to end",
                    self.root.display()
                ),
            )),
        }
    }

    /// As `lock`, for a command that writes its output elsewhere but must not run twice into
    /// it (`convert --format potree2`): the folder made for the lock goes when it is released.
    pub fn lock_only(&self, output: &Path) -> Result<OutputLock> {
        let mut lock = self.lock(output)?;
        lock.remove = Some(self.root.clone());
        Ok(lock)
    }

    /// An empty work directory, clearing what an earlier run left. The folder that becomes
    /// the dataset is emptied in place, not replaced, so that its lock holds.
    pub fn create_fresh(&self) -> Result<()> {
        // An earlier run's work files under another --temp-dir go too: nothing would resume
        // them once the root is cleared. Only a folder named as this writes them is removed.
        if let Ok(named) = fs::read(self.work_note()) {
            let old = PathBuf::from(String::from_utf8_lossy(&named).into_owned());
            let ours = old
                .file_name()
                .is_some_and(|n| n.to_string_lossy().ends_with(".strata-work"));
            if ours && old != self.work && old.is_dir() {
                fs::remove_dir_all(&old)
                    .map_err(io_err(&old, "cannot clear old work directory"))?;
            }
        }
        if self.separate() && self.work.exists() {
            fs::remove_dir_all(&self.work)
                .map_err(io_err(&self.work, "cannot clear old work directory"))?;
        }
        fs::create_dir_all(&self.root)
            .map_err(io_err(&self.root, "cannot create work directory"))?;
        let entries = fs::read_dir(&self.root).map_err(io_err(&self.root, "cannot list"))?;
        for entry in entries {
            let path = entry.map_err(io_err(&self.root, "cannot list"))?.path();
            let cleared = if path.is_dir() && !path.is_symlink() {
                fs::remove_dir_all(&path)
            } else {
                fs::remove_file(&path)
            };
            cleared.map_err(io_err(&path, "cannot clear old work directory"))?;
        }
        for dir in [self.chunks(), self.roots()] {
            fs::create_dir_all(&dir).map_err(io_err(&dir, "cannot create work directory"))?;
        }
        // Where the work files went, so that a --resume given another --temp-dir (or none)
        // is told where they are rather than starting over beside them.
        if self.separate() {
            let note = self.work_note();
            fs::write(&note, self.work.as_os_str().as_encoded_bytes())
                .map_err(io_err(&note, "cannot write"))?;
        }
        Ok(())
    }

    /// The file in the root naming a separate work folder (`--temp-dir`).
    fn work_note(&self) -> PathBuf {
        self.root.join("work-folder")
    }

    /// Removes the note of a separate work folder, once that folder is gone: the root becomes
    /// the dataset, which holds its own files only.
    pub fn forget_work_folder(&self) -> Result<()> {
        let note = self.work_note();
        match fs::remove_file(&note) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(ConvertError::io(&note, "cannot remove", e))
            }
            _ => Ok(()),
        }
    }

    /// Where an earlier run of this output kept a plan it can resume from, other than this
    /// run's work folder: the root's own (no `--temp-dir`) or the one the root names.
    pub fn plan_elsewhere(&self) -> Option<PathBuf> {
        let mut places = vec![self.root.join("work")];
        if let Ok(named) = fs::read(self.work_note()) {
            places.push(PathBuf::from(String::from_utf8_lossy(&named).into_owned()));
        }
        places
            .into_iter()
            .filter(|w| *w != self.work)
            .find(|w| w.join("plan.json").is_file())
    }

    /// Removes the files decoded from the first `inputs` inputs, those that exist.
    pub fn remove_decoded(&self, inputs: usize) -> Result<()> {
        for i in 0..inputs {
            let path = self.decoded_rows(i);
            match fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_err(&path, "cannot remove staging file")(e));
                }
                _ => {}
            }
        }
        Ok(())
    }
}
