//! Synthetic models and poses: valid models of any size without training, for tests,
//! benchmarks and profiling the runtime at chosen V, J, P and K.
//!
//! The mesh is a bumpy grid; bones form a random tree whose parents precede their children
//! ([`renumber_bones`] gives any other order);
//! skinning weights fall off smoothly with distance to random palette "centres" (so the deformed
//! mesh stays well-conditioned and normals are comparable between f32 and f64); each proxy
//! follows one bone through C2 plus a small key-gradient correction through C1; predictors have
//! random bones, scales, rotations, second bones and scale/shear matrices near identity. Rest
//! tangents follow the grid's texture coordinates (u, v) = (x, y), mirrored in u on the right
//! half (tangent −∂p/∂u, handedness −1), as mirrored UV islands are.

use glam::{DMat3, DVec3};
use rrskin::predict::{exp_rotation, Affine};
use rrskin::{DeltaMushKey, DeltaMushTerm, Key, KeyPredictor, SecondBone};
use rrskin::{Error, Model, ModelParts, ModelProblem, Result};

/// xorshift64*: deterministic, no dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn vec3(&mut self, scale: f64) -> DVec3 {
        DVec3::new(
            self.range(-scale, scale),
            self.range(-scale, scale),
            self.range(-scale, scale),
        )
    }
    /// A rotation of angle at most `max_angle`.
    pub fn rotation(&mut self, max_angle: f64) -> DMat3 {
        let axis = loop {
            let v = self.vec3(1.0);
            if v.length() > 0.1 {
                break v.normalize();
            }
        };
        exp_rotation(axis * self.range(0.0, max_angle))
    }
}

/// A rotation as the row-major array a model stores.
pub fn rows(m: DMat3) -> [f32; 9] {
    m.transpose().to_cols_array().map(|x| x as f32)
}

/// What to generate.
#[derive(Debug, Clone, Copy)]
pub struct Spec {
    /// Vertices = grid x grid, triangles = 2 (grid - 1)².
    pub grid: usize,
    pub bones: usize,
    pub proxies: usize,
    pub influences: u32,
}

