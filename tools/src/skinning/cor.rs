//! Skinning with optimized centres of rotation (Le & Hodgins 2016), a baseline an engine can
//! run at about LBS cost. Each vertex i gets one centre p*_i, precomputed from the rest mesh and
//! the weights: the area-weighted mean of the surface points whose weights resemble the
//! vertex's,
//!
//! `p*_i = ∫ s(w_i, w_x) x dA / ∫ s(w_i, w_x) dA`,
//! `s(w_a, w_b) = Σ_{j≠k} w_aj w_ak w_bj w_bk exp(−(w_aj w_bk − w_ak w_bj)² / σ²)`, σ = 0.1.
//!
//! At run time the bones' quaternions are blended as in DQS for the rotation R_i, and the
//! centre is moved by LBS: `v'_i = R_i (v_i − p*_i) + LBS_i(p*_i)`. Around a twist the centre
//! lies on the limb's axis (no candy wrapper); at a bend it lies near the joint (no DQS bulge).
//!
//! The integral is a sum over the rest triangles, each split 1 → 4 until the weights at its
//! corners differ by at most [`SUBDIVISION`] (the paper's subdivision), and sampled at the
//! centroid. s is non-zero only for pairs of bones that both weigh on the vertex and on the
//! sample, so samples are indexed by bone pair: a vertex visits the samples of its own pairs
//! only, instead of every triangle.

use super::dqs::{blended, DualQuat};
use crate::set::Affine;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// σ of the similarity (the paper's value).
pub const SIGMA: f64 = 0.1;
/// The largest weight distance |w_a − w_b| along a sample triangle's edges.
pub const SUBDIVISION: f64 = 0.1;
/// At most 4^MAX_DEPTH samples per rest triangle.
const MAX_DEPTH: usize = 4;
/// Past this |w_aj w_bk − w_ak w_bj| / σ the exponential is below 1e-16: the term is skipped.
const NEGLIGIBLE: f64 = 6.0;

/// One sample's share of a bone pair (j < k): the sample's weights of j and k, its area and its
/// centroid.
struct PairSample {
    wj: f64,
    wk: f64,
    area: f64,
    centroid: DVec3,
}

/// The centre of rotation of every vertex of `rest` (V), for its (bone, weight) list. A vertex
/// similar to no sample (one bone, or bones no triangle shares) keeps itself as centre, which
/// makes its motion LBS's.
pub fn centres(
    rest: &[DVec3],
    faces: &[[usize; 3]],
    influences: &[Vec<(usize, f64)>],
) -> Vec<DVec3> {
    let pairs = pair_samples(rest, faces, influences);
    rest.par_iter()
        .zip(influences)
        .map(|(&v, inf)| centre(&positive(inf), &pairs).unwrap_or(v))
        .collect()
}

/// Each vertex of `rest` moved about its centre: `R (v − p*) + LBS(p*)`.
pub fn deform(
    rest: &[DVec3],
    influences: &[Vec<(usize, f64)>],
    centres: &[DVec3],
    bones: &[Affine],
) -> Vec<DVec3> {
    let dq: Vec<DualQuat> = bones.iter().map(DualQuat::of).collect();
    rest.iter()
        .zip(influences)
        .zip(centres)
        .map(|((&v, inf), &c)| {
            let Some(rotation) = blended(&dq, inf) else {
                return v;
            };
            let moved_centre: DVec3 = inf.iter().map(|&(b, w)| bones[b].apply(c) * w).sum();
            rotation.real * (v - c) + moved_centre
        })
        .collect()
}

/// The weights above zero, by bone.
fn positive(inf: &[(usize, f64)]) -> Vec<(usize, f64)> {
    let mut w: Vec<(usize, f64)> = inf.iter().copied().filter(|w| w.1 > 0.0).collect();
    w.sort_by_key(|w| w.0);
    w
}

/// `p*` of a vertex of weights `w` (by bone); None where the similarity integrates to zero.
fn centre(w: &[(usize, f64)], pairs: &HashMap<(usize, usize), Vec<PairSample>>) -> Option<DVec3> {
    let (mut moment, mut mass) = (DVec3::ZERO, 0.0);
    for (x, &(j, wj)) in w.iter().enumerate() {
        for &(k, wk) in &w[x + 1..] {
            for s in pairs.get(&(j, k)).into_iter().flatten() {
                let z = (wj * s.wk - wk * s.wj) / SIGMA;
                if z.abs() > NEGLIGIBLE {
                    continue;
                }
                // Both orders (j, k) and (k, j) of the sum over j ≠ k: the terms are equal.
                // libm's exp, which inlines here: the platform's, one call per term, was 14x
                // slower on human_heavy (19.8 s against 1.4 s), for the same figures.
                let m = 2.0 * wj * wk * s.wj * s.wk * libm::exp(-z * z) * s.area;
                moment += s.centroid * m;
                mass += m;
            }
        }
    }
    (mass > 0.0).then(|| moment / mass)
}

