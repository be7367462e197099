//! `rrskin.Model`: a runtime model, with the CPU reference evaluator (`deform`), the palette an
//! engine with its own skinning uploads (`palette`, `skin`), and its file and glTF forms.

use crate::arrays::{floats, owned};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rrskin::cpu::CpuEvaluator;
use rrskin::palette::Palette;
use rrskin::predict::Affine;
use std::path::PathBuf;

/// A trained runtime model: P proxy bones over J bones, skinning V vertices with K influences.
#[pyclass(module = "rrskin", frozen)]
pub struct Model {
    palette: Palette,
    /// What training reported (`rrskin train --json`'s object), for a model trained here.
    report: Option<serde_json::Value>,
}

impl Model {
    pub fn new(model: rrskin::Model, report: Option<serde_json::Value>) -> PyResult<Model> {
        let palette = Palette::new(model).map_err(crate::error)?;
        Ok(Model { palette, report })
    }

    pub fn model(&self) -> &rrskin::Model {
        self.palette.model()
    }

    /// `bones` as C characters' J runtime transforms (C = 1 for one pose of shape (J, 3, 4)),
    /// and whether it was a batch (C, J, 3, 4).
    fn poses(&self, bones: &Bound<'_, PyAny>) -> PyResult<(Vec<Affine>, Option<usize>)> {
        let b = floats(bones, "bones")?;
        let j = self.model().bone_count() as u64;
        let batch = match b.shape[..] {
            [jj, 3, 4] if jj == j => None,
            [c, jj, 3, 4] if jj == j => Some(c as usize),
            _ => {
                return Err(crate::error(format!(
                    "bones: shape {:?}, expected (J = {j}, 3, 4) or (C, J = {j}, 3, 4)",
                    b.shape
                )))
            }
        };
        b.check_finite().map_err(crate::error)?;
        let affines = (b.data.chunks_exact(12))
            .map(|t| std::array::from_fn(|i| t[i] as f32))
            .collect();
        Ok((affines, batch))
    }

    /// (C,) + `shape`, or `shape` alone for one pose.
    fn batched(batch: Option<usize>, shape: &[usize]) -> Vec<usize> {
        batch.into_iter().chain(shape.iter().copied()).collect()
    }
}

