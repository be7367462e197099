//! The trained runtime model, as data, and its invariants.
//!
//! Letters: V vertices, T triangles, J bones, P keys (= proxy bones), K influences.
//! All matrices are stored row-major in `f32`.
//!
//! | field              | shape            | meaning                                              |
//! |--------------------|------------------|------------------------------------------------------|
//! | `rest_positions`   | V x 3            | rest mesh ŷ                                          |
//! | `triangles`        | T x 3            | corner indices into V (for normals)                  |
//! | `bone_parents`     | J                | parent bone, -1 for a root                           |
//! | `skin_indices`     | V x K            | palette entries: `< P` a proxy bone, `P + b` bone b  |
//! | `skin_weights`     | V x K            | blend weights, >= 0, summing to 1 per vertex          |
//! | `keys`             | P                | keys, each of one kind ([`Key`]): D_ℓ(q) (docs/method.md §2–3, §23) |
//! | `c1`               | 4P x 3P          | t_c = C1 d_c + C2 q_c (docs/method.md §8, paper Eq. 5) |
//! | `c2`               | 4P x 4J          |                                                      |
//! | `normal_groups`    | V or empty       | vertices sharing a normal (welded seams)             |
//! | `baseline_*`       | V x K or empty   | SSD skinning of the same mesh (bone indices, weights)|
//! | `animation`        | frames x J       | optional bone transforms to show the model with      |
//! | `rest_tangents`    | V x 4 or empty   | rest tangent xyz (unit) + handedness w = ±1 (glTF)   |
//! | `correctives`      | optional         | pose-space correctives (paper §8): N rest-space targets |
//! | `  .drivers`       | D                | driver bones (each with a parent, distinct)          |
//! | `  .map`           | N x 9D           | w = map · φ(q), φ = the drivers' R − I (see below)   |
//! | `  .targets`       | N x V x 3        | rest-space deltas, target-major (as glTF morph targets) |
//! | `proxy_correctives`| optional         | proxy correctives (docs/method.md §21): E corrected proxies |
//! | `  .centres`       | C x J x 9        | kernel centres z_cb = `centres[c J + b]` (C ≥ 0)      |
//! | `  .widths`        | J or empty       | kernel widths w_b (2σ²), > 0; empty when C = 0        |
//! | `  .proxies`       | E                | the corrected proxies, ascending, distinct, < P        |
//! | `  .driver_offsets`| E + 1            | CSR offsets into `drivers`                             |
//! | `  .drivers`       | Σ D_i            | driver joints of each corrected proxy                  |
//! | `  .up`            | 3 or none        | the model's up u, where the features see gravity       |
//! | `  .maps`          | Σ F_i x 12       | G_ef per feature f (F_i = D_i (9·linear + 3·gravity + C)) |
//!
//! Index conventions of the separable reconstruction (one identical system per row c = x, y, z):
//! `t_c[4b + j] = T_b[c][j]` (proxy transform b, 3x4), `q_c[4b + j] = Q_b[c][j]` (bone
//! transform b, 3x4), `d_c[3ℓ + j] = D_ℓ[c][j]` (key gradient ℓ, 3x3).
//! A model with P = 0 is plain linear blend skinning: every index points at a bone.
//!
//! Keys: each a key predictor (paper §3) or a delta-mush key (docs/method.md §23), in any
//! order ([`Key`]): proxy e reads whichever keys its C1 rows do.
//!
//! Pose-space correctives (paper §8, docs/method.md §20): for driver i, bone d = `drivers[i]`
//! with parent p, `R_i = rot(Q_p)ᵀ rot(Q_d)` (rot: the 3x3 of the bone transform, as
//! [`crate::predict::rotation_of`]) and `φ[9i + 3r + c] = R_i[r][c] − δ_rc`; the weights are
//! `w = map · φ` (N), and vertex a is skinned from `ŷ_a + Σ_n w_n targets[n V + a]` instead of
//! ŷ_a (normals follow from the positions; tangents and the rest normals do not see them).
//! 1 ≤ N ≤ [`MAX_CORRECTIVES`].
//!
//! Proxy correctives (docs/method.md §21): after the proxies `T_e = [M | t]` (3x4) of a
//! character are computed, each corrected proxy e is replaced by `T'_e = T_e (I + E_e)` =
//! `[M (I + A) | t + M b]`, `E_e = [A | b] = Σ_f x_f G_ef`, with the features x of its drivers
//! (see [`ProxyCorrectives`]); the palette keeps its P + J entries and skinning is unchanged.
//! They vanish at the rest pose (every bone the identity) of a character upright in the model's
//! frame, where T' = T exactly.

