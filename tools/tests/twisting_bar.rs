//! The paper's twisting-bar experiment (§7, Fig. 13): a bar of two bones whose black-box rig
//! spreads the child's twist smoothly along the bar. Linear blend skinning cannot represent a
//! twist (it collapses toward 180°); rotational regression learns it from three poses and
//! predicts an unseen one.

mod support;

use glam::{DMat3, DVec3};
use rrskin_tools::eval;
use rrskin_tools::set::{Affine, ExampleSet, Pose};
use rrskin_tools::train::TrainOptions;

const RINGS: usize = 25;
const SEGMENTS: usize = 12;

fn twist(angle: f64) -> DMat3 {
    DMat3::from_rotation_x(angle)
}

/// Fraction of the child's twist a point at `x` follows: 0 before 0.5, 1 after 1.5, smooth.
fn share(x: f64) -> f64 {
    let t = ((x - 0.5) / 1.0).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn bar_set(train_degrees: &[f64], test_degrees: &[f64]) -> ExampleSet {
    let (rest, faces) = support::tube(RINGS, SEGMENTS, 2.0, 0.2);
    let degrees: Vec<(f64, bool)> = train_degrees
        .iter()
        .map(|&d| (d, false))
        .chain(test_degrees.iter().map(|&d| (d, true)))
        .collect();
    let poses = degrees
        .iter()
        .map(|&(deg, _)| {
            let phi = deg.to_radians();
            Pose {
                bones: vec![
                    Affine {
                        q: DMat3::IDENTITY,
                        d: DVec3::ZERO,
                    },
                    Affine {
                        q: twist(phi),
                        d: DVec3::ZERO,
                    }, // about the bar's axis
                ],
                vertices: rest.iter().map(|&p| twist(phi * share(p.x)) * p).collect(),
            }
        })
        .collect();
    ExampleSet {
        rest,
        faces,
        parents: vec![None, Some(0)],
        poses,
        is_test: degrees.iter().map(|&(_, t)| t).collect(),
        bone_names: None,
        rig_weights: None,
        warnings: Vec::new(),
    }
}

#[test]
fn rotational_regression_learns_the_twist_that_skinning_cannot() {
    let set = bar_set(&[0.0, 90.0, 180.0], &[135.0]);
    let options = eval::Options {
        train: TrainOptions {
            proxies: 0,
            quiet: true,
            ..Default::default()
        },
        ..Default::default()
    };
    let report = eval::run(&set, &options).expect("training");
    let ssd = report.ssd.test.expect("a test pose");
    let full = report.rr_full.expect("eval trains the full model");
    let rr = full.test.expect("a test pose");
    assert!(ssd > 20.0, "SSD should fail on the twist: test EE {ssd}");
    // Not zero: where the twist varies along the bar it shears each triangle, tilting its
    // rotation off the bone's axis by an amount a single scale u cannot follow across poses.
    assert!(
        rr < 0.25 * ssd,
        "rotational regression test EE {rr} vs SSD {ssd}"
    );
    assert!(
        full.train < 0.25 * report.ssd.train,
        "{full:?} vs {:?}",
        report.ssd
    );
}

/// `--loocv`: the test column becomes the leave-one-out error over the training poses (each
/// predicted by a model trained without it), here on the bar's three twists.
#[test]
fn leave_one_out_reports_held_out_training_poses() {
    let set = bar_set(&[0.0, 60.0, 120.0, 180.0], &[]);
    let options = |loocv| eval::Options {
        train: TrainOptions {
            proxies: 0,
            quiet: true,
            ..Default::default()
        },
        loocv,
        ..Default::default()
    };
    let plain = eval::run(&set, &options(false)).expect("training");
    assert_eq!(plain.rr_full.and_then(|e| e.test), None, "no test poses");
    let loo = eval::run(&set, &options(true)).expect("leave-one-out");
    assert!(loo.loocv);
    let full = loo.rr_full.expect("eval trains the full model");
    let (rr, ssd) = (
        full.test.expect("LOOCV error"),
        loo.ssd.test.expect("LOOCV error"),
    );
    assert_eq!(loo.rigid.test, Some(100.0));
    assert!(
        rr.is_finite() && rr > full.train,
        "held-out {rr} vs train {}",
        full.train
    );
    assert!(rr < ssd, "leave-one-out: RR {rr} vs SSD {ssd}");
}

/// The runtime model (joint-blend proxies, refit, reweight) twists too: proxies turning by
/// fractions of the joint's twist are what linear blend skinning lacks.
#[test]
fn the_runtime_model_twists_where_skinning_collapses() {
    let set = bar_set(&[0.0, 45.0, 90.0, 120.0], &[70.0, 105.0]);
    let options = eval::Options {
        train: TrainOptions {
            full_model: false,
            quiet: true,
            ..Default::default()
        },
        ..Default::default()
    };
    let report = eval::run(&set, &options).expect("training");
    let ssd = report.ssd.test.expect("test poses");
    let reduced = report
        .rr_reduced
        .and_then(|e| e.test)
        .expect("a runtime model");
    assert!(ssd > 10.0, "SSD should fail on the twist: test EE {ssd}");
    assert!(
        reduced < 0.25 * ssd,
        "runtime model test EE {reduced} vs SSD {ssd}"
    );
}

/// Centres of rotation keep the twisted bar round (Le & Hodgins 2016): with the bar's own smooth
/// weights, LBS pulls the middle of a 170° twist onto the axis (the candy wrapper); the centres
/// lie on the axis, so every vertex keeps the bar's radius.
#[test]
fn centres_of_rotation_twist_without_the_candy_wrapper() {
    let set = bar_set(&[0.0], &[]);
    let weights: Vec<Vec<(usize, f64)>> = set
        .rest
        .iter()
        .map(|p| vec![(0, 1.0 - share(p.x)), (1, share(p.x))])
        .collect();
    let bones = [
        Affine {
            q: DMat3::IDENTITY,
            d: DVec3::ZERO,
        },
        Affine {
            q: twist(170f64.to_radians()),
            d: DVec3::ZERO,
        },
    ];
    let radius = |p: &DVec3| p.y.hypot(p.z);
    let lbs = rrskin_tools::skinning::lbs::Skinning {
        influences: weights.clone(),
    }
    .deform(&set.rest, &bones);
    let thinnest = lbs.iter().map(radius).fold(f64::INFINITY, f64::min);
    assert!(thinnest < 0.05, "LBS should collapse: radius {thinnest}");
    let centres = rrskin_tools::skinning::cor::centres(&set.rest, &set.faces, &weights);
    let cor = rrskin_tools::skinning::cor::deform(&set.rest, &weights, &centres, &bones);
    for (a, p) in cor.iter().enumerate() {
        assert!(
            (radius(p) - 0.2).abs() < 1e-9,
            "vertex {a}: radius {} (centre {:?})",
            radius(p),
            centres[a]
        );
    }
    // And it twists: the middle ring (equal weights) turns by half the joint's angle.
    let middle = (RINGS / 2) * SEGMENTS;
    let angle = cor[middle].z.atan2(cor[middle].y).to_degrees();
    assert!(
        (angle - 85.0).abs() < 1e-6,
        "middle ring turned by {angle}°"
    );
}

/// In `eval`, CoR and DDM are measured with SSD's weights: on the twist CoR beats SSD's LBS.
#[test]
fn eval_reports_centres_of_rotation_and_direct_delta_mush() {
    let set = bar_set(&[0.0, 90.0, 180.0], &[135.0]);
    let options = eval::Options {
        train: TrainOptions {
            proxies: 0,
            full_model: false,
            quiet: true,
            ..Default::default()
        },
        ..Default::default()
    };
    let report = eval::run(&set, &options).expect("training");
    let (ssd, cor) = (
        report.ssd.test.expect("a test pose"),
        report.cor.and_then(|e| e.test).expect("a test pose"),
    );
    assert!(cor < 0.5 * ssd, "CoR test EE {cor} vs SSD {ssd}");
    assert!(report
        .direct_delta_mush
        .and_then(|e| e.test)
        .is_some_and(f64::is_finite));
    let stages: Vec<&str> = report.stages.iter().map(|s| s.0).collect();
    assert!(
        stages.contains(&"cor") && stages.contains(&"ddm"),
        "{stages:?}"
    );
    let json = report.to_json();
    for key in ["cor", "ddm"] {
        assert!(
            json[key]["train"].is_number() && json[key]["test"].is_number(),
            "{json}"
        );
    }
    assert!(json["rig_cor"].is_null());
}
