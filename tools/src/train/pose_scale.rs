//! Per-pose normalisers for scoring candidates on held-out training poses
//! ([`crate::train::cross_validate`]; beyond the paper, docs/method.md §18). Random
//! range-of-motion training poses are far wider than animation, and a plain sum of squared
//! errors over them is carried by the widest, where every error is largest. Each pose is
//! weighted instead by the inverse of the rigid predictor's squared error in it, the denominator
//! of the pose's EE², so that every pose counts by its relative error, as a gentle animation pose
//! does in the held-out EE. The rigid error is floored at a tenth of its mean over the poses: at
//! or near the rest pose, where it vanishes, any error would otherwise carry everything.
//! (Weighting the joint-blend fits themselves the same way changed nothing measurable:
//! docs/experiments.md.)

use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;

/// The floor of a pose's rigid error, relative to the mean over the poses.
pub const FLOOR: f64 = 0.1;

/// Per pose of `poses`, the rigid predictor's squared error Σ_a |r_a − y_a|², floored at
/// [`FLOOR`] of the mean.
pub fn rigid_pose_errors(set: &ExampleSet, poses: &[usize], rigid: &Skinning) -> Vec<f64> {
    let errors: Vec<f64> = poses
        .iter()
        .map(|&i| {
            let pose = &set.poses[i];
            rigid
                .deform(&set.rest, &pose.bones)
                .iter()
                .zip(&pose.vertices)
                .map(|(r, y)| (*r - *y).length_squared())
                .sum()
        })
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    let floor = (FLOOR * mean).max(f64::MIN_POSITIVE);
    errors.iter().map(|&e| e.max(floor)).collect()
}

/// [`rigid_pose_errors`] of the best rigid predictor fitted on `poses` themselves, for the stages
/// that are not handed one (the joint-blend fits inside the structure's folds see only their
/// fold's poses).
pub fn own_rigid_pose_errors(set: &ExampleSet, poses: &[usize]) -> Vec<f64> {
    let rigid = Skinning::rigid(&crate::skinning::lbs::rigid_bones(
        &crate::skinning::lbs::rigid_errors(set, poses),
    ));
    rigid_pose_errors(set, poses, &rigid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::set::{Affine, Pose};
    use glam::{DMat3, DVec3};

    /// One vertex on one bone that stays put: its pose errors are its displacements squared.
    fn set_with_offsets(offsets: &[f64]) -> ExampleSet {
        let bone = Affine {
            q: DMat3::IDENTITY,
            d: DVec3::ZERO,
        };
        ExampleSet {
            rest: vec![DVec3::ZERO],
            faces: Vec::new(),
            parents: vec![None],
            bone_names: None,
            poses: offsets
                .iter()
                .map(|&x| Pose {
                    bones: vec![bone],
                    vertices: vec![DVec3::new(x, 0.0, 0.0)],
                })
                .collect(),
            is_test: vec![false; offsets.len()],
            rig_weights: None,
            warnings: Vec::new(),
        }
    }

    /// A pose's error is its rigid squared error; the rest pose's (zero) is the floor.
    #[test]
    fn rigid_pose_errors_are_floored() {
        let set = set_with_offsets(&[1.0, 2.0, 0.0]);
        let e = rigid_pose_errors(&set, &[0, 1, 2], &Skinning::rigid(&[0]));
        assert_eq!(&e[..2], &[1.0, 4.0]);
        assert!((e[2] - FLOOR * 5.0 / 3.0).abs() < 1e-15, "{e:?}");
    }
}
