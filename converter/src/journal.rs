//! What `--resume` reads back: the plan (valid only for the same inputs and options, which
//! its fingerprint records) and the journal of chunks committed to the octree file, in plan
//! order, one JSON line each.

use crate::build::ConvertOptions;
use crate::chunk_step::ChunkStep;
use crate::error::{ConvertError, Result, io_err};
use crate::plan::check_chunks;
use crate::prepare::Plan;
use crate::rowfile::RowWriter;
use crate::tree::FinishedNode;
use crate::workdir::WorkDir;
use serde::{Deserialize, Serialize};
use std::fs::{self, File, OpenOptions};
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::PathBuf;
use strata_format::{DatasetId, NodeKey, NodeRecord, OCTREE_HEAD_SIZE, octree_head};

/// A node as the journal stores it: (level, x, y, z, points, offset, size, crc, child mask).
type JournalNode = (u8, u32, u32, u32, u32, u64, u32, u32, u8);

/// One committed chunk in the journal.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JournalEntry {
    pub chunk: usize,
    /// The octree file's length once this chunk's nodes are in it.
    pub end: u64,
    pub root_mask: u8,
    nodes: Vec<JournalNode>,
    /// What the per-chunk step reported for this chunk.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub step: Vec<f64>,
}

impl JournalEntry {
    /// The entry as it reads once its octree file's bytes after the head have moved `by`
    /// bytes on (a task's nodes copied into the dataset's octree file).
    pub fn moved(mut self, by: u64) -> Self {
        self.end += by;
        for n in &mut self.nodes {
            // A node without a payload keeps offset 0 (`record_of`).
            if n.6 > 0 {
                n.5 += by;
            }
        }
        self
    }

    pub fn records(&self) -> impl Iterator<Item = (NodeKey, NodeRecord)> + '_ {
        self.nodes.iter().map(
            |&(level, x, y, z, point_count, offset, size, checksum, child_mask)| {
                (
                    NodeKey { level, x, y, z },
                    NodeRecord {
                        point_count,
                        offset,
                        size,
                        checksum,
                        child_mask,
                    },
                )
            },
        )
    }
}

/// The octree file's length after the committed chunks of `journal`.
pub fn octree_end(journal: &[JournalEntry]) -> u64 {
    journal.last().map_or(OCTREE_HEAD_SIZE, |j| j.end)
}

/// The hierarchy's record of a node whose payload was written at `offset`; a node without
/// points has no payload, and offset 0.
pub fn record_of(n: &FinishedNode, offset: u64) -> NodeRecord {
    NodeRecord {
        point_count: n.point_count,
        offset: if n.payload.is_empty() { 0 } else { offset },
        size: n.payload.len() as u32,
        checksum: n.crc,
        child_mask: n.child_mask,
    }
}

/// What makes a work directory resumable by this run: the inputs as they are on disk, and
/// every option that changes the chunks.
pub fn fingerprint(opts: &ConvertOptions) -> String {
    let mut parts = Vec::new();
    for p in &opts.inputs {
        use std::os::unix::fs::MetadataExt;
        let meta = fs::metadata(p).ok();
        let len = meta.as_ref().map_or(0, |m| m.len());
        // Both times to the nanosecond: a file rewritten within the second had the same
        // mtime, and one replaced with its old mtime put back (`touch -r`) still has a new
        // status-change time.
        let times = meta.map_or((0, 0, 0, 0), |m| {
            (m.mtime(), m.mtime_nsec(), m.ctime(), m.ctime_nsec())
        });
        let abs = fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        parts.push(format!("{}:{len}:{times:?}", abs.display()));
    }
    // A work directory of another format version has another octree head.
    parts.push(format!(
        "{}.{}",
        strata_format::VERSION_MAJOR,
        strata_format::VERSION_MINOR
    ));
    // Work files of another layout read as damaged.
    parts.push(format!("rows{}", crate::rowfile::ROWFILE_VERSION));
    parts.push(format!(
        "{}:{}:{}",
        opts.sampling.name(),
        opts.memory_limit,
        opts.threads
    ));
    parts.join("|")
}

