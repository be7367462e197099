//! A test's scratch folder, shared by the runtime's tests and the tools' (included with
//! `#[path]`).
#![allow(dead_code)] // each test binary uses a different subset

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// A fresh empty folder under the system temp dir, `rrskin-NAME-XXXXXX`, removed when dropped,
/// after a failed assertion too. Set `RRSKIN_KEEP_TEMP` to keep it and read what the test wrote.
pub fn temp_dir(name: &str) -> TempDir {
    let dir = tempfile::Builder::new()
        .prefix(&format!("rrskin-{name}-"))
        .disable_cleanup(std::env::var_os("RRSKIN_KEEP_TEMP").is_some())
        .tempdir()
        .expect("a folder in the system temp dir");
    TempDir(dir)
}

/// A scratch folder that reads as its path.
pub struct TempDir(tempfile::TempDir);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<OsStr> for TempDir {
    fn as_ref(&self) -> &OsStr {
        self.0.path().as_os_str()
    }
}

/// A folder for what a test binary makes once and keeps in a `static` (statics are never
/// dropped, so a [`TempDir`] there would never be removed): `NAME` in cargo's
/// `target/tmp`, emptied when made, replaced by the next run.
pub fn fixture_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).expect("empty the fixture folder");
    }
    std::fs::create_dir_all(&dir).expect("a folder in cargo's target/tmp");
    dir
}
