//! Model selection by k-fold cross-validation over the training poses (beyond the paper: the
//! paper fixes its choices by hand). The full model's three choices are made on held-out
//! training poses, never on test poses:
//!
//! - the near-rigid set F (§4.2): vertices below a percentile of SSD's training error;
//! - the scale/shear ridge (§3.3);
//! - per triangle, how much of the regression's gradient to trust against SSD's ([`Blend`]).

use crate::progress::Progress;
use crate::set::ExampleSet;
use crate::skinning::error::pose_errors;
use crate::skinning::lbs::Skinning;
use crate::train::cross_validate::{try_cross_validate, Folds};
use crate::train::full_model::{self, FullModel, Prepared};
use crate::train::pose_scale;
use crate::train::scale_shear::ScaleShear;
use crate::train::ssd;
use crate::train::TrainError;
use glam::DVec3;

/// Candidate F percentiles and scale/shear ridges (per pose) the cross-validation picks from,
/// the most robust first (the largest near-rigid set, the strongest ridge).
pub const PERCENTILES: [f64; 7] = [95.0, 90.0, 80.0, 70.0, 50.0, 25.0, 10.0];
pub const RIDGES: [f64; 4] = [1.0, 1e-1, 1e-2, 1e-3];

/// What the cross-validation chose, with the per-triangle regression weights α it implies.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    pub choice: Choice,
    /// Per triangle, the regression's weight α in the Poisson target (1: the paper).
    pub alpha: Vec<f64>,
}

impl Selection {
    /// The paper's choices where there are too few poses to cross-validate.
    fn fallback(triangles: usize) -> Selection {
        Selection {
            choice: Choice {
                percentile: 90.0,
                ridge: 1e-2,
                blend: Blend::Regression,
            },
            alpha: vec![1.0; triangles],
        }
    }
}

/// What a training run on some poses produces, for every (percentile, ridge) candidate.
struct FoldFit {
    ssd: Skinning,
    ssd_error: Vec<f64>,
    rotations: full_model::Rotations,
    /// Per ridge of [`RIDGES`], the triangles' scale/shear.
    stretches: Vec<Vec<ScaleShear>>,
}

fn fit_fold(set: &ExampleSet, prep: &Prepared, train: &[usize], k: usize) -> FoldFit {
    let errors = crate::skinning::lbs::rigid_errors(set, train);
    let ssd = ssd::fit(set, train, &errors, k);
    let ssd_error = crate::skinning::lbs::per_vertex_error(set, train, &ssd);
    let nearby = full_model::nearby_bones(set, &ssd);
    let rotations = full_model::fit_rotations(set, prep, train, &nearby);
    let stretches = RIDGES
        .iter()
        .map(|&ridge| full_model::fit_stretches(set, prep, train, &rotations, ridge))
        .collect();
    FoldFit {
        ssd,
        ssd_error,
        rotations,
        stretches,
    }
}

/// What the cross-validation chose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Choice {
    pub percentile: f64,
    pub ridge: f64,
    pub blend: Blend,
}

/// How each triangle's Poisson target combines the regression with SSD's gradient.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Blend {
    /// The regression alone (the paper).
    Regression,
    /// SSD's gradient where it generalised better on the held-out folds, else the regression.
    Switch,
    /// α D_rr + (1 − α) D_ssd with α minimising the held-out edge error.
    Weighted,
}

fn dot(a: &[DVec3; 2], b: &[DVec3; 2]) -> f64 {
    a[0].dot(b[0]) + a[1].dot(b[1])
}

/// Per ridge, per triangle, over the held-out poses of all folds: the edge residuals of the
/// regression (e_r) and of SSD's gradient (e_s), as Σ|e_r|², Σ|e_s|² and Σ e_r·e_s.
struct TriangleScores {
    regression: Vec<Vec<f64>>,
    cross: Vec<Vec<f64>>,
    ssd: Vec<f64>,
}

impl TriangleScores {
    /// Per triangle, the weight α of the regression in D = α D_rr + (1 − α) D_ssd, for ridge
    /// index r. Weighted: α minimises the held-out edge error |α e_r + (1 − α) e_s|², clamped
    /// to [0, 1]; Switch: α ∈ {0, 1}, whichever erred less.
    fn alpha(&self, r: usize, blend: Blend) -> Vec<f64> {
        (0..self.ssd.len())
            .map(|k| {
                let (rr, ss, rs) = (self.regression[r][k], self.ssd[k], self.cross[r][k]);
                let denom = rr + ss - 2.0 * rs;
                match blend {
                    Blend::Regression => 1.0,
                    Blend::Switch => f64::from(u8::from(rr <= ss)),
                    Blend::Weighted if denom > 0.0 => ((ss - rs) / denom).clamp(0.0, 1.0),
                    Blend::Weighted => 1.0,
                }
            })
            .collect()
    }
}

