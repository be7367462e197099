//! `rrskin eval`: trains every method on the training poses ([`crate::train::run`]) and
//! reports the enveloping error (paper §7.1, docs/method.md §10) on training and test poses, beside
//! the baselines an engine would pick instead; optionally the error budget ([`diagnose`]) and
//! leave-one-out over the training poses.
//!
//! `EE = sqrt(Σ_i Σ_a |y_a(q_i) − y_a^i|² / Σ_i Σ_a |r_a(q_i) − y_a^i|²)` in percent, r the best
//! rigid predictor (one bone per vertex, chosen on the training poses).

pub mod cost;
pub mod delta_mush;
pub mod diagnose;
pub mod learning_curve;
pub mod normals;

use crate::set::ExampleSet;
use crate::skinning::error::{deform_all, enveloping_error, squared_error};
use crate::skinning::lbs::Skinning;
use crate::skinning::{cor, direct_delta_mush, dqs};
use crate::train::budget::{CostBudget, Point, Priced, Refused};
use crate::train::proxy_corrective;
use crate::train::selection::Choice;
use crate::train::ssd;
use crate::train::structure::{Chosen, Ridges, Structure, Why};
use crate::train::{full_model, Method, TrainOptions, Trained};
use crate::{Error, Result};
use glam::DVec3;
use std::path::PathBuf;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    pub train: f64,
    pub test: Option<f64>,
}

/// What [`crate::train::corrective::fit`] chose for the runtime model.
#[derive(Debug, Clone, PartialEq)]
pub struct Correctives {
    /// None: cross-validation kept none.
    pub ridge: Option<f64>,
    /// N and D of the model (0 without correctives).
    pub targets: usize,
    pub drivers: usize,
    /// Per candidate (none, then [`crate::train::corrective::RIDGES`]): the mean held-out score
    /// and its standard error to the best.
    pub scores: Vec<(f64, f64)>,
}

/// The error budget: oracle ceilings (see [`diagnose`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    pub full_exact: Errors,
    pub reduced_oracle: Errors,
    pub reduced_oracle_keys: Errors,
    /// The runtime model with the unreduced per-vertex pose-space correction learnt from the
    /// training poses ([`diagnose::pose_space_meshes`]).
    pub pose_space: Errors,
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
    /// Dual quaternion skinning with SSD's weights.
    pub dqs: Errors,
    /// Skinning with optimized centres of rotation ([`cor`]) and direct delta mush ([`direct_delta_mush`],
    /// with `direct_delta_mush_params`, chosen on the training poses), both with SSD's weights (None with
    /// [`Options::skip_baselines`]).
    pub cor: Option<Errors>,
    pub direct_delta_mush: Option<Errors>,
    pub direct_delta_mush_params: Option<direct_delta_mush::Params>,
    /// Linear blend, dual quaternion and centres-of-rotation skinning with the rig's own
    /// weights, when the set has them.
    pub rig_lbs: Option<Errors>,
    pub rig_dqs: Option<Errors>,
    pub rig_cor: Option<Errors>,
    /// The paper's full model (None when not trained: `rrskin train` of joint-blend proxies).
    pub rr_full: Option<Errors>,
    /// The reduced runtime model, evaluated by the runtime's CPU evaluator.
    pub rr_reduced: Option<Errors>,
    pub reduced_proxies: Option<usize>,
    /// Delta-mush proxies beside the runtime model, and the cross-validation between them
    /// ([`delta_mush`]; None where training did not offer them, `TrainOptions::offers_delta_mush`,
    /// or trained no runtime model: P = 0 or [`Options::model`]).
    pub delta_mush: Option<delta_mush::DeltaMushReport>,
    /// The trained runtime model's structure (proxies, P, K) and how it was chosen.
    pub structure: Option<Chosen>,
    pub budget: Option<Budget>,
    /// The normals' held-out angular error per method and mode ([`normals`]; empty without
    /// test poses).
    pub normal_error: normals::NormalErrors,
    /// The runtime model trained here (None with `Options::model` or P = 0).
    pub model: Option<rrskin::Model>,
    /// The cost budget training kept to, and what it refused ([`crate::train::budget`]).
    pub cost_budget: CostBudget,
    /// The runtime model's price against it (None without a model trained here).
    pub priced: Option<Priced>,
    pub refused: Vec<Refused>,
    /// Every candidate training scored and priced ([`crate::train::budget::Point`]).
    pub points: Vec<Point>,
    /// The full model's F percentile, ridge and fallback chosen by cross-validation, and the
    /// mean weight of the regression in the triangles' blended gradients (1: the paper).
    pub choice: Option<(Choice, f64)>,
    /// The joint-blend model's key-stretch and C refit ridges, chosen by cross-validation (None
    /// inside: the keys kept rigid, C0 kept; None: not a joint-blend model trained here).
    pub joint_blend: Option<Ridges>,
    /// The runtime model's pose-space correctives: what cross-validation chose, and the targets
    /// and drivers kept (None: not asked for, or no runtime model trained here).
    pub correctives: Option<Correctives>,
    /// The runtime model's proxy correctives: what cross-validation chose (None: not asked for,
    /// or no runtime model trained here).
    pub proxy_correctives: Option<proxy_corrective::Fit>,
    /// Folds of the cross-validation that made `choice` (below 2: none, fixed choices).
    pub folds: usize,
    /// Wall time per stage, in order.
    pub stages: Vec<(&'static str, f64)>,
    /// Whether "test" is the leave-one-out error over the training poses.
    pub loocv: bool,
    /// The runtime model's held-out error at fractions of the training poses, and what it says
    /// about more poses (None: not asked for, or too few training poses).
    pub learning_curve: Option<learning_curve::LearningCurve>,
}

