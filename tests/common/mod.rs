#![allow(dead_code)]

pub mod servers;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name)
}

pub fn strata() -> Command {
    Command::new(env!("CARGO_BIN_EXE_strata"))
}

/// Makes a named pipe at `path` (what a reader opening it waits on for a writer).
pub fn mkfifo(path: &Path) {
    let ok = Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("mkfifo runs");
    assert!(ok.success(), "mkfifo {}", path.display());
}

/// Runs strata with `args`; returns the output.
pub fn run(args: &[&str]) -> Output {
    match strata().args(args).output() {
        Ok(o) => o,
        Err(e) => panic!("cannot run strata: {e}"),
    }
}

/// Runs strata with `args` under `timeout 60` (on lavapipe where it renders): a run that
/// would wait forever ends with exit 124 instead of hanging the suite.
pub fn run_bounded(args: &[&str]) -> Output {
    let out = Command::new("timeout")
        .arg("60")
        .arg(env!("CARGO_BIN_EXE_strata"))
        .args(args)
        .env("WGPU_BACKEND", "vulkan")
        .output();
    match out {
        Ok(o) => o,
        Err(e) => panic!("cannot run timeout strata: {e}"),
    }
}

/// Runs strata with `args` where no file may grow past `kib` KiB: writes fail as on a full
/// disk (EFBIG instead of ENOSPC), and the signal that would kill the process is ignored.
pub fn run_file_limited(kib: u32, args: &[&str]) -> Output {
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {kib}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_strata"))
        .args(args)
        .output();
    match out {
        Ok(o) => o,
        Err(e) => panic!("cannot run sh: {e}"),
    }
}

pub fn run_ok(args: &[&str]) -> Output {
    let o = run(args);
    assert!(
        o.status.success(),
        "strata {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Runs strata on the GPU (lavapipe unless WGPU_BACKEND says otherwise).
pub fn gpu_run(args: &[&str]) -> Output {
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    // Mesa's window-system probe complains on stderr without one; tests read stderr.
    let runtime = Path::new(env!("CARGO_TARGET_TMPDIR")).join("xdg-runtime");
    let _ = std::fs::create_dir_all(&runtime);
    let mut cmd = strata();
    cmd.env("WGPU_BACKEND", backend)
        .env("XDG_RUNTIME_DIR", &runtime);
    match cmd.args(args).output() {
        Ok(o) => o,
        Err(e) => panic!("cannot run strata: {e}"),
    }
}

pub fn gpu_ok(args: &[&str]) -> Output {
    let o = gpu_run(args);
    assert!(
        o.status.success(),
        "strata {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// A PNG as RGBA rows.
pub fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) => panic!("{}: {e}", path.display()),
    };
    let mut dec = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .expect("png header");
    let mut buf = vec![0; dec.output_buffer_size().expect("png size")];
    let info = dec.next_frame(&mut buf).expect("png data");
    buf.truncate(info.buffer_size());
    let rgba = match info.color_type {
        png::ColorType::Rgba => buf,
        png::ColorType::Rgb => buf
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        other => panic!("unexpected PNG colour type {other:?}"),
    };
    (info.width, info.height, rgba)
}

/// `target/tmp/TAG`, emptied: left over from an earlier run, it is rebuilt so every run
/// starts from the same files.
pub fn fresh_dir(tag: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tag);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("fixture dir");
    dir
}

/// `input` (a file of ../shared/data) converted once per test binary, fresh each run, into
/// `target/tmp/TAG/NAME.strata`.
pub fn converted(tag: &str, input: &str, name: &str) -> PathBuf {
    converted_with(tag, input, name, &[])
}

/// `converted`, with `options` given to `convert` (the tag must differ from the plain one's).
pub fn converted_with(tag: &str, input: &str, name: &str, options: &[&str]) -> PathBuf {
    static MADE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tag);
    let out = dir.join(format!("{name}.strata"));
    let mut made = MADE.lock().unwrap_or_else(|e| e.into_inner());
    if !made.contains(&out) {
        // Left over from an earlier run: rebuilt so every run starts from the same files.
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&dir).expect("fixture dir");
        let input = data(input);
        let mut args = vec!["convert", s(&input), "-o", s(&out), "--quiet"];
        args.extend_from_slice(options);
        run_ok(&args);
        made.push(out.clone());
    }
    out
}

