//! Example sets: N pairs (skeleton pose q_i, deformed mesh y_i) from a black-box rig, the bottom
//! layer that import, train, eval and export share. A set is made by [`ExampleSet::new`] from
//! its [`SetParts`], which validates once what every importer needs (as `rrskin::Model::new`
//! does for a model): importers only read files into parts.
//!
//! Letters: V vertices, T triangles, J bones, N poses; i indexes poses, a vertices, b bones.

pub mod active_bones;
pub mod affine;

pub use affine::{rotation_error, Affine, ROTATION_TOLERANCE};

use glam::DVec3;
use std::fmt;
use std::path::{Path, PathBuf};

/// Tolerance on the sum of a vertex's rig weights.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-3;

/// One example: bone transforms (J) and the rig's vertex positions (V).
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    pub bones: Vec<Affine>,
    pub vertices: Vec<DVec3>,
}

/// What an importer reads, before validation.
#[derive(Debug, Clone, PartialEq)]
pub struct SetParts {
    /// V rest positions ŷ.
    pub rest: Vec<DVec3>,
    /// T triangles.
    pub faces: Vec<[usize; 3]>,
    /// J parents (None for roots).
    pub parents: Vec<Option<usize>>,
    /// N examples.
    pub poses: Vec<Pose>,
    /// N flags: true for a held-out test pose.
    pub is_test: Vec<bool>,
    pub bone_names: Option<Vec<String>>,
    /// The rig's own skinning weights, if known: per vertex (bone, weight).
    pub rig_weights: Option<Vec<Vec<(usize, f64)>>>,
}

/// The files the parts came from, so that an error names the one to fix.
#[derive(Debug, Clone, PartialEq)]
pub struct SetFiles {
    /// The rest mesh and its triangles.
    pub mesh: PathBuf,
    /// The skeleton (parents).
    pub skeleton: PathBuf,
    /// The poses' bone transforms.
    pub transforms: PathBuf,
    /// The split into training and test poses.
    pub split: PathBuf,
    /// The rig's weights.
    pub weights: PathBuf,
    /// How the files call pose i (e.g. "pose 3", "sample 3 (t = 0.125 s)"); "pose i" if None.
    pub pose_labels: Option<Vec<String>>,
}

impl SetFiles {
    /// Every part from one file (a rig, or a set made in memory).
    pub fn one(file: impl Into<PathBuf>) -> SetFiles {
        let file = file.into();
        SetFiles {
            mesh: file.clone(),
            skeleton: file.clone(),
            transforms: file.clone(),
            split: file.clone(),
            weights: file,
            pose_labels: None,
        }
    }

    fn pose(&self, i: usize) -> String {
        match self.pose_labels.as_ref().and_then(|l| l.get(i)) {
            Some(label) => label.clone(),
            None => format!("pose {i}"),
        }
    }
}

/// A valid example set ([`ExampleSet::new`]): every pose has J rigid bone transforms and V
/// vertices, triangles index the vertices, parents form a forest, some pose is a training pose,
/// and rig weights (when known) are non-negative and sum to one per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct ExampleSet {
    pub rest: Vec<DVec3>,
    pub faces: Vec<[usize; 3]>,
    /// Every chain ends at a root.
    pub parents: Vec<Option<usize>>,
    pub poses: Vec<Pose>,
    pub is_test: Vec<bool>,
    pub bone_names: Option<Vec<String>>,
    /// A baseline (what an engine skins with today), never an input of training.
    pub rig_weights: Option<Vec<Vec<(usize, f64)>>>,
    /// Oddities that do not stop training (degenerate triangles, unreferenced vertices, and
    /// what importers add).
    pub warnings: Vec<String>,
}

/// A bad input file: which file, and what is wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    pub file: PathBuf,
    pub message: String,
}

impl InputError {
    pub fn new(file: &Path, message: impl Into<String>) -> InputError {
        InputError {
            file: file.to_path_buf(),
            message: message.into(),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.file.display(), self.message)
    }
}

impl std::error::Error for InputError {}

impl ExampleSet {
    /// Validates `parts` (the struct docs say what), naming the file of `files` at fault, and
    /// adds the mesh's warnings.
    pub fn new(mut parts: SetParts, files: &SetFiles) -> Result<ExampleSet, InputError> {
        check_mesh(&parts, files)?;
        check_skeleton(&parts.parents, &files.skeleton)?;
        // Before the poses, whose errors name bones by these names.
        if let Some(names) = &parts.bone_names {
            if names.len() != parts.parents.len() {
                let message = format!("{} names for {} bones", names.len(), parts.parents.len());
                return Err(InputError::new(&files.skeleton, message));
            }
        }
        check_poses(&parts, files)?;
        check_split(&parts, files)?;
        if let Some(w) = &parts.rig_weights {
            check_weights(w, parts.rest.len(), parts.parents.len(), &files.weights)?;
        }
        let warnings = mesh_warnings(&parts.rest, &parts.faces, &files.mesh);
        // Within the tolerance of one, and then exactly one.
        for row in parts.rig_weights.iter_mut().flatten() {
            let sum: f64 = row.iter().map(|(_, w)| w).sum();
            row.iter_mut().for_each(|(_, w)| *w /= sum);
        }
        let SetParts {
            rest,
            faces,
            parents,
            poses,
            is_test,
            bone_names,
            rig_weights,
        } = parts;
        Ok(ExampleSet {
            rest,
            faces,
            parents,
            poses,
            is_test,
            bone_names,
            rig_weights,
            warnings,
        })
    }

    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    pub fn bone_count(&self) -> usize {
        self.parents.len()
    }

