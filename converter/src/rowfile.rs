//! Work files of rows (staging rows, chunk parts, halo bands), compressed as they are written
//! so that a conversion's peak disk stays well under its rows' size. A file is a sequence of
//! blocks, each of whole rows: 4 bytes of raw length, 4 of compressed length, 4 of CRC-32 of
//! those 8 bytes and the compressed bytes (little endian), then the block's rows with their
//! bytes grouped by position in the row (every row's first byte, then every row's second, ...),
//! which lines up the slowly changing high bytes of positions and attributes, compressed with
//! lz4. The checksum is there because lz4 decodes most damaged bytes into other rows without a
//! fault: a work file changed on disk would otherwise pass into the dataset unnoticed.

use crate::error::{ConvertError, Result, io_err};
use crate::row_shuffle::{shuffle, unshuffle};
use std::fs::{File, OpenOptions};
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

const HEADER: usize = 12;

/// The most rows' bytes in one block: writers make at most a few MiB (`block_rows`, the
/// distribution's flushes), so a larger length is damage, refused before it is read.
const MAX_BLOCK_BYTES: usize = 64 << 20;

/// Changes whenever work files written by one build read differently in another: it is part
/// of a run's fingerprint, so `--resume` and a plan's tasks never read another layout.
pub const ROWFILE_VERSION: u32 = 2;

/// The checksum of a block: its two lengths and its compressed bytes.
fn block_checksum(lengths: &[u8], packed: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(lengths);
    h.update(packed);
    h.finalize()
}

/// Rows per block of a staging file, whose blocks all hold this many rows but the last, so
/// that a record's block is found by division.
pub fn block_rows(stride: usize) -> usize {
    ((1usize << 20) / stride.max(1)).clamp(1, 1 << 14)
}

/// Reusable buffers for encoding and decoding blocks.
#[derive(Default)]
pub struct Scratch {
    grouped: Vec<u8>,
    packed: Vec<u8>,
}

/// Writes `rows` as one block to `out`; returns the bytes written.
pub fn write_block(
    out: &mut impl Write,
    rows: &[u8],
    stride: usize,
    scratch: &mut Scratch,
    path: &Path,
) -> Result<u64> {
    if rows.len() > MAX_BLOCK_BYTES {
        return Err(ConvertError::internal(
            format!("writing {}", path.display()),
            format!("a block of {} bytes, more than a reader takes", rows.len()),
        ));
    }
    shuffle(rows, stride, &mut scratch.grouped);
    let packed = &mut scratch.packed;
    packed.clear();
    packed.resize(
        HEADER + lz4_flex::block::get_maximum_output_size(rows.len()),
        0,
    );
    let len =
        lz4_flex::block::compress_into(&scratch.grouped, &mut packed[HEADER..]).map_err(|e| {
            ConvertError::internal(format!("compressing {}", path.display()), e.to_string())
        })?;
    packed[..4].copy_from_slice(&(rows.len() as u32).to_le_bytes());
    packed[4..8].copy_from_slice(&(len as u32).to_le_bytes());
    let crc = block_checksum(&packed[..8], &packed[HEADER..HEADER + len]);
    packed[8..12].copy_from_slice(&crc.to_le_bytes());
    out.write_all(&packed[..HEADER + len])
        .map_err(io_err(path, "cannot write"))?;
    Ok((HEADER + len) as u64)
}

/// Appends `rows` as one block to the file at `path`, creating it; returns the bytes written.
/// The file is opened per call, so any number of files works within the descriptor limit.
pub fn append_block(path: &Path, rows: &[u8], stride: usize, scratch: &mut Scratch) -> Result<u64> {
    let mut f = OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(io_err(path, "cannot open"))?;
    write_block(&mut f, rows, stride, scratch, path)
}

struct BlockHead {
    /// Bytes of rows.
    raw: usize,
    /// Bytes compressed, after the header.
    len: usize,
    crc: u32,
    head: [u8; HEADER],
}

