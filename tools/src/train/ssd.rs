//! SSD, the baseline of paper §4.2 / §7.1: linear blend skinning ([`Skinning`]) with weights by
//! non-negative least squares over the training poses (James & Twigg 2005; docs/method.md §4).

use crate::linalg::{mirror_upper, nnls};
use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use glam::DVec3;
use rayon::prelude::*;

/// Bones tried per vertex by the NNLS: the best single bones by rigid fit.
pub const CANDIDATES: usize = 10;
/// Weight of the Σw = 1 row relative to the mean diagonal of the normal equations.
const SUM_TO_ONE_WEIGHT: f64 = 1e3;

/// SSD weights with at most `k` influences per vertex, fitted on `poses`, over the active bones
/// ([`ExampleSet::active_bones`]).
pub fn fit(set: &ExampleSet, poses: &[usize], errors: &[Vec<f64>], k: usize) -> Skinning {
    let active = set.active_bones();
    let bones: Vec<usize> = (0..set.bone_count()).filter(|&b| active[b]).collect();
    let influences = (0..set.vertex_count())
        .into_par_iter()
        .map(|a| {
            let mut order = bones.clone();
            order.sort_by(|&x, &y| errors[a][x].total_cmp(&errors[a][y]));
            order.truncate(CANDIDATES);
            let moved = |n: usize, b: usize| set.poses[poses[n]].bones[b].apply(set.rest[a]);
            fit_weights(poses.len(), &order, k, moved, |n| {
                set.poses[poses[n]].vertices[a]
            })
        })
        .collect();
    Skinning { influences }
}

/// Blend weights of one vertex over `candidates` (best first): NNLS over `poses` samples with
/// a heavily weighted Σw = 1 row; if more than `k` are non-zero, the `k` largest are refitted.
/// `moved(n, c)`: the vertex moved by candidate c in sample n; `target(n)`: where it should be.
/// Shared by SSD (candidates = bones) and the vertex reduction (candidates = proxy bones).
pub fn fit_weights(
    poses: usize,
    candidates: &[usize],
    k: usize,
    moved: impl Fn(usize, usize) -> DVec3,
    target: impl Fn(usize) -> DVec3,
) -> Vec<(usize, f64)> {
    let all: Vec<usize> = (0..candidates.len()).collect();
    Normal::new(poses, candidates, &moved, &target).fit(&all, k)
}

/// Like [`fit_weights`], but when more than `k` candidates get weight, every k-subset of that
/// support is refitted and the one with the least squared error over the samples is kept. The
/// k largest weights of the unconstrained fit are often not the best k: nearly collinear
/// candidates (a joint's proxies at neighbouring fractions) share weight that one of them could
/// carry, and dropping the small ones then costs more than dropping a large one. At most
/// C(`candidates.len()`, k) small NNLS solves per vertex (210 for 10 candidates, K = 4).
pub fn fit_weights_best_subset(
    poses: usize,
    candidates: &[usize],
    k: usize,
    moved: impl Fn(usize, usize) -> DVec3,
    target: impl Fn(usize) -> DVec3,
) -> Vec<(usize, f64)> {
    // Every subset's normal equations are a block of the candidates': summed once.
    let normal = Normal::new(poses, candidates, &moved, &target);
    let all: Vec<usize> = (0..candidates.len()).collect();
    let support = normal.fit(&all, candidates.len());
    if support.len() <= k || support.len() > MAX_SUBSET_SUPPORT {
        return normal.fit(&all, k);
    }
    let position = |c: usize| candidates.iter().position(|&x| x == c).unwrap_or(0);
    // One subset's positions and its weights' samples, reused from subset to subset.
    let (mut subset, mut moved) = (Vec::with_capacity(k), Vec::with_capacity(k));
    let mut best: Option<(f64, Vec<(usize, f64)>)> = None;
    for mask in 0u32..(1 << support.len()) {
        if mask.count_ones() as usize != k {
            continue;
        }
        subset.clear();
        subset.extend((0..support.len()).filter(|&i| mask & (1 << i) != 0));
        subset.iter_mut().for_each(|i| *i = position(support[*i].0));
        let w = normal.fit(&subset, k);
        moved.clear();
        moved.extend(w.iter().map(|&(c, x)| (&normal.moved[position(c)][..], x)));
        let e: f64 = (0..poses)
            .map(|n| {
                let y: DVec3 = moved.iter().map(|&(m, x): &(&[DVec3], f64)| m[n] * x).sum();
                (y - target(n)).length_squared()
            })
            .sum();
        if best.as_ref().is_none_or(|b| e < b.0) {
            best = Some((e, w));
        }
    }
    best.map_or(support, |b| b.1)
}

/// The largest NNLS support [`fit_weights_best_subset`] searches exhaustively.
const MAX_SUBSET_SUPPORT: usize = 16;

/// One vertex's blend over candidates: each candidate's moved point per sample, and the normal
/// equations `G = Σ_n m_n m_nᵀ`, `h = Σ_n m_n · y_n` (entries `G[r][c] = Σ_n m_r,n · m_c,n`),
/// from which any subset's equations are a block.
struct Normal<'a> {
    candidates: &'a [usize],
    /// [candidate position][sample]
    moved: Vec<Vec<DVec3>>,
    g: Vec<f64>,
    h: Vec<f64>,
}

