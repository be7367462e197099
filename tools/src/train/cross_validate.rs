//! k-fold cross-validation over the training poses, the one split and the one rule every choice
//! that training makes there goes by (beyond the paper; docs/method.md §14, §18): the full
//! model's selection, the runtime model's structure, the joint-blend keys' stretch and refit
//! ridges, the proxy correctives and the pose-space correctives. A stage supplies its
//! candidates, a fit per fold and each held-out pose's squared vertex error; this module splits,
//! assembles the errors and picks the winner.
//!
//! - **The split.** Pose n of the training list (its position, not its index in the set) is
//!   held out in fold n mod k ([`Folds`]). With fewer than two folds (fewer than two training
//!   poses, or k < 2) there is nothing to hold out against, and [`Folds::new`] says so: every
//!   stage then keeps a fixed choice of its own.
//! - **The score.** Every held-out pose counts by its relative error: its squared vertex error
//!   divided by the rigid predictor's in the same pose (the denominator of the pose's EE², floored
//!   as [`crate::train::pose_scale`] explains), averaged over the poses. Random range-of-motion
//!   training poses are far wider than animation, and a plain sum of squares is carried by the
//!   widest of them.
//! - **The rule**: one standard error (Breiman et al. 1984, *Classification and Regression
//!   Trees*, §3.4.3). Candidates are listed most robust (most regularised, cheapest) first; the
//!   first whose score is within one standard error of the best is kept, the standard error being
//!   that of the per-pose difference to the best (paired over the same held-out poses). A more
//!   flexible candidate has to win clearly on the training poses, not by a margin another fold or
//!   the gentler animation undoes (docs/experiments.md).

use rayon::prelude::*;
use std::convert::Infallible;

/// The k-fold split of a training list of `poses` poses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Folds {
    poses: usize,
    count: usize,
}

/// One fold, as positions in the training list: the poses fitted on and those held out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fold {
    pub index: usize,
    pub inner: Vec<usize>,
    pub held: Vec<usize>,
}

impl Folds {
    /// `asked` folds over `poses` training poses, at most one per pose; None where that leaves
    /// fewer than two.
    pub fn new(poses: usize, asked: usize) -> Option<Folds> {
        let count = asked.min(poses);
        (count >= 2).then_some(Folds { poses, count })
    }

    /// k.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Fold `index`: the positions n with n mod k = `index` held out, the others fitted on.
    pub fn fold(&self, index: usize) -> Fold {
        let (held, inner) = (0..self.poses).partition(|n| n % self.count == index);
        Fold { index, inner, held }
    }

    /// Every fold, in order.
    pub fn iter(&self) -> impl Iterator<Item = Fold> + '_ {
        (0..self.count).map(|k| self.fold(k))
    }
}

impl Fold {
    /// The fold's poses of the training list `train`: (fitted on, held out).
    pub fn poses(&self, train: &[usize]) -> (Vec<usize>, Vec<usize>) {
        let of = |positions: &[usize]| positions.iter().map(|&n| train[n]).collect();
        (of(&self.inner), of(&self.held))
    }
}

/// A candidate's score and standard error: the mean over the held-out poses of its relative
/// squared error (EE² / 100²), and the standard error of its per-pose difference to the best
/// candidate's (0 for the best).
pub type Score = (f64, f64);

/// What [`cross_validate`] found: every candidate's [`Score`], in the order given, and the
/// position of the one kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Validated {
    pub scores: Vec<Score>,
    pub chosen: usize,
    /// Candidates x training poses (list order): each held-out pose's relative error.
    pub relative: Vec<Vec<f64>>,
}

impl Validated {
    /// The rule with `tolerance` over `relative` (candidates x training poses, most robust
    /// first): the scores and the candidate kept.
    pub fn of(relative: Vec<Vec<f64>>, tolerance: f64) -> Validated {
        let scores = scores(&relative);
        let chosen = first_within(&scores, tolerance);
        Validated {
            scores,
            chosen,
            relative,
        }
    }

    /// The rule again over the first `n` candidates alone, with `tolerance`: the choice had the
    /// later ones not been offered (a costlier candidate that did not win by its margin).
    pub fn among_first(&self, n: usize, tolerance: f64) -> Validated {
        Validated::of(self.relative[..n].to_vec(), tolerance)
    }
}

