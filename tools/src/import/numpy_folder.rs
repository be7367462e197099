//! Example sets in the NumPy folder layout of data/README.md: read from a folder (and written
//! back to it), or from the same arrays in memory ([`Arrays`], the Python package's
//! `rrskin.ExampleSet`), validated by [`ExampleSet::new`] and [`preflight::check`] alike.
//! Errors name the file (or the caller's argument) and the index of what is wrong; oddities that
//! do not stop training (degenerate triangles, unreferenced vertices) are collected as warnings.

use crate::import::preflight;
use crate::set::{Affine, ExampleSet, InputError, Pose, SetFiles, SetParts};
use glam::{DMat3, DVec3};
use std::path::{Path, PathBuf};

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError::new(file, message)
}

/// An array of the layout, C order, named as its errors name it: its file, or the caller's
/// argument that held it.
#[derive(Debug, Clone, PartialEq)]
pub struct Named<T> {
    pub name: PathBuf,
    pub shape: Vec<u64>,
    pub data: Vec<T>,
}

/// A set's arrays, as the layout's files hold them, before validation:
/// `rest_vertices` (V, 3), `faces` (T, 3), `bone_parents` (J,) with -1 for a root,
/// `pose_transforms` (N, J, 3, 4) (each bone's `[Q | d]`, rows), `pose_vertices` (N, V, 3), and
/// optionally `split` (N,) (0 train, 1 test; all train without it), `skin_weights` (V, J) and
/// `bone_names` (J,).
#[derive(Debug, Clone, PartialEq)]
pub struct Arrays {
    pub rest: Named<f64>,
    pub faces: Named<i64>,
    pub parents: Named<i64>,
    pub transforms: Named<f64>,
    pub vertices: Named<f64>,
    pub split: Option<Named<i64>>,
    pub weights: Option<Named<f64>>,
    pub bone_names: Option<Named<String>>,
}

fn open(path: &Path) -> Result<npyz::NpyFile<std::io::Cursor<Vec<u8>>>, InputError> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, format!("cannot open: {e}")))?;
    crate::import::npy::check_shape(&bytes).map_err(|m| bad(path, m))?;
    let npy = npyz::NpyFile::new(std::io::Cursor::new(bytes))
        .map_err(|e| bad(path, format!("not a valid .npy file: {e}")))?;
    if npy.order() == npyz::Order::Fortran {
        return Err(bad(path, "Fortran-ordered array; save it in C order"));
    }
    Ok(npy)
}

/// Reads the array as `T`, from either of two stored dtypes (the narrow one first).
fn read_array<T, Narrow, Wide>(path: &Path, kinds: &str) -> Result<Named<T>, InputError>
where
    Narrow: npyz::Deserialize + Into<T>,
    Wide: npyz::Deserialize + Into<T>,
{
    let npy = open(path)?;
    let shape = npy.shape().to_vec();
    let read = |e: std::io::Error| bad(path, format!("truncated or unreadable data: {e}"));
    let data = match npy.try_data::<Narrow>() {
        Ok(r) => r
            .map(|x| x.map(Into::into))
            .collect::<Result<Vec<T>, _>>()
            .map_err(read)?,
        Err(npy) => match npy.try_data::<Wide>() {
            Ok(r) => r
                .map(|x| x.map(Into::into))
                .collect::<Result<Vec<T>, _>>()
                .map_err(read)?,
            Err(npy) => {
                return Err(bad(
                    path,
                    format!("dtype {} is not {kinds}", npy.dtype().descr()),
                ))
            }
        },
    };
    Ok(Named {
        name: path.to_path_buf(),
        shape,
        data,
    })
}

fn read_floats(path: &Path) -> Result<Named<f64>, InputError> {
    read_array::<f64, f32, f64>(path, "a float32/float64")
}

impl Named<f64> {
    /// The first element that is not a number, refused with its index.
    pub fn check_finite(&self) -> Result<(), InputError> {
        match self.data.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(bad(
                &self.name,
                format!("element {i} ({}) is not finite", index_text(&self.shape, i)),
            )),
            None => Ok(()),
        }
    }
}

/// `rest_vertices`: V > 0 points.
fn rest(rest: &Named<f64>) -> Result<Vec<DVec3>, InputError> {
    rest.check_finite()?;
    expect_shape(&rest.name, &rest.shape, &[None, Some(3)], "(V, 3)")?;
    if rest.shape[0] == 0 {
        return Err(bad(&rest.name, "no vertices"));
    }
    Ok(rest
        .data
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0], p[1], p[2]))
        .collect())
}

