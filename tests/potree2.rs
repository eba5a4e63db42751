//! `strata export DATASET -o DIR --format potree2` and `strata convert ... --format potree2`: a
//! Potree 2.0 dataset. Read back here as Potree's loader reads it (the hierarchy from the
//! root's chunk through every proxy, each node's records from octree.bin), it holds every point
//! of the Strata dataset exactly once, inside its node's box; and a real client, potree-core
//! with three.js in headless Chromium, loads all of it from `strata serve` and from nginx.

mod common;
#[path = "common/http.rs"]
mod http;
#[path = "potree2/info.rs"]
mod info;

use common::s;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A Potree 2.0 dataset as its loader sees it.
struct Potree2 {
    meta: Value,
    /// Per node name: points, byte offset and byte size in octree.bin.
    nodes: BTreeMap<String, (u32, u64, u64)>,
    octree: Vec<u8>,
}

fn read_potree2(dir: &Path) -> Potree2 {
    let meta: Value =
        serde_json::from_slice(&std::fs::read(dir.join("metadata.json")).expect("metadata"))
            .expect("metadata.json is JSON");
    let hierarchy = std::fs::read(dir.join("hierarchy.bin")).expect("hierarchy.bin");
    let octree = std::fs::read(dir.join("octree.bin")).expect("octree.bin");
    let first = meta["hierarchy"]["firstChunkSize"]
        .as_u64()
        .expect("firstChunkSize");
    let mut nodes = BTreeMap::new();
    let mut chunks = vec![("r".to_string(), 0u64, first)];
    while let Some((name, offset, size)) = chunks.pop() {
        let chunk = &hierarchy[offset as usize..(offset + size) as usize];
        let mut names = vec![name];
        for (i, e) in chunk.chunks_exact(22).enumerate() {
            let name = names[i].clone();
            let u64_at = |a: usize| u64::from_le_bytes(e[a..a + 8].try_into().expect("8 bytes"));
            let points = u32::from_le_bytes(e[2..6].try_into().expect("4 bytes"));
            if e[0] == 2 {
                chunks.push((name, u64_at(6), u64_at(14)));
                continue;
            }
            assert!(
                nodes
                    .insert(name.clone(), (points, u64_at(6), u64_at(14)))
                    .is_none(),
                "node {name} is listed twice"
            );
            for c in 0..8 {
                if e[1] & (1 << c) != 0 {
                    names.push(format!("{name}{c}"));
                }
            }
        }
        assert_eq!(
            names.len() * 22,
            chunk.len(),
            "a chunk's entries are its nodes"
        );
    }
    Potree2 {
        meta,
        nodes,
        octree,
    }
}

impl Potree2 {
    /// Bytes of one record: the attributes' sizes.
    fn record(&self) -> usize {
        self.meta["attributes"]
            .as_array()
            .expect("attributes")
            .iter()
            .map(|a| a["size"].as_u64().expect("size") as usize)
            .sum()
    }

    /// The box of node `name`: the bounding box halved per digit (4 x, 2 y, 1 z).
    fn node_box(&self, name: &str) -> ([f64; 3], [f64; 3]) {
        let corner = |w: &str| -> [f64; 3] {
            std::array::from_fn(|k| self.meta["boundingBox"][w][k].as_f64().expect("corner"))
        };
        let (mut min, mut max) = (corner("min"), corner("max"));
        for d in name.bytes().skip(1) {
            let i = d - b'0';
            for (k, bit) in [4u8, 2, 1].into_iter().enumerate() {
                let mid = (min[k] + max[k]) / 2.0;
                if i & bit != 0 {
                    min[k] = mid;
                } else {
                    max[k] = mid;
                }
            }
        }
        (min, max)
    }
}

fn converted_city(tag: &str, normals: bool) -> PathBuf {
    let dir = common::fresh_dir(tag);
    let las = dir.join("city.las");
    common::run_ok(&["synth", "--points", "60000", "-o", s(&las)]);
    let out = dir.join("city.strata");
    let mut args = vec!["convert", s(&las), "-o", s(&out), "--quiet"];
    if normals {
        args.push("--normals");
    }
    common::run_ok(&args);
    out
}

