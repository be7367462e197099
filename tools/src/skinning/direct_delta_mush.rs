//! Direct Delta DeltaMushReport (Le & Lewis 2019, variant 1), a baseline an engine can run at a small
//! multiple of LBS cost: Delta DeltaMushReport's smoothing is folded, once, into one symmetric 4x4 matrix
//! Ω_ij per vertex i and bone j, so that a pose needs no smoothing at run time.
//!
//! Precomputation, u_k = (x_k, 1) the homogeneous rest position, L̃ = D⁻¹L the normalised
//! (cotangent) Laplacian:
//!
//! - `Ψ_ij = Σ_k C_ik w_kj u_k u_kᵀ`, `C = (I + λ L̃)⁻ᵖ` (p implicit smoothing steps);
//! - `w'_ij = Σ_k B_ik w_kj`, `B = (I + κ L̃)⁻ᵖ` (smoothed weights);
//! - `p_i` the last column of `Σ_j Ψ_ij` divided by its last entry, `P_i = [p_i; 1][p_i; 1]ᵀ`;
//! - `Ω_ij = (1 − α) Ψ_ij + α w'_ij P_i`.
//!
//! Run time, M_j the bone's 4x4 transform: `Q_i = Σ_j M_j Ω_ij`, scaled so that its last entry
//! is 1, read as `[Q q; pᵀ 1]`; the rotation R_i nearest to `Q − q pᵀ` (SVD) and `t_i = q − R_i
//! p` move the vertex: `v'_i = R_i x_i + t_i`. With no smoothing (p = 0, or λ = κ = 0) this is
//! LBS.
//!
//! As in libigl's `direct_delta_mush`, L is the cotangent Laplacian; here negative edge weights
//! (obtuse angles) are clamped to zero, which keeps each step `(D + λL) x' = D x` symmetric
//! positive definite (one sparse Cholesky factor). libigl factors the non-symmetric
//! `I + λ D⁻¹L` with an LDLᵀ that reads one triangle only; this follows the formulas instead.

use crate::linalg::procrustes;
use crate::set::{Affine, ExampleSet};
use crate::skinning::error::squared_error;
use crate::{Error, Result};
use faer::prelude::*;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};

/// The smoothing: p iterations of step λ for the rotations, κ for the translations, and α, the
/// share of the translation taken from the smoothed weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    pub iterations: usize,
    pub lambda: f64,
    pub kappa: f64,
    pub alpha: f64,
}

/// An entry's rigid fit ([`DirectDeltaMush::motions`]) in linear form, what the runtime's delta-mush keys
/// carry ([`rrskin::DeltaMushKey`]): with M_j = [Q_j | d_j] (3x4) the bone transforms,
/// `R = polar(Σ_j M_j A_j)` and `t = Σ_j M_j ω_j − R p`.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    /// Per bone j of the entry: (j, A_j: 4x3 rows, ω_j: 4). With s = Σ_j Ω_j\[3\]\[3\],
    /// `A_j = (Ω_j[.., 0..3] − Ω_j[.., 3] pᵀ) / s` and `ω_j = Ω_j[.., 3] / s`.
    pub terms: Vec<(usize, [[f64; 3]; 4], [f64; 4])>,
    /// p = Σ_j Ω_j\[3\]\[0..3\] / s: the entry's smoothed rest centre.
    pub centre: DVec3,
}

/// The precomputed Ω: per vertex, for the bones j whose smoothed weight at it is above
/// `NEGLIGIBLE`, the upper triangle of the symmetric 4x4 Ω_ij, row by row: (0,0) (0,1) (0,2)
/// (0,3) (1,1) (1,2) (1,3) (2,2) (2,3) (3,3).
#[derive(Debug, Clone)]
pub struct DirectDeltaMush {
    /// V + 1 offsets: vertex i's entries are `omega[starts[i]..starts[i + 1]]`.
    starts: Vec<usize>,
    /// (j, Ω_ij).
    omega: Vec<(usize, [f64; 10])>,
}

