//! Test support: writing example-set files (through the library's NPY writer) into temp dirs.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::Path;

pub mod limb;

pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) {
    rrskin_tools::import::npy::write_f32(path, shape, data).expect("write .npy");
}

pub fn write_i32(path: &Path, shape: &[usize], data: &[i32]) {
    rrskin_tools::import::npy::write_i32(path, shape, data).expect("write .npy");
}

/// A fresh empty folder under the system temp dir.
pub fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("rrskin-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// A file of the repository's `data/`.
pub fn data(path: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(path)
}

/// Importing the bundled CesiumMan rig (`data/cesiumman_gltf`) with `cache`: its clip
/// `examples` at 24 fps, frames 41–60 held out.
pub fn cesiumman_options(cache: &Path) -> rrskin_tools::import::gltf::Options {
    rrskin_tools::import::gltf::Options {
        clip: "examples".into(),
        cache: cache.to_path_buf(),
        fps: 24.0,
        test_frames: Some((41.0, 60.0)),
    }
}