/// A random valid model (see the module docs). Errors only for impossible specs (e.g. K not
/// 4 or 8, grid < 2).
pub fn random_model(spec: Spec, seed: u64) -> Result<Model> {
    for (what, value, min) in [("grid", spec.grid, 2), ("bones", spec.bones, 1)] {
        if value < min {
            let problem = ModelProblem::Dimension {
                what,
                value: value as u64,
                reason: "too small",
            };
            return Err(Error::BadModel {
                origin: "<synthetic>".into(),
                problem,
            });
        }
    }
    let mut rng = Rng::new(seed);
    let (n, j, p) = (spec.grid, spec.bones, spec.proxies);
    let k = spec.influences as usize;
    let mut rest = Vec::with_capacity(n * n);
    let mut rest_tangents = Vec::with_capacity(n * n);
    for y in 0..n {
        for x in 0..n {
            let (u, v) = (x as f64 / (n - 1) as f64, y as f64 / (n - 1) as f64);
            rest.push([
                u as f32,
                v as f32,
                (0.1 * (6.0 * u).sin() * (4.0 * v).cos()) as f32,
            ]);
            let along_u = DVec3::new(1.0, 0.0, 0.6 * (6.0 * u).cos() * (4.0 * v).cos());
            let w = if 2 * x > n { -1.0 } else { 1.0 };
            let t = (along_u.normalize() * w).as_vec3();
            rest_tangents.push([t.x, t.y, t.z, w as f32]);
        }
    }
    let mut triangles = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let a = (y * n + x) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let bone_parents: Vec<i32> = (0..j)
        .map(|b| if b == 0 { -1 } else { rng.below(b) as i32 })
        .collect();
    // Palette entries live at random centres; weights fall off with distance.
    let entries = p + j;
    let centres: Vec<[f64; 2]> = (0..entries).map(|_| [rng.unit(), rng.unit()]).collect();
    let mut skin_indices = Vec::with_capacity(n * n * k);
    let mut skin_weights = Vec::with_capacity(n * n * k);
    for r in &rest {
        let mut by_distance: Vec<(f64, usize)> = centres
            .iter()
            .enumerate()
            .map(|(i, c)| {
                (
                    (c[0] - r[0] as f64).powi(2) + (c[1] - r[1] as f64).powi(2),
                    i,
                )
            })
            .collect();
        by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
        let used = k.min(entries);
        let raw: Vec<f64> = by_distance[..used]
            .iter()
            .map(|(d2, _)| 1.0 / (d2 + 0.02))
            .collect();
        let total: f64 = raw.iter().sum();
        for i in 0..k {
            if i < used {
                skin_indices.push(by_distance[i].1 as u32);
                skin_weights.push((raw[i] / total) as f32);
            } else {
                skin_indices.push(0);
                skin_weights.push(0.0);
            }
        }
    }
    let keys = (0..p)
        .map(|_| Key::Predictor(random_predictor(&mut rng, j)))
        .collect();
    let mut c1 = vec![0.0f32; 4 * p * 3 * p];
    for x in c1.iter_mut() {
        *x = rng.range(-0.05, 0.05) as f32;
    }
    let mut c2 = vec![0.0f32; 4 * p * 4 * j];
    for b in 0..p {
        let follow = rng.below(j);
        for r in 0..4 {
            c2[(4 * b + r) * 4 * j + 4 * follow + r] = 1.0;
        }
    }
    let parts = ModelParts {
        rest_positions: rest,
        triangles,
        bone_parents,
        influences: spec.influences,
        skin_indices,
        skin_weights,
        keys,
        c1,
        c2,
        normal_groups: Vec::new(),
        baseline_indices: Vec::new(),
        baseline_weights: Vec::new(),
        animation: Vec::new(),
        rest_tangents,
        correctives: None,
        proxy_correctives: None,
    };
    Model::new(parts)
}

/// A key predictor of a random bone of J, with a random scale, rotation and second bone (half
/// the time), and a scale/shear map H near the identity's.
fn random_predictor(rng: &mut Rng, j: usize) -> KeyPredictor {
    let mut h = [0.0f32; 63];
    for (i, x) in h.iter_mut().enumerate() {
        *x = rng.range(-0.1, 0.1) as f32;
        if i % 7 == 6 && [0, 4, 8].contains(&(i / 7)) {
            *x += 1.0; // bias column ≈ vec(I)
        }
    }
    let second = (rng.unit() < 0.5).then(|| SecondBone {
        bone: rng.below(j) as u32,
        u: rng.range(-1.0, 1.0) as f32,
        w: rows(rng.rotation(3.0)),
    });
    KeyPredictor {
        bone: rng.below(j) as u32,
        u: rng.range(-1.5, 1.5) as f32,
        w: rows(rng.rotation(3.0)),
        second,
        h,
    }
}

