use std::path::PathBuf;
use std::process::ExitCode;
use strata_converter::sys::format_bytes;
use strata_format::LocalDataset;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset directory (Strata, or Potree 2.0; or its metadata.json), or a LAS/LAZ file
    /// (a COPC file says so, with its octree), or a PLY or E57 file (its points, attributes and
    /// scanners, as `convert` reads them).
    dataset: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(mut a: Args) -> anyhow::Result<ExitCode> {
    // A dataset's metadata.json, given for its folder (as Potree users name a dataset).
    if a.dataset.is_file()
        && a.dataset.file_name().is_some_and(|n| n == "metadata.json")
        && let Some(dir) = a.dataset.parent()
    {
        a.dataset = if dir.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            dir.to_path_buf()
        };
    }
    if a.dataset.is_file() {
        return point_file(&a);
    }
    if let Some(potree) = super::info_potree2::metadata(&a.dataset) {
        return super::info_potree2::describe(&a.dataset, &potree, a.json);
    }
    let ds = LocalDataset::open(&a.dataset)?;
    let m = ds.metadata();
    let bytes = m.files.hierarchy.size + m.files.octree.size;
    if a.json {
        let attrs: Vec<serde_json::Value> = m
            .attributes
            .iter()
            .map(|at| {
                let mut v =
                    serde_json::json!({"name": at.name, "type": at.ty.name(), "count": at.count});
                if let Some(e) = &at.encoding {
                    v["encoding"] = e.as_str().into();
                }
                if let Some(t) = at.time_base {
                    v["time_base"] = serde_json::to_value(t).unwrap_or_default();
                }
                v
            })
            .collect();
        let v = serde_json::json!({
            "points": m.points,
            "nodes": m.nodes,
            "depth": m.depth,
            "bounds": {"min": m.bounds.min, "max": m.bounds.max},
            "scale": m.scale,
            "offset": m.offset,
            "spacing": m.spacing,
            "sampling": m.sampling,
            "attributes": attrs,
            "bytes": bytes,
            "point_bytes": m.point_bytes(),
            "version": format!("{}.{}", m.version[0], m.version[1]),
            "id": m.id,
            "sources": m.sources,
            "classes": m.classes,
            "scanners": m.scanners,
            "normals": m.normals,
            "crs": m.crs,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("dataset   {}", a.dataset.display());
    println!("format    {} {}.{}", m.format, m.version[0], m.version[1]);
    match m.id {
        Some(id) => println!("id        {id}"),
        None => println!("id        none (format 1.0 has no dataset id)"),
    }
    println!("points    {}", m.points);
    println!("nodes     {} (depth {})", m.nodes, m.depth);
    // To the decimals of the stored coordinates (a scan in degrees showed 11.000 48.001).
    let d = strata_format::step_decimals(strata_format::finest_step(m.scale));
    println!(
        "bounds    min {:.d$} {:.d$} {:.d$}\n          max {:.d$} {:.d$} {:.d$}",
        m.bounds.min[0],
        m.bounds.min[1],
        m.bounds.min[2],
        m.bounds.max[0],
        m.bounds.max[1],
        m.bounds.max[2]
    );
    println!("scale     {:?}\noffset    {:?}", m.scale, m.offset);
    println!(
        "spacing   {:.6} at the root ({} sampling)",
        m.spacing, m.sampling
    );
    println!(
        "size      {} in hierarchy.bin and octree.bin ({:.1} bytes/point stored, {} uncompressed)",
        format_bytes(bytes),
        bytes as f64 / m.points.max(1) as f64,
        m.point_bytes()
    );
    println!("attributes:");
    for at in &m.attributes {
        let mut shape = if at.count > 1 {
            format!("{} x {}", at.count, at.ty.name())
        } else {
            at.ty.name().to_string()
        };
        if let Some(e) = &at.encoding {
            shape.push_str(&format!(" ({e})"));
        }
        if let Some(t) = at.time_base {
            shape.push_str(&format!(" ({})", t.name()));
        }
        println!("  {:<30} {shape}", at.name);
    }
    if let Some(crs) = &m.crs {
        println!("crs       {}", crs_stated(crs));
    }
    if !m.scanners.is_empty() {
        println!(
            "scanners ({}, indexed by the `scanner` attribute):",
            m.scanners.len()
        );
        for (i, sc) in m.scanners.iter().enumerate() {
            let [x, y, z] = sc.position;
            println!("  {i:>3} {x:.3} {y:.3} {z:.3}  {}", sc.source);
        }
    }
    if let Some(n) = &m.normals {
        println!(
            "normals   k {}, oriented {}: {} computed, {} kept, {} with fewer than k neighbours in reach, {} without a normal",
            n.k, n.orient, n.computed, n.kept, n.partial, n.no_normal
        );
        println!(
            "          mean radius {:.6}, surfel radius {:.6} ({} triangles)",
            n.mean_radius, n.surfel_radius, n.triangles
        );
        if n.search_radius >= 1e-3 {
            println!("          search radius {:.6}", n.search_radius);
        } else if n.search_radius > 0.0 {
            // Finer than a millimetre in metres: six decimals would say 0.
            println!("          search radius {:.6e}", n.search_radius);
        } else {
            println!("          search radius: none (the inputs gave no density to bound it)");
        }
    }
    if !m.classes.is_empty() {
        println!("classes:");
        // By number: the map's keys are text (JSON object keys), in which 10 sorts before 2.
        let mut classes: Vec<(&String, &u64)> = m.classes.iter().collect();
        classes.sort_by_key(|(code, _)| (code.parse::<u64>().unwrap_or(u64::MAX), code.as_str()));
        for (code, n) in classes {
            let name = code
                .parse::<u8>()
                .map_or("", strata_viewer::pick::asprs_class_name);
            println!("  {code:>3} {name:<28} {n}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// What a CRS states: the WKT's name, and whether GeoTIFF keys are there.
pub fn crs_stated(crs: &strata_format::Crs) -> String {
    let mut stated = Vec::new();
    if let Some(wkt) = &crs.wkt {
        // The WKT's name: what its first quoted word says.
        let name = wkt.split('"').nth(1).unwrap_or("");
        stated.push(format!("WKT {name:?}"));
    }
    if let Some(g) = &crs.geotiff {
        stated.push(format!("GeoTIFF keys ({} values)", g.keys.len()));
    }
    stated.join(", ")
}

/// A LAS or LAZ file: its header, and for a COPC file its octree and hierarchy. A PLY or E57
/// file: what `convert` reads of it (`info_input`).
fn point_file(a: &Args) -> anyhow::Result<ExitCode> {
    let path = &a.dataset;
    if super::info_input::is_read_as_input(path) {
        return super::info_input::input_file(path, a.json);
    }
    let f = strata_converter::copc_describe::describe(path)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&f)?);
        return Ok(ExitCode::SUCCESS);
    }
    let kind = match f.kind {
        "copc" => "COPC 1.0 (LAZ with an octree: one chunk per node)",
        "laz" => "LAZ",
        _ => "LAS",
    };
    println!("file      {}", path.display());
    println!(
        "kind      {kind}, LAS {}, point format {}",
        f.version, f.point_format
    );
    println!("points    {}", f.points);
    let d = strata_format::step_decimals(strata_format::finest_step(f.scale));
    println!(
        "bounds    min {:.d$} {:.d$} {:.d$}",
        f.min[0], f.min[1], f.min[2]
    );
    println!(
        "          max {:.d$} {:.d$} {:.d$}",
        f.max[0], f.max[1], f.max[2]
    );
    println!("scale     {:?}", f.scale);
    println!("offset    {:?}", f.offset);
    if let Some(c) = &f.copc {
        println!(
            "octree    centre {:.d$} {:.d$} {:.d$}, half size {:.d$}, spacing {}",
            c.centre[0],
            c.centre[1],
            c.centre[2],
            c.halfsize,
            strata_format::number(c.spacing)
        );
        println!(
            "hierarchy {} nodes with {} points, depth {}",
            c.nodes, c.points, c.depth
        );
        println!(
            "          `strata convert {}` makes a dataset of it",
            path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