/// `fingerprint`, and the step's where it changes the chunks: chunks made by one step (and
/// bands for its margin) are nothing to another.
pub fn run_fingerprint(opts: &ConvertOptions, step: &dyn ChunkStep) -> String {
    let mut fp = fingerprint(opts);
    let step_fp = step.fingerprint();
    if !step_fp.is_empty() {
        fp.push_str(&format!("|step:{step_fp}"));
    }
    fp
}

/// The plan an interrupted run left, if `--resume` asks for it and one is there; an error if
/// it was made from other inputs or options.
pub fn resumable_plan(opts: &ConvertOptions, wd: &WorkDir, fp: &str) -> Result<Option<Plan>> {
    if !opts.resume {
        return Ok(None);
    }
    let Some(plan) = fs::read(wd.plan())
        .ok()
        .and_then(|b| serde_json::from_slice::<Plan>(&b).ok())
    else {
        // Starting over would clear the output's folder and leave the work files behind.
        if let Some(work) = wd.plan_elsewhere() {
            return Err(ConvertError::Usage(format!(
                "the interrupted run kept its work files in {}: resume with the --temp-dir it \
                 was given ({}), or run without --resume to start over",
                work.display(),
                work.parent().map_or("none".into(), |p| {
                    if p == wd.root() {
                        "none".to_string()
                    } else {
                        p.display().to_string()
                    }
                })
            )));
        }
        return Ok(None);
    };
    // Written by the run, but a file on disk all the same: what sizes tables is checked.
    check_chunks(&plan.chunks, &plan.cube, plan.points).map_err(|e| {
        ConvertError::input(
            wd.plan(),
            format!("{e}, so the conversion cannot resume: run it again without --resume"),
        )
    })?;
    if plan.fingerprint != fp {
        return Err(ConvertError::output(
            wd.root(),
            "cannot resume: the inputs or options differ from the interrupted run, or it was begun by a build that computes them otherwise (run without --resume to start over)",
        ));
    }
    Ok(Some(plan))
}

/// Starts the octree file and an empty journal, then saves the plan: from then on the work
/// directory can be resumed. The octree head's id is written when the dataset is finished.
pub fn save_plan(wd: &WorkDir, plan: &Plan) -> Result<()> {
    let octree = wd.dataset_file(strata_format::DatasetFile::Octree);
    let mut f = File::create(&octree).map_err(io_err(&octree, "cannot create"))?;
    f.write_all(&octree_head(DatasetId::default()))
        .map_err(io_err(&octree, "cannot write"))?;
    let journal = wd.journal();
    File::create(&journal).map_err(io_err(&journal, "cannot create"))?;
    let part = wd.plan_part();
    fs::write(&part, serde_json::to_vec(plan).unwrap_or_default())
        .map_err(io_err(&part, "cannot write"))?;
    fs::rename(&part, wd.plan()).map_err(io_err(&wd.plan(), "cannot write"))?;
    Ok(())
}

/// The journal a resumed run continues from: whole lines for chunks 0, 1, 2... in order,
/// checked against the octree file (`read_resumable_journal_of`). A run owns its chunk files
/// and deletes each as it commits, so a committed chunk damaged since cannot be built again:
/// refused.
pub fn read_journal(wd: &WorkDir, chunks: usize) -> Result<Vec<JournalEntry>> {
    match read_resumable_journal_of(wd, 0..chunks)? {
        (entries, None) => Ok(entries),
        (_, Some(fault)) => Err(ConvertError::Usage(format!(
            "{fault}, so the conversion cannot resume: run it again without --resume"
        ))),
    }
}