/// `faces`: triangles of the `v` vertices.
fn faces(faces: &Named<i64>, v: usize) -> Result<Vec<[usize; 3]>, InputError> {
    expect_shape(&faces.name, &faces.shape, &[None, Some(3)], "(T, 3)")?;
    if let Some(i) = faces.data.iter().position(|&x| x < 0 || x >= v as i64) {
        return Err(bad(
            &faces.name,
            format!(
                "face {} has vertex index {} outside 0..{v}",
                i / 3,
                faces.data[i]
            ),
        ));
    }
    Ok(faces
        .data
        .chunks_exact(3)
        .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
        .collect())
}

/// `bone_parents`: J > 0 parents (-1 for a root); [`ExampleSet::new`] refuses cycles.
fn parents(parents: &Named<i64>) -> Result<Vec<Option<usize>>, InputError> {
    expect_shape(&parents.name, &parents.shape, &[None], "(J,)")?;
    let j = parents.shape[0] as usize;
    if j == 0 {
        return Err(bad(&parents.name, "no bones"));
    }
    if let Some(b) = parents.data.iter().position(|&p| p < -1 || p >= j as i64) {
        return Err(bad(
            &parents.name,
            format!("bone {b} has parent {} outside -1..{j}", parents.data[b]),
        ));
    }
    Ok((parents.data.iter())
        .map(|&p| usize::try_from(p).ok())
        .collect())
}

/// `pose_transforms` (N > 0 poses of `j` bones) and `pose_vertices` (N poses of `v`
/// vertices): their shapes and numbers checked.
fn check_pose_arrays(
    transforms: &Named<f64>,
    vertices: &Named<f64>,
    j: usize,
    v: usize,
) -> Result<(), InputError> {
    transforms.check_finite()?;
    expect_shape(
        &transforms.name,
        &transforms.shape,
        &[None, Some(j as u64), Some(3), Some(4)],
        &format!("(N, J = {j}, 3, 4)"),
    )?;
    let n = transforms.shape[0] as usize;
    if n == 0 {
        return Err(bad(&transforms.name, "no poses"));
    }
    vertices.check_finite()?;
    expect_shape(
        &vertices.name,
        &vertices.shape,
        &[Some(n as u64), Some(v as u64), Some(3)],
        &format!("(N = {n}, V = {v}, 3)"),
    )
}

/// `split` if given (0 = train, 1 = test per pose; all train without it).
fn split(split: Option<&Named<i64>>, n: usize) -> Result<Vec<bool>, InputError> {
    let Some(split) = split else {
        return Ok(vec![false; n]);
    };
    expect_shape(
        &split.name,
        &split.shape,
        &[Some(n as u64)],
        &format!("(N = {n},)"),
    )?;
    if let Some(i) = split.data.iter().position(|&s| s != 0 && s != 1) {
        return Err(bad(
            &split.name,
            format!(
                "pose {i} has split {} (must be 0 = train or 1 = test)",
                split.data[i]
            ),
        ));
    }
    Ok(split.data.iter().map(|&s| s == 1).collect())
}

/// `bone_names.json` if present: a list of strings.
fn read_bone_names(path: &Path) -> Result<Option<Named<String>>, InputError> {
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(path).map_err(|e| bad(path, e.to_string()))?;
    let names: Vec<String> = serde_json::from_str(&text)
        .map_err(|e| bad(path, format!("not a JSON list of strings: {e}")))?;
    Ok(Some(Named {
        name: path.to_path_buf(),
        shape: vec![names.len() as u64],
        data: names,
    }))
}

/// `bone_names` if given: `j` names.
fn bone_names(names: Option<&Named<String>>, j: usize) -> Result<Option<Vec<String>>, InputError> {
    match names {
        Some(names) if names.data.len() != j => Err(bad(
            &names.name,
            format!("{} names for {j} bones", names.data.len()),
        )),
        names => Ok(names.map(|n| n.data.clone())),
    }
}

