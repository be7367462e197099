//! The runtime model's structure, chosen per set on the training poses (beyond the paper;
//! docs/method.md §18): how many joint-blend proxies (P), fewer or more than asked.
//!
//! Every candidate is trained end to end on k − 1 folds of the training poses (with the
//! stretch and refit ridges chosen once on all of them) and scored on the held-out fold. Two things make this differ from plain cross-validation, both because the
//! training poses are random range-of-motion poses, far wider than the animation a model is
//! used for, and cross-validation over them prefers what fits wide poses (docs/experiments.md):
//!
//! - **The score weighs every held-out pose alike**: its squared vertex error relative to the
//!   rigid predictor's in the same pose (the pose's EE²), averaged over the poses. The plain
//!   sum of squared errors is carried by the widest poses, whose rigid error is largest.
//! - **The one-standard-error rule** (Breiman et al. 1984): the candidates are listed in an
//!   order fixed in advance, most robust and cheapest first (fewer proxies first), and the
//!   first whose score is within one
//!   standard error of the best (the paired per-pose difference's), or within
//!   [`TOLERANCE`] of its EE, is kept. A more flexible structure has to win clearly on the
//!   training poses, not by what a different held-out fold or the gentler animation undoes.
//!
//! Both are [`crate::train::cross_validate`]'s, with [`TOLERANCE`].

use crate::set::ExampleSet;
use crate::skinning::error::squared_error;
use crate::skinning::lbs::Skinning;
use crate::train::cross_validate::{cross_validate, Folds};
use crate::train::full_model::{self, Prepared};
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::refit::{self, Refit};
use crate::train::reduce::stretch::{self, Stretch};
use crate::train::reduce::{self, joint_blend, vertex::Stop, Reduction};
use crate::train::rotreg::PoseFeatures;
use crate::train::ssd;
use crate::train::{augment, pose_scale, Method, TrainOptions};
use std::fmt;
use std::sync::{Arc, Mutex};

/// What [`choose`]'s folds built, for a later stage's folds over the same split (the kinds'
/// comparison in [`crate::train::delta_mush`]) to reuse instead of fitting again: per fold
/// (by index), the SSD of its inner poses and every candidate built on them with `ridges`.
#[derive(Default)]
pub struct FoldModels {
    ridges: Option<Ridges>,
    folds: Vec<Option<FoldModel>>,
}

/// One fold's: the SSD of its inner poses, and each candidate built on them.
struct FoldModel {
    ssd: Skinning,
    models: Vec<(Structure, Reduced)>,
}

impl FoldModels {
    /// Fold `fold`'s SSD of its inner poses, where its cross-validation ran.
    pub fn ssd(&self, fold: usize) -> Option<&Skinning> {
        self.folds.get(fold)?.as_ref().map(|f| &f.ssd)
    }

    /// `structure` as fold `fold` built it, where it did with `ridges`.
    pub fn model(&self, fold: usize, structure: &Structure, ridges: Ridges) -> Option<&Reduced> {
        let built = self.folds.get(fold)?.as_ref()?;
        let found = built.models.iter().find(|(s, _)| s == structure);
        found
            .filter(|_| self.ridges == Some(ridges))
            .map(|(_, r)| r)
    }
}

impl fmt::Debug for FoldModels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let built = self.folds.iter().filter(|f| f.is_some()).count();
        write!(f, "FoldModels({built} folds)")
    }
}

/// What the folds built is a cache of the choice, not part of it.
impl PartialEq for FoldModels {
    fn eq(&self, _: &FoldModels) -> bool {
        true
    }
}

/// One runtime model structure. `method` is never [`Method::Auto`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Structure {
    pub method: Method,
    pub proxies: usize,
    pub influences: usize,
}

/// A candidate's cross-validated score: the mean over held-out poses of the pose's relative
/// squared error (EE² / 100²), and the standard error of its per-pose difference to the best.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    pub structure: Structure,
    pub score: f64,
    pub standard_error: f64,
}

/// What [`choose`] chose, with every candidate's score in the order they were considered.
#[derive(Debug, Clone, PartialEq)]
pub struct Chosen {
    pub structure: Structure,
    pub candidates: Vec<Scored>,
    pub folds: usize,
    pub why: Why,
    /// Candidates x training poses: each held-out pose's relative error (empty where not
    /// cross-validated), for the rule again over fewer candidates (the cost budget's).
    pub relative: Vec<Vec<f64>>,
    /// What the folds built (empty where not cross-validated).
    pub built: Arc<FoldModels>,
}

/// How the structure came to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Why {
    /// The caller named it (`--reduction joint-blend` or `paper`).
    Asked,
    /// The rig has one candidate (fewer than three joint-blend proxies, none more than P).
    OnlyCandidate,
    /// Too few training poses to cross-validate: P as given.
    TooFewPoses,
    /// Chosen by cross-validation (`candidates` holds the scores).
    CrossValidated,
    /// Fewer proxies than the cross-validation's choice: the most the cost budget admits.
    Budget,
}

