//! A rig from glTF 2.0 (.glb, or .gltf with external buffers): the skinned mesh (all primitives
//! of every skinned mesh node, concatenated in file order; all must share one skin), the skin's
//! joints as bones (parent = nearest ancestor that is a joint), the rest mesh = the mesh skinned
//! at the nodes' default pose and default morph weights (mesh-space POSITIONs are not always the
//! rest pose), and per time `T_b = W_b(t) · W_b(default)⁻¹` from a sampled animation clip. A
//! clip's morph weight channels are not played: the cache carries their effect. An FBX rig
//! loads into the same [`Rig`] through `fbx_rig` (`Rig::load` reads either).

use crate::import::rig::{Clip, Rig, TIME_SLACK};
use crate::set::{Affine, InputError};
use glam::{DMat4, DQuat, DVec3, DVec4};
use gltf::animation::{Interpolation, Property};
use std::path::Path;
use std::sync::Arc;

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

/// Local transform of a node: translation, rotation, scale.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Trs {
    t: DVec3,
    r: DQuat,
    s: DVec3,
}

impl Trs {
    fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(self.s, self.r, self.t)
    }
}

#[derive(Debug, Clone)]
enum Values {
    Vec3(Vec<DVec3>),
    Quat(Vec<DQuat>),
}

#[derive(Debug, Clone)]
struct Channel {
    node: usize,
    property: Property,
    interpolation: Interpolation,
    times: Vec<f64>,
    /// For CUBICSPLINE: (in-tangent, value, out-tangent) per key, flattened.
    values: Values,
}

/// A glTF clip on the node tree.
#[derive(Debug, Clone)]
pub(crate) struct Channels {
    /// Node of each bone.
    joints: Vec<usize>,
    node_parents: Vec<Option<usize>>,
    defaults: Vec<Trs>,
    /// World matrices of the bones at the default pose, inverted.
    default_inverse: Vec<DMat4>,
    channels: Vec<Channel>,
}

/// Loads the glTF rig and the animation named `clip`: the file, its node tree, the skin (one
/// for every skinned mesh), the skeleton, the rest mesh with its tangents, the clip's
/// channels.
pub(crate) fn load(path: &Path, clip: &str) -> Result<Rig, InputError> {
    let (gltf, buffers) = read_file(path)?;
    let doc = &gltf.document;
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let tree = NodeTree::of(&nodes);
    let (skinned, skin) = one_skin(path, &nodes)?;
    let skeleton = Skeleton::of(path, &nodes, &tree, &skin, &buffers)?;
    let mesh = RestMesh::of(path, &skinned, &skeleton.joint_matrices, &buffers)?;
    let mut notes = mesh.notes;
    let channels = channels(path, doc, clip, &buffers, &mut notes)?;
    notes.dedup();
    Ok(Rig {
        bind: common_bind(&skeleton.joint_matrices),
        base_mesh: false,
        mesh_world: Some(tree.world_default[skinned[0].index()])
            .filter(|m| !m.abs_diff_eq(DMat4::IDENTITY, 1e-9)),
        primitives: mesh.primitives,
        notes,
        rest: mesh.rest,
        weights: mesh.weights,
        uvs: mesh.uvs,
        tangents: mesh.tangents,
        triangles: mesh.triangles,
        names: skeleton.names,
        parents: skeleton.parents,
        motion: Arc::new(Channels {
            joints: skeleton.joints,
            node_parents: tree.parents,
            defaults: tree.defaults,
            default_inverse: skeleton.default_inverse,
            channels,
        }),
    })
}

impl Clip for Channels {
    fn key_times(&self) -> Vec<f64> {
        let mut times: Vec<f64> = (self.channels.iter())
            .flat_map(|c| c.times.clone())
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup_by(|a, b| (*a - *b).abs() <= TIME_SLACK);
        times
    }

    fn holds_keys(&self) -> bool {
        (self.channels.iter()).all(|c| c.interpolation == Interpolation::Step)
    }

