use super::*;
use crate::build::{ConvertOptions, convert_with};
use crate::sampling::Sampling;
use crate::synth::{Scene, synth};
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use strata_format::{LocalDataset, oct16_decode};

/// Per point of a dataset: quantized position, real position, normal, radius, σ.
type PointNormals = Vec<([i32; 3], [f64; 3], Option<[f64; 3]>, f64, f64)>;

/// Numbers in 0..1 from `seed`, the same every run.
pub(super) fn unit_randoms(mut s: u64) -> impl FnMut() -> f64 {
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn read_normals(dir: &Path) -> PointNormals {
    let ds = LocalDataset::open(dir).expect("open");
    let layout = ds.layout().clone();
    let meta = ds.metadata().clone();
    let n = layout.index_of("normal").expect("normal attribute");
    let r = layout.index_of("radius").expect("radius attribute");
    let s = layout.index_of("surface_variation").expect("σ attribute");
    let mut out = Vec::new();
    for node in ds.all_nodes().expect("nodes") {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node).expect("node");
        let (nc, rc, sc) = (
            cols.attribute(&layout, n),
            cols.attribute(&layout, r),
            cols.attribute(&layout, s),
        );
        for i in 0..node.point_count as usize {
            let raw = [
                u16::from_le_bytes([nc[4 * i], nc[4 * i + 1]]),
                u16::from_le_bytes([nc[4 * i + 2], nc[4 * i + 3]]),
            ];
            let q = cols.position(i);
            out.push((
                q,
                meta.to_real(q),
                oct16_decode(raw),
                AttrType::F32.read_f64(&rc[4 * i..]),
                AttrType::F16.read_f64(&sc[2 * i..]),
            ));
        }
    }
    out
}

/// What the metadata says of a dataset's normals.
fn normals_info(dir: &Path) -> strata_format::NormalsInfo {
    let ds = LocalDataset::open(dir).expect("open");
    ds.metadata().normals.clone().expect("normals recorded")
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    dot(a, b).clamp(-1.0, 1.0).acos().to_degrees()
}

fn options(input: &Path, output: PathBuf, memory_limit: u64) -> ConvertOptions {
    ConvertOptions {
        inputs: vec![input.to_path_buf()],
        output,
        memory_limit,
        threads: 2,
        sampling: Sampling::Poisson,
        overwrite: false,
        resume: false,
        quiet: true,
        temp_dir: None,
    }
}

fn step(orient: Orient, viewpoint: Option<[f64; 3]>) -> NormalStep {
    NormalStep::new(NormalOptions {
        orient,
        viewpoint,
        ..NormalOptions::default()
    })
    .expect("options")
}

/// A binary PLY of float positions (and normals, where given).
fn write_ply(path: &Path, points: &[[f64; 3]], normals: Option<&[[f64; 3]]>) {
    let mut head = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        points.len()
    );
    if normals.is_some() {
        head.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    head.push_str("end_header\n");
    let mut bytes = head.into_bytes();
    for (i, p) in points.iter().enumerate() {
        let mut vals = p.to_vec();
        if let Some(n) = normals {
            vals.extend(n[i]);
        }
        for v in vals {
            bytes.extend((v as f32).to_le_bytes());
        }
    }
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&bytes))
        .expect("write ply");
}

/// Uniform random points on a sphere of radius `r` around `c`.
fn sphere(n: usize, c: [f64; 3], r: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut next = unit_randoms(seed);
    (0..n)
        .map(|_| {
            let z = next() * 2.0 - 1.0;
            let t = next() * std::f64::consts::TAU;
            let h = (1.0 - z * z).sqrt();
            [c[0] + r * h * t.cos(), c[1] + r * h * t.sin(), c[2] + r * z]
        })
        .collect()
}

