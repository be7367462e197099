//! Training chooses delta-mush proxies where the rig smooths (docs/method.md §23): a cylinder
//! chain deformed by a smoothing black box (Direct Delta DeltaMushReport of rigid weights: every vertex
//! follows one bone, the smoothing reaches the others) gets a runtime model of delta-mush keys,
//! which the runtime's CPU reference evaluates as the training proxies deform, and which beats
//! the joint-blend model on the held-out poses; the chain's own black box (each joint's rotation
//! slerped along the cylinder: no smoothing) keeps the joint-blend model, unless delta-mush
//! proxies are asked for; a chain that smooths past its second joint only gets both kinds in
//! one palette.

use glam::DVec3;
use rrskin::KeyKind;
use rrskin_tools::cylinder_chain::Chain;
use rrskin_tools::set::{ExampleSet, Pose, SetFiles, SetParts};
use rrskin_tools::skinning::direct_delta_mush::{DirectDeltaMush, Params};
use rrskin_tools::skinning::error::enveloping_error;
use rrskin_tools::skinning::lbs::Skinning;
use rrskin_tools::train::budget::CostBudget;
use rrskin_tools::train::delta_mush::{Kept, MORE_KEYS_MARGIN};
use rrskin_tools::train::{self, Method, TrainOptions};

const CHAIN: Chain = Chain {
    rings: 24,
    segments: 8,
    bones: 6,
    poses: 40,
};

/// The kinds compared by their error alone: on the chain's few vertices a delta-mush key is a
/// large share of the frame, which the default budget refuses (tools/tests/cost.rs).
fn options() -> TrainOptions {
    TrainOptions {
        proxies: 12,
        full_model: false,
        quiet: true,
        budget: CostBudget::NONE,
        ..TrainOptions::default()
    }
}

/// The chain's poses, deformed instead by Direct Delta DeltaMushReport of rigid weights (each vertex on
/// the bone under it), 16 smoothing steps.
fn smoothed_chain() -> ExampleSet {
    smoothed_from(0.0)
}

/// The chain's poses, each vertex past x = `from` (the chain runs along x from 0 to its bone
/// count) deformed by [`smoothed_chain`]'s black box, the others by the chain's own.
fn smoothed_from(from: f64) -> ExampleSet {
    let set = CHAIN.build().expect("a valid chain");
    let rigid: Vec<Vec<(usize, f64)>> = (set.rest.iter())
        .map(|p| vec![((p.x.max(0.0) as usize).min(CHAIN.bones - 1), 1.0)])
        .collect();
    let params = Params {
        iterations: 16,
        lambda: 3.0,
        kappa: 1.0,
        alpha: 0.5,
    };
    let rig = DirectDeltaMush::new(&set.rest, &set.faces, &rigid, CHAIN.bones, &params)
        .expect("smoothing");
    let test = set.test();
    let poses = (set.poses.iter())
        .map(|p| Pose {
            bones: p.bones.clone(),
            vertices: (rig.deform(&set.rest, &p.bones).into_iter())
                .zip(set.rest.iter().zip(&p.vertices))
                .map(|(smoothed, (rest, own))| if rest.x > from { smoothed } else { *own })
                .collect(),
        })
        .collect();
    let parts = SetParts {
        rest: set.rest.clone(),
        faces: set.faces.clone(),
        parents: set.parents.clone(),
        poses,
        is_test: (0..set.poses.len()).map(|i| test.contains(&i)).collect(),
        bone_names: None,
        rig_weights: None,
    };
    ExampleSet::new(parts, &SetFiles::one("<smoothed chain>")).expect("a valid set")
}

/// The runtime model's meshes of `poses`, by the runtime's CPU reference.
fn runtime_meshes(set: &ExampleSet, model: &rrskin::Model, poses: &[usize]) -> Vec<Vec<DVec3>> {
    rrskin_tools::eval::runtime_meshes(set, model, poses).expect("evaluation")
}

/// The held-out EE of the joint-blend model alone (`--no-delta-mush`) on `test`.
fn joint_blend_error(
    set: &ExampleSet,
    test: &[usize],
    rigid: &Skinning,
    options: &TrainOptions,
) -> f64 {
    let off = TrainOptions {
        delta_mush: false,
        ..options.clone()
    };
    let trained = train::run(set, &off).expect("training");
    let model = trained.model.as_ref().expect("a runtime model");
    enveloping_error(set, test, &runtime_meshes(set, model, test), rigid)
}