mod block_sparse;
mod file;
mod key;
mod validate;

pub(crate) use block_sparse::BlockSparse;
pub use file::{FORMAT_VERSION, MAGIC};
pub use key::{
    c1_in_key_frames, key_words, predictor_words, DeltaMushKey, DeltaMushTerm, Key, KeyKind,
    KeyPredictor, Mat3Rows, SecondBone, MAX_DELTA_MUSH_BONES, PREDICTOR_WORDS,
};

use crate::error::{Error, Result};

/// The most corrective targets a model may carry (N).
pub const MAX_CORRECTIVES: usize = 64;

/// Pose-space correctives (paper §8; docs/method.md §20): rest-space morph targets whose weights
/// are linear in the driver joints' rotations relative to their parents.
#[derive(Debug, Clone, PartialEq)]
pub struct Correctives {
    /// D driver joints, each with a parent (not a root), distinct.
    pub drivers: Vec<u32>,
    /// N x 9D, row-major: w = map · φ(q).
    pub map: Vec<f32>,
    /// N x V rest-space deltas (target-major, like glTF morph targets).
    pub targets: Vec<[f32; 3]>,
}

impl Correctives {
    /// D
    pub fn driver_count(&self) -> usize {
        self.drivers.len()
    }
}

/// The most kernel centres per joint a model's proxy correctives may carry (C): the GPU pass
/// loops over them per driver.
pub const MAX_PROXY_KERNELS: usize = 256;
/// The most drivers one corrected proxy may have (D_i): the GPU pass loops over them.
pub const MAX_PROXY_DRIVERS: usize = 32;

/// Proxy correctives (docs/method.md §21): per corrected proxy e (a proxy bone, < P), an affine
/// correction in the proxy's own rest frame, computed from the rotations of its driver joints:
///
/// `T'_e = T_e (I + E_e)`, `E_e = Σ_f x_f G_ef`; with `E_e = [A | b]` (A 3x3, b 3-vector) and
/// `T_e = [M | t]`, `T'_e = [M (I + A) | t + M b]`.
///
/// The features x of proxy e are, for its drivers b_1..b_D in order, concatenated per driver:
/// - if `linear`, the 9 values `φ_b = vec(R_b − I)` row-major, `φ[3r + c] = R_b[r][c] − δ_rc`,
///   `R_b = rot(Q_p)ᵀ rot(Q_b)` with p = parent(b) and rot the 3x3 of the bone transform (the
///   φ of the pose-space correctives, [`crate::predict::rotation_features`]);
/// - if `up` is the model's up u, the 3 values `γ_b = rot(Q_b)ᵀ u_c − u`: gravity seen from the
///   bone relative to rest, u_c the character's up in its bones' frame (u unless the caller
///   gives another: a character tilted by its object transform rather than its root bone;
///   [`crate::predict::gravity_features`]);
/// - then, for each kernel centre c in 0..C, `k = exp(−|φ_b − z_cb|² / w_b) − exp(−|z_cb|² / w_b)`,
///   with `z_cb = centres[c * J + b]` (9 floats, laid out as φ) and `w_b = widths[b]`;
///   |·|² is the sum of the squares of the 9 components.
///
/// Before any feature is computed, a driver's φ_b and γ_b are clamped, entry by entry, into
/// `ranges[b]` where the model has ranges: the box of the training poses' values, so that past
/// what the correctives were fitted on a driver acts as at the nearest point of its box (a
/// rigger's driver ramps clamp alike), never extrapolated.
///
/// So proxy i has `F_i = D_i (9·linear + 3·gravity + C)` features, and its map is F_i rows of 12
/// floats, row f being `G_ef = [A00 A01 A02 b0 A10 A11 A12 b1 A20 A21 A22 b2]`. Every feature is
/// zero at the rest pose of an upright character (φ = γ = 0 there), so the corrections vanish
/// exactly at rest.
///
/// Limits: 1 ≤ E ≤ P corrected proxies; D_i ≤ [`MAX_PROXY_DRIVERS`] drivers each (bones with a
/// parent, distinct within the proxy; none leaves the proxy as it is); C ≤ [`MAX_PROXY_KERNELS`];
/// at least one kind of feature; `up` of unit length; J ranges or none, each containing 0.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyCorrectives {
    /// Whether each driver contributes its 9 linear features φ_b.
    pub linear: bool,
    /// The model's up u (unit, in the bones' frame), where each driver contributes its 3
    /// gravity features γ_b after φ_b; None: the features do not see gravity.
    pub up: Option<[f32; 3]>,
    /// C x J kernel centres (z_cb = centres[c * J + b]); empty: no kernels (C = 0).
    pub centres: Vec<[f32; 9]>,
    /// J kernel widths w_b (2σ²); empty when C = 0.
    pub widths: Vec<f32>,
    /// J per-joint ranges the features are clamped into (`ranges[b]` for driver b); empty: not
    /// clamped (files before version 6).
    pub ranges: Vec<FeatureRange>,
    /// The corrected proxies, ascending, distinct, < P.
    pub proxies: Vec<u32>,
    /// proxies.len() + 1 offsets into `drivers` (CSR), starting at 0, non-decreasing.
    pub driver_offsets: Vec<u32>,
    /// Driver joints (each with a parent, < J, distinct within a proxy).
    pub drivers: Vec<u32>,
    /// Per corrected proxy i, F_i x 12 floats (F_i = D_i (9·linear + 3·gravity + C)),
    /// concatenated in proxy order.
    pub maps: Vec<f32>,
}