impl Report {
    fn seconds(&self, stages: &[&str]) -> f64 {
        self.stages
            .iter()
            .filter(|(s, _)| stages.contains(s))
            .map(|s| s.1)
            .sum()
    }

    pub fn to_json(&self) -> serde_json::Value {
        let errors = |e: &Errors| serde_json::json!({"train": e.train, "test": e.test});
        let stages: serde_json::Map<String, serde_json::Value> = self
            .stages
            .iter()
            .map(|(s, t)| (s.to_string(), (*t).into()))
            .collect();
        let reduced_seconds = self.model.as_ref().map(|_| self.seconds(&["reduction"]));
        serde_json::json!({
            "vertices": self.vertices, "triangles": self.triangles, "bones": self.bones,
            "train_poses": self.train_poses, "test_poses": self.test_poses, "proxies": self.reduced_proxies,
            "rigid": errors(&self.rigid), "ssd": errors(&self.ssd), "dqs": errors(&self.dqs),
            "cor": self.cor.as_ref().map(errors), "ddm": self.direct_delta_mush.as_ref().map(errors),
            "ddm_params": self.direct_delta_mush_params.map(|d| serde_json::json!({
                "iterations": d.iterations, "lambda": d.lambda, "kappa": d.kappa, "alpha": d.alpha,
            })),
            "rig_lbs": self.rig_lbs.as_ref().map(errors), "rig_dqs": self.rig_dqs.as_ref().map(errors),
            "rig_cor": self.rig_cor.as_ref().map(errors),
            "rr_full": self.rr_full.as_ref().map(errors),
            "rr_reduced": self.rr_reduced.as_ref().map(errors),
            "delta_mush": self.delta_mush.as_ref().map(|m| serde_json::json!({
                "proxies": m.proxies, "influences": m.influences, "mean_bones": m.mean_bones,
                "smoothing": {"iterations": m.smoothing.iterations, "alpha": m.smoothing.alpha},
                "errors": errors(&m.errors), "chosen": m.chosen,
                "candidates": m.scores.iter().map(|(score, se)| serde_json::json!({"score": score, "standard_error": se})).collect::<Vec<_>>(),
                "counts": m.counts.iter().map(|(p, score, se)| serde_json::json!({"proxies": p, "score": score, "standard_error": se})).collect::<Vec<_>>(),
            })),
            "structure": self.structure.as_ref().map(structure_json),
            "correctives": self.correctives.as_ref().map(|c| serde_json::json!({
                "ridge": c.ridge, "targets": c.targets, "drivers": c.drivers,
                "candidates": std::iter::once(None).chain(crate::train::corrective::RIDGES.map(Some))
                    .zip(&c.scores)
                    .map(|(ridge, (score, se))| serde_json::json!({"ridge": ridge, "score": score, "standard_error": se}))
                    .collect::<Vec<_>>(),
            })),
            "proxy_correctives": self.proxy_correctives.as_ref().map(|f| serde_json::json!({
                "anchor": f.chosen.map(|c| c.anchor),
                "basis": f.chosen.map(|c| basis_name(c.basis)),
                "gravity": f.chosen.map(|c| c.gravity),
                "ridge": f.chosen.map(|c| c.ridge),
                "clamped": f.chosen.map(|c| c.clamped),
                "proxies": f.correctives.as_ref().map_or(0, |c| c.proxies.len()),
                "uncorrected": {"score": f.uncorrected.0, "standard_error": f.uncorrected.1},
                "candidates": f.candidates.iter()
                    .map(|(c, (score, se))| serde_json::json!({"anchor": c.anchor, "basis": basis_name(c.basis), "gravity": c.gravity, "clamped": c.clamped, "ridge": c.ridge, "score": score, "standard_error": se}))
                    .collect::<Vec<_>>(),
            })),
            "normal_error": normals::to_json(&self.normal_error),
            "learning_curve": self.learning_curve.as_ref().map(learning_curve::points_json),
            "learning_curve_advice": self.learning_curve.as_ref().map(learning_curve::advice_json),
            "diagnose": self.budget.as_ref().map(|b| serde_json::json!({
                "full_exact_gradients": errors(&b.full_exact),
                "reduced_oracle_proxies": errors(&b.reduced_oracle),
                "reduced_oracle_keys": errors(&b.reduced_oracle_keys),
                "pose_space": errors(&b.pose_space),
            })),
            "seconds": {
                "ssd": self.seconds(&["ssd"]),
                "rr_full": self.rr_full.map(|_| self.seconds(&["gradients", "cross-validation", "full model"])),
                "rr_reduced": reduced_seconds,
            },
            "stages": stages,
            "cost": self.model.as_ref().map(cost::to_json),
            "budget": self.budget_json(),
            "pareto": self.points.iter().map(|p| serde_json::json!({
                "stage": p.stage, "kind": p.kind, "proxies": p.proxies, "ee": p.ee,
                "cost": {"frame": p.priced.frame, "palette_us": p.priced.palette_us},
                "within_budget": self.cost_budget.admits(&p.priced),
                "front": p.on_front(&self.points),
            })).collect::<Vec<_>>(),
        })
    }