/// Smoothing spreads every weight over the whole mesh, mostly by tiny amounts: a bone whose
/// smoothed weights at a vertex (both of them) are below this is left out of its Ω. C and B
/// are entrywise non-negative (inverses of M-matrices), so Ψ_ij's other entries are below it
/// times |u|² too.
const NEGLIGIBLE: f64 = 1e-9;

/// Index into the 10 stored entries of a symmetric 4x4, by row and column.
const UPPER: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 4, 5, 6], [2, 5, 7, 8], [3, 6, 8, 9]];

/// The upper triangle of u uᵀ, u = (x, 1).
fn outer(x: DVec3) -> [f64; 10] {
    let u = [x.x, x.y, x.z, 1.0];
    let mut o = [0.0; 10];
    for r in 0..4 {
        for c in r..4 {
            o[UPPER[r][c]] = u[r] * u[c];
        }
    }
    o
}

impl DirectDeltaMush {
    /// Ω for the mesh (`rest`: V, `faces`), its (bone, weight) lists and J = `bones`.
    pub fn new(
        rest: &[DVec3],
        faces: &[[usize; 3]],
        influences: &[Vec<(usize, f64)>],
        bones: usize,
        params: &Params,
    ) -> Result<DirectDeltaMush> {
        // Without a step, no step's factorisation either (λ = κ = 0 make the identity).
        let unsmoothed = Params {
            lambda: 0.0,
            kappa: 0.0,
            ..*params
        };
        let params = if params.iterations == 0 {
            &unsmoothed
        } else {
            params
        };
        let mut smoothing = Smoothed::new(rest, faces, influences, bones, params)?;
        for _ in 0..params.iterations {
            smoothing.step();
        }
        Ok(smoothing.omega(params.alpha))
    }

    /// Ω of `count` groups of vertices, Ω_gj = Σ_i s_ig Ω_ij, for `shares[i]` = vertex i's
    /// (group g, share s_ig) list; each group keeps the bones j carrying at least `floor` of its
    /// Ω's mass Σ_j Ω_gj\[3\]\[3\] (none dropped for 0), the `cap` heaviest at most. A group's [`DirectDeltaMush::motions`] entry is then
    /// the rigid motion Direct Delta DeltaMushReport gives all its vertices together: a rigid fit of the
    /// group's smoothed, weighted bone motions.
    pub fn grouped(
        &self,
        shares: &[Vec<(usize, f64)>],
        count: usize,
        floor: f64,
        cap: usize,
    ) -> DirectDeltaMush {
        let mut sums: Vec<HashMap<usize, [f64; 10]>> = vec![HashMap::new(); count];
        for (i, vertex_shares) in shares.iter().enumerate() {
            for &(g, share) in vertex_shares {
                for (j, o) in &self.omega[self.starts[i]..self.starts[i + 1]] {
                    let sum = sums[g].entry(*j).or_insert([0.0; 10]);
                    sum.iter_mut().zip(o).for_each(|(a, b)| *a += share * b);
                }
            }
        }
        let mut starts = vec![0];
        let mut omega = Vec::new();
        for group in sums {
            // By bone, so that the mass is summed in one order on every run.
            let mut kept: Vec<(usize, [f64; 10])> = group.into_iter().collect();
            kept.sort_by_key(|(j, _)| *j);
            let mass: f64 = kept.iter().map(|(_, o)| o[9]).sum();
            kept.retain(|(_, o)| o[9] >= floor * mass);
            kept.sort_by(|a, b| b.1[9].total_cmp(&a.1[9]));
            kept.truncate(cap);
            kept.sort_by_key(|(j, _)| *j);
            omega.extend(kept);
            starts.push(omega.len());
        }
        DirectDeltaMush { starts, omega }
    }

