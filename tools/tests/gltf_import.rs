//! Training from a glTF rig plus a point cache: the same figures as from the NumPy folder of the
//! same examples, a model written over the glTF file's own vertices, and clear errors (with
//! nothing written) for bad rigs and caches.

mod support;

use glam::DVec3;
use rrskin_tools::import::gltf::{import, Options};
use rrskin_tools::import::point_cache::PointCache;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use support::{cesiumman_options as options, data, temp_dir};

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
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

fn rig() -> String {
    data("cesiumman_gltf/CesiumMan_examples.glb")
        .to_string_lossy()
        .into_owned()
}

fn cache() -> String {
    data("cesiumman_gltf/CesiumMan_examples.pc2")
        .to_string_lossy()
        .into_owned()
}

/// Rigid, SSD and the full model to 1e-3. The reduced model is checked to 0.1: its greedy
/// merging is discrete, and the two exports differ by their rounding (rest 4e-7, transforms
/// 1.5e-6, data/README.md), which can flip a near-tied merge (measured: 0.015).
#[test]
fn the_gltf_rig_trains_like_the_numpy_folder() {
    let from_gltf = json(&rrskin(&[
        "eval",
        &rig(),
        "--clip",
        "examples",
        "--cache",
        &cache(),
        "--test-frames",
        "41..60",
        "--json",
    ]));
    let from_numpy = json(&rrskin(&[
        "eval",
        data("cesiumman").to_str().expect("utf-8"),
        "--json",
    ]));
    for key in [
        "vertices",
        "triangles",
        "bones",
        "train_poses",
        "test_poses",
    ] {
        assert_eq!(from_gltf[key], from_numpy[key], "{key}");
    }
    for (method, tolerance) in [
        ("rigid", 1e-3),
        ("ssd", 1e-3),
        ("rr_full", 1e-3),
        ("rr_reduced", 0.1),
    ] {
        for split in ["train", "test"] {
            let (a, b) = (
                from_gltf[method][split].as_f64(),
                from_numpy[method][split].as_f64(),
            );
            let (a, b) = (a.expect("a number"), b.expect("a number"));
            assert!(
                (a - b).abs() <= tolerance,
                "{method} {split}: glTF {a} vs NumPy {b}"
            );
        }
    }
}

#[test]
fn the_model_is_written_over_the_gltf_vertices_with_welded_seams_shading_as_one() {
    let dir = temp_dir("gltf-train");
    let out = dir.join("cm.rrs");
    let o = out.to_str().expect("utf-8");
    let trained = rrskin(&[
        "train",
        &rig(),
        "--clip",
        "examples",
        "--cache",
        &cache(),
        "--test-frames",
        "41..60",
        "--proxies",
        "20",
        "-o",
        o,
        "--json",
    ]);
    assert!(
        trained.status.success(),
        "{}",
        String::from_utf8_lossy(&trained.stderr)
    );
    let model = rrskin::Model::load(&out).expect("a valid model");
    let imported = import(Path::new(&rig()), &options(Path::new(&cache()))).expect("import");
    assert_eq!(
        model.vertex_count(),
        imported.rest.len(),
        "the glTF file's vertex count"
    );
    assert_eq!(model.vertex_count(), 3273);
    assert_eq!(model.triangle_count(), imported.triangles.len());

    // Evaluate held-out frame 50 over the glTF vertices.
    let rig = rrskin_tools::import::rig::Rig::load(Path::new(&rig()), "examples").expect("rig");
    let bones: Vec<rrskin::predict::Affine> = rig
        .bones_at(50.0 / 24.0)
        .iter()
        .map(|b| b.to_runtime())
        .collect();
    let v = model.vertex_count();
    let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
    let mut tangents = vec![[0.0f32; 4]; v];
    assert!(
        model.has_tangents(),
        "MikkTSpace from CesiumMan's TEXCOORD_0"
    );
    rrskin::cpu::CpuEvaluator::new(&model)
        .evaluate_with_tangents(&bones, &mut pos, &mut nrm, &mut tangents)
        .expect("evaluate");
    for (t, n) in tangents.iter().zip(&nrm) {
        let (t, n) = (glam::Vec3::from_slice(&t[..3]), glam::Vec3::from(*n));
        assert!((t.length() - 1.0).abs() < 1e-4 && t.dot(n).abs() < 1e-4);
    }
    let truth = &PointCache::load(Path::new(&cache()), 24.0)
        .expect("cache")
        .positions[50];
    let rms = (pos
        .iter()
        .zip(truth)
        .map(|(p, t)| (DVec3::from(p.map(f64::from)) - *t).length_squared())
        .sum::<f64>()
        / v as f64)
        .sqrt();
    assert!(
        rms < 0.02,
        "rms error {rms} at frame 50 (CesiumMan is ~1.5 high)"
    );
    // Welded duplicates: one position, one normal.
    let mut seams = 0;
    for g in 0..v {
        for h in g + 1..v {
            if imported.weld[g] == imported.weld[h] {
                seams += 1;
                assert_eq!(
                    (pos[g], nrm[g]),
                    (pos[h], nrm[h]),
                    "glTF vertices {g} and {h}"
                );
            }
        }
    }
    assert!(seams > 900, "{seams} seam pairs");
}

