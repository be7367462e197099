//! The error budget (`rrskin eval --diagnose`): oracle ceilings of each stage, so that what the
//! predictors lose and what the reduction loses can be read off on training and test poses.
//!
//! | ceiling | what is exact | what is still the model's |
//! |---|---|---|
//! | `full_exact` | every triangle's gradient D_k(q_i) | near-rigid set F, α blend, Poisson |
//! | `reduced_oracle` | the proxy transforms T(q_i), by least squares per pose | skinning weights |
//! | `reduced_oracle_keys` | the key gradients (the 3x3 parts of those T) | C1/C2, the translations |
//! | `pose_space` | nothing: the runtime model plus the unreduced per-vertex pose-space correction of its residuals ([`corrective::ceiling`]) | everything, from the training poses alone |
//!
//! So `rr_full − full_exact` is what the gradient predictors lose, `rr_reduced − rr_full` what
//! the reduction loses, `rr_reduced − reduced_oracle_keys` what the key predictors lose and
//! `reduced_oracle_keys − reduced_oracle` what the C1/C2 map loses. The oracles see the test
//! poses' meshes; `pose_space` does not: it is what the training poses support of any
//! correction linear in the nearby joints' rotations, at any per-vertex cost. Where it stays
//! above a goal held out, no such correction reaches the goal from these training poses.

use crate::set::ExampleSet;
use crate::train::corrective::{self, Residuals};
use crate::train::reduce::c1c2::Reduced;
use crate::train::Trained;
use glam::{DMat3, DVec3};

/// The meshes the runtime form gives with the best proxy transforms of each pose.
pub fn oracle_meshes(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .zip(reduced.best_transforms(set, poses, None))
        .map(|(&i, t)| reduced.skin_with(set, &t, &set.poses[i].bones))
        .collect()
}

/// The meshes the trained C1/C2 give from oracle key gradients (the best transforms' 3x3).
pub fn oracle_key_meshes(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .zip(reduced.best_transforms(set, poses, None))
        .map(|(&i, t)| {
            let keys: Vec<DMat3> = t.iter().map(|b| b.q).collect();
            reduced.predict_with_keys(set, &keys, &set.poses[i].bones)
        })
        .collect()
}

/// The meshes of `model` on `train` and on `test`, each corrected by the pose-space ceiling
/// ([`corrective::ceiling`]) fitted on `train`.
pub fn pose_space_meshes(
    set: &ExampleSet,
    trained: &Trained,
    model: &rrskin::Model,
    train: &[usize],
    test: &[usize],
    folds: usize,
) -> rrskin::Result<[Vec<Vec<DVec3>>; 2]> {
    let fitted = Residuals::of(set, &trained.feats, model, train)?;
    let held = Residuals::of(set, &trained.feats, model, test)?;
    let offsets = corrective::ceiling(
        set,
        &trained.ssd,
        &trained.rigid,
        train,
        &fitted,
        folds,
        &[&fitted, &held],
    );
    let corrected = |at: &Residuals, offsets: &[Vec<DVec3>]| -> Vec<Vec<DVec3>> {
        (at.positions.iter().zip(&at.m).zip(offsets))
            .map(|((y, m), o)| {
                (y.iter().zip(m).zip(o))
                    .map(|((y, m), o)| *y + *m * *o)
                    .collect()
            })
            .collect()
    };
    Ok([
        corrected(&fitted, &offsets[0]),
        corrected(&held, &offsets[1]),
    ])
}
