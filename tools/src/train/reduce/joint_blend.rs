//! Joint-blend proxies (beyond the paper; Mohr & Gleicher 2003's half-way joints, Kavan et
//! al. 2009's linearised nonlinear skinning): proxy bones that turn about a joint's pivot by a
//! fixed fraction of the joint's rotation, and per-vertex NNLS weights over them and the bones.
//!
//! Proxy e on joint b (parent p, pivot c_b, fraction w) moves a rest point x by
//! `T_e(q) = T_p(q) ∘ Rot(exp(w θ~_b(q)), c_b)`, the screw motion dual quaternion skinning
//! blends to between a bone and its parent. It is exactly a key predictor and a row of C1/C2
//! (§4.3's runtime form, nothing new at run time):
//!
//! - key ℓ = e: `D_e = Q_p exp(w I θ~_b)` (u = w, W = I, S = I);
//! - `T_e[:, 0..3] = D_e` (C1 = I on key e), `T_e[:, 3] = T_p ĉh_b − D_e c_b` (C2 = ĉh_bᵀ on
//!   bone p, C1 = −c_bᵀ on key e).
//!
//! Everything is geometry but the weights, so the model extrapolates as the rig's joints do:
//! a regression fitted on wide range-of-motion poses cannot bend it on gentle ones.

use crate::set::{Affine, ExampleSet};
use crate::skinning::lbs::Skinning;
use crate::train::pivots::pivots;
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::predictor::TrainedPredictor;
use crate::train::rotreg::{BoneTerm, PoseFeatures, RotationPredictor};
use crate::train::scale_shear;
use crate::train::ssd;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use rrskin::predict::exp_rotation;

/// Fractions of each joint's rotation the candidate proxies turn by.
pub const FRACTIONS: [f64; 3] = [0.25, 0.5, 0.75];

#[derive(Debug, Clone, Copy, PartialEq)]
struct Proxy {
    bone: usize,
    parent: usize,
    fraction: f64,
    pivot: DVec3,
}

impl Proxy {
    fn transform(&self, f: &PoseFeatures, bones: &[Affine]) -> Affine {
        let q = bones[self.parent].q * exp_rotation(f.theta[self.bone] * self.fraction);
        Affine {
            q,
            d: bones[self.parent].apply(self.pivot) - q * self.pivot,
        }
    }
}

/// Every candidate proxy (one per moving joint and fraction) and how much weight a first NNLS
/// fit over all of them gives each: what [`Pool::fit`] keeps the most used of, whatever P. It
/// depends only on the training poses and SSD, so the structure's candidates of one
/// cross-validation fold share it.
pub struct Pool {
    all: Vec<Proxy>,
    /// Proxy indices carrying weight, most used first.
    by_use: Vec<usize>,
}

impl Pool {
    /// The pool of the `train` poses (`ssd` fitted on them), with K = `influences`.
    pub fn new(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        train: &[usize],
        ssd: &Skinning,
        influences: usize,
    ) -> Pool {
        let pivot = pivots(set, train);
        let all: Vec<Proxy> = moving_joints(set, feats, train)
            .flat_map(|(bone, parent)| {
                FRACTIONS.map(|fraction| Proxy {
                    bone,
                    parent,
                    fraction,
                    pivot: pivot[bone],
                })
            })
            .collect();
        let palette = palettes(set, feats, train, &all);
        let first = weights(set, train, &palette, &joints(&all), ssd, influences);
        let mut usage = vec![0.0; all.len()];
        for inf in &first {
            for &(e, w) in inf {
                if e < all.len() {
                    usage[e] += w;
                }
            }
        }
        let mut by_use: Vec<usize> = (0..all.len()).filter(|&e| usage[e] > 0.0).collect();
        by_use.sort_by(|&x, &y| usage[y].total_cmp(&usage[x]));
        Pool { all, by_use }
    }

    /// At most `proxies` joint-blend proxies, the most used, and weights for every vertex (K =
    /// `influences`) over them and the bones, fitted on the `train` poses (the pool's); `ssd` is
    /// the baseline the model carries.
    pub fn fit(
        &self,
        set: &ExampleSet,
        feats: &[PoseFeatures],
        train: &[usize],
        ssd: &Skinning,
        proxies: usize,
        influences: usize,
    ) -> Reduced {
        let mut order: Vec<usize> = self.by_use.iter().copied().take(proxies).collect();
        order.sort_unstable();
        let kept: Vec<Proxy> = order.iter().map(|&e| self.all[e]).collect();
        let palette = palettes(set, feats, train, &kept);
        let skin = weights(set, train, &palette, &joints(&kept), ssd, influences);
        assemble(set, &kept, skin, ssd)
    }
}