#[test]
fn a_smoothing_rig_gets_delta_mush_proxies_that_beat_joint_blend_held_out() {
    let set = smoothed_chain();
    let trained = train::run(&set, &options()).expect("training");
    let fit = trained
        .delta_mush
        .as_ref()
        .expect("the delta-mush stage ran");
    eprintln!("scores (joint-blend, delta-mush, both): {:?}", fit.scores);
    // Alone or after the joint-blend model's (which, on the smoothed chain too, win by more
    // than their margin): the delta-mush keys are in the model.
    assert!(
        fit.kept != Kept::JointBlend,
        "scores (joint-blend, delta-mush, both): {:?}",
        fit.scores
    );
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), fit.proxies());
    let test = set.test();
    let shipped = runtime_meshes(&set, model, &test);
    let (delta_mush, blend) = (
        enveloping_error(&set, &test, &shipped, &trained.rigid),
        joint_blend_error(&set, &test, &trained.rigid, &options()),
    );
    eprintln!("held out EE: shipped {delta_mush:.2}, joint-blend {blend:.2}");
    assert!(
        delta_mush < blend,
        "held out: shipped {delta_mush}, joint-blend {blend}"
    );
}

#[test]
fn a_rig_that_does_not_smooth_keeps_joint_blend_proxies() {
    let set = CHAIN.build().expect("a valid chain");
    let trained = train::run(&set, &options()).expect("training");
    let fit = trained
        .delta_mush
        .as_ref()
        .expect("the delta-mush stage ran");
    eprintln!("scores (joint-blend, delta-mush, both): {:?}", fit.scores);
    assert!(
        fit.kept == Kept::JointBlend,
        "scores (joint-blend, delta-mush, both): {:?}",
        fit.scores
    );
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), 0);
    let off = TrainOptions {
        delta_mush: false,
        ..options()
    };
    let without = train::run(&set, &off).expect("training");
    assert!(without.delta_mush.is_none());
    assert_eq!(
        without.model.as_ref().map(|m| m.to_bytes()),
        Some(model.to_bytes())
    );
}

#[test]
fn asked_for_delta_mush_proxies_are_kept_without_cross_validation() {
    let set = CHAIN.build().expect("a valid chain");
    // Without proxy correctives, which the cross-validation may add to any kind.
    let asked = TrainOptions {
        method: Method::DeltaMush,
        delta_mush: false,
        proxy_correctives: false,
        ..options()
    };
    let trained = train::run(&set, &asked).expect("training");
    let fit = trained
        .delta_mush
        .as_ref()
        .expect("the delta-mush stage ran");
    assert!(fit.kept == Kept::DeltaMush && fit.scores.is_empty());
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), options().proxies);
    let reduced = trained.reduced.as_ref().expect("the shipped model in f64");
    assert!(reduced.predictors.is_empty() && reduced.delta_mush.is_some());
    assert!(model.proxy_correctives().is_none());
    // The runtime's CPU reference deforms every pose as the proxies do, to f32 round-off.
    let test = set.test();
    for (mesh, &i) in runtime_meshes(&set, model, &test).iter().zip(&test) {
        let want = fit.proxies.deform(&set.rest, &set.poses[i].bones);
        let worst = (mesh.iter().zip(&want))
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "pose {i}: {worst}");
    }
}

/// `--reduction both`: the joint-blend proxies then the delta-mush proxies, unasked.
#[test]
fn asked_for_both_kinds_are_kept_without_cross_validation() {
    let set = CHAIN.build().expect("a valid chain");
    let asked = TrainOptions {
        method: Method::Both,
        ..options()
    };
    let trained = train::run(&set, &asked).expect("training");
    let fit = (trained.delta_mush.as_ref()).expect("the delta-mush stage ran");
    assert_eq!(fit.kept, Kept::Both);
    let both = trained.reduced.as_ref().expect("the shipped model in f64");
    assert!(fit.scores.is_empty() && !both.predictors.is_empty());
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), options().proxies);
    assert_eq!(
        model.proxy_count(),
        both.predictors.len() + options().proxies
    );
}

