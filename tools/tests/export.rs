//! `rrskin export` against clients nobody here wrote: every file it writes passes the Khronos
//! glTF Validator (npm `gltf-validator`, installed by .ci/install-deps) with no error, and
//! Blender's own glTF importer plays it like rrskin's CPU evaluator, at the keys and between
//! them.

#[path = "support/blender.rs"]
mod blender;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use blender::{blender_script, repo, rrskin};
use rrskin::cpu::CpuEvaluator;
use rrskin::predict::Affine;
use rrskin::{Model, ModelParts};
use rrskin_render::synthetic::{
    palette_error, random_model, random_poses, with_delta_mush_keys, Spec,
};
use rrskin_tools::export::animation_pose;
use rrskin_tools::import::rig::Rig;
use scratch::temp_dir;
use std::path::Path;
use std::process::Command;

/// The validator's report of `file` (JSON); panics when Node.js or the validator is missing.
fn validate(file: &Path) -> serde_json::Value {
    let script = repo().join("tools/tests/gltf-validator/validate.mjs");
    let out = Command::new("node")
        .arg(&script)
        .arg(file)
        .output()
        .expect("node (Node.js) on PATH: run .ci/install-deps");
    assert!(
        out.status.success(),
        "the glTF Validator did not run (run .ci/install-deps): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("the validator's JSON report")
}

fn assert_valid(file: &Path) -> serde_json::Value {
    let report = validate(file);
    let issues = &report["issues"];
    assert_eq!(
        issues["numErrors"],
        0,
        "{}: the glTF Validator reports errors: {:#}",
        file.display(),
        issues["messages"]
    );
    report
}

fn export(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["export"];
    all.extend_from_slice(args);
    all.push("--json");
    let out = rrskin(&all);
    assert!(
        out.status.success(),
        "rrskin {}: {}",
        all.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("export's JSON")
}

/// `rrskin train ARGS --proxies 20 --json` (ARGS with `-o MODEL`), the model written; its CPU
/// palette, which an engine would skin with, agrees with the reference playing its animation
/// (the proxies read keys and bones as training made them).
fn train(args: &[&str]) -> Model {
    let mut all = vec!["train"];
    all.extend_from_slice(args);
    all.extend(["--proxies", "20", "--json"]);
    let out = rrskin(&all);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let at = args.iter().position(|a| *a == "-o").expect("-o MODEL") + 1;
    let model = Model::load(args[at]).expect("the trained model");
    let frames: Vec<Affine> = model.animation().flatten().copied().collect();
    let worst = palette_error(&model, &frames).expect("palette");
    assert!(
        worst <= rrskin_render::synthetic::PALETTE_TOLERANCE,
        "the CPU palette of the trained model is {worst} off"
    );
    model
}

/// A synthetic model carrying an animation of `frames` random poses.
fn animated(spec: Spec, seed: u64, frames: usize) -> Model {
    let model = random_model(spec, seed).expect("a valid model");
    let animation = random_poses(&model, frames, seed);
    Model::new(ModelParts {
        animation,
        ..model.into_parts()
    })
    .expect("valid")
}

fn s(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Models of every shape (proxies and plain LBS, K = 4 and 8, delta-mush keys) export to files
/// without errors, whose skins, joints and clips say what the model holds.
#[test]
fn every_kind_of_model_exports_to_a_valid_gltf() {
    let dir = temp_dir("export-kinds");
    let spec = |bones, proxies, influences| Spec {
        grid: 9,
        bones,
        proxies,
        influences,
    };
    let with_delta_mush =
        with_delta_mush_keys(&animated(spec(6, 7, 4), 4, 6), 7, 4).expect("7 of 7 keys");
    for (name, model) in [
        ("k4", animated(spec(6, 5, 4), 3, 6)),
        ("k8", animated(spec(7, 9, 8), 3, 6)),
        ("lbs", animated(spec(5, 0, 4), 3, 6)),
        ("delta-mush keys", with_delta_mush),
    ] {
        let (m, glb) = (
            dir.join(format!("{name}.rrs")),
            dir.join(format!("{name}.glb")),
        );
        model.save(&m).expect("save");
        let exported = export(&[s(&m), "-o", s(&glb)]);
        let report = assert_valid(&glb);
        let info = &report["info"];
        assert_eq!(info["animationCount"], 1, "{name}");
        assert_eq!(info["hasSkins"], true, "{name}");
        assert_eq!(info["maxInfluences"], model.influences(), "{name}");
        assert_eq!(
            report["issues"]["numWarnings"], 0,
            "{name}: {}",
            report["issues"]
        );
        assert!(
            info["totalVertexCount"].as_u64() == Some(81),
            "{name}: {info}"
        );
        assert_eq!(
            exported["joints"].as_u64(),
            Some((model.proxy_count() + model.bone_count()) as u64)
        );
        let clip = &exported["clips"][0];
        assert!(
            clip["samples"].as_u64() >= clip["keys"].as_u64(),
            "{name}: {clip}"
        );
        let text = std::fs::read(&glb).expect("the file");
        let json_len = u32::from_le_bytes(text[12..16].try_into().expect("4 bytes")) as usize;
        let doc: serde_json::Value =
            serde_json::from_slice(&text[20..20 + json_len]).expect("the GLB's JSON");
        let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
        assert_eq!(
            attributes.get("JOINTS_1").is_some(),
            model.influences() == 8,
            "{name}: {attributes}"
        );
    }
    // A model that is no model is refused with its file named.
    let bad = dir.join("bad.rrs");
    std::fs::write(&bad, b"not a model").expect("write");
    let out = rrskin(&["export", s(&bad), "-o", s(&dir.join("bad.glb"))]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.rrs"));
}

fn write_floats(path: &Path, floats: &[f32]) {
    let bytes: Vec<u8> = floats.iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(path, bytes).expect("write floats");
}

fn read_floats(path: &Path) -> Vec<f32> {
    std::fs::read(path)
        .expect("Blender's output")
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
        .collect()
}

/// The CesiumMan runtime model with 16 pose-space correctives, trained from the bundled glTF
/// rig and exported twice: with the rig (its materials and texture, its clip `examples`, a
/// series of poses each held until the next: STEP) and without it (its own animation, the 20
/// held-out poses at 30 fps, LINEAR, so that between two frames the export's samples are
/// interpolated). The correctives are the mesh's morph targets, their weights a channel of each
/// clip. The Validator finds no error in either, and Blender's importer, set to key times and
/// to times a third and a half of the way to the next key, gives vertices within
/// [`PLAYED_TOLERANCE`] of rrskin's CPU evaluator at the same pose.
#[test]
fn blender_plays_an_exported_model_like_the_runtime() {
    let dir = temp_dir("export-blender");
    let rig = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
    let cache = repo().join("data/cesiumman_gltf/CesiumMan_examples.pc2");
    let model_path = dir.join("cm.rrs");
    let model = train(&[
        s(&rig),
        "--clip",
        "examples",
        "--cache",
        s(&cache),
        "--test-frames",
        "41..60",
        "--correctives",
        "16",
        // Correctives, whatever they cost (the default budget refuses 16 targets).
        "--budget",
        "none",
        "-o",
        s(&model_path),
    ]);
    assert_eq!(
        model.corrective_count(),
        16,
        "the cross-validation kept correctives"
    );

    let with_rig = dir.join("with_rig.glb");
    export(&[
        s(&model_path),
        "-o",
        s(&with_rig),
        "--rig",
        s(&rig),
        "--clip",
        "examples",
    ]);
    let report = assert_valid(&with_rig);
    assert_eq!(
        report["info"]["hasMorphTargets"], true,
        "{}",
        report["info"]
    );
    assert!(report["info"]["materialCount"].as_u64() >= Some(1));
    assert!(report["info"]["hasTextures"] == true, "{}", report["info"]);
    let clip = Rig::load(&rig, "examples").expect("the rig");
    let (at_keys, between) = blender_against_model(
        &dir,
        &with_rig,
        "examples",
        &model,
        &clip.key_times(),
        |t| clip.bones_at(t).iter().map(|b| b.to_runtime()).collect(),
    );
    eprintln!("with the rig (STEP), Blender vs rrskin of the mesh's size: {at_keys:.2e} at keys, {between:.2e} between");
    assert!(
        at_keys <= PLAYED_TOLERANCE && between <= PLAYED_TOLERANCE,
        "with the rig: {at_keys:.2e} / {between:.2e}"
    );

    let alone = dir.join("alone.glb");
    let exported = export(&[s(&model_path), "-o", s(&alone), "--fps", "30"]);
    assert_valid(&alone);
    let keys: Vec<f64> = (0..model.animation().count())
        .map(|f| f as f64 / 30.0)
        .collect();
    let (at_keys, between) = blender_against_model(&dir, &alone, "animation", &model, &keys, |t| {
        animation_pose(&model, 30.0, t)
    });
    eprintln!(
        "the model's own animation (LINEAR), Blender vs rrskin of the mesh's size: {at_keys:.2e} at keys, {between:.2e} between; export's own check {}",
        exported["clips"][0]
    );
    assert!(
        at_keys <= PLAYED_TOLERANCE && between <= PLAYED_TOLERANCE,
        "alone: {at_keys:.2e} / {between:.2e}"
    );
}

/// A rig as Blender's own glTF exporter writes it (tools/tests/blender/scenarios.py: two
/// materials, so two primitives; a morph target; a clip `rom` of random poses, LINEAR and STEP
/// channels mixed), trained with its aligned cache and exported back with it: no Validator
/// error, both materials kept, and Blender's importer plays it within [`PLAYED_TOLERANCE`].
#[test]
fn a_rig_from_blenders_exporter_exports_back_with_its_materials() {
    let dir = temp_dir("export-blender-rig");
    blender_script(
        &repo().join("tools/tests/blender/scenarios.py"),
        &[
            "--out",
            s(&dir),
            "--glb",
            s(&repo().join("data/cesiumman_gltf/CesiumMan_examples.glb")),
        ],
    );
    let (rig, model_path, glb) = (dir.join("rig.glb"), dir.join("m.rrs"), dir.join("m.glb"));
    let model = train(&[
        s(&rig),
        "--clip",
        "rom",
        "--cache",
        s(&dir.join("ref.pc2")),
        "--fps",
        "24",
        "--test-frames",
        "23..30",
        "-o",
        s(&model_path),
    ]);
    let exported = export(&[s(&model_path), "-o", s(&glb), "--rig", s(&rig)]);
    let report = assert_valid(&glb);
    assert_eq!(report["info"]["materialCount"], 2, "{}", report["info"]);
    assert_eq!(report["info"]["drawCallCount"], 2, "{}", report["info"]);
    let clip = &exported["clips"][0];
    assert!(
        clip["worst_between"].as_f64() <= Some(1e-3),
        "the export's own check: {clip}"
    );
    let rom = Rig::load(&rig, "rom").expect("the rig");
    let (at_keys, between) =
        blender_against_model(&dir, &glb, "rom", &model, &rom.key_times(), |t| {
            rom.bones_at(t).iter().map(|b| b.to_runtime()).collect()
        });
    eprintln!(
        "Blender's own rig, Blender vs rrskin of the mesh's size: {at_keys:.2e} at keys, {between:.2e} between; export's own check {clip}"
    );
    assert!(
        at_keys <= PLAYED_TOLERANCE && between <= PLAYED_TOLERANCE,
        "{at_keys:.2e} / {between:.2e}"
    );
}

/// Plays `glb`'s clip in Blender at every other key and a third and a half of the way to the
/// next, and returns the largest vertex distance from the model at `pose_at` of those times,
/// relative to the rest mesh's size: (at keys, between keys).
fn blender_against_model(
    dir: &Path,
    glb: &Path,
    clip: &str,
    model: &Model,
    keys: &[f64],
    pose_at: impl Fn(f64) -> Vec<Affine>,
) -> (f64, f64) {
    let mut times = vec![keys[0]];
    for pair in keys.windows(2).step_by(2) {
        let (a, b) = (pair[0], pair[1]);
        times.extend([a + (b - a) / 3.0, a + (b - a) / 2.0, b]);
    }
    let times_path = dir.join("times.txt");
    let text: String = times.iter().map(|t| format!("{t:.9}\n")).collect();
    std::fs::write(&times_path, text).expect("times");
    let rest_path = dir.join("rest.bin");
    write_floats(&rest_path, model.parts().rest_positions.as_flattened());
    let played_path = dir.join("played.bin");
    blender_script(
        &repo().join("tools/tests/blender/play_export.py"),
        &[s(glb), clip, s(&times_path), s(&rest_path), s(&played_path)],
    );
    let played = read_floats(&played_path);
    let v = model.vertex_count();
    assert_eq!(played.len(), times.len() * v * 3);
    let bones: Vec<Affine> = times.iter().flat_map(|&t| pose_at(t)).collect();
    let (mut want, mut normals) = (
        vec![[0.0; 3]; times.len() * v],
        vec![[0.0; 3]; times.len() * v],
    );
    CpuEvaluator::new(model)
        .evaluate(&bones, &mut want, &mut normals)
        .expect("the reference");
    let size = diagonal(&model.parts().rest_positions);
    let (mut at_keys, mut between) = (0.0f64, 0.0f64);
    for (i, t) in times.iter().enumerate() {
        let worst = (0..v)
            .map(|a| {
                let (p, w) = (
                    &played[3 * (i * v + a)..3 * (i * v + a) + 3],
                    want[i * v + a],
                );
                ((0..3).map(|c| ((p[c] - w[c]) as f64).powi(2)).sum::<f64>()).sqrt()
            })
            .fold(0.0, f64::max)
            / size;
        let on_key = keys.iter().any(|k| (k - t).abs() < 1e-9);
        let slot = if on_key { &mut at_keys } else { &mut between };
        *slot = slot.max(worst);
    }
    (at_keys, between)
}

/// Blender's importer against rrskin's evaluator, as a fraction of the rest mesh's
/// bounding-box diagonal: the export's own between-key tolerance (1e-3), doubled for what the
/// importer does differently (it interpolates quaternions per component, not by slerp).
const PLAYED_TOLERANCE: f64 = 2e-3;

fn diagonal(points: &[[f32; 3]]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c] as f64);
            hi[c] = hi[c].max(p[c] as f64);
        }
    }
    (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt()
}