    /// Per entry (vertex, or group of [`DirectDeltaMush::grouped`]) its rigid motion under `bones` (J); the
    /// identity for an entry without weight.
    pub fn motions(&self, bones: &[Affine]) -> Vec<Affine> {
        (0..self.starts.len() - 1)
            .map(|i| {
                let omega = &self.omega[self.starts[i]..self.starts[i + 1]];
                let (q, d) = moved(omega, bones).unwrap_or((DMat3::IDENTITY, DVec3::ZERO));
                Affine { q, d }
            })
            .collect()
    }

    /// Entry i's rigid fit in linear form (the same motion as [`DirectDeltaMush::motions`]); None for an
    /// entry without weight (which stays at rest).
    pub fn linear_fit(&self, i: usize) -> Option<LinearFit> {
        let omega = &self.omega[self.starts[i]..self.starts[i + 1]];
        let full = |o: &[f64; 10]| -> [[f64; 4]; 4] {
            std::array::from_fn(|r| std::array::from_fn(|c| o[UPPER[r][c]]))
        };
        let scale: f64 = omega.iter().map(|(_, o)| o[9]).sum();
        if scale.is_nan() || scale <= 0.0 {
            return None;
        }
        let p: [f64; 3] =
            std::array::from_fn(|c| omega.iter().map(|(_, o)| o[UPPER[3][c]]).sum::<f64>() / scale);
        let terms = (omega.iter())
            .map(|(j, o)| {
                let o = full(o);
                let a = std::array::from_fn(|k| {
                    std::array::from_fn(|c| (o[k][c] - o[k][3] * p[c]) / scale)
                });
                (*j, a, std::array::from_fn(|k| o[k][3] / scale))
            })
            .collect();
        Some(LinearFit {
            terms,
            centre: DVec3::from(p),
        })
    }

    /// The entries: vertices, or groups of [`DirectDeltaMush::grouped`].
    pub fn entries(&self) -> usize {
        self.starts.len() - 1
    }

    /// The mean number of bones per entry: the run-time cost of [`DirectDeltaMush::motions`] is about 48
    /// multiply-adds per entry and bone, and one 3x3 rotation fit per entry.
    pub fn mean_bones(&self) -> f64 {
        self.omega.len() as f64 / (self.starts.len() - 1).max(1) as f64
    }

    /// The mesh of each of the poses `poses` of `set`.
    pub fn deform_poses(&self, set: &ExampleSet, poses: &[usize]) -> Vec<Vec<DVec3>> {
        (poses.iter())
            .map(|&i| self.deform(&set.rest, &set.poses[i].bones))
            .collect()
    }

    /// Each vertex of `rest` moved under `bones` (J).
    pub fn deform(&self, rest: &[DVec3], bones: &[Affine]) -> Vec<DVec3> {
        rest.par_iter()
            .enumerate()
            .map(|(i, &x)| {
                let omega = &self.omega[self.starts[i]..self.starts[i + 1]];
                moved(omega, bones).map_or(x, |(r, t)| r * x + t)
            })
            .collect()
    }
}

/// The rigid motion (R_i, t_i) of a vertex of Ω `omega` under `bones`; None without weight.
fn moved(omega: &[(usize, [f64; 10])], bones: &[Affine]) -> Option<(DMat3, DVec3)> {
    // Q's top three rows Σ_j [q_j | d_j] Ω_ij, and its last row Σ_j Ω_ij's.
    let (mut top, mut last) = ([[0.0; 4]; 3], [0.0; 4]);
    for (j, o) in omega {
        let bone = &bones[*j];
        for c in 0..4 {
            last[c] += o[UPPER[3][c]];
        }
        for r in 0..3 {
            let m = bone.row(r);
            for c in 0..4 {
                top[r][c] += (0..4).map(|k| m[k] * o[UPPER[k][c]]).sum::<f64>();
            }
        }
    }
    let scale = last[3];
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let q = DVec3::new(top[0][3], top[1][3], top[2][3]) / scale;
    let p = DVec3::new(last[0], last[1], last[2]) / scale;
    let column = |c: usize| DVec3::new(top[0][c], top[1][c], top[2][c]) / scale - q * p[c];
    let r = procrustes(DMat3::from_cols(column(0), column(1), column(2)));
    Some((r, q - r * p))
}

