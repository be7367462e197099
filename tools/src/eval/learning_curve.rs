//! The learning curve: how the runtime model's held-out error falls with the number of training
//! poses, and whether more poses would help (beyond the paper; docs/method.md §22).
//!
//! - **The curve.** The training poses are split into k folds as every cross-validation splits
//!   them ([`Folds`]). In each fold, the runtime model is trained as asked on the first n of the
//!   fitted-on poses, for n at [`FRACTIONS`] of them (nested: a fixed shuffle of the poses, its
//!   prefixes), and scored on the fold's held-out poses. A point's EE pools the folds:
//!   `EE(n) = 100 sqrt(Σ_folds Σ_held |y − y*|² / Σ_folds Σ_held |r − y*|²)`, r the rigid
//!   predictor of all training poses, so that every point has the same denominator.
//! - **The advice.** A power law with a floor, `EE(n) ≈ a + b n^(−c)` (a, b ≥ 0; c on a grid),
//!   is fitted to the points by least squares ([`fit`]). Doubling the N training poses gains
//!   `(EE(N) − EE(2N)) / EE(N)`. Below [`SATURATED`], or below [`MIN_GAIN`] EE points, the rig
//!   is saturated; otherwise the advice is the pose count past which a further doubling gains
//!   less than either: the least of `(b (1 − s − 2^(−c)) / (s a))^(1/c)`, s = [`SATURATED`],
//!   and `(b (1 − 2^(−c)) / g)^(1/c)`, g = [`MIN_GAIN`], or "more than [`MAX_MULTIPLE`] N"
//!   where that lies further. It extrapolates from a few noisy points, and says so.
//!
//! Every model here is trained on training poses only; the test poses are never looked at.

use crate::progress::Progress;
use crate::set::ExampleSet;
use crate::skinning::error::{deform_all, squared_error};
use crate::skinning::lbs::Skinning;
use crate::train::cross_validate::Folds;
use crate::train::{TrainOptions, MIN_TRAINING_POSES};
use crate::Result;
use rayon::prelude::*;

/// The points' share of each fold's fitted-on poses.
pub const FRACTIONS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];

/// A doubling of the poses that gains less than this share of the error is not worth it.
pub const SATURATED: f64 = 0.05;

/// Nor one that gains less than this many EE points (percent of the rigid predictor's error): a
/// model already near exact (a rig the runtime form reproduces) gains large shares of nothing.
pub const MIN_GAIN: f64 = 0.5;

/// The advice extrapolates at most this far past the training poses.
pub const MAX_MULTIPLE: usize = 8;

/// Fewer poses than this make no point: the structure's own cross-validation needs some.
const MIN_POSES: usize = 4;

/// One point: the runtime model trained on `poses` poses, its held-out EE in percent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    pub poses: usize,
    pub ee: f64,
}

/// The curve's power law `EE(n) = floor + scale n^(−exponent)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerLaw {
    pub floor: f64,
    pub scale: f64,
    pub exponent: f64,
}