fn damaged_block(path: &Path, at: u64, what: &str) -> ConvertError {
    ConvertError::input(
        path,
        format!(
            "the block of rows at byte {at} {what}: the work file was damaged or changed since it was written; convert again from the start (or, for a plan, make the plan again)"
        ),
    )
}

/// The header of the block at `at`; `None` at the file's end. Lengths no writer makes are
/// refused before anything is read or allocated for them.
fn read_head(r: &mut impl Read, path: &Path, at: u64) -> Result<Option<BlockHead>> {
    let mut head = [0u8; HEADER];
    // Read in pieces: no byte of a header is the file's clean end, part of one is a cut.
    let mut got = 0;
    while got < HEADER {
        match r.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(ConvertError::io(path, "cannot read", e)),
        }
    }
    if got == 0 {
        return Ok(None);
    }
    if got < HEADER {
        return Err(damaged_block(path, at, "is cut short"));
    }
    let word = |i: usize| u32::from_le_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    let (raw, len, crc) = (word(0) as usize, word(4) as usize, word(8));
    if raw > MAX_BLOCK_BYTES || len > lz4_flex::block::get_maximum_output_size(raw) {
        return Err(damaged_block(path, at, "has lengths no block has"));
    }
    Ok(Some(BlockHead {
        raw,
        len,
        crc,
        head,
    }))
}

/// Rows in the file at `path`, from its blocks' headers alone (no file, no rows): what a
/// chunk's halo will hold, known before it is read.
pub fn count_rows(path: &Path, stride: usize) -> Result<u64> {
    // Unbuffered: a buffer would read the blocks too, which is all a band holds.
    let mut file = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(ConvertError::io(path, "cannot open", e)),
    };
    let (mut rows, mut at) = (0u64, 0u64);
    while let Some(b) = read_head(&mut file, path, at)? {
        rows += (b.raw / stride.max(1)) as u64;
        at += (HEADER + b.len) as u64;
        file.seek(SeekFrom::Start(at))
            .map_err(io_err(path, "cannot read"))?;
    }
    Ok(rows)
}

/// Appends the next block's rows to `rows`; false at the end of the file. `at` is where the
/// block starts in the file, for the message when it is damaged.
fn read_block(
    r: &mut impl Read,
    stride: usize,
    path: &Path,
    at: u64,
    scratch: &mut Scratch,
    rows: &mut Vec<u8>,
) -> Result<bool> {
    let Some(BlockHead {
        raw,
        len,
        crc,
        head,
    }) = read_head(r, path, at)?
    else {
        return Ok(false);
    };
    let damaged = |what: &str| damaged_block(path, at, what);
    // Read as far as the file goes, not sized by the header.
    scratch.packed.clear();
    let got = r
        .by_ref()
        .take(len as u64)
        .read_to_end(&mut scratch.packed)
        .map_err(io_err(path, "cannot read"))?;
    if got != len {
        return Err(damaged("is cut short"));
    }
    if block_checksum(&head[..8], &scratch.packed) != crc {
        return Err(damaged("does not match its checksum"));
    }
    scratch.grouped.resize(raw, 0);
    let got = lz4_flex::block::decompress_into(&scratch.packed, &mut scratch.grouped);
    if got.ok() != Some(raw) || !raw.is_multiple_of(stride.max(1)) {
        return Err(damaged("does not decode to whole rows"));
    }
    unshuffle(&scratch.grouped, stride, rows);
    Ok(true)
}

/// Calls `each` on the rows of every block of the file at `path`; no file, no rows (a chunk
/// part with no rows has no file).
pub fn for_each_block(
    path: &Path,
    stride: usize,
    mut each: impl FnMut(&[u8]) -> Result<()>,
) -> Result<()> {
    let Some(mut r) = open_blocks(path)? else {
        return Ok(());
    };
    let mut scratch = Scratch::default();
    let mut rows = Vec::new();
    let mut at = 0;
    while {
        rows.clear();
        read_block(&mut r, stride, path, at, &mut scratch, &mut rows)?
    } {
        at += (HEADER + scratch.packed.len()) as u64;
        each(&rows)?;
    }
    Ok(())
}

