//! E57 (ASTM E2807) files from terrestrial scanners, read with the `e57` crate: every scan
//! (data3D entry), in world coordinates, with the position its scanner stood at where the file
//! states it (`e57_decode::scanner_positions`). Rows hold `rgb`, `intensity`, returns and
//! `gps_time` when a scan has them (`e57_extras`) and always `scanner`, the global index of
//! the scan's scanner (`NO_SCANNER` where its position is not known).
//! Decoding runs on a thread of its own (`e57_decode`), started by the first `read`.

use super::e57_decode::{self, Batch, Job, Msg, Pose, QUEUED, RowShape};
use super::e57_extras::FileExtras;
use super::e57_header::check_header;
use super::e57_limits::{OwnRanges, own_ranges};
use super::e57_section::check_sections;
use super::las_header::range_lost;
use super::laz_check::guarded;
use super::{NO_SCANNER, PointSource, Precision, SourceInfo};
use crate::crs_identity::looks_like_wkt;
use crate::error::{ConvertError, Result};
use crate::quantize::float_scale;
use e57::{E57Reader, PointCloud, RecordDataType, RecordName};
use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;
use std::sync::mpsc::{Receiver, sync_channel};
use strata_format::Crs;

pub struct E57Source {
    info: SourceInfo,
    /// The opened file, until the first `read` hands it to the decoding thread.
    job: Option<Job>,
    feed: Option<Receiver<Msg>>,
    batch: Batch,
    /// Points of `batch` already read.
    at: usize,
    row_len: usize,
    finished: bool,
}

/// The fields of a scan's records that Strata reads.
const READ: [RecordName; 10] = [
    RecordName::CartesianX,
    RecordName::CartesianY,
    RecordName::CartesianZ,
    RecordName::SphericalRange,
    RecordName::SphericalAzimuth,
    RecordName::SphericalElevation,
    RecordName::ColorRed,
    RecordName::ColorGreen,
    RecordName::ColorBlue,
    RecordName::Intensity,
];

