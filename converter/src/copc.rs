//! `strata export DATASET -o OUT.copc.laz`: the dataset as a COPC 1.0 file (Cloud Optimized
//! Point Cloud: LAS 1.4, point format 6, 7 or 8, one LAZ chunk per octree node, the EPT-style
//! hierarchy in an EVLR). Strata's octree is COPC's, node for node (the same cube halved per
//! level, the same keys), so the export re-encodes each node's points as one chunk, a node at a
//! time in bounded memory, and writes the hierarchy after them.

use crate::copc_nodes::{Grid, plan};
use crate::error::{ConvertError, Result};
use crate::export::{Target, widened};
use crate::las_records::LasRecords;
use crate::part_file::create_part;
use laz::{LasZipCompressor, LazVlrBuilder};
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;
use strata_format::{DatasetFile, LocalDataset, RowLayout};

/// The LAS 1.4 header's size.
const HEADER_SIZE: u64 = 375;
/// A VLR's header, and an EVLR's.
const VLR_HEADER: u64 = 54;
const EVLR_HEADER: u64 = 60;
/// The COPC info VLR's payload.
pub(crate) const INFO_SIZE: u64 = 160;
/// One hierarchy entry: key (4 x i32), offset (u64), byte size (i32), point count (i32).
pub(crate) const ENTRY_SIZE: usize = 32;

/// A (E)VLR: user, record id, description, payload.
type Vlr<'a> = (&'a str, u16, &'a str, Vec<u8>);

/// One node's chunk, as the hierarchy lists it.
struct Entry {
    key: [i32; 4],
    offset: u64,
    size: u64,
    points: u64,
}

/// What the header sums up, gathered while the points are written.
#[derive(Default)]
struct Totals {
    points: u64,
    by_return: [u64; 15],
    min: [i32; 3],
    max: [i32; 3],
    gps: Option<(f64, f64)>,
}

/// The LAS point format COPC allows that holds the layout's attributes: 6, 7 with colour, 8
/// with colour and near infrared.
fn copc_format(layout: &RowLayout) -> u8 {
    let rgb = layout
        .index_of("rgb")
        .is_some_and(|i| layout.attributes[i].count == 3 && layout.attributes[i].ty.size() <= 2);
    match (rgb, layout.index_of("nir").is_some()) {
        (_, true) => 8,
        (true, false) => 7,
        (false, false) => 6,
    }
}

/// Writes `dataset` to `output` as COPC; returns the number of points written.
pub fn export_copc(dataset: &Path, output: &Path, overwrite: bool) -> Result<u64> {
    crate::writers::check_file_output(output, overwrite)?;
    let ds = LocalDataset::open(dataset)?;
    let meta = ds.metadata().clone();
    let layout = ds.layout().clone();
    let wide = widened(&layout, Target::Las);
    let format = copc_format(&wide.layout);
    let records = LasRecords::new(output, &wide.layout, format)?.single_returns_where_missing();
    let fail = |what: String| ConvertError::output(output, what);
    let laz_vlr = LazVlrBuilder::default()
        .with_point_format(format, records.extra_bytes() as u16)
        .map_err(|e| fail(format!("cannot compress point format {format} ({e})")))?
        .with_variable_chunk_size()
        .build();
    let mut laz_payload = Vec::new();
    laz_vlr
        .write_to(&mut laz_payload)
        .map_err(|e| fail(format!("cannot encode the laszip VLR ({e})")))?;
    let extra_payload = records.extra_bytes_vlr();
    if let Some(d) = extra_payload
        .as_ref()
        .filter(|d| d.len() > u16::MAX as usize)
    {
        return Err(fail(format!(
            "{} extra attributes take an Extra Bytes VLR of {} bytes, more than a VLR holds",
            d.len() / 192,
            d.len()
        )));
    }
    // A WKT longer than a VLR holds (64 KiB) goes into an EVLR after the hierarchy's, as LAS
    // 1.4 allows, rather than nowhere.
    let (crs, long_wkt): (Vec<_>, Vec<_>) = meta
        .crs
        .as_ref()
        .and_then(crate::las_crs::wkt_record)
        .into_iter()
        .partition(|r| r.3.len() <= u16::MAX as usize);
    let crs = crs.into_iter().map(Some);
    let vlrs: Vec<Vlr> = [
        Some(("copc", 1, "COPC info", vec![0u8; INFO_SIZE as usize])),
        Some(("laszip encoded", 22204, "laz variable chunks", laz_payload)),
        extra_payload.map(|d| ("LASF_Spec", 4, "Extra Bytes Record", d)),
    ]
    .into_iter()
    .chain(crs)
    .flatten()
    .collect();
    let point_data = HEADER_SIZE
        + vlrs
            .iter()
            .map(|v| VLR_HEADER + v.3.len() as u64)
            .sum::<u64>();

    // Read too: the chunk table's offset is read back at the end. Removed below on a failure
    // only once it is this run's: a part another run holds is not.
    let (part, file) = create_part(output)?;
    let written = write_points(
        &ds,
        output,
        (file, &part),
        &wide,
        &records,
        laz_vlr,
        point_data,
        &vlrs,
    );
    // Every point goes to exactly one COPC node, its cell at its level: a dataset whose nodes
    // hold points outside their cubes, or other than the count it states, loses or repeats
    // some, and is refused as the other exports refuse it.
    let written = written.and_then(|w| {
        if w.2.points == meta.points {
            Ok(w)
        } else {
            Err(ConvertError::input(
                dataset.join(DatasetFile::Metadata.name()),
                format!(
                    "says the dataset holds {} points, but its nodes hold {} (counting the points \
                     inside their nodes' cubes)",
                    meta.points, w.2.points
                ),
            ))
        }
    });
    let (file, entries, totals) = match written {
        Ok(w) => w,
        Err(e) => {
            let _ = std::fs::remove_file(&part);
            return Err(e);
        }
    };
    let finished = finish(
        file,
        &part,
        &meta,
        format,
        &records,
        (point_data, &vlrs, long_wkt.first()),
        &entries,
        &totals,
    );
    if let Err(e) = finished.and_then(|_| {
        std::fs::rename(&part, output)
            .map_err(|e| ConvertError::io(output, "cannot move into place", e))
    }) {
        let _ = std::fs::remove_file(&part);
        return Err(e);
    }
    Ok(totals.points)
}

