//! `rrskin eval`: trains every method on the training poses and reports the enveloping error
//! (paper §7.1, METHOD.md §10) on training and test poses.
//!
//! `EE = sqrt(Σ_i Σ_a |y_a(q_i) − y_a^i|² / Σ_i Σ_a |r_a(q_i) − y_a^i|²)` in percent, r the best
//! rigid predictor (one bone per vertex, chosen on the training poses). The full model's two
//! choices — the near-rigid set F (percentile of SSD training error) and the scale/shear ridge —
//! are made by k-fold cross-validation inside the training poses; test poses are never looked at.

use crate::example_set::ExampleSet;
use crate::full_model::{self, FullModel, Prepared};
use crate::progress::Progress;
use crate::ssd::{self, Skinning};
use glam::DVec3;
use std::time::Instant;

/// Folds of the training-pose cross-validation.
pub const FOLDS: usize = 4;
/// Candidate F percentiles and scale/shear ridges (per pose) the cross-validation picks from.
pub const PERCENTILES: [f64; 7] = [10.0, 25.0, 50.0, 70.0, 80.0, 90.0, 95.0];
pub const RIDGES: [f64; 4] = [1e-3, 1e-2, 1e-1, 1.0];

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    pub train: f64,
    pub test: Option<f64>,
}

#[derive(Debug, Clone)]
pub struct Report {
    pub vertices: usize,
    pub triangles: usize,
    pub bones: usize,
    pub train_poses: usize,
    pub test_poses: usize,
    pub rigid: Errors,
    pub ssd: Errors,
    pub rr_full: Errors,
    /// The reduced runtime model, evaluated by the runtime's CPU evaluator.
    pub rr_reduced: Option<Errors>,
    pub rr_reduced_seconds: Option<f64>,
    pub reduced_proxies: Option<usize>,
    /// The runtime model trained here (None with `Options::model` or P = 0).
    pub model: Option<rrskin::Model>,
    pub ssd_seconds: f64,
    pub rr_full_seconds: f64,
    /// F percentile, ridge and fallback chosen by cross-validation.
    pub choice: Choice,
    /// Mean weight of the regression in the triangles' blended gradients (1: the paper).
    pub mean_alpha: f64,
    /// Wall time per stage, in order.
    pub stages: Vec<(&'static str, f64)>,
    /// Whether "test" is the leave-one-out error over the training poses.
    pub loocv: bool,
}

impl Report {
    pub fn to_json(&self) -> serde_json::Value {
        let errors = |e: &Errors| serde_json::json!({"train": e.train, "test": e.test});
        serde_json::json!({
            "vertices": self.vertices, "triangles": self.triangles, "bones": self.bones,
            "train_poses": self.train_poses, "test_poses": self.test_poses, "proxies": self.reduced_proxies,
            "rigid": errors(&self.rigid), "ssd": errors(&self.ssd), "rr_full": errors(&self.rr_full),
            "rr_reduced": self.rr_reduced.as_ref().map(errors),
            "seconds": {"ssd": self.ssd_seconds, "rr_full": self.rr_full_seconds, "rr_reduced": self.rr_reduced_seconds},
        })
    }

