//! Outputs: checked before long work starts, and shown as a user would type them.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// Creates `dir` if needed and checks that a file can be written in it, so that an unwritable
/// `--out` or `-o` fails at once instead of after minutes of training.
pub fn check_writable(dir: &Path) -> Result<()> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let fail = |problem: String| Error::Output {
        path: dir.to_path_buf(),
        problem,
    };
    if dir.exists() && !dir.is_dir() {
        return Err(fail("not a folder".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| fail(format!("cannot create the folder: {e}")))?;
    let probe = dir.join(format!(".rrskin-write-check-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| fail(format!("cannot write here: {e}")))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// `path` without `..` detours, relative to the working folder when inside it
/// (`data/cesiumman`, not `tools/../data/cesiumman`).
pub fn shown(path: &Path) -> String {
    let absolute = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let relative = std::env::current_dir()
        .and_then(std::fs::canonicalize)
        .ok()
        .and_then(|cwd| absolute.strip_prefix(cwd).ok().map(PathBuf::from));
    match relative {
        Some(r) if !r.as_os_str().is_empty() => r.display().to_string(),
        _ => absolute.display().to_string(),
    }
}
