//! Blender's own exporters with their default settings (tools/tests/blender/scenarios.py: a
//! glTF rig from `export_scene.gltf`, MDD and PC2 point caches from the bundled add-ons) fed to
//! `rrskin eval RIG.glb --clip rom --cache CACHE`: what a user who never heard of vertex
//! orders, up axes, object space or start frames gets.
//!
//! Each scenario cache holds the same evaluated vertex positions as the aligned reference cache
//! of its rig (glTF vertex order, world space, Y-up, the scene's frame numbers), written
//! differently: Blender's welded vertex order (2338 vertices against the glTF file's 4416, split
//! at UV and normal seams), Z-up (MDD), object space (PC2 defaults; for `rig_scaled.glb` in the
//! cm of an armature object at scale 0.01), times from 0 for a scene starting at frame 1 (MDD).
//! Every one must give the reference's figures, with one line on stderr saying what was
//! detected and fixed. The same caches with the rig as Blender's default FBX must give the
//! figures of the NumPy route of the same frames (`numpy/`, also written by scenarios.py).

#[path = "support/blender.rs"]
mod blender;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use blender::{assert_same_figures, blender_script, count, figure, repo, rrskin};
use scratch::fixture_dir;

/// Allowed gap between a scenario's `rigid`/`ssd`/`rig_lbs` EE (%) and its reference's. The
/// caches hold the very same float32 positions (checked in scenarios.py to 1.2e-7), so mapping
/// vertices, swapping axes and shifting frames are exact; the three references of three
/// differently written rigs (start frame 1, armature at 0.01) already agree to 1e-4 EE points
/// here. An object-space cache needs the object's transform recovered (rotation and a
/// scale of 100), which float32 round-off (1e-7 relative) moves far less than this. 0.1 EE
/// points is still 1/400 of SSD's error, so a wrong vertex map, axis or frame (tens of points)
/// cannot pass.
const TOLERANCE: f64 = 0.1;

/// What `rrskin eval` may print when it adapts a cache: the words of its stderr lines.
const NOTES: [&str; 4] = ["mapped", "z-up", "object space", "shifted"];

struct Scenarios {
    dir: PathBuf,
    manifest: serde_json::Value,
}

/// The scenario files, made once per test binary (about 10 s of Blender).
fn scenarios() -> &'static Scenarios {
    static SCENARIOS: OnceLock<Scenarios> = OnceLock::new();
    SCENARIOS.get_or_init(|| {
        let dir = fixture_dir("blender-scenarios");
        let script = repo().join("tools/tests/blender/scenarios.py");
        let glb = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
        blender_script(
            &script,
            &[
                "--out",
                dir.to_str().expect("utf-8"),
                "--glb",
                glb.to_str().expect("utf-8"),
            ],
        );
        let manifest = std::fs::read(dir.join("manifest.json")).expect("manifest.json");
        let manifest = serde_json::from_slice(&manifest).expect("manifest JSON");
        Scenarios { dir, manifest }
    })
}

/// The manifest's entry of `cache`, and its rig's.
fn entry(cache: &str) -> (serde_json::Value, serde_json::Value) {
    let s = scenarios();
    let c = s.manifest["caches"]
        .as_array()
        .expect("caches")
        .iter()
        .find(|c| c["file"] == cache)
        .unwrap_or_else(|| panic!("no {cache} in the manifest"))
        .clone();
    let rig = s.manifest["rigs"][c["rig"].as_str().expect("rig")].clone();
    (c, rig)
}

fn path(file: &str) -> String {
    scenarios()
        .dir
        .join(file)
        .to_str()
        .expect("utf-8")
        .to_string()
}

/// `rrskin eval RIG --clip CLIP --cache CACHE --fps F --test-frames A..B --json
/// --no-learning-curve` args (nothing here reads the curve, most of a reference's time;
/// tools/tests/cli.rs and blender.rs test it).
fn eval_args(cache: &str) -> Vec<String> {
    let (c, rig) = entry(cache);
    let clip = scenarios().manifest["clip"]
        .as_str()
        .expect("clip")
        .to_string();
    [
        "eval".to_string(),
        path(c["rig"].as_str().expect("rig")),
        "--clip".into(),
        clip,
        "--cache".into(),
        path(cache),
        "--fps".into(),
        c["fps"].to_string(),
        "--test-frames".into(),
        rig["test_frames"].as_str().expect("test_frames").into(),
        "--json".into(),
        "--no-learning-curve".into(),
    ]
    .to_vec()
}