impl E57Source {
    pub fn open(path: &Path) -> Result<E57Source> {
        let mut file =
            File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let bad = |what: String| ConvertError::input(path, what);
        let len = file
            .metadata()
            .map_err(|e| ConvertError::io(path, "cannot read file size", e))?
            .len();
        check_header(&mut file, len).map_err(bad)?;
        file.seek(SeekFrom::Start(0))
            .map_err(|e| ConvertError::io(path, "cannot read", e))?;
        // The page checksums of the XML section and the XML itself are checked here.
        let reader = guarded("the E57 header or XML section", || {
            E57Reader::new(BufReader::with_capacity(1 << 20, file))
                .map_err(|e| format!("not a readable E57 file ({})", e57_decode::plain(&e)))
        })
        .map_err(bad)?;
        let clouds = reader.pointclouds();
        let n = clouds.len();
        if n == 0 {
            return Err(bad(
                "the E57 file holds no point cloud (its data3D list is empty)".into(),
            ));
        }
        if n > NO_SCANNER as usize {
            return Err(bad(format!(
                "the E57 file holds {n} scans, more than the {NO_SCANNER} a dataset can number"
            )));
        }
        // A record takes at least a bit of the file (a scan whose fields never vary is no
        // scan): a count beyond that is a damaged header, refused here, naming it, rather
        // than by the disk check asking for terabytes.
        if let Some((i, c)) = clouds
            .iter()
            .enumerate()
            .find(|(_, c)| c.records > len.saturating_mul(8))
        {
            return Err(bad(format!(
                "scan {i} of {n} says it holds {} points, more than a file of {len} bytes can",
                c.records
            )));
        }
        let points = clouds
            .iter()
            .try_fold(0u64, |sum, c| sum.checked_add(c.records))
            .ok_or_else(|| bad("the scans' point counts add up to more than 2^64".into()))?;
        if points == 0 {
            return Err(bad(format!(
                "the E57 file's {} no points",
                if n == 1 {
                    "only scan holds".to_string()
                } else {
                    format!("{n} scans hold")
                }
            )));
        }
        // Packet headers a few bytes each, one seek apart: a small buffer, refilled each seek.
        let mut sections = BufReader::with_capacity(
            1 << 12,
            File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?,
        );
        check_sections(&mut sections, len, &clouds).map_err(bad)?;
        let mut poses = Vec::with_capacity(n);
        for (i, pc) in clouds.iter().enumerate() {
            if !pc.has_cartesian() && !pc.has_spherical() {
                return Err(bad(format!(
                    "scan {i} of {n} has neither Cartesian nor spherical coordinates"
                )));
            }
            poses.push(Pose::of(pc).map_err(|w| bad(format!("scan {i} of {n}: {w}")))?);
            // A scale of zero stores every value of a field that varies as its offset: all
            // points in one place. Only the fields read here count.
            if let Some(r) = pc.prototype.iter().find(|r| {
                READ.contains(&r.name)
                    && matches!(r.data_type, RecordDataType::ScaledInteger { scale, min, max, .. }
                        if min != max && !scale.is_normal())
            }) {
                return Err(bad(format!(
                    "scan {i} of {n}: its {:?} field is a scaled integer with a scale of zero, \
                     infinite or not a number, which cannot store values",
                    r.name
                )));
            }
            // Beside an offset that large the field's whole range is lost (a double holds about
            // 16 digits): every point would get the same coordinate.
            for r in pc.prototype.iter().filter(|r| READ.contains(&r.name)) {
                if let RecordDataType::ScaledInteger {
                    scale,
                    offset,
                    min,
                    max,
                } = r.data_type
                    && range_lost(offset, scale, min as f64, max as f64)
                {
                    return Err(bad(format!(
                        "scan {i} of {n}: its {:?} field is a scaled integer with an offset of \
                         {offset:e}, so large that the steps of its scale {scale:e} are lost in \
                         it: every point would get the same value",
                        r.name
                    )));
                }
            }
            // Beside a translation that large the scan's own extent is lost: every point
            // would get the same coordinate on that axis.
            if let Some(m) = scan_extent(pc) {
                let t = poses[i].translation;
                if let Some(a) = (0..3).find(|&a| range_lost(t[a], 1.0, -m, m)) {
                    return Err(bad(format!(
                        "scan {i} of {n}: its pose's translation {} = {:e} is so large that the \
                         scan's own extent of {m:e} about its origin is lost in it: every point \
                         would get the same {} coordinate",
                        ["x", "y", "z"][a],
                        t[a],
                        ["x", "y", "z"][a]
                    )));
                }
            }
        }
        let rgb = clouds.iter().any(PointCloud::has_color);
        let intensity = clouds.iter().any(PointCloud::has_intensity);
        let extras = FileExtras::of(&clouds);
        let (shape, attributes) = RowShape::new(rgb, intensity, extras);
        let ranges = own_ranges(reader.xml(), &clouds);
        let mut warnings = unstated_ranges(path, &clouds, &ranges);
        warnings.extend(FileExtras::warnings(path, &clouds));
        // The file's coordinateMetadata (ASTM E2807: the CRS of its world frame), as WKT.
        let stated = reader
            .coordinate_metadata()
            .map(str::trim)
            .filter(|t| !t.is_empty());
        let crs = stated.filter(|t| looks_like_wkt(t)).map(|wkt| Crs {
            wkt: Some(wkt.to_string()),
            geotiff: None,
        });
        if let (Some(text), None) = (stated, &crs) {
            warnings.push(format!(
                "{}: its coordinateMetadata ({:?}...) is no WKT: it states no coordinate \
                 reference system",
                path.display(),
                text.chars().take(24).collect::<String>()
            ));
        }
        let stood = e57_decode::scanner_positions(&clouds, &poses);
        let slots = e57_decode::scanner_slots(&stood);
        let info = SourceInfo {
            path: path.to_path_buf(),
            points,
            attributes,
            precision: precision(&clouds),
            warnings,
            scanners: stood.iter().flatten().copied().collect(),
            crs,
            time_from_unknown_start: extras.time == Some(None),
        };
        Ok(E57Source {
            info,
            job: Some(Job {
                reader,
                clouds,
                poses,
                ranges,
                shape,
                path: path.to_path_buf(),
                first: 0,
                slots,
            }),
            feed: None,
            batch: Batch::default(),
            at: 0,
            row_len: shape.len,
            finished: false,
        })
    }