/// Every point of `dataset` is in exactly one node of `p`, inside the node's box, with the
/// bytes Strata's export rows give it.
fn assert_holds_the_dataset(p: &Potree2, dataset: &Path) {
    let ds = strata_format::LocalDataset::open(dataset).expect("dataset");
    let meta = ds.metadata();
    assert_eq!(p.meta["version"], "2.0");
    assert_eq!(p.meta["encoding"], "DEFAULT");
    assert_eq!(p.meta["points"].as_u64(), Some(meta.points));
    let record = p.record();
    let wide =
        strata_converter::export::widened(ds.layout(), strata_converter::export::Target::Potree2);
    assert_eq!(record, wide.layout.stride, "a record is an export row");
    assert_eq!(p.octree.len(), meta.points as usize * record);
    let (scale, offset) = (meta.scale, meta.offset);
    let mut got: Vec<&[u8]> = Vec::new();
    let mut covered = 0u64;
    for (name, &(points, at, size)) in &p.nodes {
        assert_eq!(size, points as u64 * record as u64, "node {name}");
        covered += size;
        let (min, max) = p.node_box(name);
        for rec in p.octree[at as usize..(at + size) as usize].chunks_exact(record) {
            for k in 0..3 {
                let int = i32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().expect("i32"));
                let real = offset[k] + scale[k] * int as f64;
                let slack = scale[k];
                assert!(
                    real >= min[k] - slack && real <= max[k] + slack,
                    "a point of {name} lies outside its box on axis {k}: {real} not in {}..{}",
                    min[k],
                    max[k]
                );
            }
            got.push(rec);
        }
    }
    assert_eq!(covered, p.octree.len() as u64, "nodes share or skip bytes");
    let mut want = Vec::new();
    for node in ds.all_nodes().expect("nodes") {
        if node.point_count > 0 {
            let rows = ds.read_node(&node).expect("node").to_rows(ds.layout());
            let mut out = Vec::new();
            wide.convert(&rows, &mut out, Path::new("p2"))
                .expect("the dataset's values fit Potree 2.0");
            want.extend(out.chunks_exact(record).map(<[u8]>::to_vec));
        }
    }
    let mut got: Vec<Vec<u8>> = got.into_iter().map(<[u8]>::to_vec).collect();
    got.sort_unstable();
    want.sort_unstable();
    assert!(got == want, "the Potree 2 points differ from the dataset's");
}

#[test]
fn the_export_holds_every_point_once_in_its_node_as_potree_reads_it() {
    let dataset = common::converted("potree2-fixture", "autzen_trim.laz", "autzen");
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("autzen");
    common::run_ok(&["export", s(&dataset), "-o", s(&out), "--format", "potree2"]);
    let p = read_potree2(&out);
    assert_holds_the_dataset(&p, &dataset);
    let names = common::attribute_names(&p.meta);
    for want in [
        "position",
        "intensity",
        "return number",
        "classification",
        "gps-time",
        "rgb",
    ] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }
    // The names reach the deepest level the metadata states.
    let depth = p.meta["hierarchy"]["depth"].as_u64().expect("depth");
    assert!(p.nodes.keys().map(String::len).max() == Some(depth as usize + 1));

    // An existing output is refused, and replaced with --overwrite.
    let o = common::run(&["export", s(&dataset), "-o", s(&out), "--format", "potree2"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists"));
    common::run_ok(&[
        "export",
        s(&dataset),
        "-o",
        s(&out),
        "--format",
        "potree2",
        "--overwrite",
    ]);
    assert!(!dir.path().join("autzen.part").exists());
}

#[test]
fn convert_to_potree2_in_one_step_equals_convert_then_export_and_keeps_normals() {
    let dataset = converted_city("potree2-normals", true);
    let dir = dataset.parent().expect("dir");
    let exported = dir.join("exported");
    common::run_ok(&[
        "export",
        s(&dataset),
        "-o",
        s(&exported),
        "--format",
        "potree2",
    ]);
    let p = read_potree2(&exported);
    assert_holds_the_dataset(&p, &dataset);
    let attrs = p.meta["attributes"].as_array().expect("attributes");
    // Attributes beyond LAS's go out under their own names (f16 widened to float).
    for extra in ["radius", "surface_variation"] {
        let a = attrs
            .iter()
            .find(|a| a["name"] == extra)
            .unwrap_or_else(|| panic!("{extra} missing"));
        assert_eq!(a["type"], "float");
    }
    for axis in ["NormalX", "NormalY", "NormalZ"] {
        let a = attrs
            .iter()
            .find(|a| a["name"] == axis)
            .unwrap_or_else(|| panic!("{axis}"));
        assert_eq!(a["type"], "float");
        assert!(a["min"][0].as_f64().expect("min") >= -1.0 - 1e-6);
        assert!(a["max"][0].as_f64().expect("max") <= 1.0 + 1e-6);
    }

    let direct = dir.join("direct");
    common::run_ok(&[
        "convert",
        s(&dir.join("city.las")),
        "-o",
        s(&direct),
        "--normals",
        "--format",
        "potree2",
        "--quiet",
    ]);
    for f in ["octree.bin", "hierarchy.bin"] {
        assert!(
            std::fs::read(direct.join(f)).expect("direct")
                == std::fs::read(exported.join(f)).expect("exported"),
            "{f} differs between convert --format potree2 and convert then export"
        );
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .expect("dir")
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .contains("strata-for-potree2")
        })
        .collect();
    assert!(
        leftovers.is_empty(),
        "the Strata dataset built on the way is left"
    );

    // Interrupted in its export, the dataset built on the way is whole: --resume exports it
    // (it refused, naming the hidden folder as an existing output).
    let city = dir.join("city.las");
    let source = dir.join(".resumed.strata-for-potree2");
    common::run_ok(&["convert", s(&city), "-o", s(&source), "--normals", "-q"]);
    let resumed = dir.join("resumed");
    common::run_ok(&[
        "convert",
        s(&city),
        "-o",
        s(&resumed),
        "--normals",
        "--format",
        "potree2",
        "--resume",
        "-q",
    ]);
    assert!(
        std::fs::read(resumed.join("octree.bin")).ok()
            == std::fs::read(direct.join("octree.bin")).ok()
    );
    assert!(!source.exists());
}

