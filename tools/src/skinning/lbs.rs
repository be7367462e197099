//! Linear blend skinning ([`Skinning`]) and the best rigid predictor (one bone per vertex, paper
//! §4.2): the 100 % of the enveloping error.

use crate::set::{Affine, ExampleSet};
use glam::DVec3;
use rayon::prelude::*;

/// Per vertex, (bone, weight) pairs with weights ≥ 0 summing to one.
#[derive(Debug, Clone, PartialEq)]
pub struct Skinning {
    pub influences: Vec<Vec<(usize, f64)>>,
}

impl Skinning {
    /// Linear blend skinning of the rest mesh by one pose's bones.
    pub fn deform(&self, rest: &[DVec3], bones: &[Affine]) -> Vec<DVec3> {
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

/// RMS over `poses` of each vertex's error under `skin`.
pub fn per_vertex_error(set: &ExampleSet, poses: &[usize], skin: &Skinning) -> Vec<f64> {
    let mut sum = vec![0.0; set.vertex_count()];
    for &i in poses {
        for (a, p) in skin
            .deform(&set.rest, &set.poses[i].bones)
            .iter()
            .enumerate()
        {
            sum[a] += (*p - set.poses[i].vertices[a]).length_squared();
        }
    }
    sum.iter()
        .map(|s| (s / poses.len().max(1) as f64).sqrt())
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