/// The rest tangents follow the texture: on each triangle, the direction along which u grows
/// (and, through w, the one along which the image's up grows: glTF's v decreases), from its
/// positions and TEXCOORD_0, agrees with its corners' tangent frames. MikkTSpace smooths
/// across triangles, so agreement is asked of nearly every triangle, not all.
#[test]
fn rest_tangents_follow_the_texture_coordinates() {
    use rrskin_tools::import::rig::Rig;
    use rrskin_tools::import::tangents::Source;
    let imported = import(Path::new(&rig()), &options(Path::new(&cache()))).expect("import");
    let (tangents, source) = imported.tangents.as_ref().expect("tangents");
    assert_eq!(*source, Source::MikkTSpace);
    let uvs = Rig::load(Path::new(&rig()), "examples")
        .expect("rig")
        .uvs
        .expect("TEXCOORD_0");
    let rest = &imported.rest;
    let (mut along_u, mut up, mut counted) = (0, 0, 0);
    for t in &imported.triangles {
        let [a, b, c] = t.map(|i| rest[i]);
        let [ua, ub, uc] = t.map(|i| uvs[i].map(f64::from));
        let (e1, e2) = (b - a, c - a);
        let (du1, dv1, du2, dv2) = (ub[0] - ua[0], ub[1] - ua[1], uc[0] - ua[0], uc[1] - ua[1]);
        let det = du1 * dv2 - du2 * dv1;
        let n = e1.cross(e2);
        if det.abs() < 1e-12 || n.length() < 1e-12 {
            continue; // degenerate in space or in the texture
        }
        // dp/du and dp/dv of the triangle's affine map from texture to space.
        let dp_du = (e1 * dv2 - e2 * dv1) / det;
        let dp_dv = (e2 * du1 - e1 * du2) / det;
        counted += 1;
        let n = n.normalize();
        for &i in t {
            let [x, y, z, w] = tangents[i].map(f64::from);
            let tangent = DVec3::new(x, y, z);
            along_u += usize::from(tangent.dot(dp_du) > 0.0);
            up += usize::from(n.cross(tangent).dot(-dp_dv) * w > 0.0);
        }
    }
    let corners = 3 * counted;
    assert!(counted > 4000, "{counted} triangles");
    assert!(
        along_u * 100 >= 99 * corners,
        "{along_u} of {corners} corners along +u"
    );
    assert!(
        up * 100 >= 99 * corners,
        "{up} of {corners} corners with the image's up"
    );
}

fn error_of(cache: &Path, clip: &str) -> String {
    let mut o = options(cache);
    o.clip = clip.into();
    match import(Path::new(&rig()), &o) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("expected an error"),
    }
}

