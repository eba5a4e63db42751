//! The decoding side of an E57 source: every scan's points through the `e57` crate's simple
//! reader (spherical coordinates converted to Cartesian, colour and intensity normalised by the
//! scan's limits), the scan's pose applied, points without a valid position dropped, and the
//! rest handed on in batches of positions and attribute rows. It runs on a thread of its own
//! because the crate's point reader borrows the file reader: one owner for both, and bounded
//! batches over a channel, keep memory flat whatever the file's size.

use super::e57_extras::{FileExtras, ScanExtras};
use super::e57_limits::{OwnRanges, from_values, normalised};
use super::laz_check::guarded;
use e57::{CartesianCoordinate, E57Reader, PointCloud};
use std::fs::File;
use std::io::BufReader;
use std::sync::mpsc::SyncSender;
use strata_format::number;
use strata_format::{AttrType, Attribute};

/// Points per batch handed to the reading side.
pub const BATCH_POINTS: usize = 1 << 16;

/// Batches waiting to be read, at most: with the one being filled and the one being read, an
/// E57 source holds four batches (a few megabytes) whatever the size of the file.
pub const QUEUED: usize = 2;

/// Where each attribute lies in a row; every scan of a file gets the same row.
#[derive(Debug, Clone, Copy)]
pub struct RowShape {
    /// `rgb`, 3 x u16, 0..65535 from the scan's colour limits.
    pub rgb: Option<usize>,
    /// `intensity`, u16, 0..65535 from the scan's intensity limits.
    pub intensity: Option<usize>,
    /// `return_number` and `number_of_returns`, u8 each, one after the other.
    pub returns: Option<usize>,
    /// `gps_time`, f64.
    pub time: Option<usize>,
    /// The stamps become GPS time from each scan's start (`FileExtras::absolute_time`).
    pub absolute_time: bool,
    /// `scanner`, u16: the global index of the scan's scanner, where its position is known.
    pub scanner: usize,
    pub len: usize,
}

impl RowShape {
    /// The row for a file whose scans have colour, intensity and the extra fields as given
    /// (if any scan has one, every row has it; points without it get zero, or a single
    /// return), and its attributes in order.
    pub fn new(rgb: bool, intensity: bool, extras: FileExtras) -> (RowShape, Vec<Attribute>) {
        let mut attributes = Vec::new();
        let mut len = 0;
        let mut add = |a: Attribute| {
            let at = len;
            len += a.size();
            attributes.push(a);
            at
        };
        let rgb = rgb.then(|| add(Attribute::new("rgb", AttrType::U16, 3)));
        let intensity = intensity.then(|| add(Attribute::new("intensity", AttrType::U16, 1)));
        let returns = extras.returns.then(|| {
            let at = add(Attribute::new("return_number", AttrType::U8, 1));
            add(Attribute::new("number_of_returns", AttrType::U8, 1));
            at
        });
        let time = extras.time.map(|base| {
            let mut a = Attribute::new("gps_time", AttrType::F64, 1);
            a.time_base = base;
            add(a)
        });
        let scanner = add(Attribute::new(super::SCANNER, AttrType::U16, 1));
        let shape = RowShape {
            rgb,
            intensity,
            returns,
            time,
            absolute_time: extras.absolute_time(),
            scanner,
            len,
        };
        (shape, attributes)
    }
}

/// Positions and their rows, in the source's row shape.
#[derive(Debug, Default)]
pub struct Batch {
    pub xyz: Vec<[f64; 3]>,
    pub rows: Vec<u8>,
}

/// What the decoding thread sends.
pub enum Msg {
    Batch(Batch),
    /// The file's fault, as the rest of a one-sentence error.
    Failed(String),
    /// Every scan read; how many points had a valid position.
    Done {
        valid: u64,
    },
}

/// A scan's pose: world = rotation * local + translation.
#[derive(Debug, Clone, Copy)]
pub struct Pose {
    rotation: [[f64; 3]; 3],
    pub translation: [f64; 3],
}