/// λ and κ of libigl's example (tutorial 408), fixed in advance; p and α are chosen on the
/// training poses ([`choose`]).
pub const LAMBDA: f64 = 3.0;
pub const KAPPA: f64 = 1.0;
/// The candidate p, increasing: all of them cost as many smoothing steps as the last.
pub const ITERATIONS: [usize; 6] = [1, 2, 4, 8, 16, 32];
/// The candidate α (libigl's example uses 0.8).
pub const ALPHAS: [f64; 3] = [0.2, 0.5, 0.8];

/// Of the candidates [`ITERATIONS`] x [`ALPHAS`] (λ = [`LAMBDA`], κ = [`KAPPA`]), the one of
/// least squared error over the poses `poses` of `set` for the (bone, weight) lists
/// `influences` (V; SSD's), and its Ω.
pub fn choose(
    set: &ExampleSet,
    poses: &[usize],
    influences: &[Vec<(usize, f64)>],
) -> Result<(Params, DirectDeltaMush)> {
    let error = |d: &DirectDeltaMush| squared_error(set, poses, &d.deform_poses(set, poses));
    let (rest, faces, bones) = (&set.rest, &set.faces, set.bone_count());
    let mut params = Params {
        iterations: 0,
        lambda: LAMBDA,
        kappa: KAPPA,
        alpha: 0.0,
    };
    let mut smoothing = Smoothed::new(rest, faces, influences, bones, &params)?;
    let mut best: Option<(f64, Params, DirectDeltaMush)> = None;
    for iterations in ITERATIONS {
        while params.iterations < iterations {
            smoothing.step();
            params.iterations += 1;
        }
        let mut improved = false;
        for alpha in ALPHAS {
            let direct_delta_mush = smoothing.omega(alpha);
            let e = error(&direct_delta_mush);
            if best.as_ref().is_none_or(|b| e < b.0) {
                best = Some((e, Params { alpha, ..params }, direct_delta_mush));
                improved = true;
            }
        }
        // More smoothing past the first p that helps no α does not help either (the error is
        // taken as unimodal in p): the remaining, costlier candidates are skipped.
        if !improved {
            break;
        }
    }
    // None only with no candidates (ITERATIONS or ALPHAS empty).
    let (_, params, direct_delta_mush) = best.ok_or_else(|| Error::Baseline {
        method: "direct delta mush",
        problem: "no smoothing parameters to choose from".into(),
    })?;
    Ok((params, direct_delta_mush))
}

/// Ψ and w' after some number of smoothing steps, from which Ω follows for any α.
struct Smoothed {
    bones: usize,
    /// V x 10J: column 10j + e is entry e of Ψ_ij over the vertices.
    psi: Mat<f64>,
    /// V x J: w'_ij.
    weights: Mat<f64>,
    rotations: Step,
    translations: Step,
}

impl Smoothed {
    /// Ψ and w' before smoothing (p = 0), with the steps of `params`' λ and κ.
    fn new(
        rest: &[DVec3],
        faces: &[[usize; 3]],
        influences: &[Vec<(usize, f64)>],
        bones: usize,
        params: &Params,
    ) -> Result<Smoothed> {
        let v = rest.len();
        let (mut psi, mut weights) = (
            Mat::<f64>::zeros(v, 10 * bones),
            Mat::<f64>::zeros(v, bones),
        );
        for (k, (&x, inf)) in rest.iter().zip(influences).enumerate() {
            let u = outer(x);
            for &(j, w) in inf {
                weights[(k, j)] += w;
                for e in 0..10 {
                    psi[(k, 10 * j + e)] += w * u[e];
                }
            }
        }
        let edges = cotangent_weights(rest, faces);
        Ok(Smoothed {
            bones,
            psi,
            weights,
            rotations: Step::new(v, &edges, params.lambda)?,
            translations: Step::new(v, &edges, params.kappa)?,
        })
    }