/// What the curve says about more poses, for the N training poses the set has.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Advice {
    /// Doubling the poses gains less than [`SATURATED`] (`gain`: the fit's share).
    Saturated { gain: f64 },
    /// Doubling gains `gain`; about `poses` poses reach `ee`, past which a doubling gains less
    /// than [`SATURATED`] (None: more than [`MAX_MULTIPLE`] N).
    MorePoses {
        gain: f64,
        poses: Option<usize>,
        ee: f64,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub struct LearningCurve {
    pub folds: usize,
    /// The set's training poses (N).
    pub training_poses: usize,
    pub points: Vec<Point>,
    /// None with fewer than three points.
    pub fit: Option<PowerLaw>,
    pub advice: Option<Advice>,
}

/// The learning curve of training `set` with `options` (None: too few training poses for
/// folds or for two points). `rigid`: the rigid predictor of all the training poses.
pub fn measure(
    set: &ExampleSet,
    rigid: &Skinning,
    options: &TrainOptions,
) -> Result<Option<LearningCurve>> {
    let train = set.train();
    let Some(split) = Folds::new(train.len(), options.folds) else {
        return Ok(None);
    };
    let order = shuffled(train.len());
    let folds: Vec<_> = split.iter().collect();
    let smallest = folds.iter().map(|f| f.inner.len()).min().unwrap_or(0);
    let counts: Vec<usize> = FRACTIONS
        .iter()
        .map(|f| (f * smallest as f64).round() as usize)
        .filter(|&n| n >= MIN_POSES.max(MIN_TRAINING_POSES))
        .collect();
    if counts.len() < 2 {
        return Ok(None);
    }
    let progress = Progress::new("learning curve", folds.len() * counts.len(), options.quiet)
        .observed(options.observer.clone());
    // Each training quiet: the curve's own progress counts them.
    let options = TrainOptions {
        quiet: true,
        full_model: false,
        ..options.clone()
    };
    let jobs: Vec<(usize, usize)> = (0..folds.len())
        .flat_map(|f| counts.iter().map(move |&n| (f, n)))
        .collect();
    (progress.stage(&format!("{} trainings, on {counts:?} poses", jobs.len())))
        .map_err(crate::train::TrainError::from)?;
    let held: Vec<Vec<usize>> = folds.iter().map(|f| f.poses(&train).1).collect();
    // Every point's denominator: the rigid predictor's squared error over all held poses.
    let reference: f64 = (held.iter())
        .map(|h| squared_error(set, h, &deform_all(set, rigid, h)))
        .sum();
    // Per job: the model's squared error over its fold's held poses.
    let errors: Vec<f64> = jobs
        .par_iter()
        .map(|&(f, n)| {
            let kept: Vec<usize> = (order.iter())
                .filter(|p| folds[f].inner.contains(p))
                .take(n)
                .map(|&p| train[p])
                .collect();
            let left_out: Vec<usize> = (train.iter().copied())
                .filter(|i| !kept.contains(i))
                .collect();
            let error = held_out_error(&set.holding_out(&left_out), set, &held[f], &options)?;
            progress.step();
            Ok(error)
        })
        .collect::<Result<_>>()?;
    progress.finish();
    let points: Vec<Point> = (counts.iter().enumerate())
        .map(|(c, &poses)| {
            let error: f64 = (0..folds.len()).map(|f| errors[f * counts.len() + c]).sum();
            Point {
                poses,
                ee: 100.0 * (error / reference.max(1e-300)).sqrt(),
            }
        })
        .collect();
    let fit = (points.len() >= 3).then(|| fit(&points));
    Ok(Some(LearningCurve {
        folds: folds.len(),
        training_poses: train.len(),
        advice: fit.map(|law| advise(&law, train.len())),
        fit,
        points,
    }))
}

/// The runtime model trained on `inner`'s training poses (SSD where P = 0 trains none), its
/// squared error over the `held` poses of `set`.
fn held_out_error(
    inner: &ExampleSet,
    set: &ExampleSet,
    held: &[usize],
    options: &TrainOptions,
) -> Result<f64> {
    let trained = crate::train::run(inner, options)?;
    let predicted = match &trained.model {
        Some(model) => super::runtime_meshes(set, model, held)?,
        None => deform_all(set, &trained.ssd, held),
    };
    Ok(squared_error(set, held, &predicted))
}

/// Positions 0..n in a fixed pseudo-random order (splitmix64 keys): poses an exporter wrote in
/// a meaningful order (a sweep, an animation) spread over every prefix.
fn shuffled(n: usize) -> Vec<usize> {
    let key = |i: usize| {
        let mut z = (i as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| key(i));
    order
}

/// The least-squares power law with a floor through `points`: for each exponent of a grid, the
/// non-negative floor and scale solve a 2 x 2 least-squares problem (clamped to ≥ 0).
pub fn fit(points: &[Point]) -> PowerLaw {
    let residual = |law: &PowerLaw| -> f64 {
        (points.iter())
            .map(|p| (p.ee - law.at(p.poses as f64)).powi(2))
            .sum()
    };
    // The first exponent of least residual; the grid is never empty.
    let grid = (2..=60).map(|i| fit_linear(points, 0.05 * i as f64));
    grid.fold(fit_linear(points, 0.05), |best, law| {
        match residual(&law) < residual(&best) {
            true => law,
            false => best,
        }
    })
}

/// Floor and scale ≥ 0 minimising Σ (ee − floor − scale n^(−c))² for a fixed c.
fn fit_linear(points: &[Point], exponent: f64) -> PowerLaw {
    let x: Vec<f64> = points
        .iter()
        .map(|p| (p.poses as f64).powf(-exponent))
        .collect();
    let y: Vec<f64> = points.iter().map(|p| p.ee).collect();
    let m = x.len() as f64;
    let (sx, sy) = (x.iter().sum::<f64>(), y.iter().sum::<f64>());
    let sxx: f64 = x.iter().map(|v| v * v).sum();
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
    let det = m * sxx - sx * sx;
    let (mut floor, mut scale) = match det.abs() > 1e-300 {
        true => ((sy * sxx - sx * sxy) / det, (m * sxy - sx * sy) / det),
        false => (sy / m, 0.0),
    };
    // On a bound, the other parameter alone.
    if scale < 0.0 {
        (floor, scale) = (sy / m, 0.0);
    }
    if floor < 0.0 {
        (floor, scale) = (0.0, (sxy / sxx.max(1e-300)).max(0.0));
    }
    PowerLaw {
        floor,
        scale,
        exponent,
    }
}

impl PowerLaw {
    /// EE at n poses.
    pub fn at(&self, n: f64) -> f64 {
        self.floor + self.scale * n.powf(-self.exponent)
    }

    /// The share of EE(n) that doubling n poses gains.
    pub fn doubling_gain(&self, n: f64) -> f64 {
        let here = self.at(n);
        match here > 0.0 {
            true => self.doubling_points(n) / here,
            false => 0.0,
        }
    }

    /// The EE points that doubling n poses gains.
    pub fn doubling_points(&self, n: f64) -> f64 {
        self.at(n) - self.at(2.0 * n)
    }

    /// Whether doubling n poses gains too little to be worth it.
    pub fn saturated_at(&self, n: f64) -> bool {
        self.doubling_gain(n) < SATURATED || self.doubling_points(n) < MIN_GAIN
    }
}

/// What `law` says about more than the `poses` training poses.
pub fn advise(law: &PowerLaw, poses: usize) -> Advice {
    let gain = law.doubling_gain(poses as f64);
    if law.saturated_at(poses as f64) {
        return Advice::Saturated { gain };
    }
    // The pose count where a doubling gains s of the error, b n^(−c) (1 − s − 2^(−c)) = s a,
    // or g points, b n^(−c) (1 − 2^(−c)) = g: whichever comes first.
    let c = law.exponent;
    let relative =
        (law.scale * (1.0 - SATURATED - 2f64.powf(-c)) / (SATURATED * law.floor)).powf(1.0 / c);
    let absolute = (law.scale * (1.0 - 2f64.powf(-c)) / MIN_GAIN).powf(1.0 / c);
    let needed = Some(relative.min(absolute))
        .filter(|n| n.is_finite() && *n <= (MAX_MULTIPLE * poses) as f64)
        .map(|n| n.ceil() as usize);
    let ee = law.at(needed.map_or((MAX_MULTIPLE * poses) as f64, |n| n as f64));
    Advice::MorePoses {
        gain,
        poses: needed,
        ee,
    }
}

impl LearningCurve {
    /// The advice as one plain sentence.
    pub fn sentence(&self) -> String {
        let n = self.training_poses;
        match self.advice {
            None => "too few points to say whether more poses would help".into(),
            Some(Advice::Saturated { gain }) => format!(
                "saturated: doubling the {n} training poses would lower the held-out error by about {:.0} % ({:.2} EE points); more poses of this kind would add little",
                100.0 * gain,
                self.fit.map_or(0.0, |f| f.doubling_points(n as f64))
            ),
            Some(Advice::MorePoses { gain, poses, ee }) => {
                let target = match poses {
                    Some(p) => format!("about {p} poses should bring it near {ee:.1} %, past which a doubling gains under {:.0} % or {MIN_GAIN} EE points", 100.0 * SATURATED),
                    None => format!("the fit shows no floor within {MAX_MULTIPLE}x as many ({} poses: {ee:.1} %)", MAX_MULTIPLE * n),
                };
                format!(
                    "more poses would help: doubling the {n} training poses should lower the held-out error by about {:.0} %; {target} (a power law fitted to the curve)",
                    100.0 * gain
                )
            }
        }
    }
}

/// `learning_curve` of the JSON report: `[{"poses": n, "ee": …}, …]`.
pub fn points_json(curve: &LearningCurve) -> serde_json::Value {
    (curve.points.iter())
        .map(|p| serde_json::json!({"poses": p.poses, "ee": p.ee}))
        .collect()
}

/// `learning_curve_advice` of the JSON report: the fit, the doubling's gain, the pose count
/// advised (null: saturated, or none within reach) and the sentence.
pub fn advice_json(curve: &LearningCurve) -> serde_json::Value {
    let (saturated, gain, poses, ee) = match curve.advice {
        None => (None, None, None, None),
        Some(Advice::Saturated { gain }) => (Some(true), Some(gain), None, None),
        Some(Advice::MorePoses { gain, poses, ee }) => (Some(false), Some(gain), poses, Some(ee)),
    };
    serde_json::json!({
        "folds": curve.folds,
        "training_poses": curve.training_poses,
        "fit": curve.fit.map(|f| serde_json::json!({"floor": f.floor, "scale": f.scale, "exponent": f.exponent})),
        "saturated": saturated,
        "doubling_gain": gain,
        "poses": poses,
        "ee": ee,
        "sentence": curve.sentence(),
    })
}

impl LearningCurve {
    /// Two lines of the report's table: the points, then the advice.
    pub fn lines(&self) -> String {
        let points: Vec<String> = (self.points.iter())
            .map(|p| format!("{:.2} at {}", p.ee, p.poses))
            .collect();
        format!(
            "learning curve ({}-fold held-out EE % of the runtime model at n training poses): {}\n  {}\n",
            self.folds,
            points.join(", "),
            self.sentence()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(law: &PowerLaw) -> Vec<Point> {
        [8, 15, 23, 30]
            .map(|poses| Point {
                poses,
                ee: law.at(poses as f64),
            })
            .to_vec()
    }

    #[test]
    fn the_fit_recovers_a_power_law_with_a_floor() {
        let law = PowerLaw {
            floor: 10.0,
            scale: 40.0,
            exponent: 0.7,
        };
        let fitted = fit(&points(&law));
        assert!((fitted.exponent - 0.7).abs() < 1e-9, "{fitted:?}");
        assert!((fitted.floor - 10.0).abs() < 1e-6 && (fitted.scale - 40.0).abs() < 1e-6);
    }

    #[test]
    fn the_advice_is_the_count_where_a_doubling_gains_the_threshold() {
        let law = PowerLaw {
            floor: 10.0,
            scale: 40.0,
            exponent: 0.7,
        };
        let Advice::MorePoses {
            gain,
            poses: Some(n),
            ee,
        } = advise(&law, 40)
        else {
            panic!("{:?}", advise(&law, 40));
        };
        assert!(
            gain > SATURATED && n > 40 && n <= MAX_MULTIPLE * 40,
            "{gain} {n}"
        );
        // n is the first whole count past the threshold.
        assert!(law.saturated_at(n as f64 + 1e-9));
        assert!(!law.saturated_at(n as f64 - 1.0));
        assert!((ee - law.at(n as f64)).abs() < 1e-12);
    }

    #[test]
    fn a_near_exact_model_is_saturated_whatever_its_share() {
        // Halving a tenth of a percent is no reason for more poses.
        let tiny = PowerLaw {
            floor: 0.0,
            scale: 1.0,
            exponent: 1.0,
        };
        assert!(matches!(advise(&tiny, 40), Advice::Saturated { gain } if gain > 0.4));
    }

    #[test]
    fn a_flat_curve_is_saturated_and_one_without_a_floor_is_not() {
        let flat = [8, 15, 23, 30].map(|poses| Point { poses, ee: 12.0 });
        let fitted = fit(&flat);
        assert_eq!(advise(&fitted, 40), Advice::Saturated { gain: 0.0 });
        let steep = PowerLaw {
            floor: 0.0,
            scale: 100.0,
            exponent: 0.5,
        };
        let advice = advise(&fit(&points(&steep)), 40);
        assert!(
            matches!(advice, Advice::MorePoses { poses: None, .. }),
            "no floor within 8 N: {advice:?}"
        );
    }

    #[test]
    fn the_shuffle_is_a_fixed_permutation() {
        let order = shuffled(40);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..40).collect::<Vec<_>>());
        assert_ne!(order, sorted, "shuffled");
        assert_eq!(order, shuffled(40));
    }
}
