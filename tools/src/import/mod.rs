//! Importers: files read into an example set's parts (`crate::set`), then checked against the
//! rig's own skin ([`preflight`]). [`load`] is the one entry: it reads any set `rrskin train`
//! reads, dispatching once on [`SetFormat`].

pub mod alembic;
pub mod align;
pub mod fbx_rig;
pub mod gltf;
pub mod gltf_rig;
pub mod mesh_sequence;
pub mod npy;
pub mod numpy_folder;
pub mod point_cache;
pub mod preflight;
pub mod rig;
pub mod tangents;
pub mod usd;
pub mod usd_rig;
pub mod vertex_map;
pub mod weld;

use crate::set::{ExampleSet, InputError};
use rig::Rig;
use std::path::{Path, PathBuf};

impl Rig {
    /// Loads the rig at `path` (glTF, FBX or USD, by [`SetFormat`]) and its animation `clip`.
    pub fn load(path: &Path, clip: &str) -> Result<Rig, InputError> {
        match SetFormat::of(path) {
            SetFormat::Fbx => fbx_rig::load(path, clip),
            SetFormat::Usd => usd_rig::load(path, clip),
            _ => gltf_rig::load(path, clip),
        }
    }
}

/// What an example set is read from, told by its path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetFormat {
    /// A folder of NumPy arrays (`crate::import::numpy_folder`).
    NumpyFolder,
    /// A glTF rig (`.glb`, `.gltf`) posed by a point cache.
    Gltf,
    /// An FBX rig posed by a point cache.
    Fbx,
    /// A USD rig (UsdSkel) posed by a point cache; as a cache, a USD stage with time-sampled
    /// mesh points.
    Usd,
}

impl SetFormat {
    /// The format of the set at `path`, by its extension (anything else: a NumPy folder).
    pub fn of(path: &Path) -> SetFormat {
        let ext = (path.extension().and_then(|e| e.to_str())).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("glb" | "gltf") => SetFormat::Gltf,
            Some("fbx") => SetFormat::Fbx,
            Some("usd" | "usda" | "usdc") => SetFormat::Usd,
            _ => SetFormat::NumpyFolder,
        }
    }

    /// A rig posed by a point cache, not a folder of examples.
    pub fn is_rig(self) -> bool {
        self != SetFormat::NumpyFolder
    }
}

/// How a rig is posed and split: its clip, its point cache, the clip's frame rate and the
/// frames held out. A NumPy folder takes none of them.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    pub clip: Option<String>,
    pub cache: Option<PathBuf>,
    /// Frames per second (glTF key time x fps = the DCC's frame number).
    pub fps: f64,
    /// Frames (inclusive, the DCC's numbers) held out as test poses.
    pub test_frames: Option<(f64, f64)>,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            clip: None,
            cache: None,
            fps: 24.0,
            test_frames: None,
        }
    }
}

/// A loaded set: its examples, and for a rig what maps them back to the file's vertices
/// (with what the import found and fixed: `Imported::notes`).
pub enum Loaded {
    Folder(ExampleSet),
    Rig(Box<gltf::Imported>),
}

impl Loaded {
    pub fn set(&self) -> &ExampleSet {
        match self {
            Loaded::Folder(set) => set,
            Loaded::Rig(imported) => &imported.set,
        }
    }
}

/// The example set at `path`, in any format [`SetFormat`] names, with `options` for a rig
/// (refused, naming `path`, for a NumPy folder; a rig needs a clip and a cache).
pub fn load(path: &Path, options: &ImportOptions) -> Result<Loaded, InputError> {
    let bad = |message: &str| InputError {
        file: path.to_path_buf(),
        message: message.into(),
    };
    if !SetFormat::of(path).is_rig() {
        if options.clip.is_some() || options.cache.is_some() || options.test_frames.is_some() {
            return Err(bad("a clip, a cache and test frames (--clip, --cache, --test-frames) apply to a rig (.glb/.gltf/.fbx/.usd)"));
        }
        return ExampleSet::load(path).map(Loaded::Folder);
    }
    let (Some(clip), Some(cache)) = (&options.clip, &options.cache) else {
        return Err(bad("a rig needs --clip NAME and --cache FILE.pc2|FILE.mdd|FILE.abc|FILE.usd|FOLDER (its animation, and its point cache: a file, or a folder of per-frame .obj or .ply meshes)"));
    };
    let rig_options = gltf::Options {
        clip: clip.clone(),
        cache: cache.clone(),
        fps: options.fps,
        test_frames: options.test_frames,
    };
    gltf::import(path, &rig_options).map(|i| Loaded::Rig(Box::new(i)))
}

/// `read()`, with a panic of the reader (a third-party parser's fault on a malformed file, as
/// ogawa-rs's allocation of a corrupt size) turned into the error that the `format` file is
/// malformed: bad input is refused, never a crash.
pub(crate) fn guarded<T>(
    format: &str,
    read: impl FnOnce() -> Result<T, String> + std::panic::UnwindSafe,
) -> Result<T, String> {
    std::panic::catch_unwind(read).unwrap_or_else(|panic| {
        let why = (panic.downcast_ref::<String>().cloned())
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        Err(format!(
            "a malformed {format} file (the reader failed: {why})"
        ))
    })
}