#[pymethods]
impl Model {
    /// The model in the file at `path` (`rrskin train -o`'s .rrs).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Model> {
        let model = rrskin::Model::load(&path)
            .map_err(|e| crate::error(format!("{}: {e}", path.display())))?;
        Model::new(model, None)
    }

    /// Writes the model to `path` (an .rrs file the runtime and `rrskin` read).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        (self.model().save(&path)).map_err(|e| crate::error(format!("{}: {e}", path.display())))
    }

    /// Its dimensions and predicted cost: `rrskin info --json`'s object.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::to_python(py, &rrskin_tools::run::info::to_json(self.model()))
    }

    /// What training reported (`rrskin train --json`'s object: the held-out error, the
    /// choices made, the cost, the learning curve where asked); None for a loaded model.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.report
            .as_ref()
            .map(|r| crate::to_python(py, r))
            .transpose()
    }

    /// The mesh in pose `bones`, by the CPU reference evaluator (what the GPU runtime is
    /// tested against): `bones` (J, 3, 4) gives (V, 3), a batch (C, J, 3, 4) gives (C, V, 3);
    /// float32. Each bone's [Q | d] is relative to the rest pose, as in `pose_transforms`.
    /// With `normals`, also the recomputed unit normals, alike: (positions, normals).
    #[pyo3(signature = (bones, normals=false))]
    fn deform<'py>(
        &self,
        py: Python<'py>,
        bones: &Bound<'py, PyAny>,
        normals: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (poses, batch) = self.poses(bones)?;
        let (v, j) = (self.model().vertex_count(), self.model().bone_count());
        let (positions, with_normals) = py
            .detach(|| -> rrskin::Result<(Vec<f32>, Vec<f32>)> {
                let mut evaluator = CpuEvaluator::new(self.model());
                let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
                let (mut all_pos, mut all_nrm) = (Vec::new(), Vec::new());
                for pose in poses.chunks_exact(j) {
                    evaluator.evaluate(pose, &mut pos, &mut nrm)?;
                    all_pos.extend(pos.iter().flatten());
                    all_nrm.extend(nrm.iter().flatten());
                }
                Ok((all_pos, all_nrm))
            })
            .map_err(crate::error)?;
        let shape = Model::batched(batch, &[v, 3]);
        let positions = owned(py, &shape, positions)?.into_any();
        match normals {
            false => Ok(positions),
            true => {
                let normals = owned(py, &shape, with_normals)?.into_any();
                Ok((positions, normals).into_pyobject(py)?.into_any())
            }
        }
    }

    /// The palette an engine skins with, for pose `bones` ((J, 3, 4), or a batch (C, J, 3, 4)):
    /// (P + J, 3, 4) float32 (or (C, P + J, 3, 4)), the proxies then the bones, each 3x4
    /// row-major; the skin's `indices` point into it.
    fn palette<'py>(
        &self,
        py: Python<'py>,
        bones: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let (poses, batch) = self.poses(bones)?;
        let entries = self.palette.len();
        let mut out = vec![[0.0f32; 12]; poses.len() / self.model().bone_count() * entries];
        py.detach(|| self.palette.compute_batch(&poses, &mut out))
            .map_err(crate::error)?;
        let shape = Model::batched(batch, &[entries, 3, 4]);
        owned(py, &shape, out.into_iter().flatten().collect())
    }

    /// What an engine skins with besides the palette: `influences` (K), `indices` (V, K)
    /// uint32 into the palette, `weights` (V, K), `rest_positions` and `rest_normals` (V, 3),
    /// `rest_tangents` (V, 4; empty without UVs), `triangles` (T, 3) uint32, and the pose-space
    /// correctives' `corrective_targets` (N, V, 3); float32.
    #[getter]
    fn skin<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.palette.skin();
        let (v, k) = (s.rest_positions.len(), s.influences);
        let flat3 = |xs: &[[f32; 3]]| xs.iter().flatten().copied().collect::<Vec<f32>>();
        let dict = PyDict::new(py);
        dict.set_item("influences", k)?;
        dict.set_item("indices", owned(py, &[v, k], s.indices.to_vec())?)?;
        dict.set_item("weights", owned(py, &[v, k], s.weights.to_vec())?)?;
        dict.set_item(
            "rest_positions",
            owned(py, &[v, 3], flat3(s.rest_positions))?,
        )?;
        dict.set_item("rest_normals", owned(py, &[v, 3], flat3(s.rest_normals))?)?;
        let tangents: Vec<f32> = s.rest_tangents.iter().flatten().copied().collect();
        dict.set_item(
            "rest_tangents",
            owned(py, &[s.rest_tangents.len(), 4], tangents)?,
        )?;
        let triangles: Vec<u32> = s.triangles.iter().flatten().copied().collect();
        dict.set_item("triangles", owned(py, &[s.triangles.len(), 3], triangles)?)?;
        let targets = owned(py, &[s.correctives, v, 3], flat3(s.corrective_targets))?;
        dict.set_item("corrective_targets", targets)?;
        Ok(dict)
    }

    /// Writes the model as a skinned glTF (.glb) at `path`: with `rig` (the glTF it was
    /// trained from) its mesh, materials, joint names and `clips` (default every clip) baked;
    /// without, the model's own mesh and a clip at `fps`. Each clip follows the model to within
    /// `tolerance` of the mesh's size. Returns `rrskin export --json`'s object (each clip's
    /// name, keys, samples and worst distances), with the export's `notes`.
    #[pyo3(signature = (path, rig=None, clips=None, fps=30.0, tolerance=rrskin_tools::export::TOLERANCE))]
    fn export_gltf<'py>(
        &self,
        py: Python<'py>,
        path: PathBuf,
        rig: Option<PathBuf>,
        clips: Option<Vec<String>>,
        fps: f64,
        tolerance: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let options = rrskin_tools::export::Options {
            output: path,
            rig,
            clips: clips.unwrap_or_default(),
            fps,
            tolerance,
        };
        let model = self.model().clone();
        let exported = py
            .detach(|| rrskin_tools::export::run(model, &options))
            .map_err(crate::error)?;
        let mut json = exported.to_json();
        json["notes"] = serde_json::json!(exported.notes);
        crate::to_python(py, &json)
    }

    fn __repr__(&self) -> String {
        let m = self.model();
        format!(
            "Model(V = {}, J = {}, P = {} proxies, K = {})",
            m.vertex_count(),
            m.bone_count(),
            m.proxy_count(),
            m.influences()
        )
    }
}