    /// The next batch from the decoding thread (started on the first call); `None` at the end.
    fn next_batch(&mut self) -> Result<Option<Batch>> {
        if let Some(job) = self.job.take() {
            let (tx, rx) = sync_channel(QUEUED);
            std::thread::Builder::new()
                .name("e57-decode".into())
                .spawn(move || e57_decode::run(job, &tx))
                .map_err(|e| {
                    ConvertError::io(&self.info.path, "cannot start a reader thread", e)
                })?;
            self.feed = Some(rx);
        }
        let Some(feed) = &self.feed else {
            return Ok(None);
        };
        let path = &self.info.path;
        match feed.recv() {
            Ok(Msg::Batch(b)) => Ok(Some(b)),
            Ok(Msg::Failed(what)) => Err(ConvertError::input(path, what)),
            Ok(Msg::Done { valid: 0 }) => Err(ConvertError::input(
                path,
                format!(
                    "none of the E57 file's {} points has a valid position",
                    self.info.points
                ),
            )),
            Ok(Msg::Done { .. }) => {
                self.feed = None;
                Ok(None)
            }
            // Every fault of the thread, a panic among them, is sent as `Failed`.
            Err(_) => Err(ConvertError::internal(
                format!("reading {}", path.display()),
                "the E57 reader thread stopped without a word",
            )),
        }
    }
}

impl PointSource for E57Source {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read(&mut self, max: usize, xyz: &mut Vec<[f64; 3]>, rows: &mut Vec<u8>) -> Result<usize> {
        let mut got = 0;
        while got < max {
            if self.at == self.batch.xyz.len() {
                if self.finished {
                    break;
                }
                match self.next_batch()? {
                    Some(b) => {
                        self.batch = b;
                        self.at = 0;
                    }
                    None => {
                        self.finished = true;
                        break;
                    }
                }
            }
            let take = (max - got).min(self.batch.xyz.len() - self.at);
            let (from, to) = (self.at, self.at + take);
            xyz.extend_from_slice(&self.batch.xyz[from..to]);
            rows.extend_from_slice(&self.batch.rows[from * self.row_len..to * self.row_len]);
            self.at = to;
            got += take;
        }
        Ok(got)
    }

    fn set_scanner_base(&mut self, first: u16) {
        if let Some(job) = &mut self.job {
            job.first = first;
        }
    }
}

/// A warning for each scan whose colour or intensity has no range stated (a float field
/// without limits, limits of zero width), so that its values are scaled by their own.
fn unstated_ranges(path: &Path, clouds: &[PointCloud], ranges: &[OwnRanges]) -> Vec<String> {
    let n = clouds.len();
    let mut warnings = Vec::new();
    for (i, (pc, r)) in clouds.iter().zip(ranges).enumerate() {
        for (field, unstated) in [
            ("colour", pc.has_color() && r.rgb.is_none()),
            ("intensity", pc.has_intensity() && r.intensity.is_none()),
        ] {
            if unstated {
                warnings.push(format!(
                    "{}: scan {i} of {n} states no range for its {field} (a float field \
                     without limits, or limits of zero width): its values are scaled by their \
                     own, those within 0..1, 0..255 or 0..65535 on that scale",
                    path.display()
                ));
            }
        }
    }
    warnings
}

