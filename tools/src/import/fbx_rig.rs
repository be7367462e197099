//! A rig from FBX through `ufbx` (the binding of the ufbx C loader): the skinned mesh's control
//! points (the DCC's own vertices, in its order), their triangles and skin weights, the skin's
//! bones, and per frame of the named animation stack `T_b = W_b(t) · G_b · M⁻¹`, where
//! `W_b(t)` is bone b's evaluated world matrix, `G_b` the cluster's geometry-to-bone (inverse
//! bind) matrix and `M` the mesh's geometry-to-world: what LBS applies to the rest mesh in world
//! space, as for a glTF rig.
//!
//! The file is converted on load to the glTF's frame: metres, Y up, right-handed (an FBX from
//! Blender is in centimetres and Z-up; from Maya usually centimetres and Y-up). Bones without a
//! skin cluster (the `_end` leaf bones Blender's FBX exporter adds by default, IK controls)
//! deform nothing and are left out, each kind with a note.

use crate::import::rig::{Rig, Sampled};
use crate::set::{Affine, InputError};
use glam::{DMat3, DMat4, DVec3, DVec4};
use std::path::Path;
use std::sync::Arc;

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

fn mat4(m: &ufbx::Matrix) -> DMat4 {
    DMat4::from_cols(
        DVec4::new(m.m00, m.m10, m.m20, 0.0),
        DVec4::new(m.m01, m.m11, m.m21, 0.0),
        DVec4::new(m.m02, m.m12, m.m22, 0.0),
        DVec4::new(m.m03, m.m13, m.m23, 1.0),
    )
}

/// Loads the rig and the animation stack named `clip` (or `ARMATURE|clip`, as Blender names
/// its stacks), sampled at every frame of the stack at the file's frame rate.
pub fn load(path: &Path, clip: &str) -> Result<Rig, InputError> {
    let name = path
        .to_str()
        .ok_or_else(|| bad(path, "the path is not UTF-8"))?;
    let options = ufbx::LoadOpts {
        target_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_unit_meters: 1.0,
        space_conversion: ufbx::SpaceConversion::TransformRoot,
        ..Default::default()
    };
    let scene = ufbx::load_file(name, options)
        .map_err(|e| bad(path, format!("not a readable FBX file: {}", e.description)))?;
    let mut notes = vec![units_note(&scene.settings)];
    let (node, mesh) = one_skinned_mesh(path, &scene)?;
    let to_world = mat4(&node.geometry_to_world);
    let skin = &mesh.skin_deformers[0];
    let skeleton = Skeleton::of(&scene, skin, &mut notes);
    let rest: Vec<DVec3> = (mesh.vertices.iter())
        .map(|v| to_world.transform_point3(DVec3::new(v.x, v.y, v.z)))
        .collect();
    let motion = sample(
        path,
        &scene,
        clip,
        &skeleton,
        to_world.inverse(),
        &mut notes,
    )?;
    Ok(Rig {
        primitives: std::iter::once(0..rest.len()).collect(),
        triangles: triangles(mesh),
        weights: weights(skin, &skeleton.of_cluster),
        rest,
        names: skeleton.names,
        parents: skeleton.parents,
        uvs: None,
        tangents: None,
        bind: None,
        base_mesh: false,
        mesh_world: Some(to_world).filter(|m| !m.abs_diff_eq(DMat4::IDENTITY, 1e-9)),
        notes,
        motion: Arc::new(motion),
    })
}

/// The one mesh node with a skin deformer, and its mesh.
fn one_skinned_mesh<'a>(
    path: &Path,
    scene: &'a ufbx::Scene,
) -> Result<(&'a ufbx::Node, &'a ufbx::Mesh), InputError> {
    let skinned: Vec<(&ufbx::Node, &ufbx::Mesh)> = (scene.nodes.iter())
        .filter_map(|n| {
            let mesh = n.mesh.as_deref().filter(|m| !m.skin_deformers.is_empty());
            mesh.map(|m| (&**n, m))
        })
        .collect();
    match skinned.as_slice() {
        [one] => Ok(*one),
        [] => Err(bad(path, "no skinned mesh (a mesh with a skin deformer): export the character's mesh with its armature")),
        many => Err(bad(path, format!(
            "{} skinned meshes ({}): export the one character mesh the cache holds",
            many.len(),
            many.iter().map(|(n, _)| n.element.name.to_string()).collect::<Vec<_>>().join(", ")
        ))),
    }
}

