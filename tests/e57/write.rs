#![allow(dead_code)]

//! E57 files for the tests, written with the `e57` crate's writer: scans of generated points
//! with chosen storage, colour, intensity, invalid points and poses.

use e57::{
    CartesianCoordinate, E57Reader, E57Writer, Quaternion, Record, RecordDataType, RecordName,
    RecordValue, Transform, Translation,
};
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Storage {
    /// Cartesian doubles.
    Double,
    /// Cartesian scaled integers (0.1 mm).
    Scaled,
    /// Cartesian singles (f32).
    Single,
    /// Spherical doubles (range, azimuth, elevation).
    Spherical,
}

#[derive(Debug, Clone)]
pub struct ScanSpec {
    pub storage: Storage,
    pub points: usize,
    pub colour: bool,
    /// 12-bit intensity (limits 0..4095).
    pub intensity: bool,
    /// Every how many points one has no valid position (state 2, or 1: a direction only).
    pub invalid_every: Option<usize>,
    /// Rotation quaternion (w, x, y, z; normalised here) and translation.
    pub rotation: [f64; 4],
    pub translation: [f64; 3],
    /// The scale the prototype declares for `Storage::Scaled` (the values written are 0.1 mm
    /// steps whatever it says).
    pub scale: f64,
    /// The offset it declares with that scale.
    pub offset: f64,
    /// Written with its pose (else none: Cartesian clouds merged or edited by a tool).
    pub posed: bool,
}

impl ScanSpec {
    pub fn new(storage: Storage, points: usize) -> ScanSpec {
        ScanSpec {
            storage,
            points,
            colour: false,
            intensity: false,
            invalid_every: None,
            rotation: [1.0, 0.0, 0.0, 0.0],
            translation: [0.0; 3],
            scale: 1e-4,
            offset: 0.0,
            posed: true,
        }
    }

    /// A rotation of `degrees` about `axis`.
    pub fn rotated(mut self, axis: [f64; 3], degrees: f64) -> ScanSpec {
        let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        let h = degrees.to_radians() / 2.0;
        let s = h.sin() / n;
        self.rotation = [h.cos(), axis[0] * s, axis[1] * s, axis[2] * s];
        self
    }

    pub fn at(mut self, translation: [f64; 3]) -> ScanSpec {
        self.translation = translation;
        self
    }
}

/// A scan's pose: rotation quaternion (w, x, y, z) and translation.
pub fn pose([w, x, y, z]: [f64; 4], [tx, ty, tz]: [f64; 3]) -> Transform {
    Transform {
        rotation: Quaternion { w, x, y, z },
        translation: Translation {
            x: tx,
            y: ty,
            z: tz,
        },
    }
}

/// A small deterministic generator, so every run writes the same files.
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

fn prototype(spec: &ScanSpec) -> Vec<Record> {
    let rec = |name: RecordName, data_type: RecordDataType| Record { name, data_type };
    let scaled = RecordDataType::ScaledInteger {
        min: -1_000_000,
        max: 1_000_000,
        scale: spec.scale,
        offset: spec.offset,
    };
    let mut p = match spec.storage {
        Storage::Double => vec![
            Record::CARTESIAN_X_F64,
            Record::CARTESIAN_Y_F64,
            Record::CARTESIAN_Z_F64,
        ],
        Storage::Scaled => vec![
            rec(RecordName::CartesianX, scaled.clone()),
            rec(RecordName::CartesianY, scaled.clone()),
            rec(RecordName::CartesianZ, scaled),
        ],
        Storage::Single => vec![
            Record::CARTESIAN_X_F32,
            Record::CARTESIAN_Y_F32,
            Record::CARTESIAN_Z_F32,
        ],
        Storage::Spherical => vec![
            Record::SPHERICAL_RANGE_F64,
            Record::SPHERICAL_AZIMUTH_F64,
            Record::SPHERICAL_ELEVATION_F64,
        ],
    };
    if spec.invalid_every.is_some() {
        p.push(match spec.storage {
            Storage::Spherical => Record::SPHERICAL_INVALID_STATE,
            _ => Record::CARTESIAN_INVALID_STATE,
        });
    }
    if spec.colour {
        p.extend([
            Record::COLOR_RED_U8,
            Record::COLOR_GREEN_U8,
            Record::COLOR_BLUE_U8,
        ]);
    }
    if spec.intensity {
        p.push(rec(
            RecordName::Intensity,
            RecordDataType::Integer { min: 0, max: 4095 },
        ));
    }
    p
}

