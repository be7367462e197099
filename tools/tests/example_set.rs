//! The NumPy example-set loader: a valid set loads; every kind of bad file is refused with an
//! error naming the file and what is wrong with it.

mod support;

use rrskin_tools::set::ExampleSet;
use std::path::Path;
use support::{temp_dir, write_f32, write_i32};

const V: usize = 4;
const N: usize = 3;

const REST: [f32; V * 3] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];

/// 4 vertices, 2 triangles, 2 bones (1 child of 0), 3 poses (the last a test pose): bone 1
/// turned 90° about z in pose 1, bone 0 in pose 2; the vertices at rest in every pose.
fn write_valid(dir: &Path) {
    let rest = REST;
    write_f32(&dir.join("rest_vertices.npy"), &[V, 3], &rest);
    write_i32(&dir.join("faces.npy"), &[2, 3], &[0, 1, 2, 0, 2, 3]);
    write_i32(&dir.join("bone_parents.npy"), &[2], &[-1, 0]);
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let moved = [0.0, -1.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]; // 90° about z
    let transforms: Vec<f32> = [identity, identity, identity, moved, moved, identity].concat();
    write_f32(&dir.join("pose_transforms.npy"), &[N, 2, 3, 4], &transforms);
    let vertices: Vec<f32> = rest.iter().cycle().take(N * V * 3).copied().collect();
    write_f32(&dir.join("pose_vertices.npy"), &[N, V, 3], &vertices);
    write_i32(&dir.join("split.npy"), &[N], &[0, 0, 1]);
}

/// The poses' vertices as linear blend skinning with `weights` (V x 2) makes them from
/// [`write_valid`]'s rest mesh and transforms.
fn skinned_by(weights: &[f32]) -> Vec<f32> {
    type Transform<'a> = &'a dyn Fn(&[f32]) -> [f32; 3];
    let turned = |p: &[f32]| [0.5 - p[1], p[0], p[2]];
    let still = |p: &[f32]| [p[0], p[1], p[2]];
    let poses: [[Transform; 2]; N] = [[&still, &still], [&still, &turned], [&turned, &still]];
    (poses.iter())
        .flat_map(|bones| {
            REST.chunks(3)
                .zip(weights.chunks(2))
                .flat_map(move |(p, w)| {
                    let [a, b] = bones.map(|bone| bone(p));
                    [0, 1, 2].map(|c| w[0] * a[c] + w[1] * b[c])
                })
        })
        .collect()
}

/// Loads a valid set with one file broken by `breaking`; returns the error text.
fn error_after(name: &str, breaking: impl FnOnce(&Path)) -> String {
    let dir = temp_dir(&format!("set-{name}"));
    write_valid(&dir);
    breaking(&dir);
    let err = ExampleSet::load(&dir).expect_err("a broken set must be refused");
    err.to_string()
}

fn assert_names(err: &str, file: &str, what: &str) {
    assert!(err.contains(file), "error does not name {file}: {err}");
    assert!(err.contains(what), "error does not say '{what}': {err}");
}

#[test]
fn a_valid_set_loads_with_its_split() {
    let dir = temp_dir("set-valid");
    write_valid(&dir);
    let set = ExampleSet::load(&dir).expect("valid");
    assert_eq!(
        (set.vertex_count(), set.bone_count(), set.poses.len()),
        (V, 2, N)
    );
    assert_eq!((set.train(), set.test()), (vec![0, 1], vec![2]));
    assert_eq!(set.parents, vec![None, Some(0)]);
    assert!(set.warnings.is_empty(), "{:?}", set.warnings);
}

#[test]
fn missing_and_unreadable_files() {
    let e = error_after("missing", |d| {
        std::fs::remove_file(d.join("pose_vertices.npy")).expect("rm")
    });
    assert_names(&e, "pose_vertices.npy", "cannot open");
    let e = error_after("notnpy", |d| {
        std::fs::write(d.join("faces.npy"), b"hello").expect("write")
    });
    assert_names(&e, "faces.npy", "not a valid .npy file");
    let e = error_after("truncated", |d| {
        let p = d.join("pose_vertices.npy");
        let bytes = std::fs::read(&p).expect("read");
        std::fs::write(&p, &bytes[..bytes.len() - 10]).expect("write");
    });
    assert_names(&e, "pose_vertices.npy", "truncated");
    let e = error_after("dtype", |d| {
        write_f32(&d.join("faces.npy"), &[2, 3], &[0.0; 6])
    });
    assert_names(&e, "faces.npy", "is not an int32/int64");
    let e = ExampleSet::load("/nonexistent/rrskin-set")
        .expect_err("absent")
        .to_string();
    assert_names(&e, "rrskin-set", "not a folder");
}

