//! A rig from USD (UsdSkel) through `openusd`'s stage and UsdSkel schema readers: the stage's
//! one skinned mesh (a Mesh with `primvars:skel:jointIndices` / `jointWeights`), its points
//! (the DCC's own vertices, in its order), triangles and weights, the Skeleton it binds, and per
//! time sample of the SkelAnimation named by the clip every joint's transform relative to the
//! bind pose, in world space, as for a glTF or FBX rig.
//!
//! UsdSkel's skinning, in column vectors: a mesh point `p` is at `S · J_j(t) · B_j⁻¹ · G · p`
//! under joint j, where `G` is the mesh's `geomBindTransform`, `B_j` the joint's
//! `bindTransforms` entry, `J_j(t)` its skeleton-space transform at t (the SkelAnimation's
//! joint-local transforms, or `restTransforms` where it has none, composed down the joint
//! tree) and `S` the Skeleton prim's local-to-world. The rest mesh is `S · G · p` (every joint
//! at its bind transform), so joint j's transform is `S(t) · J_j(t) · B_j⁻¹ · S⁻¹`, which LBS
//! applies to the rest mesh. The stage's frame is converted to metres, Y up
//! ([`crate::import::usd`]).

use crate::import::guarded;
use crate::import::rig::{Rig, Sampled};
use crate::import::usd::{self, local_to_world, mat4, why, Stage};
use crate::set::{Affine, InputError};
use glam::{DMat3, DMat4, DVec3};
use openusd::schemas::geom::{Mesh, PointBased};
use openusd::schemas::skel::{
    InfluenceInterpolation, SkelAnimQuery, SkelAnimation, SkelBindingAPI, Skeleton, SkinningMethod,
};
use openusd::sdf::{self, Value};
use openusd::usd::{SchemaBase, TimeCode};
use std::path::Path;
use std::sync::Arc;

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

/// Loads the rig and its SkelAnimation named `clip`, sampled at its time samples.
pub fn load(path: &Path, clip: &str) -> Result<Rig, InputError> {
    guarded("USD", || read(path, clip)).map_err(|m| bad(path, m))
}

fn read(path: &Path, clip: &str) -> Result<Rig, String> {
    let stage = usd::open(path)?;
    let mut notes: Vec<String> = stage.frame_note.iter().cloned().collect();
    let binding = one_skinned_mesh(&stage)?;
    let mesh_path = binding.path().clone();
    let skeleton = bound_skeleton(&stage, &binding)?;
    let joints = Joints::of(&skeleton)?;
    let mesh = Mesh::get(&stage.stage, mesh_path.clone())
        .map_err(why)?
        .ok_or_else(|| format!("{mesh_path}: not a Mesh"))?;
    let points = usd::points(
        mesh.points_attr()
            .get_at::<Value>(TimeCode::EARLIEST)
            .map_err(why)?,
    )
    .ok_or_else(|| format!("{mesh_path}: no points"))?;
    let triangles = triangles(&mesh, points.len())?;
    let weights = weights(&binding, &joints, points.len())?;
    let bind_geometry = binding
        .geom_bind_transform()
        .map_err(why)?
        .map_or(DMat4::IDENTITY, |m| mat4(&m));
    let skeleton_world =
        stage.to_rig * local_to_world(&stage, skeleton.path(), TimeCode::EARLIEST)?;
    let mesh_to_world = skeleton_world * bind_geometry;
    let motion = sample(&stage, clip, &skeleton, &joints, skeleton_world.inverse())?;
    notes.extend(skin_notes(&binding)?);
    let rest: Vec<DVec3> = points
        .iter()
        .map(|&p| mesh_to_world.transform_point3(p))
        .collect();
    Ok(Rig {
        primitives: std::iter::once(0..rest.len()).collect(),
        triangles,
        weights,
        rest,
        names: joints.names,
        parents: joints.parents,
        uvs: None,
        tangents: None,
        bind: None,
        base_mesh: true,
        mesh_world: Some(mesh_to_world).filter(|m| !m.abs_diff_eq(DMat4::IDENTITY, 1e-9)),
        notes,
        motion: Arc::new(motion),
    })
}