/// The range of one joint's proxy-corrective features (docs/method.md §21): entries 0..9 bound
/// φ_b (laid out as φ), 9..12 bound γ_b (0 where the features do not see gravity). `lower ≤ 0 ≤
/// upper` entry by entry, so the rest pose stays exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureRange {
    pub lower: [f32; 12],
    pub upper: [f32; 12],
}

impl FeatureRange {
    /// Clamps φ_b (`x` of 9) or γ_b (`x` of 3, `first` = 9) into the range, entry by entry (in
    /// f64 for the CPU reference, f32 for the palette).
    pub fn clamp<T: Copy + PartialOrd + From<f32>, const N: usize>(
        &self,
        x: &mut [T; N],
        first: usize,
    ) {
        for (k, x) in x.iter_mut().enumerate() {
            let (lo, hi) = (
                T::from(self.lower[first + k]),
                T::from(self.upper[first + k]),
            );
            if *x < lo {
                *x = lo;
            } else if *x > hi {
                *x = hi;
            }
        }
    }
}

impl ProxyCorrectives {
    /// C, the kernel centres per joint, of a model of `bones` joints (J).
    pub fn kernel_count(&self, bones: usize) -> usize {
        self.centres.len() / bones.max(1)
    }

    /// 9·linear + 3·gravity + C: the features of one driver.
    pub fn features_per_driver(&self, bones: usize) -> usize {
        9 * usize::from(self.linear) + 3 * usize::from(self.up.is_some()) + self.kernel_count(bones)
    }

    /// The drivers of corrected proxy i (`proxies[i]`).
    pub fn drivers_of(&self, i: usize) -> &[u32] {
        &self.drivers[self.driver_offsets[i] as usize..self.driver_offsets[i + 1] as usize]
    }

    /// The map of corrected proxy i: F_i x 12 floats, row f the G_ef of feature f.
    pub fn map_of(&self, i: usize, bones: usize) -> &[f32] {
        let per = 12 * self.features_per_driver(bones);
        let (a, b) = (self.driver_offsets[i], self.driver_offsets[i + 1]);
        &self.maps[per * a as usize..per * b as usize]
    }
}

/// Everything a model holds, unchecked. Turn it into a [`Model`] with [`Model::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct ModelParts {
    pub rest_positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub bone_parents: Vec<i32>,
    /// K: influences per vertex, 4 or 8.
    pub influences: u32,
    pub skin_indices: Vec<u32>,
    pub skin_weights: Vec<f32>,
    /// The P keys, each of one kind.
    pub keys: Vec<Key>,
    pub c1: Vec<f32>,
    pub c2: Vec<f32>,
    /// Empty, or V group ids (< V): vertices of one group share their normal, summed over the
    /// triangles around all of them. For meshes split along UV seams (glTF), so that the two
    /// sides of a seam do not shade apart. Empty: every vertex is its own group.
    pub normal_groups: Vec<u32>,
    /// Empty, or V x K bone indices (< J) and weights: plain linear blend skinning (SSD) of the
    /// same mesh, the baseline every engine has; see [`Model::baseline`].
    pub baseline_indices: Vec<u32>,
    pub baseline_weights: Vec<f32>,
    /// Empty, or frames x J bone transforms (3x4 row-major, relative to the rest pose): an
    /// animation to show the model with (the crowd sample, the demo).
    pub animation: Vec<crate::predict::Affine>,
    /// Empty, or V rest tangents: xyz a unit vector along the texture's +u, w = ±1 the sign of
    /// the bitangent `cross(n, t) * w` (glTF's TANGENT convention). Skinned per frame when a
    /// crowd asks for tangents ([`crate::vk::CrowdOptions::tangents`]).
    pub rest_tangents: Vec<[f32; 4]>,
    /// Pose-space correctives (paper §8; docs/method.md §20): rest-space morph targets whose weights
    /// are linear in the driver joints' rotations. None: no correctives.
    pub correctives: Option<Correctives>,
    /// Proxy correctives (docs/method.md §21): affine corrections of some proxies' transforms,
    /// from the rotations of their driver joints, applied before skinning. None: no correction.
    pub proxy_correctives: Option<ProxyCorrectives>,
}

