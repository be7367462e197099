//! Poisson reconstruction (paper §4.1–4.2, Eq. 2; docs/method.md §5): positions whose triangle
//! edges best match predicted gradients, `min Σ_k Σ_j=2,3 |y_kj − y_k1 − D_k v̂_kj|²`, with the
//! near-rigid vertices F fixed to their SSD positions. Per coordinate c with one matrix:
//! `A_Uᵀ A_U y_U,c = A_Uᵀ (b_c − A_F y_F,c)`, A the 2T x V edge incidence. `A_Uᵀ A_U` is
//! factored once (faer sparse Cholesky) and reused for every pose.

use faer::prelude::*;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use glam::{DMat3, DVec3};

pub struct Poisson {
    faces: Vec<[usize; 3]>,
    /// Rest edges v̂2, v̂3 per triangle.
    edges: Vec<[DVec3; 2]>,
    /// Unknown index of each free vertex (None: fixed).
    free: Vec<Option<usize>>,
    llt: Llt<usize, f64>,
}

#[derive(Debug)]
pub struct PoissonError(pub String);

impl std::fmt::Display for PoissonError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Poisson system: {}", self.0)
    }
}

impl std::error::Error for PoissonError {}

impl Poisson {
    /// `fixed`: V flags. Every connected component must hold a fixed vertex (see
    /// [`anchor_components`]), or the system is singular.
    pub fn new(
        rest: &[DVec3],
        faces: &[[usize; 3]],
        fixed: &[bool],
    ) -> Result<Poisson, PoissonError> {
        assert_eq!(
            rest.len(),
            fixed.len(),
            "Poisson: one fixed flag per vertex"
        );
        let mut free = vec![None; rest.len()];
        let mut n = 0;
        for (a, f) in fixed.iter().enumerate() {
            if !f {
                free[a] = Some(n);
                n += 1;
            }
        }
        let mut trips = Vec::with_capacity(faces.len() * 8);
        for &[k1, k2, k3] in faces {
            for kj in [k2, k3] {
                // Row e: +1 at kj, −1 at k1 → AᵀA gets [1 −1; −1 1] on (kj, k1).
                for (x, sx) in [(kj, 1.0), (k1, -1.0)] {
                    for (y, sy) in [(kj, 1.0), (k1, -1.0)] {
                        if let (Some(i), Some(j)) = (free[x], free[y]) {
                            trips.push(Triplet::new(i, j, sx * sy));
                        }
                    }
                }
            }
        }
        if n == 0 {
            return Err(PoissonError("every vertex is fixed".into()));
        }
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trips)
            .map_err(|e| PoissonError(format!("assembly: {e:?}")))?;
        let sym = SymbolicLlt::try_new(a.symbolic(), Side::Lower)
            .map_err(|e| PoissonError(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(sym, a.as_ref(), Side::Lower).map_err(|e| {
            PoissonError(format!(
                "not positive definite ({e:?}): a component without a fixed vertex?"
            ))
        })?;
        let edges = faces
            .iter()
            .map(|&[a, b, c]| [rest[b] - rest[a], rest[c] - rest[a]])
            .collect();
        Ok(Poisson {
            faces: faces.to_vec(),
            edges,
            free,
            llt,
        })
    }

    /// Reconstructs one mesh per pose from its T gradients and its positions for fixed vertices
    /// (entries of free vertices are ignored, and replaced in the output).
    pub fn solve(&self, poses: &[(Vec<DMat3>, Vec<DVec3>)]) -> Vec<Vec<DVec3>> {
        let n = self.free.iter().filter(|f| f.is_some()).count();
        let mut rhs = Mat::<f64>::zeros(n, 3 * poses.len());
        for (p, (grads, fixed_pos)) in poses.iter().enumerate() {
            for ((&[k1, k2, k3], e), d) in self.faces.iter().zip(&self.edges).zip(grads) {
                for (kj, ej) in [(k2, e[0]), (k3, e[1])] {
                    // Target edge b = D v̂, minus the known (fixed) part of the row.
                    let mut b = *d * ej;
                    if self.free[kj].is_none() {
                        b -= fixed_pos[kj];
                    }
                    if self.free[k1].is_none() {
                        b += fixed_pos[k1];
                    }
                    for (x, s) in [(kj, 1.0), (k1, -1.0)] {
                        if let Some(i) = self.free[x] {
                            for c in 0..3 {
                                rhs[(i, 3 * p + c)] += s * b[c];
                            }
                        }
                    }
                }
            }
        }
        self.llt.solve_in_place(rhs.as_mut());
        poses
            .iter()
            .enumerate()
            .map(|(p, (_, fixed_pos))| {
                fixed_pos
                    .iter()
                    .zip(&self.free)
                    .map(|(&y, f)| match f {
                        Some(i) => {
                            DVec3::new(rhs[(*i, 3 * p)], rhs[(*i, 3 * p + 1)], rhs[(*i, 3 * p + 2)])
                        }
                        None => y,
                    })
                    .collect()
            })
            .collect()
    }
}

/// Adds to `fixed` the lowest-`cost` vertex of every connected component that has none (so the
/// Poisson system is non-singular); vertices in no triangle are fixed.
pub fn anchor_components(
    vertex_count: usize,
    faces: &[[usize; 3]],
    fixed: &mut [bool],
    cost: &[f64],
) {
    let mut parent: Vec<usize> = (0..vertex_count).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for &[a, b, c] in faces {
        for (x, y) in [(a, b), (a, c)] {
            let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
            if rx != ry {
                parent[rx] = ry;
            }
        }
    }
    let mut best: Vec<Option<usize>> = vec![None; vertex_count];
    let mut anchored = vec![false; vertex_count];
    for a in 0..vertex_count {
        let r = find(&mut parent, a);
        anchored[r] |= fixed[a];
        if best[r].is_none_or(|b| cost[a] < cost[b]) {
            best[r] = Some(a);
        }
    }
    for r in 0..vertex_count {
        if let (false, Some(a)) = (anchored[r], best[r]) {
            fixed[a] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::gradients::{gradients, rest_inverses};

    #[test]
    fn exact_gradients_reproduce_the_mesh() {
        // A 6 x 6 grid, bent and twisted; one fixed corner.
        let n = 6;
        let rest: Vec<DVec3> = (0..n * n)
            .map(|i| DVec3::new((i % n) as f64, (i / n) as f64, 0.0))
            .collect();
        let mut faces = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                let a = y * n + x;
                faces.push([a, a + 1, a + n + 1]);
                faces.push([a, a + n + 1, a + n]);
            }
        }
        let posed: Vec<DVec3> = rest
            .iter()
            .map(|p| {
                let r = rrskin::predict::exp_rotation(DVec3::new(
                    0.1 * p.y,
                    0.2 * p.x,
                    0.05 * p.x * p.y,
                ));
                r * (*p * 1.1) + DVec3::new(0.0, 0.0, 0.1 * p.x * p.x)
            })
            .collect();
        let mut fixed = vec![false; rest.len()];
        anchor_components(rest.len(), &faces, &mut fixed, &vec![0.0; rest.len()]);
        assert_eq!(fixed.iter().filter(|&&f| f).count(), 1);
        let solver = Poisson::new(&rest, &faces, &fixed).expect("factor");
        let grads = gradients(&posed, &faces, &rest_inverses(&rest, &faces));
        let out = solver.solve(&[(grads, posed.clone())]);
        for (a, b) in out[0].iter().zip(&posed) {
            assert!((*a - *b).length() < 1e-9, "{a} vs {b}");
        }
    }
}