impl Pose {
    /// The pose of `pc` (identity when it has none). The quaternion is normalised: files
    /// written with rounded decimals would otherwise scale their points slightly.
    pub fn of(pc: &PointCloud) -> Result<Pose, String> {
        let Some(t) = &pc.transform else {
            return Ok(Pose {
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                translation: [0.0; 3],
            });
        };
        let q = &t.rotation;
        let translation = [t.translation.x, t.translation.y, t.translation.z];
        if !translation.iter().all(|v| v.is_finite()) {
            return Err(format!(
                "its pose's translation {translation:?} is not a finite position"
            ));
        }
        let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
        if !norm.is_normal() {
            return Err(format!(
                "its pose's rotation quaternion ({}, {}, {}, {}) is not a rotation",
                number(q.w),
                number(q.x),
                number(q.y),
                number(q.z)
            ));
        }
        let [w, x, y, z] = [q.w, q.x, q.y, q.z].map(|v| v / norm);
        let rotation = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        Ok(Pose {
            rotation,
            translation,
        })
    }

    #[inline]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [0, 1, 2].map(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + self.translation[i])
    }
}

/// Everything the decoding thread needs.
pub struct Job {
    pub reader: E57Reader<BufReader<File>>,
    pub clouds: Vec<PointCloud>,
    pub poses: Vec<Pose>,
    /// Each scan's colour and intensity ranges, as its limits state them.
    pub ranges: Vec<OwnRanges>,
    pub shape: RowShape,
    /// The file, opened again for the fields the simple reader does not give.
    pub path: std::path::PathBuf,
    /// The global index of the first scan listed with a scanner position.
    pub first: u16,
    /// Per scan, its place among the scans listed with a scanner position (`scanner_slots`);
    /// none where the file says nothing of where it stood.
    pub slots: Vec<Option<u16>>,
}

/// Where the scanner of each scan stood, where the file says: a scan with a pose stood at its
/// translation, one in spherical coordinates (without one) at the origin its ranges are
/// measured from. A scan in Cartesian coordinates without a pose says nothing of it: tools
/// that merge or edit clouds write them so, in the coordinates of the whole file, and
/// orienting normals towards its origin would turn most of them into the surface.
pub fn scanner_positions(clouds: &[PointCloud], poses: &[Pose]) -> Vec<Option<[f64; 3]>> {
    clouds
        .iter()
        .zip(poses)
        .map(|(pc, pose)| {
            (pc.transform.is_some() || !pc.has_cartesian()).then_some(pose.translation)
        })
        .collect()
}

/// Each scan's place among those with a known position, in order.
pub fn scanner_slots(stood: &[Option<[f64; 3]>]) -> Vec<Option<u16>> {
    let mut next = 0u16;
    stood
        .iter()
        .map(|s| {
            s.map(|_| {
                next += 1;
                next - 1
            })
        })
        .collect()
}

/// Decodes every scan of `job` into batches sent on `tx`, then `Done`; or `Failed` at the first
/// fault. Stops quietly when the reading side has gone.
pub fn run(job: Job, tx: &SyncSender<Msg>) {
    let Job {
        mut reader,
        clouds,
        poses,
        ranges,
        shape,
        path,
        first,
        slots,
    } = job;
    let n = clouds.len();
    let mut valid = 0u64;
    for (i, ((pc, pose), own)) in clouds.iter().zip(&poses).zip(&ranges).enumerate() {
        let scan = format!("scan {i} of {n}");
        let scanner = slots
            .get(i)
            .copied()
            .flatten()
            .map_or(super::NO_SCANNER, |k| first + k);
        let sent = guarded(&format!("the point data of {scan}"), || {
            let own = with_value_ranges(&mut reader, pc, own, &scan)?;
            let at = Place {
                pose,
                own: &own,
                scanner,
                scan: &scan,
                path: &path,
            };
            decode_scan(&mut reader, pc, &at, shape, tx, &mut valid)
        });
        match sent {
            Ok(true) => {}
            Ok(false) => return,
            Err(what) => {
                let _ = tx.send(Msg::Failed(what));
                return;
            }
        }
    }
    let _ = tx.send(Msg::Done { valid });
}