    fn bones_at(&self, time: f64) -> Vec<Affine> {
        let mut locals = self.defaults.clone();
        for ch in &self.channels {
            let trs = &mut locals[ch.node];
            match (&ch.property, &ch.values) {
                (Property::Translation, Values::Vec3(v)) => trs.t = sample_vec3(ch, v, time),
                (Property::Scale, Values::Vec3(v)) => trs.s = sample_vec3(ch, v, time),
                (Property::Rotation, Values::Quat(q)) => trs.r = sample_quat(ch, q, time),
                _ => {}
            }
        }
        let world = world_matrices(
            &self.node_parents,
            &locals.iter().map(Trs::matrix).collect::<Vec<_>>(),
        );
        self.joints
            .iter()
            .zip(&self.default_inverse)
            .map(|(&n, inv)| {
                let t = world[n] * *inv;
                Affine {
                    q: glam::DMat3::from_mat4(t),
                    d: t.w_axis.truncate(),
                }
            })
            .collect()
    }
}

/// The file and its binary buffers.
fn read_file(path: &Path) -> Result<(gltf::Gltf, Buffers), InputError> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, format!("cannot read: {e}")))?;
    let gltf = gltf::Gltf::from_slice(&bytes)
        .map_err(|e| bad(path, format!("not a valid glTF file: {e}")))?;
    let buffers = Buffers(load_buffers(path, &gltf)?);
    Ok((gltf, buffers))
}

/// The binary buffers of a file, by index.
struct Buffers(Vec<Vec<u8>>);

impl Buffers {
    /// What the gltf crate's readers take to find a buffer's bytes.
    fn get<'s>(&'s self) -> impl Clone + Fn(gltf::Buffer<'_>) -> Option<&'s [u8]> + 's {
        move |b: gltf::Buffer<'_>| self.0.get(b.index()).map(Vec::as_slice)
    }
}

/// The node tree: each node's parent, its default local transform and its world matrix at
/// the default pose.
struct NodeTree {
    parents: Vec<Option<usize>>,
    defaults: Vec<Trs>,
    world_default: Vec<DMat4>,
}

impl NodeTree {
    fn of(nodes: &[gltf::Node]) -> NodeTree {
        let mut parents = vec![None; nodes.len()];
        for n in nodes {
            for c in n.children() {
                parents[c.index()] = Some(n.index());
            }
        }
        let defaults: Vec<Trs> = nodes
            .iter()
            .map(|n| {
                let (t, r, s) = n.transform().decomposed();
                Trs {
                    t: DVec3::from(t.map(f64::from)),
                    r: DQuat::from_array(r.map(f64::from)).normalize(),
                    s: DVec3::from(s.map(f64::from)),
                }
            })
            .collect();
        let world_default = world_matrices(
            &parents,
            &defaults.iter().map(Trs::matrix).collect::<Vec<_>>(),
        );
        NodeTree {
            parents,
            defaults,
            world_default,
        }
    }
}

/// The skinned mesh nodes (at least one) and their skin, which must be one for all.
fn one_skin<'a, 'n>(
    path: &Path,
    nodes: &'n [gltf::Node<'a>],
) -> Result<(Vec<&'n gltf::Node<'a>>, gltf::Skin<'a>), InputError> {
    let skinned: Vec<&gltf::Node> = nodes
        .iter()
        .filter(|n| n.mesh().is_some() && n.skin().is_some())
        .collect();
    let Some(first) = skinned.first() else {
        return Err(bad(
            path,
            "no skinned mesh (a node with both a mesh and a skin)",
        ));
    };
    let skin = first.skin().ok_or_else(|| bad(path, "no skin"))?;
    if let Some(other) = skinned
        .iter()
        .find(|n| n.skin().map(|s| s.index()) != Some(skin.index()))
    {
        return Err(bad(
            path,
            format!(
                "skinned meshes use different skins (node {} uses skin {}, node {} skin {:?}): one skin per rig",
                first.index(),
                skin.index(),
                other.index(),
                other.skin().map(|s| s.index())
            ),
        ));
    }
    Ok((skinned, skin))
}