#[test]
fn bad_clips_and_caches_are_refused_with_their_numbers() {
    let dir = temp_dir("gltf-bad");
    let e = error_of(Path::new(&cache()), "nope");
    assert!(
        e.contains("CesiumMan_examples.glb")
            && e.contains("no animation named 'nope'")
            && e.contains("examples"),
        "{e}"
    );
    let good = PointCache::load(Path::new(&cache()), 24.0).expect("cache");
    let few = PointCache {
        positions: good.positions.iter().map(|p| p[..10].to_vec()).collect(),
        ..good.clone()
    };
    let path = dir.join("few.pc2");
    std::fs::write(&path, few.to_pc2()).expect("write");
    let e = error_of(&path, "examples");
    assert!(
        e.contains("few.pc2")
            && e.contains("10 points for the rig's 3273 vertices")
            && e.contains("2338 distinct"),
        "{e}"
    );
    let mut nan = good.to_pc2();
    nan[32 + 12 * 7..32 + 12 * 7 + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&path, &nan).expect("write");
    let e = error_of(&path, "examples");
    assert!(e.contains("sample 0, point 7 is not finite"), "{e}");
    std::fs::write(&path, &good.to_pc2()[..1000]).expect("write");
    assert!(error_of(&path, "examples").contains("truncated"));
    let mdd = dir.join("wrong.mdd");
    std::fs::write(&mdd, &good.to_mdd()[..100]).expect("write");
    assert!(error_of(&mdd, "examples").contains("truncated MDD"));
    // A truncated rig, through the CLI: an error naming the file, and nothing written.
    let glb = std::fs::read(rig()).expect("read");
    let cut = dir.join("cut.glb");
    std::fs::write(&cut, &glb[..glb.len() / 2]).expect("write");
    let out = dir.join("never.rrs");
    let run = rrskin(&[
        "train",
        cut.to_str().expect("utf-8"),
        "--clip",
        "examples",
        "--cache",
        &cache(),
        "-o",
        out.to_str().expect("utf-8"),
    ]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("cut.glb"), "{err}");
    assert!(!out.exists(), "nothing may be written on error");
    let run = rrskin(&["eval", &rig(), "--cache", &cache()]);
    assert!(String::from_utf8_lossy(&run.stderr).contains("needs --clip"));
}