    pub fn table(&self, name: &str) -> String {
        let pct = |x: Option<f64>| x.map_or("     –".to_string(), |x| format!("{x:6.1}"));
        let test_label = if self.loocv {
            "LOOCV EE %"
        } else {
            "test EE %"
        };
        let mut s = format!(
            "{name}: V = {}, T = {}, J = {}; {} training poses, {} test poses\n\
             {:<26} {:>10} {:>10} {:>9}\n",
            self.vertices,
            self.triangles,
            self.bones,
            self.train_poses,
            self.test_poses,
            "method",
            "train EE %",
            test_label,
            "seconds"
        );
        for (label, e, secs) in [
            ("rigid", &self.rigid, None),
            ("SSD", &self.ssd, Some(self.ssd_seconds)),
            (
                "rotational regression",
                &self.rr_full,
                Some(self.rr_full_seconds),
            ),
        ]
        .into_iter()
        .chain(
            self.rr_reduced
                .as_ref()
                .map(|e| ("reduced (runtime model)", e, self.rr_reduced_seconds)),
        ) {
            s += &format!(
                "{label:<26} {:>10} {:>10} {:>9}\n",
                pct(Some(e.train)),
                pct(e.test),
                secs.map_or(String::new(), |t| format!("{t:.2}"))
            );
        }
        s += &format!(
            "rotational regression: F = vertices below the {:.0}th percentile of SSD error, scale/shear ridge {:e}, gradients: {:?} (mean regression weight {:.2}) (chosen by {FOLDS}-fold cross-validation on the training poses)\nstages:",
            self.choice.percentile, self.choice.ridge, self.choice.blend, self.mean_alpha
        );
        for (stage, t) in &self.stages {
            s += &format!(" {stage} {t:.2} s;");
        }
        s
    }
}

/// Σ squared distance between predicted and true meshes of `poses`.
fn squared_error(set: &ExampleSet, poses: &[usize], predicted: &[Vec<DVec3>]) -> f64 {
    poses
        .iter()
        .zip(predicted)
        .map(|(&i, y)| {
            y.iter()
                .zip(&set.poses[i].vertices)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum::<f64>()
        })
        .sum()
}

fn deform_all(set: &ExampleSet, skin: &Skinning, poses: &[usize]) -> Vec<Vec<DVec3>> {
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

/// What a training run on some poses produces, for every (percentile, ridge) candidate.
struct FoldFit {
    ssd: Skinning,
    ssd_error: Vec<f64>,
    rotations: full_model::Rotations,
}

fn fit_fold(set: &ExampleSet, prep: &Prepared, train: &[usize], k: usize) -> FoldFit {
    let errors = ssd::rigid_errors(set, train);
    let ssd = ssd::fit(set, train, &errors, k);
    let ssd_error = per_vertex_error(set, train, &ssd);
    let nearby = full_model::nearby_bones(set, &ssd);
    let rotations = full_model::fit_rotations(set, prep, train, &nearby);
    FoldFit {
        ssd,
        ssd_error,
        rotations,
    }
}

/// RMS over `poses` of each vertex's error under `skin`.
fn per_vertex_error(set: &ExampleSet, poses: &[usize], skin: &Skinning) -> Vec<f64> {
    let mut sum = vec![0.0; set.vertex_count()];
    for y in poses
        .iter()
        .map(|&i| (i, skin.deform(&set.rest, &set.poses[i].bones)))
    {
        for (a, p) in y.1.iter().enumerate() {
            sum[a] += (*p - set.poses[y.0].vertices[a]).length_squared();
        }
    }
    sum.iter()
        .map(|s| (s / poses.len().max(1) as f64).sqrt())
        .collect()
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
/// (percentile, ridge, fallback) candidate; returns the best and the triangle scores.
fn choose(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    k: usize,
    progress: &Progress,
    step: &mut usize,
) -> Result<(Choice, Option<TriangleScores>), Box<dyn std::error::Error>> {
    let folds = FOLDS.min(train.len());
    if folds < 2 {
        // Too few poses to cross-validate: a middle choice.
        return Ok((
            Choice {
                percentile: 90.0,
                ridge: 1e-2,
                blend: Blend::Regression,
            },
            None,
        ));
    }
    let edges = full_model::rest_edges(set);
    let inverses = crate::gradients::rest_inverses(&set.rest, &set.faces);
    let t = set.faces.len();
    let mut scores = TriangleScores {
        regression: vec![vec![0.0; t]; RIDGES.len()],
        cross: vec![vec![0.0; t]; RIDGES.len()],
        ssd: vec![0.0; t],
    };
    let split = |fold: usize| -> (Vec<usize>, Vec<usize>) {
        let inner = train
            .iter()
            .enumerate()
            .filter(|(n, _)| n % folds != fold)
            .map(|(_, &i)| i)
            .collect();
        let held = train
            .iter()
            .enumerate()
            .filter(|(n, _)| n % folds == fold)
            .map(|(_, &i)| i)
            .collect();
        (inner, held)
    };
    let mut fits = Vec::with_capacity(folds);
    for fold in 0..folds {
        let (inner, held) = split(fold);
        let fit = fit_fold(set, prep, &inner, k);
        let stretches: Vec<_> = RIDGES
            .iter()
            .map(|&ridge| full_model::fit_stretches(set, prep, &inner, &fit.rotations, ridge))
            .collect();
        for &i in &held {
            let skinned = fit.ssd.deform(&set.rest, &set.poses[i].bones);
            let ssd_grads = crate::gradients::gradients(&skinned, &set.faces, &inverses);
            for kk in 0..t {
                let (r, sv) = prep.polar[i][kk];
                let truth = r * sv;
                let e_ssd = full_model::edge_residuals(ssd_grads[kk], truth, &edges[kk]);
                scores.ssd[kk] += dot(&e_ssd, &e_ssd);
                for (ri, h) in stretches.iter().enumerate() {
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
        fits.push((fit, stretches));
        *step += 1;
        progress.set(*step);
    }
    let mut candidates = Vec::new();
    for blend in [Blend::Regression, Blend::Switch, Blend::Weighted] {
        for &ridge in &RIDGES {
            for &percentile in &PERCENTILES {
                candidates.push(Choice {
                    percentile,
                    ridge,
                    blend,
                });
            }
        }
    }
    let mut score = vec![0.0; candidates.len()];
    for (fold, (fit, stretches)) in fits.into_iter().enumerate() {
        let (_, held) = split(fold);
        for (c, choice) in candidates.iter().enumerate() {
            let r = RIDGES.iter().position(|&x| x == choice.ridge).unwrap_or(0);
            let fixed = full_model::near_rigid(set, &fit.ssd_error, choice.percentile);
            let alpha = scores.alpha(r, choice.blend);
            let model = FullModel::new(
                set,
                fit.rotations.clone(),
                stretches[r].clone(),
                fixed,
                alpha,
            )?;
            score[c] += squared_error(set, &held, &model.predict(set, prep, &fit.ssd, &held));
        }
    }
    let best = (0..score.len())
        .min_by(|&a, &b| score[a].total_cmp(&score[b]))
        .unwrap_or(0);
    Ok((candidates[best], Some(scores)))
}

pub struct Options {
    /// K for SSD and for the runtime model.
    pub influences: usize,
    /// P for the reduced model (0: no reduction), or fewer if `epsilon` stops merging first.
    pub proxies: usize,
    pub epsilon: Option<f64>,
    /// Evaluate this runtime model as "rr_reduced" instead of training a reduction.
    pub model: Option<rrskin::Model>,
    /// Replace the test error by leave-one-out over the training poses.
    pub loocv: bool,
    /// No progress output (for --json).
    pub quiet: bool,
}

pub fn run(set: &ExampleSet, options: &Options) -> Result<Report, Box<dyn std::error::Error>> {
    let k = options.influences;
    let (train, test) = (set.train(), set.test());
    let mut stages = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &'static str, stages: &mut Vec<(&'static str, f64)>| {
        stages.push((name, clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    let total_steps = FOLDS + 2 + if options.loocv { train.len() } else { 0 };
    let progress = Progress::new("training", total_steps, options.quiet);
    let mut step = 0;

    let prep = Prepared::new(set);
    lap("gradients", &mut stages);

    let ssd_start = Instant::now();
    let rigid_errors = ssd::rigid_errors(set, &train);
    let rigid = Skinning::rigid(&ssd::rigid_bones(&rigid_errors));
    let ssd = ssd::fit(set, &train, &rigid_errors, k);
    let ssd_seconds = ssd_start.elapsed().as_secs_f64();
    lap("ssd", &mut stages);
    step += 1;
    progress.set(step);

    let rr_start = Instant::now();
    let (choice, scores) = choose(set, &prep, &train, k, &progress, &mut step)?;
    let ridge_index = RIDGES.iter().position(|&r| r == choice.ridge).unwrap_or(0);
    let alpha = match &scores {
        Some(scores) => scores.alpha(ridge_index, choice.blend),
        None => vec![1.0; set.faces.len()],
    };
    lap("cross-validation", &mut stages);
    let fit = FoldFit {
        ssd_error: per_vertex_error(set, &train, &ssd),
        rotations: full_model::fit_rotations(
            set,
            &prep,
            &train,
            &full_model::nearby_bones(set, &ssd),
        ),
        ssd: ssd.clone(),
    };
    lap("rotations", &mut stages);
    let stretches = full_model::fit_stretches(set, &prep, &train, &fit.rotations, choice.ridge);
    let fixed = full_model::near_rigid(set, &fit.ssd_error, choice.percentile);
    let model = FullModel::new(set, fit.rotations.clone(), stretches, fixed, alpha.clone())?;
    let rr_full_seconds = rr_start.elapsed().as_secs_f64();
    lap("scale/shear + Poisson factor", &mut stages);
    step += 1;
    progress.set(step);

    let ee =
        |poses: &[usize], predicted: &[Vec<DVec3>]| enveloping_error(set, poses, predicted, &rigid);
    let errors = |model_ee: &dyn Fn(&[usize]) -> f64| Errors {
        train: model_ee(&train),
        test: (!test.is_empty()).then(|| model_ee(&test)),
    };
    let rigid_e = errors(&|p| ee(p, &deform_all(set, &rigid, p)));
    let ssd_e = errors(&|p| ee(p, &deform_all(set, &ssd, p)));
    let mut rr_e = errors(&|p| ee(p, &model.predict(set, &prep, &ssd, p)));
    if std::env::var("RRSKIN_EXP_DIAG").is_ok() {
        let exact = |p: &[usize]| ee(p, &model.reconstruct(set, &ssd, p, |i, k| { let (r, s) = prep.polar[i][k]; r * s }));
        eprintln!("diag full exact gradients: train {:.1} test {:.1}", exact(&train), exact(&test));
        let exact_rot = |p: &[usize]| ee(p, &model.reconstruct(set, &ssd, p, |i, k| {
            let (r, _) = prep.polar[i][k];
            let x = match &model.rotations.0[k] { Some(rp) => crate::scale_shear::features(&prep.feats[i], &set.parents, rp.first.bone), None => [0.0; 7] };
            r * crate::scale_shear::predict(&model.stretches[k], &x) }));
        eprintln!("diag full exact rotations, predicted S: train {:.1} test {:.1}", exact_rot(&train), exact_rot(&test));
    }
    lap("evaluation", &mut stages);

    let reduce_start = Instant::now();
    let trained = match (&options.model, options.proxies) {
        (Some(_), _) | (None, 0) => None,
        (None, p) => Some({
            let aug = std::env::var("RRSKIN_EXP_AUG").ok().map(|v| {
                let scales: Vec<f64> = v.split(',').filter_map(|x| x.parse().ok()).collect();
                let a = crate::augment::augment(set, &prep, &model, &ssd, &scales);
                let ap = Prepared::new(&a);
                (a, ap)
            });
            if let Some((a, _)) = &aug {
                let order = crate::augment::topological_order(&set.parents);
                let piv = crate::augment::pivots(set, &train);
                let worst = train.iter().map(|&i| {
                    let b = crate::augment::scaled_pose(set, &order, &piv, &set.poses[i].bones, 1.0);
                    b.iter().zip(&set.poses[i].bones).map(|(x, y)| (x.d - y.d).length() + (x.q - y.q).abs().to_cols_array().iter().sum::<f64>()).fold(0.0, f64::max)
                }).fold(0.0, f64::max);
                eprintln!("aug: {} poses, s=1 reproduction error {worst:e}", a.poses.len());
            }
            let (rs, rp, rt) = match &aug { Some((a, ap)) => (a, ap, a.train()), None => (set, &prep, train.clone()) };
            reduce(
                rs,
                rp,
                &rt,
                &ssd,
                &model.fixed,
                &model.alpha,
                crate::vertex_reduction::Stop {
                    proxies: p,
                    epsilon: options.epsilon,
                },
                k,
                choice.ridge,
            )
            .to_runtime(set, k)?
        }),
    };
    let runtime = options.model.as_ref().or(trained.as_ref());
    let rr_reduced = match runtime {
        Some(m) => Some(runtime_errors(set, m, &train, &test, &rigid)?),
        None => None,
    };
    let rr_reduced_seconds = trained
        .as_ref()
        .map(|_| reduce_start.elapsed().as_secs_f64());
    if runtime.is_some() {
        lap("reduction", &mut stages);
    }
    let reduced_proxies = runtime.map(|m| m.proxy_count());

    let (mut rigid_e, mut ssd_e) = (rigid_e, ssd_e);
    if options.loocv {
        let (mut pred_ssd, mut pred_rr, mut pred_rigid) = (Vec::new(), Vec::new(), Vec::new());
        for (n, &i) in train.iter().enumerate() {
            let others: Vec<usize> = train.iter().copied().filter(|&t| t != i).collect();
            let fold = fit_fold(set, &prep, &others, k);
            // The choices (F, ridge, blend weights) stay those made on all training poses.
            let stretches =
                full_model::fit_stretches(set, &prep, &others, &fold.rotations, choice.ridge);
            let fixed = full_model::near_rigid(set, &fold.ssd_error, choice.percentile);
            let m = FullModel::new(set, fold.rotations, stretches, fixed, alpha.clone())?;
            pred_rr.extend(m.predict(set, &prep, &fold.ssd, &[i]));
            pred_ssd.extend(deform_all(set, &fold.ssd, &[i]));
            pred_rigid.extend(deform_all(
                set,
                &Skinning::rigid(&ssd::rigid_bones(&ssd::rigid_errors(set, &others))),
                &[i],
            ));
            progress.set(step + n + 1);
        }
        let reference = squared_error(set, &train, &pred_rigid);
        let loo = |pred: &[Vec<DVec3>]| {
            Some(100.0 * (squared_error(set, &train, pred) / reference).sqrt())
        };
        rigid_e.test = Some(100.0);
        ssd_e.test = loo(&pred_ssd);
        rr_e.test = loo(&pred_rr);
        lap("leave-one-out", &mut stages);
    }
    progress.finish();
    Ok(Report {
        vertices: set.vertex_count(),
        triangles: set.faces.len(),
        bones: set.bone_count(),
        train_poses: train.len(),
        test_poses: test.len(),
        rigid: rigid_e,
        ssd: ssd_e,
        rr_full: rr_e,
        rr_reduced,
        rr_reduced_seconds,
        reduced_proxies,
        model: trained,
        ssd_seconds,
        rr_full_seconds,
        choice,
        mean_alpha: alpha.iter().sum::<f64>() / alpha.len().max(1) as f64,
        stages,
        loocv: options.loocv,
    })
}

/// Vertex reduction, predictor reduction and C1/C2 (paper §5, §4.3), for the full model's
/// near-rigid set `fixed` and per-triangle regression weights `blend`.
#[allow(clippy::too_many_arguments)]
pub fn reduce(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    ssd: &Skinning,
    fixed: &[bool],
    blend: &[f64],
    stop: crate::vertex_reduction::Stop,
    influences: usize,
    ridge: f64,
) -> crate::reduced::Reduced {
    let groups = crate::vertex_reduction::reduce(set, train, fixed, stop, influences);
    let mut keys = crate::predictor_reduction::reduce(set, prep, train, &groups);
    if std::env::var("RRSKIN_EXP_KEYS").is_ok() {
        keys.d = groups.transforms.iter().map(|ts| ts.iter().map(|t| t.m).collect()).collect();
    }
    let nearby = full_model::nearby_bones(set, ssd);
    let mut key_bones = vec![Vec::<usize>::new(); groups.count()];
    for (k, &g) in groups.triangle_group.iter().enumerate() {
        for &b in &nearby[k] {
            if !key_bones[g].contains(&b) {
                key_bones[g].push(b);
            }
        }
    }
    let predictors =
        crate::predictor_reduction::train_predictors(set, prep, train, &keys, &key_bones, ridge);
    let mut reduced = crate::reduced::assemble(set, ssd, fixed, blend, &groups, &keys, predictors);
    if let Ok(r) = std::env::var("RRSKIN_EXP_LOCAL") {
        crate::runtime_fit::local(set, train, &mut reduced, &key_bones, r.parse().unwrap_or(1e-6));
    }
    if std::env::var("RRSKIN_EXP_DIAG").is_ok() {
        let rigid = Skinning::rigid(&ssd::rigid_bones(&ssd::rigid_errors(set, train)));
        let test = set.test();
        let ee = |poses: &[usize], pred: &[Vec<DVec3>]| enveloping_error(set, poses, pred, &rigid);
        let o_tr = crate::runtime_fit::oracle_meshes(set, &reduced, train);
        let o_te = crate::runtime_fit::oracle_meshes(set, &reduced, &test);
        eprintln!("diag oracle proxies: train {:.1} test {:.1}", ee(train, &o_tr), ee(&test, &o_te));
        let r_tr: Vec<_> = train.iter().map(|&i| reduced.predict(set, &prep.feats[i], &set.poses[i].bones)).collect();
        let r_te: Vec<_> = test.iter().map(|&i| reduced.predict(set, &prep.feats[i], &set.poses[i].bones)).collect();
        eprintln!("diag reduced f64: train {:.1} test {:.1}", ee(train, &r_tr), ee(&test, &r_te));
        let ok = |poses: &[usize]| -> f64 {
            let or = crate::runtime_fit::oracle(set, &reduced, poses);
            let m: Vec<_> = poses.iter().zip(&or).map(|(&i, (_, d))| { let d: Vec<_> = d.iter().map(crate::runtime_fit::m3).collect(); reduced.predict_with_keys(set, &d, &set.poses[i].bones) }).collect();
            ee(poses, &m)
        };
        eprintln!("diag reduced with oracle keys: train {:.1} test {:.1}", ok(train), ok(&test));
    }
    if std::env::var("RRSKIN_EXP_E2E").is_ok() {
        let mask = std::env::var("RRSKIN_EXP_MASK").ok().map(|_| {
            let (p, j) = (groups.count(), set.bone_count());
            faer::Mat::<f64>::from_fn(4 * p, 3 * p + 4 * j, |r, c| {
                let e = r / 4;
                let ok = if c < 3 * p { let l = c / 3; l == e || groups.adjacency[e].contains(&l) } else { std::env::var("RRSKIN_EXP_C1ONLY").is_err() && key_bones[e].contains(&((c - 3 * p) / 4)) };
                f64::from(u8::from(ok))
            })
        });
        let choice = crate::runtime_fit::refine(set, prep, train, FOLDS, &mut reduced, mask.as_ref());
        eprintln!("e2e: {choice:?}");
    }
    reduced
}

/// EE of a runtime model evaluated by the runtime's CPU evaluator.
fn runtime_errors(
    set: &ExampleSet,
    model: &rrskin::Model,
    train: &[usize],
    test: &[usize],
    rigid: &Skinning,
) -> Result<Errors, Box<dyn std::error::Error>> {
    if model.vertex_count() != set.vertex_count() || model.bone_count() != set.bone_count() {
        return Err(format!(
            "the model has {} vertices and {} bones, the example set {} and {}",
            model.vertex_count(),
            model.bone_count(),
            set.vertex_count(),
            set.bone_count()
        )
        .into());
    }
    let predict = |poses: &[usize]| -> rrskin::Result<Vec<Vec<DVec3>>> {
        let mut evaluator = rrskin::cpu::CpuEvaluator::new(model);
        let v = set.vertex_count();
        let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
        poses
            .iter()
            .map(|&i| {
                let bones: Vec<rrskin::predict::Affine> =
                    set.poses[i].bones.iter().map(|b| b.to_affine()).collect();
                evaluator.evaluate(&bones, &mut pos, &mut nrm)?;
                Ok(pos.iter().map(|p| DVec3::from(p.map(f64::from))).collect())
            })
            .collect()
    };
    let train_e = enveloping_error(set, train, &predict(train)?, rigid);
    let test_e = match test.is_empty() {
        true => None,
        false => Some(enveloping_error(set, test, &predict(test)?, rigid)),
    };
    Ok(Errors {
        train: train_e,
        test: test_e,
    })
}