/// The journal of the chunks `chunks` (a task's) that a run may resume from: the entries
/// whose nodes the octree file still holds whole, checksums matching, up to the first that it
/// does not, and what is wrong with that one. The line is written after the nodes, but a crash
/// may leave the line on disk and not the bytes, and a file may be cut or damaged since.
pub fn read_resumable_journal_of(
    wd: &WorkDir,
    chunks: Range<usize>,
) -> Result<(Vec<JournalEntry>, Option<String>)> {
    let mut entries = read_journal_of(wd, chunks);
    if entries.is_empty() {
        return Ok((entries, None));
    }
    let path = wd.dataset_file(strata_format::DatasetFile::Octree);
    let mut octree = File::open(&path).map_err(io_err(&path, "cannot open to resume"))?;
    let len = octree
        .metadata()
        .map_err(io_err(&path, "cannot read to resume"))?
        .len();
    let mut buf = Vec::new();
    let whole = entries
        .iter()
        .take_while(|e| holds(&mut octree, len, e, &mut buf))
        .count();
    let fault = entries.get(whole).map(|bad| {
        let what = if bad.end > len {
            format!(
                "is {len} bytes long where the journal says chunk {} ends at byte {}",
                bad.chunk, bad.end
            )
        } else {
            format!(
                "does not hold chunk {}'s nodes as the journal records them",
                bad.chunk
            )
        };
        format!(
            "{}: {what} (cut or damaged since it was written)",
            path.display()
        )
    });
    entries.truncate(whole);
    Ok((entries, fault))
}

/// Whether `octree` (`len` bytes long) holds every node of `entry` whole.
fn holds(octree: &mut File, len: u64, entry: &JournalEntry, buf: &mut Vec<u8>) -> bool {
    entry.end <= len
        && entry.nodes.iter().all(|&(.., offset, size, checksum, _)| {
            if size == 0 {
                return checksum == 0;
            }
            buf.resize(size as usize, 0);
            offset
                .checked_add(u64::from(size))
                .is_some_and(|end| end <= entry.end)
                && octree.seek(SeekFrom::Start(offset)).is_ok()
                && octree.read_exact(buf).is_ok()
                && strata_format::payload_checksum(buf) == checksum
        })
}

/// The journal of the chunks `chunks` (a task's) as written: whole lines for its chunks in
/// order, not checked against the octree file.
pub fn read_journal_of(wd: &WorkDir, chunks: Range<usize>) -> Vec<JournalEntry> {
    let Ok(f) = File::open(wd.journal()) else {
        return Vec::new();
    };
    let mut out: Vec<JournalEntry> = Vec::new();
    for line in BufReader::new(f).lines() {
        let Ok(line) = line else { break };
        match serde_json::from_str::<JournalEntry>(&line) {
            Ok(e) if e.chunk == chunks.start + out.len() && e.chunk < chunks.end => out.push(e),
            _ => break,
        }
    }
    out
}

/// A chunk's built nodes, waiting for their turn to be committed.
pub struct BuiltChunk {
    pub finished: Vec<FinishedNode>,
    pub root_rows: Vec<u8>,
    /// Bytes per row of `root_rows`.
    pub stride: usize,
    pub root_mask: u8,
    pub step: Vec<f64>,
}

/// Appends chunks to the octree file and the journal, in plan order.
pub struct Committer {
    octree: File,
    octree_path: PathBuf,
    journal: File,
    journal_path: PathBuf,
    end: u64,
}

impl Committer {
    /// Cuts the octree file and the journal back to the chunks in `valid` (what an interrupted
    /// run may have written past them is lost), ready to append after them.
    pub fn open(wd: &WorkDir, valid: &[JournalEntry]) -> Result<Self> {
        let octree_path = wd.dataset_file(strata_format::DatasetFile::Octree);
        let end = octree_end(valid);
        let mut octree = OpenOptions::new()
            .write(true)
            .open(&octree_path)
            .map_err(io_err(&octree_path, "cannot open"))?;
        octree
            .set_len(end)
            .map_err(io_err(&octree_path, "cannot truncate"))?;
        octree
            .seek(SeekFrom::Start(end))
            .map_err(io_err(&octree_path, "cannot seek"))?;
        // Rewrite the journal as its valid prefix so appends follow whole lines.
        let journal_path = wd.journal();
        let mut text = String::new();
        for e in valid {
            text.push_str(&serde_json::to_string(e).unwrap_or_default());
            text.push('\n');
        }
        fs::write(&journal_path, text).map_err(io_err(&journal_path, "cannot write journal"))?;
        let journal = OpenOptions::new()
            .append(true)
            .open(&journal_path)
            .map_err(io_err(&journal_path, "cannot open journal"))?;
        Ok(Committer {
            octree,
            octree_path,
            journal,
            journal_path,
            end,
        })
    }