/// Writes the header space, the VLRs and every node's chunk; returns the file, the chunks and
/// the totals.
#[allow(clippy::too_many_arguments)]
fn write_points(
    ds: &LocalDataset,
    output: &Path,
    (file, part): (File, &Path),
    wide: &crate::export::Widened,
    records: &LasRecords,
    laz_vlr: laz::LazVlr,
    point_data: u64,
    vlrs: &[Vlr],
) -> Result<(File, Vec<Entry>, Totals)> {
    let io = |e: std::io::Error| ConvertError::io(part, "cannot write", e);
    let mut out = BufWriter::with_capacity(1 << 20, file);
    out.write_all(&[0u8; HEADER_SIZE as usize]).map_err(io)?;
    for (user, id, description, data) in vlrs {
        out.write_all(&vlr_header(
            user,
            *id,
            description,
            data.len() as u64,
            false,
        ))
        .map_err(io)?;
        out.write_all(data).map_err(io)?;
    }
    let mut compressor = LasZipCompressor::new(out, laz_vlr)
        .map_err(|e| ConvertError::output(part, format!("cannot start compressing ({e})")))?;
    compressor.reserve_offset_to_chunk_table().map_err(io)?;
    let layout = ds.layout();
    let mut entries: Vec<Entry> = Vec::new();
    let mut totals = Totals {
        min: [i32::MAX; 3],
        max: [i32::MIN; 3],
        ..Totals::default()
    };
    let (mut rows_wide, mut recs, mut kept) = (Vec::new(), Vec::new(), Vec::new());
    let with_points = ds
        .all_nodes()?
        .into_iter()
        .filter(|n| n.point_count > 0)
        .collect();
    let meta = ds.metadata();
    let grid = Grid::of(meta);
    let too_big = |what: &str, n: u64| {
        ConvertError::output(
            part,
            format!("a COPC node's {what} ({n}) is more than its hierarchy entry can hold"),
        )
    };
    for node in plan(meta, with_points) {
        let level = node.key[0] as u8;
        let mut started = false;
        let mut count = 0u64;
        // A source at a time, each appended to the node's open chunk: memory stays that of
        // one Strata node, however many meet a COPC node.
        for source in &node.sources {
            let cols = ds.read_node(source)?;
            let mut rows = cols.to_rows(layout);
            crate::export::check_finite(ds.dir(), meta, &source.key, &rows, layout.stride)?;
            // The source node's points this node keeps, by index, to say where a value the
            // output cannot hold is.
            kept.clear();
            for i in 0..cols.count {
                if grid.key_of(level, cols.position(i)) == node.key {
                    rows.copy_within(
                        i * layout.stride..(i + 1) * layout.stride,
                        kept.len() * layout.stride,
                    );
                    kept.push(i);
                }
            }
            rows.truncate(kept.len() * layout.stride);
            if kept.is_empty() {
                continue;
            }
            let placed = |e: ConvertError| {
                e.placed(ds.dir(), &source.key, |r| kept.get(r).copied().unwrap_or(r))
            };
            let rows = if wide.is_identity() {
                &rows
            } else {
                wide.convert(&rows, &mut rows_wide, output)
                    .map_err(placed)?;
                &rows_wide
            };
            records.check_fits(output, rows).map_err(placed)?;
            records.fill(rows, &mut recs);
            for rec in recs.chunks_exact(records.record_len) {
                totals.add(rec);
            }
            if !started {
                started = true;
                // The chunk before is closed here, the last by `done` (closing each one after
                // it was written would leave an empty chunk at the end).
                if entries.iter().any(|e: &Entry| e.points > 0) {
                    compressor.finish_current_chunk().map_err(io)?;
                }
                let start = compressor.get_mut().stream_position().map_err(io)?;
                if let Some(e) = entries.iter_mut().rev().find(|e| e.points > 0) {
                    e.size = start - e.offset;
                }
                entries.push(Entry {
                    key: node.key,
                    offset: start,
                    size: 0,
                    points: 0,
                });
            }
            compressor.compress_many(&recs).map_err(io)?;
            count += kept.len() as u64;
        }
        match entries.last_mut() {
            Some(e) if started => e.points = count,
            // Above others, without points of its own: listed empty.
            _ => entries.push(Entry {
                key: node.key,
                offset: 0,
                size: 0,
                points: 0,
            }),
        }
        if count > i32::MAX as u64 {
            return Err(too_big("point count", count));
        }
    }
    let chunks_start = point_data + 8;
    compressor.done().map_err(io)?;
    let out = compressor.into_inner();
    let mut file = out
        .into_inner()
        .map_err(|e| ConvertError::io(part, "cannot write", e.into_error()))?;
    // The last chunk ends where the chunk table begins, whose offset LAZ keeps in front of the
    // points.
    file.seek(SeekFrom::Start(point_data)).map_err(io)?;
    let mut at = [0u8; 8];
    file.read_exact(&mut at).map_err(io)?;
    let table = i64::from_le_bytes(at) as u64;
    if let Some(last) = entries.iter_mut().rev().find(|e| e.points > 0) {
        last.size = table.saturating_sub(last.offset);
    }
    if let Some(e) = entries.iter().find(|e| e.size > i32::MAX as u64) {
        return Err(too_big("compressed size", e.size));
    }
    debug_assert!(
        entries
            .iter()
            .find(|e| e.points > 0)
            .is_none_or(|e| e.offset == chunks_start)
    );
    Ok((file, entries, totals))
}

