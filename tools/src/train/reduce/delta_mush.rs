//! Delta-mush proxies (docs/method.md §23): P proxy bones whose transforms are Direct Delta
//! DeltaMushReport's rigid fits ([`crate::skinning::direct_delta_mush`]) for whole groups of vertices, and K-influence
//! palette skinning over them; a reduced model of delta-mush keys ([`rrskin::DeltaMushKey`],
//! [`DeltaMushProxies::reduced`]), alone or after a joint-blend model's proxies ([`join`]), where
//! [`crate::train::delta_mush`] keeps them.
//!
//! A smoothing rig (Blender's Corrective Smooth, Delta DeltaMushReport) moves a vertex by a rigid fit of
//! the bone motions of a whole neighbourhood of the mesh: on the Fox, about 11 bones reach each
//! vertex, and Direct Delta DeltaMushReport with Ω cut to a vertex's 4 heaviest bones loses 6 EE points
//! held out. Joint-blend proxies turn about one joint each, and a vertex blends at most K of
//! them. Here each proxy is itself the rigid fit over every bone its group's Ω holds:
//!
//! - groups: the vertex reduction's greedy merging of contiguous triangles (paper §5.1,
//!   [`merge_groups_at`]) on the training poses, P groups;
//! - Ω_g = Σ_a s_ag Ω_a, s_ag the share of vertex a's incident triangles in group g, bones
//!   below [`FLOOR`] of the group's mass left out (and past the runtime's 256 heaviest);
//! - per pose, T_g = [`Keys::motions`]: `Q_g = Σ_j M_j Ω_gj`, the runtime's rotation fit of
//!   its covariance part (`rrskin::polar`), and the translation that keeps the group's
//!   smoothed centre;
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
use crate::skinning::direct_delta_mush::DirectDeltaMush;
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::delta_mush_keys::Keys;
use crate::train::reduce::vertex::merge_groups_at;
use crate::train::rotreg::PoseFeatures;
use crate::train::ssd::fit_weights_best_subset;
use glam::DVec3;
use rayon::prelude::*;

/// A group's bones carrying less than this share of its Ω's mass are left out of its fit.
pub const FLOOR: f64 = 1e-3;

/// P delta-mush proxies and the vertices' weights over them.
pub struct DeltaMushProxies {
    /// P groups' keys.
    pub proxies: Keys,
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
    /// The vertex reduction's greedy merging ([`merge_groups_at`]) on the poses `train` of
    /// `set`, read off at each of `counts` groups (a grouping per count, in that order).
    pub fn merge_at(set: &ExampleSet, train: &[usize], counts: &[usize]) -> Vec<Groups> {
        (merge_groups_at(set, train, counts, None).into_iter())
            .map(|(triangle_group, adjacency)| Groups {
                shares: vertex_shares(set, &triangle_group),
                adjacency,
            })
            .collect()
    }
}

impl DeltaMushProxies {
    /// Fits K = `influences` weights on the poses `train` of `set` for the proxies of `groups`,
    /// from the per-vertex Ω `vertex_direct_delta_mush` (V entries: Direct Delta DeltaMushReport with SSD's weights) and
    /// SSD's (bone, weight) lists `bones` (V), whose bones are each vertex's candidates too.
    pub fn fit(
        set: &ExampleSet,
        train: &[usize],
        vertex_direct_delta_mush: &DirectDeltaMush,
        bones: &[Vec<(usize, f64)>],
        groups: &Groups,
        influences: usize,
    ) -> DeltaMushProxies {
        let (shares, adjacency) = (&groups.shares, &groups.adjacency);
        let cap = rrskin::model::MAX_DELTA_MUSH_BONES;
        let groups =
            Keys::of(&vertex_direct_delta_mush.grouped(shares, adjacency.len(), FLOOR, cap));
        let p = adjacency.len();
        let motions: Vec<Vec<Affine>> = (train.iter())
            .map(|&i| palette(&groups, &set.poses[i].bones))
            .collect();
        let weights = (0..set.vertex_count())
            .into_par_iter()
            .map(|a| {
                let candidates =
                    (groups_near(shares, adjacency, a)).chain(bones[a].iter().map(|&(b, _)| p + b));
                vertex_weights(set, train, &motions, a, candidates, influences)
            })
            .collect();
        DeltaMushProxies {
            proxies: groups,
            weights,
        }
    }