/// How finely the file stores positions: any scan in doubles makes it `Float64`, else the
/// finest step of its scaled (or plain) integers and its singles. Spherical scans count by
/// their range. After the pose these are real coordinates on no grid.
///
/// Singles are precise to their own magnitude in the scan's frame, not to the world's: a
/// scan of ±10 m in singles placed 5e6 m away by its (double) pose is good to a micrometre,
/// though a single of 5e6 is good only to half a metre. Where the scan states its local
/// extent (the field's limits, its Cartesian bounds, its largest range), that gives the step;
/// where it does not and its pose moves it, the pose makes its coordinates doubles.
fn precision(clouds: &[PointCloud]) -> Precision {
    let mut step = f64::INFINITY;
    let mut single = false;
    for pc in clouds {
        let moved = pc.transform.as_ref().is_some_and(|t| {
            t.translation.x != 0.0 || t.translation.y != 0.0 || t.translation.z != 0.0
        });
        for r in position_fields(pc) {
            match r.data_type {
                RecordDataType::Double { .. } => return Precision::Float64,
                RecordDataType::Single { min, max } => match local_extent(pc, min, max) {
                    Some(m) => step = step.min(float_scale(m, 23)),
                    None if moved => return Precision::Float64,
                    None => single = true,
                },
                RecordDataType::ScaledInteger { scale, .. } => step = step.min(scale.abs()),
                RecordDataType::Integer { .. } => step = step.min(1.0),
            }
        }
    }
    if single && step.is_finite() {
        // Unmoved singles (world magnitude theirs) beside scans with a finer step of their
        // own: no one variant says both, and doubles are never coarser than either.
        Precision::Float64
    } else if single {
        // Unmoved singles: their world magnitude is their own.
        Precision::Float32
    } else if step.is_normal() {
        Precision::Resolution([step; 3])
    } else {
        // A scale of zero or not a number: the coordinates say what they are worth.
        Precision::Float64
    }
}

/// The fields that place a scan's points: its Cartesian coordinates, else its spherical range
/// (the angles say nothing of the extent or of the step).
fn position_fields(pc: &PointCloud) -> impl Iterator<Item = &e57::Record> {
    let names: &[RecordName] = if pc.has_cartesian() {
        &[
            RecordName::CartesianX,
            RecordName::CartesianY,
            RecordName::CartesianZ,
        ]
    } else {
        &[RecordName::SphericalRange]
    };
    pc.prototype.iter().filter(move |r| names.contains(&r.name))
}

/// The largest magnitude a scan's positions reach in its own frame (before its pose), as its
/// coordinate fields' types or its bounds state it; `None` where the file does not say.
fn scan_extent(pc: &PointCloud) -> Option<f64> {
    let mut extent: Option<f64> = None;
    for r in position_fields(pc) {
        let field = match r.data_type {
            RecordDataType::Single { min, max } => local_extent(pc, min, max),
            RecordDataType::Double { .. } => local_extent(pc, None, None),
            RecordDataType::ScaledInteger {
                scale,
                offset,
                min,
                max,
            } => Some(
                (min as f64 * scale + offset)
                    .abs()
                    .max((max as f64 * scale + offset).abs()),
            ),
            RecordDataType::Integer { min, max } => {
                Some((min as f64).abs().max((max as f64).abs()))
            }
        };
        extent = match (extent, field) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
    }
    extent.filter(|m| m.is_finite() && *m > 0.0)
}

/// The largest magnitude a scan's single-precision coordinate field holds in its own frame,
/// where the file says: the field's limits, else the scan's Cartesian bounds (or its largest
/// range, for a spherical scan).
///
/// libE57Format writes ±FLT_MAX as the limits of every float field: values that large say
/// nothing, and where both the limits and the bounds say something the smaller is taken.
fn local_extent(pc: &PointCloud, min: Option<f32>, max: Option<f32>) -> Option<f64> {
    // No scanner measures 1e20 units from itself.
    let told = |v: f64| (v.is_finite() && v.abs() < 1e20).then_some(v.abs());
    let limits = match (min, max) {
        (Some(lo), Some(hi)) => told(f64::from(lo))
            .zip(told(f64::from(hi)))
            .map(|(a, b)| a.max(b)),
        _ => None,
    };
    let bounds = if pc.has_cartesian() {
        pc.cartesian_bounds.as_ref().and_then(|b| {
            [b.x_min, b.x_max, b.y_min, b.y_max, b.z_min, b.z_max]
                .into_iter()
                .try_fold(0.0f64, |m, v| Some(m.max(told(v?)?)))
        })
    } else {
        pc.spherical_bounds
            .as_ref()
            .and_then(|b| told(b.range_max?))
    };
    match (limits, bounds) {
        (Some(l), Some(b)) => Some(l.min(b)),
        (l, b) => l.or(b),
    }
}
