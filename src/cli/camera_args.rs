//! The camera options of `strata render` and `strata pick`: a spec, or a saved bookmark.

use anyhow::Context;
use std::path::PathBuf;
use strata_viewer::bookmarks::{self, Bookmarks};
use strata_viewer::headless::DEFAULT_FOV_DEG;

#[derive(Debug, clap::Args)]
pub struct CameraArgs {
    /// "eye=X,Y,Z;target=X,Y,Z;fov=DEG" in the dataset's coordinates (default: all in view).
    #[arg(long, conflicts_with = "camera_file")]
    pub camera: Option<String>,
    /// A bookmarks file (the window saves DATASET/bookmarks.json): view from its first
    /// bookmark, or the one --bookmark names.
    #[arg(long, value_name = "FILE")]
    pub camera_file: Option<PathBuf>,
    /// The bookmark to view from: a name in --camera-file, or in the dataset's own
    /// bookmarks.json when no file is given.
    #[arg(long, value_name = "NAME")]
    pub bookmark: Option<String>,
}

impl CameraArgs {
    /// The camera spec to render with, `None` for the default view.
    pub fn spec(&self, dataset: &str) -> anyhow::Result<Option<String>> {
        if let Some(spec) = &self.camera {
            return Ok(Some(spec.clone()));
        }
        let file = match (&self.camera_file, &self.bookmark) {
            (Some(f), _) => f.clone(),
            (None, Some(_)) => bookmarks::beside(dataset)
                .context("--bookmark without --camera-file needs a local dataset")?,
            (None, None) => return Ok(None),
        };
        // A file named on the command line must exist (absent, `load` reads it as empty).
        if std::fs::symlink_metadata(&file).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound)
        {
            match &self.camera_file {
                Some(f) => anyhow::bail!(
                    "{}: cannot read the --camera-file: no such file",
                    f.display()
                ),
                None => anyhow::bail!(
                    "{}: no bookmarks are saved for this dataset, so --bookmark names none",
                    file.display()
                ),
            }
        }
        let marks = Bookmarks::load(&file)?;
        let mark = marks.find(self.bookmark.as_deref(), &file)?;
        Ok(Some(mark.spec(DEFAULT_FOV_DEG)))
    }
}
