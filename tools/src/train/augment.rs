//! Pose augmentation by distillation (beyond the paper): the reduction sees, besides the
//! training examples, gentler poses between the rest pose and each of them, meshed by the
//! trained full model. Random range-of-motion examples are wide; animations are mostly gentle,
//! and a regression fitted on wide poses alone extrapolates toward the rest pose badly.
//!
//! A gentle pose scales every joint rotation `θ~_b` of a training pose by s and rebuilds the
//! bone transforms by forward kinematics about each joint's pivot c_b, the rest-space point
//! that parent and child move alike (`T_b c_b = T_p c_b`, least squares over the poses).

use crate::set::{Affine, ExampleSet, Pose};
use crate::skinning::lbs::Skinning;
use crate::train::full_model::{FullModel, Prepared};
use crate::train::pivots::pivots;
use crate::train::rotreg::PoseFeatures;
use glam::DVec3;
use rrskin::model::parents_first;
use rrskin::predict::{exp_rotation, log_rotation};

/// The pose with every joint rotation of `bones` scaled by `s`.
pub fn scaled_pose(
    set: &ExampleSet,
    order: &[usize],
    pivots: &[DVec3],
    bones: &[Affine],
    s: f64,
) -> Vec<Affine> {
    let mut out = bones.to_vec();
    for &b in order {
        let t = bones[b];
        out[b] = match set.parents[b] {
            None => {
                let q = exp_rotation(log_rotation(t.q) * s);
                Affine { q, d: t.d * s }
            }
            Some(p) => {
                let joint = exp_rotation(log_rotation(bones[p].q.transpose() * t.q) * s);
                let parent = out[p];
                // x ↦ T_p(c + Q~ (x − c))
                let q = parent.q * joint;
                Affine {
                    q,
                    d: parent.apply(pivots[b] - joint * pivots[b]),
                }
            }
        };
    }
    out
}

/// The joint-rotation scale of the gentle poses: half-way between the rest pose and each
/// training pose.
pub const GENTLE_SCALE: f64 = 0.5;

/// A set widened by gentle poses, with their per-pose features and polar factors.
pub struct Widened {
    pub set: ExampleSet,
    pub prep: Prepared,
}