/// The candidates, most robust first (see the module docs). P_max = `options.proxies`, K =
/// `options.influences` (the engine's skinning budget, not chosen here), P' = min(P_max,
/// `pool`) the proxies joint-blend builds from P_max:
///
/// - joint-blend proxies, P'/6 and P'/3 (about one per two moving joints and one per moving
///   joint; left out below one): rigs whose deformation is plain skinning plus local terms
///   (muscle bulges, soft flesh) are met as well or better by fewer proxies and the bones, and
///   every proxy fewer is run time saved;
/// - joint-blend proxies, P_max;
/// - joint-blend with 1.5 P_max, when the set has more candidate proxies than P_max.
///
/// The paper's reduction and K = 8 were candidates too and are not (docs/experiments.md): the
/// paper's reduction never won on seven sets and its folds cost 30–50 s per CesiumMan training;
/// K = 8 is the engine's choice (`--influences 8`), past the runtime's 1.1x cost budget.
pub fn candidates(options: &TrainOptions, pool: usize) -> Vec<Structure> {
    let (p, k) = (options.proxies, options.influences);
    let joint_blend = |proxies| Structure {
        method: Method::JointBlend,
        proxies,
        influences: k,
    };
    let built = p.min(pool);
    let mut out: Vec<Structure> = [built / 6, built / 3]
        .into_iter()
        .filter(|&fewer| fewer > 0)
        .map(joint_blend)
        .collect();
    out.push(joint_blend(p));
    if pool > p {
        out.push(joint_blend(p + p / 2));
    }
    out
}

/// What a joint-blend model's two cross-validated fits chose.
#[derive(Debug, Clone, PartialEq)]
pub struct JointBlendFit {
    pub stretch: Stretch,
    pub refit: Refit,
}

/// The ridges of a joint-blend model's stretch fit and refit, fixed instead of chosen by
/// cross-validation (inside [`choose`]'s folds: chosen there they would nest one
/// cross-validation in another).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ridges {
    pub stretch: Option<f64>,
    pub refit: Option<f64>,
}

impl JointBlendFit {
    pub fn ridges(&self) -> Ridges {
        Ridges {
            stretch: self.stretch.ridge,
            refit: self.refit.ridge,
        }
    }
}

/// Trains `structure` on `set`'s training poses (`ssd` fitted on them; `full` the full model
/// fitted on them, needed by the paper's reduction). A joint-blend model's ridges are chosen
/// by cross-validation unless `ridges` fixes them (then the returned fit holds no scores).
pub fn build(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    full: Option<(&Prepared, &full_model::FullModel)>,
    structure: &Structure,
    options: &TrainOptions,
    ridges: Option<Ridges>,
) -> (Reduced, Option<JointBlendFit>) {
    let train = set.train();
    let k = structure.influences;
    match (structure.method, full) {
        (Method::Paper, Some((prep, model))) => {
            let reduction = Reduction {
                stop: Stop {
                    proxies: structure.proxies,
                    epsilon: options.epsilon,
                },
                influences: k,
            };
            let reduced = match options.gentle_scales.is_empty() {
                true => reduce::run(set, prep, &train, ssd, model, &reduction),
                false => {
                    let wider = augment::augment(set, prep, model, ssd, &options.gentle_scales);
                    let wide_train = wider.set.train();
                    reduce::run(&wider.set, &wider.prep, &wide_train, ssd, model, &reduction)
                }
            };
            (reduced, None)
        }
        // Joint-blend proxies (the paper's reduction is never built without its model).
        _ => {
            let pool = joint_blend::Pool::new(set, feats, &train, ssd, k);
            build_joint_blend(set, feats, ssd, &pool, structure, options, ridges)
        }
    }
}

/// [`build`] of joint-blend proxies from `pool` (made from `set`'s training poses and `ssd`).
fn build_joint_blend(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    pool: &joint_blend::Pool,
    structure: &Structure,
    options: &TrainOptions,
    ridges: Option<Ridges>,
) -> (Reduced, Option<JointBlendFit>) {
    let (train, k) = (set.train(), structure.influences);
    let mut r = pool.fit(set, feats, &train, ssd, structure.proxies, k);
    let fitted = match ridges {
        None => JointBlendFit {
            stretch: stretch::fit(set, feats, &train, options.folds, &mut r),
            refit: refit::refit(set, feats, &train, options.folds, &mut r),
        },
        Some(fixed) => JointBlendFit {
            stretch: stretch::fit_with(set, feats, &train, fixed.stretch, &mut r),
            refit: refit::refit_with(set, feats, &train, fixed.refit, &mut r),
        },
    };
    joint_blend::reweight(set, feats, &train, ssd, k, &mut r);
    (r, Some(fitted))
}

