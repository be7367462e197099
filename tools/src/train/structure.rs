//! The runtime model's structure, chosen per set on the training poses (beyond the paper;
//! docs/method.md §18): which proxies (joint-blend or the paper's reduction), how many (P) and
//! how many influences per vertex (K).
//!
//! Every candidate is trained end to end on k − 1 folds of the training poses and scored on
//! the held-out fold. Two things make this differ from plain cross-validation, both because the
//! training poses are random range-of-motion poses, far wider than the animation a model is
//! used for, and cross-validation over them prefers what fits wide poses (docs/experiments.md):
//!
//! - **The score weighs every held-out pose alike**: its squared vertex error relative to the
//!   rigid predictor's in the same pose (the pose's EE²), averaged over the poses. The plain
//!   sum of squared errors is carried by the widest poses, whose rigid error is largest.
//! - **The one-standard-error rule** (Breiman et al. 1984): the candidates are listed in an
//!   order fixed in advance, most robust and cheapest first (fewer proxies, fewer influences,
//!   geometric proxies before regressed ones), and the first whose score is within one
//!   standard error of the best (the paired per-pose difference's), or within
//!   [`TOLERANCE`] of its EE, is kept. A more flexible structure has to win clearly on the
//!   training poses, not by what a different held-out fold or the gentler animation undoes.

use crate::import::example_set::ExampleSet;
use crate::train::full_model::{self, Prepared};
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::refit::{self, Refit};
use crate::train::reduce::{self, joint_blend, vertex::Stop, Reduction};
use crate::train::rotreg::PoseFeatures;
use crate::train::selection::Selection;
use crate::train::ssd::{self, Skinning};
use crate::train::{augment, pose_scale, Method, TrainError, TrainOptions};

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
}

/// What the full model provides the paper's reduction: the prepared gradients and the
/// cross-validated selection (kept as made on all training poses inside the folds, as
/// leave-one-out does).
pub struct FullParts<'a> {
    pub prep: &'a Prepared,
    pub selection: &'a Selection,
}

/// The candidates, most robust first (see the module docs). P_max = `options.proxies`:
///
/// - joint-blend proxies, P_max, K = SSD's;
/// - joint-blend with 1.5 P_max, when the set has more candidate proxies than P_max;
/// - joint-blend with K = 8, when SSD's K is 4;
/// - the paper's reduction with P_max, when joint-blend cannot fill P_max (a rig with few
///   bones) and the full model is there (`train::run` trains it then, if P_max is at most the
///   triangles).
pub fn candidates(options: &TrainOptions, pool: usize, full: bool) -> Vec<Structure> {
    let (p, k) = (options.proxies, options.influences);
    let joint_blend = |proxies, influences| Structure {
        method: Method::JointBlend,
        proxies,
        influences,
    };
    let mut out = vec![joint_blend(p, k)];
    if pool > p {
        out.push(joint_blend(p + p / 2, k));
    }
    if k == 4 {
        out.push(joint_blend(p, 8));
    }
    if full && pool < p {
        out.push(Structure {
            method: Method::Paper,
            proxies: p,
            influences: k,
        });
    }
    out
}

/// Trains `structure` on `set`'s training poses (`ssd` fitted on them; `full` the full model
/// fitted on them, needed by the paper's reduction).
pub fn build(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    full: Option<(&Prepared, &full_model::FullModel)>,
    structure: &Structure,
    options: &TrainOptions,
) -> (Reduced, Option<Refit>) {
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
        // Joint-blend proxies (the paper's reduction is never a candidate without its model).
        _ => {
            let mut r = joint_blend::fit(set, feats, &train, ssd, structure.proxies, k);
            let chosen = refit::refit(set, feats, &train, options.folds, &mut r);
            joint_blend::reweight(set, feats, &train, ssd, k, &mut r);
            (r, Some(chosen))
        }
    }
}

/// `set` with the poses of `held` marked held out, so that everything trained on it sees the
/// other training poses only.
fn without(set: &ExampleSet, held: &[usize]) -> ExampleSet {
    let mut inner = set.clone();
    for &i in held {
        inner.is_test[i] = true;
    }
    inner
}

