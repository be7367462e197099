//! The Python package (python/) under pytest, against the extension module this build made
//! (`lib_rrskin.so`, staged as `rrskin/_rrskin.abi3.so` beside the package's Python files), in
//! two interpreters the suite installs (`.ci/install-deps`): Debian's Python with NumPy 2
//! (python/tests/venv) and Blender 4.5's `bpy` Python with NumPy 1.26
//! (tools/tests/blender45/venv). Each fails, never skips, when its Python is missing. In the
//! latter, the Blender add-on's Train and Preview run headless, and the exporter's `--poses
//! auto` trains through the package with no `rrskin` binary on PATH; in a Blender window
//! (Debian's 3.4 under Xvfb), Train runs on its thread as when clicked.

#[path = "../../tests/common/artifacts.rs"]
mod artifacts;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use std::ffi::OsString;
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

/// `python ARGS` with the package staged in `dir` on its path and no `rrskin` on PATH; its
/// stdout, the run having succeeded.
fn run(python: &Path, dir: &Path, args: &[OsString]) -> String {
    assert!(
        python.is_file(),
        "{} is missing: run .ci/install-deps",
        python.display()
    );
    let out = Command::new(python)
        .args(args)
        .env("PYTHONPATH", stage(dir))
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .env("PATH", "/usr/bin:/bin")
        .env("RRSKIN_BIN", env!("CARGO_BIN_EXE_rrskin"))
        .output()
        .expect("run Python");
    assert!(
        out.status.success(),
        "{} {args:?} failed ({}):\n{}\n{}",
        python.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// python/tests under pytest in `python`.
fn pytest(python: &Path, name: &str) {
    let dir = scratch::temp_dir(name);
    let mut args: Vec<OsString> = ["-m", "pytest", "-q", "-p", "no:cacheprovider"]
        .map(OsString::from)
        .into();
    args.push(repo().join("python/tests").into());
    run(python, &dir, &args);
}

fn blender_python() -> PathBuf {
    repo().join("tools/tests/blender45/venv/bin/python")
}

fn bundled_rig() -> PathBuf {
    repo().join("data/cesiumman_gltf/CesiumMan_examples.glb")
}

#[test]
fn the_package_passes_its_tests_in_debians_python() {
    pytest(
        &repo().join("python/tests/venv/bin/python"),
        "python-debian",
    );
}

#[test]
fn the_package_passes_its_tests_in_blenders_python() {
    pytest(&blender_python(), "python-blender");
}

/// The add-on's Train and Preview in Blender 4.5, headless, on the bundled rig (plain linear
/// blend skinning in Blender, so the model must follow it to float precision): the preview
/// mesh is the model's deformation in the armature's pose, frame by frame of the walk.
#[test]
fn blender_trains_and_previews_the_model_in_process() {
    let dir = scratch::temp_dir("python-preview");
    let set = dir.join("set");
    let script = repo().join("tools/tests/blender/train_preview.py");
    let args = [
        script,
        "--".into(),
        bundled_rig(),
        set,
        "30".into(),
        "Anim_0".into(),
    ];
    let stdout = run(&blender_python(), &dir, &args.map(OsString::from));
    let line = stdout
        .lines()
        .rfind(|l| l.starts_with('{'))
        .expect("the JSON line");
    let figures: serde_json::Value = serde_json::from_str(line).expect("JSON");
    let number = |key: &str| figures[key].as_f64().expect(key);
    assert_eq!(figures["frames"], 12, "{stdout}");
    assert!(number("to_model") < 1e-5, "{stdout}");
    assert!(number("to_rig") < 1e-3, "{stdout}");
    let summary = figures["summary"].as_str().expect("the summary");
    assert!(
        summary.contains("held-out EE") && summary.contains("SSD"),
        "{stdout}"
    );
}

/// Train as clicked in a Blender window (Debian's Blender 3.4 under Xvfb, its Python the
/// system's with the package staged): the operator trains on a thread while the window's event
/// loop runs, and reports when done.
#[test]
fn blenders_window_trains_on_a_thread() {
    let dir = scratch::temp_dir("python-window");
    let script = repo().join("tools/tests/blender/train_modal.py");
    // A Blender window that never quits would hold the suite: at most two minutes.
    let out = Command::new("timeout")
        .args([
            "120",
            "xvfb-run",
            "-a",
            "blender",
            "--factory-startup",
            "--python",
        ])
        .arg(&script)
        .arg("--")
        .arg(bundled_rig())
        .arg(dir.join("set"))
        .env("PYTHONPATH", stage(&dir))
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output()
        .expect("run xvfb-run blender (.ci/install-deps installs both)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let trained = stdout.lines().find(|l| l.starts_with("trained: rrskin: "));
    assert!(
        out.status.success() && trained.is_some_and(|l| l.contains("SSD")),
        "{}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("set/model.rrs").is_file());
}

/// `export_examples.py --poses auto` in Blender 4.5's Python with the package and no binary
/// anywhere on PATH: the rounds' learning curves come from the package.
#[test]
fn the_exporters_auto_poses_train_through_the_package() {
    let dir = scratch::temp_dir("python-auto");
    let set = dir.join("set");
    let exporter = repo().join("tools/blender/export_examples.py");
    let args: [PathBuf; 10] = [
        exporter,
        "--".into(),
        "--input".into(),
        bundled_rig(),
        "--out".into(),
        set,
        "--poses".into(),
        "auto".into(),
        "--budget".into(),
        "45".into(),
    ];
    let stdout = run(&blender_python(), &dir, &args.map(OsString::from));
    assert!(
        stdout.contains("round of 40 random poses: learning curve ") && stdout.contains(" at 30;"),
        "{stdout}"
    );
}
