//! A rig, whatever file it came from: the skinned rest mesh, the bones, the skin's own weights,
//! what takes a DCC's object space to the world, and the clip (`Clip`) that poses the bones.
//! `gltf_rig`, `fbx_rig` and `usd_rig` read one; `Rig::load` (in `import`) reads any by the
//! file.

use crate::set::Affine;
use glam::{DMat3, DMat4, DVec3};
use std::sync::Arc;

/// Key times are compared with this slack (seconds): STEP keys at i/24 s stored as f32 must
/// be hit by frame times computed in f64.
pub const TIME_SLACK: f64 = 1e-5;

/// A pose is the bind pose when every bone's transform is the identity to this (rotation
/// elements; translation relative to the mesh size).
const AT_BIND: f64 = 1e-4;

/// Whether `bones` (a pose's, relative to the rest pose) are at the bind pose, on a mesh of
/// diagonal `size`.
pub(crate) fn at_bind_pose(bones: &[Affine], size: f64) -> bool {
    (bones.iter())
        .all(|x| x.q.abs_diff_eq(DMat3::IDENTITY, AT_BIND) && x.d.length() <= AT_BIND * size)
}

#[derive(Debug, Clone)]
pub struct Rig {
    /// G rest positions in glTF order (primitives concatenated).
    pub rest: Vec<DVec3>,
    /// glTF triangles (indices into `rest`).
    pub triangles: Vec<[usize; 3]>,
    /// The vertices of each primitive, in file order.
    pub primitives: Vec<std::ops::Range<usize>>,
    /// J bone names (node names, or "joint N").
    pub names: Vec<String>,
    pub parents: Vec<Option<usize>>,
    /// Per glTF vertex, the skin's own (bone, weight) pairs (JOINTS_0/WEIGHTS_0, weight > 0,
    /// normalised): the baseline an engine skins with.
    pub weights: Vec<Vec<(usize, f64)>>,
    /// Per glTF vertex, TEXCOORD_0, if every primitive has it.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Per glTF vertex, TANGENT taken to the rest mesh like the positions (xyz through the
    /// default pose's blended joint matrix, renormalised; w as stored), if every primitive has
    /// it.
    pub tangents: Option<Vec<[f32; 4]>>,
    /// The skin's bind matrix `W_j(default) · IBM_j`, mesh space to world, when every joint has
    /// the same one (the mesh was bound at the default pose): what takes an object-space cache
    /// to the rig's world.
    pub bind: Option<DMat4>,
    /// Whether `rest` is the mesh before the DCC's deformers (UsdSkel's points: a DCC's shape
    /// keys are the stage's blend shapes, and what else it ran beside the skin, such as
    /// Blender's Corrective Smooth, is in no file), not the mesh it evaluates at the bind pose
    /// (an FBX exported with its modifiers applied): then the cache's sample at the bind pose,
    /// where it has one, is the rest the rig's motion starts from.
    pub base_mesh: bool,
    /// The skinned mesh node's world matrix at the default pose (the mesh object's transform in
    /// the DCC), unless it is the identity: what takes the DCC's object space to the world.
    pub mesh_world: Option<DMat4>,
    /// What the user should know about the file that is not an error (morph targets), a line
    /// each.
    pub notes: Vec<String>,
    /// How the clip poses the bones.
    pub(crate) motion: Arc<dyn Clip>,
}

/// How a rig's clip poses its bones: a glTF clip on the node tree (`gltf_rig`, played at any
/// time), or bones at sampled times ([`Sampled`]).
pub(crate) trait Clip: std::fmt::Debug + Send + Sync {
    /// The clip's key times (seconds), increasing, without repeats.
    fn key_times(&self) -> Vec<f64>;
    /// Whether the clip holds each key until the next (STEP): a series of poses.
    fn holds_keys(&self) -> bool;
    /// Every bone's transform at `time` (seconds) relative to the rest pose.
    fn bones_at(&self, time: f64) -> Vec<Affine>;
}

/// Bones at sampled times (an FBX stack, evaluated by ufbx at each frame): a time between
/// samples takes the nearest one.
#[derive(Debug, Clone)]
pub(crate) struct Sampled {
    pub times: Vec<f64>,
    pub bones: Vec<Vec<Affine>>,
}

impl Clip for Sampled {
    fn key_times(&self) -> Vec<f64> {
        self.times.clone()
    }

    fn holds_keys(&self) -> bool {
        false
    }

    fn bones_at(&self, time: f64) -> Vec<Affine> {
        let times = &self.times;
        let k = times.partition_point(|&t| t < time);
        let nearest = [k.saturating_sub(1), k.min(times.len() - 1)]
            .into_iter()
            .min_by(|&a, &b| (times[a] - time).abs().total_cmp(&(times[b] - time).abs()));
        nearest.map_or_else(Vec::new, |k| self.bones[k].clone())
    }
}

impl Rig {
    /// The clip's key times (seconds), increasing, without repeats (an FBX stack: its frames).
    pub fn key_times(&self) -> Vec<f64> {
        self.motion.key_times()
    }

    /// Whether the clip holds its keys (every glTF channel STEP): it is a series of poses.
    pub fn holds_keys(&self) -> bool {
        self.motion.holds_keys()
    }

    /// The rest mesh under the rig's own skin (linear blend skinning with its weights).
    pub fn skin(&self, bones: &[Affine]) -> Vec<DVec3> {
        (0..self.rest.len())
            .map(|v| self.skin_vertex(v, bones))
            .collect()
    }

    /// Vertex `v` of [`Rig::skin`].
    pub fn skin_vertex(&self, v: usize, bones: &[Affine]) -> DVec3 {
        if self.weights[v].is_empty() {
            return self.rest[v];
        }
        self.weights[v]
            .iter()
            .map(|&(b, w)| bones[b].apply(self.rest[v]) * w)
            .sum()
    }

    /// Every bone's transform at `time` (seconds) relative to the rest pose.
    pub fn bones_at(&self, time: f64) -> Vec<Affine> {
        self.motion.bones_at(time)
    }
}
