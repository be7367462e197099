//! Delta-mush proxies as the runtime model (beyond the paper; docs/method.md §23): fitted to the
//! training poses ([`crate::train::reduce::mush`]) and kept in place of the joint-blend model
//! where the k-fold cross-validation over the training poses prefers them (§18's folds,
//! pose-relative score and one-standard-error rule with its tolerance, the joint-blend
//! structure first, so that it stays unless the delta-mush proxies win clearly).
//!
//! Direct Delta Mush's smoothing (p, α) is chosen on all training poses, with SSD's weights
//! ([`ddm::choose`]); the proxies' groups are merged once, on all training poses, and fixed
//! inside the folds, as the joint-blend model's ridges are there (the merging is most of the
//! cost); SSD, Ω and the weights are fitted per fold. The joint-blend side of each fold is its
//! structure as chosen, without proxy correctives: both sides are compared as fitted to the
//! poses, before anything corrects them.

use crate::set::ExampleSet;
use crate::skinning::ddm::{self, Ddm};
use crate::skinning::error::squared_error;
use crate::skinning::lbs::{rigid_errors, Skinning};
use crate::train::cross_validate::{try_cross_validate, Folds};
use crate::train::reduce::mush::{Groups, MushProxies};
use crate::train::rotreg::PoseFeatures;
use crate::train::structure::{self, Chosen, JointBlendFit, TOLERANCE};
use crate::train::{pose_scale, ssd, Method, TrainError, TrainOptions};
use glam::DVec3;

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
    /// (score, standard error) of the joint-blend structure, then of the delta-mush proxies;
    /// empty with fewer training poses than folds (then the joint-blend model stays) or with
    /// [`Method::DeltaMush`] (then they are kept unasked).
    pub scores: Vec<(f64, f64)>,
    /// Whether the cross-validation keeps the delta-mush proxies: the runtime model is theirs.
    pub chosen: bool,
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
}

/// Fits delta-mush proxies of P = `options.proxies` and K = `options.influences` to the training poses
/// and cross-validates them against the chosen joint-blend structure (kept without asking with
/// [`Method::DeltaMush`]).
pub fn fit(inputs: &Inputs, options: &TrainOptions) -> Result<Fit, TrainError> {
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
        chosen: false,
    };
    if options.method == Method::DeltaMush {
        out.chosen = true;
        return Ok(out);
    }
    let Some(split) = Folds::new(train.len(), options.folds) else {
        return Ok(out);
    };
    let (structure, ridges) = (inputs.chosen.structure, inputs.joint_blend.ridges());
    let normaliser = pose_scale::rigid_pose_errors(set, train, inputs.rigid);
    let validated = try_cross_validate(&split, &normaliser, 2, TOLERANCE, |fold| {
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
        let fold_ddm = Ddm::new(&set.rest, &set.faces, &ssd.influences, bones, &proxy_params)?;
        let mush = MushProxies::fit(&inner_set, &inner, &fold_ddm, &ssd.influences, &groups, k);
        let held_error = |predict: &dyn Fn(usize) -> Vec<DVec3>| -> Vec<f64> {
            (held.iter())
                .map(|&i| squared_error(set, &[i], &[predict(i)]))
                .collect()
        };
        Ok::<_, crate::Error>(vec![
            held_error(&|i| reduced.predict(set, &inputs.feats[i], &set.poses[i].bones)),
            held_error(&|i| mush.deform(&set.rest, &set.poses[i].bones)),
        ])
    })
    .map_err(smoothing)?;
    out.scores = validated.scores;
    out.chosen = validated.chosen == 1;
    Ok(out)
}