#[test]
fn normals_do_not_change_at_chunk_borders() {
    // The city twice over: every position repeated, which the neighbourhoods must see the
    // same way however the cloud is cut.
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    synth(&las, 150_000, Scene::City, 3, 0.0, false).expect("synth");
    let twice = |output: PathBuf, memory_limit: u64| ConvertOptions {
        inputs: vec![las.clone(), las.clone()],
        ..options(&las, output, memory_limit)
    };
    let many = convert_with(
        &twice(dir.path().join("many"), 64 << 20),
        &step(Orient::Up, None),
    )
    .expect("convert in many chunks");
    let one = convert_with(
        &twice(dir.path().join("one"), 4 << 30),
        &step(Orient::Up, None),
    )
    .expect("convert in one chunk");
    assert!(many.chunks >= 4, "{} chunks", many.chunks);
    assert_eq!(one.chunks, 1);
    type Values = (Option<[f64; 3]>, f64, f64);
    let whole: HashMap<[i32; 3], Values> = read_normals(&dir.path().join("one"))
        .into_iter()
        .map(|(q, _, n, r, s)| (q, (n, r, s)))
        .collect();
    let mut worst: f64 = 0.0;
    let cut = read_normals(&dir.path().join("many"));
    assert_eq!(cut.len(), 300_000);
    for (q, _, n, r, s) in &cut {
        let (n1, r1, s1) = whole[q];
        match (n, n1) {
            (Some(n), Some(n1)) => worst = worst.max(angle(*n, n1)),
            (None, None) => {}
            _ => panic!("a normal in one chunking only at {q:?}: {n:?} against {n1:?}"),
        }
        // The same neighbours: the same radius and variation, to the bit.
        assert_eq!((*r, *s), (r1, s1), "radius and variation at {q:?}");
    }
    assert!(
        worst <= 1.0,
        "a normal differs by {worst}° across chunkings"
    );
    let info = normals_info(&dir.path().join("many"));
    assert_eq!(info.computed, 300_000);
    let whole_info = normals_info(&dir.path().join("one"));
    assert_eq!(
        info.partial, whole_info.partial,
        "points short of k neighbours"
    );
    assert_eq!(info.orient, "up");
    assert!(info.surfel_radius > 0.0 && info.triangles > 1000);
}

#[test]
fn a_sphere_gets_radial_normals_facing_the_viewpoint() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("sphere.ply");
    let centre = [10.0, -4.0, 2.0];
    write_ply(&ply, &sphere(60_000, centre, 3.0, 9), None);
    convert_with(
        &options(&ply, dir.path().join("in"), 1 << 30),
        &step(Orient::Auto, Some(centre)),
    )
    .expect("convert");
    let pts = read_normals(&dir.path().join("in"));
    let mut errors: Vec<f64> = pts
        .iter()
        .map(|(_, p, n, _, _)| {
            let inward = [0, 1, 2].map(|a| (centre[a] - p[a]) / 3.0);
            angle(n.expect("a normal"), inward)
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    let (median, p95, worst) = (
        errors[errors.len() / 2],
        errors[errors.len() * 95 / 100],
        errors[errors.len() - 1],
    );
    assert!(median < 1.0 && p95 < 3.0, "median {median}°, p95 {p95}°");
    assert!(
        worst < 90.0,
        "a normal faces away from the viewpoint ({worst}°)"
    );
    // A sphere curves: σ is small but not zero; the radius follows the spacing.
    let sigma: f64 = pts.iter().map(|p| p.4).sum::<f64>() / pts.len() as f64;
    assert!(sigma > 1e-5 && sigma < 0.02, "mean σ {sigma}");

    convert_with(
        &options(&ply, dir.path().join("up"), 1 << 30),
        &step(Orient::Up, None),
    )
    .expect("convert");
    let up = read_normals(&dir.path().join("up"));
    assert!(
        up.iter()
            .all(|(_, _, n, _, _)| n.expect("a normal")[2] >= 0.0)
    );
}

#[test]
fn discs_of_the_radius_cover_a_randomly_sampled_plane() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("plane.ply");
    let mut next = unit_randoms(77u64);
    let side = 20.0;
    let pts: Vec<[f64; 3]> = (0..40_000)
        .map(|_| [next() * side, next() * side, 5.0])
        .collect();
    write_ply(&ply, &pts, None);
    convert_with(
        &options(&ply, dir.path().join("plane"), 1 << 30),
        &step(Orient::Auto, None),
    )
    .expect("convert");
    let got = read_normals(&dir.path().join("plane"));
    assert!(
        got.iter()
            .all(|(_, _, n, _, s)| angle(n.expect("a normal"), [0.0, 0.0, 1.0]) < 0.1 && *s < 1e-3)
    );
    // Probe the inner part of the plane on a fine grid: each probe lies in some disc.
    let cell = 0.25;
    // Per grid cell: the discs (x, y, radius) whose centres lie in it.
    type Discs = Vec<(f64, f64, f64)>;
    let mut grid: HashMap<(i64, i64), Discs> = HashMap::new();
    for (_, p, _, r, _) in &got {
        let at = ((p[0] / cell) as i64, (p[1] / cell) as i64);
        grid.entry(at).or_default().push((p[0], p[1], *r));
    }
    let max_r = got.iter().map(|g| g.3).fold(0.0, f64::max);
    let reach = (max_r / cell).ceil() as i64 + 1;
    let (mut probes, mut covered) = (0, 0);
    for i in 0..200 {
        for j in 0..200 {
            let (x, y) = (2.0 + i as f64 * 0.08, 2.0 + j as f64 * 0.08);
            probes += 1;
            let (cx, cy) = ((x / cell) as i64, (y / cell) as i64);
            let hit = (cx - reach..=cx + reach).any(|gx| {
                (cy - reach..=cy + reach).any(|gy| {
                    grid.get(&(gx, gy)).is_some_and(|v| {
                        v.iter()
                            .any(|&(px, py, r)| (px - x).powi(2) + (py - y).powi(2) <= r * r)
                    })
                })
            });
            covered += hit as usize;
        }
    }
    let share = covered as f64 / probes as f64;
    assert!(share >= 0.98, "discs cover {share} of the plane");
    // Not much larger than needed: the mean radius is near the spacing.
    let spacing = side / (40_000f64).sqrt();
    let mean: f64 = got.iter().map(|g| g.3).sum::<f64>() / got.len() as f64;
    assert!(
        mean < 1.5 * spacing,
        "mean radius {mean} for spacing {spacing}"
    );
    // Along the plane's edges the neighbours lie on one side: the radius is the density's all
    // the same, where it was about 1.4 times the inner one, and the edge's discs reached past
    // the edge by about their radius.
    let median = |within: &dyn Fn(f64) -> bool| {
        let mut r: Vec<f64> = got
            .iter()
            .filter(|g| within(g.1[0].min(g.1[1]).min(side - g.1[0]).min(side - g.1[1])))
            .map(|g| g.3)
            .collect();
        r.sort_by(f64::total_cmp);
        r[r.len() / 2]
    };
    let (edge, inner) = (
        median(&|d| d < 0.5 * spacing),
        median(&|d| d > 3.0 * spacing),
    );
    assert!(
        edge < 1.2 * inner,
        "radius {edge} at the edge against {inner} inside"
    );
}