    /// `budget`: the limits, the runtime model's price against them, and what they refused.
    fn budget_json(&self) -> serde_json::Value {
        let priced = |p: &Priced| serde_json::json!({"frame": p.frame, "palette_us": p.palette_us});
        let b = &self.cost_budget;
        serde_json::json!({
            "frame": b.frame, "palette_us": b.palette_us,
            "model": self.priced.as_ref().map(priced),
            "refused": self.refused.iter().map(|r| serde_json::json!({
                "candidate": r.candidate, "cost": priced(&r.priced), "load": r.load,
                "ee": r.ee.map(|e| e.0), "kept_ee": r.ee.map(|e| e.1), "fitted": !r.floor,
            })).collect::<Vec<_>>(),
        })
    }

    /// The runtime model's predicted cost against the budget, and what the budget refused.
    fn budget_lines(&self) -> String {
        let (Some(p), b) = (self.priced, &self.cost_budget) else {
            return String::new();
        };
        let limit = |l: Option<f64>, unit: &str| {
            l.map_or("no limit".to_string(), |l| format!("budget {l:.2}{unit}"))
        };
        let mut s = format!(
            "cost: {:.2} x the engine baseline ({}), CPU palette {:.1} us a character ({})\n",
            p.frame,
            limit(b.frame, " x"),
            p.palette_us,
            limit(b.palette_us, " us"),
        );
        let front: Vec<&Point> = (self.points.iter())
            .filter(|p| p.on_front(&self.points))
            .collect();
        if !front.is_empty() {
            s += "  the front (cross-validated EE % against the frame's cost, x the engine baseline):";
            for p in front {
                let over = if b.admits(&p.priced) {
                    ""
                } else {
                    ", over the budget"
                };
                s += &format!(
                    " {} {} {:.2} at {:.2}{over};",
                    p.proxies, p.kind, p.ee, p.priced.frame
                );
            }
            s += "\n";
        }
        // What would have gained, or was not scored (the JSON lists every refusal).
        for r in self
            .refused
            .iter()
            .filter(|r| r.ee.is_none_or(|(ee, kept)| ee < kept))
        {
            s += &format!("  refused by the budget: {}\n", r.line());
        }
        s
    }

    /// The report as a table: one row of train and test EE per method, then the normals'
    /// errors, what was chosen and how, and the stages' wall times.
    pub fn table(&self, name: &str) -> String {
        let test_label = if self.loocv {
            "LOOCV EE %"
        } else {
            "test EE %"
        };
        let mut s = format!(
            "{name}: V = {}, T = {}, J = {}; {} training poses, {} test poses\n\
             {:<34} {:>10} {:>10}\n",
            self.vertices,
            self.triangles,
            self.bones,
            self.train_poses,
            self.test_poses,
            "method",
            "train EE %",
            test_label,
        );
        s += &self.error_rows();
        s += &normals::lines(&self.normal_error);
        s += &self.choice_lines();
        if let Some(curve) = &self.learning_curve {
            s += &curve.lines();
        }
        s += "stages:";
        for (stage, t) in &self.stages {
            s += &format!(" {stage} {t:.2} s;");
        }
        s
    }