/// `model` with `keys` of its P keys made delta-mush keys ([`rrskin::DeltaMushKey`]), spread
/// among the predictors (keys ⌊i P / keys⌋, so that the kinds interleave): each a rigid fit of
/// 1 to 6 distinct random bones, bone i's term `Ω_i = w_i [I + N_i; c_iᵀ]` (4x3, rows) with a
/// weight w_i in [0.1, 1], a small random N_i and a random centre c_i, as a group's smoothed
/// weights give. Errors if `keys` exceeds P.
pub fn with_delta_mush_keys(model: &Model, keys: usize, seed: u64) -> Result<Model> {
    let mut parts = model.parts().clone();
    let p = parts.keys.len();
    if keys > p {
        return Err(Error::OutOfRange {
            what: "delta-mush keys (more than the model's keys)",
            index: keys,
            count: p,
        });
    }
    let mut rng = Rng::new(seed ^ 0x00D0_3A54);
    let j = model.bone_count();
    for i in 0..keys {
        let mut terms: Vec<DeltaMushTerm> = Vec::new();
        for _ in 0..1 + rng.below(6.min(j)) {
            let bone = rng.below(j) as u32;
            if terms.iter().any(|t| t.bone == bone) {
                continue;
            }
            let w = rng.range(0.1, 1.0);
            let (n, c) = (
                DMat3::IDENTITY
                    + DMat3::from_cols_array(&[0.0; 9].map(|_: f64| rng.range(-0.3, 0.3))),
                rng.vec3(0.5),
            );
            let t = rows(n);
            let omega = [
                t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], c.x as f32, c.y as f32,
                c.z as f32,
            ]
            .map(|x| x * w as f32);
            terms.push(DeltaMushTerm { bone, omega });
        }
        parts.keys[i * p / keys] = Key::DeltaMush(DeltaMushKey { terms });
    }
    Model::new(parts)
}

/// C random poses: per bone a local rotation of at most 2 rad (joint rotations stay away from
/// the log's branch cut at π) composed down the hierarchy, and a random translation. Any joint
/// order works: parents may come after their children (as in many glTF skins).
pub fn random_poses(model: &Model, characters: usize, seed: u64) -> Vec<Affine> {
    let mut rng = Rng::new(seed ^ 0xB0E5);
    let j = model.bone_count();
    let order = rrskin::model::parents_first(model.bone_count(), |b| model.parent(b));
    let mut out = Vec::with_capacity(characters * j);
    for _ in 0..characters {
        let local: Vec<(DMat3, DVec3)> =
            (0..j).map(|_| (rng.rotation(2.0), rng.vec3(0.5))).collect();
        let mut world = vec![DMat3::IDENTITY; j];
        for &b in &order {
            world[b] = model
                .parent(b)
                .map_or(local[b].0, |p| world[p] * local[b].0);
        }
        out.extend(world.iter().zip(&local).map(|(q, (_, d))| {
            let r = rows(*q);
            [
                r[0], r[1], r[2], d.x as f32, r[3], r[4], r[5], d.y as f32, r[6], r[7], r[8],
                d.z as f32,
            ]
        }));
    }
    out
}