impl Totals {
    /// Takes in one point format 6+ record.
    fn add(&mut self, rec: &[u8]) {
        self.points += 1;
        for k in 0..3 {
            let v =
                i32::from_le_bytes([rec[4 * k], rec[4 * k + 1], rec[4 * k + 2], rec[4 * k + 3]]);
            self.min[k] = self.min[k].min(v);
            self.max[k] = self.max[k].max(v);
        }
        let ret = (rec[14] & 0x0f) as usize;
        if (1..=15).contains(&ret) {
            self.by_return[ret - 1] += 1;
        }
        let mut t = [0u8; 8];
        t.copy_from_slice(&rec[22..30]);
        let t = f64::from_le_bytes(t);
        if t.is_finite() {
            self.gps = Some(self.gps.map_or((t, t), |(lo, hi)| (lo.min(t), hi.max(t))));
        }
    }
}

/// A VLR's (or, `extended`, an EVLR's) header.
fn vlr_header(user: &str, id: u16, description: &str, len: u64, extended: bool) -> Vec<u8> {
    let mut h = Vec::with_capacity(EVLR_HEADER as usize);
    h.extend_from_slice(&0u16.to_le_bytes());
    let mut name = [0u8; 16];
    name[..user.len().min(16)].copy_from_slice(&user.as_bytes()[..user.len().min(16)]);
    h.extend_from_slice(&name);
    h.extend_from_slice(&id.to_le_bytes());
    if extended {
        h.extend_from_slice(&len.to_le_bytes());
    } else {
        h.extend_from_slice(&(len as u16).to_le_bytes());
    }
    let mut desc = [0u8; 32];
    desc[..description.len().min(32)]
        .copy_from_slice(&description.as_bytes()[..description.len().min(32)]);
    h.extend_from_slice(&desc);
    h
}