/// The skin's joints as bones.
struct Skeleton {
    /// Node of each bone.
    joints: Vec<usize>,
    /// Parent bone: the nearest ancestor node that is a joint.
    parents: Vec<Option<usize>>,
    names: Vec<String>,
    /// World matrices of the bones at the default pose, inverted.
    default_inverse: Vec<DMat4>,
    /// `W_j(default) · IBM_j`: what skins the mesh at the default pose.
    joint_matrices: Vec<DMat4>,
}

impl Skeleton {
    fn of(
        path: &Path,
        nodes: &[gltf::Node],
        tree: &NodeTree,
        skin: &gltf::Skin,
        buffers: &Buffers,
    ) -> Result<Skeleton, InputError> {
        let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let mut bone_of_node = vec![None; nodes.len()];
        joints
            .iter()
            .enumerate()
            .for_each(|(b, &n)| bone_of_node[n] = Some(b));
        let parents: Vec<Option<usize>> = joints
            .iter()
            .map(|&n| {
                let mut p = tree.parents[n];
                while let Some(x) = p {
                    if bone_of_node[x].is_some() {
                        return bone_of_node[x];
                    }
                    p = tree.parents[x];
                }
                None
            })
            .collect();
        let names = joints
            .iter()
            .enumerate()
            .map(|(b, &n)| {
                nodes[n]
                    .name()
                    .map_or_else(|| format!("joint {b}"), str::to_string)
            })
            .collect();
        let inverse_bind = inverse_binds(path, skin, joints.len(), buffers)?;
        let mut default_inverse = Vec::with_capacity(joints.len());
        for (b, &n) in joints.iter().enumerate() {
            let w = tree.world_default[n];
            let det = w.determinant();
            if !det.is_finite() || det.abs() <= 1e-12 {
                return Err(bad(
                    path,
                    format!("joint {b} (node {n}) has a non-invertible world matrix"),
                ));
            }
            default_inverse.push(w.inverse());
        }
        let joint_matrices = joints
            .iter()
            .zip(&inverse_bind)
            .map(|(&n, ibm)| tree.world_default[n] * *ibm)
            .collect();
        Ok(Skeleton {
            joints,
            parents,
            names,
            default_inverse,
            joint_matrices,
        })
    }
}

/// The skin's inverse bind matrices (identities where the file has none), one per joint.
fn inverse_binds(
    path: &Path,
    skin: &gltf::Skin,
    joints: usize,
    buffers: &Buffers,
) -> Result<Vec<DMat4>, InputError> {
    let inverse_bind: Vec<DMat4> = match skin.reader(buffers.get()).read_inverse_bind_matrices() {
        Some(ibm) => ibm
            .map(|m| DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from))))
            .collect(),
        None => vec![DMat4::IDENTITY; joints],
    };
    if inverse_bind.len() != joints {
        return Err(bad(
            path,
            format!(
                "{} inverse bind matrices for {joints} joints",
                inverse_bind.len()
            ),
        ));
    }
    Ok(inverse_bind)
}

/// The rest mesh: every primitive of the skinned meshes, skinned at the default pose and
/// default morph weights, with the skin's weights, UVs and tangents (each where every
/// primitive has them).
struct RestMesh {
    rest: Vec<DVec3>,
    triangles: Vec<[usize; 3]>,
    primitives: Vec<std::ops::Range<usize>>,
    weights: Vec<Vec<(usize, f64)>>,
    uvs: Option<Vec<[f32; 2]>>,
    tangents: Option<Vec<[f32; 4]>>,
    notes: Vec<String>,
}