/// [`Pool::fit`] of a pool made for it alone.
pub fn fit(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    ssd: &Skinning,
    proxies: usize,
    influences: usize,
) -> Reduced {
    Pool::new(set, feats, train, ssd, influences).fit(set, feats, train, ssd, proxies, influences)
}

/// The active joints (bone, parent) that move in the `train` poses: each has a proxy per
/// fraction ([`ExampleSet::active_bones`]).
fn moving_joints<'a>(
    set: &'a ExampleSet,
    feats: &'a [PoseFeatures],
    train: &'a [usize],
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let moving = |b: usize| train.iter().any(|&i| feats[i].theta[b].length() > 1e-6);
    let active = set.active_bones();
    (0..set.bone_count())
        .filter_map(|b| set.parents[b].map(|p| (b, p)))
        .filter(move |&(b, _)| active[b] && moving(b))
}

/// How many candidate proxies [`fit`] chooses its P from: one per moving joint and fraction.
pub fn pool(set: &ExampleSet, feats: &[PoseFeatures], train: &[usize]) -> usize {
    moving_joints(set, feats, train).count() * FRACTIONS.len()
}

/// Refits `reduced`'s weights to its own proxy transforms (after [`super::refit`] moved them;
/// SSDR's alternation, Le & Deng 2012), with the same candidates as [`fit`].
pub fn reweight(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    ssd: &Skinning,
    influences: usize,
    reduced: &mut Reduced,
) {
    let palette: Vec<Vec<Affine>> = train
        .iter()
        .map(|&i| {
            let d: Vec<DMat3> = reduced
                .predictors
                .iter()
                .map(|k| k.predict(&feats[i], &set.parents))
                .collect();
            let bones = &set.poses[i].bones;
            let mut entries = reduced.proxy_transforms(&d, bones);
            entries.extend_from_slice(bones);
            entries
        })
        .collect();
    let joints: Vec<(usize, usize)> = reduced
        .predictors
        .iter()
        .map(|k| {
            let bone = k.rotation.map_or(0, |r| r.first.bone);
            (bone, set.parents[bone].unwrap_or(bone))
        })
        .collect();
    reduced.skin = weights(set, train, &palette, &joints, ssd, influences);
}

/// Per training pose, the palette: the proxies' transforms, then the bones'.
fn palettes(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    proxies: &[Proxy],
) -> Vec<Vec<Affine>> {
    train
        .iter()
        .map(|&i| {
            let bones = &set.poses[i].bones;
            proxies
                .iter()
                .map(|e| e.transform(&feats[i], bones))
                .chain(bones.iter().copied())
                .collect()
        })
        .collect()
}

/// Per proxy, the joint it blends: (bone, parent).
fn joints(proxies: &[Proxy]) -> Vec<(usize, usize)> {
    proxies.iter().map(|e| (e.bone, e.parent)).collect()
}

/// Per vertex, NNLS weights (the best K-subset of the NNLS support,
/// [`ssd::fit_weights_best_subset`]: CesiumMan test EE 28.97 → 28.40 %, human_heavy 19.27 →
/// 18.41 % against the K largest weights) over the palette's proxies (entries 0..P, each blending the joint
/// `joints[e]`) and bones (P + b); `palette[n]` is training pose n's.
fn weights(
    set: &ExampleSet,
    train: &[usize],
    palette: &[Vec<Affine>],
    joints: &[(usize, usize)],
    ssd: &Skinning,
    influences: usize,
) -> Vec<Vec<(usize, f64)>> {
    let p = joints.len();
    (0..set.vertex_count())
        .into_par_iter()
        .map(|a| {
            let rest = set.rest[a];
            let error = |e: usize| -> f64 {
                train
                    .iter()
                    .enumerate()
                    .map(|(n, &i)| {
                        (palette[n][e].apply(rest) - set.poses[i].vertices[a]).length_squared()
                    })
                    .sum()
            };
            // Candidates: the vertex's SSD bones and the proxies between two of them. Offering
            // every proxy fits the wide training poses better and generalises worse (CesiumMan
            // test EE 44.8 % against 34.4 %).
            let own: Vec<usize> = ssd.influences[a].iter().map(|&(b, _)| b).collect();
            let mut order: Vec<(usize, f64)> = (0..p)
                .filter(|&e| own.contains(&joints[e].0) && own.contains(&joints[e].1))
                .chain(own.iter().map(|&b| p + b))
                .map(|e| (e, error(e)))
                .collect();
            order.sort_by(|x, y| x.1.total_cmp(&y.1));
            let order: Vec<usize> = order.iter().take(ssd::CANDIDATES).map(|x| x.0).collect();
            ssd::fit_weights_best_subset(
                train.len(),
                &order,
                influences,
                |n, e| palette[n][e].apply(rest),
                |n| set.poses[train[n]].vertices[a],
            )
        })
        .collect()
}

