//! Pose augmentation by distillation (beyond the paper): the reduction sees, besides the
//! training examples, gentler poses between the rest pose and each of them, meshed by the
//! trained full model. Random range-of-motion examples are wide; animations are mostly gentle,
//! and a regression fitted on wide poses alone extrapolates toward the rest pose badly.
//!
//! A gentle pose scales every joint rotation `θ~_b` of a training pose by s and rebuilds the
//! bone transforms by forward kinematics about each joint's pivot c_b, the rest-space point
//! that parent and child move alike (`T_b c_b = T_p c_b`, least squares over the poses).

use crate::example_set::{Bone, ExampleSet, Pose};
use crate::full_model::{FullModel, Prepared};
use crate::ssd::Skinning;
use glam::{DMat3, DVec3};
use rrskin::predict::{exp_rotation, log_rotation};

/// Parents before children, whatever order the rig lists its bones in.
pub fn topological_order(parents: &[Option<usize>]) -> Vec<usize> {
    let mut order = Vec::with_capacity(parents.len());
    let mut placed = vec![false; parents.len()];
    while order.len() < parents.len() {
        let before = order.len();
        for b in 0..parents.len() {
            if !placed[b] && parents[b].is_none_or(|p| placed[p]) {
                placed[b] = true;
                order.push(b);
            }
        }
        if order.len() == before {
            break; // a cycle: the loader refuses those
        }
    }
    order
}

/// Each bone's pivot: argmin_c Σ_i |(Q_b − Q_p) c − (d_p − d_b)|² (roots: the origin).
pub fn pivots(set: &ExampleSet, poses: &[usize]) -> Vec<DVec3> {
    (0..set.bone_count())
        .map(|b| {
            let Some(p) = set.parents[b] else {
                return DVec3::ZERO;
            };
            let (mut g, mut h) = (DMat3::ZERO, DVec3::ZERO);
            for &i in poses {
                let (tb, tp) = (set.poses[i].bones[b], set.poses[i].bones[p]);
                let m = tb.q - tp.q;
                g += m.transpose() * m;
                h += m.transpose() * (tp.d - tb.d);
            }
            // Weak pull to the origin of the bone's frame where the joint never turns.
            let ridge = 1e-9 * (g.x_axis.x + g.y_axis.y + g.z_axis.z).max(1e-300);
            (g + DMat3::from_diagonal(DVec3::splat(ridge))).inverse() * h
        })
        .collect()
}

/// The pose with every joint rotation of `bones` scaled by `s`.
pub fn scaled_pose(set: &ExampleSet, order: &[usize], pivots: &[DVec3], bones: &[Bone], s: f64) -> Vec<Bone> {
    let mut out = bones.to_vec();
    for &b in order {
        let t = bones[b];
        out[b] = match set.parents[b] {
            None => {
                let q = exp_rotation(log_rotation(t.q) * s);
                Bone { q, d: t.d * s }
            }
            Some(p) => {
                let joint = exp_rotation(log_rotation(bones[p].q.transpose() * t.q) * s);
                let parent = out[p];
                // x ↦ T_p(c + Q~ (x − c))
                let q = parent.q * joint;
                Bone { q, d: parent.apply(pivots[b] - joint * pivots[b]) }
            }
        };
    }
    out
}

/// `set` with, for each training pose and each scale in `scales`, a gentle pose meshed by
/// `model`, appended as a training pose. Test poses stay as they are and are never used.
pub fn augment(
    set: &ExampleSet,
    prep: &Prepared,
    model: &FullModel,
    ssd: &Skinning,
    scales: &[f64],
) -> ExampleSet {
    let train = set.train();
    let order = topological_order(&set.parents);
    let pivots = pivots(set, &train);
    let mut out = set.clone();
    let mut gentle = Vec::new();
    for &s in scales {
        for &i in &train {
            gentle.push(Pose {
                bones: scaled_pose(set, &order, &pivots, &set.poses[i].bones, s),
                vertices: Vec::new(),
            });
        }
    }
    // Mesh them with the full model: a set holding only the gentle poses gives their features.
    let mut scratch = set.clone();
    scratch.poses = gentle.iter().map(|p| Pose { bones: p.bones.clone(), vertices: set.rest.clone() }).collect();
    scratch.is_test = vec![false; gentle.len()];
    let feats = crate::rotreg::PoseFeatures::all(&scratch);
    let sprep = Prepared { feats, polar: vec![Vec::new(); gentle.len()] };
    let idx: Vec<usize> = (0..gentle.len()).collect();
    let _ = prep;
    let meshes = model.predict(&scratch, &sprep, ssd, &idx);
    for (mut pose, mesh) in gentle.into_iter().zip(meshes) {
        pose.vertices = mesh;
        out.poses.push(pose);
        out.is_test.push(false);
    }
    out
}
