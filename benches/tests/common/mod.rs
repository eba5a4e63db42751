//! What the benchmarks' tests share.

use std::path::Path;

/// A closed octahedron (vertices on the axes at distance 1) as an ASCII PLY mesh: flat faces,
/// so away from its edges a sampled point's normal is exact.
pub fn write_octahedron(path: &Path) {
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
    std::fs::write(path, text).expect("write the octahedron");
}