    /// The table's rows: train and test EE per method, the runtime model's structure after its
    /// row, and the error budget where diagnosed.
    fn error_rows(&self) -> String {
        let pct = |x: Option<f64>| x.map_or("     –".to_string(), |x| format!("{x:6.1}"));
        let mut s = String::new();
        let row = |s: &mut String, label: &str, e: &Errors| {
            *s += &format!(
                "{label:<34} {:>10} {:>10}\n",
                pct(Some(e.train)),
                pct(e.test)
            );
        };
        row(&mut s, "rigid", &self.rigid);
        row(&mut s, "SSD (LBS, fitted weights)", &self.ssd);
        row(&mut s, "DQS (SSD's weights)", &self.dqs);
        if let (Some(cor), Some(direct_delta_mush)) = (&self.cor, &self.direct_delta_mush) {
            row(&mut s, "CoR (SSD's weights)", cor);
            row(&mut s, "DDM (SSD's weights)", direct_delta_mush);
        }
        if let (Some(lbs), Some(dqs)) = (&self.rig_lbs, &self.rig_dqs) {
            row(&mut s, "LBS (the rig's weights)", lbs);
            row(&mut s, "DQS (the rig's weights)", dqs);
        }
        if let Some(cor) = &self.rig_cor {
            row(&mut s, "CoR (the rig's weights)", cor);
        }
        if let Some(e) = &self.rr_full {
            row(&mut s, "rotational regression (full)", e);
        }
        if let Some(e) = &self.rr_reduced {
            let label = match self.reduced_proxies {
                Some(p) => format!("reduced, P = {p} (runtime model)"),
                None => "reduced (runtime model)".to_string(),
            };
            row(&mut s, &label, e);
        }
        if let Some(c) = &self.structure {
            s += &structure_line(c);
        }
        s += &self.budget_lines();
        if let Some(m) = &self.delta_mush {
            let label = format!("delta-mush proxies, P = {}", m.proxies);
            row(&mut s, &label, &m.errors);
            s += &delta_mush_line(m);
        }
        if let Some(b) = &self.budget {
            s += "error budget (oracle ceilings, then what the training poses support):\n";
            row(&mut s, "  full model, exact gradients", &b.full_exact);
            row(&mut s, "  runtime form, oracle proxies", &b.reduced_oracle);
            row(
                &mut s,
                "  runtime form, oracle keys",
                &b.reduced_oracle_keys,
            );
            row(&mut s, "  model + per-vertex pose-space", &b.pose_space);
        }
        s
    }

    /// One line per choice the training made (the full model's settings, the joint-blend
    /// ridges, the correctives, the proxy correctives, direct delta mush's parameters) and how
    /// it was made.
    fn choice_lines(&self) -> String {
        let mut s = String::new();
        let chosen = match self.folds {
            0 | 1 => "fixed: too few training poses to cross-validate".to_string(),
            k => format!("chosen by {k}-fold cross-validation on the training poses"),
        };
        if let Some((choice, alpha)) = &self.choice {
            s += &format!(
                "rotational regression: F = vertices below the {:.0}th percentile of SSD error, scale/shear ridge {:e}, gradients: {:?} (mean regression weight {alpha:.2}) ({chosen})\n",
                choice.percentile, choice.ridge, choice.blend
            );
        }
        if let Some(Ridges { stretch, refit }) = self.joint_blend {
            let ridge =
                |r: Option<f64>, none: &str| r.map_or(none.to_string(), |r| format!("ridge {r:e}"));
            s += &format!(
                "joint-blend proxies: key stretch {}, C refit {} ({chosen})\n",
                ridge(stretch, "none (rigid keys)"),
                ridge(refit, "none (C0)")
            );
        }
        if let Some(c) = &self.correctives {
            s += &match c.ridge {
                Some(r) => format!(
                    "pose-space correctives: N = {} targets driven by D = {} joints, ridge {r:e} ({chosen}, one-standard-error rule)\n",
                    c.targets, c.drivers
                ),
                None => format!("pose-space correctives: none ({chosen}, one-standard-error rule)\n"),
            };
        }
        if let Some(f) = &self.proxy_correctives {
            s += &match (f.chosen, &f.correctives) {
                (Some(k), Some(c)) => format!(
                    "proxy correctives: {} of {} proxies corrected, {} basis{}{}, ridge {:e}, targets anchored {} ({chosen})\n",
                    c.proxies.len(),
                    self.reduced_proxies.unwrap_or(0),
                    basis_name(k.basis),
                    if k.gravity { " and gravity" } else { "" },
                    if k.clamped { ", features clamped to the training range" } else { "" },
                    k.ridge,
                    match k.anchor {
                        0.0 => "none".to_string(),
                        mu => format!("{mu:e}"),
                    }
                ),
                _ => format!("proxy correctives: none ({chosen})\n"),
            };
        }
        if let Some(d) = &self.direct_delta_mush_params {
            s += &format!(
                "direct delta mush: p = {}, λ = {}, κ = {}, α = {} (p and α chosen on the training poses)\n",
                d.iterations, d.lambda, d.kappa, d.alpha
            );
        }
        s
    }
}

fn basis_name(b: proxy_corrective::Basis) -> &'static str {
    match b {
        proxy_corrective::Basis::Linear => "linear",
        proxy_corrective::Basis::Kernels => "linear and kernels",
    }
}

fn method_name(s: &Structure) -> &'static str {
    match s.method {
        Method::JointBlend => "joint_blend",
        Method::Paper => "paper",
        Method::Auto => "auto",
        Method::DeltaMush => "delta_mush",
        Method::Both => "both",
    }
}