/// Writes `scans` into `path`; returns each scan's valid points in local coordinates.
pub fn write_e57(path: &Path, scans: &[ScanSpec]) -> Vec<Vec<[f64; 3]>> {
    let mut w = E57Writer::from_file(path, "strata-test-file").expect("e57 writer");
    let mut local = Vec::new();
    let mut rng = Lcg(17);
    for (i, spec) in scans.iter().enumerate() {
        let mut pc = w
            .add_pointcloud(&format!("strata-test-scan-{i}"), prototype(spec))
            .expect("point cloud writer");
        if spec.posed {
            pc.set_transform(Some(pose(spec.rotation, spec.translation)));
        }
        let mut valid = Vec::new();
        for k in 0..spec.points {
            let state = match spec.invalid_every {
                Some(n) if k % n == n - 1 => 1 + (k / n % 2) as i64,
                _ => 0,
            };
            let mut values = match spec.storage {
                Storage::Double => {
                    let p = [0; 3].map(|_| rng.range(-4.0, 4.0));
                    if state == 0 {
                        valid.push(p);
                    }
                    p.map(RecordValue::Double).to_vec()
                }
                Storage::Scaled => {
                    let p = [0; 3].map(|_| (rng.range(-4.0, 4.0) * 1e4).round() as i64);
                    if state == 0 {
                        valid.push(p.map(|v| v as f64 * 1e-4));
                    }
                    p.map(RecordValue::ScaledInteger).to_vec()
                }
                Storage::Single => {
                    let p = [0; 3].map(|_| rng.range(-4.0, 4.0) as f32);
                    if state == 0 {
                        valid.push(p.map(f64::from));
                    }
                    p.map(RecordValue::Single).to_vec()
                }
                Storage::Spherical => {
                    let (r, a, e) = (
                        rng.range(1.0, 9.0),
                        rng.range(-3.1, 3.1),
                        rng.range(-1.2, 1.2),
                    );
                    if state == 0 {
                        valid.push([r * e.cos() * a.cos(), r * e.cos() * a.sin(), r * e.sin()]);
                    }
                    [r, a, e].map(RecordValue::Double).to_vec()
                }
            };
            if spec.invalid_every.is_some() {
                values.push(RecordValue::Integer(state));
            }
            if spec.colour {
                values.extend(
                    [0; 3].map(|_| RecordValue::Integer((rng.unit() * 256.0) as i64 % 256)),
                );
            }
            if spec.intensity {
                values.push(RecordValue::Integer((rng.unit() * 4096.0) as i64 % 4096));
            }
            pc.add_point(values).expect("point");
        }
        pc.finalize().expect("scan written");
        local.push(valid);
    }
    w.finalize().expect("file written");
    local
}

/// A point as the `e57` crate reads it: pose applied, spherical converted, colour and
/// intensity normalised by the scan's limits (then scaled to 16 bits), no grey from intensity.
#[derive(Debug, Clone)]
pub struct CratePoint {
    pub position: [f64; 3],
    pub scan: usize,
    pub rgb: Option<[u16; 3]>,
    pub intensity: Option<u16>,
}

pub fn crate_points(path: &Path) -> Vec<CratePoint> {
    let mut r = E57Reader::from_file(path).expect("the e57 crate reads the file");
    let sixteen = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
    let mut out = Vec::new();
    for (scan, pc) in r.pointclouds().iter().enumerate() {
        let mut points = r.pointcloud_simple(pc).expect("scan reader");
        points.intensity_to_color(false);
        for p in points {
            let p = p.expect("point");
            if let CartesianCoordinate::Valid { x, y, z } = p.cartesian {
                out.push(CratePoint {
                    position: [x, y, z],
                    scan,
                    rgb: p.color.map(|c| [c.red, c.green, c.blue].map(sixteen)),
                    intensity: p.intensity.map(sixteen),
                });
            }
        }
    }
    out
}

/// `local` in world coordinates under the pose of `spec`, computed here from the quaternion.
pub fn world(spec: &ScanSpec, local: [f64; 3]) -> [f64; 3] {
    let n = spec.rotation.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [w, x, y, z] = spec.rotation.map(|v| v / n);
    // v' = q v q*, expanded: v + 2w (u x v) + 2 u x (u x v), u = (x, y, z).
    let u = [x, y, z];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let uv = cross(u, local);
    let uuv = cross(u, uv);
    [0, 1, 2].map(|a| local[a] + 2.0 * w * uv[a] + 2.0 * uuv[a] + spec.translation[a])
}
