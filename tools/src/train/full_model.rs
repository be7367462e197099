//! The unreduced rotational-regression model (paper §3–4): per triangle a rotation predictor
//! (§3.2) and a scale/shear predictor (§3.3); meshes by Poisson reconstruction with the
//! near-rigid vertices F fixed to SSD (§4.2). The quality reference for the reduced model.

use crate::linalg::polar;
use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use crate::train::gradients::{gradients, rest_inverses};
use crate::train::poisson::{anchor_components, Poisson, PoissonError};
use crate::train::rotreg::{self, PoseFeatures, RotationPredictor};
use crate::train::scale_shear::{self, ScaleShear};
use crate::train::selection::Selection;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Everything per pose that does not depend on training choices: joint rotations and the
/// polar factors (R, S) of every triangle's deformation gradient.
pub struct Prepared {
    pub feats: Vec<PoseFeatures>,
    /// \[pose\]\[triangle\] → (R, S)
    pub polar: Vec<Vec<(DMat3, DMat3)>>,
}

impl Prepared {
    /// `feats`: [`PoseFeatures::all`] of `set`.
    pub fn new(set: &ExampleSet, feats: Vec<PoseFeatures>) -> Prepared {
        let all: Vec<usize> = (0..set.poses.len()).collect();
        Prepared {
            feats,
            polar: Prepared::polar_factors(set, &all),
        }
    }

    /// Per pose of `poses`, the polar factors (R, S) of every triangle's gradient.
    pub fn polar_factors(set: &ExampleSet, poses: &[usize]) -> Vec<Vec<(DMat3, DMat3)>> {
        let inverses = rest_inverses(&set.rest, &set.faces);
        poses
            .par_iter()
            .map(|&i| {
                gradients(&set.poses[i].vertices, &set.faces, &inverses)
                    .into_iter()
                    .map(polar)
                    .collect()
            })
            .collect()
    }
}

/// The full model on `poses` for the cross-validation's `selection`: rotation predictors
/// (§3.2) from the bones near each triangle in `ssd`, scale/shear (§3.3), the near-rigid set
/// (§4.2) and the Poisson factor (§4.1).
pub fn fit(
    set: &ExampleSet,
    prep: &Prepared,
    poses: &[usize],
    ssd: &Skinning,
    selection: &Selection,
) -> Result<FullModel, PoissonError> {
    let rotations = fit_rotations(set, prep, poses, &nearby_bones(set, ssd));
    let ridge = selection.choice.ridge;
    let stretches = fit_stretches(set, prep, poses, &rotations, ridge);
    let ssd_error = crate::skinning::lbs::per_vertex_error(set, poses, ssd);
    let fixed = near_rigid(set, &ssd_error, selection.choice.percentile);
    FullModel::new(
        set,
        rotations,
        stretches,
        fixed,
        selection.alpha.clone(),
        ridge,
    )
}

/// Per triangle: its rotation predictor (None when no nearby bone moves: then R = I).
#[derive(Debug, Clone)]
pub struct Rotations(pub Vec<Option<RotationPredictor>>);

/// Candidate bones of each triangle: those skinning its vertices in SSD, their parents and their
/// children, if active ([`ExampleSet::active_bones`]). Nearby bones only (docs/method.md §2: all
/// bones sometimes pair a shoulder with a leg).
pub fn nearby_bones(set: &ExampleSet, ssd: &Skinning) -> Vec<Vec<usize>> {
    let j = set.bone_count();
    let children = set.children();
    let active = set.active_bones();
    set.faces
        .iter()
        .map(|tri| {
            let mut near = vec![false; j];
            for &a in tri {
                for &(b, _) in &ssd.influences[a] {
                    near[b] = true;
                    if let Some(p) = set.parents[b] {
                        near[p] = true;
                    }
                    children[b].iter().for_each(|&c| near[c] = true);
                }
            }
            (0..j).filter(|&b| near[b] && active[b]).collect()
        })
        .collect()
}

pub fn fit_rotations(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    nearby: &[Vec<usize>],
) -> Rotations {
    let feats: Vec<&PoseFeatures> = train.iter().map(|&i| &prep.feats[i]).collect();
    Rotations(
        (0..set.faces.len())
            .into_par_iter()
            .map(|k| {
                let targets: Vec<DMat3> = train.iter().map(|&i| prep.polar[i][k].0).collect();
                rotreg::fit(&targets, &feats, &set.parents, &nearby[k])
            })
            .collect(),
    )
}

/// H per triangle, regressed on the triangle's first rotation bone (identity where it has none).
pub fn fit_stretches(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    rot: &Rotations,
    ridge: f64,
) -> Vec<ScaleShear> {
    rot.0
        .par_iter()
        .enumerate()
        .map(|(k, r)| match r {
            Some(r) => {
                let xs: Vec<[f64; 7]> = train
                    .iter()
                    .map(|&i| scale_shear::features(&prep.feats[i], &set.parents, r.first.bone))
                    .collect();
                let ss: Vec<DMat3> = train.iter().map(|&i| prep.polar[i][k].1).collect();
                scale_shear::fit(&ss, &xs, ridge)
            }
            None => scale_shear::identity(),
        })
        .collect()
}