impl RestMesh {
    fn of(
        path: &Path,
        skinned: &[&gltf::Node],
        joint_matrices: &[DMat4],
        buffers: &Buffers,
    ) -> Result<RestMesh, InputError> {
        let mut mesh = RestMesh {
            rest: Vec::new(),
            triangles: Vec::new(),
            primitives: Vec::new(),
            weights: Vec::new(),
            uvs: Some(Vec::new()),
            tangents: Some(Vec::new()),
            notes: Vec::new(),
        };
        for node in skinned {
            let gltf_mesh = node.mesh().ok_or_else(|| bad(path, "no mesh"))?;
            for prim in gltf_mesh.primitives() {
                mesh.add_primitive(path, node, &gltf_mesh, &prim, joint_matrices, buffers)?;
            }
        }
        Ok(mesh)
    }

    /// Appends primitive `prim` of `mesh` (of skinned node `node`).
    fn add_primitive(
        &mut self,
        path: &Path,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
        joint_matrices: &[DMat4],
        buffers: &Buffers,
    ) -> Result<(), InputError> {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            return Err(bad(
                path,
                format!(
                    "mesh {} has a primitive that is not triangles",
                    mesh.index()
                ),
            ));
        }
        let reader = prim.reader(buffers.get());
        let SkinAttributes {
            positions,
            joints: joints0,
            weights: weights0,
        } = skin_attributes(path, mesh, &reader)?;
        let positions = at_default_morph_weights(path, node, mesh, &reader, positions)?;
        self.note_morph_targets(node, mesh, prim);
        let uv: Option<Vec<[f32; 2]>> = reader.read_tex_coords(0).map(|t| t.into_f32().collect());
        let tangent: Option<Vec<[f32; 4]>> = reader.read_tangents().map(Iterator::collect);
        let counts = [joints0.len(), weights0.len()]
            .into_iter()
            .chain(uv.as_ref().map(Vec::len))
            .chain(tangent.as_ref().map(Vec::len));
        if counts.into_iter().any(|n| n != positions.len()) {
            return Err(bad(
                path,
                format!("mesh {}: attribute counts differ", mesh.index()),
            ));
        }
        match (self.uvs.as_mut(), uv) {
            (Some(all), Some(this)) => all.extend(this),
            _ => self.uvs = None,
        }
        let base = self.rest.len();
        for (i, ((p, js), ws)) in positions.iter().zip(&joints0).zip(&weights0).enumerate() {
            let p = DVec4::new(p[0] as f64, p[1] as f64, p[2] as f64, 1.0);
            self.weights.push(vertex_weights(js, ws));
            let blend = blend_matrix(path, js, ws, joint_matrices)?;
            self.rest.push((blend * p).truncate());
            match (self.tangents.as_mut(), &tangent) {
                (Some(all), Some(t)) => all.push(rest_tangent(path, mesh, i, t[i], &blend)?),
                _ => self.tangents = None,
            }
        }
        let count = positions.len();
        self.primitives.push(base..base + count);
        let indices = triangle_indices(path, mesh, &reader, count)?;
        self.triangles.extend(
            indices
                .chunks_exact(3)
                .map(|t| [base + t[0], base + t[1], base + t[2]]),
        );
        Ok(())
    }

    /// Notes, once per mesh (at its first primitive), that its morph targets are taken at
    /// their default weights.
    fn note_morph_targets(&mut self, node: &gltf::Node, mesh: &gltf::Mesh, prim: &gltf::Primitive) {
        if mesh.primitives().next().map(|p| p.index()) == Some(prim.index())
            && prim.morph_targets().len() > 0
        {
            self.notes.push(format!(
                "mesh {}: {} morph target(s), the rest mesh at their default weights {:?}",
                mesh.name()
                    .map_or_else(|| mesh.index().to_string(), str::to_string),
                prim.morph_targets().len(),
                morph_weights(node, mesh)
            ));
        }
    }
}

