//! Pose-driven stretch of the joint-blend keys (beyond the paper; docs/method.md §19): a
//! muscle that bulges as its joint bends, or skin that sags or thins, is a scale/shear of
//! the proxies around that joint, and the runtime form already carries one per key (§3.3's
//! `S(q) = H x(q)`, `x = [θ~_b; θ~_p(b); 1]`). Joint-blend keys start rigid (S = I); this fits
//! their H to the vertices.
//!
//! With the weights α and C1/C2 fixed, proxy e moves a vertex by `D_e z_e + (its bones)`, z_e
//! the vertex in the key's frame (its own C1 block applied to the rest point) and
//! `D_e = R_e (I + ΔS_e)`, `vec(ΔS_e) = H'_e φ_e(q)`, φ = [θ~_b; θ~_p] ∈ R⁶ (θ~_p left out
//! where p is a root: its "joint rotation" is the character's heading). The vertices are
//! linear in H' (54 unknowns per key, the bias pinned: with every joint at rest the key is
//! rigid, so the rest pose and any global motion are untouched):
//!
//! ```text
//! min_H'  Σ_i Σ_a |r_a^i − Σ_e α_ae R_e^i mat(H'_e φ_e^i) z_ae|² + λ Σ_e tr(G_e)/18 |H'_e|²
//! ```
//!
//! (r: the vertices less the model). Since R_e is a rotation, proxy e's own block of the
//! normal equations is 3 copies of one 18 x 18 Gram matrix G_e = Σ α² (z ⊗ φ)(z ⊗ φ)ᵀ; the keys
//! are coupled only through shared vertices, so block Gauss–Seidel over the keys solves it
//! with one small Cholesky factor per key. λ is chosen by k-fold cross-validation over the
//! training poses ([`crate::train::cross_validate`]: every held-out pose by its error relative
//! to the rigid predictor's; the most regularised within one standard error of the best, None,
//! the rigid keys, first).

use crate::linalg::DenseCholesky;
use crate::set::ExampleSet;
use crate::train::cross_validate::{cross_validate, Folds};
use crate::train::pose_scale;
use crate::train::reduce::c1c2::Reduced;
use crate::train::rotreg::PoseFeatures;
use crate::train::scale_shear;
use glam::{DMat3, DVec3, DVec4};
use rayon::prelude::*;

/// Ridge strengths tried, relative to each key's mean Gram diagonal, the most regularised first
/// (`None`: S = I kept).
pub const RIDGES: [Option<f64>; 7] = [
    None,
    Some(10.0),
    Some(1.0),
    Some(1e-1),
    Some(1e-2),
    Some(1e-3),
    Some(1e-4),
];
/// Gauss–Seidel sweeps over the keys.
const SWEEPS: usize = 4;

/// What the fit chose: the relative ridge (None: rigid keys kept) and every candidate's
/// held-out score ([`crate::train::cross_validate::Score`]'s mean), in `RIDGES` order (empty
/// where nothing was cross-validated).
#[derive(Debug, Clone, PartialEq)]
pub struct Stretch {
    pub ridge: Option<f64>,
    pub held_out: Vec<f64>,
}

/// H' of one key: `[r * 18 + c * 6 + k]` multiplies φ_k z_c into row r of ΔS z.
type Coefficients = [f64; 54];

struct Problem {
    /// Per key: its vertices (vertex, α, z).
    members: Vec<Vec<(usize, f64, DVec3)>>,
    /// [training pose][key]: R_e and φ_e.
    rotation: Vec<Vec<DMat3>>,
    phi: Vec<Vec<[f64; 6]>>,
    /// [training pose][vertex]: the example less the model.
    residual: Vec<Vec<DVec3>>,
}