/// The runtime form of the proxies: keys, C1, C2 (module docs) and the skinning.
fn assemble(
    set: &ExampleSet,
    proxies: &[Proxy],
    skin: Vec<Vec<(usize, f64)>>,
    ssd: &Skinning,
) -> Reduced {
    let (p, j) = (proxies.len(), set.bone_count());
    let (mut c1, mut c2) = (vec![0.0; 4 * p * 3 * p], vec![0.0; 4 * p * 4 * j]);
    for (e, proxy) in proxies.iter().enumerate() {
        let c = proxy.pivot.to_array();
        for k in 0..3 {
            c1[(4 * e + k) * 3 * p + 3 * e + k] = 1.0;
            c1[(4 * e + 3) * 3 * p + 3 * e + k] = -c[k];
            c2[(4 * e + 3) * 4 * j + 4 * proxy.parent + k] = c[k];
        }
        c2[(4 * e + 3) * 4 * j + 4 * proxy.parent + 3] = 1.0;
    }
    let predictors = proxies
        .iter()
        .map(|e| TrainedPredictor {
            rotation: Some(RotationPredictor {
                first: BoneTerm {
                    bone: e.bone,
                    u: e.fraction,
                    w: DMat3::IDENTITY,
                },
                second: None,
            }),
            stretch: scale_shear::identity(),
        })
        .collect();
    Reduced {
        proxies: p,
        bones: j,
        c1,
        c2,
        predictors,
        delta_mush: None,
        skin,
        baseline: ssd.influences.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rrskin::predict::log_rotation;

    /// A proxy at fraction w is the screw interpolation (ScLERP) of parent and child at w: it
    /// turns about the joint's pivot by w of the joint's angle, and at w = ½ it is exactly dual
    /// quaternion skinning's blend (DLB, which parametrises the angle differently elsewhere).
    #[test]
    fn a_proxy_is_the_screw_interpolation_of_its_joint() {
        let parent = Affine {
            q: exp_rotation(DVec3::new(0.2, -0.4, 0.3)),
            d: DVec3::new(0.5, -1.0, 0.25),
        };
        let pivot = DVec3::new(0.1, 1.2, -0.3);
        let joint = exp_rotation(DVec3::new(0.0, 1.1, 0.6));
        let child = Affine {
            q: parent.q * joint,
            d: parent.apply(pivot - joint * pivot),
        };
        let feats = PoseFeatures {
            q: vec![parent.q, child.q],
            theta: vec![
                log_rotation(parent.q),
                log_rotation(parent.q.transpose() * child.q),
            ],
        };
        let x = DVec3::new(-0.4, 0.9, 0.7);
        for w in FRACTIONS {
            let proxy = Proxy {
                bone: 1,
                parent: 0,
                fraction: w,
                pivot,
            };
            let t = proxy.transform(&feats, &[parent, child]);
            assert!(
                (t.apply(pivot) - parent.apply(pivot)).length() < 1e-12,
                "w = {w}"
            );
            let turned = log_rotation(parent.q.transpose() * t.q);
            assert!((turned - feats.theta[1] * w).length() < 1e-12, "w = {w}");
            if w == 0.5 {
                let dqs = crate::skinning::dqs::deform(
                    &[x],
                    &[vec![(0, 0.5), (1, 0.5)]],
                    &[parent, child],
                );
                assert!(
                    (t.apply(x) - dqs[0]).length() < 1e-12,
                    "{:?} vs {:?}",
                    t.apply(x),
                    dqs[0]
                );
            }
        }
    }
}
