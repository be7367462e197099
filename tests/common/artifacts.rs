//! The suite's build artifacts (the static library, the examples, the Python extension module),
//! shared by the runtime's tests and the tools' (included with `#[path]`).

use std::path::{Path, PathBuf};
use std::process::Command;

/// Builds the workspace's libraries, binaries and examples (the static library `librrskin.a`,
/// the crowd sample) as `cargo test --workspace` builds them, and returns `target/<profile>`.
/// `cargo test` alone may not have built them (when one test runs), and a narrower build (`-p
/// rrskin --lib`) resolves features and shares build-script dependencies differently, so in a
/// fresh clone it rebuilt naga and rrskin for minutes. Under `cargo test --workspace` this one
/// is a no-op.
pub fn suite_artifacts() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps")
        .to_path_buf();
    let target_dir = profile_dir.parent().expect("target/<profile>");
    let release = profile_dir.file_name().is_some_and(|n| n == "release");
    let mut cargo = Command::new(env!("CARGO"));
    cargo
        .args(["build", "--workspace", "--lib", "--bins", "--examples"])
        .args(["--profile", if release { "release" } else { "test" }])
        .arg("--target-dir")
        .arg(target_dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    let out = cargo.output().expect("run cargo");
    assert!(
        out.status.success(),
        "cargo build of the suite's artifacts failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    profile_dir
}