/// The runtime model's structure and every candidate's cross-validated score.
fn structure_json(c: &Chosen) -> serde_json::Value {
    let one = |s: &Structure| serde_json::json!({"reduction": method_name(s), "proxies": s.proxies, "influences": s.influences});
    serde_json::json!({
        "chosen": one(&c.structure),
        "folds": c.folds,
        "candidates": c.candidates.iter().map(|x| serde_json::json!({
            "structure": one(&x.structure), "score": x.score, "standard_error": x.standard_error,
        })).collect::<Vec<_>>(),
    })
}

/// One line: the structure, and how it was chosen.
fn structure_line(c: &Chosen) -> String {
    let name = |s: &Structure| {
        format!(
            "{}, P ≤ {}, K = {}",
            method_name(s).replace('_', "-"),
            s.proxies,
            s.influences
        )
    };
    let mut line = format!("structure: {}", name(&c.structure));
    let why = match c.why {
        Why::Asked => " (as asked)",
        Why::OnlyCandidate => {
            " (the only candidate: the rig has too few joint-blend proxies for fewer, none more than P)"
        }
        Why::TooFewPoses => " (P as given: too few training poses to cross-validate)",
        Why::CrossValidated => "",
        Why::Budget => " (the most the cost budget admits)",
    };
    if !why.is_empty() {
        return line + why + "\n";
    }
    line += &format!(
        " (chosen by {}-fold cross-validation on the training poses, one-standard-error rule; held-out pose EE %, RMS over the poses ± one standard error to the best:",
        c.folds
    );
    for x in &c.candidates {
        // d(EE) = 100 d(score) / (2 √score).
        let ee = 100.0 * x.score.sqrt();
        let se = 50.0 * x.standard_error / x.score.sqrt().max(1e-300);
        line += &format!(" {} {ee:.2} ± {se:.2};", name(&x.structure));
    }
    line.pop();
    line + ")\n"
}

/// The cross-validation's verdict between the delta-mush proxies and the runtime model.
fn delta_mush_line(m: &delta_mush::DeltaMushReport) -> String {
    let mut s = String::new();
    let ee = |(score, se): (f64, f64)| {
        let e = 100.0 * score.sqrt();
        format!("{e:.2} ± {:.2}", 50.0 * se / score.sqrt().max(1e-300))
    };
    let asked = match m.chosen {
        "delta-mush" => "the runtime model, as asked (--reduction delta-mush; the joint-blend model above is trained for comparison)",
        "both" => "after the joint-blend proxies, the runtime model, as asked (--reduction both)",
        _ => "",
    };
    if m.scores.is_empty() && !asked.is_empty() {
        s += &format!(
            "delta-mush proxies (K = {}, {:.1} bones per proxy): {asked}\n",
            m.influences, m.mean_bones,
        );
    }
    let margin = 100.0 * crate::train::delta_mush::MORE_KEYS_MARGIN;
    if !m.counts.is_empty() {
        let counts: Vec<String> = (m.counts.iter())
            .map(|&(p, score, se)| format!("{p} {}", ee((score, se))))
            .collect();
        s += &format!(
            "delta-mush proxy counts (cross-validation on the training poses, each with its proxy correctives, held-out pose EE %; each doubling to win by {margin:.0} %): {}: {} kept\n",
            counts.join(", "),
            m.proxies,
        );
    }
    if let [joint_blend, proxies, ref both @ ..] = m.scores[..] {
        let both = both.first().map_or(String::new(), |&b| {
            format!(", both in one palette {} (to win by {margin:.0} %)", ee(b))
        });
        s += &format!(
            "delta-mush proxies (K = {}, {:.1} bones per proxy) against the joint-blend model (cross-validation on the training poses, each kind with its proxy correctives, held-out pose EE %): joint-blend {}, delta-mush {}{both}: {} kept\n",
            m.influences,
            m.mean_bones,
            ee(joint_blend),
            ee(proxies),
            m.chosen,
        );
    }
    s
}

fn dqs_all(set: &ExampleSet, influences: &[Vec<(usize, f64)>], poses: &[usize]) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .map(|&i| dqs::deform(&set.rest, influences, &set.poses[i].bones))
        .collect()
}

fn cor_all(
    set: &ExampleSet,
    influences: &[Vec<(usize, f64)>],
    centres: &[DVec3],
    poses: &[usize],
) -> Vec<Vec<DVec3>> {
    poses
        .iter()
        .map(|&i| cor::deform(&set.rest, influences, centres, &set.poses[i].bones))
        .collect()
}

/// The baselines' precomputations: centres of rotation for SSD's weights (and the rig's), and
/// direct delta mush's Ω for SSD's weights with its parameters chosen on the training poses.
struct Baselines {
    cor: Vec<DVec3>,
    rig_cor: Option<Vec<DVec3>>,
    direct_delta_mush: direct_delta_mush::DirectDeltaMush,
    direct_delta_mush_params: direct_delta_mush::Params,
}