/// The reference eval of `rig` (its aligned cache), once per rig.
fn reference(rig: &str) -> serde_json::Value {
    static REFS: Mutex<BTreeMap<String, serde_json::Value>> = Mutex::new(BTreeMap::new());
    let mut refs = REFS.lock().unwrap_or_else(|e| e.into_inner());
    refs.entry(rig.to_string())
        .or_insert_with(|| {
            let file = match rig {
                "rig.glb" => "ref.pc2",
                "rig_start1.glb" => "ref_start1.pc2",
                "rig_scaled.glb" => "ref_scaled.pc2",
                _ => panic!("no reference cache for {rig}"),
            };
            let args = eval_args(file);
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let out = rrskin(&args);
            let dir = scenarios().dir.to_str().expect("utf-8");
            let stderr = String::from_utf8_lossy(&out.stderr).replace(dir, "DIR").to_lowercase();
            assert!(out.status.success(), "reference {file}: {stderr}");
            for note in NOTES {
                assert!(
                    !stderr.contains(note),
                    "the aligned reference {file} needs no adapting, but rrskin says {note}:\n{stderr}"
                );
            }
            serde_json::from_slice(&out.stdout).expect("JSON")
        })
        .clone()
}

/// `cache` gives its reference's figures and prints each of `notes` (`missing`: the bind-pose
/// frames the cache does not hold, training poses whose error is zero for every method).
fn same_as_reference(cache: &str, notes: &[&str], missing: u64) {
    let (c, _) = entry(cache);
    let rig = c["rig"].as_str().expect("rig").to_string();
    let expected = reference(&rig);
    let mut args = eval_args(cache);
    args.extend(["--proxies".to_string(), "0".to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = rrskin(&args);
    // The folder's name ("...blender-exports...") must not count as naming a setting.
    let dir = scenarios().dir.to_str().expect("utf-8");
    let stderr = String::from_utf8_lossy(&out.stderr).replace(dir, "DIR");
    let lower = stderr.to_lowercase();
    assert!(!lower.contains("panicked"), "{cache}: a panic:\n{stderr}");
    assert!(
        out.status.success(),
        "{cache} ({} space, {}-up, {} vertex order, start frame {}) refused:\n{stderr}",
        c["space"].as_str().unwrap_or("?"),
        c["up"].as_str().unwrap_or("?"),
        c["vertex_order"].as_str().unwrap_or("?"),
        c["start_frame"]
    );
    let e: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(
        count(&e, "train_poses") + missing,
        count(&expected, "train_poses"),
        "{cache}: train_poses"
    );
    for key in ["test_poses", "vertices", "triangles", "bones"] {
        assert_eq!(count(&e, key), count(&expected, key), "{cache}: {key}");
    }
    assert_same_figures(
        &e,
        &expected,
        TOLERANCE,
        &format!("{cache} against the reference"),
    );
    for note in notes {
        assert!(
            lower.lines().any(|l| l.contains(&note.to_lowercase())),
            "{cache}: accepted, but no line says {note:?}:\n{stderr}"
        );
    }
}

#[test]
fn the_aligned_references_train_and_agree() {
    let main = reference("rig.glb");
    assert_eq!(count(&main, "train_poses"), 23);
    assert_eq!(count(&main, "test_poses"), 8);
    assert_eq!(count(&main, "triangles"), 4672);
    assert_eq!(count(&main, "bones"), 19);
    // Two materials: two primitives, the seam between them split as well.
    let rig =
        rrskin_tools::import::rig::Rig::load(Path::new(&path("rig.glb")), "rom").expect("rig.glb");
    assert_eq!(rig.primitives.len(), 2);
    // The glTF file's 4416 vertices, welded for training: Blender's own 2338.
    assert_eq!(
        count(&main, "vertices"),
        scenarios().manifest["blender_vertices"]
            .as_u64()
            .expect("count")
    );
    let (rigid, lbs) = (
        figure(&main, "rigid", "test"),
        figure(&main, "rig_lbs", "test"),
    );
    let (ssd, rr) = (
        figure(&main, "ssd", "test"),
        figure(&main, "rr_reduced", "test"),
    );
    assert!(
        lbs > 1.0 && lbs < rigid,
        "rig_lbs {lbs}, rigid {rigid}: {main}"
    );
    assert!(rr < ssd, "rr_reduced {rr} not below ssd {ssd}: {main}");
    for rig in ["rig_start1.glb", "rig_scaled.glb"] {
        let other = reference(rig);
        for method in ["rigid", "ssd", "rig_lbs"] {
            for split in ["train", "test"] {
                let (got, want) = (figure(&other, method, split), figure(&main, method, split));
                assert!(
                    (got - want).abs() <= TOLERANCE,
                    "{rig}: {method} {split} {got:.4} against rig.glb's {want:.4}"
                );
            }
        }
    }
}

#[test]
fn default_mdd_z_up_world_blender_order() {
    same_as_reference("mdd_start0.mdd", &["Z-up", "mapped"], 0);
}

#[test]
fn default_mdd_of_a_scene_starting_at_frame_1() {
    // Times 0..30/24 s hold frames 1..31; the glTF clip's keys are at frame/fps (1/24..31/24).
    same_as_reference("mdd_start1.mdd", &["Z-up", "mapped", "shifted"], 0);
}

#[test]
fn world_space_pc2_blender_order() {
    same_as_reference("pc2_world.pc2", &["mapped"], 0);
}

#[test]
fn default_object_space_pc2() {
    same_as_reference("pc2_object.pc2", &["object space", "mapped"], 0);
}

#[test]
fn default_object_space_pc2_of_an_armature_at_scale_0_01() {
    same_as_reference("pc2_object_scaled.pc2", &["object space", "mapped"], 0);
}

/// The bind pose keyed on frame 0, the scene's range 1..30: the MDD holds frames 1..30 at times
/// 0..29/24 s (trained on poses shifted by one frame before), and no sample at the bind pose,
/// so its points are found by their trajectories.
#[test]
fn default_mdd_of_a_range_after_the_bind_frame() {
    same_as_reference(
        "mdd_range1.mdd",
        &["Z-up", "mapped by trajectory", "shifted"],
        1,
    );
}

/// The rig as Blender 3.4's default FBX (centimetres, leaf bones, the animation simplified)
/// with the MDD and the PC2s above: the figures of the NumPy route of the same rig and frames
/// (`numpy/`, Blender's own evaluation in its vertex order), each conversion on one line.
#[test]
fn an_fbx_rig_with_each_default_cache() {
    let eval = |args: &[String]| -> (serde_json::Value, String) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = rrskin(&args);
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "rrskin {}:\n{stderr}", args.join(" "));
        (serde_json::from_slice(&out.stdout).expect("JSON"), stderr)
    };
    let numpy = ["eval", &path("numpy"), "--proxies", "0", "--json"].map(String::from);
    let (expected, _) = eval(&numpy);
    let cases = [
        ("mdd_start0.mdd", "Z-up"),
        ("pc2_world.pc2", "centimetres"),
        ("pc2_object.pc2", "object space"),
    ];
    for (cache, note) in cases {
        let mut args = eval_args(cache);
        args[1] = path("rig.fbx");
        args.extend(["--proxies".to_string(), "0".to_string()]);
        let (e, stderr) = eval(&args);
        for key in ["vertices", "bones", "train_poses", "test_poses"] {
            assert_eq!(count(&e, key), count(&expected, key), "{cache}: {key}");
        }
        let what = format!("FBX + {cache} against the NumPy route");
        assert_same_figures(&e, &expected, TOLERANCE, &what);
        assert!(
            stderr.lines().any(|l| l.contains(note)),
            "FBX + {cache}: no line says {note:?}:\n{stderr}"
        );
    }
}