/// Near-rigid vertices: SSD training RMS error below the `percentile`-th percentile, plus one
/// anchor per connected component that would otherwise have none.
pub fn near_rigid(set: &ExampleSet, ssd_error: &[f64], percentile: f64) -> Vec<bool> {
    let mut sorted = ssd_error.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((percentile / 100.0) * sorted.len() as f64).floor() as usize;
    let threshold = sorted
        .get(rank.min(sorted.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    let mut fixed: Vec<bool> = ssd_error.iter().map(|&e| e < threshold).collect();
    anchor_components(set.vertex_count(), &set.faces, &mut fixed, ssd_error);
    fixed
}

/// Predicted gradient D_k(q) = R_k(q) S_k(q) of triangle k for one pose.
pub fn predict_gradient(
    set: &ExampleSet,
    f: &PoseFeatures,
    rot: &Option<RotationPredictor>,
    h: &ScaleShear,
) -> DMat3 {
    match rot {
        Some(r) => {
            let x = scale_shear::features(f, &set.parents, r.first.bone);
            r.predict(f, &set.parents) * scale_shear::predict(h, &x)
        }
        None => DMat3::IDENTITY,
    }
}

/// The error of gradient `d` on the two rest edges of a triangle: what the Poisson solve sees.
pub fn edge_residuals(d: DMat3, truth: DMat3, edges: &[DVec3; 2]) -> [DVec3; 2] {
    let diff = d - truth;
    [diff * edges[0], diff * edges[1]]
}

/// Rest edges v̂2, v̂3 of every triangle.
pub fn rest_edges(set: &ExampleSet) -> Vec<[DVec3; 2]> {
    set.faces
        .iter()
        .map(|&[a, b, c]| [set.rest[b] - set.rest[a], set.rest[c] - set.rest[a]])
        .collect()
}

/// The trained full model for one choice of F, ridge and blend weights.
pub struct FullModel {
    pub rotations: Rotations,
    pub stretches: Vec<ScaleShear>,
    pub fixed: Vec<bool>,
    /// Per triangle, the weight α of the regression in its Poisson target
    /// `α D_rr(q) + (1 − α) D_ssd(q)`, D_ssd the gradient of the SSD mesh (α from held-out
    /// errors; 1 is the paper). D_ssd is linear in q, so the reduced C1/C2 form still holds.
    pub alpha: Vec<f64>,
    /// The scale/shear ridge the stretches were fitted with (per pose).
    pub ridge: f64,
    inverses: Vec<Option<DMat3>>,
    poisson: Poisson,
}

impl FullModel {
    pub fn new(
        set: &ExampleSet,
        rotations: Rotations,
        stretches: Vec<ScaleShear>,
        fixed: Vec<bool>,
        alpha: Vec<f64>,
        ridge: f64,
    ) -> Result<FullModel, PoissonError> {
        let poisson = Poisson::new(&set.rest, &set.faces, &fixed)?;
        let inverses = rest_inverses(&set.rest, &set.faces);
        Ok(FullModel {
            rotations,
            stretches,
            fixed,
            alpha,
            ridge,
            inverses,
            poisson,
        })
    }

    /// Reconstructed meshes for `poses` (fixed vertices follow `ssd`).
    pub fn predict(
        &self,
        set: &ExampleSet,
        prep: &Prepared,
        ssd: &Skinning,
        poses: &[usize],
    ) -> Vec<Vec<DVec3>> {
        self.reconstruct(set, ssd, poses, |i, k| {
            predict_gradient(
                set,
                &prep.feats[i],
                &self.rotations.0[k],
                &self.stretches[k],
            )
        })
    }

    /// Poisson reconstruction of `poses` from per-triangle gradients `gradient(pose, k)`,
    /// blended with SSD's by the model's α (fixed vertices follow `ssd`).
    pub fn reconstruct(
        &self,
        set: &ExampleSet,
        ssd: &Skinning,
        poses: &[usize],
        gradient: impl Fn(usize, usize) -> DMat3 + Sync,
    ) -> Vec<Vec<DVec3>> {
        let inputs: Vec<(Vec<DMat3>, Vec<DVec3>)> = poses
            .par_iter()
            .map(|&i| {
                let skinned = ssd.deform(&set.rest, &set.poses[i].bones);
                let ssd_grads = gradients(&skinned, &set.faces, &self.inverses);
                let grads = (0..set.faces.len())
                    .map(|k| match self.alpha[k] {
                        a if a <= 0.0 => ssd_grads[k],
                        a => gradient(i, k) * a + ssd_grads[k] * (1.0 - a),
                    })
                    .collect();
                (grads, skinned)
            })
            .collect();
        self.poisson.solve(&inputs)
    }
}