/// The note on what the load converted: the file's units and up axis.
fn units_note(settings: &ufbx::SceneSettings) -> String {
    let centimetres = (settings.original_unit_meters - 0.01).abs() < 1e-9;
    let units = match centimetres {
        true => "centimetres".to_string(),
        false => format!("units of {} m", settings.original_unit_meters),
    };
    let up = match settings.original_axis_up {
        ufbx::CoordinateAxis::PositiveZ => ", Z up",
        ufbx::CoordinateAxis::PositiveY => ", Y up",
        _ => "",
    };
    format!("FBX in {units}{up}: converted to metres, Y up")
}

/// The skin's bones: one per cluster, parent = the nearest ancestor node that is a cluster's.
struct Skeleton<'a> {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    /// Per cluster: its bone (index into `names`).
    of_cluster: Vec<usize>,
    /// Per bone: its node, and its geometry-to-bone matrix.
    nodes: Vec<(&'a ufbx::Node, DMat4)>,
}

impl<'a> Skeleton<'a> {
    fn of(
        scene: &'a ufbx::Scene,
        skin: &'a ufbx::SkinDeformer,
        notes: &mut Vec<String>,
    ) -> Skeleton<'a> {
        let mut nodes: Vec<(&ufbx::Node, DMat4)> = Vec::new();
        let mut of_cluster = Vec::new();
        for cluster in skin.clusters.iter() {
            let Some(node) = cluster.bone_node.as_deref() else {
                of_cluster.push(usize::MAX);
                continue;
            };
            let id = node.element.element_id;
            let b = match nodes.iter().position(|(n, _)| n.element.element_id == id) {
                Some(b) => b,
                None => {
                    nodes.push((node, mat4(&cluster.geometry_to_bone)));
                    nodes.len() - 1
                }
            };
            of_cluster.push(b);
        }
        let parents = (nodes.iter())
            .map(|(n, _)| {
                let mut up = n.parent.as_deref();
                while let Some(p) = up {
                    if let Some(b) = nodes
                        .iter()
                        .position(|(x, _)| x.element.element_id == p.element.element_id)
                    {
                        return Some(b);
                    }
                    up = p.parent.as_deref();
                }
                None
            })
            .collect();
        let left_out: Vec<String> = (scene.nodes.iter())
            .filter(|n| n.bone.is_some())
            .filter(|n| {
                !nodes
                    .iter()
                    .any(|(x, _)| x.element.element_id == n.element.element_id)
            })
            .map(|n| n.element.name.to_string())
            .collect();
        let leaves = left_out.iter().filter(|n| n.ends_with("_end")).count();
        if leaves > 0 {
            notes.push(format!("{leaves} leaf bones without skin weights ('_end': Blender's FBX exporter's 'Add Leaf Bones') left out"));
        }
        let others: Vec<&String> = left_out.iter().filter(|n| !n.ends_with("_end")).collect();
        if !others.is_empty() {
            notes.push(format!(
                "bones without skin weights left out (they deform nothing): {}",
                others
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        let names = nodes
            .iter()
            .map(|(n, _)| n.element.name.to_string())
            .collect();
        Skeleton {
            names,
            parents,
            of_cluster,
            nodes,
        }
    }
}

/// The control points' triangles (each polygon triangulated by ufbx).
fn triangles(mesh: &ufbx::Mesh) -> Vec<[usize; 3]> {
    let mut corners = vec![0u32; mesh.max_face_triangles * 3];
    let mut out = Vec::with_capacity(mesh.num_triangles);
    for &face in mesh.faces.iter().filter(|f| f.num_indices >= 3) {
        let n = mesh.triangulate_face(&mut corners, face) as usize;
        out.extend(
            (corners[..3 * n].chunks_exact(3))
                .map(|t| [0, 1, 2].map(|k| mesh.vertex_indices[t[k] as usize] as usize)),
        );
    }
    out
}

/// Per control point, its (bone, weight) pairs, weight > 0, normalised.
fn weights(skin: &ufbx::SkinDeformer, of_cluster: &[usize]) -> Vec<Vec<(usize, f64)>> {
    (skin.vertices.iter())
        .map(|v| {
            let range = v.weight_begin as usize..(v.weight_begin + v.num_weights) as usize;
            let mut pairs: Vec<(usize, f64)> = (skin.weights.as_ref()[range].iter())
                .filter(|w| w.weight > 0.0)
                .filter_map(|w| {
                    of_cluster
                        .get(w.cluster_index as usize)
                        .filter(|&&b| b != usize::MAX)
                        .map(|&b| (b, w.weight))
                })
                .collect();
            let total: f64 = pairs.iter().map(|p| p.1).sum();
            pairs.iter_mut().for_each(|p| p.1 /= total);
            pairs
        })
        .collect()
}

/// The bones at every frame of the stack named `clip`.
fn sample(
    path: &Path,
    scene: &ufbx::Scene,
    clip: &str,
    skeleton: &Skeleton,
    from_world: DMat4,
    notes: &mut Vec<String>,
) -> Result<Sampled, InputError> {
    let stacks: Vec<&ufbx::AnimStack> = scene.anim_stacks.iter().map(|s| &**s).collect();
    let named = |s: &&&ufbx::AnimStack| {
        let name: &str = &s.element.name;
        name == clip || name.rsplit_once('|').is_some_and(|(_, take)| take == clip)
    };
    let Some(stack) = stacks.iter().find(named) else {
        let names: Vec<String> = stacks.iter().map(|s| s.element.name.to_string()).collect();
        return Err(bad(
            path,
            format!(
                "no animation stack '{clip}' (the file has: {})",
                names.join(", ")
            ),
        ));
    };
    let fps = scene.settings.frames_per_second;
    if fps.is_nan() || fps <= 0.0 {
        return Err(bad(path, "the file has no frame rate"));
    }
    let (first, last) = (
        (stack.time_begin * fps).round() as i64,
        (stack.time_end * fps).round() as i64,
    );
    notes.extend(simplified(stack, fps, first..=last));
    let mut times = Vec::new();
    let mut bones = Vec::new();
    for frame in first..=last {
        let time = frame as f64 / fps;
        let evaluated = ufbx::evaluate_scene(scene, &stack.anim, time, Default::default())
            .map_err(|e| {
                bad(
                    path,
                    format!("cannot evaluate '{clip}' at {time} s: {}", e.description),
                )
            })?;
        let pose = (skeleton.nodes.iter())
            .map(|(node, to_bone)| {
                let world = mat4(&evaluated.nodes[node.element.typed_id as usize].node_to_world);
                let t = world * *to_bone * from_world;
                Affine {
                    q: DMat3::from_mat4(t),
                    d: t.w_axis.truncate(),
                }
            })
            .collect();
        times.push(time);
        bones.push(pose);
    }
    Ok(Sampled { times, bones })
}

/// A note where some frames of `stack` fall between the keys of one of its animated curves:
/// the exporter simplified the curves (Blender's FBX "Simplify", 1 by default, drops keys that
/// the curve's interpolation comes within a tolerance of), so those frames' bones are
/// interpolated and may be off the rig's own by millimetres.
fn simplified(
    stack: &ufbx::AnimStack,
    fps: f64,
    frames: std::ops::RangeInclusive<i64>,
) -> Option<String> {
    let count = frames.clone().count();
    let curves = (stack.layers.iter())
        .flat_map(|l| l.anim_values.iter())
        .flat_map(|v| v.curves.iter().flatten())
        .filter(|c| c.keyframes.len() > 1);
    let mut keyed = vec![true; count];
    for curve in curves {
        let on_key =
            |f: i64| (curve.keyframes.iter()).any(|k| (k.time * fps - f as f64).abs() < 1e-3);
        for (slot, f) in keyed.iter_mut().zip(frames.clone()) {
            *slot &= on_key(f);
        }
    }
    let between = keyed.iter().filter(|k| !**k).count();
    (between > 0).then(|| {
        format!(
            "stack '{}': {between} of {count} frames fall between the keys of simplified curves, so their bones are interpolated (possibly millimetres off the rig's): for exact poses export with Simplify 0 (Blender's FBX exporter: Bake Animation > Simplify)",
            stack.element.name
        )
    })
}
