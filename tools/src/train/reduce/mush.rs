//! Delta-mush proxies (docs/method.md §23): P proxy bones whose transforms are Direct Delta
//! Mush's rigid fits ([`crate::skinning::ddm`]) for whole groups of vertices, and K-influence
//! palette skinning over them; the runtime model of the delta-mush keys ([`rrskin::MushKeys`],
//! [`MushProxies::to_runtime`]) where [`crate::train::delta_mush`] keeps them.
//!
//! A smoothing rig (Blender's Corrective Smooth, Delta Mush) moves a vertex by a rigid fit of
//! the bone motions of a whole neighbourhood of the mesh: on the Fox, about 11 bones reach each
//! vertex, and Direct Delta Mush with Ω cut to a vertex's 4 heaviest bones loses 6 EE points
//! held out. Joint-blend proxies turn about one joint each, and a vertex blends at most K of
//! them. Here each proxy is itself the rigid fit over every bone its group's Ω holds:
//!
//! - groups: the vertex reduction's greedy merging of contiguous triangles (paper §5.1,
//!   [`merge_groups`]) on the training poses, P groups;
//! - Ω_g = Σ_a s_ag Ω_a, s_ag the share of vertex a's incident triangles in group g, bones
//!   below [`FLOOR`] of the group's mass left out (and past the runtime's 256 heaviest);
//! - per pose, T_g = [`Ddm::motions`]: `Q_g = Σ_j M_j Ω_gj`, the rotation nearest to its
//!   covariance part, and the translation that keeps the group's smoothed centre;
//! - per vertex, NNLS weights (at most K, Σ = 1) over its own groups, the adjacent ones and its
//!   SSD bones (the runtime palette holds the J bones after the P proxies), fitted on the
//!   training poses (best subset, as SSD's and the vertex reduction's). Where the rig does not
//!   smooth, the bones carry the vertex; without them the Fox with 5 smoothing iterations was
//!   48.6 % EE held out, with them 41.6 %.
//!
//! Nothing else is fitted to the poses: no predictor, no refit, no stretch. Run-time cost per
//! character: P rigid fits of about `mean_bones` bones each (36 multiply-adds a bone and a
//! 3x3 rotation fit a proxy, once per character), then the palette skinning of any model.

use crate::set::{Affine, ExampleSet};
use crate::skinning::ddm::Ddm;
use crate::train::reduce::c1c2::runtime_parts;
use crate::train::reduce::vertex::{merge_groups, Stop};
use crate::train::ssd::fit_weights_best_subset;
use glam::DVec3;
use rayon::prelude::*;

/// A group's bones carrying less than this share of its Ω's mass are left out of its fit.
pub const FLOOR: f64 = 1e-3;

/// P delta-mush proxies and the vertices' weights over them.
pub struct MushProxies {
    /// P groups' Ω.
    pub proxies: Ddm,
    /// Per vertex (V): (palette entry, weight), at most K, summing to 1 (empty: a vertex on no
    /// triangle, left at rest); entries below P are proxies, P + b bone b.
    pub weights: Vec<Vec<(usize, f64)>>,
}

/// The proxies' vertex groups: P groups of contiguous triangles.
pub struct Groups {
    /// Per vertex (V): (group, share) over the groups of its incident triangles, shares summing
    /// to 1 (empty for a vertex on no triangle).
    pub shares: Vec<Vec<(usize, f64)>>,
    /// Per group (P): the contiguous groups.
    pub adjacency: Vec<Vec<usize>>,
}

impl Groups {
    /// The vertex reduction's greedy merging ([`merge_groups`]) to `proxies` groups on the
    /// poses `train` of `set`.
    pub fn merge(set: &ExampleSet, train: &[usize], proxies: usize) -> Groups {
        let stop = Stop {
            proxies,
            epsilon: None,
        };
        let (triangle_group, adjacency) = merge_groups(set, train, stop);
        Groups {
            shares: vertex_shares(set, &triangle_group),
            adjacency,
        }
    }
}