/// The stage's one mesh with joint influences.
fn one_skinned_mesh(stage: &Stage) -> Result<SkelBindingAPI, String> {
    let mut skinned = Vec::new();
    for p in usd::prims(stage)? {
        let is_mesh = Mesh::get(&stage.stage, p.clone()).map_err(why)?.is_some();
        let Some(binding) = SkelBindingAPI::get(&stage.stage, p)
            .map_err(why)?
            .filter(|_| is_mesh)
        else {
            continue;
        };
        if binding
            .joint_indices_attr()
            .get::<Value>()
            .map_err(why)?
            .is_some()
        {
            skinned.push(binding);
        }
    }
    match skinned.len() {
        1 => Ok(skinned.remove(0)),
        0 => Err("no skinned mesh (a Mesh with primvars:skel:jointIndices and jointWeights, bound to a Skeleton): export the character's mesh with its armature as UsdSkel (Blender: File > Export > Universal Scene Description with Armatures on)".into()),
        n => Err(format!(
            "{n} skinned meshes ({}): export the one character mesh the cache holds",
            skinned.iter().map(|b| b.path().as_str()).collect::<Vec<_>>().join(", ")
        )),
    }
}

/// The Skeleton the mesh binds (`skel:skeleton`, on the mesh or inherited).
fn bound_skeleton(stage: &Stage, binding: &SkelBindingAPI) -> Result<Skeleton, String> {
    let mesh = binding.path();
    let target = (binding.inherited_skeleton().map_err(why)?).ok_or_else(|| {
        format!("{mesh} binds no Skeleton (skel:skeleton): export the mesh with its armature")
    })?;
    Skeleton::get(&stage.stage, target.clone())
        .map_err(why)?
        .ok_or_else(|| format!("{mesh}: skel:skeleton targets {target}, which is not a Skeleton"))
}

/// A Skeleton's joints: names, parents, bind and rest transforms (glam's convention).
struct Joints {
    /// The skeleton's joint paths (`hips/spine`), what animations and subsets name.
    paths: Vec<String>,
    /// Their last components, the bones' names.
    names: Vec<String>,
    /// Each joint's parent, before it in the order.
    parents: Vec<Option<usize>>,
    /// World-space (skeleton-space) bind transforms, inverted.
    bind_inverse: Vec<DMat4>,
    /// Joint-local rest transforms, for joints an animation leaves out.
    rest: Vec<DMat4>,
}

impl Joints {
    fn of(skeleton: &Skeleton) -> Result<Joints, String> {
        let at = skeleton.path();
        let paths = skeleton.joints().map_err(why)?;
        if paths.is_empty() {
            return Err(format!("Skeleton {at} has no joints"));
        }
        let parents = skeleton.joint_parent_indices().map_err(why)?;
        if let Some(j) = (0..parents.len()).find(|&j| parents[j].is_some_and(|p| p >= j)) {
            return Err(format!(
                "Skeleton {at}: joint {} comes before its parent (UsdSkel orders parents first)",
                paths[j]
            ));
        }
        let n = paths.len();
        let bind = per_joint(
            at,
            "bindTransforms",
            skeleton.bind_transforms().map_err(why)?,
            n,
        )?;
        let authored = skeleton.rest_transforms().map_err(why)?;
        let rest = match authored.is_empty() {
            // Unauthored: the bind pose, in each joint's parent's frame.
            true => (0..n)
                .map(|j| parents[j].map_or(bind[j], |p| bind[p].inverse() * bind[j]))
                .collect(),
            false => per_joint(at, "restTransforms", authored, n)?,
        };
        Ok(Joints {
            names: skeleton.joint_short_names().map_err(why)?,
            bind_inverse: bind.iter().map(|b| b.inverse()).collect(),
            paths,
            parents,
            rest,
        })
    }

    /// Every joint's skeleton-space transform, from joint-local ones.
    fn skeleton_space(&self, local: &[DMat4]) -> Vec<DMat4> {
        let mut out: Vec<DMat4> = Vec::with_capacity(local.len());
        for (j, l) in local.iter().enumerate() {
            out.push(self.parents[j].map_or(*l, |p| out[p] * *l));
        }
        out
    }
}