/// `model` with its bones renumbered: bone b becomes bone `new_index[b]` (parents, skinning and
/// baseline indices, predictor bones, C2's columns, the animation, both correctives' drivers and
/// the proxy correctives' per-bone data follow), so that it
/// deforms exactly as before for poses renumbered the same way. With `new_index` = J−1, …, 0 on
/// a generated model every parent comes after its children. Errors if `new_index` is not a
/// permutation of 0..J.
pub fn renumber_bones(model: &Model, new_index: &[usize]) -> Result<Model> {
    let j = model.bone_count();
    if new_index.len() != j {
        return Err(Error::WrongLength {
            what: "new bone indices",
            expected: j,
            actual: new_index.len(),
        });
    }
    let mut seen = vec![false; j];
    for (b, &n) in new_index.iter().enumerate() {
        if n >= j || std::mem::replace(&mut seen[n], true) {
            return Err(Error::OutOfRange {
                what: "new bone index (not a permutation of the bones)",
                index: b,
                count: j,
            });
        }
    }
    let p = model.proxy_count();
    let bone = |b: u32| new_index[b as usize] as u32;
    let mut parts = model.parts().clone();
    for (b, parent) in model.parts().bone_parents.iter().enumerate() {
        parts.bone_parents[new_index[b]] = match usize::try_from(*parent) {
            Ok(q) => new_index[q] as i32,
            Err(_) => -1,
        };
    }
    // Palette entries: < P a proxy bone, P + b bone b.
    for i in parts.skin_indices.iter_mut().filter(|i| **i as usize >= p) {
        *i = p as u32 + bone(*i - p as u32);
    }
    for i in parts.baseline_indices.iter_mut() {
        *i = bone(*i);
    }
    for key in parts.keys.iter_mut() {
        match key {
            Key::Predictor(pred) => {
                pred.bone = bone(pred.bone);
                if let Some(second) = pred.second.as_mut() {
                    second.bone = bone(second.bone);
                }
            }
            Key::DeltaMush(k) => k.terms.iter_mut().for_each(|t| t.bone = bone(t.bone)),
        }
    }
    // C2: 4P x 4J, columns 4b..4b+4 belong to bone b.
    for (row, old) in parts
        .c2
        .chunks_exact_mut(4 * j)
        .zip(model.parts().c2.chunks_exact(4 * j))
    {
        for (b, cols) in old.chunks_exact(4).enumerate() {
            row[4 * new_index[b]..4 * new_index[b] + 4].copy_from_slice(cols);
        }
    }
    for (frame, old) in parts
        .animation
        .chunks_exact_mut(j)
        .zip(model.parts().animation.chunks_exact(j))
    {
        for (b, t) in old.iter().enumerate() {
            frame[new_index[b]] = *t;
        }
    }
    // The correctives' drivers (their maps' columns follow the drivers' order, kept).
    if let Some(c) = parts.correctives.as_mut() {
        c.drivers.iter_mut().for_each(|d| *d = bone(*d));
    }
    if let (Some(c), Some(old)) = (
        parts.proxy_correctives.as_mut(),
        model.parts().proxy_correctives.as_ref(),
    ) {
        c.drivers.iter_mut().for_each(|d| *d = bone(*d));
        // Kernel centres C x J, widths J and feature ranges J are per bone.
        for (row, old) in c
            .centres
            .chunks_exact_mut(j)
            .zip(old.centres.chunks_exact(j))
        {
            for (b, z) in old.iter().enumerate() {
                row[new_index[b]] = *z;
            }
        }
        for (b, w) in old.widths.iter().enumerate() {
            c.widths[new_index[b]] = *w;
        }
        for (b, r) in old.ranges.iter().enumerate() {
            c.ranges[new_index[b]] = *r;
        }
    }
    Model::new(parts)
}

/// What [`palette_error`] may be: `f32` round-off (measured about 2e-7 on the tests' synthetic
/// models), with a tenfold margin. A 0.1 % error in the key gradients gives 2e-4.
pub const PALETTE_TOLERANCE: f32 = 2e-6;