impl Problem {
    fn new(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        train: &[usize],
        reduced: &Reduced,
    ) -> Problem {
        let p = reduced.proxies;
        let mut members = vec![Vec::new(); p];
        for (a, inf) in reduced.skin.iter().enumerate() {
            let x = DVec4::from((set.rest[a], 1.0)).to_array();
            for &(e, alpha) in inf.iter().filter(|&&(e, _)| e < p) {
                let z = (0..4).fold(DVec3::ZERO, |z, r| {
                    let row = &reduced.c1[(4 * e + r) * 3 * p + 3 * e..][..3];
                    z + DVec3::from_slice(row) * x[r]
                });
                members[e].push((a, alpha, z));
            }
        }
        let (rotation, phi) = train
            .iter()
            .map(|&i| {
                reduced
                    .predictors
                    .iter()
                    .map(|k| match k.rotation {
                        Some(r) => {
                            let x = scale_shear::features(&feats[i], &set.parents, r.first.bone);
                            // A root's rotation is the character's heading, not a joint: it
                            // must not stretch anything.
                            let joints = match set.parents[r.first.bone].map(|p| set.parents[p]) {
                                Some(Some(_)) => 6,
                                _ => 3,
                            };
                            let mut phi = [0.0; 6];
                            phi[..joints].copy_from_slice(&x[..joints]);
                            (r.predict(&feats[i], &set.parents), phi)
                        }
                        None => (DMat3::IDENTITY, [0.0; 6]),
                    })
                    .unzip()
            })
            .unzip();
        let residual = train
            .par_iter()
            .map(|&i| {
                let model = reduced.predict(set, &feats[i], &set.poses[i].bones);
                set.poses[i]
                    .vertices
                    .iter()
                    .zip(model)
                    .map(|(&y, m)| y - m)
                    .collect()
            })
            .collect();
        Problem {
            members,
            rotation,
            phi,
            residual,
        }
    }

    /// The map z ↦ R_e ΔS z of key e in training pose n under coefficients h: a key's
    /// contribution to its member with key-frame point z is α times it applied to z.
    fn moved(&self, h: &Coefficients, e: usize, n: usize) -> DMat3 {
        let phi = &self.phi[n][e];
        let entry = |r: usize, c: usize| (0..6).map(|k| h[r * 18 + c * 6 + k] * phi[k]).sum();
        let s = DMat3::from_cols_array_2d(&[0, 1, 2].map(|c| [0, 1, 2].map(|r| entry(r, c))));
        self.rotation[n][e] * s
    }

    /// The normal equations' matrix of key e over the poses `inner`: with v = α (z ⊗ φ) per
    /// member and pose, `G = Σ_n Σ_m v vᵀ = (Σ_m α² z zᵀ) ⊗ (Σ_n φ φᵀ)` (18 x 18), the ridge
    /// (relative to its mean diagonal) added; None for a key without features.
    fn factor(&self, e: usize, inner: &[usize], ridge: f64) -> Option<DenseCholesky> {
        let mut zz = [[0.0; 3]; 3];
        for &(_, alpha, z) in &self.members[e] {
            let z = z.to_array();
            (0..9).for_each(|u| zz[u / 3][u % 3] += alpha * alpha * z[u / 3] * z[u % 3]);
        }
        let mut pp = [[0.0; 6]; 6];
        for &n in inner {
            let phi = &self.phi[n][e];
            (0..36).for_each(|u| pp[u / 6][u % 6] += phi[u / 6] * phi[u % 6]);
        }
        let mut g = vec![0.0; 18 * 18];
        for r in 0..18 {
            for c in 0..18 {
                g[r * 18 + c] = zz[r / 6][c / 6] * pp[r % 6][c % 6];
            }
        }
        let mean = (0..18).map(|u| g[u * 19]).sum::<f64>() / 18.0;
        (mean > 0.0).then(|| {
            (0..18).for_each(|u| g[u * 19] += ridge * mean + 1e-12);
            DenseCholesky::new(&g, 18)
        })
    }

