//! Example sets read from the NumPy folder layout of data/README.md (and written back to it),
//! validated by [`ExampleSet::new`] and [`preflight::check`]. Errors name the file and
//! the index of what is wrong; oddities that do not stop training (degenerate triangles,
//! unreferenced vertices) are collected as warnings.

use crate::import::preflight;
use crate::set::{Affine, ExampleSet, InputError, Pose, SetFiles, SetParts};
use glam::{DMat3, DVec3};
use std::path::Path;

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError::new(file, message)
}

/// An NPY array read as f64 (from f4/f8) or i64 (from i4/i8), C order.
struct Array<T> {
    shape: Vec<u64>,
    data: Vec<T>,
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
fn read_array<T, Narrow, Wide>(path: &Path, kinds: &str) -> Result<Array<T>, InputError>
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
    Ok(Array { shape, data })
}

fn read_floats(path: &Path) -> Result<Array<f64>, InputError> {
    let array = read_array::<f64, f32, f64>(path, "a float32/float64")?;
    if let Some(i) = array.data.iter().position(|x| !x.is_finite()) {
        return Err(bad(
            path,
            format!(
                "element {i} ({}) is not finite",
                index_text(&array.shape, i)
            ),
        ));
    }
    Ok(array)
}

/// `rest_vertices.npy`: V > 0 points.
fn read_rest(path: &Path) -> Result<Vec<DVec3>, InputError> {
    let rest = read_floats(path)?;
    expect_shape(path, &rest.shape, &[None, Some(3)], "(V, 3)")?;
    if rest.shape[0] == 0 {
        return Err(bad(path, "no vertices"));
    }
    Ok(rest
        .data
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0], p[1], p[2]))
        .collect())
}

/// `faces.npy`: triangles of the `v` vertices.
fn read_faces(path: &Path, v: usize) -> Result<Vec<[usize; 3]>, InputError> {
    let faces = read_ints(path)?;
    expect_shape(path, &faces.shape, &[None, Some(3)], "(T, 3)")?;
    if let Some(i) = faces.data.iter().position(|&x| x < 0 || x >= v as i64) {
        return Err(bad(
            path,
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

/// `bone_parents.npy`: J > 0 parents (-1 for a root), without cycles.
fn read_parents(path: &Path) -> Result<Vec<Option<usize>>, InputError> {
    let parents = read_ints(path)?;
    expect_shape(path, &parents.shape, &[None], "(J,)")?;
    let j = parents.shape[0] as usize;
    if j == 0 {
        return Err(bad(path, "no bones"));
    }
    if let Some(b) = parents.data.iter().position(|&p| p < -1 || p >= j as i64) {
        return Err(bad(
            path,
            format!("bone {b} has parent {} outside -1..{j}", parents.data[b]),
        ));
    }
    let parents: Vec<Option<usize>> = parents
        .data
        .iter()
        .map(|&p| usize::try_from(p).ok())
        .collect();
    Ok(parents)
}

/// `pose_transforms.npy` (N > 0 poses of `j` bones) and `pose_vertices.npy` (N poses of `v`
/// vertices), their shapes checked.
fn read_pose_arrays(
    transforms_path: &Path,
    vertices_path: &Path,
    j: usize,
    v: usize,
) -> Result<(Array<f64>, Array<f64>), InputError> {
    let transforms = read_floats(transforms_path)?;
    expect_shape(
        transforms_path,
        &transforms.shape,
        &[None, Some(j as u64), Some(3), Some(4)],
        &format!("(N, J = {j}, 3, 4)"),
    )?;
    let n = transforms.shape[0] as usize;
    if n == 0 {
        return Err(bad(transforms_path, "no poses"));
    }
    let vertices = read_floats(vertices_path)?;
    expect_shape(
        vertices_path,
        &vertices.shape,
        &[Some(n as u64), Some(v as u64), Some(3)],
        &format!("(N = {n}, V = {v}, 3)"),
    )?;
    Ok((transforms, vertices))
}

/// `split.npy` if present (0 = train, 1 = test per pose; all train without it); some pose
/// must be a training pose.
fn read_split(path: &Path, n: usize) -> Result<Vec<bool>, InputError> {
    let is_test = if path.exists() {
        let split = read_ints(path)?;
        expect_shape(
            path,
            &split.shape,
            &[Some(n as u64)],
            &format!("(N = {n},)"),
        )?;
        if let Some(i) = split.data.iter().position(|&s| s != 0 && s != 1) {
            return Err(bad(
                path,
                format!(
                    "pose {i} has split {} (must be 0 = train or 1 = test)",
                    split.data[i]
                ),
            ));
        }
        split.data.iter().map(|&s| s == 1).collect()
    } else {
        vec![false; n]
    };
    Ok(is_test)
}

/// `bone_names.json` if present: `j` names.
fn read_bone_names(path: &Path, j: usize) -> Result<Option<Vec<String>>, InputError> {
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(path).map_err(|e| bad(path, e.to_string()))?;
    let names: Vec<String> = serde_json::from_str(&text)
        .map_err(|e| bad(path, format!("not a JSON list of strings: {e}")))?;
    if names.len() != j {
        return Err(bad(path, format!("{} names for {j} bones", names.len())));
    }
    Ok(Some(names))
}

/// The poses of the arrays of [`read_pose_arrays`].
fn poses(transforms: &Array<f64>, vertices: &Array<f64>, j: usize, v: usize) -> Vec<Pose> {
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

fn read_ints(path: &Path) -> Result<Array<i64>, InputError> {
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
        let rest = read_rest(&f("rest_vertices.npy"))?;
        let v = rest.len();
        let faces_path = f("faces.npy");
        let faces = read_faces(&faces_path, v)?;
        let parents = read_parents(&f("bone_parents.npy"))?;
        let j = parents.len();
        let transforms_path = f("pose_transforms.npy");
        let (transforms, vertices) =
            read_pose_arrays(&transforms_path, &f("pose_vertices.npy"), j, v)?;
        let n = transforms.shape[0] as usize;
        let is_test = read_split(&f("split.npy"), n)?;
        let bone_names = read_bone_names(&f("bone_names.json"), j)?;
        let weights_path = f("skin_weights.npy");
        let rig_weights = match weights_path.exists() {
            true => Some(read_rig_weights(&weights_path, v, j)?),
            false => None,
        };
        let poses = poses(&transforms, &vertices, j, v);
        let parts = SetParts {
            rest,
            faces,
            parents,
            poses,
            is_test,
            bone_names,
            rig_weights,
        };
        let files = SetFiles {
            mesh: faces_path,
            skeleton: f("bone_parents.npy"),
            transforms: transforms_path.clone(),
            split: f("split.npy"),
            weights: weights_path.clone(),
            pose_labels: None,
        };
        let mut set = ExampleSet::new(parts, &files)?;
        let fix = "pose_vertices.npy is not in the space, units, vertex order or poses of pose_transforms.npy and rest_vertices.npy (by the rig's weights in skin_weights.npy)";
        preflight::check(&mut set, &weights_path, fix, &transforms_path)?;
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

/// `skin_weights.npy`: (V, J), as each vertex's non-zero weights ([`ExampleSet::new`] checks
/// them).
fn read_rig_weights(path: &Path, v: usize, j: usize) -> Result<Vec<Vec<(usize, f64)>>, InputError> {
    let w = read_floats(path)?;
    expect_shape(
        path,
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
