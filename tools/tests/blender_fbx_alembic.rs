//! The pair studios export, from Blender 4.5's own exporters at their defaults
//! (tools/tests/blender/scenarios.py run by the `bpy` module): the rig as FBX (centimetres, leaf
//! bones, the animation baked and simplified) and the deformed mesh as an Alembic cache, fed to
//! `rrskin eval RIG.fbx --clip rom --cache CACHE.abc`. They must give the figures of the NumPy
//! route of the same rig and frames (`numpy/`, written from Blender's own evaluation), with one
//! note per conversion.

#[path = "support/blender.rs"]
mod blender;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use blender::{assert_same_route, bpy_scenarios, bpy_script, count, figure, repo, rrskin};
use blender::{eval_with_notes as eval, refuses_broken_copies};
use scratch::{fixture_dir, temp_dir};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Allowed gap between the two routes' EE (%): both hold Blender's float32 positions of the same
/// evaluations, so what is left is the FBX's float32 bind matrices and its simplified curves
/// (measured: 0.001 EE points). A wrong vertex order, axis, unit or frame is tens of points.
const TOLERANCE: f64 = 0.1;

/// The scenario files, made once per test binary (about 2 s of Blender).
fn scenarios() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = fixture_dir("blender45-scenarios");
        bpy_scenarios("scenarios.py", &dir);
        dir
    })
}

#[test]
fn blenders_default_fbx_and_alembic_give_the_numpy_routes_figures() {
    let dir = scenarios();
    let at = |f: &str| dir.join(f).to_str().expect("utf-8").to_string();
    let (reference, _) = eval(&["eval", &at("numpy"), "--proxies", "0", "--json"]);
    // The plain character, then the one whose armature object is scaled 0.01 (its bones and
    // mesh 100 times larger: a character in cm, the Fox's node transform): the same motion.
    for suffix in ["", "_scaled"] {
        let (rig, cache) = (
            at(&format!("rig{suffix}.fbx")),
            at(&format!("cache{suffix}.abc")),
        );
        let notes = ["FBX in centimetres", "leaf bones", "Simplify"];
        assert_same_route(&reference, &rig, &cache, TOLERANCE, &notes);
    }
    let (rig, cache) = (at("rig.fbx"), at("cache.abc"));
    let args = ["eval", &rig, "--clip", "rom", "--cache", &cache];
    // The runtime model trains from the pair and beats SSD on the held-out frames.
    let (e, _) = eval(&[&args[..], &["--test-frames", "23..30", "--json"]].concat());
    let (ssd, rr) = (figure(&e, "ssd", "test"), figure(&e, "rr_reduced", "test"));
    assert!(rr < ssd, "runtime model {rr} against SSD {ssd}");
}

/// A clip the FBX lacks is refused, naming the file and the stacks it has (Blender names them
/// `ARMATURE|ACTION`; `--clip ACTION` finds them).
#[test]
fn wrong_clips_are_named_with_the_files_stacks() {
    let dir = scenarios();
    let at = |f: &str| dir.join(f).to_str().expect("utf-8").to_string();
    let out = rrskin(&[
        "eval",
        &at("rig.fbx"),
        "--clip",
        "walk",
        "--cache",
        &at("cache.abc"),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("rig.fbx")
            && stderr.contains("no animation stack 'walk'")
            && stderr.contains("Armature|rom"),
        "{stderr}"
    );
}

/// The first-party exporter on Blender 4.5, headless and as an add-on (File > Export > rrskin
/// example set's operator): both write the same set of the bundled rig, and the rig's own LBS
/// reproduces it (Blender's Armature modifier without Preserve Volume is LBS with those
/// weights), which checks bones, weights and axes against each other on 4.x.
#[test]
fn the_exporter_runs_on_blender_4_headless_and_as_an_add_on() {
    let dir = temp_dir("blender45-exporter");
    let glb = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
    let glb = glb.to_str().expect("utf-8");
    let (headless, addon) = (dir.join("headless"), dir.join("addon"));
    let (headless, addon) = (
        headless.to_str().expect("utf-8"),
        addon.to_str().expect("utf-8"),
    );
    let exporter = repo().join("tools/blender/export_examples.py");
    let args = [
        "--input",
        glb,
        "--out",
        headless,
        "--poses",
        "6",
        "--test-action",
        "Anim_0",
    ];
    bpy_script(&exporter, &args);
    let script = repo().join("tools/tests/blender/addon.py");
    bpy_script(&script, &[glb, addon, "6", "Anim_0"]);
    for file in [
        "pose_vertices.npy",
        "pose_transforms.npy",
        "skin_weights.npy",
    ] {
        let read = |d: &str| std::fs::read(Path::new(d).join(file)).expect(file);
        assert!(
            read(headless) == read(addon),
            "{file}: headless and add-on differ"
        );
    }
    let (e, _) = eval(&["eval", headless, "--proxies", "0", "--json"]);
    assert_eq!((count(&e, "train_poses"), count(&e, "test_poses")), (7, 48));
    for split in ["train", "test"] {
        let lbs = figure(&e, "rig_lbs", split);
        assert!(
            lbs < 0.05,
            "rig_lbs {split} {lbs}: bones, weights and axes disagree"
        );
    }
}

/// Truncated and corrupted copies of Blender's FBX and Alembic files are refused, naming the
/// file, and never panic through the loaders.
#[test]
fn broken_fbx_and_alembic_files_are_refused_naming_the_file() {
    use rrskin_tools::import::point_cache::PointCache;
    use rrskin_tools::import::rig::Rig;
    let dir = temp_dir("blender45-broken");
    let cache = |p: &Path| PointCache::load(p, 24.0).map(|_| ());
    refuses_broken_copies(&scenarios().join("cache.abc"), &dir, 7, &cache);
    let rig = |p: &Path| Rig::load(p, "rom").map(|_| ());
    refuses_broken_copies(&scenarios().join("rig.fbx"), &dir, 7, &rig);
}

/// The other mix: the bundled glTF rig with an Alembic cache of its clip `examples` from
/// Blender 4.5's importer and exporter at their defaults (plain LBS, so the rig's own skin
/// reproduces it), on the held-out frames as on the training ones.
#[test]
fn a_gltf_rig_with_blenders_alembic_of_its_clip() {
    let dir = temp_dir("blender45-gltf-abc");
    let glb = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
    let (glb, abc) = (glb.to_str().expect("utf-8"), dir.join("examples.abc"));
    let abc = abc.to_str().expect("utf-8");
    bpy_script(
        &repo().join("tools/tests/blender/alembic_of_glb.py"),
        &[glb, "examples", abc],
    );
    let args = ["eval", glb, "--clip", "examples", "--cache", abc];
    let (e, _) = eval(
        &[
            &args[..],
            &["--test-frames", "41..60", "--proxies", "0", "--json"],
        ]
        .concat(),
    );
    assert_eq!(
        (count(&e, "train_poses"), count(&e, "test_poses")),
        (41, 20)
    );
    for split in ["train", "test"] {
        let lbs = figure(&e, "rig_lbs", split);
        assert!(
            lbs < 0.05,
            "rig_lbs {split} {lbs}: the cache is not the glTF's own skin"
        );
    }
}