/// A skinned primitive's required attributes, as stored: POSITION, JOINTS_0 and WEIGHTS_0.
struct SkinAttributes {
    positions: Vec<[f32; 3]>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
}

/// A skinned primitive's [`SkinAttributes`] (an error naming the first missing).
fn skin_attributes<'a, 's, F>(
    path: &Path,
    mesh: &gltf::Mesh,
    reader: &gltf::mesh::Reader<'a, 's, F>,
) -> Result<SkinAttributes, InputError>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let missing = |what: &str| {
        bad(
            path,
            format!("mesh {}: a primitive without {what}", mesh.index()),
        )
    };
    let positions: Vec<[f32; 3]> = reader
        .read_positions()
        .ok_or_else(|| missing("POSITION"))?
        .collect();
    let joints: Vec<[u16; 4]> = reader
        .read_joints(0)
        .ok_or_else(|| missing("JOINTS_0"))?
        .into_u16()
        .collect();
    let weights: Vec<[f32; 4]> = reader
        .read_weights(0)
        .ok_or_else(|| missing("WEIGHTS_0"))?
        .into_f32()
        .collect();
    Ok(SkinAttributes {
        positions,
        joints,
        weights,
    })
}

/// A vertex's (joint, weight) pairs, normalised to sum to 1; non-positive weights (and every
/// weight where none is positive) dropped.
fn vertex_weights(js: &[u16; 4], ws: &[f32; 4]) -> Vec<(usize, f64)> {
    let total: f64 = ws.iter().map(|&w| w.max(0.0) as f64).sum();
    js.iter()
        .zip(ws)
        .filter(|(_, &w)| w > 0.0 && total > 0.0)
        .map(|(&j, &w)| (j as usize, w as f64 / total))
        .collect()
}

/// A vertex's blended joint matrix Σ w M_j, its weights as stored (an error for a joint index
/// outside the skin).
fn blend_matrix(
    path: &Path,
    js: &[u16; 4],
    ws: &[f32; 4],
    joint_matrices: &[DMat4],
) -> Result<DMat4, InputError> {
    let mut blend = DMat4::ZERO;
    for (j, w) in js.iter().zip(ws) {
        let m = joint_matrices.get(*j as usize).ok_or_else(|| {
            bad(
                path,
                format!(
                    "JOINTS_0 index {j} outside the skin's {} joints",
                    joint_matrices.len()
                ),
            )
        })?;
        blend += *m * *w as f64;
    }
    Ok(blend)
}

/// The primitive's vertex indices (0..count where it has none), each checked to be one of its
/// `count` vertices.
fn triangle_indices<'a, 's, F>(
    path: &Path,
    mesh: &gltf::Mesh,
    reader: &gltf::mesh::Reader<'a, 's, F>,
    count: usize,
) -> Result<Vec<usize>, InputError>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let indices: Vec<usize> = match reader.read_indices() {
        Some(i) => i.into_u32().map(|x| x as usize).collect(),
        None => (0..count).collect(),
    };
    if let Some(&i) = indices.iter().find(|&&i| i >= count) {
        return Err(bad(
            path,
            format!(
                "mesh {}: index {i} outside its {count} vertices",
                mesh.index()
            ),
        ));
    }
    Ok(indices)
}

/// Vertex `i`'s TANGENT `t` taken to the rest mesh like its position: xyz through the blended
/// joint matrix, renormalised; w as stored (it must be +-1).
fn rest_tangent(
    path: &Path,
    mesh: &gltf::Mesh,
    i: usize,
    t: [f32; 4],
    blend: &DMat4,
) -> Result<[f32; 4], InputError> {
    let xyz = blend.transform_vector3(DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64));
    let w = t[3];
    if !(xyz.length() > 1e-12 && xyz.is_finite() && w.abs() == 1.0) {
        return Err(bad(
            path,
            format!(
                "mesh {}: TANGENT {t:?} of vertex {i} is not a direction with w = +-1",
                mesh.index()
            ),
        ));
    }
    let xyz = xyz.normalize().as_vec3();
    Ok([xyz.x, xyz.y, xyz.z, w])
}