#[test]
fn mismatched_shapes_name_the_expected_shape() {
    let e = error_after("vcount", |d| {
        write_f32(
            &d.join("pose_vertices.npy"),
            &[N, V + 1, 3],
            &[0.0; N * (V + 1) * 3],
        )
    });
    assert_names(&e, "pose_vertices.npy", "expected (N = 3, V = 4, 3)");
    let e = error_after("bones", |d| {
        write_f32(
            &d.join("pose_transforms.npy"),
            &[N, 3, 3, 4],
            &vec![0.0; N * 36],
        )
    });
    assert_names(&e, "pose_transforms.npy", "expected (N, J = 2, 3, 4)");
    let e = error_after("split", |d| {
        write_i32(&d.join("split.npy"), &[N + 1], &[0; N + 1])
    });
    assert_names(&e, "split.npy", "expected (N = 3,)");
}

#[test]
fn bad_values_name_the_index() {
    let e = error_after("nan", |d| {
        let mut rest = [0.0f32; 12];
        rest[5] = f32::NAN;
        write_f32(&d.join("rest_vertices.npy"), &[V, 3], &rest);
    });
    assert_names(&e, "rest_vertices.npy", "element 5 ([1, 2]) is not finite");
    let e = error_after("face", |d| {
        write_i32(&d.join("faces.npy"), &[2, 3], &[0, 1, 2, 0, 7, 3])
    });
    assert_names(&e, "faces.npy", "face 1 has vertex index 7 outside 0..4");
    let e = error_after("parent", |d| {
        write_i32(&d.join("bone_parents.npy"), &[2], &[-1, 5])
    });
    assert_names(&e, "bone_parents.npy", "bone 1 has parent 5 outside -1..2");
    let e = error_after("cycle", |d| {
        write_i32(&d.join("bone_parents.npy"), &[2], &[1, 0])
    });
    assert_names(&e, "bone_parents.npy", "form a cycle");
    let e = error_after("splitval", |d| {
        write_i32(&d.join("split.npy"), &[N], &[0, 2, 1])
    });
    assert_names(&e, "split.npy", "pose 1 has split 2");
    let e = error_after("alltest", |d| {
        write_i32(&d.join("split.npy"), &[N], &[1, 1, 1])
    });
    assert_names(&e, "split.npy", "nothing to train on");
}

#[test]
fn non_rigid_pose_transforms_are_refused() {
    let e = error_after("scaled", |d| {
        let mut t = vec![0.0f32; N * 24];
        for (m, s) in t.chunks_exact_mut(12).zip([1.0, 1.0, 1.0, 1.1, 1.0, 1.0]) {
            m[0] = s;
            m[5] = 1.0;
            m[10] = 1.0;
        }
        write_f32(&d.join("pose_transforms.npy"), &[N, 2, 3, 4], &t);
    });
    assert_names(
        &e,
        "pose_transforms.npy",
        "pose 1, bone 1: the 3x3 part is not a rotation",
    );
}

