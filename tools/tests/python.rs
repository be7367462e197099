//! The Python package (python/) under pytest, against the extension module this build made
//! (`lib_rrskin.so`, staged as `rrskin/_rrskin.abi3.so` beside the package's Python files), in
//! two interpreters the suite installs (`.ci/install-deps`): Debian's Python with NumPy 2
//! (python/tests/venv) and Blender 4.5's `bpy` Python with NumPy 1.26
//! (tools/tests/blender45/venv). Each fails, never skips, when its Python is missing.

#[path = "../../tests/common/artifacts.rs"]
mod artifacts;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The package as `pip install ./python` lays it out, in `dir`: its Python files and this
/// build's extension module.
fn stage(dir: &Path) -> PathBuf {
    let package = dir.join("rrskin");
    std::fs::create_dir_all(&package).expect("a package folder");
    for file in ["__init__.py", "_rrskin.pyi", "py.typed"] {
        let from = repo().join("python/rrskin").join(file);
        std::fs::copy(&from, package.join(file)).expect("a file of python/rrskin");
    }
    let module = artifacts::suite_artifacts().join("lib_rrskin.so");
    assert!(module.exists(), "{} was not built", module.display());
    std::fs::copy(&module, package.join("_rrskin.abi3.so")).expect("the extension module");
    dir.to_path_buf()
}

/// python/tests under pytest in `python`, which must exist.
fn pytest(python: &Path, name: &str) {
    assert!(
        python.is_file(),
        "{} is missing: run .ci/install-deps",
        python.display()
    );
    let dir = scratch::temp_dir(name);
    let path = stage(&dir);
    let out = Command::new(python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(repo().join("python/tests"))
        .env("PYTHONPATH", &path)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .env("RRSKIN_BIN", env!("CARGO_BIN_EXE_rrskin"))
        .output()
        .expect("run pytest");
    assert!(
        out.status.success(),
        "pytest in {} failed ({}):\n{}\n{}",
        python.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_package_passes_its_tests_in_debians_python() {
    pytest(&repo().join("python/tests/venv/bin/python"), "python-debian");
}

#[test]
fn the_package_passes_its_tests_in_blenders_python() {
    pytest(
        &repo().join("tools/tests/blender45/venv/bin/python"),
        "python-blender",
    );
}
