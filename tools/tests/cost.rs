//! The cost model (`rrskin::cost`) and the training budget it prices (`train::budget`): the
//! engine baseline is the unit, each key kind costs what its passes do, and training keeps
//! every choice within the budget it is given, naming what the budget refused.

#[path = "../../tests/common/scratch.rs"]
mod scratch;

use rrskin::cost::{Cost, Target, LAVAPIPE};
use rrskin::Model;
use rrskin_render::synthetic::{random_model, with_delta_mush_keys, Spec};
use rrskin_tools::cylinder_chain::Chain;
use rrskin_tools::train::budget::{CostBudget, Priced};
use rrskin_tools::train::{self, TrainOptions};
use scratch::temp_dir;
use std::process::Command;

fn model(proxies: usize) -> Model {
    let spec = Spec {
        grid: 24,
        bones: 8,
        proxies,
        influences: 4,
    };
    random_model(spec, 7).expect("a valid model")
}

fn ratio(m: &Model, target: Target) -> f64 {
    Cost::of(m, target, &LAVAPIPE)
        .ratio()
        .expect("a Vulkan target")
}

#[test]
fn plain_skinning_costs_the_engine_baseline_and_recomputed_normals_cost_more() {
    let plain = model(0);
    assert_eq!(ratio(&plain, Target::Transformed), 1.0);
    assert!(ratio(&plain, Target::Recomputed) > 1.0);
    let passes: Vec<&str> = (Cost::of(&plain, Target::Recomputed, &LAVAPIPE)
        .passes
        .iter())
    .map(|p| p.pass)
    .collect();
    assert_eq!(passes, ["skinning", "normals"]);
}

#[test]
fn proxies_and_delta_mush_keys_cost_more_on_every_target() {
    let (few, many) = (model(6), model(24));
    for target in [Target::Recomputed, Target::Transformed] {
        assert!(ratio(&few, target) > 1.0);
        assert!(ratio(&many, target) > ratio(&few, target), "{target:?}");
    }
    let us = |m: &Model| Cost::of(m, Target::Palette, &LAVAPIPE).microseconds();
    assert!(us(&many) > us(&few) && us(&few) > 0.0);
    // A delta-mush key (a rigid fit over its bones) costs about what a predictor key does:
    // the model's keys' share of the frame within a factor 2 either way.
    let some = with_delta_mush_keys(&many, 8, 1).expect("delta-mush keys");
    let all = with_delta_mush_keys(&many, 24, 1).expect("delta-mush keys");
    for target in Target::ALL {
        let ns = |m: &Model| Cost::of(m, target, &LAVAPIPE).ns;
        let keys = |m: &Model| ns(m) - ns(&model(0));
        for with_delta_mush in [&some, &all] {
            let share = keys(with_delta_mush) / keys(&many);
            assert!((0.5..2.0).contains(&share), "{target:?}: {share}");
        }
    }
}

/// `rrskin ARGS`'s one JSON object, the run having succeeded.
fn json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_rrskin"))
        .args(args)
        .output()
        .expect("rrskin runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {stderr}");
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn info_reports_the_cost_of_every_target() {
    let dir = temp_dir("cost-info");
    let path = dir.join("m.rrs");
    model(12).save(&path).expect("written");
    let info = json(&["info", path.to_str().expect("utf-8"), "--json"]);
    let targets = &info["cost"]["targets"];
    for (name, ratio) in [
        ("recomputed_normals", true),
        ("transformed_normals", true),
        ("palette", false),
    ] {
        let t = &targets[name];
        assert!(t["ns"].as_f64().is_some_and(|ns| ns > 0.0), "{info}");
        assert_eq!(t["ratio"].is_number(), ratio, "{info}");
        assert!(
            !t["passes"].as_array().expect("passes").is_empty(),
            "{info}"
        );
    }
    let text = Command::new(env!("CARGO_BIN_EXE_rrskin"))
        .args(["info", path.to_str().expect("utf-8")])
        .output()
        .expect("rrskin runs");
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("x the engine baseline"), "{text}");
}

#[test]
fn bench_measures_the_palette_of_any_model() {
    let dir = temp_dir("cost-palette");
    let path = dir.join("m.rrs");
    with_delta_mush_keys(&model(12), 4, 2)
        .expect("delta-mush keys")
        .save(&path)
        .expect("written");
    let path = path.to_str().expect("utf-8");
    let b = json(&[
        "bench",
        path,
        "--palette",
        "--characters",
        "8",
        "--frames",
        "2",
        "--json",
    ]);
    for key in ["palette_us", "palette_us_threads"] {
        assert!(b[key].as_f64().is_some_and(|us| us > 0.0), "{b}");
    }
    assert_eq!(b["characters"], 8);
}

/// A cylinder chain, small: its keys are a large share of its frame.
fn chain() -> rrskin_tools::set::ExampleSet {
    let chain = Chain {
        rings: 12,
        segments: 8,
        bones: 4,
        poses: 24,
    };
    chain.build().expect("a valid chain")
}

fn trained(budget: CostBudget) -> train::Trained {
    let options = TrainOptions {
        proxies: 12,
        full_model: false,
        quiet: true,
        budget,
        ..TrainOptions::default()
    };
    train::run(&chain(), &options).expect("training")
}