/// `own` with the ranges it lacks for the scan's colour and intensity made from the scan's
/// values (`from_values`): a pass over the scan of its own, only where one is missing.
fn with_value_ranges(
    reader: &mut E57Reader<BufReader<File>>,
    pc: &PointCloud,
    own: &OwnRanges,
    scan: &str,
) -> Result<OwnRanges, String> {
    let rgb = pc.has_color() && own.rgb.is_none();
    let intensity = pc.has_intensity() && own.intensity.is_none();
    if !rgb && !intensity {
        return Ok(own.clone());
    }
    let points = simple_points(reader, pc, scan)?;
    let widen = |span: &mut (f64, f64), v: f32| {
        if v.is_finite() {
            *span = (span.0.min(f64::from(v)), span.1.max(f64::from(v)));
        }
    };
    let mut colours = (f64::INFINITY, f64::NEG_INFINITY);
    let mut intensities = colours;
    for (k, p) in points.enumerate() {
        let p = p.map_err(|e| corrupt(scan, k, &e))?;
        if let Some(c) = &p.color {
            for v in [c.red, c.green, c.blue] {
                widen(&mut colours, v);
            }
        }
        if let Some(v) = p.intensity {
            widen(&mut intensities, v);
        }
    }
    // A field whose every value is invalid: any range will do.
    let span = |(least, greatest): (f64, f64)| {
        if least <= greatest {
            from_values(least, greatest)
        } else {
            (0.0, 1.0)
        }
    };
    Ok(OwnRanges {
        rgb: own.rgb.or_else(|| Some([span(colours); 3])),
        intensity: own.intensity.or_else(|| Some(span(intensities))),
    })
}

/// The fault of a scan's point `k` that the crate could not read.
fn corrupt(scan: &str, k: usize, e: &e57::Error) -> String {
    format!("{scan} is corrupt or truncated at point {k} ({})", plain(e))
}

/// The crate's simple reading of a scan, as both passes over it read it: local Cartesian
/// coordinates (the pose is applied here, with a normalised quaternion), colour and
/// intensity raw (normalised here), and no grey from intensity, which would be a colour the
/// file does not have.
fn simple_points<'r>(
    reader: &'r mut E57Reader<BufReader<File>>,
    pc: &PointCloud,
    scan: &str,
) -> Result<PastEmptyPackets<e57::PointCloudReaderSimple<'r, BufReader<File>>>, String> {
    let mut points = reader
        .pointcloud_simple(pc)
        .map_err(|e| format!("{scan} cannot be read ({})", plain(&e)))?;
    points.apply_pose(false);
    points.intensity_to_color(false);
    points.spherical_to_cartesian(true);
    points.normalize_intensity(false);
    points.normalize_color(false);
    Ok(PastEmptyPackets(points))
}

/// What the crate's simple reader reports where the packet it read held no point.
const EMPTY_PACKET: &str = "Cannot read next point because of logic error";

/// The crate's simple reader reads one packet when it has no point left, and reports a logic
/// error where that packet completes no point (an empty data packet, or one whose streams hold
/// only parts of values, which ASTM E2807 allows). A valid file was refused. (An ignored or
/// index packet before a data packet the crate misreads; `e57_section` refuses those.)
/// Its state is whole (it counted no point), and the next call reads the packet after; every
/// call reads a packet, and the packets were walked before (`e57_section`), so a run ends.
struct PastEmptyPackets<I>(I);

impl<I: Iterator<Item = e57::Result<e57::Point>>> Iterator for PastEmptyPackets<I> {
    type Item = I::Item;

