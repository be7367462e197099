//! The `rrskin` binary end to end: exit codes, JSON output, and error messages that name the
//! file and the problem.

use std::path::PathBuf;
use std::process::{Command, Output};

#[path = "../../tests/common/scratch.rs"]
mod scratch;
use scratch::temp_dir;

fn rrskin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rrskin"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object on stdout")
}

#[test]
fn synth_info_and_profile_agree_on_the_model() {
    let dir = temp_dir("cli-profile");
    let model = dir.join("m.rrs");
    let m = model.to_str().expect("utf-8 path");
    let out = rrskin(&[
        "synth",
        "--grid",
        "9",
        "--bones",
        "5",
        "--proxies",
        "6",
        "--influences",
        "8",
        "-o",
        m,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = json(&rrskin(&["info", m, "--json"]));
    assert_eq!(info["vertices"], 81);
    assert_eq!(info["triangles"], 128);
    assert_eq!(
        (
            info["bones"].as_u64(),
            info["proxies"].as_u64(),
            info["influences"].as_u64()
        ),
        (Some(5), Some(6), Some(8))
    );
    assert_eq!(
        info["tangents"], true,
        "synthetic models carry rest tangents"
    );
    let p = json(&rrskin(&[
        "profile",
        m,
        "--characters",
        "5",
        "--frames",
        "3",
        "--json",
    ]));
    assert_eq!(
        (p["characters"].as_u64(), p["vertices"].as_u64()),
        (Some(5), Some(81))
    );
    for pass in [
        "predict_ms",
        "blend_ms",
        "skin_ms",
        "normals_ms",
        "total_ms",
        "skin_mverts_per_s",
    ] {
        let value = p[pass].as_f64().expect("a number");
        assert!(value > 0.0 && value.is_finite(), "{pass}: {p}");
    }
}

#[test]
fn bad_model_files_fail_with_the_file_and_the_problem() {
    let dir = temp_dir("cli-bad");
    let bad = dir.join("text.rrs");
    std::fs::write(&bad, "hello").expect("write");
    let out = rrskin(&["info", bad.to_str().expect("utf-8")]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("text.rrs") && err.contains("truncated"),
        "{err}"
    );
    let out = rrskin(&["profile", dir.join("absent.rrs").to_str().expect("utf-8")]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.rrs"));
    let out = rrskin(&[
        "synth",
        "--influences",
        "5",
        "-o",
        dir.join("k5.rrs").to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("must be 4 or 8"));
}

/// A closed pipe on stdout and stderr (`rrskin … 2>&1 | head`) ends output quietly: the exit
/// status is the command's, not a panic's 101.
#[test]
fn closed_pipes_end_output_quietly() {
    let dir = temp_dir("cli-pipe");
    let model = dir.join("m.rrs");
    let m = model.to_str().expect("utf-8 path");
    let closed = |args: &[&str]| {
        let (reader, writer) = std::io::pipe().expect("a pipe");
        drop(reader);
        Command::new(env!("CARGO_BIN_EXE_rrskin"))
            .args(args)
            .stdout(writer.try_clone().expect("dup"))
            .stderr(writer)
            .status()
            .expect("the binary runs")
            .code()
    };
    assert_eq!(closed(&["synth", "--grid", "5", "-o", m]), Some(0));
    assert_eq!(closed(&["info", m]), Some(0));
    assert_eq!(closed(&["info", "absent.rrs"]), Some(1));
}

/// Counts of zero, a crowd past the device's memory and unwritable outputs fail at once, exit 1,
/// naming the flag or the path.
#[test]
fn bad_counts_and_outputs_fail_before_any_work() {
    let dir = temp_dir("cli-counts");
    let model = dir.join("m.rrs");
    let m = model.to_str().expect("utf-8 path");
    assert!(rrskin(&["synth", "--grid", "5", "-o", m]).status.success());
    let failed = |args: &[&str]| {
        let out = rrskin(args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = failed(&["profile", m, "--frames", "0"]);
    assert!(
        err.contains("--frames") && err.contains("at least 1"),
        "{err}"
    );
    let err = failed(&["profile", m, "--characters", "0"]);
    assert!(err.contains("--characters"), "{err}");
    // 2e9 characters of 5 bones: 480 GB of bone transforms alone.
    let err = failed(&["profile", m, "--characters", "2000000000", "--frames", "1"]);
    assert!(
        err.contains("--characters 2000000000")
            && err.contains("makes buffers of at most")
            && err.contains("lower --characters"),
        "{err}"
    );
    let set = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/cesiumman");
    let set = set.to_str().expect("utf-8");
    let started = std::time::Instant::now();
    let out = format!("{}/c.rrs", dir.display());
    let err = failed(&["train", set, "-o", &out, "--correctives", "65"]);
    assert!(
        err.contains("--correctives 65") && err.contains("at most 64"),
        "{err}"
    );
    assert!(started.elapsed().as_secs() < 10, "trained first");
    // Outputs under a file: no folder can be made there.
    let file = dir.join("a-file");
    std::fs::write(&file, "").expect("write");
    let under = file.join("out");
    let under = under.to_str().expect("utf-8");
    for args in [
        vec!["demo", "--out", under],
        vec!["train", set, "-o", &*format!("{under}/m.rrs")],
    ] {
        let started = std::time::Instant::now();
        let err = failed(&args);
        assert!(
            err.contains("a-file") && !err.contains("training:"),
            "{err}"
        );
        assert!(started.elapsed().as_secs() < 10, "{args:?} trained first");
    }
}

/// `rrskin reference` writes the C example's inputs: the poses, and the CPU evaluator's positions
/// and tangents for exactly those poses.
#[test]
fn reference_writes_the_c_examples_inputs() {
    let dir = temp_dir("cli-reference");
    let model = dir.join("m.rrs");
    let m = model.to_str().expect("utf-8 path");
    assert!(rrskin(&[
        "synth",
        "--grid",
        "5",
        "--bones",
        "4",
        "--proxies",
        "3",
        "-o",
        m
    ])
    .status
    .success());
    let out = rrskin(&[
        "reference",
        m,
        "--frames",
        "2",
        "--characters",
        "3",
        "--out",
        dir.to_str().expect("utf-8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let floats = |name: &str| -> Vec<f32> {
        std::fs::read(dir.join(name))
            .expect(name)
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    };
    let (poses, expected) = (floats("poses.bin"), floats("expected.bin"));
    assert_eq!(
        (poses.len(), expected.len()),
        (2 * 3 * 4 * 12, 2 * 3 * 25 * 3)
    );
    let model = rrskin::Model::load(&model).expect("valid");
    let bones: Vec<[f32; 12]> = poses[3 * 4 * 12..]
        .chunks_exact(12)
        .map(|t| t.try_into().expect("12 floats"))
        .collect();
    let (mut p, mut n) = (vec![[0.0; 3]; 3 * 25], vec![[0.0; 3]; 3 * 25]);
    let mut t = vec![[0.0; 4]; 3 * 25];
    rrskin::cpu::CpuEvaluator::new(&model)
        .evaluate_with_tangents(&bones, &mut p, &mut n, &mut t)
        .expect("CPU evaluator (synthetic models carry tangents)");
    assert_eq!(p.as_flattened(), &expected[3 * 25 * 3..], "frame 1");
    assert_eq!(
        t.as_flattened(),
        &floats("tangents.bin")[3 * 25 * 4..],
        "frame 1"
    );
}

/// The learning curve of `eval`'s report: four points of 4-fold held-out EE at a quarter to all
/// of each fold's 30 or 31 fitted-on poses (41 training poses), falling from the first to the
/// last (measured: 21.9 at 8 poses, 16.2 at 30), and its advice in a sentence.
fn learning_curve_falls(e: &serde_json::Value) {
    let points = e["learning_curve"].as_array().expect("a list of points");
    let poses: Vec<u64> = points
        .iter()
        .map(|p| p["poses"].as_u64().expect("n"))
        .collect();
    assert_eq!(poses, [8, 15, 23, 30], "{points:?}");
    let ee: Vec<f64> = points
        .iter()
        .map(|p| p["ee"].as_f64().expect("EE"))
        .collect();
    assert!(ee.iter().all(|x| x.is_finite() && *x > 0.0), "{ee:?}");
    assert!(ee[3] < 0.9 * ee[0], "more poses, less error: {ee:?}");
    let advice = &e["learning_curve_advice"];
    assert_eq!(advice["training_poses"], 41);
    assert!(advice["saturated"].is_boolean(), "{advice}");
    let sentence = advice["sentence"].as_str().expect("a sentence");
    assert!(sentence.contains("41 training poses"), "{sentence}");
}

/// `rrskin eval --json --diagnose` on CesiumMan: the JSON contract of docs/cli.md and the
/// reference figures of docs/method.md §11 (SSD 37.4 / 41.0 ± 1; the full model at least as good
/// as the reference's best row, 35.1 / 49.3), with every choice made on the training poses; the
/// runtime model at most 0.75 of SSD's held-out error (measured: 0.69), below DQS with SSD's
/// weights and within 10 % (relative) of the full model; the error budget's oracle proxies no
/// worse than the model on the training poses (they are its per-pose least-squares optimum), nor
/// the pose-space ceiling.
#[test]
fn eval_on_cesiumman_meets_the_reference_figures() {
    let set = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/cesiumman");
    assert!(
        set.is_dir(),
        "the example data must be at {}",
        set.display()
    );
    let e = json(&rrskin(&[
        "eval",
        set.to_str().expect("utf-8"),
        "--json",
        "--diagnose",
    ]));
    let keys: Vec<&str> = e
        .as_object()
        .expect("an object")
        .keys()
        .map(|k| k.as_str())
        .collect();
    for key in [
        "vertices",
        "triangles",
        "bones",
        "train_poses",
        "test_poses",
        "proxies",
        "rigid",
        "ssd",
        "rr_full",
        "rr_reduced",
        "seconds",
        "dqs",
        "rig_lbs",
        "rig_dqs",
        "cor",
        "ddm",
        "ddm_params",
        "rig_cor",
        "diagnose",
        "stages",
        "structure",
        "correctives",
        "proxy_correctives",
        "normal_error",
        "learning_curve",
        "learning_curve_advice",
        "delta_mush",
        "cost",
        "budget",
        "pareto",
    ] {
        assert!(keys.contains(&key), "missing {key} in {e}");
    }
    assert_eq!(keys.len(), 30, "{e}");
    // The front: every structure candidate and every kind, scored and priced: the joint-blend
    // model once, and the delta-mush proxies alone and after it at every count the kinds'
    // comparison tried (fewer where the budget refused their proxy correctives).
    let points = e["pareto"].as_array().expect("the front's points");
    let stage = |s: &str| points.iter().filter(|p| p["stage"] == s).count();
    let kind = |k: &str| {
        (points.iter())
            .filter(|p| p["stage"] == "kind" && p["kind"] == k)
            .count()
    };
    assert_eq!(stage("structure"), 3, "{e}");
    assert_eq!(kind("joint-blend"), 1, "{e}");
    assert!(
        kind("delta-mush") >= 1 && kind("both") == kind("delta-mush"),
        "{e}"
    );
    assert_eq!(stage("kind"), 1 + 2 * kind("delta-mush"), "{e}");
    assert!(points.iter().any(|p| p["front"] == true), "{e}");
    for p in points {
        assert!(p["ee"].as_f64().is_some_and(|ee| ee > 0.0), "{p}");
        assert!(p["cost"]["frame"].as_f64().is_some_and(|r| r >= 1.0), "{p}");
    }
    // The default budget, and the model within it.
    assert_eq!(e["budget"]["frame"], 1.25, "{e}");
    let priced = e["budget"]["model"]["frame"].as_f64().expect("a price");
    assert!(priced <= 1.25, "{e}");
    assert_eq!(
        e["cost"]["targets"]["transformed_normals"]["ratio"],
        e["budget"]["model"]["frame"]
    );
    learning_curve_falls(&e);
    assert!(e["correctives"].is_null(), "off by default: {e}");
    assert!(
        e["rig_lbs"].is_null() && e["rig_dqs"].is_null() && e["rig_cor"].is_null(),
        "no skin_weights.npy here"
    );
    for baseline in ["cor", "ddm"] {
        assert!(e[baseline]["test"].is_number(), "{baseline}: {e}");
        assert!(
            e["stages"][baseline].is_number(),
            "{baseline}'s precomputation: {e}"
        );
    }
    let n = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    assert_eq!(
        (n(&e["vertices"]), n(&e["triangles"]), n(&e["bones"])),
        (2338.0, 4672.0, 19.0)
    );
    assert_eq!((n(&e["train_poses"]), n(&e["test_poses"])), (41.0, 20.0));
    // P ≤ the default 60: three joint-blend proxies per moving joint (18 here), so the
    // candidates are a sixth and a third of 54, and 60 (no more than 54 to make 90 of). The
    // walk's rig is met far better by all 54 (held-out EE about 18 against 24 and 27).
    assert_eq!(n(&e["proxies"]), 54.0);
    let structure = &e["structure"];
    let scored: Vec<(f64, f64)> = (structure["candidates"].as_array().into_iter().flatten())
        .map(|c| (n(&c["structure"]["proxies"]), n(&c["score"])))
        .collect();
    assert_eq!(
        scored.iter().map(|c| c.0).collect::<Vec<_>>(),
        [9.0, 18.0, 60.0],
        "{structure}"
    );
    assert!(
        scored.iter().all(|c| c.1 > 0.0 && c.1.is_finite()),
        "{structure}"
    );
    assert_eq!(n(&structure["chosen"]["proxies"]), 60.0, "{structure}");
    assert_eq!(
        structure["chosen"]["reduction"], "joint_blend",
        "{structure}"
    );
    assert!(e["stages"]["structure"].is_number(), "{e}");
    assert!(
        (n(&e["rigid"]["train"]) - 100.0).abs() < 1e-9
            && (n(&e["rigid"]["test"]) - 100.0).abs() < 1e-9
    );
    let (ssd_train, ssd_test) = (n(&e["ssd"]["train"]), n(&e["ssd"]["test"]));
    assert!(
        (ssd_train - 37.4).abs() <= 1.0 && (ssd_test - 41.0).abs() <= 1.0,
        "SSD {ssd_train} / {ssd_test}"
    );
    let (rr_train, rr_test) = (n(&e["rr_full"]["train"]), n(&e["rr_full"]["test"]));
    assert!(
        rr_train <= 35.1 && rr_test <= 49.3,
        "rr_full {rr_train} / {rr_test}"
    );
    assert!(
        rr_test < ssd_test,
        "rr_full must beat SSD on held-out poses: {rr_test} vs {ssd_test}"
    );
    let (red_train, red_test) = (n(&e["rr_reduced"]["train"]), n(&e["rr_reduced"]["test"]));
    assert!(
        red_test <= 1.1 * rr_test,
        "rr_reduced {red_train} / {red_test} vs rr_full {rr_test}"
    );
    assert!(
        red_train <= 1.1 * rr_train,
        "rr_reduced {red_train} / {red_test} vs rr_full {rr_train}"
    );
    // Measured: 0.69 (issue 12's acceptance was 0.8; its goal is 0.5).
    assert!(
        red_test <= 0.75 * ssd_test,
        "rr_reduced {red_test} vs SSD {ssd_test} on held-out poses"
    );
    let dqs_test = n(&e["dqs"]["test"]);
    assert!(dqs_test > 0.0 && dqs_test < ssd_test, "DQS {dqs_test}");
    assert!(
        red_test < dqs_test,
        "rr_reduced {red_test} vs DQS with SSD's weights {dqs_test}: a user would skin with DQS"
    );
    let oracle = &e["diagnose"]["reduced_oracle_proxies"];
    assert!(
        n(&oracle["train"]) <= red_train + 1e-3,
        "oracle {oracle} vs rr_reduced {red_train}"
    );
    // The pose-space ceiling is a ridge regression of the model's own training residuals: on
    // those poses it can only remove error (in the rest-space metric it is fitted in; the
    // blended matrices that carry it to the mesh are near rotations).
    let pose_space = &e["diagnose"]["pose_space"];
    assert!(
        n(&pose_space["train"]) <= red_train + 1e-3,
        "pose-space ceiling {pose_space} vs rr_reduced {red_train}"
    );
    for ceiling in [
        "full_exact_gradients",
        "reduced_oracle_proxies",
        "reduced_oracle_keys",
        "pose_space",
    ] {
        assert!(n(&e["diagnose"][ceiling]["test"]) > 0.0, "{ceiling}: {e}");
    }
    for method in ["ssd", "rr_full", "rr_reduced"] {
        assert!(n(&e["seconds"][method]) > 0.0, "{method}: {e}");
    }
    // The normals' held-out angular error, per method and mode, in degrees: every pair there,
    // 0 <= mean <= p95 <= 180, and normals recomputed from the runtime model's mesh within a few
    // degrees of the rig's (measured: 0.50 mean, 2.4 p95).
    for method in ["ssd", "dqs", "rr_reduced"] {
        for mode in ["recomputed", "transformed"] {
            let x = &e["normal_error"][method][mode];
            let (mean, p95) = (n(&x["mean_deg"]), n(&x["p95_deg"]));
            assert!(
                0.0 <= mean && mean <= p95 && p95 <= 180.0,
                "{method} {mode}: {x}"
            );
        }
    }
    let rr = &e["normal_error"]["rr_reduced"]["recomputed"];
    assert!(n(&rr["mean_deg"]) < 2.0 && n(&rr["p95_deg"]) < 8.0, "{rr}");
}

/// `rrskin train` writes a runtime model (here with pose-space correctives); `rrskin eval
/// --model` evaluates that file with the runtime's CPU evaluator and reports the same figures
/// training did.
#[test]
fn a_trained_model_file_evaluates_as_trained() {
    let set = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/cesiumman");
    let set = set.to_str().expect("utf-8");
    let dir = temp_dir("cli-train");
    let model = dir.join("cm.rrs");
    let m = model.to_str().expect("utf-8");
    let trained = json(&rrskin(&[
        "train",
        set,
        "-o",
        m,
        "--proxies",
        "20",
        "--reduction",
        "joint-blend",
        "--correctives",
        "8",
        // Correctives, whatever they cost (the default budget refuses 8 targets).
        "--budget",
        "none",
        "--json",
    ]));
    let info = json(&rrskin(&["info", m, "--json"]));
    assert_eq!(
        (info["proxies"].as_u64(), info["vertices"].as_u64()),
        (Some(20), Some(2338))
    );
    // The file carries the correctives the cross-validation kept (and the evaluation below
    // reads them back: the same figures).
    assert!(trained["correctives"]["ridge"].is_number(), "{trained}");
    assert_eq!(trained["correctives"]["targets"], 8, "{trained}");
    assert_eq!(info["correctives"], 8, "{info}");
    // And the proxy correctives (on by default) the cross-validation kept, from the linear basis
    // only (the kernels are asked for).
    let corrected = &trained["proxy_correctives"];
    assert_eq!(corrected["basis"], "linear", "{trained}");
    assert!(corrected["proxies"].as_u64() > Some(0), "{trained}");
    assert_eq!(info["proxy_correctives"], corrected["proxies"], "{info}");
    assert!(corrected["anchor"].is_number(), "{trained}");
    // Without gravity, then with it (offered by default, taken only where it wins clearly),
    // then the chosen one clamped into the training range.
    let candidates = corrected["candidates"].as_array().expect("candidates");
    assert_eq!(
        candidates.len(),
        2 * 3 * 8 + 1,
        "one candidate per gravity, anchor and ridge, and the clamp: {trained}"
    );
    let flag = |c: &serde_json::Value, what: &str| c[what].as_bool().expect("a bool");
    let gravity: Vec<bool> = candidates.iter().map(|c| flag(c, "gravity")).collect();
    assert!(gravity[..24].iter().all(|g| !g) && gravity[24..48].iter().all(|&g| g));
    let clamped: Vec<bool> = candidates.iter().map(|c| flag(c, "clamped")).collect();
    assert!(clamped[..48].iter().all(|c| !c) && clamped[48]);
    assert!(corrected["gravity"].is_boolean(), "{trained}");
    assert_eq!(info["clamped"], corrected["clamped"], "{info}");
    // The CPU palette of the trained file agrees with the reference playing its animation
    // (tests/palette.rs's tolerance).
    let trained_model = rrskin::Model::load(&model).expect("valid");
    let frames: Vec<rrskin::predict::Affine> =
        trained_model.animation().flatten().copied().collect();
    let worst = rrskin_render::synthetic::palette_error(&trained_model, &frames).expect("palette");
    assert!(
        worst <= rrskin_render::synthetic::PALETTE_TOLERANCE,
        "CPU palette {worst} off the reference"
    );
    let evaluated = json(&rrskin(&["eval", set, "--model", m, "--json"]));
    assert_eq!(evaluated["proxies"], 20);
    assert_eq!(trained["structure"]["chosen"]["proxies"], 20);
    assert!(
        trained["learning_curve"].is_null(),
        "train leaves it out unless asked"
    );
    for split in ["train", "test"] {
        let (a, b) = (
            &trained["rr_reduced"][split],
            &evaluated["rr_reduced"][split],
        );
        assert!(
            a.as_f64().is_some() && a == b,
            "{split}: trained {a}, evaluated {b}"
        );
    }
    // `bench` compares it with its SSD baseline (the contract of docs/cli.md).
    let b = json(&rrskin(&[
        "bench",
        m,
        "--characters",
        "4",
        "--frames",
        "2",
        "--json",
    ]));
    for key in [
        "device",
        "characters",
        "vertices",
        "rr_ms",
        "ssd_ms",
        "ratio",
        "paired_ratio",
        "rr_passes",
        "ssd_passes",
        "rr_mverts_per_s",
        "ssd_mverts_per_s",
        "rr_bytes_per_frame",
        "rr_effective_gbps",
        "ssd_effective_gbps",
        "previous_positions_ms",
        "previous_positions_ratio",
        "bounds_ms",
        "bounds_ratio",
        "engine_ms",
        "engine_passes",
        "rr_transformed_ms",
        "rr_vs_engine",
    ] {
        assert!(!b[key].is_null(), "{key} missing in {b}");
    }
    assert!(
        b["rr_vs_engine"]
            .as_f64()
            .is_some_and(|r| r > 0.0 && r.is_finite()),
        "{b}"
    );
    // The options' ratios are medians of per-frame ratios to the same frame's plain RR (not
    // the ratio of the medians); a model trained from the NumPy layout has no tangents.
    for option in ["previous_positions", "bounds"] {
        let ratio = b[format!("{option}_ratio")].as_f64();
        assert!(ratio.is_some_and(|r| r > 0.0 && r.is_finite()), "{b}");
    }
    assert!(
        b["tangents_ratio"].is_null() && b["tangents_ms"].is_null(),
        "{b}"
    );
    let ratio = b["rr_ms"].as_f64().unwrap_or(f64::NAN) / b["ssd_ms"].as_f64().unwrap_or(f64::NAN);
    assert!(
        (b["ratio"].as_f64().unwrap_or(f64::NAN) - ratio).abs() < 1e-9 && ratio > 0.0,
        "{b}"
    );
    // RR and SSD frames alternate: one ratio per pair of measured frames.
    assert_eq!(b["pairs"], 2, "{b}");
    assert!(
        b["paired_ratio"]
            .as_f64()
            .is_some_and(|r| r > 0.0 && r.is_finite()),
        "{b}"
    );
    assert_eq!(b["vertices"], 2338);
    let text = rrskin(&["bench", m, "--characters", "1", "--frames", "1"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains(": 1 character x 2338 vertices, median of 1 frame\n"),
        "{text}"
    );
    // A model of another mesh is refused with both sizes named.
    let other = dir.join("other.rrs");
    let o = other.to_str().expect("utf-8");
    assert!(rrskin(&["synth", "--grid", "5", "-o", o]).status.success());
    let no_baseline = rrskin(&["bench", o, "--characters", "2"]);
    assert!(String::from_utf8_lossy(&no_baseline.stderr).contains("no SSD baseline"));
    let out = rrskin(&["eval", set, "--model", o, "--json"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("25 vertices") && err.contains("2338"), "{err}");
}

/// `rrskin demo` (the README's main job) trains on the bundled example and writes the model,
/// the images and the report page.
#[test]
fn the_demo_writes_the_model_the_images_and_the_report() {
    let dir = temp_dir("cli-demo");
    let out = rrskin(&["demo", "--out", dir.to_str().expect("utf-8")]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}\n{}",
        stdout,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("rotational regression") && stdout.contains("comparison.png"),
        "{stdout}"
    );
    assert!(
        stdout.contains("rendered with the Vulkan runtime on ") && !stdout.contains("/../"),
        "{stdout}"
    );
    assert!(rrskin::Model::load(dir.join("model.rrs")).is_ok());
    for (name, size) in [
        ("comparison.png", (1200, 600)),
        ("closeup.png", (800, 400)),
        ("crowd.png", (1280, 720)),
    ] {
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(dir.join(name)).expect(name),
        ));
        let info = decoder.read_info().expect("a PNG").info().clone();
        assert_eq!((info.width, info.height), size, "{name}");
    }
    let report = std::fs::read_to_string(dir.join("report.html")).expect("report.html");
    assert!(
        [
            "comparison.png",
            "closeup.png",
            "crowd.png",
            "tradeoff.svg",
            "runtime model",
            "mesh units"
        ]
        .iter()
        .all(|s| report.contains(s)),
        "{report}"
    );
    // Five methods (rigid, SSD, DQS, full, runtime), then the runtime model at P/8, P/4, P/2
    // and P (6, 13, 27, 54).
    assert_eq!(report.matches("<tr><td>").count(), 5 + 4, "{report}");
    let svg = std::fs::read_to_string(dir.join("tradeoff.svg")).expect("tradeoff.svg");
    assert!(
        svg.starts_with("<svg")
            && svg.contains("runtime model")
            && svg.contains("DQS")
            && svg.contains("the front")
            && svg.contains("budget 1.25 x"),
        "{svg}"
    );
}

/// `profile` and `bench` on a rig that lists every bone after its children (issue 13: this
/// panicked in posing): `profile` on a synthetic one (random poses), `bench` on one carrying an
/// animation and an SSD baseline (it plays the animation).
#[test]
fn profile_and_bench_run_a_rig_listing_children_first() {
    use rrskin_render::synthetic::{random_model, random_poses, renumber_bones, Spec};
    let dir = temp_dir("cli-children-first");
    let plain = dir.join("plain.rrs");
    let p = plain.to_str().expect("utf-8 path");
    let synth = rrskin(&[
        "synth",
        "--grid",
        "8",
        "--bones",
        "9",
        "--proxies",
        "4",
        "--children-first",
        "-o",
        p,
    ]);
    assert!(
        synth.status.success(),
        "{}",
        String::from_utf8_lossy(&synth.stderr)
    );
    let model = rrskin::Model::load(&plain).expect("a valid model");
    assert!((0..9).all(|b| model.parent(b).is_none_or(|parent| parent > b)));
    let profile = json(&rrskin(&[
        "profile",
        p,
        "--characters",
        "3",
        "--frames",
        "2",
        "--json",
    ]));
    assert_eq!(
        (profile["characters"].as_u64(), profile["bones"].as_u64()),
        (Some(3), Some(9))
    );

    let generated = random_model(
        Spec {
            grid: 8,
            bones: 9,
            proxies: 4,
            influences: 4,
        },
        6,
    )
    .expect("valid spec");
    let mut parts = generated.parts().clone();
    parts.animation = random_poses(&generated, 5, 2);
    // The baseline skins to the bones alone: palette entry P + b is bone b, proxies go to bone 0.
    parts.baseline_indices = parts
        .skin_indices
        .iter()
        .map(|i| i.saturating_sub(4))
        .collect();
    parts.baseline_weights = parts.skin_weights.clone();
    let reversed: Vec<usize> = (0..9).rev().collect();
    let animated = renumber_bones(&rrskin::Model::new(parts).expect("valid"), &reversed)
        .expect("a permutation");
    let path = dir.join("animated.rrs");
    animated.save(&path).expect("save");
    let a = path.to_str().expect("utf-8 path");
    let bench = json(&rrskin(&[
        "bench",
        a,
        "--characters",
        "3",
        "--frames",
        "2",
        "--json",
    ]));
    assert_eq!(bench["characters"], 3);
    assert!(bench["ratio"].as_f64().is_some_and(|r| r > 0.0), "{bench}");
}