/// The poses of the arrays of [`check_pose_arrays`].
fn poses(transforms: &Named<f64>, vertices: &Named<f64>, j: usize, v: usize) -> Vec<Pose> {
    let n = transforms.shape[0] as usize;
    let mut poses = Vec::with_capacity(n);
    for i in 0..n {
        let mut bones = Vec::with_capacity(j);
        for b in 0..j {
            let t = &transforms.data[(i * j + b) * 12..(i * j + b + 1) * 12];
            let q = DMat3::from_cols(
                DVec3::new(t[0], t[4], t[8]),
                DVec3::new(t[1], t[5], t[9]),
                DVec3::new(t[2], t[6], t[10]),
            );
            bones.push(Affine {
                q,
                d: DVec3::new(t[3], t[7], t[11]),
            });
        }
        let y = &vertices.data[i * v * 3..(i + 1) * v * 3];
        poses.push(Pose {
            bones,
            vertices: y
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0], p[1], p[2]))
                .collect(),
        });
    }
    poses
}

fn read_ints(path: &Path) -> Result<Named<i64>, InputError> {
    read_array::<i64, i32, i64>(path, "an int32/int64")
}

/// "[i, j, k]" of flat index `flat` in an array of `shape`.
fn index_text(shape: &[u64], mut flat: usize) -> String {
    let mut idx = vec![0u64; shape.len()];
    for (d, &n) in shape.iter().enumerate().rev() {
        if n > 0 {
            idx[d] = flat as u64 % n;
            flat /= n as usize;
        }
    }
    format!("{idx:?}")
}

fn expect_shape(
    path: &Path,
    shape: &[u64],
    expected: &[Option<u64>],
    names: &str,
) -> Result<(), InputError> {
    let ok = shape.len() == expected.len()
        && shape
            .iter()
            .zip(expected)
            .all(|(s, e)| e.is_none_or(|e| e == *s));
    if !ok {
        return Err(bad(path, format!("shape {shape:?}, expected {names}")));
    }
    Ok(())
}

impl ExampleSet {
    /// Reads and validates a NumPy example-set folder: the rest mesh, the skeleton, the poses,
    /// the optional split, bone names and rig weights, then the mesh and the rig's skin.
    pub fn load(dir: impl AsRef<Path>) -> Result<ExampleSet, InputError> {
        let dir = dir.as_ref();
        if !dir.is_dir() {
            return Err(bad(dir, "not a folder (expected a NumPy example set)"));
        }
        let f = |name: &str| dir.join(name);
        let (split, weights) = (f("split.npy"), f("skin_weights.npy"));
        let arrays = Arrays {
            rest: read_floats(&f("rest_vertices.npy"))?,
            faces: read_ints(&f("faces.npy"))?,
            parents: read_ints(&f("bone_parents.npy"))?,
            transforms: read_floats(&f("pose_transforms.npy"))?,
            vertices: read_floats(&f("pose_vertices.npy"))?,
            split: split.exists().then(|| read_ints(&split)).transpose()?,
            weights: (weights.exists())
                .then(|| read_floats(&weights))
                .transpose()?,
            bone_names: read_bone_names(&f("bone_names.json"))?,
        };
        let fix = "pose_vertices.npy is not in the space, units, vertex order or poses of pose_transforms.npy and rest_vertices.npy (by the rig's weights in skin_weights.npy)";
        ExampleSet::from_arrays(&arrays, fix)
    }

    /// Validates a set's `arrays` ([`Arrays`] gives their shapes), then the mesh and, where
    /// `skin_weights` is given, the rig's skin, whose refusal says `fix`.
    pub fn from_arrays(arrays: &Arrays, fix: &str) -> Result<ExampleSet, InputError> {
        let a = arrays;
        let rest = rest(&a.rest)?;
        let v = rest.len();
        let faces = faces(&a.faces, v)?;
        let parents = parents(&a.parents)?;
        let j = parents.len();
        check_pose_arrays(&a.transforms, &a.vertices, j, v)?;
        let n = a.transforms.shape[0] as usize;
        let is_test = split(a.split.as_ref(), n)?;
        let bone_names = bone_names(a.bone_names.as_ref(), j)?;
        let rig_weights = a
            .weights
            .as_ref()
            .map(|w| rig_weights(w, v, j))
            .transpose()?;
        let parts = SetParts {
            rest,
            faces,
            parents,
            poses: poses(&a.transforms, &a.vertices, j, v),
            is_test,
            bone_names,
            rig_weights,
        };
        let name = |n: Option<&PathBuf>, default: &str| {
            n.cloned()
                .unwrap_or_else(|| a.rest.name.with_file_name(default))
        };
        let weights = name(a.weights.as_ref().map(|w| &w.name), "skin_weights.npy");
        let files = SetFiles {
            mesh: a.faces.name.clone(),
            skeleton: a.parents.name.clone(),
            transforms: a.transforms.name.clone(),
            split: name(a.split.as_ref().map(|s| &s.name), "split.npy"),
            weights: weights.clone(),
            pose_labels: None,
        };
        let mut set = ExampleSet::new(parts, &files)?;
        preflight::check(&mut set, &weights, fix, &a.transforms.name)?;
        Ok(set)
    }