impl MushProxies {
    /// Fits K = `influences` weights on the poses `train` of `set` for the proxies of `groups`,
    /// from the per-vertex Ω `vertex_ddm` (V entries: Direct Delta Mush with SSD's weights) and
    /// SSD's (bone, weight) lists `bones` (V), whose bones are each vertex's candidates too.
    pub fn fit(
        set: &ExampleSet,
        train: &[usize],
        vertex_ddm: &Ddm,
        bones: &[Vec<(usize, f64)>],
        groups: &Groups,
        influences: usize,
    ) -> MushProxies {
        let (shares, adjacency) = (&groups.shares, &groups.adjacency);
        let cap = rrskin::model::MAX_MUSH_BONES;
        let groups = vertex_ddm.grouped(shares, adjacency.len(), FLOOR, cap);
        let p = adjacency.len();
        let motions: Vec<Vec<Affine>> = (train.iter())
            .map(|&i| palette(&groups, &set.poses[i].bones))
            .collect();
        let weights = (0..set.vertex_count())
            .into_par_iter()
            .map(|a| {
                let mut candidates: Vec<usize> = (shares[a].iter())
                    .flat_map(|&(g, _)| std::iter::once(g).chain(adjacency[g].iter().copied()))
                    .collect();
                candidates.extend(bones[a].iter().map(|&(b, _)| p + b));
                candidates.sort_unstable();
                candidates.dedup();
                let moved = |n: usize, g: usize| motions[n][g].apply(set.rest[a]);
                let target = |n: usize| set.poses[train[n]].vertices[a];
                fit_weights_best_subset(train.len(), &candidates, influences, moved, target)
            })
            .collect();
        MushProxies {
            proxies: groups,
            weights,
        }
    }

    /// The runtime model (f32) of these proxies, K = `influences`, with SSD's (bone, weight)
    /// lists `baseline` as its baseline: P delta-mush keys ([`rrskin::MushKeys`]), proxy g's
    /// transform `T_g = [D_g | Σ_j M_j ω_j − D_g p_g]` ([`Ddm::linear_fit`]) through C1 (its
    /// key's D, and −p) and C2 (the ω_j), in docs/method.md §8's index convention.
    pub fn to_runtime(
        &self,
        set: &ExampleSet,
        influences: usize,
        baseline: &[Vec<(usize, f64)>],
    ) -> rrskin::Result<rrskin::Model> {
        let (p, j) = (self.proxies.entries(), set.bone_count());
        let (mut c1, mut c2) = (vec![0.0f32; 12 * p * p], vec![0.0f32; 16 * p * j]);
        let (mut offsets, mut bones, mut terms) = (vec![0u32], Vec::new(), Vec::new());
        for g in 0..p {
            (0..3).for_each(|k| c1[(4 * g + k) * 3 * p + 3 * g + k] = 1.0);
            let Some(fit) = self.proxies.linear_fit(g) else {
                // No weight: at rest, as `Ddm::motions` leaves it (D = polar(0) = I).
                bones.push(0);
                terms.push([0.0; 12]);
                offsets.push(bones.len() as u32);
                continue;
            };
            for (b, a, omega) in &fit.terms {
                bones.push(*b as u32);
                terms.push(std::array::from_fn(|i| a[i / 3][i % 3] as f32));
                for (m, w) in omega.iter().enumerate() {
                    c2[(4 * g + 3) * 4 * j + 4 * b + m] = *w as f32;
                }
            }
            for k in 0..3 {
                c1[(4 * g + 3) * 3 * p + 3 * g + k] = -fit.centre[k] as f32;
            }
            offsets.push(bones.len() as u32);
        }
        rrskin::Model::new(rrskin::ModelParts {
            c1,
            c2,
            mush_keys: Some(rrskin::MushKeys {
                offsets,
                bones,
                terms,
            }),
            ..runtime_parts(set, influences, &self.weights, baseline)
        })
    }

    /// The mesh (V) under `bones` (J).
    pub fn deform(&self, rest: &[DVec3], bones: &[Affine]) -> Vec<DVec3> {
        let motions = palette(&self.proxies, bones);
        (rest.iter().zip(&self.weights))
            .map(|(&x, w)| match w.is_empty() {
                true => x,
                false => w.iter().map(|&(g, s)| motions[g].apply(x) * s).sum(),
            })
            .collect()
    }
}