/// The largest distance, relative to `max(1, |p|)`, between positions skinned from the CPU
/// palette ([`rrskin::palette::Palette`], `f32`) and the CPU reference evaluator's (`f64`), over
/// C characters of `bones` (C x J): what the palette tests compare with their tolerance.
pub fn palette_error(model: &Model, bones: &[Affine]) -> Result<f32> {
    let palette = rrskin::palette::Palette::new(model.clone())?;
    let (v, j, n) = (model.vertex_count(), model.bone_count(), palette.len());
    let characters = bones.len() / j;
    let mut entries = vec![[0.0; 12]; characters * n];
    palette.compute_batch(bones, &mut entries)?;
    let (mut want, mut normals) = (
        vec![[0.0; 3]; characters * v],
        vec![[0.0; 3]; characters * v],
    );
    rrskin::cpu::CpuEvaluator::new(model).evaluate(bones, &mut want, &mut normals)?;
    let mut weights = vec![0.0; characters * palette.corrective_count()];
    palette.corrective_weights_batch(bones, &mut weights)?;
    let mut got = vec![[0.0; 3]; v];
    let mut worst = 0.0f32;
    let per = palette.corrective_count();
    for (c, entries) in entries.chunks_exact(n).enumerate() {
        let w = &weights[c * per..(c + 1) * per];
        palette.skin_positions(entries, w, &mut got)?;
        for (g, w) in got.iter().zip(&want[c * v..(c + 1) * v]) {
            let d = (0..3).map(|i| (g[i] - w[i]).powi(2)).sum::<f32>().sqrt();
            let size = (0..3).map(|i| w[i] * w[i]).sum::<f32>().sqrt().max(1.0);
            worst = worst.max(d / size);
        }
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rrskin::cpu::CpuEvaluator;
    use rrskin::predict::rotation_of;

    /// A generated model with its bones renumbered J−1, …, 0: every parent after its children.
    fn children_first() -> (Model, Model) {
        let spec = Spec {
            grid: 6,
            bones: 12,
            proxies: 5,
            influences: 4,
        };
        let model = random_model(spec, 4).expect("valid spec");
        let reversed: Vec<usize> = (0..spec.bones).rev().collect();
        let renumbered = renumber_bones(&model, &reversed).expect("a permutation");
        (model, renumbered)
    }

    #[test]
    fn parents_come_first_in_the_order_of_a_children_first_rig() {
        let (_, model) = children_first();
        let order = rrskin::model::parents_first(model.bone_count(), |b| model.parent(b));
        let mut position = vec![usize::MAX; model.bone_count()];
        for (i, &b) in order.iter().enumerate() {
            position[b] = i;
        }
        assert!(position.iter().all(|&i| i < order.len()), "every bone once");
        for b in 0..model.bone_count() {
            if let Some(p) = model.parent(b) {
                assert!(p > b, "the rig lists bone {b} before its parent {p}");
                assert!(position[p] < position[b], "parent {p} after child {b}");
            }
        }
    }

    #[test]
    fn random_poses_compose_down_a_children_first_hierarchy() {
        let (_, model) = children_first();
        let poses = random_poses(&model, 3, 8);
        let j = model.bone_count();
        assert_eq!(poses.len(), 3 * j);
        for pose in poses.chunks_exact(j) {
            for b in 0..j {
                if let Some(p) = model.parent(b) {
                    // The joint's own rotation, Q_pᵀ Q_b, is the local one drawn (≤ 2 rad).
                    let local = rotation_of(&pose[p]).transpose() * rotation_of(&pose[b]);
                    let angle = ((local.x_axis.x + local.y_axis.y + local.z_axis.z - 1.0) / 2.0)
                        .clamp(-1.0, 1.0)
                        .acos();
                    assert!(angle <= 2.0 + 1e-4, "bone {b}: local angle {angle}");
                }
            }
        }
    }

    #[test]
    fn renumbered_bones_deform_as_before() {
        let (model, renumbered) = children_first();
        let j = model.bone_count();
        let poses = random_poses(&model, 2, 3);
        let moved: Vec<Affine> = poses
            .chunks_exact(j)
            .flat_map(|pose| (0..j).map(move |b| pose[j - 1 - b]))
            .collect();
        let deform = |m: &Model, bones: &[Affine]| {
            let n = 2 * m.vertex_count();
            let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
            CpuEvaluator::new(m)
                .evaluate(bones, &mut p, &mut nrm)
                .expect("CPU evaluation");
            (p, nrm)
        };
        // Equal but for the order of C2's sums (column order follows the bones).
        let (before, after) = (deform(&model, &poses), deform(&renumbered, &moved));
        for (x, y) in [(&before.0, &after.0), (&before.1, &after.1)] {
            let worst = x
                .as_flattened()
                .iter()
                .zip(y.as_flattened())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(worst <= 1e-5, "differs by {worst}");
        }
    }

    #[test]
    fn renumbering_needs_a_permutation() {
        let (model, _) = children_first();
        let mut twice: Vec<usize> = (0..model.bone_count()).collect();
        twice[1] = 0;
        assert!(matches!(
            renumber_bones(&model, &twice),
            Err(Error::OutOfRange { index: 1, .. })
        ));
        assert!(matches!(
            renumber_bones(&model, &[0]),
            Err(Error::WrongLength { .. })
        ));
    }
}