impl ModelParts {
    /// P
    pub fn key_count(&self) -> usize {
        self.keys.len()
    }

    /// These parts with their delta-mush keys in their principal frames
    /// ([`DeltaMushKey::in_principal_frame`]) and C1 turned to match ([`c1_in_key_frames`]):
    /// the same model, whose keys' fits start from an exact guess for rigid motions. Files
    /// before version 7 stored the keys' terms unturned, for an exact polar rotation.
    pub fn in_key_frames(mut self) -> ModelParts {
        let frames: Vec<_> = (self.keys.iter_mut())
            .map(|key| match key {
                Key::DeltaMush(k) => {
                    let (turned, frame) = k.in_principal_frame();
                    *k = turned;
                    Some(frame)
                }
                Key::Predictor(_) => None,
            })
            .collect();
        c1_in_key_frames(&mut self.c1, &frames);
        self
    }
}

/// A validated runtime model. Immutable: every invariant in the module docs holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    parts: ModelParts,
    /// V + 1 offsets into `incident_triangles` (CSR): the triangles around each vertex, so
    /// normals are a gather with no atomics.
    incident_offsets: Vec<u32>,
    incident_triangles: Vec<u32>,
}

/// The bones 0..j in an order where every parent comes before its children, whatever order the
/// rig lists them in (glTF skins list joints freely); `parent(b)` is bone b's parent. A cycle
/// (which validated models and example sets never have) cannot loop: each walk up stops after
/// j steps.
pub fn parents_first(j: usize, parent: impl Fn(usize) -> Option<usize>) -> Vec<usize> {
    let mut placed = vec![false; j];
    let mut order = Vec::with_capacity(j);
    let mut chain = Vec::new();
    for b in 0..j {
        let mut at = Some(b);
        while let Some(a) = at.filter(|&a| !placed[a] && chain.len() < j) {
            chain.push(a);
            at = parent(a);
        }
        for &a in chain.iter().rev() {
            placed[a] = true;
            order.push(a);
        }
        chain.clear();
    }
    order
}

/// The influence counts the runtime has shaders for.
pub const SUPPORTED_INFLUENCES: [u32; 2] = [4, 8];

impl Model {
    /// Validates `parts` (dimensions, finite numbers, indices, weights, rotations, hierarchy).
    pub fn new(parts: ModelParts) -> Result<Model> {
        Self::with_origin(parts, "<parts>")
    }

    pub(crate) fn with_origin(parts: ModelParts, origin: &str) -> Result<Model> {
        validate::check(&parts).map_err(|problem| Error::BadModel {
            origin: origin.to_string(),
            problem,
        })?;
        let (incident_offsets, incident_triangles) = incidence(
            parts.rest_positions.len(),
            &parts.triangles,
            &parts.normal_groups,
        );
        Ok(Model {
            parts,
            incident_offsets,
            incident_triangles,
        })
    }