/// The scenario files are what the manifest says (sizes from the headers), so a change in
/// Blender's exporters shows here first.
#[test]
fn the_scenario_files_match_the_manifest() {
    let s = scenarios();
    for c in s.manifest["caches"].as_array().expect("caches") {
        let file = c["file"].as_str().expect("file");
        let bytes = std::fs::read(s.dir.join(file)).expect("cache file");
        let (frames, vertices) = (
            c["frames"].as_u64().expect("frames"),
            c["vertices"].as_u64().expect("v"),
        );
        let header = match c["format"].as_str() {
            Some("pc2") => {
                assert_eq!(&bytes[..12], b"POINTCACHE2\0", "{file}");
                let int =
                    |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().expect("4")) as u64;
                let float = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4"));
                assert_eq!(
                    (int(16), int(28)),
                    (vertices, frames),
                    "{file}: points, samples"
                );
                assert_eq!(
                    float(20) as u64,
                    c["start_frame"].as_u64().expect("start"),
                    "{file}"
                );
                assert_eq!(float(24), 1.0, "{file}: sample rate");
                32
            }
            Some("mdd") => {
                let int =
                    |o: usize| i32::from_be_bytes(bytes[o..o + 4].try_into().expect("4")) as u64;
                assert_eq!(
                    (int(0), int(4)),
                    (frames, vertices),
                    "{file}: frames, points"
                );
                let t1 = f32::from_be_bytes(bytes[12..16].try_into().expect("4"));
                assert!((t1 - 1.0 / 24.0).abs() < 1e-6, "{file}: second time {t1}");
                8 + 4 * frames as usize
            }
            other => panic!("{file}: format {other:?}"),
        };
        assert_eq!(
            bytes.len() as u64,
            header as u64 + frames * vertices * 12,
            "{file}: size"
        );
        assert!(Path::new(&path(c["rig"].as_str().expect("rig"))).is_file());
    }
}