    fn next(&mut self) -> Option<I::Item> {
        loop {
            match self.0.next() {
                Some(Err(e57::Error::Internal { desc, .. })) if desc == EMPTY_PACKET => {}
                other => return other,
            }
        }
    }
}

/// What a scan's points are placed and scaled by.
struct Place<'a> {
    pose: &'a Pose,
    /// The ranges colour and intensity are normalised by (see `e57_limits`).
    own: &'a OwnRanges,
    scanner: u16,
    scan: &'a str,
    path: &'a std::path::Path,
}

/// One scan; `Ok(false)` when the reading side has gone.
fn decode_scan(
    reader: &mut E57Reader<BufReader<File>>,
    pc: &PointCloud,
    at: &Place,
    shape: RowShape,
    tx: &SyncSender<Msg>,
    valid: &mut u64,
) -> Result<bool, String> {
    let Place {
        pose,
        own,
        scanner,
        scan,
        path,
    } = *at;
    // The extra fields, from raw records read in step on a reader of their own.
    let extras = ScanExtras::of(pc, shape.absolute_time);
    let mut raw_reader = match &extras {
        Some(_) => Some(ScanExtras::open(path).map_err(|e| format!("{scan}: {e}"))?),
        None => None,
    };
    let mut raw = match &mut raw_reader {
        Some(r) => Some(
            r.pointcloud_raw(pc)
                .map_err(|e| format!("{scan} cannot be read ({})", plain(&e)))?,
        ),
        None => None,
    };
    let points = simple_points(reader, pc, scan)?;
    let mut batch = Batch::default();
    for (k, p) in points.enumerate() {
        let p = p.map_err(|e| corrupt(scan, k, &e))?;
        let extra = match (&extras, &mut raw) {
            (Some(e), Some(raw)) => {
                let values = raw
                    .next()
                    .ok_or_else(|| format!("{scan} ends early at point {k}"))?
                    .map_err(|e| corrupt(scan, k, &e))?;
                Some(
                    e.read(pc, &values)
                        .map_err(|e| format!("{scan} point {k}: {e}"))?,
                )
            }
            _ => None,
        };
        let CartesianCoordinate::Valid { x, y, z } = p.cartesian else {
            continue;
        };
        // Checked in the scan's frame: a pose would spread one axis's infinity to all three.
        if let Some(a) = [x, y, z].iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "{scan} point {k} has a non-finite {} coordinate ({})",
                ["x", "y", "z"][a],
                [x, y, z][a]
            ));
        }
        batch.xyz.push(pose.apply([x, y, z]));
        let at = batch.rows.len();
        batch.rows.resize(at + shape.len, 0);
        let row = &mut batch.rows[at..];
        if let (Some(o), Some(c)) = (shape.rgb, &p.color) {
            for (k, v) in [c.red, c.green, c.blue].into_iter().enumerate() {
                let v = own.rgb.map_or(0.0, |r| normalised(v, r[k]));
                row[o + 2 * k..o + 2 * k + 2].copy_from_slice(&unit_to_u16(v).to_le_bytes());
            }
        }
        if let (Some(o), Some(v)) = (shape.intensity, p.intensity) {
            let v = own.intensity.map_or(0.0, |r| normalised(v, r));
            row[o..o + 2].copy_from_slice(&unit_to_u16(v).to_le_bytes());
        }
        if let Some(o) = shape.returns {
            let (number, count) = extra.map_or((1, 1), |e| (e.return_number, e.number_of_returns));
            row[o] = number;
            row[o + 1] = count;
        }
        if let (Some(o), Some(e)) = (shape.time, extra) {
            row[o..o + 8].copy_from_slice(&e.time.to_le_bytes());
        }
        row[shape.scanner..shape.scanner + 2].copy_from_slice(&scanner.to_le_bytes());
        if batch.xyz.len() == BATCH_POINTS {
            *valid += BATCH_POINTS as u64;
            if tx.send(Msg::Batch(std::mem::take(&mut batch))).is_err() {
                return Ok(false);
            }
        }
    }
    *valid += batch.xyz.len() as u64;
    Ok(batch.xyz.is_empty() || tx.send(Msg::Batch(batch)).is_ok())
}