/// Appends every row of the file at `path` to `out`, decoding with `scratch`'s buffers.
pub fn read_rows(
    path: &Path,
    stride: usize,
    out: &mut Vec<u8>,
    scratch: &mut Scratch,
) -> Result<()> {
    if let Some(mut r) = open_blocks(path)? {
        let mut at = 0;
        while read_block(&mut r, stride, path, at, scratch, out)? {
            at += (HEADER + scratch.packed.len()) as u64;
        }
    }
    Ok(())
}

/// The file of blocks at `path`, buffered; `None` where there is none (no rows).
fn open_blocks(path: &Path) -> Result<Option<BufReader<File>>> {
    match File::open(path) {
        Ok(f) => Ok(Some(BufReader::with_capacity(1 << 20, f))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(ConvertError::io(path, "cannot open", e)),
    }
}

/// Writes rows to a new file in blocks of `block_rows(stride)` rows.
pub struct RowWriter {
    path: PathBuf,
    out: BufWriter<File>,
    stride: usize,
    pending: Vec<u8>,
    block: usize,
    scratch: Scratch,
    pub rows: u64,
    /// Where each block starts in the file.
    offsets: Vec<u64>,
    at: u64,
}

impl RowWriter {
    pub fn create(path: &Path, stride: usize) -> Result<Self> {
        Self::with_buffers(path, stride, 4 << 20, block_rows(stride))
    }

    /// A writer that holds at most about 64 KiB of rows and 64 KiB of output at a time, in
    /// shorter blocks (read sequentially only): for many files written at once, such as a
    /// chunk's bands, one for each neighbour.
    pub fn create_small(path: &Path, stride: usize) -> Result<Self> {
        Self::with_buffers(path, stride, 64 << 10, ((64 << 10) / stride.max(1)).max(1))
    }

    fn with_buffers(path: &Path, stride: usize, buffer: usize, rows: usize) -> Result<Self> {
        let file = File::create(path).map_err(io_err(path, "cannot create"))?;
        Ok(RowWriter {
            path: path.to_path_buf(),
            out: BufWriter::with_capacity(buffer, file),
            stride,
            pending: Vec::new(),
            block: rows * stride,
            scratch: Scratch::default(),
            rows: 0,
            offsets: Vec::new(),
            at: 0,
        })
    }

    /// Adds whole rows.
    pub fn write(&mut self, mut rows: &[u8]) -> Result<()> {
        self.rows += (rows.len() / self.stride) as u64;
        while !rows.is_empty() {
            let take = (self.block - self.pending.len()).min(rows.len());
            self.pending.extend_from_slice(&rows[..take]);
            rows = &rows[take..];
            if self.pending.len() == self.block {
                self.flush_block()?;
            }
        }
        Ok(())
    }

    fn flush_block(&mut self) -> Result<()> {
        if !self.pending.is_empty() {
            self.offsets.push(self.at);
            self.at += write_block(
                &mut self.out,
                &self.pending,
                self.stride,
                &mut self.scratch,
                &self.path,
            )?;
            self.pending.clear();
        }
        Ok(())
    }

    /// Writes what is pending and closes the file; returns the rows written.
    pub fn finish(self) -> Result<u64> {
        self.finish_indexed().map(|(rows, _)| rows)
    }

    /// As `finish`, also returning where each block starts, for `for_each_in`.
    pub fn finish_indexed(mut self) -> Result<(u64, Vec<u64>)> {
        self.flush_block()?;
        self.out
            .into_inner()
            .map_err(|e| io_err(&self.path, "cannot write")(e.into_error()))?;
        Ok((self.rows, self.offsets))
    }
}

/// Frees the disk under `len` bytes at `offset` of `file`, which keeps its length (a hole reads
/// as zeros). Best effort: a file system without holes keeps the bytes until the file goes.
fn punch_hole(file: &File, offset: u64, len: u64) {
    use std::os::fd::AsRawFd;
    // SAFETY: fallocate on a descriptor this process owns; it changes no memory of ours.
    unsafe {
        libc::fallocate(
            file.as_raw_fd(),
            libc::FALLOC_FL_PUNCH_HOLE | libc::FALLOC_FL_KEEP_SIZE,
            offset as libc::off_t,
            len as libc::off_t,
        );
    }
}

/// Calls `each(rows, first)` on the rows of `range` of a file `RowWriter` wrote, in blocks,
/// `offsets` where its blocks start. With `release`, frees each block that lies wholly in
/// `range` once `each` has seen it: a staging file read for the last time shrinks as it is
/// read (by several readers of ranges apart, which is why blocks are found by `offsets`, not
/// by the headers of blocks that may already be freed).
pub fn for_each_in(
    path: &Path,
    offsets: &[u64],
    stride: usize,
    range: Range<u64>,
    release: bool,
    mut each: impl FnMut(&[u8], u64) -> Result<()>,
) -> Result<()> {
    if range.is_empty() {
        return Ok(());
    }
    let per = block_rows(stride) as u64;
    // Freeing blocks needs the file open for writing.
    let file = OpenOptions::new()
        .read(true)
        .write(release)
        .open(path)
        .map_err(io_err(path, "cannot open"))?;
    let mut r = BufReader::with_capacity(1 << 20, file);
    let block = range.start / per;
    let Some(&start) = offsets.get(block as usize) else {
        return Err(ConvertError::internal(
            format!("reading {}", path.display()),
            format!("the file ends before row {}", range.start),
        ));
    };
    let mut offset = start;
    r.seek(SeekFrom::Start(start))
        .map_err(io_err(path, "cannot read"))?;
    let mut scratch = Scratch::default();
    let mut rows = Vec::new();
    let mut at = block * per;
    while at < range.end {
        rows.clear();
        if !read_block(&mut r, stride, path, offset, &mut scratch, &mut rows)? {
            return Err(ConvertError::internal(
                format!("reading {}", path.display()),
                format!("the file ends before row {at}"),
            ));
        }
        let n = (rows.len() / stride) as u64;
        let bytes = (HEADER + scratch.packed.len()) as u64;
        let lo = range.start.max(at);
        let hi = range.end.min(at + n);
        if lo < hi {
            let s = ((lo - at) as usize) * stride;
            let e = ((hi - at) as usize) * stride;
            each(&rows[s..e], lo)?;
        }
        if release && lo == at && hi == at + n {
            punch_hole(r.get_ref(), offset, bytes);
        }
        offset += bytes;
        at += n;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_come_back_whole_and_smaller() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rows.bin");
        let stride = 16;
        let rows: Vec<u8> = (0..100_000u32)
            .flat_map(|i| {
                let mut r = [0u8; 16];
                r[..4].copy_from_slice(&(i / 3).to_le_bytes());
                r[4..8].copy_from_slice(&(1000 + i % 77).to_le_bytes());
                r[12] = (i % 5) as u8;
                r
            })
            .collect();
        // A small writer's short blocks read back the same.
        let small = dir.path().join("small.bin");
        let mut w = RowWriter::create_small(&small, stride).expect("create");
        for part in rows.chunks(stride * 999) {
            w.write(part).expect("write");
        }
        let (n, offsets) = w.finish_indexed().expect("finish");
        assert_eq!(
            (n, offsets.len()),
            (100_000, 25),
            "64 KiB blocks of 16-byte rows"
        );
        let mut back = Vec::new();
        read_rows(&small, stride, &mut back, &mut Scratch::default()).expect("read");
        assert!(back == rows);
        let mut w = RowWriter::create(&path, stride).expect("create");
        for part in rows.chunks(stride * 999) {
            w.write(part).expect("write");
        }
        let (n, offsets) = w.finish_indexed().expect("finish");
        assert_eq!(n, 100_000);
        let size = std::fs::metadata(&path).expect("meta").len();
        assert!(size * 3 < rows.len() as u64, "{size} bytes");
        let mut back = Vec::new();
        read_rows(&path, stride, &mut back, &mut Scratch::default()).expect("read");
        assert!(back == rows);
        // Any range, across blocks.
        for range in [0..1, 5..70_000, 65_535..65_537, 99_999..100_000, 7..7] {
            let mut got = Vec::new();
            let mut next = range.start;
            for_each_in(&path, &offsets, stride, range.clone(), false, |r, first| {
                assert_eq!(first, next);
                next += (r.len() / stride) as u64;
                got.extend_from_slice(r);
                Ok(())
            })
            .expect("range");
            let want = &rows[range.start as usize * stride..range.end as usize * stride];
            assert!(got == want, "{range:?}");
        }
    }

    #[test]
    fn a_changed_byte_anywhere_in_a_block_is_refused_naming_the_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("c0.bin");
        let stride = 16;
        // Rows that compress well: lz4 decodes most changes in them into other rows silently.
        let rows: Vec<u8> = (0..5000u32).flat_map(|i| [(i / 7) as u8; 16]).collect();
        let mut w = RowWriter::create(&path, stride).expect("create");
        w.write(&rows).expect("write");
        w.finish().expect("finish");
        let whole = std::fs::read(&path).expect("read");
        for at in [0, 5, 9, HEADER, whole.len() / 2, whole.len() - 1] {
            let mut bytes = whole.clone();
            bytes[at] ^= 0x10;
            std::fs::write(&path, &bytes).expect("write");
            let e = read_rows(&path, stride, &mut Vec::new(), &mut Scratch::default())
                .expect_err("damaged")
                .to_string();
            assert!(e.contains("c0.bin") && e.contains("at byte 0"), "{at}: {e}");
        }
        // Cut inside a later block's header: refused, not read as a shorter file.
        let small = dir.path().join("c1.bin");
        let mut w = RowWriter::create_small(&small, stride).expect("create");
        w.write(&rows).expect("write");
        w.finish().expect("finish");
        let many = std::fs::read(&small).expect("read");
        let second = HEADER + u32::from_le_bytes([many[4], many[5], many[6], many[7]]) as usize;
        assert!(
            second + 5 < many.len(),
            "the small writer makes several blocks"
        );
        std::fs::write(&small, &many[..second + 5]).expect("write");
        let e = read_rows(&small, stride, &mut Vec::new(), &mut Scratch::default())
            .expect_err("cut in a header")
            .to_string();
        assert!(e.contains("c1.bin") && e.contains("cut short"), "{e}");
        // A length no writer makes is refused before it is read.
        let mut bytes = whole.clone();
        bytes[..4].copy_from_slice(&u32::MAX.to_le_bytes());
        std::fs::write(&path, &bytes).expect("write");
        let e = read_rows(&path, stride, &mut Vec::new(), &mut Scratch::default())
            .expect_err("huge length")
            .to_string();
        assert!(e.contains("lengths no block has"), "{e}");
        // Cut short: refused, not read as fewer rows.
        std::fs::write(&path, &whole[..whole.len() - 3]).expect("write");
        let e = read_rows(&path, stride, &mut Vec::new(), &mut Scratch::default())
            .expect_err("cut")
            .to_string();
        assert!(e.contains("cut short"), "{e}");
    }

    #[test]
    fn a_last_reading_frees_the_blocks_it_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rows.bin");
        let stride = 16;
        // Noise, so that blocks stay large enough to free whole pages.
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let rows: Vec<u8> = (0..400_000)
            .flat_map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x.to_le_bytes()
            })
            .collect();
        let mut w = RowWriter::create(&path, stride).expect("create");
        w.write(&rows).expect("write");
        let (_, offsets) = w.finish_indexed().expect("finish");
        let used =
            |p: &Path| std::os::unix::fs::MetadataExt::blocks(&std::fs::metadata(p).expect("meta"));
        let before = used(&path);
        // Read once without releasing: nothing is freed.
        for_each_in(&path, &offsets, stride, 0..200_000, false, |_, _| Ok(())).expect("read");
        assert_eq!(used(&path), before);
        for range in [0..70_000, 70_000..200_000] {
            for_each_in(&path, &offsets, stride, range, true, |_, _| Ok(())).expect("release");
        }
        let after = used(&path);
        assert!(after * 4 < before, "{after} of {before} blocks left");
    }
}
