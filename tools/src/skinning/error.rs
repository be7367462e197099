//! The enveloping error (paper §7.1, docs/method.md §10) and the squared vertex error it is made
//! of: `EE = sqrt(Σ_i Σ_a |y_a(q_i) − y_a^i|² / Σ_i Σ_a |r_a(q_i) − y_a^i|²)` in percent, r the
//! best rigid predictor (one bone per vertex, chosen on the training poses).

use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use glam::DVec3;

/// Per pose i of `poses`, Σ_a |predicted_i,a − y_a^i|² (`predicted` in the same order).
pub fn pose_errors(set: &ExampleSet, poses: &[usize], predicted: &[Vec<DVec3>]) -> Vec<f64> {
    poses
        .iter()
        .zip(predicted)
        .map(|(&i, y)| {
            y.iter()
                .zip(&set.poses[i].vertices)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum::<f64>()
        })
        .collect()
}

/// Σ_i Σ_a |predicted_i,a − y_a^i|² over `poses`.
pub fn squared_error(set: &ExampleSet, poses: &[usize], predicted: &[Vec<DVec3>]) -> f64 {
    pose_errors(set, poses, predicted).iter().sum()
}

/// `skin`'s meshes of `poses`.
pub fn deform_all(set: &ExampleSet, skin: &Skinning, poses: &[usize]) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .map(|&i| skin.deform(&set.rest, &set.poses[i].bones))
        .collect()
}

/// EE in percent of `predicted` against the rigid predictor on the same poses.
pub fn enveloping_error(
    set: &ExampleSet,
    poses: &[usize],
    predicted: &[Vec<DVec3>],
    rigid: &Skinning,
) -> f64 {
    let reference = squared_error(set, poses, &deform_all(set, rigid, poses));
    100.0 * (squared_error(set, poses, predicted) / reference).sqrt()
}
