//! Delta-mush proxies ([`crate::train::reduce::mush`]) beside the runtime model: their EE, and
//! the k-fold cross-validation over the training poses that chooses between them and the
//! runtime model's joint-blend structure (§18's folds, pose-relative score and
//! one-standard-error rule with its tolerance, the joint-blend model first). The proxies' groups
//! are merged once, on all training poses, and fixed inside the folds, as the joint-blend
//! model's ridges are there (the merging is most of the cost: 11 s on human_heavy, four times
//! that per fold with the folds in parallel on two cores); the Ω, SSD and the weights are
//! fitted per fold. A prototype: the runtime format has no delta-mush key yet, so the choice is
//! reported, not shipped.

use super::Errors;
use crate::set::ExampleSet;
use crate::skinning::ddm::{self, Ddm};
use crate::skinning::error::squared_error;
use crate::skinning::lbs::rigid_errors;
use crate::train::cross_validate::{try_cross_validate, Folds};
use crate::train::reduce::mush::{Groups, MushProxies};
use crate::train::structure::{self, TOLERANCE};
use crate::train::{pose_scale, ssd, TrainOptions, Trained};
use crate::Result;

/// What [`evaluate`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Mush {
    /// P and K of the delta-mush proxies.
    pub proxies: usize,
    pub influences: usize,
    /// Bones per proxy's rigid fit, mean over the proxies (the run-time cost of the fits).
    pub mean_bones: f64,
    pub errors: Errors,
    /// (score, standard error) of the runtime model's joint-blend structure, then of the
    /// delta-mush proxies; empty when no joint-blend model was trained or too few poses.
    pub scores: Vec<(f64, f64)>,
    /// Whether the cross-validation keeps the delta-mush proxies.
    pub chosen: bool,
}

/// Fits delta-mush proxies (P and K of the runtime model) to the training poses, with
/// `vertex_ddm` (per-vertex Ω of SSD's weights, `params` chosen on the training poses), scores
/// them with `errors` and cross-validates them against `trained`'s joint-blend structure.
pub fn evaluate(
    set: &ExampleSet,
    trained: &Trained,
    vertex_ddm: &Ddm,
    params: &ddm::Params,
    options: &TrainOptions,
    errors: &dyn Fn(&MushProxies) -> Errors,
) -> Result<Mush> {
    let train = set.train();
    let (p, k) = (options.proxies, options.influences);
    let groups = Groups::merge(set, &train, p);
    let mush = MushProxies::fit(set, &train, vertex_ddm, &trained.ssd.influences, &groups, k);
    let mut out = Mush {
        proxies: mush.proxies.entries(),
        influences: k,
        mean_bones: mush.proxies.mean_bones(),
        errors: errors(&mush),
        scores: Vec::new(),
        chosen: false,
    };
    let runtime = (trained.structure.as_ref()).zip(trained.joint_blend.as_ref());
    let (Some((chosen, fit)), Some(split)) = (runtime, Folds::new(train.len(), options.folds))
    else {
        return Ok(out);
    };
    let (structure, ridges) = (chosen.structure, fit.ridges());
    let normaliser = pose_scale::rigid_pose_errors(set, &train, &trained.rigid);
    let validated = try_cross_validate(&split, &normaliser, 2, TOLERANCE, |fold| {
        let (_, held) = fold.poses(&train);
        let inner_set = set.holding_out(&held);
        let inner = inner_set.train();
        let errors = rigid_errors(&inner_set, &inner);
        let ssd = ssd::fit(&inner_set, &inner, &errors, k);
        let (reduced, _) = structure::build(
            &inner_set,
            &trained.feats,
            &ssd,
            None,
            &structure,
            options,
            Some(ridges),
        );
        let fold_ddm = Ddm::new(
            &set.rest,
            &set.faces,
            &ssd.influences,
            set.bone_count(),
            params,
        )?;
        let mush = MushProxies::fit(&inner_set, &inner, &fold_ddm, &ssd.influences, &groups, k);
        let held_error = |predict: &dyn Fn(usize) -> Vec<glam::DVec3>| -> Vec<f64> {
            (held.iter())
                .map(|&i| squared_error(set, &[i], &[predict(i)]))
                .collect()
        };
        Ok::<_, crate::Error>(vec![
            held_error(&|i| reduced.predict(set, &trained.feats[i], &set.poses[i].bones)),
            held_error(&|i| mush.deform(&set.rest, &set.poses[i].bones)),
        ])
    })?;
    out.scores = validated.scores;
    out.chosen = validated.chosen == 1;
    Ok(out)
}
