//! USD stages written by hand (text layers), so every expected point is known: a UsdSkel rig
//! posed by its SkelAnimation, a point cache of time-sampled mesh points converted from the
//! stage's units and up axis, the rig's own file carrying its cache, and what is refused (a
//! stage without a skinned mesh or a Skeleton, a rig stage given as a cache, a clip the file
//! lacks, a cache of another mesh, a corrupt file), each naming the file.

#[path = "../../tests/common/scratch.rs"]
mod scratch;

use glam::DVec3;
use rrskin_tools::import::point_cache::PointCache;
use rrskin_tools::import::rig::Rig;
use rrskin_tools::import::{load, ImportOptions, Loaded};
use scratch::temp_dir;
use std::path::{Path, PathBuf};

/// A quad of two joints' skin under an Xform 5 m along z: its lower points follow `root`, its
/// upper ones `root/child` (weights 2, normalised to 1), which turns 90° about z at its origin
/// (0, 1, 0) between time codes 1 and 2. `extra` is more prims at the root.
fn rig_stage(extra: &str) -> String {
    let identity = "((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1))";
    let child = "((1,0,0,0),(0,1,0,0),(0,0,1,0),(0,1,0,1))";
    format!(
        r#"#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
    timeCodesPerSecond = 24
)

def Xform "World"
{{
    double3 xformOp:translate = (0, 0, 5)
    uniform token[] xformOpOrder = ["xformOp:translate"]

    def SkelRoot "Rig"
    {{
        def Skeleton "Skel" (
            prepend apiSchemas = ["SkelBindingAPI"]
        )
        {{
            uniform token[] joints = ["root", "root/child"]
            uniform matrix4d[] bindTransforms = [{identity}, {child}]
            uniform matrix4d[] restTransforms = [{identity}, {child}]
            rel skel:animationSource = </World/Rig/Skel/anim>

            def SkelAnimation "anim"
            {{
                uniform token[] joints = ["root/child"]
                float3[] translations = [(0, 1, 0)]
                quatf[] rotations.timeSamples = {{
                    1: [(1, 0, 0, 0)],
                    2: [(0.70710678, 0, 0, 0.70710678)],
                }}
                half3[] scales = [(1, 1, 1)]
            }}
        }}

        def Mesh "Body" (
            prepend apiSchemas = ["SkelBindingAPI"]
        )
        {{
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 2, 0), (0, 2, 0)]
            int[] primvars:skel:jointIndices = [0, 0, 0, 0, 1, 0, 1, 0] (
                elementSize = 2
                interpolation = "vertex"
            )
            float[] primvars:skel:jointWeights = [1, 0, 1, 0, 2, 0, 2, 0] (
                elementSize = 2
                interpolation = "vertex"
            )
            matrix4d primvars:skel:geomBindTransform = {identity}
            rel skel:skeleton = </World/Rig/Skel>
        }}
    }}
}}
{extra}"#
    )
}

/// The quad's world positions at time codes 1 and 2 (the rig's own skin).
fn posed() -> [[DVec3; 4]; 2] {
    let p = |x, y| DVec3::new(x, y, 5.0);
    [
        [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 2.0), p(0.0, 2.0)],
        [p(0.0, 0.0), p(1.0, 0.0), p(-1.0, 2.0), p(-1.0, 1.0)],
    ]
}

/// A mesh `name` whose points are time-sampled at codes 1 and 2, `points[k]` at code k + 1.
fn baked_mesh(name: &str, points: &[Vec<DVec3>]) -> String {
    let array = |s: &[DVec3]| {
        let items: Vec<String> = s
            .iter()
            .map(|p| format!("({}, {}, {})", p.x, p.y, p.z))
            .collect();
        format!("[{}]", items.join(", "))
    };
    let samples: Vec<String> = (points.iter().enumerate())
        .map(|(k, s)| format!("        {}: {},", k + 1, array(s)))
        .collect();
    let n = points[0].len();
    format!(
        "def Mesh \"{name}\"\n{{\n    int[] faceVertexCounts = [{n}]\n    int[] faceVertexIndices = [{}]\n    point3f[] points.timeSamples = {{\n{}\n    }}\n}}\n",
        (0..n).map(|i| i.to_string()).collect::<Vec<_>>().join(", "),
        samples.join("\n")
    )
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write a stage");
    path
}

fn assert_near(got: &[DVec3], want: &[DVec3], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: point count");
    for (g, w) in got.iter().zip(want) {
        assert!(g.distance(*w) < 1e-6, "{what}: {g} against {w}");
    }
}

#[test]
fn a_usdskel_rig_skins_its_mesh_as_usd_does() {
    let dir = temp_dir("usd-rig");
    let path = write(&dir, "rig.usda", &rig_stage(""));
    let rig = Rig::load(&path, "anim").expect("the rig loads");
    assert_eq!(rig.names, ["root", "child"]);
    assert_eq!(rig.parents, [None, Some(0)]);
    assert_eq!(rig.triangles, [[0, 1, 2], [0, 2, 3]]);
    assert_eq!(rig.weights[2], [(1, 1.0)]);
    assert!(rig.base_mesh);
    assert_near(&rig.rest, &posed()[0], "rest");
    let times = rig.key_times();
    assert_eq!(times, [1.0 / 24.0, 2.0 / 24.0]);
    for (t, want) in times.iter().zip(posed()) {
        assert_near(&rig.skin(&rig.bones_at(*t)), &want, &format!("t = {t}"));
    }
}

