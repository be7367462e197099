//! `rrskin.ExampleSet`: a rig's examples (poses and the meshes it made), from NumPy arrays or
//! any file `rrskin train` reads (`rrskin.load_set`).

use crate::arrays::{floats, ints, owned, strings};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use rrskin_tools::import::numpy_folder::Arrays;
use rrskin_tools::import::{ImportOptions, Loaded};
use std::path::PathBuf;

/// What the rig's motion check says when the poses' vertices do not follow its skin.
const FIX: &str = "pose_vertices is not in the space, units, vertex order or poses of pose_transforms and rest_vertices (by the rig's weights in skin_weights)";

/// A rig's examples: N poses of J bones and the V vertices the rig made of each, over a rest
/// mesh of T triangles, split into training and test poses.
#[pyclass(module = "rrskin", frozen)]
pub struct ExampleSet {
    /// The set, and for a rig file what maps its (welded) vertices back to the file's: the set
    /// is held once.
    loaded: Loaded,
}

impl ExampleSet {
    pub fn of(set: rrskin_tools::set::ExampleSet) -> ExampleSet {
        ExampleSet {
            loaded: Loaded::Folder(set),
        }
    }

    pub fn set(&self) -> &rrskin_tools::set::ExampleSet {
        self.loaded.set()
    }
}

#[pymethods]
impl ExampleSet {
    /// A set from arrays: `rest_vertices` (V, 3), `faces` (T, 3), `bone_parents` (J,) (-1 for
    /// a root), `pose_transforms` (N, J, 3, 4) (each bone's [Q | d] relative to the rest pose,
    /// rows), `pose_vertices` (N, V, 3); optionally `split` (N,) (0 train, 1 test; all train
    /// without it), `skin_weights` (V, J) (the rig's own, a baseline and a check that the
    /// poses' vertices follow the skeleton) and `bone_names` (J strings). Validated as a NumPy
    /// folder is: a bad array raises rrskin.Error naming the argument and the index at fault.
    #[new]
    #[pyo3(signature = (rest_vertices, faces, bone_parents, pose_transforms, pose_vertices, split=None, skin_weights=None, bone_names=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        rest_vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        bone_parents: &Bound<'_, PyAny>,
        pose_transforms: &Bound<'_, PyAny>,
        pose_vertices: &Bound<'_, PyAny>,
        split: Option<&Bound<'_, PyAny>>,
        skin_weights: Option<&Bound<'_, PyAny>>,
        bone_names: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<ExampleSet> {
        let arrays = Arrays {
            rest: floats(rest_vertices, "rest_vertices")?,
            faces: ints(faces, "faces")?,
            parents: ints(bone_parents, "bone_parents")?,
            transforms: floats(pose_transforms, "pose_transforms")?,
            vertices: floats(pose_vertices, "pose_vertices")?,
            split: split.map(|s| ints(s, "split")).transpose()?,
            weights: skin_weights
                .map(|w| floats(w, "skin_weights"))
                .transpose()?,
            bone_names: bone_names.map(|n| strings(n, "bone_names")).transpose()?,
        };
        let set = rrskin_tools::set::ExampleSet::from_arrays(&arrays, FIX).map_err(crate::error)?;
        Ok(ExampleSet::of(set))
    }