/// Examples that are not the clip's keyframes (a wrong `--fps`), test frames outside the cache
/// or between its samples, a single training pose, and a model of another mesh are refused
/// before any training, with the file and the numbers named.
#[test]
fn frames_off_the_keys_or_the_cache_are_refused_before_training() {
    let dir = temp_dir("gltf-frames");
    let (rig, cache) = (rig(), cache());
    let refused = |o: Options| match import(Path::new(&rig), &o) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("expected an error"),
    };
    let o = options(Path::new(&cache));
    let e = refused(Options {
        fps: 30.0,
        ..o.clone()
    });
    assert!(
        e.contains("CesiumMan_examples.pc2")
            && e.contains("sample 1 (frame 1")
            && e.contains("--fps 30")
            && e.contains("is it --fps 24?"),
        "{e}"
    );
    let e = refused(Options {
        test_frames: Some((100.0, 200.0)),
        ..o.clone()
    });
    assert!(
        e.contains("outside the cache") && e.contains("0..60"),
        "{e}"
    );
    let e = refused(Options {
        test_frames: Some((10.2, 10.5)),
        ..o.clone()
    });
    assert!(e.contains("no test poses"), "{e}");

    let good = PointCache::load(Path::new(&cache), 24.0).expect("cache");
    let one = PointCache {
        format: good.format,
        frames: good.frames[..1].to_vec(),
        times: good.times[..1].to_vec(),
        positions: good.positions[..1].to_vec(),
    };
    let one_path = dir.join("one.pc2");
    std::fs::write(&one_path, one.to_pc2()).expect("write");
    let run = rrskin(&[
        "eval",
        &rig,
        "--clip",
        "examples",
        "--cache",
        one_path.to_str().expect("utf-8"),
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.code() == Some(1)
            && err.contains("1 training pose")
            && err.contains("at least 2"),
        "{err}"
    );
    let other = dir.join("other.rrs");
    let o = other.to_str().expect("utf-8");
    assert!(rrskin(&["synth", "--grid", "5", "-o", o]).status.success());
    let started = std::time::Instant::now();
    let run = rrskin(&[
        "eval", &rig, "--clip", "examples", "--cache", &cache, "--model", o,
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.code() == Some(1) && err.contains("other.rrs") && err.contains("3273"),
        "{err}"
    );
    assert!(
        started.elapsed().as_secs() < 20 && !err.contains("training:"),
        "refused only after training: {err}"
    );
}

/// A one-triangle rig with one joint, written as .gltf + .bin: `skin` says whether the mesh
/// node has the skin, `joint_scale` is the joint's scale.
fn tiny_rig(dir: &Path, skin: bool, joint_scale: f32) -> PathBuf {
    tiny_rig_with(dir, skin, joint_scale, None)
}

/// [`tiny_rig`], with `tangent` as every vertex's TANGENT if given.
fn tiny_rig_with(dir: &Path, skin: bool, joint_scale: f32, tangent: Option<[f32; 4]>) -> PathBuf {
    let mut bin = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes()); // POSITION: 36 bytes at 0
    }
    for _ in 0..3 {
        bin.extend_from_slice(&[0u8, 0, 0, 0]); // JOINTS_0 (u8 x 4): 12 bytes at 36
    }
    for _ in 0..3 {
        for w in [1.0f32, 0.0, 0.0, 0.0] {
            bin.extend_from_slice(&w.to_le_bytes()); // WEIGHTS_0: 48 bytes at 48
        }
    }
    for t in [0.0f32, 1.0] {
        bin.extend_from_slice(&t.to_le_bytes()); // key times: 8 bytes at 96
    }
    for v in [0.0f32, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes()); // translations: 24 bytes at 104
    }
    for x in tangent.iter().flat_map(|t| [*t; 3]).flatten() {
        bin.extend_from_slice(&x.to_le_bytes()); // TANGENT: 48 bytes at 128
    }
    let (tangent_view, tangent_accessor, tangent_attribute) = match tangent {
        Some(_) => (
            r#", {"buffer": 0, "byteOffset": 128, "byteLength": 48}"#,
            r#", {"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC4"}"#,
            r#", "TANGENT": 5"#,
        ),
        None => ("", "", ""),
    };
    std::fs::write(dir.join("tiny.bin"), &bin).expect("write bin");
    let skin_field = if skin { r#", "skin": 0"# } else { "" };
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "buffers": [{{"uri": "tiny.bin", "byteLength": {len}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 12}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 96, "byteLength": 8}},
    {{"buffer": 0, "byteOffset": 104, "byteLength": 24}}{tangent_view}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
    {{"bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC4"}},
    {{"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4"}},
    {{"bufferView": 3, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]}},
    {{"bufferView": 4, "componentType": 5126, "count": 2, "type": "VEC3"}}{tangent_accessor}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2{tangent_attribute}}}}}]}}],
  "nodes": [
    {{"name": "joint", "scale": [{s}, {s}, {s}]}},
    {{"mesh": 0{skin_field}}}
  ],
  "skins": [{{"joints": [0]}}],
  "animations": [{{"name": "a", "samplers": [{{"input": 3, "output": 4}}], "channels": [{{"sampler": 0, "target": {{"node": 0, "path": "translation"}}}}]}}],
  "scenes": [{{"nodes": [0, 1]}}]
}}"#,
        len = bin.len(),
        s = joint_scale
    );
    let path = dir.join("tiny.gltf");
    std::fs::write(&path, gltf).expect("write gltf");
    path
}

#[test]
fn rigs_without_a_skin_or_with_a_singular_joint_are_refused() {
    use rrskin_tools::import::rig::Rig;
    let dir = temp_dir("gltf-tiny");
    let ok = tiny_rig(&dir, true, 1.0);
    let rig = Rig::load(&ok, "a").expect("a valid tiny rig (.gltf with an external buffer)");
    assert_eq!(
        (rig.rest.len(), rig.triangles.len(), rig.names.clone()),
        (3, 1, vec!["joint".to_string()])
    );
    let moved = rig.bones_at(0.5);
    assert!(
        (moved[0].d - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-6,
        "LINEAR translation at t = 0.5"
    );
    let e = Rig::load(&tiny_rig(&dir, false, 1.0), "a")
        .expect_err("no skin")
        .to_string();
    assert!(
        e.contains("tiny.gltf") && e.contains("no skinned mesh"),
        "{e}"
    );
    let e = Rig::load(&tiny_rig(&dir, true, 0.0), "a")
        .expect_err("singular")
        .to_string();
    assert!(e.contains("non-invertible"), "{e}");
    let path = tiny_rig(&dir, true, 1.0);
    std::fs::remove_file(dir.join("tiny.bin")).expect("rm");
    let e = Rig::load(&path, "a")
        .expect_err("missing buffer")
        .to_string();
    assert!(
        e.contains("tiny.bin"),
        "the missing buffer file is named: {e}"
    );
}

/// A file's TANGENT is taken to the rest mesh like its positions (here through the joint's
/// scale of 2: the direction, renormalised) and kept over MikkTSpace; one with w not ±1 is
/// refused, naming the file and the vertex.
#[test]
fn a_files_tangents_are_carried_to_the_rest_mesh_and_checked() {
    use rrskin_tools::import::rig::Rig;
    let dir = temp_dir("gltf-tangent");
    let rig = Rig::load(&tiny_rig(&dir, true, 1.0), "a").expect("rig");
    assert!(rig.tangents.is_none() && rig.uvs.is_none());
    let path = tiny_rig_with(&dir, true, 2.0, Some([0.6, 0.8, 0.0, -1.0]));
    let rig = Rig::load(&path, "a").expect("rig with TANGENT");
    let tangents = rig.tangents.expect("TANGENT read");
    for t in &tangents {
        let want = [0.6, 0.8, 0.0, -1.0];
        assert!(
            t.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6),
            "{t:?}"
        );
    }
    let e = Rig::load(
        &tiny_rig_with(&dir, true, 1.0, Some([1.0, 0.0, 0.0, 0.5])),
        "a",
    )
    .expect_err("w = 0.5")
    .to_string();
    assert!(
        e.contains("tiny.gltf") && e.contains("TANGENT") && e.contains("vertex 0"),
        "{e}"
    );
}