/// Cross-validates `candidates` candidates, listed most robust first, over `folds`.
///
/// `held_out(fold)` fits every candidate on the fold's inner poses (sharing whatever work the
/// candidates share) and returns, per candidate (`candidates` rows), the squared vertex error
/// Σ_a |y_a − y_a^i|² of each of the fold's held-out poses (`fold.held.len()` columns, in
/// `fold.held` order). The folds run in parallel. `normaliser` holds per training pose (in list
/// order) the rigid predictor's squared error ([`crate::train::pose_scale::rigid_pose_errors`]):
/// the errors divided by it form the candidates x poses matrix of relative errors, which
/// [`scores`] and [`first_within`] rule on. `tolerance` widens the rule: a candidate within that
/// relative EE of the best is kept too (0: the plain rule).
pub fn cross_validate<F>(
    folds: &Folds,
    normaliser: &[f64],
    candidates: usize,
    tolerance: f64,
    held_out: F,
) -> Validated
where
    F: Fn(&Fold) -> Vec<Vec<f64>> + Sync,
{
    let fallible = |fold: &Fold| Ok::<_, Infallible>(held_out(fold));
    let Ok(validated) = try_cross_validate(folds, normaliser, candidates, tolerance, fallible);
    validated
}

/// [`cross_validate`] for a fit that can fail: the first fold's error, if any.
pub fn try_cross_validate<F, E>(
    folds: &Folds,
    normaliser: &[f64],
    candidates: usize,
    tolerance: f64,
    held_out: F,
) -> Result<Validated, E>
where
    F: Fn(&Fold) -> Result<Vec<Vec<f64>>, E> + Sync,
    E: Send,
{
    assert_eq!(
        normaliser.len(),
        folds.poses,
        "one normaliser per training pose"
    );
    let per_fold: Vec<(Fold, Vec<Vec<f64>>)> = (0..folds.count)
        .into_par_iter()
        .map(|k| {
            let fold = folds.fold(k);
            held_out(&fold).map(|errors| (fold, errors))
        })
        .collect::<Result<_, E>>()?;
    let mut relative = vec![vec![0.0; folds.poses]; candidates];
    for (fold, errors) in &per_fold {
        assert_eq!(errors.len(), candidates, "one row per candidate");
        for (row, errors) in relative.iter_mut().zip(errors) {
            assert_eq!(errors.len(), fold.held.len(), "one error per held-out pose");
            for (&n, e) in fold.held.iter().zip(errors) {
                row[n] = e / normaliser[n];
            }
        }
    }
    Ok(Validated::of(relative, tolerance))
}

