//! The last check before training: the rig's own skin must follow the examples better than
//! rigid bones do. A cache in other axes, another space, another vertex order or shifted by a
//! frame is what the glTF's skin cannot follow; training on it would make a model of garbage.

use crate::eval::enveloping_error;
use crate::import::example_set::ExampleSet;
use crate::train::ssd::{rigid_bones, rigid_errors, Skinning};

/// Linear blend skinning with the rig's weights, in EE % of the best rigid predictor on the
/// training poses, at or above which a set is refused. A rig's own skin is far below (40–60 % on
/// the bundled sets); every misaligned export measured was at 96–122 %.
pub const RIG_SKIN_LIMIT: f64 = 90.0;

/// The rig's skin EE % on the training poses (None when the set has no rig weights).
pub fn rig_skin_error(set: &ExampleSet) -> Option<f64> {
    let weights = set.rig_weights.as_ref()?;
    let train = set.train();
    let rigid = Skinning::rigid(&rigid_bones(&rigid_errors(set, &train)));
    let skin = Skinning {
        influences: weights.clone(),
    };
    let posed: Vec<_> = train
        .iter()
        .map(|&i| skin.deform(&set.rest, &set.poses[i].bones))
        .collect();
    Some(enveloping_error(set, &train, &posed, &rigid))
}
