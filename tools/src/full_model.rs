//! The unreduced rotational-regression model (paper §3–4): per triangle a rotation predictor
//! (§3.2) and a scale/shear predictor (§3.3); meshes by Poisson reconstruction with the
//! near-rigid vertices F fixed to SSD (§4.2). The quality reference for the reduced model.

use crate::example_set::ExampleSet;
use crate::gradients::{gradients, rest_inverses};
use crate::linalg::polar;
use crate::poisson::{anchor_components, Poisson, PoissonError};
use crate::rotreg::{self, PoseFeatures, RotationPredictor};
use crate::scale_shear::{self, ScaleShear};
use crate::ssd::Skinning;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Everything per pose that does not depend on training choices: joint rotations and the
/// polar factors (R, S) of every triangle's deformation gradient.
pub struct Prepared {
    pub feats: Vec<PoseFeatures>,
    /// [pose][triangle] → (R, S)
    pub polar: Vec<Vec<(DMat3, DMat3)>>,
}

impl Prepared {
    pub fn new(set: &ExampleSet) -> Prepared {
        let inverses = rest_inverses(&set.rest, &set.faces);
        let polar = set
            .poses
            .par_iter()
            .map(|p| {
                gradients(&p.vertices, &set.faces, &inverses)
                    .into_iter()
                    .map(polar)
                    .collect()
            })
            .collect();
        Prepared {
            feats: PoseFeatures::all(set),
            polar,
        }
    }
}

/// Per triangle: its rotation predictor (None when no nearby bone moves: then R = I).
#[derive(Debug, Clone)]
pub struct Rotations(pub Vec<Option<RotationPredictor>>);

/// Candidate bones of each triangle: those skinning its vertices in SSD, their parents and their
/// children. Nearby bones only (METHOD.md §2: all bones sometimes pair a shoulder with a leg).
pub fn nearby_bones(set: &ExampleSet, ssd: &Skinning) -> Vec<Vec<usize>> {
    let j = set.bone_count();
    let mut children = vec![Vec::new(); j];
    for (b, p) in set.parents.iter().enumerate() {
        if let Some(p) = p {
            children[*p].push(b);
        }
    }
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
            (0..j).filter(|&b| near[b]).collect()
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

/// Predicted gradients D_k(q) = R_k(q) S_k(q) of every triangle for one pose.
pub fn predict_gradients(
    set: &ExampleSet,
    f: &PoseFeatures,
    rot: &Rotations,
    stretch: &[ScaleShear],
) -> Vec<DMat3> {
    rot.0
        .iter()
        .zip(stretch)
        .map(|(r, h)| match r {
            Some(r) => {
                let x = scale_shear::features(f, &set.parents, r.first.bone);
                r.predict(f, &set.parents) * scale_shear::predict(h, &x)
            }
            None => DMat3::IDENTITY,
        })
        .collect()
}

/// The trained full model for one choice of F and ridge.
pub struct FullModel {
    pub rotations: Rotations,
    pub stretches: Vec<ScaleShear>,
    pub fixed: Vec<bool>,
    poisson: Poisson,
}

impl FullModel {
    pub fn new(
        set: &ExampleSet,
        rotations: Rotations,
        stretches: Vec<ScaleShear>,
        fixed: Vec<bool>,
    ) -> Result<FullModel, PoissonError> {
        let poisson = Poisson::new(&set.rest, &set.faces, &fixed)?;
        Ok(FullModel {
            rotations,
            stretches,
            fixed,
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
        let inputs: Vec<(Vec<DMat3>, Vec<DVec3>)> = poses
            .par_iter()
            .map(|&i| {
                let grads =
                    predict_gradients(set, &prep.feats[i], &self.rotations, &self.stretches);
                (grads, ssd.deform(&set.rest, &set.poses[i].bones))
            })
            .collect();
        self.poisson.solve(&inputs)
    }
}