#[test]
fn strata_serve_serves_a_potree2_dataset_its_files_and_nothing_else() {
    let dataset = common::converted("potree2-fixture", "autzen_trim.laz", "autzen");
    let root = tempfile::tempdir().expect("tempdir");
    let out = root.path().join("autzen");
    common::run_ok(&["export", s(&dataset), "-o", s(&out), "--format", "potree2"]);
    std::fs::write(out.join("notes.txt"), "not a dataset file").expect("stray file");
    let server = common::servers::Server::start_in(root.path(), &["--quiet", "--cors", "*"]);
    let list = http::request(&server.addr, "GET", "/", &[]);
    let list: Value = serde_json::from_slice(&list.body).expect("listing JSON");
    assert_eq!(list[0]["name"], "autzen");
    assert_eq!(list[0]["version"], "potree 2.0");
    let points = strata_format::LocalDataset::open(&dataset)
        .expect("dataset")
        .metadata()
        .points;
    assert_eq!(list[0]["points"].as_u64(), Some(points));
    // Potree's loader asks for byte ranges, with a Content-Type header that needs a preflight.
    let r = http::request(
        &server.addr,
        "GET",
        "/autzen/hierarchy.bin",
        &[("Range", "bytes=0-21")],
    );
    assert_eq!((r.status, r.body.len()), (206, 22));
    let pre = http::request(
        &server.addr,
        "OPTIONS",
        "/autzen/octree.bin",
        &[
            ("Origin", "null"),
            ("Access-Control-Request-Headers", "content-type,range"),
        ],
    );
    let allowed = pre
        .header("access-control-allow-headers")
        .unwrap_or_default()
        .to_lowercase();
    assert!(
        allowed.contains("content-type") && allowed.contains("range"),
        "{allowed}"
    );
    assert_eq!(
        http::request(&server.addr, "GET", "/autzen/octree.bin", &[]).status,
        200
    );
    assert_eq!(
        http::request(&server.addr, "GET", "/autzen/notes.txt", &[]).status,
        404
    );
}

