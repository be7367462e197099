//! Delta-mush proxies in the runtime model (beyond the paper; docs/method.md §23): fitted to the
//! training poses ([`crate::train::reduce::mush`]), alone or after the joint-blend model's
//! proxies in one palette ([`join`]), and kept in place of the joint-blend model where the
//! k-fold cross-validation over the training poses prefers them (§18's folds, pose-relative
//! score and one-standard-error rule with its tolerance; the joint-blend structure first, then
//! the delta-mush proxies alone, then both, so that the simpler stays unless the richer wins
//! clearly).
//!
//! Direct Delta Mush's smoothing (p, α) is chosen on all training poses, with SSD's weights
//! ([`ddm::choose`]); the proxies' groups are merged once, on all training poses, and fixed
//! inside the folds, as the joint-blend model's ridges are there (the merging is most of the
//! cost); SSD, Ω and the weights are fitted per fold. The joint-blend side of each fold is its
//! structure as chosen. Where the runtime model takes proxy correctives, every side is compared
//! as it ships: each kind's correctives are chosen on all training poses
//! ([`proxy_corrective::fit`], which may keep none), and that choice is fitted again on each
//! fold's own poses ([`proxy_corrective::fit_candidate`]), as the merging is fixed: a kind that
//! fits the poses better uncorrected may leave less to correct.

use crate::set::ExampleSet;
use crate::skinning::ddm::{self, Ddm};
use crate::skinning::error::squared_error;
use crate::skinning::lbs::{rigid_errors, Skinning};
use crate::train::cross_validate::{try_cross_validate, Folds, Validated};
use crate::train::proxy_corrective::Candidate;
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::mush::{join, Groups, MushProxies};
use crate::train::rotreg::PoseFeatures;
use crate::train::structure::{self, Chosen, JointBlendFit, TOLERANCE};
use crate::train::{corrective, proxy_corrective};
use crate::train::{pose_scale, ssd, Method, TrainError, TrainOptions};
use glam::DVec3;

/// By how much of the better EE alone both kinds in one palette must win on the training
/// folds: they add P delta-mush keys to the joint-blend model's, each a rigid fit per character
/// (cesium_cage on lavapipe, 256 characters: paired RR / SSD 1.12 → 1.44; unmeasured on a
/// GPU). The margin is a run-time cost policy, not a fit: the joint-blend ladder asks 3 %
/// ([`TOLERANCE`]) for 1.5 times the proxies.
pub const BOTH_MARGIN: f64 = 0.10;

/// What the stage fitted and chose.
pub struct Fit {
    /// Direct Delta Mush's Ω for SSD's weights, and its smoothing chosen on the training poses
    /// (evaluation's DDM baseline too).
    pub ddm: Ddm,
    pub params: ddm::Params,
    /// The proxies' smoothing: `params`, or none (p = 0) where that fits the training poses
    /// better.
    pub proxy_params: ddm::Params,
    /// The delta-mush proxies fitted to all training poses (P and K of the runtime model).
    pub proxies: MushProxies,
    pub influences: usize,
    /// (score, standard error) of the joint-blend structure, the delta-mush proxies, then
    /// both, each with its proxy correctives (where the runtime model takes them); empty with
    /// fewer training poses than folds (then the joint-blend model stays) or with
    /// [`Method::DeltaMush`] or [`Method::Both`] (then kept unasked).
    pub scores: Vec<(f64, f64)>,
    /// What the runtime model is.
    pub kept: Kept,
    /// The proxy correctives' search on the kept kind, where the cross-validation made it (the
    /// runtime model's correctives, not searched again).
    pub correctives: Option<proxy_corrective::Fit>,
}

/// The runtime model the stage keeps (asked for, or by the cross-validation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kept {
    /// The joint-blend model (the structure stage's).
    JointBlend,
    /// The delta-mush proxies alone ([`Fit::proxies`]).
    DeltaMush,
    /// Both kinds in one palette ([`join`]).
    Both,
}

impl Kept {
    /// As `rrskin eval --json` names it.
    pub fn name(self) -> &'static str {
        match self {
            Kept::JointBlend => "joint-blend",
            Kept::DeltaMush => "delta-mush",
            Kept::Both => "both",
        }
    }
}

impl Fit {
    /// P
    pub fn proxies(&self) -> usize {
        self.proxies.proxies.entries()
    }

    /// The mean bones per proxy's rigid fit: the run-time cost of the keys.
    pub fn mean_bones(&self) -> f64 {
        self.proxies.proxies.mean_bones()
    }
}