impl Baselines {
    /// Each precomputation's wall time is added to `stages`.
    fn precompute(
        set: &ExampleSet,
        trained: &Trained,
        stages: &mut Vec<(&'static str, f64)>,
    ) -> Result<Baselines> {
        let mut clock = std::time::Instant::now();
        let mut lap = |stage: &'static str| {
            stages.push((stage, clock.elapsed().as_secs_f64()));
            clock = std::time::Instant::now();
        };
        let ssd_weights = &trained.ssd.influences;
        let cor = cor::centres(&set.rest, &set.faces, ssd_weights);
        lap("cor");
        // Training chose DDM's smoothing already where it offered delta-mush proxies.
        let (direct_delta_mush_params, direct_delta_mush) = match &trained.delta_mush {
            Some(m) => (m.params, m.direct_delta_mush.clone()),
            None => direct_delta_mush::choose(set, &set.train(), ssd_weights)?,
        };
        lap("ddm");
        let rig_cor = set.rig_weights.as_ref().map(|w| {
            let centres = cor::centres(&set.rest, &set.faces, w);
            lap("rig cor");
            centres
        });
        Ok(Baselines {
            cor,
            rig_cor,
            direct_delta_mush,
            direct_delta_mush_params,
        })
    }
}

#[derive(Default)]
pub struct Options {
    pub train: TrainOptions,
    /// Evaluate this runtime model file as "rr_reduced" instead of training a reduction.
    pub model: Option<(PathBuf, rrskin::Model)>,
    /// Replace the test error by leave-one-out over the training poses.
    pub loocv: bool,
    /// Also report the error budget.
    pub diagnose: bool,
    /// Leave out the baselines that need a precomputation (CoR and DDM with SSD's weights, CoR
    /// with the rig's): `rrskin train`, which reports only what it trained.
    pub skip_baselines: bool,
    /// Also measure the learning curve ([`learning_curve`]; with a runtime model trained here:
    /// P > 0, no [`Options::model`]): k x 4 more trainings.
    pub learning_curve: bool,
}

/// Trains on `set`'s training poses ([`crate::train::run`]) and scores every method.
pub fn run(set: &ExampleSet, options: &Options) -> Result<Report> {
    if let Some((path, m)) = &options.model {
        if m.vertex_count() != set.vertex_count() || m.bone_count() != set.bone_count() {
            return Err(Error::ModelMismatch {
                model: path.clone(),
                model_size: (m.vertex_count(), m.bone_count()),
                set_size: (set.vertex_count(), set.bone_count()),
            });
        }
    }
    let mut train_options = options.train.clone();
    if options.model.is_some() {
        train_options.proxies = 0;
    }
    // eval's front prices every structure candidate; `train` (no baselines) saves that.
    train_options.front = !options.skip_baselines;
    let trained = crate::train::run(set, &train_options)?;
    let mut stages = trained.seconds.clone();
    let baselines = match options.skip_baselines {
        true => None,
        false => Some(Baselines::precompute(set, &trained, &mut stages)?),
    };
    let start = std::time::Instant::now();
    let scorer = Scorer::new(set, &trained.rigid);
    let runtime = options
        .model
        .as_ref()
        .map(|m| &m.1)
        .or(trained.model.as_ref());
    let mut report = score(set, &trained, &scorer, baselines.as_ref(), runtime)?;
    report.budget = match options.diagnose {
        true => budget(set, &trained, &scorer, runtime, options.train.folds)?,
        false => None,
    };
    report.normal_error = normals::held_out(set, &trained.ssd, runtime, &scorer.test)?;
    stages.push(("evaluation", start.elapsed().as_secs_f64()));
    report.delta_mush = trained.delta_mush.as_ref().map(|m| {
        let proxies = &m.proxies;
        let errors = scorer.errors(&|p| {
            (p.iter())
                .map(|&i| proxies.deform(&set.rest, &set.poses[i].bones))
                .collect()
        });
        delta_mush::DeltaMushReport::of(m, errors)
    });
    if options.loocv {
        let start = std::time::Instant::now();
        let loo = leave_one_out(set, &trained, &options.train)?;
        report.use_leave_one_out(&loo);
        stages.push(("leave-one-out", start.elapsed().as_secs_f64()));
    }
    if options.learning_curve && options.model.is_none() && options.train.proxies > 0 {
        let start = std::time::Instant::now();
        // The curve retrains the kind of model that ships: delta-mush proxies are offered
        // again only where they were kept, alone or with the joint-blend model's (each offer
        // costs a merging and a cross-validation).
        let kind = TrainOptions {
            delta_mush: (trained.delta_mush.as_ref())
                .is_some_and(|m| m.kept != crate::train::delta_mush::Kept::JointBlend),
            ..options.train.clone()
        };
        report.learning_curve = learning_curve::measure(set, &trained.rigid, &kind)?;
        stages.push(("learning curve", start.elapsed().as_secs_f64()));
    }
    report.stages = stages;
    report.cost_budget = options.train.budget;
    report.folds = options.train.folds.min(scorer.train.len());
    Ok(report)
}