    /// Writes the set in the NumPy folder layout (the inverse of [`ExampleSet::load`]).
    pub fn save(&self, dir: impl AsRef<Path>) -> Result<(), InputError> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| bad(dir, format!("cannot create: {e}")))?;
        let (v, j, n) = (self.vertex_count(), self.bone_count(), self.poses.len());
        let xyz = |ps: &mut dyn Iterator<Item = &DVec3>| -> Vec<f32> {
            ps.flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
                .collect()
        };
        let transforms: Vec<f32> = self
            .poses
            .iter()
            .flat_map(|p| p.bones.iter().flat_map(|b| b.to_runtime()))
            .collect();
        let vertices = xyz(&mut self.poses.iter().flat_map(|p| p.vertices.iter()));
        let faces: Vec<i32> = self.faces.iter().flatten().map(|&a| a as i32).collect();
        let parents: Vec<i32> = self
            .parents
            .iter()
            .map(|p| p.map_or(-1, |p| p as i32))
            .collect();
        let split: Vec<i32> = self.is_test.iter().map(|&t| i32::from(t)).collect();
        type Writer<'a> = Box<dyn Fn(&Path) -> std::io::Result<()> + 'a>;
        let files: [(&str, Writer); 6] = [
            (
                "rest_vertices.npy",
                Box::new(|p| {
                    crate::import::npy::write_f32(p, &[v, 3], &xyz(&mut self.rest.iter()))
                }),
            ),
            (
                "faces.npy",
                Box::new(|p| crate::import::npy::write_i32(p, &[self.faces.len(), 3], &faces)),
            ),
            (
                "bone_parents.npy",
                Box::new(|p| crate::import::npy::write_i32(p, &[j], &parents)),
            ),
            (
                "pose_transforms.npy",
                Box::new(|p| crate::import::npy::write_f32(p, &[n, j, 3, 4], &transforms)),
            ),
            (
                "pose_vertices.npy",
                Box::new(|p| crate::import::npy::write_f32(p, &[n, v, 3], &vertices)),
            ),
            (
                "split.npy",
                Box::new(|p| crate::import::npy::write_i32(p, &[n], &split)),
            ),
        ];
        for (name, write) in files {
            let path = dir.join(name);
            write(&path).map_err(|e| bad(&path, format!("cannot write: {e}")))?;
        }
        if let Some(weights) = &self.rig_weights {
            let mut dense = vec![0.0f32; v * j];
            for (a, inf) in weights.iter().enumerate() {
                for &(b, w) in inf {
                    dense[a * j + b] = w as f32;
                }
            }
            let path = dir.join("skin_weights.npy");
            crate::import::npy::write_f32(&path, &[v, j], &dense)
                .map_err(|e| bad(&path, format!("cannot write: {e}")))?;
        }
        if let Some(names) = &self.bone_names {
            let path = dir.join("bone_names.json");
            let text = serde_json::to_string(names).map_err(|e| bad(&path, e.to_string()))?;
            std::fs::write(&path, text).map_err(|e| bad(&path, format!("cannot write: {e}")))?;
        }
        Ok(())
    }
}

/// `skin_weights`: (V, J), as each vertex's non-zero weights ([`ExampleSet::new`] checks
/// them).
fn rig_weights(w: &Named<f64>, v: usize, j: usize) -> Result<Vec<Vec<(usize, f64)>>, InputError> {
    w.check_finite()?;
    expect_shape(
        &w.name,
        &w.shape,
        &[Some(v as u64), Some(j as u64)],
        &format!("(V = {v}, J = {j})"),
    )?;
    Ok(w.data
        .chunks_exact(j)
        .map(|row| {
            (row.iter().enumerate())
                .filter(|(_, &x)| x != 0.0)
                .map(|(b, &x)| (b, x))
                .collect()
        })
        .collect())
}