/// Appends the hierarchy EVLR, then writes the header and the COPC info in place.
#[allow(clippy::too_many_arguments)]
fn finish(
    mut file: File,
    part: &Path,
    meta: &strata_format::Metadata,
    format: u8,
    records: &LasRecords,
    (point_data, vlrs, long_wkt): (u64, &[Vlr], Option<&Vlr>),
    entries: &[Entry],
    totals: &Totals,
) -> Result<()> {
    let io = |e: std::io::Error| ConvertError::io(part, "cannot write", e);
    let evlr_at = file.seek(SeekFrom::End(0)).map_err(io)?;
    let mut page = Vec::with_capacity(entries.len() * ENTRY_SIZE);
    for e in entries {
        for k in e.key {
            page.extend_from_slice(&k.to_le_bytes());
        }
        page.extend_from_slice(&e.offset.to_le_bytes());
        page.extend_from_slice(&(e.size as i32).to_le_bytes());
        page.extend_from_slice(&(e.points as i32).to_le_bytes());
    }
    file.write_all(&vlr_header(
        "copc",
        1000,
        "EPT hierarchy",
        page.len() as u64,
        true,
    ))
    .map_err(io)?;
    file.write_all(&page).map_err(io)?;
    if let Some((user, id, description, payload)) = long_wkt {
        let len = payload.len() as u64;
        file.write_all(&vlr_header(user, *id, description, len, true))
            .map_err(io)?;
        file.write_all(payload).map_err(io)?;
    }

    // The octree's cube in real coordinates, and the points' bounds.
    let s = meta.scale;
    let grid = Grid::of(meta);
    let real = |k: usize, v: i32| meta.offset[k] + s[k] * v as f64;
    let (min, max) = if totals.points > 0 {
        (
            std::array::from_fn::<f64, 3, _>(|k| real(k, totals.min[k])),
            std::array::from_fn::<f64, 3, _>(|k| real(k, totals.max[k])),
        )
    } else {
        ([0.0; 3], [0.0; 3])
    };
    let mut info = Vec::with_capacity(INFO_SIZE as usize);
    let c = grid.centre;
    for v in [c[0], c[1], c[2], grid.half, grid.spacing()] {
        info.extend_from_slice(&v.to_le_bytes());
    }
    info.extend_from_slice(&(evlr_at + EVLR_HEADER).to_le_bytes());
    info.extend_from_slice(&(page.len() as u64).to_le_bytes());
    let (gps_lo, gps_hi) = totals.gps.unwrap_or((0.0, 0.0));
    info.extend_from_slice(&gps_lo.to_le_bytes());
    info.extend_from_slice(&gps_hi.to_le_bytes());
    info.resize(INFO_SIZE as usize, 0);

    let mut h = Vec::with_capacity(HEADER_SIZE as usize);
    h.extend_from_slice(b"LASF");
    h.extend_from_slice(&0u16.to_le_bytes()); // file source id
    // Global encoding: WKT, as formats 6+ require; bit 0 where the GPS times are adjusted
    // standard time.
    let adjusted = crate::writers::gps_time_adjusted(&meta.attributes);
    h.extend_from_slice(&(16u16 | u16::from(adjusted)).to_le_bytes());
    h.extend_from_slice(&[0u8; 16]); // project id
    h.extend_from_slice(&[1, 4]);
    let text = |t: &str| {
        let mut f = [0u8; 32];
        f[..t.len().min(32)].copy_from_slice(&t.as_bytes()[..t.len().min(32)]);
        f
    };
    h.extend_from_slice(&text("strata"));
    h.extend_from_slice(&text(&format!("strata {}", env!("CARGO_PKG_VERSION"))));
    let (day, year) = crate::creation_date::today();
    h.extend_from_slice(&day.to_le_bytes());
    h.extend_from_slice(&year.to_le_bytes());
    h.extend_from_slice(&(HEADER_SIZE as u16).to_le_bytes());
    h.extend_from_slice(&(point_data as u32).to_le_bytes());
    h.extend_from_slice(&(vlrs.len() as u32).to_le_bytes());
    // Bit 7 marks the points compressed, as LASzip writes it (readers take bit 6 as well for
    // something else).
    h.push(format | 0x80);
    h.extend_from_slice(&(records.record_len as u16).to_le_bytes());
    h.extend_from_slice(&[0u8; 4 + 20]); // legacy counts: 0 for formats 6+
    for v in s.iter().chain(&meta.offset) {
        h.extend_from_slice(&v.to_le_bytes());
    }
    for k in 0..3 {
        h.extend_from_slice(&max[k].to_le_bytes());
        h.extend_from_slice(&min[k].to_le_bytes());
    }
    h.extend_from_slice(&0u64.to_le_bytes()); // waveform data
    h.extend_from_slice(&evlr_at.to_le_bytes());
    h.extend_from_slice(&(1 + u32::from(long_wkt.is_some())).to_le_bytes());
    h.extend_from_slice(&totals.points.to_le_bytes());
    for n in totals.by_return {
        h.extend_from_slice(&n.to_le_bytes());
    }
    debug_assert_eq!(h.len() as u64, HEADER_SIZE);
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    file.write_all(&h).map_err(io)?;
    file.seek(SeekFrom::Start(HEADER_SIZE + VLR_HEADER))
        .map_err(io)?;
    file.write_all(&info).map_err(io)?;
    file.sync_all().map_err(io)
}