/// Per candidate (rows of `relative`: its per-pose relative errors, every row over the same
/// poses), the mean and the standard error of its per-pose difference to the best candidate's
/// (zero for the best itself): what the one-standard-error rule compares.
pub fn scores(relative: &[Vec<f64>]) -> Vec<Score> {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let means: Vec<f64> = relative.iter().map(|r| mean(r)).collect();
    let best = (0..means.len())
        .min_by(|&x, &y| means[x].total_cmp(&means[y]))
        .unwrap_or(0);
    relative
        .iter()
        .zip(&means)
        .map(|(r, &score)| {
            let diff: Vec<f64> = r.iter().zip(&relative[best]).map(|(x, y)| x - y).collect();
            let m = mean(&diff);
            let n = diff.len();
            let variance =
                diff.iter().map(|d| (d - m).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64;
            (score, (variance / n.max(1) as f64).sqrt())
        })
        .collect()
}

/// The one-standard-error rule over `scored` (most robust first): the first candidate whose
/// score is within one standard error of the best, or within `tolerance` of the best's EE (a
/// score is EE², so within (1 + tolerance)² of it). The first candidate where no score is a
/// number.
pub fn first_within(scored: &[Score], tolerance: f64) -> usize {
    let best = scored.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
    let within = (1.0 + tolerance).powi(2) * best;
    (0..scored.len())
        .find(|&c| scored[c].0 <= (best + scored[c].1).max(within))
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pose n is held out in fold n mod k; every pose is held out once and fitted on k − 1 times.
    #[test]
    fn pose_n_is_held_out_in_fold_n_mod_k() {
        let folds = Folds::new(7, 3).expect("three folds");
        assert_eq!(folds.count(), 3);
        let fold = folds.fold(1);
        assert_eq!(fold.held, [1, 4]);
        assert_eq!(fold.inner, [0, 2, 3, 5, 6]);
        let train = [10, 11, 12, 13, 14, 15, 16];
        assert_eq!(fold.poses(&train), (vec![10, 12, 13, 15, 16], vec![11, 14]));
        let mut held: Vec<usize> = folds.iter().flat_map(|f| f.held).collect();
        held.sort_unstable();
        assert_eq!(held, (0..7).collect::<Vec<_>>());
    }

    /// At most one fold per pose; fewer than two folds is no cross-validation.
    #[test]
    fn fewer_than_two_folds_is_none() {
        assert_eq!(Folds::new(3, 4).map(|f| f.count()), Some(3));
        assert_eq!(Folds::new(2, 2).map(|f| f.count()), Some(2));
        assert_eq!(Folds::new(1, 4), None);
        assert_eq!(Folds::new(0, 4), None);
        assert_eq!(Folds::new(10, 1), None);
        assert_eq!(Folds::new(10, 0), None);
    }

    /// The helper fits each fold once, divides every held-out pose's error by its normaliser
    /// and places it at the pose's position.
    #[test]
    fn the_matrix_is_held_out_error_over_the_normaliser() {
        let folds = Folds::new(4, 2).expect("two folds");
        let normaliser = [1.0, 2.0, 4.0, 8.0];
        // Candidate c errs by (c + 1) x (1 + the fold's index) x the normaliser on each pose it
        // holds out: relative errors 1, 2, 1, 2 for the first, twice those for the second.
        let v = cross_validate(&folds, &normaliser, 2, 0.0, |fold| {
            (1..=2)
                .map(|c| {
                    (fold.held.iter())
                        .map(|&n| (c * (1 + fold.index)) as f64 * normaliser[n])
                        .collect()
                })
                .collect()
        });
        assert_eq!(v.scores[0], (1.5, 0.0));
        assert_eq!(v.scores[1].0, 3.0);
        assert_eq!(v.chosen, 0);
        // A fold's error is the result.
        let failed = try_cross_validate(&folds, &normaliser, 2, 0.0, |fold| match fold.index {
            1 => Err("no fit"),
            _ => Ok(vec![vec![1.0; fold.held.len()]; 2]),
        });
        assert_eq!(failed, Err("no fit"));
    }

    /// Per-pose scores of three candidates over four poses: the rule keeps the first that is
    /// not clearly beaten.
    #[test]
    fn the_first_candidate_not_clearly_beaten_is_kept() {
        let clear = [
            vec![1.0, 2.0, 1.0, 2.0],
            vec![0.81, 1.62, 0.81, 1.62],
            vec![1.0, 2.0, 1.0, 2.0],
        ];
        let scored = scores(&clear);
        assert_eq!(scored[1].1, 0.0);
        assert_eq!(first_within(&scored, 0.03), 1);
        // A gain of 3.4 % EE that one pose of four carries and another undoes: within one
        // standard error.
        let noisy = [
            vec![1.0, 2.0, 1.0, 2.0],
            vec![0.2, 2.0, 1.0, 2.4],
            vec![1.0, 2.0, 1.0, 2.0],
        ];
        let scored = scores(&noisy);
        assert!(scored[0].1 > 0.0);
        assert_eq!(first_within(&scored, 0.0), 0);
        // A consistent gain of 1 % EE: below a tolerance of 3 %, kept without one.
        let base = [1.0, 2.0, 1.0, 2.0];
        let small: Vec<Vec<f64>> = [1.0, 0.99f64.powi(2), 1.0]
            .iter()
            .map(|f| base.iter().map(|x| x * f).collect())
            .collect();
        assert_eq!(first_within(&scores(&small), 0.03), 0);
        assert_eq!(first_within(&scores(&small), 0.0), 1);
        // No score a number: the first.
        assert_eq!(first_within(&[(f64::NAN, 0.0), (f64::NAN, 0.0)], 0.0), 0);
    }
}