    /// Reads and validates a `.rrs` file. Errors name the file.
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Model> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Self::from_bytes_named(&bytes, &path.display().to_string())
    }

    /// Parses and validates a `.rrs` image held in memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Model> {
        Self::from_bytes_named(bytes, "<memory>")
    }

    fn from_bytes_named(bytes: &[u8], origin: &str) -> Result<Model> {
        let (parts, version) = file::decode(bytes).map_err(|problem| Error::BadModel {
            origin: origin.to_string(),
            problem,
        })?;
        let model = Self::with_origin(parts, origin)?;
        match version < file::KEY_FRAMES_VERSION && model.keys_of(KeyKind::DeltaMush) > 0 {
            // Valid, so every key's range is in bounds; turning it keeps it valid.
            true => Self::with_origin(model.into_parts().in_key_frames(), origin),
            false => Ok(model),
        }
    }

    /// The `.rrs` image of this model.
    pub fn to_bytes(&self) -> Vec<u8> {
        file::encode(&self.parts)
    }

    pub fn save(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        let path = path.as_ref();
        std::fs::write(path, self.to_bytes()).map_err(|e| Error::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    }

    pub fn parts(&self) -> &ModelParts {
        &self.parts
    }

    pub fn into_parts(self) -> ModelParts {
        self.parts
    }

    /// V
    pub fn vertex_count(&self) -> usize {
        self.parts.rest_positions.len()
    }

    /// T
    pub fn triangle_count(&self) -> usize {
        self.parts.triangles.len()
    }

    /// J
    pub fn bone_count(&self) -> usize {
        self.parts.bone_parents.len()
    }

    /// P (0: plain linear blend skinning).
    pub fn proxy_count(&self) -> usize {
        self.parts.key_count()
    }

    /// The P keys.
    pub fn keys(&self) -> &[Key] {
        &self.parts.keys
    }

    /// How many keys are of kind `kind`.
    pub fn keys_of(&self, kind: KeyKind) -> usize {
        self.parts.keys.iter().filter(|k| k.kind() == kind).count()
    }

    /// K
    pub fn influences(&self) -> usize {
        self.parts.influences as usize
    }

    /// The parent of bone `b`, if any.
    pub fn parent(&self, b: usize) -> Option<usize> {
        usize::try_from(self.parts.bone_parents[b]).ok()
    }

    /// CSR offsets (V + 1) and triangle ids of the triangles around each vertex.
    pub fn incidence(&self) -> (&[u32], &[u32]) {
        (&self.incident_offsets, &self.incident_triangles)
    }

    /// The rest mesh's unit area-weighted normals (V; welded seams share theirs), what
    /// transformed normals start from ([`crate::NormalMode::Transformed`]).
    pub fn rest_normals(&self) -> Vec<[f32; 3]> {
        let rest: Vec<glam::DVec3> = (self.parts.rest_positions.iter())
            .map(|p| glam::DVec3::from(p.map(f64::from)))
            .collect();
        let group = |v| self.normal_group(v);
        crate::normals::area_weighted_grouped(&rest, self.triangle_corners(), group)
            .iter()
            .map(|n| n.as_vec3().to_array())
            .collect()
    }

    /// The normal group of vertex `v` (a vertex index): vertices of one group share a normal
    /// (welded seams); `v` itself where the model has no groups.
    pub fn normal_group(&self, v: usize) -> usize {
        group_of(&self.parts.normal_groups, v)
    }

    /// The triangles' corners as `usize` indices.
    pub fn triangle_corners(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        (self.parts.triangles.iter()).map(|t| t.map(|i| i as usize))
    }

    /// The triangles around each vertex as 1-ring fans ([`crate::normals::Fans`]), pivoted in
    /// the vertex's normal group: what the GPU's recomputed-normals pass reads.
    pub fn normal_fans(&self) -> crate::normals::Fans {
        let group = |v: u32| self.normal_group(v as usize) as u32;
        let (offsets, incident) = self.incidence();
        crate::normals::Fans::new(&self.parts.triangles, offsets, incident, group)
    }

    /// Whether the model carries rest tangents (so crowds can output tangent frames).
    pub fn has_tangents(&self) -> bool {
        !self.parts.rest_tangents.is_empty()
    }

    /// N, the corrective targets (0 without correctives).
    pub fn corrective_count(&self) -> usize {
        match &self.parts.correctives {
            Some(c) => c.targets.len() / self.vertex_count(),
            None => 0,
        }
    }

    /// D, the corrective driver bones (0 without correctives).
    pub fn corrective_driver_count(&self) -> usize {
        self.parts
            .correctives
            .as_ref()
            .map_or(0, |c| c.drivers.len())
    }

    /// The model's pose-space correctives, if it has any.
    pub fn correctives(&self) -> Option<&Correctives> {
        self.parts.correctives.as_ref()
    }

    /// E, the proxies corrected by proxy correctives (0 without them).
    pub fn proxy_corrective_count(&self) -> usize {
        self.parts
            .proxy_correctives
            .as_ref()
            .map_or(0, |c| c.proxies.len())
    }

    /// The model's proxy correctives, if it has any.
    pub fn proxy_correctives(&self) -> Option<&ProxyCorrectives> {
        self.parts.proxy_correctives.as_ref()
    }

    /// The model's up where its proxy correctives see gravity (None: a character's up changes
    /// nothing): the default of a character's up vector.
    pub fn up(&self) -> Option<[f32; 3]> {
        self.proxy_correctives().and_then(|c| c.up)
    }

    /// The model's animation: frames of J bone transforms (empty if it carries none).
    pub fn animation(&self) -> impl Iterator<Item = &[crate::predict::Affine]> {
        self.parts.animation.chunks_exact(self.bone_count())
    }

    /// The model's SSD baseline as a plain linear-blend-skinning model (P = 0) of the same mesh,
    /// if the model carries one: what `rrskin bench` compares against.
    pub fn baseline(&self) -> Option<Model> {
        if self.parts.baseline_indices.is_empty() {
            return None;
        }
        let parts = ModelParts {
            skin_indices: self.parts.baseline_indices.clone(),
            skin_weights: self.parts.baseline_weights.clone(),
            keys: Vec::new(),
            c1: Vec::new(),
            c2: Vec::new(),
            baseline_indices: Vec::new(),
            baseline_weights: Vec::new(),
            correctives: None,
            proxy_correctives: None,
            ..self.parts.clone()
        };
        Model::new(parts).ok()
    }

    /// Row-major `[C1 | C2]`: 4P x (3P + 4J), the one matrix the GEMM pass multiplies by.
    pub fn c1_c2(&self) -> Vec<f32> {
        let (p, j) = (self.proxy_count(), self.bone_count());
        let mut out = Vec::with_capacity(4 * p * (3 * p + 4 * j));
        for r in 0..4 * p {
            out.extend_from_slice(&self.parts.c1[r * 3 * p..(r + 1) * 3 * p]);
            out.extend_from_slice(&self.parts.c2[r * 4 * j..(r + 1) * 4 * j]);
        }
        out
    }
}