/// The palette of a pose (P + J): the P proxies' motions, then the J `bones`.
fn palette(proxies: &Ddm, bones: &[Affine]) -> Vec<Affine> {
    let mut out = proxies.motions(bones);
    out.extend_from_slice(bones);
    out
}

/// Per vertex (V): (group, share) over the groups of its incident triangles, shares summing to
/// 1 (empty for a vertex on no triangle).
fn vertex_shares(set: &ExampleSet, triangle_group: &[usize]) -> Vec<Vec<(usize, f64)>> {
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); set.vertex_count()];
    for (face, &g) in set.faces.iter().zip(triangle_group) {
        face.iter().for_each(|&a| incident[a].push(g));
    }
    (incident.into_iter())
        .map(|groups| {
            let share = 1.0 / groups.len().max(1) as f64;
            let mut out: Vec<(usize, f64)> = Vec::new();
            for g in groups {
                match out.iter_mut().find(|(h, _)| *h == g) {
                    Some((_, s)) => *s += share,
                    None => out.push((g, share)),
                }
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder_chain::Chain;
    use crate::skinning::ddm::Params;
    use crate::skinning::lbs::Skinning;
    use crate::train::ssd;
    use glam::DMat3;

    /// A chain of `bones` bones, its SSD (K = 4) and `groups` delta-mush proxies over Ω of
    /// `iterations` smoothing steps, fitted to its training poses.
    fn fitted(
        bones: usize,
        groups: usize,
        iterations: usize,
    ) -> (ExampleSet, Skinning, MushProxies) {
        let chain = Chain {
            rings: 12,
            segments: 8,
            bones,
            poses: 12,
        };
        let set = chain.build().expect("a valid chain");
        let train = set.train();
        let errors = crate::skinning::lbs::rigid_errors(&set, &train);
        let skin = ssd::fit(&set, &train, &errors, 4);
        let params = Params {
            iterations,
            lambda: 3.0,
            kappa: 1.0,
            alpha: 0.5,
        };
        let ddm = Ddm::new(&set.rest, &set.faces, &skin.influences, bones, &params)
            .expect("precomputation");
        let groups = Groups::merge(&set, &train, groups);
        let mush = MushProxies::fit(&set, &train, &ddm, &skin.influences, &groups, 4);
        (set, skin, mush)
    }

    /// Every proxy follows a motion of the whole character exactly, and the weights of every
    /// vertex on a triangle sum to one: the mesh moves rigidly with it.
    #[test]
    fn a_rigid_motion_of_every_bone_moves_the_mesh_rigidly() {
        let (set, _, mush) = fitted(3, 6, 2);
        assert_eq!(mush.proxies.entries(), 6);
        for w in &mush.weights {
            assert!(w.len() <= 4 && (w.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-6);
        }
        let turn = Affine {
            q: DMat3::from_rotation_z(0.9) * DMat3::from_rotation_x(-0.4),
            d: DVec3::new(0.5, 1.0, -2.0),
        };
        let moved = mush.deform(&set.rest, &[turn; 3]);
        for (y, &x) in moved.iter().zip(&set.rest) {
            assert!((*y - turn.apply(x)).length() < 1e-5, "{y:?}");
        }
    }

    /// The runtime model's CPU reference deforms every pose as the proxies do, to f32
    /// round-off (the mesh is about 1 across).
    #[test]
    fn the_runtime_model_moves_the_mesh_as_the_proxies_do() {
        let (set, skin, mush) = fitted(4, 8, 4);
        let model = mush
            .to_runtime(&set, 4, &skin.influences)
            .expect("a valid model");
        assert_eq!(model.mush_keys().map(|k| k.count()), Some(8));
        let mut cpu = rrskin::cpu::CpuEvaluator::new(&model);
        let v = set.vertex_count();
        let (mut got, mut normals) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
        let mut worst = 0.0f64;
        for pose in &set.poses {
            let bones: Vec<_> = pose.bones.iter().map(Affine::to_runtime).collect();
            cpu.evaluate(&bones, &mut got, &mut normals)
                .expect("evaluation");
            let want = mush.deform(&set.rest, &pose.bones);
            for (g, w) in got.iter().zip(&want) {
                worst = worst.max((DVec3::from(g.map(f64::from)) - *w).length());
            }
        }
        assert!(worst < 1e-4, "{worst}");
    }
}
