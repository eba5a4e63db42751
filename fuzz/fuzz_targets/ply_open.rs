//! PLY header parsing and vertex body decoding (ASCII and binary), then decoding of every point: any
//! bytes must give points or an error, never a panic, an abort or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use strata_converter::input::ply::PlySource;
use strata_converter::input::PointSource;

fuzz_target!(|data: &[u8]| {
    let Ok(dir) = tempdir() else { return };
    let path = dir.join("f.ply");
    if std::fs::write(&path, data).is_err() {
        return;
    }
    if let Ok(mut src) = PlySource::open(&path) {
        let (mut xyz, mut rows) = (Vec::new(), Vec::new());
        while let Ok(n) = src.read(4096, &mut xyz, &mut rows) {
            if n == 0 {
                break;
            }
            xyz.clear();
            rows.clear();
        }
    }
});

/// One directory per fuzzing process, in memory where the machine has /dev/shm.
fn tempdir() -> std::io::Result<std::path::PathBuf> {
    let base = if std::path::Path::new("/dev/shm").is_dir() {
        std::path::PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let dir = base.join(format!("strata-fuzz-ply-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}
