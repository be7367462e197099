//! The first-party Blender exporter (tools/blender/export_examples.py), run headless by Blender
//! 3.4 (`.ci/install-deps` installs it), and `rrskin eval` on what it writes.

#[path = "support/blender.rs"]
mod blender;
#[path = "../../tests/common/scratch.rs"]
mod scratch;

use blender::{blender, blender_script, count, eval_json, figure, repo};
use rrskin_tools::set::ExampleSet;
use scratch::temp_dir;

fn exporter() -> std::path::PathBuf {
    repo().join("tools/blender/export_examples.py")
}

fn bundled_rig() -> String {
    let glb = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
    assert!(
        glb.is_file(),
        "the bundled rig must be at {}",
        glb.display()
    );
    glb.to_str().expect("utf-8 path").to_string()
}

/// The exporter run on the bundled rig, writing the set to `out`, with `args` after those two.
fn export_bundled_rig(out: &std::path::Path, args: &[&str]) -> std::process::Output {
    let (rig, out) = (bundled_rig(), out.to_str().expect("utf-8"));
    let mut all = vec!["--input", &rig, "--out", out];
    all.extend_from_slice(args);
    blender_script(&exporter(), &all)
}

/// The bundled glb, plain linear blend skinning in Blender: 12 random poses and the file's own
/// walk (Blender names the unnamed glTF animation `Anim_0`, 48 frames) as test poses. Blender's
/// Armature modifier without Preserve Volume is LBS with the vertex-group weights, so the set's
/// own weights must reproduce it (`rig_lbs` ~ 0): that checks the bone transforms, the weights
/// and the Y-up conversion against each other; the rest mesh must be `data/cesiumman`'s
/// (exported from the same rig in Blender, Y-up), vertex for vertex.
#[test]
fn exports_the_bundled_rig_with_its_walk_as_test_poses() {
    let dir = temp_dir("blender-export");
    let out = dir.join("set");
    let run = export_bundled_rig(&out, &["--poses", "12", "--test-action", "Anim_0"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    let last = stdout
        .lines()
        .rfind(|l| l.starts_with("rrskin export: "))
        .expect("the exporter's lines");
    assert!(
        last.contains("wrote") && last.contains("61 poses (13 train, 48 test)"),
        "last line: {last}"
    );

    let set = ExampleSet::load(&out).expect("the exported set loads");
    let reference = ExampleSet::load(repo().join("data/cesiumman")).expect("data/cesiumman");
    let map = read_i32(&repo().join("data/cesiumman/gltf_vertex_map.npy"));
    assert_eq!(
        set.rest.len(),
        map.len(),
        "one vertex per glTF vertex (not welded)"
    );
    let worst = set
        .rest
        .iter()
        .zip(&map)
        .map(|(v, &m)| (*v - reference.rest[m as usize]).length())
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "rest mesh off data/cesiumman's by {worst}");

    let path = out.to_str().expect("utf-8");
    let e = eval_json(&["eval", path, "--json", "--no-learning-curve"]);
    assert_eq!(count(&e, "vertices"), 3273);
    assert_eq!(count(&e, "triangles"), 4672);
    assert_eq!(count(&e, "bones"), 19);
    assert_eq!(count(&e, "train_poses"), 13);
    assert_eq!(count(&e, "test_poses"), 48);
    for split in ["train", "test"] {
        let lbs = figure(&e, "rig_lbs", split);
        assert!(
            lbs < 0.05,
            "rig_lbs {split} {lbs}: the set's weights and transforms disagree"
        );
        assert!(figure(&e, "ssd", split) < 10.0, "{e}");
        assert!(figure(&e, "rr_full", split) < 10.0, "{e}");
    }
}

/// `--poses auto` on the bundled rig: rounds of random poses until the learning curve stops them
/// or the budget does. The first round is 40 poses; a second, if the curve advises more, goes to
/// the budget of 60. Each round's curve is printed, the last line says why it stopped, and the
/// set holds the poses of the last round.
#[test]
fn exports_as_many_poses_as_the_learning_curve_advises() {
    let dir = temp_dir("blender-auto");
    let out = dir.join("set");
    let binary = env!("CARGO_BIN_EXE_rrskin");
    let args = ["--poses", "auto", "--budget", "60", "--rrskin", binary];
    let run = export_bundled_rig(&out, &args);
    let stdout = String::from_utf8_lossy(&run.stdout);
    let rounds: Vec<&str> = stdout
        .lines()
        .filter(|l| l.contains(": round of "))
        .collect();
    assert!(
        rounds[0].contains("round of 40 random poses: learning curve ")
            && rounds[0].contains(" at 30;"),
        "{stdout}"
    );
    let last = stdout
        .lines()
        .rfind(|l| l.contains("wrote"))
        .expect("the summary");
    let set = ExampleSet::load(&out).expect("the exported set loads");
    let poses = set.train().len() - 1;
    match rounds.len() {
        1 => assert!(
            poses == 40
                && (last.contains("stopped at 40 random poses: the learning curve is saturated")
                    || last.contains("stopped at 40 random poses: the learning curve advises")),
            "{stdout}"
        ),
        2 => assert!(
            poses == 60
                && rounds[1].contains("round of 60 random poses")
                && last.contains("stopped at 60 random poses: the budget of 60 poses"),
            "{stdout}"
        ),
        n => panic!("{n} rounds: {stdout}"),
    }
}

/// A black box saved as a .blend (tests/blender/make_rig.py: welded mesh, Preserve Volume, a
/// driven corrective shape key, Corrective Smooth, and an IK pole and a helmet slot that deform
/// nothing, Deform on, moved by the held-out walk), exported with `blender -b RIG.blend`: the
/// exporter writes the 19 bones the skin weights, the runtime model must beat SSD on the
/// held-out walk, and the rig's own LBS must beat rigid.
#[test]
fn exports_a_black_box_blend_that_trains() {
    let dir = temp_dir("blender-blackbox");
    let blend = dir.join("rig.blend");
    let blend = blend.to_str().expect("utf-8");
    blender_script(
        &repo().join("tools/tests/blender/make_rig.py"),
        &[&bundled_rig(), blend, "--controls", "Anim_0_Armature"],
    );
    let out = dir.join("set");
    let out = out.to_str().expect("utf-8");
    let exporter = exporter();
    let run = blender(&[
        blend,
        "--python-exit-code",
        "1",
        "--python",
        exporter.to_str().expect("utf-8"),
        "--",
        "--out",
        out,
        "--poses",
        "24",
        "--seed",
        "3",
        "--test-action",
        "Anim_0_Armature",
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("21 deform bones posed, the 19 that the mesh's skin weights written"),
        "{stdout}"
    );
    let e = eval_json(&["eval", out, "--json", "--no-learning-curve"]);
    assert_eq!(count(&e, "vertices"), 2338, "the welded mesh");
    assert_eq!(count(&e, "triangles"), 4672);
    assert_eq!(count(&e, "bones"), 19);
    assert_eq!(count(&e, "train_poses"), 25);
    assert_eq!(count(&e, "test_poses"), 48);
    let (rigid, lbs) = (figure(&e, "rigid", "test"), figure(&e, "rig_lbs", "test"));
    let (ssd, rr) = (figure(&e, "ssd", "test"), figure(&e, "rr_reduced", "test"));
    assert!(
        lbs > 1.0 && lbs < rigid,
        "rig_lbs {lbs}, rigid {rigid}: {e}"
    );
    assert!(
        rr < ssd,
        "rr_reduced {rr} not below ssd {ssd} on the walk: {e}"
    );
    assert!(
        figure(&e, "rr_full", "train") < figure(&e, "ssd", "train"),
        "{e}"
    );
}

/// User mistakes: one `error:` line naming the problem, exit status 1, no Python traceback.
#[test]
fn user_mistakes_are_one_line_and_status_1() {
    let dir = temp_dir("blender-mistakes");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").expect("write");
    let out = dir.join("out");
    let (glb, out, file) = (
        bundled_rig(),
        out.to_str().expect("utf-8").to_string(),
        file.to_str().expect("utf-8").to_string(),
    );
    let exporter = exporter();
    // A Weld modifier (merge by distance) after the Armature modifier: the vertex count
    // changes with the pose, and the error names the modifier.
    let weld = format!(
        "import bpy, numpy as np\nnp.bool = bool\nbpy.ops.import_scene.gltf(filepath={glb:?})\n\
         bpy.data.objects['Cesium_Man'].modifiers.new('Weld', 'WELD').merge_threshold = 0.02"
    );
    let cases: [(&[&str], &str); 6] = [
        (
            &["--python-expr", &weld, "--out", &out, "--poses", "3"],
            "modifier 'Weld' (WELD) changes it",
        ),
        // The factory scene: a cube, a camera and a light.
        (&["--out", &out], "no armature"),
        (
            &["--input", &glb, "--out", &out, "--test-action", "Walk"],
            "no action named 'Walk'",
        ),
        (&["--input", &glb, "--out", &file], "not a folder"),
        (
            &["--input", &glb, "--out", &out, "--armature", "Rig"],
            "no armature named 'Rig'",
        ),
        (&["--input", &glb], "--out"),
    ];
    for (args, expected) in cases {
        // `--python-expr CODE` (a scene set-up) runs before the exporter.
        let (setup, args) = match args {
            ["--python-expr", code, rest @ ..] => (vec!["--python-expr", *code], rest),
            _ => (vec![], args),
        };
        let mut all = vec!["--factory-startup", "--python-exit-code", "1"];
        all.extend(setup);
        all.extend(["--python", exporter.to_str().expect("utf-8"), "--"]);
        all.extend_from_slice(args);
        let run = blender(&all);
        let stderr = String::from_utf8_lossy(&run.stderr);
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stdout}{stderr}");
        let error = stderr
            .lines()
            .find(|l| l.starts_with("rrskin export: error: "))
            .unwrap_or_else(|| panic!("{args:?}: no error line in:\n{stderr}"));
        assert!(error.contains(expected), "{args:?}: {error}");
        assert!(
            !stderr.contains("Traceback") && !stdout.contains("Traceback"),
            "{args:?}: a traceback:\n{stdout}{stderr}"
        );
    }
}

/// A 1-D i4 .npy file.
fn read_i32(path: &std::path::Path) -> Vec<i32> {
    let bytes = std::fs::read(path).expect("read .npy");
    npyz::NpyFile::new(&bytes[..])
        .expect("an .npy file")
        .into_vec::<i32>()
        .expect("i4 data")
}
