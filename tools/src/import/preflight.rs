//! The last check before training: the rig's own skin must follow the examples better than
//! rigid bones do. A cache in other axes, another space, another vertex order or shifted by a
//! frame is what the glTF's skin cannot follow; training on it would make a model of garbage.

use crate::import::example_set::ExampleSet;
use crate::train::selection::squared_error;
use crate::train::ssd::{rigid_errors, Skinning};

/// Linear blend skinning with the rig's weights, in EE % of the best rigid predictor on the
/// training poses, at or above which a set is refused. A rig's own skin is far below (40–60 % on
/// the bundled sets); every misaligned export measured was at 96–122 %.
pub const RIG_SKIN_LIMIT: f64 = 90.0;

/// The rig's skin EE % on the training poses (None when the set has no rig weights, or when
/// rigid bones already follow it to float precision: nothing moves that a skin could miss).
pub fn rig_skin_error(set: &ExampleSet) -> Option<f64> {
    let weights = set.rig_weights.as_ref()?;
    let train = set.train();
    // The best rigid predictor's squared error: per vertex, its best bone's.
    let reference: f64 = rigid_errors(set, &train)
        .iter()
        .map(|e| e.iter().copied().fold(f64::INFINITY, f64::min))
        .sum();
    let size = crate::import::vertex_map::diagonal(&set.rest);
    let still = (1e-6 * size).powi(2) * (set.vertex_count() * train.len()) as f64;
    if reference <= still {
        return None;
    }
    let skin = Skinning {
        influences: weights.clone(),
    };
    let posed: Vec<_> = train
        .iter()
        .map(|&i| skin.deform(&set.rest, &set.poses[i].bones))
        .collect();
    // EE as `eval::enveloping_error` computes it, with the rigid error known already.
    Some(100.0 * (squared_error(set, &train, &posed) / reference).sqrt())
}