    /// Per bone, its children, ascending.
    pub fn children(&self) -> Vec<Vec<usize>> {
        let mut children = vec![Vec::new(); self.bone_count()];
        for (b, p) in self.parents.iter().enumerate() {
            if let Some(p) = p {
                children[*p].push(b);
            }
        }
        children
    }

    /// Indices of the training poses.
    pub fn train(&self) -> Vec<usize> {
        (0..self.poses.len())
            .filter(|&i| !self.is_test[i])
            .collect()
    }

    /// Indices of the held-out test poses.
    pub fn test(&self) -> Vec<usize> {
        (0..self.poses.len()).filter(|&i| self.is_test[i]).collect()
    }

    /// This set with the poses `held` held out too: what a cross-validation fold trains on.
    pub fn holding_out(&self, held: &[usize]) -> ExampleSet {
        let mut inner = self.clone();
        for &i in held {
            inner.is_test[i] = true;
        }
        inner
    }
}

/// The bounding box of `points`: its lowest and highest corners.
pub fn bounds(points: &[DVec3]) -> (DVec3, DVec3) {
    points.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

/// The length of the bounding box's diagonal (at least 1e-12): the mesh size that relative
/// tolerances use.
pub fn diagonal(points: &[DVec3]) -> f64 {
    let (lo, hi) = bounds(points);
    (hi - lo).length().max(1e-12)
}

fn check_mesh(parts: &SetParts, files: &SetFiles) -> Result<(), InputError> {
    let v = parts.rest.len();
    if v == 0 {
        return Err(InputError::new(&files.mesh, "the rest mesh has no vertex"));
    }
    if let Some(a) = parts.rest.iter().position(|p| !p.is_finite()) {
        return Err(InputError::new(
            &files.mesh,
            format!("rest vertex {a} is not finite"),
        ));
    }
    match parts.faces.iter().position(|f| f.iter().any(|&a| a >= v)) {
        Some(k) => Err(InputError::new(
            &files.mesh,
            format!(
                "triangle {k} {:?} indexes past the {v} vertices",
                parts.faces[k]
            ),
        )),
        None => Ok(()),
    }
}

/// Parents in range and without cycles (every chain ends at a root).
fn check_skeleton(parents: &[Option<usize>], file: &Path) -> Result<(), InputError> {
    let j = parents.len();
    if j == 0 {
        return Err(InputError::new(file, "the skeleton has no bone"));
    }
    if let Some(b) = (0..j).find(|&b| parents[b].is_some_and(|p| p >= j)) {
        let message = format!(
            "bone {b}'s parent {:?} is not one of the {j} bones",
            parents[b]
        );
        return Err(InputError::new(file, message));
    }
    let cycle = (0..j).find(|&start| {
        let mut b = start;
        (0..=j).all(|_| match parents[b] {
            Some(p) => {
                b = p;
                true
            }
            None => false,
        })
    });
    match cycle {
        Some(b) => Err(InputError::new(
            file,
            format!("the parents of bone {b} form a cycle"),
        )),
        None => Ok(()),
    }
}

/// Every pose: J rigid transforms and V finite vertices.
fn check_poses(parts: &SetParts, files: &SetFiles) -> Result<(), InputError> {
    let (v, j) = (parts.rest.len(), parts.parents.len());
    for (i, pose) in parts.poses.iter().enumerate() {
        if pose.bones.len() != j || pose.vertices.len() != v {
            let message = format!(
                "{}: {} bones and {} vertices, not J = {j} and V = {v}",
                files.pose(i),
                pose.bones.len(),
                pose.vertices.len()
            );
            return Err(InputError::new(&files.transforms, message));
        }
        for (b, bone) in pose.bones.iter().enumerate() {
            let error = rotation_error(bone.q);
            if error.is_nan() || error > ROTATION_TOLERANCE || !bone.d.is_finite() {
                let name = parts
                    .bone_names
                    .as_ref()
                    .map_or(b.to_string(), |n| n[b].clone());
                let message = format!(
                    "{}, bone {name}: the 3x3 part is not a rotation (error {error:.2e} > {ROTATION_TOLERANCE:e}); transforms must be rigid (scaled joints are not supported)",
                    files.pose(i)
                );
                return Err(InputError::new(&files.transforms, message));
            }
        }
        if let Some(a) = pose.vertices.iter().position(|p| !p.is_finite()) {
            let message = format!("{}: vertex {a} is not finite", files.pose(i));
            return Err(InputError::new(&files.transforms, message));
        }
    }
    Ok(())
}

/// A flag per pose, and some training pose.
fn check_split(parts: &SetParts, files: &SetFiles) -> Result<(), InputError> {
    let n = parts.poses.len();
    if parts.is_test.len() != n {
        let message = format!("{} split flags for {n} poses", parts.is_test.len());
        return Err(InputError::new(&files.split, message));
    }
    match parts.is_test.iter().all(|&t| t) {
        true => Err(InputError::new(
            &files.split,
            "every pose is a test pose: nothing to train on",
        )),
        false => Ok(()),
    }
}

/// Per vertex (bone, weight): bones in range, weights finite and ≥ 0, summing to one.
fn check_weights(
    weights: &[Vec<(usize, f64)>],
    v: usize,
    j: usize,
    file: &Path,
) -> Result<(), InputError> {
    if weights.len() != v {
        let message = format!("weights for {} vertices, not V = {v}", weights.len());
        return Err(InputError::new(file, message));
    }
    for (a, row) in weights.iter().enumerate() {
        for &(b, w) in row {
            let fault = match () {
                _ if b >= j => format!("vertex {a}: weight on bone {b}, of bones 0..{j}"),
                _ if !w.is_finite() => format!("vertex {a}, bone {b}: weight {w}"),
                _ if w < 0.0 => format!("vertex {a}, bone {b}: negative weight {w}"),
                _ => continue,
            };
            return Err(InputError::new(file, fault));
        }
        let sum: f64 = row.iter().map(|(_, w)| w).sum();
        if (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            let message = format!("vertex {a}: weights sum to {sum}, not 1");
            return Err(InputError::new(file, message));
        }
    }
    Ok(())
}

/// Degenerate triangles and unreferenced vertices (training continues: degenerate triangles
/// get an identity gradient, unreferenced vertices follow SSD), naming `file`.
fn mesh_warnings(rest: &[DVec3], faces: &[[usize; 3]], file: &Path) -> Vec<String> {
    let mut warnings = Vec::new();
    let scale = rest
        .iter()
        .fold(0.0f64, |m, p| m.max(p.length()))
        .max(1e-12);
    let degenerate: Vec<usize> = faces
        .iter()
        .enumerate()
        .filter(|(_, [a, b, c])| {
            let (a, b, c) = (rest[*a], rest[*b], rest[*c]);
            (b - a).cross(c - a).length() <= 1e-12 * scale * scale
        })
        .map(|(k, _)| k)
        .collect();
    if !degenerate.is_empty() {
        warnings.push(format!(
            "{}: {} degenerate (zero-area) triangles, first {:?}",
            file.display(),
            degenerate.len(),
            &degenerate[..degenerate.len().min(5)]
        ));
    }
    let mut used = vec![false; rest.len()];
    faces.iter().flatten().for_each(|&a| used[a] = true);
    let unused: Vec<usize> = (0..used.len()).filter(|&a| !used[a]).collect();
    if !unused.is_empty() {
        warnings.push(format!(
            "{}: {} vertices belong to no triangle, first {:?}",
            file.display(),
            unused.len(),
            &unused[..unused.len().min(5)]
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// Too few bone names and a sheared bone: an error naming the skeleton, not a panic while
    /// naming the bone.
    #[test]
    fn bone_names_are_checked_before_the_poses_use_them() {
        let sheared = Affine {
            q: DMat3::from_cols_array(&[1.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            d: DVec3::ZERO,
        };
        let parts = SetParts {
            rest: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            faces: vec![[0, 1, 2]],
            parents: vec![None, Some(0)],
            poses: vec![Pose {
                bones: vec![sheared; 2],
                vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            }],
            is_test: vec![false],
            bone_names: Some(vec!["root".into()]),
            rig_weights: None,
        };
        let files = SetFiles {
            pose_labels: Some(Vec::new()),
            ..SetFiles::one("rig.glb")
        };
        let e = ExampleSet::new(parts.clone(), &files).err();
        assert_eq!(e.map(|e| e.message), Some("1 names for 2 bones".into()));
        let named = SetParts {
            bone_names: Some(vec!["root".into(), "arm".into()]),
            ..parts
        };
        let e = ExampleSet::new(named, &files).err().map(|e| e.message);
        assert!(
            e.as_deref()
                .is_some_and(|m| m.starts_with("pose 0, bone root: ")),
            "{e:?}"
        );
    }
}