#[test]
fn bone_names_must_match_the_bones() {
    let e = error_after("names", |d| {
        std::fs::write(d.join("bone_names.json"), r#"["root"]"#).expect("write")
    });
    assert_names(&e, "bone_names.json", "1 names for 2 bones");
    let e = error_after("namesjson", |d| {
        std::fs::write(d.join("bone_names.json"), "{").expect("write")
    });
    assert_names(&e, "bone_names.json", "not a JSON list of strings");
}

#[test]
fn degenerate_triangles_and_loose_vertices_are_warnings() {
    let dir = temp_dir("set-warn");
    write_valid(&dir);
    write_i32(&dir.join("faces.npy"), &[2, 3], &[0, 1, 2, 0, 0, 1]);
    let set = ExampleSet::load(&dir).expect("warnings do not stop loading");
    assert_eq!(set.warnings.len(), 2, "{:?}", set.warnings);
    assert!(
        set.warnings[0].contains("1 degenerate (zero-area) triangles, first [1]"),
        "{:?}",
        set.warnings
    );
    assert!(
        set.warnings[1].contains("1 vertices belong to no triangle, first [3]"),
        "{:?}",
        set.warnings
    );
}

#[test]
fn a_saved_set_loads_back() {
    let dir = temp_dir("set-save");
    write_valid(&dir);
    let set = ExampleSet::load(&dir).expect("valid");
    let copy = temp_dir("set-save-copy");
    set.save(&copy).expect("save");
    assert_eq!(ExampleSet::load(&copy).expect("reload"), set);
}

#[test]
fn the_rigs_own_weights_load_when_present() {
    let dir = temp_dir("set-weights");
    write_valid(&dir);
    assert_eq!(ExampleSet::load(&dir).expect("valid").rig_weights, None);
    let weights = [1.0, 0.0, 0.25, 0.75, 0.0, 1.0, 0.5, 0.5];
    write_f32(&dir.join("skin_weights.npy"), &[V, 2], &weights);
    // The rig's skin moves the vertices where it weights the bone moved in pose 1: the poses'
    // vertices must be that skin's (else the set is not the rig's motion, and is refused).
    let e = ExampleSet::load(&dir).expect_err("static vertices of a moving bone");
    assert_names(&e.to_string(), "skin_weights.npy", "not this rig's motion");
    write_f32(
        &dir.join("pose_vertices.npy"),
        &[N, V, 3],
        &skinned_by(&weights),
    );
    let set = ExampleSet::load(&dir).expect("valid");
    let w = set.rig_weights.expect("weights");
    assert_eq!(w[0], vec![(0, 1.0)], "zero weights are dropped");
    assert_eq!(w[1], vec![(0, 0.25), (1, 0.75)]);
    assert_eq!(w.len(), V);
}

/// A row off one by less than the tolerance (f32 exports round) loads, rescaled to sum to one.
#[test]
fn rig_weights_within_the_tolerance_are_rescaled_to_one() {
    let dir = temp_dir("set-weights-rescaled");
    write_valid(&dir);
    let weights = [1.0, 0.0, 0.25, 0.75, 0.0, 1.0, 0.5, 0.5005];
    write_f32(&dir.join("skin_weights.npy"), &[V, 2], &weights);
    write_f32(
        &dir.join("pose_vertices.npy"),
        &[N, V, 3],
        &skinned_by(&weights),
    );
    let set = ExampleSet::load(&dir).expect("within the tolerance");
    let w = set.rig_weights.expect("weights");
    let sum: f64 = w[3].iter().map(|(_, x)| x).sum();
    assert!((sum - 1.0).abs() < 1e-12, "row 3 sums to {sum}");
    assert!(
        (w[3][1].1 / w[3][0].1 - 1.001).abs() < 1e-6,
        "proportions kept: {:?}",
        w[3]
    );
}

#[test]
fn bad_rig_weights_name_the_file_and_the_vertex() {
    let file = "skin_weights.npy";
    let e = error_after("weights-shape", |d| {
        write_f32(&d.join(file), &[V, 3], &[0.0; V * 3])
    });
    assert_names(&e, file, "expected (V = 4, J = 2)");
    let e = error_after("weights-negative", |d| {
        write_f32(
            &d.join(file),
            &[V, 2],
            &[1.0, 0.0, 1.5, -0.5, 0.0, 1.0, 0.5, 0.5],
        )
    });
    assert_names(&e, file, "vertex 1, bone 1: negative weight");
    let e = error_after("weights-sum", |d| {
        write_f32(
            &d.join(file),
            &[V, 2],
            &[1.0, 0.0, 0.5, 0.25, 0.0, 1.0, 0.5, 0.5],
        )
    });
    assert_names(&e, file, "vertex 1: weights sum to 0.75");
    let e = error_after("weights-nan", |d| {
        write_f32(
            &d.join(file),
            &[V, 2],
            &[1.0, 0.0, f32::NAN, 0.5, 0.0, 1.0, 0.5, 0.5],
        )
    });
    assert_names(&e, file, "not finite");
}