/// The channels of the animation named `clip` (its morph weight channels are noted in `notes`,
/// not played).
fn channels(
    path: &Path,
    doc: &gltf::Document,
    clip: &str,
    buffers: &Buffers,
    notes: &mut Vec<String>,
) -> Result<Vec<Channel>, InputError> {
    let names_of_clips: Vec<String> = doc
        .animations()
        .filter_map(|a| a.name().map(str::to_string))
        .collect();
    let animation = doc
        .animations()
        .find(|a| a.name() == Some(clip))
        .ok_or_else(|| {
            bad(
                path,
                format!("no animation named '{clip}' (the file has {names_of_clips:?})"),
            )
        })?;
    let mut channels = Vec::new();
    for ch in animation.channels() {
        let reader = ch.reader(buffers.get());
        let times: Vec<f64> = reader
            .read_inputs()
            .ok_or_else(|| bad(path, "an animation channel without key times"))?
            .map(f64::from)
            .collect();
        let values = match reader
            .read_outputs()
            .ok_or_else(|| bad(path, "an animation channel without values"))?
        {
            gltf::animation::util::ReadOutputs::Translations(t) => {
                Values::Vec3(t.map(|v| DVec3::from(v.map(f64::from))).collect())
            }
            gltf::animation::util::ReadOutputs::Scales(s) => {
                Values::Vec3(s.map(|v| DVec3::from(v.map(f64::from))).collect())
            }
            gltf::animation::util::ReadOutputs::Rotations(r) => Values::Quat(
                r.into_f32()
                    .map(|q| DQuat::from_array(q.map(f64::from)))
                    .collect(),
            ),
            gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => {
                let node = ch.target().node();
                notes.push(format!(
                    "animation '{clip}' animates the morph weights of node {}: not played (the cache carries their effect)",
                    node.name().map_or_else(|| node.index().to_string(), str::to_string)
                ));
                continue;
            }
        };
        let interpolation = ch.sampler().interpolation();
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let n = match &values {
            Values::Vec3(v) => v.len(),
            Values::Quat(q) => q.len(),
        };
        if times.is_empty() || n != per_key * times.len() {
            return Err(bad(
                path,
                format!(
                    "animation '{clip}': {n} values for {} key times",
                    times.len()
                ),
            ));
        }
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
            return Err(bad(
                path,
                format!("animation '{clip}': key times must be finite and increasing"),
            ));
        }
        channels.push(Channel {
            node: ch.target().node().index(),
            property: ch.target().property(),
            interpolation,
            times,
            values,
        });
    }
    Ok(channels)
}

/// Joint matrices this close (largest element difference, relative to the largest element) are
/// one bind matrix.
const SAME_BIND: f64 = 1e-5;

/// The joints' common bind matrix, if they have one.
fn common_bind(joint_matrices: &[DMat4]) -> Option<DMat4> {
    let first = *joint_matrices.first()?;
    let size = first
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    joint_matrices
        .iter()
        .all(|m| {
            (*m - first)
                .to_cols_array()
                .iter()
                .all(|d| d.abs() <= SAME_BIND * size)
        })
        .then_some(first)
}

/// The node's morph weights (the node's own, else the mesh's default; glTF 2.0 §3.7.2.2).
fn morph_weights(node: &gltf::Node, mesh: &gltf::Mesh) -> Vec<f32> {
    node.weights()
        .or_else(|| mesh.weights())
        .map_or_else(Vec::new, <[f32]>::to_vec)
}