/// The training poses and what the joint-blend model of the runtime was made with.
pub struct Inputs<'a> {
    pub set: &'a ExampleSet,
    pub train: &'a [usize],
    pub feats: &'a [PoseFeatures],
    pub rigid: &'a Skinning,
    pub ssd: &'a Skinning,
    pub chosen: &'a Chosen,
    pub joint_blend: &'a JointBlendFit,
    /// The joint-blend model of `chosen`, fitted to all training poses.
    pub reduced: &'a Reduced,
}

/// Fits delta-mush proxies of P = `options.proxies` and K = `options.influences` to the
/// training poses and cross-validates them, alone and after the joint-blend model's, against the
/// chosen joint-blend structure (kept without asking with [`Method::DeltaMush`], alone, and
/// [`Method::Both`], after the joint-blend proxies). With the fit, the reduced model that ships
/// in place of the joint-blend one (None where that stays), fitted to all training poses.
pub fn fit(inputs: &Inputs, options: &TrainOptions) -> Result<(Fit, Option<Reduced>), TrainError> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let smoothing = |e: crate::Error| TrainError::Smoothing {
        problem: e.to_string(),
    };
    let ssd_weights = &inputs.ssd.influences;
    let (params, vertex_ddm) = ddm::choose(set, train, ssd_weights).map_err(smoothing)?;
    let groups = Groups::merge(set, train, options.proxies);
    // The proxies' smoothing: DDM's, or none (each group's rigid fit of its LBS motion),
    // whichever fits the training poses better; the same models, so no cross-validation.
    let unsmoothed = ddm::Params {
        iterations: 0,
        ..params
    };
    let bones = set.bone_count();
    let plain =
        Ddm::new(&set.rest, &set.faces, ssd_weights, bones, &unsmoothed).map_err(smoothing)?;
    let fit_with = |d: &Ddm| {
        let m = MushProxies::fit(set, train, d, ssd_weights, &groups, k);
        let meshes: Vec<Vec<DVec3>> = (train.iter())
            .map(|&i| m.deform(&set.rest, &set.poses[i].bones))
            .collect();
        (squared_error(set, train, &meshes), m)
    };
    let ((smoothed_error, smoothed), (plain_error, unsmoothed_fit)) =
        (fit_with(&vertex_ddm), fit_with(&plain));
    let (proxy_params, fitted) = match plain_error < smoothed_error {
        true => (unsmoothed, unsmoothed_fit),
        false => (params, smoothed),
    };
    let mut out = Fit {
        ddm: vertex_ddm,
        params,
        proxy_params,
        proxies: fitted,
        influences: k,
        scores: Vec::new(),
        kept: Kept::JointBlend,
        correctives: None,
    };
    let alone = || out.proxies.reduced(bones, ssd_weights);
    let both = || join(inputs.reduced, &out.proxies, set, train, inputs.feats, k);
    // The delta-mush proxies alone and the union on all training poses, where the
    // cross-validation made them (the kept one ships as made).
    let (mut made_alone, mut made_union) = (None, None);
    out.kept = match (options.method, Folds::new(train.len(), options.folds)) {
        (Method::DeltaMush, _) => Kept::DeltaMush,
        (Method::Both, _) => Kept::Both,
        (_, None) => Kept::JointBlend,
        (_, Some(split)) => {
            // Both kinds add P proxies to the joint-blend model's: where P is asked for
            // (`--reduction joint-blend`), only the delta-mush proxies alone stand against it.
            let offers_both = options.method == Method::Auto;
            let made_alone = &*made_alone.insert(alone());
            let made_union = offers_both.then(|| &*made_union.insert(both()));
            let kinds: Vec<&Reduced> = [inputs.reduced, made_alone]
                .into_iter()
                .chain(made_union)
                .collect();
            let mut searched = corrective_searches(inputs, options, &kinds);
            let choices: Vec<Option<Candidate>> = (searched.iter())
                .map(|fit| fit.as_ref().and_then(|f| f.chosen))
                .collect();
            let sides = Sides {
                groups: &groups,
                params: &proxy_params,
                correctives: &choices,
            };
            let validated = cross_validate(inputs, options, &split, &sides).map_err(smoothing)?;
            out.scores = validated.scores.clone();
            let index = kept(&validated);
            out.correctives = searched.swap_remove(index);
            [Kept::JointBlend, Kept::DeltaMush, Kept::Both][index]
        }
    };
    let shipped = match out.kept {
        Kept::JointBlend => None,
        Kept::DeltaMush => Some(made_alone.unwrap_or_else(alone)),
        Kept::Both => Some(made_union.unwrap_or_else(both)),
    };
    Ok((out, shipped))
}