/// k-fold cross-validation over the training poses: first the per-triangle held-out gradient
/// errors (which triangles fall back to SSD), then the held-out vertex error of every
/// (percentile, ridge, fallback) candidate ([`candidates`]), ruled as every cross-validation
/// here is ([`crate::train::cross_validate`]; `rigid` normalises each held-out pose's error);
/// returns the one kept and its triangles' regression weights.
pub fn choose(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    rigid: &Skinning,
    k: usize,
    folds: usize,
    progress: &Progress,
) -> Result<Selection, TrainError> {
    let Some(folds) = Folds::new(train.len(), folds) else {
        return Ok(Selection::fallback(set.faces.len()));
    };
    let (fits, scores) = fit_folds(set, prep, train, k, &folds, progress);
    let candidates = candidates();
    let normaliser = pose_scale::rigid_pose_errors(set, train, rigid);
    let validated = try_cross_validate(&folds, &normaliser, candidates.len(), 0.0, |fold| {
        let fit = &fits[fold.index];
        let (_, held) = fold.poses(train);
        (candidates.iter())
            .map(|choice| {
                let r = ridge_index(choice.ridge);
                let model = FullModel::new(
                    set,
                    fit.rotations.clone(),
                    fit.stretches[r].clone(),
                    full_model::near_rigid(set, &fit.ssd_error, choice.percentile),
                    scores.alpha(r, choice.blend),
                    choice.ridge,
                )?;
                Ok(pose_errors(
                    set,
                    &held,
                    &model.predict(set, prep, &fit.ssd, &held),
                ))
            })
            .collect::<Result<_, TrainError>>()
    })?;
    let choice = candidates[validated.chosen];
    Ok(Selection {
        choice,
        alpha: scores.alpha(ridge_index(choice.ridge), choice.blend),
    })
}

/// The candidates, most robust first: the paper's regression before the blends with SSD's
/// gradient that the held-out folds fit (Switch, one bit per triangle, before Weighted, one
/// weight), then the strongest ridge and the largest near-rigid set (the most vertices following
/// SSD) first.
pub fn candidates() -> Vec<Choice> {
    [Blend::Regression, Blend::Switch, Blend::Weighted]
        .into_iter()
        .flat_map(|blend| {
            RIDGES.into_iter().flat_map(move |ridge| {
                PERCENTILES.map(|percentile| Choice {
                    percentile,
                    ridge,
                    blend,
                })
            })
        })
        .collect()
}

fn ridge_index(ridge: f64) -> usize {
    RIDGES.iter().position(|&x| x == ridge).unwrap_or(0)
}

/// Per fold of `folds`, the fit on its inner poses; and, over the held-out poses of all folds,
/// the triangles' gradient scores.
fn fit_folds(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    k: usize,
    folds: &Folds,
    progress: &Progress,
) -> (Vec<FoldFit>, TriangleScores) {
    let edges = full_model::rest_edges(set);
    let inverses = crate::train::gradients::rest_inverses(&set.rest, &set.faces);
    let t = set.faces.len();
    let mut scores = TriangleScores {
        regression: vec![vec![0.0; t]; RIDGES.len()],
        cross: vec![vec![0.0; t]; RIDGES.len()],
        ssd: vec![0.0; t],
    };
    let mut fits = Vec::with_capacity(folds.count());
    for fold in folds.iter() {
        let (inner, held) = fold.poses(train);
        let fit = fit_fold(set, prep, &inner, k);
        for &i in &held {
            let skinned = fit.ssd.deform(&set.rest, &set.poses[i].bones);
            let ssd_grads = crate::train::gradients::gradients(&skinned, &set.faces, &inverses);
            for kk in 0..t {
                let (r, sv) = prep.polar[i][kk];
                let truth = r * sv;
                let e_ssd = full_model::edge_residuals(ssd_grads[kk], truth, &edges[kk]);
                scores.ssd[kk] += dot(&e_ssd, &e_ssd);
                for (ri, h) in fit.stretches.iter().enumerate() {
                    let d = full_model::predict_gradient(
                        set,
                        &prep.feats[i],
                        &fit.rotations.0[kk],
                        &h[kk],
                    );
                    let e = full_model::edge_residuals(d, truth, &edges[kk]);
                    scores.regression[ri][kk] += dot(&e, &e);
                    scores.cross[ri][kk] += dot(&e, &e_ssd);
                }
            }
        }
        fits.push(fit);
        progress.step();
    }
    (fits, scores)
}