/// POSITION plus the morph targets' displacements at the default weights (absent weights are 0).
fn at_default_morph_weights<'a, 's, F>(
    path: &Path,
    node: &gltf::Node,
    mesh: &gltf::Mesh,
    reader: &gltf::mesh::Reader<'a, 's, F>,
    mut positions: Vec<[f32; 3]>,
) -> Result<Vec<[f32; 3]>, InputError>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let weights = morph_weights(node, mesh);
    for (t, (displacements, _, _)) in reader.read_morph_targets().enumerate() {
        let w = weights.get(t).copied().unwrap_or(0.0);
        let Some(displacements) = displacements else {
            continue;
        };
        let displacements: Vec<[f32; 3]> = displacements.collect();
        if displacements.len() != positions.len() {
            return Err(bad(
                path,
                format!(
                    "mesh {}: morph target {t} has {} positions for {} vertices",
                    mesh.index(),
                    displacements.len(),
                    positions.len()
                ),
            ));
        }
        if w != 0.0 {
            for (p, d) in positions.iter_mut().zip(&displacements) {
                (0..3).for_each(|c| p[c] += w * d[c]);
            }
        }
    }
    Ok(positions)
}

/// World matrices of all nodes from local ones (parents before or after children).
fn world_matrices(parents: &[Option<usize>], local: &[DMat4]) -> Vec<DMat4> {
    let mut world: Vec<Option<DMat4>> = vec![None; local.len()];
    fn resolve(
        n: usize,
        parents: &[Option<usize>],
        local: &[DMat4],
        world: &mut [Option<DMat4>],
        depth: usize,
    ) -> DMat4 {
        if let Some(w) = world[n] {
            return w;
        }
        let w = match parents[n] {
            Some(p) if depth < parents.len() => {
                resolve(p, parents, local, world, depth + 1) * local[n]
            }
            _ => local[n],
        };
        world[n] = Some(w);
        w
    }
    (0..local.len())
        .map(|n| resolve(n, parents, local, &mut world, 0))
        .collect()
}

/// The key segment containing `time`: (k, s) with t_k ≤ time < t_k+1 and s ∈ [0, 1].
fn segment(times: &[f64], time: f64) -> (usize, f64) {
    if time <= times[0] + TIME_SLACK || times.len() == 1 {
        return (0, 0.0);
    }
    let last = times.len() - 1;
    if time >= times[last] - TIME_SLACK {
        return (last, 0.0);
    }
    let k = times.partition_point(|&t| t <= time + TIME_SLACK) - 1;
    let s = ((time - times[k]) / (times[k + 1] - times[k])).clamp(0.0, 1.0);
    (k, s)
}

fn hermite(s: f64) -> [f64; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    ]
}

fn sample_vec3(ch: &Channel, v: &[DVec3], time: f64) -> DVec3 {
    let (k, s) = segment(&ch.times, time);
    let next = (k + 1).min(ch.times.len() - 1);
    match ch.interpolation {
        Interpolation::Step => v[k],
        Interpolation::Linear => v[k].lerp(v[next], s),
        Interpolation::CubicSpline => {
            let dt = ch.times[next] - ch.times[k];
            let h = hermite(s);
            // Per key: in-tangent a, value v, out-tangent b.
            v[3 * k + 1] * h[0]
                + v[3 * k + 2] * (h[1] * dt)
                + v[3 * next + 1] * h[2]
                + v[3 * next] * (h[3] * dt)
        }
    }
}

fn sample_quat(ch: &Channel, q: &[DQuat], time: f64) -> DQuat {
    let (k, s) = segment(&ch.times, time);
    let next = (k + 1).min(ch.times.len() - 1);
    match ch.interpolation {
        Interpolation::Step => q[k].normalize(),
        Interpolation::Linear => q[k].normalize().slerp(q[next].normalize(), s),
        Interpolation::CubicSpline => {
            let dt = ch.times[next] - ch.times[k];
            let h = hermite(s);
            let v = DVec4::from(q[3 * k + 1]) * h[0]
                + DVec4::from(q[3 * k + 2]) * (h[1] * dt)
                + DVec4::from(q[3 * next + 1]) * h[2]
                + DVec4::from(q[3 * next]) * (h[3] * dt);
            DQuat::from_vec4(v).normalize()
        }
    }
}

