//! The delta-mush proxies' row ([`crate::train::delta_mush`]): their EE beside the runtime
//! model's, and the cross-validation that chose between them and the joint-blend model.

use super::Errors;
use crate::train::delta_mush::Fit;

/// The delta-mush proxies as evaluated.
#[derive(Debug, Clone, PartialEq)]
pub struct DeltaMushReport {
    /// P (the count kept) and K of the delta-mush proxies.
    pub proxies: usize,
    pub influences: usize,
    /// Bones per proxy's rigid fit, mean over the proxies (the run-time cost of the fits).
    pub mean_bones: f64,
    /// The smoothing of the proxies' Ω: DDM's p and α, or p = 0 (none).
    pub smoothing: crate::skinning::direct_delta_mush::Params,
    pub errors: Errors,
    /// (score, standard error) of the runtime model's joint-blend structure, the delta-mush
    /// proxies alone, then both in one palette; empty with too few poses, or with
    /// `--reduction delta-mush`.
    pub scores: Vec<(f64, f64)>,
    /// (proxies, score, standard error) of each count offered, as it ships; empty where the
    /// counts were not compared ([`Fit::counts`]).
    pub counts: Vec<(usize, f64, f64)>,
    /// What the runtime model is ([`crate::train::delta_mush::Kept::name`]).
    pub chosen: &'static str,
}

impl DeltaMushReport {
    /// The row of `fit`, whose proxies err by `errors`.
    pub fn of(fit: &Fit, errors: Errors) -> DeltaMushReport {
        DeltaMushReport {
            proxies: fit.proxies(),
            influences: fit.influences,
            mean_bones: fit.mean_bones(),
            smoothing: fit.proxy_params,
            errors,
            scores: fit.scores.clone(),
            counts: fit.counts.clone(),
            chosen: fit.kept.name(),
        }
    }
}