#[test]
fn input_normals_are_kept_unless_recomputed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("with.ply");
    let pts = sphere(5_000, [0.0; 3], 1.0, 4);
    // Deliberately not the surface's normals: kept ones must come back as given.
    let given: Vec<[f64; 3]> = pts.iter().map(|_| [0.6, 0.0, 0.8]).collect();
    write_ply(&ply, &pts, Some(&given));
    let keep = NormalStep::new(NormalOptions::default()).expect("options");
    convert_with(&options(&ply, dir.path().join("keep"), 1 << 30), &keep).expect("convert");
    let ds = LocalDataset::open(&dir.path().join("keep")).expect("open");
    let layout = ds.layout().clone();
    let normal = &layout.attributes[layout.index_of("normal").expect("normal")];
    assert_eq!((normal.ty, normal.count), (AttrType::F32, 3));
    let info = ds.metadata().normals.clone().expect("normals recorded");
    assert_eq!((info.kept, info.computed), (5_000, 0));

    let compute = NormalStep::new(NormalOptions {
        mode: NormalMode::Compute,
        viewpoint: Some([0.0; 3]),
        ..NormalOptions::default()
    })
    .expect("options");
    convert_with(
        &options(&ply, dir.path().join("compute"), 1 << 30),
        &compute,
    )
    .expect("convert");
    let ds = LocalDataset::open(&dir.path().join("compute")).expect("open");
    let info = ds.metadata().normals.clone().expect("normals recorded");
    assert_eq!((info.kept, info.computed), (0, 5_000));
    let layout = ds.layout().clone();
    let at = layout.index_of("normal").expect("normal");
    for node in ds.all_nodes().expect("nodes") {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node).expect("node");
        let col = cols.attribute(&layout, at);
        for i in 0..node.point_count as usize {
            let n = [0, 1, 2].map(|c| AttrType::F32.read_f64(&col[12 * i + 4 * c..]));
            let p = ds.metadata().to_real(cols.position(i));
            assert!(angle(n, p.map(|c| -c)) < 5.0, "{n:?} at {p:?}");
        }
    }
}

#[test]
fn orienting_towards_a_scanner_without_one_is_refused() {
    let step = step(Orient::Scanner, None);
    let err = step.attributes(&[]).expect_err("refused");
    assert!(err.to_string().contains("--viewpoint"), "{err}");
    assert!(
        NormalStep::new(NormalOptions {
            k: 1,
            ..NormalOptions::default()
        })
        .is_err()
    );
}