    /// H' for every key, fitted on training poses `inner` (indices into `train`): block
    /// coordinate descent over the keys, each a least-squares solve against the residual its
    /// members keep without it.
    fn solve(&self, inner: &[usize], ridge: f64) -> Vec<Coefficients> {
        let p = self.members.len();
        let mut residual: Vec<Vec<DVec3>> =
            inner.iter().map(|&n| self.residual[n].clone()).collect();
        let factors: Vec<Option<DenseCholesky>> =
            (0..p).map(|e| self.factor(e, inner, ridge)).collect();
        let mut h = vec![[0.0; 54]; p];
        for _ in 0..SWEEPS {
            for e in 0..p {
                let Some(factor) = &factors[e] else { continue };
                // b = Σ_n Σ_m α ρ ⊗ z ⊗ φ_n = Σ_n (Σ_m α ρ zᵀ) ⊗ φ_n, ρ = Rᵀ (own residual).
                let mut b = [0.0; 54];
                for (slot, &n) in inner.iter().enumerate() {
                    let (rot_t, old) = (self.rotation[n][e].transpose(), self.moved(&h[e], e, n));
                    let mut w = [[0.0; 3]; 3];
                    for &(a, alpha, z) in &self.members[e] {
                        let own = residual[slot][a] + old * z * alpha;
                        let rho = (rot_t * own).to_array();
                        let z = z.to_array();
                        (0..9).for_each(|u| w[u / 3][u % 3] += alpha * rho[u / 3] * z[u % 3]);
                    }
                    let phi = &self.phi[n][e];
                    (0..54).for_each(|u| b[u] += w[u / 18][(u / 6) % 3] * phi[u % 6]);
                }
                let mut next = [0.0; 54];
                for r in 0..3 {
                    let mut rhs = b[r * 18..][..18].to_vec();
                    factor.solve(&mut rhs);
                    next[r * 18..][..18].copy_from_slice(&rhs);
                }
                for (slot, &n) in inner.iter().enumerate() {
                    let change = self.moved(&h[e], e, n) - self.moved(&next, e, n);
                    for &(a, alpha, z) in &self.members[e] {
                        residual[slot][a] += change * z * alpha;
                    }
                }
                h[e] = next;
            }
        }
        h
    }

    /// Solves on every training pose with `ridge` and adds H' to `reduced`'s keys.
    fn apply(&self, ridge: Option<f64>, reduced: &mut Reduced) {
        let Some(r) = ridge else { return };
        let all: Vec<usize> = (0..self.residual.len()).collect();
        let h = self.solve(&all, r);
        for (k, he) in reduced.predictors.iter_mut().zip(&h) {
            for r in 0..3 {
                for c in 0..3 {
                    for f in 0..6 {
                        k.stretch[7 * (3 * r + c) + f] += he[r * 18 + c * 6 + f];
                    }
                }
            }
        }
    }

    /// Σ squared distances on training pose n with coefficients h.
    fn error(&self, h: &[Coefficients], n: usize) -> f64 {
        let mut r = self.residual[n].clone();
        for (e, he) in h.iter().enumerate() {
            let moved = self.moved(he, e, n);
            for &(a, alpha, z) in &self.members[e] {
                r[a] -= moved * z * alpha;
            }
        }
        r.iter().map(|d| d.length_squared()).sum()
    }
}

/// Fits the stretch of `reduced`'s keys (each proxy must see only its own key, as joint-blend
/// proxies and their refit do), choosing the ridge by `folds`-fold cross-validation.
pub fn fit(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    folds: usize,
    reduced: &mut Reduced,
) -> Stretch {
    let folds = Folds::new(train.len(), folds).filter(|_| reduced.proxies > 0);
    let Some(folds) = folds else {
        return Stretch {
            ridge: None,
            held_out: Vec::new(),
        };
    };
    let problem = Problem::new(set, feats, train, reduced);
    let normaliser = pose_scale::own_rigid_pose_errors(set, train);
    let validated = cross_validate(&folds, &normaliser, RIDGES.len(), 0.0, |fold| {
        RIDGES
            .par_iter()
            .map(|ridge| {
                let h = match ridge {
                    None => Vec::new(),
                    Some(ridge) => problem.solve(&fold.inner, *ridge),
                };
                fold.held.iter().map(|&n| problem.error(&h, n)).collect()
            })
            .collect()
    });
    let ridge = RIDGES[validated.chosen];
    problem.apply(ridge, reduced);
    Stretch {
        ridge,
        held_out: validated.scores.iter().map(|s| s.0).collect(),
    }
}

/// [`fit`] with the ridge given (None: rigid keys) instead of chosen; `held_out` is empty.
pub fn fit_with(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    ridge: Option<f64>,
    reduced: &mut Reduced,
) -> Stretch {
    if ridge.is_some() && reduced.proxies > 0 {
        Problem::new(set, feats, train, reduced).apply(ridge, reduced);
    }
    Stretch {
        ridge,
        held_out: Vec::new(),
    }
}