    /// Writes chunk `chunk`'s nodes and root rows, then its journal line: once the line is
    /// there, a resumed run counts the chunk as done.
    pub fn commit(
        &mut self,
        wd: &WorkDir,
        chunk: usize,
        built: BuiltChunk,
    ) -> Result<JournalEntry> {
        let mut nodes = Vec::with_capacity(built.finished.len());
        for n in &built.finished {
            self.octree
                .write_all(&n.payload)
                .map_err(io_err(&self.octree_path, "cannot write"))?;
            let r = record_of(n, self.end);
            nodes.push((
                n.key.level,
                n.key.x,
                n.key.y,
                n.key.z,
                r.point_count,
                r.offset,
                r.size,
                r.checksum,
                r.child_mask,
            ));
            self.end += n.payload.len() as u64;
        }
        let root_path = wd.chunk_root(chunk);
        // Compressed like every work file of rows; rewritten whole by a resumed run.
        let mut out = RowWriter::create(&root_path, built.stride)?;
        out.write(&built.root_rows)?;
        out.finish()?;
        let entry = JournalEntry {
            chunk,
            end: self.end,
            root_mask: built.root_mask,
            nodes,
            step: built.step,
        };
        let mut line = serde_json::to_string(&entry).unwrap_or_default();
        line.push('\n');
        self.journal
            .write_all(line.as_bytes())
            .map_err(io_err(&self.journal_path, "cannot write journal"))?;
        Ok(entry)
    }

    /// The octree file, for the merge to append the top levels to.
    pub fn into_octree(self) -> (File, PathBuf, u64) {
        (self.octree, self.octree_path, self.end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(payloads: &[&[u8]]) -> BuiltChunk {
        BuiltChunk {
            finished: payloads
                .iter()
                .enumerate()
                .map(|(i, p)| FinishedNode {
                    key: NodeKey::ROOT.child(i as u8),
                    point_count: p.len() as u32,
                    child_mask: 0,
                    payload: p.to_vec(),
                    crc: strata_format::payload_checksum(p),
                })
                .collect(),
            root_rows: vec![0; 4],
            stride: 4,
            root_mask: 0,
            step: Vec::new(),
        }
    }

    #[test]
    fn a_resume_takes_the_chunks_the_octree_file_still_holds() {
        let dir = tempfile::tempdir().expect("tempdir");
        let wd = WorkDir::new(&dir.path().join("ds"), None);
        wd.create_fresh().expect("work dir");
        let octree = wd.dataset_file(strata_format::DatasetFile::Octree);
        fs::write(&octree, octree_head(DatasetId::default())).expect("head");
        fs::write(wd.journal(), b"").expect("journal");
        let mut c = Committer::open(&wd, &[]).expect("open");
        c.commit(&wd, 0, chunk(&[b"first", b"", b"second"]))
            .expect("0");
        c.commit(&wd, 1, chunk(&[b"third"])).expect("1");
        drop(c);
        let whole = fs::read(&octree).expect("read");
        let (entries, fault) = read_resumable_journal_of(&wd, 0..2).expect("read");
        assert_eq!((entries.len(), fault), (2, None));
        // A byte of chunk 1's node changed: chunk 0 still stands.
        let mut bytes = whole.clone();
        let last = bytes.len() - 1;
        bytes[last] ^= 1;
        fs::write(&octree, &bytes).expect("write");
        let (entries, fault) = read_resumable_journal_of(&wd, 0..2).expect("read");
        assert_eq!(entries.len(), 1);
        assert!(fault.expect("fault").contains("chunk 1's nodes"));
        let e = read_journal(&wd, 2)
            .expect_err("a run cannot rebuild it")
            .to_string();
        assert!(e.contains("run it again without --resume"), "{e}");
        // Cut inside chunk 0's first node: nothing stands.
        fs::write(&octree, &whole[..OCTREE_HEAD_SIZE as usize + 2]).expect("write");
        let (entries, fault) = read_resumable_journal_of(&wd, 0..2).expect("read");
        assert!(entries.is_empty());
        assert!(
            fault
                .expect("fault")
                .contains("where the journal says chunk 0 ends")
        );
    }
}