#[test]
fn radii_hold_where_neighbours_are_few_or_distances_tiny() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut next = unit_randoms(5u64);
    // Micrometre-sized: a plane of 4000 points 10 µm wide, with a cluster of 5 points (not in
    // a line) and a row of 4, and a lone point far from it; neighbours are searched within R.
    let (side, r) = (1e-5, 2e-6);
    let mut pts: Vec<[f64; 3]> = (0..4000)
        .map(|_| [next() * side, next() * side, 0.0])
        .collect();
    pts.extend((0..5).map(|i| {
        let t = f64::from(i);
        [5e-5 + 1e-8 * t, 5e-5 + 1e-9 * t * t, 0.0]
    }));
    pts.push([-5e-5, -5e-5, 0.0]);
    pts.extend((0..4).map(|i| [-5e-5, 5e-5 + 3e-8 * f64::from(i), 1e-6]));
    let ply = dir.path().join("tiny.ply");
    write_ply(&ply, &pts, None);
    let out = dir.path().join("tiny");
    let step = NormalStep::new(NormalOptions {
        radius: Some(r),
        ..NormalOptions::default()
    })
    .expect("options");
    convert_with(&options(&ply, out.clone(), 1 << 30), &step).expect("convert");
    let got = read_normals(&out);
    let radius_at = |p: [f64; 3]| {
        got.iter()
            .filter(|g| (0..3).all(|a| (g.1[a] - p[a]).abs() < 1e-9))
            .map(|g| g.3)
            .next()
            .expect("the point")
    };
    // f32 holds micrometre radii (f16 ends at 6e-5); the plane's are near its spacing.
    let spacing = side / 4000f64.sqrt();
    let inner = got.iter().filter(|g| {
        g.1[0] > 0.2 * side && g.1[0] < 0.8 * side && g.1[1] > 0.2 * side && g.1[1] < 0.8 * side
    });
    for g in inner {
        assert!(
            g.3 > 0.5 * spacing && g.3 < 2.0 * spacing,
            "radius {} for spacing {spacing}",
            g.3
        );
    }
    // Five found within R: the density they give, R √(ln 100 / 5), at the end of their row
    // (all on one side, the least share of the disc: a quarter, so half that).
    let five = radius_at(pts[4000]);
    let want = r * COVER / 5f64.sqrt() * super::coverage::LEAST.sqrt();
    assert!((five / want - 1.0).abs() < 1e-3, "{five} against {want}");
    // Alone: no surface to cover, and not a disc as wide as the search; the disc of the
    // density the search radius was made for.
    let lone = radius_at(pts[4005]);
    let want = r * COVER / (4.0 * SEARCH_FACTOR);
    assert!((lone / want - 1.0).abs() < 1e-3, "{lone} against {want}");
    // Four in a row touch: each as wide as the gap to its neighbour.
    let row = radius_at(pts[4007]);
    assert!((row / 3e-8 - 1.0).abs() < 1e-3, "{row} against 3e-8");
    // The row and the one alone fit no plane: no normal, and the most variation there is;
    // the others have theirs.
    for (_, p, n, _, s) in &got {
        if p[0] < 0.0 {
            assert!(
                n.is_none() && (s - 1.0 / 3.0).abs() < 1e-3,
                "{p:?} fits no plane"
            );
        } else {
            assert!(n.is_some(), "{p:?} has a normal");
        }
    }
    let info = normals_info(&out);
    assert_eq!(info.no_normal, 5);
}

#[test]
fn upward_normals_of_a_wall_never_face_down() {
    // A vertical wall: every normal is horizontal, where rounding the octahedral grid alone
    // decodes some a hair below the horizon.
    let dir = tempfile::tempdir().expect("tempdir");
    let mut next = unit_randoms(9u64);
    let pts: Vec<[f64; 3]> = (0..20_000)
        .map(|_| [3.0, next() * 10.0, next() * 10.0])
        .collect();
    let ply = dir.path().join("wall.ply");
    write_ply(&ply, &pts, None);
    let out = dir.path().join("wall");
    convert_with(
        &options(&ply, out.clone(), 1 << 30),
        &step(Orient::Up, None),
    )
    .expect("convert");
    let got = read_normals(&out);
    assert_eq!(got.len(), pts.len());
    for (_, p, n, _, _) in &got {
        let n = n.expect("a normal");
        assert!(n[2] >= 0.0, "{n:?} at {p:?} faces down");
        assert!(angle(n, [1.0, 0.0, 0.0]).min(angle(n, [-1.0, 0.0, 0.0])) < 0.1);
    }
}