/// A Skeleton's array `name` of a matrix a joint (`joints` of them), in glam's convention.
fn per_joint(
    at: &sdf::Path,
    name: &str,
    matrices: Vec<openusd::gf::Matrix4d>,
    joints: usize,
) -> Result<Vec<DMat4>, String> {
    match matrices.len() == joints {
        true => Ok(matrices.iter().map(mat4).collect()),
        false => Err(format!(
            "Skeleton {at}: {} {name} for {joints} joints",
            matrices.len()
        )),
    }
}

/// The mesh's faces, each polygon a fan of triangles.
fn triangles(mesh: &Mesh, points: usize) -> Result<Vec<[usize; 3]>, String> {
    let at = mesh.path();
    let ints = |value: Option<Value>| match value {
        Some(Value::IntVec(v)) => Ok(v),
        _ => Err(format!("{at}: no faceVertexCounts and faceVertexIndices")),
    };
    let counts = ints(
        mesh.face_vertex_counts_attr()
            .get_at::<Value>(TimeCode::EARLIEST)
            .map_err(why)?,
    )?;
    let indices = ints(
        mesh.face_vertex_indices_attr()
            .get_at::<Value>(TimeCode::EARLIEST)
            .map_err(why)?,
    )?;
    if let Some(i) = indices.iter().find(|&&i| i < 0 || i as usize >= points) {
        return Err(format!(
            "{at}: face vertex index {i} outside its {points} points"
        ));
    }
    let mut out = Vec::new();
    let mut start = 0usize;
    for &n in &counts {
        let n = usize::try_from(n).map_err(|_| format!("{at}: a face of {n} vertices"))?;
        let face = indices.get(start..start + n).ok_or_else(|| {
            format!(
                "{at}: faceVertexCounts need more than its {} faceVertexIndices",
                indices.len()
            )
        })?;
        out.extend((2..n).map(|k| [face[0], face[k - 1], face[k]].map(|i| i as usize)));
        start += n;
    }
    Ok(out)
}

/// Per point, its (joint, weight) pairs, weight > 0, normalised: `elementSize` influences a
/// point (`vertex` interpolation) or one set for the whole mesh (`constant`), each an index
/// into the binding's `skel:joints` where it has them, else into the skeleton's joints.
fn weights(
    binding: &SkelBindingAPI,
    joints: &Joints,
    points: usize,
) -> Result<Vec<Vec<(usize, f64)>>, String> {
    let at = binding.path();
    let indices = binding.joint_indices().map_err(why)?;
    let weights = binding.joint_weights().map_err(why)?;
    let size = usize::try_from(binding.elements_per_element().map_err(why)?)
        .ok()
        .filter(|&n| n > 0)
        .ok_or_else(|| format!("{at}: primvars:skel:jointIndices' elementSize must be positive"))?;
    let subset = binding.joint_subset().map_err(why)?;
    let of_index: Vec<usize> = match subset.is_empty() {
        true => (0..joints.paths.len()).collect(),
        false => (subset.iter())
            .map(|name| {
                joints.paths.iter().position(|p| p == name).ok_or_else(|| {
                    format!("{at}: skel:joints names {name}, not a joint of the skeleton")
                })
            })
            .collect::<Result<_, _>>()?,
    };
    let sets = match binding.interpolation().map_err(why)? {
        InfluenceInterpolation::Vertex => points,
        InfluenceInterpolation::Constant => 1,
    };
    if indices.len() != sets * size || weights.len() != indices.len() {
        return Err(format!(
            "{at}: {} joint indices and {} weights, where {sets} sets of {size} need {}",
            indices.len(),
            weights.len(),
            sets * size
        ));
    }
    let pairs = |set: usize| -> Result<Vec<(usize, f64)>, String> {
        let range = set * size..(set + 1) * size;
        let mut pairs = Vec::new();
        for (&i, &w) in indices[range.clone()].iter().zip(&weights[range]) {
            let joint = usize::try_from(i)
                .ok()
                .and_then(|i| of_index.get(i))
                .ok_or_else(|| {
                    format!(
                        "{at}: joint index {i} outside its {} joints",
                        of_index.len()
                    )
                })?;
            if w > 0.0 {
                pairs.push((*joint, f64::from(w)));
            }
        }
        let total: f64 = pairs.iter().map(|p| p.1).sum();
        pairs.iter_mut().for_each(|p| p.1 /= total);
        Ok(pairs)
    };
    (0..points)
        .map(|v| pairs(if sets == 1 { 0 } else { v }))
        .collect()
}

