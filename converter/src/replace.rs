//! What `--overwrite` may replace: a folder holding only what Strata itself writes there (a
//! dataset, a Potree 2.0 dataset, a plan), its marker file among them, or nothing. A file, an
//! input, or a folder with anything else in it is refused before any work starts: a mistyped
//! `-o` must never cost a user their files. An export onto, into or around the dataset it
//! reads is refused too (`refuse_source`).

use crate::error::{ConvertError, Result};
use std::fs;
use std::path::Path;

/// The file a `--plan-only` writes into its folder before anything else and removes once its
/// `plan.json` is written: a plan folder holding it and no `plan.json` is one whose making
/// stopped part way, of no use to anyone.
pub const UNFINISHED_PLAN: &str = "plan.unfinished";

/// The kind of folder an output is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Folder {
    /// A Strata or Potree 2.0 dataset (PotreeConverter adds its log).
    Dataset,
    /// A plan of a conversion as tasks.
    Plan,
}

impl Folder {
    /// The entries such a folder may hold: a dataset's files (with what the viewer saves
    /// beside them, its atomic writes' leftovers, and what file browsers leave), all plain
    /// files; a plan's file and folders.
    fn holds(self, name: &str, is_file: bool) -> bool {
        match self {
            Folder::Dataset => {
                const FILES: [&str; 4] =
                    ["metadata.json", "hierarchy.bin", "octree.bin", "log.txt"];
                const CLUTTER: [&str; 3] = [".DS_Store", "Thumbs.db", "desktop.ini"];
                let base = name.strip_suffix(".part").unwrap_or(name);
                is_file
                    && (FILES.contains(&base)
                        || crate::finish::VIEWER_FILES.contains(&base)
                        || CLUTTER.contains(&name))
            }
            Folder::Plan => match name {
                "plan.json" | UNFINISHED_PLAN => is_file,
                "shares" | "staging" | "tasks" => !is_file,
                _ => false,
            },
        }
    }

    /// The file every non-empty folder of the kind holds.
    fn marker(self) -> &'static str {
        match self {
            Folder::Dataset => "metadata.json",
            Folder::Plan => "plan.json",
        }
    }

    /// Whether `name` marks a folder of the kind as Strata's: its marker, or for a plan the
    /// file a `--plan-only` writes first and removes once `plan.json` is there.
    fn is_marker(self, name: &str) -> bool {
        name == self.marker() || (self == Folder::Plan && name == UNFINISHED_PLAN)
    }

    fn name(self) -> &'static str {
        match self {
            Folder::Dataset => "dataset",
            Folder::Plan => "plan",
        }
    }
}

/// Refuses `output` where it exists, unless `overwrite` is given and it is an empty folder or
/// one that holds only what a `kind` folder holds.
pub fn check_output(output: &Path, overwrite: bool, kind: Folder) -> Result<()> {
    // `DIR/.` passes for DIR in most path functions but cannot be renamed into: refused now,
    // not after the work.
    let text = output.as_os_str().to_string_lossy();
    let last = text
        .trim_end_matches('/')
        .rsplit('/')
        .next()
        .unwrap_or_default();
    if matches!(last, "" | "." | "..") || output.file_name().is_none() {
        return Err(ConvertError::output(
            output,
            format!(
                "names no {} folder of its own: give the folder by its name, not ending in . or ..",
                kind.name()
            ),
        ));
    }
    let meta = match fs::symlink_metadata(output) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        // ENOTDIR: a folder on the way is a file.
        Err(e) if e.kind() == std::io::ErrorKind::NotADirectory => {
            return Err(ConvertError::output(
                output,
                "cannot be made: a part of its path is a file, not a folder",
            ));
        }
        Err(e) => return Err(ConvertError::io(output, "cannot look at the output", e)),
    };
    if !overwrite {
        return Err(ConvertError::output(
            output,
            "output already exists (pass --overwrite to replace it)",
        ));
    }
    let refuse = |what: String| {
        ConvertError::output(
            output,
            format!(
                "{what}; --overwrite replaces only a {} folder, so remove it yourself or choose \
                 another output",
                kind.name()
            ),
        )
    };
    if !meta.is_dir() {
        return Err(refuse(if meta.is_symlink() {
            "is a symbolic link, not a folder".into()
        } else {
            "is a file, not a folder".into()
        }));
    }
    let list = |e| ConvertError::io(output, "cannot list the output", e);
    let mut marked = false;
    let mut empty = true;
    for entry in fs::read_dir(output).map_err(list)? {
        let entry = entry.map_err(list)?;
        let name = entry.file_name();
        // Not followed: a link is neither a file nor a folder of ours.
        let file_type = entry.file_type().map_err(list)?;
        let is_file = file_type.is_file();
        let ours = name
            .to_str()
            .is_some_and(|n| (is_file || file_type.is_dir()) && kind.holds(n, is_file));
        if !ours {
            return Err(refuse(format!(
                "holds {:?}, which a {} folder does not",
                name,
                kind.name()
            )));
        }
        marked |= kind.is_marker(&name.to_string_lossy());
        empty = false;
    }
    if !empty && !marked {
        return Err(refuse(format!(
            "has no {}, so it is no {} of Strata's",
            kind.marker(),
            kind.name()
        )));
    }
    Ok(())
}