/// A value the crate normalised to 0..1 as 0..65535, the way LAS stores 16-bit colour. A range
/// of zero width makes the crate's value NaN, which becomes 0.
#[inline]
fn unit_to_u16(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// The crate's error as plain words for a one-line message: its first line without the
/// crate's repeated or internal context, a failed page checksum said simply, control
/// characters shown as `?`.
pub fn plain(e: &e57::Error) -> String {
    let text = e.to_string();
    let first = text.lines().next().unwrap_or_default();
    if first.contains("invalid checksum") {
        let page = first
            .rsplit("for page ")
            .next()
            .and_then(|p| p.trim().parse::<u64>().ok());
        return match page {
            Some(p) => format!("page {p} fails its CRC checksum"),
            None => "a page fails its CRC checksum".into(),
        };
    }
    const NOISE: [&str; 3] = [
        "Failed to read E57",
        "Invalid E57 content",
        "Failed creating paged CRC reader",
    ];
    let mut parts: Vec<&str> = Vec::new();
    for part in first.split(": ").map(str::trim) {
        if !part.is_empty() && !NOISE.contains(&part) && !parts.contains(&part) {
            parts.push(part);
        }
    }
    let said = parts.join(": ");
    let mut chars = said.chars();
    let first_char = chars.next().map(|c| c.to_lowercase().collect::<String>());
    first_char
        .unwrap_or_default()
        .chars()
        .chain(chars)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_values_span_sixteen_bits() {
        assert_eq!(unit_to_u16(0.0), 0);
        assert_eq!(unit_to_u16(1.0), 65535);
        assert_eq!(unit_to_u16(1.0 / 255.0), 257);
        assert_eq!(unit_to_u16(f32::NAN), 0);
        assert_eq!(unit_to_u16(2.0), 65535);
    }

    #[test]
    fn crate_errors_read_as_one_plain_clause() {
        let e = e57::Error::Read {
            desc: "Failed to read E57: File appears to be truncated: offset 9 is behind end of file: File appears to be truncated".into(),
            source: None,
        };
        assert_eq!(
            plain(&e),
            "file appears to be truncated: offset 9 is behind end of file"
        );
        let e = e57::Error::Read {
            desc: "Failed to read data packet buffers: Detected invalid checksum (expected: [1, 2], actual: [3, 4]) for page 4".into(),
            source: None,
        };
        assert_eq!(plain(&e), "page 4 fails its CRC checksum");
    }

    #[test]
    fn pose_rotates_then_translates() {
        // 90 degrees about z: x goes to y.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut pc = PointCloud::default();
        pc.transform = Some(e57::Transform {
            rotation: e57::Quaternion {
                w: h * 2.0,
                x: 0.0,
                y: 0.0,
                z: h * 2.0,
            },
            translation: e57::Translation {
                x: 10.0,
                y: 20.0,
                z: 30.0,
            },
        });
        let p = Pose::of(&pc).expect("pose").apply([1.0, 0.0, 0.0]);
        for (a, b) in p.iter().zip([10.0, 21.0, 30.0]) {
            assert!((a - b).abs() < 1e-12, "{p:?}");
        }
    }

    #[test]
    fn poses_that_are_no_rotation_are_refused() {
        let mut pc = PointCloud::default();
        pc.transform = Some(e57::Transform::default());
        if let Some(t) = &mut pc.transform {
            t.rotation.w = 0.0;
        }
        assert!(Pose::of(&pc).is_err());
        if let Some(t) = &mut pc.transform {
            t.rotation.w = 1.0;
            t.translation.x = f64::NAN;
        }
        assert!(Pose::of(&pc).is_err());
    }
}