#[test]
fn repeated_positions_count_once() {
    // Every point three times, one of them five thousand times more (more than a search of
    // a few thousand neighbours sees past): the same normals and radii as the cloud without
    // repeats.
    let dir = tempfile::tempdir().expect("tempdir");
    let base = sphere(4000, [0.0; 3], 1.0, 21);
    let mut repeated: Vec<[f64; 3]> = base.iter().flat_map(|&p| [p; 3]).collect();
    repeated.extend([base[7]; 5000]);
    let (mut normals, mut sizes) = (Vec::new(), Vec::new());
    for (name, pts) in [("once", &base), ("repeated", &repeated)] {
        let ply = dir.path().join(format!("{name}.ply"));
        write_ply(&ply, pts, None);
        let out = dir.path().join(name);
        convert_with(
            &options(&ply, out.clone(), 1 << 30),
            &step(Orient::None, None),
        )
        .expect("convert");
        let got = read_normals(&out);
        assert_eq!(got.len(), pts.len());
        let info = normals_info(&out);
        sizes.push((info.surfel_radius, info.triangles));
        let by_position: HashMap<[i32; 3], (Option<[f64; 3]>, f64)> =
            got.iter().map(|g| (g.0, (g.2, g.3))).collect();
        normals.push(by_position);
    }
    let (once, repeated) = (&normals[0], &normals[1]);
    assert_eq!(once.len(), repeated.len(), "the same positions");
    for (q, (n, r)) in once {
        let (m, s) = repeated[q];
        let (n, m) = (n.expect("a normal"), m.expect("a normal"));
        assert!(
            angle(n, m).min(angle(n, m.map(|c| -c))) < 1e-3,
            "{q:?}: {n:?} against {m:?}"
        );
        assert!((r / s - 1.0).abs() < 1e-6, "{q:?}: radius {r} against {s}");
    }
    // Paper 001's surfel size from triangles of distinct points (a cluster of one position
    // three times is no triangle), about the same (another sample of the sphere's triangles).
    let [(once, t1), (repeated, t2)] = [sizes[0], sizes[1]];
    assert!(t1 > 300 && t2 > 300, "triangles {t1} and {t2}");
    assert!(
        (repeated / once - 1.0).abs() < 0.1,
        "surfel size {repeated} against {once}"
    );
}

#[test]
fn scan_lines_far_apart_for_their_spacing_get_the_plane_they_lie_in() {
    // Twenty lines 0.1 apart on a tilted plane, a point every 2 mm along each (a mobile
    // scanner's profiles): the 16 nearest of a point lie on its own line. Beside them, far
    // off, one line alone (a wire), which fits no plane.
    let dir = tempfile::tempdir().expect("tempdir");
    let (along, across) = ([1.0, 0.0, 0.0], [0.0, 0.8, 0.6]);
    let truth = [0.0, -0.6, 0.8];
    let mut pts: Vec<[f64; 3]> = Vec::new();
    for line in 0..20 {
        for i in 0..500 {
            let (u, v) = (i as f64 * 0.002, line as f64 * 0.1);
            pts.push([0, 1, 2].map(|a| u * along[a] + v * across[a]));
        }
    }
    let wire: Vec<[f64; 3]> = (0..500).map(|i| [i as f64 * 0.002, 0.0, 5.0]).collect();
    pts.extend(&wire);
    let ply = dir.path().join("lines.ply");
    write_ply(&ply, &pts, None);
    let out = dir.path().join("lines");
    let step = NormalStep::new(NormalOptions {
        orient: Orient::Up,
        radius: Some(0.3),
        ..NormalOptions::default()
    })
    .expect("options");
    convert_with(&options(&ply, out.clone(), 1 << 30), &step).expect("convert");
    let got = read_normals(&out);
    assert_eq!(got.len(), pts.len());
    for (_, p, n, radius, variation) in &got {
        if p[2] > 4.0 {
            assert!(n.is_none(), "the wire at {p:?} has a normal {n:?}");
            continue;
        }
        let n = n.unwrap_or_else(|| panic!("no normal at {p:?}"));
        assert!(angle(n, truth) < 0.5, "{n:?} at {p:?}");
        assert!(*variation < 1e-3, "σ {variation} at {p:?}");
        // Discs that close the 0.1 between lines, not the density's 6 mm.
        assert!((0.05..0.06).contains(radius), "radius {radius} at {p:?}");
    }
    assert_eq!(normals_info(&out).no_normal, wire.len() as u64);
}
