//! Test support: writing example-set files (through the library's NPY writer) into temp dirs.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::Path;

pub mod limb;
#[path = "../../../tests/common/scratch.rs"]
mod scratch;
#[allow(unused_imports)] // each test binary uses a different subset
pub use scratch::temp_dir;

pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) {
    rrskin_tools::import::npy::write_f32(path, shape, data).expect("write .npy");
}

pub fn write_i32(path: &Path, shape: &[usize], data: &[i32]) {
    rrskin_tools::import::npy::write_i32(path, shape, data).expect("write .npy");
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

/// A tube along x from 0 to `length`: `rings` rings of `segments` vertices of `radius`, two
/// triangles a quad between rings (open ends). Vertex `r * segments + s` is ring r, segment s.
pub fn tube(
    rings: usize,
    segments: usize,
    length: f64,
    radius: f64,
) -> (Vec<glam::DVec3>, Vec<[usize; 3]>) {
    let mut rest = Vec::new();
    for r in 0..rings {
        let x = length * r as f64 / (rings - 1) as f64;
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            rest.push(glam::DVec3::new(x, radius * a.cos(), radius * a.sin()));
        }
    }
    let mut faces = Vec::new();
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            faces.push([a, b, b + segments]);
            faces.push([a, b + segments, a + segments]);
        }
    }
    (rest, faces)
}