    /// One more smoothing step (p + 1).
    fn step(&mut self) {
        self.rotations.apply(&mut self.psi);
        self.translations.apply(&mut self.weights);
    }

    /// Ω_ij = (1 − α) Ψ_ij + α w'_ij P_i.
    fn omega(&self, alpha: f64) -> DirectDeltaMush {
        let (j_count, v) = (self.bones, self.psi.nrows());
        let per_vertex: Vec<Vec<(usize, [f64; 10])>> = (0..v)
            .into_par_iter()
            .map(|i| {
                let psi = |j: usize, e: usize| self.psi[(i, 10 * j + e)];
                let total = |e: usize| (0..j_count).map(|j| psi(j, e)).sum::<f64>();
                let mass = total(9);
                let centre = match mass != 0.0 {
                    true => DVec3::new(total(3), total(6), total(8)) / mass,
                    false => DVec3::ZERO,
                };
                let p = outer(centre);
                (0..j_count)
                    .filter(|&j| psi(j, 9).abs().max(self.weights[(i, j)].abs()) > NEGLIGIBLE)
                    .map(|j| {
                        let w = self.weights[(i, j)];
                        let o =
                            std::array::from_fn(|e| (1.0 - alpha) * psi(j, e) + alpha * w * p[e]);
                        (j, o)
                    })
                    .collect()
            })
            .collect();
        let mut starts = Vec::with_capacity(v + 1);
        starts.push(0);
        for o in &per_vertex {
            starts.push(starts[starts.len() - 1] + o.len());
        }
        DirectDeltaMush {
            starts,
            omega: per_vertex.into_iter().flatten().collect(),
        }
    }
}

/// The implicit smoothing step `x ↦ (I + λ D⁻¹L)⁻¹ x`, solved as `(D + λL) x' = D x` (D's zero
/// entries, vertices on no edge of positive weight, taken as 1: they keep their value).
struct Step {
    diagonal: Vec<f64>,
    /// None for λ = 0: the identity.
    llt: Option<Llt<usize, f64>>,
}