/// The subdivided rest surface's samples, under each bone pair (j < k) both of whose weights
/// are positive at the sample.
fn pair_samples(
    rest: &[DVec3],
    faces: &[[usize; 3]],
    influences: &[Vec<(usize, f64)>],
) -> HashMap<(usize, usize), Vec<PairSample>> {
    let per_face: Vec<Vec<((usize, usize), PairSample)>> = faces
        .par_iter()
        .map(|&[a, b, c]| {
            let corners = [a, b, c].map(|v| positive(&influences[v]));
            let mut bones: Vec<usize> = corners.iter().flatten().map(|w| w.0).collect();
            bones.sort_unstable();
            bones.dedup();
            // Corner weights, dense over the triangle's bones.
            let dense = corners.map(|w| {
                bones
                    .iter()
                    .map(|b| w.iter().find(|x| x.0 == *b).map_or(0.0, |x| x.1))
                    .collect::<Vec<f64>>()
            });
            let mut out = Vec::new();
            subdivide(
                [rest[a], rest[b], rest[c]],
                dense,
                MAX_DEPTH,
                &mut |area, centroid, w| {
                    for x in 0..bones.len() {
                        for y in x + 1..bones.len() {
                            if w[x] > 0.0 && w[y] > 0.0 {
                                let (wj, wk) = (w[x], w[y]);
                                let sample = PairSample {
                                    wj,
                                    wk,
                                    area,
                                    centroid,
                                };
                                out.push(((bones[x], bones[y]), sample));
                            }
                        }
                    }
                },
            );
            out
        })
        .collect();
    let mut pairs: HashMap<(usize, usize), Vec<PairSample>> = HashMap::new();
    for (key, sample) in per_face.into_iter().flatten() {
        pairs.entry(key).or_default().push(sample);
    }
    pairs
}