/// Notes on what the rig's own skin (LBS of the stored points) leaves to the cache: blend
/// shapes, and dual-quaternion skinning.
fn skin_notes(binding: &SkelBindingAPI) -> Result<Vec<String>, String> {
    let at = binding.path();
    let mut notes = Vec::new();
    let shapes = binding.blend_shapes().map_err(why)?;
    if !shapes.is_empty() {
        notes.push(format!(
            "mesh {at}: {} blend shape(s) ({}) not read: the cache holds their effect",
            shapes.len(),
            shapes.join(", ")
        ));
    }
    if binding.skinning_method().map_err(why)? == SkinningMethod::DualQuaternion {
        notes.push(format!("mesh {at}: dual-quaternion skinning, the rig's own skin read as linear blend skinning (the cache holds the rig's)"));
    }
    Ok(notes)
}

/// The SkelAnimation named `clip` (its prim's name), with the names of the stage's animations
/// for the error that none is.
fn animation(stage: &Stage, clip: &str) -> Result<SkelAnimQuery, String> {
    let mut names = Vec::new();
    for p in usd::prims(stage)? {
        if SkelAnimation::get(&stage.stage, p.clone())
            .map_err(why)?
            .is_none()
        {
            continue;
        }
        if p.name() == Some(clip) {
            return SkelAnimQuery::new(&stage.stage, p.clone())
                .map_err(why)?
                .ok_or_else(|| format!("SkelAnimation {p} animates no joints"));
        }
        names.push(p.name().unwrap_or_default().to_string());
    }
    Err(match names.is_empty() {
        true => format!("no SkelAnimation '{clip}': the stage has none (export with Animation on)"),
        false => format!(
            "no SkelAnimation '{clip}' (the file has: {})",
            names.join(", ")
        ),
    })
}

/// The bones at every time sample of the animation `clip` (`from_world`: the rig's world to
/// skeleton space at the bind pose).
fn sample(
    stage: &Stage,
    clip: &str,
    skeleton: &Skeleton,
    joints: &Joints,
    from_world: DMat4,
) -> Result<Sampled, String> {
    let query = animation(stage, clip)?;
    let prim = sdf::Path::from(query.prim_path());
    let source: Vec<Option<usize>> = (joints.paths.iter())
        .map(|p| query.joint_order().iter().position(|a| a == p))
        .collect();
    if source.iter().all(Option::is_none) {
        return Err(format!(
            "SkelAnimation {prim} animates none of {}'s joints",
            skeleton.path()
        ));
    }
    let mut codes = Vec::new();
    for name in ["translations", "rotations", "scales"] {
        let attribute = stage.stage.prim(prim.clone()).attribute(name);
        codes.extend(attribute.time_sample_times().map_err(why)?);
    }
    codes.sort_by(f64::total_cmp);
    codes.dedup();
    let mut bones = Vec::with_capacity(codes.len());
    for &code in &codes {
        let time = TimeCode::new(code);
        let animated = query
            .compute_joint_local_transforms(&stage.stage, time)
            .map_err(why)?;
        let local: Vec<DMat4> = (source.iter().enumerate())
            .map(|(j, a)| a.map_or(joints.rest[j], |a| mat4(&animated[a])))
            .collect();
        let world = stage.to_rig * local_to_world(stage, skeleton.path(), time)?;
        let pose = (joints
            .skeleton_space(&local)
            .iter()
            .zip(&joints.bind_inverse))
        .map(|(posed, bind_inverse)| {
            let t = world * *posed * *bind_inverse * from_world;
            Affine {
                q: DMat3::from_mat4(t),
                d: t.w_axis.truncate(),
            }
        })
        .collect();
        bones.push(pose);
    }
    let times = codes.iter().map(|c| c / stage.codes_per_second).collect();
    Ok(Sampled { times, bones })
}
