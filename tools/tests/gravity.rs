//! Gravity as an input of the proxy correctives (docs/method.md §21): a cylinder chain whose
//! flesh sags under gravity (each bone's middle pulled along world down, as much as the bone
//! lies across it) while the root turns at random. A joint rotation is relative to its parent:
//! it cannot tell how a bone lies to gravity, which the whole chain above it decides. Offered the
//! bones' orientation to gravity, training takes it, and the runtime model beats the one trained
//! without it on the held-out poses; the CPU reference of the shipped model reads each
//! character's up vector.

use glam::DVec3;
use rrskin_tools::cylinder_chain::Chain;
use rrskin_tools::set::ExampleSet;
use rrskin_tools::skinning::error::enveloping_error;
use rrskin_tools::train::budget::CostBudget;
use rrskin_tools::train::{self, TrainOptions};

const CHAIN: Chain = Chain {
    rings: 24,
    segments: 8,
    bones: 4,
    poses: 50,
};

/// How far a bone's middle sags when the bone lies across gravity (the radius is 0.25).
const SAG: f64 = 0.1;

/// The chain's poses, each vertex also sagging by `SAG sin(π f) (g − (g·a) a)`: f its place
/// along its bone (0 at a joint, so the sag is continuous), a the bone's axis in the pose and g
/// = −Y, less the rest pose's sag (in the rest mesh, carried by the bone as it turns).
fn sagging_chain() -> ExampleSet {
    let mut set = CHAIN.build().expect("a valid chain");
    let g = DVec3::NEG_Y;
    let sag = |a: DVec3| g - g.dot(a) * a;
    for pose in &mut set.poses {
        for (rest, moved) in set.rest.iter().zip(&mut pose.vertices) {
            let b = (rest.x.max(0.0) as usize).min(CHAIN.bones - 1);
            let f = (rest.x - b as f64).clamp(0.0, 1.0);
            let q = pose.bones[b].q;
            let here = sag(q * DVec3::X) - q * sag(DVec3::X);
            *moved += SAG * (std::f64::consts::PI * f).sin() * here;
        }
    }
    set
}

fn options(up: Option<[f64; 3]>) -> TrainOptions {
    TrainOptions {
        proxies: 12,
        full_model: false,
        delta_mush: false,
        quiet: true,
        up,
        // The features compared by their error alone: on the chain's few vertices the proxy
        // correctives are a large share of the frame (tools/tests/cost.rs).
        budget: CostBudget::NONE,
        ..TrainOptions::default()
    }
}

#[test]
fn a_sagging_rig_gets_gravity_features_that_beat_joint_rotations_held_out() {
    let set = sagging_chain();
    let test = set.test();
    let held_out = |up: Option<[f64; 3]>| {
        let trained = train::run(&set, &options(up)).expect("training");
        let model = trained.model.expect("a runtime model");
        let meshes = rrskin_tools::eval::runtime_meshes(&set, &model, &test).expect("meshes");
        let error = enveloping_error(&set, &test, &meshes, &trained.rigid);
        let fit = trained
            .proxy_correctives
            .expect("the proxy correctives' stage ran");
        (model, error, fit.chosen)
    };
    let (model, with, chosen) = held_out(Some([0.0, 1.0, 0.0]));
    let (_, without, plain) = held_out(None);
    eprintln!("held-out EE: with gravity offered {with:.2} ({chosen:?}), without {without:.2} ({plain:?})");
    assert!(chosen.is_some_and(|c| c.gravity), "{chosen:?}");
    assert_eq!(model.up(), Some([0.0, 1.0, 0.0]));
    assert!(with < 0.8 * without, "with {with}, without {without}");

    // The shipped model reads a character's up: the rest pose of a character lying on its side
    // (up +X in its bones' frame) sags the other way from an upright one's, which is exact.
    let mut cpu = rrskin::cpu::CpuEvaluator::new(&model);
    let rest = vec![rrskin::palette::REST; set.bone_count()];
    let v = set.vertex_count();
    let (mut upright, mut lying, mut normals) = (
        vec![[0.0f32; 3]; v],
        vec![[0.0f32; 3]; v],
        vec![[0.0f32; 3]; v],
    );
    cpu.evaluate(&rest, &mut upright, &mut normals)
        .expect("upright");
    cpu.set_ups(&[[1.0, 0.0, 0.0]]).expect("finite");
    cpu.evaluate(&rest, &mut lying, &mut normals)
        .expect("lying");
    let moved = (upright.iter().zip(&lying))
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max);
    assert!(
        moved > 0.01,
        "lying on its side moved the rest pose by {moved}"
    );
}