/// `set` with, for each scale in `scales` and each training pose, a gentle pose meshed by the
/// full `model` (fixed vertices by `ssd`), appended as a training pose. Test poses are kept as
/// they are and never used.
pub fn augment(
    set: &ExampleSet,
    prep: &Prepared,
    model: &FullModel,
    ssd: &Skinning,
    scales: &[f64],
) -> Widened {
    let train = set.train();
    let order = parents_first(set.bone_count(), |b| set.parents[b]);
    let pivots = pivots(set, &train);
    let mut wide = set.clone();
    let first = wide.poses.len();
    for &s in scales {
        for &i in &train {
            wide.poses.push(Pose {
                bones: scaled_pose(set, &order, &pivots, &set.poses[i].bones, s),
                vertices: Vec::new(),
            });
            wide.is_test.push(false);
        }
    }
    let feats = PoseFeatures::all(&wide);
    let gentle: Vec<usize> = (first..wide.poses.len()).collect();
    // The full model needs only the features to mesh a pose.
    let features_only = Prepared {
        feats,
        polar: Vec::new(),
    };
    let meshes = model.predict(&wide, &features_only, ssd, &gentle);
    for (&i, mesh) in gentle.iter().zip(meshes) {
        wide.poses[i].vertices = mesh;
    }
    let mut wide_prep = Prepared {
        feats: features_only.feats,
        polar: prep.polar.clone(),
    };
    wide_prep
        .polar
        .extend(Prepared::polar_factors(&wide, &gentle));
    Widened {
        set: wide,
        prep: wide_prep,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::pivots::pivots;
    use glam::DMat3;

    fn chain_set() -> ExampleSet {
        // Three bones listed child first (2 → 1 → 0 is the chain 0 ← 1 ← 2 reversed): the
        // order must not matter.
        let parents = vec![Some(1), Some(2), None];
        let pivot = [
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::ZERO,
        ];
        let turn = |axis: DVec3, angle: f64| exp_rotation(axis.normalize() * angle);
        let joints = [
            turn(DVec3::new(1.0, 0.2, 0.0), 0.7),
            turn(DVec3::new(0.0, 0.3, 1.0), -0.9),
            DMat3::IDENTITY,
        ];
        // World transforms by forward kinematics, root (bone 2) first.
        let mut bones = vec![
            Affine {
                q: DMat3::IDENTITY,
                d: DVec3::ZERO
            };
            3
        ];
        for b in [2, 1, 0] {
            let parent = parents[b].map_or(
                Affine {
                    q: DMat3::IDENTITY,
                    d: DVec3::ZERO,
                },
                |p| bones[p],
            );
            let q = parent.q * joints[b];
            bones[b] = Affine {
                q,
                d: parent.apply(pivot[b] - joints[b] * pivot[b]),
            };
        }
        let second: Vec<Affine> = bones
            .iter()
            .map(|b| Affine {
                q: b.q * b.q,
                d: b.d,
            })
            .collect();
        ExampleSet {
            rest: vec![DVec3::ZERO],
            faces: Vec::new(),
            parents,
            poses: [bones, second]
                .into_iter()
                .map(|bones| Pose {
                    bones,
                    vertices: vec![DVec3::ZERO],
                })
                .collect(),
            is_test: vec![false, false],
            bone_names: None,
            rig_weights: None,
            warnings: Vec::new(),
        }
    }

    #[test]
    fn parents_come_first_whatever_the_listed_order() {
        let order = |p: &[Option<usize>]| parents_first(p.len(), |b| p[b]);
        assert_eq!(order(&[Some(1), Some(2), None]), vec![2, 1, 0]);
        assert_eq!(order(&[None, Some(0), Some(0), Some(2)]), vec![0, 1, 2, 3]);
    }

    #[test]
    fn scale_one_rebuilds_the_pose_and_scale_zero_the_rest_pose() {
        let set = chain_set();
        let order = parents_first(set.bone_count(), |b| set.parents[b]);
        let pivots = pivots(&set, &[0]);
        let bones = &set.poses[0].bones;
        for (b, t) in scaled_pose(&set, &order, &pivots, bones, 1.0)
            .iter()
            .enumerate()
        {
            // The pivots come from a least-squares fit with a weak ridge: 1e-6 is its bias.
            assert!(
                (t.q - bones[b].q)
                    .abs()
                    .to_cols_array()
                    .iter()
                    .all(|x| *x < 1e-9),
                "bone {b}"
            );
            assert!(
                (t.d - bones[b].d).length() < 1e-6,
                "bone {b}: {:?} vs {:?}",
                t.d,
                bones[b].d
            );
        }
        for t in scaled_pose(&set, &order, &pivots, bones, 0.0) {
            assert!((t.q - DMat3::IDENTITY)
                .abs()
                .to_cols_array()
                .iter()
                .all(|x| *x < 1e-9));
            assert!(t.d.length() < 1e-9);
        }
    }

    #[test]
    fn half_scale_halves_each_joint_angle() {
        let set = chain_set();
        let order = parents_first(set.bone_count(), |b| set.parents[b]);
        let pivots = pivots(&set, &[0]);
        let bones = &set.poses[0].bones;
        let half = scaled_pose(&set, &order, &pivots, bones, 0.5);
        for b in [0, 1] {
            let p = set.parents[b].unwrap_or(b);
            let full = log_rotation(bones[p].q.transpose() * bones[b].q);
            let got = log_rotation(half[p].q.transpose() * half[b].q);
            assert!((got - full * 0.5).length() < 1e-9, "bone {b}");
            // The joint's pivot moves alike under parent and child.
            assert!((half[b].apply(pivots[b]) - half[p].apply(pivots[b])).length() < 1e-9);
        }
    }
}