impl Step {
    fn new(vertices: usize, edges: &BTreeMap<(usize, usize), f64>, lambda: f64) -> Result<Step> {
        let mut diagonal = vec![0.0; vertices];
        for (&(a, b), &w) in edges {
            diagonal[a] += w;
            diagonal[b] += w;
        }
        for d in &mut diagonal {
            if *d <= 0.0 {
                *d = 1.0;
            }
        }
        if lambda == 0.0 {
            return Ok(Step {
                diagonal,
                llt: None,
            });
        }
        let problem = |what: String| Error::Baseline {
            method: "direct delta mush",
            problem: what,
        };
        if lambda < 0.0 || !lambda.is_finite() {
            return Err(problem(format!("smoothing step {lambda}: must be ≥ 0")));
        }
        let mut trips: Vec<Triplet<usize, usize, f64>> = (0..vertices)
            .map(|a| Triplet::new(a, a, diagonal[a]))
            .collect();
        for (&(a, b), &w) in edges {
            let lw = lambda * w;
            trips.extend([
                Triplet::new(a, a, lw),
                Triplet::new(b, b, lw),
                Triplet::new(a, b, -lw),
                Triplet::new(b, a, -lw),
            ]);
        }
        let m = SparseColMat::<usize, f64>::try_new_from_triplets(vertices, vertices, &trips)
            .map_err(|e| problem(format!("Laplacian assembly: {e:?}")))?;
        let sym = SymbolicLlt::try_new(m.symbolic(), Side::Lower)
            .map_err(|e| problem(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(sym, m.as_ref(), Side::Lower)
            .map_err(|e| problem(format!("smoothing system not positive definite: {e:?}")))?;
        Ok(Step {
            diagonal,
            llt: Some(llt),
        })
    }

    fn apply(&self, x: &mut Mat<f64>) {
        let Some(llt) = &self.llt else {
            return;
        };
        for c in 0..x.ncols() {
            for (r, d) in self.diagonal.iter().enumerate() {
                x[(r, c)] *= d;
            }
        }
        llt.solve_in_place(x.as_mut());
    }
}

/// The cotangent Laplacian's edge weights `½ (cot α + cot β)` (a < b), negative ones clamped to
/// zero; degenerate triangles add nothing. Ordered, so that the Laplacian's sums, and the
/// models made from it, are the same bytes on every run.
fn cotangent_weights(rest: &[DVec3], faces: &[[usize; 3]]) -> BTreeMap<(usize, usize), f64> {
    let mut edges: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    for f in faces {
        let corners = [0, 1, 2].map(|c| rest[f[c]]);
        let area2 = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .length();
        if area2 <= 0.0 || !area2.is_finite() {
            continue;
        }
        for o in 0..3 {
            let (a, b) = (f[(o + 1) % 3], f[(o + 2) % 3]);
            if a == b {
                continue;
            }
            let (ea, eb) = (rest[a] - corners[o], rest[b] - corners[o]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 0.5 * ea.dot(eb) / area2;
        }
    }
    edges.retain(|_, w| *w > 0.0);
    edges
}

#[cfg(test)]
impl DirectDeltaMush {
    /// Ω_ij's entries (zero where left out).
    fn omega_of(&self, i: usize, j: usize) -> [f64; 10] {
        let entries = &self.omega[self.starts[i]..self.starts[i + 1]];
        entries.iter().find(|o| o.0 == j).map_or([0.0; 10], |o| o.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rest positions, triangles and (bone, weight) lists.
    type Mesh = (Vec<DVec3>, Vec<[usize; 3]>, Vec<Vec<(usize, f64)>>);
    use crate::cylinder_chain::Chain;
    use crate::skinning::lbs::Skinning;
    use glam::DQuat;

    /// The synthetic chain's tube of `rings` x 6 vertices along x ∈ [0, 1], made bumpy (radii
    /// and turns varying by vertex, so that some cotangent weights are negative), weights
    /// blending bone 0 into bone 1 along it.
    fn tube(rings: usize) -> Mesh {
        let chain = Chain {
            rings,
            segments: 6,
            bones: 1,
            poses: 2,
        };
        let set = chain.build().expect("a valid size");
        let rest: Vec<DVec3> = (set.rest.iter().enumerate())
            .map(|(v, p)| {
                let (r, s) = (v / 6, v % 6);
                let turn = DMat3::from_rotation_x(0.3 * (r % 2) as f64);
                let radius = 1.0 + 0.2 * ((r * 7 + s * 3) % 5) as f64;
                turn * DVec3::new(p.x, radius * p.y, radius * p.z)
            })
            .collect();
        let weights = rest
            .iter()
            .map(|p| vec![(0, 1.0 - p.x), (1, p.x)])
            .collect();
        (rest, set.faces, weights)
    }

    fn bones() -> Vec<Affine> {
        vec![
            Affine {
                q: DMat3::from_rotation_y(0.3),
                d: DVec3::new(0.1, 0.2, -0.1),
            },
            Affine {
                q: DMat3::from_quat(DQuat::from_axis_angle(
                    DVec3::new(1.0, 0.5, 0.2).normalize(),
                    1.9,
                )),
                d: DVec3::new(-0.3, 0.5, 0.4),
            },
        ]
    }

    #[test]
    fn no_smoothing_is_linear_blend_skinning() {
        let (rest, faces, weights) = tube(8);
        let lbs = Skinning {
            influences: weights.clone(),
        }
        .deform(&rest, &bones());
        for params in [
            Params {
                iterations: 0,
                lambda: 3.0,
                kappa: 1.0,
                alpha: 0.8,
            },
            Params {
                iterations: 5,
                lambda: 0.0,
                kappa: 0.0,
                alpha: 0.8,
            },
        ] {
            let direct_delta_mush =
                DirectDeltaMush::new(&rest, &faces, &weights, 2, &params).expect("precomputation");
            let moved = direct_delta_mush.deform(&rest, &bones());
            for (a, b) in moved.iter().zip(&lbs) {
                assert!((*a - *b).length() < 1e-9, "{params:?}: {a:?} vs {b:?}");
            }
        }
        // And smoothing does change it (so the comparison above can fail).
        let smooth = Params {
            iterations: 5,
            lambda: 3.0,
            kappa: 1.0,
            alpha: 0.8,
        };
        let moved = DirectDeltaMush::new(&rest, &faces, &weights, 2, &smooth)
            .expect("precomputation")
            .deform(&rest, &bones());
        let gap = moved
            .iter()
            .zip(&lbs)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(gap > 1e-2, "smoothing moved nothing: {gap}");
    }

    /// One group per vertex moves as the vertex; a group of vertices under one rigid motion of
    /// every bone moves rigidly with it.
    #[test]
    fn groups_move_as_their_vertices() {
        let (rest, faces, weights) = tube(8);
        let params = Params {
            iterations: 5,
            lambda: 3.0,
            kappa: 1.0,
            alpha: 0.5,
        };
        let direct_delta_mush =
            DirectDeltaMush::new(&rest, &faces, &weights, 2, &params).expect("precomputation");
        let alone: Vec<Vec<(usize, f64)>> = (0..rest.len()).map(|i| vec![(i, 1.0)]).collect();
        let singles = direct_delta_mush.grouped(&alone, rest.len(), 0.0, usize::MAX);
        assert_eq!(singles.entries(), rest.len());
        let moved = direct_delta_mush.deform(&rest, &bones());
        for ((m, x), y) in singles.motions(&bones()).iter().zip(&rest).zip(&moved) {
            assert!(
                (m.apply(*x) - *y).length() < 1e-9,
                "{:?} vs {y:?}",
                m.apply(*x)
            );
        }
        let halves: Vec<Vec<(usize, f64)>> = (0..rest.len()).map(|i| vec![(i % 2, 1.0)]).collect();
        let turn = Affine {
            q: DMat3::from_rotation_y(0.7),
            d: DVec3::new(0.1, -0.2, 0.3),
        };
        for m in direct_delta_mush
            .grouped(&halves, 2, 1e-3, usize::MAX)
            .motions(&[turn, turn])
        {
            assert!(m.q.abs_diff_eq(turn.q, 1e-9) && (m.d - turn.d).length() < 1e-9);
        }
    }

    /// The paper's formulas with dense matrices: the cotangent weights from the angles, C and B
    /// as inverses of `I + λ D⁻¹L`, Ω, Q and its SVD, each written out.
    #[test]
    fn matches_the_formulas_on_a_small_mesh() {
        let (rest, faces, weights) = tube(5);
        let params = Params {
            iterations: 3,
            lambda: 2.0,
            kappa: 0.7,
            alpha: 0.6,
        };
        let (v, j) = (rest.len(), 2);
        // Edge weights ½ Σ cot of the opposite angles, clamped at zero (the one deviation from
        // libigl, documented above); L = Σ_edges w (e_a − e_b)(e_a − e_b)ᵀ.
        let mut edge = Mat::<f64>::zeros(v, v);
        for f in &faces {
            for o in 0..3 {
                let (a, b) = (f[(o + 1) % 3], f[(o + 2) % 3]);
                let angle = (rest[a] - rest[f[o]]).angle_between(rest[b] - rest[f[o]]);
                edge[(a.min(b), a.max(b))] += 0.5 / angle.tan();
            }
        }
        let mut lap = Mat::<f64>::zeros(v, v);
        let mut clamped = 0;
        for a in 0..v {
            for b in a + 1..v {
                clamped += usize::from(edge[(a, b)] < 0.0);
                let w = edge[(a, b)].max(0.0);
                lap[(a, b)] -= w;
                lap[(b, a)] -= w;
                lap[(a, a)] += w;
                lap[(b, b)] += w;
            }
        }
        assert!(clamped > 0, "the test mesh should exercise the clamping");
        let power = |step: f64| {
            let m = Mat::<f64>::from_fn(v, v, |a, b| {
                let identity = if a == b { 1.0 } else { 0.0 };
                identity + step * lap[(a, b)] / lap[(a, a)]
            });
            let inverse = m.partial_piv_lu().solve(&Mat::<f64>::identity(v, v));
            let mut c = Mat::<f64>::identity(v, v);
            for _ in 0..params.iterations {
                c = &c * &inverse;
            }
            c
        };
        let (c, b) = (power(params.lambda), power(params.kappa));
        let w = |k: usize, bone: usize| weights[k][bone].1;
        let u = |k: usize| [rest[k].x, rest[k].y, rest[k].z, 1.0];
        let direct_delta_mush =
            DirectDeltaMush::new(&rest, &faces, &weights, j, &params).expect("precomputation");
        let expected_moved: Vec<DVec3> = (0..v)
            .map(|i| {
                let psi = |bone: usize, r: usize, s: usize| {
                    (0..v)
                        .map(|k| c[(i, k)] * w(k, bone) * u(k)[r] * u(k)[s])
                        .sum::<f64>()
                };
                let w_prime = |bone: usize| (0..v).map(|k| b[(i, k)] * w(k, bone)).sum::<f64>();
                let last = |r: usize| (0..j).map(|bone| psi(bone, r, 3)).sum::<f64>();
                let p = [last(0) / last(3), last(1) / last(3), last(2) / last(3), 1.0];
                let omega = |bone: usize, r: usize, s: usize| {
                    (1.0 - params.alpha) * psi(bone, r, s)
                        + params.alpha * w_prime(bone) * p[r] * p[s]
                };
                for bone in 0..j {
                    for r in 0..4 {
                        for s in r..4 {
                            let got = direct_delta_mush.omega_of(i, bone)[UPPER[r][s]];
                            let want = omega(bone, r, s);
                            assert!(
                                (got - want).abs() < 1e-9 * (1.0 + want.abs()),
                                "Ω {i} {bone} ({r},{s}): {got} vs {want}"
                            );
                        }
                    }
                }
                // Q = Σ_j M_j Ω_ij, normalised; R from the SVD of Q − q pᵀ.
                let mut q = [[0.0; 4]; 4];
                for (bone, m) in bones().iter().enumerate() {
                    for r in 0..4 {
                        let row = if r < 3 {
                            m.row(r)
                        } else {
                            [0.0, 0.0, 0.0, 1.0]
                        };
                        for s in 0..4 {
                            q[r][s] += (0..4).map(|k| row[k] * omega(bone, k, s)).sum::<f64>();
                        }
                    }
                }
                let n = q[3][3];
                let col = |s: usize| {
                    DVec3::from_array(std::array::from_fn(|r| {
                        q[r][s] / n - q[r][3] / n * q[3][s] / n
                    }))
                };
                let cross = DMat3::from_cols(col(0), col(1), col(2));
                let (u, _, vt) = crate::linalg::svd3(cross);
                let rot = u * vt.transpose();
                let (qv, pv) = (
                    DVec3::new(q[0][3], q[1][3], q[2][3]) / n,
                    DVec3::new(q[3][0], q[3][1], q[3][2]) / n,
                );
                rot * rest[i] + qv - rot * pv
            })
            .collect();
        let moved = direct_delta_mush.deform(&rest, &bones());
        for (i, (a, e)) in moved.iter().zip(&expected_moved).enumerate() {
            assert!((*a - *e).length() < 1e-9, "vertex {i}: {a:?} vs {e:?}");
        }
    }
}