/// Cross-validates `candidates` over the training poses of `set` and keeps one by the
/// one-standard-error rule (module docs). `rigid`: the rigid predictor whose per-pose error
/// normalises each held-out pose; `ridges`: the joint-blend fits' ridges, chosen once on all
/// training poses (for the first candidate) and fixed inside the folds.
pub fn choose(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    rigid: &Skinning,
    candidates: &[Structure],
    ridges: Ridges,
    options: &TrainOptions,
) -> Chosen {
    let train = set.train();
    let folds = options.folds.min(train.len());
    let split = Folds::new(train.len(), options.folds).filter(|_| candidates.len() >= 2);
    let Some(split) = split else {
        // Without folds, the caller's P.
        let asked = candidates.iter().find(|c| c.proxies == options.proxies);
        return Chosen {
            structure: *asked.unwrap_or(&candidates[0]),
            candidates: Vec::new(),
            folds,
            why: match candidates.len() < 2 {
                true => Why::OnlyCandidate,
                false => Why::TooFewPoses,
            },
            relative: Vec::new(),
            built: Arc::default(),
        };
    };
    let normaliser = pose_scale::rigid_pose_errors(set, &train, rigid);
    let built: Vec<Mutex<Option<_>>> = (0..split.count()).map(|_| Mutex::new(None)).collect();
    let validated = cross_validate(&split, &normaliser, candidates.len(), TOLERANCE, |fold| {
        let (_, held) = fold.poses(&train);
        let inner_set = set.holding_out(&held);
        let inner = inner_set.train();
        let ssd = ssd::fit(
            &inner_set,
            &inner,
            &crate::skinning::lbs::rigid_errors(&inner_set, &inner),
            options.influences,
        );
        // The candidates differ only in how many of the pool's proxies they keep.
        let pool = joint_blend::Pool::new(&inner_set, feats, &inner, &ssd, options.influences);
        let mut models = Vec::new();
        let rows = (candidates.iter())
            .map(|structure| {
                let (reduced, _) = build_joint_blend(
                    &inner_set,
                    feats,
                    &ssd,
                    &pool,
                    structure,
                    options,
                    Some(ridges),
                );
                let row = (held.iter())
                    .map(|&i| {
                        let y = reduced.predict(set, &feats[i], &set.poses[i].bones);
                        squared_error(set, &[i], &[y])
                    })
                    .collect();
                models.push((*structure, reduced));
                row
            })
            .collect();
        let mut slot = built[fold.index].lock().unwrap_or_else(|e| e.into_inner());
        *slot = Some(FoldModel { ssd, models });
        rows
    });
    let folds_built = (built.into_iter())
        .map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner()))
        .collect();
    let built = Arc::new(FoldModels {
        ridges: Some(ridges),
        folds: folds_built,
    });
    Chosen {
        structure: candidates[validated.chosen],
        candidates: (candidates.iter().zip(&validated.scores))
            .map(|(&structure, &(score, standard_error))| Scored {
                structure,
                score,
                standard_error,
            })
            .collect(),
        folds,
        why: Why::CrossValidated,
        relative: validated.relative,
        built,
    }
}

/// Below this relative EE difference a more flexible (and for K = 8 or a larger P, costlier)
/// structure is not worth it: differences of a few percent on held-out range-of-motion poses
/// are what the animation's gentler poses undo (docs/experiments.md). The structure's
/// tolerance of the one-standard-error rule; the other stages' candidates differ in
/// regularisation, not run time, and go by the plain rule.
pub const TOLERANCE: f64 = 0.03;

#[cfg(test)]
mod tests {
    use super::*;

    fn joint_blend(proxies: usize, influences: usize) -> Structure {
        Structure {
            method: Method::JointBlend,
            proxies,
            influences,
        }
    }

    /// More proxies are a candidate only where the pool has them; K stays the caller's.
    #[test]
    fn candidates_follow_the_rig() {
        let options = TrainOptions::default();
        let (p, k) = (options.proxies, options.influences);
        assert_eq!(
            candidates(&options, 3 * p),
            [p / 6, p / 3, p, p + p / 2].map(|p| joint_blend(p, k))
        );
        // CesiumMan: 18 moving joints, 54 joint-blend proxies at most.
        assert_eq!(
            candidates(&options, 54),
            [9, 18, p].map(|p| joint_blend(p, k))
        );
        // Fewer than one proxy a sixth of the pool: left out.
        assert_eq!(candidates(&options, 3), [1, p].map(|p| joint_blend(p, k)));
        assert_eq!(candidates(&options, 2), vec![joint_blend(p, k)]);
    }
}