/// Runs `args`, which must be refused: exit 1, or 2 for a usage error the argument parser
/// reports (a panic exits 101, an abort is a signal), every word of `expect` in the message,
/// no panic. Returns stderr.
pub fn refused(args: &[&str], expect: &[&str]) -> String {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        matches!(o.status.code(), Some(1 | 2)),
        "{args:?} should be refused: {:?}, {err}",
        o.status.code()
    );
    for e in expect {
        assert!(err.contains(e), "expected {e:?} in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Converts `input` and checks the failure; returns stderr.
pub fn convert_fails(input: &Path, expect: &str) -> String {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("ds");
    let o = run(&["convert", s(input), "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(
        !o.status.success(),
        "convert of {} should fail",
        input.display()
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains(input.file_name().and_then(|n| n.to_str()).unwrap_or("?")),
        "error must name the file: {err}"
    );
    assert!(
        err.to_lowercase().contains(&expect.to_lowercase()),
        "expected {expect:?} in: {err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(!out.exists(), "no output may appear");
    assert!(
        !dir.path().join("ds.strata-tmp").exists(),
        "no work left behind"
    );
    err
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Every field of a LAS point that a round trip must keep, as comparable integers.
pub type PointKey = ([i64; 3], [i64; 19]);

pub fn las_points(path: &Path) -> (Vec<PointKey>, [f64; 3]) {
    let mut r = las::Reader::from_path(path).expect("readable LAS");
    let t = *r.header().transforms();
    let scale = [t.x.scale, t.y.scale, t.z.scale];
    let data = r.read_all().expect("all points");
    let q = |v: f64, a: usize| (v / scale[a]).round() as i64;
    let pts = data
        .points()
        .map(|p| {
            let p = p.expect("point decodes");
            let c = p.color.map_or([0; 3], |c| [c.red, c.green, c.blue]);
            (
                [q(p.x, 0), q(p.y, 1), q(p.z, 2)],
                [
                    p.intensity as i64,
                    p.return_number as i64,
                    p.number_of_returns as i64,
                    u8::from(p.classification) as i64,
                    p.is_synthetic as i64,
                    p.is_key_point as i64,
                    p.is_withheld as i64,
                    p.is_overlap as i64,
                    p.user_data as i64,
                    (p.scan_angle * 1000.0).round() as i64,
                    p.scanner_channel as i64,
                    p.point_source_id as i64,
                    p.gps_time.map_or(0, f64::to_bits) as i64,
                    c[0] as i64,
                    c[1] as i64,
                    c[2] as i64,
                    p.nir.unwrap_or(0) as i64,
                    p.is_edge_of_flight_line as i64,
                    matches!(p.scan_direction, las::point::ScanDirection::LeftToRight) as i64,
                ],
            )
        })
        .collect();
    (pts, scale)
}

/// The points of a LAS/LAZ file as a sorted multiset, read with the `las` crate's own
/// point decoder (independent of Strata's raw record decoding).
pub fn las_multiset(path: &Path) -> Vec<PointKey> {
    let mut pts = las_points(path).0;
    pts.sort_unstable();
    pts
}

pub fn las_scale(path: &Path) -> [f64; 3] {
    let r = las::Reader::from_path(path).expect("readable LAS");
    let t = r.header().transforms();
    [t.x.scale, t.y.scale, t.z.scale]
}

/// Writes a PLY of `spread` points over a square kilometre and 200,000 in a cluster a few
/// hundredths of a millimetre wide: converted, it is 20 levels deep, with proxies on several
/// pages and inner nodes whose points all went to their parents (nodes without points).
pub fn deep_ply(path: &Path, spread: usize) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut unit = move || {
        // SplitMix64, as a float in (0, 1).
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 + 1e-17
    };
    let cluster = 200_000;
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
        spread + cluster
    )
    .into_bytes();
    for _ in 0..spread {
        for v in [unit() * 1000.0, unit() * 1000.0, unit() * 10.0] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for _ in 0..cluster {
        for c in [500.123, 500.456, 5.0] {
            // Box-Muller: a normal deviation of 0.02 mm.
            let g = (-2.0 * unit().ln()).sqrt() * (std::f64::consts::TAU * unit()).cos();
            out.extend_from_slice(&(c + g * 2e-5).to_le_bytes());
        }
    }
    std::fs::write(path, out).expect("write the deep PLY");
}

/// The centre of `deep_ply`'s cluster.
pub const DEEP_CENTRE: [f64; 3] = [500.123, 500.456, 5.0];

/// `deep_ply` converted once per test binary into `target/tmp/TAG/deep.strata`.
pub fn deep_dataset(tag: &str) -> PathBuf {
    static MADE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tag);
    let out = dir.join("deep.strata");
    let mut made = MADE.lock().unwrap_or_else(|e| e.into_inner());
    if !made.contains(&out) {
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&dir).expect("fixture dir");
        let ply = dir.join("deep.ply");
        deep_ply(&ply, 20_000);
        run_ok(&["convert", s(&ply), "-o", s(&out), "--quiet"]);
        made.push(out.clone());
    }
    out
}

/// Whether xvfb-run is there for a window test; without it the test is skipped, unless CI
/// (`STRATA_REQUIRE_XVFB`) says it must run.
pub fn have_xvfb() -> bool {
    if Path::new("/usr/bin/xvfb-run").exists() {
        return true;
    }
    assert!(
        std::env::var_os("STRATA_REQUIRE_XVFB").is_none(),
        "xvfb-run is missing but STRATA_REQUIRE_XVFB is set"
    );
    eprintln!("skipping: xvfb-run is not installed");
    false
}

/// CRC-32C (Castagnoli), the checksum that ends every 1024-byte E57 page: tests that edit an
/// E57 file repair it with this.
#[allow(unused_imports)] // Shared by every test crate; only the E57 ones use it.
pub use strata_converter::input::e57_header::crc32c as e57_crc32c;

/// The names in the `attributes` list of a metadata or `info --json` document, in order.
pub fn attribute_names(doc: &serde_json::Value) -> Vec<&str> {
    doc["attributes"]
        .as_array()
        .expect("an attributes list")
        .iter()
        .map(|a| a["name"].as_str().expect("an attribute name"))
        .collect()
}

/// Writes a binary PLY of points with colours, and with normals where `normals` is given (one
/// per point).
pub fn write_coloured_ply(
    path: &Path,
    points: &[([f64; 3], [u8; 3])],
    normals: Option<&[[f32; 3]]>,
) {
    use std::io::Write;
    let extra = if normals.is_some() {
        "property float nx\nproperty float ny\nproperty float nz\n"
    } else {
        ""
    };
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).expect("create the PLY"));
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n{extra}end_header\n",
        points.len()
    )
    .expect("PLY header");
    for (k, (p, rgb)) in points.iter().enumerate() {
        for v in p {
            out.write_all(&(*v as f32).to_le_bytes())
                .expect("write the PLY");
        }
        out.write_all(rgb).expect("write the PLY");
        if let Some(n) = normals {
            for v in n[k] {
                out.write_all(&v.to_le_bytes()).expect("write the PLY");
            }
        }
    }
    out.flush().expect("write the PLY");
}