/// The chain smooths past its second joint only: each kind of proxy fits one part, and the runtime
/// model holds both (the joint-blend model's keys and the delta-mush keys); its CPU reference
/// deforms as the trained model does in f64, and it beats either kind alone held out. Without
/// proxy correctives: with them, the delta-mush proxies alone come within the union's margin
/// here, their correctives turning the joints that do not smooth.
#[test]
fn a_rig_that_smooths_in_part_gets_both_kinds_in_one_palette() {
    let set = smoothed_from(2.0);
    let uncorrected = TrainOptions {
        proxy_correctives: false,
        ..options()
    };
    let trained = train::run(&set, &uncorrected).expect("training");
    let fit = (trained.delta_mush.as_ref()).expect("the delta-mush stage ran");
    eprintln!("scores (joint-blend, delta-mush, both): {:?}", fit.scores);
    assert_eq!(
        fit.kept,
        Kept::Both,
        "scores (joint-blend, delta-mush, both): {:?}",
        fit.scores
    );
    let both = trained.reduced.as_ref().expect("the shipped model in f64");
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), fit.proxies());
    assert_eq!(model.proxy_count(), both.predictors.len() + fit.proxies());
    assert!(!both.predictors.is_empty());
    let test = set.test();
    let plain = rrskin::Model::new(rrskin::ModelParts {
        proxy_correctives: None,
        ..model.parts().clone()
    })
    .expect("valid");
    for (mesh, &i) in runtime_meshes(&set, &plain, &test).iter().zip(&test) {
        let want = both.predict(&set, &trained.feats[i], &set.poses[i].bones);
        let worst = (mesh.iter().zip(&want))
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "pose {i}: {worst}");
    }
    let shipped = runtime_meshes(&set, model, &test);
    let ee = |meshes: &[Vec<DVec3>]| enveloping_error(&set, &test, meshes, &trained.rigid);
    let alone: Vec<Vec<DVec3>> = (test.iter())
        .map(|&i| fit.proxies.deform(&set.rest, &set.poses[i].bones))
        .collect();
    let (shipped, delta_mush, blend) = (
        ee(&shipped),
        ee(&alone),
        joint_blend_error(&set, &test, &trained.rigid, &uncorrected),
    );
    eprintln!("held out EE: both {shipped:.2}, delta-mush {delta_mush:.2}, joint-blend {blend:.2}");
    assert!(
        shipped < delta_mush.min(blend),
        "{shipped} {delta_mush} {blend}"
    );
}

/// Too few delta-mush proxies for the smoothing: the counts offered are P, 2P and 4P in the
/// kind kept, each scored on the training folds with its proxy correctives (P's score the kinds'
/// own, the same folds); a larger count ships only where it wins there by the margin each
/// doubling must, and it beats the P asked for held out.
#[test]
fn delta_mush_proxies_are_doubled_where_the_folds_say_it_pays() {
    let set = smoothed_chain();
    let few = TrainOptions {
        proxies: 3,
        ..options()
    };
    let trained = train::run(&set, &few).expect("training");
    let fit = (trained.delta_mush.as_ref()).expect("the delta-mush stage ran");
    eprintln!("kinds: {:?}, counts: {:?}", fit.scores, fit.counts);
    assert_ne!(fit.kept, Kept::JointBlend, "scores: {:?}", fit.scores);
    let offered: Vec<usize> = fit.counts.iter().map(|c| c.0).collect();
    assert_eq!(offered, [3, 6, 12]);
    assert_eq!(fit.counts[0].1, fit.scores[fit.kept as usize].0);
    let kept = (fit.counts.iter())
        .position(|c| c.0 == fit.proxies())
        .expect("the count kept was offered");
    assert!(kept > 0, "counts: {:?}", fit.counts);
    let doublings = (fit.proxies() as f64 / 3.0).log2();
    let margin = (1.0 + MORE_KEYS_MARGIN).powf(2.0 * doublings);
    assert!(fit.counts[kept].1 * margin <= fit.counts[0].1);
    let model = trained.model.as_ref().expect("a runtime model");
    assert_eq!(model.keys_of(KeyKind::DeltaMush), fit.proxies());
    let test = set.test();
    let asked = TrainOptions {
        method: match fit.kept {
            Kept::Both => Method::Both,
            _ => Method::DeltaMush,
        },
        ..few
    };
    let at_p = train::run(&set, &asked).expect("training");
    let at_p = at_p.model.as_ref().expect("a runtime model");
    assert_eq!(at_p.keys_of(KeyKind::DeltaMush), 3);
    let ee = |model| {
        let meshes = runtime_meshes(&set, model, &test);
        enveloping_error(&set, &test, &meshes, &trained.rigid)
    };
    let (shipped, asked) = (ee(model), ee(at_p));
    eprintln!(
        "held out EE: {} proxies {shipped:.2}, 3 proxies {asked:.2}",
        fit.proxies()
    );
    assert!(shipped < asked, "{shipped} {asked}");
}