impl<'a> Normal<'a> {
    fn new(
        poses: usize,
        candidates: &'a [usize],
        moved: &impl Fn(usize, usize) -> DVec3,
        target: &impl Fn(usize) -> DVec3,
    ) -> Normal<'a> {
        let n = candidates.len();
        let m: Vec<Vec<DVec3>> = candidates
            .iter()
            .map(|&c| (0..poses).map(|s| moved(s, c)).collect())
            .collect();
        let (mut g, mut h) = (vec![0.0; n * n], vec![0.0; n]);
        for s in 0..poses {
            let y = target(s);
            for r in 0..n {
                h[r] += m[r][s].dot(y);
                // The upper triangle; the lower mirrors it below.
                for c in r..n {
                    g[r * n + c] += m[r][s].dot(m[c][s]);
                }
            }
        }
        mirror_upper(&mut g, n);
        Normal {
            candidates,
            moved: m,
            g,
            h,
        }
    }

    /// Weights over the candidates at `subset` (positions, best first): NNLS with a heavily
    /// weighted Σw = 1 row; if more than `k` are non-zero, the `k` largest are refitted. As
    /// (candidate, weight), normalised; the subset's first candidate alone if none fits.
    fn fit(&self, subset: &[usize], k: usize) -> Vec<(usize, f64)> {
        let solve = |subset: &[usize]| -> Vec<(usize, f64)> {
            let w = self.nnls_sum_to_one(subset);
            subset
                .iter()
                .zip(&w)
                .filter(|(_, &w)| w > 0.0)
                .map(|(&p, &w)| (p, w))
                .collect()
        };
        let mut support = solve(subset);
        if support.len() > k {
            support.sort_by(|x, y| y.1.total_cmp(&x.1));
            let kept: Vec<usize> = support[..k].iter().map(|&(p, _)| p).collect();
            support = solve(&kept);
        }
        let total: f64 = support.iter().map(|&(_, w)| w).sum();
        if support.is_empty() || total <= 0.0 {
            return vec![(self.candidates[subset[0]], 1.0)];
        }
        (support.iter())
            .map(|&(p, w)| (self.candidates[p], w / total))
            .collect()
    }

    /// NNLS over the block of `subset` with the Σw = 1 row weighted [`SUM_TO_ONE_WEIGHT`]
    /// times the block's mean diagonal.
    fn nnls_sum_to_one(&self, subset: &[usize]) -> Vec<f64> {
        let (n, all) = (subset.len(), self.candidates.len());
        let mut g: Vec<f64> = (subset.iter())
            .flat_map(|&r| subset.iter().map(move |&c| (r, c)))
            .map(|(r, c)| self.g[r * all + c])
            .collect();
        let mut h: Vec<f64> = subset.iter().map(|&r| self.h[r]).collect();
        let omega = SUM_TO_ONE_WEIGHT * (0..n).map(|r| g[r * n + r]).sum::<f64>() / n as f64;
        for r in 0..n {
            h[r] += omega;
            for c in 0..n {
                g[r * n + c] += omega;
            }
        }
        nnls(&g, &h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where the k largest NNLS weights are not the best k, the subset search finds a k-subset
    /// that fits better, and never one that fits worse; its weights sum to one.
    #[test]
    fn the_best_subset_fits_no_worse_than_the_largest_weights() {
        // Candidates: 6 random affine maps of one point per sample; the target blends 5 of them.
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (poses, c) = (12, 6);
        let table: Vec<Vec<DVec3>> = (0..poses)
            .map(|_| (0..c).map(|_| DVec3::new(rand(), rand(), rand())).collect())
            .collect();
        let truth = [0.3, 0.25, 0.2, 0.15, 0.1, 0.0];
        let target = |n: usize| -> DVec3 { (0..c).map(|e| table[n][e] * truth[e]).sum() };
        let moved = |n: usize, e: usize| table[n][e];
        let candidates: Vec<usize> = (0..c).collect();
        let error = |w: &[(usize, f64)]| -> f64 {
            (0..poses)
                .map(|n| {
                    let y: DVec3 = w.iter().map(|&(e, x)| moved(n, e) * x).sum();
                    (y - target(n)).length_squared()
                })
                .sum()
        };
        let mut better = 0;
        for k in 1..=4 {
            let largest = fit_weights(poses, &candidates, k, moved, target);
            let best = fit_weights_best_subset(poses, &candidates, k, moved, target);
            assert!(best.len() <= k, "{best:?}");
            let total: f64 = best.iter().map(|x| x.1).sum();
            assert!((total - 1.0).abs() < 1e-9, "{best:?}");
            assert!(error(&best) <= error(&largest) + 1e-12, "k = {k}");
            if error(&best) < 0.99 * error(&largest) {
                better += 1;
            }
        }
        assert!(better > 0, "the search never beat the largest weights here");
    }
}
