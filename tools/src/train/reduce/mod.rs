//! Reduction to the runtime form (paper §5 and §4.3): P proxy bones (§5.1), P key predictors
//! (§5.2), and the C1/C2 matrices mapping key gradients and bones to proxy transforms (§4.3).

pub mod c1c2;
pub mod delta_mush;
pub mod delta_mush_keys;
pub mod joint_blend;
pub mod predictor;
pub mod refit;
pub mod stretch;
pub mod vertex;

use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use crate::train::full_model::{self, FullModel, Prepared};
use c1c2::Reduced;
use vertex::Stop;

/// What the reduction is asked for: where merging stops (P, or the paper's ε) and K.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reduction {
    pub stop: Stop,
    pub influences: usize,
}

/// Vertex reduction (§5.1), predictor reduction (§5.2) and C1/C2 (§4.3) on the `train` poses,
/// for the full model's near-rigid set, regression weights and scale/shear ridge.
pub fn run(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    ssd: &Skinning,
    full: &FullModel,
    reduction: &Reduction,
) -> Reduced {
    let groups = vertex::reduce(
        set,
        train,
        &full.fixed,
        reduction.stop,
        reduction.influences,
    );
    let keys = predictor::reduce(set, prep, train, &groups);
    let nearby = full_model::nearby_bones(set, ssd);
    let mut key_bones = vec![Vec::<usize>::new(); groups.count()];
    for (k, &g) in groups.triangle_group.iter().enumerate() {
        for &b in &nearby[k] {
            if !key_bones[g].contains(&b) {
                key_bones[g].push(b);
            }
        }
    }
    let predictors = predictor::train_predictors(set, prep, train, &keys, &key_bones, full.ridge);
    c1c2::assemble(
        set,
        ssd,
        &full.fixed,
        &full.alpha,
        &groups,
        &keys,
        predictors,
    )
}