/// EE on the training and test poses of `set`, against its rigid predictor.
struct Scorer<'a> {
    set: &'a ExampleSet,
    rigid: &'a Skinning,
    train: Vec<usize>,
    test: Vec<usize>,
}

impl<'a> Scorer<'a> {
    fn new(set: &'a ExampleSet, rigid: &'a Skinning) -> Scorer<'a> {
        Scorer {
            set,
            rigid,
            train: set.train(),
            test: set.test(),
        }
    }

    fn errors(&self, predict: &dyn Fn(&[usize]) -> Vec<Vec<DVec3>>) -> Errors {
        let (set, rigid) = (self.set, self.rigid);
        Errors {
            train: enveloping_error(set, &self.train, &predict(&self.train), rigid),
            test: (!self.test.is_empty())
                .then(|| enveloping_error(set, &self.test, &predict(&self.test), rigid)),
        }
    }
}

/// Every method's errors (no budget, no normals, no leave-one-out yet).
fn score(
    set: &ExampleSet,
    trained: &Trained,
    scorer: &Scorer,
    baselines: Option<&Baselines>,
    runtime: Option<&rrskin::Model>,
) -> Result<Report> {
    let ssd_weights = &trained.ssd.influences;
    let rig_skin = set.rig_weights.as_ref().map(|w| Skinning {
        influences: w.clone(),
    });
    let with_rig = |f: &dyn Fn(&Skinning) -> Errors| rig_skin.as_ref().map(f);
    let full = trained.full.as_ref();
    Ok(Report {
        vertices: set.vertex_count(),
        triangles: set.faces.len(),
        bones: set.bone_count(),
        train_poses: scorer.train.len(),
        test_poses: scorer.test.len(),
        rigid: scorer.errors(&|p| deform_all(set, &trained.rigid, p)),
        ssd: scorer.errors(&|p| deform_all(set, &trained.ssd, p)),
        dqs: scorer.errors(&|p| dqs_all(set, ssd_weights, p)),
        cor: baselines.map(|b| scorer.errors(&|p| cor_all(set, ssd_weights, &b.cor, p))),
        direct_delta_mush: baselines
            .map(|b| scorer.errors(&|p| b.direct_delta_mush.deform_poses(set, p))),
        direct_delta_mush_params: baselines.map(|b| b.direct_delta_mush_params),
        rig_lbs: with_rig(&|s| scorer.errors(&|p| deform_all(set, s, p))),
        rig_dqs: with_rig(&|s| scorer.errors(&|p| dqs_all(set, &s.influences, p))),
        rig_cor: rig_skin
            .as_ref()
            .zip(baselines.and_then(|b| b.rig_cor.as_ref()))
            .map(|(s, c)| scorer.errors(&|p| cor_all(set, &s.influences, c, p))),
        rr_full: full.map(|f| scorer.errors(&|p| f.model.predict(set, &f.prep, &trained.ssd, p))),
        rr_reduced: runtime
            .map(|m| runtime_errors(set, m, &scorer.train, &scorer.test, scorer.rigid))
            .transpose()?,
        reduced_proxies: runtime.map(|m| m.proxy_count()),
        delta_mush: None,
        structure: trained.structure.clone(),
        budget: None,
        normal_error: Vec::new(),
        model: trained.model.clone(),
        cost_budget: CostBudget::NONE,
        priced: trained.priced,
        refused: trained.refused.clone(),
        points: trained.points.clone(),
        choice: full.map(|f| {
            let alpha = &f.selection.alpha;
            (
                f.selection.choice,
                alpha.iter().sum::<f64>() / alpha.len().max(1) as f64,
            )
        }),
        joint_blend: trained.joint_blend.as_ref().map(|f| f.ridges()),
        correctives: trained.correctives.as_ref().map(|f| Correctives {
            ridge: f.ridge,
            targets: f.correctives.as_ref().map_or(0, |c| c.targets.len()),
            drivers: f.correctives.as_ref().map_or(0, |c| c.drivers.len()),
            scores: f.scores.clone(),
        }),
        proxy_correctives: trained.proxy_correctives.clone(),
        folds: 0,
        stages: Vec::new(),
        loocv: false,
        learning_curve: None,
    })
}

/// The error budget (oracle ceilings), when there is a reduced model and a full one.
fn budget(
    set: &ExampleSet,
    trained: &Trained,
    scorer: &Scorer,
    runtime: Option<&rrskin::Model>,
    folds: usize,
) -> Result<Option<Budget>> {
    let (Some(reduced), Some(f), Some(model)) = (&trained.reduced, &trained.full, runtime) else {
        return Ok(None);
    };
    let exact = |p: &[usize]| {
        f.model.reconstruct(set, &trained.ssd, p, |i, k| {
            let (r, s) = f.prep.polar[i][k];
            r * s
        })
    };
    let (train, test) = (&scorer.train, &scorer.test);
    let [fitted, held] = diagnose::pose_space_meshes(set, trained, model, train, test, folds)?;
    Ok(Some(Budget {
        full_exact: scorer.errors(&exact),
        reduced_oracle: scorer.errors(&|p| diagnose::oracle_meshes(set, reduced, p)),
        reduced_oracle_keys: scorer.errors(&|p| diagnose::oracle_key_meshes(set, reduced, p)),
        pose_space: Errors {
            train: enveloping_error(set, train, &fitted, scorer.rigid),
            test: (!test.is_empty()).then(|| enveloping_error(set, test, &held, scorer.rigid)),
        },
    }))
}