/// A pose-space corrective target is one stream a vertex in the skinning pass (its delta's
/// address steps with the vertex: not a gather), and nothing else there changes.
#[test]
fn each_corrective_target_streams_once_a_vertex() {
    let plain = model(6);
    let with = |n: usize| {
        let mut parts = plain.parts().clone();
        let v = plain.vertex_count();
        parts.correctives = Some(rrskin::Correctives {
            drivers: vec![1],
            map: vec![0.1; n * 9],
            targets: vec![[0.0, 0.01, 0.0]; n * v],
        });
        Model::new(parts).expect("a valid model")
    };
    let skinning = |m: &Model| {
        let cost = Cost::of(m, Target::Transformed, &LAVAPIPE);
        let pass = cost.passes.iter().find(|p| p.pass == "skinning");
        pass.expect("a skinning pass").work
    };
    let a = skinning(&plain);
    assert_eq!(a.streams, 0.0);
    for n in [1, 4, 16] {
        let b = skinning(&with(n));
        assert_eq!(b.streams, (n * plain.vertex_count()) as f64, "{n} targets");
        assert_eq!(a.gathers, b.gathers, "{n} targets");
    }
    let ratio_of = |n| ratio(&with(n), Target::Transformed);
    assert!(ratio(&plain, Target::Transformed) < ratio_of(1) && ratio_of(1) < ratio_of(4));
}

#[test]
fn training_keeps_to_the_budget_and_names_what_it_refused() {
    let free = trained(CostBudget::NONE);
    assert!(free.refused.is_empty());
    let free_price = free.priced.expect("a runtime model").frame;
    // A budget below what the unlimited model costs: a cheaper model, within it.
    let limit = 1.0 + (free_price - 1.0) / 2.0;
    let budget = CostBudget {
        frame: Some(limit),
        palette_us: None,
    };
    let held = trained(budget);
    let model = held.model.as_ref().expect("a runtime model");
    let priced = Priced::of(model);
    assert_eq!(held.priced, Some(priced));
    assert!(
        priced.frame <= limit || model.proxy_count() == 1,
        "{} over {limit} with {} proxies",
        priced.frame,
        model.proxy_count()
    );
    assert!(!held.refused.is_empty());
    assert!(
        held.refused.iter().all(|r| r.load > 1.0),
        "{:?}",
        held.refused
    );
    // The palette's limit alike.
    let palette = CostBudget {
        frame: None,
        palette_us: Some(Priced::of(free.model.as_ref().expect("a model")).palette_us / 2.0),
    };
    let held = trained(palette);
    let priced = held.priced.expect("a runtime model");
    assert!(
        priced.palette_us <= palette.palette_us.expect("a limit")
            || held.model.as_ref().is_some_and(|m| m.proxy_count() == 1)
    );
}

#[test]
fn a_budget_is_a_positive_number_or_none() {
    let set = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/cesiumman");
    for (flag, value) in [
        ("--budget", "0"),
        ("--budget", "cheap"),
        ("--palette-budget", "-3"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_rrskin"))
            .args(["train", set, "-o", "unused.rrs", flag, value])
            .output()
            .expect("rrskin runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{flag} {value} accepted");
        assert!(
            err.contains(flag) && err.contains("positive number"),
            "{err}"
        );
    }
}

/// `Cost::floor` is a floor: below what every model of its vertices, influences and delta-mush
/// keys is priced, on every target, whatever else the model has (proxies beside the keys,
/// sparse or dense products, more bones a key).
#[test]
fn the_floor_is_below_every_model_of_its_keys() {
    for (grid, proxies, keys, seed) in [
        (8, 6, 6, 1),
        (24, 24, 8, 2),
        (24, 24, 24, 3),
        (40, 60, 30, 4),
    ] {
        let spec = Spec {
            grid,
            bones: 8,
            proxies,
            influences: 4,
        };
        let model = random_model(spec, seed).expect("a valid model");
        let with_delta_mush = with_delta_mush_keys(&model, keys, seed).expect("delta-mush keys");
        for target in Target::ALL {
            let floor = Cost::floor(with_delta_mush.vertex_count(), 4, keys, target, &LAVAPIPE);
            let cost = Cost::of(&with_delta_mush, target, &LAVAPIPE);
            assert!(
                floor.ns <= cost.ns,
                "{target:?} {keys} keys: {} > {}",
                floor.ns,
                cost.ns
            );
            assert!(floor.ns > 0.0);
            if let (Some(f), Some(c)) = (floor.ratio(), cost.ratio()) {
                assert!(f <= c, "{target:?}: {f} against {c}");
            }
            if target == Target::Transformed {
                // The engine's own pass and the keys' fits: more than the engine's alone.
                assert!(floor.ratio().is_some_and(|f| f > 1.0));
            }
        }
    }
}

/// A count of delta-mush proxies no model of can be within the budget is refused by its floor,
/// not fitted (`rrskin train --proxies 100000` answered at once), and training still ships a
/// model within the budget.
#[test]
fn an_impossible_count_is_refused_without_fitting_it() {
    let options = TrainOptions {
        proxies: 100_000,
        full_model: false,
        quiet: true,
        ..TrainOptions::default()
    };
    let trained = train::run(&chain(), &options).expect("training");
    let unfitted: Vec<_> = trained.refused.iter().filter(|r| r.floor).collect();
    // The largest count (the P asked, capped by the mesh) is the first met, and not fitted.
    let first = (trained.refused.iter())
        .find(|r| r.candidate.ends_with(" delta-mush proxies"))
        .expect("a delta-mush count refused");
    assert!(first.floor, "{:?}", trained.refused);
    assert!(unfitted.iter().all(|r| r.load > 1.0 && r.ee.is_none()));
    // The joint-blend proxies over the budget are named by the count built, not the P asked.
    assert!(trained
        .refused
        .iter()
        .all(|r| !r.candidate.contains("100000")));
    let priced = trained.priced.expect("a runtime model");
    assert!(priced.frame <= 1.25, "{priced:?}");
}
