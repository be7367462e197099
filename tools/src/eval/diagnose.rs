//! The error budget (`rrskin eval --diagnose`): oracle ceilings of each stage, so that what the
//! predictors lose and what the reduction loses can be read off on training and test poses.
//!
//! | ceiling | what is exact | what is still the model's |
//! |---|---|---|
//! | `full_exact` | every triangle's gradient D_k(q_i) | near-rigid set F, α blend, Poisson |
//! | `reduced_oracle` | the proxy transforms T(q_i), by least squares per pose | skinning weights |
//! | `reduced_oracle_keys` | the key gradients (the 3x3 parts of those T) | C1/C2, the translations |
//!
//! So `rr_full − full_exact` is what the gradient predictors lose, `rr_reduced − rr_full` what
//! the reduction loses, `rr_reduced − reduced_oracle_keys` what the key predictors lose and
//! `reduced_oracle_keys − reduced_oracle` what the C1/C2 map loses.

use crate::import::example_set::ExampleSet;
use crate::train::reduce::c1c2::Reduced;
use faer::prelude::*;
use faer::{Mat, Side};
use glam::{DMat3, DVec3, DVec4};

/// Per pose, every proxy transform (3 rows of 4) fitting the vertices best, with the trained
/// weights (the bones' share of each vertex is known): the ceiling of the runtime form.
pub fn oracle_transforms(
    set: &ExampleSet,
    reduced: &Reduced,
    poses: &[usize],
) -> Vec<Vec<[DVec4; 3]>> {
    let p = reduced.proxies;
    let n4p = 4 * p;
    let normal = reduced.proxy_normal_matrix(set);
    let mut gram = Mat::<f64>::from_fn(n4p, n4p, |r, c| normal[r * n4p + c]);
    // A weak ridge keeps proxies without free vertices determined (at zero: they move nothing).
    let trace = (0..n4p).map(|d| gram[(d, d)]).sum::<f64>() / n4p.max(1) as f64;
    for d in 0..n4p {
        gram[(d, d)] += 1e-9 * trace.max(1e-300);
    }
    let Ok(llt) = gram.llt(Side::Lower) else {
        return poses.iter().map(|_| vec![[DVec4::ZERO; 3]; p]).collect();
    };
    poses
        .iter()
        .map(|&i| {
            let (targets, _) = reduced.proxy_targets(set, &set.poses[i]);
            let rhs = Mat::<f64>::from_fn(n4p, 3, |r, c| targets[r][c]);
            let t = llt.solve(&rhs);
            (0..p)
                .map(|e| {
                    [0, 1, 2].map(|c| DVec4::from_array([0, 1, 2, 3].map(|r| t[(4 * e + r, c)])))
                })
                .collect()
        })
        .collect()
}

/// The meshes the runtime form gives with the oracle proxy transforms.
pub fn oracle_meshes(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<Vec<DVec3>> {
    let p = reduced.proxies;
    poses
        .iter()
        .zip(oracle_transforms(set, reduced, poses))
        .map(|(&i, t)| {
            (0..set.vertex_count())
                .map(|a| {
                    let h = DVec4::from((set.rest[a], 1.0));
                    reduced.skin[a]
                        .iter()
                        .map(|&(e, w)| match e < p {
                            true => DVec3::new(t[e][0].dot(h), t[e][1].dot(h), t[e][2].dot(h)) * w,
                            false => set.poses[i].bones[e - p].apply(set.rest[a]) * w,
                        })
                        .sum()
                })
                .collect()
        })
        .collect()
}

/// The meshes the trained C1/C2 give from oracle key gradients (the oracle transforms' 3x3).
pub fn oracle_key_meshes(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .zip(oracle_transforms(set, reduced, poses))
        .map(|(&i, t)| {
            let keys: Vec<DMat3> = t
                .iter()
                .map(|rows| {
                    DMat3::from_cols(rows[0].truncate(), rows[1].truncate(), rows[2].truncate())
                        .transpose()
                })
                .collect();
            reduced.predict_with_keys(set, &keys, &set.poses[i].bones)
        })
        .collect()
}