/// Calls `leaf(area, centroid, mean weights)` for each piece of the triangle `p` (weights `w` at
/// its corners, linear inside), split at its edges' midpoints while two corners' weights differ
/// by more than [`SUBDIVISION`] and `depth` allows.
fn subdivide(
    p: [DVec3; 3],
    w: [Vec<f64>; 3],
    depth: usize,
    leaf: &mut dyn FnMut(f64, DVec3, &[f64]),
) {
    let distance = |x: &[f64], y: &[f64]| -> f64 {
        x.iter()
            .zip(y)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt()
    };
    let spread = (0..3)
        .map(|e| distance(&w[e], &w[(e + 1) % 3]))
        .fold(0.0, f64::max);
    if depth == 0 || spread <= SUBDIVISION {
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let mean: Vec<f64> = (0..w[0].len())
            .map(|b| (w[0][b] + w[1][b] + w[2][b]) / 3.0)
            .collect();
        leaf(area, (p[0] + p[1] + p[2]) / 3.0, &mean);
        return;
    }
    let mid = |x: usize, y: usize| {
        let weights: Vec<f64> = w[x].iter().zip(&w[y]).map(|(a, b)| 0.5 * (a + b)).collect();
        (0.5 * (p[x] + p[y]), weights)
    };
    let [(p01, w01), (p12, w12), (p20, w20)] = [mid(0, 1), mid(1, 2), mid(2, 0)];
    let [w0, w1, w2] = w;
    subdivide(
        [p[0], p01, p20],
        [w0, w01.clone(), w20.clone()],
        depth - 1,
        leaf,
    );
    subdivide(
        [p01, p[1], p12],
        [w01.clone(), w1, w12.clone()],
        depth - 1,
        leaf,
    );
    subdivide(
        [p20, p12, p[2]],
        [w20.clone(), w12.clone(), w2],
        depth - 1,
        leaf,
    );
    subdivide([p01, p12, p20], [w01, w12, w20], depth - 1, leaf);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rest positions, triangles and (bone, weight) lists.
    type Mesh = (Vec<DVec3>, Vec<[usize; 3]>, Vec<Vec<(usize, f64)>>);
    use glam::DMat3;

    /// The similarity written out over ordered pairs j ≠ k, as in the paper.
    fn similarity(a: &[f64], b: &[f64]) -> f64 {
        let mut s = 0.0;
        for j in 0..a.len() {
            for k in 0..a.len() {
                if j != k {
                    let z = (a[j] * b[k] - a[k] * b[j]) / SIGMA;
                    s += a[j] * a[k] * b[j] * b[k] * (-z * z).exp();
                }
            }
        }
        s
    }

    /// A strip of 2 x n squares along x, weights from bone 0 to bone 1 by `blend(x)`.
    fn strip(n: usize, blend: impl Fn(f64) -> f64) -> Mesh {
        let rest: Vec<DVec3> = (0..=n)
            .flat_map(|i| (0..3).map(move |y| DVec3::new(i as f64, y as f64, 0.0)))
            .collect();
        let mut faces = Vec::new();
        for i in 0..n {
            // Mirror images about y = 1: diagonals (i, 0)–(i + 1, 1) and (i, 2)–(i + 1, 1).
            let a = 3 * i;
            faces.extend([[a, a + 3, a + 4], [a, a + 4, a + 1]]);
            faces.extend([[a + 2, a + 4, a + 5], [a + 2, a + 1, a + 4]]);
        }
        let weights = rest
            .iter()
            .map(|p| {
                let t = blend(p.x);
                vec![(0, 1.0 - t), (1, t)]
            })
            .collect();
        (rest, faces, weights)
    }

    #[test]
    fn the_centre_is_the_similarity_weighted_mean_of_the_triangles() {
        // Weights steep enough to split triangles: the pair index and the subdivision must
        // give the brute-force sum over every leaf sample, here computed without either.
        let (rest, faces, weights) = strip(6, |x| (x / 6.0).powi(2));
        let got = centres(&rest, &faces, &weights);
        let mut leaves = Vec::new();
        for f in &faces {
            let dense = f.map(|v| vec![weights[v][0].1, weights[v][1].1]);
            subdivide(f.map(|v| rest[v]), dense, MAX_DEPTH, &mut |area, c, w| {
                leaves.push((area, c, w.to_vec()))
            });
        }
        assert!(leaves.len() > faces.len(), "no triangle was split");
        for (v, w) in weights.iter().enumerate() {
            let w = [w[0].1, w[1].1];
            let (mut moment, mut mass) = (DVec3::ZERO, 0.0);
            for (area, c, lw) in &leaves {
                let s = similarity(&w, lw) * area;
                moment += *c * s;
                mass += s;
            }
            let expected = if mass > 0.0 { moment / mass } else { rest[v] };
            assert!(
                (got[v] - expected).length() < 1e-9,
                "vertex {v}: {:?} vs {expected:?}",
                got[v]
            );
        }
    }

    #[test]
    fn a_vertex_on_one_bone_is_its_own_centre_and_moves_rigidly() {
        let (rest, faces, weights) = strip(4, |x| (x / 4.0).clamp(0.0, 1.0));
        let c = centres(&rest, &faces, &weights);
        // x = 0 is all bone 0: s = 0 against every sample.
        for v in 0..3 {
            assert_eq!(c[v], rest[v]);
        }
        let bones = [
            Affine {
                q: DMat3::from_rotation_z(0.7),
                d: DVec3::new(0.5, -1.0, 2.0),
            },
            Affine {
                q: DMat3::IDENTITY,
                d: DVec3::ZERO,
            },
        ];
        let moved = deform(&rest, &weights, &c, &bones);
        for v in 0..3 {
            assert!((moved[v] - bones[0].apply(rest[v])).length() < 1e-12);
        }
    }

    #[test]
    fn centres_of_a_symmetric_blend_lie_on_its_axis() {
        // The strip is symmetric about y = 1 and its weights depend on x only: the centres of
        // the blended vertices lie on y = 1, between the two bones' regions.
        let (rest, faces, weights) = strip(8, |x| ((x - 2.0) / 4.0).clamp(0.0, 1.0));
        let c = centres(&rest, &faces, &weights);
        for (v, w) in weights.iter().enumerate() {
            if w[0].1 > 0.0 && w[1].1 > 0.0 {
                assert!((c[v].y - 1.0).abs() < 1e-9, "vertex {v}: {:?}", c[v]);
                assert!((2.0..=6.0).contains(&c[v].x), "vertex {v}: {:?}", c[v]);
            }
        }
    }
}