/// The rest mesh is the mesh at its default morph weights (here one target moving every vertex
/// by (0, 0, 1) at weight 0.5), and a clip animating morph weights is named on a line.
#[test]
fn the_rest_mesh_is_at_the_default_morph_weights() {
    use rrskin_tools::import::rig::Rig;
    let dir = temp_dir("gltf-morph");
    let path = tiny_rig(&dir, true, 1.0);
    let mut bin = std::fs::read(dir.join("tiny.bin")).expect("bin");
    let offset = bin.len();
    for _ in 0..3 {
        for x in [0.0f32, 0.0, 1.0] {
            bin.extend_from_slice(&x.to_le_bytes());
        }
    }
    for w in [0.5f32, 1.0] {
        bin.extend_from_slice(&w.to_le_bytes()); // the clip's morph weights at its 2 keys
    }
    std::fs::write(dir.join("tiny.bin"), &bin).expect("write bin");
    let gltf = std::fs::read_to_string(&path).expect("gltf")
        .replace(r#""byteLength": 128}"#, &format!(r#""byteLength": {}}}"#, bin.len()))
        .replace(
            r#"{"buffer": 0, "byteOffset": 104, "byteLength": 24}"#,
            &format!(
                r#"{{"buffer": 0, "byteOffset": 104, "byteLength": 24}}, {{"buffer": 0, "byteOffset": {offset}, "byteLength": 36}}, {{"buffer": 0, "byteOffset": {}, "byteLength": 8}}"#,
                offset + 36
            ),
        )
        .replace(
            r#"{"bufferView": 4, "componentType": 5126, "count": 2, "type": "VEC3"}"#,
            r#"{"bufferView": 4, "componentType": 5126, "count": 2, "type": "VEC3"}, {"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,1], "max": [0,0,1]}, {"bufferView": 6, "componentType": 5126, "count": 2, "type": "SCALAR"}"#,
        )
        .replace(
            r#""WEIGHTS_0": 2}}]}]"#,
            r#""WEIGHTS_0": 2}, "targets": [{"POSITION": 5}]}], "weights": [0.5]}]"#,
        )
        .replace(
            r#""samplers": [{"input": 3, "output": 4}]"#,
            r#""samplers": [{"input": 3, "output": 4}, {"input": 3, "output": 6}]"#,
        )
        .replace(
            r#""path": "translation"}}]"#,
            r#""path": "translation"}}, {"sampler": 1, "target": {"node": 1, "path": "weights"}}]"#,
        );
    std::fs::write(&path, gltf).expect("write gltf");
    let rig = Rig::load(&path, "a").expect("a rig with a morph target");
    let want = [[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.0, 1.0, 0.5]];
    for (p, w) in rig.rest.iter().zip(want) {
        assert!((*p - DVec3::from(w)).length() < 1e-6, "{p} against {w:?}");
    }
    let notes = rig.notes.join("\n");
    assert!(
        notes.contains("1 morph target(s), the rest mesh at their default weights [0.5]")
            && notes.contains("animation 'a' animates the morph weights"),
        "{notes}"
    );
}