    /// These proxies as a reduced model of P delta-mush keys and no predictor, over J =
    /// `bones`, with SSD's (bone, weight) lists `baseline` as its baseline (`key_rows`).
    pub fn reduced(&self, bones: usize, baseline: &[Vec<(usize, f64)>]) -> Reduced {
        let (c1, c2) = self.proxies.rows(bones);
        Reduced {
            proxies: self.proxies.count(),
            bones,
            c1,
            c2,
            predictors: Vec::new(),
            delta_mush: Some(self.proxies.clone()),
            skin: self.weights.clone(),
            baseline: baseline.to_vec(),
        }
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

/// Vertex a's candidate groups: those of its triangles and their neighbours (with repeats).
fn groups_near<'a>(
    shares: &'a [Vec<(usize, f64)>],
    adjacency: &'a [Vec<usize>],
    a: usize,
) -> impl Iterator<Item = usize> + 'a {
    (shares[a].iter()).flat_map(|&(g, _)| std::iter::once(g).chain(adjacency[g].iter().copied()))
}

/// Both kinds of proxy in one palette (docs/method.md §23): `base`'s (its predictors' keys,
/// no delta-mush key), then `delta_mush`'s; each vertex's K = `influences` weights refitted on the
/// poses `train` of `set` (`feats`: every pose's features), by NNLS as [`DeltaMushProxies::fit`]'s,
/// over its entries in either palette and its SSD bones (each kind's own best K, so at most
/// 2K + K candidates).
pub fn join(
    base: &Reduced,
    delta_mush: &DeltaMushProxies,
    set: &ExampleSet,
    train: &[usize],
    feats: &[PoseFeatures],
    influences: usize,
) -> Reduced {
    let (p1, p2, j) = (base.proxies, delta_mush.proxies.count(), set.bone_count());
    let p = p1 + p2;
    let (delta_mush_c1, delta_mush_c2) = delta_mush.proxies.rows(j);
    let mut c1 = vec![0.0; 12 * p * p];
    for r in 0..4 * p1 {
        c1[r * 3 * p..r * 3 * p + 3 * p1].copy_from_slice(&base.c1[r * 3 * p1..(r + 1) * 3 * p1]);
    }
    for r in 0..4 * p2 {
        let row = (4 * p1 + r) * 3 * p + 3 * p1;
        c1[row..row + 3 * p2].copy_from_slice(&delta_mush_c1[r * 3 * p2..(r + 1) * 3 * p2]);
    }
    let palettes: Vec<Vec<Affine>> = (train.iter())
        .map(|&i| {
            let bones = &set.poses[i].bones;
            let mut out = base.predict_proxies(set, &feats[i], bones);
            out.extend(palette(&delta_mush.proxies, bones));
            out
        })
        .collect();
    let skin = (0..set.vertex_count())
        .into_par_iter()
        .map(|a| {
            let candidates = (base.skin[a].iter())
                .map(|&(e, _)| if e < p1 { e } else { e + p2 })
                // Group g is entry P1 + g, bone P2 + b (in the delta-mush palette) P + b.
                .chain(delta_mush.weights[a].iter().map(|&(e, _)| p1 + e))
                .chain(base.baseline[a].iter().map(|&(b, _)| p + b));
            vertex_weights(set, train, &palettes, a, candidates, influences)
        })
        .collect();
    Reduced {
        proxies: p,
        bones: j,
        c1,
        c2: [base.c2.as_slice(), &delta_mush_c2].concat(),
        predictors: base.predictors.clone(),
        delta_mush: Some(delta_mush.proxies.clone()),
        skin,
        baseline: base.baseline.clone(),
    }
}