    /// V.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.set().vertex_count()
    }

    /// J.
    #[getter]
    fn bone_count(&self) -> usize {
        self.set().bone_count()
    }

    /// N.
    #[getter]
    fn pose_count(&self) -> usize {
        self.set().poses.len()
    }

    /// The training poses' indices.
    #[getter]
    fn train_poses(&self) -> Vec<usize> {
        self.set().train()
    }

    /// The test poses' indices (held out of training, for reporting).
    #[getter]
    fn test_poses(&self) -> Vec<usize> {
        self.set().test()
    }

    /// What does not stop training but may be wrong (degenerate triangles, unused bones, what
    /// an importer fixed).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.set().warnings.clone()
    }

    #[getter]
    fn bone_names(&self) -> Option<Vec<String>> {
        self.set().bone_names.clone()
    }

    /// (V, 3) float64.
    #[getter]
    fn rest_vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let data = self.set().rest.iter().flat_map(|p| p.to_array()).collect();
        owned(py, &[self.set().vertex_count(), 3], data)
    }

    /// (T, 3) int64.
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<i64>>> {
        let data = self
            .set()
            .faces
            .iter()
            .flatten()
            .map(|&a| a as i64)
            .collect();
        owned(py, &[self.set().faces.len(), 3], data)
    }

    /// (J,) int64, -1 for a root.
    #[getter]
    fn bone_parents<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<i64>>> {
        let data = (self.set().parents.iter())
            .map(|p| p.map_or(-1, |p| p as i64))
            .collect();
        owned(py, &[self.set().bone_count()], data)
    }

    /// (N, J, 3, 4) float64: each pose's bone transforms, rows of [Q | d].
    #[getter]
    fn pose_transforms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let data = (self.set().poses.iter())
            .flat_map(|p| p.bones.iter().flat_map(|b| b.to_rows()))
            .collect();
        let (n, j) = (self.set().poses.len(), self.set().bone_count());
        owned(py, &[n, j, 3, 4], data)
    }

    /// (N, V, 3) float64: the rig's vertices in each pose.
    #[getter]
    fn pose_vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let data = (self.set().poses.iter())
            .flat_map(|p| p.vertices.iter().flat_map(|v| v.to_array()))
            .collect();
        let (n, v) = (self.set().poses.len(), self.set().vertex_count());
        owned(py, &[n, v, 3], data)
    }

    /// (N,) int64: 0 for a training pose, 1 for a test pose.
    #[getter]
    fn split<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<i64>>> {
        let data = self.set().is_test.iter().map(|&t| i64::from(t)).collect();
        owned(py, &[self.set().poses.len()], data)
    }

    /// Writes the set as a NumPy folder at `path` (what `rrskin train PATH` reads).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.set().save(path).map_err(crate::error)
    }

    /// `model` (trained on this set) over the rig file's own vertices, in its order and count,
    /// as `rrskin train` writes it for `rrskin export --rig`; for a set made of arrays or a
    /// NumPy folder, the model itself.
    fn for_file(&self, model: &crate::model::Model) -> PyResult<crate::model::Model> {
        match &self.loaded {
            Loaded::Rig(imported) => {
                let expanded = imported.expand(model.model()).map_err(crate::error)?;
                crate::model::Model::new(expanded, None)
            }
            Loaded::Folder(_) => crate::model::Model::new(model.model().clone(), None),
        }
    }

    fn __repr__(&self) -> String {
        let s = self.set();
        format!(
            "ExampleSet(V = {}, T = {}, J = {}, {} training poses, {} test poses)",
            s.vertex_count(),
            s.faces.len(),
            s.bone_count(),
            s.train().len(),
            s.test().len()
        )
    }
}

/// The example set at `path`, in any format `rrskin train` reads: a NumPy folder, or a rig
/// (.glb, .gltf, .fbx, .usd/.usda/.usdc) with its `clip` and its point `cache` (.pc2, .mdd, .abc,
/// USD, or a folder of per-frame .obj/.ply meshes); `fps` the clip's frames a second (24 by default) and
/// `test_frames` an inclusive (first, last) range of frames held out. What the import found
/// and fixed is in the set's `warnings`.
#[pyfunction]
#[pyo3(signature = (path, clip=None, cache=None, fps=None, test_frames=None))]
pub fn load_set(
    py: Python<'_>,
    path: PathBuf,
    clip: Option<String>,
    cache: Option<PathBuf>,
    fps: Option<f64>,
    test_frames: Option<(f64, f64)>,
) -> PyResult<ExampleSet> {
    let options = ImportOptions {
        clip,
        cache,
        fps: fps.unwrap_or(ImportOptions::default().fps),
        test_frames,
    };
    let mut loaded = py
        .detach(|| rrskin_tools::import::load(&path, &options))
        .map_err(crate::error)?;
    if let Loaded::Rig(imported) = &mut loaded {
        let notes = imported.notes.iter();
        let notes = notes.map(|(file, line)| format!("{}: {line}", file.display()));
        let notes: Vec<String> = notes.collect();
        imported.set.warnings.extend(notes);
    }
    Ok(ExampleSet { loaded })
}