/// Vertex `v`'s normal group in `groups` (V or empty: then `v` itself).
fn group_of(groups: &[u32], v: usize) -> usize {
    groups.get(v).map_or(v, |&g| g as usize)
}

/// Per-vertex incident-triangle lists (CSR): the triangles around each vertex's normal group
/// (around the vertex itself when `groups` is empty). Shape: offsets V + 1.
fn incidence(vertex_count: usize, triangles: &[[u32; 3]], groups: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let group = |v: usize| group_of(groups, v);
    // Triangles around each group (CSR over group ids).
    let mut count = vec![0u32; vertex_count + 1];
    for tri in triangles {
        for &v in tri {
            count[group(v as usize) + 1] += 1;
        }
    }
    for g in 0..vertex_count {
        count[g + 1] += count[g];
    }
    let mut fill = count.clone();
    let mut by_group = vec![0u32; count[vertex_count] as usize];
    for (k, tri) in triangles.iter().enumerate() {
        for &v in tri {
            let g = group(v as usize);
            by_group[fill[g] as usize] = k as u32;
            fill[g] += 1;
        }
    }
    // Each vertex gets its group's list.
    let mut offsets = Vec::with_capacity(vertex_count + 1);
    let mut list = Vec::with_capacity(by_group.len());
    offsets.push(0);
    for v in 0..vertex_count {
        let g = group(v);
        list.extend_from_slice(&by_group[count[g] as usize..count[g + 1] as usize]);
        offsets.push(list.len() as u32);
    }
    (offsets, list)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incidence_lists_every_corner_once() {
        let (off, list) = incidence(4, &[[0, 1, 2], [0, 2, 3]], &[]);
        assert_eq!(off, vec![0, 2, 3, 5, 6]);
        assert_eq!(list, vec![0, 1, 0, 0, 1, 1]);
    }

    #[test]
    fn grouped_vertices_share_every_triangle_of_their_group() {
        // Vertices 1 and 4 are one seam vertex split in two.
        let (off, list) = incidence(5, &[[0, 1, 2], [4, 3, 2]], &[0, 1, 2, 3, 1]);
        assert_eq!(&list[off[1] as usize..off[2] as usize], &[0, 1]);
        assert_eq!(&list[off[4] as usize..off[5] as usize], &[0, 1]);
        assert_eq!(&list[off[0] as usize..off[1] as usize], &[0]);
    }
}