/// Vertex a's weights (at most `influences`, Σ = 1; best-subset NNLS) over the palette entries
/// `candidates` (repeats allowed), fitted on the poses `train` of `set`, whose palettes (in
/// `train` order) are `palettes`.
fn vertex_weights(
    set: &ExampleSet,
    train: &[usize],
    palettes: &[Vec<Affine>],
    a: usize,
    candidates: impl Iterator<Item = usize>,
    influences: usize,
) -> Vec<(usize, f64)> {
    let mut candidates: Vec<usize> = candidates.collect();
    candidates.sort_unstable();
    candidates.dedup();
    let moved = |n: usize, e: usize| palettes[n][e].apply(set.rest[a]);
    let target = |n: usize| set.poses[train[n]].vertices[a];
    fit_weights_best_subset(train.len(), &candidates, influences, moved, target)
}

/// The palette of a pose (P + J): the P proxies' motions, then the J `bones`.
fn palette(proxies: &Keys, bones: &[Affine]) -> Vec<Affine> {
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
    use crate::skinning::direct_delta_mush::Params;
    use crate::skinning::lbs::Skinning;
    use crate::train::ssd;
    use glam::DMat3;

    /// A chain of `bones` bones, its SSD (K = 4) and `groups` delta-mush proxies over Ω of
    /// `iterations` smoothing steps, fitted to its training poses.
    fn fitted(
        bones: usize,
        groups: usize,
        iterations: usize,
    ) -> (ExampleSet, Skinning, DeltaMushProxies) {
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
        let direct_delta_mush =
            DirectDeltaMush::new(&set.rest, &set.faces, &skin.influences, bones, &params)
                .expect("precomputation");
        let groups = Groups::merge_at(&set, &train, &[groups]).swap_remove(0);
        let delta_mush = DeltaMushProxies::fit(
            &set,
            &train,
            &direct_delta_mush,
            &skin.influences,
            &groups,
            4,
        );
        (set, skin, delta_mush)
    }

    /// Every proxy follows a motion of the whole character exactly, and the weights of every
    /// vertex on a triangle sum to one: the mesh moves rigidly with it.
    #[test]
    fn a_rigid_motion_of_every_bone_moves_the_mesh_rigidly() {
        let (set, _, delta_mush) = fitted(3, 6, 2);
        assert_eq!(delta_mush.proxies.count(), 6);
        for w in &delta_mush.weights {
            assert!(w.len() <= 4 && (w.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-6);
        }
        let turn = Affine {
            q: DMat3::from_rotation_z(0.9) * DMat3::from_rotation_x(-0.4),
            d: DVec3::new(0.5, 1.0, -2.0),
        };
        let moved = delta_mush.deform(&set.rest, &[turn; 3]);
        for (y, &x) in moved.iter().zip(&set.rest) {
            assert!((*y - turn.apply(x)).length() < 1e-5, "{y:?}");
        }
    }

    /// The runtime model's CPU reference deforms every pose as the proxies do, to f32
    /// round-off (the mesh is about 1 across).
    #[test]
    fn the_runtime_model_moves_the_mesh_as_the_proxies_do() {
        let (set, skin, delta_mush) = fitted(4, 8, 4);
        let model = (delta_mush.reduced(4, &skin.influences))
            .to_runtime(&set, 4)
            .expect("a valid model");
        assert_eq!(
            model
                .keys()
                .iter()
                .filter_map(rrskin::Key::delta_mush)
                .count(),
            8
        );
        let mut cpu = rrskin::cpu::CpuEvaluator::new(&model);
        let v = set.vertex_count();
        let (mut got, mut normals) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
        let mut worst = 0.0f64;
        for pose in &set.poses {
            let bones: Vec<_> = pose.bones.iter().map(Affine::to_runtime).collect();
            cpu.evaluate(&bones, &mut got, &mut normals)
                .expect("evaluation");
            let want = delta_mush.deform(&set.rest, &pose.bones);
            for (g, w) in got.iter().zip(&want) {
                worst = worst.max((DVec3::from(g.map(f64::from)) - *w).length());
            }
        }
        assert!(worst < 1e-4, "{worst}");
    }
}
