//! The baselines of paper §4.2 / §7.1: the best rigid predictor (one bone per vertex) and SSD
//! (linear blend skinning with weights by non-negative least squares over the training poses,
//! James & Twigg 2005; METHOD.md §4).

use crate::example_set::{Bone, ExampleSet};
use crate::linalg::nnls;
use glam::DVec3;
use rayon::prelude::*;

/// Bones tried per vertex by the NNLS: the best single bones by rigid fit.
pub const CANDIDATES: usize = 10;
/// Weight of the Σw = 1 row relative to the mean diagonal of the normal equations.
const SUM_TO_ONE_WEIGHT: f64 = 1e3;

/// Per vertex, (bone, weight) pairs with weights ≥ 0 summing to one.
#[derive(Debug, Clone, PartialEq)]
pub struct Skinning {
    pub influences: Vec<Vec<(usize, f64)>>,
}

impl Skinning {
    /// Linear blend skinning of the rest mesh by one pose's bones.
    pub fn deform(&self, rest: &[DVec3], bones: &[Bone]) -> Vec<DVec3> {
        rest.iter()
            .zip(&self.influences)
            .map(|(&p, inf)| inf.iter().map(|&(b, w)| bones[b].apply(p) * w).sum())
            .collect()
    }

    /// One bone per vertex (the rigid predictor).
    pub fn rigid(bones: &[usize]) -> Skinning {
        Skinning {
            influences: bones.iter().map(|&b| vec![(b, 1.0)]).collect(),
        }
    }
}

/// Σ_i |T_b(q_i) ŷ_a − y_a^i|² for every vertex a (rows) and bone b (columns).
pub fn rigid_errors(set: &ExampleSet, poses: &[usize]) -> Vec<Vec<f64>> {
    let j = set.bone_count();
    (0..set.vertex_count())
        .into_par_iter()
        .map(|a| {
            (0..j)
                .map(|b| {
                    poses
                        .iter()
                        .map(|&i| {
                            (set.poses[i].bones[b].apply(set.rest[a]) - set.poses[i].vertices[a])
                                .length_squared()
                        })
                        .sum()
                })
                .collect()
        })
        .collect()
}

/// b*(a): the bone whose rigid motion best follows each vertex over `poses`.
pub fn rigid_bones(errors: &[Vec<f64>]) -> Vec<usize> {
    errors
        .iter()
        .map(|e| {
            (0..e.len())
                .min_by(|&x, &y| e[x].total_cmp(&e[y]))
                .unwrap_or(0)
        })
        .collect()
}

/// SSD weights with at most `k` influences per vertex, fitted on `poses`.
pub fn fit(set: &ExampleSet, poses: &[usize], errors: &[Vec<f64>], k: usize) -> Skinning {
    let influences = (0..set.vertex_count())
        .into_par_iter()
        .map(|a| {
            let mut order: Vec<usize> = (0..set.bone_count()).collect();
            order.sort_by(|&x, &y| errors[a][x].total_cmp(&errors[a][y]));
            order.truncate(CANDIDATES);
            let w = fit_vertex(set, poses, a, &order);
            let mut support: Vec<(usize, f64)> = order
                .iter()
                .zip(&w)
                .filter(|(_, &w)| w > 0.0)
                .map(|(&b, &w)| (b, w))
                .collect();
            if support.len() > k {
                // Keep the k largest and refit on them.
                support.sort_by(|x, y| y.1.total_cmp(&x.1));
                let kept: Vec<usize> = support[..k].iter().map(|&(b, _)| b).collect();
                let w = fit_vertex(set, poses, a, &kept);
                support = kept
                    .iter()
                    .zip(&w)
                    .filter(|(_, &w)| w > 0.0)
                    .map(|(&b, &w)| (b, w))
                    .collect();
            }
            let total: f64 = support.iter().map(|&(_, w)| w).sum();
            if support.is_empty() || total <= 0.0 {
                return vec![(order[0], 1.0)];
            }
            support.iter().map(|&(b, w)| (b, w / total)).collect()
        })
        .collect();
    Skinning { influences }
}

/// NNLS for one vertex over `bones`, with a heavily weighted Σw = 1 row.
fn fit_vertex(set: &ExampleSet, poses: &[usize], a: usize, bones: &[usize]) -> Vec<f64> {
    let n = bones.len();
    let (mut g, mut h) = (vec![0.0; n * n], vec![0.0; n]);
    let mut moved = vec![DVec3::ZERO; n];
    for &i in poses {
        let pose = &set.poses[i];
        for (m, &b) in moved.iter_mut().zip(bones) {
            *m = pose.bones[b].apply(set.rest[a]);
        }
        let y = pose.vertices[a];
        for r in 0..n {
            h[r] += moved[r].dot(y);
            for c in 0..n {
                g[r * n + c] += moved[r].dot(moved[c]);
            }
        }
    }
    let omega = SUM_TO_ONE_WEIGHT * (0..n).map(|r| g[r * n + r]).sum::<f64>() / n as f64;
    for r in 0..n {
        h[r] += omega;
        for c in 0..n {
            g[r * n + c] += omega;
        }
    }
    nnls(&g, &h)
}
