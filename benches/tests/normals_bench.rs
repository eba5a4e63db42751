//! `normals-bench --mesh`: the accuracy of the conversion's normals on a mesh of the user's own,
//! against the normals of the triangles its points are sampled from.

use std::process::Command;

#[test]
fn normals_are_measured_on_a_users_mesh() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A closed octahedron: flat faces, so away from its edges a normal is exact.
    let v = [
        [1, 0, 0],
        [-1, 0, 0],
        [0, 1, 0],
        [0, -1, 0],
        [0, 0, 1],
        [0, 0, -1],
    ];
    let faces = [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\nelement face 8\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for p in v {
        text += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for f in faces {
        text += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    let mesh = dir.path().join("octa.ply");
    std::fs::write(&mesh, text).expect("write mesh");
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