impl Report {
    /// "test" becomes leave-one-out over the training poses where there is such a figure.
    fn use_leave_one_out(&mut self, loo: &LeaveOneOut) {
        self.loocv = true;
        self.rigid.test = Some(100.0);
        self.ssd.test = Some(loo.ssd);
        self.dqs.test = Some(loo.dqs);
        if let Some(e) = self.rr_full.as_mut() {
            e.test = loo.rr_full;
        }
        // Leave-one-out retrains SSD and the full model only: the reduced row and the
        // baselines precomputed from SSD's weights have no such figure.
        let delta_mush = self.delta_mush.as_mut().map(|m| &mut m.errors);
        for e in [
            self.rr_reduced.as_mut(),
            self.cor.as_mut(),
            self.direct_delta_mush.as_mut(),
            delta_mush,
        ]
        .into_iter()
        .flatten()
        {
            e.test = None;
        }
        // The rig's weights are fitted on no pose: left out, a pose errs as in training.
        for e in [&mut self.rig_lbs, &mut self.rig_dqs, &mut self.rig_cor]
            .into_iter()
            .flatten()
        {
            e.test = Some(e.train);
        }
    }
}

/// Leave-one-out EE over the training poses (against a rigid predictor also refitted without
/// the pose). The selection (F, ridge, blend weights) stays the one made on all training poses.
struct LeaveOneOut {
    ssd: f64,
    dqs: f64,
    rr_full: Option<f64>,
}

fn leave_one_out(
    set: &ExampleSet,
    trained: &Trained,
    options: &TrainOptions,
) -> Result<LeaveOneOut> {
    let k = options.influences;
    let train = set.train();
    let (mut ssd_p, mut dqs_p, mut rr_p, mut rigid_p) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let progress = crate::progress::Progress::new("leave-one-out", train.len(), options.quiet);
    for &i in &train {
        let others: Vec<usize> = train.iter().copied().filter(|&t| t != i).collect();
        let rigid_errors = crate::skinning::lbs::rigid_errors(set, &others);
        let ssd = ssd::fit(set, &others, &rigid_errors, k);
        if let Some(f) = &trained.full {
            let full = full_model::fit(set, &f.prep, &others, &ssd, &f.selection)
                .map_err(crate::train::TrainError::from)?;
            rr_p.extend(full.predict(set, &f.prep, &ssd, &[i]));
        }
        ssd_p.extend(deform_all(set, &ssd, &[i]));
        dqs_p.extend(dqs_all(set, &ssd.influences, &[i]));
        rigid_p.extend(deform_all(
            set,
            &Skinning::rigid(&crate::skinning::lbs::rigid_bones(&rigid_errors)),
            &[i],
        ));
        progress.step();
    }
    progress.finish();
    let reference = squared_error(set, &train, &rigid_p);
    let ee = |p: &[Vec<DVec3>]| 100.0 * (squared_error(set, &train, p) / reference).sqrt();
    Ok(LeaveOneOut {
        ssd: ee(&ssd_p),
        dqs: ee(&dqs_p),
        rr_full: trained.full.as_ref().map(|_| ee(&rr_p)),
    })
}

/// A runtime model's meshes of `poses`, by the runtime's CPU evaluator (its characters upright:
/// the model's up).
pub fn runtime_meshes(
    set: &ExampleSet,
    model: &rrskin::Model,
    poses: &[usize],
) -> rrskin::Result<Vec<Vec<DVec3>>> {
    let mut evaluator = rrskin::cpu::CpuEvaluator::new(model);
    let v = set.vertex_count();
    let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
    poses
        .iter()
        .map(|&i| {
            let bones: Vec<rrskin::predict::Affine> =
                set.poses[i].bones.iter().map(|b| b.to_runtime()).collect();
            evaluator.evaluate(&bones, &mut pos, &mut nrm)?;
            Ok(pos.iter().map(|p| DVec3::from(p.map(f64::from))).collect())
        })
        .collect()
}

/// EE of a runtime model evaluated by the runtime's CPU evaluator.
fn runtime_errors(
    set: &ExampleSet,
    model: &rrskin::Model,
    train: &[usize],
    test: &[usize],
    rigid: &Skinning,
) -> Result<Errors> {
    let predict = |poses: &[usize]| runtime_meshes(set, model, poses);
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