/// Centimetres and Z up, under a translated Xform: metres, Y up, in world space, at the time
/// codes over timeCodesPerSecond.
#[test]
fn a_usd_cache_is_converted_to_metres_y_up_in_world_space() {
    let dir = temp_dir("usd-cache");
    let mesh = baked_mesh(
        "Body",
        &[
            vec![
                DVec3::ZERO,
                DVec3::new(100.0, 0.0, 0.0),
                DVec3::new(0.0, 100.0, 0.0),
            ],
            vec![
                DVec3::new(0.0, 0.0, 100.0),
                DVec3::new(100.0, 0.0, 100.0),
                DVec3::new(0.0, 100.0, 100.0),
            ],
        ],
    );
    let stage = format!(
        "#usda 1.0\n(\n    metersPerUnit = 0.01\n    upAxis = \"Z\"\n    timeCodesPerSecond = 24\n)\n\ndef Xform \"World\"\n{{\n    double3 xformOp:translate = (100, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n{mesh}}}\n"
    );
    let path = write(&dir, "cache.usda", &stage);
    let cache = PointCache::load(&path, 24.0).expect("the cache loads");
    assert_eq!(cache.frames, [1.0, 2.0]);
    let v = DVec3::new;
    assert_near(
        &cache.positions[0],
        &[v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(1.0, 0.0, -1.0)],
        "sample 0",
    );
    assert_near(
        &cache.positions[1],
        &[v(1.0, 1.0, 0.0), v(2.0, 1.0, 0.0), v(1.0, 1.0, -1.0)],
        "sample 1",
    );
}

/// The rig's own file carries its cache: a second, unskinned mesh with the evaluated points.
#[test]
fn the_rigs_own_file_can_be_its_cache() {
    let dir = temp_dir("usd-own-cache");
    let baked: Vec<Vec<DVec3>> = posed().iter().map(|s| s.to_vec()).collect();
    let path = write(&dir, "rig.usda", &rig_stage(&baked_mesh("Baked", &baked)));
    let options = ImportOptions {
        clip: Some("anim".into()),
        cache: Some(path.clone()),
        ..ImportOptions::default()
    };
    let Loaded::Rig(imported) = load(&path, &options).expect("rig and cache load") else {
        panic!("a rig is a rig");
    };
    let set = &imported.set;
    assert_eq!(set.poses.len(), 2);
    assert_near(&set.poses[1].vertices, &posed()[1], "pose 1");
}

fn refused(rig: &Path, cache: &Path, clip: &str) -> String {
    let options = ImportOptions {
        clip: Some(clip.into()),
        cache: Some(cache.to_path_buf()),
        ..ImportOptions::default()
    };
    match load(rig, &options) {
        Ok(_) => panic!("{} with {} loaded", rig.display(), cache.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_usd_input_is_refused_naming_the_file() {
    let dir = temp_dir("usd-refused");
    let rig = write(&dir, "rig.usda", &rig_stage(""));
    let baked: Vec<Vec<DVec3>> = posed().iter().map(|s| s.to_vec()).collect();
    let cache = write(
        &dir,
        "cache.usda",
        &format!("#usda 1.0\n\n{}", baked_mesh("Baked", &baked)),
    );
    // A stage without a Skeleton as the rig.
    let e = refused(&cache, &cache, "anim");
    assert!(
        e.contains("cache.usda") && e.contains("no skinned mesh"),
        "{e}"
    );
    // A skinned mesh bound to no Skeleton.
    let unbound = rig_stage("").replace("rel skel:skeleton = </World/Rig/Skel>", "");
    let unbound = write(&dir, "unbound.usda", &unbound);
    let e = refused(&unbound, &cache, "anim");
    assert!(
        e.contains("unbound.usda") && e.contains("binds no Skeleton"),
        "{e}"
    );
    // The rig's stage as the cache.
    let e = refused(&rig, &rig, "anim");
    assert!(
        e.contains("rig.usda")
            && e.contains("no mesh with time-sampled points")
            && e.contains("UsdSkel rig"),
        "{e}"
    );
    // A clip the file lacks: the file's are named.
    let e = refused(&rig, &cache, "walk");
    assert!(
        e.contains("rig.usda") && e.contains("no SkelAnimation 'walk' (the file has: anim)"),
        "{e}"
    );
    // A cache of another mesh: one point more.
    let more: Vec<Vec<DVec3>> = baked
        .iter()
        .map(|s| [s.as_slice(), &[DVec3::splat(9.0)]].concat())
        .collect();
    let other = write(
        &dir,
        "other.usda",
        &format!("#usda 1.0\n\n{}", baked_mesh("Other", &more)),
    );
    let e = refused(&rig, &other, "anim");
    assert!(
        e.contains("other.usda") && e.contains('5') && e.contains('4'),
        "{e}"
    );
    // Not USD at all, under each extension.
    for name in ["junk.usda", "junk.usdc", "junk.usd"] {
        let junk = dir.join(name);
        std::fs::write(&junk, b"PXR-USDC\x00\x00\x00\x07garbage").expect("write");
        let e = refused(&junk, &cache, "anim");
        assert!(e.contains(name), "{e}");
        let e = refused(&rig, &junk, "anim");
        assert!(e.contains(name), "{e}");
    }
}