/// A LAS 1.4 file (format 1) of `points`, each (x, y, z) with its extra bytes, described by
/// the Extra Bytes `descriptor` (192 bytes a field, LAS 1.4 R15 table 24) in a VLR, or in an
/// extended VLR where `extended`.
pub fn extra_bytes_las(
    path: &Path,
    descriptor: Vec<u8>,
    extended: bool,
    points: &[([f64; 3], Vec<u8>)],
) {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(1).expect("format");
    builder.point_format.extra_bytes = points.first().map_or(0, |p| p.1.len() as u16);
    let vlr = las::Vlr {
        user_id: "LASF_Spec".into(),
        record_id: 4,
        description: "Extra Bytes Record".into(),
        data: descriptor,
    };
    if extended {
        builder.evlrs.push(vlr);
    } else {
        builder.vlrs.push(vlr);
    }
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(path, header).expect("writer");
    for ([x, y, z], extra) in points {
        writer
            .write_point(las::Point {
                x: *x,
                y: *y,
                z: *z,
                gps_time: Some(0.0),
                extra_bytes: extra.clone(),
                ..Default::default()
            })
            .expect("write");
    }
    writer.close().expect("close");
}

/// A LAS file of `points`, each (x, y, z) with a u64 extra attribute "serial".
pub fn serial_las(path: &Path, points: &[([f64; 3], u64)]) {
    let mut eb = vec![0u8; 192];
    eb[2] = 7; // data type: u64
    eb[4..10].copy_from_slice(b"serial");
    let rows: Vec<_> = points
        .iter()
        .map(|&(p, serial)| (p, serial.to_le_bytes().to_vec()))
        .collect();
    extra_bytes_las(path, eb, false, &rows);
}

/// Uniform numbers in [0, 1) from `seed`, the same on every run (a 64-bit LCG's top bits).
pub fn unit_randoms(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Where the body of `laz`'s laszip VLR starts (after its 54-byte header; the user id
/// "laszip encoded" lies 2 bytes into that header).
pub fn laszip_vlr_body(laz: &[u8]) -> usize {
    let id = laz
        .windows(14)
        .position(|w| w == b"laszip encoded")
        .expect("a laszip VLR");
    id - 2 + 54
}