/// The npm client: potree-core, three, esbuild and puppeteer-core (which drives the system's
/// Chromium), installed once per target folder, and the page bundled. `None` where node, npm,
/// Chromium or the npm registry is missing, unless STRATA_REQUIRE_POTREE is set.
fn potree_client() -> Option<PathBuf> {
    let require = std::env::var_os("STRATA_REQUIRE_POTREE").is_some();
    let skip = |why: &str| {
        assert!(!require, "{why}, but STRATA_REQUIRE_POTREE is set");
        eprintln!("skipping: {why}");
        None
    };
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return skip("Chromium is not installed");
    }
    if Command::new("npm").arg("--version").output().is_err() {
        return skip("node and npm are not installed");
    }
    let client = Path::new(env!("CARGO_TARGET_TMPDIR")).join("potree2-client");
    std::fs::create_dir_all(&client).expect("client dir");
    if !client.join("node_modules/potree-core").exists() {
        let _ = std::fs::write(client.join("package.json"), "{\"private\": true}\n");
        let ok = Command::new("npm")
            .current_dir(&client)
            .args(["install", "--no-audit", "--no-fund", "--silent"])
            .args(["potree-core@2.0.15", "three@0.187.0", "esbuild@0.28.2"])
            .arg("puppeteer-core@24.43.1")
            .status()
            .is_ok_and(|st| st.success());
        if !ok {
            return skip("npm could not install potree-core, three, esbuild and puppeteer-core");
        }
    }
    let page = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/potree2");
    for f in ["page.js", "index.html", "driver.mjs"] {
        std::fs::copy(page.join(f), client.join(f)).expect("page file");
    }
    let bundled = Command::new("npx")
        .current_dir(&client)
        .args([
            "esbuild",
            "page.js",
            "--bundle",
            "--format=iife",
            "--outfile=bundle.js",
        ])
        .args(["--log-level=warning"])
        .status()
        .is_ok_and(|st| st.success());
    assert!(bundled, "esbuild could not bundle the page");
    Some(client)
}

/// Opens `page` in headless Chromium; returns what potree-core loaded and the screenshot.
fn load_in_chromium(client: &Path, page: &str, out: &Path) -> (Value, (u32, u32, Vec<u8>)) {
    std::fs::create_dir_all(out).expect("out");
    let o = Command::new("node")
        .current_dir(client)
        .args(["driver.mjs", page, s(out)])
        .output()
        .expect("node runs");
    assert!(
        o.status.success(),
        "the browser driver failed: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let result: Value =
        serde_json::from_slice(&std::fs::read(out.join("result.json")).expect("result"))
            .expect("result JSON");
    assert!(result.get("error").is_none(), "the page failed: {result}");
    (result, common::read_png(&out.join("screenshot.png")))
}

/// potree-core loaded every node and every point, and the screenshot shows them.
fn assert_loaded_everything(result: &Value, shot: &(u32, u32, Vec<u8>), p: &Potree2, via: &str) {
    assert_eq!(
        result["points"].as_u64(),
        p.meta["points"].as_u64(),
        "{via}: {result}"
    );
    let names: Vec<&str> = result["names"]
        .as_array()
        .expect("names")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    for (name, &(points, ..)) in &p.nodes {
        assert!(
            points == 0 || names.contains(&name.as_str()),
            "{via}: node {name} not loaded"
        );
    }
    let (w, h, rgba) = shot;
    let lit = rgba
        .chunks_exact(4)
        .filter(|px| px[..3].iter().any(|&c| c > 0))
        .count();
    let share = lit as f64 / (*w as f64 * *h as f64);
    assert!(
        share > 0.02,
        "{via}: the screenshot shows {:.2} % lit pixels",
        100.0 * share
    );
}

#[test]
fn potree_core_in_chromium_loads_every_point_from_strata_serve_and_nginx() {
    let Some(client) = potree_client() else {
        return;
    };
    let dataset = common::converted("potree2-fixture", "autzen_trim.laz", "autzen");
    let root = common::fresh_dir("potree2-root");
    let served = root.join("autzen");
    common::run_ok(&[
        "export",
        s(&dataset),
        "-o",
        s(&served),
        "--format",
        "potree2",
    ]);
    let p = read_potree2(&served);

    // From `strata serve`, cross-origin: the page is a local file.
    let server = common::servers::Server::start_in(&root, &["--quiet", "--cors", "*"]);
    let page = format!(
        "file://{}?base={}/",
        client.join("index.html").display(),
        server.url("autzen")
    );
    let (result, shot) = load_in_chromium(&client, &page, &root.join("shot-strata"));
    assert_loaded_everything(&result, &shot, &p, "strata serve");
    drop(server);

    // From nginx, the page and the dataset on one origin.
    let site = root.join("site");
    std::fs::create_dir_all(&site).expect("site");
    for f in ["index.html", "bundle.js"] {
        std::fs::copy(client.join(f), site.join(f)).expect("page");
    }
    let Some((_nginx, addr)) = common::servers::nginx(&root, &root.join("nginx")) else {
        return;
    };
    let page = format!("http://{addr}/site/index.html?base=http://{addr}/autzen/");
    let (result, shot) = load_in_chromium(&client, &page, &root.join("shot-nginx"));
    assert_loaded_everything(&result, &shot, &p, "nginx");
}