/// What each fold fits its sides with: the delta-mush proxies' groups and smoothing, and per
/// kind (joint-blend, delta-mush, both where offered) the proxy correctives' candidate chosen on
/// all training poses (None: uncorrected).
struct Sides<'a> {
    groups: &'a Groups,
    params: &'a ddm::Params,
    correctives: &'a [Option<Candidate>],
}

/// Per kind of `kinds` (fitted to all training poses), the search of its proxy correctives
/// (None where the runtime model takes none).
fn corrective_searches(
    inputs: &Inputs,
    options: &TrainOptions,
    kinds: &[&Reduced],
) -> Vec<Option<proxy_corrective::Fit>> {
    let (set, train, feats) = (inputs.set, inputs.train, inputs.feats);
    let (ssd, rigid) = (inputs.ssd, inputs.rigid);
    (kinds.iter())
        .map(|model| {
            (options.proxy_correctives)
                .then(|| proxy_corrective::fit(set, feats, ssd, rigid, model, train, options))
        })
        .collect()
}

/// The candidates' scores over the folds of `split`: the chosen joint-blend structure, the
/// delta-mush proxies of `sides.groups` with Ω of smoothing `sides.params`, and, where offered
/// (a third corrective choice), both in one palette; each corrected as `sides.correctives` say.
fn cross_validate(
    inputs: &Inputs,
    options: &TrainOptions,
    split: &Folds,
    sides: &Sides,
) -> crate::Result<Validated> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let (structure, ridges) = (inputs.chosen.structure, inputs.joint_blend.ridges());
    let normaliser = pose_scale::rigid_pose_errors(set, train, inputs.rigid);
    let candidates = sides.correctives.len();
    try_cross_validate(split, &normaliser, candidates, TOLERANCE, |fold| {
        let (_, held) = fold.poses(train);
        let inner_set = set.holding_out(&held);
        let inner = inner_set.train();
        let errors = rigid_errors(&inner_set, &inner);
        let ssd = ssd::fit(&inner_set, &inner, &errors, k);
        let (reduced, _) = structure::build(
            &inner_set,
            inputs.feats,
            &ssd,
            None,
            &structure,
            options,
            Some(ridges),
        );
        let bones = set.bone_count();
        let fold_ddm = Ddm::new(&set.rest, &set.faces, &ssd.influences, bones, sides.params)?;
        let groups = sides.groups;
        let mush = MushProxies::fit(&inner_set, &inner, &fold_ddm, &ssd.influences, groups, k);
        // Each kind's held-out errors, as it ships: corrected as its candidate says.
        let phi: Vec<_> = (held.iter())
            .map(|&i| corrective::features(set, &inputs.feats[i]))
            .collect();
        let held_error = |model: &Reduced, candidate: &Option<Candidate>| -> Vec<f64> {
            let correctives = candidate.and_then(|c| {
                let feats = inputs.feats;
                proxy_corrective::fit_candidate(
                    &inner_set, feats, &ssd, model, &inner, &c, options.up,
                )
            });
            (held.iter().zip(&phi))
                .map(|(&i, phi)| {
                    let (f, pose_bones) = (&inputs.feats[i], &set.poses[i].bones);
                    let mut palette = model.predict_proxies(set, f, pose_bones);
                    if let Some(c) = &correctives {
                        c.correct(&mut palette, phi, pose_bones);
                    }
                    let mesh = model.skin_with(set, &palette, pose_bones);
                    squared_error(set, &[i], &[mesh])
                })
                .collect()
        };
        let c = sides.correctives;
        let mut rows = vec![
            held_error(&reduced, &c[0]),
            held_error(&mush.reduced(bones, &ssd.influences), &c[1]),
        ];
        if let Some(both) = c.get(2) {
            let union = join(&reduced, &mush, &inner_set, &inner, inputs.feats, k);
            rows.push(held_error(&union, both));
        }
        Ok(rows)
    })
}

/// The candidate kept: the rule's, but both kinds only where they beat the better kind alone
/// by [`BOTH_MARGIN`] (else the rule again over the two alone).
fn kept(validated: &Validated) -> usize {
    let alone = &validated.scores[..2];
    let best_alone = alone.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
    let clear = |both: f64| both * (1.0 + BOTH_MARGIN).powi(2) <= best_alone;
    match validated.chosen {
        2 if !clear(validated.scores[2].0) => validated.among_first(2, TOLERANCE).chosen,
        chosen => chosen,
    }
}