/// Cross-validates `candidates` over the training poses of `set` and keeps one by the
/// one-standard-error rule (module docs). `rigid`: the rigid predictor whose per-pose error
/// normalises each held-out pose.
pub fn choose(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    rigid: &Skinning,
    full: Option<&FullParts>,
    candidates: &[Structure],
    options: &TrainOptions,
) -> Result<Chosen, TrainError> {
    let train = set.train();
    let folds = options.folds.min(train.len());
    if folds < 2 || candidates.len() < 2 {
        return Ok(Chosen {
            structure: candidates[0],
            candidates: Vec::new(),
            folds,
        });
    }
    let normaliser = pose_scale::rigid_pose_errors(set, &train, rigid);
    // Per candidate, per training pose (in `train` order): held-out relative squared error.
    let mut relative = vec![vec![0.0; train.len()]; candidates.len()];
    for fold in 0..folds {
        let held: Vec<usize> = (0..train.len()).filter(|n| n % folds == fold).collect();
        let held_poses: Vec<usize> = held.iter().map(|&n| train[n]).collect();
        let inner_set = without(set, &held_poses);
        let inner = inner_set.train();
        let ssd = ssd::fit(
            &inner_set,
            &inner,
            &ssd::rigid_errors(&inner_set, &inner),
            options.influences,
        );
        let paper_needed = candidates.iter().any(|s| s.method == Method::Paper);
        let inner_full = match (full, paper_needed) {
            (Some(f), true) => Some(full_model::fit(
                &inner_set,
                f.prep,
                &inner,
                &ssd,
                f.selection,
            )?),
            _ => None,
        };
        let model = full.zip(inner_full.as_ref()).map(|(f, m)| (f.prep, m));
        for (c, structure) in candidates.iter().enumerate() {
            let (reduced, _) = build(&inner_set, feats, &ssd, model, structure, options);
            for (&n, &i) in held.iter().zip(&held_poses) {
                let pose = &set.poses[i];
                let y = reduced.predict(set, &feats[i], &pose.bones);
                relative[c][n] = squared(&y, &pose.vertices) / normaliser[n];
            }
        }
    }
    let scored = one_standard_error(candidates, &relative);
    let kept = pick(&scored);
    Ok(Chosen {
        structure: scored[kept].structure,
        candidates: scored,
        folds,
    })
}

fn squared(a: &[glam::DVec3], b: &[glam::DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum::<f64>()
}

/// Every candidate's mean per-pose score, and the standard error of its per-pose difference to
/// the best candidate's (zero for the best itself).
fn one_standard_error(candidates: &[Structure], relative: &[Vec<f64>]) -> Vec<Scored> {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let scores: Vec<f64> = relative.iter().map(|r| mean(r)).collect();
    let best = (0..scores.len())
        .min_by(|&x, &y| scores[x].total_cmp(&scores[y]))
        .unwrap_or(0);
    candidates
        .iter()
        .zip(relative)
        .zip(&scores)
        .map(|((&structure, r), &score)| {
            let diff: Vec<f64> = r.iter().zip(&relative[best]).map(|(x, y)| x - y).collect();
            let m = mean(&diff);
            let n = diff.len();
            let variance =
                diff.iter().map(|d| (d - m).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64;
            Scored {
                structure,
                score,
                standard_error: (variance / n.max(1) as f64).sqrt(),
            }
        })
        .collect()
}

/// Below this relative EE difference a more flexible (and for K = 8 or a larger P, costlier)
/// structure is not worth it: differences of a few percent on held-out range-of-motion poses
/// are what the animation's gentler poses undo (docs/experiments.md).
pub const TOLERANCE: f64 = 0.03;

/// The first candidate within one standard error, or within [`TOLERANCE`] of EE, of the best.
fn pick(scored: &[Scored]) -> usize {
    let best = scored.iter().map(|s| s.score).fold(f64::INFINITY, f64::min);
    let within = (1.0 + TOLERANCE).powi(2) * best;
    scored
        .iter()
        .position(|s| s.score <= (best + s.standard_error).max(within))
        .unwrap_or(0)
}

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

    /// The paper's reduction is a candidate only where joint-blend proxies cannot fill P and
    /// the full model is there; more proxies only where the pool has them; K = 8 from 4.
    #[test]
    fn candidates_follow_the_rig() {
        let options = TrainOptions::default();
        let (p, k) = (options.proxies, options.influences);
        assert_eq!(
            candidates(&options, 3 * p, true),
            vec![
                joint_blend(p, k),
                joint_blend(p + p / 2, k),
                joint_blend(p, 8)
            ]
        );
        let few = candidates(&options, 9, true);
        assert_eq!(few.len(), 3);
        assert_eq!(few[2].method, Method::Paper);
        assert_eq!(candidates(&options, 9, false).len(), 2);
    }

    /// Per-pose scores of three candidates over four poses: the rule keeps the first that is
    /// not clearly beaten.
    #[test]
    fn the_first_candidate_not_clearly_beaten_is_kept() {
        let structures = [joint_blend(60, 4), joint_blend(60, 8), joint_blend(90, 4)];
        let clear = vec![
            vec![1.0, 2.0, 1.0, 2.0],
            vec![0.81, 1.62, 0.81, 1.62],
            vec![1.0, 2.0, 1.0, 2.0],
        ];
        let scored = one_standard_error(&structures, &clear);
        assert_eq!(scored[1].standard_error, 0.0);
        assert_eq!(pick(&scored), 1);
        // A gain of 3.4 % EE that one pose of four carries and another undoes: within one
        // standard error.
        let noisy = vec![
            vec![1.0, 2.0, 1.0, 2.0],
            vec![0.2, 2.0, 1.0, 2.4],
            vec![1.0, 2.0, 1.0, 2.0],
        ];
        let scored = one_standard_error(&structures, &noisy);
        assert!(scored[0].standard_error > 0.0);
        assert_eq!(pick(&scored), 0);
        // A consistent gain of 1 % EE: below the tolerance.
        let base = [1.0, 2.0, 1.0, 2.0];
        let small: Vec<Vec<f64>> = [1.0, 0.99f64.powi(2), 1.0]
            .iter()
            .map(|f| base.iter().map(|x| x * f).collect())
            .collect();
        assert_eq!(pick(&one_standard_error(&structures, &small)), 0);
    }
}
