//! `normals-bench --mesh`: the accuracy of the conversion's normals on a mesh of the user's own,
//! against the normals of the triangles its points are sampled from.

mod common;
use std::process::Command;

#[test]
fn normals_are_measured_on_a_users_mesh() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A closed octahedron: flat faces, so away from its edges a normal is exact.
    let mesh = dir.path().join("octa.ply");
    common::write_octahedron(&mesh);
    let csv = dir.path().join("normals.csv");
    let run = Command::new(env!("CARGO_BIN_EXE_normals-bench"))
        .args(["--points", "20000", "--only-meshes", "--mesh"])
        .arg(&mesh)
        .arg("--dir")
        .arg(dir.path().join("work"))
        .arg("--csv")
        .arg(&csv)
        .output()
        .expect("normals-bench runs");
    assert!(run.status.success(), "{run:?}");
    let table = std::fs::read_to_string(&csv).expect("csv");
    let exact = table
        .lines()
        .find(|l| l.starts_with("octa,0,"))
        .unwrap_or_else(|| panic!("no noiseless octa row:\n{table}"));
    let median: f64 = exact
        .split(',')
        .nth(2)
        .and_then(|m| m.parse().ok())
        .expect("median");
    assert!(median < 0.5, "{table}");
}