/// Refuses an export `output` that is the dataset it reads (`source`), lies inside it, or
/// holds it: replacing it would destroy the points being read (a Potree 2.0 export onto its
/// own dataset passes `check_output`, both being dataset folders), and a file written inside
/// it is taken for a stranger by every later `--overwrite`. Links are followed, so that a
/// second name for the same folder is caught.
pub fn refuse_source(source: &Path, output: &Path) -> Result<()> {
    let (src, out) = (resolved(source), resolved(output));
    let how = if src == out {
        "is the dataset being exported"
    } else if out.starts_with(&src) {
        "lies inside the dataset being exported"
    } else if src.starts_with(&out) {
        "holds the dataset being exported"
    } else {
        return Ok(());
    };
    Err(ConvertError::output(
        output,
        format!(
            "{how}, {}, which writing it would destroy; give -o a place outside the dataset",
            source.display()
        ),
    ))
}

/// `path` made absolute with its links followed, as far as it exists: the part that does not
/// exist yet (an output to be made) is appended as written.
fn resolved(path: &Path) -> std::path::PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut missing = Vec::new();
    let mut at = absolute.as_path();
    loop {
        if let Ok(real) = fs::canonicalize(at) {
            return missing.iter().rev().fold(real, |p, part| p.join(part));
        }
        match (at.parent(), at.file_name()) {
            (Some(parent), Some(name)) => {
                missing.push(name.to_os_string());
                at = parent;
            }
            _ => return absolute,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(output: &Path, kind: Folder) -> String {
        match check_output(output, true, kind) {
            Err(e) => e.to_string(),
            Ok(()) => panic!("{} was accepted", output.display()),
        }
    }

    #[test]
    fn replaces_only_what_strata_writes() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        // Absent: nothing to replace, with or without --overwrite.
        assert!(check_output(&root.join("none"), false, Folder::Dataset).is_ok());
        for odd in ["new.strata/.", "new.strata/..", ".", "/", "new.strata/./"] {
            let e = check_output(&root.join(odd), true, Folder::Dataset).unwrap_err();
            assert!(e.to_string().contains("names no"), "{odd}: {e}");
        }
        // An empty folder and a dataset may be replaced, only with --overwrite.
        let ds = root.join("ds");
        fs::create_dir(&ds).unwrap();
        assert!(check_output(&ds, true, Folder::Dataset).is_ok());
        for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
            fs::write(ds.join(f), b"x").unwrap();
        }
        assert!(check_output(&ds, true, Folder::Dataset).is_ok());
        let e = check_output(&ds, false, Folder::Dataset).unwrap_err();
        assert!(e.to_string().contains("--overwrite"), "{e}");
        // Anything else in it, a file, an input: refused, naming what is in the way.
        fs::create_dir(ds.join("photos")).unwrap();
        let e = refused(&ds, Folder::Dataset);
        assert!(e.contains("\"photos\"") && e.contains("ds"), "{e}");
        let file = root.join("in.las");
        fs::write(&file, b"LASF").unwrap();
        assert!(refused(&file, Folder::Dataset).contains("is a file"));
        fs::remove_dir(ds.join("photos")).unwrap();
        // What the viewer saves in a dataset, and a file browser's leftovers, go with it.
        for f in ["measurements.geojson", "bookmarks.json.part", ".DS_Store"] {
            fs::write(ds.join(f), b"x").unwrap();
        }
        assert!(check_output(&ds, true, Folder::Dataset).is_ok());
        // Without its marker, a folder of the right names is not taken for one of ours.
        let bare = root.join("bare");
        fs::create_dir_all(bare.join("tasks/mine")).unwrap();
        assert!(refused(&bare, Folder::Plan).contains("has no plan.json"));
        fs::write(bare.join("octree.bin"), b"x").unwrap();
        fs::remove_dir_all(bare.join("tasks")).unwrap();
        assert!(refused(&bare, Folder::Dataset).contains("has no metadata.json"));
        // A dataset's names must be files.
        fs::create_dir(ds.join("hierarchy.bin.part")).unwrap();
        assert!(refused(&ds, Folder::Dataset).contains("\"hierarchy.bin.part\""));
        fs::remove_dir(ds.join("hierarchy.bin.part")).unwrap();
        // A plan folder is not a dataset, nor a dataset a plan.
        let plan = root.join("plan");
        fs::create_dir_all(plan.join("tasks")).unwrap();
        fs::write(plan.join("plan.json"), b"{}").unwrap();
        assert!(check_output(&plan, true, Folder::Plan).is_ok());
        assert!(refused(&plan, Folder::Dataset).contains("\"plan.json\""));
        assert!(refused(&ds, Folder::Plan).contains("a plan folder"));
    }

    #[test]
    fn an_export_into_or_over_its_own_dataset_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let ds = dir.path().join("ds.strata");
        fs::create_dir(&ds).unwrap();
        fs::write(ds.join("metadata.json"), b"{}").unwrap();
        let said = |out: &Path| match refuse_source(&ds, out) {
            Err(e) => e.to_string(),
            Ok(()) => panic!("{} was accepted", out.display()),
        };
        assert!(said(&ds).contains("is the dataset being exported"));
        // Another spelling of the same folder.
        fs::create_dir(dir.path().join("sub")).unwrap();
        assert!(said(&dir.path().join("sub/../ds.strata/")).contains("is the dataset"));
        assert!(said(&ds.join("out.las")).contains("lies inside the dataset"));
        assert!(said(&ds.join("new/p2")).contains("lies inside the dataset"));
        assert!(said(dir.path()).contains("holds the dataset"));
        #[cfg(unix)]
        {
            let link = dir.path().join("link");
            std::os::unix::fs::symlink(&ds, &link).unwrap();
            assert!(said(&link).contains("is the dataset"));
        }
        // Beside it, or a name that merely starts with its name: accepted.
        assert!(refuse_source(&ds, &dir.path().join("ds.strata2")).is_ok());
        assert!(refuse_source(&ds, &dir.path().join("out.las")).is_ok());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target");
        fs::create_dir(&target).unwrap();
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        assert!(refused(&link, Folder::Dataset).contains("symbolic link"));
    }
}