/// The binary buffers: the .glb's BIN chunk, or files next to a .gltf.
pub(crate) fn load_buffers(path: &Path, gltf: &gltf::Gltf) -> Result<Vec<Vec<u8>>, InputError> {
    gltf.document
        .buffers()
        .map(|b| {
            let data = match b.source() {
                gltf::buffer::Source::Bin => {
                    gltf.blob.clone().ok_or_else(|| bad(path, format!("buffer {} refers to a missing GLB binary chunk", b.index())))?
                }
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    return Err(bad(path, format!("buffer {}: embedded data URIs are not supported; use .glb or external .bin files", b.index())))
                }
                gltf::buffer::Source::Uri(uri) => {
                    let file = path.parent().unwrap_or(Path::new(".")).join(uri);
                    std::fs::read(&file).map_err(|e| bad(&file, format!("buffer {} of {}: {e}", b.index(), path.display())))?
                }
            };
            if data.len() < b.length() {
                return Err(bad(path, format!("buffer {} is truncated: {} bytes, {} declared", b.index(), data.len(), b.length())));
            }
            Ok(data)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(interpolation: Interpolation, times: Vec<f64>, values: Vec<DVec3>) -> Channel {
        Channel {
            node: 0,
            property: Property::Translation,
            interpolation,
            times,
            values: Values::Vec3(values),
        }
    }

    #[test]
    fn step_holds_each_key_until_the_next() {
        let c = channel(
            Interpolation::Step,
            vec![0.0, 1.0 / 24.0, 2.0 / 24.0],
            vec![DVec3::X, DVec3::Y, DVec3::Z],
        );
        let Values::Vec3(v) = &c.values else {
            unreachable!()
        };
        // f32-rounded key times are still hit by f64 frame times.
        assert_eq!(sample_vec3(&c, v, (1.0f32 / 24.0) as f64 - 1e-7), DVec3::Y);
        assert_eq!(sample_vec3(&c, v, 1.5 / 24.0), DVec3::Y);
        assert_eq!(sample_vec3(&c, v, -1.0), DVec3::X);
        assert_eq!(sample_vec3(&c, v, 5.0), DVec3::Z);
    }

    #[test]
    fn linear_interpolates_and_slerps() {
        let c = channel(
            Interpolation::Linear,
            vec![0.0, 2.0],
            vec![DVec3::ZERO, DVec3::new(2.0, 4.0, 6.0)],
        );
        let Values::Vec3(v) = &c.values else {
            unreachable!()
        };
        assert!((sample_vec3(&c, v, 0.5) - DVec3::new(0.5, 1.0, 1.5)).length() < 1e-12);
        let qs = vec![DQuat::IDENTITY, DQuat::from_rotation_z(2.0)];
        let q = Channel {
            values: Values::Quat(qs.clone()),
            ..c.clone()
        };
        let r = sample_quat(&q, &qs, 0.5);
        assert!(
            r.angle_between(DQuat::from_rotation_z(0.5)) < 1e-9,
            "slerp: a quarter of the angle"
        );
    }

    #[test]
    fn cubic_spline_follows_the_hermite_curve_through_its_keys() {
        // x(t) = t³ on [0, 1]: values 0, 1; tangents 0 at 0 and 3 at 1 (per second).
        let values = vec![
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::X * 3.0,
            DVec3::X,
            DVec3::ZERO,
        ];
        let c = channel(Interpolation::CubicSpline, vec![0.0, 1.0], values);
        let Values::Vec3(v) = &c.values else {
            unreachable!()
        };
        for &t in &[0.0, 0.25, 0.5, 0.9, 1.0] {
            assert!(
                (sample_vec3(&c, v, t).x - t * t * t).abs() < 1e-12,
                "t = {t}"
            );
        }
    }
}
